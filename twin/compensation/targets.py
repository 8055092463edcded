"""Random reachable targets: flange positions an arm reaches with joints well inside its limits and
away from its singularities, to measure a compensation on.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from twin.arrays import Array
from twin.compensation.ik import FULL_POSE_JOINTS
from twin.geometry.kinematics import flange_jacobian
from twin.robot import RobotModel

DEXTERITY_LENGTH_M = 0.3
"""Length that weighs the rotation rows of the Jacobian in :func:`dexterity`, m: links of some
tenths of a metre, as on the arms of about a metre's reach twin calibrates."""
MIN_DEXTERITY = 0.02
"""σ_min below which :func:`reachable_targets` rejects a posture, m/rad: for links of some tenths
of a metre, an elbow some 10° from stretched, a wrist some 6° from aligned."""


def dexterity(robot: RobotModel, q_rad: ArrayLike, length_m: float = DEXTERITY_LENGTH_M, *,
              position_only: bool = False) -> Array:
    """Smallest singular value of the joint Jacobian, rotation rows scaled by ``length_m``.

    Zero at a singularity (stretched or folded elbow, aligned wrist axes); ``length_m`` weighs
    the angular rows against the linear ones (:data:`DEXTERITY_LENGTH_M` by default). Where only
    the flange's position is asked for — Cartesian position targets, or any target of an arm of
    fewer than :data:`~twin.compensation.ik.FULL_POSE_JOINTS` joints
    (:mod:`twin.compensation.joints`) — it is that of the position rows alone: what a position
    correction needs (a SCARA's stretched elbow loses a direction of the flange's position, an
    aligned wrist none).

    Args:
        robot: The robot, SI.
        q_rad: Joint angles, shape (m, n), rad.
        length_m: Weight of the rotation rows, m.
        position_only: Take the position rows alone.

    Returns:
        σ_min, shape (m,), m/rad.
    """
    _, jacobian = flange_jacobian(robot.structure, robot.dh, np.asarray(q_rad, dtype=np.float64))
    if position_only or robot.n_joints < FULL_POSE_JOINTS:
        jacobian = jacobian[:, :3]
    else:
        jacobian[:, 3:] *= length_m
    return np.asarray(np.linalg.svd(jacobian, compute_uv=False)[:, -1])


MARGIN_M = 0.01
"""How far inside its limits a prismatic joint's travel stays for a reachable target, m."""


def reachable_targets(
    robot: RobotModel, n_targets: int, rng: np.random.Generator,
    margin_rad: float = np.deg2rad(5.0), min_dexterity: float = MIN_DEXTERITY,
) -> tuple[Array, Array]:
    """Random reachable targets: the nominal flange at random joint angles.

    Angles stay ``margin_rad`` inside every limit (a prismatic joint's travel :data:`MARGIN_M`)
    and at least ``min_dexterity`` from a singularity (see :func:`dexterity`), so a robot a few
    millimetres off the nominal one reaches them with joints a few mrad away, still inside the
    limits.

    Returns:
        ``(q_rad, base_p_target)``: shapes (n_targets, n) in rad and (n_targets, 3) in m.
    """
    margin = np.where(robot.prismatic, MARGIN_M, margin_rad)
    low, high = robot.lower_rad + margin, robot.upper_rad - margin
    kept: list[Array] = []
    while sum(len(k) for k in kept) < n_targets:
        q = rng.uniform(low, high, (2 * n_targets, robot.n_joints))
        kept.append(q[dexterity(robot, q) >= min_dexterity])
    q = np.concatenate(kept)[:n_targets]
    return q, robot.flange_positions(q)


