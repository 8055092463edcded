"""Calibration end to end: split the measurements, run a method, measure the result.

This is the Python API the CLI mirrors::

    robot = twin.default_robot()
    data = twin.load_measurements("measurements.csv")
    result = twin.calibrate(robot, data, port_m=[0.6, 0.3, 0.0], method="lm", seed=0)
    result.metrics["validation"].rmse      # m
    result.identified_robot.dh             # (4, 6), m and rad
    result.solver.stop_reason              # which test stopped the method
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from math import ceil
from typing import NamedTuple, TypedDict, Unpack

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.analysis.gauge import Gauge, unobservable_motions
from twin.analysis.identifiability import Identifiability, measurement_identifiability
from twin.analysis.metrics import Metrics, metrics
from twin.analysis.misfit import Misfit, misfit_test, repeat_sigma
from twin.analysis.uncertainty import CalibrationUncertainty, calibration_uncertainty
from twin.arrays import Array
from twin.dataset import Measurements
from twin.errors import InputError
from twin.geometry.rigid import kabsch, rotation
from twin.kinds import get_kind
from twin.loss import LEAST_SQUARES, Loss
from twin.model import Model
from twin.problem import DEFAULT_SIGMA_M, Problem
from twin.rig import Rig
from twin.robot import RobotModel, random_poses
from twin.solvers import SolverResult, get_solver
from twin.stopping import Budget, at_bounds
from twin.unknowns import make_groups

TRAIN_FRACTION = 0.8
"""Share of the poses used for identification (paper: 80 / 20)."""
WORKSPACE_POSES = 1000
"""Random poses within the joint limits over which the flange accuracy is predicted."""


def split_rows(
    n_rows: int, seed: int, train_fraction: float = TRAIN_FRACTION
) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """A random train/validation split of ``n_rows`` poses, reproducible from ``seed``.

    Returns:
        ``(train_rows, validation_rows)``, each sorted.
    """
    if not 0 < train_fraction < 1:
        raise ValueError(f"train_fraction: {train_fraction}, expected in (0, 1)")
    order = np.random.default_rng(seed).permutation(n_rows)
    n_train = round(train_fraction * n_rows)
    return np.sort(order[:n_train]), np.sort(order[n_train:])


def required_poses(n_params: int, train_fraction: float = TRAIN_FRACTION,
                   rows_per_pose: int = 1) -> int:
    """Fewest poses for which the training split has a residual per unknown and validation one
    pose."""
    per_pose = ceil(n_params / rows_per_pose)
    return max(ceil(per_pose / train_fraction), per_pose + 1)


RIG_GROUPS = {"port": "--estimate-port", "offset": "--estimate-offset",
              "attachment": "--estimate-attachment", "base": "--estimate-base"}
"""The rig's unknown groups and the flag that asks for each."""


def make_model(
    robot: RobotModel,
    rig: Rig,
    kind: str = "length",
    *,
    errors: Sequence[str] = ("dh",),
    estimate_port: bool = False,
    estimate_offset: bool = False,
    estimate_attachment: bool = False,
    estimate_base: bool = False,
) -> Model:
    """The measurement model of a calibration: the robot's error groups and the rig's unknowns.

    Args:
        robot: The nominal robot.
        rig: The nominal rig.
        kind: The measurement kind (:data:`twin.dataset.KINDS`).
        errors: The robot's error groups (:data:`twin.unknowns.GROUPS`): ``("dh",)`` is the
            paper's D-H errors alone.
        estimate_port: Also identify a correction of the rig's estimated ports (every port
            unless :attr:`twin.rig.Rig.estimated_ports` names some).
        estimate_offset: Also identify the encoder's length offset.
        estimate_attachment: Also identify the measured point in the flange frame.
        estimate_base: Also identify a correction of the tracker frame (tracker positions).

    Fixed-point data always identify their fixed points (group ``points``).
    """
    names = [*errors, *(["port"] if estimate_port else []),
             *(["offset"] if estimate_offset else []),
             *(["attachment"] if estimate_attachment else []),
             *(["base"] if estimate_base else []),
             *(["points"] if kind == "point" else [])]
    return Model(robot, rig, get_kind(kind), make_groups(names, robot, rig))


