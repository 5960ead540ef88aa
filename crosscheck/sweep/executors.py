"""Where a sweep's chunks run: in this process, a local process pool, or a Dask cluster; and
the chunk sizes each executor is given."""

from __future__ import annotations

import math
import os
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

from crosscheck.runtime.workers import default_workers, process_context, start_worker
from crosscheck.sweep.config import DASK_MAX_CHUNK, DASK_MIN_CHUNK, LOCAL_CHUNK_MAX
from crosscheck.sweep.worker import first_line, run_chunk
from reference.errors import ModelInputError


def new_mp_context():
    """The workers' process context, their server having imported what a chunk runs."""
    return process_context("crosscheck.sweep.worker")


class SerialExecutor:
    """Chunks one after another in this process (--workers 1: reproduction, debugging)."""

    def __init__(self, specs):
        self.specs = specs

    def __iter__(self):
        for spec in self.specs:
            try:
                res = run_chunk(spec)
            except Exception as exc:
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


class PoolExecutor:
    """Chunks on local worker processes, yielded as they complete. At most `window` chunks are
    in flight, so a campaign of 10^6 samples does not queue 10^5 futures up front."""

    def __init__(self, specs, workers: int):
        self.ex = ProcessPoolExecutor(
            max_workers=workers,
            mp_context=new_mp_context(),
            initializer=start_worker,
            initargs=(os.getpid(),),
        )
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
                except Exception as exc:
                    res = exc
                self._fill()  # keep the workers busy while the parent merges
                yield spec, res

    def stop(self) -> list:
        """Cancel what has not started, let the chunks in flight finish (each is short), and
        return the results not yet yielded."""
        for f in self.live:
            f.cancel()
        self.ex.shutdown(wait=True, cancel_futures=True)
        return [
            (s, f.result())
            for f, s in self.live.items()
            if f.done() and not f.cancelled() and f.exception() is None
        ]

    def close(self) -> None:
        self.ex.shutdown(wait=True, cancel_futures=True)


def dask_client(address):
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise ModelInputError(
            "--dask needs dask.distributed: pip install "
            "'multibody-crosscheck[sweep]' (or 'dask[distributed]')"
        ) from None
    if not isinstance(address, str):
        return address, None  # a Client given by the caller (tests, notebooks)
    if address.startswith("local"):
        k = address.partition(":")[2] or str(default_workers())
        if not k.isdigit() or int(k) < 1:
            raise ModelInputError(f"--dask {address!r}: expected local or local:K with K >= 1")
        cluster = LocalCluster(
            n_workers=int(k), threads_per_worker=1, processes=True, dashboard_address=None
        )
        return Client(cluster), cluster
    try:
        return Client(address, timeout="10s"), None
    except (OSError, ValueError, TypeError) as exc:
        raise ModelInputError(
            f"--dask {address!r}: cannot connect to a Dask scheduler "
            f"({first_line(exc) or type(exc).__name__})"
        ) from None


class DaskExecutor:
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
            except Exception as exc:
                res = exc
            self._fill()
            yield spec, res

    def stop(self) -> list:
        late = [
            (spec, fut.result()) for fut, spec in self.live.values() if fut.status == "finished"
        ]
        self.client.cancel([fut for fut, _ in self.live.values()])
        return late

    def close(self) -> None:
        pass


def dask_chunk(n_samples: int, threads: int) -> int:
    """Samples per Dask task: at least DASK_MIN_CHUNK, unless fewer would keep every thread
    busy; otherwise a quarter of a model's samples per thread (load balance), at most
    DASK_MAX_CHUNK (a task of seconds, not minutes: an interrupt or a lost worker costs
    little)."""
    return max(
        1,
        min(
            max(DASK_MIN_CHUNK, math.ceil(n_samples / (4 * threads))),
            math.ceil(n_samples / threads),
            DASK_MAX_CHUNK,
        ),
    )


def local_chunk(n_samples: int, workers: int) -> int:
    return max(1, min(LOCAL_CHUNK_MAX, math.ceil(n_samples / (4 * workers))))
