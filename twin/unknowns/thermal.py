"""Thermal growth: each link's length entries grow linearly with the temperature.

Per joint i, the table's length entries at the row's temperature T::

    a_i(T) = a_i + δa_i + k_a,i · (T − T_ref),   d_i(T) = d_i + δd_i + k_d,i · (T − T_ref)

one unknown per length entry of the table's first two slots (``k_a1``…``k_an``, ``k_d1``…; a
Hayati joint's second slot is an angle, β, and takes none), in m/K (results show µm/K). T is
each row's ``temperature_c`` (:data:`twin.dataset.TEMPERATURE`); T_ref is the mean temperature
of the measurements calibrated (:attr:`twin.rig.Rig.temperature_ref_c`, which results keep), so
the D-H errors δa_i, δd_i are the links' at that temperature, and poses without a temperature
are evaluated at it. Acting on the table row by row (stage ``rows``), the growth enters every
kind's kinematics exactly, not to first order.

What the data cannot see: with a temperature that never changes, every coefficient multiplies a
zero and is an exact null direction, held at 0 and said so
(:mod:`twin.calibration.hold`); a coefficient trades with whatever its entry trades with
(``k_d2`` with ``k_d3``, as d2 with d3).

Bounds ±100 µm/K: a metre of aluminium grows 23 µm/K, of steel 11.5; radius 5 µm/K.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from twin.dataset import TEMPERATURE, Measurements
from twin.rig import Rig
from twin.robot import RobotModel
from twin.units import THERMAL_UNIT
from twin.unknowns.group import Array, Group, Stage, cached

BOUND_M_PER_K = 1e-4
"""Search bound on a growth per kelvin, m/K (100 µm/K)."""
RADIUS_M_PER_K = 5e-6
"""Typical growth, m/K (5 µm/K)."""
SLOTS = 2
"""The table's slots whose length entries grow (a and d of a D-H joint)."""


def temperature_rise(data: Measurements, reference_c: float | None) -> Array:
    """Each row's temperature above the reference, shape (m,), K; zeros for measurements without
    a temperature (poses of one's choosing: evaluated at the reference).

    Raises:
        ValueError: for temperatures without a reference to take them from.
    """
    if TEMPERATURE not in data.values:
        return np.zeros(len(data))
    if reference_c is None:
        raise ValueError("thermal: the rig has no reference temperature (temperature_ref_c)")
    return np.asarray(data.values[TEMPERATURE] - reference_c, dtype=np.float64)


def growing(robot: RobotModel) -> NDArray[np.intp]:
    """Where the growing entries sit in the table, slot-major as x lays out the D-H errors,
    in the thermal group's order, shape (entries,)."""
    return np.flatnonzero(robot.structure.is_length[:SLOTS].ravel())


def grown(robot: RobotModel, growth_m_per_k: Array, rise_k: float) -> RobotModel:
    """``robot`` with its links grown ``rise_k`` kelvin above the reference temperature: each
    length entry of the table's first two slots plus its k · rise (what a result's tables are
    at a cell's temperature).

    Args:
        robot: The robot whose table grows, SI.
        growth_m_per_k: The growths k in the thermal group's order, shape (entries,), m/K.
        rise_k: T − T_ref, K.
    """
    entries = growing(robot)
    growth = np.zeros(robot.dh.size)
    growth[entries] = np.asarray(growth_m_per_k, dtype=np.float64) * rise_k
    return robot.perturbed(growth.reshape(robot.dh.shape))


def make(robot: RobotModel, rig: Rig) -> Group:
    """The thermal growth of ``robot``'s length entries about ``rig``'s reference temperature."""
    n = robot.n_joints
    entries = growing(robot)
    linear = np.zeros((4 * n, entries.size))
    linear[entries, np.arange(entries.size)] = 1.0
    names = robot.structure.parameter_names
    reference = rig.temperature_ref_c

    def basis(data: Measurements) -> Array:
        return np.repeat(temperature_rise(data, reference)[:, None], entries.size, axis=1)

    return Group(
        name="thermal", stage=Stage.ROWS, names=tuple(f"k_{names[i]}" for i in entries),
        units=(THERMAL_UNIT,) * entries.size, lower=np.full(entries.size, -BOUND_M_PER_K),
        upper=np.full(entries.size, BOUND_M_PER_K), radius=np.full(entries.size, RADIUS_M_PER_K),
        linear=linear, basis=cached(basis))
