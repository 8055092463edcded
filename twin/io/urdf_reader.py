"""URDF in: the serial chain of a URDF as a twin robot, through Pinocchio.

An adapter: it imports Pinocchio (lazily, when a URDF is read); the core never does.

Pinocchio parses the URDF (urdfdom) into its kinematic tree; the chain runs from a base link
down to a tip link:

- **base link**: ``--base-link`` / ``base_link``, by default the URDF's root link;
- **tip link**: ``--tip-link`` / ``tip_link``, by default ``tool0`` when the URDF has it, else
  ``flange``, else the one leaf link (several leaves: the error lists them);
- every joint on the way must be revolute (or continuous: limits ±180° then), prismatic (a torso
  lift, a linear track: it slides along its axis, limits in m) or fixed, and none a
  ``<mimic>``; off-chain joints (a gripper's fingers) are kept in the URDF and left at zero.

The XML is read twice, by expat here (the chain, names and numbers) and by urdfdom in
Pinocchio, so it is held to what both read alike: no document type declaration (expat expands
its entities, urdfdom does not), at most :data:`MAX_URDF_BYTES` bytes and
:data:`MAX_URDF_ELEMENTS` links and joints (urdfdom's parse grows quadratically), every origin
within 100 m and two turns, every axis a direction, the chain's limits within two turns (100 m
for a prismatic joint); and
Pinocchio's chain must have the same names, and at q = 0 the same tip and axes, as expat's.

Each moving joint's frame is turned so that its axis is z, which gives the chain as fixed
transforms T_0 … T_n (:func:`twin.geometry.kinematics.fixed_transforms`' form: fixed joints between
two moving joints merge into one transform), and :func:`twin.geometry.parametrisation.convert`
turns those into the chosen parametrisation exactly, a prismatic joint's line kept through its
URDF origin. Joint limits, rated speeds and efforts (torques, or forces on a prismatic joint)
come from the URDF's ``<limit>``, in the URDF's SI units; link masses from Pinocchio's inertias
(a joint's mass is that of every link rigidly attached after it). The URDF text itself is kept
(:class:`twin.robot.UrdfSource`) so that a calibration can be written back into it with every
name, mesh and inertial (:mod:`twin.export.urdf`).
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import tempfile
import xml.etree.ElementTree as ET
import xml.parsers.expat as expat
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from twin.arrays import Array
from twin.choices import MAX_JOINTS, MIN_JOINTS
from twin.errors import InputError
from twin.geometry.kinematics import fixed_transforms, rigid_transform
from twin.geometry.parametrisation import AUTO_PARAMETRISATION, convert, joint_frames
from twin.io.paths import read_text
from twin.io.table import shown
from twin.robot import RobotModel, UrdfSource
from twin.units import MAX_ANGLE_RAD, MAX_LINK_M

if TYPE_CHECKING:
    import pinocchio as pin


TIP_NAMES = ("tool0", "flange")
"""Tip links looked for, in this order, when none is named."""
CONTINUOUS_LIMIT_RAD = math.pi
"""Limits given to a continuous joint (the URDF gives none): ±180°."""
REVOLUTE = ("revolute", "continuous")
MOVING = (*REVOLUTE, "prismatic")
"""The joint types a chain's joints may have besides fixed: each is one of the robot's joints."""
WHAT = "a URDF file"
MAX_URDF_BYTES = 16 * 2**20
"""Largest URDF read, bytes (16 MiB; the shipped arms take under 10 kB)."""
MAX_URDF_ELEMENTS = 1000
"""Most ``<link>`` elements, and most ``<joint>`` elements, of a URDF: Pinocchio's parse grows
quadratically with them (0.05 s for a chain of 1000, 0.4 s for 3000) and a chain about 4000
joints deep overflows its stack."""
MIN_AXIS_NORM = 1e-6
"""Shortest joint axis accepted before it is normalised (as urdfdom does): a shorter one is a
zero axis, not a direction."""
AGREEMENT_TOLERANCE = 1e-9
"""How far Pinocchio's chain at q = 0 (base_T_tip, m per m of the origins' lengths, and each
joint axis) may be from the one read here before the two parses are taken to disagree."""


class Chain(NamedTuple):
    """A URDF's serial chain, as the XML names it."""

    base_link: str
    tip_link: str
    joints: tuple[ET.Element, ...]
    """Every joint element from the base link down to the tip link, in order."""

    @property
    def moving(self) -> tuple[ET.Element, ...]:
        """The chain's moving joints (revolute, continuous and prismatic), base to tip: the
        robot's joints."""
        return tuple(joint for joint in self.joints if joint.get("type") in MOVING)

    @property
    def joint_types(self) -> tuple[str, ...]:
        """Each of the robot's joints as :class:`twin.geometry.kinematics.Structure` types it
        (a continuous joint is revolute)."""
        return tuple("prismatic" if joint.get("type") == "prismatic" else "revolute"
                     for joint in self.moving)


