"""Exercises 6.1, 6.2, 6.4 and the two supplements (knife edge, moving support).

(a) the derived equations equal the printed answers as decoded in each model's docstring, for
    every formulation, and Lagrange = d'Alembert = Kane symbolically (M, f, A, b);
(b) each exercise equals a minimal-coordinate model: the multipliers and dependent coordinates
    eliminated symbolically give the minimal model's equations (for 6.1/6.2 also the hand-written
    single/two equations of part (b)), and the accelerations agree numerically;
(c) knife edge: the constraint is "not exact as written", the formulations match Newton-Euler,
    the constraint force does no work and K is conserved without applied loads;
(d) moving support: dE/dt equals the constraint power u.A^T lambda = -lambda a0 (not zero), and
    the motion matches the one-angle equation with the support acceleration;
(e) 6.1, 6.2, 6.4: the declared load power is the hand-written one and dE/dt equals it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

from crosscheck.checks.sampling import random_consistent_state
from reference import NumericModel, models
from reference.constraints import classify
from reference.formulations import derive
from reference.formulations.lagrange import kinetic_energy, potential_energy
from reference.models import exercise_6_1 as ex1
from reference.models import exercise_6_2 as ex2
from reference.models import exercise_6_4 as ex4
from reference.models.common import T_SYM, particle, planar_body
from reference.models.pendulum import rod_tension
from reference.system import Body, Force, Model, Torque, rate, rot_x, rot_z, symbols, vec

FORMS = ["lagrange", "dalembert", "kane"]
EXERCISES = ["exercise_6_1", "exercise_6_2", "exercise_6_4"]
ALL = [*EXERCISES, "knife_edge", "pendulum_moving_support"]
N_STATES = 12  # random consistent states per numeric check

# Two double-precision evaluations of the same physics through different expression trees (the
# compiled KKT solve vs a lambdified closed form) differ by round-off: a few hundred ulps of the
# largest term involved (terms up to ~1e3 in SI for these models). 1e-10 relative to that scale
# leaves four orders of margin over round-off and is far below any modelling error.
ROUNDOFF_REL = 1e-10


def _s(names: str):
    out = sp.symbols(names, real=True)
    return out if isinstance(out, tuple) else (out,)


def _zero(e) -> bool:
    return sp.simplify(sp.expand_trig(sp.expand(e))) == 0


def _assert_same(derived, printed, what=""):
    assert len(derived) == len(printed)
    for k, (d, p) in enumerate(zip(derived, printed, strict=True)):
        diff = sp.simplify(sp.expand_trig(sp.expand(d - p)))
        assert diff == 0, f"{what} equation {k + 1}: derived - printed = {diff}"


def _close(a, b, scale, tol=ROUNDOFF_REL):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b))) <= tol * max(1.0, scale)


# ---- (a) the printed answers, decoded (see each model's docstring) -------------------------


def _printed_6_1():
    m, m_p, l, k, c, F, g, th, x, xd, thd = _s("m m_p l k c F g theta x x_dot theta_dot")
    xdd, ydd, thdd, l1, l2 = _s("x_dot_dot y_dot_dot theta_dot_dot lambda1 lambda2")
    C, S = sp.cos(th), sp.sin(th)
    h = sp.Rational(1, 4)
    dyn = [
        h * m * xdd + c * xd + k * x - l1,
        (h * m + m_p) * ydd + (m / 2 + m_p) * g - (l2 - F),
        sp.Rational(1, 12) * m * l**2 * thdd - l * (-l1 * C + l2 * S),
    ]
    con = [xdd - l * (thdd * C - thd**2 * S), ydd + l * (thdd * S + thd**2 * C)]
    return dyn, con


def _printed_6_2():
    m1, m2, l, k, c, F, g, th, x, xd, thd = _s("m1 m2 l k c F g theta x x_dot theta_dot")
    xdd, thdd, xGdd, yGdd, l1, l2 = _s(
        "x_dot_dot theta_dot_dot x_G_dot_dot y_G_dot_dot lambda1 lambda2"
    )
    C, S = sp.cos(th), sp.sin(th)
    # printed order x, x_G, y_G, theta; the model's coordinates are (x, theta, x_G, y_G)
    e_x = (m1 + m2) * xdd + m2 * xGdd + c * xd + k * x - F
    e_xG = m2 * xdd + m2 * xGdd - l1
    e_yG = m2 * yGdd - m2 * g - l2
    e_th = sp.Rational(1, 12) * m2 * l**2 * thdd - l / 2 * (-l1 * C + l2 * S)
    con = [
        xGdd - l / 2 * thdd * C + l / 2 * thd**2 * S,
        yGdd + l / 2 * thdd * S + l / 2 * thd**2 * C,
    ]
    return [e_x, e_th, e_xG, e_yG], con


def _printed_6_4():
    m_d, R, m, l, k, c, M_phi, M_theta, g = _s("m_d R m l k c M_phi M_theta g")
    th, yG, phid, thd, yGd = _s("theta y_G phi_dot theta_dot y_G_dot")
    phidd, thdd, yGdd, zGdd, l1, l2 = _s(
        "phi_dot_dot theta_dot_dot y_G_dot_dot z_G_dot_dot lambda1 lambda2"
    )
    C, S = sp.cos(th), sp.sin(th)
    e_phi = (
        (m_d * R**2 / 2 + m * yG**2 + m * l**2 * S**2 / 12) * phidd
        + 2 * m * yG * yGd * phid
        + m * l**2 * S * C * thd * phid / 6
        - M_phi
    )
    e_th = (
        m * l**2 * thdd / 12
        - m * l**2 * S * C * phid**2 / 12
        + c * thd
        + k * th
        - (M_theta - l / 2 * l1 * C - l / 2 * l2 * S)
    )
    e_yG = m * yGdd - m * yG * phid**2 - l1
    e_zG = m * zGdd + m * g - l2
    # printed: y_G'' = (l/2) theta'' C - (l/2) theta'^2 S,
    #          z_G'' = (l/2) theta'' S + (l/2) theta'^2 C
    con = [
        yGdd - (l / 2 * thdd * C - l / 2 * thd**2 * S),
        zGdd - (l / 2 * thdd * S + l / 2 * thd**2 * C),
    ]
    return [e_phi, e_th, e_yG, e_zG], con


PRINTED = {"exercise_6_1": _printed_6_1, "exercise_6_2": _printed_6_2, "exercise_6_4": _printed_6_4}


@pytest.mark.parametrize("formulation", FORMS)
@pytest.mark.parametrize("name", EXERCISES)
def test_derived_equations_equal_printed_answers(name, formulation):
    eom = derive(models.get(name), formulation)
    dyn, con = PRINTED[name]()
    _assert_same(eom.residual_equations(), dyn, f"{name}/{formulation} dynamic")
    _assert_same(eom.constraint_equations(), con, f"{name}/{formulation} constraint")


@pytest.mark.parametrize("name", ALL)
def test_formulations_agree_symbolically(name):
    """Lagrange = d'Alembert = Kane: the same M, f, A, b (the speeds are the coordinate rates)."""
    model = models.get(name)
    ref = derive(model, "lagrange")
    for form in ("dalembert", "kane"):
        other = derive(model, form)
        for label in ("M", "f", "A", "b"):
            diff = getattr(other, label) - getattr(ref, label)
            assert all(_zero(e) for e in diff), f"{form} {label} differs from Lagrange: {diff}"


