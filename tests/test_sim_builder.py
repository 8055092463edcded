"""The MjSpec builder: the MuJoCo flange and cable agree with the core's D-H model."""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np
import pytest

from twin.geometry.kinematics import Structure
from twin.io.robot_file import default_robot, load_robot
from twin.kinds.length import cable_length
from twin.robot import RobotModel, random_poses
from twin.scenario import Physics
from twin.sim import build_spec, builder
from twin.sim.builder import compile_model
from twin.unknowns.dh import BOUND_M as DH_BOUND_M
from twin.unknowns.dh import BOUND_RAD as DH_BOUND_RAD

PORT_M = np.array([0.6, -0.4, 0.1])
MODELS = Path(__file__).resolve().parents[1] / "models"


def _general_arm(rng: np.random.Generator) -> RobotModel:
    """A 6-joint arm with every D-H parameter nonzero, no masses or radii."""
    dh = np.vstack([
        rng.uniform(0.05, 0.3, 6), rng.uniform(-0.2, 0.2, 6),
        rng.uniform(-np.pi, np.pi, 6), rng.uniform(-np.pi, np.pi, 6),
    ])
    return RobotModel("general", dh, np.full(6, -3.0), np.full(6, 3.0))


def _perturbed_irb120(rng: np.random.Generator) -> RobotModel:
    bound = np.repeat([DH_BOUND_M, DH_BOUND_M, DH_BOUND_RAD, DH_BOUND_RAD], 6)
    return default_robot().perturbed(rng.uniform(-bound, bound))


