"""A scenario: what the twin simulates and how the data are to be calibrated (SI inside).

Read from a TOML file by :mod:`twin.scenario.reader`; simulated by :mod:`twin.sim.simulate`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from twin.analysis.misfit import reading_sigma
from twin.arrays import Array
from twin.calibration.settings import CalibrationSettings
from twin.problem import DEFAULT_SIGMA_M
from twin.robot import RobotModel
from twin.scenario.constraints import PoseConstraints
from twin.scenario.instrument import Instrument
from twin.scenario.joint_errors import JointErrors
from twin.scenario.noise import NoiseModel
from twin.scenario.perturbation import Perturbation
from twin.scenario.physics import Physics
from twin.scenario.thermal import Thermal


@dataclass(frozen=True)
class Scenario:
    """A validated scenario (SI inside).

    Attributes:
        name: Short name.
        description: What the scenario is for.
        seed: Default seed of every random draw.
        robot: The nominal robot (what the calibration is told).
        instrument: What measures: the kind and its setup (ports, attachment, tracker,
            fixture…: :mod:`twin.scenario.instrument`).
        perturbation: How the true D-H errors are drawn.
        pose_count: Number of poses; with a plan, its first rows (0: all of them).
        pose_plan: Plan CSV of poses, or None to sample.
        constraints: What a pose must satisfy.
        noise: Encoder noise and repeatability.
        joint_errors: Joint-level errors (phases as given, or zeros when drawn).
        draw_phases: Whether transmission phases are drawn uniformly per seed.
        physics: Servo stiffness, gravity and tension.
        calibration: How the data are calibrated (``[calibration]``); its noise is
            :attr:`reading_sigma_m`, what the scenario's instrument states.
        thermal: A warm-up during the capture (``[thermal]``: the links grow with a
            temperature ramp, reference poses revisited), or None.
        study: The ``[study]`` table as written, for twin.study.
        expect: The ``[expect]`` table as written, for twin.study.expect (`twin check`).
        source: The file, or None.
    """

    name: str
    seed: int
    robot: RobotModel
    instrument: Instrument
    perturbation: Perturbation
    pose_count: int
    description: str = ""
    pose_plan: Path | None = None
    constraints: PoseConstraints = field(default_factory=PoseConstraints)
    noise: NoiseModel = field(default_factory=NoiseModel)
    joint_errors: JointErrors | None = None
    draw_phases: bool = True
    physics: Physics = field(default_factory=Physics)
    study: dict[str, Any] = field(default_factory=dict)
    expect: dict[str, Any] = field(default_factory=dict)
    source: Path | None = None
    calibration: CalibrationSettings = field(default_factory=CalibrationSettings)
    thermal: Thermal | None = None

    @property
    def reading_sigma_m(self) -> float:
        """The noise 1σ of one reading the calibration is told, m: the instrument's (a cable
        encoder's σ with its resolution folded in, a tracker's per-axis RMS) and the robot's
        repeatability (:func:`twin.analysis.misfit.reading_sigma`); the default 0.01 mm when both
        are zero. What twin simulate writes to capture.toml, so studies and `twin calibrate` on a
        simulated capture tell the filters and the misfit test the same."""
        instrument = self.instrument.setup.instrument_sigma_m(self.noise.encoder_sigma_m)
        sigma = reading_sigma(instrument if instrument > 0 else DEFAULT_SIGMA_M,
                              self.noise.repeatability_m)
        return sigma

    @property
    def port_m(self) -> Array | None:
        """The true port of the instrument's cable (its first station's with several), shape
        (3,), m; None without a cable."""
        ports = self.instrument.setup.ports_m
        return ports[0] if len(ports) else None

    def __post_init__(self) -> None:
        n = self.robot.n_joints
        if self.joint_errors is None:
            object.__setattr__(self, "joint_errors", JointErrors.none(n))
        if self.pose_count < (0 if self.pose_plan is not None else 1):
            raise ValueError("pose_count: expected >= 1 (>= 0 with a plan)")
        if self.perturbation.scale.shape != (4, n):
            raise ValueError(f"perturbation scale: expected shape (4, {n})")
        if self.thermal is not None and self.thermal.expansion_m_per_k.shape != (2, n):
            raise ValueError(f"thermal expansion: expected shape (2, {n})")
