"""Error compensation: batched IK on the identified model, and reading identified results."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from twin.analysis.uncertainty import rms_distance
from twin.calibration.pipeline import calibrate
from twin.choices import KERNEL_VARIABLE
from twin.cli import main
from twin.compensation.check import check_compensation
from twin.compensation.ik import (
    STATUS_JOINT_LIMIT,
    STATUS_OK,
    STATUS_SINGULAR,
    STATUS_UNREACHABLE,
    nominal_ik,
    solve_ik,
)
from twin.compensation.joints import compensate_program, compensate_targets
from twin.compensation.targets import reachable_targets
from twin.dataset import Measurements
from twin.errors import InputError
from twin.geometry import kinematics
from twin.geometry.kinematics import flange_jacobian
from twin.io.identified import load_result_delta
from twin.io.results import result_to_dict, write_json
from twin.io.robot_file import load_robot
from twin.robot import RobotModel

ROOT = Path(__file__).resolve().parents[1]


def test_flange_jacobian_matches_finite_differences(true_robot: RobotModel) -> None:
    """The geometric Jacobian's columns equal central differences of position and rotation."""
    rng = np.random.default_rng(3)
    q = rng.uniform(true_robot.lower_rad, true_robot.upper_rad, (20, true_robot.n_joints))
    base_T_flange, jacobian = flange_jacobian(true_robot.structure, true_robot.dh, q)
    np.testing.assert_allclose(base_T_flange, true_robot.flange_transforms(q), atol=1e-15)
    step = 1e-6
    for i in range(true_robot.n_joints):
        dq = np.zeros(true_robot.n_joints)
        dq[i] = step
        plus = true_robot.flange_transforms(q + dq)
        minus = true_robot.flange_transforms(q - dq)
        linear = (plus[:, :3, 3] - minus[:, :3, 3]) / (2 * step)
        # dR/dq · Rᵀ = [ω]×: read ω off the skew-symmetric part.
        skew = (plus[:, :3, :3] - minus[:, :3, :3]) / (2 * step) @ np.swapaxes(
            base_T_flange[:, :3, :3], -1, -2)
        angular = np.stack([skew[:, 2, 1], skew[:, 0, 2], skew[:, 1, 0]], axis=-1)
        np.testing.assert_allclose(jacobian[:, :3, i], linear, atol=1e-8)
        np.testing.assert_allclose(jacobian[:, 3:, i], angular, atol=1e-8)


@pytest.mark.parametrize("kernel", ["numpy", "numba"], indirect=True)
@pytest.mark.parametrize("model", ["irb120.toml", "scara4/scara4.toml"])
def test_position_ik_converges_quadratically_on_either_kernel(kernel: str, model: str) -> None:
    """Position targets are solved on the flange centre's trace (the compiled kernel in bulk
    work): from seeds 0.02 rad (or m) off, the walk's forward kinematics — another code path —
    puts every solution on its target within 1e-10 m, in a handful of Newton steps (a wrong
    derivative would converge linearly at best: over 20 steps from there)."""
    robot = load_robot(ROOT / "models" / model)
    rng = np.random.default_rng(4)
    q = rng.uniform(robot.lower_rad, robot.upper_rad, (60, robot.n_joints))
    target = robot.flange_positions(q)
    solved = solve_ik(robot, target, q + rng.uniform(-0.02, 0.02, q.shape))
    assert np.all(solved.converged)
    assert solved.iterations <= 8, solved.iterations
    np.testing.assert_allclose(robot.flange_positions(solved.q_rad), target, rtol=0, atol=1e-10)


