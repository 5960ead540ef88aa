"""`crosscheck sweep`: seeded random campaigns of the instantaneous cross-checks, at scale.

    crosscheck sweep MODEL [...] --samples N --seed S [--index I] [--engines pinocchio,mujoco]
                     [--workers K | --dask ADDRESS] [--chunk C] [--max-seconds T]
                     [--perturb ENGINE:PARAM=REL] [--formulation F] [--worst K] [--out DIR]
    crosscheck sweep [MODEL ...] --bench --samples N [--out DIR]   # throughput -> sweep_bench.json
    crosscheck sweep --resume DIR [--workers K | --dask ADDRESS]   # finish an interrupted one

Samples. Sample i of model M (i = I .. I+N-1) is one random parameter set, one time t and one
consistent state, drawn by crosscheck.sampling (the property tests' generator) from a numpy
Generator seeded with sampling.sample_seed(S, M, i): its randomness depends on (S, M, i) only,
never on the worker that ran it, the chunking, the executor or the other models.

Checks. For every sample and every engine variant, the instantaneous cross-checks of
`crosscheck run` (crosscheck.comparison.compare_at_state, the one comparison path; the same
metrics and named tolerances): state map, mass matrix (where the coordinates map one to one), energy,
accelerations and multipliers; for MuJoCo models with equality rows, the rigid answer recovered
from its soft output is held to RIGID_RECOVERY, its raw soft answer is reported as
`*_soft_error` (no tolerance: MuJoCo's softness) and judged against the error its impedance
predicts (`*_soft_vs_predicted`, SOFT_PREDICTION). The reference is evaluated for all samples of
a chunk in one batched call of its compiled code, with per-sample parameter arrays.

Output: DIR/sweep.json = {"meta" (command, versions, machine, seed, sampler, seeding,
executor), "status" (complete, stopped, completed sample ranges per model, outside_tolerance,
faults, verdict, passed: true only for a complete campaign with nothing failed), "series" (per model x engine x variant: evaluated, faults, or why it is not
run), "results" (per model x engine x variant x quantity: tolerance and its reason, count,
max, mean, quantiles, a log10 histogram, outside_tolerance, the worst cases), "faults" (groups
with counts, the first FAULTS_KEPT records per group), "timing" (where the time went; the only
part that is not deterministic, with "meta")}. A worst case carries its sample index, sample
seed, parameters and state, and the command lines that reproduce it exactly:
    crosscheck sweep M --seed S --index i --samples 1 --engines E --workers 1 --out DIR
(the same error, bit for bit) and `crosscheck eval M --set ... --q=... --u=... --t ...` (the
reference's accelerations and multipliers at that case, to round-off of the scalar path).
Faults (a draw whose projection fails, a singular reference, an engine that raises while
building or evaluating) are recorded per sample with the stage, the exception and its message;
the campaign goes on. An interrupted campaign (Ctrl-C, or --max-seconds) writes what it
completed, as sample-index ranges per model, and says why it stopped; every finished chunk is
also kept in DIR/sweep.chunks (crosscheck.sweep_store), and `--resume DIR` computes only the
samples no stored chunk covers, ending with the sweep.json of an uninterrupted run (meta and
timing aside). A Dask worker lost mid-campaign costs only the rerun of its tasks (the scheduler
reschedules them; the results do not depend on where a chunk ran).

Execution: local worker processes by default (all cores; ProcessPoolExecutor, chunks of at most
LOCAL_CHUNK_MAX samples), in-process with --workers 1, or a Dask distributed cluster with
--dask ADDRESS (chunks of at least DASK_MIN_CHUNK samples; `--dask local:K` starts a local
cluster of K one-thread worker processes). The aggregate is independent of the executor and the
chunking. Per worker, the compiled reference code and the engine adapters are built once (a
module-level cache); the engine MODEL depends on the parameters, so it is built per sample, and
the time that takes is recorded (timing.per_series.build_s; see the benchmark).
On a Dask cluster the workers need this package (same versions) importable, and write their
compiled reference code to their own cache directory on first use; results are bit-identical
when the workers' numpy/libm give the same floating-point results as the local machine (same
builds); --max-seconds compares wall clocks (time.time) on the workers; one-thread workers
(`dask worker --nthreads 1 --nworkers K`) suit this Python-bound work. The parent keeps every
error value (8 bytes per sample per quantity, ~20 quantities per model) to give exact quantiles:
10^6 samples of one model is ~160 MB, so run models one at a time at that scale.

Exit status: 0 when the campaign completed with every sample within every tolerance and nothing
faulted (status.verdict "passed"), 1 when a sample is outside a tolerance or faulted ("failed"),
4 when it stopped early (--max-seconds) with nothing failed in what it ran ("incomplete": not
passed), 2 on bad input (one line), 130 when interrupted (after writing sweep.json, whose
status.passed is then false).
"""
from __future__ import annotations

import copy
import json
import math
import os
import shlex
import signal
import sys
import threading
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from reference import NumericModel, models
from reference.errors import ModelInputError, SingularSystemError

from . import compare as C
from .comparison import ReferenceAnswer, build, compare_at_state, rigid_answer, tolerance
from .engines.base import EngineUnsupported
from .engines.registry import available_engines, engine_modules, get_engine
from .perturb import check_parameters, check_perturb, parse_perturb, perturbed
from .sampling import draw_sample, sample_seed

# ---- named settings, each with its reason ---------------------------------------------------
QUANTILES = (0.5, 0.9, 0.99, 0.999)
QUANTILE_METHOD = "higher"  # each quantile is an observed error (conservative), not interpolated
WORST_CASES = 5  # per model x engine x variant x quantity; --worst changes it
FAULTS_KEPT = 20  # fault records kept per model x engine x variant x stage x type (counts are all)
# A local chunk is at most this many samples: a sample costs 1-6 ms over both engines, so a chunk
# is <= ~1 s, against ~0.2 ms of pool overhead per task, and the batched reference call (a few
# hundred numpy operations, ~1 us each whatever the batch) costs 3-6 us per sample at 200
# against 11-25 us for the scalar path (break-even near 25). Smaller campaigns get smaller chunks
# (N / 4 workers) so the workers stay balanced; an interrupt loses at most one chunk per worker.
LOCAL_CHUNK_MAX = 200
# A Dask task costs ~1-3 ms of scheduling and (de)serialization; 100 samples (0.1-0.6 s) keep that
# below ~1-3% -- unless that would leave workers idle (then N / threads, rounded up).
DASK_MIN_CHUNK = 100
DASK_MAX_CHUNK = 2000
# log10 histogram of each quantity's errors (report figures): 0.25-decade bins from 1e-18 to 1e2;
# exact zeros, values below/above the range and non-finite values are counted apart
HIST_LO, HIST_HI, HIST_STEP = -18.0, 2.0, 0.25

