"""`crosscheck eval [NAME]`: the reference's accelerations, multipliers, residuals and energy of
a model at one state (every model of the --model-file files where no name is given)."""

from __future__ import annotations

from crosscheck.commands.arguments import add_model_files, add_state, assignments, given_state
from crosscheck.runtime import jsonio
from reference.errors import ModelInputError


def cmd_eval(args) -> int:
    from reference import models

    if args.name is not None:
        names = [args.name]
    elif getattr(args, "user_models", None):
        names = list(args.user_models)
    else:
        raise ModelInputError(
            "give a model name (see `crosscheck models`) or --model-file FILE (its models)"
        )
    if (args.q is not None or args.u is not None) and len(names) > 1:
        raise ModelInputError(
            f"--q and --u name one model's state; the files hold {len(names)} models: "
            "give one model name"
        )
    outs = [_evaluate(models.get(name), args) for name in names]
    if args.json:
        print(jsonio.dumps(outs[0] if args.name is not None else outs, allow_nan=False))
    return 0


def _evaluate(model, args) -> dict:
    import numpy as np

    from reference import NumericModel

    nm = NumericModel(model, args.formulation, assignments(args.set))
    q, u = given_state(nm, args)
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
    if not args.json:
        print(f"{model.name} ({model.source}), {nm.formulation}, t = {args.t}")
        for s, a in zip(out["speeds"], res.accelerations, strict=True):
            print(f"  d({s})/dt = {a:.12g}")
        for name, lam in zip(model.constraint_names or [], res.multipliers, strict=True):
            print(f"  lambda[{name}] = {lam:.12g}")
        print(
            f"  residuals: position {np.abs(pos).max() if pos.size else 0:.2e}, "
            f"velocity {np.abs(vel).max() if vel.size else 0:.2e}"
        )
    return out


def register(sub) -> None:
    e = sub.add_parser("eval", help="accelerations and multipliers of a model at a state")
    e.add_argument(
        "name",
        nargs="?",
        help="model name (see `crosscheck models`); left out with --model-file: every model "
        "of the files (--json: a list)",
    )
    e.add_argument("--formulation", default=None, help="lagrange | dalembert | kane")
    e.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override a parameter (repeatable)",
    )
    add_state(e, "at which to evaluate")
    e.add_argument("--json", action="store_true")
    add_model_files(e, project=False)
    e.set_defaults(func=cmd_eval)
