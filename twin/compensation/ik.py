"""Inverse kinematics of a serial arm: joint angles that put the flange at targets.

One batched damped-least-squares Newton iteration solves all rows at once (no loop over rows):
each step is ``Δq = Jᵀ (J Jᵀ + λ I)⁻¹ e`` with e the position error (m) and, for full poses, the
rotation error ``log(R_target Rᵀ)`` (rad, base frame); λ is adapted per row (Levenberg–
Marquardt: a step is taken only if it lowers ‖e‖). With 3 equations and 4 to 9 joints (flange
positions only) the step is the minimum-norm one, so the solution stays next to its seed.

Targets that come without joint angles are solved on the nominal model from a few joint-space
starts (:func:`nominal_ik`). The robot may stand elsewhere than it is commanded (joint-level
errors): ``joints`` maps commands to the actual angles, and the Jacobian is the table's at those
angles, leaving out ∂Δq/∂q (some 1e-3 of the identity): each step then shrinks the error by
about that factor instead of quadratically — a step or two more, the same solution.

Solutions are never clipped: a row that does not converge is *unreachable*, a converged row
whose angles (after choosing among the equivalent angles q + 2πk the one closest to the seed;
a prismatic joint's travel has no such twin) leave the joint limits is reported as a
*joint-limit* violation. A prismatic joint's column of J is in m/m beside the others' m/rad:
the minimum-norm step weighs a metre of travel like a radian of turn (a turn at a lever of 1 m).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import Array
from twin.geometry.kinematics import compiled_position_ik, flange_jacobian, trace_point
from twin.geometry.rigid import log_rotation
from twin.robot import RobotModel

_T = TypeVar("_T", bound=np.generic)

ActualAngles = Callable[[Array, NDArray[np.intp]], Array]
"""Where the joints stand for commands q (k, n) at target rows (k,): actual angles (k, n), rad
(:class:`twin.compensation.joints.ActualJoints`)."""

TOLERANCE_M = 1e-10
"""Position error below which a row has converged, m."""
TOLERANCE_RAD = 1e-10
"""Rotation error below which a full-pose row has converged, rad."""
IK_ITERATIONS = 100
INITIAL_DAMPING = 1e-6
"""Initial λ of the damped step, in units of J Jᵀ (m²/rad²): small beside J Jᵀ for an arm whose
links are tenths of a metre (J of that order, m/rad); it adapts per row from there."""
MIN_DAMPING = 1e-12
"""Floor of λ: keeps J Jᵀ + λ I invertible at a singular pose."""
MAX_DAMPING = 1e8
"""A row whose λ grows past this is stuck at a local minimum of ‖e‖: unreachable."""

STATUS_OK = "ok"
STATUS_UNREACHABLE = "unreachable"
STATUS_JOINT_LIMIT = "joint_limit"
STATUS_SINGULAR = "singular"

NOMINAL_STARTS = (16, 256)
"""Joint-space starts per target in each round of :func:`nominal_ik`."""
HOME_WRIST_RAD = np.deg2rad(30.0)
"""The second-to-last joint's angle in the reference posture (:func:`home_pose`): off the
singularity where the last two axes of a wrist align."""
FULL_POSE_JOINTS = 6
"""Joints an arm needs to take any flange pose: fewer, and a program is compensated for the
flange position alone."""


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
        regular: Whether the row is away from a singularity, shape (m,); None: not checked.
            At a singularity a small correction swings joints far (a wrist some degrees from
            aligned turns q4 and q6 by tens of degrees against each other).
    """

    q_rad: Array
    position_error_m: Array
    rotation_error_rad: Array
    converged: NDArray[np.bool_]
    within_limits: NDArray[np.bool_]
    iterations: int
    regular: NDArray[np.bool_] | None = None

    @property
    def status(self) -> NDArray[np.str_]:
        """Per row ``ok``, ``unreachable``, ``joint_limit`` or ``singular``, shape (m,)."""
        regular = np.ones_like(self.converged) if self.regular is None else self.regular
        return np.where(
            ~self.converged, STATUS_UNREACHABLE,
            np.where(~self.within_limits, STATUS_JOINT_LIMIT,
                     np.where(regular, STATUS_OK, STATUS_SINGULAR)),
        )

    @property
    def ok(self) -> NDArray[np.bool_]:
        """Converged, within limits and away from a singularity, shape (m,)."""
        ok = self.converged & self.within_limits
        return ok if self.regular is None else ok & self.regular


def home_pose(robot: RobotModel) -> Array:
    """Reference posture of :func:`nominal_ik`, shape (n,), rad: every joint at 0 but the
    second-to-last at :data:`HOME_WRIST_RAD` (off the aligned-wrist singularity of a 6-axis arm),
    each brought within its limits."""
    home = np.zeros(robot.n_joints)
    home[-2] = HOME_WRIST_RAD
    return np.asarray(np.clip(home, robot.lower_rad, robot.upper_rad), dtype=np.float64)


