"""What the data cannot see, as a subspace of the unknowns, and the one safe value along it.

Least squares is indifferent along directions the data do not see: any value there is noise, a
solver's drift or the search box (θ6 of a cable at the flange centre ends at −8° if nothing
holds it). The safe value is the nominal, reached as the minimum-norm solution relative to the
start in the **bound-scaled** unknowns z = x / w:

    x ← x − W N Nᵀ W⁻¹ x,

w the half-range of each unknown's search box (a millimetre of δa and 1.6 mrad of δθ weigh as
the box says they may) — or its prior's σ where the user gave one
(:meth:`twin.model.Model.scale`: what the user says each unknown may plausibly do) — for the
robot's unknowns, and :data:`RIG_WEIGHT` times that for the rig's (port, offset, attachment,
tracker frame, fixed points): the robot stays at its nominal along what the data cannot see
and the rig — which has no nominal to keep, it is what was measured — takes up the trade (an
estimated port turns about joint 1's axis, not θ1).

N the orthonormal basis (in z) of the unseen directions. The candidates are the null
directions of the training poses at the **start** geometry — the identifiability null space at
its rank threshold (:data:`~twin.analysis.identifiability.RANK_RTOL` of the largest singular
value of the column-scaled Jacobian; :mod:`twin.analysis.identifiability` names them: θ6, α6,
d2 − d3 for a cable at the flange centre of an IRB 120). Each is held unless the identified
geometry lets the data see it after all: it is held when, at the identified unknowns,

- it has a component in the exact null space there (α6 of a flange-centre cable never moves
  a reading; a gauge motion of an estimated port), or
- its Cramér–Rao σ (σ̂ of the fit's noise estimate, every other unknown free) exceeds
  :data:`HELD_SIGMA` half-ranges of the box (or σ of its prior): the box or the prior, not the
  data, would decide it (θ6 when a6 is a fraction of a millimetre and the model misses
  something). The test reads the data alone (the priors' rows left out), so that a prior never
  makes a direction look seen; rows of unequal noise count by their weights; or
- it is *weak* there — seen below :data:`~twin.analysis.identifiability.WEAK_RTOL` of the
  best-seen direction, as the identifiability report counts weak directions — and the answer's
  value along it, from the start, is within :data:`SIGNIFICANT_SIGMAS` of its σ, and the values
  of all such directions together within their χ² quantile at the same level: the data see
  them, but too weakly to tell their values from zero. Only the identified geometry's second-order
  effects make such a direction visible at all (θ6 through a6 of a fraction of a millimetre),
  and an estimate of −0.66° ± 0.51° (truth +0.05°) would turn a tool more than holding does
  (the README's example: tool orientation 0.80° RMS against 0.35° held).

So θ6 of the paper's rig stays at exactly 0, while a large true error that makes a candidate
visible (a6 of 5 mm in the bounds regime, θ6 of several degrees) keeps it free, and noise-free
data hold only what no reading moves. Directions exactly unseen at the identified unknowns are
always held.

The same subspace bounds the accuracy: the Cramér–Rao bound of an estimator held at the start
along N is ``σ² P (Pᵀ JᵀJ P)⁻¹ Pᵀ`` with P = S Q, Q the orthonormal complement of N in z —
finite, and the bound of the identifiable combinations only (:mod:`twin.analysis.uncertainty`).
Candidates kept with a σ above :data:`WEAK_SIGMA` half-ranges are *weakly seen*: reported with
their σ.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.analysis.identifiability import (
    RANK_RTOL,
    WEAK_RTOL,
    Identifiability,
    name_direction,
    pivot_columns,
)
from twin.analysis.linearisation import linearise
from twin.analysis.misfit import chi2_quantile
from twin.arrays import Array
from twin.dataset import Measurements
from twin.model import Model
from twin.unknowns import Stage

RIG_WEIGHT = 1e3
"""How much wider the hold's norm counts the rig's unknowns than their search box: their
deviations cost a millionth of the robot's, so the rig absorbs what trades with it."""
SIGNIFICANT_SIGMAS = 3.0
"""A weak candidate is kept where the answer's value along it is this many of its σ from the
start or more (a two-sided test at :data:`SIGNIFICANCE_LEVEL`)."""
SIGNIFICANCE_LEVEL = 0.0027
"""The level of the tests that tell a weak direction's value from zero: 3σ of a normal."""
HELD_SIGMA = 1.0
"""A direction whose Cramér–Rao σ exceeds this many half-ranges of the box is held at the
start: the box, not the data, would decide it."""
INSIDE_TOL = 1e-6
"""A candidate (unit vector, bound-scaled) within this distance of the exact null space is in
it."""
WEAK_SIGMA = 0.1
"""A kept direction whose σ exceeds this many half-ranges of the box is reported as weakly
seen."""