# ---- (b) equivalence with minimal coordinates -------------------------------------------------


def _minimal_6_1() -> Model:
    """Exercise 6.1 in the single coordinate theta (Exercises 4.3 / 5.1)."""
    m, m_p, l, k, c, F, _g = (p.symbol for p in ex1.PARAMETERS)
    (th,), (w,) = symbols("theta"), symbols("theta_dot")
    q, N = (th,), (w,)
    S, C = sp.sin(th), sp.cos(th)
    bar = planar_body("bar", m, m * l**2 / 12, vec(l * S / 2, l * C / 2, 0), th - sp.pi / 2, q, N)
    block = particle("block", m_p, vec(0, l * C, 0), q, N)
    vA, vB = rate(vec(l * S, 0, 0), q, N), rate(vec(0, l * C, 0), q, N)
    return Model(
        name="exercise_6_1_minimal",
        source="Exercises 4.3/5.1 (test)",
        title="6.1 in theta",
        parameters=ex1.PARAMETERS,
        coordinates=q,
        speeds=N,
        kinematics=N,
        bodies=(bar, block),
        gravity=ex1.GRAVITY,
        loads=(Force("damper_A", vA, -c * vA), Force("F_on_P", vB, vec(0, -F, 0))),
        potential=k * (l * S) ** 2 / 2,
        formulations=("lagrange",),
        initial_q=(ex1.THETA0,),
        initial_u=(ex1.THETA_DOT0,),
    )


