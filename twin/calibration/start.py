"""What a calibration's data must hold beyond their kind's readings: the approach directions
backlash reads. (Where a calibration starts from the data — ports matched by name, fixed points
started at the nominal model's mean point, a tracker frame at a rigid fit — belongs to each
measurement kind: :meth:`twin.kinds.base.Kind.prepare` and :meth:`~twin.kinds.base.Kind.start`.)
"""

from __future__ import annotations

from numpy.typing import ArrayLike

from twin.errors import InputError
from twin.model import Model


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
