"""Measure the OpenSim adapter against the reference: worst relative error of accelerations and
multipliers over N consistent states per model (every formulation), and the time per state;
with --trajectories, OpenSim's integrators against the reference's trajectories. The figures of
docs/engines/opensim.md.

    python benchmarks/opensim_agreement.py [N] [SEED] [models...]
    python benchmarks/opensim_agreement.py --trajectories [models...]

States as tests/test_engine_opensim.py draws them (the model's sampler for the 3-D models,
else crosscheck.checks.sampling.random_consistent_state at t ~ U(0, 2)); relative errors divide by
max(|ref|_inf, 1). Times: the median of 300 calls of timed_forward (realizeAcceleration only,
the state already set) and of forward() (mapping, solve and multiplier map).

--trajectories: from each model's initial state over 0.5 s (6 output times), max |q - q_ref|
and |u - u_ref| against the reference's DOP853 at rtol = atol = 1e-12 (Lagrange), the
Manager's steps and its wall time, per integrator and setting (TRAJECTORY_RUNS); the 3-D
models, which have no q' = u to hand to the reference's solver here, by their energy drift
(ENERGY_RUNS).
"""

from __future__ import annotations

import sys
import time

import numpy as np
from scipy.integrate import solve_ivp

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


# (model, integrator, rtol or None, fixed step or None): Verlet is left out of the slider-crank
# (crank at 8 rad/s: about 92 000 steps for 0.5 s at 1e-8, minutes of wall time)
TRAJECTORY_RUNS = (
    ("pendulum_xy", "RungeKuttaMerson", 1e-10, None),
    ("pendulum_xy", "RungeKuttaMerson", 1e-6, None),
    ("pendulum_xy", "RungeKuttaFeldberg", 1e-10, None),
    ("pendulum_xy", "CPodes", 1e-8, None),
    ("pendulum_xy", "Verlet", 1e-8, None),
    ("pendulum_xy", "ExplicitEuler", None, 1e-4),
    ("slider_crank", "RungeKuttaMerson", 1e-10, None),
    ("slider_crank", "RungeKuttaFeldberg", 1e-10, None),
    ("slider_crank", "CPodes", 1e-8, None),
    ("exercise_6_1", "RungeKuttaMerson", 1e-10, None),
    ("exercise_6_1", "CPodes", 1e-8, None),
    ("pendulum_moving_support", "RungeKuttaMerson", 1e-10, None),
    ("pendulum_moving_support", "CPodes", 1e-8, None),
)
# (model, variant, integrator, rtol, t_end): energy drift of the 3-D models
ENERGY_RUNS = (
    ("double_pendulum_3d", "free", "RungeKuttaMerson", 1e-10, 0.5),
    ("top_cartesian", None, "RungeKuttaMerson", 1e-10, 0.5),
    ("double_pendulum_3d", "free", "RungeKuttaMerson", 1e-8, 5.0),
    ("double_pendulum_3d", "tree", "RungeKuttaMerson", 1e-8, 5.0),
    ("top_cartesian", None, "RungeKuttaMerson", 1e-8, 5.0),
    ("top_euler", None, "RungeKuttaMerson", 1e-8, 5.0),
)


def trajectories(names) -> None:
    adapter = OpenSimAdapter()
    t = np.linspace(0.0, 0.5, 6)
    print("| model | integrator | setting | q err | u err | steps | wall (ms) |")
    print("|---|---|---|---|---|---|---|")
    for name, integrator, rtol, step in TRAJECTORY_RUNS:
        if names and name not in names:
            continue
        em, nm = adapter.build(name), NumericModel(get(name), "lagrange")
        q0, u0 = nm.project(nm.model.initial_q, nm.model.initial_u)
        n = len(q0)

        def rhs(t, y, nm=nm, n=n):
            return np.concatenate([y[n:], nm.forward(y[:n], y[n:], t).accelerations])

        ref = solve_ivp(
            rhs, (0.0, 0.5), np.r_[q0, u0], method="DOP853", rtol=1e-12, atol=1e-12, t_eval=t
        )
        tr = em.simulate(q0, u0, t, integrator=integrator, rtol=rtol, timestep=step)
        q_err = float(np.max(np.abs(tr.q - ref.y[:n].T)))
        u_err = float(np.max(np.abs(tr.u - ref.y[n:].T)))
        setting = f"rtol {rtol:g}" if step is None else f"step {step:g}"
        print(
            f"| {name} | {integrator} | {setting} | {q_err:.1e} | {u_err:.1e} | {tr.steps} | "
            f"{tr.wall_s * 1e3:.0f} |"
        )
    print("\n| model | integrator | rtol | span (s) | energy drift (J) | steps | wall (s) |")
    print("|---|---|---|---|---|---|---|")
    for name, variant, integrator, rtol, t_end in ENERGY_RUNS:
        if names and name not in names:
            continue
        em, nm = adapter.build(name, variant=variant), NumericModel(get(name))
        q0, u0 = nm.project(nm.model.initial_q, nm.model.initial_u)
        tr = em.simulate(q0, u0, np.linspace(0.0, t_end, 11), integrator=integrator, rtol=rtol)
        drift = float(np.max(np.abs(tr.energy - tr.energy[0])))
        label = name + (f" ({variant})" if variant else "")
        print(
            f"| {label} | {integrator} | {rtol:g} | {t_end:g} | {drift:.1e} | {tr.steps} | "
            f"{tr.wall_s:.2f} |"
        )


def main() -> None:
    if sys.argv[1:2] == ["--trajectories"]:
        trajectories(sys.argv[2:])
        return
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
