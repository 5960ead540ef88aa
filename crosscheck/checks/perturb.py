"""Parameter perturbation (fault injection), parsed and applied in one place.

`--perturb ENGINE:PARAM=REL` changes one parameter of one engine's model by a relative amount
(`crosscheck run`, `crosscheck sweep`): a run with mujoco:m2=1e-6 on the slider-crank must fail.
A user's MJCF file has no parameters (its numbers are MuJoCo's compiled ones); its
perturbable numbers are those the engines' models of it read, named as in
crosscheck.engines.compiled_model (``crank.mass``, ``crank.I2``, ``A.damping``, ``gravity``).
"""

from __future__ import annotations

from crosscheck.engines.registry import engine_names
from reference.errors import ModelInputError


def parse_perturb(specs: list[str]) -> dict[str, dict[str, float]]:
    """['mujoco:m2=1e-6'] -> {'mujoco': {'m2': 1e-6}}; engines must be registered."""
    out: dict[str, dict[str, float]] = {}
    for spec in specs or []:
        try:
            engine, rest = spec.split(":", 1)
            param, rel = rest.split("=", 1)
            out.setdefault(engine.strip(), {})[param.strip()] = value = float(rel)
        except ValueError:
            raise ModelInputError(
                f"--perturb {spec!r}: expected ENGINE:PARAM=REL, e.g. mujoco:m2=1e-6"
            ) from None
        if value == 0.0:  # REL is relative: PARAM times 1 + 0 is PARAM itself
            raise ModelInputError(
                f"--perturb {spec!r}: REL is a relative change (PARAM times 1 + REL), and "
                f"0 changes nothing; give a non-zero REL, e.g. {spec.split('=')[0]}=1e-6"
            )
        if engine.strip() not in engine_names():
            raise ModelInputError(
                f"--perturb {spec!r}: unknown engine {engine!r}; valid: {', '.join(engine_names())}"
            )
    return out


def check_parameters(name: str, parameter_names, perturb: dict[str, dict[str, float]]) -> None:
    """Every perturbed parameter exists in model `name` (before any work is done)."""
    for engine, ps in perturb.items():
        for p in ps:
            if p not in parameter_names:
                raise ModelInputError(
                    f"--perturb {engine}:{p}: model {name!r} has no "
                    f"parameter {p!r}; valid: {', '.join(parameter_names)}"
                )


def parameter_defaults(name: str) -> dict[str, float]:
    """What a perturbation of a model may change, with the values at its defaults.

    Parameters
    ----------
    name : str
        A registered model.

    Returns
    -------
    dict of str to float
        Its parameters' defaults; for a user's MJCF file (which has none), the compiled numbers
        the engines' models of it read (crosscheck.engines.compiled_model.perturbable).
    """
    from reference import models

    out = {p.name: p.default for p in models.get(name).parameters}
    src = models.user_source(name)
    if not out and hasattr(src, "mj"):
        from crosscheck.engines.compiled_model import perturbable

        out = perturbable(src.mj)
    return out


def perturbed(name, params: dict, perturb: dict) -> dict:
    """The parameters with the relative perturbations of one engine applied (fault injection);
    a perturbed number the parameters do not hold (a user's MJCF file's compiled numbers)
    starts from its value in the model (parameter_defaults)."""
    params = dict(params)
    for p, rel in perturb.items():
        if p not in params:
            defaults = parameter_defaults(name)
            if p not in defaults:
                raise ModelInputError(
                    f"--perturb: model {name!r} has no parameter {p!r}; valid: "
                    f"{', '.join(defaults)}"
                )
            params[p] = defaults[p]
        params[p] *= 1.0 + rel
    return params


def check_perturb(names, perturb: dict) -> None:
    """Before any work: every perturbed parameter exists in every model and stays valid
    (finite, positive where it must be) at the model's defaults -- a relative change of nan,
    or of -2 on a mass, is bad input (exit 2), found before the first model runs."""
    from reference import models
    from reference.numeric.model import resolve_parameters

    if not perturb:  # nothing to check; building every model here would cost ~0.8 s
        return
    for name in names:
        model = models.get(name)
        for ps in perturb.values():
            if not model.parameters:  # a user's MJCF file: its compiled numbers
                _check_compiled(name, perturbed(name, {}, ps))
                continue
            resolve_parameters(
                model, perturbed(name, {p.name: p.default for p in model.parameters}, ps)
            )


def _check_compiled(name: str, values: dict[str, float]) -> None:
    """Perturbed compiled numbers of a user's file stay finite and keep their sign (a mass,
    an inertia, a stiffness, a damping, an armature or gravity's length)."""
    import math

    defaults = parameter_defaults(name)
    bad = [
        f"{p}={v}"
        for p, v in values.items()
        if not math.isfinite(v) or (defaults[p] >= 0 and v < 0) or (defaults[p] > 0 and v == 0)
    ]
    if bad:
        raise ModelInputError(
            f"--perturb on {name!r}: {', '.join(bad)} is not a valid value (finite, and of the "
            "compiled number's sign)"
        )


def check_perturb_changes(names, engine_names, perturb: dict) -> None:
    """Before any work: every perturbation changes its engine's model of every model in the
    run (a perturbation that does nothing passes and proves nothing). The engine's
    model is built at the defaults with and without each perturbed parameter and the two
    fingerprints (EngineModel.fingerprint: masses, inertias, geometry, gravity, loads) are
    compared; an engine whose models have no fingerprint is not checked."""
    from crosscheck.checks.instantaneous import build
    from crosscheck.engines.base import EngineUnsupported
    from crosscheck.engines.registry import get_engine

    for engine, ps in perturb.items():
        if engine not in engine_names:
            raise ModelInputError(
                f"--perturb {engine}:...: {engine} is not among this run's engines "
                f"({', '.join(engine_names)}), so the perturbation would change nothing; add it "
                f"to --engines"
            )
        adapter = get_engine(engine)
        for name in names:
            defaults = parameter_defaults(name)
            for variant in adapter.variants(name):
                for p, rel in ps.items():
                    try:
                        before = build(adapter, name, defaults, variant).fingerprint()
                        after = build(
                            adapter, name, perturbed(name, defaults, {p: rel}), variant
                        ).fingerprint()
                    except (EngineUnsupported, NotImplementedError):
                        break  # nothing built, or no fingerprint: not checked
                    if before == after:
                        raise ModelInputError(
                            _no_effect(engine, name, variant, p, rel, defaults[p])
                        )


def _no_effect(engine, name, variant, p, rel, value) -> str:
    where = f"{engine}'s model of {name!r}" + (f" (variant {variant})" if variant else "")
    why = (
        f"{p} is 0 at the model's defaults, and a relative change of 0 is 0"
        if value == 0.0
        else f"{where} does not contain {p} (its masses, inertias, geometry, gravity and "
        f"loads are unchanged; the engine's coordinates or loads do not use it)"
    )
    return (
        f"--perturb {engine}:{p}={rel:g} does not change {where}: {why}; perturb a "
        f"parameter the engine's model uses"
    )
