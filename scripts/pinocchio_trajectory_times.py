"""Wall time of the Pinocchio adapter's trajectories, as `crosscheck run` integrates them
(solve_ivp DOP853 at the run's rtol = atol, from the model's projected initial state, on the
run's output grid; every variant of five models), with the number of right-hand-side calls.
--save keeps the states, --compare reads another run's to give the largest state difference
per run (to compare two commits, run it in each).

Wall times drift on a shared machine; instruction counts do not. Under valgrind's cachegrind,
the count of a run less the count of a run with --no-integrate (the same imports and model
builds, no integration) is what the trajectories cost:

    PYTHONPATH=$PWD python scripts/pinocchio_trajectory_times.py [--save F.npz] [--compare F.npz]
    PYTHONPATH=$PWD valgrind --tool=cachegrind --cache-sim=no --cachegrind-out-file=/dev/null \
        $(python -c "import sys; print(sys.executable)") \
        scripts/pinocchio_trajectory_times.py [--no-integrate]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from crosscheck.checks.trajectory.check import ENGINE_RTOL, T_END, output_grid
from crosscheck.engines.registry import get_engine
from reference.models import get
from reference.numeric.model import NumericModel

MODELS = ("double_pendulum_3d", "top_cartesian", "slider_crank", "exercise_6_1", "top_euler")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--save", help="write every run's (q, u) to this .npz")
    ap.add_argument("--compare", help="a --save file of another run: print max |difference|")
    ap.add_argument("--no-integrate", action="store_true", help="build the models, integrate none")
    args = ap.parse_args()
    adapter = get_engine("pinocchio")
    t_eval = output_grid(T_END)
    states, total = {}, 0.0
    other = dict(np.load(args.compare)) if args.compare else {}
    for name in MODELS:
        model = get(name)
        nm = NumericModel(model)
        q0, u0 = nm.project(model.initial_q, model.initial_u)  # as the run starts
        for variant in adapter.variants(name):
            em = adapter.build(name, nm.params, variant)
            if args.no_integrate:
                continue
            t0 = time.perf_counter()
            tr = em.simulate(q0, u0, t_eval, integrator="DOP853", rtol=ENGINE_RTOL)
            wall = time.perf_counter() - t0
            total += wall
            key = f"{name}:{variant}"
            states[key] = np.hstack([tr.q, tr.u])
            diff = (
                f"  max |diff| {np.max(np.abs(states[key] - other[key])):.2e}"
                if key in other
                else ""
            )
            print(f"{key:28s} {wall:7.3f} s  {tr.steps:6d} calls{diff}", flush=True)
    print(f"total {total:.2f} s")
    if args.save:
        np.savez(args.save, **states)


if __name__ == "__main__":
    main()
