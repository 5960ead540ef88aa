"""Measure the Exudyn adapter against the reference: the figures docs/engines/exudyn.md and
the adapter's tolerances quote.

    PYTHONPATH=$PWD python -m crosscheck.engines.exudyn.measure [--samples N] [--seed S] [MODEL ...]
    PYTHONPATH=$PWD python -m crosscheck.engines.exudyn.measure --trajectories [MODEL ...]

For every model (default: all the adapter builds), N instances drawn as the sweeps draw them
(crosscheck.checks.sampling: random parameters, a random time, a random consistent state): the worst
scaled error (max |x - x_ref| / max(max |x_ref|, 1)) of the accelerations and multipliers of
forward() (the extrapolated answer) and of Exudyn's plain answer (default relativeEpsilon
1e-7), and the median wall time per state of the engine call alone: the three InitializeSolver
calls forward() makes (timed_forward) and one plain call.

--trajectories: from each model's initial state over 1 s (11 output times), the largest
|q - q_ref| of both Exudyn integrators at steps 1e-2, 1e-3 and 1e-4 against the reference's
projection integrator (rtol = atol = 1e-11), with the largest engine-side position violation
and the wall time of Exudyn's stepping.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

from crosscheck.checks.sampling import random_consistent_state, random_params
from crosscheck.engines.exudyn.adapter import ExudynAdapter


def _scaled(value, ref) -> float:
    value, ref = np.asarray(value, float), np.asarray(ref, float)
    if ref.size == 0 or value is None:
        return 0.0
    return float(np.max(np.abs(value - ref)) / max(float(np.max(np.abs(ref))), 1.0))


def _median_us(call, repeat: int = 20) -> float:
    call()  # warm
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        call()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)) * 1e6


def measure(name: str, samples: int, seed: int) -> dict:
    from reference.models import get
    from reference.numeric.model import NumericModel

    adapter = ExudynAdapter()
    model = get(name)
    rng = np.random.default_rng(seed)
    worst = {"acc": 0.0, "lam": 0.0, "plain_acc": 0.0, "plain_lam": 0.0}
    us, us_plain = [], []
    for i in range(samples):
        params = random_params(model, rng)
        nm = NumericModel(model, params=params)
        t = float(rng.uniform(0.0, 2.0))
        q, u = random_consistent_state(nm, rng, t=t)
        ref = nm.forward(q, u, t)
        em = adapter.build(name, params)
        out = em.forward(q, u, t)
        worst["acc"] = max(worst["acc"], _scaled(out.accelerations, ref.accelerations))
        worst["plain_acc"] = max(
            worst["plain_acc"], _scaled(out.raw["plain_accelerations"], ref.accelerations)
        )
        if len(ref.multipliers):
            worst["lam"] = max(worst["lam"], _scaled(out.multipliers, ref.multipliers))
            worst["plain_lam"] = max(
                worst["plain_lam"], _scaled(out.raw["plain_multipliers"], ref.multipliers)
            )
        if i < 5:  # timing on the first states only (the machine is shared)
            us.append(_median_us(em.timed_forward(q, u, t)))
            qe, ve = em.to_engine_state(q, u)
            us_plain.append(
                _median_us(lambda em=em, qe=qe, ve=ve, t=t: em._plain_answer(qe, ve, t))
            )
    return dict(worst, us=float(np.median(us)), us_plain=float(np.median(us_plain)))


def trajectories(name: str) -> None:
    from crosscheck.engines.exudyn.trajectory import ExudynIntegrationError
    from reference.integrate.driver import simulate
    from reference.models import get
    from reference.numeric.model import NumericModel

    model = get(name)
    t_eval = np.linspace(0.0, 1.0, 11)
    ref = simulate(
        NumericModel(model),
        model.initial_q,
        model.initial_u,
        1.0,
        "projection",
        rtol=1e-11,
        atol=1e-11,
        t_eval=t_eval,
    )
    em = ExudynAdapter().build(name)
    for integrator in ExudynAdapter.capabilities.integrators:
        for h in (1e-2, 1e-3, 1e-4):
            try:
                tr = em.simulate(
                    model.initial_q, model.initial_u, t_eval, integrator=integrator, timestep=h
                )
            except ExudynIntegrationError:
                print(f"{name:25s} {integrator:19s} {h:7.0e}   Newton failed")
                continue
            print(
                f"{name:25s} {integrator:19s} {h:7.0e} {np.max(np.abs(tr.q - ref.q)):9.1e} "
                f"{np.max(tr.violation):9.1e} {tr.wall_s:8.3f}"
            )


def main(argv=None) -> None:
    warnings.simplefilter("ignore", DeprecationWarning)
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("models", nargs="*")
    ap.add_argument("--samples", type=int, default=50)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--trajectories", action="store_true")
    args = ap.parse_args(argv)
    names = args.models or ExudynAdapter().models()
    if args.trajectories:
        print(
            f"{'model':25s} {'integrator':19s} {'step':>7s} {'|q-q_ref|':>9s} "
            f"{'violation':>9s} {'wall s':>8s}"
        )
        for name in names:
            trajectories(name)
        return
    print(
        f"{'model':25s} {'acc':>8s} {'lam':>8s} {'plain acc':>10s} {'plain lam':>10s} "
        f"{'us/state':>9s} {'us/plain':>9s}   ({args.samples} states, seed {args.seed})"
    )
    for name in names:
        r = measure(name, args.samples, args.seed)
        print(
            f"{name:25s} {r['acc']:8.1e} {r['lam']:8.1e} {r['plain_acc']:10.1e} "
            f"{r['plain_lam']:10.1e} {r['us']:9.0f} {r['us_plain']:9.0f}"
        )


if __name__ == "__main__":
    main()