QUANTITY_ORDER = ("accelerations", "multipliers", "accelerations_soft_vs_predicted",
                  "multipliers_soft_vs_predicted", "accelerations_soft_error",
                  "multipliers_soft_error", "state_map", "mass_matrix", "energy")
SOFT_ERROR_REASON = (
    "MuJoCo's raw (soft) answer against the rigid reference: the error its impedance "
    "d = 0.9999 makes by design (~1e-4 relative); reported, not judged here -- the "
    "*_soft_vs_predicted quantity holds it to the error the impedance predicts")
REFERENCE = "reference"


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


def _adapter(engine: str):
    return _cached(("adapter", engine), lambda: get_engine(engine))


def _first_line(exc: BaseException) -> str:
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
        nmb.sref = tuple(np.array([nms[j].sref[k] for j in sel], float)
                         for k in range(len(base.sref)))
        return nmb.forward_batch(np.asarray([Q[j] for j in sel], float),
                                 np.asarray([U[j] for j in sel], float),
                                 np.asarray([T[j] for j in sel], float))

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
        faults.append({"model": name, "engine": engine, "variant": variant, "index": i,
                       "sample_seed": s, "stage": stage, "type": type(exc).__name__,
                       "reason": _first_line(exc)})

    past = (lambda: False) if spec.deadline is None else (lambda: time.time() > spec.deadline)
    # 1. draws (the property tests' generator, one seeded Generator per sample)
    t0 = time.perf_counter()
    drawn = []  # (index, sample seed, nm, t, q, u) or (index, sample seed, exception)
    for i in range(spec.start, spec.stop):
        if past():
            break
        try:
            drawn.append((i, *draw_sample(base, spec.seed, i)))
        except Exception as exc:  # noqa: BLE001 - a failed draw is a recorded fault
            drawn.append((i, sample_seed(spec.seed, name, i), exc))
    t1 = time.perf_counter()
    timing["draw_s"] = t1 - t0
    # 2. the reference, batched over the drawn samples (M and the energy are cheap scalar calls)
    ok = [d for d in drawn if len(d) == 6]
    ref = {}
    if ok:
        UD, LAM, errs = reference_batch(base, [d[2] for d in ok], [d[3] for d in ok],
                                        [d[4] for d in ok], [d[5] for d in ok])
        timing["reference_s"] = time.perf_counter() - t1
        for j, (i, _s, nm, t, q, u) in enumerate(ok):
            if errs[j] is not None:
                ref[i] = errs[j]
                continue
            ref[i] = (UD[j], LAM[j], nm.matrices(q, u, t)[0], nm.energy(q, u, t))
    timing["reference_aux_s"] = time.perf_counter() - t1 - timing["reference_s"]
    # 3. every engine variant, sample by sample
    values: dict[tuple, np.ndarray] = {}
    skips: dict[tuple, str] = {}
    soft: dict[tuple, bool] = {}
    # per engine variant: build seconds, evaluate seconds, builds attempted, samples evaluated
    per_series = {tuple(sv): [0.0, 0.0, 0, 0] for sv in spec.series}
    completed = 0
    for k, d in enumerate(drawn):
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
                em = build(_adapter(engine), name, params, variant)
            except Exception as exc:  # noqa: BLE001
                fault(i, s, engine, variant, "build", exc)
                per_series[(engine, variant)][0] += time.perf_counter() - tb
                continue
            te = time.perf_counter()
            try:
                sc = compare_at_state(em, q, u, t, ReferenceAnswer(acc, lam, M_ref, E_ref),
                                      base.m)
                vals, sk, sf = sc.values, sc.skips, sc.soft
            except Exception as exc:  # noqa: BLE001
                fault(i, s, engine, variant, "evaluate", exc)
                vals, sk, sf = None, {}, None
            tf = time.perf_counter()
            acc_t = per_series[(engine, variant)]
            acc_t[0] += te - tb
            acc_t[1] += tf - te
            if vals is None:
                continue
            acc_t[3] += 1
            soft[(engine, variant)] = sf
            for qn, reason in sk.items():
                skips.setdefault((engine, variant, qn), reason)
            for qn, v in vals.items():
                arr = values.get((engine, variant, qn))
                if arr is None:
                    arr = values[(engine, variant, qn)] = np.full(n, np.nan)
                arr[k] = v
    timing["samples"] = completed
    timing["series"] = {sv: tuple(x) for sv, x in per_series.items()}
    return {"model": name, "start": spec.start, "stop": spec.stop, "completed": completed,
            "values": {key: arr[:completed] for key, arr in values.items()},
            "soft": soft, "skips": skips, "faults": faults, "timing": timing}


# ---- the campaign (runs in the parent) ------------------------------------------------------
@dataclass
class _ModelAgg:
    name: str
    formulation: str
    start: int
    n: int
    series: list  # [(engine, variant)] evaluated
    unsupported: dict  # {(engine, variant): reason}
    values: dict = field(default_factory=dict)
    soft: dict = field(default_factory=dict)
    skips: dict = field(default_factory=dict)
    faults: list = field(default_factory=list)
    chunk_faults: list = field(default_factory=list)
    completed: np.ndarray = None
    timing: dict = field(default_factory=lambda: {"draw_s": 0.0, "reference_s": 0.0,
                                                  "reference_aux_s": 0.0, "samples": 0,
                                                  "series": {}})

    def __post_init__(self):
        self.completed = np.zeros(self.n, bool)

    def merge(self, res: dict) -> None:
        off, done = res["start"] - self.start, res["completed"]
        self.completed[off:off + done] = True
        for key, arr in res["values"].items():
            if key not in self.values:
                self.values[key] = np.full(self.n, np.nan)
            self.values[key][off:off + len(arr)] = arr
        self.soft.update(res["soft"])
        for key, reason in res["skips"].items():
            self.skips.setdefault(key, reason)
        self.faults += res["faults"]
        t = res["timing"]
        for k in ("draw_s", "reference_s", "reference_aux_s", "samples"):
            self.timing[k] += t[k]
        for sv, x in t["series"].items():
            acc = self.timing["series"].setdefault(sv, [0.0, 0.0, 0, 0])
            for j in range(4):
                acc[j] += x[j]


