"""The hot kernel compiled with numba (optional extra ``fast``): a flange point carried to the
base for a batch of tables and poses, and its Jacobian along chosen directions.

The same algorithm as :mod:`twin.geometry.kinematics` (the reference, and the path taken
without numba): the point is carried from the flange to the base through the elementary
motions of :data:`~twin.geometry.kinematics._MOTIONS`, each direction w from the base to the
flange, and a motion's column is w·e (translation along e) or w·(e × p) (rotation about e), p
the point in the frame before the motion. Loops run over motions outside and poses inside, so
the compiler vectorises over poses. Compiled once and cached on disk (``cache=True``): the
first call in a fresh install compiles, later processes load the machine code.

A revolute joint's variable adds to its θ, whose cosine and sine come from the poses' cached
cos q, sin q by the angle-sum identity; a prismatic joint's adds to the translation it drives
(its d, or a Hayati joint's slot-less slide), read from the joint values themselves — a chain
without one never reads them.

On that Jacobian, :func:`position_ik` takes the damped Newton steps of
:func:`twin.compensation.ik.solve_ik` for positions alone (a touch capture's inverse
kinematics), every row in one call, where numpy paid its overhead at each step.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from twin.arrays import Array


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _angles(table: Array, plan: Array, cq: Array, sq: Array, k: int, kq: int, m: int
            ) -> tuple[Array, Array]:
    """cos and sin of every rotation's angle for table k at every pose, shape (motions, m)
    each (a translation's rows unset); a revolute joint's is q + θ, the others the table's (the
    same at every pose): what the Jacobian's directions turn by on their way out."""
    motions = plan.shape[0]
    cos = np.empty((motions, m))
    sin = np.empty((motions, m))
    for index in range(motions):
        if plan[index, 0] == 1:
            continue
        slot, joint, driven = plan[index, 2], plan[index, 3], plan[index, 4]
        value = table[k, slot, joint]
        c, s = math.cos(value), math.sin(value)
        if driven:
            for i in range(m):
                cos[index, i] = cq[joint, kq, i] * c - sq[joint, kq, i] * s
                sin[index, i] = sq[joint, kq, i] * c + cq[joint, kq, i] * s
        else:
            for i in range(m):
                cos[index, i] = c
                sin[index, i] = s
    return cos, sin


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _carry(table: Array, plan: Array, cq: Array, sq: Array, slides: Array, k: int, kq: int,
           start: Array, kp: int, p: Array, before: Array, keep: bool) -> None:
    """Carry the point from the flange to the base for table k into ``p`` (3, m); with
    ``keep``, the point in the frame before each rotation into ``before`` (motions, 3, m).

    Each rotation's cosine and sine are made where they are used: a rotation the poses do not
    drive turns every pose by the same two numbers, a revolute joint's turn by q + θ from the
    poses' cos q, sin q (the angle sum, as :func:`_angles`). Written to arrays of m copies
    first (as the Jacobian's way out needs them), they took two thirds of a swarm's
    positions."""
    m = p.shape[1]
    for axis in range(3):
        for i in range(m):
            p[axis, i] = start[kp, axis]
    index = plan.shape[0]
    while index > 0:
        index -= 1
        kind, axis, slot, joint = plan[index, 0], plan[index, 1], plan[index, 2], plan[index, 3]
        if plan[index, 6] and not keep:
            _dh_joint(table, k, joint, cq, sq, kq, p)
            index -= 3
            continue
        if kind == 1:
            value = table[k, slot, joint] if slot >= 0 else 0.0
            if plan[index, 4]:  # a prismatic joint's slide: its travel at each pose
                for i in range(m):
                    p[axis, i] += value + slides[joint, kq, i]
                continue
            for i in range(m):
                p[axis, i] += value
            continue
        ja, jb = (axis + 1) % 3, (axis + 2) % 3
        c, s = math.cos(table[k, slot, joint]), math.sin(table[k, slot, joint])
        if plan[index, 4]:
            for i in range(m):
                ci = cq[joint, kq, i] * c - sq[joint, kq, i] * s
                si = sq[joint, kq, i] * c + cq[joint, kq, i] * s
                pa, pb = p[ja, i], p[jb, i]
                p[ja, i] = ci * pa - si * pb
                p[jb, i] = si * pa + ci * pb
        else:
            for i in range(m):
                pa, pb = p[ja, i], p[jb, i]
                p[ja, i] = c * pa - s * pb
                p[jb, i] = s * pa + c * pb
        if keep:
            for row in range(3):
                for i in range(m):
                    before[index, row, i] = p[row, i]


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _dh_joint(table: Array, k: int, joint: int, cq: Array, sq: Array, kq: int, p: Array
              ) -> None:
    """Carry the points p (3, m) through a revolute standard D-H joint of table k, flange side
    first: Rx(α), Tx(a), Tz(d), Rz(q + θ). The operations :func:`_carry` does motion by motion,
    in the same order (equal bits), in one pass over the poses: a motion per pass read and
    wrote every point four times, and the stores bounded the swarm's positions."""
    ca, sa = math.cos(table[k, 2, joint]), math.sin(table[k, 2, joint])
    ct, st = math.cos(table[k, 3, joint]), math.sin(table[k, 3, joint])
    a, d = table[k, 0, joint], table[k, 1, joint]
    for i in range(p.shape[1]):
        y = ca * p[1, i] - sa * p[2, i]
        z = sa * p[1, i] + ca * p[2, i] + d
        x = p[0, i] + a
        ci = cq[joint, kq, i] * ct - sq[joint, kq, i] * st
        si = sq[joint, kq, i] * ct + cq[joint, kq, i] * st
        p[0, i] = ci * x - si * y
        p[1, i] = si * x + ci * y
        p[2, i] = z


