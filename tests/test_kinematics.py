"""Forward kinematics of any chain of revolute and prismatic joints and its analytic
Jacobians."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from twin.geometry.kinematics import (
    JOINT_TYPES,
    PARAMETRISATIONS,
    Structure,
    fixed_transforms,
    flange_jacobian,
    flange_transform,
    frames,
    point_jacobian,
    point_position,
    rigid_transform,
    trace_point,
    xyz_rpy,
)
from twin.geometry.statics import GRAVITY_M_S2, joint_torques, link_torques
from twin.io.robot_file import default_robot
from twin.robot import RobotModel, random_poses

STANDARD = Structure.standard(6)


def _rz(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _random_rigid(rng: np.random.Generator) -> np.ndarray:
    transform = np.eye(4)
    transform[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    transform[:3, 3] = rng.normal(scale=0.1, size=3)
    return transform


def _mixed(rng: np.random.Generator, n: int = 6) -> Structure:
    """A structure with every parametrisation, revolute and prismatic joints (one in three
    slides), a base and a tool transform."""
    kinds = tuple(rng.choice(PARAMETRISATIONS, n))
    types = tuple(rng.choice(JOINT_TYPES, n, p=[2 / 3, 1 / 3]))
    return Structure(kinds, base=_random_rigid(rng), tool=_random_rigid(rng), joint_types=types)


def _move(joint_type: str, q: float) -> np.ndarray:
    """A joint's own motion: Rz(q) turning, Tz(q) sliding."""
    if joint_type == "revolute":
        return _rz(q)
    transform = np.eye(4)
    transform[2, 3] = q
    return transform


def test_irb120_flange_at_home(irb120: RobotModel) -> None:
    """At q = 0 the IRB 120 flange centre is at (374, 0, 630) mm (method-notes §1)."""
    p = point_position(STANDARD, irb120.dh, np.zeros((1, 6)))
    np.testing.assert_allclose(p[0], [0.374, 0.0, 0.630], atol=1e-12)


def test_transform_matches_dh_matrix_product(irb120: RobotModel) -> None:
    """The axis walk equals the product of the paper's eq. 2 matrices."""
    q = random_poses(irb120, 50, np.random.default_rng(0))
    expected = np.empty((50, 4, 4))
    for k, qk in enumerate(q):
        T = np.eye(4)
        for (a, d, alpha, theta), qi in zip(irb120.dh.T, qk, strict=True):
            ct, st_, ca, sa = np.cos(qi + theta), np.sin(qi + theta), np.cos(alpha), np.sin(alpha)
            T = T @ np.array([[ct, -st_ * ca, st_ * sa, a * ct], [st_, ct * ca, -ct * sa, a * st_],
                              [0, sa, ca, d], [0, 0, 0, 1]])
        expected[k] = T
    np.testing.assert_allclose(flange_transform(STANDARD, irb120.dh, q), expected, atol=1e-14)


def _elementary(kind: str, joint_type: str, slots: np.ndarray, q: float) -> np.ndarray:
    """Each parametrisation's link transform written out as 4×4 products (module docstring):
    a revolute joint's q turns with θ, a prismatic joint's slides along z with d (a Hayati
    joint's alone)."""
    a, s1, alpha, theta = slots

    def rot(axis: str, angle: float) -> np.ndarray:
        transform = np.eye(4)
        transform[:3, :3] = Rotation.from_euler(axis, angle).as_matrix()
        return transform

    def trans(axis: int, value: float) -> np.ndarray:
        transform = np.eye(4)
        transform[axis, 3] = value
        return transform

    turn, slide = (q, 0.0) if joint_type == "revolute" else (0.0, q)
    if kind == "dh":
        return rot("z", turn + theta) @ trans(2, s1 + slide) @ trans(0, a) @ rot("x", alpha)
    if kind == "mdh":
        return rot("x", alpha) @ trans(0, a) @ rot("z", turn + theta) @ trans(2, s1 + slide)
    return (rot("z", turn + theta) @ trans(2, slide) @ trans(0, a) @ rot("x", alpha)
            @ rot("y", s1))