def _ranges(mask: np.ndarray, start: int) -> list[list[int]]:
    """Index ranges [a, b) where mask is True."""
    out, i, n = [], 0, len(mask)
    while i < n:
        if mask[i]:
            j = i
            while j < n and mask[j]:
                j += 1
            out.append([start + i, start + j])
            i = j
        else:
            i += 1
    return out


def _histogram(v: np.ndarray) -> dict:
    nb = int(round((HIST_HI - HIST_LO) / HIST_STEP))
    fin = v[np.isfinite(v)]
    pos = fin[fin > 0]
    lg = np.log10(pos)
    inside = lg[(lg >= HIST_LO) & (lg < HIST_HI)]
    counts = np.bincount(np.floor((inside - HIST_LO) / HIST_STEP).astype(int).clip(0, nb - 1),
                         minlength=nb)
    return {"log10_lo": HIST_LO, "log10_hi": HIST_HI, "log10_step": HIST_STEP,
            "counts": counts.tolist(), "zero": int((fin == 0).sum()),
            "below": int((lg < HIST_LO).sum()), "above": int((lg >= HIST_HI).sum()),
            "nonfinite": int((~np.isfinite(v)).sum())}


def _fmt_floats(x) -> str:
    return ",".join(repr(float(v)) for v in np.asarray(x, float).ravel())


def reproduce_commands(cfg: "Campaign", model: str, formulation: str, engine: str | None,
                       index: int, nm, t, q, u) -> dict:
    """Command lines that reproduce one sample: the one-sample sweep (same numbers, bit for
    bit) and `crosscheck eval` of the reference at that case."""
    argv = ["crosscheck", "sweep", model, "--seed", str(cfg.seed), "--index", str(index),
            "--samples", "1", "--workers", "1"]
    if engine and engine != REFERENCE:
        argv += ["--engines", engine]
        for p, rel in sorted(cfg.perturb.get(engine, {}).items()):
            argv += ["--perturb", f"{engine}:{p}={rel!r}"]
    if cfg.formulation:
        argv += ["--formulation", cfg.formulation]
    argv += ["--out", f"repro/{model}-{index}"]
    ev = ["crosscheck", "eval", model, "--formulation", formulation]
    for k, v in nm.params.items():
        ev += ["--set", f"{k}={float(v)!r}"]
    ev += [f"--q={_fmt_floats(q)}", f"--u={_fmt_floats(u)}", "--t", repr(float(t)), "--json"]
    return {"sweep": shlex.join(argv), "eval": shlex.join(ev)}


@dataclass
class Campaign:
    models: list
    samples: int
    seed: int = 0
    index: int = 0
    engines: tuple = field(default_factory=available_engines)
    perturb: dict = field(default_factory=dict)
    formulation: str | None = None
    worst: int = WORST_CASES
    out: str | None = None

    def validate(self) -> None:
        from .arguments import resolve_engines, resolve_models
        if not self.models:
            raise ModelInputError("no models given")
        resolve_models(list(self.models))  # unknown or repeated names fail before any work
        resolve_engines(list(self.engines))
        for e in self.perturb:
            if e not in self.engines:
                raise ModelInputError(f"--perturb names engine {e!r}, which is not in "
                                      f"--engines {','.join(self.engines)}")
        for name in self.models:
            check_parameters(name, [p.name for p in models.get(name).parameters], self.perturb)
        check_perturb(self.models, self.perturb)  # nan, or a mass made negative: exit 2
        if self.samples < 1:
            raise ModelInputError(f"--samples must be >= 1, got {self.samples}")
        if self.seed < 0 or self.index < 0:
            raise ModelInputError("--seed and --index must be >= 0")
        if self.worst < 0:
            raise ModelInputError(f"--worst must be >= 0, got {self.worst}")


def _plan(cfg: Campaign):
    """Per model: the base reference (compiles on first use, here in the parent so the workers
    find it in the disk cache) and the engine variants to evaluate, or why one cannot be."""
    aggs = {}
    for name in cfg.models:
        base = base_model(name, cfg.formulation)  # raises for a bad formulation
        series, unsupported = [], {}
        for e in cfg.engines:
            ad = _adapter(e)
            for v in ad.variants(name):
                try:  # the model structure, not the parameters, decides this
                    build(ad, name, None, v)
                except EngineUnsupported as exc:
                    unsupported[(e, v)] = _first_line(exc)
                    continue
                except Exception:  # noqa: BLE001 - left to the samples, which record it
                    pass
                series.append((e, v))
        aggs[name] = _ModelAgg(name, base.formulation, cfg.index, cfg.samples, series,
                               unsupported)
    return aggs


def _specs(cfg: Campaign, aggs, chunk: int, deadline) -> list[ChunkSpec]:
    """The chunks still to run: every sample no merged chunk covers (all of them, unless the
    campaign resumes from stored chunks)."""
    specs = []
    perturb = tuple((e, tuple(sorted(p.items()))) for e, p in sorted(cfg.perturb.items()))
    end = cfg.index + cfg.samples
    for name, agg in aggs.items():
        for a in range(cfg.index, end, chunk):
            b = min(a + chunk, end)
            for lo, hi in _ranges(~agg.completed[a - cfg.index:b - cfg.index], a):
                specs.append(ChunkSpec(name, agg.formulation, cfg.seed, lo, hi,
                                       tuple(agg.series), perturb, deadline))
    return specs


def default_workers() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def _worker_init():
    # Ctrl-C goes to the whole process group: the parent handles it (cancels, keeps what is
    # done); a worker killed by it would break the pool and lose the chunks in flight
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _mp_context():
    """forkserver: workers fork from a clean server that has imported this module (and the
    engines), so they start fast and inherit no threads of the parent (a Dask client, tqdm)."""
    import multiprocessing as mp
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(["crosscheck.sweep", *engine_modules()])
    return ctx


class _Serial:
    """Chunks one after another in this process (--workers 1: reproduction, debugging)."""

    def __init__(self, specs):
        self.specs = specs

    def __iter__(self):
        for spec in self.specs:
            try:
                res = run_chunk(spec)
            except Exception as exc:  # noqa: BLE001 - a chunk that fails as a whole
                res = exc
            yield spec, res

    def stop(self) -> list:
        return []

    def close(self) -> None:
        pass