def _child(joint: ET.Element) -> str:
    element = joint.find("child")
    return "" if element is None else str(element.get("link", ""))


def _parent(joint: ET.Element) -> str:
    element = joint.find("parent")
    return "" if element is None else str(element.get("link", ""))


def _by_child(joints: list[ET.Element], source: str | Path) -> dict[str, ET.Element]:
    """Each link's parent joint; a link with two is refused (a URDF is a tree)."""
    by_child: dict[str, ET.Element] = {}
    for joint in joints:
        child = _child(joint)
        if child in by_child:
            raise InputError(f"link {child!r} the child of joints "
                             f"{by_child[child].get('name')!r} and {joint.get('name')!r}",
                             "one parent joint per link (a tree)", source=source)
        by_child[child] = joint
    return by_child


def find_chain(root: ET.Element, base_link: str | None, tip_link: str | None,
               source: str | Path) -> Chain:
    """The joints from the base link down to the tip link of a parsed URDF.

    Raises:
        InputError: for an unknown link, a link with two parents, a cycle of joints, a tip
            that is not below the base, an ambiguous default tip, or a joint on the chain that
            is neither revolute, continuous, prismatic nor fixed.
    """
    links = [str(link.get("name")) for link in root.findall("link")]
    joints = root.findall("joint")
    by_child = _by_child(joints, source)
    parents = {_parent(joint) for joint in joints}
    roots = [link for link in links if link not in by_child]
    leaves = [link for link in links if link not in parents]
    if base_link is None:
        base_link = roots[0] if len(roots) == 1 else None
        if base_link is None:
            raise InputError(f"{len(roots)} root links", "one (or --base-link NAME)",
                             source=source)
    if tip_link is None:
        named = [name for name in TIP_NAMES if name in links]
        tip_link = named[0] if named else leaves[0] if len(leaves) == 1 else None
        if tip_link is None:
            raise InputError("several leaf links (" + ", ".join(leaves) + ") and no tool0 or "
                             "flange", "--tip-link NAME to say which is the flange",
                             source=source)
    for flag, name in (("--base-link", base_link), ("--tip-link", tip_link)):
        if name not in links:
            raise InputError(f"{flag} {name!r}", "one of the URDF's links: " + ", ".join(links),
                             source=source)
    path: list[ET.Element] = []
    link, seen = tip_link, {tip_link}
    while link != base_link:
        if link not in by_child:
            raise InputError(f"tip link {tip_link!r} not below base link {base_link!r}",
                             "a tip link on the chain below the base link", source=source)
        joint = by_child[link]
        if joint.get("type") not in (*MOVING, "fixed"):
            raise InputError(f"joint {joint.get('name')!r} of type {joint.get('type')!r} on "
                             "the chain", "revolute, continuous, prismatic or fixed joints "
                             "only", source=source)
        path.append(joint)
        link = _parent(joint)
        if link in seen:  # a link its own ancestor: the walk would never reach the base
            raise InputError(f"a cycle of joints through link {link!r}",
                             "a tree (no link its own ancestor)", source=source)
        seen.add(link)
    return Chain(base_link, tip_link, tuple(reversed(path)))


