"""The two derivation paths (reference.formulations): the textbook's models stay on the
symbolic one, the sums path agrees with it on every one of them, and it derives a robot.

Tolerances of the two paths' agreement, at the run's consistent states, scaled as the suite
scales (max |sums - symbolic| / max(1, max |symbolic|)):
- MATRICES (M, f, A, b): each entry is one expression of the state on both paths, evaluated
  in another arithmetic order (simplified by trigsimp on one, summed at evaluation on the
  other), so they differ by a few ulps of the largest term: measured 6.9e-16 at worst
  (`python benchmarks/derivation_paths.py --agreement`, benchmarks/scaling.md); 1e-14 is 45
  ulps.
- SOLVE (u', lambda): the same equations through two KKT solves (the unrolled range-space
  solve against the SVD one of reference.numeric.redundant), which amplify that round-off by
  the system's conditioning: measured 9.2e-14 at worst (top_cartesian's lambda); the suite's
  bound for two exact solves, crosscheck.checks.tolerances.EXACT_KKT (1e-11).

Against the engines, the bar of MJCF files (tests/test_user_models.py's TOL_MJCF, 1e-9: the
issue's bar for Cassie); measured 2.4e-12 (u') and 1.9e-14 (lambda) on Cassie.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from benchmarks.derivation_paths import on_path, path_agreement
from crosscheck.checks.tolerances import EXACT_KKT
from crosscheck.engines.mujoco.mjcf_rigid import rigid_forward, sample_states
from reference import dag, models
from reference.formulations import SUMS_MIN_SIZE, derivation_path, derive, model_size
from reference.mjcf.loader import import_mjcf, qvel_from_rates, rates_from_qvel
from reference.numeric.model import NumericModel
from tests.support import representative

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "examples" / "a02"))
from nfourbar import mjcf  # noqa: E402
from scaling import parallelogram_states  # noqa: E402

CASSIE = ROOT / "tests" / "data" / "real" / "pinocchio_cassie.xml"
MATRICES = 1e-14
SOLVE = EXACT_KKT.value
TOL_MJCF = 1e-9
COLD_S = 120.0  # the bounds for Cassie
WARM_S = 5.0

CASES = [(name, f) for name in models.names() for f in models.get(name).formulations]
QUICK = {("slider_crank", "lagrange"), ("double_pendulum_3d", "kane"), ("top_euler", "dalembert")}


def test_textbook_models_stay_on_the_symbolic_path(monkeypatch):
    monkeypatch.delenv("CROSSCHECK_DERIVATION", raising=False)
    for name in models.names():
        model = models.get(name)
        assert model_size(model) < SUMS_MIN_SIZE / 5, name
        assert derivation_path(model) == "symbolic", name


@pytest.mark.parametrize(("name", "formulation"), representative(CASES, QUICK))
def test_the_paths_agree(name, formulation):
    worst = path_agreement(models.get(name), formulation)
    for key in ("M", "f", "A", "b"):
        assert worst[key] < MATRICES, (key, worst)
    assert worst["accelerations"] < SOLVE, worst
    assert worst["multipliers"] < SOLVE, worst


def test_written_out_sums_equal_the_symbolic_equations():
    """SummedEquations.M and .f written out (the sums made symbolic) equal the symbolic path's
    M and f as expressions (Lagrange's and Kane's, on a closed loop with a load)."""
    model = models.get("slider_crank")
    for formulation in ("lagrange", "kane"):
        sym, summed = derive(model, formulation, "symbolic"), derive(model, formulation, "sums")
        assert sp.simplify(summed.M - sym.M) == sp.zeros(*sym.M.shape)
        assert sp.simplify(summed.f - sym.f) == sp.zeros(*sym.f.shape)
        assert summed.A == sym.A


def test_the_setting_chooses_the_path(monkeypatch):
    model = models.get("pendulum_xy")
    monkeypatch.setenv("CROSSCHECK_DERIVATION", "sums")
    assert derivation_path(model) == "sums"
    nm = NumericModel(model, backend="python")
    assert nm.numeric_kkt and "_sums(_SUMS" in nm.source
    monkeypatch.setenv("CROSSCHECK_DERIVATION", "lagrangian")
    with pytest.raises(ValueError, match="CROSSCHECK_DERIVATION"):
        derivation_path(model)


# ---- the graph calculus ------------------------------------------------------------------------
def _chain(depth: int):
    """A spatial chain's end point, written as the loader writes one: each joint's rotation
    times its parent's, a graph that doubles as a tree at every level."""
    q = sp.symbols(f"q0:{depth}", real=True)
    u = sp.symbols(f"u0:{depth}", real=True)
    R, p = sp.eye(3), sp.zeros(3, 1)
    for k in range(depth):
        c, s = sp.cos(q[k]), sp.sin(q[k])
        Rk = (
            sp.Matrix([[c, -s, 0], [s, c, 0], [0, 0, 1]])
            if k % 2
            else sp.Matrix([[1, 0, 0], [0, c, -s], [0, s, c]])
        )
        R = R * Rk
        p = p + R * sp.Matrix([sp.Rational(k + 1, 7), 0, sp.Rational(1, 3)])
    return q, u, p


