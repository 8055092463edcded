"""One simulated capture: draw the truth, measure it with the twin, write it like a real rig.

Random draws come from one generator seeded with the seed, in a fixed order: D-H errors, the
port(s) the calibration is told, transmission phases, the true masses and centres of mass (only
with ``[physics] mass_error``), poses (station after station), joint jitter, then the
instrument's noise (cable: length noise and outliers; tracker: per-axis noise). Fixed points draw
their IK starts and seating errors in place of the poses and the jitter.

The measurements carry the direction each joint approached its pose from (the poses are visited
in order from home), which backlash depends on.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from twin.analysis.metrics import metrics
from twin.arrays import Array
from twin.dataset import REFERENCE, TEMPERATURE, TIME, Measurements, approach_directions
from twin.errors import InputError
from twin.geometry.kinematics import point_position
from twin.io.atomic import write_atomic
from twin.io.capture_file import write_capture
from twin.io.measurements import write_measurements
from twin.io.robot_file import robot_files
from twin.io.truth import TRUTH_FILE, write_truth
from twin.kinds import KINDS
from twin.kinds.bench import Visit
from twin.model import Model
from twin.rig import Rig
from twin.robot import RobotModel
from twin.scenario.description import Scenario
from twin.scenario.joint_errors import JointErrors
from twin.scenario.physics import true_inertia
from twin.scenario.thermal import REFERENCE_RTOL_RAD, Thermal
from twin.sim.mujoco_twin import AtRest, Twin
from twin.sim.poses import read_pose_plan, sample_poses
from twin.sim.touches import touch_poses
from twin.units import (
    ARCSEC_PER_DEG,
    dh_rows_to_display,
    m_to_mm,
    rad_to_deg,
    to_display,
)
from twin.unknowns.compliance import compliance_units

MEASUREMENTS_FILE = "measurements.csv"
ROBOT_FILE = "robot.toml"
CAPTURE_FILE = "capture.toml"


@dataclass(frozen=True)
class Simulation:
    """A simulated capture and the truth behind it.

    Attributes:
        scenario: What was simulated.
        seed: The seed of every draw.
        robot: The nominal robot (what the calibration is told).
        true_robot: The robot the twin simulated: nominal plus ``delta``, with its true masses
            and centres of mass.
        delta: True D-H errors, shape (4, n): rows δa [m], δd [m], δα [rad], δθ [rad].
        port_m: True port, shape (3,), m.
        port_nominal_m: The port the calibration is told, shape (3,), m.
        joint_errors: Joint-level errors, with the phases that were drawn.
        joint_sigma_rad: The joint jitter 1σ behind the repeatability, rad.
        rest: Where the arm really was at each pose: joints, cable lengths, measured point.
        measurements: Recorded joint angles and encoder readings, as written.
        outlier_rows: Rows that carry an outlier, shape (k,).
        rig: The true rig: every port, the measured point, the tracker frame, the fixed points.
        rig_told: The rig the calibration is told (ports and attachment as told, known
            distances; the tracker frame and fixed points are left to the calibration).
    """

    scenario: Scenario
    seed: int
    robot: RobotModel
    true_robot: RobotModel
    delta: Array
    port_m: Array | None
    port_nominal_m: Array | None
    joint_errors: JointErrors
    joint_sigma_rad: float
    rest: AtRest
    measurements: Measurements
    outlier_rows: NDArray[np.intp]
    rig: Rig = field(default_factory=Rig)
    rig_told: Rig = field(default_factory=Rig)

    @property
    def q_actual_rad(self) -> Array:
        """Where the joints really were, shape (m, n), rad."""
        return self.rest.q_rad

    @property
    def true_length_m(self) -> Array:
        """Noise-free cable lengths, shape (m,), m; NaN without a cable."""
        return self.rest.length_m

    @property
    def true_points_m(self) -> Array:
        """Where the measured point really was at each pose, base frame, shape (m, 3), m."""
        return self.rest.point_m

    @property
    def rig_told_pulled(self) -> Rig:
        """The rig the calibration is told, with the cable's pull the physics simulate (what
        the compliance unknowns' torques need)."""
        return replace(self.rig_told, tension_n=self.scenario.physics.tension_n)

    @property
    def physics(self) -> dict[str, Any]:
        """The physics section of truth.json."""
        return self.scenario.physics.to_dict()

    @property
    def noise(self) -> dict[str, Any]:
        """The noise section of truth.json (mm, arc-seconds)."""
        sigma_arcsec = float(rad_to_deg(self.joint_sigma_rad)) * ARCSEC_PER_DEG
        return {**self.scenario.noise.to_dict(), "joint_sigma_arcsec": sigma_arcsec}

    @property
    def effects(self) -> dict[str, float]:
        """How far the data are from the core's model, in mm (RMS over the residual rows).

        ``nominal_rmse_mm``: readings vs the nominal model on the told rig (before
        calibration; tracker positions: after the rigid fit of the tracker frame; fixed points:
        the spread of each point's nominal positions);
        ``non_geometric_mm``: noise-free readings vs the true table's rigid model at the
        recorded angles (what no D-H fit can absorb, up to refitting);
        ``flange_shift_mm``: flange displacement by joint errors, jitter and sag.
        """
        data = self.measurements
        kind = KINDS.lookup(data.kind)
        told, data = kind.prepare(self.robot, self.rig_told, data,
                                  self.scenario.calibration.noise)
        nominal = kind.align(Model(self.robot, told, kind, ()), data)
        rigid = Model(self.true_robot, self.rig, kind, ()).positions(np.zeros(0), data)
        shift = self.true_robot.flange_positions(self.q_actual_rad) \
            - self.true_robot.flange_positions(data.q_rad)
        return {
            "nominal_rmse_mm": float(m_to_mm(metrics(nominal.residuals(np.zeros(0), data))
                                             .rmse)),
            "non_geometric_mm": float(m_to_mm(np.sqrt(np.mean(
                kind.deviation(self.rest, rigid, self.rig, data) ** 2)))),
            "flange_shift_mm": float(m_to_mm(np.sqrt(np.mean(np.sum(shift**2, axis=1))))),
        }

    @property
    def joint_unknowns(self) -> dict[str, list[Any]]:
        """The true joint-level errors as a calibration's unknowns name them, in the units its
        results show (degrees, µrad/(N·m); a prismatic joint's scale in µm/m — the twin's is 0
        —, its lost motion in mm, its compliance in µm/N); null for a transmission error of a
        higher harmonic than the model's two."""
        robot, n = self.robot, self.robot.n_joints
        terms = self.joint_errors.coefficients()
        compliance = self.scenario.physics.compliance(n)
        return {
            "transmission": [[0.0] if sliding else [None if np.isnan(v) else float(v)
                                                    for v in row]
                             for row, sliding in zip(rad_to_deg(terms), robot.prismatic,
                                                     strict=True)],
            "backlash": to_display(0.5 * self.joint_errors.backlash_rad,
                                   robot.structure.joint_units)[0],
            "compliance": to_display(compliance, compliance_units(robot))[0],
        }

    @property
    def capture_truth(self) -> dict[str, Any]:
        """The truth a capture records when the virtual encoder serves this scenario and seed
        (`twin capture --robot-source sim`): the table errors and the port, which do not depend
        on the poses (the capture's are its plan's, not these)."""
        assert self.port_m is not None and self.port_nominal_m is not None  # one cable port
        return {"scenario": self.scenario.name, "seed": self.seed,
                "delta": dh_rows_to_display(self.delta, self.robot.is_length),
                "port": m_to_mm(self.port_m).tolist(),
                "port_told": m_to_mm(self.port_nominal_m).tolist()}

    @property
    def truth(self) -> dict[str, Any]:
        """The document written to truth.json (mm, degrees, arc-seconds)."""
        errors = self.joint_errors
        arcsec = float(rad_to_deg(1.0)) * ARCSEC_PER_DEG
        rig, told = self.rig, self.rig_told
        document: dict[str, Any] = {
            "scenario": self.scenario.name,
            "seed": self.seed,
            "kind": self.measurements.kind,
            "robot": {"name": self.true_robot.name,
                      "dh": dh_rows_to_display(self.true_robot.dh, self.robot.is_length)},
        }
        if self.port_m is not None and self.port_nominal_m is not None:
            document.update({"port": m_to_mm(self.port_m).tolist(),
                             "port_told": m_to_mm(self.port_nominal_m).tolist()})
        if len(rig.ports_m) > 1:
            document["ports"] = {name: m_to_mm(port).tolist()
                                 for name, port in zip(rig.port_names, rig.ports_m, strict=True)}
            document["ports_told"] = {name: m_to_mm(port).tolist() for name, port
                                      in zip(told.port_names, told.ports_m, strict=True)}
        document["attachment_mm"] = m_to_mm(rig.attachment_m).tolist()
        document["attachment_told_mm"] = m_to_mm(told.attachment_m).tolist()
        document.update(self.scenario.instrument.setup.truth(rig))
        if rig.point_names:
            document["points_mm"] = {name: m_to_mm(point).tolist() for name, point
                                     in zip(rig.point_names, rig.points_m, strict=True)}
        return {
            **document,
            "delta": dh_rows_to_display(self.delta, self.robot.is_length),
            "noise": self.noise,
            "joint_errors": {
                "transmission_arcsec": (errors.transmission_rad * arcsec).tolist(),
                "harmonic": errors.harmonic.astype(int).tolist(),
                "phase_deg": rad_to_deg(errors.phase_rad).tolist(),
                "backlash_arcsec": (errors.backlash_rad * arcsec).tolist(),
            },
            "physics": self.physics,
            "inertia": _inertia(self.true_robot),
            "joint_unknowns": self.joint_unknowns,
            "outlier_rows": self.outlier_rows.tolist(),
            **({} if self.scenario.thermal is None else {"thermal": {
                "start_c": self.scenario.thermal.start_c,
                "ramp_k": self.scenario.thermal.ramp_k,
                "a_um_per_k": (self.scenario.thermal.expansion_m_per_k[0] * 1e6).tolist(),
                "d_um_per_k": (self.scenario.thermal.expansion_m_per_k[1] * 1e6).tolist(),
                "delta_at": "start_c: the table grows from there"}}),
            "train_fraction": self.scenario.calibration.train_fraction,
            "effects": self.effects,
        }


