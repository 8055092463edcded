"""A MuJoCo model of a serial arm, built with :class:`mujoco.MjSpec` from a RobotModel.

The chain is the robot's fixed transforms (:func:`twin.geometry.kinematics.fixed_transforms`),
``base_T_flange(q) = T_0 · J_1(q_1) · T_1 ⋯ J_n(q_n) · T_n``, whatever the parametrisation of its
joints (standard or modified D-H, Hayati) and its base and tool transforms: body ``link<i>``
(child of ``link<i−1>``, or of the world for i = 1) sits at ``T_{i−1}`` in its parent and carries
joint ``joint<i>`` along its local z axis at its origin — a hinge for a revolute joint, a slide
(q in m) for a prismatic one; site ``flange`` sits at ``T_n`` in ``link<n>``. With the joints at
q, the flange site's pose is therefore exactly the core's ``flange_transform`` (tested over 1000
random poses, for every parametrisation and joint type).

Each link is drawn and collides as capsules along its skeleton, from its joint to the next
joint (or the flange): along the joint axis first, then across to the next origin (for a
standard D-H link: along z by d_i, then along x by a_i); a sphere when both are zero. They take
the model file's ``radius`` and share its ``mass``; when the file gives the link's centre of mass
(``com``, in link frame i), the body's mass sits there instead (an explicit inertial), as the
calibration's compliance model assumes. When joint 1 stands off the base origin, a pedestal
capsule of the world reaches up to it. Site ``point`` in ``link<n>`` is the measured point (cable
eyelet, tracker target, ball) when it is off the flange centre. World site ``port`` is the
encoder port; spatial tendon ``cable`` runs from ``port`` to ``point`` (``flange`` without one):
its ``ten_length`` is the measured cable length. With compliant physics, actuators ``servo<i>``
are position servos of the joint stiffness (N·m/rad; N/m on a slide), and actuator ``tension``
pulls the cable with a force equal to its ``ctrl`` (N).

A spec is its skeleton (the elements) placed for the robot's table (where they sit, what they
weigh). :func:`compile_model` compiles the model of :func:`build_spec` from a skeleton kept for
robots of the same kind (a study's true robots, one a trial), copied and placed.
"""

from __future__ import annotations

import math
import threading
import xml.etree.ElementTree as ET
from collections import OrderedDict
from collections.abc import Hashable
from dataclasses import fields, is_dataclass
from typing import NamedTuple

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from twin.arrays import Array
from twin.geometry.kinematics import chain_transforms, joint_placements
from twin.geometry.statics import GRAVITY_M_S2
from twin.robot import RobotModel
from twin.scenario.physics import RIGID, Physics
from twin.units import joints_to_file

DEFAULT_RADIUS_M = 0.04
"""Capsule radius when the model file gives none, m."""
ARMATURE_KG_M2 = 0.05
"""Reflected rotor inertia per joint, kg·m² (kg on a slide): keeps stiff servos stable when
stepping."""
SERVO_DAMPING_RATIO = 1.0
"""Servo damping as a ratio of critical: statics ignore it, stepping settles with it."""
TIMESTEP_S = 5e-4
CABLE_WIDTH_M = 0.002
_SEGMENT_EPS_M = 1e-6
"""A link segment shorter than this is left out, m: MuJoCo refuses a capsule shorter than
1e-7 m (an identified table's 50 nm where the nominal has 0)."""


def _quat(rotation: Array) -> Array:
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(rotation, dtype=np.float64).ravel())
    return quat


def _segments(next_m: Array) -> list[tuple[list[float], list[float], float]]:
    """A link's two skeleton segments, (start, end, length) each in its body's frame, m: along
    the joint axis z to the height of the next origin ``next_m`` (3,), then across to it; the
    ones shorter than :data:`_SEGMENT_EPS_M` are left out (none: the link is a sphere)."""
    corner = [0.0, 0.0, float(next_m[2])]
    # Python floats: numpy's norm of a 3-vector cost more than adding the geom.
    segments = [(p, q, math.dist(p, q)) for p, q in (([0.0, 0.0, 0.0], corner),
                                                     (corner, [float(v) for v in next_m]))]
    return [segment for segment in segments if segment[2] > _SEGMENT_EPS_M]


