"""One comparison path: the reference's answer against an engine's, state by state.

``compare_at_state`` compares one engine model with the reference at one consistent state and
returns the errors per quantity (the metrics and named tolerances of crosscheck.checks.tolerances);
``engine_records`` folds it over a run's states into results.json records (`crosscheck run`),
and `crosscheck sweep` aggregates the same per-state values over its samples. Each quantity's
tolerance is chosen once, by ``tolerance``.

Quantities: state_map (reference -> engine -> reference), mass_matrix (where the coordinates
map one to one), energy (``energy_error``), accelerations and multipliers. Along
trajectories: ``energy_drift``, ``work_energy_balance`` and ``constraint_residual``. An engine whose
answer is regularized at the state (``EngineForward.soft``) is held to its rigid recovery, and
its raw answer to the one predicted from the reference's answer and the engine's documented
regularization (``*_soft_vs_predicted``, Capabilities.soft_prediction: the prediction never
reads the engine's constraint solution, so a physics error shows there; the raw error itself
is ``*_soft_error``, reported, not judged).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from crosscheck.checks import tolerances as C
from crosscheck.checks.records import record
from crosscheck.engines.base import Capabilities, EngineAdapter, EngineModel, EngineUnsupported
from crosscheck.engines.registry import engine_label
from reference import models
from reference.errors import ModelInputError

NO_MASS_MATRIX = (
    "engine coordinates do not map one to one onto the reference's, so their "
    "mass matrices are not comparable"
)
NO_CONSTRAINTS = (
    "no constraints: the engine runs plain forward dynamics (ABA / unconstrained "
    "step), no multipliers to compare"
)
NO_FORCES = "the engine model has no constraint forces that map onto the reference's rows"
MASS_IN_ENGINE_SPEEDS = (
    "in the engine's own speeds: the engine's M against H^T M H, the reference's M mapped "
    "through the rate/velocity relation u = H v at the state (quaternion rates against "
    "angular velocities)"
)
SOFT_ANSWER = (
    "raw soft answer against the one predicted from the reference's answer and the "
    "documented regularization: |raw - predicted| over |predicted - reference|"
)
NO_PREDICTION = "the engine does not predict its soft answer independently"


def rigid_answer(engine: str) -> str:
    """What a soft engine's judged answer is (the records' ``answer`` field)."""
    return f"rigid, recovered from {engine_label(engine)}'s soft solution"


@dataclass(frozen=True)
class ReferenceAnswer:
    """The reference at one state: u', lambda, M and (K, V), and the constraint rows A (for
    the generalized constraint forces A^T lambda; None: not compared)."""

    accelerations: np.ndarray
    multipliers: np.ndarray
    mass_matrix: np.ndarray
    energy: tuple[float, float]
    constraint_matrix: np.ndarray | None = None


def reference_answer(nm, q, u, t: float = 0.0) -> ReferenceAnswer:
    ref = nm.forward(q, u, t)
    M, _f, A, _b = nm.matrices(q, u, t)
    return ReferenceAnswer(ref.accelerations, ref.multipliers, M, tuple(nm.energy(q, u, t)), A)


def energy_error(engine_kv, reference_kv) -> float:
    """|(K + V)_engine - (K + V)_reference| / max(|K| + |V|, 1) (compare.METRICS)."""
    Ke, Ve = engine_kv
    Kr, Vr = reference_kv
    return abs((Ke + Ve) - (Kr + Vr)) / max(abs(Kr) + abs(Vr), 1.0)


def energy_error_series(E, W=None) -> np.ndarray:
    """|E(t) - E(0)| / max(max |E|, 1) at every time, or where energy is not conserved the
    work-energy balance |E(t) - E(0) - W(t)| / max(max |E|, 1), W the work of loads and moving
    constraints. The one definition: records take its maximum, the report plots it."""
    E = np.asarray(E, float)
    change = E - E[0] if W is None else E - E[0] - np.asarray(W, float)
    return np.abs(change) / max(float(np.max(np.abs(E))), 1.0)


def energy_drift(E) -> float:
    """Drift of a total-energy series: max |E(t) - E(0)| / max(max |E|, 1)."""
    return float(np.max(energy_error_series(E)))


def work_energy_balance(E, W) -> float:
    """max |E(t) - E(0) - W(t)| / max(max |E|, 1), W the work of loads and moving constraints."""
    return float(np.max(energy_error_series(E, W)))


def constraint_residual(nm, q, u, t: float = 0.0) -> tuple[float, float]:
    """(max |f(q, t)|, max |A u + a0|) of the reference's constraints at a state (0 without)."""
    pos, vel = nm.residuals(q, u, t)
    return (
        float(np.max(np.abs(pos))) if pos.size else 0.0,
        float(np.max(np.abs(vel))) if vel.size else 0.0,
    )