# Inlined where it is called (numba's IR): as a call it took a third of the positions' time,
# its output possibly sharing memory with p for all the compiler could tell.
@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _to_base(base: Array, p: Array, out: Array, k: int) -> None:
    """out[k] = the points p (3, m) in the base frame, (m, 3)."""
    for i in range(p.shape[1]):
        for row in range(3):
            out[k, i, row] = (base[row, 0] * p[0, i] + base[row, 1] * p[1, i]
                              + base[row, 2] * p[2, i] + base[row, 3])


@numba.njit(cache=True, nogil=True, error_model="numpy")
def positions(table: Array, plan: Array, cq: Array, sq: Array, slides: Array, start: Array,
              base: Array) -> Array:
    """The point in the base frame for K tables at m poses.

    Args:
        table: Tables, shape (K, 4, n), m and rad.
        plan: The motions base to flange, rows (kind, axis, slot, joint, driven, column,
            whole), (motions, 7); slot −1 for a motion without a table entry; ``whole`` on
            the flange-side motion of a revolute standard D-H joint (carried in one pass).
        cq: cos q joint-major, shape (n, 1 or K, m). sq: sin q, likewise.
        slides: q joint-major, shape (n, 1 or K, m), read for prismatic joints only (any
            shape without one).
        start: The point in the last joint's frame (tool applied), shape (1 or K, 3), m.
        base: The base transform, (4, 4).

    Returns:
        Shape (K, m, 3), m.
    """
    tables, m = table.shape[0], cq.shape[2]
    out = np.empty((tables, m, 3))
    p = np.empty((3, m))
    unused = np.empty((0, 3, m))
    for k in range(tables):
        kq, kp = min(k, cq.shape[1] - 1), min(k, start.shape[0] - 1)
        _carry(table, plan, cq, sq, slides, k, kq, start, kp, p, unused, False)
        _to_base(base, p, out, k)
    return out


_LANES = 8
"""Running sums of :func:`anchored_sum_squares`: a vector register's doubles (AVX-512)."""


# Inlined where it is called, as _to_base: the loops vectorise over the poses.
@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _squares(table: Array, plan: Array, cq: Array, sq: Array, slides: Array, start: Array,
             base: Array, anchors: Array, k: int, p: Array, anchor: Array, square: Array,
             unused: Array) -> None:
    """Into ``square`` (m,) the squared distance of table k's point from each row's anchor,
    the point carried into ``p`` (3, m) and the anchors copied coordinate-major into
    ``anchor`` (3, m) at the first table (and at every table when each has its own);
    ``unused``, (0, 3, m), is what :func:`_carry` keeps nothing in."""
    m = square.shape[0]
    kq, kp, ka = (min(k, cq.shape[1] - 1), min(k, start.shape[0] - 1),
                  min(k, anchors.shape[0] - 1))
    _carry(table, plan, cq, sq, slides, k, kq, start, kp, p, unused, False)
    if k == 0 or anchors.shape[0] > 1:
        # Coordinate-major, as p: the loops below vectorise over the poses, where reading
        # the anchors in place and summing into out did not (slower than the two passes).
        for i in range(m):
            for row in range(3):
                anchor[row, i] = anchors[ka, i, row]
    for i in range(m):
        square[i] = 0.0
    for row in range(3):  # the squares summed x, y, z, as distances() sums them
        for i in range(m):
            step = (base[row, 0] * p[0, i] + base[row, 1] * p[1, i]
                    + base[row, 2] * p[2, i] + base[row, 3]) - anchor[row, i]
            square[i] += step * step


