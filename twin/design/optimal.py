"""Measurement design: which poses to measure, and where to put the encoder port.

A D-optimal plan maximises det(J_Bᵀ J_B), J_B the cable-length Jacobian of the base parameters
(:mod:`twin.analysis.identifiability`) at the nominal geometry: it minimises the volume of the
parameters' confidence ellipsoid, and — unlike the other criteria — it does not depend on the
units or scaling of the parameters. Each pose adds one row j, so

- **greedy**: starting from a small ridge δI, add the candidate with the largest
  ``jᵀ F⁻¹ j`` (det(F + jjᵀ) = det F · (1 + jᵀF⁻¹j));
- **exchange** (Fedorov): swap the selected pose i for the candidate c with the largest
  determinant ratio ``(1 + d_c)(1 − d_i) + d_ic² ``, d = jᵀF⁻¹j', until no swap gains.

Both steps score every candidate at once. The port is chosen among candidate positions by the
predicted RMS flange-position error over the workspace (Cramér–Rao,
:mod:`twin.analysis.uncertainty`) of the D-optimal plan made for each port.
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.analysis.identifiability import Observability, identifiability, observability
from twin.analysis.uncertainty import cramer_rao_flange_rms
from twin.arrays import Array
from twin.dataset import Measurements
from twin.model import Model

RIDGE = 1e-9
"""Greedy start F = δI, δ this fraction of the mean squared entry of the candidate rows."""
MIN_GAIN = 1e-9
"""An exchange must raise det F by at least this fraction."""


class Selection(NamedTuple):
    """A D-optimal choice of rows."""

    rows: NDArray[np.intp]
    """Chosen candidate rows, shape (n,), sorted."""
    log_det: float
    """log det(J_selᵀ J_sel) of the chosen rows."""
    exchanges: int
    """Swaps made after the greedy pass."""


def d_optimal_rows(candidates: ArrayLike, n_rows: int, max_exchanges: int = 1000) -> Selection:
    """Choose ``n_rows`` distinct rows of a candidate Jacobian that maximise det(JᵀJ).

    Args:
        candidates: One row per candidate measurement, shape (M, L).
        n_rows: Rows to choose, L ≤ n_rows ≤ M.
        max_exchanges: Cap on the exchange passes.

    Raises:
        ValueError: if ``n_rows`` is outside [L, M].
    """
    J = np.asarray(candidates, dtype=np.float64)
    M, L = J.shape
    if not L <= n_rows <= M:
        raise ValueError(f"{n_rows} rows from {M} candidates of {L} columns: need {L}..{M}")
    chosen = np.zeros(M, dtype=bool)
    F_inv = np.eye(L) / (RIDGE * float(np.mean(J**2)))
    for _ in range(n_rows):
        gain = np.sum((J @ F_inv) * J, axis=1)
        gain[chosen] = -np.inf
        best = int(np.argmax(gain))
        chosen[best] = True
        u = F_inv @ J[best]
        F_inv -= np.outer(u, u) / (1.0 + J[best] @ u)
    exchanges = 0
    while exchanges < max_exchanges:
        selected = np.flatnonzero(chosen)
        F_inv = np.asarray(np.linalg.inv(J[selected].T @ J[selected]), dtype=np.float64)
        cross = J[selected] @ F_inv @ J.T
        d_candidate = np.sum((J @ F_inv) * J, axis=1)
        d_selected = d_candidate[selected]
        ratio = np.outer(1.0 - d_selected, 1.0 + d_candidate) + cross**2
        ratio[:, chosen] = -np.inf
        out, into = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
        if ratio[out, into] <= 1.0 + MIN_GAIN:
            break
        chosen[selected[out]], chosen[into] = False, True
        exchanges += 1
    rows = np.flatnonzero(chosen)
    _, log_det = np.linalg.slogdet(J[rows].T @ J[rows])
    return Selection(rows=rows, log_det=float(log_det), exchanges=exchanges)


def base_rows(
    model: Model, x: ArrayLike, q_rad: ArrayLike
) -> tuple[Array, NDArray[np.bool_]]:
    """Cable-length Jacobian rows of the base parameters, chosen on the same poses.

    Args:
        model: The cable model that will be fitted.
        x: Unknowns at which to linearise (zeros: nominal), shape (p,).
        q_rad: Poses, shape (m, n), rad.

    Returns:
        ``(rows, base_mask)``: shape (m, L) in m/m and m/rad, and the mask (p,) of base unknowns.
    """
    jacobian = model.jacobian(np.asarray(x, dtype=np.float64), model.poses(q_rad))[1]
    mask = identifiability(jacobian, model.names).base_mask
    return jacobian[:, mask], mask


class DesignScore(NamedTuple):
    """How good a set of poses is for calibration."""

    observability: Observability
    """Indices of the base-parameter Jacobian in SI units."""
    flange_rms_m: float
    """Predicted (Cramér–Rao) RMS flange-position error over the workspace poses, m."""


def score_poses(
    model: Model,
    x: ArrayLike,
    q_rad: ArrayLike,
    base_mask: NDArray[np.bool_],
    sigma_m: float,
    q_workspace_rad: ArrayLike,
    port: ArrayLike | None = None,
) -> DesignScore:
    """Observability indices and predicted workspace accuracy of measuring at ``q_rad``
    (:func:`score_data` of those poses, at the reference temperature).

    Args:
        model: The cable model that will be fitted.
        x: Unknowns at which to linearise, shape (p,).
        q_rad: The poses to measure, shape (m, n), rad.
        base_mask: Base unknowns whose columns the indices use, shape (p,).
        sigma_m: Length noise 1σ, m.
        q_workspace_rad: Poses where the flange error is predicted, shape (k, n), rad.
        port: The station of each pose, shape (m,), for a rig of several ports; port 0 if None.
    """
    return score_data(model, x, model.poses(q_rad, port=port), base_mask, sigma_m,
                      q_workspace_rad)


def score_data(model: Model, x: ArrayLike, data: Measurements, base_mask: NDArray[np.bool_],
               sigma_m: float, q_workspace_rad: ArrayLike) -> DesignScore:
    """Observability indices and predicted workspace accuracy of measurements as they were
    taken: each row's own station, temperature and approach (arguments as
    :func:`score_poses`)."""
    jacobian = model.jacobian(np.asarray(x, dtype=np.float64), data)[1]
    return DesignScore(
        observability=observability(jacobian[:, base_mask]),
        flange_rms_m=cramer_rao_flange_rms(model, x, data, sigma_m, q_workspace_rad),
    )


class PoseDesign(NamedTuple):
    """A D-optimal plan drawn from candidate poses."""

    q_rad: Array
    """Planned poses, shape (n, joints), rad."""
    selection: Selection
    """The chosen candidate rows."""
    base_mask: NDArray[np.bool_]
    """Base unknowns the plan was optimised for, shape (p,)."""


def plan_poses(
    model: Model, x: ArrayLike, candidates_rad: ArrayLike, n_poses: int
) -> PoseDesign:
    """The D-optimal ``n_poses`` among candidate poses for fitting ``model`` near ``x``.

    Args:
        model: The cable model that will be fitted (port, which extra unknowns).
        x: Unknowns at which to linearise (zeros: nominal), shape (p,).
        candidates_rad: Candidate poses, shape (M, n), rad.
        n_poses: Poses to plan.
    """
    candidates = np.asarray(candidates_rad, dtype=np.float64)
    rows, mask = base_rows(model, x, candidates)
    selection = d_optimal_rows(rows, n_poses)
    return PoseDesign(q_rad=candidates[selection.rows], selection=selection, base_mask=mask)


class StationDesign(NamedTuple):
    """A D-optimal plan of poses and the station (port) each is measured from."""

    q_rad: Array
    """Planned poses, shape (n, joints), rad."""
    port: NDArray[np.intp]
    """The station of each planned pose, shape (n,), an index into the rig's ports."""
    selection: Selection
    """The chosen candidate rows."""
    base_mask: NDArray[np.bool_]
    """Base unknowns the plan was optimised for, shape (p,)."""


