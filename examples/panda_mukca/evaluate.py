"""MUKCa's Franka Panda ball-in-socket recordings: imported with `twin import`, calibrated with
each fixture placement held out in turn.

Run from the repository root: ``.venv/bin/python examples/panda_mukca/evaluate.py``; it writes
``out/panda_mukca/`` (the imported measurement CSV, the table) and prints the table;
``--write`` also rewrites the table in examples/panda_mukca/README.md, stamped with the commit.

For each placement P of the fixture (front, right, back-high: two sockets 50 mm apart each):
twin calibrates the Panda (its 28 D-H errors, the ball's position on the flange, the sockets of
the other placements, their 50 mm spacing) on the two other placements, then P is judged with
the model fixed: the ball's positions of P's poses are predicted, each socket's centre is their
mean, and the residuals are the predictions' offsets from it (RMS over the x, y, z components,
as `twin calibrate` reports a fixed point's residuals), and the distance between P's two socket
centres against the fixture's 50 mm. The nominal model is the URDF with the ball where MUKCa's
panda.urdf puts it (:data:`NOMINAL_BALL_MM`).
"""

from __future__ import annotations

import argparse
import datetime
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench"))

from docs_tables import commit, markdown_table, replace_block  # noqa: E402

from twin.calibration.pipeline import calibrate  # noqa: E402
from twin.calibration.settings import CalibrationSettings  # noqa: E402
from twin.cli import main as twin  # noqa: E402
from twin.dataset import Measurements  # noqa: E402
from twin.io.atomic import write_atomic  # noqa: E402
from twin.io.measurements import load_measurements  # noqa: E402
from twin.io.robot_file import load_robot  # noqa: E402
from twin.kinds.point import point_measurements  # noqa: E402
from twin.rig import Rig  # noqa: E402
from twin.robot import RobotModel  # noqa: E402
from twin.units import m_to_mm, mm_to_m  # noqa: E402

HERE = Path(__file__).resolve().parent
OUT = ROOT / "out" / "panda_mukca"
ROBOT = ROOT / "models" / "panda" / "panda.urdf"
PLACEMENTS = ("front", "right", "back-high")
SPACING_MM = 50.0
"""The fixture's socket spacing (MUKCa's tool: two sockets 50 mm apart)."""
_TURN = -np.pi / 4  # panda_hand_joint: the hand turned −45° about the flange's z
_BALL_IN_TCP_M = np.array([7.773732033005863e-05, -4.214022515884392e-05, 0.030128297908475325])
NOMINAL_BALL_MM = m_to_mm(np.array([
    np.cos(_TURN) * _BALL_IN_TCP_M[0] - np.sin(_TURN) * _BALL_IN_TCP_M[1],
    np.sin(_TURN) * _BALL_IN_TCP_M[0] + np.cos(_TURN) * _BALL_IN_TCP_M[1],
    0.1034 + _BALL_IN_TCP_M[2]]))
"""The ball in the flange frame, mm: MUKCa's urdf/panda.urdf chain panda_link8 →
panda_hand (−45° about z) → panda_hand_tcp (0.1034 m along z) → ball_link."""
TRAIN_FRACTION = 0.995
"""Of the training placements' poses, all but one or two train (the pipeline keeps a
validation row); the held-out placement is the test."""


def import_data(folder: Path = OUT) -> Path:
    """`twin import` of the six headerless files (radians, one per socket) into a folder."""
    folder.mkdir(parents=True, exist_ok=True)
    out = folder / "measurements.csv"
    files = [str(HERE / "data" / p / f"hole_{h}.csv") for p in PLACEMENTS for h in (0, 1)]
    if twin(["import", *files, "--robot", str(ROBOT), "--angle-unit", "rad", "--headerless",
             "--out", str(out)]) != 0:
        raise SystemExit("twin import failed")
    return out


def subset(data: Measurements, placements: tuple[str, ...]) -> Measurements:
    """The rows of some placements, their points renumbered."""
    point, point_names = data.index("point"), data.names("point")
    names = tuple(n for n in point_names if n.split("/")[0] in placements)
    keep = np.isin(np.asarray(point_names)[point], names)
    index = {point_names.index(n): i for i, n in enumerate(names)}
    return point_measurements(data.q_rad[keep], [index[p] for p in point[keep]],
                              point_names=names)


