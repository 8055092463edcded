"""Error compensation: the joint angles that make the identified robot go where it should.

Two requests, both solved by the batched inverse kinematics of :mod:`twin.compensation.ik`:

- a **program** (joint angles written against the nominal model): the target is the full
  nominal flange pose ``base_T_flange = FK_nominal(q)``; solve position and orientation on the
  identified model (6 equations; 6 joints, or 7 with the minimum-norm step), seeded from q
  itself. An arm of 4 or 5 joints cannot give its flange an arbitrary pose: its program is
  compensated for the flange **position** alone (3 equations, the remaining freedom taken by the
  minimum-norm step, so the orientation stays next to the program's), and the rotation left
  between the identified flange and the program's nominal one is reported
  (``rotation_error_rad``) rather than solved;
- **Cartesian targets** (flange positions only): first a nominal solution (position-only IK on
  the nominal model from a few joint-space starts, :func:`twin.compensation.ik.nominal_ik`), then
  position-only IK on the identified model seeded from it. With 3 equations and 4 to 9 joints the
  Newton step is the minimum-norm one, so the corrected joints stay next to the nominal ones and the
  flange orientation stays close to the nominal solution's.

The identified robot is its identified table and, when the calibration identified them, its
joint-level errors (:class:`ActualJoints`): commanded q, the joints stand at q + Δq(q) —
transmission error, backlash for the direction the robot comes from, compliance under the load
at the pose — and the flange is the table's at those angles. The IK solves for the command
(:mod:`twin.compensation.ik`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import Array
from twin.compensation.ik import FULL_POSE_JOINTS, IKResult, nominal_ik, solve_ik
from twin.compensation.targets import MIN_DEXTERITY, dexterity
from twin.dataset import approach_directions
from twin.geometry.rigid import rotation_angle
from twin.model import Model
from twin.robot import RobotModel
from twin.unknowns import Stage


class ActualJoints:
    """Where an identified model's joints stand when commanded: its joint-level errors.

    Args:
        model: The identified measurement model (with ``transmission``, ``backlash``,
            ``compliance`` groups, any of them).
        x: Its identified unknowns, shape (p,).
        approach: The direction each joint comes from at each target row, shape (m, n), ±1;
            needed when the model has backlash.
    """

    def __init__(self, model: Model, x: ArrayLike, approach: ArrayLike | None = None) -> None:
        self.model = model
        self.x = np.asarray(x, dtype=np.float64)
        self.approach = None if approach is None else np.asarray(approach)
        if model.needs_approach and self.approach is None:
            raise ValueError("backlash needs the direction the robot comes from at each row")

    def __call__(self, q_rad: Array, rows: NDArray[np.intp]) -> Array:
        """Actual joint angles, shape (k, n), rad, for commands q (k, n) at target rows
        ``rows`` (k,)."""
        approach = None if self.approach is None else self.approach[rows]
        return np.asarray(self.model.joints(self.x, self.model.poses(q_rad, approach=approach)),
                          dtype=np.float64)


def compensate_program(
    nominal: RobotModel, identified: RobotModel, q_program_rad: ArrayLike,
    joints: ActualJoints | None = None,
) -> IKResult:
    """Corrected joint angles that put the identified robot's flange at the nominal pose.

    Args:
        nominal: The model the program was written against, SI.
        identified: The identified (real) robot's table, SI.
        q_program_rad: Programmed joint angles, shape (m, n), rad.
        joints: The identified joint-level errors, if any (:class:`ActualJoints`).

    Returns:
        Angles whose identified flange pose (position and orientation) equals the nominal
        flange pose of the program; for an arm of fewer than :data:`FULL_POSE_JOINTS` joints,
        whose flange position does, with the rotation left reported in
        ``rotation_error_rad``. A row whose only angles within the limits lie a turn or more
        from the program's on a joint is not within limits (``joint_limit``); a row less than
        :data:`~twin.compensation.targets.MIN_DEXTERITY` from a singularity is ``singular``.
    """
    q = np.asarray(q_program_rad, dtype=np.float64)
    base_T_target = nominal.flange_transforms(q)
    target = base_T_target[:, :3, 3]
    if identified.n_joints >= FULL_POSE_JOINTS:
        solved = solve_ik(identified, target, q, base_T_target[:, :3, :3], joints=joints)
    else:
        solved = solve_ik(identified, target, q, joints=joints)
        actual = solved.q_rad if joints is None else joints(solved.q_rad, np.arange(len(q)))
        reached = identified.flange_transforms(actual)[:, :3, :3]
        left = base_T_target[:, :3, :3] @ np.swapaxes(reached, -1, -2)
        solved = solved._replace(rotation_error_rad=rotation_angle(left))
    # A correction that fits the limits only a whole turn away from the programmed angle (a
    # UR joint at 359.4° corrected past its 360° limit, wrapped to 0.2°) would spin the joint a
    # turn on the way: the row is at its joint limit, not corrected.
    same_turn = np.all(np.abs(solved.q_rad - q) <= np.pi, axis=-1)
    return solved._replace(within_limits=solved.within_limits & same_turn,
                           regular=dexterity(nominal, q) >= MIN_DEXTERITY)


def compensate_targets(
    identified: RobotModel, base_p_target: ArrayLike, q_nominal_rad: ArrayLike,
    joints: ActualJoints | None = None,
) -> IKResult:
    """Corrected joint angles that put the identified robot's flange at Cartesian targets.

    Args:
        identified: The identified (real) robot's table, SI.
        base_p_target: Flange position targets, shape (m, 3), m.
        q_nominal_rad: Nominal solutions (e.g. from :func:`nominal_ik`), shape (m, n), rad.
        joints: The identified joint-level errors, if any (:class:`ActualJoints`).

    Returns:
        The solved commands; a row whose nominal solution is less than
        :data:`~twin.compensation.targets.MIN_DEXTERITY` from a singularity of the flange's
        position (:func:`~twin.compensation.targets.dexterity`, position rows) is ``singular``:
        a correction there swings joints far, as at a program's singular rows.
    """
    solved = solve_ik(identified, base_p_target, q_nominal_rad, joints=joints)
    return solved._replace(regular=dexterity(identified, q_nominal_rad, position_only=True)
                           >= MIN_DEXTERITY)


APPROACH_PASSES = 4
"""Most solves of :func:`solve_in_order`; a pass changes sides only where a joint moves less
between two rows than the correction, so the second pass almost always settles it."""


class InOrder(NamedTuple):
    """Rows solved for visiting them in order (:func:`solve_in_order`)."""

    solved: IKResult
    """The corrected commands."""
    approach: NDArray[np.int8] | None
    """The side each joint must come from at each row, shape (m, n), ±1, for which they were
    corrected; None without backlash."""
    approach_moves: NDArray[np.bool_]
    """Rows, shape (m,), where moving straight from the previous row comes from the other side
    for some joint: the robot must make an approach move there (overshoot and come back)."""


def solve_in_order(model: Model, x: ArrayLike,
                   solve: Callable[[RobotModel, ActualJoints | None], IKResult],
                   q_rad: ArrayLike) -> InOrder:
    """Solve rows the robot will visit in order, from home, with the whole identified model.

    Backlash depends on the side each joint comes from, which is that of the corrected commands
    themselves: where a joint moves less between two rows than its correction, correcting may
    change the side. The rows are solved with the directions of ``q_rad`` (the uncorrected
    commands), then again with those of the solution, until they no longer change (at most
    :data:`APPROACH_PASSES` solves). Where a joint must move by less than its backlash no side
    is consistent (coming from either side, the correction sends it the other way): those rows
    are flagged for an approach move, and their commands hold for the side stated.

    Args:
        model: The identified measurement model.
        x: Its unknowns, shape (p,).
        solve: Solves every row on an identified arm (:func:`identified_arm`).
        q_rad: The uncorrected commands, in visiting order, shape (m, n), rad.
    """
    approach = approach_directions(q_rad) if model.needs_approach else None
    for _ in range(APPROACH_PASSES):
        solved = solve(*identified_arm(model, x, approach))
        if approach is None:
            return InOrder(solved, None, np.zeros(len(solved.q_rad), dtype=bool))
        comes_from = approach_directions(solved.q_rad)
        if np.array_equal(comes_from, approach):
            break
        used, approach = approach, comes_from
    else:
        approach = used
    moves = np.any(approach_directions(solved.q_rad) != approach, axis=1)
    return InOrder(solved, approach, moves)


def identified_arm(model: Model, x: ArrayLike, approach: ArrayLike | None
                   ) -> tuple[RobotModel, ActualJoints | None]:
    """The whole identified robot as the IK solves on it: the nominal robot with the identified
    table, and its joint-level errors when the model has any.

    Args:
        model: The identified measurement model.
        x: Its unknowns, shape (p,).
        approach: The direction each joint comes from at each row to solve, shape (m, n), ±1
            (needed with backlash).
    """
    robot = model.robot.perturbed(model.table(x) - model.robot.dh)
    has_joints = any(group.stage == Stage.JOINTS for group in model.groups)
    return robot, ActualJoints(model, x, approach) if has_joints else None




def compensate_program_rows(model: Model, x: ArrayLike, nominal: RobotModel, q_rad: ArrayLike,
                            approach: ArrayLike | None = None) -> InOrder:
    """A program's corrected commands, for the whole identified model (:func:`solve_in_order`).

    Args:
        model: The identified measurement model.
        x: Its unknowns, shape (p,).
        nominal: The robot the program was written against, SI.
        q_rad: The program, in visiting order, shape (m, n), rad.
        approach: The side each joint comes from at each row, shape (m, n), ±1, when the
            program states it (its ``approach1..N`` columns win over the visiting order).
    """
    q = np.asarray(q_rad, dtype=np.float64)
    if approach is None:
        return solve_in_order(model, x, lambda arm, joints: compensate_program(
            nominal, arm, q, joints), q)
    arm, joints = identified_arm(model, x, approach)
    solved = compensate_program(nominal, arm, q, joints)
    return InOrder(solved, np.asarray(approach, dtype=np.int8) if model.needs_approach
                   else None, np.zeros(len(q), dtype=bool))


def compensate_target_rows(model: Model, x: ArrayLike, nominal: RobotModel,
                           base_p_target: ArrayLike, rng: np.random.Generator
                           ) -> tuple[InOrder, Array]:
    """Cartesian targets' corrected commands, for the whole identified model: nominal solutions
    first (:func:`twin.compensation.ik.nominal_ik`), then :func:`solve_in_order` from them.

    Args:
        model: The identified measurement model.
        x: Its unknowns, shape (p,).
        nominal: The nominal robot, SI.
        base_p_target: Flange position targets, in visiting order, shape (m, 3), m.
        rng: Generator of the nominal solutions' random starts.

    Returns:
        ``(ordered, q_nominal_rad)``: the corrected commands, and the nominal solutions (m, n),
        rad.
    """
    target_m = np.asarray(base_p_target, dtype=np.float64)
    q_nominal = nominal_ik(nominal, target_m, rng).q_rad
    return solve_in_order(model, x, lambda arm, joints: compensate_targets(
        arm, target_m, q_nominal, joints), q_nominal), q_nominal


class PoseRows(NamedTuple):
    """Full-pose targets' corrected commands (:func:`compensate_pose_rows`)."""

    ordered: InOrder
    """The corrected commands; a row the nominal model cannot reach (on its configuration)
    keeps the nominal attempt's status."""
    nominal: IKResult
    """The nominal solutions: the joints the nominal model (the controller's) takes for each
    target, on the configuration asked for."""


