"""`crosscheck run`: the reference against Pinocchio and MuJoCo, stage by stage, then in time.

Writes DIR/results.json = {"meta": {...}, "records": [...]} (see crosscheck.compare for the
record fields). Exit 0 when every executed record passes, 1 when any fails, 2 on usage errors.
`--perturb ENGINE:PARAM=REL` changes one parameter of one engine's model by a relative amount
(fault injection: a run with mujoco:m2=1e-6 on the slider-crank must fail).
"""
from __future__ import annotations

import json
import sys
import zlib
from pathlib import Path

import numpy as np

from reference import NumericModel, models
from reference.errors import ModelInputError

from . import compare as C
from .engines.base import EngineUnsupported

ENGINE_NAMES = ("pinocchio", "mujoco")


def engine_adapter(name: str):
    if name == "pinocchio":
        from .engines.pinocchio_engine import PinocchioAdapter
        return PinocchioAdapter()
    if name == "mujoco":
        from .engines.mujoco_engine import MujocoAdapter
        return MujocoAdapter()
    raise ModelInputError(f"unknown engine {name!r}; valid: {', '.join(ENGINE_NAMES)}")


def parse_perturb(specs: list[str]) -> dict[str, dict[str, float]]:
    """['mujoco:m2=1e-6'] -> {'mujoco': {'m2': 1e-6}}."""
    out: dict[str, dict[str, float]] = {}
    for spec in specs or []:
        try:
            engine, rest = spec.split(":", 1)
            param, rel = rest.split("=", 1)
            out.setdefault(engine.strip(), {})[param.strip()] = float(rel)
        except ValueError:
            raise ModelInputError(f"--perturb {spec!r}: expected ENGINE:PARAM=REL, "
                                  f"e.g. mujoco:m2=1e-6")
        if engine.strip() not in ENGINE_NAMES:
            raise ModelInputError(f"--perturb {spec!r}: unknown engine {engine!r}; valid: "
                                  f"{', '.join(ENGINE_NAMES)}")
    return out


def check_perturb(names, perturb: dict) -> None:
    """Before any work: every perturbed parameter exists in every model and stays valid
    (finite, positive where it must be) at the model's defaults -- a relative change of nan,
    or of -2 on a mass, is bad input (exit 2), found before the first model runs."""
    from reference.numeric import resolve_parameters
    for name in names:
        model = models.get(name)
        for ps in perturb.values():
            resolve_parameters(model, perturbed(
                name, {p.name: p.default for p in model.parameters}, ps))


def consistent_states(nm: NumericModel, count: int):
    """The model's initial state and count-1 seeded random consistent states near it.

    The seed is derived from the model name so every run draws the same states (deterministic
    results), and a state whose projection fails is replaced by the next draw.
    """
    rng = np.random.default_rng(zlib.crc32(nm.model.name.encode()))
    m = nm.model
    states = [nm.project(m.initial_q, m.initial_u)]
    tries = 0
    while len(states) < count and tries < 20 * count:
        tries += 1
        q = np.asarray(m.initial_q) + 0.4 * rng.standard_normal(len(m.initial_q))
        u = np.asarray(m.initial_u) + rng.standard_normal(len(m.initial_u))
        try:
            q, u = nm.project(q, u)
            nm.forward(q, u)
        except ModelInputError:
            continue
        states.append((q, u))
    return states


