"""The compiled backend against the pure-Python path it replaces, output by output
(benchmarks/reference_speed.md, "Equality of the backends").

For each model, one NumericModel on the backend the setting gives (CROSSCHECK_BACKEND=c) and
one on the Python path, evaluated at the same 16 consistent states
(crosscheck.checks.sampling.consistent_states): every output of forward (accelerations,
multipliers, pivot ratio), matrices (M, f, A, b), residuals, energy and kinematics. Prints how
many outputs are equal to the bit and the largest relative difference of the others.

    CROSSCHECK_BACKEND=c python benchmarks/backend_equality.py [models...]
"""

from __future__ import annotations

import sys

import numpy as np

from crosscheck.checks.sampling import consistent_states
from reference import models
from reference.numeric.model import NumericModel

MODELS = ("pendulum_xy", "slider_crank", "double_pendulum_3d", "top_cartesian", "knife_edge")
STATES = 16


def outputs(nm: NumericModel, q, u) -> np.ndarray:
    fw = nm.forward(q, u)
    M, f, A, b = nm.matrices(q, u)
    pos, vel = nm.residuals(q, u)
    parts = (fw.accelerations, fw.multipliers, [fw.pivot_ratio], M, f, A, b, pos, vel)
    parts += (nm.energy(q, u), nm.kinematics(q, u))
    return np.concatenate([np.ravel(np.asarray(x, float)) for x in parts])


def main(names) -> None:
    for name in names:
        model = models.get(name)
        compiled, python = NumericModel(model), NumericModel(model, backend="python")
        same = total = 0
        worst = 0.0
        for q, u in consistent_states(python, STATES):
            a, b = outputs(compiled, q, u), outputs(python, q, u)
            equal = a == b
            total += a.size
            same += int(np.sum(equal))
            if not equal.all():
                rel = np.abs(a - b)[~equal] / np.maximum(np.abs(b[~equal]), 1e-300)
                worst = max(worst, float(np.max(rel)))
        print(
            f"{name:20s} {compiled.backend} against python: {same} / {total} outputs equal "
            f"to the bit; largest relative difference of the others {worst:.1e}",
            flush=True,
        )


if __name__ == "__main__":
    main(sys.argv[1:] or MODELS)
