"""How a calibration is run: one frozen value, read alike by the CLI, a capture's and a
scenario's ``[calibration]`` table (:mod:`twin.io.calibration_table`) and the Python API.

    settings = CalibrationSettings(errors=("dh", "compliance"), estimate=("port",),
                                   sigma_m=1e-5, stop="paper")
    twin.calibrate(robot, data, rig=rig, settings=settings)

Every rule about the settings is checked here, once: the error groups as a set (the table
``dh`` is always among them; ``compliance`` and ``link_compliance`` exclude each other), the rig
unknowns among :data:`RIG_UNKNOWNS`, the loss and its scale, the stopping protocol and its
iteration limit, the noise, the train share, and what may move and how far — the search box,
the priors and the fixed parameters (:mod:`twin.unknowns.limits`; their names are resolved
against the model's unknowns when it is made, :func:`twin.calibration.setup.make_model`). A
mistake is an :class:`~twin.errors.InputError` naming the setting (``where``); the reader of a
flag or a file adds its ``source``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from twin.choices import DEFAULT_SCALE_SIGMAS, LOSSES, MAX_ITERATIONS, PROTOCOLS
from twin.errors import InputError
from twin.kinds.base import Noise
from twin.loss import Loss
from twin.problem import DEFAULT_SIGMA_M
from twin.stopping import Budget
from twin.unknowns import ERRORS, check_errors
from twin.unknowns.limits import Bound, Prior, parse_fix

MAX_JOINT_SIGMA_RAD = math.radians(10.0)
"""The largest joint noise a calibration may be told: 10° (a typo beyond)."""
TRAIN_FRACTION = 0.8
"""Share of the poses used for identification (paper: 80 / 20); 1 trains on every pose."""
RIG_UNKNOWNS = {"port": "--estimate-port", "offset": "--estimate-offset",
                "scale": "--estimate-scale", "attachment": "--estimate-attachment",
                "base": "--estimate-base", "tool": "--estimate-tool"}
"""The rig's unknown groups a calibration may add, and the flag that asks for each."""
TOOL_ORIGIN = {"tool": "attachment"}
"""A rig unknown that brings another with it: the tool frame (6-D) is its rotation (group
``tool``) and its origin, the measured point (group ``attachment``)."""


