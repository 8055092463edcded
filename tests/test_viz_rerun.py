"""Rerun recordings of `twin simulate` and `twin calibrate`, read back with Rerun's own reader.

A short capture is simulated by the MuJoCo twin and calibrated with ``--rerun-save``; the
``.rrd`` is read with ``rerun.chunk.RrdReader`` and every entity family is checked against the
core's own numbers (FK, residuals, history), the exact values bit for bit.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
import urllib.request
import warnings
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pytest
from conftest import free_port
from rerun.chunk import RrdReader

from twin.calibration.pipeline import calibrate_many
from twin.calibration.result import CalibrationResult
from twin.cli import main
from twin.geometry.kinematics import Structure, frames
from twin.io.capture_file import load_capture
from twin.io.measurements import load_measurements
from twin.io.results import MM2_PER_M2
from twin.io.truth import load_truth_delta
from twin.units import DH_KEYS, dh_rows_to_display, m_to_mm
from twin.viz import entities
from twin.viz.options import RerunOptions
from twin.viz.recording import open_recording
from twin.viz.sinks import rerun_executable

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "geometric_irb120.toml"
SERVE_START_SECONDS = 60.0
"""Generous bound on a subprocess coming up on a loaded 2-core machine (not a timing test)."""


def read_rrd(path: Path) -> dict[str, list[pa.RecordBatch]]:
    """Every chunk of the first recording in an .rrd, as record batches by entity path."""
    batches: dict[str, list[pa.RecordBatch]] = defaultdict(list)
    for chunk in RrdReader(path).stream().to_chunks():
        batches[chunk.entity_path.lstrip("/")].append(chunk.to_record_batch())
    return batches


def column(batches: dict[str, list[pa.RecordBatch]], path: str, name: str) -> list[Any]:
    """All values of one column of an entity, in row order of its timeline (if any)."""
    rows: list[tuple[int, Any]] = []
    for batch in batches[path]:
        if name not in batch.schema.names:
            continue
        index = next((t for t in (entities.POSE_TIMELINE, entities.ITERATION_TIMELINE)
                      if t in batch.schema.names), None)
        keys = batch.column(index).to_pylist() if index else [0] * batch.num_rows
        rows += zip(keys, batch.column(name).to_pylist(), strict=True)
    assert rows, f"{path} has no column {name}"
    return [value for _, value in sorted(rows, key=lambda row: row[0])]


def scalars(batches: dict[str, list[pa.RecordBatch]], path: str) -> np.ndarray:
    """The float64 values of an entity's ``Scalars``, one per row (or the whole batch if static)."""
    values = column(batches, path, "Scalars:scalars")
    return np.array([v for row in values for v in row], dtype=np.float64)


def text(batches: dict[str, list[pa.RecordBatch]], path: str, name: str) -> str:
    """The one string of a static text component (a component batch of one)."""
    (value,) = column(batches, path, name)[0]
    return str(value)