@numba.njit(cache=True, nogil=True, error_model="numpy")
def anchored_distances(table: Array, plan: Array, cq: Array, sq: Array, slides: Array,
                       start: Array, base: Array, anchors: Array) -> Array:
    """The distance of the point from each row's anchor for K tables at m poses, the point
    carried as :func:`positions` carries it and never stored: :func:`distances` of its
    positions, bit for bit, without their (K, m, 3) array (a swarm's cable lengths, 200 tables
    at 96 poses: 344 µs against the two passes' 414 µs, the chain alone 294 µs).

    Args:
        table, plan, cq, sq, slides, start, base: As :func:`positions`.
        anchors: The anchor of each row, shape (1 or K, m, 3), m.

    Returns:
        Shape (K, m), m.
    """
    tables, m = table.shape[0], cq.shape[2]
    out = np.empty((tables, m))
    p, anchor, square, unused = (np.empty((3, m)), np.empty((3, m)), np.empty(m),
                                 np.empty((0, 3, m)))
    for k in range(tables):
        _squares(table, plan, cq, sq, slides, start, base, anchors, k, p, anchor, square,
                 unused)
        for i in range(m):
            out[k, i] = math.sqrt(square[i])
    return out


@numba.njit(cache=True, nogil=True, error_model="numpy")
def anchored_sum_squares(table: Array, plan: Array, cq: Array, sq: Array, slides: Array,
                         start: Array, base: Array, anchors: Array, readings: Array) -> Array:
    """Σ_i (d_i − L_i)² for K tables, d_i the distance of :func:`anchored_distances` (the same
    bits) and L_i the reading of row i, summed in the same pass: a swarm's least-squares cost
    without the (K, m) distances and residuals (200 tables at 96 poses: 123 µs, against 143 µs
    for the distances and numpy's three passes after them).

    Args:
        table, plan, cq, sq, slides, start, base, anchors: As :func:`anchored_distances`.
        readings: Each row's reading, shape (m,), m.

    Returns:
        Shape (K,), m².
    """
    tables, m = table.shape[0], cq.shape[2]
    out = np.empty(tables)
    p, anchor, square, unused = (np.empty((3, m)), np.empty((3, m)), np.empty(m),
                                 np.empty((0, 3, m)))
    lanes = np.empty(_LANES)
    whole = m - m % _LANES
    for k in range(tables):
        _squares(table, plan, cq, sq, slides, start, base, anchors, k, p, anchor, square,
                 unused)
        for i in range(m):  # elementwise: vectorised over the poses
            residual = math.sqrt(square[i]) - readings[i]
            square[i] = residual * residual
        # Summed in _LANES running sums, as numpy's pairwise sum starts: one sum in order
        # waits on every addition before it (129 µs against 123 µs above).
        lanes[:] = 0.0
        for i in range(0, whole, _LANES):
            for lane in range(_LANES):
                lanes[lane] += square[i + lane]
        total = 0.0
        for i in range(whole, m):
            total += square[i]
        for lane in range(_LANES):
            total += lanes[lane]
        out[k] = total
    return out


