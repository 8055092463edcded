"""Every file in models/ loads; every MJCF steps without a MuJoCo warning."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from twin.kinematics import frames
from twin.robot import load_robot
from twin.sim import load_scenario
from twin.synthetic import random_poses

MODELS = Path(__file__).parents[1] / "models"
ROBOT_FILES = sorted(MODELS.rglob("*.toml"))
MJCF_FILES = sorted(MODELS.rglob("*.xml"))
PAPER = Path(__file__).parents[1] / "scenarios" / "paper_irb120.toml"


def test_every_file_in_models_is_checked() -> None:
    """models/ holds only robot TOML, MJCF and READMEs, and the IRB 120 is among them."""
    others = [p for p in MODELS.rglob("*") if p.is_file()
              and p.suffix not in (".toml", ".xml") and p.name != "README.md"]
    assert others == []
    assert MODELS / "irb120.toml" in ROBOT_FILES
    assert {MODELS / "irb120" / "irb120.xml", MODELS / "irb120" / "scene.xml"} <= set(MJCF_FILES)


@pytest.mark.parametrize("path", ROBOT_FILES, ids=lambda p: p.name)
def test_robot_files_load(path: Path) -> None:
    """Each robot model file validates."""
    assert load_robot(path).n_joints == 6


@pytest.mark.parametrize("path", MJCF_FILES, ids=lambda p: p.name)
def test_mjcf_steps_without_warnings(path: Path) -> None:
    """Each MJCF compiles and steps 1 s from its home pose with no simulator warning."""
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    if model.nu:
        data.ctrl[:] = 0.0
    mujoco.mj_step(model, data, nstep=round(1.0 / model.opt.timestep))
    warnings = {mujoco.mjtWarning(i).name: w.number for i, w in enumerate(data.warning)
                if w.number}
    assert warnings == {}
    assert np.all(np.isfinite(data.qpos))


def test_irb120_mjcf_is_the_builders_model() -> None:
    """irb120.xml is what the builder makes of models/irb120.toml with the paper scenario's
    port and servos: its flange equals the core's FK to 1e-9 m, its links' centres of mass the
    model file's (in each link's D-H frame) to 1e-6 m, and its port, stiffness and masses are
    the scenario's and the model file's."""
    scenario = load_scenario(PAPER)
    robot = scenario.robot
    model = mujoco.MjModel.from_xml_path(str(MODELS / "irb120" / "irb120.xml"))
    data = mujoco.MjData(model)
    q = random_poses(robot, 200, np.random.default_rng(0))
    site = model.site("flange").id
    core = robot.flange_transforms(q)
    chain = frames(robot.structure, robot.dh, q)
    assert robot.com_m is not None
    rotation = np.stack([chain.x_axes, chain.y_axes, chain.z_axes], axis=-1)[:, 1:]
    centres = chain.origins[:, 1:] + np.einsum("mnij,nj->mni", rotation, robot.com_m)
    for pose, expected, com in zip(q, core, centres, strict=True):
        data.qpos[:] = pose
        mujoco.mj_kinematics(model, data)
        # The file keeps 6 significant digits of the inertial's position.
        assert np.allclose(data.xipos[1:], com, rtol=0, atol=1e-6)
        assert np.allclose(data.site_xpos[site], expected[:3, 3], rtol=0, atol=1e-9)
        assert np.allclose(data.site_xmat[site].reshape(3, 3), expected[:3, :3], rtol=0,
                           atol=1e-9)
    assert np.allclose(model.site_pos[model.site("port").id], scenario.port_m)
    assert scenario.physics.stiffness_nm_per_rad is not None
    assert np.allclose(model.actuator_gainprm[:6, 0], scenario.physics.stiffness_nm_per_rad)
    assert robot.mass_kg is not None
    assert np.allclose(model.body_mass[1:], robot.mass_kg, rtol=1e-5)
    assert model.tendon("cable").id == 0
