"""The step detector on sequences made here: a step is named where the level jumps, never on
noise, a slow drift or a lone outlier. Each sequence without a step may raise a false alarm
with probability below ALPHA = 1e-3 (the Bonferroni level over all places): over the 20 seeds
here, about 2 % of runs of the whole test could fail by chance if the detector were exactly at
its level — it is conservative (the level is an upper bound), and the seeds are fixed."""

from __future__ import annotations

import numpy as np
import pytest

from twin.analysis.steps import find_steps


@pytest.mark.parametrize("seed", range(20))
def test_a_step_is_named_at_its_row_and_noise_is_not(seed: int) -> None:
    """A 3 mm step at a random row among 120 readings of σ = 0.01 mm is found there, its size
    to 0.01 mm; the same noise without it, with a 1 mm drift over all rows or with a 3 mm
    outlier gives none."""
    rng = np.random.default_rng(seed)
    noise = rng.normal(0.0, 1e-5, 120)
    row = int(rng.integers(15, 105))
    stepped = noise + np.where(np.arange(120) >= row, 3e-3, 0.0)
    (step,) = find_steps(stepped, 1e-5)
    assert step.row == row and step.size_m == pytest.approx(3e-3, abs=1e-5)
    assert find_steps(noise, 1e-5) == ()
    assert find_steps(noise + np.linspace(0.0, 1e-3, 120), 1e-5) == ()
    outlier = noise.copy()
    outlier[row] += 3e-3
    assert find_steps(outlier, 1e-5) == ()


def test_steps_are_judged_against_the_residuals_own_scatter() -> None:
    """Residuals scattered 0.3 mm (a model that misses something) with steps of +2.5 and
    −2 mm: both named, the scatter (not the stated 0.01 mm) their yardstick."""
    rng = np.random.default_rng(3)
    r = rng.normal(0.0, 3e-4, 300)
    r[100:] += 2.5e-3
    r[200:] -= 2e-3
    found = find_steps(r, 1e-5)
    assert [step.row for step in found] == [100, 200]
    assert [round(step.size_m * 1e3, 1) for step in found] == pytest.approx([2.5, -2.0], abs=0.2)
