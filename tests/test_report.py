"""`crosscheck report` as a person uses it: run the suite, write the report, open it.

The inputs are real: `crosscheck run` on the slider-crank against Pinocchio, once clean and once
with a fault injected into Pinocchio's model (`--perturb pinocchio:m2=1e-6`), so the report has
passing, failing and skipped rows. The trajectory "series" and the bench rows that a quick test
cannot afford to measure are written here in the documented formats and say so in their labels.
The slow test opens the page in headless Chromium, as a reader would.
"""

from __future__ import annotations

import base64
import json
import shutil
import tempfile
import xml.etree.ElementTree as ET
from html.parser import HTMLParser
from pathlib import Path

import pytest

from tests.support import cli, run_browser

VERSION_KEYS = ("python", "numpy", "scipy", "sympy", "pin", "mujoco")


def crosscheck(*argv, check=True):
    """A command in this process (the program's own start and exit: tests/test_cli.py)."""
    p = cli(*argv)
    if check and p.returncode not in (0, 1):
        raise AssertionError(
            f"crosscheck {' '.join(map(str, argv))} -> {p.returncode}\n{p.stdout}\n{p.stderr}"
        )
    return p


_RUNS: dict[str, Path] = {}


def results_of(tmp_path_factory, kind: str) -> Path:
    """results.json of a real run, made once per test session (test_gate.py uses it too):
    "clean" (slider-crank against Pinocchio, 2 states), "faulty" (the same with a fault
    injected into Pinocchio's model: m2 changed by 1e-6, so its checks fail) or "clean2" (a
    second clean run, for the gate's fresh-run check)."""
    if kind not in _RUNS:
        out = tmp_path_factory.mktemp(kind)
        extra = ["--perturb", "pinocchio:m2=1e-6"] if kind == "faulty" else []
        p = crosscheck(
            "run",
            "slider_crank",
            "--engines",
            "pinocchio",
            "--states",
            "2",
            "--instantaneous",
            *extra,
            "--out",
            out,
        )
        assert p.returncode == (1 if kind == "faulty" else 0), p.stdout + p.stderr
        _RUNS[kind] = out / "results.json"
    return _RUNS[kind]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    return {k: results_of(tmp_path_factory, k) for k in ("clean", "faulty")}


def synthetic_series(model: str) -> list[dict]:
    """Trajectory series in the results.json format (labels say they are test data)."""
    t = [0.01 * i for i in range(201)]
    out = []
    for engine, label, scale in (
        ("reference", "test data: DOP853 rtol=1e-10", 0.0),
        ("pinocchio", "test data: RK4 h=1e-3", 1e-8),
    ):
        out.append(
            {
                "model": model,
                "engine": engine,
                "formulation": "lagrange",
                "label": label,
                "t": t,
                "state_error": [scale * x for x in t],
                "residual": [1e-15 + scale * x * x for x in t],
                "energy": [3.0 + 0.1 * scale * x for x in t],
            }
        )
    return out


def synthetic_bench(model: str) -> dict:
    """bench.json in the format `crosscheck bench` writes, with round numbers to check ratios."""
    fwd = [
        ("reference", "single", 1, 10.0),
        ("reference", "batched", 10000, 0.5),
        ("pinocchio", "engine:pinocchio", 1, 4.0),
        ("mujoco", "engine:mujoco", 1, 20.0),
    ]
    wp = []
    for method, cost in (("projection", 1.0), ("baumgarte", 2.0)):
        for k, tol in enumerate((1e-6, 1e-8, 1e-10)):
            wp.append(
                {
                    "model": model,
                    "engine": "reference",
                    "method": method,
                    "integrator": "DOP853",
                    "setting": tol,
                    "setting_kind": "rtol=atol",
                    "wall_s": 0.01 * cost * (k + 1),
                    "error": 10 * tol,
                    "residual": tol / 10,
                    "energy_drift": tol,
                    "nfev": 100 * (k + 1),
                }
            )
    return {
        "meta": {
            "command": "crosscheck bench (test data)",
            "date": "2026-01-01T00:00:00Z",
            "versions": {k: "test" for k in VERSION_KEYS},
            "machine": {"platform": "test", "processor": "x86_64", "cpus": 2},
        },
        "forward": [
            {
                "model": model,
                "engine": e,
                "formulation": "lagrange",
                "path": p,
                "batch": b,
                "us_per_state": us,
                "us_per_state_min": us * 0.9,
            }
            for e, p, b, us in fwd
        ],
        "work_precision": wp,
        "stress": [
            {
                "scene": "test_scene",
                "what": "test data",
                "status": "flagged",
                "reasons": ["a stated reason"],
                "wall_s": 0.1,
            }
        ],
        "targets": {
            "test_target": {"statement": "test data", "met": False, "reason": "a stated reason"}
        },
    }


