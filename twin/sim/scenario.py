"""Scenarios: declarative TOML files that say what the twin simulates.

Every key is optional unless marked; lengths in mm, angles in degrees (arc-seconds for the
joint errors), paths relative to the scenario file::

    name = "paper_irb120"                  # required
    description = "..."
    seed = 7                               # required: seeds every random draw
    robot = "../models/irb120.toml"        # nominal model (model TOML or URDF, 4 to 7 joints);
                                           # default: the packaged IRB 120

    [port]
    position_mm = [600.0, -400.0, 100.0]   # required: true port, base frame
    told_error_mm = 0.0                    # the calibration is told position + N(0, σ²) per axis
    # told_mm = [601.0, -400.0, 100.0]     # ... or exactly this (not both)

    robot_base_link = "base_link"          # for a URDF robot: its chain (default: the root
    robot_tip_link = "tool0"               #   link to tool0, flange or the one leaf)

    [perturbation]                         # the true table errors, drawn per seed
    distribution = "uniform"               # "uniform": ±scale; "normal": σ = scale
    a_mm = 1.0                             # a number, or a list of one per joint
    d_mm = 1.0                             # (not used on Hayati joints, which have no d)
    beta_deg = 0.1                         # Hayati joints' β (default: alpha_deg)
    alpha_deg = 0.1
    theta_deg = 0.1

    [poses]
    count = 120                            # required unless plan is given
    plan = "plan.csv"                      # q1..qN in degrees; replaces random sampling
    min_flange_height_mm = 50.0
    cable_clearance_mm = 0.0

    [encoder]
    range_mm = [50.0, 1500.0]              # cable lengths the encoder reads
    sigma_mm = 0.0                         # Gaussian noise 1σ
    resolution_mm = 0.004                  # quantisation step (0: none)
    outlier_rate = 0.0                     # share of readings with a gross error
    outlier_mm = 0.0                       # its typical size (random sign, ×U(0.5, 1.5))
    offset_mm = 0.0                        # unknown constant offset of the readings

    [joints]                               # joint-level errors (see twin.sim.joint_errors)
    repeatability_mm = 0.0                 # RMS flange jitter from the joints
    transmission_arcsec = 0.0              # amplitude, number or one per joint
    transmission_harmonic = 1              # cycles per joint revolution
    transmission_phase_deg = [...]         # one per joint; drawn uniformly when absent
    backlash_arcsec = 0.0                  # full lash, number or one per joint

    [physics]
    compliance = false                     # joint servos of finite stiffness
    stiffness_nm_per_rad = [...]           # required with compliance
    gravity = true                         # with compliance
    tension_n = 0.0                        # cable tension, with compliance
    mass_error = 0.0                       # true masses and centres of mass off the file's by
                                           # up to this share, drawn per seed (with compliance)

    [calibration]                          # how the data are calibrated (studies, capture.toml)
    train_fraction = 0.8
    estimate_port = false
    estimate_offset = false
    stop = "converge"                      # stopping protocol: "converge" or "paper"
    max_iterations = 200                   # optional: iteration limit of every method and stage
    errors = ["dh"]                        # the robot's error groups the calibration fits:
                                           # dh, transmission, backlash, compliance (or
                                           # link_compliance: masses unknown link by link)

    [study]                                # left to twin.study: passed through unread
    [expect]                               # left to twin.study.expect (`twin check`): unread

Every mistake is one :class:`~twin.errors.InputError` naming the file, the key, what was found
and what was expected.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from twin.dataset import MAX_POSES
from twin.errors import InputError
from twin.io.paths import read_toml
from twin.io.robot_file import load_robot
from twin.rig import MAX_TENSION_N
from twin.robot import RobotModel, default_robot
from twin.sim.joint_errors import JointErrors
from twin.sim.noise import NoiseModel
from twin.sim.perturbation import DISTRIBUTIONS, Perturbation
from twin.sim.physics import Physics
from twin.sim.poses import PoseConstraints
from twin.stopping import MAX_ITERATIONS, PROTOCOLS, Budget
from twin.units import deg_to_rad, mm_to_m, rad_to_deg
from twin.unknowns import ERRORS

Array = NDArray[np.float64]
ARCSEC_PER_DEG = 3600.0

_TOP = ("name", "description", "seed", "robot", "robot_base_link", "robot_tip_link", "port",
        "perturbation", "poses", "encoder", "joints", "physics", "calibration", "study", "expect")
_TABLES = {
    "port": ("position_mm", "told_error_mm", "told_mm"),
    "perturbation": ("distribution", "a_mm", "d_mm", "beta_deg", "alpha_deg", "theta_deg"),
    "poses": ("count", "plan", "min_flange_height_mm", "cable_clearance_mm"),
    "encoder": ("range_mm", "sigma_mm", "resolution_mm", "outlier_rate", "outlier_mm",
                "offset_mm"),
    "joints": ("repeatability_mm", "transmission_arcsec", "transmission_harmonic",
               "transmission_phase_deg", "backlash_arcsec"),
    "physics": ("compliance", "stiffness_nm_per_rad", "gravity", "tension_n", "mass_error"),
    "calibration": ("train_fraction", "estimate_port", "estimate_offset", "stop",
                    "max_iterations", "errors"),
}
DEFAULT_RESOLUTION_MM = 0.004
MAX_MASS_ERROR = 0.9
"""Largest ``[physics] mass_error``: a link may weigh a tenth of what its file says, not nothing."""


@dataclass(frozen=True)
class Scenario:
    """A validated scenario (SI inside).

    Attributes:
        name: Short name.
        description: What the scenario is for.
        seed: Default seed of every random draw.
        robot: The nominal robot (what the calibration is told).
        port_m: True port, shape (3,), m.
        port_told_m: The port the calibration is told, shape (3,), m; None means the true port
            plus an N(0, ``port_error_m``²) draw per axis.
        port_error_m: 1σ per axis of the told port's error, m.
        perturbation: How the true D-H errors are drawn.
        pose_count: Number of poses; with a plan, its first rows (0: all of them).
        pose_plan: Plan CSV of poses, or None to sample.
        constraints: What a pose must satisfy.
        noise: Encoder noise and repeatability.
        joint_errors: Joint-level errors (phases as given, or zeros when drawn).
        draw_phases: Whether transmission phases are drawn uniformly per seed.
        physics: Servo stiffness, gravity and tension.
        train_fraction: Share of poses for identification, or None (the core's 80 %).
        estimate_port: Hint: calibrate with a port correction.
        estimate_offset: Hint: calibrate with a length offset.
        stop: Stopping protocol of the calibration, one of :data:`twin.stopping.PROTOCOLS`.
        max_iterations: Iteration limit of every method and stage, or None (the protocol's).
        errors: The robot's error groups the calibration fits (:data:`twin.unknowns.ERRORS`).
        study: The ``[study]`` table as written, for twin.study.
        expect: The ``[expect]`` table as written, for twin.study.expect (`twin check`).
        source: The file, or None.
    """

    name: str
    seed: int
    robot: RobotModel
    port_m: Array
    perturbation: Perturbation
    pose_count: int
    description: str = ""
    port_told_m: Array | None = None
    port_error_m: float = 0.0
    pose_plan: Path | None = None
    constraints: PoseConstraints = field(default_factory=PoseConstraints)
    noise: NoiseModel = field(default_factory=NoiseModel)
    joint_errors: JointErrors | None = None
    draw_phases: bool = True
    physics: Physics = field(default_factory=Physics)
    train_fraction: float | None = None
    estimate_port: bool = False
    estimate_offset: bool = False
    stop: str = PROTOCOLS[0]
    max_iterations: int | None = None
    errors: tuple[str, ...] = ("dh",)
    study: dict[str, Any] = field(default_factory=dict)
    expect: dict[str, Any] = field(default_factory=dict)
    source: Path | None = None

    @property
    def budget(self) -> Budget:
        """The iteration limits and stopping tests the calibration runs with."""
        return Budget.named(self.stop, self.max_iterations)

    def __post_init__(self) -> None:
        n = self.robot.n_joints
        port = np.array(self.port_m, dtype=np.float64)
        if port.shape != (3,) or not np.all(np.isfinite(port)):
            raise ValueError("port_m: expected 3 finite values")
        port.setflags(write=False)
        object.__setattr__(self, "port_m", port)
        if self.port_told_m is not None:
            told = np.array(self.port_told_m, dtype=np.float64)
            told.setflags(write=False)
            object.__setattr__(self, "port_told_m", told)
        if self.joint_errors is None:
            object.__setattr__(self, "joint_errors", JointErrors.none(n))
        if self.pose_count < (0 if self.pose_plan is not None else 1):
            raise ValueError("pose_count: expected >= 1 (>= 0 with a plan)")
        if self.perturbation.scale.shape != (4, n):
            raise ValueError(f"perturbation scale: expected shape (4, {n})")
        if self.train_fraction is not None and not 0 < self.train_fraction < 1:
            raise ValueError("train_fraction: expected in (0, 1)")
        if self.stop not in PROTOCOLS:
            raise ValueError(f"stop: expected one of {', '.join(PROTOCOLS)}")


class _Table:
    """Typed access to one TOML table with errors that name the file and key."""

    def __init__(self, document: dict[str, Any], name: str, source: Path, allowed: tuple[str, ...]):
        self.name, self.source = name, source
        value = document.get(name, {}) if name else document
        if not isinstance(value, dict):
            raise InputError(f"{value!r}", "a table", source=source, where=f"[{name}]")
        self.values: dict[str, Any] = value
        unknown = sorted(set(value) - set(allowed))
        if unknown:
            raise InputError(f"unknown key {unknown[0]!r}", "one of " + ", ".join(allowed),
                             source=source, where=self._where(None))

    def _where(self, key: str | None) -> str:
        if not self.name:
            return key or ""
        return f"[{self.name}]" + (f" {key}" if key else "")

    def error(self, key: str, found: str, expected: str) -> InputError:
        return InputError(found, expected, source=self.source, where=self._where(key))

    def has(self, key: str) -> bool:
        return key in self.values

    def required(self, key: str, expected: str) -> Any:
        if key not in self.values:
            raise self.error(key, "nothing", expected)
        return self.values[key]

    def number(self, key: str, default: float | None = None, *, minimum: float | None = None,
               maximum: float | None = None, strict_minimum: bool = False) -> float:
        value = self.values.get(key, default)
        expected = "a number" + (f" {'>' if strict_minimum else '>='} {minimum:g}"
                                 if minimum is not None else "") \
            + (f" <= {maximum:g}" if maximum is not None else "")
        if value is None:
            raise self.error(key, "nothing", expected)
        if isinstance(value, bool) or not isinstance(value, int | float) \
                or not math.isfinite(value) \
                or (minimum is not None and (value <= minimum if strict_minimum
                                             else value < minimum)) \
                or (maximum is not None and value > maximum):
            raise self.error(key, repr(value), expected)
        return float(value)

    def integer(self, key: str, default: int | None = None, *, minimum: int = 0,
                maximum: int | None = None) -> int:
        value = self.values.get(key, default)
        if isinstance(value, bool) or not isinstance(value, int) or value < minimum \
                or (maximum is not None and value > maximum):
            within = f"in {minimum}..{maximum}" if maximum is not None else f">= {minimum}"
            raise self.error(key, repr(value), f"an integer {within}")
        return int(value)

    def boolean(self, key: str, default: bool) -> bool:
        value = self.values.get(key, default)
        if not isinstance(value, bool):
            raise self.error(key, repr(value), "true or false")
        return value

    def text(self, key: str, default: str | None = None) -> str:
        value = self.values.get(key, default)
        if not isinstance(value, str):
            raise self.error(key, repr(value), "a string")
        return value

    def vector(self, key: str, length: int, *, per_joint: bool = False, minimum: float | None
               = None, default: float | list[float] | None = None) -> Array:
        """A list of ``length`` numbers (or one number for all, when ``per_joint``)."""
        value = self.values.get(key, default)
        what = f"{length} numbers" + (" (or one for all joints)" if per_joint else "") \
            + (f" >= {minimum:g}" if minimum is not None else "")
        if per_joint and isinstance(value, int | float) and not isinstance(value, bool):
            value = [value] * length
        if not isinstance(value, list) or len(value) != length or any(
            isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v)
            or (minimum is not None and v < minimum) for v in value
        ):
            raise self.error(key, repr(value), what)
        return np.array(value, dtype=np.float64)


def parse_scenario(document: dict[str, Any], source: Path) -> Scenario:
    """Validate a parsed scenario document (paths are relative to ``source``'s folder).

    Raises:
        InputError: naming the key that is wrong.
    """
    top = _Table(document, "", source, _TOP)
    tables = {name: _Table(document, name, source, keys) for name, keys in _TABLES.items()}
    name = top.text("name") if top.has("name") else top.required("name", "a scenario name")
    folder = source.parent
    links = {key: top.text(f"robot_{key}") if top.has(f"robot_{key}") else None
             for key in ("base_link", "tip_link")}
    if not top.has("robot") and any(links.values()):
        raise top.error("robot_base_link", "robot_base_link or robot_tip_link without robot",
                        "robot = \"arm.urdf\" beside them")
    robot = load_robot(folder / top.text("robot"), **links) if top.has("robot") \
        else default_robot()
    n = robot.n_joints
    if not top.has("seed"):
        top.required("seed", "an integer seed")
    passed_through = {}
    for key in ("study", "expect"):
        value = document.get(key, {})
        if not isinstance(value, dict):
            raise InputError(f"{value!r}", "a table (read by twin.study)", source=source,
                             where=f"[{key}]")
        passed_through[key] = value

    port = tables["port"]
    port.required("position_mm", "the true port [x, y, z] in mm")
    port_m = mm_to_m(port.vector("position_mm", 3))
    if port.has("told_mm") and port.has("told_error_mm"):
        raise port.error("told_mm", "both told_mm and told_error_mm", "at most one of them")
    port_told_m = mm_to_m(port.vector("told_mm", 3)) if port.has("told_mm") else None
    port_error_m = float(mm_to_m(port.number("told_error_mm", 0.0, minimum=0.0)))

    pert = tables["perturbation"]
    distribution = pert.text("distribution", "uniform")
    if distribution not in DISTRIBUTIONS:
        raise pert.error("distribution", repr(distribution), "one of " + ", ".join(DISTRIBUTIONS))
    alpha_rad = deg_to_rad(pert.vector("alpha_deg", n, per_joint=True, minimum=0.0,
                                       default=0.0))
    # The second slot is d (m) on D-H joints and β (rad) on Hayati joints: each its own scale.
    beta_rad = deg_to_rad(pert.vector("beta_deg", n, per_joint=True, minimum=0.0,
                                      default=list(rad_to_deg(alpha_rad))))
    scale = np.stack([
        mm_to_m(pert.vector("a_mm", n, per_joint=True, minimum=0.0, default=0.0)),
        np.where(robot.is_length[1],
                 mm_to_m(pert.vector("d_mm", n, per_joint=True, minimum=0.0, default=0.0)),
                 beta_rad),
        alpha_rad,
        deg_to_rad(pert.vector("theta_deg", n, per_joint=True, minimum=0.0, default=0.0)),
    ])

    poses = tables["poses"]
    plan = folder / poses.text("plan") if poses.has("plan") else None
    if plan is None:
        poses.required("count", "the number of poses (or a plan)")
    count = poses.integer("count", minimum=1, maximum=MAX_POSES) if poses.has("count") else 0

    encoder = tables["encoder"]
    cable_range = mm_to_m(encoder.vector("range_mm", 2, minimum=0.0, default=[50.0, 1500.0]))
    if cable_range[0] >= cable_range[1]:
        raise encoder.error("range_mm", repr(encoder.values["range_mm"]),
                            "[min, max] with min < max")
    outlier_rate = encoder.number("outlier_rate", 0.0, minimum=0.0, maximum=1.0)
    outlier_mm = encoder.number("outlier_mm", 0.0, minimum=0.0)
    if outlier_rate > 0 and outlier_mm == 0:
        raise encoder.error("outlier_mm", "0 with outlier_rate > 0", "an outlier size > 0")

    joints = tables["joints"]
    arcsec = deg_to_rad(1.0 / ARCSEC_PER_DEG)
    harmonic = joints.vector("transmission_harmonic", n, per_joint=True, minimum=1.0, default=1)
    if np.any(harmonic != np.round(harmonic)):
        raise joints.error("transmission_harmonic", repr(joints.values["transmission_harmonic"]),
                           "whole numbers of cycles per revolution")
    draw_phases = not joints.has("transmission_phase_deg")
    joint_errors = JointErrors(
        transmission_rad=joints.vector("transmission_arcsec", n, per_joint=True, minimum=0.0,
                                       default=0.0) * arcsec,
        harmonic=harmonic,
        phase_rad=np.zeros(n) if draw_phases
        else deg_to_rad(joints.vector("transmission_phase_deg", n)),
        backlash_rad=joints.vector("backlash_arcsec", n, per_joint=True, minimum=0.0,
                                   default=0.0) * arcsec,
    )

    phys = tables["physics"]
    compliance = phys.boolean("compliance", False)
    if compliance:
        phys.required("stiffness_nm_per_rad", "the servo stiffness per joint in N·m/rad")
        if robot.mass_kg is None and phys.boolean("gravity", True):
            raise phys.error("gravity", "true with a robot model without masses",
                             "link masses in the model file (key 'mass'), or gravity = false")
        physics = Physics(
            stiffness_nm_per_rad=phys.vector("stiffness_nm_per_rad", n, per_joint=True,
                                             minimum=1.0),
            gravity=phys.boolean("gravity", True),
            tension_n=phys.number("tension_n", 0.0, minimum=0.0, maximum=MAX_TENSION_N),
            mass_error=phys.number("mass_error", 0.0, minimum=0.0, maximum=MAX_MASS_ERROR),
        )
    else:
        for key in ("stiffness_nm_per_rad", "gravity", "tension_n", "mass_error"):
            if phys.has(key):
                raise phys.error(key, f"{key} with compliance = false",
                                 "compliance = true to use it")
        physics = Physics()

    calibration = tables["calibration"]
    train_fraction = calibration.number("train_fraction", minimum=0.0, maximum=1.0,
                                        strict_minimum=True) \
        if calibration.has("train_fraction") else None
    if train_fraction == 1.0:
        raise calibration.error("train_fraction", "1.0", "a share below 1 (some poses held out)")
    stop = calibration.text("stop", PROTOCOLS[0])
    if stop not in PROTOCOLS:
        raise calibration.error("stop", repr(stop), "one of " + ", ".join(PROTOCOLS))
    max_iterations = calibration.integer("max_iterations", minimum=1) \
        if calibration.has("max_iterations") else None
    if max_iterations is not None and max_iterations > MAX_ITERATIONS:
        raise calibration.error("max_iterations", repr(max_iterations),
                                f"an integer from 1 to {MAX_ITERATIONS}")
    errors = calibration.values.get("errors", ["dh"])
    expected_errors = "a non-empty list of distinct error groups among " + ", ".join(ERRORS)
    if not isinstance(errors, list) or not errors or len(set(map(str, errors))) != len(errors) \
            or not all(isinstance(name, str) and name in ERRORS for name in errors):
        raise calibration.error("errors", repr(errors), expected_errors)
    if {"compliance", "link_compliance"} <= set(errors):
        raise calibration.error("errors", repr(errors), "compliance or link_compliance, not "
                                "both (link_compliance holds each joint's compliance)")

    return Scenario(
        name=name,
        description=top.text("description", ""),
        seed=top.integer("seed"),
        robot=robot,
        port_m=port_m,
        port_told_m=port_told_m,
        port_error_m=port_error_m,
        perturbation=Perturbation(distribution, scale, robot.is_length),
        pose_count=count,
        pose_plan=plan,
        constraints=PoseConstraints(
            min_flange_height_m=float(mm_to_m(poses.number("min_flange_height_mm", 50.0))),
            cable_min_m=float(cable_range[0]),
            cable_max_m=float(cable_range[1]),
            cable_clearance_m=float(mm_to_m(poses.number("cable_clearance_mm", 0.0,
                                                          minimum=0.0))),
        ),
        noise=NoiseModel(
            sigma_m=float(mm_to_m(encoder.number("sigma_mm", 0.0, minimum=0.0))),
            resolution_m=float(mm_to_m(encoder.number("resolution_mm", DEFAULT_RESOLUTION_MM,
                                                      minimum=0.0))),
            repeatability_m=float(mm_to_m(joints.number("repeatability_mm", 0.0, minimum=0.0))),
            outlier_rate=outlier_rate,
            outlier_m=float(mm_to_m(outlier_mm)),
            offset_m=float(mm_to_m(encoder.number("offset_mm", 0.0))),
        ),
        joint_errors=joint_errors,
        draw_phases=draw_phases,
        physics=physics,
        train_fraction=train_fraction,
        estimate_port=calibration.boolean("estimate_port", False),
        estimate_offset=calibration.boolean("estimate_offset", False),
        stop=stop,
        max_iterations=max_iterations,
        errors=tuple(name for name in ERRORS if name in errors),
        study=passed_through["study"],
        expect=passed_through["expect"],
        source=source,
    )


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario TOML file.

    Raises:
        InputError: if the file is missing, not TOML, or not a valid scenario.
    """
    path = Path(path)
    return parse_scenario(read_toml(path, "a scenario TOML file"), path)
