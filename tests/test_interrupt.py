"""Interrupted commands: one line, exit 130, and the output directory holds
the previous run's files, complete and consistent, or this run's, never a mix."""

from __future__ import annotations

import json
import os
import signal
import time
from pathlib import Path

import pytest

import crosscheck.report.write as report
from crosscheck.cli import main
from crosscheck.runtime.output import LEDGER, TMP_PREFIX
from crosscheck.sweep.store import chunk_files

ROOT = Path(__file__).resolve().parents[1]
RUN_FILES = [LEDGER, "index.html", "junit.xml", "report.md", "results.json"]


def _snapshot(d: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(d.iterdir())}


def _models_in(d: Path) -> set[str]:
    return {r["model"] for r in json.loads((d / "results.json").read_text())["records"]}


@pytest.fixture
def previous_run(tmp_path, capsys):
    """A completed run in tmp_path/out (instantaneous checks of one model: quick)."""
    out = tmp_path / "out"
    assert main(["run", "pendulum_angle", "--instantaneous", "--out", str(out)]) == 0
    capsys.readouterr()
    assert sorted(p.name for p in out.iterdir()) == RUN_FILES
    return out


def test_interrupt_during_report_keeps_the_previous_run(previous_run, monkeypatch, capsys):
    """Ctrl-C while the report is rendered: the new results.json must not land beside the old
    report (the bug: it did, and the stale report looked complete)."""
    before = _snapshot(previous_run)

    def ctrl_c(*_):
        raise KeyboardInterrupt

    monkeypatch.setattr(report, "render_junit", ctrl_c)  # the last file rendered
    code = main(["run", "slider_crank", "--instantaneous", "--out", str(previous_run)])
    err = capsys.readouterr().err
    assert code == 130
    assert err.count("\n") == 1 and "interrupted" in err and "Traceback" not in err
    assert _snapshot(previous_run) == before  # untouched, no temporary file left
    assert _models_in(previous_run) == {"pendulum_angle"}


def test_no_report_removes_the_stale_report(previous_run, capsys):
    """The report the suite wrote beside the old results is stale once new results land."""
    assert (
        main(["run", "slider_crank", "--instantaneous", "--no-report", "--out", str(previous_run)])
        == 0
    )
    capsys.readouterr()
    assert sorted(p.name for p in previous_run.iterdir()) == [LEDGER, "results.json"]
    assert _models_in(previous_run) == {"slider_crank"}


def test_no_report_never_removes_a_users_own_files(previous_run, capsys):
    """--out holds what the suite wrote and what the user put there: a report.md the user
    wrote (or edited) beside the results is not the suite's to remove."""
    (previous_run / "report.md").write_text("# my notes on this run\n")
    (previous_run / "index.html").unlink()
    (previous_run / "index.html").write_text("<p>my own page</p>")
    args = ["run", "slider_crank", "--instantaneous", "--no-report", "--out", str(previous_run)]
    assert main(args) == 0
    capsys.readouterr()
    assert (previous_run / "report.md").read_text() == "# my notes on this run\n"
    assert (previous_run / "index.html").read_text() == "<p>my own page</p>"
    assert not (previous_run / "junit.xml").exists()  # the suite's own stale file goes


@pytest.mark.parametrize("delay", [1.0, 3.0, 5.0, 8.0])
def test_sigint_on_a_real_run(previous_run, delay, child):
    """SIGINT to a real `crosscheck run` process, early (loading the models and engines: a
    Ctrl-C inside MuJoCo's import surfaced as "ImportError: initialization failed", exit 3, and
    one inside PyRun-executed code ended the process by the signal, status -2) and later
    (computing): one line, exit 130, the previous files intact."""
    before = _snapshot(previous_run)
    # in this process (--jobs 1; tests/test_run_jobs.py interrupts runs on worker processes),
    # every built-in model: 15-26 s warm on the 2-core machine, so every delay lands in the run
    with child.start("-m", "crosscheck", "run", "--jobs", "1", "--out", previous_run) as proc:
        time.sleep(delay)
        assert proc.poll() is None, "the run ended before it could be interrupted"
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("crosscheck: interrupted"), err
    assert _snapshot(previous_run) == before
    assert not [p for p in previous_run.iterdir() if p.name.startswith(TMP_PREFIX)]


