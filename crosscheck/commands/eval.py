"""`crosscheck eval NAME`: the reference's accelerations, multipliers, residuals and energy of a
model at one state."""

from __future__ import annotations

import math

from crosscheck.commands.arguments import (
    add_model_files,
    assignments,
    finite_float,
    float_list,
)
from crosscheck.runtime import jsonio
from reference.errors import ModelInputError


def cmd_eval(args) -> int:
    import numpy as np

    from reference import NumericModel, models

    model = models.get(args.name)
    nm = NumericModel(model, args.formulation, assignments(args.set))
    q = float_list(args.q, "--q")
    u = float_list(args.u, "--u")
    q = list(model.initial_q) if q is None else q
    u = list(model.initial_u) if u is None else u
    if not math.isfinite(args.t):
        raise ModelInputError("--t must be finite")
    if args.project:
        q, u = nm.project(q, u, args.t)
    else:
        nm.check_consistent(q, u, args.t)
    res = nm.forward(q, u, args.t)
    pos, vel = nm.residuals(q, u, args.t)
    K, V = nm.energy(q, u, args.t)
    out = {
        "model": model.name,
        "source": model.source,
        "formulation": nm.formulation,
        "parameters": nm.params,
        "t": args.t,
        "q": np.asarray(q, float),
        "u": np.asarray(u, float),
        "coordinates": [s.name for s in model.coordinates],
        "speeds": [s.name for s in model.speeds],
        "accelerations": res.accelerations,
        "multipliers": res.multipliers,
        "constraint_names": list(model.constraint_names),
        "multiplier_meaning": model.multiplier_meaning,
        "coordinate_rates": nm.kinematics(q, u, args.t),
        "residuals": {"position": pos, "velocity": vel},
        "energy": {"kinetic": K, "potential": V, "total": K + V},
        "pivot_ratio": res.pivot_ratio,
    }
    if args.json:
        print(jsonio.dumps(out, allow_nan=False))
    else:
        print(f"{model.name} ({model.source}), {nm.formulation}, t = {args.t}")
        for s, a in zip(out["speeds"], res.accelerations, strict=True):
            print(f"  d({s})/dt = {a:.12g}")
        for name, lam in zip(model.constraint_names or [], res.multipliers, strict=True):
            print(f"  lambda[{name}] = {lam:.12g}")
        print(
            f"  residuals: position {np.abs(pos).max() if pos.size else 0:.2e}, "
            f"velocity {np.abs(vel).max() if vel.size else 0:.2e}"
        )
    return 0


def register(sub) -> None:
    e = sub.add_parser("eval", help="accelerations and multipliers of a model at a state")
    e.add_argument("name", help="model name (see `crosscheck models`)")
    e.add_argument("--formulation", default=None, help="lagrange | dalembert | kane")
    e.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override a parameter (repeatable)",
    )
    e.add_argument("--q", help="coordinates, comma-separated (default: the model's initial state)")
    e.add_argument("--u", help="speeds, comma-separated (q-dots for Lagrange/d'Alembert models)")
    e.add_argument("--t", type=finite_float, default=0.0, help="time (rheonomic constraints)")
    e.add_argument(
        "--project",
        action="store_true",
        help="project the state onto the constraint manifold instead of refusing it (and a "
        "--model-file's initial state, as the other commands' --project)",
    )
    e.add_argument("--json", action="store_true")
    add_model_files(e, project=False)
    e.set_defaults(func=cmd_eval)
