"""Every measurement kind's hot path, side by side: residuals of a swarm and the analytic
Jacobian at one point, and the Jacobian against central differences.

Run by hand: ``python bench/bench_kinds.py`` (``--tiny``: 8 poses, a swarm of 4). For each
kind on the same poses of the IRB 120 (its D-H errors and its rig's unknowns): the median time
of the residuals of a swarm of x (what PSO and BIPSO evaluate), of the residuals and analytic
Jacobian at one x (what LM and the filters call), and of the Jacobian by central differences
(what a solver without the analytic one would pay), with the last two's ratio; each analytic
Jacobian is checked against its differences before its times are printed. A 6-D pose reads
orientations through scipy's rotations (Exp and Log): the table shows what that costs against a
tracker's position on the same poses.
"""

from __future__ import annotations

import argparse

import numpy as np
from _timing import median_time

from twin.calibration.settings import CalibrationSettings
from twin.calibration.setup import make_model
from twin.geometry.rigid import transform
from twin.io.robot_file import default_robot
from twin.kinds.plane import PlaneRig
from twin.kinds.pose import PoseRig
from twin.model import Model
from twin.rig import Distance, Rig
from twin.robot import RobotModel, random_poses

REPEATS = 5
FRAME = transform([1.6, 0.3, -0.2], [0.05, -0.1, 2.8])


def models(robot: RobotModel) -> dict[str, tuple[Model, dict[str, np.ndarray]]]:
    """Each kind's model with its rig's unknowns, and the labels of its rows (by pose index)."""
    planes = PlaneRig(("a", "b", "c"), np.array([[0, 0, 1.0], [0, 0, 1.0], [0.6, 0.8, 0]]),
                      np.array([0.15, 0.25, 0.4]))
    points = Rig(attachment_m=[0.0, 0.0, 0.08], point_names=("a", "b", "c"),
                 points_m=np.array([[0.4, 0.0, 0.3], [0.45, 0.0, 0.3], [0.4, 0.1, 0.35]]),
                 distances=(Distance("a", "b", 0.05),))
    setups = {
        "length": (Rig.cable([0.6, -0.4, 0.1]), ("port", "offset")),
        "position": (Rig(attachment_m=[0.02, 0.0, 0.05], base_in_tracker=FRAME),
                     ("attachment", "base")),
        "point": (points, ("attachment",)),
        "pose": (Rig(attachment_m=[0.02, 0.0, 0.05], base_in_tracker=FRAME,
                     part=PoseRig(np.eye(3))), ("base", "tool")),
        "plane": (Rig(attachment_m=[0.0, 0.0, 0.08], part=planes,
                      distances=(Distance("a", "b", 0.1),)), ("attachment",)),
    }
    labels = {"point": "point", "plane": "plane"}
    found = {}
    for kind, (rig, estimate) in setups.items():
        found[kind] = (make_model(robot, rig, kind, CalibrationSettings(estimate=estimate)),
                       {labels[kind]: np.zeros(0)} if kind in labels else {})
    return found


def differences(model: Model, x: np.ndarray, data: object, eps: float = 1e-6) -> np.ndarray:
    """∂r/∂x by central differences, one batched call of 2p residuals."""
    steps = np.eye(x.size) * eps
    both = model.residuals(np.concatenate([x + steps, x - steps]), data)  # type: ignore[arg-type]
    return np.asarray((both[: x.size] - both[x.size:]).T / (2 * eps))


def timings(model: Model, data: object, x: np.ndarray, swarm: np.ndarray) -> list[float]:
    """Median times of the swarm's residuals, r and J at x, J by differences at x, s."""
    return [median_time(run, REPEATS)[0] for run in (
        lambda: model.residuals(swarm, data),  # type: ignore[arg-type]
        lambda: model.jacobian(x, data),  # type: ignore[arg-type]
        lambda: differences(model, x, data))]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=96)
    parser.add_argument("--swarm", type=int, default=100)
    parser.add_argument("--tiny", action="store_true",
                        help="smoke size (8 poses, a swarm of 4): no figure means anything")
    args = parser.parse_args()
    if args.tiny:
        args.poses, args.swarm = 8, 4
    robot = default_robot()
    rng = np.random.default_rng(0)
    q = random_poses(robot, args.poses, rng)
    print(f"{'kind':<10}{'rows':>6}{'p':>5}{'swarm residuals':>18}{'r and J':>12}"
          f"{'J by differences':>19}{'ratio':>8}")
    for kind, (model, labels) in models(robot).items():
        data = model.poses(q, **{name: np.arange(args.poses) % 3 for name in labels})
        x = rng.normal(scale=1e-3, size=model.n_params)
        swarm = x + rng.normal(scale=1e-3, size=(args.swarm, model.n_params))
        r, jacobian = model.jacobian(x, data)
        np.testing.assert_allclose(jacobian, differences(model, x, data), atol=1e-7)
        times = timings(model, data, x, swarm)
        print(f"{kind:<10}{r.size:>6}{model.n_params:>5}{times[0] * 1e3:>15.2f} ms"
              f"{times[1] * 1e3:>9.2f} ms{times[2] * 1e3:>16.2f} ms{times[2] / times[1]:>7.1f}×")


if __name__ == "__main__":
    main()