@pytest.fixture(scope="module")
def full_report(runs, tmp_path_factory):
    """The faulty run plus trajectories and a bench file, reported through the CLI."""
    root = tmp_path_factory.mktemp("report")
    results = json.loads(runs["faulty"].read_text())
    results["series"] = synthetic_series("slider_crank")
    (root / "results.json").write_text(json.dumps(results))
    (root / "bench.json").write_text(json.dumps(synthetic_bench("slider_crank")))
    p = crosscheck(
        "report",
        "--results",
        root / "results.json",
        "--bench",
        root / "bench.json",
        "--out",
        root / "site",
    )
    assert p.returncode == 0, p.stderr
    return {"dir": root / "site", "results": results, "root": root}


class _Page(HTMLParser):
    """Collects what a self-containment and table check needs from index.html."""

    def __init__(self):
        super().__init__()
        self.urls, self.images, self.scripts, self.rows = [], [], 0, []
        self._row = None
        self._cell = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        for k in ("src", "href", "data", "action", "poster"):
            if a.get(k) is not None:
                self.urls.append(a[k])
        if tag == "img":
            self.images.append(a)
        if tag in ("script", "iframe", "object", "embed"):
            self.scripts += 1
        if tag == "link":
            self.urls.append(a.get("href", ""))
        if tag == "tr":
            self._row = {"class": a.get("class", ""), "cells": []}
        if tag == "td" and self._row is not None:
            self._cell = []

    def handle_endtag(self, tag):
        if tag == "td" and self._row is not None and self._cell is not None:
            self._row["cells"].append("".join(self._cell).strip())
            self._cell = None
        if tag == "tr" and self._row is not None:
            self.rows.append(self._row)
            self._row = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)


def parse_page(path: Path) -> _Page:
    page = _Page()
    page.feed(path.read_text(encoding="utf-8"))
    return page


def check_rows(page: _Page) -> list[dict]:
    """Rows of the per-model check tables (their first cell is the status badge)."""
    return [r for r in page.rows if r["cells"] and r["cells"][0] in ("PASS", "FAIL", "SKIP")]


# ---- the HTML ----------------------------------------------------------------------------------
def test_every_record_is_a_row_and_failing_rows_stay_marked(full_report):
    page = parse_page(full_report["dir"] / "index.html")
    rows = check_rows(page)
    records = full_report["results"]["records"]
    assert len(rows) == len(records)
    for row, rec in zip(rows, records, strict=True):  # same order as results.json
        expected = "SKIP" if rec["skipped"] else "PASS" if rec["passed"] else "FAIL"
        assert row["cells"][0] == expected
        assert row["cells"][2] == rec["engine"] and row["cells"][4] == rec["quantity"]
        if expected == "FAIL":
            assert "fail" in row["class"]
        if expected == "SKIP":
            assert "skip" in row["class"] and rec["reason"] in row["cells"][-1]
    failing = [r for r in records if r["passed"] is False]
    assert failing, "the fault injection must produce failing rows"
    html = (full_report["dir"] / "index.html").read_text()
    assert f"{len(failing)} of" in html and "FAIL" in html
    for r in failing:  # listed at the top too, by their full key
        assert f"slider_crank/{r['formulation']}/{r['engine']}/{r['check']}/{r['quantity']}" in html


def test_html_is_self_contained_and_every_figure_is_an_svg(full_report):
    page = parse_page(full_report["dir"] / "index.html")
    # one inline script, and only it: a link to a folded model section unfolds it
    assert (
        page.scripts == 1 and "<script src" not in (full_report["dir"] / "index.html").read_text()
    )
    external = [u for u in page.urls if not (u.startswith("data:") or u.startswith("#"))]
    assert external == [], external
    assert "http://" not in (full_report["dir"] / "index.html").read_text().split("<svg")[0]
    alts = [img.get("alt", "") for img in page.images]
    # agreement, trajectories and work-precision for the one model
    assert any(a.startswith("agreement plot") for a in alts)
    assert any(a.startswith("trajectories") for a in alts)
    assert any(a.startswith("work-precision") for a in alts)
    for img in page.images:
        prefix = "data:image/svg+xml;base64,"
        assert img["src"].startswith(prefix)
        svg = base64.b64decode(img["src"][len(prefix) :])
        root = ET.fromstring(svg)
        assert root.tag.endswith("svg")
        assert len(list(root.iter())) > 50  # axes, ticks, lines: not an empty picture


