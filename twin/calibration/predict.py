"""What an identified model predicts at any poses: where the measured point is, what its
instrument reads. This is how a model is checked against anything else (a tracker, another
capture, the twin's truth)::

    settings = twin.CalibrationSettings(errors=("dh", "compliance"))
    result = twin.calibrate(robot, data, rig=rig, settings=settings)
    prediction = twin.predict(result, q_rad, approach=None)   # or a load_result(...) model
    prediction.position_m               # (m, 3) measured point, base frame, m
    prediction.readings["length_m"]     # (m,) cable length, m, when the rig has one port
    prediction.readings["position_m"]   # (m, 3) the point in the tracker frame, m, for
                                        # tracker results

The readings are the measurement kind's (:meth:`twin.kinds.base.Kind.predict`).

The measured point is the rig's attachment point (the flange centre unless one is set), moved by
every group of the model: the D-H table, the joints' transmission error, backlash (for each row's
approach direction) and compliance (under gravity and the cable's pull at the pose).
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple, Protocol

import numpy as np
from numpy.typing import ArrayLike

from twin.arrays import Array
from twin.calibration.start import check_approach
from twin.dataset import TEMPERATURE
from twin.model import Model


class Identified(Protocol):
    """An identified model: a calibration result, or one read back from a result file."""

    @property
    def model(self) -> Model:
        """The measurement model that was fitted."""
        ...

    @property
    def x(self) -> Array:
        """The identified unknowns, shape (p,), SI."""
        ...


class Prediction(NamedTuple):
    """What the identified model predicts at each pose."""

    position_m: Array
    """The measured point in the base frame, shape (m, 3), m."""
    kind: str
    """The measurement kind of the model (:data:`twin.kinds.KINDS`), whose readings these
    are."""
    readings: dict[str, Array]
    """What the instrument reads there, by the kind's names (:meth:`twin.kinds.base.Kind.predict`:
    ``length_m`` (m,) of a cable from a single port, ``position_m`` (m, 3) of a tracker in its
    frame…), SI."""


def predict(identified: Identified, q_rad: ArrayLike, *, approach: ArrayLike | None = None,
            port_m: ArrayLike | None = None, temperature_c: ArrayLike | None = None
            ) -> Prediction:
    """The measured point (and cable length) an identified model predicts at poses.

    Args:
        identified: The model and its unknowns
        (:class:`~twin.calibration.pipeline.CalibrationResult`,
            :class:`~twin.io.identified.IdentifiedModel`).
        q_rad: Joint angles, shape (m, n), rad.
        approach: The direction each joint approached each pose from, shape (m, n), ±1; needed
            when the model has backlash.
        port_m: A port in the base frame, shape (3,), m: the length is the straight distance
            from it (no identified port correction or offset applies to a port one names), and
            the cable pulls towards it (compliance). None: the model's own single port, its
            identified correction and offset included.
        temperature_c: The temperature at each pose, shape (m,), °C, for a model with thermal
            growth (:mod:`twin.unknowns.thermal`); None: at the model's reference temperature.

    Raises:
        InputError: if the model has backlash and no approach directions are given.
    """
    model, x = identified.model, np.asarray(identified.x, dtype=np.float64)
    if port_m is not None:
        rig = replace(model.rig, ports_m=np.asarray(port_m, dtype=np.float64).reshape(1, 3),
                      port_names=("port",))
        model, x = model.with_rig(rig, x)
        for name in ("port", "offset"):
            if model.has(name):
                x[model.slice(name)] = 0.0
    q = np.asarray(q_rad, dtype=np.float64)
    check_approach(model, approach)
    poses = model.poses(q, approach=approach)
    if temperature_c is not None:
        poses = replace(poses, values={**poses.values, TEMPERATURE: np.broadcast_to(
            np.asarray(temperature_c, dtype=np.float64), (len(q),))})
    position = model.positions(x, poses)
    return Prediction(np.asarray(position, dtype=np.float64), model.kind.name,
                      model.kind.predict(model, x, poses))
