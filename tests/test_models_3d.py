"""The three-dimensional systems of the unit: Example 3, Example 4, Exercises 6.5-6.7.

(a) the derived equations equal the printed ones (docs/textbook.md; for 6.5/6.7 the seed's answers,
    whose right sides decode term by term and whose left sides are 2 E^T (I omega' + omega x
    I omega)), symbolically;
(b) Exercise 6.6: lambda = 0 with d'Alembert (and Kane); lambda = 2V - 4K with Lagrange;
(c) kinematics: R^T R' = skew(omega) and v_G = d r_G/dt at random consistent states (the
    models' samplers, their states checked consistent: tests.support.states);
(d) energy: dE/dt = grad E . (q', u') vanishes (or equals the motors' power, Example 3);
(e) Example 4 against sympy.physics.mechanics' KanesMethod with six independent speeds, and its
    multipliers against a Newton-Euler solve written here in numpy; the multipliers of
    Example 3 and Exercise 6.7 against their stated physical meaning.
The printed equations are typed here from the textbook, never built from the model modules.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
import sympy as sp
from scipy.spatial.transform import Rotation

from reference import NumericModel, models
from reference.formulations import derive
from reference.formulations.lagrange import kinetic_energy, potential_energy
from tests.support import scaled_error, states

# Round-off of a handful of products of O(1..1e2) numbers (rotation matrices, omega up to ~80
# rad/s for the top), relative to the size of the terms: ~1e-15 per operation, with margin.
KIN_REL = 1e-12
# A KKT solve of up to 18 unknowns whose M has a condition number ~1e3 (Example 4: transverse
# inertia 1/12 vs axial 1e-4) loses ~3 digits of the 16: round-off ~1e-13 relative, with margin.
SOLVE_REL = 1e-10
# dE/dt is a sum of power terms of size |u| (|M u'| + |f|); round-off of those sums.
ENERGY_REL = 1e-11


def _sym(name):
    return sp.Symbol(name, real=True)


def _syms(fmt, idx):
    return [_sym(fmt.format(i)) for i in idx]


def _vanishes_on_circles(expr, angles) -> bool:
    """expr, rational in sin and cos of `angles` and polynomial in other symbols, is identically
    0. Its numerator with s_a = sin a, c_a = cos a is a polynomial that must lie in the ideal
    (s_a^2 + c_a^2 - 1): these generators have coprime leading terms s_a^2, so they are a
    Groebner basis and the ideal is prime; a zero remainder is necessary and sufficient."""
    num = sp.numer(sp.together(sp.expand(expr)))
    gens, ideal, rep = [], [], {}
    for a in angles:
        s, c = sp.Dummy(f"s_{a}"), sp.Dummy(f"c_{a}")
        rep[sp.sin(a)], rep[sp.cos(a)] = s, c
        gens += [s, c]
        ideal.append(s**2 + c**2 - 1)
    poly = sp.expand(num.xreplace(rep))
    assert not poly.atoms(sp.sin, sp.cos, sp.tan), f"other trigonometric terms in {poly}"
    if poly == 0:
        return True
    others = sorted(poly.free_symbols - set(gens), key=str)
    _, remainder = sp.reduced(poly, ideal, *gens, *others, order="lex")
    return remainder == 0


def _assert_same(derived, printed, angles=None):
    """derived - printed is identically 0: expanded (polynomials), or, given the angles,
    reduced modulo sin^2 + cos^2 = 1 (trigonometric identities)."""
    assert len(derived) == len(printed)
    for k, (d, p) in enumerate(zip(derived, printed, strict=True)):
        diff = sp.expand(d - p)
        ok = diff == 0 or (angles is not None and _vanishes_on_circles(diff, angles))
        assert ok, f"equation {k + 1}: derived - printed = {diff}"


_NUMERIC: dict = {}


def _numeric(name, formulation=None, params=None):
    key = (name, formulation, tuple(sorted((params or {}).items())))
    if key not in _NUMERIC:
        _NUMERIC[key] = NumericModel(models.get(name), formulation, params)
    return _NUMERIC[key]


ALL_3D = ["frame_bar", "double_pendulum_3d", "top_euler", "top_cartesian"]


# ---------------------------------------------------------------------------------------------
# (a) printed equations
# ---------------------------------------------------------------------------------------------
def test_example_3_printed_equations():
    m, d, I1, I2, I3, Mp, Mt, th, lam = map(
        _sym, ["m", "d", "I1", "I2", "I3", "M_phi", "M_theta", "theta", "lambda1"]
    )
    w1, w2, w3 = _syms("omega{}", (1, 2, 3))
    a1, a2, a3 = _syms("omega{}_dot", (1, 2, 3))
    S, C = sp.sin(th), sp.cos(th)
    printed = [
        (I1 + m * d**2) * a1 + (I3 + m * d**2 - I2) * w2 * w3 - (-S * Mp + lam * C),
        I2 * a2 + (I1 - I3) * w1 * w3 - Mt,
        (I3 + m * d**2) * a3 + (I2 - I1 - m * d**2) * w1 * w2 - (C * Mp + lam * S),
    ]
    # the row omega1 C + omega3 S = 0 differentiated with theta' = omega2
    printed_con = [C * a1 + S * a3 + w2 * (w3 * C - w1 * S)]
    eom = derive(models.get("frame_bar"), "kane")
    _assert_same(eom.residual_equations(), printed)
    _assert_same(eom.constraint_equations(), printed_con)


def _textbook_R(a, b, c, lib=sp):
    """Example 4's 3-1-3 R_i as printed (N components -> link components)."""
    C1, S1, C2, S2, C3, S3 = (
        lib.cos(a),
        lib.sin(a),
        lib.cos(b),
        lib.sin(b),
        lib.cos(c),
        lib.sin(c),
    )
    rows = [
        [C1 * C3 - S1 * C2 * S3, S1 * C3 + C1 * C2 * S3, S2 * S3],
        [-C1 * S3 - S1 * C2 * C3, -S1 * S3 + C1 * C2 * C3, S2 * C3],
        [S1 * S2, -C1 * S2, C2],
    ]
    return sp.Matrix(rows) if lib is sp else np.array(rows)


