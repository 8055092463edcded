"""One trial: simulate a capture, run every method on the same split, measure against the truth.

Trial k of a study is seeded with ``SeedSequence([scenario seed, k])``: its perturbation, port,
poses, noise, split and every method's random draws are the same whatever executor runs it and
in whatever order. The same seed is used at every sweep point (common random numbers).

Against the truth, for each method:

- **flange error**: RMS over a fixed set of random workspace poses (seeded from the scenario's
  seed, the same for every trial) of the distance between the true and the identified flange
  centres. A fit of the D-H table alone is held to the true table (what a D-H model can
  represent: how much of the non-geometric errors it folds into the table); a fit with
  joint-level groups (transmission, backlash, compliance) is held to where the twin's flange
  really is — MuJoCo at rest with transmission error, backlash and sag (``Twin.at_rest``), the
  workspace poses visited in order from home — against the identified model's prediction at the
  same commanded poses and approach directions;
- **Cramér–Rao bound** of that error (:func:`twin.analysis.uncertainty.cramer_rao_rms`) for
the
  trial's training poses, with the length-noise variance σ² + res²/12 + (jitter seen along the
  cable), averaged over the poses, from the fitted model's Jacobian (joint groups included);
  with joint angles recorded to a resolution, each row's own variance adds the rounding through
  its ∂ℓ/∂q (the bound of the best linear estimator, which weights the rows by it).
  Outliers are not noise, nor are compliance and joint errors to a D-H-only model, so in those
  regimes the bound is the floor of the Gaussian part only and ratios below 1 can occur;
- **gauge-free errors**: the flange error modulo the motions the data cannot see, and the
  measured point's (eyelet, tracker target, ball) error likewise, with its own Cramér–Rao bound
  (:mod:`twin.calibration.accuracy`, :mod:`twin.analysis.gauge`);
- **identifiable parameter error**: x̂ − x_true with its components along the null space of the
  cable Jacobian removed (:mod:`twin.analysis.identifiability`). The null space is taken at the
  nominal geometry, where it is exact (rank 19 of 24 for the IRB 120 with a known port): at the
  perturbed truth the same directions have singular values some 1e-4–1e-7 of the largest, so
  they are numerically but not practically identifiable, and would swamp the comparison.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from itertools import groupby
from operator import itemgetter
from typing import Any, NamedTuple

import numpy as np

from twin.analysis.linearisation import model_jacobian
from twin.analysis.metrics import NO_ROWS
from twin.analysis.uncertainty import cramer_rao_rms
from twin.arrays import Array
from twin.calibration.accuracy import TruthErrors, rigid_truth, truth_errors
from twin.calibration.pipeline import calibrate_many
from twin.dataset import TEMPERATURE, approach_directions
from twin.geometry.kinematics import for_bulk_work, load_compiled, takes_compiled
from twin.geometry.rigid import angles, log_rotation
from twin.kinds.plane import plane_corrections, plane_part
from twin.kinds.pose import pose_part
from twin.model import Model
from twin.robot import RobotModel, random_poses
from twin.scenario import Scenario
from twin.sim.mujoco_twin import Twin
from twin.sim.simulate import Simulation, simulate
from twin.study.rows import TrialRow
from twin.study.store import TrialOutcome
from twin.units import m_to_mm, to_display
from twin.unknowns import Stage
from twin.unknowns.transmission import unknowns as transmission_unknowns

WORKSPACE_STREAM = 0x5EED
"""Second word of the workspace poses' seed sequence, apart from every trial's."""


class TrialSpec(NamedTuple):
    """What a worker needs to run trials of one case (pickled to the worker)."""

    scenario: Scenario
    methods: tuple[str, ...]
    workspace_poses: int


def trial_seed(scenario_seed: int, trial: int) -> int:
    """The seed of trial ``trial``, derived from the scenario's seed."""
    return int(np.random.SeedSequence([scenario_seed, trial]).generate_state(1)[0])


def workspace(spec: TrialSpec) -> Array:
    """The workspace poses where flange errors are measured, shape (k, n), rad."""
    rng = np.random.default_rng(np.random.SeedSequence([spec.scenario.seed, WORKSPACE_STREAM]))
    return random_poses(spec.scenario.robot, spec.workspace_poses, rng)