@numba.njit(cache=True, nogil=True, error_model="numpy")
def jacobian(table: Array, plan: Array, cq: Array, sq: Array, slides: Array, start: Array,
             base: Array, tool: Array, directions: Array, n_columns: int
             ) -> tuple[Array, Array, Array]:
    """The point and its derivatives along r directions per pose, for K tables at m poses.

    Args:
        table, plan, cq, sq, slides, start, base: As :func:`positions`.
        tool: The tool transform, (4, 4).
        directions: Directions in the base frame, shape (1 or K, 1 or m, r, 3).
        n_columns: Number of derivative columns (the plan's largest column + 1).

    Returns:
        ``(position, columns, rotation)``: shapes (K, m, 3), (K, m, r, n_columns) — the
        error vector's order (slot-major), then the slot-less slides —, (K, m, r, 3).
    """
    tables, m, motions, r = table.shape[0], cq.shape[2], plan.shape[0], directions.shape[2]
    position = np.empty((tables, m, 3))
    columns = np.empty((tables, m, r, n_columns))
    rotation = np.empty((tables, m, r, 3))
    before = np.empty((motions, 3, m))
    p = np.empty((3, m))
    w = np.empty((3, m))
    for k in range(tables):
        kq, kp, kw = (min(k, cq.shape[1] - 1), min(k, start.shape[0] - 1),
                      min(k, directions.shape[0] - 1))
        _carry(table, plan, cq, sq, slides, k, kq, start, kp, p, before, True)
        cos, sin = _angles(table, plan, cq, sq, k, kq, m)
        _to_base(base, p, position, k)
        for direction in range(r):
            for i in range(m):
                iw = min(i, directions.shape[1] - 1)
                for row in range(3):  # R_baseᵀ w
                    w[row, i] = (base[0, row] * directions[kw, iw, direction, 0]
                                 + base[1, row] * directions[kw, iw, direction, 1]
                                 + base[2, row] * directions[kw, iw, direction, 2])
            for index in range(motions):
                kind, axis, column = plan[index, 0], plan[index, 1], plan[index, 5]
                if kind == 1:
                    for i in range(m):
                        columns[k, i, direction, column] = w[axis, i]
                    continue
                ja, jb = (axis + 1) % 3, (axis + 2) % 3
                for i in range(m):
                    c, s = cos[index, i], sin[index, i]
                    wa, wb = w[ja, i], w[jb, i]
                    columns[k, i, direction, column] = (wb * before[index, ja, i]
                                                        - wa * before[index, jb, i])
                    w[ja, i] = c * wa + s * wb
                    w[jb, i] = c * wb - s * wa
            for i in range(m):
                for row in range(3):  # R_toolᵀ w
                    rotation[k, i, direction, row] = (tool[0, row] * w[0, i]
                                                      + tool[1, row] * w[1, i]
                                                      + tool[2, row] * w[2, i])
    return position, columns, rotation


@numba.njit(cache=True, nogil=True, error_model="numpy")
def distances(points: Array, anchors: Array) -> Array:
    """‖point − anchor‖ of every row in one pass, written as :func:`twin.arrays.lengths` is
    (the same numbers bit for bit).

    Args:
        points: Points, shape (K, m, 3), m.
        anchors: The anchor of each row, shape (1 or K, m, 3), m.

    Returns:
        Shape (K, m), m.
    """
    tables, m = points.shape[0], points.shape[1]
    out = np.empty((tables, m))
    for k in range(tables):
        ka = min(k, anchors.shape[0] - 1)
        for i in range(m):
            x = points[k, i, 0] - anchors[ka, i, 0]
            y = points[k, i, 1] - anchors[ka, i, 1]
            z = points[k, i, 2] - anchors[ka, i, 2]
            out[k, i] = x * x + y * y + z * z
        for i in range(m):  # apart, where the compiler vectorises it: half the time
            out[k, i] = math.sqrt(out[k, i])
    return out


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _point_and_joints(table: Array, plan: Array, start: Array, base: Array, tool: Array,
                      n_columns: int, joint_columns: Array, q: Array, point: Array,
                      joints: Array) -> None:
    """Into ``point`` (k, 3) the point at each row of q (k, n) on table 0, and into
    ``joints`` (k, 3, n) its derivatives by the joints, ∂p/∂q (the columns
    ``joint_columns`` (n,) of :func:`jacobian` along the base axes)."""
    k, n = q.shape
    cq, sq, slides = np.empty((n, 1, k)), np.empty((n, 1, k)), np.empty((n, 1, k))
    for row in range(k):
        for joint in range(n):
            value = q[row, joint]
            cq[joint, 0, row], sq[joint, 0, row] = math.cos(value), math.sin(value)
            slides[joint, 0, row] = value
    axes = np.zeros((1, 1, 3, 3))
    for axis in range(3):
        axes[0, 0, axis, axis] = 1.0
    position, columns, _ = jacobian(table, plan, cq, sq, slides, start, base, tool, axes,
                                    n_columns)
    for row in range(k):
        for axis in range(3):
            point[row, axis] = position[0, row, axis]
            for joint in range(n):
                joints[row, axis, joint] = columns[0, row, axis, joint_columns[joint]]


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _damped_step(jac: Array, error: Array, damping: float, step: Array) -> None:
    """Into ``step`` (n,) Jᵀ (J Jᵀ + λI)⁻¹ e for J (3, n) and e (3,): the 3×3 system solved
    by Cholesky (positive definite for λ > 0)."""
    a = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            total = 0.0
            for c in range(jac.shape[1]):
                total += jac[i, c] * jac[j, c]
            a[i, j] = total
        a[i, i] += damping
    l00 = math.sqrt(a[0, 0])
    l10, l20 = a[1, 0] / l00, a[2, 0] / l00
    l11 = math.sqrt(a[1, 1] - l10 * l10)
    l21 = (a[2, 1] - l20 * l10) / l11
    l22 = math.sqrt(a[2, 2] - l20 * l20 - l21 * l21)
    z0 = error[0] / l00
    z1 = (error[1] - l10 * z0) / l11
    z2 = (error[2] - l20 * z0 - l21 * z1) / l22
    y2 = z2 / l22
    y1 = (z1 - l21 * y2) / l11
    y0 = (z0 - l10 * y1 - l20 * y2) / l00
    for c in range(jac.shape[1]):
        step[c] = jac[0, c] * y0 + jac[1, c] * y1 + jac[2, c] * y2


