"""Robot description: a kinematic table with its parametrisation, joint types, joint limits and
fixed ends, SI inside (a revolute joint's values in rad, a prismatic joint's in m). The files it
is read from and written to (a model TOML, a URDF) are :mod:`twin.io.robot_file`'s.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import frozen_array
from twin.geometry.kinematics import Structure, fixed_transforms, flange_transform, point_position
from twin.geometry.parametrisation import convert, joint_frames


@dataclass(frozen=True)
class UrdfSource:
    """The URDF a robot was read from, kept whole so that a calibration can be written back
    into it (:mod:`twin.export.urdf`) with every name, mesh, inertial and limit.

    Attributes:
        text: The URDF document.
        base_link: The link the chain starts from (the robot's base frame).
        tip_link: The link whose frame is the flange.
        joint_names: The moving (revolute, continuous, prismatic) joints of the chain, base
            to tip, length n.
        frame_offsets: Where each URDF joint's frame (turned so that its axis is z) sits in the
            table's frame of that joint, whose z is the same axis (line): a shift along it (m)
            and a turn about it (rad), shape (n, 2). Kept so that writing a calibration back moves
            the URDF's link frames (and their meshes and inertials) by the calibration only.
    """

    text: str
    base_link: str
    tip_link: str
    joint_names: tuple[str, ...]
    frame_offsets: NDArray[np.float64]

    def __post_init__(self) -> None:
        offsets = frozen_array(self.frame_offsets, (len(self.joint_names), 2), "frame_offsets")
        object.__setattr__(self, "frame_offsets", offsets)


@dataclass(frozen=True)
class RobotModel:
    """A serial arm: a kinematic table with its structure, joint limits, and what the twin
    and the exports need, SI inside. The readers hold a robot to
    :data:`twin.choices.MIN_JOINTS` to :data:`twin.choices.MAX_JOINTS` joints.

    Attributes:
        name: Human-readable name.
        dh: Kinematic table, shape (4, n): slots a [m], d [m] (β [rad] on a Hayati joint),
            alpha [rad], theta offset [rad] (:mod:`twin.geometry.kinematics`).
        lower_rad: Lower joint limits, shape (n,), rad (m for a prismatic joint).
        upper_rad: Upper joint limits, shape (n,), rad (m for a prismatic joint).
        mass_kg: Link masses, shape (n,), kg, or None when the file gives none.
        radius_m: Link capsule radii, shape (n,), m, or None when the file gives none.
        structure: What the table means (parametrisation and type per joint, base and tool
            transforms); standard D-H revolute joints with bare ends by default.
        velocity_rad_s: Rated joint speeds, shape (n,), rad/s (m/s for a prismatic joint), or
            None when unknown.
        effort_nm: Rated joint torques, shape (n,), N·m (N, a force, for a prismatic joint),
            or None when unknown.
        urdf: The URDF the robot was read from, or None.
        com_m: Link centres of mass, row i in link i's frame (frame i of the chain, which
            turns with joint i), shape (n, 3), m, or None when the file gives none; needs
            ``mass_kg``.
    """

    name: str
    dh: NDArray[np.float64]
    lower_rad: NDArray[np.float64]
    upper_rad: NDArray[np.float64]
    mass_kg: NDArray[np.float64] | None = field(default=None)
    radius_m: NDArray[np.float64] | None = field(default=None)
    structure: Structure = field(default=None)  # type: ignore[assignment]
    velocity_rad_s: NDArray[np.float64] | None = field(default=None)
    effort_nm: NDArray[np.float64] | None = field(default=None)
    urdf: UrdfSource | None = field(default=None)
    com_m: NDArray[np.float64] | None = field(default=None)

    def __post_init__(self) -> None:
        dh = np.asarray(self.dh, dtype=np.float64)
        if dh.ndim != 2 or dh.shape[0] != 4 or dh.shape[1] < 1:
            raise ValueError(f"dh: shape {dh.shape}, expected (4, n)")
        n = dh.shape[1]
        object.__setattr__(self, "dh", frozen_array(dh, (4, n), "dh"))
        if self.structure is None:
            object.__setattr__(self, "structure", Structure.standard(n))
        if self.structure.n_joints != n:
            raise ValueError(f"structure: {self.structure.n_joints} joints for a table of {n}")
        object.__setattr__(self, "lower_rad", frozen_array(self.lower_rad, (n,), "lower_rad"))
        object.__setattr__(self, "upper_rad", frozen_array(self.upper_rad, (n,), "upper_rad"))
        if np.any(self.lower_rad >= self.upper_rad):
            raise ValueError("joint limits: lower must be below upper")
        for name in ("mass_kg", "radius_m", "velocity_rad_s", "effort_nm"):
            value = getattr(self, name)
            if value is not None:
                array = frozen_array(value, (n,), name)
                if np.any(array < 0):
                    raise ValueError(f"{name}: negative values")
                object.__setattr__(self, name, array)
        if self.urdf is not None and len(self.urdf.joint_names) != n:
            raise ValueError(f"urdf: {len(self.urdf.joint_names)} joint names for {n} joints")
        if self.com_m is not None:
            if self.mass_kg is None:
                raise ValueError("com_m: centres of mass need link masses (mass_kg)")
            object.__setattr__(self, "com_m", frozen_array(self.com_m, (n, 3), "com_m"))

    @property
    def n_joints(self) -> int:
        """Number of joints n."""
        return int(self.dh.shape[1])

    @property
    def prismatic(self) -> NDArray[np.bool_]:
        """Whether each joint slides (values in m) rather than turns (rad), shape (n,)."""
        return self.structure.prismatic

    @property
    def is_length(self) -> NDArray[np.bool_]:
        """Whether each table entry is a length (m) rather than an angle (rad), shape (4, n)."""
        return self.structure.is_length

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The joints' names: the URDF's, or ``joint_1``…``joint_n``."""
        if self.urdf is not None:
            return self.urdf.joint_names
        return tuple(f"joint_{i + 1}" for i in range(self.n_joints))

    def perturbed(self, delta: ArrayLike) -> RobotModel:
        """This robot with errors of its table added.

        Args:
            delta: Errors in the table's slot order (δa1..n, δd1..n, δα1..n, δθ1..n for a D-H
                arm), shape (4n,) or (4, n), m and rad.
        """
        delta_rows = np.asarray(delta, dtype=np.float64).reshape(4, self.n_joints)
        return replace(self, dh=self.dh + delta_rows)

    def flange_positions(self, q_rad: ArrayLike) -> NDArray[np.float64]:
        """The flange centre at joint values q (m, n), rad (m for a prismatic joint): shape
        (m, 3), m, base frame."""
        return point_position(self.structure, self.dh, q_rad)

    def flange_transforms(self, q_rad: ArrayLike) -> NDArray[np.float64]:
        """base_T_flange at joint values q (m, n), rad (m for a prismatic joint): shape
        (m, 4, 4), m."""
        return flange_transform(self.structure, self.dh, q_rad)

    def reparametrised(self, request: str | Sequence[str]) -> RobotModel:
        """The same arm (same forward kinematics, to 1e-9 m) in another parametrisation:
        ``auto``, one of :data:`twin.geometry.kinematics.PARAMETRISATIONS`, or one per joint; a
        URDF's joint frames keep their place (:attr:`UrdfSource.frame_offsets` follow the table)."""
        structure, table = convert(fixed_transforms(self.structure, self.dh), request,
                                   self.structure.joint_types)
        urdf = self.urdf
        if urdf is not None:
            old = joint_frames(fixed_transforms(self.structure, self.dh))[0]
            new = joint_frames(fixed_transforms(structure, table))[0]
            shift, turn = urdf.frame_offsets.T
            screws = np.zeros((len(shift), 4, 4))
            screws[:, 0, 0] = screws[:, 1, 1] = np.cos(turn)
            screws[:, 1, 0], screws[:, 0, 1] = np.sin(turn), -np.sin(turn)
            screws[:, 2, 2] = screws[:, 3, 3] = 1.0
            screws[:, 2, 3] = shift
            offsets = np.linalg.inv(new) @ old @ screws
            urdf = replace(urdf, frame_offsets=np.column_stack(
                [offsets[:, 2, 3], np.arctan2(offsets[:, 1, 0], offsets[:, 0, 0])]))
        return replace(self, dh=table, structure=structure, urdf=urdf)


def random_poses(robot: RobotModel, n_poses: int, rng: np.random.Generator) -> NDArray[np.float64]:
    """Joint values drawn uniformly within the joint limits, shape (n_poses, n), rad (m for a
    prismatic joint)."""
    return rng.uniform(robot.lower_rad, robot.upper_rad, size=(n_poses, robot.n_joints))
