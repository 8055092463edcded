"""RAPID modules in and out: the reader on hand-written modules, the plan module parsed back, and
program filtering held to the twin's truth: a module's targets, compensated, read back by this
test's own reader, solved by this test's own controller model and run on the twin's true robot."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from conftest import Refusals
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from twin.cli import main
from twin.compensation.configuration import configuration
from twin.compensation.poses import controller_tool0
from twin.compensation.targets import reachable_targets
from twin.io.rapid import format_number, parse_module, rewrite
from twin.io.rapid_filter import find_targets
from twin.io.robot_file import default_robot
from twin.io.truth import load_truth_delta
from twin.io.urdf_reader import load_urdf
from twin.robot import RobotModel

ROOT = Path(__file__).resolve().parents[1]
NO_AXES = "[9E9,9E9,9E9,9E9,9E9,9E9]"
AGGREGATE = re.compile(r"(robtarget|jointtarget)\s+(\w+)\s*:=\s*(\[[^;]*\]);")
INLINE = re.compile(r"(MoveL|MoveJ)\s+(\[\[[^;]*?\]\]),")
NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")


# -- this test's own RAPID reader and controller -------------------------------------------------

def read_targets(text: str) -> dict[str, list]:
    """Every declared robtarget/jointtarget literal by name, as nested lists (a RAPID
    aggregate of numbers is JSON)."""
    return {name: json.loads(value) for _, name, value in AGGREGATE.findall(text)}


def quaternion_matrix(q_wxyz: list[float]) -> np.ndarray:
    return Rotation.from_quat(np.asarray(q_wxyz) / np.linalg.norm(q_wxyz),
                              scalar_first=True).as_matrix()


def pose(trans_mm: list[float], q_wxyz: list[float]) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = quaternion_matrix(q_wxyz), np.asarray(trans_mm) / 1000.0
    return T


def abb_configuration(robot: RobotModel, q: np.ndarray) -> list[int]:
    """cf1, cf4, cf6, cfx from the D-H frames of a standard table, as ABB's manual states them:
    the wrist centre in frame 1 (x < 0: behind axis 1) and in frame 2 (y < 0: behind the lower
    arm), the sign of axis 5."""
    def link(i: int) -> np.ndarray:
        a, d, alpha, theta = robot.dh[:, i]
        ct, st, ca, sa = np.cos(q[i] + theta), np.sin(q[i] + theta), np.cos(alpha), np.sin(alpha)
        return np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st],
                         [0, sa, ca, d], [0, 0, 0, 1]])
    T = [link(i) for i in range(6)]
    wrist = np.append((T[0] @ T[1] @ T[2] @ T[3] @ T[4])[:3, 3], 1.0)
    a = int(np.linalg.solve(T[0], wrist)[0] < 0)
    b = int(np.linalg.solve(T[0] @ T[1], wrist)[1] < 0)
    quarter = [int(np.floor(q[j] / (np.pi / 2))) for j in (0, 3, 5)]
    return [*quarter, 4 * a + 2 * b + int(q[4] < 0)]


def controller_joints(robot: RobotModel, base_T_flange: np.ndarray, seed: np.ndarray
                      ) -> np.ndarray:
    """What a controller holding the nominal model commands for a flange pose: its joints,
    solved here by scipy from a seed on the right branch."""
    def residual(q: np.ndarray) -> np.ndarray:
        T = robot.flange_transforms(q[None])[0]
        rotation = Rotation.from_matrix(base_T_flange[:3, :3] @ T[:3, :3].T).as_rotvec()
        return np.concatenate([T[:3, 3] - base_T_flange[:3, 3], rotation])
    return least_squares(residual, seed, xtol=1e-15, ftol=1e-15, gtol=1e-15).x


# -- the reader --------------------------------------------------------------------------------

MODULE = """%%%
  VERSION:1
