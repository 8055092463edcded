"""The float array type every module annotates with, and the validation of the arrays held by
frozen value objects."""

from __future__ import annotations

import contextlib
from typing import TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]
"""A float64 array; each use states its shape and unit in its docstring."""
ScalarT = TypeVar("ScalarT", bound=np.generic)
"""Any numpy scalar type: :func:`read_only` returns its input's."""


def frozen_array(
    values: ArrayLike, shape: tuple[int, ...], what: str, *, broadcast: bool = False
) -> Array:
    """A read-only float64 copy of ``values`` with the given shape and only finite entries.

    Args:
        values: The values.
        shape: The required shape.
        what: The field's name, for the error message.
        broadcast: Accept values that broadcast to ``shape`` (e.g. one number for every joint).

    Raises:
        ValueError: naming the field, the shape found and the one expected, or non-finite values.
    """
    array = np.asarray(values, dtype=np.float64)
    if broadcast and array.shape != shape:
        with contextlib.suppress(ValueError):  # a shape that cannot broadcast is reported below
            array = np.broadcast_to(array, shape)
    if array.shape != shape:
        raise ValueError(f"{what}: shape {array.shape}, expected {shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{what}: non-finite values")
    array = np.array(array)
    array.setflags(write=False)
    return array


def read_only(array: NDArray[ScalarT]) -> NDArray[ScalarT]:
    """``array`` if it is read-only, else a read-only view of it (the caller's array stays
    writeable): what the compiled kernels are handed, so that numba keeps one version of each
    (it makes one per writeable flag of every input, seconds of compiling each on a fresh
    install)."""
    if not array.flags.writeable:
        return array
    view = array.view()
    view.setflags(write=False)
    return view


def lengths(vectors: Array) -> Array:
    """Euclidean length of 3-vectors over the last axis, (..., 3) to (...): written out, equal
    bit for bit to ``np.linalg.norm(vectors, axis=-1)`` and three times faster on a swarm's
    (K, m, 3), where a reduction over an axis of three costs more than the arithmetic."""
    x, y, z = vectors[..., 0], vectors[..., 1], vectors[..., 2]
    return np.asarray(np.sqrt(x * x + y * y + z * z), dtype=np.float64)
