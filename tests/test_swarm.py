"""The swarm building blocks: the B-spline step of BIPSO, the slot selection, the initial swarm."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from twin.arrays import read_only
from twin.calibration.setup import make_model
from twin.geometry import kinematics
from twin.geometry.kinematics import KERNEL_VARIABLE
from twin.io.robot_file import default_robot
from twin.kinds.length import LENGTH, length_measurements
from twin.problem import Problem
from twin.rig import Rig
from twin.solvers.swarm import (
    best_in_slots,
    chord_parameters,
    initial_swarm,
    interpolated_points,
    interpolating_curve,
)


def _particles(n: int = 100, p: int = 24, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).normal(0.0, 1e-3, size=(n, p))


def test_bspline_passes_through_the_particles() -> None:
    """The cubic B-spline evaluated at the chord parameters returns every particle."""
    x = _particles()
    t, curve = interpolating_curve(x)
    assert curve.k == 3
    np.testing.assert_allclose(curve(t), x, rtol=0, atol=1e-15)


def test_chord_parameters_are_normalised_cumulative_full_vector_distances() -> None:
    """t_0 = 0, t_{N−1} = 1 and each step is the Euclidean distance in R^p over the total."""
    x = _particles(10)
    t, kept = chord_parameters(x)
    chords = np.linalg.norm(np.diff(x, axis=0), axis=1)
    np.testing.assert_allclose(t, np.r_[0.0, np.cumsum(chords)] / np.sum(chords), rtol=1e-14)
    np.testing.assert_array_equal(kept, x)


def test_duplicate_particles_are_dropped_and_the_curve_still_interpolates() -> None:
    """A particle equal to its predecessor (zero chord) is left out; the rest are interpolated."""
    x = _particles(20)
    x[5] = x[4]
    x[6] = x[4]
    t, curve = interpolating_curve(x)
    kept = np.delete(x, [5, 6], axis=0)
    assert t.size == 18 and np.all(np.diff(t) > 0)
    np.testing.assert_allclose(curve(t), kept, rtol=0, atol=1e-15)


@pytest.mark.parametrize("kernel", ["numpy"], indirect=True)
def test_interpolated_points_run_from_the_first_to_the_last_particle(kernel: str) -> None:
    """M points at evenly spaced t in [0, 1]: the ends are the first and last particles."""
    x = _particles()
    points = interpolated_points(x, 100)
    assert points.shape == (100, 24)
    np.testing.assert_allclose(points[[0, -1]], x[[0, -1]], rtol=0, atol=1e-15)
    _, curve = interpolating_curve(x)
    np.testing.assert_allclose(points, curve(np.linspace(0.0, 1.0, 100)), rtol=0, atol=0)


@pytest.mark.parametrize("count", [4, 5, 7, 100])
def test_the_compiled_curve_is_scipys(count: int) -> None:
    """The compiled step (:mod:`twin.solvers.compiled`) draws scipy's cubic not-a-knot B-spline
    to round-off, at evenly spaced and at the particles' own parameters, with chords of very
    different lengths (particles spread over four orders of magnitude)."""
    pytest.importorskip("numba")
    from scipy.interpolate import make_interp_spline

    from twin.solvers.compiled import curve_points

    rng = np.random.default_rng(count)
    for p in (1, 24):
        x = rng.normal(size=(count, p)) * 10.0 ** rng.uniform(-4, 0, (count, 1))
        t, kept = chord_parameters(x)
        curve = make_interp_spline(t, kept, k=3, axis=0)
        for at in map(read_only, (np.linspace(0.0, 1.0, 100), t)):  # as _even keeps them
            np.testing.assert_allclose(curve_points(t, kept, at), curve(at), rtol=0,
                                       atol=1e-12 * np.max(np.abs(kept)))


@pytest.mark.parametrize("kernel", ["numba"], indirect=True)
def test_interpolated_points_on_the_compiled_kernel(kernel: str) -> None:
    """A study's workers draw the curve on the compiled kernel: the points scipy's curve gives,
    to round-off; fewer than four distinct particles still go to scipy (a lower degree)."""
    x = _particles()
    points = interpolated_points(x, 100)
    _, curve = interpolating_curve(x)
    np.testing.assert_allclose(points, curve(np.linspace(0.0, 1.0, 100)), rtol=0,
                               atol=1e-13 * np.max(np.abs(x)))
    few = _particles(3)
    np.testing.assert_array_equal(interpolated_points(few, 9),
                                  interpolating_curve(few)[1](np.linspace(0.0, 1.0, 9)))


def test_a_collapsed_swarm_interpolates_to_its_single_point() -> None:
    """All particles equal: no curve can be drawn, the interpolated points are that point."""
    x = np.repeat(_particles(1), 7, axis=0)
    np.testing.assert_array_equal(interpolated_points(x, 5), np.repeat(x[:1], 5, axis=0))
    with pytest.raises(ValueError, match="two distinct"):
        interpolating_curve(x)


def test_best_in_slots_keeps_survivors_in_place_and_fills_freed_slots() -> None:
    """Moved particles among the best N keep their slot; the best extra points fill the rest."""
    candidates = np.arange(6.0)[:, None]  # slots 0..3, then 2 B-spline points
    f = np.array([5.0, 1.0, 9.0, 2.0, 0.5, 7.0])
    x, fx = best_in_slots(candidates, f, 4)
    # best four: 4 (0.5), 1 (1.0), 3 (2.0), 0 (5.0) -> slot 2 (9.0) is freed for point 4.
    np.testing.assert_array_equal(x[:, 0], [0.0, 1.0, 4.0, 3.0])
    np.testing.assert_array_equal(fx, [5.0, 1.0, 0.5, 2.0])


def test_initial_swarm_is_within_1mm_1deg_of_the_centre() -> None:
    """Eq. 14 with the text's radius: ±1 mm on lengths, ±1° on angles; slot 0 is the centre."""
    robot = default_robot()
    q = np.zeros((30, 6))
    problem = Problem(make_model(robot, Rig.cable(np.array([0.6, -0.4, 0.1]))),
                      length_measurements(q[:25], np.ones(25)),
                      length_measurements(q[25:], np.ones(5)))
    center = np.full(24, 1e-4)
    x = initial_swarm(problem, center, 100, np.random.default_rng(0))
    radius = np.where(problem.model.is_length, 1e-3, np.deg2rad(1.0))
    assert x.shape == (100, 24)
    np.testing.assert_array_equal(x[0], center)
    assert np.all(np.abs(x - center) <= radius)
    assert np.all(np.max(np.abs(x - center), axis=0) > 0.9 * radius)


