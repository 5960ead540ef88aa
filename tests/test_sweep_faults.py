"""Campaigns under faults: an interrupted sweep resumes from its finished
chunks and ends identical to an uninterrupted one, recomputing nothing it finished; a Dask
worker process killed mid-campaign changes nothing in the results."""

from __future__ import annotations

import json
import os
import signal
import time
from pathlib import Path

import pytest

from crosscheck.cli import main
from crosscheck.runtime.output import TMP_PREFIX
from crosscheck.sweep.campaign import campaign
from crosscheck.sweep.config import Campaign
from crosscheck.sweep.store import STORE, ChunkStore, chunk_files

from .test_sweep import _same

MODELS = ["pendulum_xy", "slider_crank_split"]
SAMPLES, SEED, CHUNK = 8, 11, 2


@pytest.fixture(scope="module")
def undisturbed():
    cfg = Campaign(MODELS, samples=SAMPLES, seed=SEED)
    return campaign(cfg, workers=1, chunk=CHUNK)


def _interrupted(out, after: int) -> tuple[dict, list]:
    """The campaign stopped by Ctrl-C (as campaign() sees it) after `after` chunks, storing its
    finished chunks in out/sweep.chunks the way `crosscheck sweep --out out` does."""
    cfg = Campaign(MODELS, samples=SAMPLES, seed=SEED, out=str(out))
    merged = []

    def ctrl_c(res):
        merged.append((res["model"], res["start"], res["completed"]))
        if len(merged) == after:
            raise KeyboardInterrupt

    res = campaign(cfg, workers=1, chunk=CHUNK, on_chunk=ctrl_c, store=ChunkStore(out, cfg))
    return res, merged


def test_resume_computes_only_what_is_missing(tmp_path, undisturbed):
    part, merged = _interrupted(tmp_path, after=3)
    assert part["status"]["stopped"] == "interrupted" and not part["status"]["passed"]
    assert len(list((tmp_path / STORE).glob("*-*.json"))) == 3
    # a chunk a killed process left half written under its temporary name: not a stored chunk
    (tmp_path / STORE / f"{TMP_PREFIX}999-{MODELS[0]}-6.json").write_text('{"model": "pen')
    cfg = Campaign(MODELS, samples=SAMPLES, seed=SEED, out=str(tmp_path))
    computed = []
    res = campaign(
        cfg,
        workers=1,
        chunk=CHUNK,
        store=ChunkStore(tmp_path, cfg),
        resume=True,
        on_chunk=lambda r: computed.append((r["model"], r["start"])),
    )
    assert res["meta"]["resumed"]["chunks"] == 3
    assert res["meta"]["resumed"]["samples"] == sum(c for *_, c in merged)
    assert not {(m, s) for m, s, _ in merged} & set(computed)  # nothing finished recomputed
    assert len(computed) == len(MODELS) * SAMPLES // CHUNK - 3
    _same(undisturbed, res)


def test_cli_resume_ends_identical_to_an_uninterrupted_run(tmp_path, capsys, undisturbed):
    _interrupted(tmp_path, after=2)
    code = main(["sweep", "--resume", str(tmp_path), "--workers", "1"])
    out = capsys.readouterr().out
    assert code == 0, out
    res = json.loads((tmp_path / "sweep.json").read_text())
    assert res["status"]["complete"] and res["status"]["passed"]
    assert res["meta"]["resumed"]["chunks"] == 2
    _same(undisturbed, res)
    assert not (tmp_path / STORE).exists()  # complete: nothing left to resume
    code = main(["sweep", "--resume", str(tmp_path)])
    assert code == 2 and "no interrupted campaign there" in capsys.readouterr().err


def test_an_interrupted_cli_sweep_says_how_to_resume(tmp_path, capsys):
    code = main(
        [
            "sweep",
            "pendulum_xy",
            "--samples",
            "100000",
            "--max-seconds",
            "1",
            "--workers",
            "1",
            "--engines",
            "pinocchio",
            "--out",
            str(tmp_path),
        ]
    )
    out = capsys.readouterr().out
    assert code in (1, 4) and f"crosscheck sweep --resume {tmp_path}" in out
    assert list((tmp_path / STORE).glob("*-*.json"))