def held_out(robot: RobotModel, ball_m: np.ndarray, data: Measurements) -> tuple[float, float]:
    """RMS of the residuals (mm, per component) and the socket distance error (mm) of one
    placement, the model fixed and the two socket centres fitted (their means)."""
    transforms = robot.flange_transforms(data.q_rad)
    balls = transforms[:, :3, :3] @ ball_m + transforms[:, :3, 3]
    point = data.index("point")
    centres = np.stack([balls[point == j].mean(axis=0)
                        for j in range(len(data.names("point")))])
    residuals = balls - centres[point]
    distance = np.linalg.norm(centres[0] - centres[1])
    return float(m_to_mm(np.sqrt(np.mean(residuals**2)))), float(
        m_to_mm(distance) - SPACING_MM)


def evaluate(measurements: Path) -> list[list[str]]:
    """One table row per held-out placement, and their mean."""
    robot = load_robot(ROBOT)
    data = load_measurements(measurements, robot)
    nominal_ball = mm_to_m(NOMINAL_BALL_MM)
    rows, figures = [], []
    for placement in PLACEMENTS:
        training = tuple(p for p in PLACEMENTS if p != placement)
        rig = Rig(attachment_m=nominal_ball, distances=tuple(
            (f"{p}/hole_0", f"{p}/hole_1", mm_to_m(SPACING_MM)) for p in training))
        result = calibrate(robot, subset(data, training), rig=rig, seed=0,
                           settings=CalibrationSettings(estimate=("attachment",),
                                                        train_fraction=TRAIN_FRACTION))
        test = subset(data, (placement,))
        before = held_out(robot, nominal_ball, test)
        after = held_out(result.identified_geometry, result.attachment_m, test)
        figures.append((*before, *after))
        rows.append([placement, f"{', '.join(training)}", str(len(test.q_rad)),
                     f"{before[0]:.3f}", f"{after[0]:.3f}", f"{before[1]:+.3f}",
                     f"{after[1]:+.3f}"])
    mean = np.mean(np.abs(figures), axis=0)
    rows.append(["mean", "", "", f"{mean[0]:.3f}", f"{mean[2]:.3f}", f"{mean[1]:.3f}*",
                 f"{mean[3]:.3f}*"])
    rig = Rig(attachment_m=nominal_ball, distances=tuple(
        (f"{p}/hole_0", f"{p}/hole_1", mm_to_m(SPACING_MM)) for p in PLACEMENTS))
    split = calibrate(robot, data, rig=rig, seed=0,
                      settings=CalibrationSettings(estimate=("attachment",)))
    rows.append(["random 20 % of all", "the other 80 %", str(len(split.validation_rows)),
                 f"{m_to_mm(split.metrics['before'].rmse):.3f}",
                 f"{m_to_mm(split.metrics['validation'].rmse):.3f}", "", ""])
    return rows


HEADER = ("held out", "trained on", "poses", "RMSE nominal [mm]", "RMSE calibrated [mm]",
          "spacing error nominal [mm]", "spacing error calibrated [mm]")


def main() -> None:
    """Import, evaluate, print (and with --write, rewrite the README's table)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true",
                        help="rewrite the table in examples/panda_mukca/README.md")
    args = parser.parse_args()
    table = markdown_table(HEADER, evaluate(import_data()))
    today = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d")
    block = (f"{table}\n\n\\* the mean of the absolute spacing errors. The last row is `twin "
             "calibrate`'s own random split of all 182 poses (seed 0), its fixed points fitted "
             "on the training poses.\n\n*Measured at commit "
             f"`{commit()}` on {today} by `examples/panda_mukca/evaluate.py`.*\n")
    write_atomic(OUT / "table.md", block)
    print(block)
    if args.write:
        readme = HERE / "README.md"
        write_atomic(readme, replace_block(readme.read_text(encoding="utf-8"), "mukca", block))


if __name__ == "__main__":
    main()