def test_sigint_on_a_real_sweep(tmp_path, child):
    """An interrupted campaign writes what it completed and never reads as passed."""
    out = tmp_path / "sweep"
    argv = ["sweep", "pendulum_xy", "--samples", "1000000", "--workers", "1"]
    argv += ["--engines", "pinocchio", "--out", out]
    with child.start("-m", "crosscheck", *argv) as proc:
        deadline = time.time() + 300
        while time.time() < deadline:  # interrupt once a chunk is finished (and stored)
            time.sleep(0.5)
            # a stored chunk, not campaign.json's temporary name (it matches *-*.json too: a
            # signal once came while the store was being created, before the campaign started)
            if proc.poll() is not None or chunk_files(out / "sweep.chunks"):
                break
        proc.send_signal(signal.SIGINT)
        stdout, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    st = json.loads((out / "sweep.json").read_text())["status"]
    assert st["stopped"] == "interrupted" and not st["complete"]
    assert st["passed"] is False and st["verdict"] == "incomplete"
    assert 0 < st["completed"]["pendulum_xy"] < 1000000
    assert "stopped: interrupted" in stdout
    # the finished chunks stay for `--resume` (tests/test_sweep_faults.py), nothing else
    assert sorted(p.name for p in out.iterdir()) == ["sweep.chunks", "sweep.json"]
    assert f"crosscheck sweep --resume {out}" in stdout


def test_an_interrupt_the_engine_swallowed_still_interrupts(previous_run, monkeypatch, capsys):
    """An engine that catches the KeyboardInterrupt raised inside its solve (Exudyn: the solve
    reports failure, or the interrupt vanishes) must not turn Ctrl-C into a failed record or a
    finished run: the remembered signal stops the command before its files are committed."""
    from crosscheck.runtime import interrupts

    before = _snapshot(previous_run)
    monkeypatch.setattr(interrupts, "_seen", [signal.SIGINT])  # as if swallowed mid-run
    code = main(["run", "slider_crank", "--instantaneous", "--out", str(previous_run)])
    err = capsys.readouterr().err
    assert code == 130 and "interrupted" in err
    assert _snapshot(previous_run) == before


@pytest.mark.parametrize("delay", [3.0, 4.0, 5.0])
def test_sigint_during_exudyn_solves(previous_run, delay, child):
    """The measured case: Exudyn's solver caught Ctrl-C at 3-4 s into a run of slider_crank
    (exit 0 with every record, or exit 1 with a failed trajectory record). The slider-cranks
    run first and every Exudyn model follows, so each delay lands inside the run whatever the
    machine's speed (all of them: 12-24 s warm, `/usr/bin/time -f %e python -m crosscheck run
    --engines exudyn --jobs 1 --out <dir>`; the two slider-cranks alone took 4.8 s)."""
    before = _snapshot(previous_run)
    models = ["slider_crank", "slider_crank_free", "slider_crank_split", "top_euler"]
    models += ["top_cartesian", "double_pendulum_3d", "exercise_6_4", "frame_bar"]
    # --jobs 1: the solves run in the process that gets the signal (workers ignore it)
    argv = ["run", *models, "--engines", "exudyn", "--jobs", "1", "--out", previous_run]
    with child.start("-m", "crosscheck", *argv) as proc:
        time.sleep(delay)
        assert proc.poll() is None, "the run ended before it could be interrupted"
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert _snapshot(previous_run) == before


def test_a_deferred_interrupt_arrives_after_the_block(monkeypatch):
    """interrupts.deferred: a SIGINT during the block does not cut it; it is raised once the
    block is done, and remembered for interrupts.check."""
    import os as _os

    from crosscheck.runtime import interrupts

    monkeypatch.setattr(interrupts, "_seen", [])
    before = signal.getsignal(signal.SIGINT)
    finished = []
    with pytest.raises(KeyboardInterrupt):
        with interrupts.deferred():
            _os.kill(_os.getpid(), signal.SIGINT)
            time.sleep(0.05)  # the handler has run by now
            finished.append(True)
    assert finished == [True]
    assert interrupts.seen()
    assert signal.getsignal(signal.SIGINT) is before


def test_sigterm_stops_a_run_with_143_and_one_line(previous_run, child):
    """SIGTERM (a cancelled CI job, `kill`) takes Ctrl-C's path: the workers stop, the previous
    files stay, no temporary file is left, one line says so, exit 143."""
    before = _snapshot(previous_run)
    with child.start("-m", "crosscheck", "run", "--jobs", "2", "--out", previous_run) as proc:
        time.sleep(3.0)
        assert proc.poll() is None, "the run ended before it could be terminated"
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("crosscheck: terminated (SIGTERM)"), err
    assert _snapshot(previous_run) == before


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def test_a_killed_commands_temporary_files_are_removed_by_the_next_one(previous_run, capsys):
    """SIGKILL leaves a command no chance to clean up: its temporary files (named with its
    pid) are removed by the next command that writes there; a live command's are kept."""
    dead = next(pid for pid in range(4_000_000, 0, -1) if not _running(pid))
    orphan = previous_run / f"{TMP_PREFIX}{dead}-results.json"
    orphan.write_text("{half a file")
    live = previous_run / f"{TMP_PREFIX}{os.getppid()}-results.json"  # pytest's parent runs
    live.write_text("{another command's file")
    assert main(["run", "pendulum_angle", "--instantaneous", "--out", str(previous_run)]) == 0
    capsys.readouterr()
    assert not orphan.exists() and live.exists()
    live.unlink()