def _example_4_symbols():
    s = {
        n: _sym(n)
        for n in ["l1", "l2", "m1", "m2", "I1_11", "I1_22", "I1_33", "I2_11", "I2_22", "I2_33", "g"]
    }
    th = [_syms(f"theta{i}{{}}", (1, 2, 3)) for i in (1, 2)]
    w = [_syms(f"w{i}{{}}", (1, 2, 3)) for i in (1, 2)]
    wd = [_syms(f"w{i}{{}}_dot", (1, 2, 3)) for i in (1, 2)]
    vd = [_syms(f"v{i}{{}}_dot", (1, 2, 3)) for i in (1, 2)]
    lam = _syms("lambda{}", range(1, 7))
    return s, th, w, wd, vd, lam


def test_example_4_printed_dynamics_eqs_10_to_21():
    s, th, w, wd, vd, lam = _example_4_symbols()
    l1, l2, m1, m2, g = s["l1"], s["l2"], s["m1"], s["m2"], s["g"]
    R1, R2 = _textbook_R(*th[0]), _textbook_R(*th[1])
    La, Lb = sp.Matrix(lam[:3]), sp.Matrix(lam[3:])
    I1 = [s["I1_11"], s["I1_22"], s["I1_33"]]
    I2 = [s["I2_11"], s["I2_22"], s["I2_33"]]
    (w11, w12, w13), (w21, w22, w23) = w
    (a11, a12, a13), (a21, a22, a23) = wd
    printed = [
        I1[0] * a11
        + (I1[2] - I1[1]) * w12 * w13  # (10)
        - (l1 / 2 * (R1[2, :] * La)[0] + l1 * (R1[2, :] * Lb)[0]),
        I1[1] * a12 + (I1[0] - I1[2]) * w11 * w13,  # (11)
        I1[2] * a13
        + (I1[1] - I1[0]) * w11 * w12  # (12)
        - (-l1 / 2 * (R1[0, :] * La)[0] - l1 * (R1[0, :] * Lb)[0]),
        I2[0] * a21 + (I2[2] - I2[1]) * w22 * w23 - l2 / 2 * (R2[2, :] * Lb)[0],  # (13)
        I2[1] * a22 + (I2[0] - I2[2]) * w21 * w23,  # (14)
        I2[2] * a23 + (I2[1] - I2[0]) * w21 * w22 + l2 / 2 * (R2[0, :] * Lb)[0],  # (15)
    ]
    for i, (mi, v) in enumerate(((m1, vd[0]), (m2, vd[1]))):  # (16)-(21)
        for j in range(3):
            printed.append(mi * v[j] - lam[3 * i + j] + (mi * g if j == 1 else 0))
    eom = derive(models.get("double_pendulum_3d"), "kane")
    _assert_same(eom.residual_equations(), printed)


