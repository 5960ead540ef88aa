"""`crosscheck sensitivity [MODELS] [--engines ...]`: the smallest error in each engine's model
that the suite catches, per parameter, written to DIR/sensitivity.json (the search:
crosscheck.checks.sensitivity).

Each evaluation builds the engine's model with one parameter changed by a relative amount and
repeats the instantaneous comparison at the consistent states `crosscheck run` uses, at the
model's generic parameter set (reference/generic.py). A parameter whose 10 % change moves no
compared figure is searched with the trajectory comparison instead when it changes the engine's
model (its fingerprint: exudyn's and OpenSim's pendulum_xy rod length, which only a run's drift
sees), and is otherwise reported as not used by the engine's model, with that reason.
"""

from __future__ import annotations

import json
import sys
import time

from crosscheck.checks.sensitivity import DECADES, STATES, Threshold, engine_thresholds

DEFAULT_MODELS = ("pendulum_xy", "slider_crank", "double_pendulum_3d")


def cmd_sensitivity(args) -> int:
    from crosscheck.commands.arguments import output_dir, resolve_engines, resolve_models
    from crosscheck.runtime.output import write_atomic

    files = getattr(args, "user_models", None)
    names = resolve_models(args.models, files) if args.models or files else list(DEFAULT_MODELS)
    engines = resolve_engines(args.engines)  # unknown or unimportable: exit 2, before any work
    out = output_dir(args.out)  # an unusable --out fails now, not after the search
    t0 = time.perf_counter()
    rows: list[Threshold] = []
    for name in names:
        for engine in engines:
            rows += engine_thresholds(name, engine, args.states)
    blocks = _derivative_rows(names, engines, args.states) if args.derivatives else []
    doc = {
        "command": "crosscheck " + " ".join(sys.argv[1:]),
        "decades": [10.0**k for k in DECADES],
        "states_per_model": args.states,
        "wall_s": time.perf_counter() - t0,
        "thresholds": [r.to_json() for r in rows],
    }
    if args.derivatives:
        doc["derivative_thresholds"] = [r.to_json() for r in blocks]
    write_atomic(out / "sensitivity.json", json.dumps(doc, indent=2))
    for r in rows:
        at = f"{r.caught_at:.0e}" if r.caught_at is not None else "NOT CAUGHT"
        print(
            f"{r.model:20s} {r.engine:10s} {r.parameter:8s} {at:>10s}  "
            f"{r.failing_check or r.reason}"
        )
    for b in blocks:
        at = f"{b.caught_at:.0e}" if b.caught_at is not None else "NOT SEARCHED"
        which = f"{b.engine}/{b.variant}" if b.variant else b.engine
        print(f"{b.model:20s} {which:15s} {b.quantity:26s} {at:>12s}  {b.reason}")
    print(
        f"crosscheck sensitivity: {len(rows)} parameters"
        + (f", {len(blocks)} derivative blocks" if args.derivatives else "")
        + f" in {doc['wall_s']:.1f} s -> {out / 'sensitivity.json'}"
    )
    return 0


def _derivative_rows(names, engines, n_states) -> list:
    """The smallest relative error in each block of each engine's derivatives that the
    derivatives records catch (crosscheck.checks.derivatives.sensitivity)."""
    from crosscheck.checks.derivatives.sensitivity import derivative_thresholds

    return [b for n in names for e in engines for b in derivative_thresholds(n, e, n_states)]


def register(sub) -> None:
    s = sub.add_parser(
        "sensitivity", help="smallest relative parameter error in each engine the suite catches"
    )
    from crosscheck.commands.arguments import add_engines, add_model_files, states_count

    s.add_argument(
        "models",
        nargs="*",
        help=f"models (default: the --model-file models, else {', '.join(DEFAULT_MODELS)})",
    )
    add_model_files(s)
    add_engines(s)
    s.add_argument(
        "--states", type=states_count, default=STATES, help="consistent states per model"
    )
    s.add_argument("--out", default="out", help="directory for sensitivity.json")
    s.add_argument(
        "--derivatives",
        action="store_true",
        help="also the smallest relative error in each block of each engine's derivatives "
        "(du'/dq ... dlambda/dtau) the derivatives records catch",
    )
    s.set_defaults(func=cmd_sensitivity)
