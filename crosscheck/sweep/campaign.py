"""A sweep campaign from plan to summary: the models' engine variants, the chunks still to run,
the executor, merging as chunks finish, and what an interrupt or the time budget leaves."""

from __future__ import annotations

import sys
import time

from crosscheck.checks.instantaneous import build
from crosscheck.engines.base import EngineUnsupported
from crosscheck.runtime import interrupts
from crosscheck.sweep.aggregate import (
    ModelAggregate,
    campaign_meta,
    completed_index_ranges,
    summarize,
    timing_summary,
)
from crosscheck.sweep.config import Campaign
from crosscheck.sweep.executors import (
    DaskExecutor,
    PoolExecutor,
    SerialExecutor,
    dask_chunk,
    dask_client,
    default_workers,
    local_chunk,
)
from crosscheck.sweep.worker import ChunkSpec, base_model, cached_adapter, first_line
from reference.errors import ModelInputError


def _plan(cfg: Campaign):
    """Per model: the base reference (compiles on first use, here in the parent so the workers
    find it in the disk cache) and the engine variants to evaluate, or why one cannot be."""
    aggs = {}
    for name in cfg.models:
        base = base_model(name, cfg.formulation)  # raises for a bad formulation
        series, unsupported = [], {}
        for e in cfg.engines:
            ad = cached_adapter(e)
            for v in ad.variants(name):
                try:  # the model structure, not the parameters, decides this
                    build(ad, name, None, v)
                except EngineUnsupported as exc:
                    unsupported[(e, v)] = first_line(exc)
                    continue
                except Exception:
                    pass
                series.append((e, v))
        aggs[name] = ModelAggregate(
            name, base.formulation, cfg.index, cfg.samples, series, unsupported
        )
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
            for lo, hi in completed_index_ranges(~agg.completed[a - cfg.index : b - cfg.index], a):
                specs.append(
                    ChunkSpec(
                        name,
                        agg.formulation,
                        cfg.seed,
                        lo,
                        hi,
                        tuple(agg.series),
                        perturb,
                        deadline,
                        derivatives=cfg.derivatives,
                    )
                )
    return specs


def _executor(cfg: Campaign, workers, dask, chunk):
    """The executor's settings: (client, cluster, workers, threads, chunk, meta's "executor")."""
    threads = None
    client = cluster = None
    if dask is not None:
        client, cluster = dask_client(dask)
        threads = sum(client.nthreads().values()) or 1
        chunk = chunk or dask_chunk(cfg.samples, threads)
        executor = {
            "kind": "dask",
            "address": dask if isinstance(dask, str) else str(client.scheduler.address),
            "threads": threads,
            "chunk": chunk,
        }
    else:
        workers = workers or default_workers()
        if workers < 1:
            raise ModelInputError(f"--workers must be >= 1, got {workers}")
        chunk = chunk or local_chunk(cfg.samples, workers)
        executor = {
            "kind": "serial" if workers == 1 else "processes",
            "workers": workers,
            "chunk": chunk,
        }
    if chunk < 1:
        raise ModelInputError(f"--chunk must be >= 1, got {chunk}")
    return client, cluster, workers, threads, chunk, executor


class _Merger:
    """Merges each finished chunk into its model's aggregate (a chunk that failed as a whole is
    recorded as a chunk fault), stores it for --resume and reports progress."""

    def __init__(self, aggs, store, progress, on_chunk):
        self.aggs, self.store, self.progress, self.on_chunk = aggs, store, progress, on_chunk
        self.seen: set = set()

    def __call__(self, spec, res) -> None:
        self.seen.add((spec.model, spec.start))
        agg = self.aggs[spec.model]
        if isinstance(res, BaseException):
            agg.chunk_faults.append(
                {
                    "model": spec.model,
                    "start": spec.start,
                    "stop": spec.stop,
                    "type": type(res).__name__,
                    "reason": first_line(res),
                }
            )
            return
        if self.store is not None:
            self.store.save(res)  # stored first: what is merged is what a resume finds
        agg.merge(res)
        if self.progress:
            self.progress(res["completed"])
        if self.on_chunk:
            self.on_chunk(res)


