"""One chunk of a sweep's samples, as it runs on a worker: draws, the batched reference, then
every engine variant per sample (crosscheck.commands.sweep has the campaign around it)."""

from __future__ import annotations

import copy
import threading
import time
from dataclasses import dataclass

import numpy as np

from crosscheck.checks.instantaneous import ReferenceAnswer, build, compare_at_state
from crosscheck.checks.perturb import perturbed
from crosscheck.checks.sampling import draw_sample, sample_seed
from crosscheck.engines.registry import get_engine
from crosscheck.runtime import interrupts
from crosscheck.sweep.config import REFERENCE
from reference import NumericModel, models
from reference.errors import SingularSystemError


# ---- one chunk of samples (runs on a worker) ------------------------------------------------
@dataclass(frozen=True)
class ChunkSpec:
    model: str
    formulation: str
    seed: int
    start: int
    stop: int
    series: tuple  # ((engine, variant), ...) to evaluate
    perturb: tuple = ()  # ((engine, ((param, rel), ...)), ...)
    deadline: float | None = None  # time.time() after which no further sample is started
    derivatives: bool = False  # also the derivatives comparison (error / derived tolerance)


_CACHE: dict = {}
_CACHE_LOCK = threading.Lock()


def _cached(key, factory):
    """Per-worker (per-process) cache of what does not depend on the parameters: the compiled
    reference code and the engine adapters. Threads of one Dask worker share it."""
    with _CACHE_LOCK:
        if key not in _CACHE:
            _CACHE[key] = factory()
        return _CACHE[key]


def base_model(name: str, formulation: str | None = None) -> NumericModel:
    model = models.get(name)
    formulation = formulation or model.formulations[0]
    return _cached(("numeric", name, formulation), lambda: NumericModel(model, formulation))


def cached_adapter(engine: str):
    return _cached(("adapter", engine), lambda: get_engine(engine))


def first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return (text[0] if text else "")[:400]


def reference_batch(base: NumericModel, nms, T, Q, U):
    """The reference's u' and lambda at N samples with N parameter sets, in one batched call.

    The compiled code is straight-line and elementwise, so the parameters, the Schur pivot
    references and t can be arrays like the states: NumericModel.forward_batch on a copy of the
    base model whose parameter tuple holds one array per parameter. Returns (UD (N, n),
    LAM (N, m), errors): errors[j] is the exception of a singular sample (then its rows are
    NaN), found by evaluating the batch sample by sample (the same batched code, N = 1) when
    the whole batch is refused. tests/test_sweep.py checks this against the scalar path."""
    N = len(nms)

    def batch(sel):
        nmb = copy.copy(base)
        nmb.p = tuple(np.array([nms[j].p[k] for j in sel], float) for k in range(len(base.p)))
        nmb.sref = tuple(
            np.array([nms[j].sref[k] for j in sel], float) for k in range(len(base.sref))
        )
        return nmb.forward_batch(
            np.asarray([Q[j] for j in sel], float),
            np.asarray([U[j] for j in sel], float),
            np.asarray([T[j] for j in sel], float),
        )

    errors: list = [None] * N
    try:
        UD, LAM, _ = batch(range(N))
    except SingularSystemError:
        UD, LAM = np.full((N, base.n), np.nan), np.full((N, base.m), np.nan)
        for j in range(N):
            try:
                UD[j], LAM[j], _ = (x[0] for x in batch([j]))
            except SingularSystemError as exc:
                errors[j] = exc
    return UD, LAM, errors


def _draw_chunk(spec: ChunkSpec, base, past, timing: dict) -> list:
    """1. draws (the property tests' generator, one seeded Generator per sample)."""
    name = spec.model
    t0 = time.perf_counter()
    drawn = []  # (index, sample seed, nm, t, q, u) or (index, sample seed, exception)
    for i in range(spec.start, spec.stop):
        interrupts.check()
        if past():
            break
        try:
            drawn.append((i, *draw_sample(base, spec.seed, i)))
        except Exception as exc:
            drawn.append((i, sample_seed(spec.seed, name, i), exc))
    t1 = time.perf_counter()
    timing["draw_s"] = t1 - t0
    return drawn


def _reference_chunk(base, drawn: list, timing: dict) -> dict:
    """2. the reference, batched over the drawn samples (M and the energy are cheap scalar
    calls)."""
    t1 = time.perf_counter()
    ok = [d for d in drawn if len(d) == 6]
    ref = {}
    if ok:
        UD, LAM, errs = reference_batch(
            base, [d[2] for d in ok], [d[3] for d in ok], [d[4] for d in ok], [d[5] for d in ok]
        )
        timing["reference_s"] = time.perf_counter() - t1
        for j, (i, _s, nm, t, q, u) in enumerate(ok):
            if errs[j] is not None:
                ref[i] = errs[j]
                continue
            ref[i] = (UD[j], LAM[j], nm.matrices(q, u, t)[0], nm.energy(q, u, t))
    timing["reference_aux_s"] = time.perf_counter() - t1 - timing["reference_s"]
    return ref


