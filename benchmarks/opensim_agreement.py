"""Measure the OpenSim adapter against the reference: worst relative error of accelerations and
multipliers over N consistent states per model (every formulation), and the time per state.

    python benchmarks/opensim_agreement.py [N] [SEED] [models...]

States as tests/test_engine_opensim.py draws them (the model's sampler for the 3-D models,
else crosscheck.checks.sampling.random_consistent_state at t ~ U(0, 2)); relative errors divide by
max(|ref|_inf, 1). Times: the median of 300 calls of timed_forward (realizeAcceleration only,
the state already set) and of forward() (mapping, solve and multiplier map).
"""

from __future__ import annotations

import sys
import time

import numpy as np

from crosscheck.checks.sampling import random_consistent_state
from crosscheck.engines.opensim import OpenSimAdapter
from reference.models import get
from reference.numeric.model import NumericModel

PARAMS = {
    "slider_crank": {"T": 0.7},
    "slider_crank_split": {"T": 0.7},
    "slider_crank_free": {"T": 0.7},
    "exercise_6_4": {"M_phi": 0.3, "M_theta": -0.2},
    "frame_bar": {"M_phi": 0.3, "M_theta": -0.2},
}


def _rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b)) / max(float(np.max(np.abs(b))), 1.0)) if b.size else 0.0


def _median_us(fn, n=300) -> float:
    out = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return 1e6 * float(np.median(out))


def measure(name: str, n: int, seed: int, variant=None) -> dict:
    mod, adapter = get(name), OpenSimAdapter()
    em = adapter.build(name, PARAMS.get(name, {}), variant=variant)
    rng = np.random.default_rng(seed)
    nm0 = NumericModel(mod, mod.formulations[0], PARAMS.get(name, {}))
    draws = []
    for _ in range(n):
        if mod.state_sampler is not None:
            q, u = nm0.project(*(np.array(x, float) for x in mod.state_sampler(rng, nm0.params)))
            t = 0.0
        else:
            t = float(rng.uniform(0.0, 2.0))
            q, u = random_consistent_state(nm0, rng, t=t)
        draws.append((q, u, t))
    worst_a = worst_l = 0.0
    for form in mod.formulations:
        nm = NumericModel(mod, form, PARAMS.get(name, {}))
        for q, u, t in draws:
            ref, got = nm.forward(q, u, t), em.forward(q, u, t)
            worst_a = max(worst_a, _rel(got.accelerations, ref.accelerations))
            if got.multipliers is not None:
                worst_l = max(worst_l, _rel(got.multipliers, ref.multipliers))
    q, u, t = draws[0]
    call = em.timed_forward(q, u)
    label = name if variant is None else f"{name} ({variant})"
    return {
        "model": label,
        "acc": worst_a,
        "lam": worst_l,
        "lam_mapped": em.forward(q, u, t).multipliers is not None,
        "solve_us": _median_us(call),
        "forward_us": _median_us(lambda: em.forward(q, u, t)),
        "tol": adapter.exact_tolerance(name).value,
    }


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 100
    seed = int(sys.argv[2]) if len(sys.argv) > 2 else 0
    print(
        f"| model | worst rel. acc | worst rel. lambda | tolerance | realizeAcceleration "
        f"(us) | forward() (us) |   ({n} states, seed {seed})"
    )
    print("|---|---|---|---|---|---|")
    adapter = OpenSimAdapter()
    names = sys.argv[3:] or adapter.models()
    cases = [(name, v) for name in names for v in adapter.variants(name)]
    for name, variant in cases:
        r = measure(name, n, seed, variant)
        lam = f"{r['lam']:.1e}" if r["lam_mapped"] else "None (not a force)"
        print(
            f"| {r['model']} | {r['acc']:.1e} | {lam} | {r['tol']:.0e} | {r['solve_us']:.0f} | "
            f"{r['forward_us']:.0f} |"
        )


if __name__ == "__main__":
    main()
