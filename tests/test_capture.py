"""Durable capture against the virtual encoder over real ptys, with faults and kills.

Every device here is a `twin virtual-encoder` process serving the MuJoCo twin of a small test
scenario on a pseudo-terminal; `twin capture` reads it with the same drivers as a USB adapter.
Captures run in-process (the CLI's ``main``) unless they must be killed, then as processes.
"""

from __future__ import annotations

import io
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from twin.calibration.pipeline import calibrate
from twin.cli import main
from twin.dataset import REFERENCE, TIME, approach_directions
from twin.errors import InputError, TwinError
from twin.hardware.capture_session import CAPTURE_COLUMNS, HEADER, check_folder, locked, recover
from twin.hardware.robot_sources.file import FileRobot
from twin.hardware.robot_sources.manual import ManualRobot
from twin.io.capture_file import load_capture
from twin.io.measurements import load_measurements, read_table
from twin.units import deg_to_rad, m_to_mm

SCENARIO = """
name = "capture_test"
seed = 11
[port]
position_mm = [600.0, -400.0, 100.0]
[perturbation]
a_mm = 1.0
d_mm = 1.0
alpha_deg = 0.1
theta_deg = 0.1
[poses]
count = 4
[encoder]
sigma_mm = 0.002
resolution_mm = 0.001
[joints]
backlash_arcsec = 20.0
"""
SIDES = ",0.0,0,+1,+1,+1,+1,+1,+1"
"""The t_s, reference and approach columns of a row written by hand."""
SETTLE = ["--settle-k", "4", "--settle-tol", "0.03", "--settle-timeout", "5"]
N_SHORT, N_LONG = 10, 32
TWIN = [sys.executable, "-m", "twin"]


