"""Pinocchio's trajectories as a first-order ODE y' = F(t, y), y = [q_e, v_e] in the engine's
coordinates (machinery.PinEngineModel.simulate).

Quaternions (x, y, z, w: spherical and free-flyer joints) are renormalized before each
evaluation; their rates come from the local angular velocity, q' = q (x) (omega, 0) / 2, and a
free flyer's position rate is R v_linear (its linear velocity is in the local frame).

Written for the integrator's inner loop, which calls F a dozen times per step: the joint layout
is read from Pinocchio's model once (``model.joints`` builds Python objects on every access),
the quaternion arithmetic is done on Python floats (numpy's call overhead on 3- and 4-vectors
is several times the arithmetic), and the engine's forward call is made without reading back
its constraint forces, which F does not use.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

SPHERICAL, FREE_FLYER = "JointModelSpherical", "JointModelFreeFlyer"


@dataclass(frozen=True)
class JointLayout:
    """Where each joint's coordinates and velocities sit in q_e and v_e."""

    nq: int
    nv: int
    spherical: tuple[tuple[int, int], ...]  # (index in q_e, index in v_e) per ball joint
    free_flyer: tuple[tuple[int, int], ...]  # the same per free flyer
    plain: tuple[tuple[int, int, int], ...]  # (iq, iv, size): q' = v on these (hinge, slide)
    quaternions: tuple[int, ...]  # index in q_e of every quaternion's x


def joint_layout(model: pin.Model) -> JointLayout:
    spherical, free, plain = [], [], []
    for jm in model.joints[1:]:
        kind = jm.shortname()
        if kind == SPHERICAL:
            spherical.append((jm.idx_q, jm.idx_v))
        elif kind == FREE_FLYER:
            free.append((jm.idx_q, jm.idx_v))
        else:
            if jm.nq != jm.nv:
                raise NotImplementedError(
                    f"Pinocchio joint {kind}: {jm.nq} coordinates for {jm.nv} velocities; the "
                    "trajectories know ball joints and free flyers as such (add its rates here)"
                )
            plain.append((jm.idx_q, jm.idx_v, jm.nq))
    quaternions = [iq for iq, _ in spherical] + [iq + 3 for iq, _ in free]
    return JointLayout(
        model.nq, model.nv, tuple(spherical), tuple(free), tuple(plain), tuple(quaternions)
    )


def quat_rate(qxyzw, omega_local) -> list[float]:
    """d/dt of a unit quaternion (x, y, z, w) for the local angular velocity: q (x) (omega, 0)
    / 2, i.e. (w omega + v x omega, -v . omega) / 2 with v = (x, y, z). Written out on floats,
    with the same result to the bit as numpy's form (tests/test_engine_pinocchio.py)."""
    return _quat_rate(*(float(c) for c in qxyzw), *(float(o) for o in omega_local))


def _quat_rate(x, y, z, w, a, b, c) -> list[float]:
    return [
        0.5 * (w * a + (y * c - z * b)),
        0.5 * (w * b + (z * a - x * c)),
        0.5 * (w * c + (x * b - y * a)),
        0.5 * -(x * a + y * b + z * c),
    ]


def quat_rotate(qxyzw, v) -> list[float]:
    """R v for the rotation (local -> world) of a unit quaternion (x, y, z, w): Eigen's
    toRotationMatrix entries, each row applied to v in order, on floats. (numpy's R @ v may
    round differently: its BLAS fuses multiply-adds.)"""
    return _quat_rotate(*(float(c) for c in qxyzw), *(float(o) for o in v))


def _quat_rotate(x, y, z, w, a, b, c) -> list[float]:
    tx, ty, tz = 2.0 * x, 2.0 * y, 2.0 * z
    twx, twy, twz = tx * w, ty * w, tz * w
    txx, txy, txz = tx * x, ty * x, tz * x
    tyy, tyz, tzz = ty * y, tz * y, tz * z
    return [
        (1.0 - (tyy + tzz)) * a + (txy - twz) * b + (txz + twy) * c,
        (txy + twz) * a + (1.0 - (txx + tzz)) * b + (tyz - twx) * c,
        (txz - twy) * a + (tyz + twx) * b + (1.0 - (txx + tyy)) * c,
    ]


def normalized(layout: JointLayout, qe) -> np.ndarray:
    """A copy of q_e with every quaternion scaled to unit length (q_e itself where none)."""
    if not layout.quaternions:
        return qe
    q = np.asarray(qe, float).tolist()
    _unit_quaternions(layout, q)
    return np.array(q)


def _unit_quaternions(layout: JointLayout, q: list[float]) -> None:
    """Scale every quaternion of q_e (a list of floats, changed in place) to unit length."""
    for iq in layout.quaternions:
        x, y, z, w = q[iq : iq + 4]
        n = math.sqrt(x * x + y * y + z * z + w * w)
        q[iq : iq + 4] = (x / n, y / n, z / n, w / n)


def coordinate_rates(layout: JointLayout, q: list[float], v: list[float]) -> list[float]:
    """q_e' from q_e and v_e given as lists of floats (the integrator's path converts each
    state once: numpy's call per 3- or 4-vector slice costs several times the arithmetic)."""
    rates = [0.0] * layout.nq
    for iq, iv, n in layout.plain:
        rates[iq : iq + n] = v[iv : iv + n]
    for iq, iv in layout.spherical:
        rates[iq : iq + 4] = _quat_rate(*q[iq : iq + 4], *v[iv : iv + 3])
    for iq, iv in layout.free_flyer:
        quat = q[iq + 3 : iq + 7]
        rates[iq : iq + 3] = _quat_rotate(*quat, *v[iv : iv + 3])
        rates[iq + 3 : iq + 7] = _quat_rate(*quat, *v[iv + 3 : iv + 6])
    return rates


def right_hand_side(layout: JointLayout, accelerations):
    """F(t, y) = [q_e', v_e'] with v_e' = accelerations(q_e, v_e, t), the engine's forward call
    returning only the accelerations (an array it may own: it is copied here).

    F.into(t, y, out) writes F(t, y) into `out`: LeanDOP853 (reference.integrate.rk) fills each
    stage's row of its stage matrix that way, with no fresh vector and no copy per call."""
    nq, size = layout.nq, layout.nq + layout.nv

    def into(t, y, out) -> None:
        ve = y[nq:]
        if layout.quaternions:
            values = y.tolist()
            q = values[:nq]
            _unit_quaternions(layout, q)
            out[:nq] = coordinate_rates(layout, q, values[nq:])
            qe = np.array(q)
        else:  # q_e' = v_e
            qe = y[:nq]
            out[:nq] = ve
        out[nq:] = accelerations(qe, ve, t)

    def rhs(t, y):
        out = np.empty(size)
        into(t, y, out)
        return out

    rhs.into = into  # type: ignore[attr-defined]
    return rhs