def _add_link_geoms(body: mujoco.MjsBody, capsules: int, radius_m: float) -> None:
    """The link's geoms: ``capsules`` capsules along its skeleton (:func:`_segments`), or a
    sphere without any; where they sit and what they weigh is :func:`_place_link_geoms`'s."""
    rgba = [0.85, 0.45, 0.1, 1.0]
    kind = mujoco.mjtGeom.mjGEOM_CAPSULE if capsules else mujoco.mjtGeom.mjGEOM_SPHERE
    for _ in range(max(capsules, 1)):
        body.add_geom(type=kind, size=[radius_m, 0, 0], rgba=rgba)


def _place_link_geoms(body: mujoco.MjsBody, next_m: Array, mass_kg: float | None) -> None:
    """The link's capsules along its skeleton to the next origin ``next_m`` (3, in the body's
    frame, m), sharing the link mass by length (a sphere takes it whole)."""
    segments = _segments(next_m)
    geoms = body.geoms
    if not segments:
        if mass_kg is not None:
            geoms[0].mass = mass_kg
        return
    total = sum(length for _, _, length in segments)
    for geom, (start, end, length) in zip(geoms, segments, strict=True):
        geom.fromto = [*start, *end]
        if mass_kg is not None:
            geom.mass = mass_kg * length / total


def _set_inertial(body: mujoco.MjsBody, mass_kg: float, com_in_body_m: Array,
                  radius_m: float) -> None:
    """The link's mass at its centre of mass (in the body's frame), overriding what the
    capsules would make of it (the body's inertial is explicit: :func:`_add_chain`); the
    inertia of a ball of the capsule's radius (statics do not depend on it)."""
    body.mass = mass_kg
    body.ipos = np.asarray(com_in_body_m, dtype=np.float64)
    body.inertia = np.full(3, 0.4 * mass_kg * radius_m**2)


class Layout(NamedTuple):
    """The elements a robot's spec holds beyond its joints, sites and cable, which its table
    decides: two specs of one layout (and one skeleton: :func:`compile_model`) differ only in
    where the elements sit and what they weigh."""

    pedestal: bool
    """Joint 1 stands off the base origin: a pedestal capsule reaches up to it."""
    capsules: tuple[int, ...]
    """Each link's capsules (0: a sphere), :func:`_segments`."""
    touching: tuple[tuple[int, int], ...]
    """Pairs of links (1-based) whose contacts are excluded (:func:`_touching`)."""


class _Placed(NamedTuple):
    """What a robot's table places: its fixed transforms (n + 1, 4, 4), each link frame in its
    joint's body (n, 4, 4) (:func:`joint_placements`'s post) and the layout they make."""

    fixed: Array
    post: Array
    layout: Layout


def _radii(robot: RobotModel) -> Array:
    """Each link's capsule radius, shape (n,), m: the model file's, or the default."""
    return robot.radius_m if robot.radius_m is not None \
        else np.full(robot.n_joints, DEFAULT_RADIUS_M)


def _placed(robot: RobotModel) -> _Placed:
    """Where the robot's table puts its chain, and the layout that makes."""
    placements = joint_placements(robot.structure, robot.dh)
    fixed = chain_transforms(robot.structure, *placements)
    layout = Layout(math.hypot(*fixed[0][:3, 3]) > _SEGMENT_EPS_M,
                    tuple(len(_segments(fixed[i + 1][:3, 3])) for i in range(robot.n_joints)),
                    tuple(_touching(fixed, _radii(robot))))
    return _Placed(fixed, placements[1], layout)


def build_spec(
    robot: RobotModel,
    port_m: ArrayLike | None = None,
    physics: Physics = RIGID,
    *,
    floor: bool = False,
    attachment_m: ArrayLike | None = None,
) -> mujoco.MjSpec:
    """The MjSpec of a robot (and its cable, when a port is given).

    Args:
        robot: The arm; its ``mass_kg`` and ``radius_m`` size the links when given.
        port_m: Encoder port in the base frame, shape (3,), m; None for the arm alone.
        physics: Adds the joint servos (stiffness) and the cable's tension actuator when
            compliant; gravity is always in the model's options (statics switch it off when
            ``physics.gravity`` is false).
        floor: Add a floor plane at z = 0 and a light (what `scene.xml` adds to the robot).
        attachment_m: The measured point in the flange frame, shape (3,), m: site ``point``,
            where the cable ends; None for the flange centre.

    Returns:
        An uncompiled spec; ``spec.compile()`` gives the model, ``spec.to_xml()`` its MJCF.
    """
    placed = _placed(robot)
    spec = _skeleton(robot, placed.layout, port_m is not None, physics, floor,
                     attachment_m is not None)
    _place(spec, robot, placed, port_m, attachment_m)
    return spec