@pytest.mark.parametrize("seed", range(6))
def test_every_parametrisation_matches_its_matrix_product(seed: int) -> None:
    """Mixed D-H, modified D-H and Hayati joints, revolute and prismatic, with base and tool
    transforms: the flange pose, a flange point and the fixed-transform form all equal the
    written-out matrix product."""
    rng = np.random.default_rng(seed)
    structure = _mixed(rng)
    robot = default_robot()
    table = robot.dh + rng.normal(scale=0.05, size=(4, 6))
    q = random_poses(robot, 8, rng)
    point = rng.normal(scale=0.05, size=3)
    fixed = fixed_transforms(structure, table)
    poses = flange_transform(structure, table, q)
    points = point_position(structure, table, q, point)
    for k, qk in enumerate(q):
        expected = structure.base.copy()
        via_fixed = fixed[0].copy()
        for i, (kind, joint_type) in enumerate(zip(structure.parametrisation,
                                                   structure.joint_types, strict=True)):
            expected = expected @ _elementary(kind, joint_type, table[:, i], qk[i])
            via_fixed = via_fixed @ _move(joint_type, qk[i]) @ fixed[i + 1]
        expected = expected @ structure.tool
        np.testing.assert_allclose(poses[k], expected, atol=1e-13)
        np.testing.assert_allclose(via_fixed, expected, atol=1e-13)
        np.testing.assert_allclose(points[k], expected[:3, :3] @ point + expected[:3, 3],
                                   atol=1e-13)


@pytest.mark.parametrize("seed", range(4))
def test_a_stack_of_tables_has_each_tables_fixed_transforms(seed: int) -> None:
    """A warm-up places its rows' tables all at once: the stack's fixed transforms are each
    table's (the one-table form, held to the matrix product above), for every parametrisation
    and joint type."""
    rng = np.random.default_rng(seed)
    structure = _mixed(rng)
    tables = default_robot().dh + rng.normal(scale=0.05, size=(5, 4, 6))
    stacked = fixed_transforms(structure, tables)
    assert stacked.shape == (5, 7, 4, 4)
    for table, fixed in zip(tables, stacked, strict=True):
        np.testing.assert_allclose(fixed, fixed_transforms(structure, table), rtol=0,
                                   atol=1e-15)
    with pytest.raises(ValueError, match="expected"):
        fixed_transforms(structure, tables[None])


def test_batched_tables_equal_one_by_one(irb120: RobotModel) -> None:
    """K tables × m poses in one call give what K separate calls give."""
    rng = np.random.default_rng(1)
    q = random_poses(irb120, 20, rng)
    tables = irb120.dh + rng.normal(scale=1e-3, size=(7, 4, 6))
    points = rng.normal(scale=0.02, size=(7, 3))
    batched = point_position(STANDARD, tables, q, points)
    assert batched.shape == (7, 20, 3)
    for k in range(7):
        np.testing.assert_array_equal(batched[k], point_position(STANDARD, tables[k], q,
                                                                 points[k]))


def test_frames_end_at_the_flange(irb120: RobotModel) -> None:
    """The last joint frame is the flange of a bare chain, the first the base."""
    q = random_poses(irb120, 5, np.random.default_rng(2))
    chain = frames(STANDARD, irb120.dh, q)
    assert chain.origins.shape == (5, 7, 3)
    np.testing.assert_allclose(chain.origins[:, -1], irb120.flange_positions(q), atol=1e-15)
    np.testing.assert_allclose(chain.flange, irb120.flange_transforms(q), atol=1e-15)
    np.testing.assert_array_equal(chain.origins[:, 0], 0.0)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_point_jacobian_matches_finite_differences(seed: int) -> None:
    """∂p/∂table, ∂p/∂q and ∂p/∂point equal central differences, every parametrisation,
    revolute and prismatic joints (q of a sliding joint in m)."""
    rng = np.random.default_rng(seed)
    structure = _mixed(rng)
    robot = default_robot()
    table = robot.dh + rng.normal(scale=2e-3, size=(4, 6))
    q = random_poses(robot, 4, rng)
    point = rng.normal(scale=0.05, size=3)
    jacobian = point_jacobian(structure, table, q, point)
    eps = 1e-6
    steps = np.eye(24).reshape(24, 4, 6) * eps
    numeric = (point_position(structure, table + steps, q, point)
               - point_position(structure, table - steps, q, point)) / (2 * eps)
    np.testing.assert_allclose(jacobian.table, np.moveaxis(numeric, 0, -1), atol=1e-8)
    joint_steps = np.eye(6)[:, None, :] * eps
    numeric_q = (point_position(structure, table, q + joint_steps, point)
                 - point_position(structure, table, q - joint_steps, point)) / (2 * eps)
    np.testing.assert_allclose(jacobian.joints, np.moveaxis(numeric_q, 0, -1), atol=1e-8)
    point_steps = np.eye(3) * eps
    numeric_t = (point_position(structure, table, q, point + point_steps)
                 - point_position(structure, table, q, point - point_steps))
    np.testing.assert_allclose(jacobian.rotation, np.moveaxis(numeric_t / (2 * eps), 0, -1),
                               atol=1e-8)