def test_graph_derivatives_equal_sympys():
    q, u, p = _chain(4)
    t = sp.Symbol("t", real=True)
    calc = dag.Calculus(q, u, t)
    rng = np.random.default_rng(3)
    at = {s: float(v) for s, v in zip(q + u, rng.uniform(-1, 1, 8), strict=True)}
    value = lambda e: float(sp.sympify(e).xreplace(at))
    e = p[0] * p[1] + sp.sqrt(2 + p[2] ** 2)
    rate = sum((sp.diff(e, qk) * uk for qk, uk in zip(q, u, strict=True)), sp.Integer(0))
    assert value(calc.rate(e)) == pytest.approx(value(rate), rel=1e-13)
    for x, g in zip(q, calc.gradient(e, q), strict=True):
        assert value(calc.diff(e, x)) == pytest.approx(value(sp.diff(e, x)), rel=1e-13)
        assert value(g) == pytest.approx(value(sp.diff(e, x)), rel=1e-13)
    assert calc.replace(e, {q[0]: 0}) == e.xreplace({q[0]: 0})


def test_graph_sizes_and_digests_see_the_sharing():
    _q, _u, p = _chain(12)
    assert dag.tree_size(list(p)) > 20 * len(dag._nodes(list(p)))  # written out vs shared
    _q2, _u2, p2 = _chain(12)  # the same structure built again
    assert dag.digest([p, "x", None]) == dag.digest([p2, "x", None])
    assert dag.digest([p]) != dag.digest([p2 + sp.Matrix([0, 0, 1])])


# ---- large models -------------------------------------------------------------------------------
def _pinocchio_and_mujoco(um, nm, states) -> dict:
    """Largest scaled differences of the reference's u' and loop multipliers from Pinocchio's
    (the suite's adapter) and MuJoCo's rigid answer at `states` (MuJoCo's qpos, qvel)."""
    from crosscheck.engines.pinocchio.user_file import UserFilePinModel

    imp, pin = um.mjcf, UserFilePinModel(um.name)
    loops = 3 * imp.mj.neq  # the connect rows, MuJoCo's order, before the quaternion rows
    worst = dict.fromkeys(("pin_u", "pin_lambda", "mujoco_u", "mujoco_lambda"), 0.0)
    for qpos, qvel in states:
        u = rates_from_qvel(imp.joints, qpos, qvel)
        ref = nm.forward(qpos, u)
        qacc = qvel_from_rates(imp.joints, qpos, ref.accelerations, imp.mj.nv)
        got, rigid = pin.forward(qpos, u), rigid_forward(imp.mj, qpos, qvel)
        scale_u = max(1.0, float(np.max(np.abs(ref.accelerations))))
        scale_l = max(1.0, float(np.max(np.abs(ref.multipliers[:loops]))))
        rows = list(got.multiplier_rows) if got.multiplier_rows is not None else range(nm.m)
        for key, err in (
            ("pin_u", np.abs(got.accelerations - ref.accelerations).max() / scale_u),
            ("pin_lambda", np.abs(got.multipliers[rows] - ref.multipliers[rows]).max() / scale_l),
            ("mujoco_u", np.abs(rigid.qacc - qacc).max() / max(1.0, np.abs(qacc).max())),
            ("mujoco_lambda", np.abs(rigid.multipliers - ref.multipliers[:loops]).max() / scale_l),
        ):
            worst[key] = max(worst[key], float(err))
    return worst


def _load(path: Path):
    from crosscheck.user_models import load_model_file, register_all

    um = load_model_file(path)[0]
    register_all([um])
    return um


def test_a02_chain_on_the_sums_path_agrees_with_pinocchio_and_mujoco(tmp_path):
    path = tmp_path / "a02_10.xml"
    path.write_text(mjcf(10))
    um = _load(path)
    with on_path("sums"):
        nm = NumericModel(um.model)
    assert "_sums(_SUMS" in nm.source
    worst = _pinocchio_and_mujoco(um, nm, parallelogram_states(10, 2))
    assert max(worst.values()) < TOL_MJCF, worst


@pytest.mark.slow
@pytest.mark.parametrize("cells", [20, 40])
def test_long_a02_chains_take_the_sums_path_and_agree(cells, tmp_path):
    path = tmp_path / f"a02_{cells}.xml"
    path.write_text(mjcf(cells))
    um = _load(path)
    assert derivation_path(um.model) == "sums"
    nm = NumericModel(um.model)
    worst = _pinocchio_and_mujoco(um, nm, parallelogram_states(cells, 2))
    assert max(worst.values()) < TOL_MJCF, worst


def test_cassie_derives_cold_and_starts_warm_within_the_bounds(fresh_cache):
    """Cassie (Pinocchio's closed-chain model: 32 dof, a free base, four loops) cold in an
    empty cache within COLD_S, then its import and model read back within WARM_S, and its
    accelerations and loop multipliers within the bar of Pinocchio's and MuJoCo's rigid ones."""
    t0 = time.perf_counter()
    um = _load(CASSIE)
    assert derivation_path(um.model) == "sums"
    nm = NumericModel(um.model)
    cold = time.perf_counter() - t0
    t0 = time.perf_counter()
    NumericModel(import_mjcf(CASSIE).model)
    warm = time.perf_counter() - t0
    assert cold < COLD_S and warm < WARM_S, (cold, warm)
    assert (nm.n, nm.m, nm.rank) == (35, 15, 13)  # a dependent row per planar loop
    worst = _pinocchio_and_mujoco(um, nm, sample_states(um.mjcf, 2))
    assert max(worst.values()) < TOL_MJCF, worst