def test_example_4_printed_constraint_eqs_22_23():
    """Eqs. 22-23: the derived rows differentiate R_i^T through the 3-1-3 kinematic equations
    (with 1/sin(theta_i2)); the printed ones use d(R^T x)/dt = R^T (x' + omega x x). Equal
    through sin^2 + cos^2 = 1 only, so the differences are reduced modulo those identities."""
    s, th, w, wd, vd, _lam = _example_4_symbols()
    l1, l2 = s["l1"], s["l2"]
    R1, R2 = _textbook_R(*th[0]), _textbook_R(*th[1])

    def h(wi, ai):  # printed bracket: (-w3' + w1 w2, -(w1^2 + w3^2), w1' + w2 w3)
        return sp.Matrix(
            [-ai[2] + wi[0] * wi[1], -(wi[0] ** 2 + wi[2] ** 2), ai[0] + wi[1] * wi[2]]
        )

    printed = list(sp.Matrix(vd[0]) + l1 / 2 * R1.T * h(w[0], wd[0]))  # (22)
    printed += list(
        sp.Matrix(vd[1])
        + l1 * R1.T * h(w[0], wd[0])  # (23)
        + l2 / 2 * R2.T * h(w[1], wd[1])
    )
    eom = derive(models.get("double_pendulum_3d"), "kane")
    _assert_same(eom.constraint_equations(), printed, angles=th[0] + th[1])


def _top_symbols(n_coords):
    eps = _syms("eps{}", (1, 2, 3, 4))
    ed = _syms("eps{}_dot", (1, 2, 3, 4))
    edd = _syms("eps{}_dot_dot", (1, 2, 3, 4))
    m, L, I, I3, g = map(_sym, ["m", "L", "I", "I3", "g"])
    lam = _syms("lambda{}", range(1, n_coords + 1))
    return eps, ed, edd, m, L, I, I3, g, lam


def _printed_euler_lhs(eps, ed, edd, It, I3):
    """The left sides 2 E^T (I omega' + omega x I omega) of 6.5 (It = I + m L^2) and 6.7
    (It = I), written out row by row as printed, then expressed in the Euler parameters with
    omega = 2 E eps' and omega' = 2 E eps'' (E(eps') eps' = 0)."""
    e1, e2, e3, e4 = eps
    Et = sp.Matrix([[e4, e3, -e2, -e1], [-e3, e4, e1, -e2], [e2, -e1, e4, -e3]])  # typed here
    W, Wd = 2 * Et * sp.Matrix(ed), 2 * Et * sp.Matrix(edd)
    w1, w2, w3 = W
    a1, a2, a3 = Wd
    return [
        2 * It * (e4 * a1 - e3 * a2) + 2 * I3 * e2 * a3 + 2 * (I3 - It) * w3 * (e4 * w2 + e3 * w1),
        2 * It * (e3 * a1 + e4 * a2) - 2 * I3 * e1 * a3 + 2 * (I3 - It) * w3 * (e3 * w2 - e4 * w1),
        2 * It * (e1 * a2 - e2 * a1) + 2 * I3 * e4 * a3 - 2 * (I3 - It) * w3 * (e1 * w1 + e2 * w2),
        -2 * It * (e1 * a1 + e2 * a2) - 2 * I3 * e3 * a3 + 2 * (I3 - It) * w3 * (e2 * w1 - e1 * w2),
    ]


@pytest.mark.parametrize("formulation", ["dalembert", "kane"])
def test_exercise_6_5_printed_equations(formulation):
    eps, ed, edd, m, L, I, I3, g, (lam,) = _top_symbols(1)
    e1, e2, e3, e4 = eps
    lhs = _printed_euler_lhs(eps, ed, edd, I + m * L**2, I3)
    rhs = [
        4 * m * g * L * e1 * (e3**2 + e4**2) + lam * e1,
        4 * m * g * L * e2 * (e3**2 + e4**2) + lam * e2,
        -4 * m * g * L * e3 * (e1**2 + e2**2) + lam * e3,
        -4 * m * g * L * e4 * (e1**2 + e2**2) + lam * e4,
    ]
    eom = derive(models.get("top_euler"), formulation)
    _assert_same(eom.residual_equations(), [a - b for a, b in zip(lhs, rhs, strict=True)])
    # fourth row of the kinematical equations, 0 = 2 eps . eps', differentiated (halved)
    _assert_same(
        eom.constraint_equations(),
        [sum(e * a for e, a in zip(eps, edd, strict=True)) + sum(v**2 for v in ed)],
    )