@pytest.mark.parametrize(("tables", "poses", "points"), [
    ((), (), ()), ((3,), (), (3,)), ((), (3,), ()), ((3,), (3,), ()), ((2, 3), (), (2, 3))])
def test_jacobian_along_directions_is_the_projected_jacobian(
        tables: tuple[int, ...], poses: tuple[int, ...], points: tuple[int, ...]) -> None:
    """Derivatives along r directions per pose (what a measurement's rows need) equal the
    directions times the whole Jacobian, for any batch of tables, poses and points, every
    parametrisation; the traced position is point_position's."""
    rng = np.random.default_rng(11)
    structure = _mixed(rng)
    robot = default_robot()
    table = robot.dh + rng.normal(scale=2e-3, size=(*tables, 4, 6))
    q = random_poses(robot, 5 * int(np.prod(poses)), rng).reshape(*poses, 5, 6)
    point = rng.normal(scale=0.05, size=(*points, 3))
    trace = trace_point(structure, table, q, point)
    whole = trace.jacobian()
    directions = rng.normal(size=(*whole.position.shape[:-1], 2, 3))
    along = trace.jacobian(directions)
    np.testing.assert_allclose(trace.position, point_position(structure, table, q, point),
                               atol=1e-15)
    for name in ("table", "joints", "rotation"):
        np.testing.assert_allclose(getattr(along, name),
                                   directions @ getattr(whole, name), atol=1e-14)


def test_flange_jacobian_is_the_twist_per_joint(irb120: RobotModel) -> None:
    """Linear rows are ∂p/∂q; angular rows turn the flange frame as finite differences say
    (not at all for a prismatic joint)."""
    rng = np.random.default_rng(6)
    structure = _mixed(rng)
    q = random_poses(irb120, 3, rng)
    pose, jacobian = flange_jacobian(structure, irb120.dh, q)
    np.testing.assert_allclose(jacobian[:, :3], point_jacobian(structure, irb120.dh, q).joints,
                               atol=1e-15)
    eps = 1e-7
    for i in range(6):
        moved = flange_transform(structure, irb120.dh, q + np.eye(6)[i] * eps)
        delta = Rotation.from_matrix(moved[:, :3, :3] @ np.swapaxes(pose[:, :3, :3], 1, 2))
        np.testing.assert_allclose(delta.as_rotvec() / eps, jacobian[:, 3:, i], atol=1e-6)
    assert structure.prismatic.any()
    np.testing.assert_array_equal(jacobian[:, 3:, structure.prismatic], 0.0)


def test_batched_poses_with_one_table(irb120: RobotModel) -> None:
    """Poses with their own batch dimensions (k, m, n) work with one table, and tables (k, 4, n)
    pair with pose sets (k, m, n) one to one."""
    rng = np.random.default_rng(5)
    q = random_poses(irb120, 12, rng).reshape(3, 4, 6)
    tables = irb120.dh + rng.normal(scale=1e-3, size=(3, 4, 6))
    one_table = point_position(STANDARD, irb120.dh, q)
    paired = point_position(STANDARD, tables, q)
    assert one_table.shape == paired.shape == (3, 4, 3)
    for k in range(3):
        np.testing.assert_allclose(one_table[k], irb120.flange_positions(q[k]), atol=1e-15)
        np.testing.assert_allclose(paired[k], point_position(STANDARD, tables[k], q[k]),
                                   atol=1e-15)