TEMPLATES = 8
"""Skeletons :func:`compile_model` keeps, the least recently used dropped first."""
_templates: OrderedDict[Hashable, mujoco.MjSpec] = OrderedDict()
_templates_lock = threading.Lock()  # twins are built in any thread
_PLACED_FIELDS = ("dh", "mass_kg", "com_m")
"""What :func:`_place` sets of a robot: the rest of it is its skeleton's."""


def compile_model(
    robot: RobotModel,
    port_m: ArrayLike | None = None,
    physics: Physics = RIGID,
    *,
    floor: bool = False,
    attachment_m: ArrayLike | None = None,
) -> mujoco.MjModel:
    """``build_spec(...).compile()`` (the same arguments), the same model to the bit, with the
    elements added once per skeleton: the spec of everything but where the elements sit and
    what they weigh is kept for the next robot of the same kind and layout, copied (15 µs) and
    placed: a study's true robots, one a trial, whose twins took 0.80 ms each and now take
    0.65 ms (bench/bench_sim.py; the compile itself 0.26 ms)."""
    placed = _placed(robot)
    key = (tuple(_fingerprint(getattr(robot, item.name)) for item in fields(robot)
                 if item.name not in _PLACED_FIELDS),
           robot.mass_kg is None, robot.com_m is None, placed.layout, port_m is None,
           _fingerprint(physics), floor, attachment_m is None)
    with _templates_lock:
        template = _templates.get(key)
        if template is None:
            template = _skeleton(robot, placed.layout, port_m is not None, physics, floor,
                                 attachment_m is not None)
            _templates[key] = template
            while len(_templates) > TEMPLATES:
                _templates.popitem(last=False)
        _templates.move_to_end(key)
        spec = template.copy()
    _place(spec, robot, placed, port_m, attachment_m)
    return spec.compile()


def _fingerprint(value: object) -> Hashable:
    """A hashable value that is equal for equal fields: arrays by their dtype, shape and bytes,
    dataclasses field by field."""
    if isinstance(value, np.ndarray):
        return value.dtype.str, value.shape, value.tobytes()
    if is_dataclass(value) and not isinstance(value, type):
        return type(value).__name__, tuple(_fingerprint(getattr(value, item.name))
                                           for item in fields(value))
    if isinstance(value, (tuple, list)):
        return tuple(_fingerprint(item) for item in value)
    assert isinstance(value, Hashable)
    return value


def _skeleton(robot: RobotModel, layout: Layout, cable: bool, physics: Physics, floor: bool,
              point: bool) -> mujoco.MjSpec:
    """Every element of :func:`build_spec`'s spec, none of them placed (:func:`_place`)."""
    spec = mujoco.MjSpec()
    spec.modelname = robot.name.lower().replace(" ", "_")
    spec.compiler.degree = False
    spec.option.timestep = TIMESTEP_S
    spec.option.gravity = [0.0, 0.0, -GRAVITY_M_S2]
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    end = _add_chain(spec, robot, layout, point)
    for first, second in layout.touching:
        spec.add_exclude(bodyname1=f"link{first}", bodyname2=f"link{second}")
    # Link 1 stands on the floor at the base; it only turns about the vertical.
    spec.add_exclude(bodyname1="world", bodyname2="link1")
    if floor:
        spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE,
                                size=[2.0, 2.0, 0.05], rgba=[0.8, 0.8, 0.8, 1.0])
        spec.worldbody.add_light(name="light", pos=[0.0, 0.0, 3.0], dir=[0.0, 0.0, -1.0])
    if physics.stiffness_nm_per_rad is not None:
        _add_servos(spec, robot, physics.stiffness_nm_per_rad)
    if cable:
        _add_cable(spec, end, physics)
    return spec


def _place(spec: mujoco.MjSpec, robot: RobotModel, placed: _Placed, port_m: ArrayLike | None,
           attachment_m: ArrayLike | None) -> None:
    """Put the elements of a skeleton of ``placed``'s layout where the robot's table has them
    (link frame i in body i, the chain's fixed transforms between them; the pedestal, the
    sites, the port), with the robot's masses at the centres of mass ``post`` places."""
    fixed, post = placed.fixed, placed.post
    radius = _radii(robot)
    if placed.layout.pedestal:
        spec.geom("pedestal").fromto = [0.0, 0.0, 0.0, *fixed[0][:3, 3]]
    frames = chain_frames(fixed, attachment_m)
    for i in range(robot.n_joints):
        body = spec.body(f"link{i + 1}")
        body.pos, body.quat = frames.link_pos[i], frames.link_quat[i]
        _place_link_geoms(body, fixed[i + 1][:3, 3],
                          None if robot.mass_kg is None else float(robot.mass_kg[i]))
        if robot.com_m is not None:
            assert robot.mass_kg is not None  # RobotModel: a centre of mass needs a mass
            link = post[i]  # link frame i in the body, which moves with joint i
            _set_inertial(body, float(robot.mass_kg[i]), link[:3, :3] @ robot.com_m[i]
                          + link[:3, 3], radius[i])
    flange = spec.site("flange")
    flange.pos, flange.quat = frames.flange_pos, frames.site_quat
    if attachment_m is not None:
        point = spec.site("point")
        point.pos, point.quat = frames.point_pos, frames.site_quat
    if port_m is not None:
        spec.site("port").pos = np.asarray(port_m, dtype=np.float64)