@numba.njit(cache=True, nogil=True, error_model="numpy")
def position_ik(table: Array, plan: Array, start: Array, base: Array, tool: Array,
                n_columns: int, joint_columns: Array, targets: Array, seeds: Array,
                tolerance: float, max_iterations: int, damping0: float, smallest: float,
                largest: float) -> tuple[Array, Array, int]:
    """Damped Newton steps that bring the point to each row's target, the rows in lockstep,
    as :func:`twin.compensation.ik.solve_ik` takes them for positions alone: a row is worked
    on while it is farther than ``tolerance`` and its damping below ``largest``; a step that
    brings it closer is kept and the damping divided by 3 (not below ``smallest``), else the
    damping multiplied by 10.

    Args:
        table, plan, start, base, tool, n_columns: As :func:`jacobian`, one table.
        joint_columns: Each joint's column among the derivative columns, shape (n,).
        targets: Each row's target in the base frame, shape (m, 3), m.
        seeds: Starting joint values, shape (m, n), rad (m on a slide).

    Returns:
        ``(q, error, iterations)``: joint values (m, n), target − point (m, 3), and how many
        lockstep iterations ran.
    """
    m, n = seeds.shape
    q = seeds.copy()
    point, joints = np.empty((m, 3)), np.empty((m, 3, n))
    _point_and_joints(table, plan, start, base, tool, n_columns, joint_columns, q, point,
                      joints)
    error = targets - point
    size = np.empty(m)
    for row in range(m):
        size[row] = math.sqrt(error[row, 0] ** 2 + error[row, 1] ** 2 + error[row, 2] ** 2)
    damping = np.full(m, damping0)
    tried, tried_point, tried_joints = np.empty((m, n)), np.empty((m, 3)), np.empty((m, 3, n))
    iterations = 0
    while iterations < max_iterations:
        active = np.flatnonzero((size > tolerance) & (damping < largest))
        k = active.size
        if k == 0:
            break
        iterations += 1
        for a in range(k):
            row = active[a]
            _damped_step(joints[row], error[row], damping[row], tried[a])
            for joint in range(n):
                tried[a, joint] += q[row, joint]
        _point_and_joints(table, plan, start, base, tool, n_columns, joint_columns,
                          tried[:k], tried_point[:k], tried_joints[:k])
        for a in range(k):
            row = active[a]
            e0 = targets[row, 0] - tried_point[a, 0]
            e1 = targets[row, 1] - tried_point[a, 1]
            e2 = targets[row, 2] - tried_point[a, 2]
            reached = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
            if reached < size[row]:
                q[row], joints[row] = tried[a], tried_joints[a]
                error[row, 0], error[row, 1], error[row, 2] = e0, e1, e2
                size[row] = reached
                damping[row] = max(damping[row] / 3.0, smallest)
            else:
                damping[row] *= 10.0
    return q, error, iterations
