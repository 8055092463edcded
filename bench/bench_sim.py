"""Benchmark the MuJoCo twin: lengths per second rigid vs at static equilibrium, MuJoCo FK vs
the core's vectorised FK, a warm-up's rows on a twin compiled per row vs on one twin with its
bodies placed per row (:meth:`twin.sim.Twin.at_rest_of`), the twins of a study's true robots
with their specs built vs from a kept skeleton (:func:`twin.sim.builder.compile_model`), and
one whole simulated capture. Run by hand:

    .venv/bin/python bench/bench_sim.py
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np
from _timing import tiny_run

from twin.dataset import approach_directions
from twin.io.robot_file import default_robot
from twin.kinds.length import cable_length
from twin.robot import RobotModel, random_poses
from twin.scenario import Physics, load_scenario
from twin.sim import Twin, build_spec, simulate
from twin.sim.builder import compile_model

ROOT = Path(__file__).parents[1]
PORT_M = np.array([0.6, -0.4, 0.1])
N_POSES = 2000
WARM_ROWS = 100


def _best_seconds(run: Callable[[], object], repeat: int = 3) -> float:
    best = np.inf
    for _ in range(repeat):
        start = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - start)
    return float(best)


def main() -> None:
    """Print the timings and their ratios, measured side by side in one run."""
    global N_POSES
    if tiny_run(__doc__):
        N_POSES = 5  # and a warm-up of as many rows
    robot = default_robot()
    q = random_poses(robot, N_POSES, np.random.default_rng(0))
    paper = load_scenario(ROOT / "scenarios" / "paper_irb120.toml")
    rigid = Twin.build(robot, PORT_M)
    compliant = Twin.build(robot, PORT_M, paper.physics)
    model = build_spec(robot, PORT_M).compile()
    data = mujoco.MjData(model)

    def mujoco_fk() -> None:
        for pose in q:
            data.qpos[:] = pose
            mujoco.mj_kinematics(model, data)

    timings = {
        "core cable_length (vectorised)": _best_seconds(
            lambda: cable_length(robot.structure, robot.dh, q, PORT_M)),
        "core flange_position (vectorised)": _best_seconds(lambda: robot.flange_positions(q)),
        "MuJoCo mj_kinematics per pose": _best_seconds(mujoco_fk),
        "twin lengths, rigid": _best_seconds(lambda: rigid.lengths(q)),
        "twin lengths, static equilibrium": _best_seconds(lambda: compliant.lengths(q), 1),
    }
    base = timings["twin lengths, rigid"]
    print(f"{N_POSES} random IRB 120 poses")
    print(f"  {'':<36}{'µs/pose':>10}{'poses/s':>12}{'vs rigid twin':>15}")
    for name, seconds in timings.items():
        per_pose = seconds / N_POSES
        print(f"  {name:<36}{per_pose * 1e6:>10.2f}{1 / per_pose:>12.0f}{seconds / base:>15.2f}")

    shift = compliant.flange_positions(q) - robot.flange_positions(q)
    sag_um = np.linalg.norm(shift, axis=1) * 1e6
    print(f"flange sag at equilibrium ({paper.name} physics): RMS {np.sqrt(np.mean(sag_um**2)):.1f}"
          f" µm, median {np.median(sag_um):.1f} µm, max {np.max(sag_um):.1f} µm")
    for label, physics in [
        ("gravity only", Physics(paper.physics.stiffness_nm_per_rad, True, 0.0)),
        ("tension only (5 N)", Physics(paper.physics.stiffness_nm_per_rad, False, 5.0)),
    ]:
        part = Twin.build(robot, PORT_M, physics).flange_positions(q) - robot.flange_positions(q)
        print(f"  {label:<20} RMS {np.sqrt(np.mean(np.sum(part**2, axis=1))) * 1e6:.1f} µm")

    warm_up(robot, q[:WARM_ROWS])
    true_twins(robot, 5 if N_POSES < WARM_ROWS else 100)
    for path in sorted((ROOT / "scenarios").glob("*_irb120.toml")):
        scenario = load_scenario(path)
        seconds = _best_seconds(lambda scenario=scenario: simulate(scenario), 1)
        print(f"simulate({scenario.name}): {seconds * 1e3:.0f} ms for {scenario.pose_count} poses")


def warm_up(robot: RobotModel, q: np.ndarray) -> None:
    """A warm-up's rows, each on the robot grown by its own micrometres: a twin compiled for
    each row against one twin placed for each, all rows in one call (the same lengths, checked
    first)."""
    rng = np.random.default_rng(1)
    grown = [robot.perturbed(np.concatenate([rng.uniform(0.0, 2e-5, 2 * robot.n_joints),
                                             np.zeros(2 * robot.n_joints)]))
             for _ in range(len(q))]
    approach = approach_directions(q)
    station = Twin.build(robot, PORT_M)

    def compiled() -> list[float]:
        return [float(Twin.build(warm, PORT_M).lengths(q[k:k + 1], approach[k:k + 1])[0])
                for k, warm in enumerate(grown)]

    tables = np.stack([warm.dh for warm in grown])

    def placed() -> list[float]:
        return station.at_rest_of(tables, q, approach).length_m.tolist()

    assert np.max(np.abs(np.subtract(compiled(), placed()))) < 1e-12
    times = {"compiled": _best_seconds(compiled), "placed": _best_seconds(placed)}
    print(f"a warm-up's {len(q)} rows: a twin compiled per row {times['compiled'] * 1e3:.1f} ms, "
          f"one twin placed per row {times['placed'] * 1e3:.1f} ms "
          f"({times['compiled'] / times['placed']:.1f}x)")


def true_twins(robot: RobotModel, count: int) -> None:
    """The models of ``count`` true robots (the nominal perturbed, as a study's trials draw
    them): each spec built and compiled against each compiled from the skeleton kept for the
    first (the same arrays, checked first)."""
    rng = np.random.default_rng(2)
    scale = np.where(robot.is_length, 1.5e-3, np.deg2rad(0.2)).ravel()
    robots = [robot.perturbed(rng.uniform(-1.0, 1.0, scale.size) * scale) for _ in range(count)]

    def built() -> list[mujoco.MjModel]:
        return [build_spec(true, PORT_M, floor=True).compile() for true in robots]

    def kept() -> list[mujoco.MjModel]:
        return [compile_model(true, PORT_M, floor=True) for true in robots]

    for one, other in zip(built(), kept(), strict=True):
        assert np.array_equal(one.body_pos, other.body_pos)
        assert np.array_equal(one.geom_size, other.geom_size)
    times = {"built": _best_seconds(built), "kept": _best_seconds(kept)}
    print(f"twins of {count} true robots: each spec built and compiled "
          f"{times['built'] / count * 1e3:.2f} ms, from the kept skeleton "
          f"{times['kept'] / count * 1e3:.2f} ms ({times['built'] / times['kept']:.2f}x)")


if __name__ == "__main__":
    main()
