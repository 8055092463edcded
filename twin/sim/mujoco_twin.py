"""The digital twin: a compiled MuJoCo model of the true robot, its port and its cable.

``Twin.lengths(q)`` is what an ideal encoder reads with the controller at joint angles q: the
joint errors move the joints off q, the servos sag under gravity and the cable's tension, and
the tendon ``cable`` is read at rest. ``Twin.at_rest(q).point_m`` is where the measured point
(site ``point``, or the flange) is then: what a laser tracker sees. A twin without a port has
no cable. Noise is added elsewhere (:mod:`twin.scenario.noise`).

A Twin owns mutable MuJoCo data: use one per thread. Making an ``MjData`` costs the bindings
some 0.85 ms whatever its arena, as much as compiling the model: a twin that is collected hands
its data to the next twin of the same sizes (a study's trials, a warm-up's rows).
"""

from __future__ import annotations

import copy
import math
import threading
import weakref
from typing import NamedTuple

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import Array
from twin.dataset import approach_directions
from twin.geometry.kinematics import fixed_transforms
from twin.robot import RobotModel
from twin.scenario.joint_errors import JointErrors
from twin.scenario.physics import RIGID, Physics
from twin.sim.builder import Frames, chain_frames, compile_model
from twin.sim.equilibrium import static_equilibrium

_STATICS_OFF = (
    mujoco.mjtDisableBit.mjDSBL_CONTACT
    | mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    | mujoco.mjtDisableBit.mjDSBL_CLAMPCTRL
)


SPARE_DATA = 2
"""Scratch data kept for reuse per set of model sizes."""
_spare: dict[tuple[int, ...], list[mujoco.MjData]] = {}
_spare_lock = threading.Lock()  # a twin may be collected in any thread
_size_fields: list[str] = []


def _sizes(model: mujoco.MjModel) -> tuple[int, ...]:
    """Every size of the model (``nq``, ``nbody``, ``nbuffer``, ``narena``…): two models with the
    same sizes lay their data out alike."""
    if not _size_fields:
        _size_fields.extend(name for name in dir(model) if name.startswith("n")
                            and isinstance(getattr(model, name), int))
    return tuple(getattr(model, name) for name in _size_fields)


def _scratch(model: mujoco.MjModel) -> tuple[mujoco.MjData, tuple[int, ...]]:
    """Data for ``model``, reset to its initial state: a collected twin's of the same sizes
    when there is one; and the sizes, to hand it back under."""
    sizes = _sizes(model)
    with _spare_lock:
        kept = _spare.get(sizes)
        data = kept.pop() if kept else None
    if data is None:
        return mujoco.MjData(model), sizes
    mujoco.mj_resetData(model, data)
    return data, sizes


def _hand_back(sizes: tuple[int, ...], data: mujoco.MjData) -> None:
    with _spare_lock:
        kept = _spare.setdefault(sizes, [])
        if len(kept) < SPARE_DATA:
            kept.append(data)


class AtRest(NamedTuple):
    """The arm at rest with the controller at some recorded joint angles."""

    q_rad: Array
    """Actual joint angles, shape (m, n), rad."""
    length_m: Array
    """Cable lengths (``ten_length``), shape (m,), m; NaN without a cable."""
    flange_m: Array
    """Flange centres in the base frame, shape (m, 3), m."""
    point_m: Array
    """The measured point in the base frame, shape (m, 3), m."""
    rotation: Array
    """The flange's orientation in the base frame, base_R_flange, shape (m, 3, 3)."""


