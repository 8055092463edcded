"""The measurement model: residuals of every unknown group and their analytic Jacobian."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from twin.calibration.settings import CalibrationSettings
from twin.calibration.setup import make_model
from twin.dataset import Measurements, approach_directions
from twin.errors import InputError, UnknownChoiceError
from twin.geometry.kinematics import flange_transform
from twin.kinds.length import cable_length, length_measurements
from twin.model import Model
from twin.rig import Rig
from twin.robot import RobotModel
from twin.unknowns import GROUPS, make_groups

ALL_RIG_UNKNOWNS = [(False, False), (True, False), (False, True), (True, True)]


def test_length_is_distance_port_to_flange(irb120: RobotModel, port_m: np.ndarray) -> None:
    """ℓ = ‖P − P_E‖ (paper eq. 1) at the home pose."""
    q = np.zeros((1, 6))
    expected = np.linalg.norm(np.array([0.374, 0.0, 0.630]) - port_m)
    assert cable_length(irb120.structure, irb120.dh, q, port_m)[0] == pytest.approx(
        expected, abs=1e-12)


def _numeric_jacobian(model: Model, x: np.ndarray, data: Measurements) -> np.ndarray:
    eps = 1e-6
    steps = np.eye(model.n_params) * eps
    return (model.residuals(x + steps, data) - model.residuals(x - steps, data)).T / (2 * eps)


@pytest.mark.parametrize(("port", "offset"), ALL_RIG_UNKNOWNS)
def test_jacobian_matches_finite_differences(
    irb120: RobotModel, measurements: Measurements, port_m: np.ndarray, port: bool, offset: bool
) -> None:
    """∂r/∂x equals central differences for every unknown layout."""
    model = make_model(irb120, Rig.cable(port_m),
                       settings=CalibrationSettings(estimate=(*(('port',) if port else ()),
                                                              *(('offset',) if offset else ()))))
    x = np.random.default_rng(3).normal(scale=1e-3, size=model.n_params)
    data = measurements.subset(np.arange(15))
    r, jacobian = model.jacobian(x, data)
    np.testing.assert_allclose(r, model.residuals(x, data), atol=1e-15)
    np.testing.assert_allclose(jacobian, _numeric_jacobian(model, x, data), atol=1e-8)


def test_several_ports_and_an_attachment(irb120: RobotModel, measurements: Measurements) -> None:
    """Rows from three ports, the cable hooked off the flange centre: the lengths are the
    distances to each row's port, and the Jacobian (ports estimated) matches differences."""
    rng = np.random.default_rng(8)
    ports = np.array([[0.6, -0.4, 0.1], [0.5, 0.5, 0.0], [-0.3, 0.6, 0.2]])
    attachment = np.array([0.025, -0.015, 0.04])
    rig = Rig(ports, ("front", "left", "back"), attachment)
    which = rng.integers(0, 3, len(measurements))
    model = make_model(irb120, rig, settings=CalibrationSettings(estimate=('port', 'offset')))
    assert model.names[24:27] == ("front_x", "front_y", "front_z")
    data = model.measure(np.zeros(model.n_params), measurements.q_rad, port=which)
    flange = irb120.flange_transforms(measurements.q_rad)
    point = flange[:, :3, :3] @ attachment + flange[:, :3, 3]
    np.testing.assert_allclose(data.value("length_m"), np.linalg.norm(point - ports[which], axis=1),
                               atol=1e-15)
    x = rng.normal(scale=1e-3, size=model.n_params)
    subset = data.subset(np.arange(20))
    _, jacobian = model.jacobian(x, subset)
    np.testing.assert_allclose(jacobian, _numeric_jacobian(model, x, subset), atol=1e-8)


def test_unknown_layout(irb120: RobotModel, port_m: np.ndarray) -> None:
    """Names and bounds follow eq. 7's order, then port, then offset; units per unknown."""
    model = make_model(irb120, Rig.cable(port_m), settings=CalibrationSettings(estimate=('port',
                                                                                         'offset')))
    assert model.n_params == 28
    assert model.names[:2] == ("a1", "a2") and model.names[-4:] == (
        "port_x", "port_y", "port_z", "offset")
    assert model.units[:12] == ("m",) * 12 and model.units[12:24] == ("rad",) * 12
    lower, upper = model.bounds()
    np.testing.assert_allclose(upper[:12], 5e-3)
    np.testing.assert_allclose(upper[12:24], np.deg2rad(8.0))
    np.testing.assert_array_equal(lower, -upper)
    assert list(GROUPS) == ["dh", "transmission", "backlash", "compliance", "link_compliance",
                            "thermal", "port", "offset", "scale", "attachment", "base",
                            "points", "tool", "planes"]