def _derivative_values(base, em, engine, name, nm, t, q, u) -> tuple[dict, dict]:
    """The derivatives comparison at one sample: {quantity: error / the tolerance derived at
    the sample} and the skips (crosscheck.checks.derivatives.engine); nothing where the
    difference stencil reaches a contact or limit (the sample is not counted there)."""
    from crosscheck.checks.derivatives.differences import StencilLeaves
    from crosscheck.checks.derivatives.engine import compare_at_state
    from reference.derivatives import DerivativeModel

    dm = _cached(("derivatives", name, base.formulation), lambda: DerivativeModel(base))
    try:
        sd = compare_at_state(em, cached_adapter(engine), dm.for_model(nm), name, q, u, t)
    except StencilLeaves:
        return {}, {}
    return {k: float(j.ratio) for k, j in sd.judged.items()}, dict(sd.skips)


def _evaluate_chunk(
    spec: ChunkSpec, base, drawn: list, ref: dict, perturb: dict, n: int, past, fault
) -> tuple:
    """3. every engine variant, sample by sample."""
    name = spec.model
    values: dict[tuple, np.ndarray] = {}
    skips: dict[tuple, str] = {}
    soft: dict[tuple, bool] = {}
    # per engine variant: build seconds, evaluate seconds, builds attempted, samples evaluated
    per_series = {tuple(sv): [0.0, 0.0, 0, 0] for sv in spec.series}
    completed = 0
    for k, d in enumerate(drawn):
        # Ctrl-C in this process (a campaign on --workers 1): the chunk is dropped as a whole,
        # within one sample, whatever an engine did with the interrupt (one that swallows it
        # can return a wrong answer for the sample it interrupted)
        interrupts.check()
        if past():
            break
        completed = k + 1
        i, s = d[0], d[1]
        if len(d) == 3:
            fault(i, s, REFERENCE, None, "draw", d[2])
            continue
        _, _, nm, t, q, u = d
        if isinstance(ref[i], Exception):
            fault(i, s, REFERENCE, None, "forward", ref[i])
            continue
        acc, lam, M_ref, E_ref = ref[i]
        for engine, variant in spec.series:
            tb = time.perf_counter()
            per_series[(engine, variant)][2] += 1
            try:
                params = perturbed(name, nm.params, perturb.get(engine, {}))
                em = build(cached_adapter(engine), name, params, variant)
            except Exception as exc:
                fault(i, s, engine, variant, "build", exc)
                per_series[(engine, variant)][0] += time.perf_counter() - tb
                continue
            te = time.perf_counter()
            try:
                sc = compare_at_state(
                    em,
                    q,
                    u,
                    t,
                    ReferenceAnswer(acc, lam, M_ref, E_ref),
                    base.m,
                    cached_adapter(engine).capabilities,
                )
                vals, sk, sf = sc.values, sc.skips, sc.soft
            except Exception as exc:
                fault(i, s, engine, variant, "evaluate", exc)
                vals, sk, sf = None, {}, None
            tf = time.perf_counter()
            acc_t = per_series[(engine, variant)]
            acc_t[0] += te - tb
            acc_t[1] += tf - te
            if vals is None:
                continue
            acc_t[3] += 1
            if spec.derivatives:
                try:
                    dv, dsk = _derivative_values(base, em, engine, name, nm, t, q, u)
                    vals = {**vals, **dv}
                    sk = {**sk, **dsk}
                except Exception as exc:
                    fault(i, s, engine, variant, "derivatives", exc)
            soft[(engine, variant)] = sf
            for qn, reason in sk.items():
                skips.setdefault((engine, variant, qn), reason)
            for qn, v in vals.items():
                arr = values.get((engine, variant, qn))
                if arr is None:
                    arr = values[(engine, variant, qn)] = np.full(n, np.nan)
                arr[k] = v
    return values, skips, soft, per_series, completed


def run_chunk(spec: ChunkSpec) -> dict:
    """Samples spec.start .. spec.stop-1 of one model: draws, the batched reference, then every
    engine variant per sample. Never raises for a sample: faults are returned as records.

    Returns {"model", "start", "completed" (samples done from start on: a prefix), "values"
    {(engine, variant, quantity): float array over the completed samples, NaN = not evaluated},
    "soft" {(engine, variant): bool}, "skips" {(engine, variant, quantity): reason},
    "faults" [...], "timing" {...}}."""
    name = spec.model
    base = base_model(name, spec.formulation)
    perturb = {e: dict(p) for e, p in spec.perturb}
    n = spec.stop - spec.start
    timing = {"draw_s": 0.0, "reference_s": 0.0, "reference_aux_s": 0.0, "samples": 0}
    faults: list[dict] = []

    def fault(i, s, engine, variant, stage, exc):
        faults.append(
            {
                "model": name,
                "engine": engine,
                "variant": variant,
                "index": i,
                "sample_seed": s,
                "stage": stage,
                "type": type(exc).__name__,
                "reason": first_line(exc),
            }
        )

    past = (lambda: False) if spec.deadline is None else (lambda: time.time() > spec.deadline)
    drawn = _draw_chunk(spec, base, past, timing)
    ref = _reference_chunk(base, drawn, timing)
    interrupts.check()
    values, skips, soft, per_series, completed = _evaluate_chunk(
        spec, base, drawn, ref, perturb, n, past, fault
    )
    timing["samples"] = completed
    timing["series"] = {sv: tuple(x) for sv, x in per_series.items()}
    return {
        "model": name,
        "start": spec.start,
        "stop": spec.stop,
        "completed": completed,
        "values": {key: arr[:completed] for key, arr in values.items()},
        "soft": soft,
        "skips": skips,
        "faults": faults,
        "timing": timing,
    }
