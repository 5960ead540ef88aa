"""`crosscheck run --jobs N`: the models of a run on N local worker processes.

A model's checks need nothing from another model's (its consistent states are seeded by its own
name, crosscheck.checks.sampling), so each model is one piece of work: a worker runs
crosscheck.run.checks.run on it, and the parent puts the records, series and agreement matrices back
in the models' order. results.json is the serial run's, record for record (tests/test_run_jobs.py).

Faults keep the serial run's meaning: bad input in several models reports the first model's, as
a serial run would meet it; a worker that dies (an engine crashing) is an error naming the
models it may have been checking, never a silently shorter results.json. Ctrl-C reaches the
parent (workers ignore SIGINT), which stops the workers at once: one line, exit 130.
"""

from __future__ import annotations

import argparse
import os
import threading
import time
import traceback
from concurrent.futures import FIRST_COMPLETED, Future, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field

from crosscheck.run.order import hand_out_order, known_times, remember_times, setting_key
from crosscheck.runtime import interrupts
from crosscheck.runtime.workers import WorkerPool, process_context, start_worker
from reference.errors import ModelInputError

# what the workers' server imports before forking them: this module and the checks it runs
# (the trajectories' with scipy.integrate, which the engines' modules leave to their first use)
WORKER_MODULES = (
    "crosscheck.run.jobs",
    "crosscheck.run.checks",
    "crosscheck.checks.trajectory.check",
)
SETTINGS = "CROSSCHECK_"  # the environment variables that are the suite's settings


def _settings() -> tuple[tuple[str, str], ...]:
    return tuple(sorted((k, v) for k, v in os.environ.items() if k.startswith(SETTINGS)))


@dataclass(frozen=True)
class ModelJob:
    """One model of a run, as crosscheck.run.checks.run takes it."""

    name: str
    engines: tuple[str, ...]
    n_states: int
    perturb: dict
    trajectories: bool
    t_end: float
    derivatives: bool = False  # the derivatives records (crosscheck.checks.derivatives)
    # the parent's CROSSCHECK_* settings when the job was made: the workers' server keeps the
    # environment it was started with, and a caller in one process may have changed it since
    settings: tuple[tuple[str, str], ...] = field(default_factory=_settings)

    @property
    def setting(self) -> str:
        """What the model's time depends on besides the model (run_order)."""
        key = setting_key(self.engines, self.n_states, self.trajectories, self.t_end)
        return key + (" | derivatives" if self.derivatives else "")


class WorkerError(RuntimeError):
    """A worker's internal error (a bug, not a failed check), with the worker's traceback."""


def _start_worker(parent: int, model_files: tuple[str, ...], loading: tuple = ()) -> None:
    """workers.start_worker, then register the user's models (their files, the
    `crosscheck.models` entry points) as the parent did, loaded the same way (``loading``:
    the --project flag and the --ctrl pairs): a worker is a fresh process."""
    start_worker(parent)
    from crosscheck.commands.arguments import load_model_files

    project, ctrl = loading or (False, ())
    load_model_files(
        argparse.Namespace(model_file=list(model_files), project=project, ctrl=list(ctrl))
    )


def run_model(job: ModelJob) -> tuple:
    """("ok", records, series, agreement, seconds), ("input", message) or ("internal",
    traceback). Errors travel as text: an exception class with its own constructor arguments
    does not survive pickling back to the parent."""
    from crosscheck.run.checks import run

    start = time.perf_counter()
    for key in [k for k in os.environ if k.startswith(SETTINGS)]:
        del os.environ[key]
    os.environ.update(job.settings)
    try:
        agreement: list = []
        records, series = run(
            [job.name],
            list(job.engines),
            job.n_states,
            job.perturb,
            trajectories=job.trajectories,
            t_end=job.t_end,
            agreement=agreement,
            derivatives=job.derivatives,
        )
        return ("ok", records, series, agreement, time.perf_counter() - start)
    except ModelInputError as exc:
        return ("input", str(exc))
    except Exception:
        return ("internal", traceback.format_exc())


