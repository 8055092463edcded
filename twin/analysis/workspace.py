"""Where a calibration's accuracy is stated: the region its data cover.

A flange error averaged over the whole range of every joint says nothing about a calibration
whose data moved joint 1 through 20°: far from the data the identified table extrapolates, and
the "workspace" figure of a narrow data set reached a metre on a real recording. Every figure a
calibration states over a workspace — the predicted flange accuracy, the error against a known
truth, the map of the flange error — is taken over poses drawn uniformly within the joint
ranges its training poses cover (each joint from its smallest to its largest recorded angle),
and says so. A design with no data yet (`twin plan`) keeps the joint limits.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from twin.arrays import Array
from twin.report.display import plain
from twin.units import joints_to_file

WORKSPACE_POSES = 1000
"""Random poses over which a flange accuracy is stated."""
DATA_RANGES = "the joint ranges of the training poses"
"""What a calibration's workspace covers, as a report says it."""
MEASURED_RANGES = "the joint ranges of the measured poses"
"""What an assessment's workspace covers (`twin identify`: every pose)."""


class Workspace(NamedTuple):
    """Poses drawn within joint ranges, and the ranges."""

    q_rad: Array
    """The poses, shape (k, n), rad."""
    lower_rad: Array
    """Each joint's smallest angle, shape (n,), rad."""
    upper_rad: Array
    """Each joint's largest angle, shape (n,), rad."""
    covers: str
    """What the ranges are: :data:`DATA_RANGES` or ``the joint limits``."""

    def describe(self, prismatic: ArrayLike | None = None) -> str:
        """``1000 poses within the joint ranges of the training poses (q1 -30…45, … deg)``; a
        prismatic joint's (``prismatic``, shape (n,)) in mm: ``(q1 0…400 mm, q2 -30…45, …
        deg)``."""
        sliding = np.zeros(self.lower_rad.size, dtype=bool) if prismatic is None \
            else np.asarray(prismatic, dtype=bool)
        lower, upper = (joints_to_file(v, sliding) for v in (self.lower_rad, self.upper_rad))
        ranges = ", ".join(
            f"q{j + 1} {plain(low, 0)}…{plain(high, 0)}{' mm' if slides else ''}"
            for j, (low, high, slides) in enumerate(zip(lower, upper, sliding, strict=True)))
        return f"{len(self.q_rad)} poses within {self.covers} ({ranges} deg)"

    def grid(self, n_per_axis: int) -> tuple[Array, Array, Array]:
        """A grid over joints 2 and 3 within their ranges, the other joints at the middle of
        theirs (joints 2 and 3 set the reach and height of the wrist).

        Returns:
            ``(q2_rad, q3_rad, q_rad)``: axes (n_per_axis,) each, and poses
            (n_per_axis², n) with q2 varying slowest.
        """
        q2 = np.linspace(self.lower_rad[1], self.upper_rad[1], n_per_axis)
        q3 = np.linspace(self.lower_rad[2], self.upper_rad[2], n_per_axis)
        q = np.tile(0.5 * (self.lower_rad + self.upper_rad), (n_per_axis * n_per_axis, 1))
        q[:, 1], q[:, 2] = (axis.ravel() for axis in np.meshgrid(q2, q3, indexing="ij"))
        return q2, q3, q


def within(lower_rad: ArrayLike, upper_rad: ArrayLike, count: int, rng: np.random.Generator,
           covers: str) -> Workspace:
    """``count`` poses uniform within the ranges (n,) each, rad."""
    lower = np.asarray(lower_rad, dtype=np.float64)
    upper = np.asarray(upper_rad, dtype=np.float64)
    q = lower + (upper - lower) * rng.random((count, lower.size))
    return Workspace(q, lower, upper, covers)


def data_workspace(q_rad: ArrayLike, rng: np.random.Generator, count: int = WORKSPACE_POSES,
                   covers: str = DATA_RANGES) -> Workspace:
    """``count`` poses uniform within the joint ranges the poses ``q_rad`` (m, n) cover;
    ``covers`` says which poses they are."""
    q = np.asarray(q_rad, dtype=np.float64)
    return within(np.min(q, axis=0), np.max(q, axis=0), count, rng, covers)


__all__ = ["DATA_RANGES", "MEASURED_RANGES", "WORKSPACE_POSES", "Workspace", "data_workspace",
           "within"]
