"""What a single-state forward call costs, and where it goes, on the model's backend.

    python benchmarks/call_overhead.py [models...]
    python benchmarks/call_overhead.py pendulum_xy --rounds 2 --number 10   # a smoke run

Per model, min us per call over interleaved rounds at bench's first state: the checked call
(NumericModel.forward), the fast call (forward_fast: fresh arrays, and into a preallocated
out), the backend's forward kernel alone (nm.kernels.function('forward'), into a
preallocated out), the Python path of each call (what a state the bound C calls cannot take
goes to), and Pinocchio's timed call; then each over Pinocchio's.
"""

from __future__ import annotations

import argparse
import timeit

import numpy as np

ROUNDS, NUMBER = 31, 5000
MODELS = ("pendulum_xy", "slider_crank", "double_pendulum_3d", "top_cartesian")


def _min_us(stmts: dict, env: dict, rounds: int, number: int) -> dict:
    """Min over `rounds` interleaved rounds of `number` calls, us per call."""
    res: dict = {k: [] for k in stmts}
    for _ in range(rounds):
        for k, s in stmts.items():
            res[k].append(timeit.timeit(s, globals=env, number=number) / number * 1e6)
    return {k: min(v) for k, v in res.items()}


def calls(names, rounds: int = ROUNDS, number: int = NUMBER) -> None:
    from crosscheck.checks.sampling import consistent_states
    from crosscheck.engines.registry import get_engine
    from reference import NumericModel, models

    for name in names:
        nm = NumericModel(models.get(name))
        q, u = (np.asarray(x, float) for x in consistent_states(nm, 16)[0])
        k = nm.kernels
        env = dict(
            nm=nm, q=q, u=u, buf=np.empty(nm.n + nm.m + 1), kf=k.function("forward"),
            pa=nm.kernel_parameters, db=k.zero_db,
            pin=get_engine("pinocchio").build(name, nm.params).timed_forward(q, u),
        )  # fmt: skip
        t = _min_us(
            {
                "checked": "nm.forward(q, u)",
                "fast": "nm.forward_fast(q, u, 0.0)",
                "fast-out": "nm.forward_fast(q, u, 0.0, out=buf)",
                "kernel": "kf(q, u, 0.0, pa, db, buf)",
                "checked, Python path": "nm._forward_checked(q, u, 0.0)",
                "fast-out, Python path": "nm._forward_fast_checked(q, u, 0.0, None, buf)",
                "pinocchio": "pin()",
            },
            env,
            rounds,
            number,
        )
        print(f"{name} ({nm.backend}): " + ", ".join(f"{k} {v:.3f}" for k, v in t.items()))
        print(
            "  over pinocchio: " + ", ".join(f"{k} {v / t['pinocchio']:.2f}" for k, v in t.items())
        )


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("models", nargs="*", default=list(MODELS))
    ap.add_argument("--rounds", type=int, default=ROUNDS, help="interleaved rounds (min taken)")
    ap.add_argument("--number", type=int, default=NUMBER, help="calls per round")
    args = ap.parse_args()
    calls(args.models, args.rounds, args.number)