def test_footer_has_the_commands_machine_and_versions(full_report):
    html = (full_report["dir"] / "index.html").read_text()
    meta = full_report["results"]["meta"]
    footer = html[html.index('<footer id="footer">') :]
    assert meta["command"] in footer
    assert "crosscheck bench (test data)" in footer
    site = full_report["dir"]
    assert (
        f"crosscheck report --results {full_report['root'] / 'results.json'} --bench "
        f"{full_report['root'] / 'bench.json'} --out {site}"
    ) in footer
    assert meta["machine"]["platform"] in footer
    for key in VERSION_KEYS:
        assert f"<td>{key}</td>" in footer
        assert f"<td>{meta['versions'][key]}</td>" in footer


def test_timing_ratios_are_against_the_engines_of_the_same_run(full_report):
    page = parse_page(full_report["dir"] / "index.html")
    by_path = {r["cells"][1]: r["cells"] for r in page.rows if len(r["cells"]) == 7}
    # columns: engine, path, batch, median, min, x Pinocchio, x MuJoCo
    assert by_path["single"][5:] == ["2.5×", "0.5×"]
    assert by_path["batched"][5:] == ["0.125×", "0.025×"]
    assert by_path["engine:pinocchio"][5] == "1×"


def test_trajectories_work_precision_and_other_bench_sections(full_report):
    html = (full_report["dir"] / "index.html").read_text()
    assert "No trajectory was run" not in html
    assert "test data: RK4 h=1e-3" in html  # the series table names each line
    assert "projection/DOP853" in html and "rtol=atol 1e-08" in html
    assert "test_scene" in html and "flagged" in html and "not met" in html


def test_markdown_has_the_tables_and_the_regenerate_commands(full_report):
    md = (full_report["dir"] / "report.md").read_text()
    records = full_report["results"]["records"]
    rows = [
        line
        for line in md.splitlines()
        if line.startswith("| PASS") or line.startswith("| FAIL") or line.startswith("| SKIP")
    ]
    assert len(rows) == len(records)
    assert sum(r.startswith("| FAIL") for r in rows) == sum(r["passed"] is False for r in records)
    assert full_report["results"]["meta"]["command"] in md
    assert "crosscheck report --results" in md
    assert "pin " + full_report["results"]["meta"]["versions"]["pin"] in md


def test_junit_has_one_case_per_record_with_reasons(full_report):
    root = ET.parse(full_report["dir"] / "junit.xml").getroot()
    records = full_report["results"]["records"]
    cases = list(root.iter("testcase"))
    assert len(cases) == len(records) == int(root.get("tests"))
    for case, rec in zip(cases, records, strict=True):
        assert case.get("classname") == f"crosscheck.{rec['model']}.{rec['engine']}"
        failure, skipped = case.find("failure"), case.find("skipped")
        if rec["skipped"]:
            assert skipped is not None and skipped.get("message") == rec["reason"]
        elif rec["passed"]:
            assert failure is None and skipped is None
        else:
            assert failure is not None
            assert rec["reason"] in failure.get("message")
            assert f"{rec['error']:.2e}" in failure.get("message")
    assert int(root.get("failures")) == sum(r["passed"] is False for r in records)
    assert int(root.get("skipped")) == sum(bool(r["skipped"]) for r in records)


def test_report_is_deterministic(full_report):
    from crosscheck.report.write import generate
    from crosscheck.runtime.output import LEDGER

    site, root = full_report["dir"], full_report["root"]
    before = {p.name: p.read_bytes() for p in site.iterdir()}
    generate(str(root / "results.json"), str(root / "bench.json"), str(site))
    after = {p.name: p.read_bytes() for p in site.iterdir()}
    assert before.keys() == after.keys() == {"index.html", "report.md", "junit.xml", LEDGER}
    for name in before:
        assert before[name] == after[name], name


