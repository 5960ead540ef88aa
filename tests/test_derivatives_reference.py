"""The reference's exact derivatives (reference.derivatives): against the slow, obvious path
(central differences of its own forward call), between the two exact paths, across the
formulations along the consistent directions, and the cache they live in."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from crosscheck.checks.sampling import consistent_states
from crosscheck.user_models import load_model_file, register_all
from reference import NumericModel, models
from reference.backends import codegen
from reference.derivatives import DerivativeModel
from reference.derivatives.differences import STEP, central_differences
from reference.derivatives.directions import along, consistent_directions
from tests.support import representative

DATA = Path(__file__).parent / "data"
BLOCKS = ("dud_dq", "dud_du", "dud_dtau", "dlam_dq", "dlam_du", "dlam_dtau")
# the reference's forward answer is exact to about 16 eps cond(K) of its size; the stencil
# magnifies that by 1.5/h
ROUND_OFF = 16 * np.finfo(float).eps * 1.5 / STEP
QUICK = {"pendulum_xy", "slider_crank", "top_euler", "double_pendulum_3d"}
CASES = [(name, f) for name in models.names() for f in models.get(name).formulations]


def _scaled(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / max(float(np.max(np.abs(b))), 1.0)) if b.size else 0.0


@pytest.mark.parametrize(("name", "formulation"), representative(CASES, QUICK, lambda c: c[0]))
def test_exact_derivatives_agree_with_central_differences(name, formulation):
    """Whole Jacobians (every coordinate, speed and generalized force) of every block, at three
    consistent states: the exact derivatives against the fourth-order central differences of
    the reference's own forward answer, within twice the stencil's truncation (estimated from
    the step 2h) plus its round-off (measured: 5e-13..1.3e-10, scaled)."""
    nm = NumericModel(models.get(name), formulation)
    dm = DerivativeModel(nm)
    for q, u in consistent_states(nm, 3):
        exact = dm.at(q, u)
        slow, trunc = central_differences(nm, q, u)
        M, _f, A, _b = nm.matrices(q, u)
        m = A.shape[0]
        kappa = np.linalg.cond(np.block([[M, -A.T], [A, np.zeros((m, m))]]))
        for block in BLOCKS:
            got, fd = getattr(exact, block), getattr(slow, block)
            if not fd.size:
                continue
            scale = max(float(np.max(np.abs(got))), 1.0)
            values = max(float(np.max(np.abs(exact.accelerations))), 1.0)
            bound = (2 * float(np.max(getattr(trunc, block))) + ROUND_OFF * kappa * values) / scale
            assert _scaled(fd, got) <= bound + 1e-12, (name, formulation, block)


@pytest.mark.parametrize("name", ["slider_crank", "double_pendulum_3d"])
def test_the_forward_part_is_the_forward_code_bit_for_bit(name):
    """The derivative kernel solves the forward problem with the forward module's expressions
    in its order: u' and lambda equal NumericModel.forward's exactly."""
    nm = NumericModel(models.get(name))
    dm = DerivativeModel(nm)
    for q, u in consistent_states(nm, 3):
        d, fw = dm.at(q, u), nm.forward(q, u)
        assert np.array_equal(d.accelerations, fw.accelerations)
        assert np.array_equal(d.multipliers, fw.multipliers)


@pytest.mark.parametrize("name", ["slider_crank", "top_euler", "double_pendulum_3d"])
def test_the_numeric_path_equals_the_unrolled_one(name):
    """The generated partial derivatives with the solve in numpy ('residual', the path of
    models with dependent rows) against the unrolled kernel ('kkt'): round-off apart."""
    nm = NumericModel(models.get(name))
    kkt, res = DerivativeModel(nm), DerivativeModel(nm, kind="residual")
    for q, u in consistent_states(nm, 3):
        a, b = kkt.at(q, u), res.at(q, u)
        for block in BLOCKS:
            assert _scaled(getattr(b, block), getattr(a, block)) <= 1e-12, block


def test_formulations_differ_off_the_manifold_and_agree_along_it():
    """The top's Lagrange equations extend off |eps| = 1 unlike d'Alembert's (their
    q-Jacobians differ at order one), and along the consistent directions, the tangent space of
    the unit sphere, every block agrees to round-off."""
    model = models.get("top_euler")
    dms = {f: DerivativeModel(NumericModel(model, f)) for f in model.formulations}
    base = dms["dalembert"]
    q, u = consistent_states(base.nm, 2)[1]
    dirs = consistent_directions(base, q, u)
    ref = base.at(q, u)
    lag = dms["lagrange"].at(q, u)
    assert _scaled(lag.dud_dq, ref.dud_dq) > 1e-2
    for d in (dms[f].at(q, u) for f in model.formulations):
        for block in ("dq", "du", "dtau"):
            got, want = (
                along(d, dirs, "accelerations", block),
                along(ref, dirs, "accelerations", block),
            )
            assert _scaled(got, want) <= 1e-13, block


def test_consistent_directions_are_tangent_to_the_manifold():
    """q-directions move no position row to first order and keep A u + a0 = 0; u-directions
    are admissible speeds; both bases orthonormal."""
    nm = NumericModel(models.get("top_cartesian"))
    dm = DerivativeModel(nm)
    q, u = consistent_states(nm, 2)[1]
    dirs = consistent_directions(dm, q, u)
    fq = nm._position_jacobian(q, 0.0)
    A = nm.matrices(q, u)[2]
    assert np.max(np.abs(fq @ dirs.dq)) <= 1e-14
    moved = dm.velocity_jacobian(q, u) @ dirs.dq + A @ dirs.du_of_dq
    assert np.max(np.abs(moved)) <= 1e-13
    assert np.max(np.abs(A @ dirs.du)) <= 1e-14
    for B in (dirs.dq, dirs.du):
        assert np.allclose(B.T @ B, np.eye(B.shape[1]), atol=1e-14)


def test_dependent_rows_give_u_dot_and_the_constraint_force():
    """A weld on a one-degree-of-freedom chain: six rows, dependent in a combination that
    turns with the chain. The derivatives of u' and of A^T lambda (unique) agree with central
    differences of the forward call along the manifold and in tau; lambda's own derivative is
    not claimed."""
    (name,) = register_all(load_model_file(DATA / "weld_sites.xml"))
    nm = NumericModel(models.get(name))
    dm = DerivativeModel(nm)
    assert dm.kind == "residual"
    for q, u in consistent_states(nm, 3):
        d = dm.at(q, u)
        assert d.dlam_dq is None and d.dforce_dq is not None
        dirs = consistent_directions(dm, q, u)
        for k in range(dirs.du.shape[1]):  # u-directions keep A u + a0 = 0 exactly
            e = dirs.du[:, k]

            def g(s, e=e, q=q, u=u):
                fw = nm.forward(q, u + s * e)
                M, f, _A, _b = nm.matrices(q, u + s * e)
                return np.concatenate([fw.accelerations, M @ fw.accelerations - f])

            fd = (8 * (g(1e-3) - g(-1e-3)) - (g(2e-3) - g(-2e-3))) / 12e-3
            want = np.concatenate([d.dud_du @ e, d.dforce_du @ e])
            assert _scaled(fd, want) <= 1e-9
        slow, _trunc = central_differences(nm, q, u, blocks=("dtau",))
        assert _scaled(slow.dud_dtau, d.dud_dtau) <= 1e-9


def test_derivative_modules_are_cached_apart_from_the_forward_code(tmp_path, monkeypatch):
    """The derivative module is its own cache entry, keyed by the forward entry and its
    generator: the forward entries and their keys are untouched (its source is not a
    derivation source), and a second model reads the entry instead of deriving."""
    monkeypatch.setenv("CROSSCHECK_CACHE_DIR", str(tmp_path))
    assert not any("derivatives" in str(p) for p in codegen.DERIVATION_SOURCES)
    nm = NumericModel(models.get("pendulum_xy"))
    before = {p.name for p in tmp_path.glob("*.py")}
    dm = DerivativeModel(nm, backend="python")
    after = {p.name for p in tmp_path.glob("*.py")}
    assert after - before == {dm.cache_path.name}
    assert dm.cache_path.stem.startswith(nm.cache_path.stem + "-dkkt-")
    mtime = dm.cache_path.stat().st_mtime_ns
    again = DerivativeModel(NumericModel(models.get("pendulum_xy")), backend="python")
    assert again.cache_path == dm.cache_path and dm.cache_path.stat().st_mtime_ns == mtime


def test_quaternion_coordinates_with_a_weld_agree_with_the_slow_path():
    """A free body's quaternion welded to a hinged arm (dependent rows, a unit-norm row): the
    q-directions are tangent to the unit sphere, and the exact u' derivatives agree with the
    slow path along them, the speeds' directions and tau within the derived tolerances
    (crosscheck's reference records; A^T lambda is not compared: the norm row's multiplier is
    the formulation's)."""
    from crosscheck.checks.derivatives.records import reference_records

    (name,) = register_all(load_model_file(DATA / "free_weld.xml"))
    nm = NumericModel(models.get(name))
    dm = DerivativeModel(nm)
    dirs = consistent_directions(dm, *consistent_states(nm, 2)[1])
    q = consistent_states(nm, 2)[1][0]
    assert np.max(np.abs(nm._position_jacobian(q, 0.0) @ dirs.dq)) <= 1e-14
    recs = {r["quantity"]: r for r in reference_records(name, nm, dm, consistent_states(nm, 2))}
    judged = {k for k, r in recs.items() if not r["skipped"]}
    assert judged == {f"daccelerations_{b}" for b in ("dq", "du", "dtau")}, recs
    assert all(recs[k]["passed"] for k in judged)


@pytest.mark.slow  # MuJoCo's weld.xml: five free beams, about 50 s to derive cold
def test_a_tolerance_that_judges_nothing_is_reported_not_judged():
    """MuJoCo's weld.xml (welds with torquescale 0.002: cond(K) 8.5e11, multipliers of 3e6):
    the slow path's derived tolerance is above 1, which no scaled error could fail; the
    records say so, with the measured agreement, instead of passing."""
    from crosscheck.checks.derivatives.records import VACUOUS, reference_records

    path = DATA / "real" / "mujoco_weld.xml"
    (name,) = register_all(load_model_file(path, project=True))
    nm = NumericModel(models.get(name))
    states = consistent_states(nm, 3)
    recs = {r["quantity"]: r for r in reference_records(name, nm, DerivativeModel(nm), states)}
    r = recs["daccelerations_dtau"]
    assert r["skipped"] and r["reason"].startswith("not judged: the derived tolerance"), r
    assert f"at least {VACUOUS:g}" in r["reason"]


def test_a_model_too_large_to_differentiate_is_one_skipped_record(monkeypatch):
    """Past DERIVATIVES_MAX_SIZE the symbolic derivatives are not attempted (they write M and f
    out: Cassie's did not finish in 25 minutes): on the symbolic path, where nothing else
    works, DerivativeModel refuses in one line naming the size, the bound and the ways out,
    and a run's derivatives are one skipped record saying so (here with the bound lowered
    below slider_crank's size, 29; on the sums path the same model takes complex steps:
    tests/test_derivatives_complex_step.py)."""
    import reference.derivatives.exact as exact
    from crosscheck.checks.derivatives.records import model_records
    from reference.errors import UnsupportedModelError

    monkeypatch.setattr(exact, "DERIVATIVES_MAX_SIZE", 20)
    monkeypatch.delenv("CROSSCHECK_DERIVATION", raising=False)
    nm = NumericModel(models.get("slider_crank"))
    why = r"size 29 .* bound is 20.*without --derivatives"
    with pytest.raises(UnsupportedModelError, match=why):
        DerivativeModel(nm)
    (rec,) = model_records("slider_crank", nm, consistent_states(nm, 2), [], {})
    assert (rec["check"], rec["skipped"]) == ("derivatives", True)
    assert "no exact derivatives" in rec["reason"]
