"""M9 — the paper's method: AMLM (M7) cascaded with BIPSO (M8) centred on the AMLM result.

30 + 30 iterations under the paper's protocol, each stage to its own stopping test under
``converge`` (see :mod:`twin.solvers.cascade`). AMLM makes no random draws, so the first stage
equals M7 run with the stage's budget (under the paper's protocol: 30 iterations with the
f-change rule off).
"""

from __future__ import annotations

import numpy as np

from twin.problem import Problem
from twin.solvers.amlm import amlm
from twin.solvers.base import Solver, SolverResult
from twin.solvers.bipso import bipso
from twin.solvers.cascade import run_cascade
from twin.stopping import Budget


def _solve(problem: Problem, budget: Budget, rng: np.random.Generator) -> SolverResult:
    return run_cascade(problem, budget, rng, "amlm-bipso", ("amlm", amlm), ("bipso", bipso))


SOLVER = Solver(name="amlm-bipso", title="AMLM cascaded with BIPSO", solve=_solve)
