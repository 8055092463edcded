"""Statics of the twin: servos of finite stiffness under gravity and the cable's tension."""

from __future__ import annotations

import gc
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np
import pytest

from twin.dataset import approach_directions
from twin.io.robot_file import default_robot, load_robot
from twin.kinds.length import cable_length, length_measurements
from twin.robot import RobotModel, random_poses
from twin.scenario import Physics
from twin.scenario.joint_errors import JointErrors
from twin.scenario.physics import RIGID
from twin.sim import Twin, static_equilibrium

PORT_M = np.array([0.6, -0.4, 0.1])
STIFFNESS = np.array([2e5, 2e5, 2e5, 5e4, 5e4, 5e4])
PAPER = Physics(STIFFNESS, gravity=True, tension_n=5.0)


def _poses(count: int, seed: int = 3) -> np.ndarray:
    robot = default_robot()
    q = random_poses(robot, count, np.random.default_rng(seed))
    # Keep away from the joint limits so that stepping never touches them.
    return np.clip(q, robot.lower_rad + 0.1, robot.upper_rad - 0.1)


def test_fixed_point_matches_stepping_to_rest() -> None:
    """The fixed-point equilibrium equals where the damped dynamics come to rest (1e-9 rad)."""
    twin = Twin.build(default_robot(), PORT_M, PAPER)
    q_cmd = _poses(3)
    q_rest = twin.joint_angles(q_cmd)
    model = twin.statics_model
    model.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
    data = mujoco.MjData(model)
    for target, expected in zip(q_cmd, q_rest, strict=True):
        mujoco.mj_resetData(model, data)
        data.qpos[:] = target
        data.ctrl[:6] = target
        data.ctrl[model.actuator("tension").id] = PAPER.tension_n
        for _ in range(4000):  # 2 s of the critically damped servos
            mujoco.mj_step(model, data)
        assert np.max(np.abs(data.qvel)) < 1e-9
        assert np.max(np.abs(data.qpos - expected)) < 1e-9


def test_equilibrium_balances_the_generalised_forces() -> None:
    """At the returned angles servo, gravity and tension torques cancel to 1e-6 N·m."""
    twin = Twin.build(default_robot(), PORT_M, PAPER)
    q_cmd = _poses(20)
    q_rest = static_equilibrium(twin.statics_model, twin.statics_data, q_cmd, STIFFNESS)
    data = twin.statics_data
    for target, q in zip(q_cmd, q_rest, strict=True):
        data.ctrl[:6] = target
        data.qpos[:] = q
        mujoco.mj_forward(twin.statics_model, data)
        assert np.max(np.abs(data.qfrc_actuator - data.qfrc_bias)) < 1e-6


def test_deflection_is_tens_of_micrometres() -> None:
    """With the paper scenario's stiffness the flange sags by tens of µm RMS (10–200 µm)."""
    robot = default_robot()
    q = _poses(200)
    shift = Twin.build(robot, PORT_M, PAPER).flange_positions(q) - robot.flange_positions(q)
    rms_um = np.sqrt(np.mean(np.sum(shift**2, axis=1))) * 1e6
    assert 10.0 < rms_um < 200.0
    # Half the stiffness, twice the sag (linear statics).
    soft = Twin.build(robot, PORT_M, Physics(STIFFNESS / 2, True, 5.0)).flange_positions(q)
    soft_um = np.sqrt(np.mean(np.sum((soft - robot.flange_positions(q))**2, axis=1))) * 1e6
    assert soft_um == pytest.approx(2 * rms_um, rel=0.01)


def test_tension_alone_shortens_the_cable() -> None:
    """Without gravity the cable's pull moves the flange towards the port at every pose."""
    robot = default_robot()
    q = _poses(50)
    pulled = Twin.build(robot, PORT_M, Physics(STIFFNESS, False, 5.0)).lengths(q)
    rigid = cable_length(robot.structure, robot.dh, q, PORT_M)
    assert np.all(pulled < rigid)
    assert np.all(rigid - pulled < 1e-4)


def test_rigid_twin_equals_core_model() -> None:
    """Rigid joints: the twin's lengths equal the core's model to 1e-9 m."""
    robot = default_robot()
    q = _poses(300)
    assert np.max(np.abs(Twin.build(robot, PORT_M).lengths(q)
                         - cable_length(robot.structure, robot.dh, q, PORT_M))) < 1e-9


