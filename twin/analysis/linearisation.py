"""The model linearised at a point, computed once and shared by every check after a fit.

Identifiability, the unseen and weak directions, the uncertainty and the Cramér–Rao bound all
read the same thing: the identifiable Jacobian J (M, p) of a model at unknowns x on a set of
poses (its rows scaled by σ/σ_i when the rows' noise differs), and they ask for it several
times at the same x — the answer a method returned is held, checked, bounded and compared
with the truth. Here it is evaluated once, with one QR factorisation J = Q R. Everything those
checks compute depends on J only through JᵀJ = RᵀR, so they factorise the small R (p, p)
instead of J: J D = Q (R D) for any column scaling D, so R D has the singular values and right
singular vectors of J D (to round-off), and the same Gram matrix.

Linearisations are kept for a few recent points (:data:`KEPT`), recognised by the model's
identity, x, the poses' content and the rows' weights; their arrays are read-only. The same
goes for the flange's and the measured point's Jacobians over workspace poses
(:func:`chain_jacobian`), which the unobservable motions and the uncertainty both read, and
for the model's own Jacobian (:func:`model_jacobian`), which is the identifiable one of a kind
without known gauge directions.
"""

from __future__ import annotations

import hashlib
import weakref
from collections.abc import Callable
from typing import NamedTuple, TypeVar

import numpy as np
from numpy.typing import ArrayLike

from twin.arrays import Array
from twin.dataset import Measurements
from twin.model import Model

KEPT = 8
"""Linearisations kept: a calibration and a study trial come back to the same three or four
points — the start, the answer, the truth."""
KEPT_CHAINS = 2
"""Chain Jacobians kept: the unobservable motions and the uncertainty read the flange's one
after the other, at the answer over the same workspace; over thousands of workspace poses each
weighs megabytes."""

Kept = TypeVar("Kept")


class Linearisation(NamedTuple):
    """The model at one point on one set of poses, rows weighted; arrays read-only."""

    residuals: Array
    """Residual rows r_i w_i, shape (M,), m."""
    jacobian: Array
    """Identifiable Jacobian rows J_i w_i (:meth:`twin.model.Model.identifiable_jacobian`),
    shape (M, p)."""
    triangle: Array
    """R of J = Q R, shape (min(M, p), p): RᵀR = JᵀJ."""


def fingerprint(data: Measurements) -> bytes:
    """A digest of everything a model reads from ``data`` (joints, readings, indices, labels,
    names): equal sets made apart (a subset taken twice) share what is kept for them."""
    digest = hashlib.blake2b(digest_size=16)
    arrays: list[np.ndarray] = [data.q_rad, *(data.values[name] for name in sorted(data.values)),
                                *(data.labels[name].indices for name in sorted(data.labels))]
    if data.approach is not None:
        arrays.append(data.approach)
    for value in arrays:
        digest.update(np.ascontiguousarray(value).tobytes())
        digest.update(b"|")
    digest.update(repr((data.kind, data.q_rad.shape, data.approach is None,
                        [(name, data.values[name].shape) for name in sorted(data.values)],
                        [(name, data.labels[name].names) for name in sorted(data.labels)])
                       ).encode())
    return digest.digest()


def _key(x: Array, data: Measurements, *extra: object) -> tuple[object, ...]:
    return (x.tobytes(), fingerprint(data), *extra)


def _kept(store: list[tuple[weakref.ref[Model], tuple[object, ...], Kept]], model: Model,
          key: tuple[object, ...], make: Callable[[], Kept], size: int) -> Kept:
    """The value kept in ``store`` for (model, key), else ``make()`` kept there with the last
    ``size - 1`` others."""
    for model_ref, kept_key, value in store:
        if model_ref() is model and kept_key == key:
            return value
    value = make()
    store[:] = [*store[len(store) - size + 1:], (weakref.ref(model), key, value)]
    return value


def _read_only(*arrays: Array) -> None:
    for array in arrays:
        array.setflags(write=False)


def linearise(model: Model, x: ArrayLike, data: Measurements,
              row_weight: ArrayLike | None = None) -> Linearisation:
    """The model's identifiable residuals and Jacobian at unknowns x (p,) on ``data``, each row
    scaled by ``row_weight`` (M,) when given (σ/σ_i, errors in variables), and the R factor
    of that Jacobian; kept for the next caller at the same point."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    weight = None if row_weight is None \
        else np.ascontiguousarray(row_weight, dtype=np.float64)

    def make() -> Linearisation:
        # Without known gauge directions the identifiable Jacobian is the model's own, which
        # a trial's noise and a fit's steps read too.
        residuals, jacobian = model.identifiable_jacobian(x, data) \
            if model.symmetries(x).shape[1] else model_jacobian(model, x, data)
        if weight is not None:
            residuals, jacobian = residuals * weight, jacobian * weight[:, None]
        triangle = np.asarray(np.linalg.qr(jacobian, mode="r"), dtype=np.float64)
        _read_only(residuals, jacobian, triangle)
        return Linearisation(residuals, jacobian, triangle)

    return _kept(_LINEARISED, model, _key(x, data, None if weight is None else
                                          weight.tobytes()), make, KEPT)


def model_jacobian(model: Model, x: ArrayLike, data: Measurements) -> tuple[Array, Array]:
    """The model's residuals (M,) and Jacobian (M, p) at unknowns x (p,) on ``data``
    (:meth:`twin.model.Model.jacobian`), read-only; kept for the next caller."""
    x = np.ascontiguousarray(x, dtype=np.float64)

    def make() -> tuple[Array, Array]:
        residuals, jacobian = model.jacobian(x, data)
        _read_only(residuals, jacobian)
        return residuals, jacobian

    return _kept(_JACOBIANS, model, _key(x, data), make, KEPT)


def chain_jacobian(model: Model, x: ArrayLike, data: Measurements, *, measured: bool) -> Array:
    """∂(measured point)/∂x (``measured``) or ∂(flange centre)/∂x at unknowns x (p,) over the
    poses of ``data``, shape (m, 3, p) (:meth:`twin.model.Model.position_jacobian`,
    :meth:`~twin.model.Model.flange_jacobian`), read-only; kept for the next caller."""
    x = np.ascontiguousarray(x, dtype=np.float64)

    def make() -> Array:
        jacobian = model.position_jacobian(x, data) if measured \
            else model.flange_jacobian(x, data)
        _read_only(jacobian)
        return jacobian

    return _kept(_CHAINS, model, _key(x, data, measured), make, KEPT_CHAINS)


_JACOBIANS: list[tuple[weakref.ref[Model], tuple[object, ...], tuple[Array, Array]]] = []
_LINEARISED: list[tuple[weakref.ref[Model], tuple[object, ...], Linearisation]] = []
_CHAINS: list[tuple[weakref.ref[Model], tuple[object, ...], Array]] = []


__all__ = ["Linearisation", "chain_jacobian", "fingerprint", "linearise", "model_jacobian"]
