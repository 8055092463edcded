"""Scenarios: the pure description of what the twin simulates, read from TOML.

A scenario states the nominal robot, the true errors to draw (perturbation, joint-level
errors), the instrument and its noise, the physics (servo stiffness, gravity, tension), the
constraints a pose must meet, and how the data are to be calibrated. Nothing here imports
MuJoCo: the twin that simulates a scenario is :mod:`twin.sim`.

Public API (SI inside: m, rad)::

    from twin.scenario import load_scenario

    scenario = load_scenario("scenarios/paper_irb120.toml")  # Scenario; InputError if invalid
    scenario.robot, scenario.port_m          # nominal robot, true port (3,) m
    scenario.perturbation.draw(rng)          # (4, n) true D-H errors, m and rad
    scenario.noise.read(length_m, rng)       # encoder readings of true lengths
    scenario.joint_errors.actual(q, approach)  # where the joints really stand
"""

from twin.scenario.constraints import PoseConstraints
from twin.scenario.description import Scenario
from twin.scenario.instrument import Instrument
from twin.scenario.joint_errors import JointErrors
from twin.scenario.noise import NoiseModel, Readings
from twin.scenario.perturbation import DISTRIBUTIONS, Perturbation
from twin.scenario.physics import RIGID, Physics, true_inertia
from twin.scenario.reader import load_scenario, parse_scenario

__all__ = [
    "DISTRIBUTIONS",
    "RIGID",
    "Instrument",
    "JointErrors",
    "NoiseModel",
    "Perturbation",
    "Physics",
    "PoseConstraints",
    "Readings",
    "Scenario",
    "load_scenario",
    "parse_scenario",
    "tracker_readings",
    "true_inertia",
]
