"""Registry of the unit's multiplier formulations: name -> function(model) -> equations, on
one of two derivation paths.

- "symbolic": M and f written out as expressions and simplified (reference.formulations.
  lagrange, dalembert, kane: EquationsOfMotion). The textbook's models take it.
- "sums": each body's partial velocities and force terms as expressions, the sums over the
  bodies left to the evaluation (kane_sums, lagrange_sums: SummedEquations). Writing M out
  costs what the bodies' expressions cost as trees, which grows exponentially with a chain's
  depth (a robot) and quadratically with its length; the sums cost what they cost as graphs.

`derivation_path(model)` chooses by the size of the model's expressions as trees
(SUMS_MIN_SIZE, measured: docs/architecture.md, "Two derivation paths"); CROSSCHECK_DERIVATION
(symbolic, sums; unset or auto: by size) overrides it.
"""

from __future__ import annotations

import os

from reference.dag import tree_size
from reference.errors import ModelInputError
from reference.formulations.dalembert import dalembert
from reference.formulations.kane import kane
from reference.formulations.kane_sums import dalembert_sums, kane_sums
from reference.formulations.lagrange import lagrange
from reference.formulations.lagrange_sums import lagrange_sums

FORMULATIONS = {"lagrange": lagrange, "dalembert": dalembert, "kane": kane}
SUMMED = {"lagrange": lagrange_sums, "dalembert": dalembert_sums, "kane": kane_sums}
PATHS = ("symbolic", "sums")

# A model whose bodies' velocities, angular velocities and constraint rows hold more
# operations than this as trees takes the sums path. Measured cold (benchmarks/scaling.md,
# "Two derivation paths"): the symbolic path took 1-5 s up to size 325 (every built-in model
# is under 100), 7-8 s at 554-692 (the A02 chain, N = 10; tests/data/gripper.xml), 18 s at
# 1034 (spatial_mix.xml), 40 s at 1104 (A02, N = 20) and did not finish Cassie (2.4e6) in 25
# minutes; the sums path took 0.1-2.6 s on every one of them. Past 600 the symbolic path's
# one advantage, simplified entries, no longer pays for its growth.
SUMS_MIN_SIZE = 600


def model_size(model) -> int:
    """The operations of the expressions the symbolic path multiplies out: the bodies' v_G
    and omega and the constraint rows, written out as trees (counted on their graph)."""
    exprs = [x for b in model.bodies for x in (*b.v_G, *b.omega)]
    exprs += [*model.configuration_constraints, *model.motion_constraints]
    return tree_size(exprs)


def derivation_path(model) -> str:
    """'symbolic' or 'sums' for `model`: CROSSCHECK_DERIVATION when set to one of them, else
    'sums' past SUMS_MIN_SIZE."""
    want = os.environ.get("CROSSCHECK_DERIVATION", "").strip().lower() or "auto"
    if want in PATHS:
        return want
    if want != "auto":
        raise ModelInputError(
            f"CROSSCHECK_DERIVATION={want!r}: valid values are auto, {', '.join(PATHS)}"
        )
    return "sums" if model_size(model) > SUMS_MIN_SIZE else "symbolic"


def derive(model, formulation: str, path: str | None = None):
    """Derive the equations of motion of `model` with the named formulation, on `path`
    ('symbolic' or 'sums'; None: derivation_path(model))."""
    if formulation not in FORMULATIONS:
        raise ModelInputError(
            f"unknown formulation {formulation!r}; valid: {', '.join(FORMULATIONS)}"
        )
    if formulation not in model.formulations:
        raise ModelInputError(
            f"model {model.name!r} does not declare formulation {formulation!r}; "
            f"it has: {', '.join(model.formulations)}"
        )
    if (path or derivation_path(model)) == "sums":
        return SUMMED[formulation](model)
    return FORMULATIONS[formulation](model)