@pytest.mark.parametrize(
    "argv,fragment",
    [
        (["--samples", "9"], "continues the campaign stored there (samples 8)"),
        (["pendulum_xy"], "(models ['pendulum_xy', 'slider_crank_split'])"),
        (["--bench"], "give one of them"),
        # a flag equal to its default is still a flag: compared, not ignored
        (["--seed", "0"], "continues the campaign stored there (seed 11)"),
        (["--samples", "100"], "continues the campaign stored there (samples 8)"),
        (["--index", "0", "--seed", "11", "--samples", "7"], "(samples 8)"),
    ],
)
def test_resume_refuses_a_different_campaign(tmp_path, capsys, argv, fragment):
    _interrupted(tmp_path, after=1)
    before = sorted(p.name for p in (tmp_path / STORE).iterdir())
    code = main(["sweep", "--resume", str(tmp_path), *argv])
    err = capsys.readouterr().err
    assert code == 2 and fragment in err and err.count("\n") == 1, err
    assert sorted(p.name for p in (tmp_path / STORE).iterdir()) == before


def test_a_killed_dask_worker_changes_nothing(undisturbed):
    """A real LocalCluster of two worker processes; one is killed (SIGKILL) while it runs a
    chunk. Its nanny restarts it, the scheduler reruns the lost task, the aggregate is the
    undisturbed one."""
    distributed = pytest.importorskip("distributed")
    cfg = Campaign(MODELS, samples=SAMPLES, seed=SEED)
    killed = []
    with (
        distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        pids = client.run(os.getpid)

        def kill_a_busy_worker(_res):
            if killed:
                return
            busy = [w for w, keys in client.processing().items() if keys and w in pids]
            if busy:
                os.kill(pids[busy[0]], signal.SIGKILL)
                killed.append(pids[busy[0]])

        res = campaign(cfg, dask=client, chunk=CHUNK, on_chunk=kill_a_busy_worker)
    assert killed, "no worker was busy when a chunk finished: nothing was disturbed"
    assert res["meta"]["executor"]["kind"] == "dask"
    assert not res["faults"]["chunks"]
    _same(undisturbed, res)


def _ctrl_c_at_sample(monkeypatch, at: int):
    """Ctrl-C as --workers 1 meets it: the signal arrives while sample `at` (counted over the
    campaign) is evaluated, and the engine swallows it (as Exudyn's solver can), returning a
    wrong figure for that sample; interrupts.check() finds the signal afterwards."""
    from crosscheck.runtime import interrupts
    from crosscheck.sweep import worker

    real = worker.compare_at_state
    calls = []

    def compare(*a, **k):
        calls.append(1)
        sc = real(*a, **k)
        if len(calls) == at:
            interrupts._seen.append(signal.SIGINT)
            sc.values = {qn: 1.0 for qn in sc.values}  # what a swallowed interrupt may leave
        return sc

    monkeypatch.setattr(worker, "compare_at_state", compare)
    monkeypatch.setattr(interrupts, "_seen", [])


@pytest.mark.parametrize("at", [1, 4, 9, 17])
def test_an_interrupt_at_any_sample_then_resume_equals_the_undisturbed_campaign(
    tmp_path, monkeypatch, undisturbed, at
):
    """However deep in a chunk the interrupt lands, the chunk it interrupted is dropped whole:
    sweep.json claims exactly the stored chunks and judges nothing the interrupt touched, and
    the resumed campaign is the undisturbed one."""
    from crosscheck.runtime import interrupts

    cfg = Campaign(MODELS, samples=SAMPLES, seed=SEED, out=str(tmp_path))
    _ctrl_c_at_sample(monkeypatch, at)
    part = campaign(cfg, workers=1, chunk=CHUNK, store=ChunkStore(tmp_path, cfg))
    st = part["status"]
    assert st["stopped"] == "interrupted" and not st["passed"]
    stored = ChunkStore(tmp_path, cfg).load()
    claimed = {m: sum(b - a for a, b in r) for m, r in st["completed_ranges"].items()}
    assert claimed == {m: sum(c["completed"] for c in stored if c["model"] == m) for m in MODELS}
    assert st["outside_tolerance"] == 0 and st["faults"] == 0  # the wrong figure was dropped
    monkeypatch.setattr(interrupts, "_seen", [])
    cfg = Campaign(MODELS, samples=SAMPLES, seed=SEED, out=str(tmp_path))
    res = campaign(cfg, workers=1, chunk=CHUNK, store=ChunkStore(tmp_path, cfg), resume=True)
    _same(undisturbed, res)


def test_a_resumed_campaigns_meta_names_the_command_that_started_it(tmp_path, monkeypatch):
    monkeypatch.setattr("sys.argv", ["crosscheck", "sweep", "--seed", "11", "--samples", "8"])
    _interrupted(tmp_path, after=1)
    cfg = Campaign(MODELS, samples=SAMPLES, seed=SEED, out=str(tmp_path))
    res = campaign(cfg, workers=1, chunk=CHUNK, store=ChunkStore(tmp_path, cfg), resume=True)
    assert res["meta"]["resumed"]["campaign_command"] == "crosscheck sweep --seed 11 --samples 8"
    assert res["meta"]["seed"] == SEED


def test_a_campaign_too_large_to_hold_is_refused_before_any_work(tmp_path, capsys):
    code = main(["sweep", "pendulum_xy", "--samples", "100000000", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and "split it into campaigns with --index" in err and err.count("\n") == 1
    assert not list(tmp_path.iterdir())


REAL = ["sweep", "pendulum_xy", "--engines", "pinocchio", "--samples", "20000", "--seed", "3"]
REAL += ["--workers", "1", "--chunk", "50"]


@pytest.fixture(scope="module")
def whole_sweep(session_child, tmp_path_factory) -> dict:
    """The undisturbed `crosscheck sweep` of REAL, run once for the module."""
    out = tmp_path_factory.mktemp("whole")
    whole = session_child.crosscheck(*REAL, "--out", out)
    assert whole.returncode == 0, whole.stdout + whole.stderr
    return json.loads((out / "sweep.json").read_text())


def _first_chunk(proc, out: Path, timeout: float = 60.0) -> None:
    """Wait until the sweep has stored its first chunk (the campaign is under way)."""
    t_end = time.monotonic() + timeout
    while not (out / STORE).is_dir() or not chunk_files(out / STORE):
        assert proc.poll() is None, "the sweep ended before storing a chunk"
        assert time.monotonic() < t_end, "no chunk stored within the timeout"
        time.sleep(0.02)


@pytest.mark.parametrize("after", [0.0, 1.0])
def test_a_real_ctrl_c_then_resume_equals_the_undisturbed_sweep(
    tmp_path, child, after, whole_sweep
):
    """SIGINT to a `crosscheck sweep --workers 1` process at two moments (as its first chunk
    is stored, and a second later), then --resume: the resumed sweep.json is the undisturbed
    campaign's (meta and timing aside), the interrupted one claimed no more than its stored
    chunks, and Ctrl-C acted within 2 s."""
    with child.start("-m", "crosscheck", *REAL, "--out", tmp_path) as proc:
        _first_chunk(proc, tmp_path)
        time.sleep(after)
        assert proc.poll() is None, "the sweep ended before it could be interrupted"
        t0 = time.perf_counter()
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=120)
        acted = time.perf_counter() - t0
    assert proc.returncode == 130
    assert acted < 2.0, f"Ctrl-C took {acted:.1f} s to act"
    cut = json.loads((tmp_path / "sweep.json").read_text())["status"]
    stored = sum(c["completed"] for c in _stored(tmp_path))
    assert cut["completed"]["pendulum_xy"] == stored
    resumed = child.crosscheck("sweep", "--resume", tmp_path, "--workers", "1")
    assert resumed.returncode == 0, resumed.stdout + resumed.stderr
    _same(whole_sweep, json.loads((tmp_path / "sweep.json").read_text()))


def _stored(out) -> list[dict]:
    cfg = Campaign(["pendulum_xy"], samples=20000, seed=3, engines=("pinocchio",), out=str(out))
    return ChunkStore(out, cfg).load()