def test_batched_residuals(
    irb120: RobotModel, measurements: Measurements, port_m: np.ndarray
) -> None:
    """Residuals of K candidates in one call equal K single calls."""
    model = make_model(irb120, Rig.cable(port_m), settings=CalibrationSettings(estimate=('port',
                                                                                         'offset')))
    x = np.random.default_rng(4).normal(scale=1e-3, size=(5, model.n_params))
    batched = model.residuals(x, measurements)
    for k in range(5):
        np.testing.assert_allclose(batched[k], model.residuals(x[k], measurements), atol=1e-15)


@pytest.mark.parametrize(("errors", "estimate"), [(("dh",), ("port", "offset", "scale")),
                                                (("dh", "thermal"), ()),
                                                (("dh", "transmission"), ("attachment",))])
@pytest.mark.parametrize("kernel", ["numpy", "numba"], indirect=True)
def test_residuals_from_the_anchors_are_the_kinds_of_the_points(
    irb120: RobotModel, measurements: Measurements, port_m: np.ndarray,
    errors: tuple[str, ...], estimate: tuple[str, ...], kernel: str
) -> None:
    """A cable model's residuals, its lengths taken in one pass of the chain from the ports
    (:meth:`twin.kinds.base.Kind.ranges`), are the kind's residuals of the measured
    points bit for bit, for one x and a batch, on either kernel: an estimated port, offset and
    scale; a table per row (thermal growth); joints turned by the model and a point off the
    flange."""
    data = measurements
    if "thermal" in errors:
        rng = np.random.default_rng(2)
        data = replace(data, values={**data.values,
                                     "temperature_c": rng.uniform(20.0, 30.0, len(data))})
    rig = Rig(port_m[None], ("port",), np.array([0.01, -0.02, 0.03]), temperature_ref_c=23.0)
    model = make_model(irb120, rig, settings=CalibrationSettings(errors=errors,
                                                                 estimate=estimate))
    x = np.random.default_rng(9).normal(scale=1e-4, size=(4, model.n_params))
    for at in (x, x[1]):
        kind = model.kind.residuals(model.measured(at, data), model._measurement_values(at),
                                    data, model.rig)
        np.testing.assert_array_equal(model.residuals(at, data), kind)


def test_offset_adds_to_every_length(
    irb120: RobotModel, measurements: Measurements, port_m: np.ndarray
) -> None:
    """The offset unknown shifts every model length by its value."""
    model = make_model(irb120, Rig.cable(port_m),
                       settings=CalibrationSettings(estimate=('offset',)))
    x = np.zeros(25)
    x[-1] = 0.002
    plain = np.linalg.norm(irb120.flange_positions(measurements.q_rad) - port_m, axis=-1)
    np.testing.assert_allclose(model.residuals(x, measurements) + measurements.value("length_m"),
                               plain + 0.002, atol=1e-15)


def test_flange_jacobian_sees_the_table_not_the_rig(
    irb120: RobotModel, measurements: Measurements, port_m: np.ndarray
) -> None:
    """The flange moves with the D-H errors as differences say, and not with the port."""
    model = make_model(irb120, Rig.cable(port_m), settings=CalibrationSettings(estimate=('port',)))
    x = np.random.default_rng(9).normal(scale=1e-3, size=model.n_params)
    data = measurements.subset(np.arange(6))
    jacobian = model.flange_jacobian(x, data)
    eps = 1e-6
    steps = np.eye(model.n_params) * eps
    numeric = (model.flange_positions(x + steps, data)
               - model.flange_positions(x - steps, data)) / (2 * eps)
    np.testing.assert_allclose(jacobian, np.moveaxis(numeric, 0, -1), atol=1e-8)
    np.testing.assert_array_equal(jacobian[..., model.slice("port")], 0.0)


