"""Pose sampling under the rig's constraints, and pose-plan CSV files."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from twin.compensation.ik import IKResult, solve_ik
from twin.errors import InputError, TwinError
from twin.geometry import kinematics
from twin.geometry.kinematics import KERNEL_VARIABLE, point_position
from twin.io.robot_file import default_robot
from twin.robot import RobotModel, random_poses
from twin.scenario import PoseConstraints, load_scenario
from twin.sim import Twin, read_pose_plan, sample_poses, touches
from twin.sim.poses import usable, violations
from twin.sim.simulate import simulate
from twin.sim.touches import touch_poses
from twin.units import deg_to_rad

PORT_M = np.array([0.6, -0.4, 0.1])
CONSTRAINTS = PoseConstraints(min_flange_height_m=0.05, cable_min_m=0.1, cable_max_m=1.2)

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"


def test_sampled_poses_satisfy_every_constraint() -> None:
    """Drawn poses are within the limits, above the floor, collision-free, in the encoder's range
    and with a free line of sight; they are reproducible from the seed."""
    robot = default_robot()
    twin = Twin.build(robot, PORT_M)
    q = sample_poses(twin, 60, CONSTRAINTS, np.random.default_rng(5))
    assert q.shape == (60, 6)
    assert np.all((robot.lower_rad <= q) & (q <= robot.upper_rad))
    flange = robot.flange_positions(q)
    length = np.linalg.norm(flange - PORT_M, axis=1)
    assert np.all(flange[:, 2] >= 0.05)
    assert np.all((length >= 0.1) & (length <= 1.2))
    assert not np.any(twin.in_collision(q)) and not np.any(twin.cable_blocked(q))
    assert np.array_equal(q, sample_poses(twin, 60, CONSTRAINTS, np.random.default_rng(5)))


@pytest.mark.parametrize("constraints", [
    CONSTRAINTS,
    # A narrow cable range keeps under half of each batch: several batches are drawn.
    PoseConstraints(min_flange_height_m=0.05, cable_min_m=0.6, cable_max_m=0.8)])
def test_sampled_poses_are_the_first_usable_draws(constraints: PoseConstraints) -> None:
    """The sampler returns the first usable poses of its draws in their order, as testing every
    draw of each batch of twice the count would (its slices stop MuJoCo's tests early)."""
    robot = default_robot()
    twin = Twin.build(robot, PORT_M)
    count = 50
    rng = np.random.default_rng(8)
    usable_draws = []
    while sum(len(part) for part in usable_draws) < count:
        batch = rng.uniform(robot.lower_rad, robot.upper_rad, size=(2 * count, 6))
        failed = np.zeros(len(batch), dtype=bool)
        for _, check in violations(constraints, twin, batch):
            failed |= check
        usable_draws.append(batch[~failed])
    expected = np.concatenate(usable_draws)[:count]
    np.testing.assert_array_equal(
        sample_poses(twin, count, constraints, np.random.default_rng(8)), expected)


def test_flange_below_the_floor_is_a_collision() -> None:
    """Every random pose whose flange centre is below the floor is reported in collision."""
    robot = default_robot()
    q = random_poses(robot, 3000, np.random.default_rng(6))
    below = q[robot.flange_positions(q)[:, 2] < -0.01]
    assert len(below) > 0
    assert np.all(Twin.build(robot, PORT_M).in_collision(below))


def test_cable_through_the_upper_arm_is_blocked() -> None:
    """At q = 0 a port behind the robot sees the flange through the upper arm; the usual port
    in front does not."""
    robot = default_robot()
    home = np.zeros((1, 6))
    assert Twin.build(robot, [-0.5, 0.0, 0.15]).cable_blocked(home)[0]
    assert not Twin.build(robot, PORT_M).cable_blocked(home)[0]


def test_one_pass_of_mujocos_tests_fails_where_either_does() -> None:
    """MuJoCo's two tests in one pass (the cable cast where nothing touches) fail exactly the
    poses in collision or with the cable through a link, with a clearance; without a cable,
    those in collision."""
    robot = default_robot()
    q = random_poses(robot, 400, np.random.default_rng(9))
    for port in (PORT_M, None):
        twin = Twin.build(robot, port)
        collides, blocked = twin.in_collision(q), twin.cable_blocked(q, 0.01)
        assert np.array_equal(twin.obstructed(q, 0.01), collides | blocked)
        assert collides.any() and (blocked & ~collides).any() == (port is not None)


def test_impossible_constraints_fail_with_a_message() -> None:
    """A cable range no pose can reach stops the sampler with an explanation."""
    twin = Twin.build(default_robot(), PORT_M)
    impossible = PoseConstraints(cable_min_m=5.0, cable_max_m=6.0)
    with pytest.raises(TwinError, match="satisfy the constraints"):
        sample_poses(twin, 2, impossible, np.random.default_rng(0))


def test_an_error_that_names_its_source_is_not_laid_on_the_scenario(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The scenario is named for constraints that leave no pose, not for a refused
    ``TWIN_KERNEL`` met at the first pose test (it was reported as the scenario's [port])."""
    scenario = load_scenario(SCENARIOS / "geometric_irb120.toml")
    monkeypatch.setenv(KERNEL_VARIABLE, "fast")
    kinematics._compiled.cache_clear()
    with pytest.raises(InputError) as raised:
        simulate(scenario, 0)
    monkeypatch.delenv(KERNEL_VARIABLE)
    kinematics._compiled.cache_clear()
    assert (raised.value.source, raised.value.where) == (KERNEL_VARIABLE, None)
    impossible = replace(scenario, constraints=PoseConstraints(cable_min_m=5.0,
                                                               cable_max_m=6.0))
    with pytest.raises(InputError, match="satisfy the constraints") as raised:
        simulate(impossible, 0)
    assert (raised.value.source, raised.value.where) == (
        str(scenario.source), "[port], [poses], [encoder] range_mm")


def test_pose_plan_is_read_in_degrees_and_checked(tmp_path: Path) -> None:
    """A plan's q1..q6 (degrees) are read as radians; a pose out of limits or below the floor
    is an InputError naming its line."""
    twin = Twin.build(default_robot(), PORT_M)
    plan = tmp_path / "plan.csv"
    plan.write_text("q1,q2,q3,q4,q5,q6,note\n0,0,0,0,30,0,a\n10,-20,15,5,40,90,b\n")
    q = read_pose_plan(plan, twin, CONSTRAINTS)
    assert np.allclose(q, deg_to_rad([[0, 0, 0, 0, 30, 0], [10, -20, 15, 5, 40, 90]]))
    plan.write_text("q1,q2,q3,q4,q5,q6\n0,0,0,0,30,0\n0,0,95,0,0,0\n")
    with pytest.raises(InputError, match=r"line 3.*q3"):
        read_pose_plan(plan, twin, CONSTRAINTS)
    plan.write_text("q1,q2,q3,q4,q5,q6\n0,0,0,0,30,0\n0,100,60,0,90,0\n")
    with pytest.raises(InputError, match="line 3"):
        read_pose_plan(plan, twin, CONSTRAINTS)


def test_touches_seat_the_ball_in_each_socket_from_usable_configurations() -> None:
    """Every fixed point is touched ``touches`` times, point after point, each configuration of
    the true robot bringing the ball within its seating error of the socket, inside the limits
    and free of collisions; the same seed gives the same configurations."""
    robot = default_robot()
    eyelet = np.array([0.0, 0.0, 0.05])
    twin = Twin.build(robot, None, attachment_m=eyelet)
    sockets = np.array([[0.45, 0.0, 0.3], [0.35, 0.25, 0.45], [0.4, -0.2, 0.2]])
    sigma_m = np.full(3, 2e-5)
    constraints = PoseConstraints()
    q, point = touch_poses(robot, twin, sockets, 3, constraints, sigma_m,
                           np.random.default_rng(4))
    assert q.shape == (9, robot.n_joints) and point.tolist() == [0, 0, 0, 1, 1, 1, 2, 2, 2]
    ball = point_position(robot.structure, robot.dh, q, eyelet)
    assert np.max(np.abs(ball - sockets[point])) < 6 * sigma_m[0]
    assert np.all(usable(constraints, twin, q))
    again, _ = touch_poses(robot, twin, sockets, 3, constraints, sigma_m,
                           np.random.default_rng(4))
    assert np.array_equal(again, q)


def test_a_socket_out_of_reach_is_named_after_its_starts(monkeypatch: pytest.MonkeyPatch
                                                        ) -> None:
    """A socket 3 m away: refused, naming the socket and what was found, once it has had its
    IK_STARTS_PER_TOUCH starts per touch — in batches that double after the second round
    (4, 4, 8, 16, 32 starts, then the 16 left), not in 20 rounds of 4."""
    robot = default_robot()
    twin = Twin.build(robot, None)
    sockets = np.array([[0.45, 0.0, 0.3], [3.0, 0.0, 0.3]])
    far: list[int] = []

    def counted(pointer: RobotModel, targets: np.ndarray, seeds: np.ndarray) -> IKResult:
        far.append(int(np.sum(targets[:, 0] > 2.0)))
        return solve_ik(pointer, targets, seeds)

    monkeypatch.setattr(touches, "solve_ik", counted)
    with pytest.raises(InputError, match=r"0 configurations reaching fixed point 2 at "
                       r"\[3000\.0, 0\.0, 300\.0\] mm"):
        touch_poses(robot, twin, sockets, 2, PoseConstraints(), np.full(3, 2e-5),
                    np.random.default_rng(4))
    assert far == [4, 4, 8, 16, 32, 16]
    assert sum(far) == touches.IK_STARTS_PER_TOUCH * 2