def _minimal_6_2() -> Model:
    """Exercise 6.2 in the two coordinates (x, theta) (Exercises 4.4 / 5.2)."""
    m1, m2, l, k, c, F, _g = (p.symbol for p in ex2.PARAMETERS)
    x, th = symbols("x theta")
    xd, w = symbols("x_dot theta_dot")
    q, N = (x, th), (xd, w)
    block = particle("block", m1, vec(x, 0, 0), q, N)
    bar = planar_body(
        "bar",
        m2,
        m2 * l**2 / 12,
        vec(x + l / 2 * sp.sin(th), l / 2 * sp.cos(th), 0),
        sp.pi / 2 - th,
        q,
        N,
    )
    v = vec(xd, 0, 0)
    return Model(
        name="exercise_6_2_minimal",
        source="Exercises 4.4/5.2 (test)",
        title="6.2 in (x, theta)",
        parameters=ex2.PARAMETERS,
        coordinates=q,
        speeds=N,
        kinematics=N,
        bodies=(block, bar),
        gravity=ex2.GRAVITY,
        loads=(Force("damper", v, vec(-c * xd, 0, 0)), Force("F", v, vec(F, 0, 0))),
        potential=k * x**2 / 2,
        formulations=("lagrange",),
        initial_q=(ex2.X0, ex2.THETA0),
        initial_u=(ex2.X_DOT0, ex2.THETA_DOT0),
    )


def _minimal_6_4() -> Model:
    """Exercise 6.4 in the two coordinates (phi, theta), the same assumed geometry."""
    m_d, R, m, l, k, c, M_phi, M_theta, _g = (p.symbol for p in ex4.PARAMETERS)
    phi, th = symbols("phi theta")
    phid, thd = symbols("phi_dot theta_dot")
    q, N = (phi, th), (phid, thd)
    disk = Body(
        "disk",
        m_d,
        v_G=vec(0, 0, 0),
        inertia=sp.diag(m_d * R**2 / 4, m_d * R**2 / 4, m_d * R**2 / 2),
        omega=vec(0, 0, phid),
        r_G=vec(0, 0, 0),
        R=rot_z(phi),
    )
    r_G = rot_z(phi) * vec(0, R + l / 2 * sp.sin(th), -l / 2 * sp.cos(th))
    bar = Body(
        "bar",
        m,
        v_G=rate(r_G, q, N, T_SYM),
        inertia=sp.diag(m * l**2 / 12, m * l**2 / 12, 0),
        omega=vec(thd, phid * sp.sin(th), phid * sp.cos(th)),
        r_G=r_G,
        R=rot_z(phi) * rot_x(th),
    )
    rel = vec(thd, 0, 0)
    return Model(
        name="exercise_6_4_minimal",
        source="Exercise 6.4 (test)",
        title="6.4 in (phi, theta)",
        parameters=ex4.PARAMETERS,
        coordinates=q,
        speeds=N,
        kinematics=N,
        bodies=(disk, bar),
        gravity=ex4.GRAVITY,
        loads=(
            Torque("M_phi", vec(0, 0, phid), vec(0, 0, M_phi)),
            Torque("M_theta", rel, vec(M_theta, 0, 0)),
            Torque("damper_P", rel, vec(-c * thd, 0, 0)),
        ),
        potential=k * th**2 / 2,
        formulations=("lagrange",),
        initial_q=(ex4.PHI0, ex4.THETA0),
        initial_u=(ex4.PHI_DOT0, ex4.THETA_DOT0),
    )