def test_structure_names_and_units() -> None:
    """A Hayati joint's second slot is the angle β; names follow the slot order."""
    structure = Structure(("dh", "hayati", "dh", "dh", "mdh", "dh"))
    names = structure.parameter_names
    assert names[:6] == ("a1", "a2", "a3", "a4", "a5", "a6")
    assert names[6:12] == ("d1", "beta2", "d3", "d4", "d5", "d6")
    assert not structure.is_length[1, 1] and structure.is_length[1, 0]
    with pytest.raises(ValueError, match="dh, mdh, hayati"):
        Structure(("dh", "screw"))
    with pytest.raises(ValueError, match="revolute, prismatic for each of 2 joints"):
        Structure(("dh", "dh"), joint_types=("revolute", "helical"))
    with pytest.raises(ValueError, match="revolute, prismatic for each of 2 joints"):
        Structure(("dh", "dh"), joint_types=("prismatic",))
    bent = np.eye(4)
    bent[0, 0] = 2.0
    with pytest.raises(ValueError, match="not a rigid transform"):
        Structure(("dh",), base=bent)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-np.pi, np.pi), min_size=3, max_size=3),
       st.sampled_from([None, np.pi / 2, -np.pi / 2, np.pi / 2 - 1e-7]))
def test_rpy_round_trip_matches_scipy(rpy: list[float], pitch: float | None) -> None:
    """rigid_transform is URDF's fixed-axis roll-pitch-yaw (scipy's extrinsic "xyz"), and
    xyz_rpy gives angles that rebuild the same transform, at and next to gimbal lock."""
    if pitch is not None:
        rpy[1] = pitch
    transform = rigid_transform([0.1, -0.2, 0.3], rpy)
    np.testing.assert_allclose(transform[:3, :3], Rotation.from_euler("xyz", rpy).as_matrix(),
                               rtol=0.0, atol=1e-15)
    xyz, back = xyz_rpy(transform)
    assert abs(back[1]) <= np.pi / 2
    np.testing.assert_allclose(rigid_transform(xyz, back), transform, rtol=0.0, atol=1e-11)


def test_prismatic_joints_columns_and_units() -> None:
    """A prismatic joint's variable is its d (column n + i), a prismatic Hayati joint's a
    column of its own after the table's; the units say m beside rad."""
    structure = Structure(("dh", "hayati", "mdh", "dh"),
                          joint_types=("prismatic", "prismatic", "revolute", "revolute"))
    assert structure.joint_columns.tolist() == [4, 16, 14, 15]
    assert structure.n_columns == 17
    assert structure.joint_units == ("m", "m", "rad", "rad")
    assert structure.prismatic.tolist() == [True, True, False, False]
    assert not structure.all_revolute and Structure.standard(4).all_revolute


@pytest.mark.parametrize("seed", range(3))
def test_joint_loads_are_the_potentials_slope(seed: int) -> None:
    """Gravity's load on every joint — a torque about a revolute axis, a force along a
    prismatic one — is minus the slope of the links' potential energy along q (virtual work, by
    central differences), and link by link it sums to the whole."""
    rng = np.random.default_rng(seed)
    structure = _mixed(rng)
    assert structure.prismatic.any() and not structure.prismatic.all()
    robot = default_robot()
    table = robot.dh + rng.normal(scale=0.05, size=(4, 6))
    q = random_poses(robot, 5, rng)
    mass = rng.uniform(1.0, 5.0, 6)
    com = rng.normal(scale=0.05, size=(6, 3))

    def potential(values: np.ndarray) -> np.ndarray:
        chain = frames(structure, table, values)
        rotation = np.stack([chain.x_axes, chain.y_axes, chain.z_axes], axis=-1)[..., 1:, :, :]
        height = chain.origins[..., 1:, 2] + np.einsum("...nj,nj->...n", rotation[..., 2, :], com)
        return np.asarray(GRAVITY_M_S2 * height @ mass)

    eps = 1e-6
    steps = np.eye(6)[:, None, :] * eps
    slope = (potential(q + steps) - potential(q - steps)).T / (2 * eps)
    loads = joint_torques(structure, table, q, mass, com)
    np.testing.assert_allclose(loads, -slope, atol=1e-7)
    np.testing.assert_allclose(link_torques(structure, table, q, mass, com).sum(axis=2), loads,
                               atol=1e-12)