def _errors(
    robot: RobotModel, q_rad: Array, base_p_target: Array, base_R_target: Array | None,
    actual: Array | None = None,
) -> tuple[Array, Array]:
    """Stacked error e (m, k) and Jacobian J (m, k, n), k = 3 or 6, with the joints at the
    commands or, if given, at ``actual`` (m, n)."""
    q = q_rad if actual is None else actual
    if base_R_target is None:
        # Positions alone need the flange centre's rows only: the point trace the calibration
        # runs on gives them for a fifth of the whole pose's walk on the compiled kernel of a
        # study's workers (67 against 380 µs at 160 rows) — most of a plane or fixed-point
        # scenario's capture was this walk; on the numpy path 0.28 against 0.35 ms at 8 rows,
        # 0.42 against 0.37 ms at 160 and 0.49 against 1.9 ms at 1000.
        trace = trace_point(robot.structure, robot.dh, q)
        return base_p_target - trace.position, trace.jacobian().joints
    base_T_flange, jacobian = flange_jacobian(robot.structure, robot.dh, q)
    error = base_p_target - base_T_flange[:, :3, 3]
    rotation = log_rotation(base_R_target @ np.swapaxes(base_T_flange[:, :3, :3], -1, -2))
    return np.concatenate([error, rotation], axis=-1), jacobian


def _into_limits(robot: RobotModel, q_rad: Array, q_seed: Array) -> tuple[Array, NDArray[np.bool_]]:
    """Per joint, the angle q + 2πk inside the limits closest to the seed (if any); a
    prismatic joint's travel as it is."""
    turns = np.arange(-2, 3) * np.where(robot.prismatic, 0.0, 1.0)[:, None]  # (n, 5)
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
    max_iterations: int = IK_ITERATIONS,
    joints: ActualAngles | None = None,
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
        joints: Where the joints stand for a command (the identified joint-level errors,
            :class:`twin.compensation.joints.ActualJoints`), or None: exactly at it.

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

    # Positions alone on the compiled kernel, where this process takes it: the rows' Newton
    # steps without numpy's overhead at each (most of a touch capture's time).
    found = compiled_position_ik(robot.structure, robot.dh, p_target, q, tolerance_m,
                                 max_iterations, (INITIAL_DAMPING, MIN_DAMPING, MAX_DAMPING)) \
        if R_target is None and joints is None else None
    q, error, iterations = found if found is not None else _newton(
        robot, p_target, q, R_target, (tolerance_m, tolerance_rad), max_iterations, joints)
    position_m, rotation_rad = _norms(error)
    converged = (position_m <= tolerance_m) & (rotation_rad <= tolerance_rad)
    q, within = _into_limits(robot, q, np.asarray(q_seed, dtype=np.float64))
    return IKResult(q, position_m, rotation_rad, converged, within, iterations)


def _norms(error: Array) -> tuple[Array, Array]:
    """Each row's position and (for 6-D rows) rotation error, shapes (m,), m and rad."""
    rotation = np.linalg.norm(error[:, 3:], axis=-1) if error.shape[1] > 3 else np.zeros(
        len(error))
    return np.linalg.norm(error[:, :3], axis=-1), rotation