def plan_stations(model: Model, x: ArrayLike, candidates_rad: ArrayLike, n_poses: int
                  ) -> StationDesign:
    """The D-optimal ``n_poses`` (pose, station) pairs for a rig of several ports measured
    together: every candidate pose of every station is one candidate row, and the greedy and
    exchange steps choose among all of them at once, so stations and poses are chosen together.

    Args:
        model: The cable model that will be fitted, its rig holding every station.
        x: Unknowns at which to linearise (zeros: nominal), shape (p,).
        candidates_rad: Candidate poses per station, shape (K, M, n), rad (each station's poses
            are those it can measure).
        n_poses: Poses to plan.
    """
    candidates = np.asarray(candidates_rad, dtype=np.float64)
    stations, count = candidates.shape[:2]
    q_all = candidates.reshape(stations * count, -1)
    port = np.repeat(np.arange(stations, dtype=np.intp), count)
    jacobian = model.jacobian(np.asarray(x, dtype=np.float64), model.poses(q_all, port=port))[1]
    mask = identifiability(jacobian, model.names).base_mask
    selection = d_optimal_rows(jacobian[:, mask], n_poses)
    return StationDesign(q_all[selection.rows], port[selection.rows], selection, mask)


class PortChoice(NamedTuple):
    """The best port among candidates, with every candidate's plan score."""

    best: int
    """Index of the chosen port."""
    flange_rms_m: Array
    """Predicted workspace RMS flange error of each port's plan, shape (K,), m."""
    plans: tuple[PoseDesign, ...]
    """Each port's D-optimal plan."""


def choose_port(
    model: Model,
    ports_m: ArrayLike,
    candidates_rad: ArrayLike,
    n_poses: int,
    sigma_m: float,
    q_workspace_rad: ArrayLike,
) -> PortChoice:
    """Plan for each candidate port and keep the one with the best predicted flange accuracy.

    Args:
        model: The cable model to fit; its port is replaced by each candidate.
        ports_m: Candidate ports in the base frame, shape (K, 3), m.
        candidates_rad: Candidate poses, shape (M, n), rad, or one set per port (K, M, n)
            when which poses can be measured depends on the port.
        n_poses: Poses per plan.
        sigma_m: Length noise 1σ, m.
        q_workspace_rad: Poses where the flange error is predicted, shape (k, n), rad.
    """
    x = np.zeros(model.n_params)
    ports = np.asarray(ports_m, dtype=np.float64).reshape(-1, 3)
    candidates = np.asarray(candidates_rad, dtype=np.float64)
    if candidates.ndim == 2:
        candidates = np.broadcast_to(candidates, (len(ports), *candidates.shape))
    plans, scores = [], []
    for port, port_candidates in zip(ports, candidates, strict=True):
        # Made again for the port: the cable's pull loads the joints (compliance) towards it.
        at_port = model.with_rig(replace(model.rig, ports_m=port[None]), x)[0]
        plan = plan_poses(at_port, x, port_candidates, n_poses)
        plans.append(plan)
        scores.append(
            score_poses(at_port, x, plan.q_rad, plan.base_mask, sigma_m, q_workspace_rad)
            .flange_rms_m
        )
    rms = np.asarray(scores)
    return PortChoice(best=int(np.argmin(rms)), flange_rms_m=rms, plans=tuple(plans))