@dataclass(frozen=True)
class CalibrationResult:
    """One method's calibration of one measurement set.

    Attributes:
        robot: The nominal robot.
        model: The measurement model (nominal robot and rig, measurement kind, unknowns).
        solver: The method's raw result (x, history, evaluations, time).
        seed: Seed of the split and of the method's random draws.
        train_rows: Row indices used for identification, shape (m_train,).
        validation_rows: Held-out row indices, shape (m_val,).
        metrics: ``{"before", "train", "validation"}`` metrics in m; ``before`` is the nominal
            model on the validation poses.
        identifiability: What the training poses identify at the start (nominal) geometry.
        identified_identifiability: The same at the identified geometry.
        uncertainty: Noise estimate, base-parameter covariance and predicted flange accuracy.
        budget: The iteration limits and stopping tests the method ran with.
        misfit: The chi-square test of the training residuals against the noise
            (:mod:`twin.analysis.misfit`).
        rejected_rows: Measurement rows (poses, 0-based, train and validation) whose residual
            the robust loss rejects (:mod:`twin.loss`), ascending; empty for least squares.
        gauge: The motions of the flange the data cannot see (:mod:`twin.analysis.gauge`).
        loss: The loss the methods minimised.
    """

    robot: RobotModel
    model: Model
    solver: SolverResult
    seed: int
    train_rows: NDArray[np.intp]
    validation_rows: NDArray[np.intp]
    metrics: dict[str, Metrics]
    identifiability: Identifiability | None = None
    identified_identifiability: Identifiability | None = None
    uncertainty: CalibrationUncertainty | None = None
    budget: Budget = field(default_factory=Budget)
    misfit: Misfit | None = None
    rejected_rows: NDArray[np.intp] = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    gauge: Gauge | None = None
    loss: Loss = LEAST_SQUARES

    @property
    def x(self) -> Array:
        """The identified unknowns, shape (p,), SI (``solver.x``)."""
        return self.solver.x

    @property
    def method(self) -> str:
        """The method's name."""
        return self.solver.method

    @property
    def delta(self) -> Array:
        """Identified errors of the kinematic table, shape (4, n): rows δa [m], δd [m], δα [rad],
        δθ [rad] for a D-H arm; zeros when the table was not identified."""
        return self.model.table(self.solver.x) - self.robot.dh

    @property
    def identified_robot(self) -> RobotModel:
        """The nominal robot with the identified errors added."""
        return self.robot.perturbed(self.delta)

    @property
    def at_bounds(self) -> tuple[str, ...]:
        """Names of the unknowns the method left on a bound of the search box."""
        lower, upper = self.model.bounds()
        return tuple(np.asarray(self.model.names)[at_bounds(self.solver.x, lower, upper)])

    @property
    def ports_m(self) -> Array:
        """Ports used or identified, base frame, shape (k, 3), m."""
        rig = self.model.rig
        ports = np.array(rig.ports_m)
        if self.model.has("port"):
            ports[rig.estimated_port_index] += self.model.block(self.solver.x, "port").reshape(
                -1, 3)
        return ports

    @property
    def attachment_m(self) -> Array:
        """The measured point in the flange frame, used or identified, shape (3,), m."""
        return self.model.point(self.solver.x)

    @property
    def base_in_tracker(self) -> Array:
        """Where the base frame sits in the tracker frame, used or identified, (4, 4), m."""
        transform = np.array(self.model.rig.base_in_tracker)
        if self.model.has("base"):
            correction = self.model.block(self.solver.x, "base")
            turn = rotation(correction[3:])
            transform[:3, :3] = turn @ transform[:3, :3]
            transform[:3, 3] = turn @ transform[:3, 3] + correction[:3]
        return transform

    @property
    def points_m(self) -> Array:
        """The fixed points, used or identified, base frame, shape (f, 3), m."""
        points = np.array(self.model.rig.points_m)
        if self.model.has("points"):
            points += self.model.block(self.solver.x, "points").reshape(points.shape)
        return points

    @property
    def port_m(self) -> Array:
        """The port used or identified when there is one, shape (3,), m."""
        return self.ports_m[0]

    @property
    def offset_m(self) -> float:
        """Identified cable-length offset, m (0 unless estimated)."""
        return float(self.model.block(self.solver.x, "offset")[0]) if self.model.has("offset") \
            else 0.0


class SplitProblem(NamedTuple):
    """A problem and the rows of the measurements it trains and validates on."""

    problem: Problem
    train_rows: NDArray[np.intp]
    """Row indices used for identification, shape (m_train,)."""
    validation_rows: NDArray[np.intp]
    """Held-out row indices, shape (m_val,)."""