class Twin:
    """A true robot in MuJoCo, with an encoder port and a cable.

    Attributes:
        robot: The true robot (its table is the truth).
        port_m: True port, shape (3,), m; None without a cable.
        physics: Servo stiffness, gravity and tension.
        joint_errors: Transmission error and backlash.
        attachment_m: The measured point in the flange frame, shape (3,), m.
        model: Compiled model with a floor (contacts on), for collision checks.
        statics_model: The same model with contacts, constraints and control clamping off,
            for lengths and statics; without servos (rigid physics) the model itself, whose
            kinematics and tendons read none of those options.
        data: Scratch data of either model (``statics_data`` is the same object).
    """

    def __init__(self, robot: RobotModel, port_m: ArrayLike | None, physics: Physics,
                 joint_errors: JointErrors, attachment_m: ArrayLike | None = None,
                 compiled: mujoco.MjModel | None = None) -> None:
        self.robot = robot
        self.port_m = None if port_m is None else np.array(port_m, dtype=np.float64)
        self.physics = physics
        self.joint_errors = joint_errors
        self.attachment_m = np.zeros(3) if attachment_m is None \
            else np.array(attachment_m, dtype=np.float64)
        if compiled is None:
            self.model = compile_model(robot, self.port_m, physics, floor=True,
                                       attachment_m=attachment_m)
        else:
            # A twin of the same robot with a cable (with_port): its model with the port moved.
            self.model = copy.copy(compiled)
            self.model.site_pos[self.model.site("port").id] = self.port_m
        self.statics_model = self.model
        if physics.stiffness_nm_per_rad is not None:
            # The same compiled model, copied rather than compiled again (a third of the cost);
            # without servos there are no statics, and a copy was a tenth of a study's twin.
            self.statics_model = copy.copy(self.model)
            self.statics_model.opt.disableflags |= int(_STATICS_OFF)
            if not physics.gravity:
                self.statics_model.opt.gravity[:] = 0.0
        # One scratch data for both models, which differ in their options only: each use sets
        # the state it reads (the joints; the statics the velocities and the servos' targets,
        # the cable's pull set here), and a second arena was a quarter of building a twin.
        self.data, sizes = _scratch(self.model)
        weakref.finalize(self, _hand_back, sizes, self.data)
        self.statics_data = self.data
        if not physics.rigid and self.port_m is not None:
            self.statics_data.ctrl[self.statics_model.actuator("tension").id] = physics.tension_n
        self._flange = self.model.site("flange").id
        self._point = self.model.site("point" if attachment_m is not None else "flange").id
        self._cable = None if self.port_m is None else self.model.tendon("cable").id
        self._links = [self.model.body(f"link{i + 1}").id for i in range(robot.n_joints)]
        self._link6 = self._links[-1]

    @classmethod
    def build(cls, robot: RobotModel, port_m: ArrayLike | None, physics: Physics = RIGID,
              joint_errors: JointErrors | None = None, attachment_m: ArrayLike | None = None
              ) -> Twin:
        """The twin of ``robot`` with its port at ``port_m`` (base frame, m; None: no cable)
        and the measured point at ``attachment_m`` (flange frame, m; None: the flange)."""
        stiffness = physics.stiffness_nm_per_rad
        if stiffness is not None and stiffness.shape != (robot.n_joints,):
            raise ValueError("physics: one stiffness per joint expected")
        return cls(robot, port_m, physics,
                   joint_errors if joint_errors is not None else JointErrors.none(robot.n_joints),
                   attachment_m)

    def with_port(self, port_m: ArrayLike | None) -> Twin:
        """This twin with its encoder port at ``port_m`` (base frame, m) instead: its compiled
        model copied and the port site moved, which reads as a twin built there (an encoder
        moved between three stations compiled a twin at each: 1.4 ms of a 26 ms trial).

        Raises:
            ValueError: for a twin without a cable, or no port.
        """
        if self.port_m is None or port_m is None:
            raise ValueError("with_port: a twin with a cable and a port expected")
        return Twin(self.robot, port_m, self.physics, self.joint_errors,
                    self.attachment_m if self._point != self._flange else None, self.model)

    def joint_angles(self, q_rad: ArrayLike, approach: ArrayLike | None = None) -> Array:
        """Where the joints really are when the controller records q.

        Args:
            q_rad: Recorded joint angles, shape (m, n), rad.
            approach: Direction each joint last moved in, shape (m, n), ±1; by default the
                directions of visiting the poses in order from home (q = 0).

        Returns:
            Actual joint angles at rest, shape (m, n), rad.
        """
        q = np.atleast_2d(np.asarray(q_rad, dtype=np.float64))
        if self.joint_errors.active:
            q = self.joint_errors.actual(q, approach_directions(q) if approach is None
                                         else approach)
        if self.physics.stiffness_nm_per_rad is None:
            return q
        return static_equilibrium(self.statics_model, self.statics_data, q,
                                  self.physics.stiffness_nm_per_rad)

    def at_rest(self, q_rad: ArrayLike, approach: ArrayLike | None = None) -> AtRest:
        """Actual joints, cable lengths and flange positions with the controller at q.

        Args:
            q_rad: Recorded joint angles, shape (m, n), rad.
            approach: As in :meth:`joint_angles`.
        """
        return self._read(self.joint_angles(q_rad, approach))

    def at_rest_of(self, tables: ArrayLike, q_rad: ArrayLike, approach: ArrayLike) -> AtRest:
        """:meth:`at_rest` with each row on its own table and this twin's joints (a warm-up's
        links grown at each row): the bodies and sites of this twin's model placed for the row
        as :func:`twin.sim.builder.build_spec` places them for that table, and put back after —
        a twin built for the table reads the same, and compiling one was most of a warm-up's
        capture. Rigid joints only: statics would read masses placed from the geoms, which
        stay.

        Args:
            tables: Each row's parameter table, shape (m, 4, n), m and rad.
            q_rad: Recorded joint angles, shape (m, n), rad.
            approach: Direction each joint last moved in, shape (m, n), ±1.

        Raises:
            ValueError: with servos, or for tables of another shape.
        """
        if not self.physics.rigid:
            raise ValueError("at_rest_of: rigid joints only (statics read the geoms' masses)")
        q_actual = self.joint_angles(q_rad, approach)
        rows = np.asarray(tables, dtype=np.float64)
        if rows.shape != (len(q_actual), *self.robot.dh.shape):
            raise ValueError(f"at_rest_of: tables of shape {rows.shape}, expected "
                             f"({len(q_actual)}, {', '.join(map(str, self.robot.dh.shape))})")
        model = self.model
        placed = (model.body_pos, model.body_quat, model.site_pos, model.site_quat)
        saved = [array.copy() for array in placed]
        try:
            return self._read(q_actual, rows)
        finally:
            for array, kept in zip(placed, saved, strict=True):
                array[:] = kept

    def _read(self, q_actual: Array, tables: Array | None = None) -> AtRest:
        """What :meth:`at_rest` reads at actual joint angles (m, n), rad; with ``tables``
        (m, 4, n), each row after the bodies and sites are placed for its table."""
        m = len(q_actual)
        model, data = self.statics_model, self.statics_data
        lengths = np.full(m, np.nan)
        # Every site at once and the flange's axes flat, parted after the loop: a copy per
        # field and pose was a third of reading a capture (0.38 ms at 120 poses).
        sites = np.empty((m, model.nsite, 3))
        turns = np.empty((m, 9))
        frames = None if tables is None \
            else chain_frames(fixed_transforms(self.robot.structure, tables), self.attachment_m)
        # MuJoCo's arrays and functions looked up once (2.4 against 1.8 µs a pose).
        qpos, site_xpos, flange_xmat = data.qpos, data.site_xpos, data.site_xmat[self._flange]
        kinematics, tendon, ten_length = mujoco.mj_kinematics, mujoco.mj_tendon, data.ten_length
        for row, q in enumerate(q_actual):
            if frames is not None:
                self._place(Frames(*(part[row] for part in frames)))
            qpos[:] = q
            kinematics(model, data)
            if self._cable is not None:
                tendon(model, data)
                lengths[row] = ten_length[self._cable]
            sites[row] = site_xpos
            turns[row] = flange_xmat
        return AtRest(q_actual, lengths, sites[:, self._flange], sites[:, self._point],
                      turns.reshape(m, 3, 3))

    def _place(self, frames: Frames) -> None:
        """The bodies and sites of the model where :func:`twin.sim.builder.build_spec` puts
        them for one table (rigid: the model is the statics')."""
        model = self.model
        model.body_pos[self._links] = frames.link_pos
        model.body_quat[self._links] = frames.link_quat
        model.site_pos[self._flange], model.site_pos[self._point] = \
            frames.flange_pos, frames.point_pos
        model.site_quat[[self._flange, self._point]] = frames.site_quat

    def lengths(self, q_rad: ArrayLike, approach: ArrayLike | None = None) -> Array:
        """Noise-free cable lengths, shape (m,), m, with the controller at q (m, n) rad."""
        return self.at_rest(q_rad, approach).length_m

    def flange_positions(self, q_rad: ArrayLike, approach: ArrayLike | None = None) -> Array:
        """Flange centres in the base frame, shape (m, 3), m, with the controller at q."""
        return self.at_rest(q_rad, approach).flange_m

    def in_collision(self, q_rad: ArrayLike) -> NDArray[np.bool_]:
        """Whether the links touch each other or the floor at each pose, shape (m,)."""
        return self._scan(q_rad, True, None)

    def cable_blocked(self, q_rad: ArrayLike, clearance_m: float = 0.0) -> NDArray[np.bool_]:
        """Whether the straight cable from the port to the measured point passes through a
        link (never, without a cable).

        The last link, which the cable is attached to, is not counted.

        Args:
            q_rad: Joint angles, shape (m, n), rad.
            clearance_m: The cable must clear the geoms by this much before the flange, m.

        Returns:
            Shape (m,), True where the cable is blocked.
        """
        return self._scan(q_rad, False, clearance_m)

    def obstructed(self, q_rad: ArrayLike, clearance_m: float) -> NDArray[np.bool_]:
        """:meth:`in_collision` or :meth:`cable_blocked` at each pose, shape (m,), in one pass
        (the cable cast only where nothing touches): a pose's kinematics once, where the two
        tests took them twice (an eighth of drawing a capture's poses: 1.59 against 1.40 ms)."""
        return self._scan(q_rad, True, clearance_m)

    def _scan(self, q_rad: ArrayLike, contacts: bool, clearance_m: float | None
              ) -> NDArray[np.bool_]:
        """Where a pose fails MuJoCo's tests, shape (m,): with ``contacts``, links touching
        each other or the floor; with a clearance (and a cable), the straight cable from the
        port through a link before the flange by less than it (cast where nothing touches)."""
        model, data = self.model, self.data
        q = np.atleast_2d(np.asarray(q_rad, dtype=np.float64))
        port = None if clearance_m is None else self.port_m  # where the cable is cast from
        clearance = 0.0 if clearance_m is None else clearance_m
        if not contacts and port is None:
            return np.zeros(len(q), dtype=bool)
        failed = [False] * len(q)
        geom = np.zeros(1, dtype=np.int32)
        # Python floats for the three numbers of a pose's ray, and MuJoCo's arrays and
        # functions looked up once: numpy's calls on 3-vectors were half of a pose's test
        # (6.1 against 4.5 µs a pose, MuJoCo's own work 2.5 µs).
        qpos, point = data.qpos, data.site_xpos[self._point]
        kinematics, collision, cast = mujoco.mj_kinematics, mujoco.mj_collision, mujoco.mj_ray
        port_x, port_y, port_z = (0.0, 0.0, 0.0) if port is None else port.tolist()
        for row, pose in enumerate(q):
            qpos[:] = pose
            kinematics(model, data)
            if contacts:
                collision(model, data)
                if data.ncon > 0:
                    failed[row] = True
                    continue
            if port is not None:
                x, y, z = point.tolist()
                dx, dy, dz = x - port_x, y - port_y, z - port_z
                length = math.sqrt(dx * dx + dy * dy + dz * dz)
                ray = np.array((dx / length, dy / length, dz / length))
                hit = cast(model, data, port, ray, None, 1, self._link6, geom)
                failed[row] = 0.0 <= hit < length - clearance
        return np.array(failed, dtype=bool)
