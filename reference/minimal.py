"""High-accuracy reference solutions for trajectory errors (work-precision, tests).

Where a model has a minimal-coordinate form the reference comes from it, never from the method
being judged:
- the pendulum (pendulum_angle, pendulum_xy): the exact solution in Jacobi elliptic functions,
  sin(theta/2) = k sn(omega0 t + phi, k^2), theta' = 2 k omega0 cn(...), k = sin(theta_max/2),
  omega0 = sqrt(g/L) (theta from the downward vertical, Example 1), checked against a DOP853
  run of pendulum_angle at rtol 1e-13 (tests/test_integrate.py);
- the slider-crank (slider_crank, slider_crank_split): Example 2(b) reduced to one coordinate,
  theta2 = asin(-l1 sin(theta1) / l2) on the +x branch (C right of A, cos(theta2) > 0),
  integrated by DOP853 at rtol = atol = 1e-13; the model is built here the way
  tests/test_formulations_agree.py builds it (not registered: it is a reference device, not a
  model of the unit);
- everything else: a converged tight run of the model itself (projection, DOP853 at
  rtol = atol = 1e-13).
Each reference states its own accuracy: the largest difference between the tight run and a run
at 10x the tolerance (an upper estimate of the tight run's error, since DOP853's error falls
with the tolerance), or between the elliptic formula and the tight run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import numpy as np
import sympy as sp
from scipy import special
from scipy.integrate import solve_ivp

from reference import models
from reference.errors import ModelInputError
from reference.numeric.model import NumericModel

TIGHT_RTOL = 1e-13
TIGHT_ATOL = 1e-13
CHECK_RTOL = 1e-12  # the second run whose difference estimates the reference's error


@dataclass
class Reference:
    q: np.ndarray
    u: np.ndarray
    kind: str  # what produced it
    accuracy: float  # estimated max error over (q, u)
    note: str = ""

    @property
    def state(self) -> np.ndarray:
        return np.concatenate([self.q, self.u])


# ---- the pendulum, exactly ---------------------------------------------------------------
def pendulum_exact(theta0: float, theta_dot0: float, g: float, L: float, t):
    """theta(t), theta'(t) of theta'' = -(g/L) sin(theta) (libration only)."""
    w0 = math.sqrt(g / L)
    c = 0.5 * (theta_dot0 / w0) ** 2 + (1.0 - math.cos(theta0)) / 1.0  # 1 - cos(theta_max)
    if not c < 2.0:
        raise ModelInputError("pendulum_exact covers libration only (energy below the top)")
    k = math.sqrt(c / 2.0)  # sin(theta_max / 2)
    m = k * k
    if k == 0.0:
        t = np.asarray(t, float)
        return np.zeros_like(t), np.zeros_like(t)
    K = special.ellipk(m)
    s0 = max(-1.0, min(1.0, math.sin(theta0 / 2.0) / k))
    phi = special.ellipkinc(math.asin(s0), m)  # F(asin(s0) | m), cn(phi) >= 0
    if theta_dot0 < 0:
        phi = 2.0 * K - phi  # the same sn, cn < 0
    arg = np.mod(w0 * np.asarray(t, float) + phi, 4.0 * K)  # ellipj is most accurate near 0
    sn, cn, _dn, _ = special.ellipj(arg, m)
    theta = 2.0 * np.arcsin(k * sn)
    theta_dot = 2.0 * k * w0 * cn
    return theta, theta_dot


# ---- the slider-crank in one coordinate -------------------------------------------------------
def slider_crank_one_coordinate():
    """Example 2(b) with theta2 eliminated on the +x branch (the reduction the tests compare
    Example 2(b) and Exercise 6.3 with, and the slider-crank's high-accuracy reference)."""
    from reference.models import slider_crank as sc
    from reference.models.common import particle, planar_body
    from reference.system import Model, Torque, vec

    th1, w1 = sp.Symbol("theta1", real=True), sp.Symbol("theta1_dot", real=True)
    th2 = sp.asin(-sc.l1 * sp.sin(th1) / sc.l2)
    q, N = (th1,), (w1,)
    e1, e2 = vec(sp.cos(th1), sp.sin(th1), 0), vec(sp.cos(th2), sp.sin(th2), 0)
    bodies = (
        planar_body("crank", sc.m1, sc.I_G1, sc.r1 * e1, th1, q, N),
        planar_body("rod", sc.m2, sc.I_G2, sc.l1 * e1 + sc.r2 * e2, th2, q, N),
        particle("slider", sc.m3, sc.l1 * e1 + sc.l2 * e2, q, N),
    )
    return Model(
        name="slider_crank_1dof",
        source="reference reduction of Example 2(b)",
        title="Slider-crank in theta1 only (+x branch)",
        parameters=sc.PARAMETERS,
        coordinates=q,
        speeds=N,
        kinematics=N,
        bodies=bodies,
        gravity=sc.GRAVITY,
        loads=(Torque("T", vec(0, 0, w1), vec(0, 0, sc.T)),),
        formulations=("lagrange",),
        initial_q=(sc.THETA1_0,),
        initial_u=(sc.THETA1_DOT0,),
    )


@cache
def _one_coordinate_model():
    return slider_crank_one_coordinate()