def _elimination_6_1(dyn):
    """Part (b): lambda1, lambda2 from the x and y equations into the theta equation, then
    x, y and their rates and accelerations in terms of theta."""
    l, th, w, a = _s("l theta theta_dot theta_dot_dot")
    x, y, xd, yd, xdd, ydd, l1, l2 = _s("x y x_dot y_dot x_dot_dot y_dot_dot lambda1 lambda2")
    S, C = sp.sin(th), sp.cos(th)
    lam = sp.solve([dyn[0], dyn[1]], [l1, l2], dict=True)[0]
    e = dyn[2].subs(lam)
    e = e.subs(
        {xdd: l * (a * C - w**2 * S), ydd: -l * (a * S + w**2 * C), xd: l * C * w, yd: -l * S * w}
    ).subs({x: l * S, y: l * C})
    return [e]


def _elimination_6_2(dyn):
    l, th, w, a = _s("l theta theta_dot theta_dot_dot")
    xG, yG, xGd, yGd, xGdd, yGdd, l1, l2 = _s(
        "x_G y_G x_G_dot y_G_dot x_G_dot_dot y_G_dot_dot lambda1 lambda2"
    )
    S, C = sp.sin(th), sp.cos(th)
    lam = sp.solve([dyn[2], dyn[3]], [l1, l2], dict=True)[0]
    sub = {
        xGdd: l / 2 * (a * C - w**2 * S),
        yGdd: -l / 2 * (a * S + w**2 * C),
        xGd: l / 2 * C * w,
        yGd: -l / 2 * S * w,
        xG: l / 2 * S,
        yG: l / 2 * C,
    }
    return [dyn[0].subs(sub), dyn[1].subs(lam).subs(sub)]


def _elimination_6_4(dyn):
    R, l, th, w, a = _s("R l theta theta_dot theta_dot_dot")
    yG, zG, yGd, zGd, yGdd, zGdd, l1, l2 = _s(
        "y_G z_G y_G_dot z_G_dot y_G_dot_dot z_G_dot_dot lambda1 lambda2"
    )
    S, C = sp.sin(th), sp.cos(th)
    lam = sp.solve([dyn[2], dyn[3]], [l1, l2], dict=True)[0]
    sub = {
        yGdd: l / 2 * (a * C - w**2 * S),
        zGdd: l / 2 * (a * S + w**2 * C),
        yGd: l / 2 * C * w,
        zGd: l / 2 * S * w,
        yG: R + l / 2 * S,
        zG: -l / 2 * C,
    }
    return [dyn[0].subs(sub), dyn[1].subs(lam).subs(sub)]


def _hand_6_1():
    """The single equation of Exercises 4.3/5.1 for the assumed geometry (docstring)."""
    m, m_p, l, k, c, F, g, th, w, a = _s("m m_p l k c F g theta theta_dot theta_dot_dot")
    S, C = sp.sin(th), sp.cos(th)
    return [
        (m * l**2 / 3 + m_p * l**2 * S**2) * a
        + m_p * l**2 * S * C * w**2
        + c * l**2 * C**2 * w
        + k * l**2 * S * C
        - (m / 2 + m_p) * g * l * S
        - F * l * S
    ]


def _hand_6_2():
    """The two equations of Exercises 4.4/5.2 for the assumed geometry (docstring)."""
    m1, m2, l, k, c, F, g, th, x, xd, w, xdd, a = _s(
        "m1 m2 l k c F g theta x x_dot theta_dot x_dot_dot theta_dot_dot"
    )
    S, C = sp.sin(th), sp.cos(th)
    return [
        (m1 + m2) * xdd + m2 * l / 2 * (C * a - S * w**2) + c * xd + k * x - F,
        m2 * l**2 / 3 * a + m2 * l / 2 * C * xdd + m2 * g * l / 2 * S,
    ]


