"""Compliance with each link's weight apart: for a robot whose link masses are not known.

Per joint i::

    Δq_i = compliance{i}_cable · τ_i^cable + Σ_{j ≥ i} compliance{i}_link{j} · τ_ij

with τ_ij the torque link j's weight puts on joint i (:func:`twin.geometry.statics.link_torques`,
from the robot file's masses and centres of mass, at the nominal geometry and the recorded pose) and
τ_i^cable the cable's pull's (the rig's ``tension_n``). Each coefficient is the joint's
compliance times how far the link's true weight (and lever) is from the file's: the group
``compliance`` assumes the file's masses right up to a common scale per joint, this one lets
every link be off by its own share. n + n(n+1)/2 unknowns (27 for six joints), in rad/(N·m)
(results show µrad/(N·m)); use it instead of ``compliance``, not beside it.

Why it exists: with the masses 20 % off link by link, the shape of the gravity torque on the
shoulder and elbow over the poses changes (one link heavier than its file, another lighter);
c_i τ_i cannot follow it and leaves a few µrad of deflection in the residual — on soft joints
several times the Cramér–Rao bound of the flange (docs/methods.md). Split by link, it is linear
again.

What the cable cannot see: joint 1's axis is vertical, so no weight loads it (its six link
coefficients are zero columns; its cable coefficient remains); the last joint's are unseen at
the flange centre; and the wrist links' weights act almost at the wrist centre, so on the
shoulder and elbow they trade with the forearm's (weak directions).

Bounds −100 to 10000 µrad/(N·m): ten times compliance's upper bound, for a link up to ten times
heavier than its file says; a little below zero for the weak directions. Radius 10 µrad/(N·m).
A prismatic joint's coefficients are in m/N, on the force along its axis, bounded likewise at ten
times compliance's (−1 to 100 µm/N).
"""

from __future__ import annotations

import numpy as np

from twin.dataset import Measurements
from twin.geometry.statics import joint_torques, link_torques
from twin.rig import Rig
from twin.robot import RobotModel
from twin.unknowns.compliance import (
    LINEAR_LOWER,
    LINEAR_RADIUS,
    LINEAR_UPPER,
    RADIUS,
    cable_forces,
    compliance_units,
    require_inertia,
)
from twin.unknowns.group import Array, Group, Stage, cached

LOWER = -1e-4
"""Lower search bound of a coefficient, rad/(N·m)."""
UPPER = 1e-2
"""Upper search bound of a coefficient, rad/(N·m)."""


def make(robot: RobotModel, rig: Rig) -> Group:
    """Per joint, a compliance for the cable and one for each link's weight.

    Raises:
        InputError: if the robot file gives no masses and centres of mass.
    """
    mass, com = require_inertia(robot)
    n = robot.n_joints
    joint, link = np.triu_indices(n)  # link j turns with joint i when j >= i
    names = tuple(f"compliance{i + 1}_cable" for i in range(n)) + tuple(
        f"compliance{i + 1}_link{j + 1}" for i, j in zip(joint, link, strict=True))

    def basis(data: Measurements) -> Array:
        cable = joint_torques(robot.structure, robot.dh, data.q_rad, np.zeros(n), com,
                              rig.attachment_m, cable_forces(robot, rig, data))
        weights = link_torques(robot.structure, robot.dh, data.q_rad, mass, com)
        return np.concatenate([cable, weights[:, joint, link]], axis=1)

    turned = (*range(n), *joint.tolist())
    sliding = robot.prismatic[list(turned)]
    units = compliance_units(robot)
    return Group(name="link_compliance", stage=Stage.JOINTS, names=names,
                 units=tuple(units[i] for i in turned),
                 lower=np.where(sliding, 10.0 * LINEAR_LOWER, LOWER),
                 upper=np.where(sliding, 10.0 * LINEAR_UPPER, UPPER),
                 radius=np.where(sliding, LINEAR_RADIUS, RADIUS), basis=cached(basis),
                 joint=turned)