HELD_SHARE = 0.01
"""An unknown with more than this share of it in the held subspace (a squared row norm of
its orthonormal basis) is not measured alone: reports and result files mark it."""


class Unseen(NamedTuple):
    """The directions of the unknowns the data cannot see (module docstring)."""

    scale: Array
    """w: the hold's weight of each unknown (half its search range, the rig's times
    :data:`RIG_WEIGHT`), shape (p,), m and rad."""
    basis: Array
    """N: orthonormal basis of the unseen directions in the weighted unknowns z = x / w,
    shape (p, k)."""
    names: tuple[str, ...]
    """The unseen subspace as sparse combinations (``theta6``, ``d2-d3``), length k."""
    noise_m: float
    """The noise estimate the Cramér–Rao test used, m."""
    weak_names: tuple[str, ...] = ()
    """The weakly seen directions, named."""
    weak_sigma: Array = np.zeros(0)
    """Their Cramér–Rao σ, in half-ranges of the box, shape (w,)."""

    def held(self, names: tuple[str, ...]) -> frozenset[str]:
        """The unknowns (of ``names``, the model's, length p) more than :data:`HELD_SHARE` of
        which lies in the held subspace (the squared row norm of N: 0 seen alone, 1 not seen
        at all): their values are the hold's minimum-norm split of what the data saw."""
        share = np.sum(self.basis**2, axis=1)
        return frozenset(name for name, part in zip(names, share, strict=True)
                         if part > HELD_SHARE)

    @property
    def seen(self) -> Array:
        """Q: orthonormal basis of the complement of N in the bound-scaled unknowns, (p, p − k)."""
        p, k = self.basis.shape
        if not k:
            return np.eye(p)
        q, _ = np.linalg.qr(np.column_stack([self.basis, np.eye(p)]))
        return np.asarray(q[:, k:p], dtype=np.float64)

    @property
    def seen_x(self) -> Array:
        """P = S Q: the seen directions in the units of x (m, rad), shape (p, p − k)."""
        return self.scale[:, None] * self.seen

    def remove(self, x: ArrayLike) -> Array:
        """x (..., p) without its components along N: ``x − S N Nᵀ S⁻¹ x``."""
        z = np.asarray(x, dtype=np.float64) / self.scale
        return np.asarray(self.scale * (z - (z @ self.basis) @ self.basis.T), dtype=np.float64)

    def along(self, x: ArrayLike) -> Array:
        """The components of x (p,) along N, in bound-scaled units, shape (k,)."""
        return np.asarray((np.asarray(x, dtype=np.float64) / self.scale) @ self.basis,
                          dtype=np.float64)


