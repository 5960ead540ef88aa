"""Registry of the unit's multiplier formulations: name -> function(model) -> EquationsOfMotion."""

from __future__ import annotations

from reference.errors import ModelInputError
from reference.formulations.dalembert import dalembert
from reference.formulations.kane import kane
from reference.formulations.lagrange import lagrange

FORMULATIONS = {"lagrange": lagrange, "dalembert": dalembert, "kane": kane}


def derive(model, formulation: str):
    """Derive the equations of motion of `model` with the named formulation."""
    if formulation not in FORMULATIONS:
        raise ModelInputError(
            f"unknown formulation {formulation!r}; valid: {', '.join(FORMULATIONS)}"
        )
    if formulation not in model.formulations:
        raise ModelInputError(
            f"model {model.name!r} does not declare formulation {formulation!r}; "
            f"it has: {', '.join(model.formulations)}"
        )
    return FORMULATIONS[formulation](model)
