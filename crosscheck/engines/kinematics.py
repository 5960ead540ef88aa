"""Rotation helpers every engine adapter shares, written once (textbook conventions).

3-1-3 body angles (Example 4) and Euler parameters eps = (eps1, eps2, eps3, eps4), eps4 scalar
(the tops): omega_body = 2 E(eps) eps', so on |eps| = 1 eps' = E^T omega / 2 and
eps'' = (E(eps')^T omega + E(eps)^T omega') / 2. Quaternion storage orders differ per engine
(Pinocchio x, y, z, w; MuJoCo w, x, y, z), so their conversions stay with each engine and use
the engine's own routines.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from reference.models.double_pendulum import R313 as _R313_reference


def R313(a, b, c) -> np.ndarray:
    """The textbook's 3-1-3 matrix (N components -> body components), Example 4 (the
    reference's own definition, evaluated in floats)."""
    return np.asarray(_R313_reference(float(a), float(b), float(c)), float)


def angles313(R) -> np.ndarray:
    """3-1-3 angles of an N -> body matrix, on the branch theta2 in [0, pi] (the reference's
    sampler keeps theta2 in [0.3, pi - 0.3]), theta1, theta3 in (-pi, pi]."""
    R = np.asarray(R, float)
    b = math.acos(max(-1.0, min(1.0, R[2, 2])))
    a = math.atan2(R[2, 0], -R[2, 1])
    c = math.atan2(R[0, 2], R[1, 2])
    return np.array([a, b, c])


def E(eps) -> np.ndarray:
    """The textbook's E(eps) (omega = 2 E eps', eps4 scalar); linear in eps."""
    e1, e2, e3, e4 = (float(x) for x in eps)
    return np.array([[e4, e3, -e2, -e1], [-e3, e4, e1, -e2], [e2, -e1, e4, -e3]])


def eps_rates(eps, omega) -> np.ndarray:
    """eps' from the body-fixed omega on |eps| = 1."""
    return 0.5 * E(eps).T @ omega


def eps_ddot(eps, eps_dot, omega, omega_dot) -> np.ndarray:
    """eps'' = (E(eps')^T omega + E(eps)^T omega') / 2."""
    return 0.5 * (E(eps_dot).T @ omega + E(eps).T @ omega_dot)


# ---- state maps every engine writes the same way ------------------------------------------
class IdentityMaps:
    """Engine coordinates and speeds are the reference's, same order and meaning (a mixin
    before the engine's model class)."""

    def to_engine_state(self, q, u):
        return np.array(q, float).reshape(-1), np.array(u, float).reshape(-1)

    def from_engine_state(self, qe, ve):
        return np.array(qe, float).reshape(-1), np.array(ve, float).reshape(-1)

    def _acc_to_reference(self, qe, ve, ae):
        return np.array(ae, float).reshape(-1)


class LinearMaps:
    """Engine coordinates q_e = P q and speeds v_e = P u with one constant matrix P (a mixin
    before the engine's model class, which sets ``_P`` and its inverse ``_Pinv``)."""

    _P: Any
    _Pinv: Any

    def to_engine_state(self, q, u):
        return self._P @ np.asarray(q, float), self._P @ np.asarray(u, float)

    def from_engine_state(self, qe, ve):
        return self._Pinv @ np.asarray(qe, float), self._Pinv @ np.asarray(ve, float)

    def _acc_to_reference(self, qe, ve, ae):
        return self._Pinv @ np.asarray(ae, float)


def frame_bar_to_engine(q, u) -> tuple[np.ndarray, np.ndarray]:
    """Example 3: (phi, theta) and the bar's body-fixed omega (w1, w2, w3) -> the engine's
    hinge angles and rates (phi, theta), phi' = -sin(theta) w1 + cos(theta) w3, theta' = w2."""
    phi, th = (float(v) for v in q)
    w1, w2, w3 = (float(v) for v in u)
    return np.array([phi, th]), np.array([-math.sin(th) * w1 + math.cos(th) * w3, w2])


def frame_bar_from_engine(qe, ve) -> tuple[np.ndarray, np.ndarray]:
    """The inverse of frame_bar_to_engine: omega = (-sin(theta) phi', theta', cos(theta) phi')."""
    th = float(qe[1])
    return (
        np.array(qe, float).copy(),
        np.array([-math.sin(th) * ve[0], ve[1], math.cos(th) * ve[0]]),
    )


def xyz_angles(R) -> np.ndarray:
    """Body-fixed X-Y-Z angles (x, y, z) with R = Rx(x) Ry(y) Rz(z) (OpenSim's ball and free
    joints and its frames' orientations), y in [-pi/2, pi/2]."""
    R = np.asarray(R, float)
    y = math.asin(max(-1.0, min(1.0, R[0, 2])))
    return np.array([math.atan2(-R[1, 2], R[2, 2]), y, math.atan2(-R[0, 1], R[0, 0])])


def rotation_xyz(x: float, y: float, z: float) -> np.ndarray:
    """Rx(x) Ry(y) Rz(z), the inverse of ``xyz_angles``."""
    cx, sx, cy, sy = math.cos(x), math.sin(x), math.cos(y), math.sin(y)
    cz, sz = math.cos(z), math.sin(z)
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Rx @ Ry @ Rz