def _inertia(robot: RobotModel) -> dict[str, Any]:
    """The true masses (kg) and centres of mass (mm, each link's D-H frame), or nulls."""
    return {"mass_kg": None if robot.mass_kg is None else robot.mass_kg.tolist(),
            "com_mm": None if robot.com_m is None else m_to_mm(robot.com_m).tolist()}


def simulate(scenario: Scenario, seed: int | None = None) -> Simulation:
    """Simulate one capture of a scenario: the truth drawn here, the readings made by the
    scenario's instrument (:meth:`twin.kinds.bench.Setup.capture`) on the twin.

    Args:
        scenario: What to simulate.
        seed: Seed of every random draw; None uses the scenario's.

    Raises:
        InputError: if a pose plan is invalid, or the pose constraints leave no usable pose.
    """
    seed = scenario.seed if seed is None else int(seed)
    rng = np.random.default_rng(seed)
    n = scenario.robot.n_joints
    setup = scenario.instrument.setup
    delta = scenario.perturbation.draw(rng)
    true_robot = scenario.robot.perturbed(delta.ravel())
    rig, rig_told = setup.rigs(rng)
    phases = rng.uniform(0.0, 2.0 * np.pi, n)
    true_robot = true_inertia(true_robot, scenario.physics.mass_error, rng)
    joint_errors = scenario.joint_errors or JointErrors.none(n)
    if scenario.draw_phases:
        joint_errors = replace(joint_errors, phase_rad=phases)
    if scenario.thermal is not None and setup.pose_count is not None:
        raise InputError("a [thermal] warm-up with poses the instrument sets (touches)",
                         "[thermal] with cable lengths, tracker positions or 6-D poses",
                         source=scenario.source, where="[thermal]")
    captured = setup.capture(Bench(scenario, true_robot, joint_errors), rig, rng)
    measurements = captured.measurements
    if scenario.thermal is not None:
        measurements = replace(measurements, values={**measurements.values,
                                                     **_thermal_columns(scenario.thermal,
                                                                        measurements)})
    first = len(rig.ports_m) > 0
    return Simulation(
        scenario=scenario, seed=seed, robot=scenario.robot, true_robot=true_robot, delta=delta,
        port_m=rig.ports_m[0] if first else None,
        port_nominal_m=rig_told.ports_m[0] if first else None,
        joint_errors=joint_errors, joint_sigma_rad=captured.joint_sigma_rad,
        rest=captured.rest, measurements=measurements,
        outlier_rows=captured.outlier_rows, rig=rig, rig_told=rig_told)