def _submittable(specs):
    """The specs still worth sending: none once the time budget is spent (they would return at
    once with nothing done)."""
    for spec in specs:
        if spec.deadline is not None and time.time() > spec.deadline:
            return
        yield spec


class _Pool:
    """Chunks on local worker processes, yielded as they complete. At most `window` chunks are
    in flight, so a campaign of 10^6 samples does not queue 10^5 futures up front."""

    def __init__(self, specs, workers: int):
        self.ex = ProcessPoolExecutor(max_workers=workers, mp_context=_mp_context(),
                                      initializer=_worker_init)
        self.todo = _submittable(specs)
        self.live: dict = {}  # future -> spec
        self.window = 2 * workers

    def _fill(self):
        while len(self.live) < self.window:
            spec = next(self.todo, None)
            if spec is None:
                return
            self.live[self.ex.submit(run_chunk, spec)] = spec

    def __iter__(self):
        self._fill()
        while self.live:
            done, _ = wait(list(self.live), return_when=FIRST_COMPLETED)
            for fut in done:
                spec = self.live.pop(fut)
                try:
                    res = fut.result()
                except Exception as exc:  # noqa: BLE001 - e.g. a worker that died
                    res = exc
                self._fill()  # keep the workers busy while the parent merges
                yield spec, res

    def stop(self) -> list:
        """Cancel what has not started, let the chunks in flight finish (each is short), and
        return the results not yet yielded."""
        for f in self.live:
            f.cancel()
        self.ex.shutdown(wait=True, cancel_futures=True)
        return [(s, f.result()) for f, s in self.live.items()
                if f.done() and not f.cancelled() and f.exception() is None]

    def close(self) -> None:
        self.ex.shutdown(wait=True, cancel_futures=True)


def _dask_client(address):
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise ModelInputError("--dask needs dask.distributed: pip install "
                              "'multibody-crosscheck[sweep]' (or 'dask[distributed]')")
    if not isinstance(address, str):
        return address, None  # a Client given by the caller (tests, notebooks)
    if address.startswith("local"):
        k = address.partition(":")[2] or str(default_workers())
        if not k.isdigit() or int(k) < 1:
            raise ModelInputError(f"--dask {address!r}: expected local or local:K with K >= 1")
        cluster = LocalCluster(n_workers=int(k), threads_per_worker=1, processes=True,
                               dashboard_address=None)
        return Client(cluster), cluster
    try:
        return Client(address, timeout="10s"), None
    except (OSError, ValueError, TypeError) as exc:
        raise ModelInputError(f"--dask {address!r}: cannot connect to a Dask scheduler "
                              f"({_first_line(exc) or type(exc).__name__})")


class _Dask:
    """Chunks as tasks on a Dask distributed cluster, yielded as they complete; at most
    `window` tasks in flight (the scheduler is not handed 10^5 tasks at once)."""

    def __init__(self, specs, client, threads: int):
        from distributed import as_completed as dask_completed
        self.client = client
        self.todo = _submittable(specs)
        self.live: dict = {}  # key -> (future, spec)
        self.window = 2 * threads
        self.ac = dask_completed()

    def _fill(self):
        while len(self.live) < self.window:
            spec = next(self.todo, None)
            if spec is None:
                return
            fut = self.client.submit(run_chunk, spec, pure=False)
            self.live[fut.key] = (fut, spec)
            self.ac.add(fut)

    def __iter__(self):
        self._fill()
        for fut in self.ac:
            _, spec = self.live.pop(fut.key)
            try:
                res = fut.result()
            except Exception as exc:  # noqa: BLE001 - a task that failed as a whole
                res = exc
            self._fill()
            yield spec, res

    def stop(self) -> list:
        late = [(spec, fut.result()) for fut, spec in self.live.values()
                if fut.status == "finished"]
        self.client.cancel([fut for fut, _ in self.live.values()])
        return late

    def close(self) -> None:
        pass


def dask_chunk(n_samples: int, threads: int) -> int:
    """Samples per Dask task: at least DASK_MIN_CHUNK, unless fewer would keep every thread
    busy; otherwise a quarter of a model's samples per thread (load balance), at most
    DASK_MAX_CHUNK (a task of seconds, not minutes: an interrupt or a lost worker costs
    little)."""
    return max(1, min(max(DASK_MIN_CHUNK, math.ceil(n_samples / (4 * threads))),
                      math.ceil(n_samples / threads), DASK_MAX_CHUNK))


def local_chunk(n_samples: int, workers: int) -> int:
    return max(1, min(LOCAL_CHUNK_MAX, math.ceil(n_samples / (4 * workers))))


