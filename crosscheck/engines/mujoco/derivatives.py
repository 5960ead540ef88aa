"""MuJoCo's own derivatives of its soft answer: mjd_transitionFD, read at the acceleration
level.

mjd_transitionFD differences MuJoCo's step x_next = step(x) (qpos in its tangent space, qvel),
centred, with step EPS. With the Euler integrator the velocity update is
v_next = v + h qacc(q, v), so the velocity rows of its A matrix are h dqacc/dq and
I + h dqacc/dv: the derivatives of MuJoCo's soft answer qacc itself, whole Jacobians in its own
coordinates (the soft rows react to a violation too). The model is stepped with h = 1 for
this (the velocity rows are then the Jacobians themselves, no 1/h magnifying the differences'
round-off), Euler's implicit damping off (mjDSBL_EULERDAMP: v_next = v + h qacc exactly) and
the solref safety clamp off (mjDSBL_REFSAFE: the time constant is not raised to 2h), which
leaves mj_forward's qacc as it is at the model's own step (tests/test_derivatives_engines.py
holds it). The settings are restored after the call.

The Jacobians carry no constraint forces (transitionFD differences states), so this gives the
soft accelerations' derivatives only; along the reference's consistent directions they are
judged against the soft derivatives the impedance predicts
(crosscheck.checks.derivatives.engine). Applied forces: qfrc_applied is not an input of
transitionFD, so there is no 'dtau' block here.
"""

from __future__ import annotations

import mujoco
import numpy as np

from crosscheck.engines.base import EngineUnsupported
from crosscheck.engines.linearization import EngineJacobians, EngineMaps

# mjd_transitionFD's step: its centred differences err by EPS^2 (truncation) and by about
# eps |x_next| / EPS (round-off): 1e-6 puts both near 1e-10 of the state's size
EPS = 1e-6
_FLAGS = int(mujoco.mjtDisableBit.mjDSBL_EULERDAMP) | int(mujoco.mjtDisableBit.mjDSBL_REFSAFE)
METHOD = f"mjd_transitionFD (Euler, step 1, centred, eps {EPS:g})"


def transition_jacobians(em, qe: np.ndarray, ve: np.ndarray) -> EngineJacobians:
    """MuJoCo's qacc at (qe, ve) and its Jacobians from mjd_transitionFD (module docstring)."""
    m, d = em.m, em.d
    saved = (m.opt.timestep, m.opt.integrator, m.opt.disableflags)
    nv = m.nv
    try:
        m.opt.timestep = 1.0
        m.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
        m.opt.disableflags = saved[2] | _FLAGS
        em._set(qe, ve)
        mujoco.mj_forward(m, d)
        qacc = d.qacc.copy()
        A = np.zeros((2 * nv + m.na, 2 * nv + m.na))
        mujoco.mjd_transitionFD(m, d, EPS, True, A, None, None, None)
    except mujoco.FatalError as exc:  # e.g. a model with sleeping enabled
        raise EngineUnsupported(
            f"MuJoCo's mjd_transitionFD refuses this model ({exc}): its answer is differenced"
        ) from exc
    finally:
        m.opt.timestep, m.opt.integrator, m.opt.disableflags = saved
    aq = A[nv : 2 * nv, :nv].copy()
    av = A[nv : 2 * nv, nv : 2 * nv] - np.eye(nv)
    return EngineJacobians(qacc, np.zeros(0), {"q": aq, "v": av}, {}, METHOD)


def maps(em) -> EngineMaps:
    """The engine model's maps as the linearization reads them (accelerations only)."""
    m = em.m

    def tangent(q0, q1):
        out = np.zeros(m.nv)
        mujoco.mj_differentiatePos(m, out, 1.0, np.asarray(q0, float), np.asarray(q1, float))
        return out

    return EngineMaps(
        to_engine=lambda q, u: em.to_engine_state(q, u),
        tangent=tangent,
        back=lambda qe, ve, ae, fe: (em._acc_to_reference(qe, ve, ae), None),
        applied=lambda qe, ve: np.zeros(m.nv),
        jacobians=lambda qe, ve: transition_jacobians(em, qe, ve),
        fault=getattr(em, "planted_fault", None),
    )