@pytest.mark.parametrize("formulation", ["dalembert", "kane"])
def test_exercise_6_7_printed_equations(formulation):
    eps, ed, edd, m, L, I, I3, g, lam = _top_symbols(4)
    e1, e2, e3, e4 = eps
    l1, l2, l3, l4 = lam
    xdd = _syms("x{}_dot_dot", (1, 2, 3))
    printed = [m * xdd[0] - l1, m * xdd[1] - l2, m * xdd[2] + m * g - l3]
    lhs = _printed_euler_lhs(eps, ed, edd, I, I3)
    rhs = [
        -2 * L * e3 * l1 + 2 * L * e4 * l2 + 2 * L * e1 * l3 + e1 * l4,
        -2 * L * e4 * l1 - 2 * L * e3 * l2 + 2 * L * e2 * l3 + e2 * l4,
        -2 * L * e1 * l1 - 2 * L * e2 * l2 - 2 * L * e3 * l3 + e3 * l4,
        -2 * L * e2 * l1 + 2 * L * e1 * l2 - 2 * L * e4 * l3 + e4 * l4,
    ]
    printed += [a - b for a, b in zip(lhs, rhs, strict=True)]
    # printed position rows x - L(...) = 0 and the normalization, differentiated twice here
    t = sp.Symbol("t")
    X = [sp.Function(f"X{i}")(t) for i in (1, 2, 3)]
    P = [sp.Function(f"P{i}")(t) for i in (1, 2, 3, 4)]
    f = [
        X[0] - 2 * L * (P[0] * P[2] + P[1] * P[3]),
        X[1] - 2 * L * (P[1] * P[2] - P[0] * P[3]),
        X[2] + L * (P[0] ** 2 + P[1] ** 2 - P[2] ** 2 - P[3] ** 2),
        (sum(p**2 for p in P) - 1) / 2,
    ]
    rep = {}
    for fn, sym, d1, d2 in zip(
        X + P,
        _syms("x{}", (1, 2, 3)) + eps,
        _syms("x{}_dot", (1, 2, 3)) + ed,
        xdd + edd,
        strict=True,
    ):
        rep.update({fn.diff(t, 2): d2, fn.diff(t): d1})
        rep[fn] = sym
    printed_con = [sp.expand(fj.diff(t, 2)).subs(rep) for fj in f]
    eom = derive(models.get("top_cartesian"), formulation)
    _assert_same(eom.residual_equations(), printed)
    _assert_same(eom.constraint_equations(), printed_con)


def test_printed_equation_check_can_fail():
    """The comparison detects a wrong sign: Example 3 with lambda S replaced by -lambda S."""
    m, d, I1, I2, I3, Mp, th, lam = map(
        _sym, ["m", "d", "I1", "I2", "I3", "M_phi", "theta", "lambda1"]
    )
    w1, w2 = _syms("omega{}", (1, 2))
    a3 = _sym("omega3_dot")
    wrong = (
        (I3 + m * d**2) * a3 + (I2 - I1 - m * d**2) * w1 * w2 - (sp.cos(th) * Mp - lam * sp.sin(th))
    )
    eom = derive(models.get("frame_bar"), "kane")
    with pytest.raises(AssertionError):
        _assert_same([eom.residual_equations()[2]], [wrong])


# ---------------------------------------------------------------------------------------------
# (b) Exercise 6.6
# ---------------------------------------------------------------------------------------------
def _lambda_free_sum(eom):
    """sum_k eps_k (M u' - f)_k: equals lambda eps.eps by the equations of motion."""
    eps = eom.model.coordinates[-4:]
    res0 = eom.M * sp.Matrix(eom.accelerations) - eom.f
    return sp.expand(sum(e * r for e, r in zip(eps, list(res0)[-4:], strict=True)))


@pytest.mark.parametrize("formulation", ["dalembert", "kane"])
def test_exercise_6_6_multiplier_is_zero(formulation):
    """Symbolically: eps . (M eps'' - f) = 0 identically (the textbook's hint), so lambda = 0;
    numerically at random consistent states."""
    eom = derive(models.get("top_euler"), formulation)
    assert _lambda_free_sum(eom) == 0
    nm = _numeric("top_euler", formulation)
    for q, u in states(nm, 20, seed=66):
        fw = nm.forward(q, u)
        M, f, _, _ = nm.matrices(q, u)
        # lambda is a difference of generalized forces of size |M u'| + |f|
        scale = np.abs(M @ fw.accelerations).max() + np.abs(f).max()
        assert abs(fw.multipliers[0]) < SOLVE_REL * scale, (q, u, fw.multipliers)