def _formulation_records(name, nm, states):
    """The reference's formulations against its primary one (Lagrange = d'Alembert = Kane)."""
    model = nm.model
    out = []
    dependent = dict(model.formulation_dependent_rows)
    keep = [j for j, c in enumerate(model.constraint_names or [""] * nm.m) if c not in dependent]
    tol = C.Tolerance(1e-11, "two derivations of the same equations evaluated in different "
                             "arithmetic order: round-off only")
    for other in model.formulations[1:]:
        on = NumericModel(model, other, nm.params)
        acc, lam = C.WorstCase(), C.WorstCase()
        for i, (q, u) in enumerate(states):
            a, b = nm.forward(q, u), on.forward(q, u)
            acc.add(C.scaled_error(b.accelerations, a.accelerations), i)
            lam.add(C.scaled_error(b.multipliers[keep], a.multipliers[keep]), i)
        out.append(C.record(name, other, "reference", "formulations", "accelerations",
                            acc.error, tol, worst_state=acc.state,
                            against=nm.formulation))
        if nm.m == 0:
            out.append(C.record(name, other, "reference", "formulations", "multipliers", None,
                                None, "no constraints, so no multipliers to compare"))
            continue
        reason = ""
        if dependent:
            reason = (tol.reason + "; rows not compared because their multiplier depends on "
                      "the formulation: " + "; ".join(f"{k}: {v}" for k, v in dependent.items()))
        out.append(C.record(name, other, "reference", "formulations", "multipliers",
                            lam.error, tol, reason, worst_state=lam.state, against=nm.formulation))
    return out


def _soft_check(worst, extras, quantity, raw_value, reference, predicted_error, i):
    """MuJoCo's raw soft answer: (raw - reference) should equal the predicted error."""
    miss, raw_err, pred = C.soft_prediction(raw_value, reference, predicted_error)
    worst[f"{quantity}_soft"].add(miss, i)
    extras["predicted_rel_error"].append(pred)
    extras["soft_error"].append(raw_err)


def perturbed(name, params: dict, perturb: dict) -> dict:
    """The parameters with the relative perturbations of one engine applied (fault injection)."""
    params = dict(params)
    for p, rel in perturb.items():
        if p not in params:
            raise ModelInputError(f"--perturb: model {name!r} has no parameter {p!r}; valid: "
                                  f"{', '.join(params)}")
        params[p] *= 1.0 + rel
    return params