def campaign(cfg: Campaign, workers: int | None = None, dask=None, chunk: int | None = None,
             max_seconds: float | None = None, progress=None, on_chunk=None,
             store=None, resume: bool = False) -> dict:
    """Run a campaign and return the sweep.json content.

    workers: local processes (default: all cores; 1 = in this process); dask: a scheduler
    address, "local[:K]" or a distributed.Client (then workers is ignored); chunk: samples per
    task (default: local_chunk / dask_chunk); max_seconds: time budget; on_chunk(result) is
    called after each chunk is merged (tests use it to interrupt); store: a
    sweep_store.ChunkStore that keeps every finished chunk on disk, and with resume=True
    supplies the chunks an interrupted run of the same campaign finished (not recomputed)."""
    from .bench import meta
    cfg.validate()
    if max_seconds is not None and not max_seconds > 0:
        raise ModelInputError(f"--max-seconds must be > 0, got {max_seconds}")
    t_start = time.perf_counter()
    deadline = None if max_seconds is None else time.time() + max_seconds
    aggs = _plan(cfg)
    client = cluster = None
    if dask is not None:
        client, cluster = _dask_client(dask)
        threads = sum(client.nthreads().values()) or 1
        chunk = chunk or dask_chunk(cfg.samples, threads)
        executor = {"kind": "dask", "address": dask if isinstance(dask, str)
                    else str(client.scheduler.address), "threads": threads, "chunk": chunk}
    else:
        workers = workers or default_workers()
        if workers < 1:
            raise ModelInputError(f"--workers must be >= 1, got {workers}")
        chunk = chunk or local_chunk(cfg.samples, workers)
        executor = {"kind": "serial" if workers == 1 else "processes", "workers": workers,
                    "chunk": chunk}
    if chunk < 1:
        raise ModelInputError(f"--chunk must be >= 1, got {chunk}")
    loaded = _load_stored(cfg, aggs, store, resume, progress)
    specs = _specs(cfg, aggs, chunk, deadline)
    stopped = None
    seen = set()

    def merge(spec, res):
        seen.add((spec.model, spec.start))
        agg = aggs[spec.model]
        if isinstance(res, BaseException):
            agg.chunk_faults.append({"model": spec.model, "start": spec.start, "stop": spec.stop,
                                     "type": type(res).__name__, "reason": _first_line(res)})
            return
        agg.merge(res)
        if store is not None:
            store.save(res)
        if progress:
            progress(res["completed"])
        if on_chunk:
            on_chunk(res)

    runner = None
    try:
        runner = (_Dask(specs, client, threads) if client is not None
                  else _Serial(specs) if workers == 1 else _Pool(specs, workers))
        try:
            for spec, res in runner:
                merge(spec, res)
        except KeyboardInterrupt:
            stopped = "interrupted"
            for spec, res in runner.stop():  # chunks that finished while stopping
                if (spec.model, spec.start) not in seen:
                    aggs[spec.model].merge(res)
                    if store is not None:
                        store.save(res)
    finally:
        if runner is not None:
            runner.close()
        if cluster is not None:
            client.close()
            cluster.close()
    done = {n: int(a.completed.sum()) for n, a in aggs.items()}
    if stopped is None and any(d < cfg.samples for d in done.values()):
        if deadline is not None and time.time() > deadline:
            stopped = f"time budget --max-seconds {max_seconds:g} reached"
        elif any(a.chunk_faults for a in aggs.values()):
            stopped = "chunks failed as a whole (see faults.chunks)"
    out = _summarize(cfg, aggs, stopped, done)
    out["meta"] = {**meta(sys.argv[1:]), **_campaign_meta(cfg, aggs), "executor": executor}
    if resume:
        out["meta"]["resumed"] = loaded
    out["timing"] = _timing(aggs, time.perf_counter() - t_start)
    return out


def _load_stored(cfg: Campaign, aggs, store, resume: bool, progress) -> dict:
    """Merge the chunks a stored, interrupted run of this campaign finished (resume), or start
    a fresh store; returns what was loaded (for meta)."""
    if store is None:
        return {}
    if not resume:
        store.start()
        return {}
    chunks = [r for r in store.load() if r["model"] in aggs]
    for res in chunks:
        aggs[res["model"]].merge(res)
        if progress:
            progress(res["completed"])
    return {"chunks": len(chunks), "samples": sum(r["completed"] for r in chunks),
            "from": str(store.dir)}


def _campaign_meta(cfg: Campaign, aggs) -> dict:
    return {
        "seed": cfg.seed, "samples": cfg.samples, "index": cfg.index,
        "models": list(cfg.models), "engines": list(cfg.engines),
        "formulations": {n: a.formulation for n, a in aggs.items()},
        "perturb": cfg.perturb,
        "sampler": "crosscheck.sampling.draw_instance (the property tests' generator): "
                   "parameters x U(0.8, 1.25) (signed loads U(-1, 1) x max(1, |default|)), "
                   "t ~ U(0, 2), initial state + N(0, 0.3) / N(0, 1) noise, projected",
        "seeding": "sample i of model M: numpy default_rng(sample_seed), sample_seed = "
                   "SeedSequence([seed, crc32(M), i]).generate_state(1, uint32)[0]",
        "quantiles": {"levels": list(QUANTILES), "method": QUANTILE_METHOD},
        "metrics": {**C.METRICS, "relative_energy_error":
                    "|(K + V)_engine - (K + V)_reference| / max(|K| + |V|, 1)"},
    }


def _summarize(cfg: Campaign, aggs, stopped, done) -> dict:
    results, series_rows, fault_groups, fault_records, chunk_faults = [], [], {}, [], []
    outside_total = 0
    for name, agg in aggs.items():
        base = base_model(name, cfg.formulation)
        redrawn = {}

        def case(i):
            if i not in redrawn:
                redrawn[i] = draw_sample(base, cfg.seed, i)
            return redrawn[i]

        faults = sorted(agg.faults, key=lambda f: (f["index"], str(f["engine"]),
                                                   str(f["variant"]), f["stage"]))
        for f in faults:
            key = (name, f["engine"], f["variant"], f["stage"], f["type"])
            g = fault_groups.setdefault(key, {"model": name, "engine": f["engine"],
                                              "variant": f["variant"], "stage": f["stage"],
                                              "type": f["type"], "count": 0,
                                              "first_reason": f["reason"]})
            g["count"] += 1
            if g["count"] <= FAULTS_KEPT:
                f = dict(f)
                f["reproduce"] = _fault_command(cfg, name, f)
                fault_records.append(f)
        chunk_faults += agg.chunk_faults
        for (e, v), reason in agg.unsupported.items():
            series_rows.append({"model": name, "engine": e, "variant": v, "unsupported": reason,
                                "samples": done[name], "evaluated": 0, "faults": 0})
        for e, v in agg.series:
            n_faults = sum(1 for f in agg.faults if f["engine"] == e and f["variant"] == v)
            keys = [k for k in QUANTITY_ORDER if (e, v, k) in agg.values or (e, v, k) in agg.skips]
            evaluated = 0
            for qn in keys:
                if (e, v, qn) in agg.values:
                    evaluated = int(np.sum(~np.isnan(agg.values[(e, v, qn)])))
                    break
            series_rows.append({"model": name, "engine": e, "variant": v, "unsupported": None,
                                "samples": done[name], "evaluated": evaluated,
                                "faults": n_faults})
            soft = bool(agg.soft.get((e, v)))
            for qn in keys:
                tol, metric = tolerance(qn, soft, _adapter(e), name)
                row = {"model": name, "formulation": agg.formulation, "engine": e,
                       "variant": v, "quantity": qn}
                if (e, v, qn) not in agg.values:
                    results.append({**row, "skipped": agg.skips[(e, v, qn)], "count": 0})
                    continue
                arr = agg.values[(e, v, qn)]
                idx = np.flatnonzero(~np.isnan(arr))
                vals = arr[idx]
                fin = np.isfinite(vals)
                outside = None
                if tol is not None:
                    outside = int(np.sum(~(vals <= tol.value)))
                    outside_total += outside
                order = np.lexsort((idx, -np.where(fin, vals, np.inf)))[:cfg.worst]
                worst = []
                for j in order:
                    i = int(cfg.index + idx[j])
                    s, nm, t, q, u = case(i)
                    w = {"index": i, "sample_seed": s, "error": float(vals[j]),
                         "parameters": nm.params, "t": t, "q": np.asarray(q).tolist(),
                         "u": np.asarray(u).tolist(),
                         "reproduce": reproduce_commands(cfg, name, agg.formulation, e, i,
                                                         nm, t, q, u)}
                    if cfg.perturb.get(e):
                        w["engine_parameters"] = perturbed(name, nm.params, cfg.perturb[e])
                    worst.append(w)
                rec = {**row, "metric": metric,
                       "tolerance": None if tol is None else tol.value,
                       "reason": SOFT_ERROR_REASON if tol is None else tol.reason,
                       "count": int(len(vals)), "nonfinite": int(np.sum(~fin)),
                       "outside_tolerance": outside,
                       "max": float(vals.max()) if len(vals) else None,
                       "mean": float(vals[fin].mean()) if fin.any() else None,
                       "quantiles": ({str(p): float(x) for p, x in zip(
                           QUANTILES, np.quantile(vals, QUANTILES, method=QUANTILE_METHOD))}
                           if len(vals) else {}),
                       "histogram": _histogram(vals), "worst": worst}
                if soft and qn in ("accelerations", "multipliers"):
                    rec["answer"] = rigid_answer(e)
                results.append(rec)
    n_faults = sum(g["count"] for g in fault_groups.values())
    complete = stopped is None and all(d == cfg.samples for d in done.values())
    status = {
        "complete": complete, "stopped": stopped,
        "requested": {n: cfg.samples for n in aggs},
        "completed": done,
        "completed_ranges": {n: _ranges(a.completed, cfg.index) for n, a in aggs.items()},
        "outside_tolerance": outside_total, "faults": n_faults + len(chunk_faults),
    }
    # an incomplete campaign never reads as passed: what it did not run, it did not check
    clean = outside_total == 0 and n_faults == 0 and not chunk_faults
    status["verdict"] = "failed" if not clean else "passed" if complete else "incomplete"
    status["passed"] = status["verdict"] == "passed"
    return {"status": status, "series": series_rows, "results": results,
            "faults": {"groups": list(fault_groups.values()), "records": fault_records,
                       "kept_per_group": FAULTS_KEPT, "chunks": chunk_faults}}


