"""`crosscheck sweep`: seeded random campaigns of the instantaneous cross-checks, at scale.

What a campaign samples, checks and writes, its executors, resume and exit status: docs/cli.md,
"sweep". The campaign's machinery is crosscheck.sweep; this module is the command line."""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

from crosscheck.checks.perturb import parse_perturb
from crosscheck.runtime import jsonio
from crosscheck.sweep.bench import bench, print_bench
from crosscheck.sweep.campaign import campaign
from crosscheck.sweep.config import (
    WORST_CASES,
    Campaign,
)
from reference.errors import ModelInputError


# ---- command line ---------------------------------------------------------------------------
def _print_summary(res: dict, path: Path) -> None:
    st = res["status"]
    for r in res["results"]:
        if r.get("outside_tolerance"):
            w = r["worst"][0] if r["worst"] else {}
            print(
                f"OUTSIDE {r['model']} {r['engine']}{'/' + r['variant'] if r['variant'] else ''}"
                f" {r['quantity']}: {r['outside_tolerance']} of {r['count']} samples > "
                f"{r['tolerance']:.0e} (max {r['max']:.3e}); reproduce the worst: "
                f"{w.get('reproduce', {}).get('sweep', '')}",
                file=sys.stderr,
            )
    for g in res["faults"]["groups"]:
        print(
            f"FAULT {g['model']} {g['engine']}{'/' + g['variant'] if g['variant'] else ''} "
            f"{g['stage']} {g['type']} x{g['count']}: {g['first_reason'][:160]}",
            file=sys.stderr,
        )
    for c in res["faults"]["chunks"]:
        print(
            f"CHUNK FAILED {c['model']} [{c['start']}, {c['stop']}): {c['type']} "
            f"{c['reason'][:160]}",
            file=sys.stderr,
        )
    total = sum(st["completed"].values())
    requested = sum(st["requested"].values())
    print(
        f"crosscheck sweep: {total} of {requested} samples, {st['outside_tolerance']} "
        f"outside tolerance, {st['faults']} faults"
        + (f", stopped: {st['stopped']}" if st["stopped"] else "")
        + f" -> {path}"
    )


def _user_models_here(args, names) -> None:
    """User models (--model-file) are registered in this process only: their samples run
    here (--workers 1); Dask workers elsewhere could not load the files."""
    from reference import models

    if not set(names) & set(models.user_names()):
        return
    if args.dask is not None:
        raise ModelInputError(
            "--model-file models run in this process only; leave out --dask "
            "(the workers would not have the file's models)"
        )
    args.workers = 1


def cmd_sweep(args) -> int:
    from crosscheck.commands.arguments import output_dir, resolve_engines, resolve_models
    from crosscheck.runtime.output import write_atomic
    from crosscheck.sweep.store import ChunkStore

    if args.workers is not None and args.dask is not None:
        raise ModelInputError("give --workers or --dask, not both")
    if args.resume is not None:
        cfg, out = _resumed_campaign(args)
    else:
        names = resolve_models(args.models, getattr(args, "user_models", None))
        engines = tuple(resolve_engines(args.engines))
        _user_models_here(args, names)
        out = output_dir(args.out)  # an unusable --out fails now, not after the campaign
        if args.bench:
            return _cmd_bench(args, names, engines, out)
        given = _campaign_values(args)
        cfg = Campaign(
            list(names),
            given["samples"],
            given["seed"],
            given["index"],
            engines,
            parse_perturb(args.perturb),
            args.formulation,
            given["worst"],
            str(out),
            bool(args.derivatives),
        )
    bar = None
    if sys.stderr.isatty():
        from tqdm import tqdm

        bar = tqdm(
            total=cfg.samples * len(cfg.models), desc="samples", unit="sample", file=sys.stderr
        )
    store = ChunkStore(out, cfg)
    try:
        res = campaign(
            cfg,
            workers=args.workers,
            dask=args.dask,
            chunk=args.chunk,
            max_seconds=args.max_seconds,
            progress=bar.update if bar else None,
            store=store,
            resume=args.resume is not None,
        )
    finally:
        if bar:
            bar.close()
    # written after a Ctrl-C too: its status says "interrupted" and what was completed
    path = write_atomic(out / "sweep.json", jsonio.dumps(res), after_interrupt=True)
    _print_summary(res, path)
    if res["status"]["complete"]:
        store.remove()  # after sweep.json is in place: nothing left to resume
    else:
        print(
            f"finished chunks kept in {store.dir}; continue with: "
            f"{shlex.join(['crosscheck', 'sweep', '--resume', str(out)])}"
        )
    return exit_code(res["status"])


# campaign options of the command line and their defaults. The parser leaves them None (or
# empty) when they are not given, so that under --resume a given option, even one equal to its
# default, is compared with the stored campaign and refused where it differs
_CAMPAIGN_DEFAULTS = {"samples": 100, "seed": 0, "index": 0, "worst": WORST_CASES}
_CAMPAIGN_OPTIONS = ("models", "samples", "seed", "index", "engines", "perturb", "formulation")
_CAMPAIGN_OPTIONS += ("worst", "derivatives")


def _campaign_values(args) -> dict:
    """The counts of a new campaign: the given ones, else their defaults."""
    return {
        k: getattr(args, k) if getattr(args, k) is not None else v
        for k, v in _CAMPAIGN_DEFAULTS.items()
    }


