"""The reference's speeds and MuJoCo's: the coordinate rates of an imported file against qvel.

Hinges and slides: the same. Ball and free joints: the reference's speeds are the quaternion
rates q', MuJoCo's the local angular velocity omega = 2 (w v' - w' v - v x v') of q = (w, v)
(and a free joint's world linear velocity, the position's rate): q' = q (x) (0, omega) / 2 and
omega = 2 E(q) q'. Both maps are linear in the speeds at a configuration.
"""

from __future__ import annotations

import mujoco
import numpy as np

JNT = mujoco.mjtJoint


def rates_from_qvel(joints, qpos, qvel) -> np.ndarray:
    """Coordinate rates from MuJoCo's qvel: hinge/slide as they are, quaternion rates
    q' = q (x) (0, omega) / 2 for ball and free joints (omega local)."""
    out = np.zeros(len(qpos))
    for ji in joints:
        a, d = ji.qposadr, ji.dofadr
        if ji.type in (int(JNT.mjJNT_HINGE), int(JNT.mjJNT_SLIDE)):
            out[a] = qvel[d]
            continue
        if ji.type == int(JNT.mjJNT_FREE):
            out[a : a + 3] = qvel[d : d + 3]
            a, d = a + 3, d + 3
        qd = np.zeros(4)
        mujoco.mju_mulQuat(
            qd, np.asarray(qpos[a : a + 4], float), np.array([0.0, *qvel[d : d + 3]])
        )
        out[a : a + 4] = 0.5 * qd
    return out


def _E(quat) -> np.ndarray:
    """omega = 2 E(q) q' for a quaternion (w, x, y, z) with local omega."""
    w, x, y, z = quat
    return np.array([[-x, w, z, -y], [-y, -z, w, x], [-z, y, -x, w]], float)


def qvel_from_rates(joints, qpos, rates, nv: int) -> np.ndarray:
    """MuJoCo's qvel (or qacc from the second derivatives: E(q) q' q' = 0 makes the same map
    linear in the rates' derivatives) from the reference's coordinate rates."""
    out = np.zeros(nv)
    for ji in joints:
        a, d = ji.qposadr, ji.dofadr
        if ji.type in (int(JNT.mjJNT_HINGE), int(JNT.mjJNT_SLIDE)):
            out[d] = rates[a]
            continue
        if ji.type == int(JNT.mjJNT_FREE):
            out[d : d + 3] = rates[a : a + 3]
            a, d = a + 3, d + 3
        out[d : d + 3] = 2 * _E(qpos[a : a + 4]) @ np.asarray(rates[a : a + 4], float)
    return out