def _sparse_names(basis: Array, column_units: Array, names: tuple[str, ...]) -> tuple[str, ...]:
    """Readable names of a subspace, in column-scaled units as
    :func:`twin.analysis.identifiability.name_direction` names null directions: its basis
    turned so that each direction has one pivot unknown, 1 on its own pivot and 0 on the
    others'. The pivots are the unknowns the subspace moves most (QR with column pivoting; on a
    tie the last in the order of x), so every other coefficient stays of order one and each
    name carries its own pivot: pivots chosen by rank alone could fall on an unknown the
    subspace barely moves, whose inverse blew the others up until every name read alike."""
    k = basis.shape[1]
    scaled = column_units[:, None] * basis
    # Reversed, so that of equal candidates the pivoting takes the last unknown.
    pivots = scaled.shape[0] - 1 - pivot_columns(scaled[::-1].T, k)
    sparse = scaled @ np.linalg.inv(scaled[pivots])
    sparse[np.abs(sparse) < 1e-12] = 0.0
    return tuple(name_direction(sparse[:, j], names) for j in np.argsort(pivots))


def rig_unknowns(model: Model) -> NDArray[np.bool_]:
    """Which unknowns are the rig's (the measurement's and the measured point's groups), (p,)."""
    rig = np.zeros(model.n_params, dtype=bool)
    for group in model.groups:
        if group.stage in (Stage.MEASUREMENT, Stage.POINT):
            rig[model.slice(group.name)] = True
    return rig


def _column_units(jacobian: Array, scale: Array) -> Array:
    """Each bound-scaled unknown's column norm, for names in column-scaled units (a column that
    moves nothing counts as a typical one)."""
    units = np.linalg.norm(jacobian, axis=0) * scale
    moving = units > RANK_RTOL * np.max(units, initial=0.0)
    typical = float(np.median(units[moving])) if np.any(moving) else 1.0
    return np.where(moving, units, typical)


class _Sight(NamedTuple):
    """What the data see at one x, before any candidate is held: the tests with and without
    the start read it alike."""

    scale: Array
    """The unknowns' plausible moves, shape (p,) (:func:`unseen_directions`' ``scale``)."""
    weight: Array
    """The hold's weight w, shape (p,)."""
    jacobian: Array
    """The linearised rows' Jacobian, shape (M, p)."""
    best: float
    """The largest singular value of the bound-scaled Jacobian."""
    exact: Array
    """Orthonormal basis of its exact null space, bound-scaled, shape (p, e)."""
    covariance: Array
    """The Cramér–Rao covariance of the bound-scaled unknowns, every other one free, (p, p)."""
    candidates: Array
    """The nominal null directions as unit vectors, bound-scaled, shape (p, k)."""
    outside: Array
    """Each candidate's distance from the exact null space, shape (k,)."""
    sigma: Array
    """Each candidate's Cramér–Rao σ, in half-ranges of the box, shape (k,)."""


def _sight(model: Model, x: Array, data: Measurements, noise_m: float, scale: Array,
           nominal: Identifiability, row_weight: ArrayLike | None) -> _Sight:
    """The factorisation and the candidates' tests at x (arguments of
    :func:`unseen_directions`)."""
    weight = np.where(rig_unknowns(model), RIG_WEIGHT, 1.0) * scale
    linearised = linearise(model, x, data, row_weight)
    # The scaled J's singular values and right vectors are its R factor's, scaled alike.
    _, s, vt = np.linalg.svd(linearised.triangle * scale, full_matrices=True)
    s = np.concatenate([s, np.zeros(scale.size - s.size)])
    exact = vt[s <= RANK_RTOL * max(s[0], 1e-300)].T
    keep = s > RANK_RTOL * max(s[0], 1e-300)
    covariance = (vt[keep].T / s[keep] ** 2) @ vt[keep] * noise_m**2
    candidates = nominal.null_space / scale[:, None]
    candidates = candidates / np.linalg.norm(candidates, axis=0)
    outside = np.linalg.norm(candidates - exact @ (exact.T @ candidates), axis=0)
    sigma = np.sqrt(np.maximum(np.einsum("pk,pq,qk->k", candidates, covariance, candidates),
                               0.0))
    return _Sight(scale, weight, linearised.jacobian, float(s[0]), exact, covariance,
                  candidates, outside, sigma)