def campaign(
    cfg: Campaign,
    workers: int | None = None,
    dask=None,
    chunk: int | None = None,
    max_seconds: float | None = None,
    progress=None,
    on_chunk=None,
    store=None,
    resume: bool = False,
) -> dict:
    """Run a campaign and return the sweep.json content.

    workers: local processes (default: all cores; 1 = in this process); dask: a scheduler
    address, "local[:K]" or a distributed.Client (then workers is ignored); chunk: samples per
    task (default: local_chunk / dask_chunk); max_seconds: time budget; on_chunk(result) is
    called after each chunk is merged (tests use it to interrupt); store: a
    sweep_store.ChunkStore that keeps every finished chunk on disk, and with resume=True
    supplies the chunks an interrupted run of the same campaign finished (not recomputed)."""
    from crosscheck.runtime.provenance import meta

    cfg.validate()
    if max_seconds is not None and not max_seconds > 0:
        raise ModelInputError(f"--max-seconds must be > 0, got {max_seconds}")
    t_start = time.perf_counter()
    deadline = None if max_seconds is None else time.time() + max_seconds
    aggs = _plan(cfg)
    client, cluster, workers, threads, chunk, executor = _executor(cfg, workers, dask, chunk)
    loaded = _load_stored(cfg, aggs, store, resume, progress)
    specs = _specs(cfg, aggs, chunk, deadline)
    stopped = None
    merge = _Merger(aggs, store, progress, on_chunk)
    seen = merge.seen
    runner = None
    try:
        runner = (
            DaskExecutor(specs, client, threads)
            if client is not None
            else SerialExecutor(specs)
            if workers == 1
            else PoolExecutor(specs, workers)
        )
        try:
            for spec, res in runner:
                merge(spec, res)
        except KeyboardInterrupt:
            stopped = "interrupted"
            for spec, res in runner.stop():  # chunks workers finished while stopping
                if (spec.model, spec.start) not in seen:
                    if store is not None:
                        store.save(res)
                    aggs[spec.model].merge(res)
    finally:
        if runner is not None:
            runner.close()
        if cluster is not None:
            client.close()
            cluster.close()
    if stopped is None and interrupts.seen():  # a Ctrl-C an engine swallowed in this process
        stopped = "interrupted"
    if store is not None:
        # the summary is made from the chunks on disk, the same a resume starts from: an
        # interrupt at any instant cannot make sweep.json claim, or judge, anything else
        aggs = _from_store(cfg, store, aggs)
    done = {n: int(a.completed.sum()) for n, a in aggs.items()}
    if stopped is None and any(d < cfg.samples for d in done.values()):
        if deadline is not None and time.time() > deadline:
            stopped = f"time budget --max-seconds {max_seconds:g} reached"
        elif any(a.chunk_faults for a in aggs.values()):
            stopped = "chunks failed as a whole (see faults.chunks)"
    out = summarize(cfg, aggs, stopped, done)
    out["meta"] = {**meta(sys.argv[1:]), **campaign_meta(cfg, aggs), "executor": executor}
    if resume:
        out["meta"]["resumed"] = loaded
    out["timing"] = timing_summary(aggs, time.perf_counter() - t_start)
    return out


def _from_store(cfg: Campaign, store, planned) -> dict:
    """Fresh aggregates of the planned series, holding exactly the stored chunks (the chunk
    faults of this run, never stored, are kept)."""
    aggs = {
        n: ModelAggregate(n, a.formulation, cfg.index, cfg.samples, a.series, a.unsupported)
        for n, a in planned.items()
    }
    for res in store.load():
        if res["model"] in aggs:
            aggs[res["model"]].merge(res)
    for n, a in planned.items():
        aggs[n].chunk_faults = a.chunk_faults
    return aggs


def _load_stored(cfg: Campaign, aggs, store, resume: bool, progress) -> dict:
    """Merge the chunks a stored, interrupted run of this campaign finished (resume), or start
    a fresh store; returns what was loaded (for meta)."""
    if store is None:
        return {}
    if not resume:
        store.start(" ".join(["crosscheck", *sys.argv[1:]]))
        return {}
    chunks = [r for r in store.load() if r["model"] in aggs]
    for res in chunks:
        aggs[res["model"]].merge(res)
        if progress:
            progress(res["completed"])
    return {
        "chunks": len(chunks),
        "samples": sum(r["completed"] for r in chunks),
        "from": str(store.dir),
        # the campaign's own command: its settings, where the resuming one may name none
        "campaign_command": store.stored_command(),
    }
