"""The robot-source interface: bring the robot to a plan pose and say where it really is."""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np
from numpy.typing import NDArray


class RobotSource(ABC):
    """Where the joint angles of each captured pose come from.

    Poses are numbered from 1, as shown to the operator (``pose K/N``) and written to the
    ``pose`` column of the measurement file.
    """

    @abstractmethod
    def move_to(self, pose: int, n_poses: int, target_q_rad: NDArray[np.float64]
                ) -> NDArray[np.float64]:
        """Bring the robot to a plan pose and return the joint angles it reached.

        Args:
            pose: Pose number K, 1..N.
            n_poses: Number of plan poses N.
            target_q_rad: The plan's joint angles, shape (n,), rad.

        Returns:
            The joint angles reached (what the controller reports), shape (n,), rad.
        """