def _thermal_columns(thermal: Thermal, data: Measurements) -> dict[str, Array]:
    """Each row's time and temperature, and with revisits the reference flag: the rows at the
    first pose's recorded angles."""
    m = len(data)
    columns = {TIME: thermal.times_s(m), TEMPERATURE: thermal.temperatures_c(m)}
    if thermal.reference_every:
        same = np.all(np.abs(data.q_rad - data.q_rad[0]) <= REFERENCE_RTOL_RAD, axis=1)
        columns[REFERENCE] = same.astype(np.float64)
    return columns


class Bench:
    """The MuJoCo twin as an instrument measures on it (:class:`twin.kinds.bench.Bench`): the
    true robot with its joint errors and physics, the scenario's poses and encoder noise.

    Attributes:
        scenario: What is simulated.
        robot: The true robot.
        joint_errors: Its joint-level errors, with the phases that were drawn.
    """

    def __init__(self, scenario: Scenario, robot: RobotModel, joint_errors: JointErrors) -> None:
        self.scenario = scenario
        self.robot = robot
        self.joint_errors = joint_errors

    def _twin(self, port_m: Array | None, growth_m: Array | None = None) -> Twin:
        robot = self.robot if growth_m is None else self.robot.perturbed(growth_m)
        return Twin.build(robot, port_m, self.scenario.physics, self.joint_errors,
                          self.scenario.instrument.attachment_m)

    def visit(self, stations_m: Sequence[Array | None], rng: np.random.Generator) -> Visit:
        """Poses station after station (:func:`_poses`; with a warm-up, the first revisited as
        its ``[thermal]`` says), the joint jitter, the arm at rest, the angles as recorded
        (:meth:`twin.scenario.noise.NoiseModel.recorded`)."""
        # Several stations move one cable's port: the first station's twin, its port moved.
        first, *others = stations_m
        twins = [self._twin(first)]
        twins += [twins[0].with_port(port) for port in others]
        q, station = _poses(self.scenario, twins, rng)
        thermal = self.scenario.thermal
        if thermal is not None:
            order = thermal.visits(len(q))
            q, station = q[order], station[order]
        joint_sigma = self.scenario.noise.joint_sigma_rad(self.robot, q)
        jitter = rng.normal(0.0, 1.0, q.shape) * joint_sigma
        approach = approach_directions(q)
        actual = q + jitter
        rows = [np.flatnonzero(station == k) for k in range(len(twins))]
        if thermal is None:
            rests = [twin.at_rest(actual[at], approach[at]) for at, twin in zip(rows, twins,
                                                                                 strict=True)]
        elif self.scenario.physics.rigid:
            # The links grow during the capture: each row is measured on the MuJoCo model of
            # the robot as warm as it was then (its station's, the bodies placed for it).
            tables = self.robot.dh + np.stack([thermal.growth(temperature) for temperature
                                               in thermal.temperatures_c(len(q))])
            rests = [twin.at_rest_of(tables[at], actual[at], approach[at])
                     for at, twin in zip(rows, twins, strict=True)]
        else:
            # With servos the masses move with the links too: a twin compiled for each row.
            rows = [np.array([k]) for k in range(len(q))]
            rests = [self._twin(stations_m[station[k]], thermal.growth(temperature))
                     .at_rest(actual[k:k + 1], approach[k:k + 1])
                     for k, temperature in enumerate(thermal.temperatures_c(len(q)))]
        # Back in the order of the rows (a warm-up's revisits interleave the stations).
        order = np.argsort(np.concatenate(rows), kind="stable")
        rest = AtRest(*(np.concatenate(parts)[order] for parts in zip(*rests, strict=True)))
        return Visit(self.scenario.noise.recorded(q), station, rest, joint_sigma, approach)

    def touch(self, places_m: Array, touches: int, sigma_m: Array, rng: np.random.Generator
              ) -> tuple[Array, NDArray[np.intp]]:
        """:func:`twin.sim.touches.touch_poses` on a twin without a cable."""
        return touch_poses(self.robot, self._twin(None), places_m, touches,
                           self.scenario.constraints, sigma_m, rng)

    def rigid(self, q_rad: Array) -> AtRest:
        """The true robot's rigid model at q: no joint errors, no cable."""
        point = point_position(self.robot.structure, self.robot.dh, q_rad,
                               self.scenario.instrument.attachment_m)
        flange = self.robot.flange_transforms(q_rad)
        return AtRest(q_rad, np.full(len(q_rad), np.nan), flange[:, :3, 3], point,
                      flange[:, :3, :3])

    def read_lengths(self, length_m: Array, rng: np.random.Generator
                     ) -> tuple[Array, NDArray[np.intp]]:
        """The scenario's encoder noise (:meth:`twin.scenario.noise.NoiseModel.read`)."""
        read = self.scenario.noise.read(length_m, rng)
        return read.length_m, read.outlier_rows