def _newton(robot: RobotModel, p_target: Array, q: Array, R_target: Array | None,
            tolerances: tuple[float, float], max_iterations: int, joints: ActualAngles | None
            ) -> tuple[Array, Array, int]:
    """:func:`solve_ik`'s damped Newton steps in numpy, the rows in lockstep: the commands
    (m, n) (q, changed in place), the errors (m, 3 or 6) and the iterations run."""

    def evaluate(q_rows: Array, rows: NDArray[np.intp]) -> tuple[Array, Array]:
        actual = None if joints is None else joints(q_rows, rows)
        return _errors(robot, q_rows, p_target[rows],
                       None if R_target is None else R_target[rows], actual)

    error, jacobian = evaluate(q, np.arange(len(q)))
    damping = np.full(len(q), INITIAL_DAMPING)
    identity = np.eye(error.shape[1])
    iterations = 0
    while iterations < max_iterations:
        position_m, rotation_rad = _norms(error)
        active = ((position_m > tolerances[0]) | (rotation_rad > tolerances[1])) & (
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
    return q, error, iterations


Accept = Callable[[Array, NDArray[np.intp]], NDArray[np.bool_]]
"""Whether solutions q (k, n) of target rows (k,) are acceptable (on the configuration asked
for, :func:`twin.compensation.configuration.on_branch`), shape (k,)."""
Starts = Callable[[np.random.Generator, int], Array]
"""Draws k starting joint angles per target, shape (k, m, n), rad."""


def _best_of_starts(
    robot: RobotModel, base_p_target: Array, rng: np.random.Generator, n_starts: int,
    base_R_target: Array | None = None, draw: Starts | None = None, accept: Accept | None = None,
) -> IKResult:
    """IK from the home posture and n_starts − 1 random ones (within the limits, or ``draw``'s);
    per target the ok (and accepted) solution closest to home (the first start's result when
    none is)."""
    m = len(base_p_target)
    home = home_pose(robot)
    starts = rng.uniform(robot.lower_rad, robot.upper_rad, (n_starts, m, robot.n_joints)) \
        if draw is None else draw(rng, n_starts)
    if draw is None:
        starts[0] = home
    solved = solve_ik(robot, np.tile(base_p_target, (n_starts, 1)),
                      starts.reshape(-1, robot.n_joints),
                      None if base_R_target is None else np.tile(base_R_target, (n_starts, 1, 1)))
    ok = solved.ok
    if accept is not None:
        ok = ok & accept(solved.q_rad, np.tile(np.arange(m), n_starts))
    ok = ok.reshape(n_starts, m)
    distance = np.linalg.norm(solved.q_rad.reshape(n_starts, m, -1) - home, axis=-1)
    pick = np.where(np.any(ok, axis=0), np.argmin(np.where(ok, distance, np.inf), axis=0), 0)
    rows = pick * m + np.arange(m)
    return IKResult(
        solved.q_rad[rows], solved.position_error_m[rows], solved.rotation_error_rad[rows],
        solved.converged[rows], solved.within_limits[rows] & ok[pick, np.arange(m)]
        if accept is not None else solved.within_limits[rows], solved.iterations,
    )


def _replace_rows(values: NDArray[_T], rows: NDArray[np.intp], new: NDArray[_T]) -> NDArray[_T]:
    merged = np.array(values)
    merged[rows] = new
    return merged


def nominal_ik(
    robot: RobotModel, base_p_target: ArrayLike, rng: np.random.Generator,
    starts: tuple[int, ...] = NOMINAL_STARTS, *, base_R_target: ArrayLike | None = None,
    draw: Callable[[NDArray[np.intp]], Starts] | None = None,
    accept: Callable[[NDArray[np.intp]], Accept] | None = None,
) -> IKResult:
    """IK on the nominal model, for targets that come without joint angles.

    Flange positions alone leave the orientation free, so there is no closed form; the batched
    solver runs from the home posture and random postures within the limits, and keeps per
    target the converged in-limit solution closest to home. Targets left without one (a folded
    arm near a limit, say) get a second, larger round of starts, and so on through ``starts``.
    Full poses (``base_R_target``) are solved alike; a configuration (the branch a controller
    takes, :mod:`twin.compensation.configuration`) is honoured by drawing the starts on it
    (``draw``) and keeping only solutions on it (``accept``).

    Args:
        robot: Nominal robot, SI.
        base_p_target: Flange position targets, shape (m, 3), m.
        rng: Generator of the random starts.
        starts: Starts per target in each round.
        base_R_target: Flange orientation targets, shape (m, 3, 3), or None for positions only.
        draw: Given target rows (k,), a sampler of their starts (k', k, n).
        accept: Given target rows (k,), a filter of solutions (:data:`Accept`); a row whose
            solutions are all refused is reported as a joint-limit row (``within_limits``
            false: no acceptable solution within the limits).

    Returns:
        One solution per target; a target no round solves keeps its first-start result, flagged.
    """
    p_target = np.asarray(base_p_target, dtype=np.float64)
    R_target = None if base_R_target is None else np.asarray(base_R_target, dtype=np.float64)

    def attempt(rows: NDArray[np.intp], n_starts: int) -> IKResult:
        return _best_of_starts(robot, p_target[rows], rng, n_starts,
                               None if R_target is None else R_target[rows],
                               None if draw is None else draw(rows),
                               None if accept is None else accept(rows))

    result = attempt(np.arange(len(p_target)), starts[0])
    for n_starts in starts[1:]:
        failed = np.flatnonzero(~result.ok)
        if failed.size == 0:
            break
        retry = attempt(failed, n_starts)
        result = IKResult(
            _replace_rows(result.q_rad, failed, retry.q_rad),
            _replace_rows(result.position_error_m, failed, retry.position_error_m),
            _replace_rows(result.rotation_error_rad, failed, retry.rotation_error_rad),
            _replace_rows(result.converged, failed, retry.converged),
            _replace_rows(result.within_limits, failed, retry.within_limits),
            max(result.iterations, retry.iterations),
        )
    return result