def test_groups_must_fit_the_kind(irb120: RobotModel, port_m: np.ndarray) -> None:
    """Naming a group twice or one the measurement kind cannot read is refused."""
    rig = Rig.cable(port_m)
    with pytest.raises(UnknownChoiceError, match="error group 'nonsense', expected one of dh"):
        make_groups(["dh", "nonsense"], irb120, rig)
    model = make_model(irb120, rig)
    with pytest.raises(ValueError, match="twice"):
        Model(irb120, rig, model.kind, (*model.groups, *model.groups))


def test_rows_that_turn_the_flange_are_refused_with_poses(irb120: RobotModel) -> None:
    """A per-row change of the table's angles would turn the flange row by row, which 6-D poses
    read on one table: refused; the thermal growth (lengths alone) is taken."""
    thermal = make_model(irb120, Rig(temperature_ref_c=20.0), "pose",
                         CalibrationSettings(errors=("dh", "thermal"))).group("thermal")
    assert thermal.linear is not None
    turning = np.zeros_like(thermal.linear)
    turning[3 * irb120.n_joints] = 1.0  # θ1 grows with the temperature
    kind = make_model(irb120, Rig(), "pose").kind
    with pytest.raises(ValueError, match="thermal: not with 6-D poses"):
        Model(irb120, Rig(temperature_ref_c=20.0), kind, (replace(thermal, linear=turning),))


JOINT_GROUPS = ["transmission", "backlash", "compliance"]


def _assert_jacobians(model: Model, x: np.ndarray, data: Measurements) -> None:
    """∂r/∂x and ∂(flange)/∂x at x equal central differences; r is the residuals'."""
    r, jacobian = model.jacobian(x, data)
    np.testing.assert_allclose(r, model.residuals(x, data), atol=1e-15)
    np.testing.assert_allclose(jacobian, _numeric_jacobian(model, x, data), atol=1e-8)
    eps = 1e-6
    steps = np.eye(model.n_params) * eps
    numeric = (model.flange_positions(x + steps, data)
               - model.flange_positions(x - steps, data)) / (2 * eps)
    np.testing.assert_allclose(model.flange_jacobian(x, data), np.moveaxis(numeric, 0, -1),
                               atol=1e-8)


def _with_approach(data: Measurements) -> Measurements:
    return length_measurements(data.q_rad, data.value("length_m"),
                               approach=approach_directions(data.q_rad))


@pytest.mark.parametrize("group", [*JOINT_GROUPS, "link_compliance", "all"])
def test_joint_groups_jacobian_matches_finite_differences(
    irb120: RobotModel, measurements: Measurements, port_m: np.ndarray, group: str
) -> None:
    """Each joint-level group, alone and all together with the rig's unknowns and the cable
    pulling: ∂r/∂x and ∂(flange)/∂x equal central differences."""
    errors = ["dh", *(JOINT_GROUPS if group == "all" else [group])]
    rig = Rig.cable(port_m, [0.01, -0.02, 0.03], tension_n=5.0)
    estimate = ("port", "offset") if group == "all" else ()
    model = make_model(irb120, rig, settings=CalibrationSettings(errors=errors,
                                                                 estimate=estimate))
    x = np.random.default_rng(3).normal(scale=1e-3, size=model.n_params)
    x[model.slice(errors[-1])] *= 0.1 if "compliance" in errors[-1] else 1.0
    data = _with_approach(measurements.subset(np.arange(15)))
    _assert_jacobians(model, x, data)


def test_flange_rotations_are_the_walked_chains(
    irb120: RobotModel, measurements: Measurements, port_m: np.ndarray
) -> None:
    """The flange's orientation, with the joint groups moving the joints: the walked chain's
    base_R_flange at the model's table and joints, for one x and for a stack of them."""
    rig = Rig.cable(port_m, [0.01, -0.02, 0.03], tension_n=5.0)
    model = make_model(irb120, rig, settings=CalibrationSettings(errors=["dh", *JOINT_GROUPS]))
    rng = np.random.default_rng(4)
    xs = rng.normal(scale=1e-3, size=(3, model.n_params))
    data = _with_approach(measurements.subset(np.arange(25)))
    stacked = model.flange_rotations(xs, data)
    assert stacked.shape == (3, 25, 3, 3)
    for x, rotations in zip(xs, stacked, strict=True):
        walked = flange_transform(irb120.structure, model.table(x), model.joints(x, data))
        np.testing.assert_allclose(rotations, walked[..., :3, :3], rtol=0.0, atol=1e-14)
        np.testing.assert_allclose(model.flange_rotations(x, data), rotations, atol=1e-15)


