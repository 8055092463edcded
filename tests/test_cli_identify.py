"""`twin identify`, `twin plan`, and the identifiability and σ fields of `twin calibrate --json`."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

from twin.cli import main
from twin.io.capture_file import write_capture
from twin.io.measurements import read_table
from twin.io.robot_file import load_robot, robot_to_toml
from twin.robot import RobotModel
from twin.units import dh_rows_to_display

PORT = "600,-400,100"


@pytest.mark.slow
def test_identify_reports_rank_names_and_sigma(
    csv_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The report has rank 19 of 24 with the named directions, the bound, a σ table with —
    for the dependent unknowns; the JSON and the PNG map are written and read back."""
    out, png = tmp_path / "id.json", tmp_path / "map.png"
    assert main(["identify", str(csv_path), "--port", PORT, "--json", str(out),
                 "--map", str(png)]) == 0
    printed = capsys.readouterr().out
    assert "rank 19 of 24" in printed
    for name in ("theta6", "alpha6", "d2-d3", "Cramér–Rao", "σ theta [deg]", "—"):
        assert name in printed
    document = json.loads(out.read_text())
    nominal = document["nominal"]
    assert (nominal["rank"], nominal["parameters"], nominal["at"]) == (19, 24, "nominal")
    assert {"theta6", "alpha6", "d2-d3"} <= set(nominal["unidentifiable"])
    assert set(nominal["observability"]) == {"o1", "o3", "o4", "condition"}
    assert 0 < nominal["cramer_rao_flange_rms"] < 0.05
    assert document["calibration"]["method"] == "lm"
    image = imread(png)
    assert image.ndim == 3 and image.shape[0] > 200 and image.shape[1] > 200


def test_identify_reads_a_capture_with_the_unknown_port_and_offset(
    csv_path: Path, tmp_path: Path, irb120: RobotModel, port_m: np.ndarray,
    true_delta: np.ndarray, capsys: pytest.CaptureFixture[str],
) -> None:
    """A capture.toml needs no --port; port and offset unknown give rank 21 of 28 with
    d1+port_z among the unidentifiable directions. With its truth file, the true flange error
    is printed beside the prediction, and is within a factor of 3 of it."""
    (tmp_path / "robot.toml").write_text(robot_to_toml(irb120))
    (tmp_path / "truth.json").write_text(json.dumps({"delta": dh_rows_to_display(true_delta)}))
    capture = tmp_path / "capture.toml"
    write_capture(capture, robot="robot.toml", port_m=port_m, measurements=csv_path.name,
                  truth="truth.json")
    assert main(["identify", str(capture)]) == 0
    printed = capsys.readouterr().out
    predicted = float(re.search(r"predicted flange RMS error over the workspace (\S+)",
                                printed).group(1))
    true = float(re.search(r"true flange RMS error over the workspace (\S+)", printed).group(1))
    assert predicted / 3 < true < 3 * predicted
    assert main(["identify", str(capture), "--estimate-port", "--estimate-offset"]) == 0
    printed = capsys.readouterr().out
    assert "rank 21 of 28" in printed and "d1+port_z" in printed


