"""The one interface of an unknown group: named parameters, their units and bounds, and the
stage of the measurement model they act at.

A calibration's unknown vector x is the concatenation of its groups' blocks, D-H first. Each
group acts at one stage of :class:`twin.model.Model`:

- ``table``: adds to the kinematic parameter table, ``Δtable = linear @ x_g`` (D-H errors);
- ``joints``: adds to the joint angles, linear in its coefficients, as transmission error,
  backlash and compliance are; each coefficient c moves one joint, ``joint[c]``:
  ``Δq_joint[c] += basis(data)[:, c] · x_c`` (a dense (m, n, p_g) basis would be mostly zeros);
- ``rows``: adds to each row's kinematic table by how that row's conditions differ, ``Δtable_k
  = linear @ (basis(data)[k] ⊙ x_g)`` (a link's growth per kelvin times the row's temperature
  above the reference: :mod:`twin.unknowns.thermal`);
- ``point``: moves the measured point in the flange frame, ``Δt = linear @ x_g``;
- ``measurement``: enters the measurement kind's own equation (a port, a length offset, a
  tracker frame, a fixed point); the kind reads its block by the group's name.

A group module exports ``make(robot, rig) -> Group`` and the registry
(:mod:`twin.unknowns`) lists it.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from enum import StrEnum
from typing import TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import Array, frozen_array
from twin.dataset import Measurements


class Stage(StrEnum):
    """Where in the measurement model a group acts."""

    TABLE = "table"
    ROWS = "rows"
    JOINTS = "joints"
    POINT = "point"
    MEASUREMENT = "measurement"


@dataclass(frozen=True)
class Group:
    """One named block of unknowns.

    Attributes:
        name: The registry name (``dh``, ``port``…).
        stage: Where it acts.
        names: One name per parameter (``a1``, ``port_x``…), length p_g.
        units: The SI unit of each parameter (``m``, ``rad``…; :mod:`twin.units` converts them
            for people).
        lower: Lower bounds, shape (p_g,).
        upper: Upper bounds, shape (p_g,).
        radius: A typical size of each parameter's error, shape (p_g,): the spread of a
            swarm's first particles.
        linear: ``table`` and ``rows``: (4n, p_g), ``point``: (3, p_g); None at other stages.
        basis: ``joints``: ``basis(data) -> (m, p_g)``, how far each coefficient turns its
            joint at each pose, rad per unit; ``rows``: how much of each coefficient each row's
            table takes (a temperature difference, K); None at other stages.
        joint: ``joints``: the joint (0-based) each coefficient turns, length p_g; empty at
            other stages.
        needs_approach: Whether the basis reads the direction each joint approached its pose
            from (``data.approach``): measurements without it cannot be fitted.
        prior_weight: 1/σ of each parameter's zero-mean Gaussian prior (the nominal, N(0, σ²)),
            in 1/unit, shape (p_g,); 0 where there is none (the default): a calibration appends
            the rows ``x_i · prior_weight_i`` to its residuals (:class:`twin.problem.Problem`).
        full_names: The names of the group before a calibration fixed some of its parameters
            at the nominal (:meth:`restricted`); ``names`` is a subsequence of them. Empty:
            ``names``.
    """

    name: str
    stage: Stage
    names: tuple[str, ...]
    units: tuple[str, ...]
    lower: Array
    upper: Array
    radius: Array
    linear: Array | None = None
    basis: Callable[[Measurements], Array] | None = None
    joint: tuple[int, ...] = ()
    needs_approach: bool = False
    prior_weight: Array = field(default_factory=lambda: np.zeros(0))
    full_names: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        p = len(self.names)
        if not np.size(self.prior_weight):
            object.__setattr__(self, "prior_weight", np.zeros(p))
        if not self.full_names:
            object.__setattr__(self, "full_names", tuple(self.names))
        if not set(self.names) <= set(self.full_names):
            raise ValueError(f"group {self.name}: names beyond its full names")
        if len(self.units) != p:
            raise ValueError(f"group {self.name}: {len(self.units)} units for {p} parameters")
        for attribute in ("lower", "upper", "radius", "prior_weight"):
            object.__setattr__(self, attribute,
                               frozen_array(getattr(self, attribute), (p,), attribute))
        if np.any(self.lower >= self.upper):
            raise ValueError(f"group {self.name}: lower bounds must be below upper bounds")
        if np.any(self.prior_weight < 0):
            raise ValueError(f"group {self.name}: a prior's weight 1/σ must be >= 0")
        needs_linear = self.stage in (Stage.TABLE, Stage.ROWS, Stage.POINT)
        if needs_linear != (self.linear is not None):
            raise ValueError(f"group {self.name}: a linear map goes with the table, rows and "
                             "point stages only")
        if (self.stage in (Stage.JOINTS, Stage.ROWS)) != (self.basis is not None):
            raise ValueError(f"group {self.name}: a basis goes with the joints and rows stages "
                             "only")
        if len(self.joint) != (p if self.stage == Stage.JOINTS else 0):
            raise ValueError(f"group {self.name}: a joints-stage group names the joint of each "
                             f"of its {p} parameters, other groups none")
        if self.linear is not None:
            linear = np.asarray(self.linear, dtype=np.float64)
            object.__setattr__(self, "linear", frozen_array(linear, linear.shape, "linear"))

    @property
    def size(self) -> int:
        """Number of parameters p_g."""
        return len(self.names)

    @property
    def positions(self) -> NDArray[np.intp]:
        """Where each parameter sits among :attr:`full_names`, shape (p_g,)."""
        return np.array([self.full_names.index(name) for name in self.names], dtype=np.intp)

    def take(self, full: ArrayLike) -> Array:
        """This group's block of a block of the full group (..., len(full_names)): (..., p_g)."""
        return np.asarray(np.asarray(full, dtype=np.float64)[..., self.positions],
                          dtype=np.float64)

    def spread(self, block: ArrayLike, fill: float = 0.0) -> Array:
        """A block of this group (..., p_g) as one of the full group, (..., len(full_names)),
        with ``fill`` where a parameter was fixed."""
        block = np.asarray(block, dtype=np.float64)
        full = np.full((*block.shape[:-1], len(self.full_names)), fill)
        full[..., self.positions] = block
        return full

    def restricted(self, keep: ArrayLike, lower: ArrayLike, upper: ArrayLike,
                   prior_weight: ArrayLike) -> Group:
        """This group with new bounds and priors (each shape (p_g,)) and only the parameters
        ``keep`` (bool, (p_g,)) left free: the others are fixed at the nominal, which the group
        then leaves out (its linear map loses their columns, its basis their coefficients).

        Raises:
            ValueError: for a measurement-stage group that would lose parameters (its kind reads
                the whole block).
        """
        keep = np.asarray(keep, dtype=bool)
        index = np.flatnonzero(keep)
        if index.size < self.size and self.stage == Stage.MEASUREMENT:
            raise ValueError(f"group {self.name}: a measurement's unknowns are fixed as a whole")
        basis = self.basis
        if basis is not None and index.size < self.size:
            whole = basis

            def basis(data: Measurements) -> Array:
                return whole(data)[:, index]

        return replace(
            self, names=tuple(np.asarray(self.names, dtype=object)[index]),
            units=tuple(np.asarray(self.units, dtype=object)[index]),
            lower=np.asarray(lower, dtype=np.float64)[index],
            upper=np.asarray(upper, dtype=np.float64)[index], radius=self.radius[index],
            prior_weight=np.asarray(prior_weight, dtype=np.float64)[index],
            linear=None if self.linear is None else self.linear[:, index], basis=basis,
            joint=tuple(np.asarray(self.joint, dtype=int)[index].tolist()) if self.joint else (),
            full_names=self.full_names)

    def like(self, other: Group) -> Group:
        """This group (made again, for another rig) restricted as ``other`` of the same name:
        its bounds, priors and fixed parameters carried over by name; unchanged when the two
        have other parameters (a correction per port of another rig)."""
        if other.full_names != self.full_names:
            return self
        keep = np.isin(np.asarray(self.names, dtype=object),
                       np.asarray(other.names, dtype=object))
        lower, upper, weight = (self.take(other.spread(values)) for values in
                                (other.lower, other.upper, other.prior_weight))
        return self.restricted(keep, lower, upper, weight)


Cached = TypeVar("Cached")

CACHED = 4
"""Measurement sets a :func:`cached` basis keeps: a fit alternates between its training and
validation poses."""


def cached(basis: Callable[[Measurements], Cached]) -> Callable[[Measurements], Cached]:
    """A value that depends on the measurements alone (not on x) — a joints-stage basis, the
    poses' cosines and sines — computed once per measurement set: a fit evaluates it at every
    residual and Jacobian on the same poses, and measurements are immutable. Sets are
    recognised by identity and held weakly; arrays are kept read-only."""
    kept: list[tuple[weakref.ref[Measurements], Cached]] = []

    def lookup(data: Measurements) -> Cached:
        for reference, value in kept:
            if reference() is data:
                return value
        value = basis(data)
        for array in (value if isinstance(value, tuple) else (value,)):
            if isinstance(array, np.ndarray):
                array.setflags(write=False)
        kept[:] = [*kept[-(CACHED - 1):], (weakref.ref(data), value)]
        return value

    return lookup
