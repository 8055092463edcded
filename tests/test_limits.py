"""What may move and how far: the search box (``--bounds``), priors (``--prior``) and fixed
parameters (``--fix``) — in the CLI, a ``[calibration]`` table and the API alike — and what
the result, the report and every command that uses a result say about them.

Referees: the twin's truth (MuJoCo) and :func:`scipy.optimize.least_squares` on the same
residual, run inside each test."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import least_squares

import twin
from twin.analysis.uncertainty import cramer_rao_flange_rms, rms_distance
from twin.calibration.setup import make_problem
from twin.cli import main
from twin.dataset import Measurements
from twin.errors import InputError
from twin.io.calibration_table import calibration_lines, parse_calibration
from twin.io.identified import load_result
from twin.io.paths import read_toml
from twin.io.results import result_to_dict, write_json
from twin.io.table import Table
from twin.robot import RobotModel, random_poses
from twin.scenario import load_scenario
from twin.sim import Simulation, simulate
from twin.solvers import get_solver
from twin.stopping import Budget
from twin.unknowns.dh import BOUND_M, BOUND_RAD
from twin.unknowns.limits import Bound, Prior

ROOT = Path(__file__).resolve().parents[1]
WIDE = ROOT / "scenarios" / "wide_irb120.toml"
PORT = "600,-400,100"


@pytest.fixture(scope="module")
def wide() -> Simulation:
    """One draw of the wide scenario: a robot further from its table than the paper's box."""
    return simulate(load_scenario(WIDE), 0)


def _flange_error(robot: RobotModel, result: twin.CalibrationResult, sim: Simulation,
                  workspace: np.ndarray) -> float:
    poses = result.model.poses(workspace)
    return rms_distance(result.model.flange_positions(result.x, poses),
                        sim.true_robot.flange_positions(workspace))


def test_a_truth_outside_the_paper_box_is_recovered_with_bounds(wide: Simulation) -> None:
    """The truth lies beyond ±5 mm / ±8°: in the paper's box LM ends on its bounds, metres of
    cable error left; with ``bounds`` it reaches the Cramér–Rao bound against the twin's truth
    and scipy's optimum on the same residual in the same box."""
    bound = np.where(wide.robot.is_length, BOUND_M, BOUND_RAD)
    assert np.any(np.abs(wide.delta) > bound)  # the premise
    workspace = random_poses(wide.robot, 500, np.random.default_rng(3))
    paper = twin.calibrate(wide.robot, wide.measurements, wide.port_nominal_m)
    assert paper.at_bounds and _flange_error(wide.robot, paper, wide, workspace) > 1e-3
    settings = twin.CalibrationSettings(bounds=("dh=20mm", "dh=15deg"))
    split = make_problem(wide.robot, wide.measurements, wide.port_nominal_m, settings=settings)
    problem = split.problem
    wider = twin.calibrate(wide.robot, wide.measurements, wide.port_nominal_m,
                           settings=settings)
    assert not wider.at_bounds
    reference = least_squares(
        lambda x: problem.model.residuals(x, problem.train), problem.x0,
        jac=lambda x: problem.model.jacobian(x, problem.train)[1],
        bounds=(problem.lower, problem.upper), method="trf", x_scale="jac")
    referee = rms_distance(
        problem.model.flange_positions(reference.x, problem.model.poses(workspace)),
        wide.true_robot.flange_positions(workspace))
    crlb = cramer_rao_flange_rms(problem.model, wide.delta.ravel(), problem.train, 1e-5,
                                 workspace)
    error = _flange_error(wide.robot, wider, wide, workspace)
    assert error < 2.0 * crlb and error < 1.25 * referee, (error, crlb, referee)