def true_unknowns(sim: Simulation, model: Model) -> Array:
    """The unknowns x a perfect calibration returns, shape (p,), SI: the D-H errors, the
    transmission error in the model's harmonics (0 for a higher harmonic, which it cannot
    hold), half the lash, the compliances 1/k (with the file's masses, which the model uses),
    the links' growth per kelvin (the table at the reference temperature:
    :func:`warm_robot`), the port's correction and the offset (of the robot's errors, those
    the calibration did not fix); the rig's other unknowns (attachment, instrument frame,
    fixed points, tool rotation, planes) as the corrections of the model's start."""
    x = np.zeros(model.n_params)
    n = sim.robot.n_joints
    thermal = sim.scenario.thermal
    lengths = sim.robot.structure.is_length[:2].ravel()
    robot_errors = {
        "dh": lambda: (warm_robot(sim, model).dh - sim.robot.dh).ravel(),
        "thermal": lambda: np.zeros(int(lengths.sum())) if thermal is None
        else thermal.expansion_m_per_k.ravel()[lengths],
        "transmission": lambda: transmission_unknowns(
            sim.robot, np.nan_to_num(sim.joint_errors.coefficients()), np.zeros(n)),
        "backlash": lambda: 0.5 * sim.joint_errors.backlash_rad,
        "compliance": lambda: sim.scenario.physics.compliance(sim.robot.n_joints)}
    for name, truth in robot_errors.items():
        if model.has(name):
            x[model.slice(name)] = model.group(name).take(truth())
    rig = model.rig
    if model.has("port"):
        index = rig.estimated_port_index
        x[model.slice("port")] = (sim.rig.ports_m[index] - rig.ports_m[index]).ravel()
    if model.has("offset"):
        x[model.slice("offset")] = sim.scenario.noise.offset_m
    if model.has("scale"):
        x[model.slice("scale")] = sim.scenario.noise.scale
    if model.has("attachment"):
        x[model.slice("attachment")] = sim.rig.attachment_m - rig.attachment_m
    if model.has("base"):
        start, true = rig.base_in_tracker, sim.rig.base_in_tracker
        turn = true[:3, :3] @ start[:3, :3].T
        x[model.slice("base")] = np.r_[true[:3, 3] - turn @ start[:3, 3], angles(turn)]
    if model.has("points"):
        x[model.slice("points")] = (sim.rig.points_m - rig.points_m).ravel()
    if model.has("tool"):
        turn = pose_part(rig).tool_rotation.T @ pose_part(sim.rig).tool_rotation
        x[model.slice("tool")] = log_rotation(turn)
    if model.has("planes"):
        x[model.slice("planes")] = plane_corrections(plane_part(rig), plane_part(sim.rig))
    return x


def warm_robot(sim: Simulation, model: Model) -> RobotModel:
    """The twin's true robot as warm as the model's table holds it: after a warm-up
    (``[thermal]``) its links grown to the model's reference temperature, or to the capture's
    mean temperature for a model without thermal growth (a rigid table fitted over the
    warm-up is best at its middle); the true robot as it is without a warm-up."""
    thermal = sim.scenario.thermal
    if thermal is None:
        return sim.true_robot
    reference = model.rig.temperature_ref_c
    if reference is None:
        reference = float(np.mean(sim.measurements.value(TEMPERATURE)))
    return sim.true_robot.perturbed(thermal.growth(reference))


def noise_sigma_m(sim: Simulation, jacobian: Array) -> float:
    """RMS length noise of the readings (Gaussian, quantisation, joint jitter), m.

    Args:
        sim: The simulation.
        jacobian: Cable Jacobian at the truth on the training poses, shape (m, p); its θ
            columns are ∂ℓ/∂q, which carry the joint jitter onto the cable.
    """
    noise = sim.scenario.noise
    n = sim.robot.n_joints
    dl_dq = jacobian[:, 3 * n : 4 * n]  # the θ slot of the table, first in x
    jitter = sim.joint_sigma_rad**2 * float(np.mean(np.sum(dl_dq**2, axis=1)))
    instrument = sim.scenario.instrument.setup.instrument_sigma_m(noise.encoder_sigma_m)
    return float(np.sqrt(instrument**2 + jitter))