def _finite(x: float) -> float:
    x = float(x)
    return x if math.isfinite(x) else math.inf


@dataclass
class StateComparison:
    """Errors of one engine model at one state: values {quantity: error} (non-finite -> inf),
    skips {quantity: reason}, soft (judged on the rigid recovery), the solver's iterations,
    and the predicted relative soft errors (accelerations, multipliers) where soft."""

    values: dict[str, float]
    skips: dict[str, str]
    soft: bool
    iterations: int | None = None
    predicted: list = field(default_factory=list)
    answers: dict = field(default_factory=dict)  # the judged u' and lambda (the agreement matrix)
    left_out: tuple[int, ...] = ()  # the reference's rows whose multipliers are not compared
    in_engine_speeds: bool = False  # the mass matrix compared in the engine's own speeds
    left_out_note: str = ""  # why those rows are left out (the engine's multipliers_note)


# engine coordinates of two readings of one configuration, and the bodies' states they encode
# (encoded_state), agree to round-off of the trig functions and a rotation's composition
# (1e-15 relative; the 3-D double pendulum's other-branch readings, 13 samples of sweep seeds
# 1-8 in every engine variant: <= 5.3e-14); 1e-9 leaves room, and a different configuration
# differs at order one
SAME_CONFIGURATION = 1e-9


def whole_turns_removed(em: EngineModel, q, u, q2, qe) -> np.ndarray:
    """The round trip q -> engine -> q2 read back angles with atan2, so an angle outside
    (-pi, pi] comes back a whole number of turns away (sweep seed 4 sample 322 of the 3-D
    double pendulum: theta21 = -3.28 returned as 3.00, state_map 1.9). Those turns are removed
    only where the engine shows them to be the same configuration: q2 with them removed maps to
    the same engine coordinates as q (to round-off); anything else stays an error."""
    q, q2 = np.asarray(q, float), np.asarray(q2, float)
    turns = np.round((q2 - q) / (2 * math.pi))
    if not turns.any():
        return q2
    qe2, _ = em.to_engine_state(q2, u)
    if C.scaled_error(qe2, qe) > SAME_CONFIGURATION:
        return q2
    return q2 - 2 * math.pi * turns


@functools.cache
def _encoded_state_functions(model_name: str, content_hash: str):
    """(configuration, motion) functions of (q, u, t, parameters) for a model's bodies, and
    its parameter names; None where the bodies' R and r_G do not see every coordinate or their
    omega and v_G every speed (a difference there would go unseen)."""
    import sympy as sp

    model = models.get(model_name)
    pose, motion = [], []
    for b in model.bodies:
        pose += [x for m in (b.R, b.r_G) if m is not None for x in m]
        motion += [*b.omega, *b.v_G]

    def seen(exprs):
        return set().union(set(), *(sp.sympify(x).free_symbols for x in exprs))

    if not (set(model.coordinates) <= seen(pose) and set(model.speeds) <= seen(motion)):
        return None
    args = (*model.coordinates, *model.speeds, model.t, *model.parameter_symbols)
    return (
        sp.lambdify(args, pose, modules="numpy", cse=True),
        sp.lambdify(args, motion, modules="numpy", cse=True),
        tuple(p.name for p in model.parameters),
    )


def encoded_state(em: EngineModel, q, u, t: float):
    """The state the reference's (q, u) encode, whatever reading of it they are (a turn, the
    other branch of 3-1-3 angles, the opposite Euler parameters): every body's R and r_G
    (configuration), then its omega and v_G (motion), at the maps' parameter values. None
    where the model is not in this process's registry or its bodies do not see every
    coordinate and speed."""
    try:
        model = models.get(em.model_name)
    except ModelInputError:
        return None
    fns = _encoded_state_functions(model.name, model.content_hash())
    if fns is None:
        return None
    pose, motion, names = fns
    args = (*np.asarray(q, float), *np.asarray(u, float), float(t))
    args += tuple(em.map_params[n] for n in names)
    return np.asarray(pose(*args), float), np.asarray(motion(*args), float)


