"""`crosscheck run` starts its workers' server before it imports the models and engines
(crosscheck/commands/run.py start_workers_early): only where the run will hand models to
workers, and from a module that stays light."""

from __future__ import annotations

import os
import subprocess
import uuid

import pytest

# whether the workers' server started: a child of this process running multiprocessing's
# forkserver (read from /proc, so no private attribute of multiprocessing is relied on)
PROBE = """
import os, sys, time
WAIT_S = 1.0
from crosscheck.commands.run import start_workers_early
start_workers_early(sys.argv[1:])
def children():
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    ppid = int(f.read().rsplit(")", 1)[1].split()[1])
                with open(f"/proc/{entry}/cmdline", "rb") as f:
                    cmd = f.read()
            except OSError:
                continue
            if ppid == os.getpid():
                yield cmd
# a forked child shows its parent's command line until it has exec'd the server: look again
# for up to WAIT_S before calling it absent
deadline = time.monotonic() + WAIT_S
while not (found := any(b"multiprocessing.forkserver" in c for c in children())):
    if time.monotonic() > deadline:
        break
    time.sleep(0.02)
print(found)
"""


def _started(child, *argv: str) -> tuple[bool, str]:
    """Whether the server started, and what the process (and the server) printed to stderr."""
    out = child.python(PROBE, *argv, check=True)
    return out.stdout.strip() == "True", out.stderr


@pytest.mark.parametrize(
    "argv",
    [
        ("--jobs", "2"),  # every built-in model
        ("pendulum_angle", "pendulum_xy", "--jobs", "2", "--engines", "pinocchio"),
        ("--jobs=2", "--t-end", "0.5", "--engines", "mujoco", "--no-report"),
    ],
)
def test_a_run_on_workers_starts_the_server_early(argv, child):
    assert _started(child, *argv)[0]


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
        ("no_such_model", "pendulum_xy", "--jobs", "2"),  # refused: no server to leave behind
        ("pendulum_xy", "pendulum_angle", "--jobs", "2", "--engines", "no_such_engine"),
    ],
)
def test_no_early_server_where_it_is_not_needed_or_the_input_is_bad(argv, child):
    started, stderr = _started(child, *argv)
    assert not started
    assert not stderr  # nothing printed here: the full parser reports bad input


def test_the_command_module_imports_no_numerics(child):
    """What the command line imports before the early start: sympy and numpy (1.2 s with the
    models) would delay the server by as much."""
    code = (
        "import sys, crosscheck.cli, crosscheck.commands.run; "
        "print(sorted(m for m in ('numpy', 'sympy', 'scipy', 'reference.numeric.model') "
        "if m in sys.modules))"
    )
    out = child.python(code, check=True)
    assert out.stdout.strip() == "[]"


def test_resolving_the_engines_leaves_scipy_integrate_to_the_workers(child):
    """The command line imports the adapters of the engines it checks the names of; the
    trajectories' scipy.integrate (a second of imports) loads in the workers' server."""
    from crosscheck.run.jobs import WORKER_MODULES

    code = (
        "import sys; from crosscheck.commands.arguments import resolve_engines; "
        "resolve_engines(None); "
        "print('scipy.integrate' in sys.modules)"
    )
    out = child.python(code, check=True)
    assert out.stdout.strip() == "False"
    assert "crosscheck.checks.trajectory.check" in WORKER_MODULES


def _servers_with(marker: str) -> list[int]:
    """The workers' servers (multiprocessing's forkserver) whose environment holds `marker`.
    multiprocessing's resource tracker, started with the server, ends on its own as soon as
    the command has (it reads the command's end from a pipe) and is not looked for."""
    found = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/environ", "rb") as f:
                ours = marker.encode() in f.read()
            with open(f"/proc/{entry}/cmdline", "rb") as f:
                server = b"multiprocessing.forkserver" in f.read()
        except OSError:  # ended meanwhile, or not ours to read
            continue
        if ours and server:
            found.append(int(entry))
    return found


@pytest.mark.skipif(not os.path.isdir("/proc"), reason="reads processes from /proc (Linux)")
def test_a_run_refused_for_a_bad_name_leaves_no_server(tmp_path, child):
    """An unknown model among several ends the command with exit 2 before the server starts:
    no server is left importing the engines with the command's output pipe open."""
    marker = f"CROSSCHECK_TEST_MARK={uuid.uuid4().hex}"
    env = dict([marker.split("=")])
    argv = ["run", "no_such_model", "pendulum_xy", "--jobs", "2", "--out", tmp_path]
    log = tmp_path / "stderr.txt"
    with open(log, "w") as stderr:  # a file, not a pipe: the run returns at the command's exit
        proc = child.crosscheck(*argv, stdout=subprocess.DEVNULL, stderr=stderr, env=env)
    left = _servers_with(marker)
    assert proc.returncode == 2, log.read_text()
    assert "unknown model 'no_such_model'" in log.read_text()
    assert left == []
