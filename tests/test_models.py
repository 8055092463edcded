"""Every model in models/ loads and steps in MuJoCo without a warning, and every shipped MJCF is
what the twin's builder makes of its robot."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from twin.choices import MAX_JOINTS, MIN_JOINTS
from twin.geometry.kinematics import frames
from twin.io.robot_file import load_robot
from twin.robot import random_poses
from twin.scenario import load_scenario
from twin.sim.builder import build_spec

MODELS = Path(__file__).parents[1] / "models"
SCENARIOS = Path(__file__).parents[1] / "scenarios"
ROBOT_FILES = sorted([*MODELS.rglob("*.toml"), *MODELS.rglob("*.urdf")])
MJCF_FILES = sorted(MODELS.rglob("*.xml"))
BUILT = {"irb120": "paper_irb120", "ur5e": "geometric_ur5e", "fr3": "geometric_fr3",
         "scara4": "geometric_scara4", "fr3_torso": "geometric_torso"}
"""Each models/<robot>/<robot>.xml and the scenario whose port (and servos) it was made with."""


def test_every_file_in_models_is_checked() -> None:
    """models/ holds only robot TOML, URDF, MJCF and READMEs; the IRB 120, a UR5e, a 7-axis
    arm, a 7-axis arm on a prismatic torso lift and a 4-axis chain are among them, each in its
    folder with a README."""
    others = [p for p in MODELS.rglob("*") if p.is_file()
              and p.suffix not in (".toml", ".urdf", ".xml") and p.name != "README.md"]
    assert others == []
    assert MODELS / "irb120.toml" in ROBOT_FILES
    assert {MODELS / "irb120" / "irb120.xml", MODELS / "irb120" / "scene.xml"} <= set(MJCF_FILES)
    assert {len(load_robot(path).joint_names) for path in ROBOT_FILES} >= {4, 6, 7, 8}
    assert any(load_robot(path).prismatic.any() for path in ROBOT_FILES)
    for name in BUILT:
        assert (MODELS / name / "README.md").is_file()
        assert (MODELS / name / "scene.xml") in MJCF_FILES


def _assert_no_warnings(data: mujoco.MjData) -> None:
    warnings = {mujoco.mjtWarning(i).name: w.number for i, w in enumerate(data.warning)
                if w.number}
    assert warnings == {}
    assert np.all(np.isfinite(data.qpos))


@pytest.mark.parametrize("path", ROBOT_FILES, ids=lambda p: p.relative_to(MODELS).as_posix())
def test_robot_files_load_and_step(path: Path) -> None:
    """Each robot file (model TOML or URDF) validates with 4 to 9 joints, and the twin built
    from it (floor, port, cable) compiles and steps 1 s from its home pose without a MuJoCo
    warning."""
    robot = load_robot(path)
    assert MIN_JOINTS <= robot.n_joints <= MAX_JOINTS
    model = build_spec(robot, [0.6, -0.4, 0.1], floor=True).compile()
    data = mujoco.MjData(model)
    data.qpos[:] = np.clip(0.0, robot.lower_rad, robot.upper_rad)
    mujoco.mj_step(model, data, nstep=round(1.0 / model.opt.timestep))
    _assert_no_warnings(data)


@pytest.mark.parametrize("path", MJCF_FILES, ids=lambda p: p.relative_to(MODELS).as_posix())
def test_mjcf_steps_without_warnings(path: Path) -> None:
    """Each MJCF compiles and steps 1 s from its home pose with no simulator warning."""
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    if model.nu:
        data.ctrl[:] = 0.0
    mujoco.mj_step(model, data, nstep=round(1.0 / model.opt.timestep))
    _assert_no_warnings(data)


@pytest.mark.parametrize("name", list(BUILT))
def test_mjcf_is_the_builders_model(name: str) -> None:
    """models/<robot>/<robot>.xml is what the builder makes of the robot with its scenario's
    port (and, for the IRB 120, the paper scenario's servos): its flange equals the core's FK to
    1e-9 m, its port is the scenario's, its link masses the model's, and, where the model gives
    them, its links' centres of mass the model file's (in each link frame) to 1e-6 m."""
    scenario = load_scenario(SCENARIOS / f"{BUILT[name]}.toml")
    robot = scenario.robot
    model = mujoco.MjModel.from_xml_path(str(MODELS / name / f"{name}.xml"))
    data = mujoco.MjData(model)
    q = random_poses(robot, 200, np.random.default_rng(0))
    site = model.site("flange").id
    core = robot.flange_transforms(q)
    chain = frames(robot.structure, robot.dh, q)
    rotation = np.stack([chain.x_axes, chain.y_axes, chain.z_axes], axis=-1)[:, 1:]
    centres = None if robot.com_m is None else \
        chain.origins[:, 1:] + np.einsum("mnij,nj->mni", rotation, robot.com_m)
    for k, (pose, expected) in enumerate(zip(q, core, strict=True)):
        data.qpos[:] = pose
        mujoco.mj_kinematics(model, data)
        if centres is not None:
            # The file keeps 6 significant digits of the inertial's position.
            assert np.allclose(data.xipos[1:], centres[k], rtol=0, atol=1e-6)
        assert np.allclose(data.site_xpos[site], expected[:3, 3], rtol=0, atol=1e-9)
        assert np.allclose(data.site_xmat[site].reshape(3, 3), expected[:3, :3], rtol=0,
                           atol=1e-9)
    assert np.allclose(model.site_pos[model.site("port").id], scenario.port_m)
    stiffness = scenario.physics.stiffness_nm_per_rad
    if stiffness is not None:
        assert np.allclose(model.actuator_gainprm[:robot.n_joints, 0], stiffness)
    assert robot.mass_kg is not None
    np.testing.assert_allclose(model.body_mass[1:], robot.mass_kg, rtol=1e-5)
    assert model.tendon("cable").id == 0