def match_ports(measurements: Measurements, rig: Rig) -> Measurements:
    """The measurements with each row's port as an index into the rig's ports.

    Data that name their ports (a ``port`` column) are matched to the rig's ports by name;
    unnamed data use the rig's ports in order.

    Raises:
        InputError: for a port the rig does not have, or data from several unnamed ports.
    """
    if measurements.kind != "length":
        return measurements
    if measurements.port_names:
        unknown = [name for name in measurements.port_names if name not in rig.port_names]
        if unknown:
            raise InputError(f"port {unknown[0]!r} in the measurements",
                             "one of the rig's ports: " + ", ".join(rig.port_names))
        index = np.array([rig.port_names.index(name) for name in measurements.port_names])
        return replace(measurements, port=index[measurements.port_index],
                       port_names=rig.port_names)
    if int(measurements.port_index.max()) >= len(rig.ports_m):
        raise InputError(f"{int(measurements.port_index.max()) + 1} ports in the measurements",
                         f"at most the rig's {len(rig.ports_m)}")
    return measurements


def check_approach(model: Model, approach: ArrayLike | None) -> None:
    """Refuse poses without the approach directions a group of the model reads.

    Args:
        model: The model to fit or evaluate.
        approach: The poses' approach directions, shape (m, n), or None if not recorded.

    Raises:
        InputError: naming the missing columns ``approach1..approachN``.
    """
    if model.needs_approach and approach is None:
        n = model.robot.n_joints
        raise InputError(
            f"no columns approach1..approach{n}",
            f"approach1..approach{n} (+1 or -1: the direction each joint last moved in before "
            "the reading), which backlash needs")


def _rig(port_m: ArrayLike | None, rig: Rig | None) -> Rig:
    if port_m is not None and rig is not None:
        raise ValueError("give either port_m or rig")
    if rig is not None:
        return rig
    return Rig.cable(np.asarray(port_m, dtype=np.float64)) if port_m is not None else Rig()


def with_fixed_points(robot: RobotModel, rig: Rig, measurements: Measurements) -> Rig:
    """The rig with the fixed points of fixed-point data, each started at the mean of the
    nominal model's measured points of its rows (every row: a start, not a fit).

    Raises:
        InputError: for a known distance between points the data do not name.
    """
    assert measurements.point is not None
    names = measurements.point_names or tuple(
        f"point{j + 1}" for j in range(int(measurements.point.max()) + 1))
    nominal = Model(robot, replace(rig, point_names=(), points_m=np.zeros((0, 3)),
                                   distances=()), get_kind("point"), ())
    positions = nominal.positions(np.zeros(0), measurements)
    counts = np.bincount(measurements.point, minlength=len(names))
    starts = np.stack([np.bincount(measurements.point, positions[:, k], minlength=len(names))
                       for k in range(3)], axis=1) / np.maximum(counts, 1)[:, None]
    for distance in rig.distances:
        for name in (distance.first, distance.second):
            if name not in names:
                raise InputError(f"a distance to the point {name!r}", "distances between "
                                 "points the measurements name: " + ", ".join(names),
                                 source="--distance")
    return replace(rig, point_names=names, points_m=starts)


def tracker_start(model: Model, train: Measurements) -> Model:
    """The model with its tracker frame started at the rigid fit (Kabsch) of the nominal model's
    measured points onto the training readings."""
    nominal = replace(model, rig=replace(model.rig, base_in_tracker=np.eye(4)))
    positions = nominal.positions(np.zeros(model.n_params), train)
    assert train.position_m is not None
    fit = kabsch(positions, train.position_m)
    return replace(model, rig=replace(model.rig, base_in_tracker=fit.transform))


class ProblemOptions(TypedDict, total=False):
    """The keywords :func:`calibrate` and :func:`calibrate_many` pass on to
    :func:`make_problem`, which describes each (and gives its default)."""

    rig: Rig | None
    errors: Sequence[str]
    estimate_port: bool
    estimate_offset: bool
    estimate_attachment: bool
    estimate_base: bool
    sigma_m: float
    loss: Loss
    train_fraction: float


