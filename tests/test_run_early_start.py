"""`crosscheck run` starts its workers' server before it imports the models and engines
(crosscheck/run_command.py start_workers_early): only where the run will hand models to
workers, and from a module that stays light."""

from __future__ import annotations

import subprocess
import sys

import pytest

# multiprocessing's forkserver keeps its process id in this private attribute: the one
# place that says whether the server was started in a process
PROBE = """
import sys
from multiprocessing import forkserver
from crosscheck.run_command import start_workers_early
start_workers_early(sys.argv[1:])
print(forkserver._forkserver._forkserver_pid is not None)
"""


def _started(*argv: str) -> tuple[bool, str]:
    """Whether the server started, and what the process (and the server) printed to stderr."""
    out = subprocess.run(
        [sys.executable, "-c", PROBE, *argv], capture_output=True, text=True, check=True
    )
    return out.stdout.strip() == "True", out.stderr


@pytest.mark.parametrize(
    "argv",
    [
        ("--jobs", "2"),  # every built-in model
        ("pendulum_angle", "pendulum_xy", "--jobs", "2", "--engines", "pinocchio"),
        ("--jobs=2", "--t-end", "0.5", "--engines", "mujoco", "--no-report"),
    ],
)
def test_a_run_on_workers_starts_the_server_early(argv):
    assert _started(*argv)[0]


@pytest.mark.parametrize(
    "argv",
    [
        ("pendulum_angle",),  # one model: run in this process
        ("pendulum_angle", "pendulum_angle"),  # the same one twice (refused later)
        ("--jobs", "1"),
        ("--model-file", "models.py"),  # how many models is not known before loading it
        ("--help",),
        ("--jobs", "zero"),  # refused by the full parser, which says so
        ("--t-end", "-1"),
    ],
)
def test_no_early_server_where_it_is_not_needed_or_the_input_is_bad(argv):
    started, stderr = _started(*argv)
    assert not started
    assert not stderr  # nothing printed here: the full parser reports bad input


def test_the_command_module_imports_no_numerics():
    """What the command line imports before the early start: sympy and numpy (1.2 s with the
    models) would delay the server by as much."""
    code = (
        "import sys, crosscheck.cli, crosscheck.run_command; "
        "print(sorted(m for m in ('numpy', 'sympy', 'scipy', 'reference.numeric') "
        "if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_resolving_the_engines_leaves_scipy_integrate_to_the_workers():
    """The command line imports the adapters of the engines it checks the names of; the
    trajectories' scipy.integrate (a second of imports) loads in the workers' server."""
    from crosscheck.run_jobs import WORKER_MODULES

    code = (
        "import sys; from crosscheck.arguments import resolve_engines; resolve_engines(None); "
        "print('scipy.integrate' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
    assert "crosscheck.trajectory" in WORKER_MODULES
