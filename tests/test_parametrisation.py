"""Joint axes to a parameter table: the choice per joint and the exact conversion."""

from __future__ import annotations

import numpy as np
import pytest

from twin.choices import MAX_JOINTS
from twin.geometry.kinematics import (
    JOINT_TYPES,
    Structure,
    fixed_transforms,
    flange_transform,
    rigid_transform,
)
from twin.geometry.parametrisation import (
    PARALLEL_THRESHOLD_DEG,
    axis_angles_deg,
    chain_flange,
    choose,
    convert,
    resolve,
)
from twin.io.robot_file import default_robot

IRB120_DH = np.array([[0.0, 0.27, 0.07, 0.0, 0.0, 0.0],
                      [0.29, 0.0, 0.0, 0.302, 0.0, 0.072],
                      np.deg2rad([-90.0, 0.0, -90.0, 90.0, -90.0, 0.0]),
                      np.deg2rad([0.0, -90.0, 0.0, 0.0, 0.0, 0.0])])


def _random_chain(rng: np.random.Generator, n: int, parallel_pairs: int = 0) -> np.ndarray:
    """Fixed transforms T_0..T_n with random origins and axes; ``parallel_pairs`` joints
    followed by an exactly parallel axis (a shift only, no turn off z)."""
    fixed = []
    for i in range(n + 1):
        rpy = rng.uniform(-np.pi, np.pi, 3)
        if 0 < i < n and i <= parallel_pairs:
            rpy[:2] = 0.0  # joint i + 1's axis parallel to joint i's
        fixed.append(rigid_transform(rng.uniform(-0.3, 0.3, 3), rpy))
    return np.stack(fixed)


def _assert_same_chain(fixed: np.ndarray, structure: Structure, table: np.ndarray,
                       atol: float = 1e-12) -> None:
    q = np.random.default_rng(7).uniform(-np.pi, np.pi, (500, structure.n_joints))
    np.testing.assert_allclose(flange_transform(structure, table, q),
                               chain_flange(fixed, q, structure.joint_types), rtol=0.0, atol=atol)


@pytest.mark.parametrize("request_", ["dh", "mdh", "auto", "hayati-where-parallel"])
@pytest.mark.parametrize("seed", range(8))
def test_conversion_keeps_the_forward_kinematics(request_: str, seed: int) -> None:
    """Random 4- to 9-joint chains, some with parallel consecutive axes and (odd seeds)
    prismatic joints, converted to each parametrisation have the source's flange pose to 1e-12
    over 500 random poses (a prismatic joint's q in m)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(4, MAX_JOINTS + 1))
    fixed = _random_chain(rng, n, parallel_pairs=seed % 3)
    types = tuple(rng.choice(JOINT_TYPES, n)) if seed % 2 else ()
    wanted = choose(fixed) if request_ == "hayati-where-parallel" else request_
    structure, table = convert(fixed, wanted, types)
    assert structure.n_joints == n
    assert structure.joint_types == (types or ("revolute",) * n)
    _assert_same_chain(fixed, structure, table)


def test_irb120_tables_are_the_paper_and_craig() -> None:
    """The IRB 120's chain converted back to standard D-H is the paper's table with bare ends;
    auto changes only joint 2 (axes 2 and 3 parallel) into a Hayati joint with β2 = 0; modified
    D-H shifts a and α one joint down (Craig)."""
    robot = default_robot()
    fixed = fixed_transforms(robot.structure, robot.dh)
    dh, dh_table = convert(fixed, "dh")
    assert dh.parametrisation == ("dh",) * 6
    np.testing.assert_allclose([dh.base, dh.tool], [np.eye(4)] * 2, rtol=0.0, atol=1e-15)
    np.testing.assert_allclose(dh_table, IRB120_DH, rtol=0.0, atol=1e-15)
    auto, auto_table = convert(fixed, "auto")
    assert auto.parametrisation == ("dh", "hayati", "dh", "dh", "dh", "dh")
    np.testing.assert_allclose(auto_table, IRB120_DH, rtol=0.0, atol=1e-15)
    assert auto.parameter_names[7] == "beta2"
    mdh, mdh_table = convert(fixed, "mdh")
    np.testing.assert_allclose(mdh_table[[0, 2], 1:], IRB120_DH[[0, 2], :-1], atol=1e-15)
    np.testing.assert_allclose(mdh_table[[1, 3]], IRB120_DH[[1, 3]], atol=1e-15)
    np.testing.assert_allclose(mdh.base, np.eye(4), atol=1e-15)


def _tilted_irb120(tilt_rad: float) -> np.ndarray:
    """The IRB 120's chain with axis 3 tilted by ``tilt_rad`` towards the upper arm."""
    robot = default_robot()
    fixed = fixed_transforms(robot.structure, robot.dh)
    fixed[2] = fixed[2] @ rigid_transform(np.zeros(3), [0.0, tilt_rad, 0.0])
    fixed[3] = rigid_transform(np.zeros(3), [0.0, -tilt_rad, 0.0]) @ fixed[3]
    return fixed


