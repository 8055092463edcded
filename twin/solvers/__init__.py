"""Calibration methods behind one interface (:class:`~twin.solvers.base.Solver`).

Each method lives in its own module and exports ``SOLVER``; this registry resolves a CLI name or
the paper's alias (``m1``…``m9``).
"""

from __future__ import annotations

from twin.errors import UnknownChoiceError
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

SOLVERS: dict[str, Solver] = {
    solver.name: solver
    for solver in (
        ekf.SOLVER,
        lm.SOLVER,
        pso.SOLVER,
        ukf_vslm.SOLVER,
        ekf_qibas.SOLVER,
        ekf_qpso.SOLVER,
        amlm.SOLVER,
        bipso.SOLVER,
        amlm_bipso.SOLVER,
        lm_base.SOLVER,
    )
}
"""Every method, by name, in the paper's order, then the methods beyond the paper."""


def solver_choices() -> list[str]:
    """``name (alias)`` for every method, for help texts and error messages."""
    return [f"{s.name} ({s.alias})" if s.alias else s.name for s in SOLVERS.values()]


def get_solver(name: str) -> Solver:
    """The method called ``name`` or aliased ``name`` (case-insensitive).

    Raises:
        UnknownChoiceError: listing the valid names and aliases.
    """
    key = name.strip().lower()
    for solver in SOLVERS.values():
        if key in (solver.name, solver.alias):
            return solver
    raise UnknownChoiceError("method", name, [*solver_choices(), "all"])


__all__ = [
    "SOLVERS",
    "IterationRecord",
    "Solver",
    "SolverResult",
    "Tracker",
    "get_solver",
    "solver_choices",
]