def test_the_cli_bounds_flag_and_the_result_file(wide: Simulation, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """``--bounds`` on the command line gives the API's answer; the result records each
    unknown's box and is applied (predict, export) beyond the paper's box, inside its own."""
    csv = tmp_path / "m.csv"
    twin.write_measurements(csv, wide.measurements)
    out = tmp_path / "r.json"
    assert main(["calibrate", str(csv), "--port", PORT, "--bounds", "dh=20mm",
                 "--bounds", "dh=15deg", "--json", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "search box: dh=20mm, dh=15deg" in printed
    document = json.loads(out.read_text())
    api = twin.calibrate(wide.robot, wide.measurements, wide.port_nominal_m,
                         settings=twin.CalibrationSettings(bounds=("dh=20mm", "dh=15deg")))
    assert np.allclose(np.array(document["delta"]["a"]) * 1e-3, api.delta[0], atol=1e-8)
    assert document["limits"]["bounds"] == ["dh=20mm", "dh=15deg"]
    first = document["unknowns"]["parameters"][0]
    assert (first["lower"], first["upper"], first["unit"]) == (-20.0, 20.0, "mm")
    assert max(abs(v) for v in document["delta"]["a"]) > 5.0  # beyond the paper's box
    loaded = load_result(out)
    assert np.allclose(loaded.delta, api.delta, atol=1e-8)
    assert main(["export", str(out), "--format", "dh", "--out", str(tmp_path / "e.toml")]) == 0
    # A value beyond the box the file records is refused.
    tampered = json.loads(out.read_text())
    tampered["unknowns"]["parameters"][0]["upper"] = 1.0
    tampered["unknowns"]["parameters"][0]["value"] = 3.0
    tampered["delta"]["a"][0] = 3.0
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(tampered))
    with pytest.raises(InputError, match="within the search bounds"):
        load_result(bad)


def test_the_prior_rows_are_the_objective_of_every_method(
        irb120: RobotModel, measurements: Measurements, port_m: np.ndarray) -> None:
    """With priors the objective is [r; σ x/σ_p]: its Jacobian matches finite differences, LM
    reaches scipy's minimum of it, and a filter and a cascade see it too (their cost is the
    problem's cost of the same rows)."""
    settings = twin.CalibrationSettings(priors=("dh=0.3mm", "dh=0.05deg"))
    problem = make_problem(irb120, measurements, port_m, settings=settings).problem
    assert problem.prior_rows == 24
    x = np.random.default_rng(0).normal(0.0, 1e-4, problem.model.n_params)
    rows, jacobian = problem.jacobian(x)
    step = 1e-7
    numeric = np.stack([(problem.residuals(x + step * e) - problem.residuals(x - step * e))
                        / (2 * step) for e in np.eye(x.size)], axis=1)
    assert np.allclose(jacobian, numeric, atol=1e-6)
    assert np.allclose(rows[-24:], problem.sigma_m * x * problem.model.prior_weight())
    reference = least_squares(problem.residuals, problem.x0, jac=lambda v: problem.jacobian(v)[1],
                              method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    lm = get_solver("lm").solve(problem, Budget(), np.random.default_rng(0))
    assert float(problem.cost(problem.residuals(lm.x))) <= float(
        problem.cost(reference.fun)) * (1 + 1e-9)
    # The same point, to well within its posterior σ (the prior makes it unique).
    assert np.all(np.abs(lm.x - reference.x) < 1e-3 * np.sqrt(np.diag(np.linalg.inv(
        jacobian.T @ jacobian))) * problem.sigma_m)
    for method in ("ekf", "amlm-bipso"):
        result = get_solver(method).solve(problem, Budget(), np.random.default_rng(0))
        recorded = result.history[-1].f_m2
        assert recorded == pytest.approx(float(problem.cost(problem.residuals(result.x))))
        # Shrunk by the same prior: within a few σ of the data's fit of the MAP estimate.
        assert rms_distance(
            problem.model.flange_positions(result.x, problem.train),
            problem.model.flange_positions(reference.x, problem.train)) < 5e-5, method


def test_a_prior_decides_what_the_data_barely_see(
        irb120: RobotModel, measurements: Measurements, port_m: np.ndarray,
        true_delta: np.ndarray, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A prior a hundred times tighter than the data on a2 decides it (shrunk to a hundredth
    of the truth's 0.8 mm); the data decide a1 under the same prior as a2's before; α6, which
    no reading of the flange centre moves, is the prior's and held at the nominal — named in
    the report, the result and the warning of every command that uses it."""
    result = twin.calibrate(irb120, measurements, port_m, settings=twin.CalibrationSettings(
        priors=("dh=1mm", "dh=0.5deg", "a2=0.0001mm")))
    assert "a2" in result.prior_decided and "a1" not in result.prior_decided
    assert abs(result.delta[0, 1]) < 0.01 * abs(true_delta[0, 1])
    assert abs(result.delta[0, 0] - true_delta[0, 0]) < 0.1 * abs(true_delta[0, 0])
    assert "alpha6" in result.prior_decided and abs(result.delta[2, 5]) < 1e-12
    csv = tmp_path / "m.csv"
    twin.write_measurements(csv, measurements)
    out = tmp_path / "r.json"
    assert main(["calibrate", str(csv), "--port", PORT, "--prior", "dh=1mm,dh=0.5deg",
                 "--prior", "a2=0.0001mm", "--json", str(out)]) == 0
    assert "decided by the prior, not the data" in capsys.readouterr().out
    document = json.loads(out.read_text())
    assert "a2" in document["prior_decided"]
    assert main(["predict", "--identified", str(out), "--joints", str(csv), "--out",
                 str(tmp_path / "p.csv")]) == 0
    assert "twin: warning: " in (err := capsys.readouterr().err)
    assert "the prior, not the data, decided a2" in err


def test_a_fixed_parameter_stays_at_the_nominal_and_frees_its_partner(
        irb120: RobotModel, measurements: Measurements, port_m: np.ndarray,
        true_delta: np.ndarray, tmp_path: Path) -> None:
    """``fix=("d2",)``: d2 is no unknown, δd2 = 0 exactly; d3 alone carries the sum d2 + d3
    the cable sees along the parallel axes of joints 2 and 3, and is identified (the true sum
    comes back); the file round-trips it."""
    result = twin.calibrate(irb120, measurements, port_m,
                            settings=twin.CalibrationSettings(fix=("d2", "theta6")))
    assert result.model.n_params == 22 and "d2" not in result.model.names
    assert result.delta[1, 1] == 0.0 and result.delta[3, 5] == 0.0
    assert result.identifiability is not None
    assert not any("d3" in name for name in result.identifiability.unidentifiable)
    assert result.delta[1, 2] == pytest.approx(true_delta[1, 2] + true_delta[1, 1], abs=2e-5)
    out = tmp_path / "r.json"
    write_json(out, result_to_dict(result))
    document = json.loads(out.read_text())
    assert document["unknowns"]["fixed"] == ["d2", "theta6"]
    loaded = load_result(out)
    assert loaded.model.names == result.model.names
    assert np.allclose(twin.predict(result, measurements.q_rad).position_m,
                       loaded.model.positions(loaded.x, loaded.model.poses(measurements.q_rad)),
                       atol=1e-9)


def test_settings_read_alike_from_a_table_the_api_and_a_capture(tmp_path: Path) -> None:
    """A ``[calibration]`` table's bounds, priors and fix make the same settings as the API's
    texts, and a capture file writes them back as it read them."""
    table = Table({"bounds": ["dh=20mm", "a2=-5:20mm"], "priors": ["theta=0.5deg"],
                   "fix": ["theta6"]}, "capture.toml", "calibration")
    read = parse_calibration(table, 1e-5)
    made = twin.CalibrationSettings(sigma_m=1e-5, bounds=("dh=20mm", "a2=-5:20mm"),
                                    priors=("theta=0.5deg",), fix=("theta6",))
    assert read == made
    assert read.bounds[1] == Bound("a2", "m", -0.005, 0.02)
    assert read.priors[0] == Prior("theta", "rad", float(np.deg2rad(0.5)))
    path = tmp_path / "c.toml"
    path.write_text("\n".join(calibration_lines(read)) + "\n")
    document = read_toml(path, "a capture")
    again = parse_calibration(Table(document["calibration"], path, "calibration"), 1e-5)
    assert again == read


@pytest.mark.parametrize(("flags", "message"), [
    (["--bounds", "dh=20"], "--bounds: found 'dh=20', expected a value with one of the units"),
    (["--bounds", "dh=5:20mm"], "--bounds: found 'dh=5:20mm', expected a range that holds the "
     "nominal (0)"),
    (["--bounds", "wrist=1mm"], "--bounds: found 'wrist', expected an unknown of this "
     "calibration, a family or a group"),
    (["--bounds", "theta=3mm"], "--bounds: found 'theta=3mm', expected a value in the unit of "
     "theta (deg)"),
    (["--prior", "dh=0mm"], "--prior: found 'dh=0mm', expected a σ > 0"),
    (["--fix", "port", "--estimate-port"], "--fix: found fixing port, expected robot errors "
     "or the attachment"),
])
def test_a_wrong_rule_is_one_line_naming_its_flag(flags: list[str], message: str,
                                                 csv_path: Path, refusals: object) -> None:
    """Each mistake in a rule: one line, exit code 2, the flag and the rule named."""
    refusals.cli(["calibrate", csv_path, "--port", PORT, *flags], [csv_path],  # type: ignore
                 message)
