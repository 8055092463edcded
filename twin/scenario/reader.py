"""Scenarios: declarative TOML files that say what the twin simulates.

Every key is optional unless marked; lengths in mm, angles in degrees (arc-seconds for the
joint errors), paths relative to the scenario file::

    name = "paper_irb120"                  # required
    description = "..."
    seed = 7                               # required: seeds every random draw
    robot = "../models/irb120.toml"        # nominal model (model TOML or URDF, 4 to 9 joints);
                                           # default: the packaged IRB 120
    robot_base_link = "base_link"          # for a URDF robot: its chain (default: the root
    robot_tip_link = "tool0"               #   link to tool0, flange or the one leaf)

    [port]
    position_mm = [600.0, -400.0, 100.0]   # required for cable lengths: true port, base frame
    told_error_mm = 0.0                    # the calibration is told position + N(0, σ²) per axis
    # told_mm = [601.0, -400.0, 100.0]     # ... or exactly this (not both)
    # [port.stations_mm]                   # ... or an encoder moved between stations (instead of
    # front = [600.0, -400.0, 100.0]       # position_mm): true ports by name; the poses are
    # left = [500.0, 500.0, 0.0]           # shared out evenly, each told with told_error_mm

    [cable]
    attachment_mm = [0.0, 0.0, 0.0]        # true eyelet in the flange frame
    told_attachment_mm = [0.0, 0.0, 0.0]   # what the calibration is told (default: the truth)

    [measurement]                          # another instrument than the cable (see instrument.py)
    kind = "length"                        # "position": laser tracker; "point": fixed points
    sigma_mm = 0.01                        # tracker noise / ball seating, number or [x, y, z]
    tracker_pose = [2000.0, 0.0, 0.0, 0.0, 0.0, 180.0]  # base in the tracker: mm, deg (x y z)
    attachment_mm = [0.0, 0.0, 80.0]       # true target / ball centre in the flange frame
    told_attachment_mm = [0.0, 0.0, 0.0]   # what the calibration is told (default: the truth)

    [fixture]                              # fixed points: a ball fixture set down several times
    sockets_mm = [[0.0, 0.0, 0.0], [50.0, 0.0, 0.0]]   # in the fixture's frame
    placements = [[450.0, -150.0, 250.0, 0.0, 0.0, 20.0]]  # fixture in the base: mm, deg
    touches = 12                           # configurations per socket and placement
    distances = true                       # tell the calibration the socket spacings

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
    scale_ppm = 0.0                        # the encoder's scale error: it reads (1 + s) times
                                           # the cable's length, s in ppm (within ±5000)

    [joints]                               # joint-level errors (see twin.scenario.joint_errors)
    repeatability_mm = 0.0                 # RMS flange jitter from the joints
    resolution_deg = 0.0                   # the joint angles recorded to this (or one per
                                           # joint; a prismatic joint's travel is exact)
    transmission_arcsec = 0.0              # amplitude, number or one per joint (0 on a
                                           # prismatic joint)
    transmission_harmonic = 1              # cycles per joint revolution
    transmission_phase_deg = [...]         # one per joint; drawn uniformly when absent
    backlash_arcsec = 0.0                  # full lash, number or one per joint (0 on a
                                           # prismatic joint)

    [physics]
    compliance = false                     # joint servos of finite stiffness
    stiffness_nm_per_rad = [...]           # required with compliance (N/m on a prismatic
                                           # joint)
    gravity = true                         # with compliance
    tension_n = 0.0                        # cable tension, with compliance
    mass_error = 0.0                       # true masses and centres of mass off the file's by
                                           # up to this share, drawn per seed (with compliance)

    [calibration]                          # how the data are calibrated (studies, capture.toml)
    train_fraction = 0.8
    estimate_port = false
    estimate_offset = false
    estimate_scale = false                 # the encoder's scale (with the port told)
    estimate_attachment = false
    estimate_base = false                  # tracker frame (started at a rigid fit)
    loss = "linear"                        # or "huber", "soft_l1", "cauchy" (twin.loss)
    loss_scale_mm = 0.03                   # with a robust loss; default 3 σ of the noise
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

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from twin.arrays import Array
from twin.calibration.settings import joint_noise
from twin.choices import MAX_POSES, MAX_TENSION_N
from twin.dataset import TEMPERATURE_RANGE_C
from twin.io.calibration_table import KEYS, parse_calibration
from twin.io.paths import read_toml
from twin.io.robot_file import load_robot_or_default
from twin.io.table import Table
from twin.kinds import DEFAULT_KIND, KINDS
from twin.rig import Rig
from twin.robot import RobotModel
from twin.scenario.constraints import PoseConstraints
from twin.scenario.description import Scenario
from twin.scenario.instrument import Instrument
from twin.scenario.joint_errors import JointErrors
from twin.scenario.noise import NoiseModel
from twin.scenario.perturbation import DISTRIBUTIONS, Perturbation
from twin.scenario.physics import Physics
from twin.scenario.thermal import Thermal
from twin.units import ARCSEC_PER_DEG, MICRO, deg_to_rad, mm_to_m, rad_to_deg
from twin.unknowns import make_groups
from twin.unknowns.limits import group_box
from twin.unknowns.scale import BOUND as MAX_SCALE

_KIND_TABLES = {table: keys for kind in KINDS.values() for table, keys in kind.scenario_tables}
"""The tables of one kind alone (a fixed-point scenario's ``[fixture]``…)."""
_TOP = ("name", "description", "seed", "robot", "robot_base_link", "robot_tip_link", "port",
        "cable", "measurement", *_KIND_TABLES, "perturbation", "poses", "encoder", "joints",
        "physics", "thermal", "calibration", "study", "expect")
_TABLES = {
    "port": ("position_mm", "told_error_mm", "told_mm", "stations_mm"),
    "cable": ("attachment_mm", "told_attachment_mm"),
    "measurement": ("kind", *dict.fromkeys(key for kind in KINDS.values()
                                           for key in kind.measurement_keys)),
    **_KIND_TABLES,
    "perturbation": ("distribution", "a_mm", "d_mm", "beta_deg", "alpha_deg", "theta_deg"),
    "poses": ("count", "plan", "min_flange_height_mm", "cable_clearance_mm"),
    "encoder": ("range_mm", "sigma_mm", "resolution_mm", "outlier_rate", "outlier_mm",
                "offset_mm", "scale_ppm"),
    "joints": ("repeatability_mm", "resolution_deg", "transmission_arcsec",
               "transmission_harmonic", "transmission_phase_deg", "backlash_arcsec"),
    "physics": ("compliance", "stiffness_nm_per_rad", "gravity", "tension_n", "mass_error"),
    "thermal": ("start_c", "ramp_k", "seconds_per_pose", "a_um_per_k", "d_um_per_k",
                "reference_every"),
    "calibration": KEYS,
}
MAX_EXPANSION_UM_PER_K = 1000.0
"""Largest growth of a link per kelvin in a scenario, µm/K: a metre of aluminium grows 23."""
MAX_RAMP_K = 100.0
"""Largest temperature change over a capture in a scenario, K."""
DEFAULT_RESOLUTION_MM = 0.004
MAX_MASS_ERROR = 0.9
"""Largest ``[physics] mass_error``: a link may weigh a tenth of what its file says, not nothing."""


def parse_scenario(document: dict[str, Any], source: Path) -> Scenario:
    """Validate a parsed scenario document (paths are relative to ``source``'s folder).

    Each table has its own reader below, called in the order the errors are reported.

    Raises:
        InputError: naming the key that is wrong.
    """
    top = Table(document, source, allowed=_TOP)
    tables = {name: top.table(name, allowed=keys) for name, keys in _TABLES.items()}
    name = top.text("name") if top.has("name") else top.required("name", "a scenario name")
    robot = _robot(top, source.parent)
    if not top.has("seed"):
        top.required("seed", "an integer seed")
    passed_through = {key: dict(top.table(key, expected="a table (read by twin.study)").values)
                      for key in ("study", "expect")}
    instrument = _instrument(tables)
    perturbation = _perturbation(tables["perturbation"], robot)
    plan, count = _poses(tables["poses"], instrument, source.parent)
    cable_range = _cable_range(tables["encoder"])
    joint_errors, draw_phases = _joint_errors(tables["joints"], robot)
    physics = _physics(tables["physics"], robot)
    scenario = Scenario(
        name=name,
        description=top.text("description", ""),
        seed=top.integer("seed", minimum=0),
        robot=robot,
        instrument=instrument,
        perturbation=perturbation,
        pose_count=count,
        pose_plan=plan,
        constraints=_constraints(tables["poses"], cable_range),
        noise=_noise(tables["encoder"], tables["joints"], robot),
        joint_errors=joint_errors,
        draw_phases=draw_phases,
        physics=physics,
        study=passed_through["study"],
        expect=passed_through["expect"],
        source=source,
        thermal=_thermal(tables["thermal"], robot),
    )
    calibration = parse_calibration(tables["calibration"], scenario.reading_sigma_m,
                                    joint_noise((), scenario.noise.joint_resolution_rad),
                                    instrument.setup.angle_sigma_rad())
    lower, upper = group_box(make_groups(["dh"], robot, Rig())[0], calibration.bounds)
    box = (np.reshape(lower, robot.dh.shape), np.reshape(upper, robot.dh.shape))
    return replace(scenario, calibration=calibration,
                   perturbation=replace(perturbation, box=box))


def _thermal(thermal: Table, robot: RobotModel) -> Thermal | None:
    """``[thermal]``: the links' growth per kelvin (µm/K, one per joint or one for all), the
    temperature ramp and the pace of the capture, the reference pose's revisits; None when the
    table is absent."""
    if not thermal.values:
        return None
    expansion = np.stack([thermal.vector(key, robot.n_joints, per_joint=True, default=0.0,
                                         within=MAX_EXPANSION_UM_PER_K)
                          for key in ("a_um_per_k", "d_um_per_k")])
    angle = np.flatnonzero(~robot.is_length[1] & (np.abs(expansion[1]) > 0))
    if angle.size:
        raise thermal.error("d_um_per_k", f"a growth of joint {angle[0] + 1}, whose second "
                            "slot is an angle (β of a Hayati joint)", "0 for that joint")
    start = thermal.number("start_c", 20.0, minimum=TEMPERATURE_RANGE_C[0],
                           maximum=TEMPERATURE_RANGE_C[1])
    return Thermal(
        expansion_m_per_k=expansion * 1e-6, start_c=start,
        ramp_k=thermal.number("ramp_k", 0.0, minimum=-MAX_RAMP_K, maximum=MAX_RAMP_K),
        seconds_per_pose=thermal.number("seconds_per_pose", 30.0, minimum=0.0,
                                        strict_minimum=True),
        reference_every=thermal.integer("reference_every", 0, minimum=0))


def _robot(top: Table, folder: Path) -> RobotModel:
    """``robot`` (a model file or URDF beside the scenario; the IRB 120 without it) and, for a
    URDF, ``robot_base_link`` and ``robot_tip_link``."""
    links = {key: top.text(f"robot_{key}") if top.has(f"robot_{key}") else None
             for key in ("base_link", "tip_link")}
    if not top.has("robot") and any(links.values()):
        raise top.error("robot_base_link", "robot_base_link or robot_tip_link without robot",
                        "robot = \"arm.urdf\" beside them")
    return load_robot_or_default(folder / top.text("robot") if top.has("robot") else None,
                                 base_link=links["base_link"], tip_link=links["tip_link"])


def _perturbation(pert: Table, robot: RobotModel) -> Perturbation:
    """``[perturbation]``: the distribution and each table entry's scale."""
    n = robot.n_joints
    distribution = pert.text("distribution", "uniform", choices=DISTRIBUTIONS)
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
    return Perturbation(distribution, scale, robot.is_length)


def _poses(poses: Table, instrument: Instrument, folder: Path) -> tuple[Path | None, int]:
    """``[poses]``: the plan file (or None) and the number of poses to draw, unless the
    instrument sets them (fixed points: one per touch of every socket of every placement)."""
    fixed = instrument.setup.pose_count
    if fixed is not None:
        return None, fixed
    plan = folder / poses.text("plan") if poses.has("plan") else None
    if plan is None:
        poses.required("count", "the number of poses (or a plan)")
    return plan, poses.integer("count", minimum=1, maximum=MAX_POSES) if poses.has("count") \
        else 0


def _cable_range(encoder: Table) -> Array:
    """``[encoder] range_mm`` as ``[min, max]``, m; the outliers checked (:func:`_noise` reads
    them)."""
    cable_range = mm_to_m(encoder.vector("range_mm", 2, minimum=0.0, default=[50.0, 1500.0]))
    if cable_range[0] >= cable_range[1]:
        raise encoder.error("range_mm", repr(encoder.values["range_mm"]),
                            "[min, max] with min < max")
    outlier_rate = encoder.number("outlier_rate", 0.0, minimum=0.0, maximum=1.0)
    outlier_mm = encoder.number("outlier_mm", 0.0, minimum=0.0)
    if outlier_rate > 0 and outlier_mm <= 0:
        raise encoder.error("outlier_mm", "0 with outlier_rate > 0", "an outlier size > 0")
    return cable_range


def _joint_errors(joints: Table, robot: RobotModel) -> tuple[JointErrors, bool]:
    """``[joints]``' transmission error and backlash, and whether the phases are to be drawn
    (none given). They are a gearbox's angles: a prismatic joint has none in the twin."""
    n = robot.n_joints
    for key in ("transmission_arcsec", "backlash_arcsec"):
        given = joints.vector(key, n, per_joint=True, minimum=0.0, default=0.0)
        sliding = np.flatnonzero((given > 0) & robot.prismatic)
        if sliding.size:
            raise joints.error(key, f"{given[sliding[0]]:g} arcsec on joint {sliding[0] + 1}, "
                               f"prismatic ({robot.joint_names[sliding[0]]})", "0 for a "
                               "prismatic joint: the twin simulates a gearbox's angles, not "
                               "a linear axis's lead error or lost motion (a list with 0 there)")
    arcsec = deg_to_rad(1.0 / ARCSEC_PER_DEG)
    harmonic = joints.vector("transmission_harmonic", n, per_joint=True, minimum=1.0, default=1)
    if np.any(harmonic != np.round(harmonic)):
        raise joints.error("transmission_harmonic", repr(joints.values["transmission_harmonic"]),
                           "whole numbers of cycles per revolution")
    draw_phases = not joints.has("transmission_phase_deg")
    return JointErrors(
        transmission_rad=joints.vector("transmission_arcsec", n, per_joint=True, minimum=0.0,
                                       default=0.0) * arcsec,
        harmonic=harmonic,
        phase_rad=np.zeros(n) if draw_phases
        else deg_to_rad(joints.vector("transmission_phase_deg", n)),
        backlash_rad=joints.vector("backlash_arcsec", n, per_joint=True, minimum=0.0,
                                   default=0.0) * arcsec,
    ), draw_phases


def _physics(phys: Table, robot: RobotModel) -> Physics:
    """``[physics]``: servo stiffness, gravity, the cable's pull and the mass error, only with
    ``compliance = true``."""
    if not phys.boolean("compliance", False):
        for key in ("stiffness_nm_per_rad", "gravity", "tension_n", "mass_error"):
            if phys.has(key):
                raise phys.error(key, f"{key} with compliance = false",
                                 "compliance = true to use it")
        return Physics()
    phys.required("stiffness_nm_per_rad", "the servo stiffness per joint in N·m/rad (N/m "
                  "on a prismatic joint)")
    if robot.mass_kg is None and phys.boolean("gravity", True):
        raise phys.error("gravity", "true with a robot model without masses",
                         "link masses in the model file (key 'mass'), or gravity = false")
    return Physics(
        stiffness_nm_per_rad=phys.vector("stiffness_nm_per_rad", robot.n_joints, per_joint=True,
                                         minimum=1.0),
        gravity=phys.boolean("gravity", True),
        tension_n=phys.number("tension_n", 0.0, minimum=0.0, maximum=MAX_TENSION_N),
        mass_error=phys.number("mass_error", 0.0, minimum=0.0, maximum=MAX_MASS_ERROR),
    )


def _constraints(poses: Table, cable_range: Array) -> PoseConstraints:
    """What a drawn pose must meet: ``[poses]``' flange height and cable clearance, the
    encoder's range."""
    return PoseConstraints(
        min_flange_height_m=float(mm_to_m(poses.number("min_flange_height_mm", 50.0))),
        cable_min_m=float(cable_range[0]),
        cable_max_m=float(cable_range[1]),
        cable_clearance_m=float(mm_to_m(poses.number("cable_clearance_mm", 0.0, minimum=0.0))),
    )


def _noise(encoder: Table, joints: Table, robot: RobotModel) -> NoiseModel:
    """The reading's noise: ``[encoder]``'s σ, resolution, outliers, offset and scale, the
    robot's repeatability and the resolution its joint angles are recorded to (``[joints]``; an
    angle's: a prismatic joint's travel is recorded exactly)."""
    resolution = deg_to_rad(joints.vector("resolution_deg", robot.n_joints, per_joint=True,
                                          minimum=0.0, default=0.0))
    return NoiseModel(
        joint_resolution_rad=tuple(np.where(robot.prismatic, 0.0, resolution).tolist()),
        sigma_m=float(mm_to_m(encoder.number("sigma_mm", 0.0, minimum=0.0))),
        resolution_m=float(mm_to_m(encoder.number("resolution_mm", DEFAULT_RESOLUTION_MM,
                                                  minimum=0.0))),
        repeatability_m=float(mm_to_m(joints.number("repeatability_mm", 0.0, minimum=0.0))),
        outlier_rate=encoder.number("outlier_rate", 0.0, minimum=0.0, maximum=1.0),
        outlier_m=float(mm_to_m(encoder.number("outlier_mm", 0.0, minimum=0.0))),
        offset_m=float(mm_to_m(encoder.number("offset_mm", 0.0))),
        scale=_scale(encoder),
    )


def _scale(encoder: Table) -> float:
    """``[encoder] scale_ppm``, within the calibration's search bound, as a fraction (m/m)."""
    largest_ppm = MAX_SCALE * MICRO
    return encoder.number("scale_ppm", 0.0, minimum=-largest_ppm, maximum=largest_ppm,
                          expected=f"a scale error in ppm within ±{largest_ppm:g}") / MICRO


def _instrument(tables: dict[str, Table]) -> Instrument:
    """``[measurement] kind``, and the tables its kind reads
    (:meth:`twin.kinds.base.Kind.read_setup`: ``[cable]``, ``[port]``, ``[measurement]``,
    ``[fixture]``…)."""
    measurement = tables["measurement"]
    kind = KINDS.lookup(measurement.text("kind", DEFAULT_KIND, choices=tuple(KINDS)))
    for other in KINDS.values():
        for table, _ in other.scenario_tables:
            if other is not kind and tables[table].values:
                raise tables[table].error(sorted(tables[table].values)[0], f"a [{table}] table",
                                          f"[{table}] with {other.what} "
                                          f"(kind = \"{other.name}\") only")
    setup = kind.read_setup(tables)
    encoder = tables["encoder"]
    for other in KINDS.values():
        for key in other.encoder_keys:
            if encoder.has(key) and key not in kind.encoder_keys:
                raise encoder.error(key, f"{key} with {kind.what}",
                                    f"[encoder] {key} with {other.what} only")
    for key in measurement.values:
        if key != "kind" and key not in kind.measurement_keys:
            raise measurement.error(key, f"{key} with {kind.what}",
                                    f"[measurement] keys for {kind.what}: "
                                    + ", ".join(("kind", *kind.measurement_keys)))
    return Instrument(kind.name, setup)


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario TOML file.

    Raises:
        InputError: if the file is missing, not TOML, or not a valid scenario.
    """
    path = Path(path)
    return parse_scenario(read_toml(path, "a scenario TOML file"), path)
