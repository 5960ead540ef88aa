"""Forward-dynamics speed: one evaluation of the accelerations and multipliers at a state,
timed on every path:
- reference paths, each record's `call` field naming the exact call (PATHS): `single` (the
  checked public call), `single-raw` (the fast call integrators use, fresh arrays out),
  `single-raw-out` (the same call writing into the caller's preallocated array, as
  Pinocchio's timed call writes into its own data), `single-into` (the backend's forward
  kernel alone), `batched` (10^4 states in one call);
- `baseline`: the plain route a user would write first, sympy lambdify of M, f, A, b (numpy)
  plus np.linalg.solve of the KKT matrix, single state and batched (np.linalg.solve on a stack);
- each engine's constrained forward call at the same state, timed through the adapter's
  `timed_forward` hook when it has one (engine call only, no mapping).
All figures come from one run, so their ratios are meaningful on this noisy machine.
"""

from __future__ import annotations

import numpy as np
import sympy as sp

from crosscheck.bench.timing import interleaved_seconds, per_call_seconds
from crosscheck.engines.base import EngineUnsupported
from reference import NumericModel, models
from reference.formulations import derive

BATCH = 10_000

# what each reference path times (bench.json `forward_paths`, and each record's `call`)
PATHS = {
    "single": "NumericModel.forward(q, u): the checked public call (sizes, finiteness, pivot "
    "test; a bad state raises); returns a Forward record of fresh arrays (on the C backend one "
    "C call builds it)",
    "single-raw": "NumericModel.forward_fast(q, u, t): the fast call the integrators use "
    "(sizes checked, no raise on a singular KKT matrix, NaN in -> NaN out); returns fresh "
    "(u', lambda) arrays and the pivot ratio",
    "single-raw-out": "NumericModel.forward_fast(q, u, t, out=buf): the same fast call writing "
    "u' | lambda | pivot ratio into the caller's preallocated float64 array (the counterpart of "
    "Pinocchio's timed call, which returns its preallocated data.ddq)",
    "single-into": "nm.kernels.function('forward')(q, u, t, pa, db, buf): the backend's "
    "forward kernel alone (reference.backends.kernels; its own argument checks), output into a "
    "preallocated array, status returned",
    "batched": "NumericModel.forward_batch(Q, U): 10^4 states in one call, per state",
}


def _states(nm, n):
    """n seeded consistent states (the ones `crosscheck run` compares at) as (Q, U) arrays."""
    from crosscheck.checks.sampling import consistent_states

    states = consistent_states(nm, n)
    return np.array([q for q, _ in states]), np.array([u for _, u in states])


def _baseline(model, formulation, params):
    """lambdify(M, f, A, b) with numpy + np.linalg.solve: the obvious implementation."""
    eom = derive(model, formulation)
    args = list(model.coordinates) + list(model.speeds) + [model.t] + list(model.parameter_symbols)
    fn = sp.lambdify(args, [eom.M, eom.f, eom.A, eom.b], modules="numpy", cse=True)
    n, m = len(model.speeds), eom.A.shape[0]
    flat = list(eom.M) + list(eom.f) + list(eom.A) + list(eom.b)
    fn_flat = sp.lambdify(args, flat, modules="numpy", cse=True)
    p = [params[pp.name] for pp in model.parameters]

    def single(q, u, t=0.0):
        M, f, A, b = (np.asarray(x, float) for x in fn(*q, *u, t, *p))
        K = np.zeros((n + m, n + m))
        K[:n, :n] = M
        K[:n, n:] = -A.T
        K[n:, :n] = A
        rhs = np.concatenate([f.ravel(), b.ravel()])
        if model.redundant_constraints:  # dependent rows: K is singular, u' still unique
            return np.linalg.lstsq(K, rhs, rcond=None)[0]
        return np.linalg.solve(K, rhs)

    def batched(Q, U, t=0.0):
        N = Q.shape[0]
        vals = [np.broadcast_to(v, (N,)) for v in fn_flat(*Q.T, *U.T, t, *p)]
        M = np.stack(vals[: n * n], -1).reshape(N, n, n)
        f = np.stack(vals[n * n : n * n + n], -1)
        K = np.zeros((N, n + m, n + m))
        K[:, :n, :n] = M
        rhs = np.zeros((N, n + m))
        rhs[:, :n] = f
        if m:
            A = np.stack(vals[n * n + n : n * n + n + m * n], -1).reshape(N, m, n)
            K[:, :n, n:] = -np.transpose(A, (0, 2, 1))
            K[:, n:, :n] = A
            rhs[:, n:] = np.stack(vals[n * n + n + m * n :], -1)
        if model.redundant_constraints:  # dependent rows (user models): minimum-norm solve
            return (np.linalg.pinv(K) @ rhs[..., None])[..., 0]
        return np.linalg.solve(K, rhs[..., None])[..., 0]

    return single, batched