def _resumed_campaign(args):
    """The campaign stored in --resume DIR; options that contradict it are refused."""
    from crosscheck.commands.arguments import output_dir
    from crosscheck.sweep.store import stored_settings

    if args.bench:
        raise ModelInputError(
            "--resume continues a campaign; --bench measures throughput: give one of them"
        )
    out = output_dir(args.resume, "--resume")
    if args.out not in ("out", args.resume):
        raise ModelInputError(f"--resume {args.resume!r} writes there; drop --out {args.out!r}")
    st = stored_settings(out)
    given = {"perturb": parse_perturb(args.perturb)}
    for key in _CAMPAIGN_OPTIONS:
        value = getattr(args, key)
        if value is None or value == []:  # not given
            continue
        stored = st.get(key, False)  # a campaign stored before --derivatives existed: off
        if given.get(key, value) != stored:
            raise ModelInputError(
                f"--resume {args.resume!r} continues the campaign stored there ({key} "
                f"{stored!r}); drop --{key} {value!r} or start a new campaign with --out"
            )
    cfg = Campaign(
        list(st["models"]),
        st["samples"],
        st["seed"],
        st["index"],
        tuple(st["engines"]),
        st["perturb"],
        st["formulation"],
        st["worst"],
        str(out),
        bool(st.get("derivatives", False)),
    )
    return cfg, out


def _cmd_bench(args, names, engines, out) -> int:
    from crosscheck.runtime.output import write_atomic

    given = _campaign_values(args)
    cfg = Campaign(list(names), given["samples"], given["seed"], given["index"], engines)
    cfg.validate()
    b = bench(
        names,
        given["samples"],
        given["seed"],
        engines,
        log=lambda m: print(m, file=sys.stderr, flush=True),
    )
    write_atomic(out / "sweep_bench.json", jsonio.dumps(b))
    print_bench(b)
    print(f"wrote {out / 'sweep_bench.json'}")
    return 0


def exit_code(status: dict) -> int:
    """130 when interrupted, 1 when a sample failed a check or faulted, 4 when the campaign
    stopped early (time budget) with nothing failed in what it ran, 0 when it passed."""
    from crosscheck.cli import EXIT_INCOMPLETE, EXIT_INTERRUPTED, EXIT_TERMINATED
    from crosscheck.runtime import interrupts

    if status["stopped"] == "interrupted":
        return EXIT_TERMINATED if interrupts.terminated() else EXIT_INTERRUPTED
    return {"passed": 0, "failed": 1}.get(status["verdict"], EXIT_INCOMPLETE)


def register(sub):
    from crosscheck.commands.arguments import (
        MAX_INDEX,
        MAX_SAMPLES,
        add_engines,
        add_models,
        at_most,
        nonnegative_int,
        positive_int,
    )

    s = sub.add_parser(
        "sweep",
        help="seeded random campaigns of the cross-checks (local workers or Dask)",
        description="Draw N seeded random parameter sets and consistent states per model, run "
        "the instantaneous cross-checks on each, write DIR/sweep.json.",
    )
    add_models(s)
    s.add_argument(
        "--samples", type=positive_int, default=None, help="samples per model (default 100)"
    )
    s.add_argument("--seed", type=nonnegative_int, default=None, help="campaign seed (default 0)")
    s.add_argument(
        "--index",
        type=at_most(nonnegative_int, MAX_INDEX, "sweep.json keeps indices below 2**53"),
        default=None,
        help="first sample index (default 0): --index I --samples 1 reruns sample I",
    )
    add_engines(s)
    s.add_argument(
        "--formulation", default=None, help="reference formulation (default: each model's first)"
    )
    s.add_argument(
        "--perturb",
        action="append",
        default=[],
        metavar="ENGINE:PARAM=REL",
        help="fault injection, as in crosscheck run",
    )
    _add_execution(s)
    s.add_argument(
        "--worst",
        type=at_most(nonnegative_int, MAX_SAMPLES, "the samples a campaign keeps"),
        default=None,
        help=f"worst cases kept per quantity (default {WORST_CASES})",
    )
    s.add_argument(
        "--derivatives",
        action="store_const",
        const=True,
        default=None,
        help="also the derivatives comparison at each sample (error over its derived tolerance)",
    )
    s.add_argument(
        "--bench",
        action="store_true",
        help="measure throughput (per model and engine, 1 vs 2 workers) and write "
        "DIR/sweep_bench.json instead of running a campaign",
    )
    s.add_argument("--out", default="out")
    s.add_argument(
        "--resume",
        default=None,
        metavar="DIR",
        help="continue the interrupted campaign whose --out was DIR: its finished "
        "chunks (DIR/sweep.chunks) are kept, only the rest is computed",
    )
    s.set_defaults(func=cmd_sweep)


def _add_execution(s) -> None:
    """Where and for how long a campaign runs: none of it changes the results."""
    from crosscheck.commands.arguments import (
        MAX_SAMPLES,
        at_most,
        positive_int,
        positive_seconds,
        processes,
    )

    s.add_argument(
        "--workers",
        type=processes,
        default=None,
        help="local worker processes (default: all cores; 1 runs in this process)",
    )
    s.add_argument(
        "--dask",
        default=None,
        metavar="ADDRESS",
        help="run on a Dask distributed scheduler (tcp://host:8786), or local[:K]",
    )
    s.add_argument(
        "--chunk",
        type=at_most(positive_int, MAX_SAMPLES, "the samples a campaign keeps in memory"),
        default=None,
        help="samples per task (default: sized per executor)",
    )
    s.add_argument(
        "--max-seconds",
        type=positive_seconds,
        default=None,
        help="time budget: stop and report what is done",
    )
