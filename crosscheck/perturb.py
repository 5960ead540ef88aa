"""Parameter perturbation (fault injection), parsed and applied in one place.

`--perturb ENGINE:PARAM=REL` changes one parameter of one engine's model by a relative amount
(`crosscheck run`, `crosscheck sweep`): a run with mujoco:m2=1e-6 on the slider-crank must fail.
"""
from __future__ import annotations

from reference.errors import ModelInputError

from .engines.registry import engine_names


def parse_perturb(specs: list[str]) -> dict[str, dict[str, float]]:
    """['mujoco:m2=1e-6'] -> {'mujoco': {'m2': 1e-6}}; engines must be registered."""
    out: dict[str, dict[str, float]] = {}
    for spec in specs or []:
        try:
            engine, rest = spec.split(":", 1)
            param, rel = rest.split("=", 1)
            out.setdefault(engine.strip(), {})[param.strip()] = float(rel)
        except ValueError:
            raise ModelInputError(f"--perturb {spec!r}: expected ENGINE:PARAM=REL, "
                                  f"e.g. mujoco:m2=1e-6")
        if engine.strip() not in engine_names():
            raise ModelInputError(f"--perturb {spec!r}: unknown engine {engine!r}; valid: "
                                  f"{', '.join(engine_names())}")
    return out


def check_parameters(name: str, parameter_names, perturb: dict[str, dict[str, float]]) -> None:
    """Every perturbed parameter exists in model `name` (before any work is done)."""
    for engine, ps in perturb.items():
        for p in ps:
            if p not in parameter_names:
                raise ModelInputError(f"--perturb {engine}:{p}: model {name!r} has no "
                                      f"parameter {p!r}; valid: {', '.join(parameter_names)}")


def perturbed(name, params: dict, perturb: dict) -> dict:
    """The parameters with the relative perturbations of one engine applied (fault injection)."""
    params = dict(params)
    for p, rel in perturb.items():
        if p not in params:
            raise ModelInputError(f"--perturb: model {name!r} has no parameter {p!r}; valid: "
                                  f"{', '.join(params)}")
        params[p] *= 1.0 + rel
    return params
