"""`twin import`: bags written here with rosbags' own writers (ROS 2 SQLite and MCAP, ROS 1)
from the twin's simulated data, and CSV files as other tools write them, import to the poses
they hold; every row left out says why."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_typestore

from twin.cli import main
from twin.io.importers import StillRule, import_files
from twin.io.measurements import joint_columns, load_measurements
from twin.io.robot_file import load_robot
from twin.scenario import load_scenario
from twin.sim import simulate
from twin.units import m_to_mm, rad_to_deg

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "geometric_fr3.toml"
N_POSES = 8
RATE_HZ, MOVE_S, STILL_S = 100.0, 1.0, 1.5


def recording(seed: int = 0) -> dict[str, np.ndarray]:
    """The twin's poses and lengths as a robot would be recorded: home still for 1 s without
    readings, then for each pose a 1 s move and a 1.5 s stop, joint states at 100 Hz with
    1e-5 rad of encoder noise, readings at 50 Hz with the instrument's noise, also while
    moving."""
    sim = simulate(load_scenario(SCENARIO))
    q_poses = sim.measurements.q_rad[:N_POSES]
    lengths = sim.measurements.value("length_m")[:N_POSES]
    points = sim.true_robot.flange_positions(q_poses)
    rng = np.random.default_rng(seed)
    t, q, t_read, length, point = [], [], [], [], []
    previous = np.clip(np.zeros(7), sim.robot.lower_rad, sim.robot.upper_rad)
    clock = 0.0
    for _ in np.arange(0, 1.0, 1 / RATE_HZ):  # home, still, no readings
        t.append(clock)
        q.append(previous)
        clock += 1 / RATE_HZ
    for k in range(N_POSES):
        for share in np.arange(1, RATE_HZ * MOVE_S + 1) / (RATE_HZ * MOVE_S):
            t.append(clock)
            q.append(previous + share * (q_poses[k] - previous))
            if len(t) % 2:
                t_read.append(clock)
                length.append(lengths[k] + 0.2)  # the cable swings while the arm moves
                point.append(points[k] + 0.01)
            clock += 1 / RATE_HZ
        for _ in np.arange(0, STILL_S, 1 / RATE_HZ):
            t.append(clock)
            q.append(q_poses[k] + rng.normal(0, 1e-5, 7))
            if len(t) % 2:
                t_read.append(clock)
                length.append(lengths[k] + rng.normal(0, 1e-5))
                point.append(points[k] + rng.normal(0, 1e-5, 3))
            clock += 1 / RATE_HZ
        previous = q_poses[k]
    return {"t": np.array(t), "q": np.array(q), "t_read": np.array(t_read),
            "length": np.array(length), "point": np.array(point), "q_poses": q_poses,
            "lengths": lengths, "points": points, "names": np.array(sim.robot.joint_names)}


def write_bag(path: Path, data: dict[str, np.ndarray], reading: str, ros1: bool = False,
              storage: StoragePlugin = StoragePlugin.SQLITE3) -> None:
    """A bag of /joint_states and one reading topic, with rosbags' writer."""
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    types = store.types
    JointState, Header = types["sensor_msgs/msg/JointState"], types["std_msgs/msg/Header"]
    Time = types["builtin_interfaces/msg/Time"]
    reading_type = {"length": "std_msgs/msg/Float64",
                    "point": "geometry_msgs/msg/PointStamped"}[reading]
    writer = Writer1(path) if ros1 else Writer2(path, version=9, storage_plugin=storage)
    serialize = store.serialize_ros1 if ros1 else store.serialize_cdr
    with writer:
        joints = writer.add_connection("/joint_states", JointState.__msgtype__, typestore=store)
        readings = writer.add_connection(f"/{reading}", reading_type, typestore=store)

        def header(stamp: float) -> object:
            kwargs = {"seq": 0} if ros1 else {}
            return Header(stamp=Time(sec=int(stamp), nanosec=int(stamp % 1 * 1e9)),
                          frame_id="base", **kwargs)

        messages = [(s, joints, JointState(
            header=header(s), name=list(data["names"]), position=q.astype(np.float64),
            velocity=np.zeros(0), effort=np.zeros(0))) for s, q in zip(data["t"], data["q"],
                                                                    strict=True)]
        for stamp, length, point in zip(data["t_read"], data["length"], data["point"],
                                        strict=True):
            if reading == "length":
                message = types["std_msgs/msg/Float64"](data=float(length))
            else:
                message = types["geometry_msgs/msg/PointStamped"](
                    header=header(stamp), point=types["geometry_msgs/msg/Point"](
                        x=float(point[0]), y=float(point[1]), z=float(point[2])))
            messages.append((stamp, readings, message))
        for stamp, connection, message in sorted(messages, key=lambda m: m[0]):
            writer.write(connection, int(stamp * 1e9 + 1e9),
                         serialize(message, connection.msgtype))


