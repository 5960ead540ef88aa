"""The report files: results.json (+ bench.json, sweep.json) -> DIR/index.html, DIR/report.md,
DIR/junit.xml.

- index.html is one self-contained file (inline CSS, figures as data: URIs, no script, nothing
  fetched), so it opens from disk or a CI artifact with no network.
- Per model: a table of every check (failing rows kept and marked, skipped rows with their
  reason), the agreement plot (error against tolerance per quantity and engine, log scale),
  trajectories from results.json's "series" (state error against the reference, constraint
  residual, energy drift against time), work-precision diagrams and the forward timing table
  from bench.json, with ratios against the engines timed in the same bench run.
- junit.xml: one test case per record; failures carry the error, the tolerance and the reason;
  skipped records are <skipped message=reason>.
- Every page ends with the commands that regenerate it, the machine and the package versions,
  taken from the inputs' "meta" (the run that produced the numbers, not the report's process).

Output is deterministic for the same inputs and arguments: nothing here reads the clock, and the
figures are rendered with fixed ids (see crosscheck.report.plots).
"""

from __future__ import annotations

import json
import shlex
from pathlib import Path

from crosscheck.report.content import Content, check_bench, check_results, check_sweep, load_json
from crosscheck.report.html import render_html
from crosscheck.report.junit import render_junit
from crosscheck.report.markdown import render_md


def write_report(
    results: dict | None,
    bench: dict | None,
    out_dir: str | Path,
    command: str,
    results_path: str | None = None,
    bench_path: str | None = None,
    sweep: dict | None = None,
    sweep_path: str | None = None,
    outputs=None,
) -> dict:
    """Write index.html, report.md and junit.xml into out_dir; returns their paths.

    The files are staged and renamed into place together (crosscheck.runtime.output), so an
    interrupt leaves the previous report or this one, never a mix; with `outputs` given (a run
    staging its results.json too) they are only staged, and the caller commits them all at once."""
    from crosscheck.runtime.output import Outputs

    c = Content(results, bench, command, results_path, bench_path, sweep, sweep_path)
    names = {"html": "index.html", "md": "report.md", "junit": "junit.xml"}
    if results is None:
        names.pop("junit")
    renderers = {"html": render_html, "md": render_md, "junit": render_junit}
    if outputs is not None:
        for key, name in names.items():
            outputs.stage(name, renderers[key](c))
        return {k: outputs.path(v) for k, v in names.items()}
    with Outputs(out_dir) as staged:
        for key, name in names.items():
            staged.stage(name, renderers[key](c))
        staged.commit(stale=("junit.xml",))  # no results: an old junit.xml is not this one
    return {k: staged.path(v) for k, v in names.items()}


def generate(
    results_path: str | None,
    bench_path: str | None,
    out_dir: str,
    sweep_path: str | None = None,
    outputs=None,
    results_text: str | None = None,
) -> dict:
    """Load and check the inputs, then write the report (`run` calls this with its staged
    outputs and the results.json text it is about to commit)."""
    if results_text is not None:
        results = check_results(json.loads(results_text), results_path)
    else:
        results = (
            check_results(load_json(results_path, "results"), results_path)
            if results_path
            else None
        )
    bench = check_bench(load_json(bench_path, "bench"), bench_path) if bench_path else None
    sweep = check_sweep(load_json(sweep_path, "sweep"), sweep_path) if sweep_path else None
    argv = ["crosscheck", "report"]
    if results_path:
        argv += ["--results", str(results_path)]
    if bench_path:
        argv += ["--bench", str(bench_path)]
    if sweep_path:
        argv += ["--sweep", str(sweep_path)]
    argv += ["--out", str(out_dir)]
    return write_report(
        results,
        bench,
        out_dir,
        shlex.join(argv),
        results_path,
        bench_path,
        sweep,
        sweep_path,
        outputs,
    )