@pytest.mark.slow
@pytest.mark.parametrize("iterations", [2, 10, None])
def test_a_swarm_never_returns_worse_than_its_start(iterations: int | None) -> None:
    """PSO stopped after 2 or 10 iterations, or run to its own test, on three seeds of the
    geometric and paper scenarios: the validation RMSE never exceeds the start's; when the
    swarm's point does not beat the start by BIC, the start itself comes back (x = x0) and the
    report says why."""
    from dataclasses import replace

    from twin.calibration.pipeline import calibrate
    from twin.report.text import format_result
    from twin.scenario import load_scenario
    from twin.sim import simulate

    scenarios = Path(__file__).resolve().parents[1] / "scenarios"
    for name in ("geometric_irb120", "paper_irb120"):
        scenario = load_scenario(scenarios / f"{name}.toml")
        settings = replace(scenario.calibration, stop="converge", max_iterations=iterations)
        for seed in range(3):
            sim = simulate(scenario, seed)
            result = calibrate(sim.robot, sim.measurements, rig=sim.rig_told_pulled,
                               settings=settings, seed=seed, method="pso")
            metrics = result.metrics
            assert metrics["validation"].rmse <= metrics["before"].rmse, (name, seed)
            assert result.held is not None
            if result.held.kept_start:
                assert np.array_equal(result.x, np.zeros(result.model.n_params))
                assert "returned the start" in format_result(result)


def _plain_bipso(problem: Problem, center: np.ndarray, iterations: int,
                 rng: np.random.Generator) -> tuple[np.ndarray, list[float]]:
    """BIPSO as method-notes §4 reads, one candidate at a time: eq. 18's move, the cubic
    B-spline through the moved particles by chord length (scipy's make_interp_spline with its
    checks), M evenly spaced points on it, the best N of the pool kept in their slots, elitist
    bests. Returns G_best and its f after each iteration (the start first)."""
    from scipy.interpolate import make_interp_spline

    n, m, c = 100, 100, 1.49618
    lower, upper = problem.lower, problem.upper
    vmax = 0.2 * (upper - lower)

    def objective(points: np.ndarray) -> np.ndarray:
        return np.array([problem.cost(problem.residuals(point)) for point in points])

    x = initial_swarm(problem, center, n, rng)
    v = np.zeros_like(x)
    best_x, best_f = x.copy(), objective(x)
    history = [float(best_f.min())]
    for k in range(iterations):
        omega = 0.9 - 0.5 * k / (iterations - 1)
        r1, r2 = rng.random((2, *x.shape))
        g = best_x[np.argmin(best_f)]
        v = np.clip(omega * v + c * r1 * (best_x - x) + c * r2 * (g - x), -vmax, vmax)
        moved = np.clip(x + v, lower, upper)
        chords = np.linalg.norm(np.diff(moved, axis=0), axis=1)
        t = np.concatenate([[0.0], np.cumsum(chords)]) / np.sum(chords)
        points = make_interp_spline(t, moved, k=3)(np.linspace(0.0, 1.0, m))
        pool = np.clip(np.vstack([moved, points]), lower, upper)
        f = objective(pool)
        order = np.argsort(f, kind="stable")[:n]
        x, fx = pool[:n].copy(), f[:n].copy()
        freed = [slot for slot in range(n) if slot not in order]
        x[freed], fx[freed] = pool[order[order >= n]], f[order[order >= n]]
        improved = fx < best_f
        best_x[improved], best_f[improved] = x[improved], fx[improved]
        history.append(float(best_f.min()))
    return best_x[np.argmin(best_f)], history


