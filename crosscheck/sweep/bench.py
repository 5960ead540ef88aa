"""`crosscheck sweep --bench`: the sweep's throughput per stage and the machine's own scaling."""

from __future__ import annotations

import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from crosscheck.checks.sampling import draw_sample
from crosscheck.engines.registry import available_engines
from crosscheck.sweep.campaign import campaign
from crosscheck.sweep.config import LOCAL_CHUNK_MAX, REFERENCE, Campaign
from crosscheck.sweep.executors import default_workers, new_mp_context
from crosscheck.sweep.worker import base_model
from reference import models


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
        with ProcessPoolExecutor(max_workers=w, mp_context=new_mp_context()) as ex:
            list(ex.map(_spin, [1000] * w))  # start the workers before timing
            t0 = time.perf_counter()
            list(ex.map(_spin, [n] * tasks))
            out.append({"workers": w, "wall_s": time.perf_counter() - t0})
    for r in out:
        r["speedup_vs_1"] = out[0]["wall_s"] / r["wall_s"]
    return out


def _scalar_forward_us(name: str, seed: int, samples: int) -> float | None:
    """Median time of the reference's scalar forward call over the first 20 samples (a draw
    that fails is not timed: the campaign itself records it as a fault)."""
    base = base_model(name)
    scalar = []
    for i in range(min(samples, 20)):
        try:
            _, nmi, t, q, u = draw_sample(base, seed, i)
        except Exception:
            continue
        t1 = time.perf_counter()
        for _ in range(20):
            nmi.forward(q, u, t)
        scalar.append((time.perf_counter() - t1) / 20)
    return 1e6 * float(np.median(scalar)) if scalar else None


def _one_engine_rows(name: str, e: str, samples: int, seed: int, log) -> list[dict]:
    """A one-engine campaign of one model in this process: one row per engine variant."""
    cfg = Campaign([name], samples, seed, engines=(e,))
    t0 = time.perf_counter()
    res = campaign(cfg, workers=1, chunk=LOCAL_CHUNK_MAX)
    wall = time.perf_counter() - t0
    per_series = res["timing"]["per_series"]
    ref = next(r for r in per_series if r["engine"] == REFERENCE)
    scalar_us = _scalar_forward_us(name, seed, samples)
    rows = []
    for s in res["series"]:
        if s["engine"] != e:
            continue
        tim = next(
            (r for r in per_series if r["engine"] == e and r["variant"] == s["variant"]), None
        )
        rows.append(
            {
                "model": name,
                "engine": e,
                "variant": s["variant"],
                "unsupported": s["unsupported"],
                "samples": samples,
                "wall_s": wall,
                "samples_per_s_per_core": None if s["unsupported"] else samples / wall,
                "draw_us": ref["draw_us_per_sample"],
                "reference_batched_us": ref["reference_batched_us_per_sample"],
                "reference_scalar_us": scalar_us,
                "reference_mass_matrix_energy_us": ref[
                    "reference_mass_matrix_energy_us_per_sample"
                ],
                "build_us": tim and tim["build_us_per_sample"],
                "evaluate_us": tim and tim["evaluate_us_per_sample"],
                "build_fraction": tim and tim["build_fraction"],
                "faults": s["faults"],
            }
        )
    log(f"{name} {e}: {samples / wall:.0f} samples/s")
    return rows


def _scaling(names, samples, seed, engines, scaling_workers, log) -> list[dict]:
    """The whole campaign with 1 and more workers: samples per second and speedup."""
    campaign(Campaign(names[:1], 4, seed + 1, engines=tuple(engines)), workers=2)  # forkserver
    scaling = []
    for w in scaling_workers:
        cfg = Campaign(names, samples, seed, engines=tuple(engines))
        t0 = time.perf_counter()
        res = campaign(cfg, workers=w, chunk=LOCAL_CHUNK_MAX)
        wall = time.perf_counter() - t0
        total = samples * len(names)
        scaling.append(
            {
                "workers": w,
                "executor": res["meta"]["executor"],
                "samples": total,
                "wall_s": wall,
                "samples_per_s": total / wall,
            }
        )
        log(f"{w} worker(s): {total / wall:.0f} samples/s")
    for s in scaling:
        s["speedup_vs_1"] = s["samples_per_s"] / scaling[0]["samples_per_s"]
    return scaling


def bench(
    model_names=None,
    samples: int = 200,
    seed: int = 0,
    engines=None,
    scaling_workers=(1, 2),
    log=None,
) -> dict:
    """Throughput of campaigns, measured (not asserted). For `crosscheck sweep --bench` and for
    crosscheck.commands.bench to call.

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
            rows += _one_engine_rows(name, e, samples, seed, log)
    scaling = _scaling(names, samples, seed, engines, scaling_workers, log)
    from crosscheck.runtime.provenance import meta

    return {
        "meta": {
            **meta(sys.argv[1:]),
            "samples_per_model": samples,
            "seed": seed,
            "cores": default_workers(),
            "note": "samples_per_s_per_core: one-engine campaign in one process after "
            "a warm-up; stage columns are CPU microseconds per sample",
        },
        "per_model_engine": rows,
        "scaling": scaling,
        "machine_scaling": _machine_scaling(scaling_workers),
    }


def print_bench(b: dict) -> None:
    print(
        f"{'model':24s} {'engine':10s} {'variant':8s} {'samples/s':>9s} {'draw':>6s} "
        f"{'ref batch':>9s} {'ref scalar':>10s} {'ref M,E':>7s} {'build':>7s} "
        f"{'evaluate':>8s} {'build %':>7s}   (us per sample)"
    )
    for r in b["per_model_engine"]:
        if r["unsupported"]:
            print(
                f"{r['model']:24s} {r['engine']:10s} {r['variant'] or '-'!s:8s} "
                f"unsupported: {r['unsupported'][:60]}"
            )
            continue
        f = lambda x, w=7: f"{x:{w}.0f}" if x is not None else f"{'-':>{w}s}"
        print(
            f"{r['model']:24s} {r['engine']:10s} {r['variant'] or '-'!s:8s} "
            f"{r['samples_per_s_per_core']:9.1f} {f(r['draw_us'], 6)} "
            f"{f(r['reference_batched_us'], 9)} {f(r['reference_scalar_us'], 10)} "
            f"{f(r['reference_mass_matrix_energy_us'])} {f(r['build_us'])} "
            f"{f(r['evaluate_us'], 8)} {100 * (r['build_fraction'] or 0):6.0f}%"
            + (f"  ({r['faults']} faults)" if r["faults"] else "")
        )
    for s in b["scaling"]:
        print(
            f"{s['workers']} worker(s): {s['samples']} samples in {s['wall_s']:.2f} s = "
            f"{s['samples_per_s']:.1f} samples/s, speedup {s['speedup_vs_1']:.2f}"
        )
    print(
        "machine baseline (pure-Python work, same pool): "
        + ", ".join(
            f"{m['workers']} worker(s) speedup {m['speedup_vs_1']:.2f}"
            for m in b["machine_scaling"]
        )
    )
