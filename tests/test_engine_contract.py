"""The engine contract (crosscheck/engines/base.py), checked for every registered engine that
imports here on every built-in model: a model the engine claims satisfies the contract and
everything its Capabilities promise; a model it cannot express is refused with a reason, which
`crosscheck run` records as a skip. Real engines, no mocks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from crosscheck.checks import tolerances as C
from crosscheck.checks.instantaneous import build, engine_records
from crosscheck.checks.sampling import consistent_states
from crosscheck.engines.base import (
    EngineAdapter,
    EngineForward,
    EngineModel,
    EngineTrajectory,
    EngineUnsupported,
)
from crosscheck.engines.registry import available_engines, get_engine
from reference import NumericModel, models
from reference.constraints import classify

ENGINES = available_engines()
CASES = [(e, m) for e in ENGINES for m in models.names()]
STATES = 3  # the initial state and two of run's seeded consistent states
# a short trajectory: enough steps to exercise the integrator, cheap on every model
T_GRID = np.linspace(0.0, 0.02, 3)
RTOL, TIMESTEP = 1e-8, 1e-3


def _nonholonomic(model) -> bool:
    """A motion row the reference's integrability test does not find exact (the knife edge)."""
    return any(
        r["kind"] == "motion" and r["holonomic"].startswith("not exact") for r in classify(model)
    )


def test_the_built_in_engines_are_registered_and_import():
    assert {"pinocchio", "mujoco"} <= set(ENGINES)
    for e in ENGINES:
        adapter = get_engine(e)
        assert isinstance(adapter, EngineAdapter) and adapter.name == e and adapter.distribution


@pytest.mark.parametrize("engine,name", CASES)
def test_every_model_is_claimed_or_refused_with_a_reason(engine, name):
    adapter = get_engine(engine)
    claimed, refused = set(adapter.models()), adapter.unsupported()
    assert (name in claimed) != (name in refused), "a model is either claimed or refused"
    if name in refused:
        assert refused[name].strip(), "a refusal names its reason"
    model = models.get(name)
    if _nonholonomic(model) and not adapter.capabilities.nonholonomic:
        assert name in refused, "a nonholonomic model needs Capabilities.nonholonomic"


@pytest.mark.parametrize(
    "engine,name", [(e, m) for e, m in CASES if m in get_engine(e).unsupported()]
)
def test_a_refused_model_raises_and_becomes_a_skip_record(engine, name):
    adapter = get_engine(engine)
    with pytest.raises(EngineUnsupported) as exc:
        adapter.build(name, None)
    assert str(exc.value).strip()
    nm = NumericModel(models.get(name))
    recs = engine_records(name, nm, consistent_states(nm, 1), adapter, nm.params)
    assert recs and all(r["skipped"] and r["engine"] == engine for r in recs)
    assert all(str(exc.value) in r["reason"] for r in recs)


def _check_forward(adapter, em, nm, q, u):
    caps = adapter.capabilities
    ef = em.forward(q, u)
    assert isinstance(ef, EngineForward)
    acc = np.asarray(ef.accelerations)
    assert acc.shape == (nm.n,) and np.all(np.isfinite(acc))
    if ef.multipliers is None:
        assert nm.m == 0 or ef.multipliers_note or not caps.multipliers
    else:
        lam = np.asarray(ef.multipliers)
        assert lam.shape == (nm.m,) and np.all(np.isfinite(lam))
    if caps.rigid_recovery:  # the rigid answer recovered from the engine's own output
        assert np.asarray(ef.rigid_accelerations).shape == (nm.n,)
        assert np.all(np.isfinite(ef.rigid_accelerations))
        if ef.multipliers is not None:
            assert np.asarray(ef.rigid_multipliers).shape == (nm.m,)
        if ef.soft:
            assert np.asarray(ef.predicted_acceleration_error).shape == (nm.n,)
    if caps.soft_prediction and ef.soft:  # predicted from the reference's answer alone
        try:
            acc_p, lam_p = em.predict_soft(q, u, nm.forward(q, u).accelerations)
        except EngineUnsupported as exc:  # a row type without a documented regularization
            assert str(exc).strip()
        else:
            assert np.asarray(acc_p).shape == (nm.n,) and np.all(np.isfinite(acc_p))
            assert lam_p is None or np.asarray(lam_p).shape == (nm.m,)
    if caps.soft_limit and em.soft_constraints:  # a stiffer copy, the same physics otherwise
        stiff = em.stiffened(2.0)
        assert stiff is not em and stiff.fingerprint() == em.fingerprint()
    if caps.exact:
        assert not ef.soft, "an exact engine's answer is not regularized"
    assert ef.iterations is None or ef.iterations >= 0
    K, V = em.energy(q, u)
    assert np.isfinite(K) and np.isfinite(V) and K >= 0.0
    M = em.mass_matrix(q)  # None where the coordinates do not map linearly
    if M is not None:
        assert caps.mass_matrix and M.shape == (nm.n, nm.n) and np.all(np.isfinite(M))
    timed = em.timed_forward(q, u)
    assert callable(timed)
    timed()


