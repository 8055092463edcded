"""The measurement rig as the calibration is told it: where the instrument is, where it hooks.

The nominal values of everything around the robot that a measurement model needs. Each may be
known (used as it is) or an unknown group whose correction is identified with the robot's
errors (:mod:`twin.unknowns`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import frozen_array

Array = NDArray[np.float64]

MAX_TENSION_N = 1000.0
"""Largest cable tension accepted, N: drawstring springs pull a few newtons; a kilonewton would
bend an IRB 120 rather than load it."""


def _origin() -> Array:
    return np.zeros(3)


@dataclass(frozen=True)
class Rig:
    """Ports of the cable and the point of the tool that is measured.

    Attributes:
        ports_m: Cable ports in the robot base frame, shape (k, 3), m; row j is the port a
            measurement with ``port == j`` ran from.
        port_names: A name per port, length k.
        attachment_m: The measured point (cable eyelet, tracker target, ball) in the flange
            frame, shape (3,), m; the flange centre by default.
        tension_n: The cable's pull on the attachment point, towards each row's port, N (a
            drawstring encoder's spring force; its data sheet gives it). It loads the joints
            of a compliant arm (unknown group ``compliance``); 0 for instruments that do not
            touch the robot.
    """

    ports_m: Array = field(default_factory=lambda: np.zeros((0, 3)))
    port_names: tuple[str, ...] = ()
    attachment_m: Array = field(default_factory=_origin)
    tension_n: float = 0.0

    def __post_init__(self) -> None:
        ports = np.asarray(self.ports_m, dtype=np.float64).reshape(-1, 3)
        object.__setattr__(self, "ports_m", frozen_array(ports, ports.shape, "ports_m"))
        names = tuple(self.port_names) or tuple(
            "port" if len(ports) == 1 else f"port{j + 1}" for j in range(len(ports)))
        if len(names) != len(ports) or len(set(names)) != len(names):
            raise ValueError(f"port_names {names!r}: expected {len(ports)} distinct names")
        object.__setattr__(self, "port_names", names)
        object.__setattr__(self, "attachment_m",
                           frozen_array(self.attachment_m, (3,), "attachment_m"))
        if not (np.isfinite(self.tension_n) and 0.0 <= self.tension_n <= MAX_TENSION_N):
            raise ValueError(f"tension_n: {self.tension_n}, expected 0 to {MAX_TENSION_N:g} N")
        object.__setattr__(self, "tension_n", float(self.tension_n))

    @classmethod
    def cable(cls, port_m: ArrayLike, attachment_m: ArrayLike | None = None,
              tension_n: float = 0.0) -> Rig:
        """One port, base frame, shape (3,), m; the measured point at ``attachment_m``; the
        cable pulling with ``tension_n`` newtons."""
        return cls(np.asarray(port_m, dtype=np.float64).reshape(1, 3),
                   attachment_m=_origin() if attachment_m is None
                   else np.asarray(attachment_m, dtype=np.float64), tension_n=tension_n)

    @property
    def port_m(self) -> Array:
        """The only port, shape (3,), m.

        Raises:
            ValueError: if the rig has no port or several.
        """
        if len(self.ports_m) != 1:
            raise ValueError(f"the rig has {len(self.ports_m)} ports, not one")
        return self.ports_m[0]
