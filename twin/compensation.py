"""Error compensation: the joint angles that make the identified robot go where it should.

Two requests, both solved by one batched damped-least-squares Newton iteration on all rows at
once (no loop over rows):

- a **program** (joint angles written against the nominal model): the target is the full
  nominal flange pose ``base_T_flange = FK_nominal(q)``; solve position and orientation on the
  identified model (6 equations; 6 joints, or 7 with the minimum-norm step), seeded from q
  itself. An arm of 4 or 5 joints cannot give its flange an arbitrary pose: its program is
  compensated for the flange **position** alone (3 equations, the remaining freedom taken by the
  minimum-norm step, so the orientation stays next to the program's), and the rotation left
  between the identified flange and the program's nominal one is reported
  (``rotation_error_rad``) rather than solved;
- **Cartesian targets** (flange positions only): first a nominal solution (position-only IK on
  the nominal model from a few joint-space starts, see :func:`nominal_ik`), then position-only
  IK on the identified model seeded from it. With 3 equations and 4 to 7 joints the Newton step
  is the minimum-norm one, so the corrected joints stay next to the nominal ones and the flange
  orientation stays close to the nominal solution's.

Each step is ``Δq = Jᵀ (J Jᵀ + λ I)⁻¹ e`` with e the position error (m) and, for full poses, the
rotation error ``log(R_target Rᵀ)`` (rad, base frame); λ is adapted per row (Levenberg–
Marquardt: a step is taken only if it lowers ‖e‖).

The identified robot is its identified table and, when the calibration identified them, its
joint-level errors (:class:`ActualJoints`): commanded q, the joints stand at q + Δq(q) —
transmission error, backlash for the direction the robot comes from, compliance under the load
at the pose — and the flange is the table's at those angles. The IK solves for the command; its
Jacobian is the table's at the actual angles, leaving out ∂Δq/∂q (some 1e-3 of the identity):
each step then shrinks the error by about that factor instead of quadratically — a step or two
more, the same solution.

Solutions are never clipped: a row that does not converge is *unreachable*, a converged row
whose angles (after choosing among the equivalent angles q + 2πk the one closest to the seed)
leave the joint limits is reported as a *joint-limit* violation.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from twin.arrays import Array
from twin.dataset import approach_directions
from twin.kinematics import flange_jacobian
from twin.metrics import Metrics, metrics
from twin.model import Model
from twin.robot import RobotModel
from twin.unknowns import Stage

_T = TypeVar("_T", bound=np.generic)

TOLERANCE_M = 1e-10
"""Position error below which a row has converged, m."""
TOLERANCE_RAD = 1e-10
"""Rotation error below which a full-pose row has converged, rad."""
MAX_ITERATIONS = 100
INITIAL_DAMPING = 1e-6
"""Initial λ of the damped step, in units of J Jᵀ (m²/rad²); J ~ 0.3 m/rad for the IRB 120."""
MIN_DAMPING = 1e-12
"""Floor of λ: keeps J Jᵀ + λ I invertible at a singular pose."""
MAX_DAMPING = 1e8
"""A row whose λ grows past this is stuck at a local minimum of ‖e‖: unreachable."""

STATUS_OK = "ok"
STATUS_UNREACHABLE = "unreachable"
STATUS_JOINT_LIMIT = "joint_limit"

NOMINAL_STARTS = (16, 256)
"""Joint-space starts per target in each round of :func:`nominal_ik`."""
HOME_WRIST_RAD = np.deg2rad(30.0)
"""The second-to-last joint's angle in the reference posture (:func:`home_pose`)."""
FULL_POSE_JOINTS = 6
"""Joints an arm needs to take any flange pose: fewer, and a program is compensated for the
flange position alone."""


DEXTERITY_LENGTH_M = 0.3
"""Length that weighs the rotation rows of the Jacobian in :func:`dexterity`, m."""
MIN_DEXTERITY = 0.02
"""σ_min below which :func:`reachable_targets` rejects a posture (≈ 10° from the IRB 120's
stretched elbow, 6° from its aligned wrist), m/rad."""


class IKResult(NamedTuple):
    """Joint angles solved for a batch of targets.

    Attributes:
        q_rad: Solved joint angles, shape (m, n), rad; not clipped.
        position_error_m: Remaining flange position error, shape (m,), m.
        rotation_error_rad: Remaining flange rotation error, shape (m,), rad; zeros when only
            positions were asked for.
        converged: Whether the error is within tolerance, shape (m,).
        within_limits: Whether q_rad is within the joint limits, shape (m,).
        iterations: Newton iterations run (the batch stops when every row is done).
    """

    q_rad: Array
    position_error_m: Array
    rotation_error_rad: Array
    converged: NDArray[np.bool_]
    within_limits: NDArray[np.bool_]
    iterations: int

    @property
    def status(self) -> NDArray[np.str_]:
        """Per row ``ok``, ``unreachable`` or ``joint_limit``, shape (m,)."""
        return np.where(
            ~self.converged, STATUS_UNREACHABLE,
            np.where(self.within_limits, STATUS_OK, STATUS_JOINT_LIMIT),
        )

    @property
    def ok(self) -> NDArray[np.bool_]:
        """Converged and within limits, shape (m,)."""
        return self.converged & self.within_limits