def _check_bad_states(em, nm, q, u):
    """A wrong-sized or non-finite state is refused in the reference's words, never mapped
    into the engine (MuJoCo's models raised numpy's broadcast error before they checked)."""
    from reference.errors import ModelInputError

    bad = [
        ([*list(q), 0.0], u, "coordinates"),
        (q, [*list(u), 0.0], "speeds"),
        ([math.nan, *list(q)[1:]], u, "NaN"),
    ]
    for bq, bu, what in bad:
        with pytest.raises(ModelInputError, match=what):
            em.forward(bq, bu)


def _check_simulate(adapter, em, nm, q0, u0):
    caps = adapter.capabilities
    if not caps.integrators:
        with pytest.raises(EngineUnsupported):
            em.simulate(q0, u0, T_GRID, integrator="none")
        return
    integ = caps.integrators[0]
    setting = {"rtol": RTOL} if integ in caps.adaptive_integrators else {"timestep": TIMESTEP}
    tr = em.simulate(q0, u0, T_GRID, integrator=integ, **setting)
    assert isinstance(tr, EngineTrajectory) and tr.integrator == integ and tr.failure is None
    assert np.allclose(tr.t, T_GRID, atol=1e-12, rtol=0)
    k = len(T_GRID)
    assert tr.q.shape == (k, nm.nq) and tr.u.shape == (k, nm.n)
    for series in (tr.violation, tr.velocity_violation, tr.energy):
        assert np.asarray(series).shape == (k,) and np.all(np.isfinite(series))
    assert np.all(np.isfinite(tr.q)) and np.all(np.isfinite(tr.u))
    assert C.scaled_error(tr.q[0], q0) <= C.STATE_MAP.value  # starts where it was asked to


@pytest.mark.parametrize("engine,name", [(e, m) for e, m in CASES if m in get_engine(e).models()])
def test_a_claimed_model_satisfies_the_contract(engine, name):
    adapter = get_engine(engine)
    nm = NumericModel(models.get(name))
    states = consistent_states(nm, STATES)
    variants = adapter.variants(name)
    assert variants and (adapter.capabilities.variants or variants == (None,))
    for variant in variants:
        em = build(adapter, name, nm.params, variant)
        assert isinstance(em, EngineModel) and em.engine == engine and em.model_name == name
        assert em.variant == variant
        _check_bad_states(em, nm, *states[0])
        for q, u in states:
            qe, ve = em.to_engine_state(q, u)
            q2, u2 = em.from_engine_state(qe, ve)  # the state round trip
            assert C.scaled_error(q2, q) <= C.STATE_MAP.value
            assert C.scaled_error(u2, u) <= C.STATE_MAP.value
            _check_forward(adapter, em, nm, q, u)
        _check_simulate(adapter, em, nm, *states[0])


def test_registry_order_labels_and_unknown_names():
    """Default engine order follows EngineAdapter.rank (the built-ins first), an unknown name
    is refused with the registered ones listed, and results' versions are keyed by package."""
    from crosscheck.engines.registry import (
        UnknownEngineError,
        engine_label,
        engine_names,
        engine_versions,
    )

    order = list(ENGINES)
    assert order.index("pinocchio") < order.index("mujoco")
    assert [get_engine(e).rank for e in order] == sorted(get_engine(e).rank for e in order)
    assert engine_label("mujoco") == "MuJoCo" and engine_label("no_such") == "no_such"
    with pytest.raises(UnknownEngineError) as exc:
        get_engine("no_such_engine")
    assert all(name in str(exc.value) for name in engine_names())
    versions = engine_versions()
    assert set(versions) == {get_engine(e).distribution for e in ENGINES}
    assert all(versions.values())


def test_perturbation_is_parsed_checked_and_applied_in_one_place():
    from crosscheck.checks.perturb import check_parameters, parse_perturb, perturbed
    from reference.errors import ModelInputError

    assert parse_perturb(["mujoco:m2=1e-6", "mujoco:l1=-0.5"]) == {
        "mujoco": {"m2": 1e-6, "l1": -0.5}
    }
    with pytest.raises(ModelInputError, match="pinocchio"):  # the registered ones are listed
        parse_perturb(["nope:m=1"])
    with pytest.raises(ModelInputError, match="ENGINE:PARAM=REL"):
        parse_perturb(["mujoco-m2"])
    names = [p.name for p in models.get("slider_crank").parameters]
    with pytest.raises(ModelInputError, match="no parameter 'zz'"):
        check_parameters("slider_crank", names, {"mujoco": {"zz": 1.0}})
    base = NumericModel(models.get("slider_crank")).params
    out = perturbed("slider_crank", base, {"m2": 0.5})
    assert out["m2"] == base["m2"] * 1.5 and base["m2"] != out["m2"]
    assert all(out[k] == base[k] for k in base if k != "m2")