def make_problem(
    robot: RobotModel,
    measurements: Measurements,
    port_m: ArrayLike | None = None,
    *,
    rig: Rig | None = None,
    errors: Sequence[str] = ("dh",),
    seed: int = 0,
    estimate_port: bool = False,
    estimate_offset: bool = False,
    estimate_attachment: bool = False,
    estimate_base: bool = False,
    sigma_m: float = DEFAULT_SIGMA_M,
    loss: Loss = LEAST_SQUARES,
    train_fraction: float = TRAIN_FRACTION,
) -> SplitProblem:
    """The problem the solvers see, with its train/validation split.

    Tracker data with ``estimate_base`` start the tracker frame at a rigid fit of the nominal
    model's points to the training readings; fixed-point data start their points at the
    nominal model's mean point of each name.

    Args:
        robot: Nominal robot.
        measurements: Joint angles (rad) and what was read (lengths, tracker positions in m,
            or fixed-point names).
        port_m: Encoder port in the base frame, shape (3,), m — shorthand for
            ``rig=Rig.cable(port_m)``; cable lengths need one of the two.
        rig: The nominal rig (ports, attachment point, tracker frame, known distances).
        errors: The robot's error groups (:data:`twin.unknowns.GROUPS`); the paper's D-H
            errors by default.
        seed: Seed of the train/validation split.
        estimate_port: Also identify a correction to the (estimated) port positions.
        estimate_offset: Also identify an unknown cable-length offset.
        estimate_attachment: Also identify the measured point in the flange frame.
        estimate_base: Also identify the tracker frame (tracker positions), started at a rigid
            fit of the nominal model's points.
        sigma_m: The noise 1σ of a reading, m: the filters' measurement noise and the misfit
            test's reference (:mod:`twin.analysis.misfit`).
        loss: How residual rows count (:mod:`twin.loss`); least squares by default.
        train_fraction: Share of the poses used for identification (paper: 0.8).

    Raises:
        InputError: if there are fewer poses than the unknowns need, the measurements lack
            what a group reads (the approach directions of backlash), or an unknown is asked
            for that these measurements cannot have (a port of tracker data…).
    """
    setup = _rig(port_m, rig)
    kind = get_kind(measurements.kind)
    wanted = {"port": estimate_port, "offset": estimate_offset, "base": estimate_base}
    for name, asked in wanted.items():
        if asked and name not in kind.groups:
            raise InputError(f"{RIG_GROUPS[name]} with {measurements.kind} measurements",
                             "only the unknowns they can have: " + ", ".join(
                                 flag for group, flag in RIG_GROUPS.items()
                                 if group in kind.groups or group == "attachment"))
    if measurements.kind == "length":
        if not len(setup.ports_m):
            raise InputError("cable lengths without a port", "the port (--port X,Y,Z or "
                             "--port NAME=X,Y,Z)")
        measurements = match_ports(measurements, setup)
    elif measurements.kind == "point":
        setup = with_fixed_points(robot, setup, measurements)
    model = make_model(robot, setup, measurements.kind, errors=errors,
                       estimate_port=estimate_port, estimate_offset=estimate_offset,
                       estimate_attachment=estimate_attachment, estimate_base=estimate_base)
    check_approach(model, measurements.approach)
    needed = required_poses(model.n_params, train_fraction, model.kind.rows_per_pose)
    if len(measurements) < needed:
        percent = round(100 * train_fraction)
        raise InputError(
            f"{len(measurements)} poses",
            f"at least {needed} for {model.n_params} unknowns with a {percent}/{100 - percent} "
            "split",
        )
    train_rows, validation_rows = split_rows(len(measurements), seed, train_fraction)
    train = measurements.subset(train_rows)
    if estimate_base:
        model = tracker_start(model, train)
    problem = Problem(model, train, measurements.subset(validation_rows), sigma_m=sigma_m,
                      loss=loss)
    return SplitProblem(problem, train_rows, validation_rows)


def calibrate_many(
    robot: RobotModel,
    measurements: Measurements,
    port_m: ArrayLike | None,
    methods: Sequence[str],
    *,
    seed: int = 0,
    budget: Budget | None = None,
    on_result: Callable[[CalibrationResult], None] | None = None,
    **options: Unpack[ProblemOptions],
) -> dict[str, CalibrationResult]:
    """Run several methods on the same split, each with a generator seeded from ``seed``.

    Takes the arguments of :func:`calibrate`, with a list of methods, and ``on_result``, called
    with each method's result as soon as it is done (to show a run live).

    Returns:
        Results keyed by each method's name, in the order given.
    """
    split = make_problem(robot, measurements, port_m, seed=seed, **options)
    return solve_many(robot, split, methods, seed=seed, budget=budget, on_result=on_result)