def _held(sight: _Sight, noise_m: float, offset: Array | None) -> NDArray[np.bool_]:
    """Which candidates are held (module docstring); the weak ones the answer does not tell
    from the start too when ``offset`` (the answer less the start, bound-scaled, (p,)) is
    given."""
    sigma = sight.sigma
    held = (sight.outside < INSIDE_TOL) | (sigma > HELD_SIGMA) | ~np.isfinite(sigma)
    if offset is not None and noise_m > 0:
        # Weak: seen below WEAK_RTOL of the best-seen direction (σ·s_max/σ̂ is the inverse of
        # its relative sensitivity), as the identifiability report counts weak directions.
        weak = ~held & (sigma * sight.best > noise_m / WEAK_RTOL)
        held |= _indistinct(sight.candidates, sight.covariance, weak, offset)
    return np.asarray(held)


def _subspace(sight: _Sight, held: NDArray[np.bool_], nominal: Identifiability, model: Model,
              noise_m: float, named: bool = True) -> Unseen:
    """The unseen subspace of the exact null space and the ``held`` candidates (its names
    left empty unless ``named``)."""
    scale, weight, exact, candidates = sight.scale, sight.weight, sight.exact, sight.candidates
    # A held candidate adds to the exact null space only what lies outside it: a candidate
    # inside it (to INSIDE_TOL) would add its round-off, normalised into a random direction.
    new = held & (sight.outside >= INSIDE_TOL)
    rest = candidates[:, new] - exact @ (exact.T @ candidates[:, new])
    basis = exact
    if rest.shape[1]:
        u, singular, _ = np.linalg.svd(rest, full_matrices=False)
        basis = np.column_stack([exact, u[:, singular > INSIDE_TOL]])
    if basis.shape[1]:
        # The same subspace, orthonormal in the hold's weighted unknowns.
        basis = np.linalg.qr(basis * (scale / weight)[:, None])[0]
    weak = ~held & (sight.sigma > WEAK_SIGMA)
    labels = np.asarray(nominal.unidentifiable, dtype=object)
    names = (*labels[held], *_extra_names(
        basis, candidates[:, held] * (scale / weight)[:, None], sight.jacobian, weight,
        model.names)) if named else ()
    return Unseen(weight, np.asarray(basis, dtype=np.float64), names,
                  float(noise_m), tuple(labels[weak]),
                  np.asarray(sight.sigma[weak], dtype=np.float64))


def unseen_directions(model: Model, x: ArrayLike, data: Measurements, noise_m: float,
                      scale: ArrayLike, nominal: Identifiability,
                      row_weight: ArrayLike | None = None, start: ArrayLike | None = None,
                      *, named: bool = True) -> Unseen:
    """What ``data`` cannot see at the unknowns x (module docstring).

    Args:
        model: The measurement model.
        x: The unknowns the Jacobian is evaluated at (the identified ones), shape (p,).
        data: The poses (the training poses of a fit).
        noise_m: The noise 1σ of a reading the Cramér–Rao test uses, m (0: the rank test
            alone).
        scale: How far each unknown may plausibly move, shape (p,): its prior's σ, else half
            its search range (:meth:`twin.model.Model.scale`).
        nominal: What the same poses identify at the start geometry: its null directions are
            the candidates.
        row_weight: σ / σ_i of each row of ``data`` (M,), when the rows' noise differs (errors
            in variables, :class:`twin.problem.Problem`); ``noise_m`` is then that of a
            scaled row.
        start: Where the fit started (the nominal), shape (p,): a candidate whose value from
            it is within :data:`SIGNIFICANT_SIGMAS` of its σ is held too; None: no such test.
        named: False leaves the names empty: the subspace alone, for a look that reads
            nothing else (the hold's looks again after each hold, where naming was a tenth
            of a fixed-point or plane capture's hold).
    """
    x = np.asarray(x, dtype=np.float64)
    scale = np.asarray(scale, dtype=np.float64)
    sight = _sight(model, x, data, noise_m, scale, nominal, row_weight)
    offset = None if start is None else (x - np.asarray(start, np.float64)) / scale
    return _subspace(sight, _held(sight, noise_m, offset), nominal, model, noise_m, named)


