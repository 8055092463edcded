"""The MuJoCo digital twin: synthetic measurements from an independent physical model.

The calibration core fits ``‖P(D + X, q) − P_E‖`` to measured lengths; this package produces
those lengths from a MuJoCo model of a perturbed robot (built with ``mujoco.MjSpec``), with a
spatial tendon as the drawstring, optional joint servos of finite stiffness loaded by gravity
and the cable's tension, joint-level errors (transmission error, backlash), the arm's
repeatability and the encoder's noise, resolution, outliers and offset, as a scenario
(:mod:`twin.scenario`) describes them. Everything random is drawn from one generator seeded by
the scenario or the caller.

Public API (SI inside: m, rad)::

    from twin.scenario import load_scenario
    from twin.sim import simulate, write_simulation, Twin, build_spec

    scenario = load_scenario("scenarios/paper_irb120.toml")
    sim = simulate(scenario, seed=None)      # Simulation; seed None -> scenario.seed
    sim.robot, sim.true_robot                # nominal and true RobotModel
    sim.delta                                # (4, n) true D-H errors, m and rad
    sim.port_m, sim.port_nominal_m           # (3,) true port / port the calibration is told
    sim.measurements                         # Measurements: recorded q, noisy readings
    sim.truth                                # the dict written to truth.json (mm, deg)
    write_simulation("out/run", sim)         # measurements.csv, robot.toml, truth.json,
                                             # capture.toml, each written atomically

    twin = Twin.build(true_robot, port_m, physics=scenario.physics,
                      joint_errors=sim.joint_errors)   # physics and joint errors optional
    twin.lengths(q_rad)                      # (m, 6) rad -> (m,) m, noise-free, at rest
    twin.at_rest(q_rad)                      # actual joints, lengths, flange positions
    spec = build_spec(robot, port_m=None)    # mujoco.MjSpec of any 6-joint D-H arm

Importing this package imports MuJoCo; the calibration core and the scenario never import it.
"""

from twin.sim.builder import build_spec, model_xml
from twin.sim.equilibrium import static_equilibrium
from twin.sim.mujoco_twin import AtRest, Twin
from twin.sim.poses import read_pose_plan, sample_poses, usable, violations
from twin.sim.simulate import Simulation, simulate, write_simulation
from twin.sim.touches import touch_poses

__all__ = [
    "AtRest",
    "Simulation",
    "Twin",
    "build_spec",
    "model_xml",
    "read_pose_plan",
    "sample_poses",
    "simulate",
    "static_equilibrium",
    "touch_poses",
    "usable",
    "violations",
    "write_simulation",
]
