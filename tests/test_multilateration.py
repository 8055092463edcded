"""Multilateration on points made here: a point is found from its distances, with and without
unknown offsets shared by groups of rows; points on one plane are said not to determine it."""

from __future__ import annotations

import numpy as np
import pytest

from twin.geometry.multilateration import multilaterate


@pytest.mark.parametrize("offset", [False, True])
def test_a_point_is_found_from_its_distances(offset: bool) -> None:
    """Distances with σ = 0.01 mm from 60 points in a 1 m box to a point 0.9 m off (and, with
    an offset, all 20 mm short): the point comes back to 0.02 mm, the offset too."""
    rng = np.random.default_rng(8)
    points = rng.uniform(-0.5, 0.5, (60, 3))
    truth = np.array([0.9, -0.3, 0.1])
    short = 0.02 if offset else 0.0
    distances = np.linalg.norm(points - truth, axis=1) - short + rng.normal(0.0, 1e-5, 60)
    found = multilaterate(points, distances, offsets=np.zeros(60, int) if offset else None)
    assert found.determined
    assert np.linalg.norm(found.point_m - truth) < 2e-5
    assert found.offsets_m.tolist() == ([pytest.approx(short, abs=2e-5)] if offset else [])
    assert found.rms_m < 2e-5


def test_points_on_a_plane_do_not_determine_a_point() -> None:
    """Points on one plane leave the point's mirror image as good: said, not hidden."""
    rng = np.random.default_rng(2)
    points = np.column_stack([rng.uniform(-0.5, 0.5, (30, 2)), np.zeros(30)])
    distances = np.linalg.norm(points - [0.2, 0.3, 0.4], axis=1)
    assert not multilaterate(points, distances).determined
