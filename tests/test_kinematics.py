"""Forward kinematics and its analytic Jacobian."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from twin.kinematics import chain, flange_position, flange_position_jacobian, flange_transform
from twin.robot import RobotModel
from twin.synthetic import random_poses


def test_irb120_flange_at_home(irb120: RobotModel) -> None:
    """At q = 0 the IRB 120 flange centre is at (374, 0, 630) mm (method-notes §1)."""
    p = flange_position(irb120.dh, np.zeros((1, 6)))
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
    np.testing.assert_allclose(flange_transform(irb120.dh, q), expected, atol=1e-14)


def test_batched_tables_equal_one_by_one(irb120: RobotModel) -> None:
    """K tables × m poses in one call give what K separate calls give."""
    rng = np.random.default_rng(1)
    q = random_poses(irb120, 20, rng)
    tables = irb120.dh + rng.normal(scale=1e-3, size=(7, 4, 6))
    batched = flange_position(tables, q)
    assert batched.shape == (7, 20, 3)
    for k in range(7):
        np.testing.assert_array_equal(batched[k], flange_position(tables[k], q))


def test_chain_ends_at_flange(irb120: RobotModel) -> None:
    """The last frame of the chain is the flange, the first the base."""
    q = random_poses(irb120, 5, np.random.default_rng(2))
    frames = chain(irb120.dh, q)
    assert frames.origins.shape == (5, 7, 3)
    np.testing.assert_allclose(frames.origins[:, -1], flange_position(irb120.dh, q), atol=1e-15)
    np.testing.assert_array_equal(frames.origins[:, 0], 0.0)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_position_jacobian_matches_finite_differences(seed: int) -> None:
    """∂P/∂(a, d, α, θ) equals central differences at random tables and poses."""
    rng = np.random.default_rng(seed)
    from twin.robot import default_robot

    robot = default_robot()
    dh = robot.dh + rng.normal(scale=2e-3, size=(4, 6))
    q = random_poses(robot, 4, rng)
    _, jacobian = flange_position_jacobian(dh, q)
    eps = 1e-6
    steps = np.eye(24).reshape(24, 4, 6) * eps
    numeric = (flange_position(dh + steps, q) - flange_position(dh - steps, q)) / (2 * eps)
    np.testing.assert_allclose(jacobian, np.moveaxis(numeric, 0, -1), atol=1e-8)


def test_batched_poses_with_one_table(irb120: RobotModel) -> None:
    """Poses with their own batch dimensions (k, m, n) work with one table, and tables (k, 4, n)
    pair with pose sets (k, m, n) one to one."""
    rng = np.random.default_rng(5)
    q = random_poses(irb120, 12, rng).reshape(3, 4, 6)
    tables = irb120.dh + rng.normal(scale=1e-3, size=(3, 4, 6))
    one_table = flange_position(irb120.dh, q)
    paired = flange_position(tables, q)
    assert one_table.shape == paired.shape == (3, 4, 3)
    for k in range(3):
        np.testing.assert_allclose(one_table[k], flange_position(irb120.dh, q[k]), atol=1e-15)
        np.testing.assert_allclose(paired[k], flange_position(tables[k], q[k]), atol=1e-15)
