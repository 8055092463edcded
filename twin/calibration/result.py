"""What a calibration returns: one method's result on one measurement set, and the problem
it was solved on with its split."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from twin.analysis.drift import Drift
from twin.analysis.gauge import Gauge
from twin.analysis.identifiability import Identifiability
from twin.analysis.metrics import Metrics
from twin.analysis.misfit import Misfit
from twin.analysis.steps import Step
from twin.analysis.uncertainty import CalibrationUncertainty
from twin.analysis.unseen import Unseen
from twin.analysis.workspace import Workspace
from twin.arrays import Array
from twin.calibration.hold import Held
from twin.calibration.noise import NoiseEstimate
from twin.calibration.settings import CalibrationSettings
from twin.geometry.rigid import rotation
from twin.loss import Loss
from twin.model import Model
from twin.problem import Problem
from twin.robot import RobotModel
from twin.solvers import SolverResult
from twin.stopping import Budget, at_bounds


@dataclass(frozen=True)
class CalibrationResult:
    """One method's calibration of one measurement set.

    Attributes:
        robot: The nominal robot.
        model: The measurement model (nominal robot and rig, measurement kind, unknowns).
        solver: The method's raw result (x, history, evaluations, time).
        seed: Seed of the split and of the method's random draws.
        train_rows: Row indices used for identification, shape (m_train,).
        validation_rows: Held-out row indices, shape (m_val,).
        metrics: ``{"before", "train", "validation"}`` metrics in m; ``before`` is the nominal
            model on the validation poses — on the training poses, and no ``validation``,
            when there are none (every pose trained on).
        identifiability: What the training poses identify at the start (nominal) geometry.
        identified_identifiability: The same at the identified geometry.
        uncertainty: Noise estimate, base-parameter covariance and predicted flange accuracy.
        settings: What was estimated and how (the error groups, the rig's unknowns, the
            noise, the loss, the stopping protocol, the split).
        misfit: The chi-square test of the training residuals against the noise
            (:mod:`twin.analysis.misfit`).
        rejected_rows: Measurement rows (poses, 0-based, train and validation) whose residual
            the robust loss rejects (:mod:`twin.loss`), ascending; empty for least squares.
        gauge: The motions of the flange the data cannot see (:mod:`twin.analysis.gauge`).
        unseen: The directions of the unknowns the training poses cannot see, held at the
            start (:mod:`twin.analysis.unseen`).
        held: What holding them did to the method's answer, and whether the start was kept
            instead (:mod:`twin.calibration.hold`).
        held_out: Where the validation poses come from when they are not a split of the
            measurements (a separate file); empty for a split.
        noise: How σ was estimated from the data (``settings.sigma_auto``), or None.
        row_sigma: The noise 1σ of each training row the fit weighted it by, shape (M,), m,
            when the joints' noise entered them (errors in variables); None otherwise.
        workspace: Where the accuracy is stated: poses within the joint ranges of the
            training poses (:mod:`twin.analysis.workspace`).
        drift: The test of the reference pose's readings against time
            (:mod:`twin.analysis.drift`; its series' rows are the measurements'), or None
            without reference rows.
        steps: Where the identified model's residuals, over every row of the measurements
            in their order, jump by more than the noise allows (:mod:`twin.analysis.steps`):
            a re-hooked cable, a re-zeroed encoder, a new session; empty when none (or for
            kinds of several rows per pose).
    """

    robot: RobotModel
    model: Model
    solver: SolverResult
    seed: int
    train_rows: NDArray[np.intp]
    validation_rows: NDArray[np.intp]
    metrics: dict[str, Metrics]
    identifiability: Identifiability | None = None
    identified_identifiability: Identifiability | None = None
    uncertainty: CalibrationUncertainty | None = None
    settings: CalibrationSettings = field(default_factory=CalibrationSettings)
    misfit: Misfit | None = None
    rejected_rows: NDArray[np.intp] = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    gauge: Gauge | None = None
    unseen: Unseen | None = None
    held: Held | None = None
    held_out: str = ""
    noise: NoiseEstimate | None = None
    row_sigma: Array | None = None
    workspace: Workspace | None = None
    drift: Drift | None = None
    steps: tuple[Step, ...] = ()

    @property
    def validated(self) -> bool:
        """Whether there were validation poses (``metrics["validation"]``)."""
        return "validation" in self.metrics

    @property
    def x(self) -> Array:
        """The identified unknowns, shape (p,), SI (``solver.x``)."""
        return self.solver.x

    @property
    def method(self) -> str:
        """The method's name."""
        return self.solver.method

    @property
    def delta(self) -> Array:
        """Identified errors of the kinematic table, shape (4, n): rows δa [m], δd [m], δα [rad],
        δθ [rad] for a D-H arm; zeros when the table was not identified."""
        return self.model.table(self.solver.x) - self.robot.dh

    @property
    def identified_geometry(self) -> RobotModel:
        """The nominal robot with the identified table: its geometry alone. The joint-level
        errors (transmission, backlash, compliance) and the rig are in :attr:`model` and
        :attr:`x`; :func:`twin.calibration.predict.predict` uses all of it."""
        return self.robot.perturbed(self.delta)

    @property
    def budget(self) -> Budget:
        """The iteration limits and stopping tests the method ran with."""
        return self.settings.budget

    @property
    def loss(self) -> Loss:
        """The loss the methods minimised."""
        return self.settings.loss_function

    @property
    def at_bounds(self) -> tuple[str, ...]:
        """Names of the unknowns the method left on a bound of the search box."""
        lower, upper = self.model.bounds()
        return tuple(np.asarray(self.model.names)[at_bounds(self.solver.x, lower, upper)])

    @property
    def prior_decided(self) -> tuple[str, ...]:
        """Names of the unknowns their prior, not the data, decided: a prior given, and the
        data adding less information than it — a posterior σ above :data:`PRIOR_DECIDED` of the
        prior's — or none (held at the nominal)."""
        weight = self.model.prior_weight()
        if self.uncertainty is None or not np.any(weight > 0):
            return ()
        ratio = self.uncertainty.sigma * weight  # posterior σ / prior σ; NaN where held
        decided = (weight > 0) & ~(ratio <= PRIOR_DECIDED)
        return tuple(np.asarray(self.model.names)[decided])

    @property
    def ports_m(self) -> Array:
        """Ports used or identified, base frame, shape (k, 3), m."""
        rig = self.model.rig
        ports = np.array(rig.ports_m)
        if self.model.has("port"):
            ports[rig.estimated_port_index] += self.model.block(self.solver.x, "port").reshape(
                -1, 3)
        return ports

    @property
    def attachment_m(self) -> Array:
        """The measured point in the flange frame, used or identified, shape (3,), m."""
        return self.model.point(self.solver.x)

    @property
    def base_in_tracker(self) -> Array:
        """Where the base frame sits in the tracker frame, used or identified, (4, 4), m."""
        transform = np.array(self.model.rig.base_in_tracker)
        if self.model.has("base"):
            correction = self.model.block(self.solver.x, "base")
            turn = rotation(correction[3:])
            transform[:3, :3] = turn @ transform[:3, :3]
            transform[:3, 3] = turn @ transform[:3, 3] + correction[:3]
        return transform

    @property
    def points_m(self) -> Array:
        """The fixed points, used or identified, base frame, shape (f, 3), m."""
        points = np.array(self.model.rig.points_m)
        if self.model.has("points"):
            points += self.model.block(self.solver.x, "points").reshape(points.shape)
        return points

    @property
    def port_m(self) -> Array:
        """The port used or identified when there is one, shape (3,), m."""
        return self.ports_m[0]

    @property
    def offset_m(self) -> float:
        """Identified cable-length offset, m (0 unless estimated; the first session's with
        several: :attr:`offsets_m`)."""
        return float(self.offsets_m[0]) if self.model.has("offset") else 0.0

    @property
    def offsets_m(self) -> Array:
        """Identified cable-length offset of each capture session (one without sessions),
        shape (s,), m; empty unless estimated."""
        return np.asarray(self.model.block(self.solver.x, "offset"), dtype=np.float64) \
            if self.model.has("offset") else np.zeros(0)

    @property
    def scale(self) -> float:
        """Identified encoder scale error, m/m (0 unless estimated): the length kind's gain
        ``1 + scale`` on every modelled length (:mod:`twin.unknowns.scale`)."""
        return float(self.model.block(self.solver.x, "scale")[0]) if self.model.has("scale") \
            else 0.0


PRIOR_DECIDED = float(np.sqrt(0.5))
"""An unknown with a posterior σ above this share of its prior's σ was decided by the prior: the
data's information about it (1/σ_data² = 1/σ² − 1/σ_p²) is less than the prior's."""


class SplitProblem(NamedTuple):
    """A problem, the rows of the measurements it trains and validates on, and the settings it
    was made from."""

    problem: Problem
    train_rows: NDArray[np.intp]
    """Row indices used for identification, shape (m_train,)."""
    validation_rows: NDArray[np.intp]
    """Held-out row indices, shape (m_val,)."""
    settings: CalibrationSettings
    """What is estimated and how (:mod:`twin.calibration.settings`)."""
    held_out: str = ""
    """Where the validation poses come from when they are not a split of the measurements (a
    separate file, named; ``validation_rows`` then empty: every row trains); empty for a
    split."""
    noise: NoiseEstimate | None = None
    """How σ was estimated from the data (``sigma_auto``); None when it was stated."""
