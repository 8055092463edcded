"""What a set of cable lengths can and cannot identify.

One cable length per pose gives one row of the Jacobian J = ∂ℓ/∂x (m, p). Its numerical rank
says how many combinations of the unknowns the measurement set determines; the rest — the null
space — moves no cable length at all, so any method returns arbitrary values along it.

How it is computed, and why:

- **Column scaling.** Lengths (m) and angles (rad) have different units, so J is scaled column
  by column to unit norm before its singular values are compared: the rank and the condition
  number are then independent of the units. A column whose norm is negligible against the
  largest (below :data:`COLUMN_RTOL`) is declared unidentifiable *directly* and left out: scaling
  such a column (θ6, α6 of the IRB 120 have norms ~1e-17 m/rad, round-off) up to unit norm
  would turn round-off into a fake identifiable direction.
- **Rank.** Singular values of the scaled J below :data:`RANK_RTOL` times the largest count as
  zero. For distance-only data on the IRB 120 the gap is some fourteen orders of magnitude wide
  (1e-2 against 1e-16), so the rank does not hinge on the tolerance.
- **Base parameters.** Going through the unknowns in the order of x, each one whose column
  raises the numerical rank of those kept so far is kept: the base set is then the same for any
  pose set with the same structure (d2 is kept, d3 depends on it), instead of following the
  round-off that breaks ties in a pivoted QR. (Should this in-order choice not reach the rank —
  only on a tolerance right at a singular value — pivoted QR picks the base instead.) Each
  dependent column is a combination of base columns, J_D = J_B β, so ``e_dependent − β`` (in
  scaled units) is a null direction. These directions are sparse and readable: ``d2-d3``,
  ``a5+theta5``…
- **Names.** A null direction is printed in the scaled space (each unknown in units of its own
  column norm, so the coefficients are dimensionless and comparable), terms in the order of x,
  largest coefficient ±1 and the first term positive; coefficients below
  :data:`NAME_COEFFICIENT_TOL` are dropped and coefficients within that of ±1 are not printed.
"""

from __future__ import annotations

import warnings
import weakref
from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.analysis.linearisation import fingerprint, linearise
from twin.arrays import Array
from twin.dataset import Measurements
from twin.model import NULL_RTOL, Model
from twin.robot import RobotModel, random_poses
from twin.unknowns import Stage

RANK_RTOL = NULL_RTOL
"""Singular values below this fraction of the largest are treated as zero."""
COLUMN_RTOL = 1e-8
"""Columns whose norm is below this fraction of the largest are unidentifiable outright."""
WEAK_RTOL = 1e-3
"""Identified singular values below this fraction of the largest count as weak: noise along
them is amplified more than a thousandfold against the best-seen direction."""
NAME_COEFFICIENT_TOL = 1e-3
"""Coefficients of a named null direction smaller than this (relative) are left out."""
DECIDED_MARGIN = 2.0
"""The base parameters' quick test leaves to the SVD of each trial the columns whose distance,
or the kept columns whose σ_min, lies within this factor of the rank's threshold."""
PIVOT_TIE_RTOL = 1e-12
"""Column distances within this fraction of the largest are a tie for :func:`pivot_columns`,
which takes the first of them."""
SPREAD_POSES = 200
"""Random poses of :func:`spread_rank`: many times the unknowns, so no direction is missed by
chance."""


class RankWarning(UserWarning):
    """Poses that identify fewer directions than the same unknowns on well-spread poses."""


