"""`crosscheck sensitivity [MODELS] [--engines ...]`: the smallest error in each engine's model
that the suite catches, per parameter (see crosscheck/checks/sensitivity.py for the search).

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
from pathlib import Path

from crosscheck.checks.sensitivity import DECADES, Threshold, search

DEFAULT_MODELS = ("pendulum_xy", "slider_crank", "double_pendulum_3d")
# "caught" means the suite's own verdict: some instantaneous record fails its tolerance
STATES = 3


def _engine_figures(name, nm, states, adapter, perturb) -> tuple[str, dict[str, float]]:
    """(first failing record, every record's error) of one engine at the states."""
    from crosscheck.checks.instantaneous import (
        engine_records,  # the one comparison of `crosscheck run`
    )
    from crosscheck.checks.perturb import perturbed

    params = perturbed(name, nm.params, perturb)
    recs = [
        r
        for variant in adapter.variants(name)
        for r in engine_records(name, nm, states, adapter, params, variant)
    ]
    figures = {f"{r['check']}/{r['quantity']}": r["error"] for r in recs if r["error"] is not None}
    return _first_failing(recs, adapter.name), figures


def _first_failing(recs, engine: str) -> str:
    """ "model/engine/check/quantity" of the engine's first failing record, or ""."""
    return next(
        (
            f"{r['model']}/{r['engine']}/{r['check']}/{r['quantity']}"
            for r in recs
            if r["engine"] == engine and r["passed"] is False
        ),
        "",
    )


def engine_thresholds(name: str, engine: str, n_states: int = STATES) -> list[Threshold]:
    """One threshold per parameter of the model, for one engine."""
    from crosscheck.engines.base import EngineUnsupported
    from crosscheck.engines.registry import get_engine
    from crosscheck.run.checks import consistent_states, generic_model

    adapter = get_engine(engine)
    nm = generic_model(name)
    states = consistent_states(nm, n_states)
    params = [p.name for p in nm.model.parameters]
    try:
        failing, base = _engine_figures(name, nm, states, adapter, {})
    except EngineUnsupported as exc:
        return [
            search(name, engine, p, lambda rel: "", f"engine cannot represent the model: {exc}")
            for p in params
        ]
    if failing:
        return [
            search(
                name,
                engine,
                p,
                lambda rel: "",
                f"the unperturbed comparison already fails ({failing})",
            )
            for p in params
        ]
    out, trajectory_base = [], {}
    for p in params:
        sign, k, moved, refused = _largest_change(name, nm, states, adapter, p)
        if moved is None:
            out.append(
                search(
                    name,
                    engine,
                    p,
                    lambda rel: "",
                    f"the engine refuses every change of it: {refused}",
                )
            )
            continue

        def evaluate(rel, p=p, sign=sign):
            return _engine_figures(name, nm, states, adapter, {p: sign * rel})[0]

        if moved != base:
            out.append(search(name, engine, p, evaluate, largest=k))
        elif _changes_model(name, nm, adapter, p, sign * 10.0**k):
            out.append(_trajectory_threshold(name, adapter, p, sign, k, trajectory_base))
        else:
            out.append(search(name, engine, p, evaluate, _unused_reason(sign * 10.0**k)))
    return out


def _changes_model(name, nm, adapter, p, rel) -> bool:
    """A change `rel` of `p` alters the engine's model (its fingerprint) in some variant."""
    from crosscheck.checks.instantaneous import build
    from crosscheck.checks.perturb import perturbed

    try:
        return any(
            build(adapter, name, nm.params, v).fingerprint()
            != build(adapter, name, perturbed(name, nm.params, {p: rel}), v).fingerprint()
            for v in adapter.variants(name)
        )
    except NotImplementedError:  # no fingerprint: the figures are all there is to go by
        return False


def _unused_reason(rel: float) -> str:
    return (
        f"not used by the engine's model: a {rel:.0e} change moves no compared figure "
        "(the engine's coordinates or loads do not contain it)"
    )


def _trajectory_threshold(name, adapter, p, sign, k, base: dict) -> Threshold:
    """The threshold of a parameter in the engine's model that no instantaneous check sees
    (exudyn's and OpenSim's pendulum_xy rod length: the distance constraint's length, on which
    the acceleration-level rows at a consistent state do not depend): the decades are searched
    with the trajectory comparison `crosscheck run` makes, at the textbook defaults and over
    its T_END (a run costs ~0.4 s, so no shorter horizon is needed); "caught" means one of the
    engine's trajectory records fails. `base` caches the unperturbed run's verdict per
    model and engine (computed on first use)."""
    from crosscheck.checks.perturb import perturbed
    from crosscheck.checks.trajectory.check import T_END, trajectory_records
    from reference import NumericModel, models

    nm = NumericModel(models.get(name))  # the parameters of `crosscheck run`'s trajectories

    def evaluate(rel: float) -> str:
        params = perturbed(name, nm.params, {p: sign * rel})
        recs, _ = trajectory_records(name, nm, [adapter], T_END, {adapter.name: params})
        return _first_failing(recs, adapter.name)

    how = (
        f"no instantaneous check sees it (a change alters the engine's model, its fingerprint, "
        f"but no compared figure at the consistent states), so the trajectory comparison of "
        f"`crosscheck run {name} --engines {adapter.name} --perturb {adapter.name}:{p}=REL` "
        f"was searched: {T_END:g} s from the model's initial state at its textbook defaults"
    )
    key = (name, adapter.name)
    if key not in base:
        base[key] = evaluate(0.0)
    if base[key]:
        reason = f"{how}; the unperturbed trajectory comparison already fails ({base[key]})"
        return search(name, adapter.name, p, evaluate, reason, comparison="trajectory")
    return search(name, adapter.name, p, evaluate, largest=k, comparison="trajectory", how=how)


def _largest_change(name, nm, states, adapter, p):
    """(sign, decade, figures there, refusal) of the largest change the engine accepts: an
    increase of 10 % first, else a decrease, else smaller decades (a principal inertia at the
    edge of the triangle inequality admits only small changes)."""
    refused = ""
    for k in reversed(DECADES):
        for sign in (1.0, -1.0):
            try:
                _, moved = _engine_figures(name, nm, states, adapter, {p: sign * 10.0**k})
                return sign, k, moved, ""
            except ValueError as exc:  # the engine's own refusal of the changed model
                refused = str(exc).splitlines()[0]
    return 1.0, DECADES[0], None, refused


def cmd_sensitivity(args) -> int:
    from crosscheck.commands.arguments import name_list, resolve_models
    from crosscheck.engines.registry import available_engines

    names = resolve_models(args.models) if args.models else list(DEFAULT_MODELS)
    engines = name_list(args.engines) if args.engines else list(available_engines())
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    rows: list[Threshold] = []
    for name in names:
        for engine in engines:
            rows += engine_thresholds(name, engine, args.states)
    doc = {
        "command": "crosscheck " + " ".join(sys.argv[1:]),
        "decades": [10.0**k for k in DECADES],
        "states_per_model": args.states,
        "wall_s": time.perf_counter() - t0,
        "thresholds": [r.to_json() for r in rows],
    }
    (out / "sensitivity.json").write_text(json.dumps(doc, indent=2))
    for r in rows:
        at = f"{r.caught_at:.0e}" if r.caught_at is not None else "NOT CAUGHT"
        print(
            f"{r.model:20s} {r.engine:10s} {r.parameter:8s} {at:>10s}  "
            f"{r.failing_check or r.reason}"
        )
    print(
        f"crosscheck sensitivity: {len(rows)} parameters in {doc['wall_s']:.1f} s -> "
        f"{out / 'sensitivity.json'}"
    )
    return 0


def register(sub) -> None:
    s = sub.add_parser(
        "sensitivity", help="smallest relative parameter error in each engine the suite catches"
    )
    s.add_argument("models", nargs="*", help=f"models (default: {', '.join(DEFAULT_MODELS)})")
    s.add_argument("--engines", default=None, help="comma-separated (default: every engine)")
    s.add_argument("--states", type=int, default=STATES, help="consistent states per model")
    s.add_argument("--out", default="out", help="directory for sensitivity.json")
    s.set_defaults(func=cmd_sensitivity)