def _poses(scenario: Scenario, twins: list[Twin], rng: np.random.Generator
           ) -> tuple[Array, NDArray[np.intp]]:
    """The poses, from the plan or drawn station after station (count shared out evenly, the
    first stations taking the remainder), and each pose's station."""
    if scenario.pose_plan is not None:
        q = read_pose_plan(scenario.pose_plan, twins[0], scenario.constraints)
        if scenario.pose_count > len(q):
            raise InputError(f"{len(q)} poses", f"at least [poses] count = {scenario.pose_count}",
                             source=scenario.pose_plan)
        q = q[: scenario.pose_count] if scenario.pose_count else q
        return q, np.zeros(len(q), dtype=np.intp)
    share, extra = divmod(scenario.pose_count, len(twins))
    drawn = []
    for k, twin in enumerate(twins):
        try:
            drawn.append(sample_poses(twin, share + (k < extra), scenario.constraints, rng))
        except InputError as exc:
            if exc.source is not None:  # not the constraints' (TWIN_KERNEL, met at a pose test)
                raise
            raise InputError(exc.found, exc.expected, source=scenario.source,
                             where="[port], [poses], [encoder] range_mm") from None
    station = np.concatenate([np.full(len(part), k, dtype=np.intp)
                              for k, part in enumerate(drawn)])
    return np.concatenate(drawn), station


def write_simulation(out_dir: str | Path, sim: Simulation) -> Path:
    """Write measurements.csv, robot.toml (and robot.urdf for a robot read from a URDF),
    truth.json and capture.toml (last), each atomically.

    Returns:
        The capture file's path.
    """
    out = Path(out_dir)
    write_measurements(out / MEASUREMENTS_FILE, sim.measurements, sim.robot)
    for name, text in robot_files(sim.robot, Path(ROBOT_FILE).stem).items():
        write_atomic(out / name, text)
    write_truth(out / TRUTH_FILE, sim.truth)
    scenario = sim.scenario
    noise = scenario.instrument.setup.noise_mm(scenario.noise.sigma_m,
                                               scenario.noise.resolution_m)
    noise["repeatability_mm"] = float(m_to_mm(scenario.noise.repeatability_m))
    write_capture(out / CAPTURE_FILE, robot=ROBOT_FILE, rig=sim.rig_told_pulled,
                  measurements=MEASUREMENTS_FILE, truth=TRUTH_FILE,
                  calibration=scenario.calibration,
                  encoder={key: value for key, value in noise.items() if value > 0})
    return out / CAPTURE_FILE
