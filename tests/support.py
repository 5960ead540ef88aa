"""What several test modules share: child processes, consistent states, the error metric.

Child processes go through `Child` (the `child` fixture of conftest.py), so every test that
starts one is in the `subprocess` tier; a test module that calls `subprocess` itself is refused
by tests/test_tiers.py.
"""

from __future__ import annotations

import contextlib
import io
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from crosscheck.checks.sampling import consistent_states
from crosscheck.checks.tolerances import scaled_error

ROOT = Path(__file__).resolve().parents[1]

__all__ = [
    "ROOT",
    "Child",
    "Outcome",
    "cli",
    "representative",
    "run_browser",
    "scaled_error",
    "state",
    "states",
]


@dataclass(frozen=True)
class Outcome:
    """What a command gave: its exit status and what it printed."""

    returncode: int
    stdout: str
    stderr: str


def cli(*argv) -> Outcome:
    """A `crosscheck` command run in this process (crosscheck.cli.main), its output captured:
    what the program does but the interpreter's start and exit, which the subprocess tier
    checks."""
    from crosscheck.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in argv])
    return Outcome(code, out.getvalue(), err.getvalue())


class Child:
    """Runs Python in a child process with this checkout first on PYTHONPATH, in the test's own
    directory, with text output captured. `env` entries are added to (None: removed from) this
    process's environment."""

    def __init__(self, cwd: Path):
        self.cwd = cwd

    def _env(self, env: dict | None) -> dict:
        out = dict(os.environ)
        out["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), out.get("PYTHONPATH")) if p)
        for key, value in (env or {}).items():
            if value is None:
                out.pop(key, None)
            else:
                out[key] = str(value)
        return out

    def run(self, *argv, env=None, timeout: float = 600, cwd=None, **kw):
        """`python *argv` to its end: a CompletedProcess (returncode, stdout, stderr)."""
        kw.setdefault("capture_output", "stdout" not in kw and "stderr" not in kw)
        return subprocess.run(
            [sys.executable, *map(str, argv)],
            env=self._env(env),
            cwd=cwd or self.cwd,
            text=True,
            timeout=timeout,
            **kw,
        )

    def program(self, *argv, env=None, timeout: float = 600, cwd=None, **kw):
        """Any program (`argv[0]`: bash, git...) to its end, with the same environment."""
        kw.setdefault("capture_output", "stdout" not in kw and "stderr" not in kw)
        return subprocess.run(
            [str(a) for a in argv],
            env=self._env(env),
            cwd=cwd or self.cwd,
            text=True,
            timeout=timeout,
            **kw,
        )

    def crosscheck(self, *args, **kw):
        """The `crosscheck` program with `args`, to its end."""
        return self.run("-m", "crosscheck", *args, **kw)

    def python(self, code: str, *args, **kw):
        """`python -c code *args`, to its end."""
        return self.run("-c", code, *args, **kw)

    def start(self, *argv, env=None, cwd=None, **kw) -> subprocess.Popen:
        """`python *argv`, running: a Popen to use as a context manager (its pipes closed
        whatever the test's outcome)."""
        kw.setdefault("stdout", subprocess.PIPE)
        kw.setdefault("stderr", subprocess.PIPE)
        return subprocess.Popen(
            [sys.executable, *map(str, argv)],
            env=self._env(env),
            cwd=cwd or self.cwd,
            text=True,
            **kw,
        )


def run_browser(argv: list, timeout: float = 180) -> subprocess.CompletedProcess:
    """The browser (argv[0], the `chromium` fixture's path) to its end, output captured."""
    return subprocess.run([str(a) for a in argv], capture_output=True, text=True, timeout=timeout)


def states(nm, n: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """`n` seeded consistent states of a numeric model, the ones `crosscheck run` checks at."""
    return consistent_states(nm, n)


def state(nm) -> tuple[np.ndarray, np.ndarray]:
    """The first of those states."""
    return consistent_states(nm, 1)[0]


def representative(cases, keep, key=lambda c: c):
    """`cases` as pytest params, those whose key is not in `keep` in the slow tier: a
    parametrization over every model or engine runs its representative cases in the quick
    tier and the rest in the full run."""
    return [
        case if key(case) in keep else pytest.param(*_values(case), marks=pytest.mark.slow)
        for case in cases
    ]


def _values(case):
    return case if isinstance(case, tuple) else (case,)
