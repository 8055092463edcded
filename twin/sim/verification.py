"""Compensation measured in the twin: simulate a scenario's capture, calibrate it, and move the
true robot (MuJoCo) to random reachable targets through the nominal model, the identified model
and the true D-H table; the true flange errors say what compensation buys.

The robot visits the targets in order from home; the twin's joints then come from the
directions of the commands actually sent (approach moves where the compensation asks for them).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from twin.calibration.pipeline import calibrate
from twin.calibration.result import CalibrationResult
from twin.compensation.check import CompensationCheck, check_compensation
from twin.compensation.joints import compensate_targets, solve_in_order
from twin.compensation.targets import reachable_targets
from twin.dataset import approach_directions
from twin.report.display import mm
from twin.scenario import Scenario
from twin.sim.mujoco_twin import Twin
from twin.sim.simulate import Simulation, simulate
from twin.unknowns import Stage


class Verification(NamedTuple):
    """Compensation measured in the twin (:func:`verify_compensation`)."""

    simulation: Simulation
    """The simulated capture that was calibrated."""
    result: CalibrationResult
    """Its calibration."""
    checks: dict[str, CompensationCheck]
    """True flange errors per compensation: ``identified model`` (or ``identified table`` when
    the result has no joint-level errors), then ``true D-H table``; each holds the nominal
    joints' errors too."""
    approach_moves: int
    """Targets the identified model reaches only with an approach move (a joint moving less than
    its backlash from the target before)."""


def verify_compensation(scenario: Scenario, *, seed: int | None = None, method: str = "lm",
                        count: int, progress: Callable[[str], None] = lambda line: None
                        ) -> Verification:
    """Simulate, calibrate, and compare true flange errors with and without compensation.

    Args:
        scenario: What to simulate and how to calibrate it.
        seed: Seed of the simulation (None: the scenario's); the calibration and the targets
            draw from the simulation's seed.
        method: The calibration method.
        count: Random reachable targets.
        progress: Called with a line at each stage (simulated, calibrated, targets drawn).
    """
    sim = simulate(scenario, seed=seed)
    progress(f"{scenario.name}: simulated {len(sim.measurements)} poses (seed {sim.seed}); "
             f"calibrating {'+'.join(scenario.calibration.errors)}…")
    result = calibrate(sim.robot, sim.measurements, rig=sim.rig_told_pulled, method=method,
                       settings=scenario.calibration, seed=sim.seed)
    scored = "validation" if result.validated else "train"
    progress(f"  {result.method}: {scored} RMSE {mm(result.metrics[scored].rmse)} "
             f"(before {mm(result.metrics['before'].rmse)})")
    twin = Twin.build(sim.true_robot, sim.port_m, scenario.physics, sim.joint_errors,
                      sim.rig.attachment_m)
    rng = np.random.default_rng(sim.seed)
    q_nominal, target_m = reachable_targets(sim.robot, count, rng)
    progress(f"{count} random reachable targets: solving and moving the true robot…")
    at_nominal = twin.flange_positions(q_nominal, approach_directions(q_nominal))
    extended = any(group.stage == Stage.JOINTS for group in result.model.groups)
    ordered = solve_in_order(result.model, result.x, lambda arm, joints: compensate_targets(
        arm, target_m, q_nominal, joints), q_nominal)
    solutions = {
        "identified model" if extended else "identified table": ordered.solved,
        "true D-H table": compensate_targets(sim.true_robot, target_m, q_nominal),
    }
    checks = {}
    for label, solved in solutions.items():
        # Approach moves where the compensation asks for them, else straight from the row
        # before.
        approach = approach_directions(solved.q_rad) if ordered.approach is None \
            or solved is not ordered.solved else ordered.approach
        reached = twin.flange_positions(solved.q_rad, approach)
        checks[label] = check_compensation(target_m, at_nominal, reached, solved)
    return Verification(sim, result, checks, int(np.sum(ordered.approach_moves)))