@dataclass(frozen=True)
class CalibrationSettings:
    """What to estimate and how: everything about a calibration but the robot, the rig and the
    data.

    Attributes:
        errors: The robot's error groups (:data:`twin.unknowns.ERRORS`), in the registry's
            order; the D-H table ``dh`` always among them.
        estimate: The rig's unknowns to identify too (:data:`RIG_UNKNOWNS`), in that order.
        sigma_m: The noise 1σ of one reading, m: the filters' measurement noise and the
            misfit test's reference.
        sigma_rad: The noise 1σ of one angle read (a 6-D pose's orientation), rad: what an
            orientation row weighs against a position row (:mod:`twin.kinds.pose`); None: the
            kind's default.
        loss: How residual rows count (:data:`twin.loss.LOSSES`).
        loss_scale_m: The robust loss's scale, m, or None for
            :data:`twin.loss.DEFAULT_SCALE_SIGMAS` times ``sigma_m``.
        stop: The stopping protocol (:data:`twin.stopping.PROTOCOLS`).
        max_iterations: Iteration limit of every method and stage, or None (the protocol's).
        train_fraction: Share of the poses used for identification, in (0, 1]: 1 trains on
            every pose (no validation poses: score on another file, or cross-validate).
        bounds: The search box, as rules over the unknowns (:class:`~twin.unknowns.limits.Bound`
            or its text, ``"dh=20mm"``), applied in order over each group's own box (the
            paper's ±5 mm / ±8° for the table).
        priors: Zero-mean Gaussian priors (:class:`~twin.unknowns.limits.Prior` or its text,
            ``"dh=1mm"``), applied in order; none by default.
        fix: Unknowns held at the nominal and left out (names, families or groups).
        joint_sigma_rad: The noise 1σ of each recorded joint angle, rad — one for every joint
            or one per joint; a resolution r counts as r/√12. Empty (the default): the joints
            are exact. Otherwise each row's variance is the reading's and the joints' through
            the row's Jacobian, and the fit weights the rows by it (errors in variables,
            :mod:`twin.problem`).
        sigma_auto: Estimate σ of a reading from the data (repeat readings, else the residuals
            of a first fit; :mod:`twin.calibration.noise`) instead of ``sigma_m``.
    """

    errors: tuple[str, ...] = ("dh",)
    estimate: tuple[str, ...] = ()
    sigma_m: float = DEFAULT_SIGMA_M
    sigma_rad: float | None = None
    loss: str = LOSSES[0]
    loss_scale_m: float | None = None
    stop: str = PROTOCOLS[0]
    max_iterations: int | None = None
    train_fraction: float = TRAIN_FRACTION
    bounds: tuple[Bound, ...] = ()
    priors: tuple[Prior, ...] = ()
    fix: tuple[str, ...] = ()
    joint_sigma_rad: tuple[float, ...] = ()
    sigma_auto: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "errors", check_errors(self.errors))
        unknown = [name for name in self.estimate if name not in RIG_UNKNOWNS]
        if unknown:
            raise InputError(f"the rig unknown {unknown[0]!r}",
                             "some of " + ", ".join(RIG_UNKNOWNS), where="estimate")
        brought = {TOOL_ORIGIN[name] for name in self.estimate if name in TOOL_ORIGIN}
        object.__setattr__(self, "estimate", tuple(name for name in RIG_UNKNOWNS
                                                   if name in {*self.estimate, *brought}))
        _check(math.isfinite(self.sigma_m) and self.sigma_m > 0, "sigma_m", self.sigma_m,
               "a noise 1σ > 0, m")
        _check(self.sigma_rad is None or (math.isfinite(self.sigma_rad) and self.sigma_rad > 0),
               "sigma_rad", self.sigma_rad, "an angle noise 1σ > 0, rad")
        _check(self.loss in LOSSES, "loss", self.loss, "one of " + ", ".join(LOSSES))
        _check(self.loss_scale_m is None or (math.isfinite(self.loss_scale_m)
                                             and self.loss_scale_m > 0),
               "loss_scale_m", self.loss_scale_m, "a scale > 0, m")
        _check(self.stop in PROTOCOLS, "stop", self.stop, "one of " + ", ".join(PROTOCOLS))
        _check(self.max_iterations is None or 1 <= self.max_iterations <= MAX_ITERATIONS,
               "max_iterations", self.max_iterations, f"an integer from 1 to {MAX_ITERATIONS}")
        _check(0 < self.train_fraction <= 1, "train_fraction", self.train_fraction,
               "a share in (0, 1]")
        object.__setattr__(self, "bounds", tuple(
            rule if isinstance(rule, Bound) else Bound.parse(rule) for rule in self.bounds))
        object.__setattr__(self, "priors", tuple(
            rule if isinstance(rule, Prior) else Prior.parse(rule) for rule in self.priors))
        object.__setattr__(self, "fix", tuple(dict.fromkeys(parse_fix(name)
                                                            for name in self.fix)))
        joints = tuple(float(value) for value in np.ravel(self.joint_sigma_rad))
        _check(all(math.isfinite(value) and 0 <= value <= MAX_JOINT_SIGMA_RAD
                   for value in joints), "joint_sigma_rad", self.joint_sigma_rad,
               f"joint noise 1σ from 0 to {math.degrees(MAX_JOINT_SIGMA_RAD):g}°, one for all "
               "joints or one per joint")
        object.__setattr__(self, "joint_sigma_rad", joints if any(joints) else ())

    def joint_sigma(self, n_joints: int) -> NDArray[np.float64]:
        """The noise 1σ of each of ``n_joints`` recorded joint angles, shape (n,), rad (zeros:
        exact joints).

        Raises:
            InputError: for another number of values than one or ``n_joints``.
        """
        values = np.asarray(self.joint_sigma_rad, dtype=np.float64)
        if values.size not in (0, 1, n_joints):
            raise InputError(f"{values.size} joint noise values", f"one for all joints or one "
                             f"for each of the {n_joints}", where="joint_sigma_rad")
        return np.zeros(n_joints) + (values if values.size else 0.0)

    def estimates(self, name: str) -> bool:
        """Whether the rig unknown ``name`` is identified."""
        return name in self.estimate

    @property
    def groups(self) -> tuple[str, ...]:
        """The unknown groups of the model: the error groups, then the rig's."""
        return (*self.errors, *self.estimate)

    @property
    def noise(self) -> Noise:
        """The noise of one reading, as a kind weighs its rows with it."""
        return Noise(self.sigma_m, self.sigma_rad)

    @property
    def budget(self) -> Budget:
        """The iteration limits and stopping tests the settings ask for."""
        return Budget.named(self.stop, self.max_iterations)

    @property
    def loss_function(self) -> Loss:
        """The loss, its scale defaulting to 3 σ of a reading."""
        scale = self.loss_scale_m if self.loss_scale_m is not None \
            else DEFAULT_SCALE_SIGMAS * self.sigma_m
        return Loss(self.loss, scale)


def joint_noise(sigma_rad: Sequence[float] = (), resolution_rad: Sequence[float] = ()
                ) -> tuple[float, ...]:
    """The noise 1σ of each recorded joint angle from a stated σ and a resolution r (r/√12, the
    σ of rounding), added in quadrature; each one value for every joint or one per joint, rad.

    Raises:
        InputError: for lists of different lengths (neither of them one value).
    """
    sigma = np.asarray(sigma_rad, dtype=np.float64).ravel()
    resolution = np.asarray(resolution_rad, dtype=np.float64).ravel()
    if sigma.size > 1 and resolution.size > 1 and sigma.size != resolution.size:
        raise InputError(f"{sigma.size} joint σ and {resolution.size} resolutions",
                         "one value for all joints or one per joint, the same count",
                         where="joint_sigma_rad")
    if not sigma.size and not resolution.size:
        return ()
    sigma = sigma if sigma.size else np.zeros(1)
    resolution = resolution if resolution.size else np.zeros(1)
    return tuple(np.hypot(sigma, resolution / math.sqrt(12.0)).tolist())


def _check(ok: bool, name: str, value: object, expected: str) -> None:
    if not ok:
        raise InputError(f"{value!r}", expected, where=name)


__all__ = ["ERRORS", "RIG_UNKNOWNS", "TRAIN_FRACTION", "Bound", "CalibrationSettings", "Prior",
           "joint_noise"]