def _fault_command(cfg: Campaign, model: str, f: dict) -> str:
    argv = ["crosscheck", "sweep", model, "--seed", str(cfg.seed), "--index", str(f["index"]),
            "--samples", "1", "--workers", "1"]
    if f["engine"] != REFERENCE:
        argv += ["--engines", f["engine"]]
        for p, rel in sorted(cfg.perturb.get(f["engine"], {}).items()):
            argv += ["--perturb", f"{f['engine']}:{p}={rel!r}"]
    if cfg.formulation:
        argv += ["--formulation", cfg.formulation]
    return shlex.join(argv + ["--out", f"repro/{model}-{f['index']}"])


def _timing(aggs, wall: float) -> dict:
    """Where the time went (not part of the deterministic results)."""
    rows = []
    for name, a in aggs.items():
        n = max(a.timing["samples"], 1)
        rows.append({"model": name, "engine": REFERENCE, "variant": None,
                     "samples": a.timing["samples"],
                     "draw_us_per_sample": 1e6 * a.timing["draw_s"] / n,
                     "reference_batched_us_per_sample": 1e6 * a.timing["reference_s"] / n,
                     "reference_mass_matrix_energy_us_per_sample":
                         1e6 * a.timing["reference_aux_s"] / n})
        for (e, v), (b, ev, tried, c) in a.timing["series"].items():
            rows.append({"model": name, "engine": e, "variant": v, "builds": tried,
                         "evaluated": c, "build_s": b, "evaluate_s": ev,
                         "build_us_per_sample": 1e6 * b / max(tried, 1),
                         "evaluate_us_per_sample": 1e6 * ev / max(c, 1),
                         "build_fraction": b / (b + ev) if b + ev > 0 else None})
    return {"wall_s": wall, "per_series": rows,
            "note": "summed over workers (CPU-seconds of each stage), wall_s is the campaign's"}


# ---- throughput benchmark -------------------------------------------------------------------
def _spin(n: int) -> int:
    """Pure-Python work for the machine's own scaling baseline."""
    x = 0
    for i in range(n):
        x += i * i
    return x


def _machine_scaling(workers=(1, 2), tasks: int = 8, n: int = 2_000_000) -> list[dict]:
    """How this machine scales pure-Python work over local processes (the same pool type):
    the ceiling for any Python-bound campaign here (cores may be shared or throttled)."""
    out = []
    for w in workers:
        with ProcessPoolExecutor(max_workers=w, mp_context=_mp_context()) as ex:
            list(ex.map(_spin, [1000] * w))  # start the workers before timing
            t0 = time.perf_counter()
            list(ex.map(_spin, [n] * tasks))
            out.append({"workers": w, "wall_s": time.perf_counter() - t0})
    for r in out:
        r["speedup_vs_1"] = out[0]["wall_s"] / r["wall_s"]
    return out


