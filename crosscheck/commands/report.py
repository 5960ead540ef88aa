"""`crosscheck report`: results.json (+ bench.json) -> DIR/index.html, DIR/report.md, DIR/junit.xml.

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

from crosscheck.report.content import (
    DEFAULT_RESULTS,
    Content,
    ReportInputError,
    check_bench,
    check_results,
    check_sweep,
    load_json,
)
from crosscheck.report.html import render_html
from crosscheck.report.junit import render_junit
from crosscheck.report.markdown import render_md

__all__ = [
    "ReportInputError",
    "check_bench",
    "check_results",
    "check_sweep",
    "generate",
    "load_json",
    "render_html",
    "render_junit",
    "render_md",
    "write_report",
]

# ---- entry points ----------------------------------------------------------------------------


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


def cmd_report(args) -> int:
    results_path = args.results
    sweep_path = getattr(args, "sweep", None)
    if results_path is None:
        results_path = DEFAULT_RESULTS
        if not Path(results_path).is_file():
            if args.bench is None and sweep_path is None:
                raise ReportInputError(
                    f"no results file: {DEFAULT_RESULTS} does not exist "
                    f"(run `crosscheck run` first, or give --results FILE)"
                )
            results_path = None  # a benchmark-only report
    bench_path = args.bench
    if bench_path is None and results_path is not None:
        beside = Path(results_path).parent / "bench.json"  # the same --out of run and bench
        if beside.is_file():
            bench_path = str(beside)
    if sweep_path is None and results_path is not None:
        beside = Path(results_path).parent / "sweep.json"  # the same --out of run and sweep
        if beside.is_file():
            sweep_path = str(beside)
    out_dir = args.out or str(Path(results_path or bench_path or sweep_path).parent)
    from crosscheck.commands.arguments import output_dir

    output_dir(out_dir)
    paths = generate(results_path, bench_path, out_dir, sweep_path)
    print("crosscheck report: " + ", ".join(str(p) for p in paths.values()))
    return 0


def register(sub):
    r = sub.add_parser(
        "report",
        help="HTML, Markdown and JUnit reports from results/bench JSON",
        description="Write DIR/index.html (self-contained), DIR/report.md and "
        "DIR/junit.xml from a results.json and an optional bench.json.",
    )
    r.add_argument(
        "--results",
        default=None,
        metavar="FILE",
        help=f"results.json from `crosscheck run` (default: {DEFAULT_RESULTS})",
    )
    r.add_argument(
        "--bench",
        default=None,
        metavar="FILE",
        help="bench.json from `crosscheck bench` (default: bench.json beside the "
        "results file, when it exists)",
    )
    r.add_argument(
        "--sweep",
        default=None,
        metavar="FILE",
        help="sweep.json from `crosscheck sweep`: error histograms per quantity "
        "(default: sweep.json beside the results file, when it exists)",
    )
    r.add_argument(
        "--out",
        default=None,
        metavar="DIR",
        help="output directory (default: the results file's directory)",
    )
    r.set_defaults(func=cmd_report)