class Identifiability(NamedTuple):
    """What one Jacobian identifies.

    The unknowns are those of the Jacobian's columns (p of them), named by ``names``.
    """

    rank: int
    """Numerical rank of the scaled Jacobian."""
    n_params: int
    """Number of unknowns p."""
    condition: float
    """σ_max / σ_min of the scaled Jacobian over its ``rank`` non-zero singular values."""
    singular_values: Array
    """Singular values of the scaled Jacobian (without the negligible columns), descending."""
    tolerance: float
    """Relative singular-value cutoff used for the rank."""
    names: tuple[str, ...]
    """Names of the unknowns, length p."""
    column_norms: Array
    """Norm of each column of the unscaled Jacobian, shape (p,), m/m or m/rad."""
    base: NDArray[np.intp]
    """Indices of the base parameters, shape (rank,), ascending."""
    null_space: Array
    """Null directions in the units of x (m and rad), shape (p, p − rank), one per column."""
    unidentifiable: tuple[str, ...]
    """Each null direction named as a combination, e.g. ``theta6``, ``d2-d3``."""
    weak_names: tuple[str, ...] = ()
    """Each weakly identified direction (singular value below :data:`WEAK_RTOL` of the largest,
    above the rank's threshold) named as a combination, weakest last."""
    weak_leading: NDArray[np.intp] = np.zeros(0, dtype=np.intp)
    """The unknown whose coefficient leads each weak direction's name (its unit is the
    direction's), shape (w,)."""
    weak_sigma_per_noise: Array = np.zeros(0)
    """σ along each weak direction, in the unit of its leading unknown, per metre of reading
    noise: multiplied by the noise σ it is the Cramér–Rao σ of the combination, shape (w,)."""
    beyond_points: tuple[str, ...] = ()
    """For a kind that reads more than a point (a 6-D pose), the combinations its point rows
    alone cannot identify and its other rows do (:func:`seen_beyond_points`), named."""

    @property
    def weak(self) -> int:
        """How many of the ``rank`` identified directions are weak (see :data:`WEAK_RTOL`)."""
        s = self.singular_values[: self.rank]
        return int(np.sum(s < WEAK_RTOL * s[0]))

    @property
    def dependent(self) -> NDArray[np.intp]:
        """Indices of the unknowns that are not base parameters, shape (p − rank,)."""
        return _others(self.n_params, self.base)

    @property
    def base_mask(self) -> NDArray[np.bool_]:
        """True for the base parameters, shape (p,)."""
        mask = np.zeros(self.n_params, dtype=bool)
        mask[self.base] = True
        return mask

    @property
    def base_names(self) -> tuple[str, ...]:
        """Names of the base parameters, in the order of x."""
        return tuple(self.names[i] for i in np.sort(self.base))


def _format_coefficient(value: float, name: str, first: bool) -> str:
    sign = "-" if value < 0 else ("" if first else "+")
    magnitude = abs(value)
    if abs(magnitude - 1.0) < NAME_COEFFICIENT_TOL:
        return f"{sign}{name}"
    return f"{sign}{magnitude:.3g}*{name}"


def name_direction(direction: ArrayLike, names: tuple[str, ...]) -> str:
    """A readable name of one direction given in scaled units, e.g. ``a5+0.302*theta5``.

    Args:
        direction: Coefficients in the scaled space, shape (p,).
        names: Names of the unknowns, length p.
    """
    v = np.asarray(direction, dtype=np.float64)
    v = v / v[np.argmax(np.abs(v))]
    terms = np.flatnonzero(np.abs(v) >= NAME_COEFFICIENT_TOL)
    v = v * np.sign(v[terms[0]])
    return "".join(
        _format_coefficient(float(v[k]), names[k], first=i == 0) for i, k in enumerate(terms)
    )


def _others(count: int, taken: ArrayLike) -> NDArray[np.intp]:
    """The indices 0 … count − 1 not in ``taken``, ascending (``np.setdiff1d`` on a range, by a
    mask: a tenth of its time, which sorts)."""
    kept = np.ones(count, dtype=bool)
    kept[np.asarray(taken, dtype=np.intp)] = False
    return np.flatnonzero(kept)


def _base_in_order(R: Array, threshold: float, order: NDArray[np.intp]) -> NDArray[np.intp]:
    """Columns tried in ``order``, each kept if it raises the rank of those kept
    (σ_min > threshold); returned ascending."""
    decided = _base_by_distances(R, threshold, order)
    if decided is not None:
        return decided
    if R.shape[0] >= R.shape[1]:
        return _base_by_bisection(R, threshold, order)
    kept: list[int] = []
    for column in order:
        trial = R[:, [*kept, column]]
        if np.linalg.svd(trial, compute_uv=False)[-1] > threshold:
            kept.append(int(column))
    return np.sort(np.asarray(kept, dtype=np.intp))


def pivot_columns(matrix: ArrayLike, count: int) -> NDArray[np.intp]:
    """The first ``count`` pivots of QR with column pivoting (Businger & Golub 1965), shape
    (count,): at each step the column farthest from the span of those taken before, the first
    of those within :data:`PIVOT_TIE_RTOL` of it.

    Modified Gram–Schmidt on a copy of ``matrix`` (m, n): its distances are as accurate as
    Householder's R (Björck 1967). Numpy has no pivoted QR, and scipy.linalg's, the only use of
    scipy.linalg on a calibration's path, cost every command that calibrates 0.1 s to import.
    LAPACK's takes the first of bitwise-equal downdated norms, where round-off decides a tie.
    """
    rest = np.array(matrix, dtype=np.float64)
    taken = np.zeros(rest.shape[1], dtype=bool)
    pivots = np.empty(count, dtype=np.intp)
    for step in range(count):
        squares = np.einsum("ij,ij->j", rest, rest)
        squares[taken] = -1.0
        largest = float(squares.max())
        pivot = int(np.argmax(squares >= largest * (1.0 - PIVOT_TIE_RTOL) ** 2))
        pivots[step] = pivot
        taken[pivot] = True
        if largest > 0.0:
            direction = rest[:, pivot] / np.sqrt(largest)
            rest -= np.outer(direction, direction @ rest)
    return pivots