def state_map_error(em: EngineModel, q, u, t: float, q2, u2) -> float:
    """The round trip's error: the scaled difference of the coordinates and of the speeds. A
    read-back more than SAME_CONFIGURATION away may be another reading of the same state
    (from_engine_state picks one branch: 3-1-3 angles come back with theta2 in [0, pi], so
    sweep seed 5 sample 1131 of the 3-D double pendulum, theta22 = -0.034, came back as
    (theta21 + pi, 0.034, theta23 - pi), state_map 1.69), so there the error is that of the
    state both encode (encoded_state): round-off for another reading of the same state, the
    size of the map's error for a wrong one."""
    literal = max(C.scaled_error(q2, q), C.scaled_error(u2, u))
    if literal <= SAME_CONFIGURATION:
        return literal
    given, back = encoded_state(em, q, u, t), encoded_state(em, q2, u2, t)
    if given is None or back is None:
        return literal
    return max(C.scaled_error(b, g) for b, g in zip(back, given, strict=True))


def _mass_matrix(em: EngineModel, q, ref: ReferenceAnswer, vals: dict, skips: dict) -> bool:
    """The engine's M against the reference's, in the reference's speeds where they map one to
    one, else in the engine's own (mass_matrix_in_engine_speeds); True for the latter."""
    M_e = em.mass_matrix(q)
    if M_e is not None:
        vals["mass_matrix"] = C.scaled_error(M_e, ref.mass_matrix)
        return False
    own = em.mass_matrix_in_engine_speeds(q)
    if own is None:
        skips["mass_matrix"] = em.mass_matrix_note or NO_MASS_MATRIX
        return False
    M_e, H = own
    vals["mass_matrix"] = C.scaled_error(M_e, H.T @ ref.mass_matrix @ H)
    return True


def _pairs(ef, ref: ReferenceAnswer, n_rows: int, skips: dict) -> list:
    """(quantity, raw, rigid, reference) of the compared answers: u', lambda on the rows the
    engine answers (EngineForward.multiplier_rows), and A^T lambda of those rows where the
    engine gives it, in the engine's speeds (EngineForward.speed_map)."""
    pairs = [("accelerations", ef.accelerations, ef.rigid_accelerations, ref.accelerations)]
    if n_rows == 0:
        skips["multipliers"] = NO_CONSTRAINTS
    elif ef.multipliers is None:
        skips["multipliers"] = ef.multipliers_note or NO_FORCES
    if "multipliers" in skips:
        return pairs
    rows = list(range(n_rows) if ef.multiplier_rows is None else ef.multiplier_rows)
    if not rows:  # every row left out (a free body's norm row alone): nothing to compare
        skips["multipliers"] = f"{ef.multipliers_note or NO_FORCES}; no other constraint rows"
        return pairs

    def pick(x):
        return None if x is None else np.asarray(x, float)[rows]

    pairs.append(
        ("multipliers", pick(ef.multipliers), pick(ef.rigid_multipliers), pick(ref.multipliers))
    )
    if ef.constraint_forces is not None and ref.constraint_matrix is not None:
        A = np.asarray(ref.constraint_matrix, float)[rows]
        generalized = A.T @ np.asarray(ref.multipliers, float)[rows]
        if ef.speed_map is not None:  # in the engine's speeds: H^T A^T lambda
            generalized = np.asarray(ef.speed_map, float).T @ generalized
        pairs.append(
            ("constraint_forces", ef.constraint_forces, ef.rigid_constraint_forces, generalized)
        )
    return pairs


def _agreement_answers(pairs, soft: bool, ref: ReferenceAnswer, left_out) -> dict:
    """The judged u' and lambda for the agreement matrix, lambda on every row: the rows the
    engine does not answer take the reference's values, so that every pair compares the
    answered rows only."""
    answers = {qty: (rigid if soft else raw) for qty, raw, rigid, _ in pairs[:2]}
    if left_out and answers.get("multipliers") is not None:
        full = np.array(ref.multipliers, float)
        keep = [i for i in range(full.size) if i not in set(left_out)]
        full[keep] = answers["multipliers"]
        answers["multipliers"] = full
    return answers