def _ode_run(nm: NumericModel, y0, t_end, rtol, atol):
    """Plain solve_ivp DOP853 of an unconstrained model (y = (q, u), q' = u)."""
    fr, nq = nm.forward_fast, nm.nq

    def fun(t, y):
        yl = y.tolist()
        ud = fr(yl[:nq], yl[nq:], t)[0]
        return yl[nq:] + list(ud)  # list concatenation (ud is an array)

    sol = solve_ivp(fun, (0.0, t_end), np.asarray(y0, float), method="DOP853", rtol=rtol, atol=atol)
    if not sol.success:
        raise RuntimeError(f"reference run failed: {sol.message}")
    return sol.y[:, -1]


def _two_runs(run):
    a, b = run(TIGHT_RTOL, TIGHT_ATOL), run(CHECK_RTOL, CHECK_ATOL)
    return a, float(np.max(np.abs(a - b)))


CHECK_ATOL = 1e-12


def _slider_from_theta1(th1, w1, l1, l2, split: bool):
    s2 = -l1 * math.sin(th1) / l2
    th2 = math.asin(s2)
    w2 = -l1 * math.cos(th1) * w1 / (l2 * math.cos(th2))
    if not split:
        return np.array([th1, th2]), np.array([w1, w2])
    x = l1 * math.cos(th1) + l2 * math.cos(th2)
    xd = -l1 * math.sin(th1) * w1 - l2 * math.sin(th2) * w2
    return np.array([th1, x, th2 + math.pi]), np.array([w1, xd, w2])


def reference_final_state(
    model_name: str,
    t_end: float,
    params: dict | None = None,
    q0=None,
    u0=None,
    formulation: str | None = None,
) -> Reference:
    """The high-accuracy final state at t_end from (q0, u0) (default: the model's initial state,
    which must be consistent), in the model's own coordinates, with its estimated accuracy."""
    model = models.get(model_name)
    nm = NumericModel(model, formulation, params)
    q0 = np.asarray(model.initial_q if q0 is None else q0, float)
    u0 = np.asarray(model.initial_u if u0 is None else u0, float)
    P = nm.params
    if model_name in ("pendulum_angle", "pendulum_xy"):
        g, L = P["g"], P["L"]
        if model_name == "pendulum_angle":
            th0, w0 = float(q0[0]), float(u0[0])
        else:
            x, y = q0
            xd, yd = u0
            th0, w0 = math.atan2(x, y), (y * xd - x * yd) / (x * x + y * y)
        th, w = pendulum_exact(th0, w0, g, L, t_end)
        th, w = float(th), float(w)
        # the formula's own accuracy: against a tight run of the theta ODE (measured ~1e-13)
        ang = NumericModel(models.get("pendulum_angle"), params=params)
        yb = _ode_run(ang, [th0, w0], t_end, TIGHT_RTOL, TIGHT_ATOL)
        acc = float(max(abs(yb[0] - th), abs(yb[1] - w)))
        if model_name == "pendulum_angle":
            q, u = np.array([th]), np.array([w])
        else:
            q = np.array([L * math.sin(th), L * math.cos(th)])
            u = np.array([L * w * math.cos(th), -L * w * math.sin(th)])
            acc *= max(L, L * abs(w), 1.0)
        return Reference(
            q,
            u,
            "exact (Jacobi elliptic functions)",
            acc,
            "accuracy: |elliptic - DOP853 rtol 1e-13 run of theta| (mapped)",
        )
    if model_name in ("slider_crank", "slider_crank_split"):
        split = model_name == "slider_crank_split"
        l1, l2 = P["l1"], P["l2"]
        th1, w1 = float(q0[0]), float(u0[0])
        th2 = float(q0[2] - math.pi) if split else float(q0[1])
        if not math.cos(th2) > 0 or l2 <= l1:
            raise ModelInputError(
                f"{model_name}: the one-coordinate reference covers the +x branch with l2 > l1 "
                f"(cos(theta2) > 0); got cos(theta2) = {math.cos(th2):.3f}, l1 = {l1}, l2 = {l2}"
            )
        one = NumericModel(_one_coordinate_model(), params=params)
        y, acc = _two_runs(lambda r, a: _ode_run(one, [th1, w1], t_end, r, a))
        q, u = _slider_from_theta1(float(y[0]), float(y[1]), l1, l2, split)
        # the map's derivative is at most ~ max(1, l1/l2 ...) <= 2 here: scale the estimate
        return Reference(
            q,
            u,
            "one-coordinate reduction (theta1), DOP853 rtol 1e-13",
            2 * acc,
            "accuracy: 2 x |rtol 1e-13 - rtol 1e-12 run| (the map's gain <= 2)",
        )
    # a converged tight run of the model itself
    from reference.integrate.driver import simulate

    method = "index1" if nm.m == 0 else "projection"

    def run(r, a):
        tr = simulate(nm, q0, u0, t_end, method, rtol=r, atol=a, energy="none")
        return tr.final_state

    y, acc = _two_runs(run)
    return Reference(
        y[: nm.nq],
        y[nm.nq :],
        f"tight run ({method}, DOP853 rtol 1e-13)",
        acc,
        "accuracy: |rtol 1e-13 - rtol 1e-12 run|",
    )