def home_pose(robot: RobotModel) -> Array:
    """Reference posture of :func:`nominal_ik`, shape (n,), rad: every joint at 0 but the
    second-to-last at 30° (off the aligned-wrist singularity of a 6-axis arm: q5 of the IRB
    120), each brought within its limits."""
    home = np.zeros(robot.n_joints)
    home[-2] = HOME_WRIST_RAD
    return np.asarray(np.clip(home, robot.lower_rad, robot.upper_rad), dtype=np.float64)


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


def _errors(
    robot: RobotModel, q_rad: Array, base_p_target: Array, base_R_target: Array | None,
    actual: Array | None = None,
) -> tuple[Array, Array]:
    """Stacked error e (m, k) and Jacobian J (m, k, n), k = 3 or 6, with the joints at the
    commands or, if given, at ``actual`` (m, n)."""
    base_T_flange, jacobian = flange_jacobian(robot.structure, robot.dh,
                                              q_rad if actual is None else actual)
    error = base_p_target - base_T_flange[:, :3, 3]
    if base_R_target is None:
        return error, jacobian[:, :3, :]
    rotation = Rotation.from_matrix(
        base_R_target @ np.swapaxes(base_T_flange[:, :3, :3], -1, -2)
    ).as_rotvec()
    return np.concatenate([error, rotation], axis=-1), jacobian


def _into_limits(robot: RobotModel, q_rad: Array, q_seed: Array) -> tuple[Array, NDArray[np.bool_]]:
    """Per joint, the angle q + 2πk inside the limits closest to the seed (if any)."""
    turns = np.arange(-2, 3)
    candidates = q_rad[..., None] + 2 * np.pi * turns  # (m, n, 5)
    inside = (candidates >= robot.lower_rad[:, None]) & (candidates <= robot.upper_rad[:, None])
    distance = np.abs(candidates - q_seed[..., None]) + np.where(inside, 0.0, 1e3)
    best = np.take_along_axis(candidates, np.argmin(distance, axis=-1)[..., None], -1)[..., 0]
    return best, np.all(np.any(inside, axis=-1), axis=-1)


def solve_ik(
    robot: RobotModel,
    base_p_target: ArrayLike,
    q_seed: ArrayLike,
    base_R_target: ArrayLike | None = None,
    *,
    tolerance_m: float = TOLERANCE_M,
    tolerance_rad: float = TOLERANCE_RAD,
    max_iterations: int = MAX_ITERATIONS,
    joints: ActualJoints | None = None,
) -> IKResult:
    """Joint angles to command so that the robot's flange reaches the targets, all rows at once.

    Args:
        robot: The robot to solve on (nominal or identified table), SI.
        base_p_target: Flange position targets, shape (m, 3), m, base frame.
        q_seed: Starting joint angles, shape (m, n), rad.
        base_R_target: Flange orientation targets, shape (m, 3, 3), or None for position only.
        tolerance_m: Position convergence tolerance, m.
        tolerance_rad: Rotation convergence tolerance, rad.
        max_iterations: Newton iterations at most.
        joints: Where the joints stand for a command (the identified joint-level errors), or
            None: exactly at it.

    Returns:
        The solved commands and per-row convergence and limit flags.
    """
    p_target = np.asarray(base_p_target, dtype=np.float64)
    q = np.array(q_seed, dtype=np.float64)
    R_target = None if base_R_target is None else np.asarray(base_R_target, dtype=np.float64)
    if p_target.ndim != 2 or p_target.shape[1] != 3:
        raise ValueError(f"base_p_target: shape {p_target.shape}, expected (m, 3)")
    if q.shape != (len(p_target), robot.n_joints):
        raise ValueError(f"q_seed: shape {q.shape}, expected ({len(p_target)}, {robot.n_joints})")
    if R_target is not None and R_target.shape != (len(p_target), 3, 3):
        raise ValueError(f"base_R_target: shape {R_target.shape}, expected ({len(p_target)}, 3, 3)")

    def norms(error: Array) -> tuple[Array, Array]:
        rotation = np.linalg.norm(error[:, 3:], axis=-1) if R_target is not None else np.zeros(
            len(error))
        return np.linalg.norm(error[:, :3], axis=-1), rotation

    def evaluate(q_rows: Array, rows: NDArray[np.intp]) -> tuple[Array, Array]:
        actual = None if joints is None else joints(q_rows, rows)
        return _errors(robot, q_rows, p_target[rows],
                       None if R_target is None else R_target[rows], actual)

    error, jacobian = evaluate(q, np.arange(len(q)))
    damping = np.full(len(q), INITIAL_DAMPING)
    identity = np.eye(error.shape[1])
    iterations = 0
    while iterations < max_iterations:
        position_m, rotation_rad = norms(error)
        active = ((position_m > tolerance_m) | (rotation_rad > tolerance_rad)) & (
            damping < MAX_DAMPING
        )
        if not np.any(active):
            break
        iterations += 1
        J, e = jacobian[active], error[active]
        JJt = J @ np.swapaxes(J, -1, -2) + damping[active, None, None] * identity
        step = (np.swapaxes(J, -1, -2) @ np.linalg.solve(JJt, e[..., None]))[..., 0]
        q_try = q[active] + step
        rows = np.flatnonzero(active)
        error_try, jacobian_try = evaluate(q_try, rows)
        better = np.linalg.norm(error_try, axis=-1) < np.linalg.norm(e, axis=-1)
        taken = rows[better]
        q[taken], error[taken], jacobian[taken] = (
            q_try[better], error_try[better], jacobian_try[better],
        )
        damping[taken] = np.maximum(damping[taken] / 3.0, MIN_DAMPING)
        damping[rows[~better]] *= 10.0
    position_m, rotation_rad = norms(error)
    converged = (position_m <= tolerance_m) & (rotation_rad <= tolerance_rad)
    q, within = _into_limits(robot, q, np.asarray(q_seed, dtype=np.float64))
    return IKResult(q, position_m, rotation_rad, converged, within, iterations)


