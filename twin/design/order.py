"""The order a plan's poses are visited in: a short round trip from home.

A D-optimal plan picks poses for what they show, and lists them in the order the design found
them — a sequence that swings the arm from one end of its range to the other between
consecutive poses. Each swing is a long joint move between poses nobody checked for collisions,
and time. The plan is visited instead as a short closed tour from home and back: nearest
neighbour, then 2-opt exchanges until none shortens it. The cost of a move is the time a
joint move (``MoveAbsJ``, every joint arriving together) takes, ``max_j |Δq_j| / v_j`` with
``v`` the robot's rated joint speeds (equal weights when the model has none).

The order does not change what the plan identifies (the same poses), and a capture records the
direction each joint approached its pose from (for backlash) whatever the order. With several
stations, each station's poses are toured in turn, in the order the plan lists the stations.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import Array
from twin.robot import RobotModel

MAX_TOUR_POSES = 5000
"""Plans of more poses per station keep the design's order: the tour costs O(m²) memory."""
MAX_EXCHANGE_ROUNDS = 50
"""Rounds of 2-opt exchanges at most (each round tries every pair; one rarely needs ten)."""
SHORTER_RTOL = 1e-12
"""An exchange is taken when it shortens the tour by more than this fraction of its length."""


class Visit(NamedTuple):
    """A plan in its visiting order (:func:`visiting_order`)."""

    order: NDArray[np.intp]
    """The plan's rows in the order they are visited, shape (m,)."""
    travel_s: float
    """The tour's cost from home through every pose and back, in seconds at the rated speeds
    (in radians of the slowest joint when the model has no speeds)."""
    given_s: float
    """The same for the plan's own order."""


def _weights(robot: RobotModel) -> Array:
    """1 / v per joint, s/rad (ones without rated speeds)."""
    if robot.velocity_rad_s is None:
        return np.ones(robot.n_joints)
    return np.asarray(1.0 / robot.velocity_rad_s, dtype=np.float64)


def _costs(points: Array, weights: Array) -> Array:
    """Move cost between every two points (k, n): shape (k, k)."""
    return np.max(np.abs(points[:, None, :] - points[None, :, :]) * weights, axis=-1)


def _tour_length(tour: NDArray[np.intp], cost: Array) -> float:
    return float(cost[tour, np.roll(tour, -1)].sum())


def _nearest_neighbour(cost: Array) -> NDArray[np.intp]:
    """A closed tour from node 0 (home), always to the nearest node not yet visited."""
    k = len(cost)
    tour = np.zeros(k, dtype=np.intp)
    free = np.ones(k, dtype=bool)
    free[0] = False
    for step in range(1, k):
        row = np.where(free, cost[tour[step - 1]], np.inf)
        tour[step] = int(np.argmin(row))
        free[tour[step]] = False
    return tour


def _two_opt(tour: NDArray[np.intp], cost: Array) -> NDArray[np.intp]:
    """Reverse tour segments while that shortens the tour (node 0, home, stays first).

    The move costs are symmetric, so reversing ``tour[i:j + 1]`` changes the length by
    ``c(a, c) + c(b, d) − c(a, b) − c(c, d)`` with a, b the nodes at i − 1, i and c, d at j,
    j + 1: every (i, j) is scored at once, the best exchange taken, until none gains."""
    tour = tour.copy()
    k = len(tour)
    if k < 4:
        return tour
    i, j = np.triu_indices(k, 1)
    keep = i >= 1
    i, j = i[keep], j[keep]
    for _ in range(MAX_EXCHANGE_ROUNDS):
        a, b, c, d = tour[i - 1], tour[i], tour[j], tour[(j + 1) % k]
        gain = cost[a, b] + cost[c, d] - cost[a, c] - cost[b, d]
        best = int(np.argmax(gain))
        if gain[best] <= SHORTER_RTOL * _tour_length(tour, cost):
            break
        tour[i[best]:j[best] + 1] = tour[i[best]:j[best] + 1][::-1]
    return tour


def _tour(q_rad: Array, start_rad: Array, weights: Array) -> tuple[NDArray[np.intp], float,
                                                                     float]:
    """The rows of q (m, n) in tour order from ``start`` and back; its cost and the given
    order's."""
    points = np.vstack([start_rad, q_rad])
    cost = _costs(points, weights)
    given = np.arange(len(points), dtype=np.intp)
    if len(q_rad) > MAX_TOUR_POSES:
        return given[1:] - 1, _tour_length(given, cost), _tour_length(given, cost)
    tour = _two_opt(_nearest_neighbour(cost), cost)
    return tour[1:] - 1, _tour_length(tour, cost), _tour_length(given, cost)


def visiting_order(robot: RobotModel, q_rad: ArrayLike, start_rad: ArrayLike,
                   port: ArrayLike | None = None) -> Visit:
    """A short order to visit a plan's poses in, from ``start`` and back to it.

    Args:
        robot: The robot (its rated joint speeds weigh the joints).
        q_rad: The planned poses, shape (m, n), rad.
        start_rad: Where the robot starts and ends (home), shape (n,), rad.
        port: The station of each pose, shape (m,), when the encoder moves between stations:
            each station's poses are toured in turn, the stations in the order they first
            appear.

    Returns:
        The order, and the tour's cost beside the given order's.
    """
    q = np.asarray(q_rad, dtype=np.float64)
    start = np.asarray(start_rad, dtype=np.float64)
    stations = np.zeros(len(q), dtype=np.intp) if port is None else np.asarray(port, np.intp)
    weights = _weights(robot)
    order, travel, given = [], 0.0, 0.0
    for station in dict.fromkeys(stations.tolist()):
        rows = np.flatnonzero(stations == station)
        tour, length, before = _tour(q[rows], start, weights)
        order.append(rows[tour])
        travel += length
        given += before
    return Visit(np.concatenate(order) if order else np.zeros(0, dtype=np.intp), travel, given)


__all__ = ["Visit", "visiting_order"]
