"""The measurement model a calibration fits: unknowns x to residuals, with the analytic Jacobian.

For unknowns x (the blocks of its groups, :mod:`twin.unknowns`) and a pose q:

1. the kinematic table is the nominal plus every ``table`` group's correction, and each row's
   plus every ``rows`` group's for that row (a link's thermal growth: one table per row);
2. the joints stand at q plus every ``joints`` group's correction (transmission error,
   backlash, compliance);
3. the measured point sits at the rig's attachment plus every ``point`` group's correction, in
   the flange frame;
4. the forward kinematics (:mod:`twin.geometry.kinematics`) carry it to the base frame, and the
   measurement kind (:mod:`twin.kinds`) turns it into residuals, reading the ``measurement``
   groups (ports, offset…).

Every step is vectorised over a batch of x (the swarms evaluate hundreds at once) and over the
poses. The Jacobian is assembled by the chain rule from the kinematic Jacobians (table, joints,
point) and the kind's derivatives; ``tests/test_model.py`` checks it against finite
differences for every group.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import Array
from twin.dataset import Measurements, approach_directions
from twin.geometry.kinematics import (
    PointJacobian,
    Turns,
    distances,
    flange_turn_jacobian,
    point_distances,
    point_position,
    point_sum_squares,
    trace_point,
    turns,
)
from twin.kinds import Kind, KindJacobian, Measured
from twin.rig import Rig
from twin.robot import RobotModel
from twin.unknowns import Group, Stage, make_groups
from twin.unknowns.group import cached

NULL_RTOL = 1e-8
"""Singular values of the column-scaled Jacobian below this fraction of the largest make an
exact null direction (the rank tolerance of :mod:`twin.analysis.identifiability`)."""
FLANGE_ATOL = 1e-12
"""A fixed attachment closer than this to the flange centre, m, is the flange centre."""


@dataclass(frozen=True)
class Model:
    """Maps unknowns x to residuals for a nominal robot, a rig and a measurement kind.

    Attributes:
        robot: The nominal robot (its structure and table).
        rig: The nominal rig (ports, attachment).
        kind: How a measured point becomes residuals.
        groups: The unknown groups, in the order of x.
    """

    robot: RobotModel
    rig: Rig
    kind: Kind
    groups: tuple[Group, ...]
    _slices: dict[str, slice] = field(init=False, repr=False, compare=False)
    _size: int = field(init=False, repr=False, compare=False)
    _joint_columns: NDArray[np.intp] = field(init=False, repr=False, compare=False)
    _joint_turned: NDArray[np.intp] = field(init=False, repr=False, compare=False)
    _joint_sums: Array = field(init=False, repr=False, compare=False)
    _joint_basis: Callable[[Measurements], Array] = field(init=False, repr=False, compare=False)
    _turns: Callable[[Measurements], Turns] = field(init=False, repr=False, compare=False)
    _row_groups: tuple[Group, ...] = field(init=False, repr=False, compare=False)
    _table_maps: tuple[tuple[slice, Array | None], ...] = field(init=False, repr=False,
                                                                compare=False)
    _point_moves: bool = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        slices, start = {}, 0
        for group in self.groups:
            if group.name in slices:
                raise ValueError(f"unknown group {group.name!r} twice")
            if group.stage == Stage.MEASUREMENT and group.name not in self.kind.groups:
                raise ValueError(f"unknown group {group.name!r}: {self.kind.name} measurements "
                                 f"read only {', '.join(self.kind.groups) or 'no groups'}")
            slices[group.name] = slice(start, start + group.size)
            start += group.size
        object.__setattr__(self, "_slices", slices)
        object.__setattr__(self, "_size", start)
        # The coefficients of the joints-stage groups as one block: where each sits in x, and a
        # 0/1 matrix (P, n) that sums them onto the joint each turns.
        joint_groups = [group for group in self.groups if group.stage == Stage.JOINTS]
        columns = [np.arange(slices[group.name].start, slices[group.name].stop)
                   for group in joint_groups]
        turned = np.array([joint for group in joint_groups for joint in group.joint],
                          dtype=np.intp)
        sums = np.zeros((turned.size, self.robot.n_joints))
        sums[np.arange(turned.size), turned] = 1.0
        object.__setattr__(self, "_joint_columns", np.concatenate(columns) if columns
                           else np.zeros(0, dtype=np.intp))
        object.__setattr__(self, "_joint_turned", turned)
        object.__setattr__(self, "_joint_sums", sums)
        object.__setattr__(self, "_joint_basis", cached(self._joined_bases))
        # The measured joints never change during a fit: their cosines and sines are made once
        # per measurement set, and every evaluation on it reuses them.
        object.__setattr__(self, "_turns", cached(lambda data: turns(data.q_rad)))
        rows = tuple(group for group in self.groups if group.stage == Stage.ROWS)
        # The flange's orientation is read on the table without the rows' changes (one walk of
        # the frame serves every row): exact for changes of lengths alone, which do not turn it.
        turning = ~self.robot.structure.is_length.ravel()
        turns_flange = [group.name for group in rows
                        if group.linear is not None and np.count_nonzero(group.linear[turning])]
        if turns_flange and self.kind.reads_rotation:
            raise ValueError(f"{', '.join(turns_flange)}: not with {self.kind.what}, which "
                             "read the flange's orientation")
        object.__setattr__(self, "_row_groups", rows)
        # Each table group's place in x and its map's transpose; None where the map is the
        # identity (the D-H errors, entry by entry): the swarms' (K, 4n) @ (4n, 4n) product
        # with it was a tenth of their batched evaluation's Python-side time, for x itself.
        maps = []
        for group in self.groups:
            if group.stage == Stage.TABLE:
                assert group.linear is not None
                identity = group.linear.shape == (group.size, group.size) \
                    and np.array_equal(group.linear, np.eye(group.size))
                maps.append((slices[group.name], None if identity else group.linear.T))
        object.__setattr__(self, "_table_maps", tuple(maps))
        object.__setattr__(self, "_point_moves",
                           any(group.stage == Stage.POINT for group in self.groups))

    # --- the unknowns ---------------------------------------------------------------------

    @property
    def n_params(self) -> int:
        """Length p of the unknown vector x."""
        return self._size

    @property
    def names(self) -> tuple[str, ...]:
        """Names of the unknowns, in the order of x."""
        return tuple(name for group in self.groups for name in group.names)

    @property
    def units(self) -> tuple[str, ...]:
        """SI unit of each unknown (``m``, ``rad``…), in the order of x."""
        return tuple(unit for group in self.groups for unit in group.units)

    @property
    def is_length(self) -> NDArray[np.bool_]:
        """Whether each unknown is a length (m), shape (p,)."""
        return np.array([unit == "m" for unit in self.units], dtype=bool)

    @property
    def radius(self) -> Array:
        """A typical error of each unknown, shape (p,): the spread of a swarm's first particles."""
        return np.concatenate([group.radius for group in self.groups]) if self.groups \
            else np.zeros(0)

    def bounds(self) -> tuple[Array, Array]:
        """Search box (lower, upper), each shape (p,)."""
        return (np.concatenate([group.lower for group in self.groups]),
                np.concatenate([group.upper for group in self.groups]))

    def prior_weight(self) -> Array:
        """1/σ of each unknown's zero-mean Gaussian prior, 0 where none, shape (p,)."""
        return np.concatenate([group.prior_weight for group in self.groups]) if self.groups \
            else np.zeros(0)

    def scale(self) -> Array:
        """How far each unknown may plausibly move, shape (p,): its prior's σ, else half its
        search range — the unit of the step tests and of the norm in which what the data
        cannot see is held at the nominal (:mod:`twin.analysis.unseen`)."""
        lower, upper = self.bounds()
        weight = self.prior_weight()
        return np.where(weight > 0, 1.0 / np.where(weight > 0, weight, 1.0),
                        0.5 * (upper - lower))

    @property
    def needs_approach(self) -> bool:
        """Whether a group reads the direction each joint approached its pose from (backlash):
        measurements without it cannot be fitted or predicted."""
        return any(group.needs_approach for group in self.groups)

    def has(self, name: str) -> bool:
        """Whether the group ``name`` is among the unknowns."""
        return name in self._slices

    def slice(self, name: str) -> slice:
        """Where group ``name`` sits in x.

        Raises:
            KeyError: if the model has no such group.
        """
        return self._slices[name]

    def block(self, x: ArrayLike, name: str) -> Array:
        """Group ``name``'s block of x (..., p), shape (..., p_g)."""
        return np.asarray(x, dtype=np.float64)[..., self.slice(name)]

    def group(self, name: str) -> Group:
        """The group called ``name``."""
        return self.groups[list(self._slices).index(name)]

    def with_rig(self, rig: Rig, x: ArrayLike) -> tuple[Model, Array]:
        """This model for another rig (other ports, another cable tension), and unknowns x (p,)
        carried over: the groups are made again for it (compliance depends on the cable's
        pull), with the bounds, priors and fixed parameters they had; a group whose size
        changes with the rig (a correction per port) starts again at zero.

        Returns:
            ``(model, x)``: the model for ``rig`` and its unknowns, shape (p',).
        """
        x = self._check(x)
        model = Model(self.robot, rig, self.kind, tuple(
            group.like(self.group(group.name)) for group in
            make_groups([group.name for group in self.groups], self.robot, rig)))
        carried = np.zeros(model.n_params)
        for group in model.groups:
            if group.size == self.group(group.name).size:
                carried[model.slice(group.name)] = self.block(x, group.name)
        return model, carried

    def _check(self, x: ArrayLike) -> Array:
        x = np.asarray(x, dtype=np.float64)
        if x.shape[-1:] != (self.n_params,):
            raise ValueError(f"x: shape {x.shape}, expected (..., {self.n_params})")
        return x

    @property
    def measures_flange(self) -> bool:
        """Whether the measured point is the flange centre at every x: no point group, and the
        rig's attachment within :data:`FLANGE_ATOL` of the centre. Its positions and their
        Jacobians are then the flange's, and are not worked out twice."""
        return not self._point_moves \
            and float(np.max(np.abs(self.rig.attachment_m))) <= FLANGE_ATOL

    # --- the chain ------------------------------------------------------------------------

    def table(self, x: ArrayLike) -> Array:
        """The kinematic tables of unknowns x (..., p): shape (..., 4, n), m and rad."""
        x = self._check(x)
        shape = (*x.shape[:-1], *self.robot.dh.shape)
        table = self.robot.dh
        for where, linear_t in self._table_maps:
            correction = x[..., where] if linear_t is None else x[..., where] @ linear_t
            table = table + correction.reshape(shape)
        return table if table.shape == shape else np.broadcast_to(table, shape)

    def point(self, x: ArrayLike) -> Array:
        """The measured point in the flange frame for unknowns x (..., p): shape (..., 3), m."""
        x = self._check(x)
        shape = (*x.shape[:-1], 3)
        point = self.rig.attachment_m
        for group in self.groups:
            if group.stage == Stage.POINT:
                assert group.linear is not None
                point = point + self.block(x, group.name) @ group.linear.T
        return point if point.shape == shape else np.broadcast_to(point, shape)

    def joints(self, x: ArrayLike, data: Measurements) -> Array:
        """Where the joints stand: recorded angles plus the joint-level corrections of x (..., p),
        shape (m, n) without joint groups, else (..., m, n), rad."""
        return self._joint_turns(self._check(x), data).q_rad

    def _joint_turns(self, x: Array, data: Measurements) -> Turns:
        """:meth:`joints` with their cosines and sines, from the measurement set's own."""
        measured = self._turns(data)
        if not self._joint_columns.size:
            return measured
        shift = self._joint_basis(data) * x[..., None, self._joint_columns]  # (..., m, P)
        return measured.shifted(shift @ self._joint_sums)

    def _joined_bases(self, data: Measurements) -> Array:
        """How far each joint-level coefficient turns its joint at each pose, (m, P), rad per
        unit, in the order of :attr:`_joint_columns` (kept per measurement set as
        :attr:`_joint_basis`)."""
        bases = [group.basis(data) for group in self.groups
                 if group.stage == Stage.JOINTS and group.basis is not None]
        return np.concatenate(bases, axis=1) if len(bases) > 1 else bases[0]

    def positions(self, x: ArrayLike, data: Measurements) -> Array:
        """The measured point in the base frame at every pose, shape (..., m, 3), m."""
        x = self._check(x)
        return self._place(x, data, self._point_m(x))

    def _point_m(self, x: Array) -> Array:
        """The measured point in the flange frame for unknowns (..., p): (..., 3) or (3,), m."""
        # Without a point group the point is the rig's attachment for every x: handed over
        # once (the kernel then carries one start, not a copy per candidate), the same numbers.
        return self.point(x) if self._point_moves else self.rig.attachment_m

    def _kinematics(self, x: Array, data: Measurements) -> tuple[Array, Turns]:
        """What the kinematics read: the table (..., 4, n) and the joints (..., m, n); with a
        ``rows`` group, each row's own table (..., m, 4, n) and its joints as that table's one
        pose (..., m, 1, n)."""
        table, joints = self.table(x), self._joint_turns(x, data)
        if not self._row_groups:
            return table, joints
        rows = table[..., None, :, :]
        for group in self._row_groups:
            assert group.linear is not None and group.basis is not None
            change = (self.block(x, group.name)[..., None, :] * group.basis(data)) \
                @ group.linear.T  # (..., m, 4n)
            rows = rows + change.reshape(*change.shape[:-1], *self.robot.dh.shape)
        return rows, Turns(joints.q_rad[..., None, :], joints.cos[..., None],
                           joints.sin[..., None])

    def _place(self, x: Array, data: Measurements, point_m: Array | None = None) -> Array:
        """A point fixed to the flange (..., 3) or (3,), m, at every pose, (..., m, 3), m."""
        table, joints = self._kinematics(x, data)
        if not self._row_groups:
            return point_position(self.robot.structure, table, joints, point_m)
        # A point of each candidate (..., 3) broadcast over its rows; one point as it is, which
        # the compiled kernel takes (a (1, 3) batch of points was beyond it: every thermal
        # model's rows took numpy's path in a study's workers).
        point = None if point_m is None else np.asarray(point_m)
        if point is not None and point.ndim > 1:
            point = point[..., None, :]
        return point_position(self.robot.structure, table, joints, point)[..., 0, :]

    def _trace(self, x: Array, data: Measurements, point_m: Array | None
               ) -> tuple[Array, Callable[[Array | None], PointJacobian]]:
        """The point at every pose (m, 3), m, at one x, and how it moves along directions
        (m, r, 3) or the base axes (None): :meth:`PointTrace.jacobian` of the row tables'
        traces too."""
        table, joints = self._kinematics(x, data)
        trace = trace_point(self.robot.structure, table, joints, point_m)
        if not self._row_groups:
            return trace.position, trace.jacobian

        def moves(directions: Array | None) -> PointJacobian:
            along = None if directions is None else directions[:, None]
            return PointJacobian(*(part[:, 0] for part in trace.jacobian(along)))

        return trace.position[:, 0], moves

    def _measurement_values(self, x: Array) -> dict[str, Array]:
        return {group.name: self.block(x, group.name) for group in self.groups
                if group.stage == Stage.MEASUREMENT}

    def poses(self, q_rad: ArrayLike, approach: ArrayLike | None = None,
              **labels: ArrayLike | None) -> Measurements:
        """Poses where nothing was read, as measurements of this model's kind with zero
        readings: for the positions, flanges and Jacobians at poses of one's choosing.

        Args:
            q_rad: Joint angles, shape (m, n), rad.
            approach: Direction each joint last moved in, shape (m, n), ±1, if known. If None
                and the model needs it (:attr:`needs_approach`): the directions of visiting
                the poses in the order given, from home (:func:`twin.dataset.approach_directions`).
            labels: The index of each row into the kind's labels, shape (m,) each (``port``
                for cable lengths, ``point`` for fixed points…); the first if not given (or
                None).
        """
        q = np.asarray(q_rad, dtype=np.float64)
        if approach is None and self.needs_approach:
            approach = approach_directions(q)
        template = self.kind.template(q, self.rig, {name: np.asarray(index, dtype=np.intp)
                                                    for name, index in labels.items()
                                                    if index is not None})
        return template if approach is None else replace(template,
                                                         approach=np.asarray(approach))

    def measure(self, x: ArrayLike, q_rad: ArrayLike, approach: ArrayLike | None = None,
                **labels: ArrayLike | None) -> Measurements:
        """Noise-free measurements of this model's kind at unknowns x (p,) and poses q (m, n):
        what the model fits exactly (arguments as :meth:`poses`)."""
        return self.read(x, self.poses(q_rad, approach, **labels))

    def read(self, x: ArrayLike, template: Measurements) -> Measurements:
        """Noise-free measurements of this model's kind at unknowns x (p,) on the rows of a
        template (:meth:`poses`, with any per-row column the model reads: a temperature)."""
        x = self._check(x)
        return self.kind.measure(self.measured(x, template), self._measurement_values(x),
                                 template, self.rig)

    def measured(self, x: ArrayLike, data: Measurements) -> Measured:
        """Where the measured point is at every pose for unknowns x (..., p), and the flange's
        orientation if the kind reads it (:class:`twin.kinds.base.Measured`)."""
        x = self._check(x)
        if not self.kind.reads_rotation:
            return Measured(self.positions(x, data))
        return Measured(self.positions(x, data), self._rotations(x, data))

    def flange_rotations(self, x: ArrayLike, data: Measurements) -> Array:
        """The flange's orientation base_R_flange at every pose, for unknowns x (..., p): shape
        (..., m, 3, 3)."""
        return self._rotations(self._check(x), data)

    def _rotations(self, x: Array, data: Measurements) -> Array:
        # The flange's axes as the points one metre along them less its origin: the point
        # kernel (compiled where it can be) carries a swarm's tables at once, where a walk
        # of the whole frame would not (and a walk of 500 workspace poses took 0.5 ms).
        origin = self._place(x, data)
        axes = [self._place(x, data, axis) - origin for axis in np.eye(3)]
        return np.stack(axes, axis=-1)

    def flange_positions(self, x: ArrayLike, data: Measurements) -> Array:
        """The flange centre (not the measured point) at every pose, for unknowns x (..., p):
        shape (..., m, 3), m, base frame — where the identified model puts the flange."""
        return self._place(self._check(x), data)

    def flange_jacobian(self, x: ArrayLike, data: Measurements) -> Array:
        """∂(flange centre)/∂x at every pose, shape (m, 3, p), for unknowns x (p,): the table and
        joint groups move the flange; the rig's unknowns and the measured point do not."""
        return self._chain_jacobian(self._check(x), data, measured=False)

    def position_jacobian(self, x: ArrayLike, data: Measurements) -> Array:
        """∂(measured point, base frame)/∂x at every pose, shape (m, 3, p), for unknowns x (p,):
        the table, joint and point groups move it; the instrument's unknowns do not."""
        return self._chain_jacobian(self._check(x), data, measured=True)

    def _chain_jacobian(self, x: Array, data: Measurements, measured: bool) -> Array:
        _, moves = self._trace(x, data, self.point(x) if measured else None)
        jacobian = np.zeros((len(data), 3, self.n_params))
        self._chain_rule(moves(None), data, measured, jacobian)
        return jacobian

    def _chain_rule(self, moves: PointJacobian, data: Measurements, measured: bool,
                    out: Array) -> None:
        """Write into ``out`` (m, r, p) the derivatives of the r rows of every pose w.r.t. the
        table, joint and (if ``measured``) point groups, from the point's derivatives along
        those rows (:meth:`twin.geometry.kinematics.PointTrace.jacobian`); other columns stay as
        they are."""
        m, rows = out.shape[:2]
        if self._joint_columns.size:
            # Coefficient c turns joint j(c) by basis[:, c]: its column is ∂r/∂q_j(c) times that.
            out[..., self._joint_columns] = (moves.joints[..., self._joint_turned]
                                             * self._joint_basis(data)[:, None, :])
        for group in self.groups:
            where = self.slice(group.name)
            if group.stage in (Stage.TABLE, Stage.ROWS):
                assert group.linear is not None
                table = moves.table.reshape(m * rows, -1)
                out[..., where] = (table @ group.linear).reshape(m, rows, -1)
                if group.basis is not None:  # each row's share of the coefficient
                    out[..., where] *= group.basis(data)[:, None, :]
            elif group.stage == Stage.POINT and measured:
                assert group.linear is not None
                point = moves.rotation.reshape(m * rows, 3)
                out[..., where] = (point @ group.linear).reshape(m, rows, -1)

    # --- residuals ------------------------------------------------------------------------

    def residuals(self, x: ArrayLike, data: Measurements) -> Array:
        """Residuals r(x), shape (..., M), m, for unknowns of shape (..., p)."""
        x = self._check(x)
        values = self._measurement_values(x)
        ranges = self.kind.ranges(values, data, self.rig)
        if ranges is None:
            return self.kind.residuals(self.measured(x, data), values, data, self.rig)
        return ranges.residuals(self._distances(x, data, ranges.anchors_m))

    def sum_squares(self, x: ArrayLike, data: Measurements) -> Array | None:
        """Σ r² over the residual rows, shape (...,), m², for unknowns (..., p), summed in the
        chain's pass where the kind's rows are its distances less the readings
        (:attr:`twin.kinds.base.Ranges.readings_m`; a swarm's least-squares cost,
        :func:`twin.geometry.kinematics.point_sum_squares`); None where they are not (its
        caller sums :meth:`residuals`)."""
        x = self._check(x)
        ranges = self.kind.ranges(self._measurement_values(x), data, self.rig)
        if ranges is None or ranges.readings_m is None or self._row_groups:
            return None
        table, joints = self._kinematics(x, data)
        return point_sum_squares(self.robot.structure, table, joints, self._point_m(x),
                                 ranges.anchors_m, ranges.readings_m)

    def _distances(self, x: Array, data: Measurements, anchors_m: Array) -> Array:
        """The measured point's distance from each row's anchor, (..., m), m, for unknowns
        (..., p) — the kind's distances (:meth:`twin.kinds.base.Kind.ranges`) in one
        pass of the chain (a swarm's candidates: no (..., m, 3) points)."""
        point = self._point_m(x)
        if self._row_groups:
            return distances(self._place(x, data, point), anchors_m)
        table, joints = self._kinematics(x, data)
        return point_distances(self.robot.structure, table, joints, point, anchors_m)

    def jacobian(self, x: ArrayLike, data: Measurements) -> tuple[Array, Array]:
        """Residuals and their analytic Jacobian at one x.

        Args:
            x: Unknowns, shape (p,).
            data: The poses and readings.

        Returns:
            ``(r, J)``: residuals (M,) in m, Jacobian ∂r/∂x (M, p).
        """
        kind, moves = self._moves(self._check(x), data)
        m, rows = len(data), self.kind.rows_per_pose
        jacobian = np.zeros((kind.residuals.size, self.n_params))
        self._chain_rule(moves, data, True, jacobian[: m * rows].reshape(m, rows, self.n_params))
        for group in self.groups:
            if group.stage == Stage.MEASUREMENT:
                jacobian[:, self.slice(group.name)] = kind.by_group[group.name]
        return kind.residuals, jacobian

    def joint_jacobian(self, x: ArrayLike, data: Measurements) -> Array:
        """How each residual row moves with the recorded joint angles, ∂r/∂q, shape (M, n),
        m/rad, at one x (p,): the rows that are not a pose's (known distances) do not move.
        Noise in the recorded angles reaches the rows through it (errors in variables); a
        joint-level correction's own dependence on q is second order and left out."""
        kind, moves = self._moves(self._check(x), data)
        m, rows = len(data), self.kind.rows_per_pose
        joints = np.zeros((kind.residuals.size, self.robot.n_joints))
        joints[: m * rows] = moves.joints.reshape(m * rows, -1)
        return joints

    def _moves(self, x: Array, data: Measurements) -> tuple[KindJacobian, PointJacobian]:
        """The kind's residuals and derivatives at one x, and how each pose's rows move with
        the table, the joints and the measured point (:meth:`_chain_rule` takes them to x)."""
        position, trace = self._trace(x, data, self.point(x))
        flange = by_table = by_joint = None
        if self.kind.reads_rotation:
            flange, by_table, by_joint = flange_turn_jacobian(self.robot.structure,
                                                              self.table(x),
                                                              self._joint_turns(x, data).q_rad)
        kind = self.kind.jacobian(Measured(position, flange), self._measurement_values(x), data,
                                  self.rig)
        # The kind's rows move with the point along ∂r/∂p: the point's derivatives are taken
        # along those directions alone (one row per pose for a length, not three).
        moves = trace(kind.by_position)
        if kind.by_rotation is not None and by_table is not None and by_joint is not None:
            # Rows that read the flange's orientation turn with it: ∂r/∂ω times the flange's
            # angular velocity per table entry and per joint rate.
            moves = moves._replace(table=moves.table + kind.by_rotation @ by_table,
                                   joints=moves.joints + kind.by_rotation @ by_joint)
        return kind, moves

    def symmetries(self, x: ArrayLike) -> Array:
        """The kind's known gauge directions at x (:meth:`twin.kinds.base.Kind.symmetries`),
        shape (p, g)."""
        return self.kind.symmetries(self, self._check(x))

    def identifiable_jacobian(self, x: ArrayLike, data: Measurements,
                              rtol: float = NULL_RTOL) -> tuple[Array, Array]:
        """:meth:`jacobian` with the kind's known gauge directions G projected out: what the
        data can identify. Equal to :meth:`jacobian` for kinds without such directions (cable
        lengths, tracker positions).

        Along G the rows move by the size of the residuals only (the cost is flat there), so the
        projection subtracts noise-sized columns: ``J − (J B) B⁺`` with ``B = [G, N]``, N the
        exact null directions of J (singular values of the column-scaled J below ``rtol`` of the
        largest), so that G joins the null space and N stays in it. (Projecting on G alone,
        orthogonally, would smear J G into exact null directions that overlap G — a shift
        along joint 1's axis overlaps a scale — and turn them weak.)
        """
        r, jacobian = self.jacobian(x, data)
        gauge = self.symmetries(x)
        if not gauge.shape[1]:
            return r, jacobian
        norms = np.linalg.norm(jacobian, axis=0)
        unit = np.where(norms > rtol * np.max(norms), norms, 1.0)
        # Every row of V, but no more of U than V needs: a full U is (m, m).
        _, s, vt = np.linalg.svd(jacobian / unit,
                                 full_matrices=jacobian.shape[0] < jacobian.shape[1])
        s = np.concatenate([s, np.zeros(self.n_params - s.size)])
        null = vt[s <= rtol * s[0]].T / unit[:, None]
        basis = np.concatenate([gauge, null], axis=1)
        return r, jacobian - (jacobian @ basis) @ np.linalg.pinv(basis)