def bench(model_names=None, samples: int = 200, seed: int = 0, engines=None,
          scaling_workers=(1, 2), log=None) -> dict:
    """Throughput of campaigns, measured (not asserted). For `crosscheck sweep --bench` and for
    crosscheck.bench to call.

    - per model and engine: a one-engine campaign in this process (one core), after a warm-up
      campaign (imports, compiled code); samples per second end to end (draw + reference +
      engine build + evaluation + aggregation), with the CPU time per sample of each stage and
      the reference's scalar forward per sample beside its batched one;
    - scaling: the whole campaign (all models, all engines) with 1 worker (in this process,
      as --workers 1 runs) and 2 local worker processes (pool start and transfer included, so
      the speedup is conservative), samples per second and speedup, beside the machine's own
      scaling of pure-Python work over the same kind of pool.
    """
    names = list(model_names or models.names())
    engines = tuple(available_engines() if engines is None else engines)
    log = log or (lambda msg: None)
    rows = []
    for name in names:
        campaign(Campaign([name], 2, seed + 1, engines=tuple(engines)), workers=1)  # warm-up
        for e in engines:
            cfg = Campaign([name], samples, seed, engines=(e,))
            t0 = time.perf_counter()
            res = campaign(cfg, workers=1, chunk=LOCAL_CHUNK_MAX)
            wall = time.perf_counter() - t0
            ref = next(r for r in res["timing"]["per_series"] if r["engine"] == REFERENCE)
            base = base_model(name)
            scalar = []
            for i in range(min(samples, 20)):
                try:
                    _, nmi, t, q, u = draw_sample(base, seed, i)
                except Exception:  # noqa: BLE001 - a faulty draw is not timed
                    continue
                t1 = time.perf_counter()
                for _ in range(20):
                    nmi.forward(q, u, t)
                scalar.append((time.perf_counter() - t1) / 20)
            for s in res["series"]:
                if s["engine"] != e:
                    continue
                tim = next((r for r in res["timing"]["per_series"]
                            if r["engine"] == e and r["variant"] == s["variant"]), None)
                rows.append({
                    "model": name, "engine": e, "variant": s["variant"],
                    "unsupported": s["unsupported"], "samples": samples, "wall_s": wall,
                    "samples_per_s_per_core": None if s["unsupported"] else samples / wall,
                    "draw_us": ref["draw_us_per_sample"],
                    "reference_batched_us": ref["reference_batched_us_per_sample"],
                    "reference_scalar_us": 1e6 * float(np.median(scalar)) if scalar else None,
                    "reference_mass_matrix_energy_us":
                        ref["reference_mass_matrix_energy_us_per_sample"],
                    "build_us": tim and tim["build_us_per_sample"],
                    "evaluate_us": tim and tim["evaluate_us_per_sample"],
                    "build_fraction": tim and tim["build_fraction"],
                    "faults": s["faults"]})
            log(f"{name} {e}: {samples / wall:.0f} samples/s")
    campaign(Campaign(names[:1], 4, seed + 1, engines=tuple(engines)), workers=2)  # forkserver
    scaling = []
    for w in scaling_workers:
        cfg = Campaign(names, samples, seed, engines=tuple(engines))
        t0 = time.perf_counter()
        res = campaign(cfg, workers=w, chunk=LOCAL_CHUNK_MAX)
        wall = time.perf_counter() - t0
        total = samples * len(names)
        scaling.append({"workers": w, "executor": res["meta"]["executor"], "samples": total,
                        "wall_s": wall, "samples_per_s": total / wall})
        log(f"{w} worker(s): {total / wall:.0f} samples/s")
    for s in scaling:
        s["speedup_vs_1"] = s["samples_per_s"] / scaling[0]["samples_per_s"]
    from .bench import meta
    return {"meta": {**meta(sys.argv[1:]), "samples_per_model": samples, "seed": seed,
                     "cores": default_workers(),
                     "note": "samples_per_s_per_core: one-engine campaign in one process after "
                             "a warm-up; stage columns are CPU microseconds per sample"},
            "per_model_engine": rows, "scaling": scaling,
            "machine_scaling": _machine_scaling(scaling_workers)}


def _print_bench(b: dict) -> None:
    print(f"{'model':24s} {'engine':10s} {'variant':8s} {'samples/s':>9s} {'draw':>6s} "
          f"{'ref batch':>9s} {'ref scalar':>10s} {'ref M,E':>7s} {'build':>7s} "
          f"{'evaluate':>8s} {'build %':>7s}   (us per sample)")
    for r in b["per_model_engine"]:
        if r["unsupported"]:
            print(f"{r['model']:24s} {r['engine']:10s} {str(r['variant'] or '-'):8s} "
                  f"unsupported: {r['unsupported'][:60]}")
            continue
        f = lambda x, w=7: f"{x:{w}.0f}" if x is not None else f"{'-':>{w}s}"  # noqa: E731
        print(f"{r['model']:24s} {r['engine']:10s} {str(r['variant'] or '-'):8s} "
              f"{r['samples_per_s_per_core']:9.1f} {f(r['draw_us'], 6)} "
              f"{f(r['reference_batched_us'], 9)} {f(r['reference_scalar_us'], 10)} "
              f"{f(r['reference_mass_matrix_energy_us'])} {f(r['build_us'])} "
              f"{f(r['evaluate_us'], 8)} {100 * (r['build_fraction'] or 0):6.0f}%"
              + (f"  ({r['faults']} faults)" if r["faults"] else ""))
    for s in b["scaling"]:
        print(f"{s['workers']} worker(s): {s['samples']} samples in {s['wall_s']:.2f} s = "
              f"{s['samples_per_s']:.1f} samples/s, speedup {s['speedup_vs_1']:.2f}")
    print("machine baseline (pure-Python work, same pool): " + ", ".join(
        f"{m['workers']} worker(s) speedup {m['speedup_vs_1']:.2f}"
        for m in b["machine_scaling"]))


# ---- command line ---------------------------------------------------------------------------
def _print_summary(res: dict, path: Path) -> None:
    st = res["status"]
    for r in res["results"]:
        if r.get("outside_tolerance"):
            w = r["worst"][0] if r["worst"] else {}
            print(f"OUTSIDE {r['model']} {r['engine']}{'/' + r['variant'] if r['variant'] else ''}"
                  f" {r['quantity']}: {r['outside_tolerance']} of {r['count']} samples > "
                  f"{r['tolerance']:.0e} (max {r['max']:.3e}); reproduce the worst: "
                  f"{w.get('reproduce', {}).get('sweep', '')}", file=sys.stderr)
    for g in res["faults"]["groups"]:
        print(f"FAULT {g['model']} {g['engine']}{'/' + g['variant'] if g['variant'] else ''} "
              f"{g['stage']} {g['type']} x{g['count']}: {g['first_reason'][:160]}",
              file=sys.stderr)
    for c in res["faults"]["chunks"]:
        print(f"CHUNK FAILED {c['model']} [{c['start']}, {c['stop']}): {c['type']} "
              f"{c['reason'][:160]}", file=sys.stderr)
    total = sum(st["completed"].values())
    requested = sum(st["requested"].values())
    print(f"crosscheck sweep: {total} of {requested} samples, {st['outside_tolerance']} "
          f"outside tolerance, {st['faults']} faults"
          + (f", stopped: {st['stopped']}" if st["stopped"] else "") + f" -> {path}")


def _user_models_here(args, names) -> None:
    """User models (--model-file) are registered in this process only: their samples run
    here (--workers 1); Dask workers elsewhere could not load the files."""
    from reference import models
    if not set(names) & set(models.user_names()):
        return
    if args.dask is not None:
        raise ModelInputError("--model-file models run in this process only; leave out --dask "
                              "(the workers would not have the file's models)")
    args.workers = 1