def _triple(element: ET.Element | None, attribute: str, default: str,
            largest: tuple[float, str] | None, source: str | Path, where: str) -> Array:
    """Three finite numbers from an attribute, each within ±largest (a bound and its unit)
    when given, shape (3,)."""
    written = default if element is None else str(element.get(attribute, default))
    try:
        values = np.array([float(part) for part in written.split()], dtype=np.float64)
    except ValueError:
        values = np.zeros(0)
    bound = math.inf if largest is None else largest[0]
    if values.shape != (3,) or not np.all(np.isfinite(values) & (np.abs(values) <= bound)):
        expected = "three finite numbers" if largest is None else \
            f"three numbers within ±{largest[0]:g} {largest[1]}"
        raise InputError(f"{attribute}={shown(written)}", expected, source=source,
                         where=where)
    return values


def origin_transform(joint: ET.Element, source: str | Path) -> Array:
    """parent_T_joint of a URDF joint's ``<origin>`` (identity without one), shape (4, 4), m.

    Raises:
        InputError: for an ``xyz`` that is not three numbers within ±1 km, or an ``rpy`` not
            three within ±4π rad, naming the joint.
    """
    where = f"joint {joint.get('name')!r} <origin>"
    origin = joint.find("origin")
    xyz = _triple(origin, "xyz", "0 0 0", (MAX_LINK_M, "m"), source, where)
    rpy = _triple(origin, "rpy", "0 0 0", (MAX_ANGLE_RAD, "rad (two turns)"), source, where)
    return rigid_transform(xyz, rpy)


def joint_axis(joint: ET.Element, source: str | Path) -> Array:
    """The unit axis of a URDF joint in its frame (URDF's default: x), shape (3,).

    Raises:
        InputError: for an axis that is not three finite numbers, or shorter than
            :data:`MIN_AXIS_NORM` (a zero axis), naming the joint.
    """
    where = f"joint {joint.get('name')!r} <axis>"
    element = joint.find("axis")
    axis = _triple(element, "xyz", "1 0 0", None, source, where)
    norm = float(np.linalg.norm(axis))
    if norm < MIN_AXIS_NORM:
        raise InputError(f"an axis of length {norm:g}", f"a direction (length at least "
                         f"{MIN_AXIS_NORM:g}; it is normalised)", source=source, where=where)
    return axis / norm