@pytest.mark.parametrize("model", ["irb120.toml", "scara4/scara4.toml", "fr3/fr3.urdf"])
def test_compiled_position_ik_takes_the_numpy_steps(model: str,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """Position IK from seeds anywhere within the limits, as a touch capture starts it (some
    rows converge, the others give up at the largest damping or run out of steps): the
    compiled kernel takes numpy's steps — the same rows converge, in as many lockstep
    iterations, onto their targets, at the same commands to 1e-6 rad (m on a slide: a 3-D
    target leaves an arm's other joints free, along which round-off steers a solution by
    0.5 µrad). An arm with a slide, and one read from a URDF (its own parametrisation, base
    and tool transforms)."""
    pytest.importorskip("numba")
    robot = load_robot(ROOT / "models" / model)
    rng = np.random.default_rng(6)
    q = rng.uniform(robot.lower_rad, robot.upper_rad, (150, robot.n_joints))
    targets = robot.flange_positions(q) + rng.normal(0.0, 0.05, (150, 3))
    seeds = rng.uniform(robot.lower_rad, robot.upper_rad, q.shape)
    solved = {}
    for kernel in ("numpy", "numba"):
        monkeypatch.setenv(KERNEL_VARIABLE, kernel)
        kinematics._compiled.cache_clear()
        assert kinematics.takes_compiled() == (kernel == "numba")
        solved[kernel] = solve_ik(robot, targets, seeds)
    monkeypatch.delenv(KERNEL_VARIABLE)
    kinematics._compiled.cache_clear()
    reference, compiled = solved["numpy"], solved["numba"]
    assert 0 < np.sum(reference.converged) < len(q)
    np.testing.assert_array_equal(compiled.converged, reference.converged)
    assert compiled.iterations == reference.iterations
    done = reference.converged
    np.testing.assert_allclose(compiled.q_rad[done], reference.q_rad[done], rtol=0, atol=1e-6)
    np.testing.assert_allclose(robot.flange_positions(compiled.q_rad[done]), targets[done],
                               rtol=0, atol=1e-10)


def test_program_compensation_reaches_nominal_pose(
    irb120: RobotModel, true_robot: RobotModel
) -> None:
    """Corrected program joints put the identified flange at the nominal pose (1e-10 m / rad)."""
    rng = np.random.default_rng(0)
    q, _ = reachable_targets(irb120, 500, rng)
    solved = compensate_program(irb120, true_robot, q)
    assert np.all(solved.status == STATUS_OK)
    reached, wanted = true_robot.flange_transforms(solved.q_rad), irb120.flange_transforms(q)
    np.testing.assert_allclose(reached[:, :3, 3], wanted[:, :3, 3], atol=2e-10)
    np.testing.assert_allclose(reached[:, :3, :3], wanted[:, :3, :3], atol=2e-10)
    # Millimetre-sized table errors need corrections of a few degrees at most near the wrist,
    # not a jump to another IK branch (which differs by radians).
    assert np.max(np.abs(solved.q_rad - q)) < 0.2


def test_target_compensation_is_minimum_norm(irb120: RobotModel, true_robot: RobotModel) -> None:
    """Position-only compensation reaches the targets with the smallest joint change."""
    rng = np.random.default_rng(1)
    q, target = reachable_targets(irb120, 300, rng)
    solved = compensate_targets(true_robot, target, q)
    assert np.all(solved.ok)
    np.testing.assert_allclose(true_robot.flange_positions(solved.q_rad), target, atol=2e-10)
    # The change lies in the row space of the position Jacobian (the minimum-norm solution's
    # first-order condition); its component in the null space is second order.
    _, jacobian = flange_jacobian(true_robot.structure, true_robot.dh, solved.q_rad)
    change = solved.q_rad - q
    _, _, vt = np.linalg.svd(jacobian[:, :3, :])
    null_part = np.einsum("mkj,mj->mk", vt[:, 3:, :], change)
    assert np.max(np.linalg.norm(null_part, axis=-1) / np.linalg.norm(change, axis=-1)) < 0.05


def test_nominal_ik_finds_in_limit_solutions(irb120: RobotModel) -> None:
    """Multi-start nominal IK solves every reachable target within the joint limits."""
    rng = np.random.default_rng(2)
    _, target = reachable_targets(irb120, 200, rng)
    solved = nominal_ik(irb120, target, np.random.default_rng(5))
    assert np.all(solved.ok)
    np.testing.assert_allclose(irb120.flange_positions(solved.q_rad), target, atol=2e-10)
    assert np.all(solved.q_rad >= irb120.lower_rad) and np.all(solved.q_rad <= irb120.upper_rad)


def test_unreachable_and_out_of_limits_are_flagged(irb120: RobotModel) -> None:
    """A target beyond reach is unreachable; a solution past a limit is flagged, not clipped."""
    far = np.array([[2.0, 0.0, 0.3]])
    assert nominal_ik(irb120, far, np.random.default_rng(0)).status.tolist() == [
        STATUS_UNREACHABLE
    ]
    # Joint 3 at its upper limit: the same pose with q3 a little beyond needs no limit change
    # in the table, only a target that the chain reaches past the limit.
    q = np.array([[0.2, 0.3, irb120.upper_rad[2] + 0.01, 0.4, 0.5, 0.6]])
    target = irb120.flange_positions(q)
    solved = solve_ik(irb120, target, q - np.array([0, 0, 0.02, 0, 0, 0]))
    assert solved.status.tolist() == [STATUS_JOINT_LIMIT]
    assert solved.q_rad[0, 2] > irb120.upper_rad[2]


def test_a_correction_a_turn_away_is_at_the_joint_limit() -> None:
    """UR5e joint 2 programmed at 359.5°, its limit 360°, a real robot whose θ2 is 1° short:
    the correction needs 360.5°, whose only angle within the limits is 0.5°, a turn away —
    the joint would spin round on the way. That row is at its joint limit, not corrected; the
    row beside it (q2 = 300°) is corrected by 1°."""
    nominal = load_robot(ROOT / "models" / "ur5e" / "ur5e.urdf")
    delta = np.zeros_like(nominal.dh)
    delta[3, 1] = np.deg2rad(-1.0)
    identified = nominal.perturbed(delta)
    q = np.deg2rad([[10.0, 359.5, -60.0, 30.0, 45.0, 20.0],
                    [10.0, 300.0, -60.0, 30.0, 45.0, 20.0]])
    solved = compensate_program(nominal, identified, q)
    assert solved.status.tolist() == [STATUS_JOINT_LIMIT, STATUS_OK]
    assert np.rad2deg(solved.q_rad[1] - q[1]) == pytest.approx([0, 1, 0, 0, 0, 0], abs=1e-6)


def test_a_program_row_at_an_aligned_wrist_is_singular(irb120: RobotModel,
                                                       true_robot: RobotModel) -> None:
    """The same pose with the wrist 0.4° from aligned and 40° from it: the first needs q4 and
    q6 turned degrees against each other (the smallest singular value of the scaled Jacobian,
    from numpy's SVD, below 0.02 m/rad) and is flagged singular, not counted as corrected; the
    second is corrected by a fraction of a degree."""
    q = np.deg2rad([[20.0, 10.0, 15.0, 30.0, 0.4, -20.0],
                    [20.0, 10.0, 15.0, 30.0, 40.0, -20.0]])
    solved = compensate_program(irb120, true_robot, q)
    assert solved.status.tolist() == [STATUS_SINGULAR, STATUS_OK]
    assert not solved.ok[0]
    change_deg = np.rad2deg(np.abs(solved.q_rad - q))
    assert change_deg[0, 3] > 2.0 and change_deg[0, 5] > 2.0 and change_deg[1].max() < 1.0
    _, jacobian = flange_jacobian(irb120.structure, irb120.dh, q)
    jacobian[:, 3:] *= 0.3
    smallest = np.linalg.svd(jacobian, compute_uv=False)[:, -1]
    assert smallest[0] < 0.02 < smallest[1]


def test_a_position_target_at_a_stretched_arm_is_singular(irb120: RobotModel,
                                                         true_robot: RobotModel) -> None:
    """Cartesian position targets: with the elbow stretched and the wrist 0.5° from aligned the
    flange moves outwards only through large joint motions, and the row is flagged singular
    (the position rows' smallest singular value, from numpy's SVD, below 0.02 m/rad) — its
    correction turns joints more than twice as far as the same target's with the wrist bent
    40°, which is corrected as usual."""
    q = np.deg2rad([[20.0, 30.0, -79.9, 30.0, 0.5, -20.0],
                    [20.0, 30.0, -79.9, 30.0, 40.0, -20.0]])
    solved = compensate_targets(true_robot, irb120.flange_positions(q), q)
    assert solved.status.tolist() == [STATUS_SINGULAR, STATUS_OK]
    assert np.all(solved.position_error_m < 1e-9)
    _, jacobian = flange_jacobian(true_robot.structure, true_robot.dh, q)
    smallest = np.linalg.svd(jacobian[:, :3], compute_uv=False)[:, -1]
    assert smallest[0] < 0.02 < smallest[1]
    change_deg = np.rad2deg(np.max(np.abs(solved.q_rad - q), axis=1))
    assert change_deg[0] > 2.0 * change_deg[1]


def test_compensation_with_identified_model_reaches_identification_accuracy(
    irb120: RobotModel, true_robot: RobotModel, measurements: Measurements, port_m: np.ndarray
) -> None:
    """After LM on core-made data, compensated targets miss by the identified model's own
    flange error (hundredths of a mm), against millimetres uncompensated."""
    result = calibrate(irb120, measurements, port_m, method="lm", seed=0)
    identified = result.identified_geometry
    rng = np.random.default_rng(11)
    q, target = reachable_targets(irb120, 1000, rng)
    solved = compensate_targets(identified, target, q)
    check = check_compensation(
        target, true_robot.flange_positions(q), true_robot.flange_positions(solved.q_rad),
        solved,
    )
    assert check.n_failed == 0
    assert check.nominal.rmse > 1e-3
    floor = rms_distance(identified.flange_positions(q), true_robot.flange_positions(q))
    assert check.compensated.rmse < 3 * floor
    assert check.compensated.rmse < 0.1 * check.nominal.rmse


def test_load_result_delta_single_and_all(
    tmp_path: Path, irb120: RobotModel, measurements: Measurements, port_m: np.ndarray
) -> None:
    """A result file round-trips its delta; a multi-method file needs --method and names them."""
    result = calibrate(irb120, measurements, port_m, method="lm", seed=0)
    single, multi = tmp_path / "one.json", tmp_path / "all.json"
    write_json(single, result_to_dict(result))
    write_json(multi, {"methods": {"lm": result_to_dict(result)}})
    # The file holds 1e-6 mm and 1e-6 degree.
    tolerance = np.array([[1e-9], [1e-9], [np.deg2rad(1e-6)], [np.deg2rad(1e-6)]])
    for delta in (load_result_delta(single, irb120), load_result_delta(multi, irb120, "lm")):
        assert np.all(np.abs(delta - result.delta) <= 0.5 * tolerance + 1e-18)
    with pytest.raises(InputError, match="lm"):
        load_result_delta(multi, irb120)
    with pytest.raises(InputError, match="one of lm"):
        load_result_delta(multi, irb120, "pso")
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"delta": {"a": [0.0] * 5}}))
    with pytest.raises(InputError, match=r"bad\.json: delta"):
        load_result_delta(bad, irb120)


