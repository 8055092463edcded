"""Where a calibration starts and what its data must hold, by rig: ports matched by name,
fixed points started at the nominal model's mean point, the tracker frame at a rigid fit, the
approach directions backlash reads."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike

from twin.dataset import Measurements
from twin.errors import InputError
from twin.geometry.rigid import kabsch
from twin.kinds import KINDS
from twin.model import Model
from twin.rig import Rig
from twin.robot import RobotModel


def match_ports(measurements: Measurements, rig: Rig) -> Measurements:
    """The measurements with each row's port as an index into the rig's ports.

    Data that name their ports (a ``port`` column) are matched to the rig's ports by name;
    unnamed data use the rig's ports in order.

    Raises:
        InputError: for a port the rig does not have, or data from several unnamed ports.
    """
    if measurements.kind != "length":
        return measurements
    if measurements.port_names:
        unknown = [name for name in measurements.port_names if name not in rig.port_names]
        if unknown:
            raise InputError(f"port {unknown[0]!r} in the measurements",
                             "one of the rig's ports: " + ", ".join(rig.port_names))
        index = np.array([rig.port_names.index(name) for name in measurements.port_names])
        return replace(measurements, port=index[measurements.port_index],
                       port_names=rig.port_names)
    if int(measurements.port_index.max()) >= len(rig.ports_m):
        raise InputError(f"{int(measurements.port_index.max()) + 1} ports in the measurements",
                         f"at most the rig's {len(rig.ports_m)}")
    return measurements


def check_approach(model: Model, approach: ArrayLike | None) -> None:
    """Refuse poses without the approach directions a group of the model reads.

    Args:
        model: The model to fit or evaluate.
        approach: The poses' approach directions, shape (m, n), or None if not recorded.

    Raises:
        InputError: naming the missing columns ``approach1..approachN``.
    """
    if model.needs_approach and approach is None:
        n = model.robot.n_joints
        raise InputError(
            f"no columns approach1..approach{n}",
            f"approach1..approach{n} (+1 or -1: the direction each joint last moved in before "
            "the reading), which backlash needs")


def with_fixed_points(robot: RobotModel, rig: Rig, measurements: Measurements) -> Rig:
    """The rig with the fixed points of fixed-point data, each started at the mean of the
    nominal model's measured points of its rows (every row: a start, not a fit).

    Raises:
        InputError: for a known distance between points the data do not name.
    """
    assert measurements.point is not None
    names = measurements.point_names or tuple(
        f"point{j + 1}" for j in range(int(measurements.point.max()) + 1))
    nominal = Model(robot, replace(rig, point_names=(), points_m=np.zeros((0, 3)),
                                   distances=()), KINDS.lookup("point"), ())
    positions = nominal.positions(np.zeros(0), measurements)
    counts = np.bincount(measurements.point, minlength=len(names))
    starts = np.stack([np.bincount(measurements.point, positions[:, k], minlength=len(names))
                       for k in range(3)], axis=1) / np.maximum(counts, 1)[:, None]
    for distance in rig.distances:
        for name in (distance.first, distance.second):
            if name not in names:
                raise InputError(f"a distance to the point {name!r}", "distances between "
                                 "points the measurements name: " + ", ".join(names),
                                 where="distances")
    return replace(rig, point_names=names, points_m=starts)


def tracker_start(model: Model, train: Measurements) -> Model:
    """The model with its tracker frame started at the rigid fit (Kabsch) of the nominal model's
    measured points onto the training readings."""
    nominal = replace(model, rig=replace(model.rig, base_in_tracker=np.eye(4)))
    positions = nominal.positions(np.zeros(model.n_params), train)
    assert train.position_m is not None
    fit = kabsch(positions, train.position_m)
    return replace(model, rig=replace(model.rig, base_in_tracker=fit.transform))
