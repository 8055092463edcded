"""Rank, named null directions, base parameters and observability indices of cable data."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from twin.analysis.identifiability import (
    _base_by_distances,
    identifiability,
    measurement_identifiability,
    name_direction,
    observability,
    pivot_columns,
)
from twin.calibration.settings import CalibrationSettings
from twin.calibration.setup import make_model
from twin.dataset import Measurements
from twin.kinds.length import length_measurements
from twin.rig import Rig
from twin.robot import RobotModel, random_poses

KNOWN_PORT_NULL = {"theta6", "alpha6", "d2-d3", "a5+theta5", "d5-alpha5"}


@pytest.fixture(scope="module")
def poses(irb120: RobotModel) -> Measurements:
    """200 random poses (their lengths do not enter a Jacobian)."""
    q = random_poses(irb120, 200, np.random.default_rng(0))
    return length_measurements(q, np.ones(len(q)))


def _at_nominal(robot: RobotModel, port_m: np.ndarray, data: Measurements,
                port: bool = False, offset: bool = False):
    model = make_model(robot, Rig.cable(port_m),
                       settings=CalibrationSettings(estimate=(*(('port',) if port else ()),
                                                              *(('offset',) if offset else ()))))
    return model, measurement_identifiability(model, np.zeros(model.n_params), data)


def test_known_port_rank_19_with_named_null_directions(irb120, port_m, poses) -> None:
    """IRB 120, known port, nominal geometry: rank 19 of 24; θ6, α6, d2−d3 and two wrist
    combinations are the unidentifiable directions, and a tolerance a million times looser or
    tighter gives the same rank (the gap is wide)."""
    model, ident = _at_nominal(irb120, port_m, poses)
    assert (ident.rank, ident.n_params) == (19, 24)
    assert set(ident.unidentifiable) == KNOWN_PORT_NULL
    assert len(ident.base) == 19 and len(ident.base_names) == 19
    # Base parameters kept in the order of x: the later of each dependent pair is dropped.
    assert set(model.names) - set(ident.base_names) == {"d3", "alpha5", "theta5", "alpha6",
                                                        "theta6"}
    _, J = model.jacobian(np.zeros(24), poses)
    for rtol in (1e-5, 1e-11):
        assert identifiability(J, model.names, rtol).rank == 19
    assert 1 < ident.condition < 1e3


def test_negligible_columns_are_not_scaled_into_fake_rank(irb120, port_m, poses) -> None:
    """θ6 and α6 columns are zero up to round-off: declared unidentifiable directly. Scaling
    round-off (here 1e-17-sized noise) to unit norm like the other columns would report a fake
    rank above 19."""
    model = make_model(irb120, Rig.cable(port_m))
    _, J = model.jacobian(np.zeros(24), poses)
    blind = [model.names.index("alpha6"), model.names.index("theta6")]
    J[:, blind] = 1e-17 * np.random.default_rng(2).normal(size=(len(poses), 2))
    naive = J / np.linalg.norm(J, axis=0)
    s = np.linalg.svd(naive, compute_uv=False)
    assert int(np.sum(s > 1e-8 * s[0])) > 19
    ident = identifiability(J, model.names)
    assert ident.rank == 19 and {"theta6", "alpha6"} <= set(ident.unidentifiable)


def test_null_directions_leave_every_length_unchanged(irb120, port_m, poses) -> None:
    """θ6, α6 and d2−d3 are exactly invisible: 1 mm / 1 mrad along them changes no length
    beyond round-off. Every null direction is invisible to first order: a 1e-6 step moves the
    lengths a thousand times less than the same step along a base parameter."""
    model, ident = _at_nominal(irb120, port_m, poses)
    start = model.residuals(np.zeros(24), poses)

    def change(step: np.ndarray) -> float:
        return float(np.max(np.abs(model.residuals(step, poses) - start)))

    directions = dict(zip(ident.unidentifiable, ident.null_space.T, strict=True))
    for name in ("theta6", "alpha6", "d2-d3"):
        assert change(1e-3 * directions[name] / np.max(np.abs(directions[name]))) < 1e-12
    base_step = min(change(1e-6 * np.eye(24)[i]) for i in ident.base)
    assert base_step > 1e-8
    for direction in ident.null_space.T:
        assert change(1e-6 * direction / np.max(np.abs(direction))) < 1e-3 * base_step


def test_unknown_port_and_offset_add_named_directions(irb120, port_m, poses) -> None:
    """Port unknown: +3 unknowns, +1 rank — d1+port_z (a shift along joint 1's axis) and a turn
    about it (θ1 with port x, y) join the null space. Offset unknown: identifiable."""
    expected = {(True, False): (20, 27), (False, True): (20, 25), (True, True): (21, 28)}
    for (port, offset), (rank, p) in expected.items():
        _, ident = _at_nominal(irb120, port_m, poses, port, offset)
        assert (ident.rank, ident.n_params) == (rank, p)
        assert set(ident.unidentifiable) >= KNOWN_PORT_NULL
        assert ("offset" in ident.base_names) == offset
        if port:
            extra = set(ident.unidentifiable) - KNOWN_PORT_NULL
            assert "d1+port_z" in extra
            (turn,) = extra - {"d1+port_z"}
            assert all(name in turn for name in ("theta1", "port_x", "port_y"))


def test_identified_geometry_sees_more_but_weakly(irb120, port_m, poses, true_delta) -> None:
    """Away from the nominal geometry the parallel axes and the centred flange are broken by
    the errors themselves: the rank rises above 19 through weak directions; α6 stays unseen."""
    model = make_model(irb120, Rig.cable(port_m))
    ident = measurement_identifiability(model, true_delta.ravel(), poses)
    assert ident.rank > 19 and ident.weak >= 1
    assert "alpha6" in ident.unidentifiable
    assert ident.condition > 1e3


def test_rank_matches_svd_on_a_made_up_matrix() -> None:
    """A matrix with a known dependency: column 2 = column 0 − 2·column 1, column 3 is zero."""
    rng = np.random.default_rng(3)
    A = rng.normal(size=(50, 2))
    J = np.column_stack([A[:, 0], A[:, 1], A[:, 0] - 2 * A[:, 1], 1e-20 * A[:, 0]])
    ident = identifiability(J, ("u", "v", "w", "z"))
    assert ident.rank == 2
    assert "z" in ident.unidentifiable
    np.testing.assert_allclose(J @ ident.null_space, 0.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(ident.null_space, axis=0), 1.0)


def test_names_are_sparse_and_signed() -> None:
    """Largest coefficient ±1 and printed bare, first term positive, tiny ones dropped."""
    names = ("a", "b", "c", "d")
    assert name_direction([0.0, -1.0, 0.302, 1e-9], names) == "b-0.302*c"
    assert name_direction([0.0, 0.5, 0.0, -1.0], names) == "0.5*b-d"
    assert name_direction([2.0, 0, 0, 0], names) == "a"


def test_observability_indices_of_known_singular_values() -> None:
    """J with singular values 3, 2, 1 over 4 rows: O1 = 6^(1/3)/2, O3 = 1, O4 = 1/3, κ = 3."""
    q, _ = np.linalg.qr(np.random.default_rng(1).normal(size=(4, 3)))
    J = q @ np.diag([3.0, 2.0, 1.0])
    o = observability(J)
    assert o.o1 == pytest.approx(6 ** (1 / 3) / 2)
    assert (o.o3, o.o4, o.condition) == pytest.approx((1.0, 1 / 3, 3.0))



def test_base_set_does_not_depend_on_the_pose_set(irb120, port_m, poses) -> None:
    """Any subset of poses rich enough gives the same base parameters (no round-off ties)."""
    model = make_model(irb120, Rig.cable(port_m))
    bases = {
        measurement_identifiability(model, np.zeros(24), poses.subset(rows)).base_names
        for rows in (np.arange(40), np.arange(50, 120), np.arange(0, 200, 3))
    }
    assert len(bases) == 1


def _base_one_svd_per_column(J: np.ndarray, rtol: float, prefer: list[int]) -> list[int]:
    """The reference of the in-order base: each column of the column-scaled J, in order (the
    preferred first), kept if the SVD of those kept with it has σ_min above the threshold."""
    norms = np.linalg.norm(J, axis=0)
    visible = np.flatnonzero(norms > 1e-8 * np.max(norms))
    scaled = J[:, visible] / norms[visible]
    threshold = rtol * np.linalg.svd(scaled, compute_uv=False)[0]
    first = [k for k in range(visible.size) if visible[k] in prefer]
    kept: list[int] = []
    for column in [*first, *(k for k in range(visible.size) if k not in first)]:
        if np.linalg.svd(scaled[:, [*kept, column]], compute_uv=False)[-1] > threshold:
            kept.append(column)
    return sorted(int(visible[k]) for k in kept)


def _planted(rng: np.random.Generator, supports: list[tuple[int, int]], p: int = 9,
             sigma: float = 0.3e-8) -> np.ndarray:
    """A (50, p) Jacobian of unit columns with a near-null direction per (first, last) support:
    σ ≈ ``sigma`` (below the rank's threshold of 1e-8) along v spread over columns first..last,
    its last component 1e-4 — so small that the column's distance from those before it is far
    above the threshold, and the quick test leaves the decision to the SVDs."""
    J = rng.normal(size=(50, p))
    J /= np.linalg.norm(J, axis=0)
    for first, last in supports:
        v = np.zeros(p)
        v[first:last] = rng.normal(size=last - first)
        v[last] = 1e-4
        v /= np.linalg.norm(v)
        u = rng.normal(size=50)
        J = J - np.outer(J @ v, v) + sigma * np.outer(u / np.linalg.norm(u), v)
    return J


def test_base_decisions_left_to_the_svds_match_one_svd_per_column() -> None:
    """Where a dependency's last column stands far from those before it (its component along
    the near-null direction is small), the quick test cannot decide, and the bisection over the
    columns in order keeps the same ones as an SVD per column: one dependency ending at the
    last column, in the middle, two of them, and with preferred columns."""
    rng = np.random.default_rng(11)
    names = tuple("abcdefghi")
    for supports, prefer in (([(0, 8)], []), ([(0, 4)], []), ([(1, 3), (4, 7)], []),
                             ([(2, 6)], [5, 7])):
        J = _planted(rng, supports)
        scaled = J / np.linalg.norm(J, axis=0)
        R = np.linalg.qr(scaled, mode="r")
        threshold = 1e-8 * np.linalg.svd(R, compute_uv=False)[0]
        order = np.r_[prefer, [k for k in range(9) if k not in prefer]].astype(np.intp)
        assert _base_by_distances(R, threshold, order) is None  # the SVDs decide
        found = identifiability(J, names, prefer=prefer)
        assert found.rank == 9 - len(supports)
        assert sorted(found.base) == _base_one_svd_per_column(J, 1e-8, prefer)
        assert len(found.base) == found.rank


def test_base_decisions_match_one_svd_per_column(irb120, port_m, poses, true_delta) -> None:
    """The base parameters (found with one QR per rejected column) are those of trying each
    column with an SVD of its own: at the nominal and a perturbed geometry, with the rig's
    unknowns preferred, and on a matrix whose dependent column sits within a factor of the
    rank's threshold, where the quick test leaves the decision to the SVDs."""
    for port, offset in ((False, False), (True, True)):
        model, _ = _at_nominal(irb120, port_m, poses, port=port, offset=offset)
        prefer = [k for k, name in enumerate(model.names) if name.startswith(("port", "offset"))]
        for x in (np.zeros(model.n_params),
                  np.r_[true_delta.ravel(), np.zeros(model.n_params - 24)]):
            _, J = model.jacobian(x, poses)
            found = identifiability(J, model.names, prefer=prefer)
            assert sorted(found.base) == _base_one_svd_per_column(J, 1e-8, prefer)
    rng = np.random.default_rng(5)
    A = rng.normal(size=(60, 4))
    for tiny in (1e-12, 0.7e-8, 1.5e-8, 1e-6):
        J = np.column_stack([A, A[:, 0] + A[:, 1] + tiny * rng.normal(size=60), A[:, 2:]])
        found = identifiability(J, tuple("abcdefg"))
        assert sorted(found.base) == _base_one_svd_per_column(J, 1e-8, [])


@pytest.mark.parametrize("rank_deficient", [False, True])
def test_pivot_columns_are_lapacks(rank_deficient: bool) -> None:
    """The pivots of QR with column pivoting, as scipy.linalg.qr (LAPACK's dgeqp3) takes them,
    on full-rank and rank-deficient matrices of any shape, as many as the rank."""
    rng = np.random.default_rng(7)
    for _ in range(300):
        rows, columns = (int(size) for size in rng.integers(2, 30, 2))
        rank = min(rows, columns)
        matrix = rng.normal(size=(rows, columns))
        if rank_deficient:
            rank = int(rng.integers(1, rank + 1))
            matrix = rng.normal(size=(rows, rank)) @ rng.normal(size=(rank, columns))
        expected = scipy.linalg.qr(matrix, pivoting=True)[2][:rank]
        np.testing.assert_array_equal(pivot_columns(matrix, rank), expected)


def test_pivot_columns_take_the_first_of_a_tie_round_off_decides() -> None:
    """Columns equally far from the span of those taken but for round-off: the first is taken
    (LAPACK takes the one round-off made larger); a column farther by more than the tie's
    tolerance is taken before them."""
    column = np.array([0.3, -0.4, 0.5, 0.1])
    matrix = np.c_[2 * column, column, 2 * column * (1 + 1e-15), [0.0, 0.0, 0.0, 1.0]]
    assert np.linalg.norm(matrix[:, 2]) > np.linalg.norm(matrix[:, 0])
    assert pivot_columns(matrix, 2).tolist() == [0, 3]
    matrix[:, 2] = 2 * column * (1 + 1e-9)
    assert pivot_columns(matrix, 2).tolist() == [2, 3]
