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
   the revolute chain's: what the prismatic path costs, on whichever kernel is installed.

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
from twin.geometry.kinematics import point_jacobian, point_position
from twin.io.robot_file import default_robot
from twin.rig import Rig
from twin.robot import random_poses
from twin.synthetic import synthesize
from twin.units import mm_to_m

REPEATS = 7
N_TABLES = 100
N_POSES = 96
N_ROWS = 1000


def report(label: str, ours_s: float, theirs_s: float, theirs: str) -> None:
    print(f"{label}\n  twin, batched   {ours_s * 1e3:10.2f} ms\n"
          f"  {theirs:<15} {theirs_s * 1e3:10.2f} ms\n  ratio           {theirs_s / ours_s:10.1f}×")


def main() -> None:
    global REPEATS, N_TABLES, N_POSES, N_ROWS
    if tiny_run(__doc__):
        REPEATS, N_TABLES, N_POSES, N_ROWS = 1, 3, 8, 10
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


if __name__ == "__main__":
    main()