@pytest.mark.parametrize("tilt_rad", [1e-4, 1e-6])
def test_a_tilt_is_a_small_beta_where_dh_needs_kilometres(tilt_rad: float) -> None:
    """Tilt the IRB 120's axis 3 by 0.1 mrad or 1 µrad towards the upper arm: standard D-H
    moves the common normal of axes 2 and 3 some 0.27 m / tilt along the axes (d2, d3 of
    2.7 km or 270 km, huge and opposite); the Hayati joint takes the tilt as β2 with every
    length as before — Hayati's reason. Both reproduce the chain."""
    tilted = _tilted_irb120(tilt_rad)
    structure, dh_table = convert(tilted, "dh")
    assert abs(dh_table[1, 1]) == pytest.approx(0.27 / tilt_rad, rel=1e-3)
    assert abs(dh_table[1, 1] + dh_table[1, 2]) < 1.0
    _assert_same_chain(tilted, structure, dh_table, atol=1e-9)
    structure, hayati = convert(tilted, "auto")
    assert structure.parametrisation[1] == "hayati"
    assert hayati[1, 1] == pytest.approx(tilt_rad, rel=1e-6)  # β2
    np.testing.assert_allclose(hayati[0], IRB120_DH[0], atol=1e-9)
    _assert_same_chain(tilted, structure, hayati)


def test_choice_follows_the_stated_threshold() -> None:
    """Hayati where the next axis is within the threshold of parallel (or antiparallel), D-H
    otherwise and on the last joint."""
    base = np.stack([rigid_transform([0.0, 0.0, 0.3], [0.0, 0.0, 0.0])] * 5)
    just_under, just_over = PARALLEL_THRESHOLD_DEG - 0.5, PARALLEL_THRESHOLD_DEG + 0.5
    base[1] = rigid_transform([0.3, 0.0, 0.0], np.deg2rad([just_under, 0.0, 0.0]))
    base[2] = rigid_transform([0.3, 0.0, 0.0], np.deg2rad([180.0 - just_under, 0.0, 0.0]))
    base[3] = rigid_transform([0.3, 0.0, 0.0], np.deg2rad([just_over, 0.0, 0.0]))
    np.testing.assert_allclose(axis_angles_deg(base), [just_under, just_under, just_over])
    assert choose(base) == ("hayati", "hayati", "dh", "dh")


def test_requests_that_cannot_hold_the_chain_are_refused() -> None:
    """Modified D-H mixed with other joints, a list of the wrong length, an unknown name, and
    a Hayati joint between perpendicular axes are refused, each saying why."""
    fixed = fixed_transforms(default_robot().structure, default_robot().dh)
    with pytest.raises(ValueError, match="whole chain"):
        resolve(["mdh", "dh", "dh", "dh", "dh", "dh"], fixed)
    with pytest.raises(ValueError, match="expected 6"):
        resolve(["dh"] * 5, fixed)
    with pytest.raises(ValueError, match="one of dh, mdh, hayati, auto"):
        resolve("craig", fixed)
    with pytest.raises(ValueError, match="within 60° of parallel"):
        convert(fixed, ["hayati", "dh", "dh", "dh", "dh", "dh"])
