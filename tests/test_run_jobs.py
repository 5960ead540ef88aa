"""`crosscheck run --jobs N` (crosscheck/run/jobs.py): the models on worker processes give the
serial run's results record for record; bad input, a worker's bug and a dying worker keep
their meaning; an interrupt leaves no worker behind."""

from __future__ import annotations

import json
import os
import signal
import time
import uuid
from pathlib import Path

import pytest

from crosscheck.cli import main
from crosscheck.run.jobs import ModelJob, WorkerError, run_models
from reference.errors import ModelInputError

ROOT = Path(__file__).resolve().parents[1]
MODELS = ["pendulum_angle", "knife_edge", "pendulum_xy"]


def _results(out: Path) -> dict:
    return json.loads((out / "results.json").read_text())


def test_jobs_give_the_serial_records(tmp_path, capsys):
    """Trajectories included (a short horizon): every record, series and agreement matrix in
    the same order and to the bit; only meta's `jobs` differs."""
    runs = {}
    for jobs in ("1", "2"):
        out = tmp_path / f"jobs{jobs}"
        args = ["run", *MODELS, "--t-end", "0.5", "--no-report", "--jobs", jobs]
        assert main([*args, "--out", str(out)]) == 0
        runs[jobs] = _results(out)
    capsys.readouterr()
    serial, parallel = runs["1"], runs["2"]
    assert (serial["meta"]["jobs"], parallel["meta"]["jobs"]) == (1, 2)
    assert [r["model"] for r in parallel["records"]] == [r["model"] for r in serial["records"]]
    for key in ("records", "series", "agreement"):
        assert parallel[key] == serial[key], key
    assert {r["model"] for r in serial["records"]} == set(MODELS)


def _job(name: str, perturb: dict | None = None, n_states=2) -> ModelJob:
    return ModelJob(name, ("pinocchio",), n_states, perturb or {}, False, 1.0)


def test_bad_input_reports_the_first_model_a_serial_run_meets():
    """Two models with bad input: the error is the earlier one's, as in a serial run, even
    when the later one fails first (it is the cheaper one here)."""
    bad = {"pinocchio": {"no_such_parameter": 1e-3}}
    jobs = [_job("pendulum_angle"), _job("double_pendulum_3d", bad), _job("pendulum_xy", bad)]
    with pytest.raises(ModelInputError, match="model 'double_pendulum_3d' has no parameter"):
        run_models(jobs, 2)


def test_results_come_back_in_the_models_order():
    progress: list[str] = []
    records, _series = run_models(
        [_job("pendulum_xy"), _job("pendulum_angle")], 2, progress=progress.append
    )
    assert sorted(progress) == ["pendulum_angle", "pendulum_xy"]
    models = [r["model"] for r in records]
    assert set(models) == {"pendulum_xy", "pendulum_angle"}
    assert models == sorted(models, key=["pendulum_xy", "pendulum_angle"].index)


def test_the_meanwhile_work_runs_beside_the_hand_out_and_its_error_reaches_the_caller():
    """run_models(meanwhile=...) runs the work on a thread of its own (the hand-out waits for
    the workers' server meanwhile), once; an exception in it is the caller's."""
    import threading

    threads: list[str] = []
    jobs = [_job("pendulum_angle"), _job("pendulum_xy")]
    records, _series = run_models(
        jobs, 2, meanwhile=lambda: threads.append(threading.current_thread().name)
    )
    assert len(threads) == 1 and threads[0] != threading.main_thread().name
    assert {r["model"] for r in records} == {"pendulum_angle", "pendulum_xy"}

    def broken():
        raise RuntimeError("the meta could not be read")

    with pytest.raises(RuntimeError, match="the meta could not be read"):
        run_models(jobs, 2, meanwhile=broken)


def test_the_meta_of_a_run_on_workers_names_every_engine(tmp_path, child):
    """In a fresh program, a run on workers reads its meta on a thread beside the hand-out
    (run_jobs._Meanwhile): that thread imports the adapters of the engines the run did not
    name, so every available engine's version is there, as in a serial run."""
    from crosscheck.engines.registry import engine_distributions

    args = ["run", "pendulum_angle", "pendulum_xy", "--engines", "pinocchio", "--jobs", "2"]
    args += ["--instantaneous", "--no-report", "--out", str(tmp_path)]
    r = child.crosscheck(*args, timeout=300)
    assert r.returncode == 0, r.stderr
    meta = _results(tmp_path)["meta"]
    assert meta["jobs"] == 2
    assert set(engine_distributions()) <= set(meta["versions"])


def test_a_bug_in_a_worker_carries_its_traceback():
    with pytest.raises(WorkerError, match=r"(?s)checking pendulum_angle.*Traceback"):
        run_models([_job("pendulum_angle", n_states="two"), _job("pendulum_xy")], 2)


DYING_FILE = """
import dataclasses
import multiprocessing
import os

from reference import models as builtin


def models():
    if multiprocessing.parent_process() is not None:  # a worker: die as a crashed engine would
        os._exit(3)
    return [dataclasses.replace(builtin.get("pendulum_angle"), name="my_pendulum")]
"""