def _base_by_bisection(R: Array, threshold: float, order: NDArray[np.intp]) -> NDArray[np.intp]:
    """:func:`_base_in_order`'s decisions for a tall R, about log₂ p SVDs per rejected column
    instead of one per column: σ_min of the kept columns and the first j of the rest cannot
    rise as j grows (interlacing, for as many rows as columns), so the first column that takes
    it to the threshold is found by bisection; the ones before it are kept, it is not."""
    kept: list[int] = []
    rest = [int(column) for column in order]
    while rest:
        passing, failing = 0, len(rest) + 1  # the longest prefix known to pass, one known not
        while failing - passing > 1:
            middle = (passing + failing) // 2
            if np.linalg.svd(R[:, [*kept, *rest[:middle]]], compute_uv=False)[-1] <= threshold:
                failing = middle
            else:
                passing = middle
        kept += rest[:passing]
        rest = rest[passing + 1:]
    return np.sort(np.asarray(kept, dtype=np.intp))


def _base_by_distances(R: Array, threshold: float, order: NDArray[np.intp]
                       ) -> NDArray[np.intp] | None:
    """:func:`_base_in_order`'s decisions with one QR per rejected column and one SVD in all,
    instead of one SVD per column; None where that cannot vouch for them.

    A column's distance from the span of those kept before it (the diagonal of the R factor of
    the columns in that order) bounds from above the smallest singular value of the kept
    columns with it: at or below the threshold it is rejected, and with a margin of
    :data:`DECIDED_MARGIN` that cannot be round-off. Every column kept this way is vouched for
    at the end: the columns kept in all have σ_min above the threshold, and fewer of them
    (each earlier trial) have σ_min no smaller (interlacing).
    """
    if R.shape[0] < R.shape[1]:
        return None  # wider than tall: more columns than rows can pass, as the SVD test has it
    kept: list[int] = []
    rest = [int(column) for column in order]
    while rest:
        distance = np.abs(np.diagonal(np.linalg.qr(R[:, [*kept, *rest]], mode="r")))[len(kept):]
        rejected = np.flatnonzero(distance <= threshold * DECIDED_MARGIN)
        first = int(rejected[0]) if rejected.size else len(rest)
        if first < len(rest) and distance[first] > threshold / DECIDED_MARGIN:
            return None
        kept += rest[:first]
        rest = rest[first + 1:]
    if kept and np.linalg.svd(R[:, kept], compute_uv=False)[-1] <= threshold * DECIDED_MARGIN:
        return None
    return np.sort(np.asarray(kept, dtype=np.intp))


