"""`crosscheck run`: the reference against every engine, stage by stage, then in time (the
checks: crosscheck/run/checks.py).

Writes DIR/results.json (its schema: crosscheck/schema/results.schema.json, docs/results.md)
and the report beside it. Exit 0 when every executed record passes, 1 when any fails, 2 on
usage errors.
`--perturb ENGINE:PARAM=REL` changes one parameter of one engine's model by a relative amount
(fault injection: a run with mujoco:m2=1e-6 on the slider-crank must fail).

This module imports only the standard library and the suite's light modules at load, so the
command line can start the workers' server (start_workers_early) before it imports the
models and engines.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from crosscheck.run.jobs import WORKER_MODULES
from crosscheck.runtime import jsonio
from crosscheck.runtime.workers import default_workers, process_context


class _Quiet(argparse.ArgumentParser):
    """A parser that raises instead of printing: the full command line reports bad input."""

    def error(self, message: str):  # type: ignore[override]
        raise ValueError(message)


def start_workers_early(argv: list[str]) -> None:
    """Start the workers' server of a `crosscheck run` that will hand its models to workers,
    before the command line imports the models and engines (about 1 s, which the server
    imports too): the server's own imports (0.9-1.5 s) then run on the other core from the
    start. `argv` follows "run". Nothing starts here for a run that will not use workers (one
    model named, `--jobs 1`, one core), a --model-file run without names (how many models is
    not known yet), a request for help, or input the command will refuse: an argument the
    parser refuses, an unknown model or engine name. Refused input therefore never leaves a
    server behind; input refused later (a model file's contents) leaves the server to end by
    itself once its imports are done and it sees this process gone."""
    if "-h" in argv or "--help" in argv:
        return
    parser = _Quiet(prog="crosscheck", add_help=False)
    register(parser.add_subparsers(dest="command"))
    try:
        args, _unknown = parser.parse_known_args(["run", *argv])
    except Exception:  # anything the full parser will report (or a type check of ours)
        return
    several = len(set(args.models)) > 1 if args.models else not args.model_file
    if not (several and (args.jobs or default_workers()) > 1):
        return
    if _refused_names(args):
        return
    _start_server(args.engines)


def _refused_names(args) -> bool:
    """Whether the command will refuse a model or engine name (the registries list the names
    without importing a model or an engine)."""
    from crosscheck.engines.entry_points import entry_points
    from reference import models

    if args.models and not args.model_file and not set(args.models) <= set(models.names()):
        return True
    return bool(args.engines) and not set(args.engines) <= set(entry_points())


def _start_server(engines) -> None:
    """The workers' server, preloading the checks and the engines named (None: every one)."""
    process_context(*WORKER_MODULES, engines=engines or None)


def cmd_run(args) -> int:
    from crosscheck.checks import tolerances as C
    from crosscheck.checks.perturb import check_perturb, check_perturb_changes, parse_perturb
    from crosscheck.commands.arguments import output_dir, resolve_engines, resolve_models

    # unknown or repeated names fail before any work; none named: the --model-file models
    names = resolve_models(args.models, getattr(args, "user_models", None))
    jobs = min(args.jobs or default_workers(), len(names))
    if jobs > 1:  # started here unless start_workers_early did; a no-op then
        _start_server(args.engines)
    engine_names = resolve_engines(args.engines)
    perturb = parse_perturb(args.perturb)
    check_perturb(names, perturb)
    check_perturb_changes(names, engine_names, perturb)
    output_dir(args.out)  # an unusable --out fails now, not after the computation
    bar = None
    if sys.stderr.isatty():  # progress only for a person at a terminal; CI logs stay quiet
        from tqdm import tqdm

        bar = tqdm(total=len(names), desc="models", unit="model", file=sys.stderr)
    agreement: list[dict] = []
    progress = (lambda n: bar.update(1)) if bar else None
    records, series, provenance = _checks(
        args, names, engine_names, perturb, jobs, progress, agreement
    )
    if bar:
        bar.close()
    out = Path(args.out)
    result = {
        "meta": {
            **provenance,
            "states_per_model": args.states,
            "state_seed": "crc32 of the model name (crosscheck.checks.sampling.consistent_states)",
            "jobs": jobs,
            "metrics": C.METRICS,
        },
        "records": records,
        "series": series,
        "agreement": agreement,
    }
    _write_outputs(out, jsonio.dumps(result), not args.no_report)
    return _summary(records, out, args.no_report)


def _checks(args, names, engine_names, perturb, jobs, progress, agreement):
    """(records, series, meta) of the run: on `jobs` worker processes or in this one."""
    from crosscheck.runtime.provenance import meta

    if jobs <= 1:
        from crosscheck.run.checks import run

        records, series = run(
            names,
            engine_names,
            args.states,
            perturb,
            progress=progress,
            trajectories=not args.instantaneous,
            t_end=args.t_end,
            agreement=agreement,
            derivatives=args.derivatives,
        )
        return records, series, meta(sys.argv[1:])
    from crosscheck.run.jobs import ModelJob, run_models

    work = [
        ModelJob(
            n,
            tuple(engine_names),
            args.states,
            perturb,
            not args.instantaneous,
            args.t_end,
            derivatives=args.derivatives,
        )
        for n in names
    ]
    provenance: dict = {}
    records, series = run_models(
        work,
        jobs,
        tuple(args.model_file),
        progress,
        agreement,
        # meta's engine versions import every engine's adapter, also those this run does
        # not use (about 0.4 s): read while the hand-out waits for the workers' server
        meanwhile=lambda: provenance.update(meta(sys.argv[1:])),
        loading=(args.project, tuple(args.ctrl)),
    )
    return records, series, provenance


def _summary(records, out: Path, no_report: bool) -> int:
    """The failed records and the counts on the terminal; the exit status."""
    failed = [r for r in records if r["passed"] is False]
    skipped = [r for r in records if r["skipped"]]
    passed = sum(1 for r in records if r["passed"])
    for r in failed:
        # the reference failing its own trajectory checks: the run is too long for it to vouch
        own = r["engine"] == "reference" and r["check"] == "trajectory"
        print(
            f"FAIL {r['model']} {r['engine']} {r['check']} {r['quantity']}: error "
            f"{r['error']:.3e} > {r['tolerance']:.1e}"
            + (" (the horizon is the likely cause: rerun with a shorter --t-end)" if own else ""),
            file=sys.stderr,
        )
    print(
        f"crosscheck run: {passed} passed, {len(failed)} failed, {len(skipped)} skipped "
        f"-> {out / 'results.json'}" + ("" if no_report else f", {out / 'index.html'}")
    )
    return 1 if failed else 0


REPORT_FILES = ("index.html", "report.md", "junit.xml")


def _write_outputs(out: Path, results_text: str, report: bool) -> None:
    """results.json and the report, staged and renamed into place together: an interrupt leaves
    the previous run's files or this run's, never a mix; without the report, an old one is
    removed (it would describe other results)."""
    from crosscheck.runtime.output import Outputs

    with Outputs(out) as staged:
        staged.stage("results.json", results_text)
        if report:  # the main job leaves a report a person can open
            from crosscheck.report.write import generate

            bench = out / "bench.json"
            generate(
                str(out / "results.json"),
                str(bench) if bench.exists() else None,
                str(out),
                outputs=staged,
                results_text=results_text,
            )
        staged.commit(stale=REPORT_FILES)


def register(sub):
    from crosscheck.commands.arguments import (
        MAX_T_END,
        add_engines,
        add_models,
        horizon,
        processes,
        states_count,
    )

    r = sub.add_parser("run", help="cross-check the reference against the engines")
    add_models(r)
    add_engines(r)
    r.add_argument("--out", default="out")
    r.add_argument("--perturb", action="append", default=[], metavar="ENGINE:PARAM=REL")
    r.add_argument("--states", type=states_count, default=6, help="consistent states per model")
    r.add_argument(
        "--jobs",
        type=processes,
        default=None,
        help="worker processes, one model at a time each (default: the cores this process "
        "may use; 1 runs in this process). The records are the same either way",
    )
    r.add_argument(
        "--instantaneous",
        action="store_true",
        help="only the checks at consistent states, no trajectories",
    )
    r.add_argument(
        "--derivatives",
        action="store_true",
        help="also the derivatives of u' and lambda with respect to coordinates, speeds and "
        "applied forces: the reference's exact ones against its slow path and every engine's "
        "(docs/checks.md)",
    )
    r.add_argument(
        "--t-end",
        type=horizon,
        default=5.0,
        help=f"trajectory length [s], > 0 and at most {MAX_T_END:g}",
    )
    r.add_argument(
        "--no-report",
        action="store_true",
        help="write results.json only (no index.html / report.md / junit.xml)",
    )
    r.set_defaults(func=cmd_run)