def _best_of_starts(
    robot: RobotModel, base_p_target: Array, rng: np.random.Generator, n_starts: int
) -> IKResult:
    """Position-only IK from the home posture and n_starts − 1 random ones; per target the ok
    solution closest to home (the home-start result when none is ok)."""
    m = len(base_p_target)
    home = home_pose(robot)
    starts = rng.uniform(robot.lower_rad, robot.upper_rad, (n_starts, m, robot.n_joints))
    starts[0] = home
    solved = solve_ik(robot, np.tile(base_p_target, (n_starts, 1)),
                      starts.reshape(-1, robot.n_joints))
    ok = solved.ok.reshape(n_starts, m)
    distance = np.linalg.norm(solved.q_rad.reshape(n_starts, m, -1) - home, axis=-1)
    pick = np.argmin(np.where(ok, distance, np.inf), axis=0)
    rows = pick * m + np.arange(m)
    return IKResult(
        solved.q_rad[rows], solved.position_error_m[rows], solved.rotation_error_rad[rows],
        solved.converged[rows], solved.within_limits[rows], solved.iterations,
    )


def _replace_rows(values: NDArray[_T], rows: NDArray[np.intp], new: NDArray[_T]) -> NDArray[_T]:
    merged = np.array(values)
    merged[rows] = new
    return merged


def nominal_ik(
    robot: RobotModel, base_p_target: ArrayLike, rng: np.random.Generator,
    starts: tuple[int, ...] = NOMINAL_STARTS,
) -> IKResult:
    """Position-only IK on the nominal model, for targets that come without joint angles.

    Orientation is free, so there is no closed form; the batched solver runs from the home
    posture and random postures within the limits, and keeps per target the converged in-limit
    solution closest to home. Targets left without one (a folded arm near a limit, say) get a
    second, larger round of starts, and so on through ``starts``.

    Args:
        robot: Nominal robot, SI.
        base_p_target: Flange position targets, shape (m, 3), m.
        rng: Generator of the random starts.
        starts: Starts per target in each round.

    Returns:
        One solution per target; a target no round solves keeps its home-start result, flagged.
    """
    p_target = np.asarray(base_p_target, dtype=np.float64)
    result = _best_of_starts(robot, p_target, rng, starts[0])
    for n_starts in starts[1:]:
        failed = np.flatnonzero(~result.ok)
        if failed.size == 0:
            break
        retry = _best_of_starts(robot, p_target[failed], rng, n_starts)
        result = IKResult(
            _replace_rows(result.q_rad, failed, retry.q_rad),
            _replace_rows(result.position_error_m, failed, retry.position_error_m),
            _replace_rows(result.rotation_error_rad, failed, retry.rotation_error_rad),
            _replace_rows(result.converged, failed, retry.converged),
            _replace_rows(result.within_limits, failed, retry.within_limits),
            max(result.iterations, retry.iterations),
        )
    return result


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
        ``rotation_error_rad``.
    """
    q = np.asarray(q_program_rad, dtype=np.float64)
    base_T_target = nominal.flange_transforms(q)
    target = base_T_target[:, :3, 3]
    if identified.n_joints >= FULL_POSE_JOINTS:
        return solve_ik(identified, target, q, base_T_target[:, :3, :3], joints=joints)
    solved = solve_ik(identified, target, q, joints=joints)
    actual = solved.q_rad if joints is None else joints(solved.q_rad, np.arange(len(q)))
    reached = identified.flange_transforms(actual)[:, :3, :3]
    left = Rotation.from_matrix(base_T_target[:, :3, :3] @ np.swapaxes(reached, -1, -2))
    return solved._replace(rotation_error_rad=np.asarray(left.magnitude(), dtype=np.float64))


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
    """
    return solve_ik(identified, base_p_target, q_nominal_rad, joints=joints)


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


