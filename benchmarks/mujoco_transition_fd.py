"""MuJoCo's own finite differences (mjd_transitionFD) of its soft accelerations, read along the
constraint manifold's tangent, against central differences of its answer on the manifold and
against the soft derivatives its impedance predicts (docs/engines/mujoco.md, "Derivatives").

    python benchmarks/mujoco_transition_fd.py [MODEL ...]     (default: pendulum_xy slider_crank)

For each model (one consistent state) and transitionFD step eps, the q-directions' largest
difference |transitionFD - central| (absolute, u' units) next to the predicted soft effect on
the derivative: a difference growing as 1/eps is round-off over eps, not physics.
"""

from __future__ import annotations

import sys

import numpy as np

import crosscheck.engines.mujoco.derivatives as md
from crosscheck.checks.derivatives.differences import engine_differences
from crosscheck.checks.derivatives.engine import ReferenceAtState
from crosscheck.checks.sampling import consistent_states
from crosscheck.engines.registry import get_engine
from reference import NumericModel, models
from reference.derivatives import DerivativeModel

STEP = 1e-2  # the central differences' step on the manifold


def main(names) -> None:
    adapter = get_engine("mujoco")
    for name in names:
        nm = NumericModel(models.get(name))
        em = adapter.build(name, nm.params)
        q, u = consistent_states(nm, 3)[1]
        ref = ReferenceAtState(DerivativeModel(nm), q, u, 0.0)
        diff = engine_differences(em, nm, ref.dirs, ref.q, ref.u, 0.0, STEP, True)
        raw = diff.get("dq", "accelerations", "raw")
        effect = diff.get("dq", "accelerations", "predicted") - diff.get(
            "dq", "accelerations", "reference"
        )
        for eps in (1e-4, 1e-6, 1e-8):
            md.EPS = eps
            own = em.derivatives(q, u, 0.0, ref.dirs).blocks["dq"][0]
            print(
                f"{name:16s} eps {eps:.0e}  |transitionFD - central| "
                f"{np.max(np.abs(own - raw)):.2e}  predicted soft effect "
                f"{np.max(np.abs(effect)):.2e}"
            )


if __name__ == "__main__":
    main(sys.argv[1:] or ["pendulum_xy", "slider_crank"])