def test_joint_groups_move_the_joints_as_stated(
    irb120: RobotModel, measurements: Measurements, port_m: np.ndarray
) -> None:
    """Transmission adds its harmonics of the recorded angle, backlash b·s, compliance c·τ:
    the model's joints equal those written out by hand."""
    rig = Rig.cable(port_m, tension_n=4.0)
    model = make_model(irb120, rig, settings=CalibrationSettings(errors=["dh", *JOINT_GROUPS]))
    data = _with_approach(measurements.subset(np.arange(10)))
    rng = np.random.default_rng(5)
    x = np.zeros(model.n_params)
    harmonic = rng.normal(scale=1e-3, size=(6, 4))
    backlash = rng.normal(scale=1e-3, size=6)
    compliance = rng.uniform(1e-6, 1e-4, size=6)
    x[model.slice("transmission")] = harmonic.ravel()
    x[model.slice("backlash")] = backlash
    x[model.slice("compliance")] = compliance
    q = data.q_rad
    from twin.unknowns.compliance import torques

    expected = (q + harmonic[:, 0] * np.sin(q) + harmonic[:, 1] * np.cos(q)
                + harmonic[:, 2] * np.sin(2 * q) + harmonic[:, 3] * np.cos(2 * q)
                + backlash * data.approach + compliance * torques(irb120, rig, data))
    np.testing.assert_allclose(model.joints(x, data), expected, atol=1e-15)


def test_joint_groups_need_what_they_read(
    irb120: RobotModel, measurements: Measurements, port_m: np.ndarray
) -> None:
    """Backlash needs the approach directions (a model's own poses get those of visiting them
    in order); compliance needs the links' masses and centres of mass."""
    model = make_model(irb120, Rig.cable(port_m), settings=CalibrationSettings(errors=["dh",
                                                                                       "backlash"]))
    assert model.needs_approach
    with pytest.raises(ValueError, match="approach"):
        model.residuals(np.zeros(model.n_params), measurements)
    poses = model.poses(measurements.q_rad[:5])
    assert poses.approach is not None
    np.testing.assert_array_equal(poses.approach, approach_directions(measurements.q_rad[:5]))
    bare = RobotModel("bare", irb120.dh, irb120.lower_rad, irb120.upper_rad,
                      mass_kg=irb120.mass_kg)
    for compliant in ("compliance", "link_compliance"):
        with pytest.raises(InputError, match="without centres of mass"):
            make_model(bare, Rig.cable(port_m),
                       settings=CalibrationSettings(errors=("dh", compliant)))
    with pytest.raises(InputError, match="compliance with link_compliance"):
        CalibrationSettings(errors=("dh", "compliance", "link_compliance"))


def test_link_compliance_holds_compliance(
    irb120: RobotModel, measurements: Measurements, port_m: np.ndarray
) -> None:
    """Each link's gravity torque summed over the links is the gravity part of the joint
    torque; so link_compliance with every link coefficient of joint i equal to c_i moves the
    joints exactly as compliance c_i does."""
    from twin.geometry.statics import joint_torques, link_torques

    assert irb120.mass_kg is not None and irb120.com_m is not None
    q = measurements.q_rad[:20]
    by_link = link_torques(irb120.structure, irb120.dh, q, irb120.mass_kg, irb120.com_m)
    np.testing.assert_allclose(by_link.sum(axis=2), joint_torques(
        irb120.structure, irb120.dh, q, irb120.mass_kg, irb120.com_m), atol=1e-12)
    np.testing.assert_array_equal(np.tril(np.ones((6, 6)), -1) * by_link, 0.0)
    rig = Rig.cable(port_m, tension_n=5.0)
    plain = make_model(irb120, rig, settings=CalibrationSettings(errors=["dh", "compliance"]))
    split = make_model(irb120, rig, settings=CalibrationSettings(errors=["dh", "link_compliance"]))
    c = np.random.default_rng(2).uniform(1e-6, 5e-5, 6)
    x_plain = np.zeros(plain.n_params)
    x_plain[plain.slice("compliance")] = c
    x_split = np.zeros(split.n_params)
    rows, _ = np.triu_indices(6)
    x_split[split.slice("link_compliance")] = np.r_[c, c[rows]]
    data = measurements.subset(np.arange(20))
    np.testing.assert_allclose(split.joints(x_split, data), plain.joints(x_plain, data),
                               atol=1e-15)


