"""`crosscheck models [--json]`: every model (built-in and from --model-file): coordinates,
speeds, parameters with units, constraints and their classification, formulations."""

from __future__ import annotations

from crosscheck.commands.arguments import add_model_files
from crosscheck.runtime import jsonio


def describe_model(model) -> dict:
    from reference.constraints import classify

    return {
        "name": model.name,
        "source": model.source,
        "title": model.title,
        "coordinates": [s.name for s in model.coordinates],
        "speeds": [s.name for s in model.speeds],
        "parameters": {p.name: p.default for p in model.parameters},
        "parameter_units": {p.name: p.unit for p in model.parameters},
        "constraints": classify(model),
        "formulations": list(model.formulations),
        "multiplier_meaning": model.multiplier_meaning,
        "geometry_note": model.geometry_note,
        "initial_state": {"q": list(model.initial_q), "u": list(model.initial_u)},
    }


def cmd_models(args) -> int:
    from reference import models

    described = [
        {**describe_model(models.get(n)), "origin": models.origin(n)}
        for n in [*models.names(), *models.user_names()]
    ]
    if args.json:
        print(jsonio.dumps(described, allow_nan=False))
        return 0
    rows = [("name", "origin", "source", "q", "u", "constraints", "formulations")]
    for d in described:
        rows.append(
            (
                d["name"],
                d["origin"],
                d["source"],
                ",".join(d["coordinates"]),
                str(len(d["speeds"])),
                str(len(d["constraints"])),
                ",".join(d["formulations"]),
            )
        )
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    for r in rows:
        print("  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip())
    return 0


def register(sub) -> None:
    m = sub.add_parser("models", help="list the models of the unit")
    m.add_argument("--json", action="store_true", help="machine-readable list")
    add_model_files(m)
    m.set_defaults(func=cmd_models)