def compare_at_state(
    em: EngineModel, q, u, t: float, ref: ReferenceAnswer, n_rows: int, caps: Capabilities
) -> StateComparison:
    """The engine model against the reference's answer at one consistent state (q, u, t);
    ``caps`` are its adapter's capabilities (soft_prediction)."""
    vals: dict[str, float] = {}
    skips: dict[str, str] = {}
    qe, ve = em.to_engine_state(q, u)
    q2, u2 = em.from_engine_state(qe, ve)
    q2 = whole_turns_removed(em, q, u, q2, qe)
    vals["state_map"] = state_map_error(em, q, u, t, q2, u2)
    in_engine_speeds = _mass_matrix(em, q, ref, vals, skips)
    ef = em.forward(q, u, t)
    vals["energy"] = energy_error(em.energy(q, u), ref.energy)
    pairs = _pairs(ef, ref, n_rows, skips)
    rows = ef.multiplier_rows
    left_out = (
        () if rows is None or len(pairs) < 2 else tuple(sorted(set(range(n_rows)) - set(rows)))
    )
    predicted = _soft_predictions(em, q, u, ref, ef.soft, caps, skips)
    if predicted is not None and rows is not None and predicted[1] is not None:
        predicted = (predicted[0], np.asarray(predicted[1], float)[list(rows)])
    for k, (qty, raw_value, rigid, reference) in enumerate(pairs):
        if not ef.soft:
            vals[qty] = C.scaled_error(raw_value, reference)
            continue
        vals[qty] = C.scaled_error(rigid, reference)
        vals[f"{qty}_soft_error"] = C.scaled_error(raw_value, reference)
        if predicted is not None and k < len(predicted) and predicted[k] is not None:
            vals[f"{qty}_soft_vs_predicted"] = C.soft_prediction(
                raw_value, reference, np.asarray(predicted[k], float) - reference
            )[0]
    return StateComparison(
        {k: _finite(v) for k, v in vals.items()},
        skips,
        ef.soft,
        ef.iterations,
        _predicted_errors(pairs, predicted),
        _agreement_answers(pairs, ef.soft, ref, left_out),
        left_out,
        in_engine_speeds,
        (ef.multipliers_note or "") if left_out else "",
    )


def _soft_predictions(em, q, u, ref, soft, caps, skips):
    """The engine's predicted raw (accelerations, multipliers) where its answer is soft and it
    predicts one (None otherwise, with the skip reason of the ``*_soft_vs_predicted`` rows)."""
    if not soft:
        return None
    reason = NO_PREDICTION
    if caps.soft_prediction:
        try:
            return em.predict_soft(q, u, ref.accelerations)
        except EngineUnsupported as exc:
            reason = f"no soft prediction: {exc}"
    for qty in ("accelerations", "multipliers"):
        skips.setdefault(f"{qty}_soft_vs_predicted", reason)
    return None


def _predicted_errors(pairs, predicted) -> list:
    """max |predicted - reference| (scaled) of each compared quantity: the size of the soft
    effect the prediction expects (records' predicted_rel_error_max)."""
    if predicted is None:
        return []
    return [
        C.scaled_error(p, reference)
        for (_, _, _, reference), p in zip(pairs, predicted, strict=False)
        if p is not None
    ]


def tolerance(
    quantity: str, soft: bool, adapter: EngineAdapter, model_name: str = ""
) -> tuple[C.Tolerance | None, str]:
    """(named tolerance, metric) of a quantity; None: reported, not judged."""
    if quantity == "state_map":
        return C.STATE_MAP, "scaled_error"
    if quantity == "mass_matrix":
        return C.MASS_MATRIX, "scaled_error"
    if quantity == "energy":
        return C.ENERGY, "relative_energy_error"
    if quantity.endswith("_soft_vs_predicted"):
        return C.SOFT_PREDICTION, "relative_miss"
    if quantity.endswith("_soft_error"):
        return None, "scaled_error"
    return (C.RIGID_RECOVERY if soft else adapter.exact_tolerance(model_name)), "scaled_error"


def build(
    adapter: EngineAdapter, name: str, params, variant: str | None, nominal: dict | None = None
) -> EngineModel:
    """The engine model of a variant (build's default when variant is None); its maps use
    `nominal` (the unperturbed values: a perturbation changes only the physics)."""
    em = adapter.build(name, params, variant=variant) if variant else adapter.build(name, params)
    if nominal is not None:
        em.nominal = dict(nominal)
    return em


