"""Calibration methods behind one interface (:class:`~twin.solvers.base.Solver`).

Each method lives in its own module and exports ``SOLVER``; the registry (:data:`SOLVERS`, a
:class:`twin.distribution.Registry`) resolves a CLI name or the paper's alias (``m1``…``m9``).
"""

from __future__ import annotations

from twin.distribution import Registry
from twin.solvers import (
    amlm,
    amlm_bipso,
    bipso,
    ekf,
    ekf_qibas,
    ekf_qpso,
    lm,
    lm_base,
    pso,
    ukf_vslm,
)
from twin.solvers.base import IterationRecord, Solver, SolverResult, Tracker

_SOLVERS = (ekf.SOLVER, lm.SOLVER, pso.SOLVER, ukf_vslm.SOLVER, ekf_qibas.SOLVER, ekf_qpso.SOLVER,
            amlm.SOLVER, bipso.SOLVER, amlm_bipso.SOLVER, lm_base.SOLVER)
SOLVERS: Registry[Solver] = Registry(
    "method", {solver.name: solver for solver in _SOLVERS},
    aliases={solver.alias: solver.name for solver in _SOLVERS if solver.alias}, ignore_case=True)
"""Every method, by name (or the paper's alias, case-insensitive), in the paper's order, then
the methods beyond the paper."""


def get_solver(name: str) -> Solver:
    """The method called or aliased ``name`` (case-insensitive).

    Raises:
        UnknownChoiceError: listing the valid names and aliases.
    """
    return SOLVERS.lookup(name, also=["all"])


__all__ = [
    "SOLVERS",
    "IterationRecord",
    "Solver",
    "SolverResult",
    "Tracker",
    "get_solver",
]