def compensate_pose_rows(model: Model, x: ArrayLike, nominal: RobotModel, base_T_flange: ArrayLike,
                         rng: np.random.Generator, configuration: ArrayLike | None = None
                         ) -> PoseRows:
    """Flange poses' corrected commands, for the whole identified model.

    First the joints the nominal model takes for each pose (full-pose
    :func:`twin.compensation.ik.nominal_ik`; on the configuration given, else the solution
    nearest home), then the program those joints make is compensated
    (:func:`compensate_program`, in visiting order with :func:`solve_in_order`): the identified
    robot's flange at the corrected joints is the nominal flange at the nominal ones, the pose
    asked for.

    Args:
        model: The identified measurement model.
        x: Its unknowns, shape (p,).
        nominal: The nominal robot, SI (6 joints with a configuration).
        base_T_flange: Flange poses, in visiting order, shape (m, 4, 4), m.
        rng: Generator of the nominal solutions' random starts.
        configuration: ``(cf1, cf4, cf6, cfx)`` per pose, shape (m, 4)
            (:mod:`twin.compensation.configuration`), or None.
    """
    from twin.compensation.configuration import branch_starts, on_branch

    poses = np.asarray(base_T_flange, dtype=np.float64).reshape(-1, 4, 4)
    if configuration is None:
        solved = nominal_ik(nominal, poses[:, :3, 3], rng, base_R_target=poses[:, :3, :3])
    else:
        wanted = np.asarray(configuration, dtype=np.int64).reshape(-1, 4)
        solved = nominal_ik(nominal, poses[:, :3, 3], rng, base_R_target=poses[:, :3, :3],
                            draw=lambda rows: branch_starts(nominal, wanted[rows]),
                            accept=lambda rows: on_branch(nominal, wanted[rows]))
    q_nominal = solved.q_rad
    ordered = solve_in_order(model, x, lambda arm, joints: compensate_program(
        nominal, arm, q_nominal, joints), q_nominal)
    corrected = ordered.solved
    merged = corrected._replace(converged=corrected.converged & solved.converged,
                                within_limits=corrected.within_limits & solved.within_limits)
    return PoseRows(ordered._replace(solved=merged), solved)
