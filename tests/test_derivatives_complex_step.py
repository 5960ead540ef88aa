"""The exact derivatives of a model on the sums path by complex steps of its forward module
(reference.derivatives.complex_step): equal to the symbolic ones where both work, within the
slow path's derived tolerance, and given for Cassie, too large for the symbolic ones.

Tolerances, scaled as the suite scales (max |a - b| / max(1, max |b|)):
- SAME_SOLVE: the two methods' partial derivatives of R are each exact to round-off (the
  complex step has no subtractive cancellation, its truncation is h^2 = 1e-60 relative) and go
  through the same solve, so they differ by a few ulps of the largest term: measured 2.2e-15
  at worst (top_cartesian; the MJCF files 9.6e-16); 1e-12 is the bound asked of them.
- Across the derivation paths the solves differ too (the unrolled one against the SVD one):
  the suite's bound for two exact solves, EXACT_KKT (1e-11); measured 2.6e-14 (top_cartesian).
- STENCIL (Cassie, which has no symbolic derivatives to compare with): R's partial derivatives
  against fourth-order central differences of its M, f, A, b at h = 1e-3. Their round-off is
  1.5 eps |R| / h over the derivatives' scale: R ~ 1.5e3 against u-derivatives ~ 16 gives
  3.1e-11 (R is quadratic in u, so there is no truncation); in q the scale is R's own (3e-13)
  and the truncation h^4 = 1e-12 times fifth derivatives of sines of sums of angles, of the
  entries' size. Measured 5.2e-14 (q) and 6.2e-12 (u); 1e-10 is 3x the u bound.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from benchmarks.derivation_paths import on_path
from crosscheck.checks.derivatives.records import model_records, reference_records
from crosscheck.checks.sampling import consistent_states
from crosscheck.checks.tolerances import EXACT_KKT
from crosscheck.user_models import load_model_file
from reference import NumericModel, models
from reference.backends import body_sums
from reference.derivatives import DerivativeModel
from reference.derivatives.complex_step import unsupported
from tests.support import representative

DATA = Path(__file__).parent / "data"
CASSIE = DATA / "real" / "pinocchio_cassie.xml"
SAME_SOLVE = 1e-12
STENCIL = 1e-10
CASES = [(name, f) for name in models.names() for f in models.get(name).formulations]
QUICK = {("slider_crank", "kane"), ("top_cartesian", "kane"), ("knife_edge", "lagrange")}


def _scaled(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / max(float(np.max(np.abs(b))), 1.0)) if b.size else 0.0


def _summed(model, formulation: str | None = None) -> NumericModel:
    with on_path("sums"):
        return NumericModel(model, formulation)


def _same_solve(nm: NumericModel, states: int = 3) -> float:
    """The complex steps against the symbolic partial derivatives of the same summed module,
    through the same solve: the worst scaled difference of the Jacobian and d(A^T lambda)."""
    with on_path("sums"):  # the symbolic module differentiates the summed equations written out
        steps, symbolic = DerivativeModel(nm), DerivativeModel(nm, method="symbolic")
    assert (steps.method, symbolic.method) == ("complex_step", "symbolic")
    worst = 0.0
    for q, u in consistent_states(nm, states):
        a, b = steps.at(q, u), symbolic.at(q, u)
        assert np.array_equal(np.isnan(a.jacobian), np.isnan(b.jacobian))
        worst = max(worst, _scaled(np.nan_to_num(a.jacobian), np.nan_to_num(b.jacobian)))
        assert a.forces is not None and b.forces is not None
        worst = max(worst, _scaled(a.forces, b.forces))
    return worst


@pytest.mark.parametrize(("name", "formulation"), representative(CASES, QUICK))
def test_complex_steps_equal_the_symbolic_derivatives(name, formulation):
    """Every built-in model on the sums path: complex steps against the symbolic partial
    derivatives (same module, same solve), and against the symbolic path's unrolled kernel."""
    model = models.get(name)
    nm = _summed(model, formulation)
    assert _same_solve(nm) <= SAME_SOLVE
    symbolic = DerivativeModel(NumericModel(model, formulation))
    steps = DerivativeModel(nm)
    for q, u in consistent_states(nm, 3):
        a, b = steps.at(q, u), symbolic.at(q, u)
        assert _scaled(a.jacobian[: nm.n], b.jacobian[: nm.n]) <= EXACT_KKT.value
        if not np.isnan(a.jacobian).any():
            assert _scaled(a.jacobian, b.jacobian) <= EXACT_KKT.value


