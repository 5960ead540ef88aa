"""Local worker processes, shared by the commands that spread work over the cores
(`crosscheck run --jobs`, `crosscheck sweep --workers`)."""

from __future__ import annotations

import os
import select
import signal
import threading
import time
from collections.abc import Sequence

from crosscheck.engines.entry_points import engine_modules


def default_workers() -> int:
    """The cores this process may run on (its affinity mask, not the machine's count)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def start_worker(parent: int) -> None:
    """A worker's first act (the pool's initializer, given the parent's pid). Ctrl-C goes to
    the whole process group: the parent handles it (cancels, keeps what is done, stops the
    workers); a worker killed by it would break the pool and lose the work in flight. And a
    worker ends when the parent does: one forked after the parent was interrupted (the
    server still importing when the fork was asked for) or whose parent was killed would
    otherwise block for ever writing its result into a pipe nobody reads."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    watch = threading.Thread(target=_exit_with, args=(parent,), daemon=True, name="parent")
    watch.start()


def _exit_with(parent: int) -> None:
    """Wait for process `parent` to end, then end this process."""
    try:
        fd = os.pidfd_open(parent)  # Linux >= 5.3: readable once the process has ended
    except (AttributeError, OSError):
        fd = None
    if fd is not None:
        select.select([fd], [], [])
    else:  # pragma: no cover - no pidfd: poll
        while True:
            time.sleep(0.5)
            try:
                os.kill(parent, 0)
            except ProcessLookupError:
                break
            except PermissionError:
                pass
    os._exit(1)


def process_context(*modules: str, engines: Sequence[str] | None = None):
    """The workers' process context, its server started (start_server): forkserver, so
    workers fork from a clean server that has imported `modules` and the engines (those named,
    or every registered one), start fast and inherit no threads of the parent (a Dask client,
    tqdm, the C builds running ahead)."""
    import multiprocessing as mp

    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload([*modules, *engine_modules(engines)])
    start_server()
    return ctx


def start_server() -> None:
    """Start the workers' server if it is not running, with Ctrl-C ignored: an ignored signal
    stays ignored across exec, so a Ctrl-C at the terminal (it goes to the whole process
    group) cannot break the server's imports (a traceback in the terminal), and the workers
    it forks ignore it from their first instruction (they inherit the server's setting).
    The parent ignores SIGINT only for the fork and exec, a few milliseconds. Called early
    (crosscheck run), the server's imports (0.9-1.5 s with the engines, benchmarks/run_time.md
    "Before the first model") run on another core while this process does its own."""
    from multiprocessing import forkserver

    if threading.current_thread() is not threading.main_thread():
        forkserver.ensure_running()  # signal handlers belong to the main thread
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        forkserver.ensure_running()
    finally:
        signal.signal(signal.SIGINT, previous)


class WorkerPool:
    """A ProcessPoolExecutor whose workers report their process ids as they start, so that
    `stop` ends them at once: an interrupt must not wait for the work in flight, and the
    workers ignore SIGINT (start_worker). Submit with `submit`, end with `shutdown` (all work
    done) or `stop` (now)."""

    def __init__(self, workers: int, context, initializer, initargs: tuple = ()):
        from concurrent.futures import ProcessPoolExecutor

        self._pids = context.SimpleQueue()
        self.executor = ProcessPoolExecutor(
            max_workers=workers,
            mp_context=context,
            initializer=_report_pid_then,
            initargs=(self._pids, initializer, tuple(initargs)),
        )

    def submit(self, fn, *args):
        return self.executor.submit(fn, *args)

    def shutdown(self) -> None:
        self.executor.shutdown(wait=True)

    def stop(self) -> None:
        """End the workers now, cancel what has not started, release the pool's pipes and
        semaphores. A worker reports its pid before it takes any work, so every worker busy
        with a task is in the queue."""
        while not self._pids.empty():
            try:
                os.kill(self._pids.get(), signal.SIGTERM)
            except ProcessLookupError:
                pass
        self.executor.shutdown(wait=True, cancel_futures=True)
        self._pids.close()


def _report_pid_then(pids, initializer, initargs: tuple) -> None:
    """A worker's first act: its pid to the parent, then the pool's own initializer."""
    pids.put(os.getpid())
    initializer(*initargs)