def identifiability(
    jacobian: ArrayLike,
    names: tuple[str, ...] | list[str],
    rtol: float = RANK_RTOL,
    prefer: Sequence[int] = (),
    triangle: ArrayLike | None = None,
) -> Identifiability:
    """Rank, condition, base parameters and named null directions of a Jacobian.

    Args:
        jacobian: Cable-length Jacobian ∂ℓ/∂x, shape (m, p), m/m and m/rad.
        names: Names of the p unknowns.
        rtol: Relative singular-value cutoff of the rank.
        prefer: Unknowns to try first as base parameters; the rest follow in the order of x.
        triangle: The R factor of ``jacobian`` (:mod:`twin.analysis.linearisation`), shape
            (min(m, p), p), when it is already known: not factorised again.

    Returns:
        The :class:`Identifiability` of the measurement set at the geometry J was computed at.
    """
    J = np.asarray(jacobian, dtype=np.float64)
    names = tuple(names)
    p = J.shape[1]
    if len(names) != p:
        raise ValueError(f"{len(names)} names for {p} columns")
    norms = np.linalg.norm(J, axis=0)
    visible = np.flatnonzero(norms > COLUMN_RTOL * np.max(norms))
    scaled = J[:, visible] / norms[visible]
    # R has J's Gram matrix, so every rank decision below can work on it instead of J (the
    # scaled J's R is J's with the same columns scaled).
    R = np.asarray(np.linalg.qr(scaled, mode="r"), dtype=np.float64) if triangle is None \
        else np.asarray(triangle, dtype=np.float64)[:, visible] / norms[visible]
    _, singular_values, vt = np.linalg.svd(R)
    threshold = rtol * singular_values[0]
    rank = int(np.sum(singular_values > threshold))
    preferred = np.zeros(p, dtype=bool)
    preferred[np.asarray(prefer, dtype=np.intp)] = True
    first = np.flatnonzero(preferred[visible])
    order = np.r_[first, _others(visible.size, first)].astype(np.intp)
    base_local = _base_in_order(R, threshold, order)
    if base_local.size != rank:
        base_local = np.sort(pivot_columns(R, rank))
    dependent_local = _others(visible.size, base_local)
    beta = np.linalg.lstsq(R[:, base_local], R[:, dependent_local], rcond=None)[0]
    # Scaled null directions: one per negligible column, then e_dependent − β for each dependent.
    invisible = _others(p, visible)
    directions = np.zeros((p, p - rank))
    directions[invisible, np.arange(invisible.size)] = 1.0
    columns = invisible.size + np.arange(dependent_local.size)
    directions[visible[dependent_local], columns] = 1.0
    directions[np.ix_(visible[base_local], columns)] = -beta
    labels = tuple(name_direction(directions[:, k], names) for k in range(p - rank))
    unit = np.where(norms > 0, norms, 1.0)
    null_si = directions / unit[:, None]
    null_si /= np.linalg.norm(null_si, axis=0)
    weak = _weak_directions(singular_values[:rank], vt[:rank], visible, norms, names)
    return Identifiability(
        rank=rank,
        n_params=p,
        condition=float(singular_values[0] / singular_values[rank - 1]),
        singular_values=singular_values,
        tolerance=rtol,
        names=names,
        column_norms=norms,
        base=visible[base_local],
        null_space=null_si,
        unidentifiable=labels,
        weak_names=weak[0],
        weak_leading=weak[1],
        weak_sigma_per_noise=weak[2],
    )


def _weak_directions(s: Array, vt: Array, visible: NDArray[np.intp], norms: Array,
                     names: tuple[str, ...]) -> tuple[tuple[str, ...], NDArray[np.intp], Array]:
    """The weak identified directions: names, leading unknowns and σ per unit noise.

    A right singular vector v (scaled units) with singular value s has a coefficient of
    variance σ²/s²; along the SI direction normalised to 1 on its leading unknown k, the
    coefficient's σ is σ |v_k| / (s ‖J_k‖).
    """
    weak = np.flatnonzero(s < WEAK_RTOL * s[0])
    directions = np.zeros((weak.size, norms.size))
    directions[:, visible] = vt[weak]
    leading = np.argmax(np.abs(directions), axis=1).astype(np.intp)
    factor = np.abs(directions[np.arange(weak.size), leading]) / (s[weak] * norms[leading])
    return (tuple(name_direction(row, names) for row in directions), leading,
            np.asarray(factor, dtype=np.float64))


def measurement_identifiability(
    model: Model, x: ArrayLike, data: Measurements, rtol: float = RANK_RTOL
) -> Identifiability:
    """:func:`identifiability` of the model's Jacobian at unknowns ``x`` (p,) and poses.

    The rig's unknowns (port correction, length offset, attachment point, tracker frame…) are
    preferred as base parameters: where they trade against a D-H error (d1 + port_z, d6 +
    attachment_z), the unknown with the wide bound carries the combination and the D-H error,
    bounded to ±5 mm, is the one held.
    """
    x = np.asarray(x, dtype=np.float64)
    key = (x.tobytes(), fingerprint(data), float(rtol))
    for model_ref, kept_key, kept in _KEPT:
        if model_ref() is model and kept_key == key:
            return kept
    linearised = linearise(model, x, data)
    prefer = [index for group in model.groups
              if group.stage in (Stage.MEASUREMENT, Stage.POINT)
              for index in range(model.n_params)[model.slice(group.name)]]
    found = identifiability(linearised.jacobian, model.names, rtol, prefer=prefer,
                            triangle=linearised.triangle)
    found = found._replace(beyond_points=seen_beyond_points(model, linearised.jacobian, found,
                                                            rtol))
    _KEPT[:] = [*_KEPT[-(KEPT - 1):], (weakref.ref(model), key, found)]
    return found


SEEN_RTOL = 1e-6
"""A direction the point rows leave unseen counts as seen by the whole rows when it lies farther
than this (relative, column-scaled) from the whole rows' null space."""