@pytest.mark.parametrize("kernel", ["numpy", "numba"], indirect=True)
def test_bipso_takes_the_particles_a_plain_reading_takes(kernel: str) -> None:
    """The batched swarm (every candidate of an iteration in one call, on either kernel —
    numpy and scipy's spline, or the compiled positions and curve — the spline built once per
    iteration) moves the same particles as the plain loop of the method on the same seed:
    G_best and its f per iteration equal to round-off."""
    from twin.solvers.base import Tracker
    from twin.solvers.bipso import bipso
    from twin.stopping import Budget

    robot = default_robot()
    rng = np.random.default_rng(11)
    model = make_model(robot, Rig.cable(np.array([0.6, -0.4, 0.1])))
    truth = rng.uniform(-1.0, 1.0, model.n_params) * model.radius
    q = rng.uniform(-1.5, 1.5, (40, 6))
    problem = Problem(model, model.measure(truth, q[:30]), model.measure(truth, q[30:]))
    center = 0.5 * truth
    iterations = 5
    budget = Budget(max_iterations=iterations, stall_iterations=0)
    tracker = Tracker(problem, "bipso")
    outcome = bipso(tracker, center, budget, np.random.default_rng(3))
    expected_x, expected_f = _plain_bipso(problem, center, iterations, np.random.default_rng(3))
    np.testing.assert_allclose([record.f_m2 for record in tracker.history], expected_f,
                               rtol=1e-9, atol=0)
    np.testing.assert_allclose(outcome.x, expected_x, rtol=1e-9, atol=1e-15)
    assert expected_f[-1] < expected_f[0]


def _cable_problem(seed: int) -> Problem:
    """A cable problem of the IRB 120 with its 24 D-H errors: 30 training and 10 validation
    poses, lengths read with 0.01 mm noise (so that no method fits them exactly)."""
    robot = default_robot()
    rng = np.random.default_rng(seed)
    model = make_model(robot, Rig.cable(np.array([0.6, -0.4, 0.1])))
    truth = rng.uniform(-1.0, 1.0, model.n_params) * model.radius
    q = rng.uniform(-1.5, 1.5, (40, 6))
    lengths = model.measure(truth, q).value(LENGTH) + rng.normal(0.0, 1e-5, 40)
    return Problem(model, length_measurements(q[:30], lengths[:30]),
                   length_measurements(q[30:], lengths[30:]))


