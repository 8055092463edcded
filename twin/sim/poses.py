"""Poses to measure: drawn at random under the rig's constraints, or read from a plan CSV.

A pose is usable when the joints are within their limits, the flange is above the floor by a
margin, no link touches another link or the floor (MuJoCo contacts), the cable length is
inside the encoder's range, and the straight cable from the port reaches the flange without
passing through a link (a MuJoCo ray cast).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from twin.arrays import Array
from twin.errors import InputError
from twin.geometry.kinematics import point_position
from twin.io.measurements import load_plan
from twin.report.display import AS_GIVEN, mm, mm_values
from twin.robot import RobotModel
from twin.scenario.constraints import PoseConstraints
from twin.sim.mujoco_twin import Twin

MAX_DRAWS_PER_POSE = 500
"""Give up when this many candidates per wanted pose were not enough."""
SLICE_MARGIN = 1.5
"""How many more candidates than the share passing so far predicts are tested at once."""


Check = tuple[str, Callable[[Array], NDArray[np.bool_]]]
"""A constraint's name and its test: ``failed(q (m, n) rad) -> (m,)``, True where it fails."""


def _checks(constraints: PoseConstraints, twin: Twin, *, together: bool = False
            ) -> list[Check]:
    """Every constraint in the order a report names them: the arithmetic ones first, then
    MuJoCo's collision test and (with a cable) its ray cast — ``together``, as one test in
    one pass over the poses (:meth:`twin.sim.mujoco_twin.Twin.obstructed`)."""
    robot = twin.robot

    def outside(q_rad: Array) -> NDArray[np.bool_]:
        return ~np.all((robot.lower_rad <= q_rad) & (q_rad <= robot.upper_rad), axis=1)

    def low(q_rad: Array) -> NDArray[np.bool_]:
        return robot.flange_positions(q_rad)[:, 2] < constraints.min_flange_height_m

    checks: list[Check] = [
        ("outside the joint limits", outside),
        (f"flange below {mm(constraints.min_flange_height_m, significant=AS_GIVEN)}", low)]
    port_m = twin.port_m
    if port_m is not None:
        def out_of_range(q_rad: Array) -> NDArray[np.bool_]:
            point = point_position(robot.structure, robot.dh, q_rad, twin.attachment_m)
            length = np.linalg.norm(point - port_m, axis=-1)
            return (length < constraints.cable_min_m) | (length > constraints.cable_max_m)

        checks.append(("cable length outside ["
                       + mm_values([constraints.cable_min_m, constraints.cable_max_m],
                                   significant=AS_GIVEN) + "] mm", out_of_range))
    clearance = constraints.cable_clearance_m
    if together:
        checks.append(("links in collision or cable through a link",
                       lambda q_rad: twin.obstructed(q_rad, clearance)))
        return checks
    checks.append(("links in collision", twin.in_collision))
    if port_m is not None:
        checks.append(("cable through a link",
                       lambda q_rad: twin.cable_blocked(q_rad, clearance)))
    return checks


def violations(constraints: PoseConstraints, twin: Twin, q_rad: Array
               ) -> list[tuple[str, NDArray[np.bool_]]]:
    """Each constraint's name and where it fails, each mask of shape (m,); the cable's only
    when the twin has one."""
    return [(name, failed(q_rad)) for name, failed in _checks(constraints, twin)]


def usable(constraints: PoseConstraints, twin: Twin, q_rad: Array) -> NDArray[np.bool_]:
    """Mask of the usable poses, shape (m,): each constraint tested only on the poses that
    passed the ones before it (MuJoCo's tests, a pose at a time, on the fewest, in one pass)."""
    ok = np.ones(len(q_rad), dtype=bool)
    for _, failed in _checks(constraints, twin, together=True):
        rows = np.flatnonzero(ok)
        if not rows.size:
            break
        ok[rows] = ~failed(q_rad[rows])
    return ok


def sample_poses(
    twin: Twin, count: int, constraints: PoseConstraints, rng: np.random.Generator
) -> Array:
    """``count`` usable poses drawn uniformly within the joint limits, shape (count, n), rad.

    Candidates are drawn in batches and filtered; the accepted ones keep their draw order.

    Raises:
        InputError: if the constraints leave (almost) no usable pose (a user's setting: the
            port, the cable range, the flange height); the caller names its source.
    """
    robot = twin.robot
    accepted: list[Array] = []
    found = drawn = 0
    while found < count:
        if drawn >= MAX_DRAWS_PER_POSE * count:
            raise InputError(
                f"only {found} of {count} poses that satisfy the constraints after {drawn} "
                "draws", "constraints that leave usable poses: widen the cable range, move "
                "the port or lower the flange height"
            )
        batch = rng.uniform(robot.lower_rad, robot.upper_rad, size=(2 * count, robot.n_joints))
        drawn += len(batch)
        good = _first_usable(constraints, twin, batch, count - found)
        accepted.append(good)
        found += len(good)
    return np.concatenate(accepted)[:count]


def _first_usable(constraints: PoseConstraints, twin: Twin, q_rad: Array, wanted: int
                  ) -> Array:
    """The first ``wanted`` usable poses of ``q_rad`` (m, n) in their order, or all of them when
    there are fewer, shape (≤ wanted, n), rad.

    Tested in slices sized by the share that passed so far, with :data:`SLICE_MARGIN` to
    spare: MuJoCo's tests, a pose at a time, were a third spent on poses beyond those wanted
    (a batch of twice the count keeps some 70 % of its draws).
    """
    found: list[Array] = []
    start = tested = passed = 0
    while start < len(q_rad) and passed < wanted:
        share = max(passed, 1) / max(tested, 1)
        part = q_rad[start:start + math.ceil((wanted - passed) / share * SLICE_MARGIN)]
        good = part[usable(constraints, twin, part)]
        found.append(good)
        passed += len(good)
        tested += len(part)
        start += len(part)
    return np.concatenate(found)[:wanted]


def read_pose_plan(path: str | Path, twin: Twin, constraints: PoseConstraints) -> Array:
    """Poses from a plan CSV (columns q1..q6 in degrees), checked like drawn ones.

    Returns:
        Joint angles, shape (m, 6), rad.

    Raises:
        InputError: naming the line of the first pose outside the limits or the constraints.
    """
    q_rad, lines = load_plan(path, twin.robot)
    for name, failed in violations(constraints, twin, q_rad):
        if np.any(failed):
            row = int(np.flatnonzero(failed)[0])
            raise InputError(f"a pose with {name}", "poses the rig can measure",
                             source=path, where=f"line {lines[row]}")
    return q_rad


def feasible_sampler(robot: RobotModel, rng: np.random.Generator
                     ) -> Callable[[Array, int], Array]:
    """A candidate sampler for :mod:`twin.design.planning`: poses the MuJoCo twin with the
    encoder at a port can measure (its default constraints), drawn from ``rng``."""
    constraints = PoseConstraints()

    def draw(port_m: Array, count: int) -> Array:
        try:
            return sample_poses(Twin.build(robot, port_m), count, constraints, rng)
        except InputError as exc:
            port = mm_values(port_m, significant=AS_GIVEN, separator=",")
            raise InputError(exc.found, exc.expected + " (or --joint-limits-only)",
                             source=f"--port {port}") from None

    return draw
