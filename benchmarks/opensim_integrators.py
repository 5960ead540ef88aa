"""OpenSim's adaptive integrators in `crosscheck run`'s trajectory check (docs/engines/opensim.md,
"Trajectories"): for each model and integrator, the
wall time of the run at the check's rtol, its steps, and every trajectory record's error as a
fraction of its tolerance, the integrator put first in the adapter's list as the check reads
it. Then one `Manager.integrate(5 s)` call with the same setting: whether stopping at the 250
output times is what the run costs (it is not: the cost is Simbody's own steps).

    python benchmarks/opensim_integrators.py
    python benchmarks/opensim_integrators.py top_euler --integrators CPodes
"""

from __future__ import annotations

import argparse
import dataclasses
import time

from crosscheck.checks.trajectory.check import ENGINE_RTOL, output_grid, trajectory_records
from crosscheck.engines.registry import get_engine
from reference import NumericModel, models


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("models", nargs="*", default=["slider_crank", "double_pendulum_3d"])
    ap.add_argument("--integrators", nargs="+", default=["RungeKuttaMerson", "RungeKuttaFeldberg"])
    args = ap.parse_args()
    adapter = get_engine("opensim")
    caps = adapter.capabilities
    for name in args.models:
        nm = NumericModel(models.get(name))
        q0, u0 = nm.project(nm.model.initial_q, nm.model.initial_u)
        for integrator in args.integrators:
            em = adapter.build(name, nm.params)
            t0 = time.perf_counter()
            tr = em.simulate(q0, u0, output_grid(5.0), integrator=integrator, rtol=ENGINE_RTOL)
            wall = time.perf_counter() - t0
            first = (integrator, *(i for i in caps.integrators if i != integrator))
            adapter.capabilities = dataclasses.replace(caps, integrators=first)
            try:
                records, _series = trajectory_records(name, nm, [adapter])
            finally:
                adapter.capabilities = caps
            ratios = ", ".join(
                f"{r.get('variant') or ''}{'/' if r.get('variant') else ''}{r['quantity']} "
                f"{r['error'] / r['tolerance']:.3f}"
                for r in records
                if r["engine"] == "opensim" and r["error"] is not None and r["tolerance"]
            )
            print(f"{name:20} {integrator:20} {wall:6.2f} s {tr.steps:6d} steps  {ratios}")
            wall, steps = _one_call(em, q0, u0, integrator)
            print(f"{'':20} {'one integrate call':20} {wall:6.2f} s {steps:6d} steps")


def _one_call(em, q0, u0, integrator: str) -> tuple[float, int]:
    """One Manager.integrate to 5 s, set up as the adapter's simulate sets it up."""
    qe, ve = em.to_engine_state(q0, u0)
    state = em.model.initializeState()
    em._set_state_on(state, qe, ve, 0.0)
    manager, _setting = em._manager(integrator, ENGINE_RTOL, None)
    em.model.realizeAcceleration(state)
    manager.initialize(state)
    t0 = time.perf_counter()
    manager.integrate(5.0)
    return time.perf_counter() - t0, int(manager.getStatesTable().getNumRows()) - 1


if __name__ == "__main__":
    main()