def _write_result(path: Path, robot: RobotModel, measurements: Measurements,
                  port_m: np.ndarray) -> RobotModel:
    result = calibrate(robot, measurements, port_m, method="lm", seed=0)
    write_json(path, result_to_dict(result))
    return result.identified_geometry


def test_cli_corrects_a_program(
    tmp_path: Path, irb120: RobotModel, measurements: Measurements, port_m: np.ndarray
) -> None:
    """`twin compensate --joints` writes angles whose identified pose is the nominal pose."""
    identified = _write_result(tmp_path / "result.json", irb120, measurements, port_m)
    q_deg = np.array([[10.0, 20.0, -30.0, 40.0, 50.0, 60.0], [-90.0, 45.0, 30.0, -100.0, -60.0,
                                                              200.0]])
    program = tmp_path / "program.csv"
    program.write_text("q1,q2,q3,q4,q5,q6\n" + "\n".join(",".join(map(str, q)) for q in q_deg))
    out = tmp_path / "corrected.csv"
    assert main(["compensate", "--identified", str(tmp_path / "result.json"),
                 "--joints", str(program), "--out", str(out)]) == 0
    lines = out.read_text().splitlines()
    assert lines[0] == "q1,q2,q3,q4,q5,q6,status,error_mm"
    corrected = np.deg2rad([[float(v) for v in line.split(",")[:6]] for line in lines[1:]])
    assert [line.split(",")[6] for line in lines[1:]] == [STATUS_OK, STATUS_OK]
    reached = identified.flange_transforms(corrected)
    wanted = irb120.flange_transforms(np.deg2rad(q_deg))
    # Angles are written to 1e-6 degree (≤ 0.5e-6° each, ~1e-8 m at the flange); the result
    # file's table to 1e-6 mm and degree.
    np.testing.assert_allclose(reached[:, :3, 3], wanted[:, :3, 3], atol=5e-8)