def axis_alignment(axis: ArrayLike) -> Array:
    """A rotation R with R · e_z = the unit joint axis (so that the joint turns about z of its
    frame turned by R), shape (3, 3)."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    c = float(a[2])
    v = np.array([-a[1], a[0], 0.0])  # e_z × a
    s = float(np.linalg.norm(v))
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    k = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.asarray(np.eye(3) + k + k @ k * ((1.0 - c) / s**2), dtype=np.float64)


@contextlib.contextmanager
def _captured_stderr() -> Iterator[list[str]]:
    """Collect what C++ code writes to file descriptor 2 (urdfdom reports its errors there,
    around Python's back) instead of letting it reach the terminal."""
    lines: list[str] = []
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield lines
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            lines += sink.read().decode("utf-8", errors="replace").splitlines()


def _pinocchio_model(text: str, source: str | Path) -> pin.Model:
    import pinocchio as pin

    failure = ""
    with _captured_stderr() as messages:
        try:
            return pin.buildModelFromXML(text)
        except (RuntimeError, ValueError) as exc:
            failure = str(exc).strip()
    reasons = [line.split("Error:", 1)[1].strip() for line in messages if "Error:" in line]
    reason = reasons[0] if reasons else failure or "Pinocchio's parser says nothing more"
    raise InputError(f"a URDF Pinocchio cannot read ({reason})", WHAT, source=source)


def _fixed_transforms(model: pin.Model, chain: Chain) -> tuple[Array, list[int]]:
    """T_0..T_n of the chain from Pinocchio's placements at q = 0, and the chain's joint ids.

    Joint k's frame is Pinocchio's joint frame turned by :func:`axis_alignment` of its axis
    (read back from the joint's Jacobian, whatever Pinocchio's joint type: the angular column
    of a revolute joint, the linear one of a prismatic joint)."""
    import pinocchio as pin

    data = model.createData()
    pin.forwardKinematics(model, data, pin.neutral(model))
    pin.updateFramePlacements(model, data)
    ids = [model.getJointId(str(joint.get("name"))) for joint in chain.moving]
    pin.computeJointJacobians(model, data, pin.neutral(model))
    frames = []
    for joint_id, joint_type in zip(ids, chain.joint_types, strict=True):
        jacobian = pin.getJointJacobian(model, data, joint_id, pin.ReferenceFrame.LOCAL)
        rows = slice(0, 3) if joint_type == "prismatic" else slice(3, 6)
        axis = jacobian[rows, model.joints[joint_id].idx_v]
        frame = data.oMi[joint_id].homogeneous.copy()
        frame[:3, :3] = frame[:3, :3] @ axis_alignment(axis)
        frames.append(frame)
    base = data.oMf[model.getFrameId(chain.base_link, pin.FrameType.BODY)].homogeneous
    tip = data.oMf[model.getFrameId(chain.tip_link, pin.FrameType.BODY)].homogeneous
    inverse = np.linalg.inv
    fixed = [inverse(base) @ frames[0]]
    fixed += [inverse(frames[i]) @ frames[i + 1] for i in range(len(frames) - 1)]
    fixed.append(inverse(frames[-1]) @ tip)
    return np.stack(fixed), ids


def frame_offsets(urdf_frames: Array, table_frames: Array) -> Array:
    """Each URDF joint frame in the table's frame of the same joint: a shift along and a turn
    about their common z axis, shape (n, 2), m and rad.

    Args:
        urdf_frames: base_T_joint of the URDF's joints (axis along z), shape (n, 4, 4).
        table_frames: base_T_joint of the converted table's joints, shape (n, 4, 4).
    """
    offsets = np.linalg.inv(table_frames) @ urdf_frames
    screw = max(float(np.abs(offsets[:, :2, 3]).max()), float(np.abs(offsets[:, :2, 2]).max()))
    if screw > 1e-9:  # both frames turn about the same axis, by construction of the table
        raise AssertionError(f"joint frames off their axis by {screw:.3g}")
    return np.column_stack([offsets[:, 2, 3], np.arctan2(offsets[:, 1, 0], offsets[:, 0, 0])])


class _RootReachedError(Exception):
    """Stops the prologue's parse at the root element."""


def _parse(text: str, source: str | Path) -> ET.Element:
    """The document's root, after the checks that keep both parsers on the same, small file.

    A document type declaration is refused: expat (here) expands its entities, urdfdom
    (Pinocchio) does not, so the two would read different names and numbers.
    """
    size = len(text.encode("utf-8"))
    if size > MAX_URDF_BYTES:
        raise InputError(f"{size} bytes", f"{WHAT} of at most {MAX_URDF_BYTES} bytes",
                         source=source)
    prologue = expat.ParserCreate()

    def refuse(*_: object) -> None:
        raise InputError("a document type declaration (<!DOCTYPE …>)", f"{WHAT} without "
                         "one (Pinocchio's parser ignores its entities)", source=source)

    def stop(*_: object) -> None:
        raise _RootReachedError  # no declaration can follow the root element

    prologue.StartDoctypeDeclHandler = refuse
    prologue.StartElementHandler = stop
    with contextlib.suppress(_RootReachedError, expat.ExpatError):  # ET names an XML error
        prologue.Parse(text, True)
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise InputError(f"invalid XML ({exc})", WHAT, source=source) from None
    if root.tag != "robot":
        raise InputError(f"a <{root.tag}> document", f"{WHAT} (a <robot> document)",
                         source=source)
    for tag in ("link", "joint"):
        count = len(root.findall(tag))
        if count > MAX_URDF_ELEMENTS:
            raise InputError(f"{count} <{tag}> elements",
                             f"{WHAT} of at most {MAX_URDF_ELEMENTS}", source=source)
    return root


def _check_numbers(root: ET.Element, chain: Chain, source: str | Path) -> None:
    """Every joint's origin and axis plausible, and each moving joint of the chain independent
    (no ``<mimic>``) with limits within two turns (100 m for a prismatic joint).

    Raises:
        InputError: naming the joint and the field.
    """
    for joint in root.findall("joint"):
        origin_transform(joint, source)
        if joint.get("type") not in ("fixed", "floating"):
            joint_axis(joint, source)
    for joint in chain.moving:
        name = joint.get("name")
        mimic = joint.find("mimic")
        if mimic is not None:
            raise InputError(f"a <mimic> joint on the chain (it follows "
                             f"{mimic.get('joint')!r})", "independent joints from base to "
                             "tip (twin calibrates each joint's own angle)", source=source,
                             where=f"joint {name!r}")
        limit = joint.find("limit")
        if joint.get("type") == "continuous" or limit is None:
            continue  # urdfdom refuses a revolute or prismatic joint without limits
        where = f"joint {name!r} <limit>"
        largest, unit = (MAX_LINK_M, "m") if joint.get("type") == "prismatic" \
            else (MAX_ANGLE_RAD, "rad (two turns)")
        bounds = []
        for key in ("lower", "upper"):
            written = str(limit.get(key, "0"))
            try:
                value = float(written)
            except ValueError:
                value = math.nan
            if not abs(value) <= largest:
                raise InputError(f"{key}={shown(written)}", f"a number within ±{largest:g} "
                                 f"{unit}", source=source, where=where)
            bounds.append(value)
        if bounds[0] >= bounds[1]:
            raise InputError(f"lower={bounds[0]:g} >= upper={bounds[1]:g}", "lower < upper",
                             source=source, where=where)


def _check_agreement(model: pin.Model, chain: Chain, source: str | Path) -> None:
    """Pinocchio's model has the chain's names (an absent one would be used as an index).

    Raises:
        InputError: naming what Pinocchio did not read.
    """
    import pinocchio as pin

    missing = [f"joint {str(joint.get('name'))!r}" for joint in chain.moving
               if not model.existJointName(str(joint.get("name")))]
    missing += [f"link {link!r}" for link in (chain.base_link, chain.tip_link)
                if not model.existFrame(link, pin.FrameType.BODY)]
    if missing:
        raise InputError(f"names Pinocchio does not read the same: {', '.join(missing)}",
                         f"{WHAT} both parsers read alike", source=source)


def _check_same_chain(fixed: Array, chain: Chain, source: str | Path) -> None:
    """Pinocchio's chain (fixed transforms, (n + 1, 4, 4)) is the XML's: base_T_tip at q = 0
    and every joint axis.

    Raises:
        InputError: when the two parses disagree.
    """
    transform, axes = np.eye(4), []
    for joint in chain.joints:
        transform = transform @ origin_transform(joint, source)
        if joint.get("type") in MOVING:
            axes.append(transform[:3, :3] @ joint_axis(joint, source))
    frames, tip = joint_frames(fixed)
    scale = 1.0 + sum(float(np.abs(origin_transform(j, source)[:3, 3]).sum())
                      for j in chain.joints)
    gap = max(float(np.abs(tip[:3, 3] - transform[:3, 3]).max()) / scale,
              float(np.abs(tip[:3, :3] - transform[:3, :3]).max()),
              float(np.abs(frames[:, :3, 2] - np.array(axes)).max()))
    if not gap <= AGREEMENT_TOLERANCE:
        raise InputError(f"a chain Pinocchio reads {gap:.3g} away from the XML",
                         f"{WHAT} both parsers read alike", source=source)


def load_urdf(path: str | Path, *, base_link: str | None = None, tip_link: str | None = None,
              parametrisation: str | Sequence[str] = AUTO_PARAMETRISATION, text: str | None = None
              ) -> RobotModel:
    """The serial chain of a URDF as a robot, in the parametrisation asked for.

    Args:
        path: The URDF file.
        base_link: The link the chain starts from; the root link if None.
        tip_link: The flange link; ``tool0``, ``flange`` or the one leaf if None.
        parametrisation: ``auto`` (Hayati where consecutive axes are nearly parallel, standard
            D-H elsewhere), ``dh``, ``mdh``, or one per joint
            (:mod:`twin.geometry.parametrisation`).
        text: The URDF's text when it does not come from ``path`` itself (a xacro expanded,
            :mod:`twin.io.xacro_reader`); ``path`` then names it in messages.

    Returns:
        The robot, its forward kinematics equal to Pinocchio's to 1e-9 m, with the URDF kept.

    Raises:
        InputError: for a file that is not a URDF Pinocchio reads (or reads otherwise than
            expat: a document type declaration), one larger than :data:`MAX_URDF_BYTES` or
            with more than :data:`MAX_URDF_ELEMENTS` links or joints, links it does not have,
            a chain of other joints than revolute, prismatic and fixed (or a ``<mimic>`` one),
            fewer than 4 or more than 9 moving joints, an origin, axis or limit that cannot be
            right
            (:func:`origin_transform`, :func:`joint_axis`), or a parametrisation the chain
            cannot take.
    """
    text = read_text(path, WHAT) if text is None else text
    root = _parse(text, path)
    chain = find_chain(root, base_link, tip_link, path)
    moving = chain.moving
    if not MIN_JOINTS <= len(moving) <= MAX_JOINTS:
        raise InputError(f"{len(moving)} moving joints from {chain.base_link!r} to "
                         f"{chain.tip_link!r}", f"{MIN_JOINTS} to {MAX_JOINTS} (revolute, "
                         "continuous or prismatic)", source=path)
    _check_numbers(root, chain, path)
    model = _pinocchio_model(text, path)
    _check_agreement(model, chain, path)
    fixed, ids = _fixed_transforms(model, chain)
    _check_same_chain(fixed, chain, path)
    try:
        structure, table = convert(fixed, parametrisation, chain.joint_types)
    except ValueError as exc:
        raise InputError(str(exc), "a parametrisation the chain can take (auto)",
                         source=path, where="parametrisation") from None
    offsets = frame_offsets(joint_frames(fixed)[0],
                            joint_frames(fixed_transforms(structure, table))[0])
    lower, upper, velocity, effort = [], [], [], []
    for joint, joint_id in zip(moving, ids, strict=True):
        index = model.joints[joint_id].idx_q
        if joint.get("type") == "continuous":
            lower.append(-CONTINUOUS_LIMIT_RAD)
            upper.append(CONTINUOUS_LIMIT_RAD)
        else:
            lower.append(float(model.lowerPositionLimit[index]))
            upper.append(float(model.upperPositionLimit[index]))
        velocity.append(float(model.velocityLimit[model.joints[joint_id].idx_v]))
        effort.append(float(model.effortLimit[model.joints[joint_id].idx_v]))
    mass = np.array([model.inertias[joint_id].mass for joint_id in ids])
    names = tuple(str(joint.get("name")) for joint in moving)
    try:
        return RobotModel(
            name=str(root.get("name") or Path(path).stem), dh=table, structure=structure,
            lower_rad=np.array(lower), upper_rad=np.array(upper),
            mass_kg=mass if np.all(mass > 0) else None,
            velocity_rad_s=np.array(velocity), effort_nm=np.array(effort),
            urdf=UrdfSource(text, chain.base_link, chain.tip_link, names, offsets),
        )
    except ValueError as exc:
        raise InputError(str(exc), "joint limits with lower < upper", source=path) from None
