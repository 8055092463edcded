"""Static joint torques of a serial arm: gravity on its links and a force on its flange.

The torque that loads joint i is the moment about its axis of every load beyond it,

    τ_i = u_i · Σ_j (p_j − o_i) × F_j,

and for a prismatic joint the force along its axis, τ_i = u_i · Σ_j F_j (N, its generalised
force),

with u_i, o_i the joint's axis and a point on it (:func:`twin.geometry.kinematics.joint_axes`), F_j
= m_j g at the centre of mass p_j of each link j ≥ i, and an external force (the drawstring's pull)
at a point fixed to the flange. It is the generalised force the loads exert on the joint (what
MuJoCo calls ``qfrc_actuator − qfrc_bias`` for a pulling tendon, at rest): a joint held by a servo
of stiffness k deflects by τ / k in the direction of q. The sum over j ≥ i is taken from the flange
down: Σ_{j≥i} (p_j − o_i) × F_j = Σ_{j≥i} p_j × F_j − o_i × Σ_{j≥i} F_j, two cumulative sums.

The base frame's z axis points up (the robot stands on the floor): gravity is −z.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from twin.arrays import Array
from twin.geometry.kinematics import Structure, frames, joint_axes

GRAVITY_M_S2 = 9.81
"""Standard gravity, m/s², along −z of the base frame."""


def joint_torques(
    structure: Structure,
    dh: ArrayLike,
    q_rad: ArrayLike,
    mass_kg: ArrayLike,
    com_m: ArrayLike,
    point_m: ArrayLike | None = None,
    force_n: ArrayLike | None = None,
) -> Array:
    """Torque on every joint from gravity on the links and a force at a flange point.

    Args:
        structure: What the table means.
        dh: One parameter table, shape (4, n), m and rad.
        q_rad: Joint angles, shape (m, n), rad.
        mass_kg: Link masses, shape (n,), kg; link i turns with joint i.
        com_m: Link centres of mass, row i in frame i of the chain, shape (n, 3), m.
        point_m: Where the force acts, in the flange frame, shape (3,), m; the flange centre
            if None.
        force_n: The force at that point in the base frame, shape (m, 3), N; none if None.

    Returns:
        τ, shape (m, n), N·m (N on a prismatic joint): positive where the loads move the joint
        towards larger q.
    """
    q = np.asarray(q_rad, dtype=np.float64)
    mass = np.asarray(mass_kg, dtype=np.float64)
    com = np.asarray(com_m, dtype=np.float64)
    chain = frames(structure, dh, q)
    # Link i's frame is frame i (index 1..n); its axes are columns of base_R_frame.
    rotation = np.stack([chain.x_axes, chain.y_axes, chain.z_axes], axis=-1)[:, 1:]
    centres = chain.origins[:, 1:] + np.einsum("mnij,nj->mni", rotation, com)
    weights = np.zeros((*centres.shape[:-1], 3))
    weights[..., 2] = -GRAVITY_M_S2 * mass
    moment = np.cross(centres, weights)  # about the base origin, (m, n, 3)
    # Loads beyond joint i: links i..n, summed from the flange down.
    moment_beyond = np.flip(np.cumsum(np.flip(moment, axis=1), axis=1), axis=1)
    force_beyond = np.flip(np.cumsum(np.flip(weights, axis=1), axis=1), axis=1)
    if force_n is not None:
        force = np.asarray(force_n, dtype=np.float64)
        local = np.zeros(3) if point_m is None else np.asarray(point_m, dtype=np.float64)
        at = chain.flange[:, :3, :3] @ local + chain.flange[:, :3, 3]
        moment_beyond = moment_beyond + np.cross(at, force)[:, None, :]
        force_beyond = force_beyond + force[:, None, :]
    origins, axes = joint_axes(structure, dh, q)
    about_joint = moment_beyond - np.cross(origins, force_beyond)
    load = np.where(structure.prismatic[:, None], force_beyond, about_joint)
    return np.asarray(np.sum(axes * load, axis=-1), dtype=np.float64)


def link_torques(structure: Structure, dh: ArrayLike, q_rad: ArrayLike, mass_kg: ArrayLike,
                 com_m: ArrayLike) -> Array:
    """The torque each link's weight puts on each joint, apart: ``τ[:, i, j]`` from link j on
    joint i, zero where link j does not turn with joint i (j < i). Summed over the links it is
    the gravity part of :func:`joint_torques`.

    Args:
        structure, dh, q_rad, mass_kg, com_m: As :func:`joint_torques`.

    Returns:
        Shape (m, n, n), N·m (N on a prismatic joint).
    """
    q = np.asarray(q_rad, dtype=np.float64)
    mass = np.asarray(mass_kg, dtype=np.float64)
    chain = frames(structure, dh, q)
    rotation = np.stack([chain.x_axes, chain.y_axes, chain.z_axes], axis=-1)[:, 1:]
    centres = chain.origins[:, 1:] + np.einsum("mnij,nj->mni", rotation,
                                               np.asarray(com_m, dtype=np.float64))
    weights = np.zeros(centres.shape)
    weights[..., 2] = -GRAVITY_M_S2 * mass
    origins, axes = joint_axes(structure, dh, q)
    arms = centres[:, None, :, :] - origins[:, :, None, :]  # (m, joint i, link j, 3)
    moments = np.cross(arms, weights[:, None, :, :])
    loads = np.where(structure.prismatic[None, :, None, None], weights[:, None, :, :], moments)
    torque = np.einsum("mic,mijc->mij", axes, loads)
    n = mass.size
    return np.asarray(torque * (np.arange(n)[None, :] >= np.arange(n)[:, None]),
                      dtype=np.float64)