def seen_beyond_points(model: Model, jacobian: Array, whole: Identifiability,
                       rtol: float = RANK_RTOL) -> tuple[str, ...]:
    """The null directions of a kind's point rows (:attr:`twin.kinds.base.Kind.point_rows`: a
    6-D pose's x, y, z) that its whole rows (``jacobian``, (M, p), and its ``whole``
    identifiability) see, named: what orientations add to positions. Empty for a kind that
    reads a point or less."""
    rows, per = model.kind.point_rows, model.kind.rows_per_pose
    if not rows:
        return ()
    poses = jacobian.shape[0] // per
    pick = (np.arange(poses)[:, None] * per + np.asarray(rows)).ravel()
    points = identifiability(jacobian[pick], model.names, rtol)
    unit = np.where(whole.column_norms > 0, whole.column_norms, 1.0)
    basis = whole.null_space * unit[:, None]
    seen = []
    for k, name in enumerate(points.unidentifiable):
        direction = points.null_space[:, k] * unit
        left = direction - basis @ np.linalg.lstsq(basis, direction, rcond=None)[0] \
            if basis.shape[1] else direction
        if np.linalg.norm(left) > SEEN_RTOL * np.linalg.norm(direction):
            seen.append(name)
    return tuple(seen)


KEPT = 8
"""Identifiabilities :func:`measurement_identifiability` keeps: a calibration asks for the same
one (the start's, on the training poses) from the hold, the uncertainty and the checks after
it, and a study trial again on the same poses; they are read-only values of immutable inputs,
recognised by the model's identity and the poses' content
(:func:`twin.analysis.linearisation.fingerprint`), the model held weakly."""
_KEPT: list[tuple[weakref.ref[Model], tuple[bytes, bytes, float], Identifiability]] = []


def spread_rank(model: Model, robot: RobotModel, rng: np.random.Generator,
                n_poses: int = SPREAD_POSES) -> int:
    """The rank the model's unknowns reach on well-spread poses: ``n_poses`` drawn uniformly
    within the robot's joint limits, at the nominal geometry.

    This is the reference a measurement set's rank is held against: with distance data on the
    IRB 120 it is 19 of 24 (five directions no cable length sees), and a set of poses that
    reaches less misses directions it could have seen.
    """
    x0 = np.zeros(model.n_params)
    spread = model.measure(x0, random_poses(robot, n_poses, rng))
    return measurement_identifiability(model, x0, spread).rank


def warn_rank_deficient(robot: RobotModel, model: Model, x0: ArrayLike, train: Measurements,
                        source: str | Path, seed: int) -> None:
    """Warn, before anything is calibrated, when the training poses identify fewer directions
    than the same unknowns on well-spread poses: the result is then arbitrary along the
    directions these poses miss (all rows alike give rank 1)."""
    found = measurement_identifiability(model, x0, train).rank
    reachable = spread_rank(model, robot, np.random.default_rng(seed))
    if found < reachable:
        warnings.warn(
            f"{source}: the {len(train)} training poses identify {found} of the "
            f"{reachable} directions well-spread poses identify ({model.n_params} "
            "unknowns); the calibration below is arbitrary along the other "
            f"{reachable - found}: measure more varied poses (twin plan)",
            RankWarning, stacklevel=2)


class Observability(NamedTuple):
    """Observability indices of a Jacobian (Sun & Hollerbach 2008), over its non-zero
    singular values σ_1 ≥ … ≥ σ_L of the base-parameter columns; larger is better, except
    for the condition number."""

    o1: float
    """(σ_1 ⋯ σ_L)^(1/L) / √m: geometric mean of the singular values per pose (D-optimality)."""
    o3: float
    """σ_L, the smallest singular value (E-optimality)."""
    o4: float
    """σ_L² / σ_1, the noise amplification index."""
    condition: float
    """σ_1 / σ_L."""


def observability(jacobian: ArrayLike) -> Observability:
    """Observability indices of a full-column-rank Jacobian, shape (m, L).

    Pass the base-parameter columns in fixed units (for example SI) so that indices of
    different pose sets compare.
    """
    J = np.asarray(jacobian, dtype=np.float64)
    s = np.linalg.svd(J, compute_uv=False)
    return Observability(
        o1=float(np.exp(np.mean(np.log(s))) / np.sqrt(J.shape[0])),
        o3=float(s[-1]),
        o4=float(s[-1] ** 2 / s[0]),
        condition=float(s[0] / s[-1]),
    )