@pytest.fixture(scope="module")
def capture(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A capture simulated by `twin simulate` (MuJoCo twin), with a recording of it."""
    out = tmp_path_factory.mktemp("sim")
    assert main(["simulate", str(SCENARIO), "--out", str(out),
                 "--rerun-save", str(out / "simulate.rrd")]) == 0
    return out / "capture.toml"


@pytest.fixture(scope="module")
def calibrated(capture: Path) -> tuple[Path, CalibrationResult]:
    """`twin calibrate --rerun-save` on the capture, and the same calibration by the API."""
    rrd = capture.parent / "calibrate.rrd"
    assert main(["calibrate", str(capture), "--rerun-save", str(rrd)]) == 0
    loaded = load_capture(capture)
    measurements = load_measurements(loaded.measurements, loaded.robot)
    result = calibrate_many(loaded.robot, measurements, loaded.port_m, ["lm"], seed=0)["lm"]
    return rrd, result


def test_simulate_recording_has_the_scene(capture: Path) -> None:
    """`twin simulate --rerun-save` logs nominal and true robots per pose, port and cable."""
    batches = read_rrd(capture.parent / "simulate.rrd")
    loaded = load_capture(capture)
    measurements = load_measurements(loaded.measurements, loaded.robot)
    truth = load_truth_delta(loaded.truth, 6) if loaded.truth else None
    assert truth is not None
    for label in ("nominal", "true"):
        strips = column(batches, entities.robot(label), "LineStrips3D:strips")
        assert len(strips) == len(measurements)
    true_flange = loaded.robot.perturbed(truth).flange_positions(measurements.q_rad)
    cable = np.array([row[0] for row in column(batches, entities.CABLE, "LineStrips3D:strips")])
    np.testing.assert_allclose(cable[:, 1], true_flange, atol=1e-6)  # float32 positions
    assert "# Measurements of ABB IRB 120" in text(batches, entities.REPORT, "TextDocument:text")


def test_every_family_round_trips(calibrated: tuple[Path, CalibrationResult],
                                  capture: Path) -> None:
    """Every family of the layout holds the core's numbers; the exact values bit for bit."""
    rrd, result = calibrated
    batches = read_rrd(rrd)
    loaded = load_capture(capture)
    measurements = load_measurements(loaded.measurements, loaded.robot)
    assert loaded.truth is not None
    truth = load_truth_delta(loaded.truth, 6)
    q = measurements.q_rad
    n_poses = len(measurements)

    # world/robot: one polyline per pose, the frame origins of the core's FK.
    for label, dh in (("nominal", result.robot.dh), ("true", result.robot.dh + truth),
                      ("identified/lm", result.identified_geometry.dh)):
        strips = np.array([row[0] for row in column(batches, entities.robot(label),
                                                    "LineStrips3D:strips")])
        assert strips.shape == (n_poses, 7, 3)
        np.testing.assert_array_equal(strips, frames(Structure.standard(6), dh, q).origins
                                      .astype(np.float32))
    # world/port and world/cable: port to the true flange, labelled with the measured length.
    port = np.array(column(batches, entities.PORT, "Points3D:positions")[0])
    np.testing.assert_array_equal(port, [loaded.port_m.astype(np.float32)])
    labels = column(batches, entities.CABLE, "LineStrips3D:labels")
    first_length_mm = float(m_to_mm(measurements.value("length_m")[0]))
    assert len(labels) == n_poses and labels[0] == [f"L = {first_length_mm:.3f} mm"]
    # residuals: per pose, before (nominal) and after, in mm, float64.
    before = result.model.residuals(np.zeros(result.model.n_params), measurements)
    after = result.model.residuals(result.solver.x, measurements)
    np.testing.assert_array_equal(scalars(batches, entities.RESIDUALS_BEFORE), m_to_mm(before))
    np.testing.assert_array_equal(scalars(batches, entities.residuals_after("lm")), m_to_mm(after))
    assert np.sqrt(np.mean(after**2)) < 0.1 * np.sqrt(np.mean(before**2))
    # convergence: f [mm²] and RMSEs [mm] on the iteration timeline.
    history = result.solver.history
    np.testing.assert_array_equal(scalars(batches, entities.convergence("lm", "f")),
                                  np.array([r.f_m2 for r in history]) * MM2_PER_M2)
    np.testing.assert_array_equal(
        scalars(batches, entities.convergence("lm", "validation_rmse")),
        m_to_mm([r.validation_rmse_m for r in history]))
    iterations = [i for b in batches[entities.convergence("lm", "train_rmse")]
                  if entities.ITERATION_TIMELINE in b.schema.names
                  for i in b.column(entities.ITERATION_TIMELINE).to_pylist()]
    assert sorted(iterations) == list(range(len(history)))
    # parameters: bars in mm/deg, exact values in SI, bit for bit.
    for method, delta in (("lm", result.delta), (None, truth)):
        display = dh_rows_to_display(delta)
        for key in DH_KEYS:
            (bars,) = column(batches, entities.parameter_bars(method, key), "BarChart:values")[0]
            np.testing.assert_array_equal(bars["buffer"], display[key])
    identified = scalars(batches, entities.parameter_exact("lm"))
    assert identified.tobytes() == np.asarray(result.solver.x, dtype=np.float64).tobytes()
    true_values = scalars(batches, entities.parameter_exact(None))
    assert true_values.tobytes() == truth.ravel().tobytes()
    names = column(batches, entities.parameter_exact(None), "names")[0]
    assert names[:2] == ["a1", "a2"] and len(names) == 24
    # report: markdown with metrics, truth and identifiability.
    report = text(batches, entities.REPORT, "TextDocument:text")
    assert text(batches, entities.REPORT, "TextDocument:media_type") == "text/markdown"
    for part in ("## Metrics", "after, validation", "## Against the truth", "## Identifiability",
                 "rank **19 of 24**"):
        assert part in report
    # and a default blueprint, stored beside the recording.
    assert RrdReader(rrd).blueprints()


def test_each_method_has_its_convergence(capture: Path, tmp_path: Path) -> None:
    """Several methods on one split: one convergence/<method> family and one identified robot each.

    Also: extra timelines (a study's ``case``) are stamped on every row.
    """
    loaded = load_capture(capture)
    measurements = load_measurements(loaded.measurements, loaded.robot)
    results = calibrate_many(loaded.robot, measurements, loaded.port_m, ["lm", "amlm"], seed=1)
    path = tmp_path / "two.rrd"
    with open_recording(RerunOptions(save=path), "study") as recording:
        for case in range(2):
            recording.log_calibration(results, measurements, times={"case": case})
    batches = read_rrd(path)
    for method, result in results.items():
        f = scalars(batches, entities.convergence(method, "f"))
        expected = np.array([r.f_m2 for r in result.solver.history]) * MM2_PER_M2
        np.testing.assert_array_equal(f, np.repeat(expected, 2))  # cases 0 and 1 per iteration
        assert entities.robot(entities.identified_label(method)) in batches
    assert entities.robot("true") not in batches and "parameters/true/exact" not in batches
    cases = {value for batch in batches[entities.REPORT] for value in
             batch.column("case").to_pylist()}
    assert cases == {0, 1}


def test_spawn_without_display_saves_a_file(
    calibrated: tuple[Path, CalibrationResult], capture: Path, tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
) -> None:
    """--rerun-spawn with no display says so and saves beside the --json output instead."""
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    out = tmp_path / "out"
    assert main(["calibrate", str(capture), "--rerun-spawn", "--json",
                 str(out / "result.json")]) == 0
    err = capsys.readouterr().err
    assert "cannot spawn the viewer: no display" in err
    (saved,) = out.glob("twin-calibrate-*.rrd")
    assert str(saved) in err
    assert entities.REPORT in read_rrd(saved)
    assert not list(out.glob(".*.tmp"))


def test_bad_port_is_a_usage_error(capture: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A port outside 1..65535 is refused by the parser with exit code 2 and one line naming
    the flag and the value."""
    assert main(["calibrate", str(capture), "--rerun-serve", "--rerun-web-port", "70000"]) == 2
    assert capsys.readouterr().err == ("twin: error: --rerun-web-port: found '70000', expected "
                                       "a TCP port in 1..65535\n")


@pytest.mark.slow
def test_the_program_leaves_its_recording_whole(calibrated: tuple[Path, CalibrationResult],
                                                tmp_path: Path) -> None:
    """`python -m twin calibrate --rerun-save` — the program, which exits without the
    interpreter's last garbage collection (:func:`twin.cli.run`) — writes every entity, row
    for row, that the same command called in this process writes: nothing Rerun writes out as
    the process ends is lost."""
    rrd, _ = calibrated
    program = tmp_path / "program.rrd"
    done = subprocess.run([sys.executable, "-m", "twin", "calibrate",
                           str(rrd.parent / "capture.toml"), "--rerun-save", str(program)],
                          capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr

    def rows(path: Path) -> dict[str, int]:
        return {entity: sum(batch.num_rows for batch in batches)
                for entity, batches in read_rrd(path).items()}

    assert rows(program) == rows(rrd) and "report" in rows(rrd)


@pytest.mark.slow
def test_cli_does_not_import_rerun_without_a_flag(capture: Path) -> None:
    """Building the CLI and calibrating without --rerun-* never loads rerun."""
    code = (
        "import sys\nfrom twin.cli import main\n"
        f"assert main(['calibrate', {str(capture)!r}]) == 0\n"
        "assert 'rerun' not in sys.modules, 'rerun was imported'\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=False)
    assert done.returncode == 0, done.stderr


@pytest.mark.slow
@pytest.mark.skipif(rerun_executable() is None, reason="needs the rerun executable")
def test_serve_prints_the_url_and_serves_until_interrupted(capture: Path, tmp_path: Path) -> None:
    """--rerun-serve: URL on stderr, web viewer and data on 127.0.0.1, clean exit on Ctrl-C."""
    web_port, grpc_port = free_port(), free_port()
    twin = Path(sys.executable).with_name("twin")
    server = subprocess.Popen(
        [str(twin), "calibrate", str(capture), "--rerun-serve", "--rerun-web-port",
         str(web_port), "--rerun-grpc-port", str(grpc_port)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    client = None
    try:
        assert server.stderr is not None
        lines = []
        while not any("press Ctrl-C" in line for line in lines):
            line = server.stderr.readline()
            assert line, "".join(lines)
            lines.append(line)
        url = f"http://127.0.0.1:{web_port}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{grpc_port}"
        assert url in "".join(lines)
        with urllib.request.urlopen(f"http://127.0.0.1:{web_port}/", timeout=30) as page:
            assert page.status == 200 and b"<html" in page.read().lower()
        # A real viewer-side client: the rerun CLI reads the served stream into a file.
        saved = tmp_path / "served.rrd"
        client = subprocess.Popen(
            [str(rerun_executable()), f"rerun+http://127.0.0.1:{grpc_port}/proxy", "--save",
             str(saved), "--bind", "127.0.0.1", "--port", str(free_port())],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
        )
        deadline = time.monotonic() + SERVE_START_SECONDS
        received: set[str] = set()
        while entities.REPORT not in received and time.monotonic() < deadline:
            time.sleep(0.5)
            try:
                with warnings.catch_warnings():  # a file being streamed has no footer yet
                    warnings.simplefilter("ignore")
                    received = set(read_rrd(saved))
            except Exception:  # a chunk is still being written
                continue
        assert {entities.REPORT, entities.robot("nominal"), entities.parameter_exact("lm")} <= \
            received
        server.send_signal(signal.SIGINT)
        _, err = server.communicate(timeout=SERVE_START_SECONDS)
        assert server.returncode == 0, err
        assert "stopped serving" in err
    finally:
        if client is not None:
            os.killpg(client.pid, signal.SIGTERM)
            client.wait(timeout=30)
        if server.poll() is None:
            server.kill()
            server.wait()
    for port in (web_port, grpc_port):
        with socket.socket() as probe:  # the server we started is gone: nothing listens
            assert probe.connect_ex(("127.0.0.1", port)) != 0


def test_an_arm_from_a_urdf_with_hayati_joints_records(tmp_path: Path) -> None:
    """Any arm records: a UR5e read from its URDF (Hayati joints 2 and 3) simulated and
    calibrated with --rerun-save shows each robot as its frame origins 0..6 (and the flange
    when the tool transform moves it), and its table errors as bars in their own units — d in
    mm, the Hayati β apart in degrees — true and identified alike."""
    out = tmp_path / "ur5e"
    assert main(["simulate", str(ROOT / "scenarios" / "geometric_ur5e.toml"), "--out",
                 str(out)]) == 0
    rrd = tmp_path / "ur5e.rrd"
    assert main(["calibrate", str(out / "capture.toml"), "--rerun-save", str(rrd)]) == 0
    loaded = load_capture(out / "capture.toml")
    robot = loaded.robot
    assert loaded.truth is not None
    truth = load_truth_delta(loaded.truth, 6, robot.is_length)
    batches = read_rrd(rrd)
    measurements = load_measurements(loaded.measurements, robot)
    strips = np.array([row[0] for row in column(batches, entities.robot("true"),
                                                "LineStrips3D:strips")])
    chain = frames(robot.structure, robot.dh + truth, measurements.q_rad)
    expected = np.concatenate([chain.origins, chain.flange[..., None, :3, 3]], axis=-2) \
        if np.linalg.norm(robot.structure.tool[:3, 3]) > 1e-9 else chain.origins
    np.testing.assert_allclose(strips, expected.astype(np.float32), atol=1e-6)
    hayati = ~robot.is_length[1]
    (beta,) = column(batches, entities.parameter_bars(None, "beta"), "BarChart:values")[0]
    (d,) = column(batches, entities.parameter_bars(None, "d"), "BarChart:values")[0]
    np.testing.assert_allclose(np.asarray(beta["buffer"])[hayati], np.rad2deg(truth[1, hayati]))
    np.testing.assert_allclose(np.asarray(d["buffer"])[~hayati], truth[1, ~hayati] * 1e3)
    assert not np.any(np.asarray(d["buffer"])[hayati])
    assert column(batches, entities.parameter_bars("lm", "beta"), "BarChart:values")