class CompensationCheck(NamedTuple):
    """True flange errors over targets, commanded through the nominal or the identified model.

    Attributes:
        nominal_error_m: Distance from the target with the nominal solutions, shape (k,), m.
        compensated_error_m: Distance with the compensated solutions, shape (k,), m.
        n_failed: Targets whose compensated solution was not ok (left out of both arrays).
    """

    nominal_error_m: Array
    compensated_error_m: Array
    n_failed: int

    @property
    def nominal(self) -> Metrics:
        """Metrics of :attr:`nominal_error_m` (mae is the mean distance), m."""
        return metrics(self.nominal_error_m)

    @property
    def compensated(self) -> Metrics:
        """Metrics of :attr:`compensated_error_m`, m."""
        return metrics(self.compensated_error_m)

    @property
    def n_targets(self) -> int:
        """Targets drawn."""
        return len(self.nominal_error_m) + self.n_failed


def dexterity(robot: RobotModel, q_rad: ArrayLike) -> Array:
    """Smallest singular value of the joint Jacobian, rotation rows scaled by 0.3 m.

    Zero at a singularity (stretched or folded elbow, aligned wrist axes); 0.3 m is the IRB 120's
    scale, so linear and angular rows weigh alike. An arm of fewer than
    :data:`FULL_POSE_JOINTS` joints is only ever asked for positions (see the module
    docstring): its dexterity is that of the position rows alone (a SCARA's stretched elbow
    loses a direction of the flange's position, not of its 6D motion).

    Args:
        robot: The robot, SI.
        q_rad: Joint angles, shape (m, n), rad.

    Returns:
        σ_min, shape (m,), m/rad.
    """
    _, jacobian = flange_jacobian(robot.structure, robot.dh, np.asarray(q_rad, dtype=np.float64))
    if robot.n_joints < FULL_POSE_JOINTS:
        jacobian = jacobian[:, :3]
    else:
        jacobian[:, 3:] *= DEXTERITY_LENGTH_M
    return np.asarray(np.linalg.svd(jacobian, compute_uv=False)[:, -1])


def reachable_targets(
    robot: RobotModel, n_targets: int, rng: np.random.Generator,
    margin_rad: float = np.deg2rad(5.0), min_dexterity: float = MIN_DEXTERITY,
) -> tuple[Array, Array]:
    """Random reachable targets: the nominal flange at random joint angles.

    Angles stay ``margin_rad`` inside every limit and at least ``min_dexterity`` from a
    singularity (see :func:`dexterity`), so a robot a few millimetres off the nominal one reaches
    them with joints a few mrad away, still inside the limits.

    Returns:
        ``(q_rad, base_p_target)``: shapes (n_targets, n) in rad and (n_targets, 3) in m.
    """
    low, high = robot.lower_rad + margin_rad, robot.upper_rad - margin_rad
    kept: list[Array] = []
    while sum(len(k) for k in kept) < n_targets:
        q = rng.uniform(low, high, (2 * n_targets, robot.n_joints))
        kept.append(q[dexterity(robot, q) >= min_dexterity])
    q = np.concatenate(kept)[:n_targets]
    return q, robot.flange_positions(q)


def check_compensation(
    base_p_target: ArrayLike,
    true_at_nominal_m: ArrayLike,
    true_at_compensated_m: ArrayLike,
    compensated: IKResult,
) -> CompensationCheck:
    """Summarise the true flange errors without and with compensation.

    Args:
        base_p_target: Targets, shape (m, 3), m.
        true_at_nominal_m: True flange at the nominal solutions, shape (m, 3), m.
        true_at_compensated_m: True flange at the compensated solutions, shape (m, 3), m.
        compensated: The compensated IK result; rows that are not ok are left out of both.
    """
    ok = compensated.ok
    target = np.asarray(base_p_target)[ok]
    before = np.linalg.norm(np.asarray(true_at_nominal_m)[ok] - target, axis=-1)
    after = np.linalg.norm(np.asarray(true_at_compensated_m)[ok] - target, axis=-1)
    return CompensationCheck(before, after, int(np.sum(~ok)))
