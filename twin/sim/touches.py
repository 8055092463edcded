"""Fixed points on the twin: configurations of the true robot that bring its measured point (the
ball) into each socket of a fixture (:class:`twin.scenario.instrument.Instrument`).

For each socket the arm brings the ball into it from ``touches`` different configurations —
position-only inverse kinematics of the *true* robot, from random starts, kept when within the
limits, above the floor and free of collisions. The ball seats with an error of σ per axis (the
IK target is the socket plus that error); the recorded joint angles are those the arm then
stands at.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from twin.arrays import Array
from twin.compensation.ik import solve_ik
from twin.errors import InputError
from twin.robot import RobotModel
from twin.scenario.constraints import PoseConstraints
from twin.sim.mujoco_twin import Twin
from twin.sim.poses import usable

IK_STARTS_PER_TOUCH = 40
"""Random starts tried per wanted configuration before a socket counts as unreachable."""


def touch_poses(robot: RobotModel, twin: Twin, points_m: Array, touches: int,
                constraints: PoseConstraints, sigma_m: Array, rng: np.random.Generator
                ) -> tuple[Array, NDArray[np.intp]]:
    """Configurations of the true robot that bring its measured point into each fixed point.

    Args:
        robot: The true robot.
        twin: Its twin (no cable), with the true measured point: checks floor and collisions.
        points_m: The fixed points, base frame, shape (f, 3), m.
        touches: Configurations per fixed point.
        constraints: What a configuration must satisfy (the cable's part does not apply).
        sigma_m: The seating error 1σ per axis, shape (3,), m.
        rng: Draws the starts and the seating errors.

    Returns:
        ``(q_rad, point)``: joint angles (f · touches, n), rad, point after point, and each
        row's fixed point.

    Raises:
        InputError: if a fixed point cannot be reached ``touches`` times.
    """
    tool = np.eye(4)
    tool[:3, 3] = twin.attachment_m
    structure = robot.structure
    pointer = replace(robot, structure=replace(structure, tool=structure.tool @ tool))
    found: list[list[Array]] = [[] for _ in points_m]
    tried = np.zeros(len(points_m), dtype=np.intp)
    rounds = np.zeros(len(points_m), dtype=np.intp)
    limit = IK_STARTS_PER_TOUCH * touches
    # Round after round, every point still short of its touches draws a batch of starts and
    # seatings (point after point) and all of them are solved at once: the IK of two rows was
    # mostly numpy's overhead, 157 calls and 1.5 s for the plane scenario's 80 sockets. From
    # its third round a point still short doubles its batch (2, 2, 4, 8… starts a touch): a
    # round costs its slowest row's Newton steps whatever its size, and about 30 % of random
    # starts reach a plane's socket, so that fixed batches of two took 5-8 rounds; most
    # points have their touches within two rounds, drawn as they were before.
    while lacking := [j for j, got in enumerate(found) if len(got) < touches]:
        for j in lacking:
            if tried[j] >= limit:
                raise InputError(f"{len(found[j])} configurations reaching fixed point {j + 1} "
                                 f"at {np.round(points_m[j] * 1e3, 1).tolist()} mm",
                                 f"{touches}: a placement the arm can reach")
        batches = [min(2 * touches << max(int(rounds[j]) - 1, 0), limit - tried[j])
                   for j in lacking]
        tried[lacking] += batches
        rounds[lacking] += 1
        draws = [(rng.uniform(robot.lower_rad, robot.upper_rad, (batch, robot.n_joints)),
                  points_m[j] + rng.normal(0.0, 1.0, (batch, 3)) * sigma_m)
                 for j, batch in zip(lacking, batches, strict=True)]
        solved = solve_ik(pointer, np.concatenate([targets for _, targets in draws]),
                          np.concatenate([seeds for seeds, _ in draws]))
        good = solved.ok.copy()
        good[good] = usable(constraints, twin, solved.q_rad[good])
        ends = np.cumsum(batches)
        for j, end, batch in zip(lacking, ends, batches, strict=True):
            rows = slice(end - batch, end)
            found[j].extend(solved.q_rad[rows][good[rows]][: touches - len(found[j])])
    return (np.concatenate([np.stack(got) for got in found]),
            np.repeat(np.arange(len(points_m), dtype=np.intp), touches))