# name -> (minimal model, elimination, hand-written part (b) or None, index of the minimal
# coordinates among the dependent ones)
MINIMAL = {
    "exercise_6_1": (_minimal_6_1, _elimination_6_1, _hand_6_1, [2]),
    "exercise_6_2": (_minimal_6_2, _elimination_6_2, _hand_6_2, [0, 1]),
    "exercise_6_4": (_minimal_6_4, _elimination_6_4, None, [0, 1]),
}


@pytest.mark.parametrize("name", EXERCISES)
def test_eliminating_multipliers_gives_minimal_equations(name):
    make_minimal, eliminate, hand, _ = MINIMAL[name]
    dyn = derive(models.get(name), "lagrange").residual_equations()
    reduced = eliminate(list(dyn))
    minimal = derive(make_minimal(), "lagrange").residual_equations()
    _assert_same(reduced, list(minimal), f"{name} eliminated vs minimal model")
    if hand is not None:
        _assert_same(reduced, hand(), f"{name} eliminated vs part (b)")


@pytest.mark.parametrize("name", EXERCISES)
def test_accelerations_equal_minimal_model(name):
    make_minimal, _, _, idx = MINIMAL[name]
    full = NumericModel(models.get(name))
    small = NumericModel(make_minimal())
    rng = np.random.default_rng(61)
    for _ in range(N_STATES):
        q, u = random_consistent_state(full, rng)
        a_full = full.forward(q, u).accelerations
        a_min = small.forward(q[idx], u[idx]).accelerations
        assert _close(a_full[idx], a_min, np.max(np.abs(a_min))), (name, q, u)


# ---- (e) work-energy balance of the exercises --------------------------------------------------


def _load_power(model: Model) -> sp.Expr:
    """sum F.v over the declared loads (computed here, independently of the core)."""
    P = sp.Integer(0)
    for ld in model.loads:
        if isinstance(ld, Force):
            P += (ld.force.T * ld.velocity)[0]
        else:
            P += (ld.torque.T * ld.omega)[0]
    return P


def _hand_load_power(name):
    if name == "exercise_6_1":
        c, F, xd, yd = _s("c F x_dot y_dot")
        return -c * xd**2 - F * yd  # damper at A, F pushing the block down
    if name == "exercise_6_2":
        c, F, xd = _s("c F x_dot")
        return -c * xd**2 + F * xd
    c, M_phi, M_theta, phid, thd = _s("c M_phi M_theta phi_dot theta_dot")
    return M_phi * phid + M_theta * thd - c * thd**2  # damper/motor between D and B: relative rate


class _EnergyRate:
    """dE/dt = dE/dq q' + dE/du u' + dE/dt and the load power, lambdified from the model."""

    def __init__(self, model: Model, params: dict):
        E = kinetic_energy(model) + potential_energy(model)
        ud = sp.symbols(f"ud0:{len(model.speeds)}", real=True)
        dE = sp.diff(E, model.t) + sum(
            sp.diff(E, q) * k for q, k in zip(model.coordinates, model.kinematics, strict=True)
        )
        dE += sum(sp.diff(E, u) * a for u, a in zip(model.speeds, ud, strict=True))
        pv = {p.symbol: params[p.name] for p in model.parameters}
        args = [*model.coordinates, *model.speeds, *ud, model.t]
        self.dE = sp.lambdify(args, dE.xreplace(pv), "math")
        self.P = sp.lambdify(args, _load_power(model).xreplace(pv), "math")
        # a scale for the comparison: the sum of the magnitudes of the terms of dE/dt
        self.scale = sp.lambdify(
            args, sum(abs(t) for t in sp.Add.make_args(sp.expand(dE.xreplace(pv)))), "math"
        )

    def __call__(self, q, u, ud, t=0.0):
        args = [*q, *u, *ud, t]
        return self.dE(*args), self.P(*args), self.scale(*args)


@pytest.mark.parametrize("name", EXERCISES)
def test_load_power_is_the_declared_one(name):
    assert _zero(_load_power(models.get(name)) - _hand_load_power(name))