def test_a_collected_twins_data_serves_the_next_twin_as_new_data_would() -> None:
    """A twin's scratch data passes, once it is collected, to the next twin of the same sizes,
    which reads what a twin on data of its own reads (the servos' statics and the cable's pull
    included); twins alive together never share data."""
    robot, other = _perturbed(default_robot(), 5), _perturbed(default_robot(), 6)
    q = _poses(40)
    gc.collect()  # the earlier tests' twins hand theirs back first
    gc.disable()  # and no collection in between hands back another
    try:
        first = Twin.build(robot, PORT_M, PAPER)
        handed = first.data
        del first
        reused = Twin.build(other, PORT_M + 0.05, PAPER)
        alongside = Twin.build(other, PORT_M + 0.05, PAPER)
    finally:
        gc.enable()
    assert reused.data is handed and alongside.data is not handed
    assert np.array_equal(reused.lengths(q), alongside.lengths(q))
    assert np.array_equal(reused.in_collision(q), alongside.in_collision(q))


def test_a_twin_placed_for_another_table_reads_as_a_twin_built_for_it() -> None:
    """A warm-up's rows: the twin's bodies and sites placed for a grown table read what a twin
    compiled for it reads (joint errors and an eyelet off the flange included), and the twin
    reads its own table again after."""
    robot, warm = _perturbed(default_robot(), 5), _perturbed(default_robot(), 6)
    n = robot.n_joints
    errors = JointErrors(np.full(n, 2e-4), np.ones(n), np.linspace(0.0, 3.0, n),
                         np.full(n, 1e-4))
    eyelet = np.array([0.01, -0.02, 0.03])
    q = _poses(30)
    approach = approach_directions(q)
    twin = Twin.build(robot, PORT_M, joint_errors=errors, attachment_m=eyelet)
    before = twin.at_rest(q, approach)
    placed = twin.at_rest_of(np.broadcast_to(warm.dh, (len(q), *warm.dh.shape)), q, approach)
    built = Twin.build(warm, PORT_M, joint_errors=errors, attachment_m=eyelet).at_rest(q, approach)
    for mine, theirs in zip(placed, built, strict=True):
        assert np.max(np.abs(mine - theirs)) < 1e-12
    assert np.max(np.abs(placed.length_m - before.length_m)) > 1e-6  # the tables differ
    for again, first in zip(twin.at_rest(q, approach), before, strict=True):
        assert np.array_equal(again, first)
    with pytest.raises(ValueError, match="rigid joints only"):
        Twin.build(robot, PORT_M, PAPER).at_rest_of(np.stack([warm.dh] * len(q)), q, approach)
    with pytest.raises(ValueError, match=r"tables of shape \(4, 6\), expected \(30, 4, 6\)"):
        twin.at_rest_of(warm.dh, q, approach)


def test_each_row_of_a_warm_up_reads_as_a_twin_built_for_its_own_table() -> None:
    """A warm-up's rows each on its own table, placed in one call: every row reads what a twin
    compiled for its table reads at that row (the rows' frames made at once, then placed in
    turn)."""
    robot = _perturbed(default_robot(), 7)
    q = _poses(8)
    approach = approach_directions(q)
    grown = [_perturbed(robot, 10 + k) for k in range(len(q))]
    eyelet = np.array([0.01, -0.02, 0.03])
    placed = Twin.build(robot, PORT_M, attachment_m=eyelet).at_rest_of(
        np.stack([warm.dh for warm in grown]), q, approach)
    for k, warm in enumerate(grown):
        built = Twin.build(warm, PORT_M, attachment_m=eyelet).at_rest(q[k:k + 1],
                                                                       approach[k:k + 1])
        for mine, theirs in zip(placed, built, strict=True):
            assert np.max(np.abs(mine[k] - theirs[0])) < 1e-12


