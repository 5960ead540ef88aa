"""`crosscheck` command line. Subcommand names and JSON fields are a contract (see README).

Bad input prints one line `crosscheck: error: ...` and exits with status 2, never a traceback.
Exit 1 means only "a check failed"; Ctrl-C prints one line and exits 130; an unexpected
exception (a bug) prints its traceback and exits 3; a sweep stopped by its time budget with
nothing failed exits 4 (incomplete, not passed).
"""

from __future__ import annotations

import argparse
import atexit
import math
import os
import re
import sys

# Only the standard library at import time: the models and engines (numpy, sympy, seconds to
# import) load inside main(), where a Ctrl-C is answered with one line, not a traceback.
from crosscheck.commands.arguments import OneLineParser, add_model_files, finite_float
from crosscheck.runtime import (
    interrupts,  # standard library only
    jsonio,
)

EXIT_USAGE = 2
EXIT_INTERNAL = 3  # an unexpected exception: a bug, never to be read as "a check failed" (1)
EXIT_INCOMPLETE = 4  # a campaign stopped by its time budget: nothing failed, not all was run
EXIT_INTERRUPTED = 130  # 128 + SIGINT, the shell's convention for Ctrl-C


def UsageError(message: str) -> Exception:
    """Bad command-line input: a ModelInputError, printed as one line with exit status 2."""
    from reference.errors import ModelInputError

    return ModelInputError(message)


def _floats(text: str | None, what: str) -> list[float] | None:
    if text is None:
        return None
    out = []
    for item in text.split(","):
        item = item.strip()
        if not item:
            continue
        try:
            out.append(float(item))
        except ValueError:
            raise UsageError(
                f"{what}: {item!r} is not a number (give comma-separated values)"
            ) from None
    return out


def _assignments(pairs: list[str]) -> dict[str, float]:
    out = {}
    for pair in pairs or []:
        if "=" not in pair:
            raise UsageError(f"--set {pair!r}: expected NAME=VALUE")
        name, value = pair.split("=", 1)
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise UsageError(f"--set {pair!r}: {value!r} is not a number") from None
    return out


_json_default = jsonio.default


def dump_json(obj) -> str:
    return jsonio.dumps(obj, allow_nan=False)


# ---- models ------------------------------------------------------------------------------
def describe_model(model) -> dict:
    from reference.constraints import classify

    return {
        "name": model.name,
        "source": model.source,
        "title": model.title,
        "coordinates": [s.name for s in model.coordinates],
        "speeds": [s.name for s in model.speeds],
        "parameters": {p.name: p.default for p in model.parameters},
        "parameter_units": {p.name: p.unit for p in model.parameters},
        "constraints": classify(model),
        "formulations": list(model.formulations),
        "multiplier_meaning": model.multiplier_meaning,
        "geometry_note": model.geometry_note,
        "initial_state": {"q": list(model.initial_q), "u": list(model.initial_u)},
    }


def cmd_models(args) -> int:
    from reference import models

    described = [
        {**describe_model(models.get(n)), "origin": models.origin(n)}
        for n in [*models.names(), *models.user_names()]
    ]
    if args.json:
        print(dump_json(described))
        return 0
    rows = [("name", "origin", "source", "q", "u", "constraints", "formulations")]
    for d in described:
        rows.append(
            (
                d["name"],
                d["origin"],
                d["source"],
                ",".join(d["coordinates"]),
                str(len(d["speeds"])),
                str(len(d["constraints"])),
                ",".join(d["formulations"]),
            )
        )
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    for r in rows:
        print("  ".join(c.ljust(w) for c, w in zip(r, widths, strict=False)).rstrip())
    return 0


