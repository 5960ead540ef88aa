"""A ball or free joint as links of Exudyn's ObjectKinematicTree (user_system.py): three
prismatic links along the world axes (free joint only) and three revolute links about x, y, z
of a base rotation R0, so the joint's rotation is R0 Rx(a) Ry(b) Rz(c).

The angles are singular where cos b = 0, so R0 is re-based at every mapped state to the
joint's rotation there (the angles are then zero, the singularity a quarter turn away).
The joint's angular velocity in its child frame is G(phi) phi', its angular acceleration
G phi'' + a' g1 x (b' g2 + c' g3) + b' g2 x c' g3 (g_i the columns of G: each g_i' is
g_i x the angular velocity of the links after it).
"""

from __future__ import annotations

import numpy as np

__all__ = ["euler_columns", "euler_rotation", "euler_velocity_terms"]


def _axis(k: int, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    i, j = (k + 1) % 3, (k + 2) % 3
    R = np.eye(3)
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


def euler_rotation(phi) -> np.ndarray:
    """Rx(a) Ry(b) Rz(c) of phi = (a, b, c)."""
    return _axis(0, phi[0]) @ _axis(1, phi[1]) @ _axis(2, phi[2])


def euler_columns(phi) -> np.ndarray:
    """G with the child-frame angular velocity G phi' (columns g1, g2, g3)."""
    Rz, Ry = _axis(2, phi[2]), _axis(1, phi[1])
    return np.column_stack([Rz.T @ Ry.T @ [1.0, 0, 0], Rz.T @ [0.0, 1, 0], [0.0, 0, 1]])


def euler_velocity_terms(phi, phid) -> np.ndarray:
    """The angular acceleration's part in phi' alone: a' g1 x (b' g2 + c' g3) + b' g2 x c' g3."""
    g = euler_columns(phi)
    a, b, c = phid
    return a * np.cross(g[:, 0], b * g[:, 1] + c * g[:, 2]) + b * c * np.cross(g[:, 1], g[:, 2])