def rejected_poses(problem: Problem, x: ArrayLike, data: Measurements) -> NDArray[np.bool_]:
    """Which poses of ``data`` have a residual row the problem's loss rejects, shape (m,)."""
    rows = problem.model.kind.rows_per_pose
    residuals = problem.model.residuals(np.asarray(x, dtype=np.float64), data)
    beyond = problem.loss.rejected(residuals[: rows * len(data)])
    return np.asarray(np.any(beyond.reshape(len(data), rows), axis=1))


def _assess(split: SplitProblem, x: Array, identified: Identifiability, q_workspace: Array
            ) -> tuple[Misfit, NDArray[np.intp], Measurements, Gauge]:
    """The fit test, the rejected rows, the training poses kept and the unobservable motions."""
    problem, train_rows, validation_rows = split
    out_train = rejected_poses(problem, x, problem.train)
    out_validation = rejected_poses(problem, x, problem.validation)
    rejected = np.sort(np.concatenate([train_rows[out_train], validation_rows[out_validation]]))
    rows = problem.model.kind.rows_per_pose
    # A loss that rejects nearly everything (a swarm far from the optimum) leaves no degree of
    # freedom to test or to estimate the noise from: then every training row counts.
    enough = rows * int(np.sum(~out_train)) > identified.rank
    kept = problem.train.subset(np.flatnonzero(~out_train)) if enough else problem.train
    residuals = problem.model.residuals(x, kept)
    misfit = misfit_test(residuals, identified.rank, problem.sigma_m,
                         repeat_sigma(kept, residuals, rows))
    gauge = unobservable_motions(problem.model, x, identified.null_space, q_workspace)
    return misfit, rejected.astype(np.intp), kept, gauge


def solve_many(
    robot: RobotModel,
    split: SplitProblem,
    methods: Sequence[str],
    *,
    seed: int = 0,
    budget: Budget | None = None,
    on_result: Callable[[CalibrationResult], None] | None = None,
) -> dict[str, CalibrationResult]:
    """:func:`calibrate_many` on a problem already made (and so already checked) by
    :func:`make_problem`."""
    solvers = [get_solver(name) for name in methods]
    problem, train_rows, validation_rows = split
    before = metrics(problem.model.residuals(problem.x0, problem.validation))
    nominal = measurement_identifiability(problem.model, problem.x0, problem.train)
    q_workspace = random_poses(robot, WORKSPACE_POSES, np.random.default_rng(seed))
    budget = budget or Budget()
    results = {}
    for solver in solvers:
        solved = solver.solve(problem, budget, np.random.default_rng(seed))
        identified = measurement_identifiability(problem.model, solved.x, problem.train)
        misfit, rejected, kept, gauge = _assess(split, solved.x, identified, q_workspace)
        results[solver.name] = CalibrationResult(
            robot=robot, model=problem.model, solver=solved, seed=seed,
            train_rows=train_rows, validation_rows=validation_rows,
            metrics={
                "before": before,
                "train": metrics(problem.model.residuals(solved.x, problem.train)),
                "validation": metrics(problem.model.residuals(solved.x, problem.validation)),
            },
            identifiability=nominal,
            identified_identifiability=identified,
            uncertainty=calibration_uncertainty(
                problem.model, solved.x, kept, nominal.base, q_workspace
            ),
            budget=budget,
            misfit=misfit,
            rejected_rows=rejected,
            gauge=gauge,
            loss=problem.loss,
        )
        if on_result is not None:
            on_result(results[solver.name])
    return results


def calibrate(
    robot: RobotModel,
    measurements: Measurements,
    port_m: ArrayLike | None = None,
    *,
    method: str = "lm",
    seed: int = 0,
    budget: Budget | None = None,
    **options: Unpack[ProblemOptions],
) -> CalibrationResult:
    """Identify the errors of ``robot`` (and the rig's unknowns) from measurements.

    ``robot``, ``measurements`` and ``port_m`` (or ``rig``) are those of :func:`make_problem`.

    Args:
        method: A method name or paper alias (``lm``, ``m2``, …).
        seed: Seed of the train/validation split and of any random draw of the method.
        budget: Iteration limits and stopping tests; by default ``Budget()``, run to
            convergence (``Budget.paper()`` is the paper's protocol).
        **options: How the problem is made (:class:`ProblemOptions`: the rig, the error
            groups, which rig unknowns to estimate, the noise, the loss, the split), as
            :func:`make_problem` takes them.
    """
    return calibrate_many(robot, measurements, port_m, [method], seed=seed, budget=budget,
                          **options)[get_solver(method).name]