def _engine_records(name, nm, states, adapter, perturb, variant=None):
    formulation = nm.formulation
    params = perturbed(name, nm.params, perturb)

    def rec(*a, **k):
        r = C.record(name, formulation, adapter.name, *a, **k)
        if variant is not None:  # e.g. Example 4 as a ball-joint tree or as free bodies
            r["variant"] = variant
        return r
    try:
        em = adapter.build(name, params, variant=variant) if variant else adapter.build(name, params)
    except EngineUnsupported as exc:
        return [rec("instantaneous", q, None, None, f"engine cannot represent the model: {exc}")
                for q in ("accelerations", "multipliers")]
    worst = {k: C.WorstCase() for k in ("state_map", "mass_matrix", "accelerations",
                                        "multipliers", "energy", "accelerations_rigid",
                                        "multipliers_rigid", "accelerations_soft",
                                        "multipliers_soft")}
    skipped: dict[str, str] = {}
    extras: dict[str, list] = {"iterations": [], "predicted_rel_error": [], "soft_error": []}
    for i, (q, u) in enumerate(states):
        ref = nm.forward(q, u)
        qe, ve = em.to_engine_state(q, u)
        q2, u2 = em.from_engine_state(qe, ve)
        worst["state_map"].add(max(C.scaled_error(q2, q), C.scaled_error(u2, u)), i)
        M_e = em.mass_matrix(q) if hasattr(em, "mass_matrix") else None
        if M_e is None:
            skipped["mass_matrix"] = getattr(em, "mass_matrix_note", None) or (
                "engine coordinates do not map one to one onto the reference's, so their mass "
                "matrices are not comparable")
        else:
            M_r, *_ = nm.matrices(q, u)
            worst["mass_matrix"].add(C.scaled_error(M_e, M_r), i)
        ef = em.forward(q, u)
        raw = ef.raw or {}
        if "iterations" in raw:
            extras["iterations"].append(int(raw["iterations"]))
        Ke, Ve = em.energy(q, u)
        Kr, Vr = nm.energy(q, u)
        worst["energy"].add(abs((Ke + Ve) - (Kr + Vr)) / max(abs(Kr) + abs(Vr), 1.0), i)
        # MuJoCo with equality rows: a soft answer, its rigid recovery and the predicted error
        soft = "rigid_accelerations" in raw and "predicted_acceleration_error" in raw
        err_acc = C.scaled_error(ef.accelerations, ref.accelerations)
        if nm.m == 0:
            skipped["multipliers"] = ("no constraints: the engine runs plain forward dynamics "
                                      "(ABA / unconstrained step), no multipliers to compare")
            err_lam = 0.0
        elif ef.multipliers is None:
            skipped["multipliers"] = raw.get("multipliers_note") or (
                "the engine model has no constraint forces that map onto the reference's rows")
            err_lam = 0.0
        else:
            err_lam = C.scaled_error(ef.multipliers, ref.multipliers)
        if soft:
            # MuJoCo: the rigid answer recovered from its own soft output must match exactly;
            # the raw soft answer must lie within what its impedance predicts
            worst["accelerations_rigid"].add(
                C.scaled_error(raw["rigid_accelerations"], ref.accelerations), i)
            pred_acc = np.asarray(raw["predicted_acceleration_error"], float)
            _soft_check(worst, extras, "accelerations", ef.accelerations, ref.accelerations,
                        pred_acc, i)
            if "multipliers" not in skipped:
                worst["multipliers_rigid"].add(
                    C.scaled_error(raw["rigid_multipliers"], ref.multipliers), i)
                _soft_check(worst, extras, "multipliers", ef.multipliers, ref.multipliers,
                            np.asarray(raw["predicted_multiplier_error"], float), i)
        else:
            worst["accelerations"].add(err_acc, i)
            if "multipliers" not in skipped:
                worst["multipliers"].add(err_lam, i)
    out = [rec("instantaneous", "state_map", worst["state_map"].error, C.STATE_MAP,
               worst_state=worst["state_map"].state)]
    if "mass_matrix" in skipped:
        out.append(rec("instantaneous", "mass_matrix", None, None, skipped["mass_matrix"]))
    else:
        out.append(rec("instantaneous", "mass_matrix", worst["mass_matrix"].error, C.MASS_MATRIX,
                       worst_state=worst["mass_matrix"].state))
    out.append(rec("instantaneous", "energy", worst["energy"].error, C.ENERGY,
                   worst_state=worst["energy"].state, metric="relative_energy_error"))
    it = {"iterations_max": max(extras["iterations"])} if extras["iterations"] else {}
    if extras["soft_error"]:
        soft = {"predicted_rel_error_max": float(max(extras["predicted_rel_error"])),
                "soft_rel_error_max": float(max(extras["soft_error"]))}
        for q in ("accelerations", "multipliers"):
            if q in skipped:
                out.append(rec("instantaneous", q, None, None, skipped[q]))
                continue
            w = worst[f"{q}_rigid"]
            out.append(rec("instantaneous", q, w.error, C.RIGID_RECOVERY, worst_state=w.state,
                           answer="rigid, recovered from MuJoCo's soft solution", **soft, **it))
            w = worst[f"{q}_soft"]
            out.append(rec("instantaneous", f"{q}_soft_vs_predicted", w.error,
                           C.SOFT_PREDICTION, worst_state=w.state, metric="relative_miss",
                           answer="raw soft answer: |(raw - reference) - predicted error| "
                                  "over |predicted error|", **soft))
    else:
        out.append(rec("instantaneous", "accelerations", worst["accelerations"].error,
                       C.exact_tolerance(adapter.name), worst_state=worst["accelerations"].state,
                       **it))
        if "multipliers" in skipped:
            out.append(rec("instantaneous", "multipliers", None, None, skipped["multipliers"]))
        else:
            out.append(rec("instantaneous", "multipliers", worst["multipliers"].error,
                           C.exact_tolerance(adapter.name), worst_state=worst["multipliers"].state,
                           **it))
    return out