def engine_records(
    name: str,
    nm,
    states,
    adapter: EngineAdapter,
    params: dict,
    variant: str | None = None,
    answers=None,
    refs: list[ReferenceAnswer] | None = None,
) -> list[dict]:
    """results.json records of one engine model over a run's states (t = 0): the worst error
    of each quantity, at which state, against its tolerance. ``answers`` (an
    agreement.Answers) collects the judged answers for the agreement matrix; ``refs`` are the
    reference's answers at the states when the caller has them (one solve per state for all
    engines), else they are computed here."""

    # e.g. Example 4 as a ball-joint tree or as free bodies
    which = {} if variant is None else {"variant": variant}

    def rec(*a, **k):
        return record(name, nm.formulation, adapter.name, *a, **k, **which)

    try:
        em = build(adapter, name, params, variant, nominal=nm.params)
    except EngineUnsupported as exc:
        return [
            rec("instantaneous", q, None, None, f"engine cannot represent the model: {exc}")
            for q in ("accelerations", "multipliers")
        ]
    worst: dict[str, C.WorstCase] = {}
    skipped: dict[str, str] = {}
    notes: dict[str, dict] = {}
    iterations, predicted, soft = [], [], False
    for i, (q, u) in enumerate(states):
        ref = refs[i] if refs is not None else reference_answer(nm, q, u)
        sc = compare_at_state(em, q, u, 0.0, ref, nm.m, adapter.capabilities)
        for qty, err in sc.values.items():
            worst.setdefault(qty, C.WorstCase()).add(err, i)
        skipped.update(sc.skips)
        notes.update(_notes(sc, nm.model.constraint_names))
        soft = soft or sc.soft
        predicted += sc.predicted
        if sc.iterations is not None:
            iterations.append(sc.iterations)
        if answers is not None:
            side = adapter.name + (f"/{variant}" if variant else "")
            for qty, value in sc.answers.items():
                tol = tolerance(qty, sc.soft, adapter, name)[0]
                answers.add(side, i, qty, value, tol)
    return _fold(rec, worst, skipped, soft, iterations, predicted, adapter, name, notes)


def _notes(sc: StateComparison, row_names) -> dict[str, dict]:
    """What a record adds where the comparison is not the plain one: the mass matrix in the
    engine's speeds, the rows left out of the multipliers and of A^T lambda (their names, and
    why, for the reason)."""
    out: dict[str, dict] = {}
    if sc.in_engine_speeds:
        out["mass_matrix"] = {"answer": MASS_IN_ENGINE_SPEEDS, "why": MASS_IN_ENGINE_SPEEDS}
    if sc.left_out:
        names = [row_names[i] if i < len(row_names) else f"row {i}" for i in sc.left_out]
        why = f"rows left out: {', '.join(names)} ({sc.left_out_note or NO_FORCES})"
        for qty in ("multipliers", "constraint_forces"):
            out[qty] = {"rows_left_out": names, "why": why}
    return out


def _fold(rec, worst, skipped, soft, iterations, predicted, adapter, name, notes) -> list[dict]:
    """The records of one engine model from its worst cases (run's record order)."""

    def judged(qty, **extra):
        tol, metric = tolerance(qty, soft, adapter, name)
        w = worst[qty]
        kw = {} if metric == "scaled_error" else {"metric": metric}
        note = dict(notes.get(qty.removesuffix("_soft_vs_predicted"), {}))
        if "why" in note:
            kw["reason"] = f"{tol.reason}; {note.pop('why')}"
        return rec("instantaneous", qty, w.error, tol, worst_state=w.state, **kw, **note, **extra)

    out = [judged("state_map")]
    out.append(
        rec("instantaneous", "mass_matrix", None, None, skipped["mass_matrix"])
        if "mass_matrix" in skipped
        else judged("mass_matrix")
    )
    out.append(judged("energy"))
    it = {"iterations_max": max(iterations)} if iterations else {}
    for qty in ("accelerations", "multipliers", "constraint_forces"):
        if qty == "constraint_forces" and qty not in worst:
            continue  # only where the engine gives its generalized constraint forces
        if qty in skipped:
            out.append(rec("instantaneous", qty, None, None, skipped[qty]))
        elif not soft:
            out.append(judged(qty, **it))
        elif qty == "constraint_forces":  # judged on the rigid recovery; lambda's prediction
            out.append(judged(qty, answer=rigid_answer(adapter.name)))
        else:
            raw_errors = [
                worst[f"{k}_soft_error"].error
                for k in ("accelerations", "multipliers")
                if f"{k}_soft_error" in worst
            ]
            extra = {"soft_rel_error_max": float(max(raw_errors))}
            if predicted:
                extra["predicted_rel_error_max"] = float(max(predicted))
            out.append(judged(qty, answer=rigid_answer(adapter.name), **extra, **it))
            name_p = f"{qty}_soft_vs_predicted"
            out.append(
                judged(name_p, answer=SOFT_ANSWER, **extra)
                if name_p in worst
                else rec("instantaneous", name_p, None, None, skipped.get(name_p, NO_PREDICTION))
            )
    return out
