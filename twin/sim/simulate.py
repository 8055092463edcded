"""One simulated capture: draw the truth, measure it with the twin, write it like a real rig.

Random draws come from one generator seeded with the seed, in a fixed order: D-H errors, the
port the calibration is told, transmission phases, the true masses and centres of mass (only with
``[physics] mass_error``), poses, joint jitter, length noise, outliers.

The measurements carry the direction each joint approached its pose from (the poses are visited
in order from home), which backlash depends on.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from twin.calibration import TRAIN_FRACTION
from twin.dataset import Measurements, approach_directions
from twin.errors import InputError
from twin.io.atomic import write_atomic
from twin.io.capture_file import CalibrationSettings, write_capture
from twin.io.measurements import write_measurements
from twin.io.results import write_json
from twin.kinds.length import cable_length
from twin.metrics import metrics
from twin.robot import RobotModel, robot_files
from twin.sim.joint_errors import JointErrors
from twin.sim.physics import true_inertia
from twin.sim.poses import read_pose_plan, sample_poses
from twin.sim.scenario import ARCSEC_PER_DEG, Scenario
from twin.sim.twin import Twin
from twin.units import COMPLIANCE_UNIT, dh_rows_to_display, m_to_mm, rad_to_deg, to_display

Array = NDArray[np.float64]

MEASUREMENTS_FILE = "measurements.csv"
ROBOT_FILE = "robot.toml"
TRUTH_FILE = "truth.json"
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
        q_actual_rad: Where the joints really were, shape (m, n), rad.
        true_length_m: Noise-free cable lengths, shape (m,), m.
        measurements: Recorded joint angles and encoder readings, as written.
        outlier_rows: Rows that carry an outlier, shape (k,).
        train_fraction: Share of poses for identification, if the scenario sets one.
    """

    scenario: Scenario
    seed: int
    robot: RobotModel
    true_robot: RobotModel
    delta: Array
    port_m: Array
    port_nominal_m: Array
    joint_errors: JointErrors
    joint_sigma_rad: float
    q_actual_rad: Array
    true_length_m: Array
    measurements: Measurements
    outlier_rows: NDArray[np.intp]
    train_fraction: float | None

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
        """How far the data are from the core's model, in mm (RMS over the poses).

        ``nominal_rmse_mm``: readings vs the nominal model at the told port (before
        calibration); ``non_geometric_mm``: noise-free lengths vs the true table's rigid
        model at the recorded angles (what no D-H fit can absorb, up to refitting);
        ``flange_shift_mm``: flange displacement by joint errors, jitter and sag.
        """
        q = self.measurements.q_rad
        nominal = cable_length(self.robot.structure, self.robot.dh, q, self.port_nominal_m)
        rigid = cable_length(self.true_robot.structure, self.true_robot.dh, q, self.port_m)
        shift = self.true_robot.flange_positions(self.q_actual_rad) \
            - self.true_robot.flange_positions(q)
        return {
            "nominal_rmse_mm": float(m_to_mm(metrics(nominal - self.measurements.lengths).rmse)),
            "non_geometric_mm": float(m_to_mm(metrics(self.true_length_m - rigid).rmse)),
            "flange_shift_mm": float(m_to_mm(np.sqrt(np.mean(np.sum(shift**2, axis=1))))),
        }

    @property
    def joint_unknowns(self) -> dict[str, list[Any]]:
        """The true joint-level errors as a calibration's unknowns name them, in the units its
        results show (degrees, µrad/(N·m)); null for a transmission error of a higher harmonic
        than the model's two."""
        n = self.robot.n_joints
        terms = self.joint_errors.coefficients()
        compliance = self.scenario.physics.compliance(n)
        return {
            "transmission": [[None if np.isnan(v) else float(v) for v in row]
                             for row in rad_to_deg(terms)],
            "backlash": rad_to_deg(0.5 * self.joint_errors.backlash_rad).tolist(),
            "compliance": to_display(compliance, [COMPLIANCE_UNIT] * n)[0],
        }

    @property
    def truth(self) -> dict[str, Any]:
        """The document written to truth.json (mm, degrees, arc-seconds)."""
        errors = self.joint_errors
        arcsec = float(rad_to_deg(1.0)) * ARCSEC_PER_DEG
        return {
            "scenario": self.scenario.name,
            "seed": self.seed,
            "robot": {"name": self.true_robot.name,
                      "dh": dh_rows_to_display(self.true_robot.dh, self.robot.is_length)},
            "port": m_to_mm(self.port_m).tolist(),
            "port_told": m_to_mm(self.port_nominal_m).tolist(),
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
            "train_fraction": self.train_fraction,
            "effects": self.effects,
        }