@pytest.mark.parametrize(
    "file",
    ["gripper.xml", "fourbar_connect.xml", pytest.param("spatial_mix.xml", marks=pytest.mark.slow)],
)
def test_complex_steps_equal_the_symbolic_derivatives_on_mjcf_files(file):
    """Users' MJCF files on the sums path (the gripper and spatial_mix are on it by size;
    spatial_mix's symbolic derivative module takes 74 s cold): dependent rows, loops, balls."""
    (um,) = load_model_file(DATA / file)
    assert _same_solve(_summed(um.model)) <= SAME_SOLVE


@pytest.mark.parametrize("name", ["slider_crank", "top_cartesian", "exercise_6_4"])
def test_complex_steps_pass_the_slow_path(name):
    """The reference's own derivatives records (whole Jacobians against central differences
    of its forward answer, within their derived tolerance) pass on the sums path."""
    nm = _summed(models.get(name))
    recs = reference_records(name, nm, DerivativeModel(nm), consistent_states(nm, 3))
    judged = [r for r in recs if not r["skipped"]]
    assert judged and all(r["passed"] for r in judged), recs
    assert all("complex steps" in r["reason"] for r in judged)


def test_complex_steps_pass_the_slow_path_on_a_users_loop():
    (um,) = load_model_file(DATA / "fourbar_connect.xml")
    nm = _summed(um.model)
    recs = reference_records(um.name, nm, DerivativeModel(nm), consistent_states(nm, 3))
    judged = [r for r in recs if not r["skipped"]]
    assert judged and all(r["passed"] for r in judged), recs


def test_the_sums_keep_complex_values():
    """body_sums on complex values keeps their imaginary parts (a float array would drop them,
    with a ComplexWarning, an error in this suite): M's is the complex step's derivative."""
    S = body_sums.sum_tables(2, [(0, 1)], [(1,)])
    p = np.array([1.0, 2.0, 0.5, -1.0, 0.0, 3.0])  # P: 3 x 2, row by row
    w = np.eye(3).ravel() * 2.0
    inertia = [*(p + 1e-30j * np.arange(6)), *w]
    M, f = body_sums.sums_batched(S, inertia, [0.0] * 6, [1.0, 2.0])
    P, dP = p.reshape(3, 2), np.arange(6.0).reshape(3, 2)
    assert M.dtype.kind == "c" and f.dtype.kind == "f"
    assert np.allclose(M.real.ravel(), (2 * P.T @ P).ravel(), rtol=1e-15)
    assert np.allclose(M.imag.ravel() / 1e-30, (2 * (dP.T @ P + P.T @ dP)).ravel(), rtol=1e-15)


def test_functions_a_complex_step_cannot_differentiate_are_named():
    assert not unsupported("def matrices(_q, _u, _t, _p):\n    return sin(_q0)*cos(_q1),")
    assert unsupported("    _s0 = abs(_q0) + atan2(_q1, _q0)") == {"abs", "atan2"}


def test_a_sums_model_past_the_symbolic_bound_is_differentiated(monkeypatch):
    """DERIVATIVES_MAX_SIZE stops only the symbolic derivatives: the same model on the sums
    path takes complex steps and has judged records."""
    import reference.derivatives.exact as exact

    monkeypatch.setattr(exact, "DERIVATIVES_MAX_SIZE", 20)
    nm = _summed(models.get("slider_crank"))
    recs = model_records("slider_crank", nm, consistent_states(nm, 2), [], {})
    assert len(recs) > 1 and all(r["passed"] for r in recs if not r["skipped"])


def _stencil(R, x: np.ndarray, h: float = 1e-3) -> np.ndarray:
    """Fourth-order central differences of R at x, one column per entry of x."""
    cols = []
    for k in range(x.size):
        e = np.zeros(x.size)
        e[k] = h
        cols.append((8 * (R(x + e) - R(x - e)) - (R(x + 2 * e) - R(x - 2 * e))) / (12 * h))
    return np.array(cols).T


