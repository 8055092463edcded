"""Static equilibrium of the twin's compliant joints under gravity and the cable's pull.

The robot holds each joint with a position servo of stiffness k_j (N·m/rad; N/m on a slide): at
rest the joint sits where the servo torque (force) balances gravity and the cable's pull,

    k (q − q_cmd) = τ_actuator,cable(q) − τ_gravity(q).

MuJoCo computes both generalised forces (``qfrc_actuator`` with the servos' own term, and
``qfrc_bias`` at zero velocity); :func:`static_equilibrium` finds q by the fixed point
``q ← q + K⁻¹ (qfrc_actuator − qfrc_bias)``. The load torques change slowly with q compared
with k, so the iteration contracts by ~‖K⁻¹ ∂τ/∂q‖ ≈ 1e-4 per step and converges to 1e-13 rad
in three or four steps, deterministically. A test checks the result against stepping the
damped dynamics to rest.
"""

from __future__ import annotations

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from twin.arrays import Array

EQUILIBRIUM_TOL_RAD = 1e-13
"""Stop the fixed point when no joint moves by more than this, rad."""
EQUILIBRIUM_MAX_ITERATIONS = 50


def static_equilibrium(
    model: mujoco.MjModel, data: mujoco.MjData, q_cmd_rad: ArrayLike, stiffness: ArrayLike
) -> Array:
    """Joint angles at rest under the servos, gravity and the cable's tension.

    ``model`` carries one position servo per joint (actuators 0..n−1, gain = stiffness) and the
    cable actuator, whose ``ctrl`` the caller has set. MuJoCo works on one state at a time,
    hence the loop over poses; each pose costs a few ``mj_forward`` calls.

    Args:
        model: Compiled twin with servos; contacts and constraints should be disabled.
        data: Scratch data of that model (overwritten).
        q_cmd_rad: Commanded joint angles, shape (m, n), rad.
        stiffness: Servo stiffness k, shape (n,), N·m/rad (N/m on a slide).

    Returns:
        Joint angles at static equilibrium, shape (m, n), rad.

    Raises:
        RuntimeError: if a pose does not converge (a load beyond what the servos hold).
    """
    q_cmd = np.asarray(q_cmd_rad, dtype=np.float64)
    inverse_k = 1.0 / np.asarray(stiffness, dtype=np.float64)
    n = q_cmd.shape[1]
    q_rest = np.empty_like(q_cmd)
    data.qvel[:] = 0.0
    for row, target in enumerate(q_cmd):
        data.ctrl[:n] = target
        q = target.copy()
        for _ in range(EQUILIBRIUM_MAX_ITERATIONS):
            data.qpos[:] = q
            mujoco.mj_forward(model, data)
            step = inverse_k * (data.qfrc_actuator - data.qfrc_bias)
            q += step
            if np.max(np.abs(step)) <= EQUILIBRIUM_TOL_RAD:
                break
        else:
            raise RuntimeError(f"static equilibrium did not converge at pose {row}")
        q_rest[row] = q
    return q_rest
