"""`crosscheck` command line. Subcommand names and JSON fields are a contract (docs/cli.md).

Bad input prints one line `crosscheck: error: ...` and exits with status 2, never a traceback.
Exit 1 means only "a check failed"; Ctrl-C prints one line and exits 130; an unexpected
exception (a bug) prints its traceback and exits 3; a sweep stopped by its time budget with
nothing failed exits 4 (incomplete, not passed).
"""

from __future__ import annotations

import argparse
import errno
import gc
import os
import re
import sys

# Only the standard library at import time: the models and engines (numpy, sympy, seconds to
# import) load inside main(), where a Ctrl-C is answered with one line, not a traceback.
from crosscheck.commands.arguments import OneLineParser
from crosscheck.runtime import interrupts  # standard library only

EXIT_USAGE = 2
EXIT_INTERNAL = 3  # an unexpected exception: a bug, never to be read as "a check failed" (1)
EXIT_INCOMPLETE = 4  # a campaign stopped by its time budget: nothing failed, not all was run
EXIT_INTERRUPTED = 130  # 128 + SIGINT, the shell's convention for Ctrl-C
EXIT_TERMINATED = 143  # 128 + SIGTERM


# Every command, in the order `crosscheck --help` lists them: crosscheck.commands.<name> has
# register(subparsers), which adds the command's parser and the function it runs.
COMMANDS = ("models", "eval", "simulate", "run", "bench", "report", "gate", "sweep", "engines")
COMMANDS += ("sensitivity",)


def build_parser() -> argparse.ArgumentParser:
    from importlib import import_module

    p = OneLineParser(
        prog="crosscheck",
        description="Textbook multiplier formulations cross-checked against the registered "
        "engines (Pinocchio, MuJoCo, Exudyn, OpenSim)",
    )
    sub = p.add_subparsers(dest="command", required=True)
    for name in COMMANDS:
        import_module(f"crosscheck.commands.{name}").register(sub)
    return p


# A value that starts with a minus sign: a number or a comma-separated list of numbers
# ("-0.5,0.2", "-1e-3"). argparse takes any such token after an option for another option
# unless it is a single plain negative number, so `--q -0.5,0.2` would fail.
_NEGATIVE_VALUE = re.compile(r"^-(\d|\.\d|inf|nan)", re.IGNORECASE)


def attach_negative_values(argv: list[str]) -> list[str]:
    """`--q -0.5,0.2` -> `--q=-0.5,0.2`, so users can type negative coordinates, speeds and
    parameters the natural way. No option of the CLI takes a value that starts with "-" for
    another purpose, and a flag followed by such a token is refused by argparse either way."""
    out: list[str] = []
    i = 0
    while i < len(argv):
        tok = argv[i]
        nxt = argv[i + 1] if i + 1 < len(argv) else ""
        if tok.startswith("--") and "=" not in tok and _NEGATIVE_VALUE.match(nxt):
            out.append(f"{tok}={nxt}")
            i += 2
            continue
        out.append(tok)
        i += 1
    return out


# The suite's matrices are small (at most a few hundred rows): a second BLAS thread only adds
# synchronization, and on a loaded 2-core machine it waits for a core. Measured: an SVD of the
# 40-cell four-bar's 120 x 81 constraint Jacobian takes 0.8 ms with one thread and 81 ms with
# numpy's default two while other jobs run (benchmarks/run_time.md). Set before numpy loads; a
# user's setting wins.
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def one_blas_thread() -> None:
    for var in BLAS_THREAD_VARIABLES:
        os.environ.setdefault(var, "1")


