"""`crosscheck report`: the report of a results.json (+ bench.json, sweep.json) written into a
directory (crosscheck.report.write)."""

from __future__ import annotations

from pathlib import Path

from crosscheck.commands.arguments import add_model_files
from crosscheck.report.content import DEFAULT_RESULTS, ReportInputError
from crosscheck.report.write import generate


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
    add_model_files(r)
    r.set_defaults(func=cmd_report)