def test_exercise_6_6_lagrange_multiplier_is_2V_minus_4K():
    """Lagrange: eps . (M eps'' - f) = 2V - 4K identically (K homogeneous of degree 2 in eps and
    in eps', eps . dK/deps' = 0, V = m g L R33 homogeneous of degree 2), so on eps.eps = 1
    lambda = 2V - 4K != 0: the multiplier depends on the formulation, the motion does not."""
    model = models.get("top_euler")
    eom = derive(model, "lagrange")
    K, V = kinetic_energy(model), potential_energy(model)
    assert sp.expand(_lambda_free_sum(eom) - (2 * V - 4 * K)) == 0
    nm, nd = _numeric("top_euler", "lagrange"), _numeric("top_euler", "dalembert")
    for q, u in states(nm, 20, seed=67):
        fw = nm.forward(q, u)
        K, V = nm.energy(q, u)
        assert abs(fw.multipliers[0] - (2 * V - 4 * K)) < SOLVE_REL * (abs(V) + 4 * abs(K))
        assert abs(fw.multipliers[0]) > 1e-3 * (abs(V) + K)  # really nonzero
        assert scaled_error(fw.accelerations, nd.forward(q, u).accelerations) < SOLVE_REL


# ---------------------------------------------------------------------------------------------
# (c) kinematic consistency
# ---------------------------------------------------------------------------------------------
def _body_functions(model, body, R=None):
    """Numeric R, R', omega, v_G (inertial), r_G, r_G' of a body at (q, u, params)."""
    R = body.R if R is None else R
    v_in = body.v_G if body.v_frame == "inertial" else R * body.v_G
    exprs = [
        R,
        model.time_derivative(R),
        body.omega,
        v_in,
        body.r_G,
        model.time_derivative(body.r_G),
    ]
    args = (model.coordinates, model.speeds, model.parameter_symbols, model.t)
    return sp.lambdify(args, exprs, "numpy")


@pytest.mark.parametrize("name", ALL_3D)
def test_rotation_rate_and_mass_center_velocity(name):
    model = models.get(name)
    nm = _numeric(name)
    p = [nm.params[x.name] for x in model.parameters]
    for body in model.bodies:
        fn = _body_functions(model, body)
        for q, u in states(nm, 15, seed=3):
            R, Rd, w, v, _r, rd = (np.array(x, float) for x in fn(q, u, p, 0.0))
            w = w.ravel()
            scale = 1 + np.abs(w).max()
            assert np.abs(R.T @ R - np.eye(3)).max() < KIN_REL
            assert np.abs(np.linalg.det(R) - 1) < KIN_REL
            W = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
            assert np.abs(R.T @ Rd - W).max() < KIN_REL * scale, (name, body.name, q, u)
            assert np.abs(v.ravel() - rd.ravel()).max() < KIN_REL * (1 + np.abs(rd).max())


def test_example_4_rotation_convention_matters():
    """The check above can fail: the textbook's R_i (N -> n_i) itself, untransposed, is not a
    body -> inertial matrix with these kinematics."""
    model = models.get("double_pendulum_3d")
    nm = _numeric("double_pendulum_3d")
    body = model.bodies[0]
    fn = _body_functions(model, body, R=body.R.T)
    q, u = states(nm, 1, seed=4)[0]
    p = [nm.params[x.name] for x in model.parameters]
    R, Rd, w, *_ = (np.array(x, float) for x in fn(q, u, p, 0.0))
    w = w.ravel()
    W = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    assert np.abs(R.T @ Rd - W).max() > 1e-3