def _mujoco_flange(robot: RobotModel, q_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Flange poses and cable lengths from a model compiled straight from the spec."""
    model = build_spec(robot, PORT_M).compile()
    data = mujoco.MjData(model)
    site, cable = model.site("flange").id, model.tendon("cable").id
    poses = np.zeros((len(q_rad), 4, 4))
    lengths = np.empty(len(q_rad))
    for row, q in enumerate(q_rad):
        data.qpos[:] = q
        mujoco.mj_fwdPosition(model, data)
        poses[row, :3, :3] = data.site_xmat[site].reshape(3, 3)
        poses[row, :3, 3] = data.site_xpos[site]
        poses[row, 3, 3] = 1.0
        lengths[row] = data.ten_length[cable]
    return poses, lengths


def _other_arm(path: str, request: str | None = None) -> Callable[[np.random.Generator],
                                                                  RobotModel]:
    """A shipped model (URDF or TOML), optionally re-expressed, perturbed in its own units."""
    def make(rng: np.random.Generator) -> RobotModel:
        robot = load_robot(MODELS / path)
        if request is not None:
            robot = robot.reparametrised(request)
        scale = np.where(robot.is_length, 2e-3, 0.02)
        return robot.perturbed(rng.uniform(-1.0, 1.0, scale.shape) * scale)
    return make


def _sliding_arm(rng: np.random.Generator) -> RobotModel:
    """A 9-joint chain of standard D-H and Hayati joints, two prismatic joints (a gantry's
    x and y) then seven revolute ones, base and tool transforms, every entry nonzero."""
    kinds = ("dh", "hayati", "dh", "dh", "hayati", "dh", "dh", "dh", "dh")
    types = ("prismatic", "prismatic") + ("revolute",) * 7
    dh = np.vstack([rng.uniform(0.05, 0.3, 9), rng.uniform(-0.2, 0.2, 9),
                    rng.uniform(-np.pi, np.pi, 9), rng.uniform(-np.pi, np.pi, 9)])
    base, tool = np.eye(4), np.eye(4)
    base[:3, 3], tool[:3, 3] = rng.normal(scale=0.1, size=3), rng.normal(scale=0.1, size=3)
    structure = Structure(kinds, base=base, tool=tool, joint_types=types)
    lower = np.r_[-0.5, -0.5, np.full(7, -3.0)]
    return RobotModel("gantry", dh, lower, -lower, structure=structure)


def _sub_micrometre_links(rng: np.random.Generator) -> RobotModel:
    """The IRB 120 with every zero length entry made 50 nm (an identified table's, its
    nominal 0 identified as a few nanometres): MuJoCo refuses a capsule shorter than 1e-7 m."""
    robot = default_robot()
    return robot.perturbed(np.where(robot.is_length & (np.abs(robot.dh) < 1e-12), 5e-8, 0.0))


ARMS = [
    lambda rng: default_robot(), _perturbed_irb120, _general_arm, _sub_micrometre_links,
    _other_arm("irb120.toml", "mdh"), _other_arm("ur5e/ur5e.urdf"), _other_arm("fr3/fr3.urdf"),
    _other_arm("scara4/scara4.toml"), _other_arm("fr3_torso/fr3_torso.urdf"),
    _other_arm("fr3_torso/fr3_torso.urdf", "dh"), _sliding_arm,
]


@pytest.mark.parametrize("make", ARMS, ids=[
    "irb120", "irb120 perturbed", "general", "irb120 50 nm links", "irb120 mdh", "ur5e auto",
    "fr3 7 axes", "scara 4 axes", "fr3 on a torso lift", "fr3 on a torso lift dh",
    "gantry 9 joints"])
def test_flange_site_and_cable_equal_core_model(make) -> None:
    """Over 1000 random poses the flange site's position (1e-9 m) and orientation, and the
    tendon length (1e-9 m), equal the core's FK and cable model, for the nominal IRB 120, an
    IRB 120 perturbed up to the search bounds, a general arm, and perturbed arms of 4 to 9
    joints in modified D-H, Hayati and standard D-H with base and tool transforms, prismatic
    joints among them (MuJoCo slides, q in m)."""
    rng = np.random.default_rng(11)
    robot = make(rng)
    q = random_poses(robot, 1000, rng)
    poses, lengths = _mujoco_flange(robot, q)
    core = robot.flange_transforms(q)
    assert np.max(np.abs(poses[:, :3, 3] - core[:, :3, 3])) < 1e-9
    assert np.max(np.abs(poses[:, :3, :3] - core[:, :3, :3])) < 1e-9
    assert np.max(np.abs(lengths - cable_length(robot.structure, robot.dh, q, PORT_M))) < 1e-9


def test_links_sized_and_weighted_from_model_file() -> None:
    """Each link's geoms have the model file's radius and together its mass; the port site sits
    at the port; without a port there is no cable."""
    robot = default_robot()
    model = build_spec(robot, PORT_M).compile()
    assert robot.mass_kg is not None and robot.radius_m is not None
    for i in range(6):
        body = model.body(f"link{i + 1}").id
        geoms = np.flatnonzero(model.geom_bodyid == body)
        assert np.allclose(model.geom_size[geoms, 0], robot.radius_m[i])
        assert model.body_mass[body] == pytest.approx(robot.mass_kg[i], rel=1e-9)
    assert np.allclose(model.site_pos[model.site("port").id], PORT_M)
    bare = build_spec(robot).compile()
    assert bare.ntendon == 0 and bare.nu == 0


def test_compliant_spec_has_servos_and_tension() -> None:
    """With compliant physics the model has one position servo per joint of the given stiffness
    and a tendon actuator on the cable."""
    stiffness = np.array([1e5, 2e5, 3e5, 4e4, 5e4, 6e4])
    model = build_spec(default_robot(), PORT_M, Physics(stiffness, True, 5.0)).compile()
    assert model.nu == 7
    assert np.allclose(model.actuator_gainprm[:6, 0], stiffness)
    assert np.allclose(model.actuator_biasprm[:6, 1], -stiffness)
    tension = model.actuator("tension")
    assert tension.trntype == mujoco.mjtTrn.mjTRN_TENDON
    assert tension.gear[0] == -1.0


def _model_arrays(model: mujoco.MjModel) -> dict[str, np.ndarray]:
    return {name: np.array(value) for name in dir(model) if not name.startswith("_")
            and isinstance(value := getattr(model, name), np.ndarray)}


def test_compiled_from_a_kept_skeleton_equals_a_built_model(monkeypatch) -> None:
    """compile_model gives build_spec's model, every array to the bit, for each arm in turn:
    alone; perturbed with a port and an eyelet, then perturbed again (the skeleton reused);
    with other masses and servos, twice (reused); with other capsule radii and joint limits
    (a skeleton of its own: the one kept would size and limit them wrongly); with every length
    zero (spheres: a layout of its own)."""
    monkeypatch.setattr(builder, "TEMPLATES", 1000)
    rng = np.random.default_rng(5)
    eyelet, stiff = [0.01, -0.02, 0.03], Physics(np.full(1, 1.0), True, 5.0)
    for make in ARMS:
        monkeypatch.setattr(builder, "_templates", OrderedDict())
        robot = make(rng)
        n = robot.n_joints
        servos = replace(stiff, stiffness_nm_per_rad=np.full(n, 1e5))
        heavier = [None if robot.mass_kg is None else robot.mass_kg * rng.uniform(0.8, 1.2, n)
                   for _ in range(2)]
        variants = [  # arm, port, physics, attachment, whether a skeleton is kept for it
            (robot, None, Physics(), None, True),
            (_perturbed(robot, rng), PORT_M, Physics(), eyelet, True),
            (_perturbed(robot, rng), PORT_M, Physics(), eyelet, False),
            (replace(_perturbed(robot, rng), mass_kg=heavier[0]), PORT_M, servos, None, True),
            (replace(_perturbed(robot, rng), mass_kg=heavier[1]), PORT_M, servos, None, False),
            (replace(robot, radius_m=np.full(n, 0.031), lower_rad=robot.lower_rad * 0.9),
             PORT_M, Physics(), eyelet, True),
            # every length zero: spheres, not capsules (another layout)
            (replace(robot, dh=np.where(robot.is_length, 0.0, robot.dh)), PORT_M, Physics(),
             eyelet, True),
        ]
        for arm, port, physics, attachment, new in variants:
            kept = len(builder._templates)
            model = compile_model(arm, port, physics, floor=True, attachment_m=attachment)
            built = build_spec(arm, port, physics, floor=True, attachment_m=attachment).compile()
            expected, found = _model_arrays(built), _model_arrays(model)
            assert found.keys() == expected.keys()
            for name, value in expected.items():
                assert np.array_equal(found[name], value, equal_nan=True), (arm.name, name)
            assert len(builder._templates) == kept + new, (arm.name, new)


def _perturbed(robot: RobotModel, rng: np.random.Generator) -> RobotModel:
    return robot.perturbed(rng.uniform(-1.0, 1.0, robot.dh.size)
                           * np.where(robot.is_length, 1e-3, 0.01).ravel())
