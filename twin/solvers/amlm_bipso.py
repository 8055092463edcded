"""M9 — the paper's method: AMLM (M7) cascaded with BIPSO (M8) centred on the AMLM result.

30 + 30 iterations (``budget.stage_iterations``), see :mod:`twin.solvers.cascade`. AMLM makes no
random draws, so the first stage equals M7 run for 30 iterations with the f-change rule off.
"""

from __future__ import annotations

import numpy as np

from twin.problem import Budget, Problem
from twin.solvers.amlm import amlm
from twin.solvers.base import Solver, SolverResult
from twin.solvers.bipso import bipso
from twin.solvers.cascade import STAGE_FTOL_M2, run_cascade


def _solve(problem: Problem, budget: Budget, rng: np.random.Generator) -> SolverResult:
    return run_cascade(
        problem, budget, rng, "amlm-bipso",
        lambda tracker, x0, iterations, _: amlm(tracker, x0, iterations, STAGE_FTOL_M2)[0],
        bipso,
    )


SOLVER = Solver(name="amlm-bipso", alias="m9", title="AMLM cascaded with BIPSO", solve=_solve)