def row_sigma_m(sim: Simulation, jacobian: Array, sigma_m: float) -> Array | None:
    """Each training row's noise 1σ when the joint angles are recorded to a resolution: the
    readings' σ and the rounding (r/√12 per joint) through the row's ∂ℓ/∂q, shape (m,), m;
    None when they are exact (every row's σ is ``sigma_m``)."""
    resolution = np.asarray(sim.scenario.noise.joint_resolution_rad or (0.0,))
    if not np.any(resolution > 0):
        return None
    n = sim.robot.n_joints
    dl_dq = jacobian[:, 3 * n : 4 * n]  # the θ slot of the table, as in noise_sigma_m
    return np.asarray(np.sqrt(sigma_m**2 + np.sum((dl_dq * resolution) ** 2, axis=1) / 12.0),
                      dtype=np.float64)


def _mm(value_m: float) -> float:
    return float(m_to_mm(value_m))


def _display(values: Array, model: Model) -> list[float]:
    return to_display(values, model.units)[0]


def has_joint_groups(model: Model) -> bool:
    """Whether the model holds joint-level errors: then it is held to the physical flange."""
    return any(group.stage == Stage.JOINTS for group in model.groups)


def true_points(sim: Simulation, q_workspace: Array, robot: RobotModel | None = None
                ) -> tuple[Array, Array]:
    """Where the twin's flange centre and measured point really are at the workspace poses,
    visited in order from home: MuJoCo at rest with joint errors and sag, shapes (k, 3), m;
    of ``robot`` (the true robot by default: :func:`warm_robot` after a warm-up)."""
    twin = Twin.build(sim.true_robot if robot is None else robot, sim.port_m,
                      sim.scenario.physics, sim.joint_errors, sim.rig.attachment_m)
    rest = twin.at_rest(q_workspace, approach_directions(q_workspace))
    return rest.flange_m, rest.point_m


def trial_truth(sim: Simulation, model: Model, q_workspace: Array) -> tuple[Array, Array]:
    """The truth a trial's model is held to at the workspace poses, flange centres and measured
    points (k, 3) each, m: the twin's physical robot for a model with joint-level errors, the
    rigid true table for one without (whose flange is the table's by definition); after a
    warm-up, the robot as warm as the model's table (:func:`warm_robot`)."""
    robot = warm_robot(sim, model)
    if has_joint_groups(model):
        return true_points(sim, q_workspace, robot)
    return rigid_truth(robot, sim.rig.attachment_m, q_workspace)


def run_trial(spec: TrialSpec, case: str, trial: int, q_workspace: Array) -> TrialOutcome:
    """Simulate trial ``trial`` of a case, calibrate with every method, compare with the truth."""
    seed = trial_seed(spec.scenario.seed, trial)
    return _judged(spec, case, trial, seed, simulate(spec.scenario, seed), q_workspace)


