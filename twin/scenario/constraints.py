"""What a measured pose must satisfy: the rig's constraints, as a scenario states them.

The twin checks them (:func:`twin.sim.poses.violations`): joint limits, the flange above the
floor by a margin, no link touching another or the floor, the cable inside the encoder's range
and clear of the links.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class PoseConstraints:
    """What a measured pose must satisfy.

    Attributes:
        min_flange_height_m: Lowest flange centre above the floor (z = 0), m.
        cable_min_m: Shortest cable the encoder reads, m.
        cable_max_m: Longest cable the encoder reads, m.
        cable_clearance_m: Gap the cable must keep from every link but the last, m.
    """

    min_flange_height_m: float = 0.05
    cable_min_m: float = 0.05
    cable_max_m: float = 1.5
    cable_clearance_m: float = 0.0

    def __post_init__(self) -> None:
        if not 0 <= self.cable_min_m < self.cable_max_m:
            raise ValueError("cable range: expected 0 <= min < max")
