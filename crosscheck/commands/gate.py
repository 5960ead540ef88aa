"""`crosscheck gate`: a fresh results.json (and bench.json) against a committed baseline; the
rules are crosscheck.gate's."""

from __future__ import annotations

import math
import shlex
import sys
from pathlib import Path

from crosscheck.gate import (
    FACTOR,
    ROUND_OFF_FLOOR,
    TIMING_BAND,
    GateInputError,
    compare,
    fmt,
    load_baseline,
    make_baseline,
    record_key,
    verdict,
)
from crosscheck.report.inputs import check_bench, check_results, load_json
from crosscheck.runtime import jsonio
from crosscheck.runtime.output import write_atomic


def _print_list(title: str, items: list[str], stream=None):
    if items:
        print(f"{title} ({len(items)}):", file=stream or sys.stdout)
        for it in items:
            print(f"  {it}", file=stream or sys.stdout)


def _update(args, results, bench, baseline_path: Path) -> int:
    """`--update`: write the baseline from these results, listing what changed against the old."""
    from crosscheck.commands.arguments import output_dir

    if baseline_path.is_dir():
        raise GateInputError(
            f"--baseline {args.baseline!r} is a directory; give the "
            f"baseline file's path (e.g. reports/baseline.json)"
        )
    output_dir(str(baseline_path.parent), "--baseline")  # writable, before the comparison
    old = load_baseline(args.baseline) if baseline_path.exists() else None
    argv = ["crosscheck", "gate", "--baseline", args.baseline, "--results", args.results]
    if args.bench:
        argv += ["--bench", args.bench]
    new = make_baseline(results, bench, shlex.join([*argv, "--update"]))
    if old is None:
        print(
            f"crosscheck gate: created baseline {args.baseline} with "
            f"{len(new['records'])} records"
            + (
                f", {len(new['bench']['timing_ratios'])} timing ratios and "
                f"{len(new['bench']['work_precision'])} work-precision rows"
                if bench is not None
                else ""
            )
        )
        _print_list(
            "failing, accepted as known failures",
            [
                f"{record_key(r)}: error {fmt(r.get('error'))} > tolerance "
                f"{fmt(r.get('tolerance'))}"
                for r in new["records"]
                if verdict(r) == "failed"
            ],
        )
    else:
        o = compare(
            old, results, bench, args.factor, args.floor, args.timing_band, accept_new=True
        )  # what is new is listed as new, not as a regression
        if bench is None and old.get("bench"):
            new["bench"] = old["bench"]  # keep the benchmark part: not re-measured here
            new["meta"]["bench_meta"] = old.get("meta", {}).get("bench_meta", {})
        changed = o.regressions + o.improvements + o.accepted
        print(
            f"crosscheck gate: updating baseline {args.baseline}: {len(old['records'])} "
            f"-> {len(new['records'])} records; what changed against the old baseline:"
        )
        _print_list("would have been regressions", o.regressions)
        _print_list("improvements", o.improvements)
        _print_list("new", o.accepted)
        _print_list("still failing", o.known_failures)
        if not changed:
            print("  nothing beyond the gate's factor and floor (figures refreshed)")
    write_atomic(baseline_path, jsonio.dumps(new) + "\n")
    return 0


def cmd_gate(args) -> int:
    for name, value, lo in (
        ("--factor", args.factor, 1.0),
        ("--timing-band", args.timing_band, 1.0),
        ("--floor", args.floor, 0.0),
    ):
        if not (math.isfinite(value) and value >= lo):
            raise GateInputError(f"{name} {value!r}: must be a finite number >= {lo:g}")
    results = check_results(load_json(args.results, "results"), args.results)
    bench = check_bench(load_json(args.bench, "bench"), args.bench) if args.bench else None
    baseline_path = Path(args.baseline)
    if args.update:
        return _update(args, results, bench, baseline_path)
    if not baseline_path.exists():
        raise GateInputError(
            f"baseline file {args.baseline!r} not found (create it "
            f"deliberately with `crosscheck gate --baseline {args.baseline} "
            f"--results {args.results} --update`)"
        )
    baseline = load_baseline(args.baseline)
    o = compare(
        baseline, results, bench, args.factor, args.floor, args.timing_band, args.accept_new
    )
    _print_list("REGRESSIONS", o.regressions)
    _print_list("known failures (failing in the baseline too)", o.known_failures)
    _print_list("improvements (run --update to keep them)", o.improvements)
    _print_list(
        "not in the baseline, accepted by --accept-new (run --update to gate them)", o.accepted
    )
    for n in o.notes:
        print(f"note: {n}")
    n_old = len(baseline.get("records", []))
    rule = f"factor {args.factor:g}, round-off floor {args.floor:g}" + (
        f", timing band {args.timing_band:g}x" if bench is not None else ""
    )
    if o.regressions:
        print(
            f"crosscheck gate: {len(o.regressions)} regressions against {args.baseline} "
            f"({n_old} baseline records; {rule})"
        )
        return 1
    print(
        f"crosscheck gate: no regressions against {args.baseline} ({n_old} baseline records; "
        f"{rule})"
    )
    return 0


def register(sub):
    g = sub.add_parser(
        "gate",
        help="fail on regressions against a committed baseline",
        description="Exit 0 when nothing regressed against the baseline, 1 with "
        "the list of regressions, 2 on usage errors.",
    )
    g.add_argument(
        "--baseline",
        required=True,
        metavar="FILE",
        help="baseline JSON (reports/baseline.json; a results.json also works)",
    )
    g.add_argument(
        "--results", required=True, metavar="FILE", help="results.json of a fresh `crosscheck run`"
    )
    g.add_argument(
        "--bench",
        default=None,
        metavar="FILE",
        help="bench.json of the same revision: gates work-precision accuracy and "
        "same-run timing ratios",
    )
    g.add_argument(
        "--update",
        action="store_true",
        help="rewrite the baseline from these results (deliberately), printing what changed",
    )
    g.add_argument(
        "--accept-new",
        action="store_true",
        help="records the baseline lacks pass (listed as accepted) instead of "
        "failing the gate; a new record that fails still fails it",
    )
    g.add_argument(
        "--factor",
        type=float,
        default=FACTOR,
        help=f"an accuracy figure may worsen by this factor (default {FACTOR:g})",
    )
    g.add_argument(
        "--floor",
        type=float,
        default=ROUND_OFF_FLOOR,
        help=f"figures below this are round-off and compare as equal (default {ROUND_OFF_FLOOR:g})",
    )
    g.add_argument(
        "--timing-band",
        type=float,
        default=TIMING_BAND,
        help=f"a same-run timing ratio may grow by this factor (default {TIMING_BAND:g})",
    )
    g.set_defaults(func=cmd_gate)
