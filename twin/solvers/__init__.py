"""Calibration methods behind one interface (:class:`~twin.solvers.base.Solver`).

Each method lives in its own module and exports ``SOLVER``; the registry (:data:`SOLVERS`, a
:class:`twin.distribution.Registry`) resolves a CLI name or the paper's alias (``m1``…``m9``)
and imports a method's module when it is first asked for (the names and aliases alone need no
numpy: the command line's help lists them).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from twin.distribution import Lazy, Registry, lazy_exports

if TYPE_CHECKING:
    from twin.solvers.base import IterationRecord, Solver, SolverResult, Tracker

_PAPER = ("ekf", "lm", "pso", "ukf-vslm", "ekf-qibas", "ekf-qpso", "amlm", "bipso", "amlm-bipso")
"""The paper's methods M1–M9, in its order."""
SOLVERS: Registry[Solver] = Registry(
    "method",
    {name: Lazy(f"twin.solvers.{name.replace('-', '_')}:SOLVER") for name in (*_PAPER,
                                                                             "lm-base")},
    aliases={f"m{k}": name for k, name in enumerate(_PAPER, start=1)}, ignore_case=True)
"""Every method, by name (or the paper's alias, case-insensitive), in the paper's order, then
the methods beyond the paper."""


def get_solver(name: str) -> Solver:
    """The method called or aliased ``name`` (case-insensitive).

    Raises:
        UnknownChoiceError: listing the valid names and aliases.
    """
    return SOLVERS.lookup(name, also=["all"])


__getattr__ = lazy_exports(__name__, {
    "twin.solvers.base": ("IterationRecord", "Solver", "SolverResult", "Tracker")})

__all__ = [
    "SOLVERS",
    "IterationRecord",
    "Solver",
    "SolverResult",
    "Tracker",
    "get_solver",
]