@pytest.mark.slow
def test_cassie_complex_steps_equal_central_differences_of_its_matrices():
    """R = [M u' - f; A^T lambda; A u' - b] at a state off the manifold with arbitrary u' and
    lambda (R's partial derivatives are defined everywhere): complex steps against the stencil."""
    (um,) = load_model_file(CASSIE)
    nm = NumericModel(um.model)
    rng = np.random.default_rng(1)
    q = np.asarray(um.model.initial_q, float) + 0.1 * rng.standard_normal(nm.nq)
    u, ud, lam = (rng.standard_normal(k) for k in (nm.n, nm.n, nm.m))
    J = DerivativeModel(nm).residual_jacobians(q, u, 0.0, ud, lam)

    def R(qq, uu):
        M, f, A, b = nm.matrices(qq, uu)
        return np.concatenate([M @ ud - f, A.T @ lam, A @ ud - b])

    for x, fd in (("q", _stencil(lambda x: R(x, u), q)), ("u", _stencil(lambda x: R(q, x), u))):
        steps = np.vstack([J[f"P_{x}"], J[f"L_{x}"], J[f"C_{x}"]])
        assert _scaled(fd, steps) <= STENCIL, x


@pytest.mark.slow
def test_cassie_has_exact_derivatives():
    """Cassie (35 speeds, a free base, four loops; size 2.4e6, past the symbolic bound): its
    reference records are judged and pass, its accelerations' derivatives whole Jacobians."""
    (um,) = load_model_file(CASSIE)
    nm = NumericModel(um.model)
    dm = DerivativeModel(nm)
    assert dm.method == "complex_step"
    recs = reference_records(um.name, nm, dm, consistent_states(nm, 2))
    judged = {r["quantity"]: r for r in recs if not r["skipped"]}
    assert {"daccelerations_dq", "daccelerations_du", "daccelerations_dtau"} <= set(judged)
    assert all(r["passed"] for r in judged.values()), judged


def test_the_derivative_benchmark_times_pinocchio_on_a_users_file():
    """benchmarks/derivative_speed.py --model-file: Pinocchio's routine on the file's rows as
    its constraint models (how Cassie's per-state figure is measured)."""
    from crosscheck.bench.derivatives import derivative_records
    from crosscheck.engines.registry import get_engine
    from crosscheck.user_models import register_all

    names = register_all(load_model_file(DATA / "fourbar_connect.xml"))
    rows = {r["path"]: r for r in derivative_records(names, [get_engine("pinocchio")])}
    assert "file's rows" in rows["pinocchio"]["call"]
    assert (
        rows["reference-checked"]["us_per_state"] > 0 and "checked_over_pinocchio" in rows["ratio"]
    )


def test_another_parameter_set_steps_with_its_own_parameters():
    """DerivativeModel.for_model (the sweeps' call): the complex steps evaluate the new
    parameters, as a DerivativeModel made for them does."""
    nm = _summed(models.get("slider_crank"))
    other = nm.with_params({p.name: 1.3 * nm.params[p.name] for p in nm.model.parameters})
    reused, fresh = DerivativeModel(nm).for_model(other), DerivativeModel(other)
    for q, u in consistent_states(other, 2):
        a, b = reused.at(q, u), fresh.at(q, u)
        assert np.array_equal(a.jacobian, b.jacobian)
        assert _scaled(a.jacobian, DerivativeModel(nm).at(q, u).jacobian) > 1e-6


@pytest.mark.slow
def test_pinocchio_derivatives_on_cassie_pass():
    """Pinocchio's analytical derivatives on Cassie against the complex-step ones: neither
    known defect reaches it (its loops join moving bodies, and its column 0, the free flyer's
    translation, does not rotate, so the loop-closure term counted nv extra times is zero)."""
    from crosscheck.checks.derivatives.records import engine_records
    from crosscheck.engines.registry import get_engine
    from crosscheck.user_models import register_all

    (name,) = register_all(load_model_file(CASSIE))
    nm = NumericModel(models.get(name))
    adapter = get_engine("pinocchio")
    recs = engine_records(
        name, nm, DerivativeModel(nm), consistent_states(nm, 2), adapter, nm.params
    )
    judged = {r["quantity"]: r for r in recs if not r["skipped"]}
    assert {"daccelerations_dq", "daccelerations_du", "daccelerations_dtau"} <= set(judged)
    assert all(r["passed"] for r in judged.values()), judged