def test_example_4_rotation_rate_symbolic():
    """R_i d(R_i^T)/dt = skew(omega_i) identically with the 3-1-3 kinematic equations, and
    R_i R_i^T = 1 (each entry reduced modulo sin^2 + cos^2 = 1)."""
    model = models.get("double_pendulum_3d")
    for body in model.bodies:
        Rb = body.R  # body -> inertial = R_i^T
        w = body.omega
        W = sp.Matrix([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
        _assert_same(list(Rb.T * model.time_derivative(Rb)), list(W), angles=model.coordinates)
        _assert_same(list(Rb.T * Rb), list(sp.eye(3)), angles=model.coordinates)
    # and the reduction is not vacuous: a wrong kinematic equation is caught
    th1, th2, th3 = model.coordinates[:3]
    assert not _vanishes_on_circles(sp.sin(th1) * sp.cos(th2) - sp.sin(th2), (th1, th2, th3))


# ---------------------------------------------------------------------------------------------
# (d) energy
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "name,formulation", [(n, f) for n in ALL_3D for f in models.get(n).formulations]
)
def test_energy_rate(name, formulation):
    """dE/dt = grad E . (q', u') along the dynamics: 0 for the conservative systems; for
    Example 3 with motor torques, M_phi phi' + M_theta theta' (power of the motors)."""
    params = {"M_phi": 0.7, "M_theta": -0.4} if name == "frame_bar" else {}
    nm = _numeric(name, formulation, params)
    for q, u in states(nm, 15, seed=5):
        pb = nm.power_balance(q, u)
        M, f, _, _ = nm.matrices(q, u)
        ud = nm.forward(q, u).accelerations
        scale = np.abs(u).max() * (np.abs(M @ ud).max() + np.abs(f).max())
        if name == "frame_bar":
            phi_dot, theta_dot = nm.kinematics(q, u)
            expected = params["M_phi"] * phi_dot + params["M_theta"] * theta_dot
        else:
            expected = 0.0
        assert abs(pb["dE_dt"] - expected) < ENERGY_REL * scale, (q, u, pb)


# ---------------------------------------------------------------------------------------------
# (e) independent checks of Example 4, and the multipliers' meaning
# ---------------------------------------------------------------------------------------------
@functools.cache
def _kanes_double_pendulum():
    """The same double pendulum in sympy.physics.mechanics: 3-1-3 orientations, six independent
    speeds (body-fixed omegas), kinematic equations derived by sympy from the orientation."""
    import sympy.physics.mechanics as me

    q = me.dynamicsymbols("q1:7")
    u = me.dynamicsymbols("u1:7")
    l1, l2, m1, m2, g = sp.symbols("l1 l2 m1 m2 g")
    Ia, Ib = sp.symbols("Ia1:4"), sp.symbols("Ib1:4")
    N = me.ReferenceFrame("N")
    A, B = me.ReferenceFrame("A"), me.ReferenceFrame("B")
    A.orient_body_fixed(N, q[:3], "313")
    B.orient_body_fixed(N, q[3:], "313")
    kd = []
    for F, us in ((A, u[:3]), (B, u[3:])):
        wv = F.ang_vel_in(N)
        kd += [wv.dot(F.x) - us[0], wv.dot(F.y) - us[1], wv.dot(F.z) - us[2]]
    A.set_ang_vel(N, u[0] * A.x + u[1] * A.y + u[2] * A.z)
    B.set_ang_vel(N, u[3] * B.x + u[4] * B.y + u[5] * B.z)
    O = me.Point("O")
    O.set_vel(N, 0)
    G1 = O.locatenew("G1", -l1 / 2 * A.y)
    PA = O.locatenew("A", -l1 * A.y)
    G2 = PA.locatenew("G2", -l2 / 2 * B.y)
    G1.v2pt_theory(O, N, A)
    PA.v2pt_theory(O, N, A)
    G2.v2pt_theory(PA, N, B)
    bodies = [
        me.RigidBody("b1", G1, A, m1, (me.inertia(A, *Ia), G1)),
        me.RigidBody("b2", G2, B, m2, (me.inertia(B, *Ib), G2)),
    ]
    KM = me.KanesMethod(N, q_ind=q, u_ind=u, kd_eqs=kd)
    KM.kanes_equations(bodies, [(G1, -m1 * g * N.y), (G2, -m2 * g * N.y)])
    qs, us = sp.symbols("q1:7"), sp.symbols("u1:7")
    rep = dict(zip(q, qs, strict=True)) | dict(zip(u, us, strict=True))
    pars = (l1, l2, m1, m2, *Ia, *Ib, g)
    fn = sp.lambdify((qs, us, pars), [KM.mass_matrix.xreplace(rep), KM.forcing.xreplace(rep)])
    dcm = sp.lambdify((qs,), [A.dcm(N).xreplace(rep), B.dcm(N).xreplace(rep)])
    return fn, dcm


def _dp_params(nm):
    P = nm.params
    return (
        P["l1"],
        P["l2"],
        P["m1"],
        P["m2"],
        P["I1_11"],
        P["I1_22"],
        P["I1_33"],
        P["I2_11"],
        P["I2_22"],
        P["I2_33"],
        P["g"],
    )


def test_example_4_against_kanes_method():
    fn, dcm = _kanes_double_pendulum()
    nm = _numeric("double_pendulum_3d")
    model = nm.model
    Rfun = sp.lambdify((model.coordinates,), [b.R for b in model.bodies])
    for q, u in states(nm, 8, seed=44):
        # our Body.R (body -> N) is the transpose of sympy's (and the textbook's) N -> body DCM
        for Rb, D in zip(Rfun(q), dcm(q), strict=True):
            assert np.abs(np.array(Rb, float).T - np.array(D, float)).max() < KIN_REL
        M, F = (np.array(x, float) for x in fn(q, u[:6], _dp_params(nm)))
        wdot = np.linalg.solve(M, F.ravel())
        assert scaled_error(nm.forward(q, u).accelerations[:6], wdot) < SOLVE_REL, (q, u)


def _newton_euler(q, u, P):
    """Ball-joint double pendulum by Newton-Euler in N components (numpy, independent of the
    model): unknowns alpha1, alpha2, a_G1, a_G2, F_O (ground on link 1), F_A (link 1 on 2)."""
    l1, l2, m1, m2, i11, i12, i13, i21, i22, i23, g = P
    R1, R2 = (_textbook_R(*q[3 * i : 3 * i + 3], lib=np).T for i in (0, 1))  # link -> N
    n12, n22 = R1[:, 1], R2[:, 1]
    rG1, rA = -l1 / 2 * n12, -l1 * n12
    rG2 = rA - l2 / 2 * n22
    w1, w2 = R1 @ u[0:3], R2 @ u[3:6]
    J1, J2 = R1 @ np.diag([i11, i12, i13]) @ R1.T, R2 @ np.diag([i21, i22, i23]) @ R2.T
    X = lambda r: np.array([[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]])
    Z, E = np.zeros((3, 3)), np.eye(3)
    W = np.array([0.0, -g, 0.0])
    # columns: alpha1, alpha2, aG1, aG2, F_O, F_A
    K = np.block(
        [
            [Z, Z, m1 * E, Z, -E, E],  # m1 aG1 = F_O - F_A + m1 W
            [Z, Z, Z, m2 * E, Z, -E],  # m2 aG2 = F_A + m2 W
            [
                J1,
                Z,
                Z,
                Z,
                -X(-rG1),
                X(rA - rG1),
            ],  # J1 al1 + w1 x J1 w1 = (O-G1) x F_O + (A-G1) x -F_A
            [Z, J2, Z, Z, Z, -X(rA - rG2)],  # J2 al2 + w2 x J2 w2 = (A-G2) x F_A
            [X(rG1), Z, E, Z, Z, Z],  # aG1 = al1 x rG1 + w1 x (w1 x rG1)
            [X(rA), X(rG2 - rA), Z, E, Z, Z],  # aG2 = al1 x rA + al2 x (rG2 - rA) + centripetal
        ]
    )
    rhs = np.concatenate(
        [
            m1 * W,
            m2 * W,
            -np.cross(w1, J1 @ w1),
            -np.cross(w2, J2 @ w2),
            np.cross(w1, np.cross(w1, rG1)),
            np.cross(w1, np.cross(w1, rA)) + np.cross(w2, np.cross(w2, rG2 - rA)),
        ]
    )
    x = np.linalg.solve(K, rhs)
    a1, a2, aG1, aG2, FO, FA = (x[3 * k : 3 * k + 3] for k in range(6))
    return R1.T @ a1, R2.T @ a2, aG1, aG2, FO, FA


def test_example_4_multipliers_are_joint_forces():
    """lambda[3:6] = F_A (link 1 on link 2), lambda[0:3] = F_O - F_A; the accelerations agree
    too (omega' in link components, v' = a_G in N components)."""
    nm = _numeric("double_pendulum_3d")
    for q, u in states(nm, 8, seed=45):
        fw = nm.forward(q, u)
        al1, al2, aG1, aG2, FO, FA = _newton_euler(q, u, _dp_params(nm))
        assert scaled_error(fw.accelerations, np.concatenate([al1, al2, aG1, aG2])) < SOLVE_REL
        assert scaled_error(fw.multipliers, np.concatenate([FO - FA, FA])) < SOLVE_REL


def test_example_3_multiplier_meaning():
    """lambda = m d a_G . k + (I alpha + omega x H) . n1: the n1 component of the bearing moment
    on the light frame (C times Eq. k=1 plus S times Eq. k=3)."""
    params = {"M_phi": 0.7, "M_theta": -0.4}
    nm = _numeric("frame_bar", None, params)
    P = nm.params
    Iv = np.array([P["I1"], P["I2"], P["I3"]])
    for q, u in states(nm, 15, seed=33):
        fw = nm.forward(q, u)
        S, C = math.sin(q[1]), math.cos(q[1])
        w, a = u, fw.accelerations
        aG = P["d"] * np.array([-a[2] + w[0] * w[1], -(w[0] ** 2 + w[2] ** 2), a[0] + w[1] * w[2]])
        Tstar = Iv * a + np.cross(w, Iv * w)
        lam = P["m"] * P["d"] * aG @ np.array([-S, 0, C]) + Tstar @ np.array([C, 0, S])
        assert abs(fw.multipliers[0] - lam) < SOLVE_REL * (
            1 + np.abs(Tstar).max() + P["m"] * P["d"] * np.abs(aG).max()
        )


def test_example_3_multiplier_depends_on_partial_velocities():
    """docs/textbook.md: lambda depends on how v_G is written in the dependent speeds. Adding
    d (omega1 C + omega3 S) n2 to v_G (zero on the manifold) leaves the motion and shifts lambda
    by m d a_G . n2 = -m d^2 phi'^2."""
    import dataclasses

    model = models.get("frame_bar")
    w1, _, w3 = model.speeds
    th = model.coordinates[1]
    bar = model.bodies[0]
    extra = _sym("d") * (w1 * sp.cos(th) + w3 * sp.sin(th)) * sp.Matrix([0, 1, 0])
    variant = dataclasses.replace(
        model,
        name="frame_bar_test_variant",
        bodies=(dataclasses.replace(bar, v_G=bar.v_G + extra),),
    )
    params = {"M_phi": 0.7, "M_theta": -0.4}
    nm, nv = _numeric("frame_bar", None, params), NumericModel(variant, None, params)
    P = nm.params
    for q, u in states(nm, 10, seed=34):
        a, b = nm.forward(q, u), nv.forward(q, u)
        phi_dot = nm.kinematics(q, u)[0]
        shift = -P["m"] * P["d"] ** 2 * phi_dot**2
        assert scaled_error(b.accelerations, a.accelerations) < SOLVE_REL
        assert abs(b.multipliers[0] - a.multipliers[0] - shift) < SOLVE_REL * (1 + abs(shift))
        if abs(shift) > 1e-3:
            assert abs(b.multipliers[0] - a.multipliers[0]) > 1e-6


def test_exercise_6_7_multipliers_are_the_socket_force():
    """(lambda1, lambda2, lambda3) = F_O: with it, Euler's equations about G hold,
    I alpha + omega x I omega = (-L e3) x R^T F_O with alpha = 2 E eps'' and R from scipy's
    quaternion (an independent rotation convention); and the motion equals 6.5's."""
    nm = _numeric("top_cartesian")
    ne = _numeric("top_euler")
    P = nm.params
    Iv = np.array([P["I"], P["I"], P["I3"]])
    for q, u in states(nm, 15, seed=77):
        fw = nm.forward(q, u)
        e1, e2, e3, e4 = q[3:]
        E = np.array([[e4, e3, -e2, -e1], [-e3, e4, e1, -e2], [e2, -e1, e4, -e3]])
        w, alpha = 2 * E @ u[3:], 2 * E @ fw.accelerations[3:]
        R = Rotation.from_quat([e1, e2, e3, e4]).as_matrix()  # scalar last; body -> N
        F_body = R.T @ fw.multipliers[:3]
        lhs = Iv * alpha + np.cross(w, Iv * w)
        rhs = np.cross([0.0, 0.0, -P["L"]], F_body)
        assert np.abs(lhs - rhs).max() < SOLVE_REL * (
            1 + np.abs(Iv * alpha).max() + np.abs(np.cross(w, Iv * w)).max()
        )
        assert (
            scaled_error(fw.accelerations[3:], ne.forward(q[3:], u[3:]).accelerations) < SOLVE_REL
        )
        # eps times the Euler-parameter rows: 0 = -2 x . F_O + lambda4 (E eps = 0, and each
        # x_j - L (R e3)_j is homogeneous of degree 2 in eps)
        lam4 = 2 * q[:3] @ fw.multipliers[:3]
        assert abs(fw.multipliers[3] - lam4) < SOLVE_REL * (
            1 + np.abs(q[:3]).max() * np.abs(fw.multipliers[:3]).max()
        )
