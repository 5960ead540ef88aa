"""Where a `crosscheck run` on workers spends its wall time, as seen from its own process: when
the hand-out starts (the parent's imports done), when the meta work (results.json's versions)
starts and ends, when the last model is back, and when results.json is written. The models'
own times are in `<cache dir>/run_times.json` after the run (crosscheck/run/order.py).

The program's entry (crosscheck.cli.main) runs unchanged, with timestamps around three of its
functions; run it in a warm cache, on a machine otherwise idle:

    CROSSCHECK_CACHE_DIR=<warm> python benchmarks/run_phases.py -- \
        --engines pinocchio,mujoco --out /tmp/phases --no-report
"""

from __future__ import annotations

import sys
import time

T0 = time.perf_counter()


def _stamp(what: str) -> None:
    print(f"{time.perf_counter() - T0:6.2f} s  {what}", file=sys.stderr)


def _instrument() -> None:
    from crosscheck.commands import run as run_command
    from crosscheck.run import jobs as run_jobs

    run_models = run_jobs.run_models

    def timed_run_models(*args, **kwargs):
        _stamp("hand-out starts (this process's imports done)")
        work = kwargs.get("meanwhile")
        if work is not None:

            def timed_work():
                _stamp("meta work starts")
                work()
                _stamp("meta work ends")

            kwargs["meanwhile"] = timed_work
        out = run_models(*args, **kwargs)
        _stamp("last model back")
        return out

    write = run_command._write_outputs

    def timed_write(*args, **kwargs):
        write(*args, **kwargs)
        _stamp("results written")

    run_jobs.run_models = timed_run_models
    run_command._write_outputs = timed_write


def main() -> None:
    argv = sys.argv[1:]
    if argv[:1] == ["--"]:
        argv = argv[1:]
    _instrument()
    sys.argv = ["crosscheck", "run", *argv]  # the program's own entry: its environment too
    from crosscheck.cli import main as crosscheck_main

    crosscheck_main()


if __name__ == "__main__":  # the workers' server imports nothing from here
    main()