%%%
MODULE Cell(SYSMODULE)
  ! a comment with [1,2,3]; and "a quote
  LOCAL CONST robtarget p10 := [ [ 374, 0 , 630 ], [0.707107,0,0.707107,0],
      [0,0,0,0], [9E+09,9E+09,9E9,9E9,9E9,9E9] ];  ! trailing comment ]
  TASK PERS robtarget path{2} := [[[1,2,-3.5e1],[1,0,0,0],[-1,0,-1,1],AXES],
                                  [[.5,+2,3],[0,1,0,0],[0,0,0,0],AXES]];
  PERS tooldata gun := [TRUE,[[10,0,150],[1,0,0,0]],[1,[0,0,50],[1,0,0,0],0,0,0]];
  VAR string s := "MoveL [1,2] ! not a comment";
  CONST jointtarget home := [[0,0,0,0,30,0],AXES];
  PROC main()
    CONST robtarget p10 := [[1,1,1],[1,0,0,0],[0,0,0,0],AXES];
    MoveL p10, v100\\T:=2, fine, gun\\WObj:=wobj0;
    MoveJ \\Conc, path{2}, v100, z10, tool0;
    MoveAbsJ home\\NoEOffs, v100, fine, tool0;
    MoveC path{1}, [[4,5,6],[1,0,0,0],[0,0,0,0],AXES], v100, fine, gun;
  ENDPROC
