"""D-optimal pose selection (greedy + exchange) and the choice of the port."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from twin.calibration.setup import make_model
from twin.compensation.ik import home_pose
from twin.design.optimal import choose_port, d_optimal_rows, plan_poses, score_poses
from twin.design.order import visiting_order
from twin.rig import Rig
from twin.robot import RobotModel, random_poses

SIGMA_M = 1e-5


def _log_det(J: np.ndarray, rows) -> float:
    return float(np.linalg.slogdet(J[list(rows)].T @ J[list(rows)])[1])


def test_exchange_ends_at_a_local_optimum_no_worse_than_greedy() -> None:
    """After the exchange no single swap of a chosen row for an unchosen one raises det(JᵀJ),
    and the result is at least as good as the greedy pass alone."""
    J = np.random.default_rng(4).normal(size=(60, 4))
    chosen = d_optimal_rows(J, 8)
    greedy = d_optimal_rows(J, 8, max_exchanges=0)
    assert chosen.log_det >= greedy.log_det - 1e-12
    assert chosen.log_det == pytest.approx(_log_det(J, chosen.rows))
    others = np.setdiff1d(np.arange(60), chosen.rows)
    for out, into in itertools.product(range(8), others):
        swapped = np.r_[np.delete(chosen.rows, out), into]
        assert _log_det(J, swapped) <= chosen.log_det + 1e-9


def test_small_problem_reaches_the_brute_force_optimum() -> None:
    """Choosing 4 of 14 rows in 3-D: the plan's determinant equals the best of all 1001 subsets."""
    J = np.random.default_rng(8).normal(size=(14, 3))
    best = max(_log_det(J, rows) for rows in itertools.combinations(range(14), 4))
    assert d_optimal_rows(J, 4).log_det == pytest.approx(best)


def test_too_few_rows_is_an_error() -> None:
    """Fewer rows than columns cannot have a non-zero determinant."""
    with pytest.raises(ValueError):
        d_optimal_rows(np.ones((10, 4)), 3)


def test_30_planned_poses_beat_30_random_ones(irb120: RobotModel, port_m: np.ndarray) -> None:
    """30 D-optimal poses of 1500 candidates predict a lower flange error over the workspace
    than every one of 10 draws of 30 random poses, by a margin (under 0.8× their median)."""
    rng = np.random.default_rng(0)
    model = make_model(irb120, Rig.cable(port_m))
    x0 = np.zeros(24)
    candidates = random_poses(irb120, 1500, rng)
    workspace = random_poses(irb120, 500, rng)
    plan = plan_poses(model, x0, candidates, 30)
    assert plan.q_rad.shape == (30, 6) and plan.base_mask.sum() == 19
    planned = score_poses(model, x0, plan.q_rad, plan.base_mask, SIGMA_M, workspace)
    drawn = [
        score_poses(model, x0, random_poses(irb120, 30, rng), plan.base_mask, SIGMA_M, workspace)
        for _ in range(10)
    ]
    random_rms = np.array([score.flange_rms_m for score in drawn])
    assert planned.flange_rms_m < random_rms.min()
    assert planned.flange_rms_m < 0.8 * np.median(random_rms)
    assert planned.observability.o1 > max(score.observability.o1 for score in drawn)


def test_port_choice_avoids_a_port_that_sees_along_one_direction(
    irb120: RobotModel, port_m: np.ndarray
) -> None:
    """A port 20 m away sees every flange from nearly the same direction, so its lengths say
    little about the other two: the choice keeps the near port, the one of lowest score."""
    rng = np.random.default_rng(1)
    candidates = random_poses(irb120, 600, rng)
    workspace = random_poses(irb120, 300, rng)
    far = np.array([20.0, 0.0, 0.3])
    choice = choose_port(make_model(irb120, Rig.cable(port_m)), np.stack([far, port_m]), candidates,
                         30, SIGMA_M, workspace)
    assert choice.best == 1 == int(np.argmin(choice.flange_rms_m))
    assert choice.flange_rms_m[0] > 2 * choice.flange_rms_m[1]
    assert len(choice.plans) == 2


@pytest.mark.parametrize("seed", range(4))
def test_the_visiting_order_is_a_short_tour(irb120: RobotModel, seed: int) -> None:
    """A plan of 7 poses is visited in a tour from home and back within 5 % of the shortest
    one (every order tried, the referee), and never longer than the design's order; each
    pose exactly once."""
    rng = np.random.default_rng(seed)
    q = random_poses(irb120, 7, rng)
    home = home_pose(irb120)
    visit = visiting_order(irb120, q, home)
    assert sorted(visit.order.tolist()) == list(range(7))

    def cost(rows: tuple[int, ...]) -> float:
        path = np.vstack([home, q[list(rows)], home])
        return float(np.sum(np.max(np.abs(np.diff(path, axis=0)) / irb120.velocity_rad_s,
                                   axis=1)))

    shortest = min(cost(rows) for rows in itertools.permutations(range(7)))
    assert cost(tuple(visit.order)) == pytest.approx(visit.travel_s, rel=1e-12)
    assert visit.travel_s <= 1.05 * shortest
    assert visit.travel_s <= visit.given_s == pytest.approx(cost(tuple(range(7))), rel=1e-12)


def test_the_visiting_order_keeps_each_station_together(irb120: RobotModel) -> None:
    """With stations, each station's poses are toured in turn, stations in the plan's order."""
    q = random_poses(irb120, 30, np.random.default_rng(5))
    port = np.array([1, 0, 2] * 10)
    visit = visiting_order(irb120, q, home_pose(irb120), port)
    assert port[visit.order].tolist() == [1] * 10 + [0] * 10 + [2] * 10
    assert sorted(visit.order.tolist()) == list(range(30))