class Device:
    """A `twin virtual-encoder` process; ``url`` waits for the lines it prints. Python's
    faulthandler is on in it, so that a device that does not stop says where it is."""

    def __init__(self, scenario: Path, pose_file: Path, *extra: str) -> None:
        self.pose_file = pose_file
        self.process = subprocess.Popen(
            [sys.executable, "-X", "faulthandler", *TWIN[1:], "virtual-encoder", str(scenario),
             "--pose-file", str(pose_file), *extra],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        self._url: str | None = None

    @property
    def url(self) -> str:
        if self._url is None:
            assert self.process.stdout is not None
            path, url = self.process.stdout.readline(), self.process.stdout.readline()
            assert path.startswith("/dev/"), self.process.stderr.read() if self.process.stderr \
                else path
            self._url = url.strip()
        return self._url

    def stop(self) -> None:
        """SIGTERM, and the device's exit within 10 s; else every thread's stack (SIGABRT, which
        the faulthandler answers) in the failure."""
        self.process.terminate()
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.send_signal(signal.SIGABRT)
            _, error = self.process.communicate(timeout=10)
            raise AssertionError("the virtual encoder did not stop on SIGTERM within 10 s:\n"
                                 + error[-4000:]) from None


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The scenario and plans: N_LONG poses inside 60 % of the joint ranges; its first N_SHORT."""
    folder = tmp_path_factory.mktemp("capture")
    (folder / "scenario.toml").write_text(SCENARIO)
    rng = np.random.default_rng(5)
    limits = np.array([165, 110, 70, 160, 120, 400])
    q_deg = rng.uniform(-0.6 * limits, 0.6 * limits, size=(N_LONG, 6))
    for name, rows in (("plan.csv", q_deg[:N_SHORT]), ("plan_long.csv", q_deg)):
        lines = ["q1,q2,q3,q4,q5,q6"] + [",".join(f"{v:.3f}" for v in row) for row in rows]
        (folder / name).write_text("\n".join(lines) + "\n")
    return folder


@pytest.fixture(scope="module")
def devices(folder: Path) -> dict[str, Device]:
    """The devices of the module, started together (each takes seconds to import MuJoCo)."""
    scenario = folder / "scenario.toml"
    started = {
        "ascii": Device(scenario, folder / "pose_ascii.json"),
        "modbus": Device(scenario, folder / "pose_modbus.json", "--protocol", "modbus"),
        "garbage": Device(scenario, folder / "pose_garbage.json", "--garbage-every", "4"),
        "doomed": Device(scenario, folder / "pose_doomed.json"),
    }
    yield started
    for device in started.values():
        if device.process.poll() is None:
            device.stop()


@pytest.fixture(scope="module")
def true_lengths_mm(folder: Path) -> np.ndarray:
    """The twin's noise-free lengths of the long plan visited in order, shape (N_LONG,), mm."""
    from twin.dataset import approach_directions
    from twin.scenario import load_scenario
    from twin.sim import Twin, simulate

    scenario = load_scenario(folder / "scenario.toml")
    sim = simulate(scenario)
    twin = Twin.build(sim.true_robot, sim.port_m, scenario.physics, sim.joint_errors)
    values, _ = read_table(folder / "plan_long.csv", ("q1", "q2", "q3", "q4", "q5", "q6"), "")
    q_rad = deg_to_rad(values)
    return m_to_mm(twin.lengths(q_rad, approach_directions(q_rad)))


def capture_args(folder: Path, device: Device, out: Path, plan: str = "plan.csv",
                 url: str | None = None) -> list[str]:
    return ["capture", "--plan", str(folder / plan), "--encoder", url or device.url,
            "--robot-source", "sim", "--scenario", str(folder / "scenario.toml"),
            "--pose-file", str(device.pose_file), "--out", str(out), *SETTLE]


def rows(out: Path) -> np.ndarray:
    """The capture's rows (pose, q1..q6, length), as written."""
    path = out / "measurements.csv"
    if path.read_text().count("\n") < 2:
        return np.empty((0, len(CAPTURE_COLUMNS)))
    return read_table(path, CAPTURE_COLUMNS, "")[0]


def wait_for_rows(out: Path, count: int, timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not ((out / "measurements.csv").exists() and len(rows(out)) >= count):
        assert time.monotonic() < deadline, f"fewer than {count} rows after {timeout_s} s"
        time.sleep(0.02)


def times_s(out: Path) -> np.ndarray:
    """The capture's t_s column, shape (rows,), s."""
    return rows(out)[:, CAPTURE_COLUMNS.index(TIME)]


def without_time(out: Path) -> list[list[str]]:
    """The capture's measurement file as cells, its t_s column left out (a clock's reading)."""
    k = CAPTURE_COLUMNS.index(TIME)
    return [line.split(",")[:k] + line.split(",")[k + 1:]
            for line in (out / "measurements.csv").read_text().splitlines()]


def check_complete(out: Path, n: int, true_mm: np.ndarray) -> None:
    """Every plan pose exactly once, in order, each at the twin's length within the noise."""
    table = rows(out)
    assert table[:, 0].tolist() == list(range(1, n + 1))
    assert np.max(np.abs(table[:, CAPTURE_COLUMNS.index("length")] - true_mm[:n])) < 0.01


def test_recover_drops_a_partial_line_and_refuses_a_pose_twice(tmp_path: Path) -> None:
    """A torn last line is truncated away; a repeated pose number is an InputError."""
    path = tmp_path / "measurements.csv"
    assert recover(path, 5, 6) == (set(), None) and path.read_text() == HEADER
    path.write_text(HEADER + "1,0,0,0,0,0,0,500.0" + SIDES + "\n2,0,0,0,0,0,0,501.0" + SIDES
                    + "\n3,0,0,0,0")
    done, note = recover(path, 5, 6)
    assert done == {1, 2} and note is not None and "partial last line" in note
    assert path.read_text().endswith("501.0" + SIDES + "\n")
    path.write_text(HEADER + ("1,0,0,0,0,0,0,500.0" + SIDES + "\n") * 2)
    with pytest.raises(InputError, match="pose 1 a second time"):
        recover(path, 5, 6)
    path.write_text("")
    assert recover(path, 5, 6) == (set(), None) and path.read_text() == HEADER
    path.write_text(HEADER + "7,0,0,0,0,0,0,500.0" + SIDES + "\n")
    with pytest.raises(InputError, match=r"a pose number in 1\.\.5"):
        recover(path, 5, 6)


def test_resume_compares_robot_models_not_their_digits(tmp_path: Path) -> None:
    """A folder whose robot.toml an older twin wrote at full precision resumes with the same
    robot; another robot (a 0.01 mm longer link) is refused."""
    from twin.io.robot_file import default_robot, robot_to_toml

    robot = default_robot()
    plan = tmp_path / "plan.csv"
    plan.write_text("q1,q2,q3,q4,q5,q6\n10,20,-30,40,50,60\n")
    q_rad = deg_to_rad([[10.0, 20.0, -30.0, 40.0, 50.0, 60.0]])
    columns = ", ".join(f"{key} = {value!r}" for key, value in (
        ("a", 0.0), ("d", 290.0), ("alpha", -90.00000000000001), ("theta", 0.0),
        ("lower", -165.00000000000003), ("upper", 165.00000000000003), ("mass", 3.067),
        ("radius", 60.0), ("velocity", 250.00000000000003),
        ("com", [0.09800000000000001, 51.59, -0.12])))
    rows = robot_to_toml(robot).splitlines()
    rows[5] = "  { " + columns + " },"
    (tmp_path / "robot.toml").write_text("\n".join(rows) + "\n")
    check_folder(tmp_path, plan, q_rad, robot)
    other = robot.perturbed(np.r_[0.0, 1e-5, np.zeros(22)])
    with pytest.raises(InputError, match="a capture of another robot model"):
        check_folder(tmp_path, plan, q_rad, other)


@pytest.mark.slow
@pytest.mark.parametrize("protocol", ["ascii", "modbus"])
def test_capture_end_to_end_then_rerun_measures_nothing(
        protocol: str, folder: Path, devices: dict[str, Device], true_lengths_mm: np.ndarray,
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A full capture writes every pose once at the twin's lengths, each with the side every
    joint came from (plan pose K − 1 to K, home first); running it again is a no-op and the
    folder calibrates as a capture (capture.toml, robot.toml, truth.json)."""
    out = tmp_path / "run"
    args = capture_args(folder, devices[protocol], out)
    assert main(args) == 0
    check_complete(out, N_SHORT, true_lengths_mm)
    before = (out / "measurements.csv").read_bytes()
    assert main(args) == 0
    assert "nothing left to measure" in capsys.readouterr().out
    assert (out / "measurements.csv").read_bytes() == before
    capture = load_capture(out / "capture.toml")
    assert capture.truth is not None and capture.truth.exists()
    assert capture.encoder["url"].startswith("serial:///dev/pts/")
    measured = load_measurements(capture.measurements, capture.robot)
    assert len(measured) == N_SHORT and measured.approach is not None
    np.testing.assert_array_equal(measured.approach, approach_directions(measured.q_rad))


@pytest.mark.slow
def test_garbage_bytes_are_retried_and_the_capture_completes(
        folder: Path, devices: dict[str, Device], true_lengths_mm: np.ndarray, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """Every 4th answer is garbage (binary, not a number, partial line): retried, reported."""
    device = devices["garbage"]
    out = tmp_path / "run"
    assert main(capture_args(folder, device, out, url=device.url + "&timeout=0.2")) == 0
    report = capsys.readouterr().out
    assert "retrying" in report and "not ASCII" in report and "partial answer" in report
    check_complete(out, N_SHORT, true_lengths_mm)


@pytest.mark.slow
def test_device_closed_mid_capture_then_resumed(
        folder: Path, devices: dict[str, Device], true_lengths_mm: np.ndarray, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """Unplugging the device stops the capture with a clear message and keeps its rows; the
    same capture against the device back (on a new path) completes every pose once."""
    device = devices["doomed"]
    out = tmp_path / "run"
    args = [*capture_args(folder, device, out), "--settle-interval", "0.05", "--reconnect", "0.3"]
    codes: list[int] = []
    worker = threading.Thread(target=lambda: codes.append(main(args)))
    worker.start()
    wait_for_rows(out, 3)
    device.stop()
    worker.join(timeout=60)
    assert codes == [1]
    error = capsys.readouterr().err
    assert "failed" in error and "run the same command again to resume" in error
    kept = rows(out)
    assert 3 <= len(kept) < N_SHORT
    back = Device(folder / "scenario.toml", device.pose_file)
    try:
        assert main(capture_args(folder, back, out)) == 0
    finally:
        back.stop()
    assert f"resuming at pose {len(kept) + 1}/{N_SHORT}" in capsys.readouterr().out
    check_complete(out, N_SHORT, true_lengths_mm)


@pytest.mark.slow
def test_capture_interrupted_twice_calibrates_like_an_uninterrupted_one(
        folder: Path, devices: dict[str, Device], true_lengths_mm: np.ndarray,
        tmp_path: Path) -> None:
    """A capture process killed by SIGKILL, then one stopped by SIGTERM (as Ctrl-C: it says
    which poses are saved), then one by Ctrl-C (SIGINT), then a final run: every pose exactly
    once, the same file byte for byte as one uninterrupted capture, hence the same calibration;
    and that calibration is real (5x below the nominal RMSE)."""
    device = devices["ascii"]
    whole, pieces = tmp_path / "whole", tmp_path / "pieces"
    assert main(capture_args(folder, device, whole, plan="plan_long.csv")) == 0
    args = capture_args(folder, device, pieces, plan="plan_long.csv")
    kept: list[int] = []
    for stop_at, sig, code in ((8, signal.SIGKILL, -signal.SIGKILL),
                               (14, signal.SIGTERM, 143), (20, signal.SIGINT, 130)):
        process = subprocess.Popen([*TWIN, *args, "--settle-interval", "0.03"],
                                   stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        wait_for_rows(pieces, stop_at)
        process.send_signal(sig)
        output, _ = process.communicate(timeout=30)
        assert process.returncode == code, output
        kept.append(len(rows(pieces)))
        assert kept[-1] < N_LONG
        if sig != signal.SIGKILL:
            assert "interrupted at pose" in output and "run the same command again" in output
            assert not (pieces / ".lock").exists()
    assert main(args) == 0
    check_complete(pieces, N_LONG, true_lengths_mm)
    # Every cell but the clock's as one uninterrupted capture; the clock runs on across each
    # stop and resume (a resumed capture that restarted at 0 would go back at a kept row).
    assert without_time(pieces) == without_time(whole)
    t_s = times_s(pieces)
    assert t_s[0] == 0.0 and np.all(np.diff(t_s) > 0), (kept, t_s)
    results = []
    for out in (whole, pieces):
        capture = load_capture(out / "capture.toml")
        results.append(calibrate(capture.robot, load_measurements(capture.measurements),
                                 capture.port_m))
    assert np.array_equal(results[0].delta, results[1].delta)
    before, after = results[0].metrics["before"].rmse, results[0].metrics["validation"].rmse
    assert after < before / 5


@pytest.mark.slow
def test_second_capture_on_the_same_folder_is_refused(
        folder: Path, devices: dict[str, Device], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """While one capture holds the folder, another exits 2 and writes nothing."""
    out = tmp_path / "run"
    with locked(out):
        assert main(capture_args(folder, devices["ascii"], out)) == 2
    assert f"found another command writing this folder (twin capture, pid {os.getpid()} " \
        in capsys.readouterr().err
    assert not (out / "measurements.csv").exists()


@pytest.mark.slow
def test_resume_with_another_plan_is_refused(
        folder: Path, devices: dict[str, Device], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """A folder started with one plan refuses another: rows are matched to poses by number."""
    out = tmp_path / "run"
    assert main(capture_args(folder, devices["ascii"], out)) == 0
    assert main(capture_args(folder, devices["ascii"], out, plan="plan_long.csv")) == 2
    assert "another plan" in capsys.readouterr().err


@pytest.mark.slow
def test_file_robot_source_records_the_logged_angles(
        folder: Path, devices: dict[str, Device], tmp_path: Path) -> None:
    """With --robot-source file, each row carries the controller's logged angles for its pose."""
    log = tmp_path / "joints.csv"
    values, _ = read_table(folder / "plan.csv", ("q1", "q2", "q3", "q4", "q5", "q6"), "")
    logged = values[:4] + 0.01
    log.write_text("pose,q1,q2,q3,q4,q5,q6\n" + "".join(
        f"{k},{','.join(map(str, row))}\n" for k, row in enumerate(logged, start=1)))
    plan = tmp_path / "plan4.csv"
    plan.write_text("\n".join((folder / "plan.csv").read_text().splitlines()[:5]) + "\n")
    out = tmp_path / "run"
    assert main(["capture", "--plan", str(plan), "--encoder", devices["ascii"].url,
                 "--robot-source", "file", "--joint-log", str(log), "--port", "600,-400,100",
                 "--out", str(out), *SETTLE]) == 0
    assert np.allclose(rows(out)[:, 1:7], logged, atol=1e-9)


def test_file_robot_source_names_a_missing_pose(tmp_path: Path) -> None:
    """A pose the controller has not logged (even in an empty log) is an InputError naming the
    log and the pose once the wait is over."""
    log = tmp_path / "joints.csv"
    robot = FileRobot(log, wait_s=0.0)
    for text in ("", "pose,q1,q2,q3,q4,q5,q6\n"):  # nothing logged yet: keep waiting
        log.write_text(text)
        with pytest.raises(InputError, match="no row for pose 1/2"):
            robot.move_to(1, 2, np.ones(6))
    log.write_text("pose,q1,q2,q3,q4,q5,q6\n1,0,0,0,0,0,0\n")
    assert np.array_equal(robot.move_to(1, 2, np.ones(6)), np.zeros(6))
    with pytest.raises(InputError, match="no row for pose 2/2"):
        robot.move_to(2, 2, np.ones(6))


def test_manual_robot_source_prompts_and_reads_reached_angles() -> None:
    """The prompt shows pose K/N and the target; Enter keeps it, six numbers replace it,
    anything else asks again, and a closed terminal stops the capture."""
    prompts = io.StringIO()
    answers = io.StringIO("\n1 2 3 4 5 6\nabc\n1,2,3\n10, 20, 30, 40, 50, 60\n")
    robot = ManualRobot(prompts, answers)
    target = deg_to_rad([10.0, -20.0, 30.0, 0.0, 45.0, 90.0])
    assert np.array_equal(robot.move_to(1, 3, target), target)
    assert "pose 1/3" in prompts.getvalue() and "10.000 -20.000 30.000" in prompts.getvalue()
    assert np.allclose(robot.move_to(2, 3, target), deg_to_rad([1, 2, 3, 4, 5, 6]))
    assert np.allclose(robot.move_to(3, 3, target), deg_to_rad([10, 20, 30, 40, 50, 60]))
    assert prompts.getvalue().count("try again") == 2
    with pytest.raises(TwinError, match="terminal closed"):
        robot.move_to(3, 3, target)


def _one_port_torso(tmp_path: Path) -> Path:
    """scenarios/geometric_torso.toml with one station (the virtual encoder serves one cable)."""
    source = Path(__file__).parents[1] / "scenarios" / "geometric_torso.toml"
    text = source.read_text().replace("../models", (source.parents[1] / "models").as_posix())
    start, end = text.index("[port.stations_mm]"), text.index("[perturbation]")
    path = tmp_path / "torso.toml"
    path.write_text(text[:start] + "[port]\nposition_mm = [900.0, -500.0, 100.0]\n\n"
                    + text[end:])
    return path


@pytest.mark.slow
@pytest.mark.parametrize("name", ["fr3", "torso"])
def test_a_urdf_arm_captures_with_the_virtual_encoder(tmp_path: Path, name: str) -> None:
    """The FR3 read from its URDF (7 joints), and the FR3 on its torso lift (8, the lift
    prismatic: its column in mm in the plan, the pose file and the journal), simulated: the
    capture writes pose, q1..qN, length, t_s, reference, approach1..N rows at the twin's
    lengths, the URDF beside the robot file, and the capture file reads back as the same
    robot."""
    from twin.io.robot_file import load_robot
    from twin.scenario import load_scenario
    from twin.sim import Twin, simulate
    from twin.units import joints_to_file

    scenario_path = Path(__file__).parents[1] / "scenarios" / "geometric_fr3.toml" \
        if name == "fr3" else _one_port_torso(tmp_path)
    sim = simulate(load_scenario(scenario_path))
    robot, n = sim.robot, sim.robot.n_joints
    q_rad = sim.measurements.q_rad[:5]
    plan = tmp_path / "plan.csv"
    plan.write_text(",".join(f"q{i}" for i in range(1, n + 1)) + "\n" + "".join(
        ",".join(repr(float(v)) for v in row) + "\n"
        for row in joints_to_file(q_rad, robot.prismatic)))
    device = Device(scenario_path, tmp_path / "pose.json")
    out = tmp_path / "cap"
    try:
        assert main(["capture", "--plan", str(plan), "--encoder", device.url,
                     "--robot-source", "sim", "--scenario", str(scenario_path),
                     "--pose-file", str(device.pose_file), "--out", str(out),
                     "--settle-tol", "0.08", "--settle-k", "4"]) == 0
    finally:
        device.stop()
    columns = ("pose", *(f"q{i}" for i in range(1, n + 1)), "length", "t_s", "reference",
               *(f"approach{i}" for i in range(1, n + 1)))
    assert (out / "measurements.csv").read_text().splitlines()[0] == ",".join(columns)
    table = read_table(out / "measurements.csv", columns, "")[0]
    np.testing.assert_allclose(table[:, 1:n + 1], joints_to_file(q_rad, robot.prismatic),
                               rtol=0, atol=1e-9)
    twin = Twin.build(sim.true_robot, sim.port_m)
    true_mm = m_to_mm(twin.lengths(q_rad, approach_directions(q_rad)))
    assert table[:, 0].tolist() == [1, 2, 3, 4, 5]
    # The settled mean of 4 readings of σ = 0.01 mm noise and a dying 0.05 mm swing.
    assert np.max(np.abs(table[:, n + 1] - true_mm)) < 0.05
    urdf = {"fr3": "fr3/fr3.urdf", "torso": "fr3_torso/fr3_torso.urdf"}[name]
    assert (out / "robot.urdf").read_text() == (
        Path(__file__).parents[1] / "models" / urdf).read_text()
    assert load_robot(out / "robot.toml").n_joints == n
    assert load_capture(out / "capture.toml").robot.urdf is not None


EYELET_SCENARIO = """
name = "capture_eyelet"
seed = 12
[port]
position_mm = [600.0, -400.0, 100.0]
[cable]
attachment_mm = [25.0, -15.0, 40.0]
[perturbation]
a_mm = 1.0
d_mm = 1.0
[physics]
compliance = true
stiffness_nm_per_rad = [2e5, 2e5, 2e5, 5e4, 5e4, 5e4]
tension_n = 5.0
[poses]
count = 4
[encoder]
resolution_mm = 0.001
"""


@pytest.mark.slow
def test_the_virtual_rig_hooks_the_cable_on_the_eyelet_and_the_capture_says_so(
        folder: Path, tmp_path: Path) -> None:
    """A scenario's eyelet and cable tension reach the virtual encoder (its lengths are the
    twin's to the eyelet, some millimetres from the flange's) and the capture's capture.toml
    (the told attachment, the tension), so `twin calibrate` on it needs no flag."""
    from twin.dataset import approach_directions
    from twin.scenario import load_scenario
    from twin.sim import Twin, simulate

    scenario_path = tmp_path / "eyelet.toml"
    scenario_path.write_text(EYELET_SCENARIO)
    device = Device(scenario_path, tmp_path / "pose.json")
    try:
        out = tmp_path / "run"
        assert main(["capture", "--plan", str(folder / "plan.csv"), "--encoder", device.url,
                     "--robot-source", "sim", "--scenario", str(scenario_path),
                     "--pose-file", str(device.pose_file), "--out", str(out), *SETTLE]) == 0
    finally:
        device.stop()
    scenario = load_scenario(scenario_path)
    sim = simulate(scenario)
    q_rad = deg_to_rad(rows(out)[:, 1:7])
    approach = approach_directions(q_rad)
    to_eyelet = Twin.build(sim.true_robot, sim.port_m, scenario.physics, sim.joint_errors,
                           sim.rig.attachment_m).lengths(q_rad, approach)
    to_flange = Twin.build(sim.true_robot, sim.port_m, scenario.physics,
                           sim.joint_errors).lengths(q_rad, approach)
    measured_mm = rows(out)[:, CAPTURE_COLUMNS.index("length")]
    assert np.max(np.abs(measured_mm - m_to_mm(to_eyelet))) < 0.01
    assert np.max(np.abs(m_to_mm(to_flange - to_eyelet))) > 1.0
    capture = load_capture(out / "capture.toml")
    np.testing.assert_allclose(capture.rig.attachment_m, [0.025, -0.015, 0.040], atol=1e-9)
    assert capture.rig.tension_n == pytest.approx(5.0)


@pytest.mark.slow
def test_capture_refuses_rig_flags_with_the_scenarios_rig(folder: Path, tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]
                                                           ) -> None:
    """With --robot-source sim the scenario gives the rig: --attachment is a one-line error."""
    assert main(["capture", "--plan", str(folder / "plan.csv"), "--encoder",
                 "serial:///dev/null", "--robot-source", "sim", "--scenario",
                 str(folder / "scenario.toml"), "--attachment", "0,0,40", "--out",
                 str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--attachment with --robot-source sim" in err


PLAN_POSES, EVERY = 25, 5
"""A plan of 25 poses (at least the 24 unknowns) revisiting its first after every 5 others."""


@pytest.mark.slow
def test_plan_revisits_its_first_pose_after_every_n(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """--reference-every 5: the first pose, then 5 others and a revisit, ..., a revisit at the
    end (30 rows), each revisit flagged; the RAPID module visits the same 30 rows; a count
    below 1 is refused naming the flag."""
    plan = ["plan", "--port", "600,-400,100", "--poses", str(PLAN_POSES), "--candidates", "300",
            "--joint-limits-only", "--reference-every", str(EVERY)]
    assert main([*plan, "--out", str(tmp_path / "plan.csv")]) == 0
    values, _ = read_table(tmp_path / "plan.csv", ("q1", "q2", "q3", "q4", "q5", "q6",
                                                   REFERENCE), "")
    q, flag = values[:, :6], values[:, 6]
    assert np.flatnonzero(flag).tolist() == [0, 6, 12, 18, 24, 29]
    assert np.all(q[flag == 1] == q[0])
    assert len(np.unique(q[flag == 0], axis=0)) == PLAN_POSES - 1
    assert not np.any(np.all(q[flag == 0] == q[0], axis=1))
    assert "5 revisits of the first pose, 30 rows" in capsys.readouterr().out
    assert main([*plan, "--out", str(tmp_path / "plan.mod")]) == 0
    assert "jointtarget twin_poses{30} :=" in (tmp_path / "plan.mod").read_text()
    for bad in ("0", "2.5", "x"):
        assert main([*plan[:-2], "--reference-every", bad, "--out",
                     str(tmp_path / "bad.csv")]) == 2
        error = capsys.readouterr().err.strip()
        assert "--reference-every" in error and "\n" not in error and "Traceback" not in error
    assert not (tmp_path / "bad.csv").exists()


@pytest.mark.slow
def test_capture_of_a_plan_with_revisits_times_its_rows_and_tests_drift(
        folder: Path, devices: dict[str, Device], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """A capture of a plan with revisits writes each row's time (from 0, increasing) and the
    plan's reference flags; `twin calibrate` runs the drift test on the reference pose's 6
    readings and, the twin's rig being still, finds no drift; a capture killed after 7 rows
    and resumed goes on counting from the kept rows' time."""
    assert main(["plan", "--port", "600,-400,100", "--poses", str(PLAN_POSES), "--candidates",
                 "300", "--joint-limits-only", "--reference-every", str(EVERY), "--out",
                 str(folder / "plan_revisits.csv")]) == 0
    flags = read_table(folder / "plan_revisits.csv", (REFERENCE,), "")[0][:, 0]
    out = tmp_path / "run"
    args = capture_args(folder, devices["ascii"], out, plan="plan_revisits.csv")
    process = subprocess.Popen([*TWIN, *args, "--settle-interval", "0.03"],
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    wait_for_rows(out, 7)
    process.send_signal(signal.SIGKILL)
    process.communicate(timeout=30)
    kept = times_s(out)
    assert 7 <= len(kept) < len(flags)
    capsys.readouterr()
    assert main(args) == 0
    table = rows(out)
    t_s = table[:, CAPTURE_COLUMNS.index(TIME)]
    assert len(table) == len(flags) == 30
    np.testing.assert_array_equal(t_s[:len(kept)], kept)
    assert t_s[0] == 0.0 and np.all(np.diff(t_s) > 0) and t_s[len(kept)] > kept[-1]
    np.testing.assert_array_equal(table[:, CAPTURE_COLUMNS.index(REFERENCE)], flags)
    capsys.readouterr()
    result = tmp_path / "result.json"
    assert main(["calibrate", str(out / "capture.toml"), "--json", str(result)]) == 0
    report = capsys.readouterr().out
    line = [line for line in report.splitlines() if line.strip().startswith("drift:")]
    assert len(line) == 1 and "1 reference pose(s), 6 readings over" in line[0], report
    assert line[0].endswith("no drift beyond the noise"), line[0]
    drift = json.loads(result.read_text())["drift"]
    assert drift["reference_rows"] == 6 and drift["tests"] == 1 and not drift["drift"]
    (series,) = drift["series"]
    assert sorted(series["rows"]) == np.flatnonzero(flags).tolist()
    np.testing.assert_allclose(series["time_s"], np.sort(t_s[flags == 1]))
    print(line[0], f"t_s {t_s[0]:g}..{t_s[-1]:g} s, {len(kept)} rows kept to {kept[-1]:g} s",
          file=sys.stderr)