def run_models(
    jobs: list[ModelJob],
    workers: int,
    model_files: tuple[str, ...] = (),
    progress=None,
    agreement: list | None = None,
    meanwhile=None,
    loading: tuple = (),
) -> tuple[list, list]:
    """run() over `jobs` on `workers` processes: (records, series) in the jobs' order;
    ``agreement`` receives the matrices as run() gives them; ``progress(name)`` is called as
    each model completes; ``meanwhile()`` runs while the models are handed out (_Meanwhile),
    its exception raised here; ``loading`` is how the workers load ``model_files``
    (--project, the --ctrl pairs). Models go out longest first (run_order)."""
    outcomes: dict[int, tuple] = {}
    setting = jobs[0].setting if jobs else ""
    order = hand_out_order([j.name for j in jobs], known_times(setting))
    ex = WorkerPool(
        workers,
        process_context(*WORKER_MODULES, engines=jobs[0].engines if jobs else None),
        _start_worker,
        (os.getpid(), tuple(model_files), tuple(loading)),
    )
    side = _Meanwhile(meanwhile) if meanwhile is not None else None
    try:
        with interrupts.deferred():  # the first submit starts every worker (forkserver)
            futures: dict[Future, int] = {ex.submit(run_model, jobs[i]): i for i in order}
        if side is not None:
            side.join()
        first_fault = len(jobs)
        while not all(i in outcomes for i in range(first_fault)):
            done, _ = wait(list(futures), return_when=FIRST_COMPLETED)
            for fut in done:
                i = futures.pop(fut)
                outcomes[i] = _outcome(fut, jobs, futures.values(), i)
                if outcomes[i][0] != "ok":
                    first_fault = min(first_fault, i)
                    for later, k in futures.items():  # a serial run would not reach them
                        if k > i:
                            later.cancel()
                elif progress:
                    progress(jobs[i].name)
            futures = {f: k for f, k in futures.items() if k < first_fault}
    except BaseException:
        ex.stop()  # Ctrl-C: no waiting for the models in flight
        raise
    if first_fault < len(jobs):
        ex.stop()  # a later model still computing is not waited for
        _raise(outcomes[first_fault], jobs[first_fault].name)
    ex.shutdown()
    remember_times(setting, {jobs[i].name: outcomes[i][4] for i in range(len(jobs))})
    records: list = []
    series: list = []
    for i in range(len(jobs)):
        _, recs, ser, agr, _seconds = outcomes[i]
        records += recs
        series += ser
        if agreement is not None:
            agreement += agr
    return records, series


class _Meanwhile:
    """`work()` on a thread of its own from before the hand-out: the first submit waits for
    the workers' server to finish its imports (about 1 s after this process has finished its
    own; benchmarks/run_time.md), and `work` runs in that wait on the core the workers do not use
    yet, not beside them. A daemon thread: Ctrl-C does not wait for it."""

    def __init__(self, work):
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, args=(work,), daemon=True)
        self._thread.start()

    def _run(self, work) -> None:
        try:
            work()
        except BaseException as exc:  # raised in the caller's thread by join
            self._error = exc

    def join(self) -> None:
        self._thread.join()
        if self._error is not None:
            raise self._error


def _outcome(fut: Future, jobs: list[ModelJob], in_flight, i: int) -> tuple:
    try:
        return fut.result()
    except BrokenProcessPool:
        names = sorted({jobs[i].name, *(jobs[k].name for k in in_flight)})
        return (
            "died",
            "a worker process ended abruptly (an engine crashed, or the machine ran out of "
            f"memory) while checking one of: {', '.join(names)}; run one of them with "
            "--jobs 1 to see where",
        )


def _raise(outcome: tuple, name: str):
    kind, text = outcome
    if kind == "input":
        raise ModelInputError(text)
    if kind == "died":
        raise WorkerError(text)
    raise WorkerError(f"in the worker checking {name}:\n{text}")
