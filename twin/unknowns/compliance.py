"""Compliance: each joint gives way under the static torque it carries.

Per joint i, ``Δq_i = c_i · τ_i`` with τ_i the torque on joint i
(:func:`twin.geometry.statics.joint_torques`) from gravity on the links (masses and centres of mass
of the robot file: keys ``mass`` and ``com``) and from the cable's pull (the rig's ``tension_n``
towards each row's port, at the attachment point). n unknowns ``compliance1``… in rad/(N·m)
(results show µrad/(N·m)); c_i is the inverse of the joint's stiffness.

τ is computed at the nominal geometry and the recorded (undeflected) pose, with the port the
calibration is told: the deflection changes the torque only at second order (method-notes §6),
and so the model stays linear in c. The masses are never exact; a mass error common to the links
that load a joint scales its c_i, so what is identified is the product c_i τ_i — and the share of
a mass error that changes the shape of τ_i over the poses is left as a residual.

Bounds −10 to 1000 µrad/(N·m): an IRB 120 joint is some 1e4–1e6 N·m/rad stiff (1–100
µrad/(N·m)); 1000 µrad/(N·m) would sag a degree under its own weight. A compliance is never
negative; the lower bound sits a little below zero so that a joint that carries almost no torque
(joint 1 sees only the cable's pull; the last joint carries nothing at the flange centre) comes
out as noise around zero instead of resting on the bound. Radius 10 µrad/(N·m).

A prismatic joint gives way along its axis under the force along it (its τ_i is that force, N:
:func:`twin.geometry.statics.joint_torques`): c_i in m/N (results show µm/N), bounds −0.1 to 10
µm/N (a lift or a track is some 1e6–1e8 N/m stiff: 0.01–1 µm/N), radius 0.1 µm/N. A vertical
lift carries the same weight in every pose: that part of c_i τ_i is a constant, which trades with
the joint's δd; the cable's pull, which changes with the pose, is what separates them.
"""

from __future__ import annotations

import numpy as np

from twin.dataset import Measurements
from twin.errors import InputError
from twin.geometry.statics import joint_torques
from twin.rig import PORT_LABELS, Rig
from twin.robot import RobotModel
from twin.units import COMPLIANCE_UNIT, LINEAR_COMPLIANCE_UNIT
from twin.unknowns.group import Array, Group, Stage, cached

LOWER = -1e-5
"""Lower search bound of a compliance, rad/(N·m)."""
UPPER = 1e-3
"""Upper search bound of a compliance, rad/(N·m)."""
RADIUS = 1e-5
"""Typical compliance, rad/(N·m)."""
LINEAR_LOWER, LINEAR_UPPER, LINEAR_RADIUS = -1e-7, 1e-5, 1e-7
"""A prismatic joint's search bounds and typical compliance, m/N."""


def compliance_units(robot: RobotModel) -> tuple[str, ...]:
    """The unit of each joint's compliance: rad/(N·m), or m/N for a prismatic joint."""
    return tuple(LINEAR_COMPLIANCE_UNIT if sliding else COMPLIANCE_UNIT
                 for sliding in robot.prismatic)


def cable_forces(robot: RobotModel, rig: Rig, data: Measurements) -> Array:
    """The cable's pull at every pose, base frame, shape (m, 3), N: ``rig.tension_n`` from the
    attachment point towards the row's port, at the nominal geometry."""
    if rig.tension_n <= 0.0 or not len(rig.ports_m):
        return np.zeros((len(data), 3))
    flange = robot.flange_transforms(data.q_rad)
    at = flange[:, :3, :3] @ rig.attachment_m + flange[:, :3, 3]
    towards = rig.ports_m[data.index(PORT_LABELS)] - at
    return rig.tension_n * towards / np.linalg.norm(towards, axis=-1, keepdims=True)


def torques(robot: RobotModel, rig: Rig, data: Measurements) -> Array:
    """The static torque on every joint at every pose, shape (m, n), N·m (module docstring).

    Raises:
        ValueError: if the robot has no masses and centres of mass.
    """
    if robot.mass_kg is None or robot.com_m is None:
        raise ValueError(f"{robot.name}: compliance needs link masses and centres of mass")
    return joint_torques(robot.structure, robot.dh, data.q_rad, robot.mass_kg, robot.com_m,
                         rig.attachment_m, cable_forces(robot, rig, data))


def require_inertia(robot: RobotModel) -> tuple[Array, Array]:
    """The robot's link masses (n,) and centres of mass (n, 3), which compliance needs.

    Raises:
        InputError: if the robot file gives no masses and centres of mass.
    """
    if robot.mass_kg is None or robot.com_m is None:
        missing = "masses" if robot.mass_kg is None else "centres of mass"
        raise InputError(f"a robot model without {missing} ({robot.name})",
                         "link masses and centres of mass (keys 'mass' and 'com' on every "
                         "joint of the robot file) for the compliance unknowns")
    return robot.mass_kg, robot.com_m


def make(robot: RobotModel, rig: Rig) -> Group:
    """The compliance of every joint of ``robot``.

    Raises:
        InputError: if the robot file gives no masses and centres of mass.
    """
    require_inertia(robot)
    n = robot.n_joints

    def basis(data: Measurements) -> Array:
        return torques(robot, rig, data)

    sliding = robot.prismatic
    return Group(
        name="compliance", stage=Stage.JOINTS,
        names=tuple(f"compliance{i + 1}" for i in range(n)), units=compliance_units(robot),
        lower=np.where(sliding, LINEAR_LOWER, LOWER), upper=np.where(sliding, LINEAR_UPPER, UPPER),
        radius=np.where(sliding, LINEAR_RADIUS, RADIUS), basis=cached(basis),
        joint=tuple(range(n)),
    )