@pytest.mark.parametrize("name", EXERCISES)
def test_energy_rate_equals_load_power(name):
    model = models.get(name)
    nm = NumericModel(model)
    rate_of = _EnergyRate(model, nm.params)
    rng = np.random.default_rng(62)
    for _ in range(N_STATES):
        q, u = random_consistent_state(nm, rng)
        fw = nm.forward(q, u)
        dE, P, scale = rate_of(q, u, fw.accelerations)
        assert abs(dE - P) <= ROUNDOFF_REL * max(1.0, scale), (name, dE, P)
        _, _, A, _ = nm.matrices(q, u)
        # scleronomic constraints: their forces do no work (A u = 0 on the manifold)
        assert abs(fw.multipliers @ (A @ u)) <= ROUNDOFF_REL * max(1.0, scale)


# ---- (c) knife edge / Chaplygin sled ------------------------------------------------------------


def test_knife_edge_is_not_exact_as_written():
    (row,) = classify(models.get("knife_edge"))
    assert row["kind"] == "motion"
    assert row["holonomic"] == "not exact as written"
    assert row["time"] == "scleronomic"


@pytest.mark.parametrize("formulation", FORMS)
def test_knife_edge_matches_newton_euler(formulation):
    """m (v' - a w^2) = P, (I_G + m a^2) w' = -m a v w + T, lambda = m (v w + a w')."""
    params = {"P": 0.7, "T": -0.3}
    nm = NumericModel(models.get("knife_edge"), formulation, params)
    m, I_G, a, P, T = (nm.params[k] for k in ("m", "I_G", "a", "P", "T"))
    rng = np.random.default_rng(63)
    for _ in range(N_STATES):
        q, u = random_consistent_state(nm, rng, q_spread=2.0, u_spread=2.0)
        fw = nm.forward(q, u)
        th = q[2]
        v, w = math.cos(th) * u[0] + math.sin(th) * u[1], u[2]
        vdot = math.cos(th) * fw.accelerations[0] + math.sin(th) * fw.accelerations[1]
        wdot = fw.accelerations[2]
        scale = max(abs(v * w), w**2, abs(P), abs(T)) * max(m, I_G, 1.0)
        assert abs(m * (vdot - a * w**2) - P) <= ROUNDOFF_REL * scale
        assert abs((I_G + m * a**2) * wdot + m * a * v * w - T) <= ROUNDOFF_REL * scale
        assert abs(fw.multipliers[0] - m * (v * w + a * wdot)) <= ROUNDOFF_REL * scale


def test_knife_edge_constraint_force_does_no_work_and_energy_is_conserved():
    nm = NumericModel(models.get("knife_edge"), "lagrange", {"P": 0.0, "T": 0.0})
    rate_of = _EnergyRate(nm.model, nm.params)
    rng = np.random.default_rng(64)
    for _ in range(N_STATES):
        q, u = random_consistent_state(nm, rng, q_spread=2.0, u_spread=2.0)
        fw = nm.forward(q, u)
        _, _, A, _ = nm.matrices(q, u)
        dE, P, scale = rate_of(q, u, fw.accelerations)
        # the constraint force lambda (-S, C) at C is normal to the velocity of C
        assert abs(fw.multipliers @ (A @ u)) <= ROUNDOFF_REL * max(1.0, scale)
        assert P == 0.0
        assert abs(dE) <= ROUNDOFF_REL * max(1.0, scale), (q, u, dE)
        assert abs(fw.multipliers[0]) > 1e-3  # the constraint force itself is not zero

    # along a trajectory: K stays constant although the sled turns and drifts
    def rhs(t, s):
        ud, _, _ = nm.forward_fast(list(s[:3]), list(s[3:]), t)
        return np.concatenate([s[3:], ud])

    q0, u0 = np.array(nm.model.initial_q), np.array(nm.model.initial_u)
    K0 = nm.energy(q0, u0)[0]
    sol = solve_ivp(
        rhs, (0.0, 5.0), np.concatenate([q0, u0]), method="DOP853", rtol=1e-12, atol=1e-12
    )
    assert sol.success
    K_end = nm.energy(sol.y[:3, -1], sol.y[3:, -1])[0]
    # DOP853 at rtol = atol = 1e-12 over 5 s: the global error stays near 1e-10 of K (the
    # energy is a quadratic invariant the method does not preserve exactly)
    INTEGRATION_REL = 1e-8
    assert abs(K_end - K0) <= INTEGRATION_REL * K0
    _, vel = nm.residuals(sol.y[:3, -1], sol.y[3:, -1])
    assert abs(vel[0]) <= INTEGRATION_REL * np.max(np.abs(sol.y[3:, -1]))
    assert abs(sol.y[2, -1] - q0[2]) > 0.3  # it did turn (the sled's yaw rate decays as v grows)