def forward_records(names, quick=False, engines=()):
    """Timings of one forward call per model: the reference's paths, a lambdify+solve
    baseline, and each engine's call (single and as a Python loop over the batch)."""
    recs = []
    for name in names:
        recs += _model_forward_records(name, quick, engines)
    return recs


def _model_forward_records(name, quick, engines) -> list[dict]:
    model = models.get(name)
    nm = NumericModel(model)
    Q, U = _states(nm, 16 if quick else 64)
    q, u = Q[0], U[0]
    recs: list[dict] = []
    # single-state calls (the reference's and each engine's) are timed together at the end,
    # in interleaved rounds: their ratios are the targets, and back-to-back timings on this
    # shared machine moved them 2x between paths of one run (benchmarks/reference_speed.md)
    pending: dict = {}

    def rec(path, batch, t):
        engine = "reference" if not path.startswith("engine") else path.split(":")[1]
        r = {
            "model": name,
            "engine": engine,
            "formulation": nm.formulation,
            "path": path,
            "call": PATHS.get(path, path),
            "batch": batch,
        }
        recs.append(r)
        if callable(t):
            pending[path] = (r, t)
        else:
            r.update(
                us_per_state=t["median"] / batch * 1e6, us_per_state_min=t["min"] / batch * 1e6
            )

    rec("single", 1, lambda: nm.forward(q, u))
    raw, buf = nm.forward_fast, np.empty(nm.n + nm.m + 1)
    # each backend's native inputs: float64 vectors for C, lists for the generated Python
    qr, ur = (q, u) if nm.backend != "python" else (q.tolist(), u.tolist())
    rec("single-raw", 1, lambda: raw(qr, ur, 0.0))
    rec("single-raw-out", 1, lambda: raw(qr, ur, 0.0, out=buf))
    k = nm.kernels
    if k.has("forward"):  # the kernel alone, into an array (none where the solve is numeric)
        kf, pa, db = k.function("forward"), nm.kernel_parameters, k.zero_db
        rec("single-into", 1, lambda: kf(qr, ur, 0.0, pa, db, buf))
    reps = int(np.ceil(BATCH / Q.shape[0]))
    QB, UB = np.tile(Q, (reps, 1))[:BATCH], np.tile(U, (reps, 1))[:BATCH]
    rec("batched", BATCH, per_call_seconds(lambda: nm.forward_batch(QB, UB), repeats=5))
    b_single, b_batched = _baseline(model, nm.formulation, nm.params)
    # the baseline must agree before it is timed (a fast wrong baseline proves nothing)
    ref = nm.forward(q, u)
    sol = b_single(q, u)
    assert np.allclose(sol[: nm.n], ref.accelerations, rtol=1e-9, atol=1e-9), name
    rec("baseline-lambdify-solve", 1, lambda: b_single(q, u))
    rec(
        "baseline-lambdify-solve-batched",
        BATCH,
        per_call_seconds(lambda: b_batched(QB, UB), repeats=3),
    )
    for engine in engines:
        recs += _engine_forward_records(name, nm, engine, Q, U, rec)
    timed = interleaved_seconds({path: fn for path, (_r, fn) in pending.items()})
    for path, (r, _fn) in pending.items():
        t = timed[path]
        r.update(
            us_per_state=t["median"] * 1e6,
            us_per_state_min=t["min"] * 1e6,
            timing=f"interleaved with this model's other single-state calls, {t['repeats']} "
            f"rounds (median and min over rounds)",
        )
    return recs