def _sliding(irb120: RobotModel) -> RobotModel:
    """The IRB 120 with joint 1 a prismatic standard D-H joint and joint 2 a prismatic Hayati
    joint (the slide that holds no table entry), masses and centres of mass kept."""
    auto = irb120.reparametrised("auto")
    types = ("prismatic", "prismatic", "revolute", "revolute", "revolute", "revolute")
    return replace(auto, structure=replace(auto.structure, joint_types=types),
                   lower_rad=np.r_[-0.2, -0.2, auto.lower_rad[2:]],
                   upper_rad=np.r_[0.3, 0.3, auto.upper_rad[2:]])


@pytest.mark.parametrize("group", ["dh", *JOINT_GROUPS, "link_compliance", "all"])
def test_every_group_on_prismatic_joints_matches_finite_differences(
    irb120: RobotModel, port_m: np.ndarray, group: str
) -> None:
    """A chain with a prismatic D-H joint and a prismatic Hayati joint: every group — D-H,
    transmission (a scale on the slides), backlash (m), compliance (m/N on the force along the
    slide), link compliance, and all with the rig's unknowns — has ∂r/∂x and ∂(flange)/∂x equal
    to central differences."""
    robot = _sliding(irb120)
    assert robot.structure.parametrisation[:2] == ("dh", "hayati")
    errors = ["dh", *(JOINT_GROUPS if group == "all" else [group] if group != "dh" else [])]
    rig = Rig.cable(port_m, [0.01, -0.02, 0.03], tension_n=5.0)
    estimate = ("port", "offset") if group == "all" else ()
    model = make_model(robot, rig, settings=CalibrationSettings(errors=errors,
                                                                estimate=estimate))
    rng = np.random.default_rng(3)
    x = rng.normal(scale=1e-3, size=model.n_params)
    x[model.slice(errors[-1])] *= 0.1 if "compliance" in errors[-1] else 1.0
    q = rng.uniform(robot.lower_rad, robot.upper_rad, (15, 6))
    data = length_measurements(q, np.full(15, 0.8), approach=approach_directions(q))
    _assert_jacobians(model, x, data)


def test_joint_groups_move_a_prismatic_joint_as_stated(
    irb120: RobotModel, port_m: np.ndarray
) -> None:
    """On a prismatic joint transmission is a scale of the travel (s·q, m/m), backlash a lost
    motion b·s (m) and compliance c·F with F the force along the slide (m/N); the revolute
    joints keep their harmonics; names and units say so."""
    from twin.unknowns.compliance import torques

    robot = _sliding(irb120)
    rig = Rig.cable(port_m, tension_n=4.0)
    model = make_model(robot, rig, settings=CalibrationSettings(errors=["dh", *JOINT_GROUPS]))
    transmission = model.group("transmission")
    assert transmission.names[:6] == ("scale_q1", "scale_q2", "sin_q3", "cos_q3", "sin2_q3",
                                      "cos2_q3")
    assert transmission.units[:3] == ("m/m", "m/m", "rad")
    assert model.group("backlash").units[:3] == ("m", "m", "rad")
    assert model.group("compliance").units[:3] == ("m/N", "m/N", "rad/(N·m)")
    rng = np.random.default_rng(5)
    q = rng.uniform(robot.lower_rad, robot.upper_rad, (10, 6))
    data = length_measurements(q, np.full(10, 0.8), approach=approach_directions(q))
    scale, harmonic = rng.normal(scale=1e-4, size=2), rng.normal(scale=1e-3, size=(4, 4))
    backlash, compliance = rng.normal(scale=1e-4, size=6), rng.uniform(1e-7, 1e-6, size=6)
    x = np.zeros(model.n_params)
    x[model.slice("transmission")] = np.r_[scale, harmonic.ravel()]
    x[model.slice("backlash")] = backlash
    x[model.slice("compliance")] = compliance
    turned = q[:, 2:]
    expected = q + backlash * data.approach + compliance * torques(robot, rig, data)
    expected[:, :2] += scale * q[:, :2]
    expected[:, 2:] += (harmonic[:, 0] * np.sin(turned) + harmonic[:, 1] * np.cos(turned)
                        + harmonic[:, 2] * np.sin(2 * turned) + harmonic[:, 3] * np.cos(2 * turned))
    np.testing.assert_allclose(model.joints(x, data), expected, atol=1e-15)
