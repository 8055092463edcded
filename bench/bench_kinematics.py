"""Batched kinematics and IK vs per-pose loops (Pinocchio, or our own solver row by row).

Run by hand: ``python bench/bench_kinematics.py``. Prints the median wall time of repeated runs
of each pair, side by side in one run, and their ratio:

1. flange positions of 100 D-H tables (a swarm) × 96 poses:
``twin.geometry.kinematics.point_position``
   on all at once vs a Pinocchio model per table and ``framesForwardKinematics`` per pose;
2. the cable residuals and their analytic Jacobian (24 D-H columns) on 96 poses, one call, vs
   Pinocchio's flange joint Jacobian (6 columns only) in a loop over the poses;
3. compensation IK of 1000 program rows: the batched Newton vs the same solver row by row;
4. the residuals and Jacobian of item 2 with joint 1 made prismatic (its q adding to d1) beside
   the revolute chain's: what the prismatic path costs, on whichever kernel is installed;
5. the kernel a study takes (compiled where numba is installed) under a cable Jacobian (the
   point traced and moved along each row's direction) for 10 trials, each its own table and
   96 poses: one call for all of them vs one call a trial, as a study fits its trials one
   after the other. The same numbers to the bit; the ratio is what fitting a block of trials
   in lockstep (a stack of problems, which the model does not evaluate) would gain on the
   kernel's share of a trial's Jacobians.

Every result pair is checked to agree before its times are printed.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin
from _timing import median_time, tiny_run

from twin.calibration.setup import make_model
from twin.compensation.joints import compensate_program
from twin.compensation.targets import reachable_targets
from twin.export.pinocchio import FLANGE_FRAME, build_model
from twin.geometry.kinematics import (
    bulk_work,
    for_bulk_work,
    point_jacobian,
    point_position,
    takes_compiled,
    trace_point,
    turns,
)
from twin.io.robot_file import default_robot
from twin.rig import Rig
from twin.robot import RobotModel, random_poses
from twin.synthetic import synthesize
from twin.units import mm_to_m

REPEATS = 7
N_TABLES = 100
N_POSES = 96
N_ROWS = 1000
N_TRIALS = 10


def report(label: str, ours_s: float, theirs_s: float, theirs: str) -> None:
    print(f"{label}\n  twin, batched   {ours_s * 1e3:10.2f} ms\n"
          f"  {theirs:<15} {theirs_s * 1e3:10.2f} ms\n  ratio           {theirs_s / ours_s:10.1f}×")


def main() -> None:
    global REPEATS, N_TABLES, N_POSES, N_ROWS, N_TRIALS
    if tiny_run(__doc__):
        REPEATS, N_TABLES, N_POSES, N_ROWS, N_TRIALS = 1, 3, 8, 10, 2
    robot = default_robot()
    rng = np.random.default_rng(0)
    scale = np.repeat([1.5e-3, 1.5e-3, np.deg2rad(0.2), np.deg2rad(0.2)], robot.n_joints)
    tables = robot.dh + (rng.uniform(-1, 1, (N_TABLES, 4 * robot.n_joints)) * scale).reshape(
        N_TABLES, 4, robot.n_joints)
    q = random_poses(robot, N_POSES, rng)

    # 1. FK of a swarm of tables.
    models = [build_model(robot.perturbed((table - robot.dh).ravel())) for table in tables]
    datas = [model.createData() for model in models]
    frame = models[0].getFrameId(FLANGE_FRAME)

    def pinocchio_fk() -> np.ndarray:
        out = np.empty((N_TABLES, N_POSES, 3))
        for k, (model, data) in enumerate(zip(models, datas, strict=True)):
            for i, pose in enumerate(q):
                pin.framesForwardKinematics(model, data, pose)
                out[k, i] = data.oMf[frame].translation
        return out

    ours_s, ours = median_time(lambda: point_position(robot.structure, tables, q), REPEATS)
    theirs_s, theirs = median_time(pinocchio_fk, 3)
    assert np.max(np.abs(ours - theirs)) < 1e-9
    report(f"FK, {N_TABLES} tables × {N_POSES} poses", ours_s, theirs_s, "Pinocchio loop")

    # 2. Residuals and Jacobian of the cable model.
    port_m = mm_to_m([600.0, -400.0, 100.0])
    data = synthesize(robot.perturbed(scale * 0.5), q, port_m, 1e-5, rng)
    cable = make_model(robot, Rig.cable(port_m))
    x = np.zeros(cable.n_params)

    def residuals_and_jacobian() -> tuple[np.ndarray, np.ndarray]:
        return cable.residuals(x, data), cable.jacobian(x, data)[1]

    model, pdata = models[0], datas[0]

    def pinocchio_jacobians() -> np.ndarray:
        out = np.empty((N_POSES, 3, robot.n_joints))
        for i, pose in enumerate(q):
            out[i] = pin.computeFrameJacobian(model, pdata, pose, frame,
                                              pin.LOCAL_WORLD_ALIGNED)[:3]
        return out

    ours_s, _ = median_time(residuals_and_jacobian, 50)
    theirs_s, theirs = median_time(pinocchio_jacobians, 50)
    ours_jacobian = point_jacobian(robot.structure, tables[0], q).joints
    assert np.max(np.abs(ours_jacobian - theirs)) < 1e-9
    report(f"cable residuals + 24-column Jacobian, {N_POSES} poses (vs joint Jacobian only)",
           ours_s, theirs_s, "Pinocchio loop")
    print(f"  throughput      {1.0 / ours_s:10.0f} residual+Jacobian evaluations/s")

    # 3. Compensation IK, batched vs row by row.
    identified = robot.perturbed(scale * rng.uniform(-1, 1, 4 * robot.n_joints))
    q_program, _ = reachable_targets(robot, N_ROWS, rng)

    def row_by_row() -> np.ndarray:
        return np.concatenate([
            compensate_program(robot, identified, q_program[i:i + 1]).q_rad
            for i in range(N_ROWS)
        ])

    ours_s, batched = median_time(
        lambda: compensate_program(robot, identified, q_program).q_rad, REPEATS)
    theirs_s, looped = median_time(row_by_row, 3)
    assert np.max(np.abs(batched - looped)) < 1e-8
    report(f"compensation IK (full pose), {N_ROWS} rows", ours_s, theirs_s, "row by row")

    # 4. The same chain with a prismatic joint 1, side by side with the revolute one.
    types = ("prismatic",) + ("revolute",) * (robot.n_joints - 1)
    sliding = replace(robot, structure=replace(robot.structure, joint_types=types))
    q_slide = q.copy()
    q_slide[:, 0] = rng.uniform(0.0, 0.3, len(q))
    data_slide = synthesize(sliding.perturbed(scale * 0.5), q_slide, port_m, 1e-5, rng)
    cable_slide = make_model(sliding, Rig.cable(port_m))

    def prismatic() -> tuple[np.ndarray, np.ndarray]:
        return cable_slide.residuals(x, data_slide), cable_slide.jacobian(x, data_slide)[1]

    slide_s, _ = median_time(prismatic, 50)
    revolute_s, _ = median_time(residuals_and_jacobian, 50)
    report(f"cable residuals + Jacobian, {N_POSES} poses, joint 1 prismatic vs revolute",
           revolute_s, slide_s, "prismatic")
    with bulk_work():
        for_bulk_work()  # the kernel a study's worker takes
        trials_at_once(robot, tables[:N_TRIALS], rng)


def trials_at_once(robot: RobotModel, tables: np.ndarray, rng: np.random.Generator) -> None:
    """Item 5: the tables (K, 4, n) each with poses of its own, traced and moved along unit
    directions in one call of the kernel vs one call a table."""
    poses = np.stack([random_poses(robot, N_POSES, rng) for _ in tables])
    angles = turns(poses)
    each = [turns(q) for q in poses]
    directions = rng.normal(size=(len(tables), N_POSES, 1, 3))
    directions /= np.linalg.norm(directions, axis=-1, keepdims=True)

    def stacked() -> np.ndarray:
        return trace_point(robot.structure, tables, angles).jacobian(directions).table

    def one_by_one() -> np.ndarray:
        return np.stack([trace_point(robot.structure, table, turned).jacobian(direction).table
                         for table, turned, direction in zip(tables, each, directions,
                                                             strict=True)])

    ours_s, together = median_time(stacked, 50)
    theirs_s, apart = median_time(one_by_one, 50)
    assert np.array_equal(together, apart)
    kernel = "compiled" if takes_compiled() else "numpy"
    report(f"{len(tables)} trials' cable Jacobians ({N_POSES} poses each, {kernel} kernel): "
           "one call vs one a trial", ours_s, theirs_s, "one a trial")


if __name__ == "__main__":
    main()