def _touching(fixed: Array, radius_m: Array) -> list[tuple[int, int]]:
    """Pairs of links (1-based) whose capsules meet whatever the joints: every link and the one
    two on (neighbours share a joint; with a spherical wrist and a shoulder offset, links two
    apart meet at the wrist and elbow centres), and link i with link j > i + 2 when links
    i + 1 … j − 1 all start within a capsule radius of one point (link i ends about where link
    j starts: the FR3's shoulder behind a torso lift, also with a calibration's millimetres
    added)."""
    n = len(fixed) - 1
    at_parent = [bool(math.hypot(*fixed[k][:3, 3]) < radius_m[min(k, n - 1)])
                 for k in range(n + 1)]
    pairs = []
    for i in range(1, n - 1):
        pairs.append((i, i + 2))
        j = i + 2
        while at_parent[i + 1] and j < n and at_parent[j]:
            pairs.append((i, j + 1))
            j += 1
    return pairs


class Frames(NamedTuple):
    """Where the chain's bodies and sites sit in their parents: all that MuJoCo's kinematics
    and a spatial tendon read of the robot's table; of one table, or of each of a stack
    (a leading axis of k tables on every field)."""

    link_pos: Array
    """Body ``link<i>`` in its parent, shape (n, 3), m."""
    link_quat: Array
    """Its orientation, shape (n, 4), w x y z."""
    flange_pos: Array
    """Site ``flange`` in body ``link<n>``, shape (3,), m."""
    point_pos: Array
    """Site ``point`` in body ``link<n>`` (the flange's without an attachment), shape (3,), m."""
    site_quat: Array
    """Both sites' orientation, shape (4,), w x y z."""


def chain_frames(fixed: Array, attachment_m: ArrayLike | None) -> Frames:
    """The :class:`Frames` of the chain's fixed transforms ``fixed`` (n + 1, 4, 4), or of a
    stack of chains (k, n + 1, 4, 4), with the measured point at ``attachment_m`` (flange
    frame, (3,), m; None: the flange centre)."""
    flange = fixed[..., -1, :, :]
    point = flange[..., :3, 3] if attachment_m is None \
        else flange[..., :3, 3] + flange[..., :3, :3] @ np.asarray(attachment_m, dtype=np.float64)
    turns = fixed[..., :3, :3]
    quats = np.array([_quat(turn) for turn in turns.reshape(-1, 3, 3)]) \
        .reshape(*turns.shape[:-2], 4)
    return Frames(fixed[..., :-1, :3, 3], quats[..., :-1, :], flange[..., :3, 3], point,
                  quats[..., -1, :])


def _add_chain(spec: mujoco.MjSpec, robot: RobotModel, layout: Layout, point: bool) -> str:
    """The pedestal (with ``layout.pedestal``), the links with their joints, geoms and
    (with centres of mass) explicit inertials, site ``flange`` and, with ``point``, site
    ``point``; nothing placed (:func:`_place`). Returns the site the cable ends at."""
    radius = _radii(robot)
    if layout.pedestal:
        # Joint 1 stands off the base origin (a base transform, a Hayati joint 1): a pedestal.
        spec.worldbody.add_geom(name="pedestal", type=mujoco.mjtGeom.mjGEOM_CAPSULE,
                                size=[radius[0], 0, 0], rgba=[0.85, 0.45, 0.1, 1.0])
    parent = spec.worldbody
    for i in range(robot.n_joints):
        body = parent.add_body(name=f"link{i + 1}")
        kind = mujoco.mjtJoint.mjJNT_SLIDE if robot.prismatic[i] else mujoco.mjtJoint.mjJNT_HINGE
        joint = body.add_joint(name=f"joint{i + 1}", type=kind, axis=[0.0, 0.0, 1.0],
                               armature=ARMATURE_KG_M2)
        joint.limited = mujoco.mjtLimited.mjLIMITED_TRUE
        joint.range = [robot.lower_rad[i], robot.upper_rad[i]]
        _add_link_geoms(body, layout.capsules[i], radius[i])
        body.explicitinertial = robot.com_m is not None
        parent = body
    parent.add_site(name="flange", size=[0.008, 0, 0], rgba=[0.1, 0.6, 0.1, 1.0])
    if not point:
        return "flange"
    # The attachment is given in the flange frame; the site lives in link n's body.
    parent.add_site(name="point", size=[0.006, 0, 0], rgba=[0.8, 0.1, 0.1, 1.0])
    return "point"


