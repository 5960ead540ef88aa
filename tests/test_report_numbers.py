"""The report survives any number a run can write: huge, tiny, zero, negative, infinite, NaN,
in records, trajectories and bench rows. Figures clip and mark what is off their scale; a
record is never shown as passing unless its error is a finite number within its tolerance."""

from __future__ import annotations

import copy
import json
import math

import pytest

from tests.support import cli
from tests.test_report import results_of, synthetic_bench, synthetic_series

EXTREMES = [1e300, -1e300, math.inf, -math.inf, math.nan, 0.0, 1e-300, -1.0]


def _judged(r: dict, error: float) -> dict:
    """A judged record with `error`, judged as the suite judges (a finite error within the
    tolerance passes); skips, and errors the schema cannot hold (negative), stay as they are."""
    if r.get("skipped") or r.get("tolerance") is None or error < 0:
        return r
    return dict(r, error=error, passed=bool(math.isfinite(error) and error <= r["tolerance"]))


def _series_with(series: list[dict], value: float) -> list[dict]:
    out = copy.deepcopy(series)
    for s in out:
        for key, v in s.items():
            if isinstance(v, list) and key != "t" and v and isinstance(v[0], (int, float)):
                s[key] = [value if i % 7 == 3 else x for i, x in enumerate(v)]
    return out


def _bench_with(bench: dict, value: float) -> dict:
    out = copy.deepcopy(bench)
    for row in out.get("work_precision", []):
        for key in ("error", "residual", "energy_drift", "wall_s"):
            if key in row:
                row[key] = value
    for row in out.get("forward", []):
        if "us_per_state" in row:
            row["us_per_state"] = value
    return out


@pytest.fixture(scope="module")
def clean(tmp_path_factory) -> dict:
    return json.loads(results_of(tmp_path_factory, "faulty").read_text())


@pytest.mark.parametrize("value", EXTREMES, ids=repr)
def test_every_number_is_drawn_or_marked_never_a_crash(clean, tmp_path, value):
    results = dict(clean)
    results["records"] = [_judged(r, value) for r in clean["records"]]
    results["series"] = _series_with(synthetic_series("slider_crank"), value)
    (tmp_path / "results.json").write_text(json.dumps(results))
    bench = _bench_with(synthetic_bench("slider_crank"), value)
    (tmp_path / "bench.json").write_text(json.dumps(bench))
    out = cli(
        "report",
        "--results",
        tmp_path / "results.json",
        "--bench",
        tmp_path / "bench.json",
        "--out",
        tmp_path / "site",
    )
    assert out.returncode == 0, out.stderr[-2000:]
    html = (tmp_path / "site" / "index.html").read_text()
    assert "data:image/svg+xml;base64," in html  # the figures were drawn
    md = (tmp_path / "site" / "report.md").read_text()
    if not (value < 0 or (math.isfinite(value) and value <= 1e-11)):  # every record judged
        assert "| pass |" not in md.lower().replace("**", "")


@pytest.mark.parametrize("error", [math.nan, math.inf, 1.0])
@pytest.mark.parametrize("command", ["report", "gate"])
def test_a_record_that_says_passed_with_an_error_out_of_tolerance_is_refused(
    clean, tmp_path, error, command
):
    """A file whose record says passed although its error is NaN, infinite or above its
    tolerance contradicts itself (the suite never writes one): refused in one line, not shown
    as a pass by the report nor as a regression by the gate."""
    results = copy.deepcopy(clean)
    judged = next(r for r in results["records"] if r.get("tolerance"))
    judged.update(error=error, passed=True)
    path = tmp_path / "results.json"
    path.write_text(json.dumps(results))
    argv = (
        ["report", "--results", path, "--out", tmp_path / "site"]
        if command == "report"
        else ["gate", "--baseline", tmp_path / "base.json", "--results", path]
    )
    if command == "gate":
        (tmp_path / "base.json").write_text(json.dumps(clean))
    out = cli(*argv)
    assert out.returncode == 2, out.stdout + out.stderr
    assert out.stderr.count("\n") == 1 and "passed" in out.stderr, out.stderr