@pytest.mark.parametrize("kernel", ["numpy", "numba"])
def test_the_objective_is_the_cost_of_the_rows(kernel: str,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """f of a swarm's candidates, summed in the chain's pass where the rows are plain cable
    lengths, is the mean cost of the objective's rows: bit for bit on the numpy path, to
    round-off on the compiled kernel; with an offset estimated, a robust loss or a prior, the
    rows' cost itself."""
    if kernel == "numba":
        pytest.importorskip("numba")
    from dataclasses import replace

    from twin.calibration.settings import CalibrationSettings
    from twin.loss import Loss

    monkeypatch.setenv(KERNEL_VARIABLE, kernel)
    kinematics._compiled.cache_clear()
    plain = _cable_problem(3)
    robot, rig = plain.model.robot, plain.model.rig
    offset = make_model(robot, rig, settings=CalibrationSettings(estimate=("offset",)))
    priors = make_model(robot, rig, settings=CalibrationSettings(priors=("dh=0.3mm",)))
    for problem, summed in ((plain, True), (replace(plain, loss=Loss("huber", 2e-5)), False),
                            (Problem(offset, plain.train, plain.validation), False),
                            (Problem(priors, plain.train, plain.validation), False)):
        x = _particles(50, problem.model.n_params, 4)
        found = problem.objective(x)
        expected = problem.cost(problem.residuals(x))
        if summed:
            assert problem.model.sum_squares(x, problem.train) is not None
        if summed and kernel == "numba":
            np.testing.assert_allclose(found, expected, rtol=1e-14, atol=0)
        else:
            np.testing.assert_array_equal(found, expected)
        assert problem.objective(x[7]) == pytest.approx(expected[7], rel=1e-14)
    # An estimated offset is more than the distance less the reading: no sum in the pass.
    assert offset.sum_squares(np.zeros(offset.n_params), plain.train) is None
    monkeypatch.delenv(KERNEL_VARIABLE)
    kinematics._compiled.cache_clear()


def test_the_compiled_swarm_step_is_the_numpy_step() -> None:
    """One iteration's moves (eq. 18's velocity, clamp, move, the B-spline points) and the
    selection with the personal-best update, compiled (:mod:`twin.solvers.compiled`), give
    what the numpy functions give from the same r1, r2: velocities and moves bit for bit, the
    curve's points to round-off, the selection exactly."""
    pytest.importorskip("numba")
    from twin.solvers.compiled import keep_best, pso_candidates
    from twin.solvers.swarm import C_PERSONAL, C_SOCIAL, CHORD_RTOL, pso_velocity

    rng = np.random.default_rng(5)
    n, m, p = 100, 100, 24
    lower, upper = np.full(p, -2e-3), np.full(p, 2e-3)
    vmax = 0.2 * (upper - lower)
    x, best_x = _particles(n, p, 1), _particles(n, p, 2)
    v = _particles(n, p, 3)
    g_x = best_x[7]
    r = rng.random((2, n, p))
    at = read_only(np.linspace(0.0, 1.0, m))  # as _even keeps them
    v_numpy = pso_velocity(x, v, best_x, g_x, 0.7, vmax, r)
    moved = np.clip(x + v_numpy, lower, upper)
    points = np.clip(interpolated_points(moved, m), lower, upper)
    v_compiled = v.copy()
    candidates, drawn = pso_candidates(x, v_compiled, best_x, g_x, r, 0.7,
                                       np.array([C_PERSONAL, C_SOCIAL]), vmax, lower, upper,
                                       at, CHORD_RTOL)
    assert drawn
    np.testing.assert_array_equal(v_compiled, v_numpy)
    np.testing.assert_array_equal(candidates[:n], moved)
    np.testing.assert_allclose(candidates[n:], points, rtol=0, atol=1e-13 * np.max(np.abs(moved)))

    f = rng.random(n + m)
    f[[3, 150]] = f[40]  # ties keep the stable order
    best_f = rng.random(n)
    expected_x, expected_f = best_in_slots(candidates, f, n)
    improved = expected_f < best_f
    expected_best_x, expected_best_f = best_x.copy(), best_f.copy()
    expected_best_x[improved], expected_best_f[improved] = (expected_x[improved],
                                                            expected_f[improved])
    slots = x.copy()
    keep_best(candidates, f, np.argsort(f, kind="stable")[:n], slots, best_x, best_f)
    np.testing.assert_array_equal(slots, expected_x)
    np.testing.assert_array_equal(best_x, expected_best_x)
    np.testing.assert_array_equal(best_f, expected_best_f)


@pytest.mark.parametrize(("method", "iterations"),
                         [("amlm-bipso", None), ("pso", None), ("bipso", 20)])
def test_swarms_find_the_same_g_best_on_either_kernel(
        method: str, iterations: int | None, monkeypatch: pytest.MonkeyPatch) -> None:
    """M9 (AMLM then BIPSO) and PSO under the paper's protocol, and BIPSO for 20 iterations, on
    the compiled kernels (positions, moves, selection) and on the numpy path with one seed: the
    same G_best and f at every iteration, to round-off, and the same evaluations (the random
    draws are the same, in the same order). BIPSO alone runs 20 iterations, not 60: its curve
    is scipy's on one path and the compiled one on the other, equal to round-off, and a swarm
    started far from the optimum amplifies round-off tenfold every few iterations (by its
    60th, G_best differs by a few per cent), where M9's swarm, started at AMLM's optimum, does
    not."""
    pytest.importorskip("numba")
    from twin.solvers import get_solver
    from twin.stopping import Budget

    problem = _cable_problem(11)
    budget = Budget.paper() if iterations is None else Budget(max_iterations=iterations,
                                                              stall_iterations=0)
    results = {}
    for mode in ("numpy", "numba"):
        monkeypatch.setenv(KERNEL_VARIABLE, mode)
        kinematics._compiled.cache_clear()
        assert kinematics.takes_compiled() == (mode == "numba")
        results[mode] = get_solver(method).solve(problem, budget, np.random.default_rng(4))
    monkeypatch.delenv(KERNEL_VARIABLE)
    kinematics._compiled.cache_clear()
    numpy_run, compiled_run = results["numpy"], results["numba"]
    np.testing.assert_allclose(compiled_run.x, numpy_run.x, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose([record.f_m2 for record in compiled_run.history],
                               [record.f_m2 for record in numpy_run.history], rtol=1e-9, atol=0)
    assert compiled_run.evaluations == numpy_run.evaluations
    assert numpy_run.history[-1].f_m2 < numpy_run.history[0].f_m2