# ---- (d) pendulum with a moving support ---------------------------------------------------------


@pytest.mark.parametrize("formulation", FORMS)
def test_moving_support_energy_rate_equals_constraint_power(formulation):
    model = models.get("pendulum_moving_support")
    nm = NumericModel(model, formulation)
    rate_of = _EnergyRate(model, nm.params)
    cs_a0 = sp.lambdify(
        [*model.coordinates, model.t],
        _a0(model).xreplace({p.symbol: nm.params[p.name] for p in model.parameters}),
        "math",
    )
    rng = np.random.default_rng(65)
    powers = []
    for _ in range(N_STATES):
        t = float(rng.uniform(0.0, 3.0))
        q, u = random_consistent_state(nm, rng, t=t)
        fw = nm.forward(q, u, t)
        _, _, A, _ = nm.matrices(q, u, t)
        dE, P_loads, scale = rate_of(q, u, fw.accelerations, t)
        P_c = float(fw.multipliers @ (A @ u))  # u . A^T lambda
        a0 = cs_a0(*q, t)
        assert P_loads == 0.0
        assert abs(P_c + fw.multipliers[0] * a0) <= ROUNDOFF_REL * max(1.0, scale)  # = -lambda a0
        assert abs(dE - P_c) <= ROUNDOFF_REL * max(1.0, scale), (t, dE, P_c)
        powers.append(abs(P_c))
    assert max(powers) > 0.1  # the support really does work on the pendulum


def _a0(model):
    f = sp.Matrix(model.configuration_constraints)
    return f.diff(model.t)[0]


def test_moving_support_matches_the_angle_equation():
    """theta'' = -(g sin(theta) + x_s'' cos(theta))/L and T = m (L w^2 + g C - x_s'' S)."""
    nm = NumericModel(models.get("pendulum_moving_support"))
    m, L, a, W, g = (nm.params[k] for k in ("m", "L", "a", "Omega", "g"))
    rng = np.random.default_rng(66)
    for _ in range(N_STATES):
        t = float(rng.uniform(0.0, 3.0))
        q, u = random_consistent_state(nm, rng, t=t)
        xs, xs_d, xs_dd = a * math.sin(W * t), a * W * math.cos(W * t), -a * W**2 * math.sin(W * t)
        th = math.atan2(q[0] - xs, q[1])
        S, C = math.sin(th), math.cos(th)
        w = ((u[0] - xs_d) * C - u[1] * S) / L
        thdd = -(g * S + xs_dd * C) / L
        expected = [xs_dd + L * (thdd * C - w**2 * S), -L * (thdd * S + w**2 * C)]
        fw = nm.forward(q, u, t)
        scale = max(g, L * w**2, abs(xs_dd))
        assert _close(fw.accelerations, expected, scale)
        T = m * (L * w**2 + g * C - xs_dd * S)
        assert abs(rod_tension(fw.multipliers[0], L) - T) <= ROUNDOFF_REL * max(1.0, m * scale)


def test_moving_support_is_rheonomic_configuration_constraint():
    (row,) = classify(models.get("pendulum_moving_support"))
    assert (row["kind"], row["holonomic"], row["time"]) == (
        "configuration",
        "holonomic",
        "rheonomic",
    )
