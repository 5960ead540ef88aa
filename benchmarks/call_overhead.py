"""What a single-state forward call costs on the numba backend, and where it goes: the
figures of benchmarks/reference_speed.md, "Why C beside numba".

    CROSSCHECK_BACKEND=numba python benchmarks/call_overhead.py [models...]

Per model, min us per call over interleaved rounds at bench's first state: the checked call,
the raw call (fresh arrays, and into a preallocated out), forward_into, the kernel through
numba's dispatch, the compiled entry point bare and behind the cheapest safe Python guard (and
the dispatch in the same Python frame), and Pinocchio's timed call; then each over Pinocchio's.
A cold numba cache compiles each model's kernels first (10-20 s per model).
"""

from __future__ import annotations

import sys
import timeit

import numpy as np

ROUNDS, NUMBER = 31, 5000
MODELS = ("pendulum_xy", "slider_crank", "double_pendulum_3d", "top_cartesian")


def _min_us(stmts: dict, env: dict) -> dict:
    """Min over ROUNDS interleaved rounds of NUMBER calls, us per call."""
    res: dict = {k: [] for k in stmts}
    for _ in range(ROUNDS):
        for k, s in stmts.items():
            res[k].append(timeit.timeit(s, globals=env, number=NUMBER) / NUMBER * 1e6)
    return {k: min(v) for k, v in res.items()}


def calls(names) -> None:
    from crosscheck.checks.sampling import consistent_states
    from crosscheck.engines.registry import get_engine
    from reference import NumericModel, models

    f64, s8, nd = np.dtype(np.float64), (8,), np.ndarray
    for name in names:
        nm = NumericModel(models.get(name))
        q, u = (np.asarray(x, float) for x in consistent_states(nm, 16)[0])
        kf = nm._kf
        ep = kf.overloads[kf.signatures[0]].entry_point

        scratch = np.empty(nm._nf)

        def guarded(q, u, ep=ep, pa=nm._pa, db=nm._db0, out=scratch):
            if type(q) is nd and type(u) is nd and q.dtype is f64 is u.dtype:
                if q.strides == s8 == u.strides:
                    return ep(q, u, 0.0, pa, db, out)
            return None

        def dispatched(q, u, kf=kf, pa=nm._pa, db=nm._db0, out=scratch):  # guarded's frame
            return kf(q, u, 0.0, pa, db, out)

        env = dict(
            nm=nm, q=q, u=u, buf=np.empty(nm._nf), kf=kf, ep=ep, guarded=guarded,
            dispatched=dispatched, pa=nm._pa, db=nm._db0,
            pin=get_engine("pinocchio").build(name, nm.params).timed_forward(q, u),
        )  # fmt: skip
        t = _min_us(
            {
                "checked": "nm.forward(q, u)",
                "raw": "nm.forward_raw(q, u, 0.0)",
                "raw-out": "nm.forward_raw(q, u, 0.0, out=buf)",
                "into": "nm.forward_into(q, u, 0.0, buf)",
                "dispatch": "kf(q, u, 0.0, pa, db, buf)",
                "entry point": "ep(q, u, 0.0, pa, db, buf)",
                "guarded entry point": "guarded(q, u)",
                "dispatch, same frame": "dispatched(q, u)",
                "pinocchio": "pin()",
            },
            env,
        )
        print(f"{name}: " + ", ".join(f"{k} {v:.3f}" for k, v in t.items()))
        print(
            "  over pinocchio: " + ", ".join(f"{k} {v / t['pinocchio']:.2f}" for k, v in t.items())
        )


if __name__ == "__main__":
    calls(sys.argv[1:] or MODELS)
