"""Non-geometric physics a scenario asks of the twin: joint servos of finite stiffness, gravity,
cable tension, and how far the true masses are from the robot file's.

The robot holds each joint with a position servo of stiffness k_j (N·m/rad; N/m on a prismatic
joint): at rest the joint sits where the servo torque (force) balances gravity and the cable's
pull (the twin solves it, :mod:`twin.sim.equilibrium`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from twin.arrays import Array
from twin.robot import RobotModel


@dataclass(frozen=True)
class Physics:
    """Which non-geometric effects the twin simulates.

    Attributes:
        stiffness_nm_per_rad: Servo stiffness per joint, shape (n,), N·m/rad (N/m on a
            prismatic joint); None means rigid joints (the joint value is exactly the commanded
            one, no statics are solved).
        gravity: Whether gravity (9.81 m/s², −z of the base) loads the joints.
        tension_n: Constant cable tension pulling the flange towards the port, N.
        mass_error: Relative error of the robot file's link masses and centres of mass: the
            true robot's are drawn per seed (:func:`true_inertia`), so that a calibration meets
            the mismatch a real one meets; 0 for the file's exactly.
    """

    stiffness_nm_per_rad: Array | None = field(default=None)
    gravity: bool = False
    tension_n: float = 0.0
    mass_error: float = 0.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.mass_error) and 0.0 <= self.mass_error < 1.0):
            raise ValueError("mass_error: expected a share in [0, 1)")
        if self.stiffness_nm_per_rad is None:
            if self.gravity or self.tension_n or self.mass_error:
                raise ValueError("gravity, tension and mass errors need joint stiffness "
                                 "(compliant joints)")
            return
        stiffness = np.array(self.stiffness_nm_per_rad, dtype=np.float64)
        if stiffness.ndim != 1 or not np.all(np.isfinite(stiffness)) or np.any(stiffness <= 0):
            raise ValueError("stiffness_nm_per_rad: expected positive finite values, shape (n,)")
        if not (np.isfinite(self.tension_n) and self.tension_n >= 0):
            raise ValueError("tension_n: expected a finite value >= 0")
        stiffness.setflags(write=False)
        object.__setattr__(self, "stiffness_nm_per_rad", stiffness)

    @property
    def rigid(self) -> bool:
        """True when the joints are rigid and no statics are solved."""
        return self.stiffness_nm_per_rad is None

    def to_dict(self) -> dict[str, object]:
        """The JSON form written to truth.json (N·m/rad, N)."""
        stiffness = self.stiffness_nm_per_rad
        return {
            "compliance": not self.rigid,
            "stiffness_nm_per_rad": None if stiffness is None else stiffness.tolist(),
            "gravity": self.gravity,
            "tension_n": self.tension_n,
            "mass_error": self.mass_error,
        }

    def compliance(self, n: int) -> Array:
        """The joints' compliance 1/k, shape (n,), rad/(N·m) (m/N on a prismatic joint): what
        the ``compliance`` unknowns of a calibration identify (zeros for rigid joints)."""
        stiffness = self.stiffness_nm_per_rad
        return np.zeros(n) if stiffness is None else 1.0 / stiffness


def true_inertia(robot: RobotModel, mass_error: float, rng: np.random.Generator) -> RobotModel:
    """The robot with the masses and centres of mass the twin really has.

    Each link's mass and each coordinate of its centre of mass (when the file gives them) is
    scaled by an independent factor 1 + U(−e, e), e = ``mass_error``: a coordinate the file puts
    on a link's axis of symmetry (0) stays there.

    Args:
        robot: The robot as its file describes it.
        mass_error: e, in [0, 1).
        rng: The scenario's generator (draws 4n numbers when the file gives centres of mass,
            else n; none when e is 0 or the file gives no masses).
    """
    if mass_error <= 0.0 or robot.mass_kg is None:
        return robot
    n = robot.n_joints
    mass = robot.mass_kg * (1.0 + rng.uniform(-mass_error, mass_error, n))
    com = None if robot.com_m is None \
        else robot.com_m * (1.0 + rng.uniform(-mass_error, mass_error, (n, 3)))
    return replace(robot, mass_kg=mass, com_m=com)


RIGID = Physics()
"""Rigid joints, no loads: the twin is pure kinematics."""
