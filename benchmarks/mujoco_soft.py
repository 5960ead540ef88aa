"""MuJoCo's soft constraints: the figures docs/engines/mujoco.md and docs/tolerances.md quote.

python benchmarks/mujoco_soft.py limit [models...]
    per model with equality rows, 5 s of RK4 from the initial state: the soft effect
    S(tc) = max state error against the reference at solref tc = 0.02, 0.01, 0.005 s, the
    ratio r = S(tc) / S(tc/2), the rigid limit's error (runs at tc and tc/2 extrapolated
    to tc -> 0, crosscheck.checks.trajectory.soft.SOFT_LIMIT_*) and its ratio to the correction,
    and the step-halving difference at tc = 0.02 s.
python benchmarks/mujoco_soft.py energy
    slider_crank_split, 0.5 s: max |E - E0| for Euler, implicitfast, RK4 at h = 2, 1, 0.5,
    0.25 ms and solref tc = 0.02, 0.01 s (tests/test_mujoco_bounds.py's energy bounds).
python benchmarks/mujoco_soft.py predict [N [models...]]
    MuJoCo's raw soft answer against EngineModel.predict_soft over N consistent states per
    model (crosscheck.checks.tolerances.SOFT_PREDICTION's figures).
"""

from __future__ import annotations

import sys

import numpy as np

from crosscheck.checks.sampling import consistent_states
from crosscheck.checks.tolerances import scaled_error, soft_prediction
from crosscheck.checks.trajectory.check import T_END, output_grid
from crosscheck.checks.trajectory.measures import state_error
from crosscheck.checks.trajectory.soft import SOFT_LIMIT_FACTOR, SOFT_LIMIT_ORDER
from crosscheck.engines.mujoco.adapter import MujocoAdapter
from reference import models
from reference.integrate.driver import simulate
from reference.models import get
from reference.numeric.model import NumericModel


def _limit(names) -> None:
    grid = output_grid(T_END)
    ad = MujocoAdapter()
    w = 1.0 / (SOFT_LIMIT_FACTOR**SOFT_LIMIT_ORDER - 1.0)
    print(
        f"{'model':20s} {'variant':7s} {'S(.02)':>9s} {'S(.01)':>9s} {'S(.005)':>9s} "
        f"{'r':>5s} {'limit':>9s} {'lim/corr':>8s} {'step':>9s}"
    )
    for name in names or ad.models():
        if name in ad.unsupported():
            continue
        nm = NumericModel(models.get(name))
        q0, u0 = nm.project(nm.model.initial_q, nm.model.initial_u)
        ref = simulate(nm, q0, u0, T_END, "projection", rtol=1e-12, atol=1e-12, t_eval=grid)
        for v in ad.variants(name):
            em = ad.build(name, None, v)
            if not em.soft_constraints:
                continue
            run = {
                tc: em.stiffened(0.02 / tc).simulate(q0, u0, grid, integrator="RK4", timestep=1e-3)
                for tc in (0.02, 0.01, 0.005)
            }
            half = em.simulate(q0, u0, grid, integrator="RK4", timestep=5e-4)
            S = {tc: float(np.max(state_error(tr.q, tr.u, ref.q, ref.u))) for tc, tr in run.items()}
            a, b = run[0.02], run[0.01]
            lim = float(
                np.max(state_error(b.q + w * (b.q - a.q), b.u + w * (b.u - a.u), ref.q, ref.u))
            )
            corr = w * float(np.max(state_error(a.q, a.u, b.q, b.u)))
            step = float(np.max(state_error(a.q, a.u, half.q, half.u)))
            print(
                f"{name:20s} {v or '-'!s:7s} {S[0.02]:9.2e} {S[0.01]:9.2e} "
                f"{S[0.005]:9.2e} {S[0.02] / S[0.01]:5.1f} {lim:9.2e} {lim / corr:8.2f} "
                f"{step:9.2e}",
                flush=True,
            )


def _energy() -> None:
    m = models.get("slider_crank_split")
    for integ in ("Euler", "implicitfast", "RK4"):
        for tc in (0.02, 0.01):
            em = MujocoAdapter(solref=(tc, 1.0)).build("slider_crank_split")
            cells = []
            for h in (2e-3, 1e-3, 5e-4, 2.5e-4):
                tr = em.simulate(
                    m.initial_q, m.initial_u, np.linspace(0, 0.5, 51), integrator=integ, timestep=h
                )
                cells.append(f"h={h:g}: {np.max(np.abs(tr.energy - tr.energy[0])):.3e}")
            print(f"{integ:12s} tc={tc:<5g} " + "  ".join(cells))


def _predict_agreement(n_states: int = 200, names=None) -> list[dict]:
    """MuJoCo's raw soft answer against EngineModel.predict_soft over the run's consistent
    states (the initial state and n_states - 1 seeded random ones, crosscheck.checks.sampling) of
    every MuJoCo model with soft rows: the worst miss max |raw - predicted| (scaled as
    crosscheck.checks.tolerances.scaled_error), the predicted soft effect's range and the judged
    ratio (crosscheck.checks.tolerances.soft_prediction), of the accelerations and (lam_*) the
    multipliers."""
    ad, rows = MujocoAdapter(), []
    for name in names or ad.models():
        if name in ad.unsupported():
            continue
        nm = NumericModel(get(name))
        for variant in ad.variants(name):
            em = ad.build(name, None, variant)
            if not em.soft_constraints:
                continue
            w: dict = {"model": name, "variant": variant}
            for q, u in consistent_states(nm, n_states):
                ref, fw = nm.forward(q, u), em.forward(q, u)
                acc, lam = em.predict_soft(q, u, ref.accelerations)
                pairs = [("", fw.accelerations, acc, ref.accelerations)]
                if fw.multipliers is not None and lam is not None:
                    pairs.append(("lam_", fw.multipliers, lam, ref.multipliers))
                for key, raw, p, r in pairs:
                    pred = scaled_error(p, r)
                    for k, v in (
                        ("miss", scaled_error(raw, p)),
                        ("pred_max", pred),
                        ("ratio", soft_prediction(raw, r, p - r)[0]),
                    ):
                        w[key + k] = max(w.get(key + k, 0.0), v)
                    w[key + "pred_min"] = min(w.get(key + "pred_min", np.inf), pred)
            rows.append(w)
    return rows


def _predict(args) -> None:
    n = int(args[0]) if args else 200
    keys = ("miss", "ratio", "pred_min", "pred_max")
    print(
        f"{'model':20s} {'variant':8s} "
        + " ".join(f"{k:>9s}" for k in keys)
        + " "
        + " ".join(f"{'lam_' + k:>12s}" for k in keys)
    )
    for r in _predict_agreement(n, args[1:] or None):
        print(
            f"{r['model']:20s} {r['variant'] or '-'!s:8s} "
            + " ".join(f"{r[k]:9.2e}" for k in keys)
            + " "
            + " ".join(f"{r.get('lam_' + k, float('nan')):12.2e}" for k in keys)
        )


if __name__ == "__main__":
    what, rest = (sys.argv[1], sys.argv[2:]) if len(sys.argv) > 1 else ("limit", [])
    {"energy": lambda _: _energy(), "predict": _predict}.get(what, _limit)(rest)
