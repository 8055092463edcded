"""The train/validation split of a measurement set, and how many poses a fit needs."""

from __future__ import annotations

from math import ceil

import numpy as np
from numpy.typing import NDArray

from twin.calibration.settings import TRAIN_FRACTION


def split_rows(
    n_rows: int, seed: int, train_fraction: float = TRAIN_FRACTION
) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """A random train/validation split of ``n_rows`` poses, reproducible from ``seed``: the
    nearest whole number of training poses, at least one; none left to validate on when the
    share is 1 or rounds to every pose.

    Returns:
        ``(train_rows, validation_rows)``, each sorted.
    """
    if not 0 < train_fraction <= 1:
        raise ValueError(f"train_fraction: {train_fraction}, expected in (0, 1]")
    order = np.random.default_rng(seed).permutation(n_rows)
    n_train = min(n_rows, max(1, round(train_fraction * n_rows)))
    return np.sort(order[:n_train]), np.sort(order[n_train:])


def required_poses(n_params: int, train_fraction: float = TRAIN_FRACTION,
                   rows_per_pose: int = 1) -> int:
    """Fewest poses for which the training split has a residual per unknown and one more (a
    degree of freedom for the noise estimate)."""
    per_pose = ceil(n_params / rows_per_pose)
    return max(ceil(per_pose / train_fraction), per_pose + 1)