# ---- eval --------------------------------------------------------------------------------
def cmd_eval(args) -> int:
    import numpy as np

    from reference import NumericModel, models

    model = models.get(args.name)
    nm = NumericModel(model, args.formulation, _assignments(args.set))
    q = _floats(args.q, "--q")
    u = _floats(args.u, "--u")
    q = list(model.initial_q) if q is None else q
    u = list(model.initial_u) if u is None else u
    if not math.isfinite(args.t):
        raise UsageError("--t must be finite")
    if args.project:
        q, u = nm.project(q, u, args.t)
    else:
        nm.check_consistent(q, u, args.t)
    res = nm.forward(q, u, args.t)
    pos, vel = nm.residuals(q, u, args.t)
    K, V = nm.energy(q, u, args.t)
    out = {
        "model": model.name,
        "source": model.source,
        "formulation": nm.formulation,
        "parameters": nm.params,
        "t": args.t,
        "q": np.asarray(q, float),
        "u": np.asarray(u, float),
        "coordinates": [s.name for s in model.coordinates],
        "speeds": [s.name for s in model.speeds],
        "accelerations": res.accelerations,
        "multipliers": res.multipliers,
        "constraint_names": list(model.constraint_names),
        "multiplier_meaning": model.multiplier_meaning,
        "coordinate_rates": nm.kinematics(q, u, args.t),
        "residuals": {"position": pos, "velocity": vel},
        "energy": {"kinetic": K, "potential": V, "total": K + V},
        "pivot_ratio": res.pivot_ratio,
    }
    if args.json:
        print(dump_json(out))
    else:
        print(f"{model.name} ({model.source}), {nm.formulation}, t = {args.t}")
        for s, a in zip(out["speeds"], res.accelerations, strict=False):
            print(f"  d({s})/dt = {a:.12g}")
        for name, lam in zip(model.constraint_names or [], res.multipliers, strict=False):
            print(f"  lambda[{name}] = {lam:.12g}")
        print(
            f"  residuals: position {np.abs(pos).max() if pos.size else 0:.2e}, "
            f"velocity {np.abs(vel).max() if vel.size else 0:.2e}"
        )
    return 0


# ---- parser ------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(
        prog="crosscheck",
        description="Textbook multiplier formulations cross-checked against Pinocchio and MuJoCo",
    )
    sub = p.add_subparsers(dest="command", required=True)

    m = sub.add_parser("models", help="list the models of the unit")
    m.add_argument("--json", action="store_true", help="machine-readable list")
    add_model_files(m)
    m.set_defaults(func=cmd_models)

    e = sub.add_parser("eval", help="accelerations and multipliers of a model at a state")
    e.add_argument("name", help="model name (see `crosscheck models`)")
    e.add_argument("--formulation", default=None, help="lagrange | dalembert | kane")
    e.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override a parameter (repeatable)",
    )
    e.add_argument("--q", help="coordinates, comma-separated (default: the model's initial state)")
    e.add_argument("--u", help="speeds, comma-separated (q-dots for Lagrange/d'Alembert models)")
    e.add_argument("--t", type=finite_float, default=0.0, help="time (rheonomic constraints)")
    e.add_argument(
        "--project",
        action="store_true",
        help="project the state onto the constraint manifold instead of refusing it",
    )
    e.add_argument("--json", action="store_true")
    add_model_files(e)
    e.set_defaults(func=cmd_eval)

    for register in _optional_commands():
        register(sub)
    add_model_files(sub.choices["report"])  # report's own module is being split; added here
    return p


def _optional_commands():
    """Subcommands that live in their own modules: each has a register(subparsers)."""
    from importlib import import_module

    return [
        import_module(f"crosscheck.commands.{name}").register
        for name in ("run", "bench", "report", "gate", "sweep", "engines", "sensitivity")
    ]


# A value that starts with a minus sign: a number or a comma-separated list of numbers
# ("-0.5,0.2", "-1e-3"). argparse takes any such token after an option for another option
# unless it is a single plain negative number, so `--q -0.5,0.2` would fail.
_NEGATIVE_VALUE = re.compile(r"^-(\d|\.\d|inf|nan)", re.IGNORECASE)


def _attach_negative_values(parser: argparse.ArgumentParser, argv: list[str]) -> list[str]:
    """`--q -0.5,0.2` -> `--q=-0.5,0.2` for every option that takes one value, so users can
    type negative coordinates, speeds and parameters the natural way."""
    takes_value = set()
    stack = [parser]
    while stack:
        p = stack.pop()
        for action in p._actions:
            if isinstance(action, argparse._SubParsersAction):
                stack.extend(action.choices.values())
            elif action.option_strings and action.nargs is None:
                takes_value.update(s for s in action.option_strings if s.startswith("--"))
    out: list[str] = []
    i = 0
    while i < len(argv):
        tok = argv[i]
        if tok in takes_value and i + 1 < len(argv) and _NEGATIVE_VALUE.match(argv[i + 1]):
            out.append(f"{tok}={argv[i + 1]}")
            i += 2
            continue
        out.append(tok)
        i += 1
    return out


# The suite's matrices are small (at most a few hundred rows): a second BLAS thread only adds
# synchronization, and on a loaded 2-core machine it waits for a core. Measured: one SVD of the
# 40-cell four-bar's 120 x 81 constraint Jacobian took 308 ms with numpy's default two threads
# and 8 ms with one (docs/numerics.md). Set before numpy loads; a user's setting wins.
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")  # not OMP: numba reads it