def run(model_names, engine_names, n_states=6, perturb=None, progress=None,
        trajectories=True, t_end=5.0):
    """All records (and trajectory series) for the models; see the module docstring."""
    from .trajectory import trajectory_records
    perturb = perturb or {}
    adapters = [engine_adapter(e) for e in engine_names]
    records, series = [], []
    for name in model_names:
        model = models.get(name)
        nm = NumericModel(model)
        states = consistent_states(nm, n_states)
        records += _formulation_records(name, nm, states)
        for adapter in adapters:
            variants = adapter.variants(name) if hasattr(adapter, "variants") else (None,)
            for variant in variants:
                records += _engine_records(name, nm, states, adapter,
                                           perturb.get(adapter.name, {}), variant)
        if trajectories:
            engine_params = {a.name: perturbed(name, nm.params, perturb.get(a.name, {}))
                             for a in adapters}
            recs, ser = trajectory_records(name, nm, adapters, t_end, engine_params)
            records += recs
            series += ser
        else:  # skipped on request: visible in the results, not silently absent
            records.append(C.record(name, nm.formulation, "reference", "trajectory",
                                    "state_error", None, None,
                                    "instantaneous checks only (--instantaneous)"))
        if progress:
            progress(name)
    return records, series


def cmd_run(args) -> int:
    from .arguments import output_dir, resolve_engines, resolve_models
    from .bench import meta
    names = resolve_models(args.models)  # unknown or repeated names fail before any work
    engine_names = resolve_engines(args.engines)
    perturb = parse_perturb(args.perturb)
    check_perturb(names, perturb)
    output_dir(args.out)  # an unusable --out fails now, not after the computation
    bar = None
    if sys.stderr.isatty():  # progress only for a person at a terminal; CI logs stay quiet
        from tqdm import tqdm
        bar = tqdm(total=len(names), desc="models", unit="model", file=sys.stderr)
    records, series = run(names, engine_names, args.states, perturb,
                          progress=(lambda n: bar.update(1)) if bar else None,
                          trajectories=not args.instantaneous, t_end=args.t_end)
    if bar:
        bar.close()
    out = Path(args.out)
    result = {"meta": {**meta(sys.argv[1:]), "states_per_model": args.states,
                       "state_seed": "crc32 of the model name (crosscheck.run.consistent_states)",
                       "metrics": C.METRICS},
              "records": records, "series": series}
    _write_outputs(out, json.dumps(result, indent=2, allow_nan=True), not args.no_report)
    failed = [r for r in records if r["passed"] is False]
    skipped = [r for r in records if r["skipped"]]
    passed = sum(1 for r in records if r["passed"])
    for r in failed:
        print(f"FAIL {r['model']} {r['engine']} {r['check']} {r['quantity']}: error "
              f"{r['error']:.3e} > {r['tolerance']:.1e}", file=sys.stderr)
    print(f"crosscheck run: {passed} passed, {len(failed)} failed, {len(skipped)} skipped "
          f"-> {out / 'results.json'}" + ("" if args.no_report else f", {out / 'index.html'}"))
    return 1 if failed else 0


REPORT_FILES = ("index.html", "report.md", "junit.xml")


def _write_outputs(out: Path, results_text: str, report: bool) -> None:
    """results.json and the report, staged and renamed into place together: an interrupt leaves
    the previous run's files or this run's, never a mix; without the report, an old one is
    removed (it would describe other results)."""
    from .output import Outputs
    with Outputs(out) as staged:
        staged.stage("results.json", results_text)
        if report:  # the main job leaves a report a person can open
            from .report import generate
            bench = out / "bench.json"
            generate(str(out / "results.json"), str(bench) if bench.exists() else None,
                     str(out), outputs=staged, results_text=results_text)
        staged.commit(stale=REPORT_FILES)


def register(sub):
    from .arguments import MAX_T_END, add_engines, add_models, horizon, positive_int
    r = sub.add_parser("run", help="cross-check the reference against the engines")
    add_models(r)
    add_engines(r)
    r.add_argument("--out", default="out")
    r.add_argument("--perturb", action="append", default=[], metavar="ENGINE:PARAM=REL")
    r.add_argument("--states", type=positive_int, default=6, help="consistent states per model")
    r.add_argument("--instantaneous", action="store_true",
                   help="only the checks at consistent states, no trajectories")
    r.add_argument("--t-end", type=horizon, default=5.0,
                   help=f"trajectory length [s], > 0 and at most {MAX_T_END:g}")
    r.add_argument("--no-report", action="store_true",
                   help="write results.json only (no index.html / report.md / junit.xml)")
    r.set_defaults(func=cmd_run)