def test_calibrate_json_carries_identifiability_and_sigma(
    csv_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`calibrate --json`: identifiability at the nominal geometry (rank 19 of 24), σ in mm and
    degrees with null for the unidentifiable unknowns, the noise estimate and the predicted
    flange accuracy; the printed report has the identifiability lines."""
    out = tmp_path / "result.json"
    assert main(["calibrate", str(csv_path), "--port", PORT, "--method", "lm-base",
                 "--json", str(out)]) == 0
    assert "rank 19 of 24" in capsys.readouterr().out
    document = json.loads(out.read_text())
    ident = document["identifiability"]
    assert (ident["rank"], ident["parameters"], ident["at"]) == (19, 24, "nominal")
    assert ident["condition"] > 1
    assert {"theta6", "alpha6", "d2-d3"} <= set(ident["unidentifiable"])
    assert document["identifiability_identified"]["at"] == "identified"
    sigma = document["sigma"]
    assert set(sigma) == {"a", "d", "alpha", "theta"}
    # alpha6 never moves the flange centre, and theta6 only as weakly as these data cannot
    # tell it from zero: held entirely, they have no σ; the other unseen directions are
    # combinations, and each unknown in them has the σ of the held estimate.
    assert sigma["alpha"][5] is None and sigma["theta"][5] is None
    assert sum(v is None for values in sigma.values() for v in values) == 2
    # Joint 5's a, d, alpha, theta are seen only weakly (a5+theta5, d5-alpha5): about 1 mm, 1°.
    assert all(0 < v < 2.0 for values in sigma.values() for v in values if v is not None)
    assert 0.005 < document["noise_sigma"] < 0.02
    assert 0 < document["predicted_flange_rms"] < 0.05


def test_calibrate_estimate_port_and_offset_from_the_cli(
    csv_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`--estimate-port --estimate-offset`: the JSON has the identified port and offset near
    the true ones (the data's port is the nominal one, zero offset) and their σ; the port's
    turn about joint 1's axis and shift along it trade with δθ1 and δd1, which stay at the
    nominal, so the port is the true one modulo that motion (its distance from the axis)."""
    out = tmp_path / "result.json"
    assert main(["calibrate", str(csv_path), "--port", PORT, "--estimate-port",
                 "--estimate-offset", "--json", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "identified port" in printed and "identified length offset" in printed
    document = json.loads(out.read_text())
    assert document["identifiability"]["rank"] == 21
    assert abs(document["offset"]) < 5 * document["sigma"]["offset"]
    assert len(document["sigma"]["port"]) == 3
    port = np.array(document["port"])
    assert np.hypot(*port[:2]) == pytest.approx(np.hypot(600, -400), abs=2.0)
    assert abs(document["delta"]["theta"][0]) < 1e-4 and abs(document["delta"]["d"][0]) < 1e-3


def test_plan_writes_poses_that_beat_random_ones(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], irb120: RobotModel
) -> None:
    """`twin plan`: a CSV of N poses (q1..q6, degrees, within the limits) and a table where the
    planned poses predict a lower flange error than as many random ones; with several ports
    the one of lowest predicted error is chosen."""
    out = tmp_path / "plan.csv"
    assert main(["plan", "--port", PORT, "--port", "20000,0,300", "--poses", "30",
                 "--candidates", "600", "--joint-limits-only", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    q_deg, _ = read_table(out, tuple(f"q{i}" for i in range(1, 7)), "plan")
    assert q_deg.shape == (30, 6)
    assert np.all(np.deg2rad(q_deg) >= irb120.lower_rad - 1e-9)
    assert np.all(np.deg2rad(q_deg) <= irb120.upper_rad + 1e-9)
    planned = float(re.search(r"planned(?:\s+\S+){4}\s+(\S+)", printed).group(1))
    drawn = float(re.search(r"random(?:\s+\S+){4}\s+(\S+)", printed).group(1))
    assert planned < drawn
    assert re.search(r"\(600, -400, 100\)\s+\S+\s+<- chosen", printed)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["plan", "--port", PORT, "--poses", "5", "--out", "{tmp}/p.csv"], "--poses: found 5"),
        (["plan", "--port", "1,2", "--poses", "30", "--out", "{tmp}/p.csv"], "--port"),
        (["identify", "{csv}"], "found no --port"),
        (["identify", "{csv}", "--port", PORT, "--sigma", "0"], "--sigma"),
    ],
)
def test_user_mistakes_exit_2_with_one_line(
    argv: list[str], message: str, csv_path: Path, tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Exit code 2, one line on stderr naming the flag or file, nothing written."""
    code = main([a.format(tmp=tmp_path, csv=csv_path) for a in argv])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("twin: error: ") and message in err, err
    assert not (tmp_path / "p.csv").exists()


def test_feasible_plan_passes_the_twins_own_pose_check(
    tmp_path: Path, irb120: RobotModel, port_m: np.ndarray, capsys: pytest.CaptureFixture[str]
) -> None:
    """`twin plan` draws candidates with the MuJoCo twin's constraints by default: the plan it
    writes is accepted by the twin's plan reader (floor, collisions, cable range and path)."""
    from twin.scenario import PoseConstraints
    from twin.sim import read_pose_plan
    from twin.sim.mujoco_twin import Twin

    out = tmp_path / "plan.csv"
    assert main(["plan", "--port", PORT, "--poses", "30", "--candidates", "400",
                 "--out", str(out)]) == 0
    assert "feasible candidates" in capsys.readouterr().out
    q = read_pose_plan(out, Twin.build(irb120, port_m), PoseConstraints())
    assert q.shape == (30, 6)


def test_plan_a_seven_axis_urdf(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`twin plan --robot fr3.urdf` plans for the 28 unknowns of a 7-axis arm: q1..q7 within
    the FR3's limits (its joints 4 and 6 exclude 0), among poses the twin can measure."""
    robot_path = Path(__file__).parents[1] / "models" / "fr3" / "fr3.urdf"
    out = tmp_path / "plan.csv"
    assert main(["plan", "--robot", str(robot_path), "--port", PORT, "--poses", "40",
                 "--candidates", "300", "--out", str(out)]) == 0
    assert "28 unknowns" in capsys.readouterr().out
    q_deg, _ = read_table(out, tuple(f"q{i}" for i in range(1, 8)), "plan")
    robot = load_robot(robot_path)
    q_rad = np.deg2rad(q_deg)
    assert q_rad.shape == (40, 7)
    assert np.all((robot.lower_rad <= q_rad) & (q_rad <= robot.upper_rad))


def test_identify_states_calibrates_noise_and_no_flange_it_cannot_pin(
    csv_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """identify runs calibrate's default method, so both state the same noise estimate; with the
    attachment estimated the data do not pin the flange, and identify states the bound and the
    prediction of the measured point, never a flange figure (its JSON has no flange bound)."""
    out = tmp_path / "id.json"
    flags = ["--port", PORT, "--estimate-attachment"]
    assert main(["identify", str(csv_path), *flags, "--json", str(out)]) == 0
    identified = capsys.readouterr().out
    assert main(["calibrate", str(csv_path), *flags]) == 0
    calibrated = capsys.readouterr().out
    noise = re.compile(r"noise estimate (\S+ mm)")
    assert noise.findall(identified) == noise.findall(calibrated)
    assert "flange RMS" not in identified
    assert "Cramér–Rao bound at σ = 0.01 mm: RMS error of the measured point" in identified
    assert "predicted RMS error of the measured point" in identified
    nominal = json.loads(out.read_text())["nominal"]
    assert nominal["cramer_rao_flange_rms"] is None and nominal["cramer_rao_point_rms"] > 0
    assert main(["identify", str(csv_path), "--port", PORT, "--method", "all"]) == 2
    assert "--method" in capsys.readouterr().err