@pytest.mark.parametrize("physics", [RIGID, PAPER], ids=["rigid", "servos"])
@pytest.mark.parametrize("eyelet", [None, np.array([0.01, -0.02, 0.03])], ids=["flange", "eyelet"])
def test_a_twin_with_its_port_moved_reads_as_a_twin_built_there(
        physics: Physics, eyelet: np.ndarray | None) -> None:
    """An encoder moved between stations: the first station's twin with its port moved reads,
    bit for bit, what a twin compiled with the port there reads (the servos' statics under the
    cable's pull, the collisions, the cable through a link), and the first twin still reads its
    own port."""
    robot = _perturbed(default_robot(), 8)
    n = robot.n_joints
    errors = JointErrors(np.full(n, 2e-4), np.ones(n), np.linspace(0.0, 3.0, n),
                         np.full(n, 1e-4))
    station = np.array([0.3, 0.5, 0.05])
    q = _poses(40, seed=4)
    first = Twin.build(robot, PORT_M, physics, errors, eyelet)
    before = first.at_rest(q)
    moved = first.with_port(station)
    built = Twin.build(robot, station, physics, errors, eyelet)
    for mine, theirs in zip(moved.at_rest(q), built.at_rest(q), strict=True):
        assert np.array_equal(mine, theirs)
    assert np.array_equal(moved.in_collision(q), built.in_collision(q))
    blocked = moved.cable_blocked(q)
    assert np.array_equal(blocked, built.cable_blocked(q)) and blocked.any() and not blocked.all()
    assert np.max(np.abs(moved.lengths(q) - before.length_m)) > 0.1  # the ports differ
    for again, kept in zip(first.at_rest(q), before, strict=True):
        assert np.array_equal(again, kept)
    with pytest.raises(ValueError, match="a twin with a cable and a port expected"):
        Twin.build(robot, None).with_port(station)


def _perturbed(robot: RobotModel, seed: int) -> RobotModel:
    """Every D-H entry off the nominal (no link of zero length: the same geoms, the same
    sizes)."""
    return robot.perturbed(np.random.default_rng(seed).uniform(1e-4, 1e-3, robot.dh.size))


def test_physics_rejects_loads_without_stiffness() -> None:
    """Gravity or tension on rigid joints is a mistake, and stiffness must be positive."""
    with pytest.raises(ValueError, match="stiffness"):
        Physics(gravity=True)
    with pytest.raises(ValueError, match="stiffness"):
        Physics(tension_n=5.0)
    with pytest.raises(ValueError, match="positive"):
        Physics(np.array([1e5, 0, 1e5, 1e5, 1e5, 1e5]))


def _torso() -> RobotModel:
    """The FR3 on its torso lift with centres of mass (its URDF gives masses alone)."""
    robot = load_robot(Path(__file__).resolve().parents[1] / "models" / "fr3_torso"
                       / "fr3_torso.urdf")
    return replace(robot, com_m=np.random.default_rng(4).normal(scale=0.05, size=(8, 3)))


@pytest.mark.parametrize("make", [default_robot, _torso], ids=["irb120", "fr3 on a torso lift"])
def test_core_torques_equal_mujoco_generalised_forces(make: Callable[[], RobotModel]) -> None:
    """The calibration's static torques (twin.geometry.statics: gravity at the robot file's centres
    of mass, the cable's pull towards the port) equal MuJoCo's generalised forces on the twin built
    from the same file, qfrc_actuator − qfrc_bias with the servos at the pose, to 1e-9 N·m — and
    on a prismatic lift the force along it (N, a slide's generalised force)."""
    from twin.rig import Rig
    from twin.unknowns.compliance import torques

    robot = make()
    n = robot.n_joints
    physics = Physics(np.full(n, 2e5), gravity=True, tension_n=5.0)
    twin = Twin.build(robot, PORT_M, physics)
    q = random_poses(robot, 25, np.random.default_rng(11))
    q = np.clip(q, robot.lower_rad + 0.01, robot.upper_rad - 0.01)
    data = twin.statics_data
    expected = np.empty_like(q)
    for row, pose in enumerate(q):
        data.ctrl[:n] = pose
        data.qpos[:] = pose
        data.qvel[:] = 0.0
        mujoco.mj_forward(twin.statics_model, data)
        expected[row] = data.qfrc_actuator - data.qfrc_bias
    rig = Rig.cable(PORT_M, tension_n=physics.tension_n)
    tau = torques(robot, rig, length_measurements(q, np.zeros(len(q))))
    assert np.max(np.abs(expected)) > 10.0  # the shoulder carries tens of N·m
    np.testing.assert_allclose(tau, expected, atol=1e-9)
    if robot.prismatic.any():  # the lift carries the whole arm's weight, some 200 N
        assert np.all(-tau[:, 0] > 150.0)