def test_clean_run_without_series_or_bench_says_so(runs, tmp_path):
    from crosscheck.cli import main

    shutil.copy(runs["clean"], tmp_path / "results.json")
    assert main(["report", "--results", str(tmp_path / "results.json")]) == 0
    html = (tmp_path / "index.html").read_text()  # default --out: beside the results
    records = json.loads((tmp_path / "results.json").read_text())["records"]
    executed = sum(1 for r in records if not r["skipped"])  # defaults and generic set alike
    skipped = len(records) - executed
    assert f"All {executed} executed checks pass ({skipped} skipped)" in html
    assert "No trajectory was run" in html
    assert "Work-precision" not in html  # no bench given, none beside the results
    assert "FAIL" not in "".join(
        r["cells"][0] for r in check_rows(parse_page(tmp_path / "index.html"))
    )


@pytest.mark.parametrize(
    "setup,needle",
    [
        (lambda d: None, "not found"),
        (lambda d: (d / "results.json").write_text("{not json"), "not valid JSON"),
        (lambda d: (d / "results.json").write_text('{"meta": {}}'), 'no "records" list'),
        (lambda d: (d / "results.json").write_text("[1, 2]"), "JSON object"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, setup, needle):
    from crosscheck.cli import main

    setup(tmp_path)
    code = main(
        ["report", "--results", str(tmp_path / "results.json"), "--out", str(tmp_path / "o")]
    )
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and needle in err and err.startswith("crosscheck: error:")
    assert not (tmp_path / "o" / "index.html").exists()


# ---- in a browser --------------------------------------------------------------------------
CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--hide-scrollbars",
    "--enable-logging=stderr",
    "--v=0",
]

# Injected into a copy of the page only (the report itself has no script): records script
# errors, console errors and warnings, and resources that fail to load, and on `load` writes
# them, with every image's decoded size, into the DOM for --dump-dom to return.
PROBE = """<script>
(function () {
  var seen = [];
  window.addEventListener('error', function (e) {
    var t = e.target;
    seen.push(t && t !== window ? 'resource failed: ' + t.tagName + ' ' + (t.alt || '')
                                : 'error: ' + e.message);
  }, true);
  window.addEventListener('unhandledrejection', function (e) {
    seen.push('rejection: ' + e.reason);
  });
  ['error', 'warn'].forEach(function (k) {
    var orig = console[k];
    console[k] = function () { seen.push(k + ': ' + Array.prototype.join.call(arguments, ' '));
                               return orig.apply(console, arguments); };
  });
  window.addEventListener('load', function () {
    var imgs = Array.prototype.slice.call(document.images);
    var pre = document.createElement('pre');
    pre.id = 'probe';
    pre.textContent = JSON.stringify({errors: seen, images: imgs.map(function (i) {
      return {alt: i.alt, complete: i.complete, w: i.naturalWidth, h: i.naturalHeight}; })});
    document.body.appendChild(pre);
  });
})();
</script>"""


def _chromium(browser: str, args, tmp: Path):
    with tempfile.TemporaryDirectory(dir=tmp) as profile:
        return run_browser([browser, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", *args])


def _console_lines(stderr: str) -> list[str]:
    # Chromium logs every console message and uncaught exception as ...:CONSOLE(n)] "..." ;
    # the report has no script, so any such line is a defect
    return [ln for ln in stderr.splitlines() if ":CONSOLE" in ln or "Uncaught" in ln]


def test_report_renders_in_headless_chromium(tmp_path, chromium):
    """The README's flow: run, bench, report; then open index.html from disk in Chromium."""
    out = tmp_path / "out"
    assert (
        crosscheck(
            "run", "slider_crank", "--engines", "pinocchio", "--states", "2", "--out", out
        ).returncode
        == 0
    )
    assert (
        crosscheck(
            "bench", "slider_crank", "--quick", "--engines", "pinocchio", "--out", out
        ).returncode
        == 0
    )
    assert crosscheck("report", "--results", out / "results.json", "--out", out).returncode == 0
    index = out / "index.html"
    html = index.read_text()
    assert "bench.json" in html  # picked up from beside results.json

    shot = tmp_path / "page.png"
    p = _chromium(
        chromium, [f"--screenshot={shot}", "--window-size=1280,3000", index.as_uri()], tmp_path
    )
    assert shot.exists(), p.stderr[-2000:]
    assert _console_lines(p.stderr) == []

    import numpy as np
    from matplotlib.image import imread

    img = imread(shot)[..., :3]
    assert img.shape[0] == 3000 and img.shape[1] == 1280
    gray = img.mean(axis=2)
    assert gray.std() > 0.05, "the screenshot is blank"
    assert (gray < 0.9).mean() > 0.02, "almost nothing is drawn"
    # the agreement plot draws Pinocchio's points in its colour (#1f77b4) inside the viewport
    pin = np.array([0x1F, 0x77, 0xB4]) / 255
    assert (np.abs(img - pin).max(axis=2) < 0.06).sum() > 30, "no plot rendered in view"

    probed = tmp_path / "probed.html"
    probed.write_text(html.replace("<head>", "<head>" + PROBE, 1), encoding="utf-8")
    p = _chromium(
        chromium, ["--dump-dom", "--virtual-time-budget=10000", probed.as_uri()], tmp_path
    )
    dom = p.stdout
    assert 'id="probe"' in dom, p.stderr[-2000:]
    import html as html_mod

    data = json.loads(html_mod.unescape(dom.split('id="probe">', 1)[1].split("</pre>", 1)[0]))
    assert data["errors"] == []
    alts = [i["alt"] for i in data["images"]]
    assert any(a.startswith("agreement plot") for a in alts)
    assert any(a.startswith("work-precision") for a in alts)
    for i in data["images"]:
        assert i["complete"] and i["w"] > 200 and i["h"] > 100, i
    assert _console_lines(p.stderr) == []


def _details_open(html: str) -> dict[str, bool]:
    import re

    return {
        m: "open" in attrs
        for attrs, m in re.findall(
            r'<details class="model"([^>]*)><summary><h2 id="model-([^"]+)"', html
        )
    }


def test_long_pages_fold_passing_models_and_never_a_failing_one(runs, tmp_path):
    """More than UNFOLDED_MODELS models: a passing model's section is folded to its summary
    line (name, verdict), a model with a failing check stays open."""
    from crosscheck.report.html import UNFOLDED_MODELS

    faulty = json.loads(runs["faulty"].read_text())
    clean = json.loads(runs["clean"].read_text())["records"]
    others = ["pendulum_xy", "knife_edge", "frame_bar", "exercise_6_1"][:UNFOLDED_MODELS]
    for name in others:  # test data: the clean records filed under other models' names
        faulty["records"] += [dict(r, model=name) for r in clean]
    (tmp_path / "results.json").write_text(json.dumps(faulty))
    p = crosscheck("report", "--results", tmp_path / "results.json", "--out", tmp_path / "site")
    assert p.returncode == 0, p.stderr
    opened = _details_open((tmp_path / "site" / "index.html").read_text())
    assert opened == {"slider_crank": True, **{m: False for m in others}}


def test_trajectory_caption_names_only_the_panels_drawn_and_the_balance_where_not_conserved():
    from crosscheck.report import plots
    from crosscheck.report.content import energy_heading
    from crosscheck.report.html import _trajectory_caption

    ss = synthetic_series("pendulum_angle")
    for s in ss:
        s["residual"] = [0.0] * len(s["t"])  # no constraints: nothing to draw
    assert [k for k, _ in plots.trajectory_panels(ss)] == ["state_error", "energy"]
    cap = _trajectory_caption(ss)
    assert "No panel for largest position-constraint violation" in cap
    assert "energy drift" in cap and "work-energy" not in cap
    assert energy_heading(ss) == "max energy drift"
    moving = synthetic_series("pendulum_moving_support")
    for s in moving:  # energy changes by the work done: the balance is what is checked
        s["work"] = [e - s["energy"][0] for e in s["energy"]]
    panels = dict(plots.trajectory_panels(moving))
    assert panels["energy"] == plots.BALANCE_PANEL
    cap = _trajectory_caption(moving)
    assert "work-energy balance" in cap and "energy drift" not in cap
    assert energy_heading(moving).startswith("max work-energy balance error")


def test_series_energy_error_is_the_records_definition():
    """The report's energy column and the records use one definition (comparison.py)."""
    from crosscheck.checks.instantaneous import energy_drift, work_energy_balance
    from crosscheck.report.content import series_stats

    s = synthetic_series("slider_crank")[1]
    assert series_stats(s)["energy"] == energy_drift(s["energy"])
    s["work"] = [0.5 * (e - s["energy"][0]) for e in s["energy"]]
    assert series_stats(s)["energy"] == work_energy_balance(s["energy"], s["work"])


def test_engine_against_engine_tables(full_report):
    """results.json "agreement" is shown per model and quantity, the faulty pair marked."""
    html = (full_report["dir"] / "index.html").read_text()
    md = (full_report["dir"] / "report.md").read_text()
    assert "<h3>Engine against engine</h3>" in html
    assert "Engine against engine, accelerations: some pairs disagree" in md
    assert full_report["results"]["agreement"], "the run wrote no agreement matrix"
