"""A model whose reference trajectory cannot vouch for itself over the default horizon (a
mechanism that spins up) fails naming the horizon as the likely cause and `--t-end` as the
way out; over a shorter horizon it passes."""

from __future__ import annotations

import json

from tests.support import ROOT, cli

SPIN_UP = ROOT / "tests" / "data" / "spin_up.py"


def _run(tmp_path, *extra):
    out = tmp_path / "out"
    argv = ["run", "--model-file", SPIN_UP, "--engines", "mujoco", "--states", "1"]
    return cli(*argv, "--out", out, "--no-report", *extra), out


def test_the_failing_reference_record_names_the_horizon(tmp_path):
    res, out = _run(tmp_path)
    assert res.returncode == 1, res.stderr
    records = json.loads((out / "results.json").read_text())["records"]
    failed = [r for r in records if r["passed"] is False]
    assert failed and all(r["engine"] == "reference" for r in failed)
    assert all("horizon is the likely cause" in r["reason"] for r in failed)
    assert all("--t-end" in r["reason"] and "t_end = 5 s" in r["reason"] for r in failed)
    fails = [line for line in res.stderr.splitlines() if line.startswith("FAIL")]
    assert fails and all(line.endswith("rerun with a shorter --t-end)") for line in fails)


def test_a_shorter_horizon_passes(tmp_path):
    res, out = _run(tmp_path, "--t-end", "2")
    assert res.returncode == 0, res.stderr
    records = json.loads((out / "results.json").read_text())["records"]
    assert not [r for r in records if "likely cause" in r["reason"]]