def unseen_with_weak(model: Model, x: ArrayLike, data: Measurements, noise_m: float,
                     scale: ArrayLike, nominal: Identifiability, row_weight: ArrayLike | None,
                     start: ArrayLike) -> tuple[Unseen, Unseen]:
    """:func:`unseen_directions` at one x without and with ``start``, the Jacobian factorised
    once for both (the same subspace twice when the start's test holds nothing more)."""
    x = np.asarray(x, dtype=np.float64)
    scale = np.asarray(scale, dtype=np.float64)
    sight = _sight(model, x, data, noise_m, scale, nominal, row_weight)
    held = _held(sight, noise_m, None)
    with_start = _held(sight, noise_m, (x - np.asarray(start, np.float64)) / scale)
    unseen = _subspace(sight, held, nominal, model, noise_m)
    if np.array_equal(held, with_start):
        return unseen, unseen
    return unseen, _subspace(sight, with_start, nominal, model, noise_m)


def _indistinct(candidates: Array, covariance: Array, weak: NDArray[np.bool_], offset: Array
                ) -> NDArray[np.bool_]:
    """Which weak candidates (k,) the answer does not tell from the start: each within
    :data:`SIGNIFICANT_SIGMAS` of its σ, and all of those together within the χ² quantile of
    the same level — so that several weak directions that each look like noise but together
    carry a real effect (the compliances of link-by-link masses) are kept.

    Args:
        candidates: Unit candidate directions in the bound-scaled unknowns, shape (p, k).
        covariance: Cramér–Rao covariance of the bound-scaled unknowns, shape (p, p).
        weak: Which candidates are weakly seen, shape (k,).
        offset: The answer minus the start, bound-scaled, shape (p,).
    """
    if not np.any(weak):
        return np.zeros(weak.shape, dtype=bool)
    coordinates = np.linalg.pinv(candidates)
    value = coordinates @ offset
    value_covariance = coordinates @ covariance @ coordinates.T
    sigma = np.sqrt(np.maximum(np.diag(value_covariance), 0.0))
    rows = np.flatnonzero(weak & (np.abs(value) < SIGNIFICANT_SIGMAS * sigma))
    if not rows.size:
        return np.zeros(weak.shape, dtype=bool)
    chosen = value[rows]
    statistic = float(chosen @ np.linalg.pinv(value_covariance[np.ix_(rows, rows)]) @ chosen)
    indistinct = np.zeros(weak.shape, dtype=bool)
    indistinct[rows] = statistic < chi2_quantile(1 - SIGNIFICANCE_LEVEL, rows.size)
    return indistinct


def _extra_names(basis: Array, named: Array, jacobian: Array, scale: Array,
                 names: tuple[str, ...]) -> tuple[str, ...]:
    """Names of the unseen directions beyond the named candidates (exact null directions of
    the identified geometry the start geometry did not have)."""
    if basis.shape[1] <= named.shape[1]:
        return ()
    if named.shape[1]:
        q, _ = np.linalg.qr(named)
        rest = basis - q @ (q.T @ basis)
        u = np.linalg.svd(rest, full_matrices=False)[0]
        rest = u[:, : basis.shape[1] - named.shape[1]]
    else:
        rest = basis
    return _sparse_names(rest, _column_units(jacobian, scale), names)


__all__ = ["HELD_SIGMA", "RIG_WEIGHT", "SIGNIFICANT_SIGMAS", "WEAK_SIGMA", "Unseen",
           "rig_unknowns", "unseen_directions", "unseen_with_weak"]