def _judged(spec: TrialSpec, case: str, trial: int, seed: int, sim: Simulation,
            q_workspace: Array) -> TrialOutcome:
    """Trial ``trial`` of a case (seeded ``seed``) on its simulation: every method's
    calibration, compared with the truth."""
    # Against the truth a trial reads the answers alone, not the checks a report shows.
    results = calibrate_many(sim.robot, sim.measurements, None, spec.methods,
                             rig=sim.rig_told_pulled, settings=spec.scenario.calibration,
                             seed=seed, report=False)
    first = next(iter(results.values()))
    model = first.model
    train = sim.measurements.subset(first.train_rows)
    validation = sim.measurements.subset(first.validation_rows)
    x_true = true_unknowns(sim, model)
    _, jacobian = model_jacobian(model, x_true, train)  # as the bound linearises it below
    sigma_m = noise_sigma_m(sim, jacobian)
    crlb_m, point_crlb_m = cramer_rao_rms(model, x_true, train, sigma_m, q_workspace,
                                          row_sigma_m(sim, jacobian, sigma_m))
    # At the nominal geometry (the start) on the training rows, as every result holds it.
    nominal = first.identifiability
    assert nominal is not None  # calibrate_many sets it on every result
    null_space = nominal.null_space
    rows: list[TrialRow] = []
    methods: dict[str, Any] = {}
    truth = trial_truth(sim, model, q_workspace)
    for name, result in results.items():
        # The model's poses come with the approach directions of visiting them in order, as
        # the twin's flange.
        errors = truth_errors(result, *truth, q_workspace)
        flange_m = errors.flange_m
        error = result.solver.x - x_true
        if null_space.shape[1]:
            error = error - null_space @ np.linalg.lstsq(null_space, error, rcond=None)[0]
        before_m, train_m, validation_m = (result.metrics.get(stage, NO_ROWS)
                                           for stage in ("before", "train", "validation"))
        rows.append(TrialRow(
            trial=trial, case=case, seed=seed, method=name,
            before_rmse_mm=_mm(before_m.rmse), before_mae_mm=_mm(before_m.mae),
            before_std_mm=_mm(before_m.std), before_max_mm=_mm(before_m.max),
            train_rmse_mm=_mm(train_m.rmse), train_mae_mm=_mm(train_m.mae),
            train_std_mm=_mm(train_m.std), train_max_mm=_mm(train_m.max),
            validation_rmse_mm=_mm(validation_m.rmse), validation_mae_mm=_mm(validation_m.mae),
            validation_std_mm=_mm(validation_m.std), validation_max_mm=_mm(validation_m.max),
            flange_error_mm=_mm(flange_m), crlb_mm=_mm(crlb_m),
            crlb_ratio=flange_m / crlb_m if crlb_m > 0 else float("nan"),
            iterations=result.solver.iterations, evaluations=result.solver.evaluations,
            seconds=result.solver.seconds, converged=result.solver.converged,
            stop_reason=result.solver.stop_label,
            **_truth_columns(errors, crlb_m, point_crlb_m),
        ))
        methods[name] = {
            "history_mm": m_to_mm([r.validation_rmse_m for r in result.solver.history]).tolist(),
            "residuals_mm": m_to_mm(model.residuals(result.solver.x, validation)).tolist(),
            "parameter_error": _display(error, model),
        }
    before = model.residuals(np.zeros(model.n_params), validation)
    detail = {
        "before_residuals_mm": m_to_mm(before).tolist(),
        "noise_sigma_mm": float(m_to_mm(sigma_m)),
        "parameter_names": list(model.names),
        "parameter_units": to_display(np.zeros(model.n_params), model.units)[1],
        "methods": methods,
    }
    return TrialOutcome(case=case, trial=trial, seed=seed, rows=tuple(rows), detail=detail)


def _truth_columns(errors: TruthErrors, crlb_m: float, point_crlb_m: float) -> dict[str, float]:
    """The gauge-free flange and measured-point errors against the truth (flange centres and
    measured points, :func:`trial_truth`), and their ratios to the bounds (NaN where a bound
    is zero: no noise)."""
    return {
        "flange_error_gauge_free_mm": _mm(errors.flange_gauge_free_m),
        "crlb_ratio_gauge_free": errors.flange_gauge_free_m / crlb_m if crlb_m > 0
        else float("nan"),
        "point_error_mm": _mm(errors.point_gauge_free_m),
        "point_crlb_ratio": errors.point_gauge_free_m / point_crlb_m if point_crlb_m > 0
        else float("nan"),
    }


def run_batch(specs: Mapping[str, TrialSpec], batch: Sequence[tuple[str, int]]
              ) -> list[TrialOutcome]:
    """Run a batch of (case, trial) pairs, each case's consecutive trials simulated before any
    of them is fitted; the unit of work an executor ships to a worker (whose many trials pay
    the compiled kernel's import once: :func:`~twin.geometry.kinematics.for_bulk_work`, with
    the kernels loaded before any method is timed:
    :func:`~twin.geometry.kinematics.load_compiled`, :func:`twin.solvers.compiled.load`). The
    outcomes are :func:`run_trial`'s, in the batch's order."""
    for_bulk_work()
    if takes_compiled():
        from twin.solvers.compiled import load

        load_compiled()
        load()
    spaces: dict[str, Array] = {}
    outcomes = []
    for case, block in groupby(batch, key=itemgetter(0)):
        spec = specs[case]
        if case not in spaces:
            spaces[case] = workspace(spec)
        trials = [trial for _, trial in block]
        seeds = [trial_seed(spec.scenario.seed, trial) for trial in trials]
        # Every simulation of a case's run of trials first, then their fits: MuJoCo's and
        # the capture's code stay warm in the caches from one to the next (4.6 % less CPU a
        # geometric_irb120 trial in blocks of 10, 1.8 % a plane_irb120 trial; the fits and
        # the checks staged too took more, not less).
        sims = [simulate(spec.scenario, seed) for seed in seeds]
        outcomes += [_judged(spec, case, trial, seed, sim, spaces[case])
                     for trial, seed, sim in zip(trials, seeds, sims, strict=True)]
    return outcomes