def _add_servos(spec: mujoco.MjSpec, robot: RobotModel, stiffness_nm_per_rad: Array) -> None:
    """Actuators ``servo<i>``: position servos of each joint's stiffness (N·m/rad, N/m on a
    slide), within the joint's limits."""
    for i, (kp, lower, upper) in enumerate(
        zip(stiffness_nm_per_rad, robot.lower_rad, robot.upper_rad, strict=True)
    ):
        servo = spec.add_actuator(name=f"servo{i + 1}", target=f"joint{i + 1}",
                                  trntype=mujoco.mjtTrn.mjTRN_JOINT)
        servo.set_to_position(kp=float(kp), dampratio=SERVO_DAMPING_RATIO)
        servo.ctrlrange = [lower, upper]
        servo.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE


def _add_cable(spec: mujoco.MjSpec, end: str, physics: Physics) -> None:
    """World site ``port`` (placed by :func:`_place`), tendon ``cable`` from it to site ``end``
    and, with compliant physics, actuator ``tension`` pulling the cable."""
    spec.worldbody.add_site(name="port", size=[0.01, 0, 0], rgba=[0.1, 0.1, 0.8, 1.0])
    cable = spec.add_tendon(name="cable", width=CABLE_WIDTH_M, rgba=[0.2, 0.2, 0.2, 1.0])
    cable.wrap_site("port")
    cable.wrap_site(end)
    if physics.stiffness_nm_per_rad is not None:
        # gear −1: a positive control (N) shortens the cable, i.e. pulls the flange.
        tension = spec.add_actuator(name="tension", target="cable",
                                    trntype=mujoco.mjtTrn.mjTRN_TENDON)
        tension.gear = [-1.0, 0, 0, 0, 0, 0]
        tension.ctrlrange = [0.0, max(10.0 * physics.tension_n, 1.0)]
        tension.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE


def _exact(values: object) -> str:
    return " ".join(repr(float(v)) for v in np.ravel(np.asarray(values, dtype=np.float64)))


def model_xml(robot: RobotModel, port_m: ArrayLike | None = None,
              physics: Physics = RIGID) -> str:
    """MJCF text of :func:`build_spec` (no floor), with a comment naming its source.

    MuJoCo's XML writer keeps 6 significant digits, which moves the flange by up to a
    micrometre; the kinematic attributes (body and site ``pos`` / ``quat``, joint ``range``) are
    written again from the spec at full double precision, so the file's FK agrees to 1e-9 m.
    """
    spec = build_spec(robot, port_m, physics)
    units = "mm|deg" if robot.prismatic.any() else "deg"
    spec.comment = (
        f"{robot.name}: generated by twin.sim.builder.model_xml from the kinematic table "
        f"(joint limits {np.round(joints_to_file(robot.lower_rad, robot.prismatic), 3).tolist()}"
        f" .. {np.round(joints_to_file(robot.upper_rad, robot.prismatic), 3).tolist()} {units})"
    )
    root = ET.fromstring(str(spec.to_xml()),
                         ET.XMLParser(target=ET.TreeBuilder(insert_comments=True)))
    world = root.find("worldbody")
    assert world is not None  # MuJoCo always writes one
    for body in world.iter("body"):
        source = spec.body(body.attrib["name"])
        body.set("pos", _exact(source.pos))
        body.set("quat", _exact(source.quat))
    for joint in world.iter("joint"):
        joint.set("range", _exact(spec.joint(joint.attrib["name"]).range))
    for site in world.iter("site"):  # not the tendon's references to sites
        source = spec.site(site.attrib["name"])
        site.set("pos", _exact(source.pos))
        site.set("quat", _exact(source.quat))
    ET.indent(root)
    return ET.tostring(root, encoding="unicode") + "\n"