@pytest.fixture(scope="module")
def data() -> dict[str, np.ndarray]:
    return recording()


@pytest.mark.slow
@pytest.mark.parametrize("storage", [StoragePlugin.SQLITE3, StoragePlugin.MCAP])
def test_a_ros2_bag_imports_to_the_poses_it_holds(storage: StoragePlugin,
                                                  data: dict[str, np.ndarray],
                                                  tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """A ROS 2 bag (SQLite and MCAP storage) of the FR3's joint states (named as its URDF's
    joints) and cable lengths: `twin import` gives the 8 poses, joints to 1e-5 rad and lengths
    to 1e-5 m of what the bag holds; the home stop without a reading is left out, saying so."""
    bag = tmp_path / "bag"
    write_bag(bag, data, "length", storage=storage)
    out = tmp_path / "imported.csv"
    robot_file = ROOT / "models" / "fr3" / "fr3.urdf"
    assert main(["import", str(bag), "--robot", str(robot_file), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "no /length message inside: dropped" in printed
    assert "imported 8 poses (length)" in printed
    imported = load_measurements(out, load_robot(robot_file))
    assert np.max(np.abs(imported.q_rad - data["q_poses"])) < 1e-5
    assert np.max(np.abs(imported.value("length_m") - data["lengths"])) < 1e-5


@pytest.mark.slow
def test_a_ros1_bag_of_points_imports_to_its_poses(data: dict[str, np.ndarray],
                                                   tmp_path: Path) -> None:
    """A ROS 1 bag with geometry_msgs/PointStamped: the tracker's points, median per stop."""
    bag = tmp_path / "run.bag"
    write_bag(bag, data, "point", ros1=True)
    robot = load_robot(ROOT / "models" / "fr3" / "fr3.urdf")
    imported = import_files([bag], robot, angle_unit=None, rule=StillRule())
    assert np.max(np.abs(imported.measurements.q_rad - data["q_poses"])) < 1e-5
    assert np.max(np.abs(imported.measurements.value("position_m") - data["points"])) < 1e-5


def test_a_bag_without_its_topics_is_one_line(data: dict[str, np.ndarray], tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    """A topic named that the bag lacks: one line listing what it has, exit 2."""
    bag = tmp_path / "bag"
    write_bag(bag, data, "length")
    code = main(["import", str(bag), "--robot", str(ROOT / "models/fr3/fr3.urdf"),
                 "--reading-topic", "/nope", "--out", str(tmp_path / "x.csv")])
    error = capsys.readouterr().err
    assert code == 2 and error.count("\n") == 1 and "topic '/nope' not in the bag" in error
    assert not (tmp_path / "x.csv").exists()


def test_csv_files_in_their_units_import(tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    """Headerless files of radians, one per fixed point (named by their path), and a file with
    the URDF's joint names as columns, degrees and metres; a row that is not numbers and one
    outside the joint limits are left out with the reason."""
    robot_file = ROOT / "models" / "fr3" / "fr3.urdf"
    robot = load_robot(robot_file)
    rng = np.random.default_rng(3)
    q = rng.uniform(robot.lower_rad * 0.5 + robot.upper_rad * 0.5 - 0.3,
                    robot.lower_rad * 0.5 + robot.upper_rad * 0.5 + 0.3, size=(6, 7))
    for placement in ("front", "left"):
        (tmp_path / placement).mkdir()
        for hole in (0, 1):
            rows = [",".join(f"{v:.18e}" for v in row) for row in q[hole * 3:hole * 3 + 3]]
            if hole == 1:
                rows.append("nan," * 6 + "1.0")
            (tmp_path / placement / f"hole_{hole}.csv").write_text("\n".join(rows) + "\n")
    files = sorted(str(p) for p in tmp_path.glob("*/hole_*.csv"))
    out = tmp_path / "points.csv"
    assert main(["import", *files, "--robot", str(robot_file), "--angle-unit", "rad",
                 "--headerless", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert printed.count("a field that is not a finite number: dropped") == 2
    imported = load_measurements(out, robot)
    assert imported.names("point") == ("front/hole_0", "front/hole_1", "left/hole_0", "left/hole_1")
    assert np.bincount(imported.index("point")).tolist() == [3, 3, 3, 3]
    assert np.max(np.abs(imported.q_rad - np.vstack([q, q]))) < 1e-12

    named = tmp_path / "named.csv"
    lines = [",".join([*robot.joint_names, "note", "length"])]
    lines += [",".join([*(f"{v:.9f}" for v in rad_to_deg(row)), "ok", "0.75"]) for row in q]
    lines.append(",".join(["0"] * 7 + ["outside", "0.75"]))  # joint 4 of the FR3 cannot be 0
    named.write_text("\n".join(lines) + "\n")
    assert main(["import", str(named), "--robot", str(robot_file), "--angle-unit", "deg",
                 "--length-unit", "m", "--out", str(tmp_path / "lengths.csv")]) == 0
    assert "fr3_joint4 = 0.000 deg outside" in capsys.readouterr().out
    lengths = load_measurements(tmp_path / "lengths.csv", robot)
    assert np.allclose(m_to_mm(lengths.value("length_m")), 750.0) and len(lengths) == 6


@pytest.mark.parametrize("delimiter", [";", "\t"])
def test_a_spreadsheets_csv_imports_as_the_comma_one(tmp_path: Path, delimiter: str,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """A spreadsheet's export where the decimal mark is a comma (fields separated by semicolons,
    or tabs) imports to the same poses and lengths as the comma-separated file of the same
    numbers; a field with both marks (1.234,5) is not a number: the row is left out."""
    robot = load_robot(ROOT / "models" / "irb120.toml")
    rng = np.random.default_rng(8)
    q_deg = rad_to_deg(rng.uniform(robot.lower_rad * 0.8, robot.upper_rad * 0.8, size=(5, 6)))
    lengths_mm = rng.uniform(400.0, 1200.0, 5)
    rows = [[f"{v:.9f}" for v in [*q, length]] for q, length in zip(q_deg, lengths_mm,
                                                                      strict=True)]
    header = [*joint_columns(6), "length"]
    (tmp_path / "comma.csv").write_text("\n".join(",".join(r) for r in [header, *rows]) + "\n")
    local = [[v.replace(".", ",") for v in r] for r in rows]
    local.append(["1.234,5", *local[0][1:]])
    (tmp_path / "local.csv").write_text("# exported\n" + "\n".join(
        delimiter.join(r) for r in [header, *local]) + "\n")
    for name in ("comma", "local"):
        assert main(["import", str(tmp_path / f"{name}.csv"), "--angle-unit", "deg",
                     "--out", str(tmp_path / f"{name}_out.csv")]) == 0
    assert "local.csv: line 8: a field that is not a finite number: dropped" in \
        capsys.readouterr().out
    comma, local_read = (load_measurements(tmp_path / f"{name}_out.csv", robot)
                         for name in ("comma", "local"))
    np.testing.assert_array_equal(local_read.q_rad, comma.q_rad)
    np.testing.assert_array_equal(local_read.value("length_m"), comma.value("length_m"))
    np.testing.assert_allclose(rad_to_deg(comma.q_rad), q_deg, rtol=0, atol=1e-9)