ENDMODULE
""".replace("AXES", NO_AXES)


def test_reader_finds_targets_their_numbers_and_their_moves() -> None:
    """Declarations (LOCAL/TASK, arrays, a routine's own shadowing the module's), inline targets,
    comments and strings holding brackets: every target found with its values, its number spans
    pointing at exactly its digits, and the tools of the moves that use it."""
    module = parse_module(MODULE, "cell.mod")
    targets = {(t.name, t.line): t for t in find_targets(module)}
    assert sorted(name for name, _ in targets) == ["home", "inline MoveC", "p10", "p10",
                                                   "path{1}", "path{2}"]
    module_p10 = targets[("p10", 6)]
    assert module_p10.uses == ()  # main's moves go to its own p10
    local_p10 = targets[("p10", 14)]
    assert [(u.tool, u.wobj) for u in local_p10.uses] == [("gun", "wobj0")]
    assert module_p10.literal.trans_mm.tolist() == [374.0, 0.0, 630.0]
    path1 = targets[("path{1}", 8)].literal
    assert path1.trans_mm.tolist() == [1.0, 2.0, -35.0]
    assert path1.configuration.tolist() == [-1, 0, -1, 1]
    assert [MODULE[n.start:n.end] for n in path1.trans] == ["1", "2", "-3.5e1"]
    assert [MODULE[n.start:n.end] for n in targets[("path{2}", 8)].literal.trans] == [
        ".5", "+2", "3"]
    assert [u.tool for u in targets[("path{1}", 8)].uses] == ["gun"]
    assert [u.tool for u in targets[("path{2}", 8)].uses] == ["tool0"]
    assert targets[("home", 12)].literal.robax_deg.tolist() == [0, 0, 0, 0, 30, 0]
    assert targets[("inline MoveC", 18)].literal.trans_mm.tolist() == [4.0, 5.0, 6.0]
    assert rewrite(MODULE, []) == MODULE


def test_rewrite_changes_only_the_numbers_given() -> None:
    """A rewrite puts new text where each number was and keeps every other byte."""
    module = parse_module(MODULE, "cell.mod")
    literal = next(t for t in find_targets(module) if t.name == "path{1}").literal
    text = rewrite(MODULE, [(literal.trans[2], "-35.25"), (literal.rot[0], "0.5")])
    assert text.replace("-35.25", "-3.5e1").replace("[[1,2,-3.5e1],[0.5", "[[1,2,-3.5e1],[1"
                        ) == MODULE
    assert format_number(-0.0000001, 6) == "0" and format_number(2.5, 6) == "2.5"


def test_tool0_is_abbs_flange_frame() -> None:
    """twin's IRB 120 flange turned by the controller's tool0 convention is ROS-Industrial's
    tool0 (REP 199: ABB's own flange frame) on 200 random poses, and at the calibration position
    tool0 faces forward with its x axis down (quaternion 0.707107, 0, 0.707107, 0)."""
    pytest.importorskip("pinocchio")
    robot = default_robot()
    urdf = load_urdf(ROOT / "models" / "irb120" / "irb120_3_58.urdf")
    assert urdf.urdf is not None and urdf.urdf.tip_link == "tool0"
    flange_T_tool0 = controller_tool0(robot)
    assert flange_T_tool0 is not None
    np.testing.assert_allclose(controller_tool0(urdf), np.eye(4))
    q = np.random.default_rng(0).uniform(robot.lower_rad, robot.upper_rad, (200, 6))
    np.testing.assert_allclose(robot.flange_transforms(q) @ flange_T_tool0,
                               urdf.flange_transforms(q), atol=1e-9)
    home = (robot.flange_transforms(np.zeros((1, 6)))[0] @ flange_T_tool0)[:3, :3]
    np.testing.assert_allclose(home, quaternion_matrix([0.707107, 0, 0.707107, 0]), atol=1e-6)


@pytest.mark.slow
def test_configuration_is_abbs() -> None:
    """cf1, cf4, cf6, cfx of twin's geometric definition equal the manual's, computed from the
    D-H frames (this test's own), on 2000 random poses of the IRB 120, all eight cfx seen."""
    robot = default_robot()
    q = np.random.default_rng(1).uniform(robot.lower_rad, robot.upper_rad, (2000, 6))
    ours = configuration(robot, q)
    theirs = np.array([abb_configuration(robot, row) for row in q])
    np.testing.assert_array_equal(ours, theirs)
    assert set(ours[:, 3]) == set(range(8))


# -- the plan as a module ------------------------------------------------------------------------

def test_plan_module_parses_back_to_the_plans_joints(tmp_path: Path) -> None:
    """`twin plan --out plan.mod` holds exactly the joints `--out plan.csv` holds for the same
    seed (both written to 1e-6 degree), in order, with the handshake symbols a capture follows,
    home first and last, every move fine."""
    args = ["plan", "--port", "600,-400,100", "--poses", "30", "--candidates", "200",
            "--joint-limits-only", "--seed", "4"]
    assert main([*args, "--out", str(tmp_path / "plan.csv")]) == 0
    assert main([*args, "--out", str(tmp_path / "plan.mod"), "--speed", "v50"]) == 0
    csv_rows = [[float(v) for v in line.split(",")] for line in
                (tmp_path / "plan.csv").read_text().splitlines()[1:]]
    text = (tmp_path / "plan.mod").read_text()
    block = re.search(r"jointtarget twin_poses\{30\} := (\[.*?\]);", text, re.S)
    assert block is not None
    poses = [robax for robax, _ in json.loads(block.group(1))]
    assert poses == csv_rows
    assert "PERS num twin_pose := 0;" in text and "PERS bool twin_ready := FALSE;" in text
    moves = re.findall(r"MoveAbsJ (\w+(?:\{k\})?), v50, fine, tool0\\WObj:=wobj0;", text)
    assert moves == ["twin_home", "twin_poses{k}", "twin_home"]
    assert text.index("twin_ready := TRUE") < text.index("WaitUntil twin_ready = FALSE")
    robot = default_robot()
    found = re.search(r"twin_home := (\[.*?\]);", text)
    assert found is not None
    home = np.deg2rad(json.loads(found.group(1))[0])
    assert np.all(home >= robot.lower_rad) and np.all(home <= robot.upper_rad)


def test_plan_module_refuses_what_the_controller_would(tmp_path: Path, refusals: Refusals) -> None:
    """A home beyond the limits, an unknown speed, a module option with a CSV: one line, exit 2,
    nothing written."""
    base = ["plan", "--port", "600,-400,100", "--poses", "30", "--candidates", "200",
            "--joint-limits-only"]
    out = tmp_path / "plan.mod"
    refusals.cli([*base, "--out", out, "--home", "0,0,0,0,130,0"], [], "joint 5 at 130 deg")
    refusals.cli([*base, "--out", out, "--speed", "v17"], [], "one of ABB's speeddata")
    refusals.cli([*base, "--out", tmp_path / "plan.csv", "--tool", "gun"], [], "--out PLAN.mod")
    assert not out.exists() and not (tmp_path / "plan.csv").exists()


# -- program filtering, held to the twin's truth ------------------------------------------------

TOOLS = {"gun": ([12.0, -5.0, 160.0], [1.0, 0.0, 0.0, 0.0]),
         "bent": ([0.0, 60.0, 110.0], list(Rotation.from_euler("x", 30, degrees=True)
                                           .as_quat(scalar_first=True)))}
WOBJ = (([450.0, -150.0, 80.0], list(Rotation.from_euler("z", 35, degrees=True)
                                     .as_quat(scalar_first=True))),
        ([20.0, 10.0, 0.0], list(Rotation.from_euler("x", 5, degrees=True)
                                 .as_quat(scalar_first=True))))


def _numbers(values: list[float], decimals: int) -> str:
    return ",".join(format_number(v, decimals) for v in values)


def _frame_text(trans: list[float], quaternion: list[float]) -> str:
    return f"[[{_numbers(trans, 6)}],[{_numbers(quaternion, 9)}]]"


def _cell_module(robot: RobotModel, rng: np.random.Generator) -> tuple[str, dict[str, dict]]:
    """A module of 40 robtargets (two tools, wobj0 and a turned work object, the
    configurations of random poses) and 10 jointtargets, and what each means."""
    flange_T_tool0 = controller_tool0(robot)
    assert flange_T_tool0 is not None
    base_T_wobj = pose(*WOBJ[0]) @ pose(*WOBJ[1])
    q, _ = reachable_targets(robot, 50, rng)
    lines = ["MODULE Cell", "  ! made by tests/test_rapid.py",
             *[f"  PERS tooldata {name} := [TRUE,{_frame_text(*frame)},[1.5,[0,0,60],[1,0,0,0],"
               "0,0,0]];" for name, frame in TOOLS.items()],
             f"  TASK PERS wobjdata fixture := [FALSE,TRUE,\"\",{_frame_text(*WOBJ[0])},"
             f"{_frame_text(*WOBJ[1])}];"]
    meaning: dict[str, dict] = {}
    moves = []
    for k in range(40):
        tool = list(TOOLS)[k % 2]
        wobj = "fixture" if k % 4 >= 2 else None
        tcp = robot.flange_transforms(q[k:k + 1])[0] @ flange_T_tool0 @ pose(*TOOLS[tool])
        in_wobj = (np.linalg.inv(base_T_wobj) if wobj else np.eye(4)) @ tcp
        trans = list(in_wobj[:3, 3] * 1000.0)
        quaternion = list(Rotation.from_matrix(in_wobj[:3, :3]).as_quat(scalar_first=True))
        conf = abb_configuration(robot, q[k])
        lines.append(f"  CONST robtarget p{k} := [[{_numbers(trans, 6)}],[{_numbers(quaternion, 9)}"
                     f"],[{','.join(map(str, conf))}],{NO_AXES}];")
        moves.append(f"    MoveL p{k}, v200, fine, {tool}" + (f"\\WObj:={wobj};" if wobj else ";"))
        meaning[f"p{k}"] = {"q": q[k], "tool": tool, "wobj": wobj, "conf": conf}
    for k in range(40, 50):
        degrees = [float(format_number(v, 6)) for v in np.rad2deg(q[k])]
        lines.append(f"  CONST jointtarget j{k} := [[{_numbers(degrees, 6)}],{NO_AXES}];")
        moves.append(f"    MoveAbsJ j{k}, v200, fine, tool0;")
        meaning[f"j{k}"] = {"q": np.deg2rad(degrees)}
    lines += ["  PROC main()", *moves, "  ENDPROC", "ENDMODULE", ""]
    return "\n".join(lines), meaning


def _skeleton(text: str) -> str:
    """The module with every number of a target literal replaced by '#' (what must not change
    is all the rest), the external axes kept."""
    def mask(match: re.Match[str]) -> str:
        literal = match.group(0)
        head, _, axes = literal.rpartition("[9E9")
        return NUMBER.sub("#", head) + "[9E9" + axes
    return re.sub(r"(?<=:= )\[\[.*?\]\];", mask, text)


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """The geometric scenario simulated by the twin, calibrated by `twin calibrate`."""
    folder = tmp_path_factory.mktemp("cell")
    assert main(["simulate", str(ROOT / "scenarios" / "geometric_irb120.toml"), "--out",
                 str(folder / "sim")]) == 0
    assert main(["calibrate", str(folder / "sim" / "capture.toml"), "--json",
                 str(folder / "result.json")]) == 0
    robot = default_robot()
    truth = robot.perturbed(load_truth_delta(folder / "sim" / "truth.json", 6, robot.is_length))
    return {"folder": folder, "robot": robot, "truth": truth}


@pytest.mark.slow
def test_filtered_module_brings_the_true_robot_to_every_target(calibrated: dict) -> None:
    """Done when of #23: 40 robtargets (two tools, a turned work object, several configurations)
    and 10 jointtargets, compensated by `twin compensate --rapid`, read back by this test's
    reader, commanded by this test's model of the controller (the nominal model, on each
    target's written configuration) and run on the twin's true robot. Every corrected target's
    flange lands within twice the calibration's flange error there (its identified model against
    the truth at the nominal joints), twenty times closer than the nominal program's, and its
    TCP within twice the calibration's error at the TCP (which the flange orientation the cable
    cannot see dominates: docs/compensation.md); a target left uncorrected is listed and written
    exactly as it was; every byte but the targets' numbers is as written, external axes too."""
    from twin.io.identified import load_result_delta

    folder, robot, truth = calibrated["folder"], calibrated["robot"], calibrated["truth"]
    identified = robot.perturbed(load_result_delta(folder / "result.json", robot))
    text, meaning = _cell_module(robot, np.random.default_rng(11))
    source, out = folder / "cell.mod", folder / "cell_compensated.mod"
    source.write_text(text)
    assert main(["compensate", "--identified", str(folder / "result.json"), "--rapid",
                 str(source), "--out", str(out)]) == 0
    written = out.read_text()
    assert source.read_text() == text
    assert _skeleton(written) == _skeleton(text)
    original = read_targets(text)
    flange_T_tool0 = controller_tool0(robot)
    base_T_wobj = pose(*WOBJ[0]) @ pose(*WOBJ[1])
    errors: dict[str, list[float]] = {key: [] for key in (
        "before", "after", "model", "tcp_after", "tcp_model")}
    confs, left = set(), []
    for name, literal in read_targets(written).items():
        target = meaning[name]
        if literal == original[name]:
            left.append(name)
            continue
        if name.startswith("j"):
            q_cmd, chain = np.deg2rad(literal[0]), np.eye(4)
            assert literal[1] == [9e9] * 6
        else:
            trans, quaternion, conf, axes = literal
            assert conf[3] == target["conf"][3] and axes == [9e9] * 6
            confs.add(tuple(target["conf"]))
            wobj = base_T_wobj if target["wobj"] else np.eye(4)
            tool = pose(*TOOLS[target["tool"]])
            flange = wobj @ pose(trans, quaternion) @ np.linalg.inv(tool) \
                @ np.linalg.inv(flange_T_tool0)
            q_cmd = controller_joints(robot, flange, target["q"])
            assert abb_configuration(robot, q_cmd) == conf
            chain = flange_T_tool0 @ tool
        at = target["q"][None]
        wanted, believed = robot.flange_transforms(at)[0], identified.flange_transforms(at)[0]
        unmoved, reached = truth.flange_transforms(at)[0], truth.flange_transforms(q_cmd[None])[0]
        errors["before"].append(np.linalg.norm(unmoved[:3, 3] - wanted[:3, 3]))
        errors["after"].append(np.linalg.norm(reached[:3, 3] - wanted[:3, 3]))
        errors["model"].append(np.linalg.norm(believed[:3, 3] - unmoved[:3, 3]))
        errors["tcp_after"].append(np.linalg.norm((reached @ chain - wanted @ chain)[:3, 3]))
        errors["tcp_model"].append(np.linalg.norm((believed @ chain - unmoved @ chain)[:3, 3]))
    e = {key: np.array(value) for key, value in errors.items()}
    assert len(left) <= 2 and len(e["after"]) + len(left) == 50
    assert len(confs) >= 2 and len({c[3] for c in confs}) >= 2
    assert np.all(e["after"] <= 2.0 * e["model"] + 1e-6), (e["after"], e["model"])
    assert np.max(e["after"]) < np.min(e["before"]) / 20.0
    assert np.all(e["tcp_after"] <= 2.0 * e["tcp_model"] + 1e-6), (e["tcp_after"], e["tcp_model"])


@pytest.mark.slow
def test_filtering_refusals(calibrated: dict, tmp_path: Path, refusals: Refusals) -> None:
    """A robtarget that is not one, a module for a robot whose tool0 twin does not know, an
    output that is not a module: one line naming the line or flag, exit 2, nothing written."""
    result = calibrated["folder"] / "result.json"
    out = tmp_path / "out.mod"
    bad = tmp_path / "bad.mod"
    bad.write_text("MODULE Bad\n  CONST robtarget p := [[1,2,3],[1,0,0,0],[0,0,0,0]];\nENDMODULE\n")
    refusals.cli(["compensate", "--identified", result, "--rapid", bad, "--out", out], [bad],
                 "line 2")
    good = tmp_path / "good.mod"
    good.write_text(_cell_module(default_robot(), np.random.default_rng(1))[0])
    refusals.cli(["compensate", "--identified", result, "--rapid", good, "--out",
                  tmp_path / "out.csv"], [good], "an output RAPID module")
    renamed = tmp_path / "arm.toml"
    renamed.write_text((ROOT / "models" / "irb120.toml").read_text().replace(
        'name = "ABB IRB 120"', 'name = "my arm"'))
    mine = tmp_path / "mine.json"
    assert main(["calibrate", str(ROOT / "examples" / "irb120_lm" / "measurements.csv"),
                 "--robot", str(renamed), "--port", "600,-400,100", "--json", str(mine)]) == 0
    refusals.cli(["compensate", "--identified", mine, "--robot", renamed, "--rapid", good,
                  "--out", out], [good, mine], "--tool0-in-flange")
    assert not out.exists()


def test_a_jointtarget_at_an_aligned_wrist_is_left_as_written(
        calibrated: dict, capsys: pytest.CaptureFixture[str]) -> None:
    """A jointtarget 0.4° from an aligned wrist is listed as singular and written exactly as it
    was (its correction would turn q4 and q6 by degrees against each other); the same pose at
    q5 = 40° is corrected."""
    folder = calibrated["folder"]
    source, out = folder / "wrist.mod", folder / "wrist_compensated.mod"
    source.write_text("MODULE Wrist\n"
                      f"  CONST jointtarget near := [[20,10,15,30,0.4,-20],{NO_AXES}];\n"
                      f"  CONST jointtarget away := [[20,10,15,30,40,-20],{NO_AXES}];\n"
                      "  PROC main()\n    MoveAbsJ near, v200, fine, tool0;\n"
                      "    MoveAbsJ away, v200, fine, tool0;\n  ENDPROC\nENDMODULE\n")
    capsys.readouterr()
    assert main(["compensate", "--identified", str(folder / "result.json"), "--rapid",
                 str(source), "--out", str(out)]) == 0
    report = capsys.readouterr().out
    assert re.search(r"near\b.*singular.*next to a singularity", report), report
    before, after = read_targets(source.read_text()), read_targets(out.read_text())
    assert after["near"] == before["near"] and after["away"] != before["away"]
