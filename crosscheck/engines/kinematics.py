"""Rotation helpers every engine adapter shares, written once (textbook conventions).

3-1-3 body angles (Example 4) and Euler parameters eps = (eps1, eps2, eps3, eps4), eps4 scalar
(the tops): omega_body = 2 E(eps) eps', so on |eps| = 1 eps' = E^T omega / 2 and
eps'' = (E(eps')^T omega + E(eps)^T omega') / 2. Quaternion storage orders differ per engine
(Pinocchio x, y, z, w; MuJoCo w, x, y, z), so their conversions stay with each engine and use
the engine's own routines.
"""
from __future__ import annotations

import math

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
