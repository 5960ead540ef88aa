"""What several test modules share: child processes, consistent states, the error metric.

The metric is the suite's own, crosscheck.checks.tolerances.scaled_error (max |value -
reference| / max(max |reference|, 1)); `max_abs` is the largest magnitude, for absolute bounds.
Consistent states come from `states` (at a model's parameters) and `instances` (parameters and
times drawn as the sweeps draw them, then `states`).

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

from crosscheck.checks.sampling import T_RANGE, consistent_states, random_params
from crosscheck.checks.tolerances import scaled_error
from reference.errors import ModelInputError
from reference.integrate.driver import PROJECTION_TOL

ROOT = Path(__file__).resolve().parents[1]

__all__ = [
    "QUICK_MODELS",
    "ROOT",
    "Child",
    "Outcome",
    "cli",
    "instances",
    "max_abs",
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
        try:
            code = main([str(a) for a in argv])
        except SystemExit as exc:  # argparse's refusal of an option (exit 2), as the program
            code = exc.code if isinstance(exc.code, int) else 1
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


# A drawn state (a model without a state sampler): the initial coordinates plus this much
# normal noise (radians for angles, metres for positions: any pose, every branch of a closed
# loop, both of the slider-crank's), the initial speeds plus U_SPREAD; Gauss-Newton projects
# every such draw (60 per model with random parameters, none refused); a refused one, or one
# at a singular pose, is drawn again.
Q_SPREAD = 3.0
U_SPREAD = 3.0
DRAWS_PER_STATE = 20


def states(nm, n: int, seed=None, *, t: float = 0.0) -> list[tuple[np.ndarray, np.ndarray]]:
    """`n` consistent states of a numeric model.

    No seed: the seeded states `crosscheck run` checks at (the initial state first,
    crosscheck.checks.sampling.consistent_states). A seed (an int or a numpy Generator): `n`
    states at time `t` drawn from it, by the model's own state_sampler where it has one (it
    keeps away from the coordinates' singular poses; its states are checked consistent, not
    trusted), else around the initial state (Q_SPREAD, U_SPREAD), then projected onto the
    manifold to PROJECTION_TOL (1 + |q|), the integrators' few ulps: consistent to round-off,
    so an engine's map or energy is measured, not the projection's default stopping test
    (1e-13 (1 + |q|), which a map recomputing a dependent coordinate returns as its error)."""
    if seed is None:
        return consistent_states(nm, n)
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    m, out = nm.model, []
    for _ in range(n * DRAWS_PER_STATE):
        if len(out) == n:
            break
        if m.state_sampler is not None:
            q, u = m.state_sampler(rng, nm.params)
            nm.check_consistent(q, u, t)
        else:
            q = np.asarray(m.initial_q, float) + Q_SPREAD * rng.standard_normal(nm.nq)
            u = np.asarray(m.initial_u, float) + U_SPREAD * rng.standard_normal(nm.n)
        try:
            q, u = nm.project(q, u, t, tol=PROJECTION_TOL)
            nm.forward(q, u, t)  # a singular pose is drawn again, as the run's states are
        except ModelInputError:
            continue
        out.append((q, u))
    assert len(out) == n, f"{m.name}: {len(out)} of {n} draws projected"
    return out


def state(nm) -> tuple[np.ndarray, np.ndarray]:
    """The first of the run's states: the model's initial state, projected."""
    return consistent_states(nm, 1)[0]


def instances(nm, n: int, seed) -> list:
    """`n` instances (numeric model, t, q, u): parameters and time drawn as the sweeps draw
    them (crosscheck.checks.sampling.random_params: each positive parameter x U(0.8, 1.25),
    inertias physical; t in T_RANGE), the state by `states` at that time."""
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    out = []
    for _ in range(n):
        drawn = nm.with_params(random_params(nm.model, rng))
        t = float(rng.uniform(*T_RANGE))
        ((q, u),) = states(drawn, 1, rng, t=t)
        out.append((drawn, t, q, u))
    return out


def max_abs(x) -> float:
    """The largest magnitude of an array's entries (0 for an empty one): an absolute bound."""
    x = np.asarray(x, float)
    return float(np.max(np.abs(x))) if x.size else 0.0


# The models the quick tier runs every engine on: a closed planar loop, the 3-D double pendulum
# (3-1-3 angles, two engine variants in some engines), the top in Euler parameters (a
# formulation-dependent multiplier some engines do not model), the rheonomic pendulum and the
# nonholonomic knife edge. The full run takes every model.
QUICK_MODELS = frozenset(
    {"slider_crank", "double_pendulum_3d", "top_euler", "pendulum_moving_support", "knife_edge"}
)


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
