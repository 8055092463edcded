"""Identifiability and measurement design, measured side by side in one run.

Run by hand: ``python bench/bench_design.py``. IRB 120, port (600, −400, 100) mm, σ = 0.01 mm.

1. Rank and unidentifiable directions at the nominal geometry (200 random poses) with the port
   known, unknown, the length offset unknown, and both.
2. 30 D-optimal poses (greedy + exchange among 2000 random candidates) against 30 random poses
   (20 draws): O1, O3, O4, condition and the predicted (Cramér–Rao) RMS flange error over 1000
   workspace poses; the time of greedy + exchange.
3. The same plans used for real: lm-base calibrations on noisy synthetic data (20 noise draws,
   a known ~1.3 mm perturbation), true RMS flange error over the workspace.
4. The port chosen among candidate positions.
"""

from __future__ import annotations

import statistics

import numpy as np
from _timing import median_time, tiny_run

from twin.analysis.identifiability import measurement_identifiability
from twin.analysis.uncertainty import rms_distance
from twin.calibration.settings import CalibrationSettings
from twin.calibration.setup import make_model
from twin.design.optimal import choose_port, plan_poses, score_poses
from twin.io.robot_file import default_robot
from twin.kinds.length import length_measurements
from twin.problem import Problem
from twin.rig import Rig
from twin.robot import random_poses
from twin.solvers import get_solver
from twin.stopping import Budget
from twin.synthetic import synthesize
from twin.units import dh_rows_from_display, m_to_mm, mm_to_m

PORT_M = mm_to_m([600.0, -400.0, 100.0])
SIGMA_M = float(mm_to_m(0.01))
N_POSES = 30
DRAWS = 20
DELTA = dh_rows_from_display({
    "a": [0.5, -0.8, 0.6, 0.3, -0.4, 0.2],
    "d": [0.7, 0.4, -0.6, 0.5, 0.3, -0.5],
    "alpha": [0.1, -0.2, 0.15, -0.1, 0.2, 0.1],
    "theta": [0.2, 0.1, -0.15, 0.1, -0.2, 0.05],
})


def main() -> None:
    global N_POSES, DRAWS
    tiny = tiny_run(__doc__)
    if tiny:
        N_POSES, DRAWS = 26, 2
    robot = default_robot()
    rng = np.random.default_rng(0)

    print("1. Identifiability at the nominal geometry, 200 random poses")
    q = random_poses(robot, 40 if tiny else 200, rng)
    data = length_measurements(q, np.ones(len(q)))
    for port, offset in [(False, False), (True, False), (False, True), (True, True)]:
        model = make_model(robot, Rig.cable(PORT_M),
                           settings=CalibrationSettings(estimate=(*(["port"] if port else []),
                                                                  *(["offset"] if offset else []))))
        ident = measurement_identifiability(model, np.zeros(model.n_params), data)
        label = "known port" + (" +port" if port else "") + (" +offset" if offset else "")
        print(f"  {label:<24} rank {ident.rank:>2} of {ident.n_params}, condition "
              f"{ident.condition:6.1f}: {', '.join(ident.unidentifiable)}")

    print(f"\n2. {N_POSES} D-optimal vs {N_POSES} random poses (predicted, σ = 0.01 mm)")
    model = make_model(robot, Rig.cable(PORT_M))
    x0 = np.zeros(24)
    candidates = random_poses(robot, 60 if tiny else 2000, rng)
    workspace = random_poses(robot, 20 if tiny else 1000, rng)
    plan_s, plan = median_time(lambda: plan_poses(model, x0, candidates, N_POSES), 1 if tiny else 5)
    planned = score_poses(model, x0, plan.q_rad, plan.base_mask, SIGMA_M, workspace)
    random_sets = [random_poses(robot, N_POSES, rng) for _ in range(DRAWS)]
    drawn = [score_poses(model, x0, qr, plan.base_mask, SIGMA_M, workspace) for qr in random_sets]

    def median(values: list[float]) -> float:
        return statistics.median(values)

    print("  poses                O1       O3         O4  condition  flange RMS [mm]")
    o = planned.observability
    print(f"  planned        {o.o1:8.4f} {o.o3:8.4f} {o.o4:10.6f} {o.condition:10.1f}"
          f" {float(m_to_mm(planned.flange_rms_m)):16.4f}")
    print(f"  random median  {median([d.observability.o1 for d in drawn]):8.4f} "
          f"{median([d.observability.o3 for d in drawn]):8.4f} "
          f"{median([d.observability.o4 for d in drawn]):10.6f} "
          f"{median([d.observability.condition for d in drawn]):10.1f}"
          f" {float(m_to_mm(median([d.flange_rms_m for d in drawn]))):16.4f}")
    best = min(d.flange_rms_m for d in drawn)
    print(f"  ratio random/planned flange RMS: median "
          f"{median([d.flange_rms_m for d in drawn]) / planned.flange_rms_m:.2f}, "
          f"best random draw {best / planned.flange_rms_m:.2f}")
    print(f"  greedy + exchange over 2000 candidates: {plan_s:.3f} s "
          f"({plan.selection.exchanges} exchanges)")

    print(f"\n3. lm-base on noisy data, {DRAWS} noise draws, true flange RMS error [mm]")
    true_robot = robot.perturbed(DELTA.ravel())
    errors: dict[str, list[float]] = {"planned": [], "random": []}
    budget = Budget()
    solver = get_solver("lm-base")
    for draw in range(DRAWS):
        noise_rng = np.random.default_rng(100 + draw)
        for label, poses in (("planned", plan.q_rad), ("random", random_sets[draw])):
            # Every planned pose trains; the validation set only feeds the history.
            measured = synthesize(true_robot, poses, PORT_M, SIGMA_M, noise_rng)
            solved = solver.solve(Problem(model, measured, measured), budget, noise_rng)
            identified = model.flange_positions(solved.x, model.poses(workspace))
            errors[label].append(rms_distance(identified, true_robot.flange_positions(workspace)))
    for label, values in errors.items():
        print(f"  {label:<8} median {float(m_to_mm(median(values))):.4f}  "
              f"max {float(m_to_mm(max(values))):.4f}")
    ratio = median(errors["random"]) / median(errors["planned"])
    print(f"  ratio random/planned (median): {ratio:.2f}")

    print("\n4. Port among candidates (D-optimal 30-pose plan each, predicted flange RMS)")
    ports_mm = np.array([[600, -400, 100], [400, 400, 0], [0, 600, 300], [800, 0, 0],
                         [300, 0, 1200], [-600, -600, 0]], dtype=float)
    choice = choose_port(model, mm_to_m(ports_mm), candidates, N_POSES, SIGMA_M, workspace)
    for k, (port, rms) in enumerate(zip(ports_mm, choice.flange_rms_m, strict=True)):
        mark = "  <- chosen" if k == choice.best else ""
        print(f"  ({', '.join(f'{v:g}' for v in port)}) mm: {float(m_to_mm(rms)):.4f} mm{mark}")


if __name__ == "__main__":
    main()