def _engine_forward_records(name, nm, engine, Q, U, rec) -> list[dict]:
    """One engine's call at the first state and as a loop over the batch; a refusal is a
    skip with its reason, any other build error a failed check."""
    base = {
        "model": name,
        "engine": engine.name,
        "path": "engine",
        "batch": 1,
        "us_per_state": None,
    }
    try:
        em = engine.build(name, nm.params)
    except EngineUnsupported as exc:  # the expected refusal: a skip with its reason
        return [{**base, "skipped": True, "refusal": "EngineUnsupported", "reason": str(exc)}]
    except Exception as exc:  # anything else is a broken build: a failed check
        return [{**base, "failed": f"engine build: {type(exc).__name__}: {exc}"}]
    rec(f"engine:{engine.name}", 1, em.timed_forward(Q[0], U[0]))
    # the engine over the batch's states, one call each (a Python loop)
    calls = [em.timed_forward(Q[i], U[i]) for i in range(Q.shape[0])]
    seq = [calls[i % len(calls)] for i in range(BATCH)]

    def loop():
        for c in seq:
            c()

    rec(f"engine-loop:{engine.name}", BATCH, per_call_seconds(loop, repeats=3))
    return []


def forward_ratios(recs) -> list[dict]:
    """One row of ratios per model (see _ratios), from the forward records of one run."""
    names = list(dict.fromkeys(r["model"] for r in recs))
    return [_ratios(n, [r for r in recs if r["model"] == n]) for n in names]


def _ratios(name, recs) -> dict:
    """The speed ratios from this run's records: the reference's checked and raw single-state
    calls over each engine's call (targets <= 0.5 and <= 0.25 against every engine with exact
    multipliers), and each engine's loop over the batched reference per state (target >= 20)."""
    from crosscheck.engines.registry import get_engine
    from reference.backends import select

    t = {r["path"]: r["us_per_state"] for r in recs if r.get("us_per_state") is not None}
    out: dict = {"model": name, "backend": select.backend()}
    if "single" not in t:
        return out
    met = {}
    for path in [p for p in t if p.startswith("engine:")]:
        eng = path.split(":", 1)[1]
        e, loop = t[path], t.get(f"engine-loop:{eng}")
        out[f"checked_over_{eng}"] = t["single"] / e
        out[f"raw_over_{eng}"] = t["single-raw"] / e
        if "single-raw-out" in t:
            out[f"raw_out_over_{eng}"] = t["single-raw-out"] / e
        if "single-into" in t:
            out[f"into_over_{eng}"] = t["single-into"] / e
        if loop:
            out[f"{eng}_loop_over_batched"] = loop / t["batched"]
        if get_engine(eng).capabilities.exact:
            met[f"checked <= 0.5 x {eng}"] = out[f"checked_over_{eng}"] <= 0.5
            met[f"raw <= 0.25 x {eng}"] = out[f"raw_over_{eng}"] <= 0.25
            if "single-raw-out" in t:
                met[f"raw into the caller's out <= 0.25 x {eng}"] = (
                    out[f"raw_out_over_{eng}"] <= 0.25
                )
            if "single-into" in t:
                met[f"kernel into a preallocated output <= 0.25 x {eng}"] = (
                    out[f"into_over_{eng}"] <= 0.25
                )
            if loop:
                met[f"batched >= 20 x {eng} loop"] = out[f"{eng}_loop_over_batched"] >= 20
    if met:
        out["met"] = met
    return out