@pytest.mark.slow
def test_cli_targets_report_unreachable_rows(
    tmp_path: Path, irb120: RobotModel, measurements: Measurements, port_m: np.ndarray
) -> None:
    """`twin compensate --targets` solves reachable rows, marks a far one unreachable and one
    at the edge of the reach (the arm stretched to reach it) singular."""
    identified = _write_result(tmp_path / "result.json", irb120, measurements, port_m)
    targets = tmp_path / "targets.csv"
    targets.write_text("x,y,z\n400,100,500\n2000,0,0\n300,-200,400\n457.1,0,752.8\n")
    out = tmp_path / "corrected.csv"
    assert main(["compensate", "--identified", str(tmp_path / "result.json"),
                 "--targets", str(targets), "--out", str(out)]) == 0
    rows = [line.split(",") for line in out.read_text().splitlines()[1:]]
    assert [row[6] for row in rows] == [STATUS_OK, STATUS_UNREACHABLE, STATUS_OK,
                                        STATUS_SINGULAR]
    assert rows[1][:6] == [""] * 6 and float(rows[1][7]) > 1000.0
    q = np.deg2rad([[float(v) for v in rows[i][:6]] for i in (0, 2)])
    np.testing.assert_allclose(identified.flange_positions(q) * 1e3,
                               [[400, 100, 500], [300, -200, 400]], atol=5e-5)


