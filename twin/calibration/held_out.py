"""How a calibration is scored on poses it did not train on.

The identified model is fixed; the held-out readings are compared with what it predicts. Some
of the rig's unknowns may be touched by held-out poses alone — a fixed point only the held-out
placement of a fixture names, a port only the held-out rows read: no training row moved them,
so the fit left them where they started. Judging the model with them there would judge the
start, not the model: they are fitted to the held-out rows first (Gauss–Newton, the robot's
unknowns and every rig unknown the training saw held fixed), as a user re-measures a new
fixture placement with a calibrated robot. That is how leave-one-placement-out figures of
real data sets are made (MUKCa's fixtures: examples/panda_mukca).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.analysis.linearisation import model_jacobian
from twin.analysis.unseen import rig_unknowns
from twin.arrays import Array
from twin.dataset import Measurements
from twin.model import Model

SEEN_RTOL = 1e-9
"""A column whose norm is below this fraction of the largest moves no row."""
REFIT_ITERATIONS = 10
"""Gauss–Newton steps of the held-out refit (its unknowns enter the rows nearly linearly)."""


def held_out_only(model: Model, x: ArrayLike, train: Measurements, held_out: Measurements
                  ) -> NDArray[np.bool_]:
    """Which unknowns are the rig's, moved by held-out rows and by no training pose's row,
    (p,) bool. A row of no pose does not count: a known distance between two sockets of the
    held-out placement says how far apart they are, not where."""
    rig = rig_unknowns(model)
    if not rig.any():  # a model of the robot alone: no Jacobian to take
        return rig
    x = np.asarray(x, dtype=np.float64)
    poses = model.kind.rows_per_pose * len(train)
    # The kept Jacobians (a calibration's checks took the training rows' at the start and at
    # the answer already): two 6-D pose Jacobians a call were a tenth of a pose trial.
    seen_train = np.linalg.norm(model_jacobian(model, x, train)[1][:poses], axis=0)
    seen_held = np.linalg.norm(model_jacobian(model, x, held_out)[1], axis=0)
    largest = max(float(np.max(seen_train, initial=0.0)), float(np.max(seen_held, initial=0.0)))
    tolerance = SEEN_RTOL * largest
    return np.asarray(rig & (seen_train <= tolerance) & (seen_held > tolerance))


def held_out_residuals(model: Model, x: ArrayLike, train: Measurements, held_out: Measurements
                       ) -> Array:
    """The held-out rows' residuals of the identified model, shape (M,), m — the rig's unknowns
    only held-out rows touch fitted to them first (module docstring)."""
    x = np.array(x, dtype=np.float64)
    if not len(held_out):
        return np.zeros(0)
    free = held_out_only(model, x, train, held_out)
    if not np.any(free):
        return model.residuals(x, held_out)
    for _ in range(REFIT_ITERATIONS):
        r, jacobian = model.jacobian(x, held_out)
        step = np.linalg.lstsq(jacobian[:, free], -r, rcond=None)[0]
        x[free] += step
        if np.linalg.norm(step) <= 1e-12 * max(float(np.linalg.norm(x[free])), 1.0):
            break
    return model.residuals(x, held_out)


__all__ = ["held_out_only", "held_out_residuals"]
