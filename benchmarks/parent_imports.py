"""What `crosscheck run` does in its own process before it hands the models to the workers, by
phase, in a fresh interpreter: the command line's parser (it imports every command's module),
the model names, the engine names (importing the named engines' adapters) and the checks'
module. The workers' server starts before all of it (crosscheck/commands/run.py), so the
first models start when both this and the server's own imports are done
(benchmarks/run_time.md, "Before the first model").

    python benchmarks/parent_imports.py --engines pinocchio,mujoco
    python benchmarks/parent_imports.py            # every engine
"""

from __future__ import annotations

import argparse
import sys
import time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--engines", default=None, help="comma-separated, as crosscheck run takes")
    args = ap.parse_args()
    t0 = time.perf_counter()
    from crosscheck.cli import build_parser

    build_parser()
    t1 = time.perf_counter()
    from crosscheck.commands.arguments import resolve_engines, resolve_models

    resolve_models([], None)
    t2 = time.perf_counter()
    resolve_engines(args.engines.split(",") if args.engines else None)
    t3 = time.perf_counter()
    import crosscheck.run.checks  # noqa: F401 - what the serial path would import

    t4 = time.perf_counter()
    print(
        f"parser {t1 - t0:.2f} s, models {t2 - t1:.2f} s, engines {t3 - t2:.2f} s, "
        f"checks {t4 - t3:.2f} s: {t4 - t0:.2f} s in all; scipy.integrate loaded: "
        f"{'scipy.integrate' in sys.modules}"
    )


if __name__ == "__main__":
    main()