def _inertia(robot: RobotModel) -> dict[str, Any]:
    """The true masses (kg) and centres of mass (mm, each link's D-H frame), or nulls."""
    return {"mass_kg": None if robot.mass_kg is None else robot.mass_kg.tolist(),
            "com_mm": None if robot.com_m is None else m_to_mm(robot.com_m).tolist()}


def simulate(scenario: Scenario, seed: int | None = None) -> Simulation:
    """Simulate one capture of a scenario.

    Args:
        scenario: What to simulate.
        seed: Seed of every random draw; None uses the scenario's.

    Raises:
        InputError: if a pose plan is invalid, or the pose constraints leave no usable pose.
    """
    seed = scenario.seed if seed is None else int(seed)
    rng = np.random.default_rng(seed)
    n = scenario.robot.n_joints
    delta = scenario.perturbation.draw(rng)
    true_robot = scenario.robot.perturbed(delta.ravel())
    told_error = rng.normal(0.0, 1.0, 3) * scenario.port_error_m
    port_nominal = scenario.port_told_m if scenario.port_told_m is not None \
        else scenario.port_m + told_error
    phases = rng.uniform(0.0, 2.0 * np.pi, n)
    true_robot = true_inertia(true_robot, scenario.physics.mass_error, rng)
    joint_errors = scenario.joint_errors or JointErrors.none(n)
    if scenario.draw_phases:
        joint_errors = replace(joint_errors, phase_rad=phases)
    twin = Twin.build(true_robot, scenario.port_m, scenario.physics, joint_errors)
    if scenario.pose_plan is not None:
        q = read_pose_plan(scenario.pose_plan, twin, scenario.constraints)
        if scenario.pose_count > len(q):
            raise InputError(f"{len(q)} poses", f"at least [poses] count = {scenario.pose_count}",
                             source=scenario.pose_plan)
        q = q[: scenario.pose_count] if scenario.pose_count else q
    else:
        try:
            q = sample_poses(twin, scenario.pose_count, scenario.constraints, rng)
        except InputError as exc:
            raise InputError(exc.found, exc.expected, source=scenario.source,
                             where="[port], [poses], [encoder] range_mm") from None
    joint_sigma = scenario.noise.joint_sigma_rad(true_robot, q)
    jitter = rng.normal(0.0, 1.0, q.shape) * joint_sigma
    rest = twin.at_rest(q + jitter, approach_directions(q))
    readings = scenario.noise.read(rest.length_m, rng)
    return Simulation(
        scenario=scenario, seed=seed, robot=scenario.robot, true_robot=true_robot, delta=delta,
        port_m=scenario.port_m, port_nominal_m=np.asarray(port_nominal, dtype=np.float64),
        joint_errors=joint_errors, joint_sigma_rad=joint_sigma, q_actual_rad=rest.q_rad,
        true_length_m=rest.length_m,
        measurements=Measurements(q, readings.length_m, approach=approach_directions(q)),
        outlier_rows=readings.outlier_rows, train_fraction=scenario.train_fraction,
    )


def write_simulation(out_dir: str | Path, sim: Simulation) -> Path:
    """Write measurements.csv, robot.toml (and robot.urdf for a robot read from a URDF),
    truth.json and capture.toml (last), each atomically.

    Returns:
        The capture file's path.
    """
    out = Path(out_dir)
    write_measurements(out / MEASUREMENTS_FILE, sim.measurements)
    for name, text in robot_files(sim.robot, Path(ROBOT_FILE).stem).items():
        write_atomic(out / name, text)
    write_json(out / TRUTH_FILE, sim.truth)
    settings = CalibrationSettings(
        estimate_port=sim.scenario.estimate_port, estimate_offset=sim.scenario.estimate_offset,
        train_fraction=sim.train_fraction or TRAIN_FRACTION, stop=sim.scenario.stop,
        max_iterations=sim.scenario.max_iterations, errors=sim.scenario.errors,
        cable_tension_n=sim.scenario.physics.tension_n,
    )
    write_capture(out / CAPTURE_FILE, robot=ROBOT_FILE, port_m=sim.port_nominal_m,
                  measurements=MEASUREMENTS_FILE, truth=TRUTH_FILE, calibration=settings)
    return out / CAPTURE_FILE