def cmd_sweep(args) -> int:
    from .arguments import output_dir, resolve_engines, resolve_models
    from .cli import _json_default
    from .output import write_atomic
    from .sweep_store import ChunkStore
    if args.workers is not None and args.dask is not None:
        raise ModelInputError("give --workers or --dask, not both")
    if args.resume is not None:
        cfg, out = _resumed_campaign(args)
    else:
        names = resolve_models(args.models, getattr(args, "user_models", None))
        engines = tuple(resolve_engines(args.engines))
        _user_models_here(args, names)
        out = output_dir(args.out)  # an unusable --out fails now, not after the campaign
        if args.bench:
            return _cmd_bench(args, names, engines, out)
        cfg = Campaign(list(names), args.samples, args.seed, args.index, engines,
                       parse_perturb(args.perturb), args.formulation, args.worst, str(out))
    bar = None
    if sys.stderr.isatty():
        from tqdm import tqdm
        bar = tqdm(total=cfg.samples * len(cfg.models), desc="samples", unit="sample",
                   file=sys.stderr)
    store = ChunkStore(out, cfg)
    try:
        res = campaign(cfg, workers=args.workers, dask=args.dask, chunk=args.chunk,
                       max_seconds=args.max_seconds, progress=bar.update if bar else None,
                       store=store, resume=args.resume is not None)
    finally:
        if bar:
            bar.close()
    path = write_atomic(out / "sweep.json",
                        json.dumps(res, indent=2, default=_json_default, allow_nan=True))
    _print_summary(res, path)
    if res["status"]["complete"]:
        store.remove()  # after sweep.json is in place: nothing left to resume
    else:
        print(f"finished chunks kept in {store.dir}; continue with: "
              f"{shlex.join(['crosscheck', 'sweep', '--resume', str(out)])}")
    return exit_code(res["status"])


# campaign options of the command line, with their defaults: under --resume each must be left
# at its default or agree with the stored campaign
_CAMPAIGN_OPTIONS = {"models": [], "samples": 100, "seed": 0, "index": 0,
                     "engines": None, "perturb": [], "formulation": None,
                     "worst": WORST_CASES}


def _resumed_campaign(args):
    """The campaign stored in --resume DIR; options that contradict it are refused."""
    from .arguments import output_dir
    from .sweep_store import stored_settings
    if args.bench:
        raise ModelInputError("--resume continues a campaign; --bench measures throughput: "
                              "give one of them")
    out = output_dir(args.resume, "--resume")
    if args.out not in ("out", args.resume):
        raise ModelInputError(f"--resume {args.resume!r} writes there; drop --out {args.out!r}")
    st = stored_settings(out)
    given = {"perturb": parse_perturb(args.perturb)}
    for key, default in _CAMPAIGN_OPTIONS.items():
        value = getattr(args, key)
        if value != default and given.get(key, value) != st[key]:
            raise ModelInputError(
                f"--resume {args.resume!r} continues the campaign stored there ({key} "
                f"{st[key]!r}); drop --{key} {value!r} or start a new campaign with --out")
    cfg = Campaign(list(st["models"]), st["samples"], st["seed"], st["index"],
                   tuple(st["engines"]), st["perturb"], st["formulation"], st["worst"],
                   str(out))
    return cfg, out


def _cmd_bench(args, names, engines, out) -> int:
    from .cli import _json_default
    from .output import write_atomic
    cfg = Campaign(list(names), args.samples, args.seed, args.index, engines)
    cfg.validate()
    b = bench(names, args.samples, args.seed, engines,
              log=lambda m: print(m, file=sys.stderr, flush=True))
    write_atomic(out / "sweep_bench.json", json.dumps(b, indent=2, default=_json_default))
    _print_bench(b)
    print(f"wrote {out / 'sweep_bench.json'}")
    return 0


def exit_code(status: dict) -> int:
    """130 when interrupted, 1 when a sample failed a check or faulted, 4 when the campaign
    stopped early (time budget) with nothing failed in what it ran, 0 when it passed."""
    from .cli import EXIT_INCOMPLETE, EXIT_INTERRUPTED
    if status["stopped"] == "interrupted":
        return EXIT_INTERRUPTED
    return {"passed": 0, "failed": 1}.get(status["verdict"], EXIT_INCOMPLETE)


def register(sub):
    from .arguments import (
        add_engines,
        add_models,
        nonnegative_int,
        positive_int,
        positive_seconds,
    )
    s = sub.add_parser(
        "sweep", help="seeded random campaigns of the cross-checks (local workers or Dask)",
        description="Draw N seeded random parameter sets and consistent states per model, run "
                    "the instantaneous cross-checks on each, write DIR/sweep.json.")
    add_models(s)
    s.add_argument("--samples", type=positive_int, default=100,
                   help="samples per model (default 100)")
    s.add_argument("--seed", type=nonnegative_int, default=0, help="campaign seed (default 0)")
    s.add_argument("--index", type=nonnegative_int, default=0,
                   help="first sample index (default 0): --index I --samples 1 reruns sample I")
    add_engines(s)
    s.add_argument("--formulation", default=None,
                   help="reference formulation (default: each model's first)")
    s.add_argument("--perturb", action="append", default=[], metavar="ENGINE:PARAM=REL",
                   help="fault injection, as in crosscheck run")
    s.add_argument("--workers", type=positive_int, default=None, help="local worker processes (default: all cores; "
                                                   "1 runs in this process)")
    s.add_argument("--dask", default=None, metavar="ADDRESS",
                   help="run on a Dask distributed scheduler (tcp://host:8786), or local[:K]")
    s.add_argument("--chunk", type=positive_int, default=None,
                   help="samples per task (default: sized per executor)")
    s.add_argument("--max-seconds", type=positive_seconds, default=None,
                   help="time budget: stop and report what is done")
    s.add_argument("--worst", type=nonnegative_int, default=WORST_CASES,
                   help="worst cases kept per quantity")
    s.add_argument("--bench", action="store_true",
                   help="measure throughput (per model and engine, 1 vs 2 workers) and write "
                        "DIR/sweep_bench.json instead of running a campaign")
    s.add_argument("--out", default="out")
    s.add_argument("--resume", default=None, metavar="DIR",
                   help="continue the interrupted campaign whose --out was DIR: its finished "
                        "chunks (DIR/sweep.chunks) are kept, only the rest is computed")
    s.set_defaults(func=cmd_sweep)