def test_a_worker_that_dies_is_an_error_naming_the_models(tmp_path, capsys):
    """Never a shorter results.json: the run fails (exit 3) and says which models were in
    flight and how to see where (--jobs 1)."""
    path = tmp_path / "dying.py"
    path.write_text(DYING_FILE)
    out = tmp_path / "out"
    args = ["run", "my_pendulum", "pendulum_angle", "--model-file", str(path)]
    code = main([*args, "--instantaneous", "--jobs", "2", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 3, err
    assert "a worker process ended abruptly" in err and "my_pendulum" in err
    assert "--jobs 1" in err
    assert not (out / "results.json").exists()


def _tagged_processes(tag: str) -> list[int]:
    """The processes whose environment holds `tag` (the run, its server and its workers)."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                if tag.encode() in (entry / "environ").read_bytes():
                    found.append(int(entry.name))
            except OSError:
                continue
    return found


@pytest.mark.skipif(not Path("/proc/self/environ").exists(), reason="needs Linux /proc")
@pytest.mark.parametrize(
    "delay,whole_group", [(2.0, False), (3.5, False), (6.0, False), (2.0, True), (3.5, True)]
)
def test_sigint_on_a_parallel_run_leaves_no_worker(tmp_path, delay, whole_group, child):
    """SIGINT to the parent only (as `kill -INT pid`), or to the whole process group (as
    Ctrl-C at a terminal: the server and the workers get it too): one line, exit 130, and
    within a few seconds no worker or server of the run is left. Delays from the server's
    imports (a fork asked for then is served after the parent has gone) to the models'
    computing."""
    tag = f"CROSSCHECK_TEST_TAG={uuid.uuid4().hex}"
    key, value = tag.split("=")
    # every built-in model: 15-25 s warm on two workers, so every delay lands in the run
    with child.start(
        "-m",
        "crosscheck",
        "run",
        "--jobs",
        "2",
        "--out",
        "out",
        env={key: value},
        start_new_session=True,  # its own process group, as a terminal gives a command
        # and Ctrl-C's default action, as a terminal's shell gives it (pytest may have been
        # started in the background, with SIGINT ignored, and children inherit that)
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    ) as proc:
        time.sleep(delay)
        assert proc.poll() is None, "the run ended before it could be interrupted"
        if whole_group:
            os.killpg(proc.pid, signal.SIGINT)
        else:
            proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("crosscheck: interrupted"), err
    deadline = time.time() + 15
    while _tagged_processes(tag) and time.time() < deadline:
        time.sleep(0.2)
    left = _tagged_processes(tag)
    for pid in left:  # do not leak them into the rest of the session
        os.kill(pid, signal.SIGKILL)
    assert not left, f"processes left after the interrupt: {left}"


def test_the_callers_settings_reach_the_workers(monkeypatch):
    """The workers' server keeps the environment it started with; a CROSSCHECK_* setting made
    afterwards in this process still reaches the workers (here a wrong one, so its error
    shows that it arrived)."""
    run_models([_job("pendulum_angle")], 2)  # the server is running now
    monkeypatch.setenv("CROSSCHECK_BACKEND", "fortran")
    with pytest.raises(ModelInputError, match="CROSSCHECK_BACKEND"):
        run_models([_job("pendulum_angle"), _job("pendulum_xy")], 2)


def test_a_users_model_file_is_loaded_in_every_worker(tmp_path, capsys):
    """--model-file models run on the workers as in one process: each worker registers the
    files again (they are not inherited), and the records are the serial run's."""
    from .test_user_models_cli import FOURBAR

    runs = {}
    for jobs in ("1", "2"):
        out = tmp_path / f"jobs{jobs}"
        args = ["run", "pendulum_angle", "fourbar_connect", "--model-file", FOURBAR]
        args.append("--instantaneous")
        assert main([*args, "--no-report", "--jobs", jobs, "--out", str(out)]) == 0
        runs[jobs] = _results(out)["records"]
    capsys.readouterr()
    assert runs["2"] == runs["1"]
    assert len({r["model"] for r in runs["1"]}) == 2


def test_models_go_out_longest_first_and_their_times_are_kept(tmp_path, monkeypatch):
    """With one worker the models complete in the order they were handed out: the longer
    one by the times on file first; the results still come back in the models' order, and
    the run's own times replace those on file (another setting's entry is kept)."""
    from crosscheck.run import order as run_order

    monkeypatch.setattr(run_order, "_path", lambda: tmp_path / run_order.FILE)
    jobs = [_job("pendulum_angle"), _job("pendulum_xy")]
    setting = jobs[0].setting
    run_order.remember_times(setting, {"pendulum_angle": 0.1, "pendulum_xy": 50.0})
    run_order.remember_times("another setting", {"pendulum_angle": 7.0})
    completed: list[str] = []
    records, _series = run_models(jobs, 1, progress=completed.append)
    assert completed == ["pendulum_xy", "pendulum_angle"]
    assert list(dict.fromkeys(r["model"] for r in records)) == ["pendulum_angle", "pendulum_xy"]
    kept = run_order.known_times(setting)
    assert set(kept) == {"pendulum_angle", "pendulum_xy"} and kept["pendulum_xy"] < 50.0
    assert run_order.known_times("another setting") == {"pendulum_angle": 7.0}