# No command renders with MuJoCo, whose import otherwise loads its OpenGL context code and
# with it the glfw package, which starts a Python subprocess to ask the GLFW library for its
# version: 0.05 s of each process that imports MuJoCo (this one and the workers' server,
# whose imports the first models wait for; benchmarks/run_time.md). Set before MuJoCo loads; a
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
    if entry and code in (EXIT_INTERRUPTED, EXIT_TERMINATED):
        # CPython ends a program by SIGINT (status -2, not 130) when an interrupt passed through
        # code it ran with PyRun_* (some extensions' imports), even one handled here: leave with
        # the status the command promises. The command has stopped its workers and written
        # nothing; what atexit would run has nothing left to do.
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):  # a closed pipe
                pass
        os._exit(code)
    if entry:
        code = _flush_stdout(code)
        # The collections of the interpreter's teardown walk every object the models and
        # engines created: 0.4 s after a run. Frozen objects are skipped (the files are written
        # and closed; the OS takes the memory back): 0.1 s.
        gc.freeze()
    return code


def _flush_stdout(code: int) -> int:
    """What the command printed reaches its destination now, or one line says why not (a full
    disk: `crosscheck models > /dev/full`), exit 2; the interpreter's own flush at exit then has
    nothing left to fail on."""
    try:
        sys.stdout.flush()
    except BrokenPipeError:  # `crosscheck models | head`: the reader has what it wanted
        _discard_stdout()
    except OSError as exc:
        _discard_stdout()
        print(f"crosscheck: error: {_cannot_write(exc)}", file=sys.stderr)
        return EXIT_USAGE
    return code


def _discard_stdout() -> None:
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    os.close(devnull)


# errors of the storage written to, not of the command: one line, exit 2
WRITE_ERRORS = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EIO, errno.EROFS)


def _cannot_write(exc: OSError) -> str:
    where = f" {exc.filename}" if exc.filename else " the output"
    return (
        f"cannot write{where}: {exc.strerror or exc}; free space or choose another place "
        "(the command's files are renamed into place only once all are written)"
    )


def _main(argv) -> int:
    args = None
    try:
        from reference.errors import ModelInputError

        argv = list(sys.argv[1:] if argv is None else argv)
        if argv[:1] == ["run"]:  # its workers' server starts before the imports below
            from crosscheck.commands.run import start_workers_early

            start_workers_early(argv[1:])
        parser = build_parser()
        args = parser.parse_args(attach_negative_values(argv))
        try:
            if hasattr(args, "model_file"):  # before any model name is resolved
                from crosscheck.commands.arguments import load_model_files

                load_model_files(args)
            code = int(args.func(args) or 0)
            if code in (EXIT_INTERRUPTED, EXIT_TERMINATED):  # it wrote what it kept, and said so
                return code
            interrupts.check()  # an interrupt an engine swallowed is not a finished command
            return code
        except ModelInputError as exc:
            print(f"crosscheck: error: {exc}", file=sys.stderr)
            return EXIT_USAGE
    except KeyboardInterrupt:
        return _interrupted(args)
    except BrokenPipeError:  # pragma: no cover - `crosscheck models | head`
        return 0
    except OSError as exc:
        if exc.errno not in WRITE_ERRORS:
            return _internal_error(args)
        print(f"crosscheck: error: {_cannot_write(exc)}", file=sys.stderr)
        return EXIT_USAGE
    except Exception:
        return _internal_error(args)


def _internal_error(args) -> int:
    """An unexpected exception (a bug): its traceback and one line saying so, exit 3."""
    # a Ctrl-C inside a C extension's import surfaces as that import's error
    # ("ImportError: initialization failed" from MuJoCo): still an interrupt
    if interrupts.seen():
        return _interrupted(args)
    import traceback

    traceback.print_exc()
    print(
        "crosscheck: internal error (a bug, not a failed check; the traceback above says where)",
        file=sys.stderr,
    )
    return EXIT_INTERNAL


def _interrupted(args) -> int:
    what = "terminated (SIGTERM)" if interrupts.terminated() else "interrupted"
    print(
        f"crosscheck: {what}; no new output written (a command's files are renamed "
        f"into place only once all are complete){_out_note(args)}",
        file=sys.stderr,
    )
    return EXIT_TERMINATED if interrupts.terminated() else EXIT_INTERRUPTED


def _out_note(args) -> str:
    out = getattr(args, "out", None)
    return f"; {out} holds what it held before" if out else ""


if __name__ == "__main__":
    sys.exit(main())