def one_blas_thread() -> None:
    for var in BLAS_THREAD_VARIABLES:
        os.environ.setdefault(var, "1")


# No command renders with MuJoCo, whose import otherwise loads its OpenGL context code and
# with it the glfw package, which starts a Python subprocess to ask the GLFW library for its
# version: 0.15-0.2 s of each process that imports MuJoCo (this one and the workers' server,
# whose imports the first models wait for; docs/compiled.md). Set before MuJoCo loads; a
# user's setting wins.
def no_mujoco_rendering() -> None:
    os.environ.setdefault("MUJOCO_GL", "disable")


def main(argv=None) -> int:
    entry = argv is None  # the `crosscheck` program itself, not a caller in this process
    if entry:
        interrupts.install()
        one_blas_thread()
        no_mujoco_rendering()
    code = _main(argv)
    if entry and (code == EXIT_INTERRUPTED or not (_running_threads() or _observed())):
        # CPython kills itself with SIGINT at exit (status -2, not 130) when the interrupt
        # passed through code run by PyRun_* (some extensions' imports), even though it was
        # handled here: leave with the status the command promises. And a finished command
        # has written and closed its files: the interpreter's teardown of every module it
        # imported (sympy, the engines) would add 0.4-1 s to each command's wall time
        # (docs/compiled.md, "The warm run's own overheads"), so it is skipped
        _leave(code)
    return code


def _running_threads() -> bool:
    """Whether a thread other than this one still works (a C build, an executor's worker):
    the interpreter's normal exit waits for those, os._exit would cut them off."""
    import threading

    main_thread = threading.main_thread()
    return any(t is not main_thread and not t.daemon for t in threading.enumerate())


def _observed() -> bool:
    """Whether a profiler or tracer watches this process (`python -m cProfile -m crosscheck`,
    coverage): it writes what it saw at the normal exit, which os._exit would skip."""
    return sys.getprofile() is not None or sys.gettrace() is not None


def _leave(code: int) -> None:
    """Exit at once with `code`, after what a normal exit runs first: the standard streams'
    buffers and the atexit functions (multiprocessing's finalizers release a worker pool's
    semaphores; without them its resource tracker warns of leaks)."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe (`crosscheck models | head`)
            pass
    atexit._run_exitfuncs()
    os._exit(code)


def _main(argv) -> int:
    args = None
    try:
        from reference.errors import ModelInputError

        argv = list(sys.argv[1:] if argv is None else argv)
        if argv[:1] == ["run"]:  # its workers' server starts before the imports below
            from crosscheck.commands.run import start_workers_early

            start_workers_early(argv[1:])
        parser = build_parser()
        args = parser.parse_args(_attach_negative_values(parser, argv))
        try:
            if hasattr(args, "model_file"):  # before any model name is resolved
                from crosscheck.commands.arguments import load_model_files

                load_model_files(args)
            code = int(args.func(args) or 0)
            interrupts.check()  # an interrupt an engine swallowed is not a finished command
            return code
        except ModelInputError as exc:
            print(f"crosscheck: error: {exc}", file=sys.stderr)
            _stop_workers_server()
            return EXIT_USAGE
    except KeyboardInterrupt:
        return _interrupted(args)
    except BrokenPipeError:  # pragma: no cover - `crosscheck models | head`
        return 0
    except Exception:
        # a Ctrl-C inside a C extension's import surfaces as that import's error
        # ("ImportError: initialization failed" from MuJoCo): still an interrupt
        if interrupts.seen():
            return _interrupted(args)
        import traceback

        traceback.print_exc()
        _stop_workers_server()
        print(
            "crosscheck: internal error (a bug, not a failed check; the traceback above "
            "says where)",
            file=sys.stderr,
        )
        return EXIT_INTERNAL


def _stop_workers_server() -> None:
    """A command that ends in an error or an interrupt hands nothing more to workers: the
    server `run` started (early, or for its workers) must not outlive it
    (crosscheck.runtime.workers.stop_server)."""
    if "multiprocessing.forkserver" in sys.modules:  # else no server was started
        from crosscheck.runtime.workers import stop_server

        stop_server()


def _interrupted(args) -> int:
    _stop_workers_server()
    print(
        f"crosscheck: interrupted; no new output written (a command's files are renamed "
        f"into place only once all are complete){_out_note(args)}",
        file=sys.stderr,
    )
    return EXIT_INTERRUPTED


def _out_note(args) -> str:
    out = getattr(args, "out", None)
    return f"; {out} holds what it held before" if out else ""


if __name__ == "__main__":
    sys.exit(main())