def test_cli_bad_input_is_one_line(
    tmp_path: Path, irb120: RobotModel, measurements: Measurements, port_m: np.ndarray,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """A non-number in a target file exits 2 with one line naming file, line and column."""
    _write_result(tmp_path / "result.json", irb120, measurements, port_m)
    targets = tmp_path / "targets.csv"
    targets.write_text("x,y,z\n400,abc,500\n")
    out = tmp_path / "corrected.csv"
    assert main(["compensate", "--identified", str(tmp_path / "result.json"),
                 "--targets", str(targets), "--out", str(out)]) == 2
    error = capsys.readouterr().err.strip()
    assert "\n" not in error and "targets.csv: line 2, column y" in error
    assert not out.exists()


def test_cli_verify_geometric_scenario(capsys: pytest.CaptureFixture[str]) -> None:
    """--verify in the twin: compensation with the LM table takes the true flange error from
    millimetres to hundredths of a millimetre on the geometric scenario."""
    scenario = Path(__file__).parent.parent / "scenarios" / "geometric_irb120.toml"
    assert main(["compensate", "--verify", str(scenario), "--count", "200"]) == 0
    rows = capsys.readouterr().out.split("true flange error")[1].splitlines()[1:]
    table = {line[:36].strip(): [float(v) for v in line[36:].split()[:3]] for line in rows}
    nominal_rms = table["nominal joints"][1]
    compensated_rms = table["compensated, identified table"][1]
    assert nominal_rms > 1.0
    assert compensated_rms < 0.05


def test_home_pose_is_the_irb120s_and_within_any_arms_limits() -> None:
    """The reference posture of nominal IK: the IRB 120's (q5 = 30°, the rest 0); for the FR3,
    whose joints 4 and 6 exclude 0, within the limits."""
    from twin.compensation.ik import home_pose
    from twin.io.robot_file import default_robot, load_robot

    np.testing.assert_allclose(home_pose(default_robot()), np.deg2rad([0, 0, 0, 0, 30, 0]))
    fr3 = load_robot(Path(__file__).parents[1] / "models" / "fr3" / "fr3.urdf")
    home = home_pose(fr3)
    assert np.all((fr3.lower_rad <= home) & (home <= fr3.upper_rad))


def test_cli_compensates_a_four_axis_program_for_position(tmp_path: Path) -> None:
    """`twin compensate --joints` on a 4-axis arm: columns q1..q4, every row ok, the identified
    flange at the program's nominal flange position (the orientation is not solved: four joints
    cannot take any pose)."""
    from twin.io.robot_file import load_robot
    from twin.robot import random_poses
    from twin.synthetic import synthesize

    model_file = Path(__file__).parents[1] / "models" / "scara4" / "scara4.toml"
    robot = load_robot(model_file)
    port = np.array([0.6, -0.4, 0.1])
    rng = np.random.default_rng(0)
    true = robot.perturbed(rng.uniform(-1, 1, (4, 4)) * np.where(robot.is_length, 1e-3, 3e-3))
    q = random_poses(robot, 60, rng)
    result = calibrate(robot, synthesize(true, q, port, 1e-5, rng), port, method="lm", seed=0)
    write_json(tmp_path / "result.json", result_to_dict(result))
    program = tmp_path / "program.csv"
    program.write_text("q1,q2,q3,q4\n10,45,-30,20\n-60,-90,40,0\n")
    out = tmp_path / "corrected.csv"
    assert main(["compensate", "--robot", str(model_file), "--identified",
                 str(tmp_path / "result.json"), "--joints", str(program), "--out",
                 str(out)]) == 0
    lines = out.read_text().splitlines()
    assert lines[0] == "q1,q2,q3,q4,status,error_mm"
    assert [line.split(",")[4] for line in lines[1:]] == [STATUS_OK, STATUS_OK]
    corrected = np.deg2rad([[float(v) for v in line.split(",")[:4]] for line in lines[1:]])
    wanted = robot.flange_positions(np.deg2rad([[10, 45, -30, 20], [-60, -90, 40, 0]]))
    np.testing.assert_allclose(result.identified_geometry.flange_positions(corrected), wanted,
                               atol=5e-8)
