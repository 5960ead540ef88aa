"""`crosscheck simulate NAME`: the reference's trajectory of one model, written to take away.

Three files in --out: NAME.csv, one row per output time (t, the coordinates, the speeds, the
multipliers, the position residuals f(q, t), the velocity residuals A u + a0); NAME.npz, the
same arrays with their names; NAME.json, the run (model, parameters, formulation, method,
integrator, tolerances, the error estimate and how it was made, the machine and versions).
The error estimate is the largest scaled difference max |x - x_tight| / max(max |x_tight|, 1)
over the outputs between this run and one at a hundredth of its tolerances, as `crosscheck
run` judges the reference's own trajectory (docs/checks.md).
"""

from __future__ import annotations

import io
import itertools
import math
import sys

from crosscheck.commands.arguments import (
    add_model_files,
    add_state,
    assignments,
    finite_float,
    float_list,
    given_state,
    horizon,
    output_dir,
    positive_int,
)
from reference.errors import ModelInputError
from reference.integrate import METHODS

# Outputs written: the sampled grid is capped so a file stays readable and the run's cost is
# the integrator's, not the output's.
MAX_POINTS = 100_000
# The tighter run that estimates the error is at rtol / TIGHTER, but never below TIGHTEST:
# DOP853's error stops following rtol near 1e-14 (round-off of the state, eps = 2.2e-16 times
# the stages' sums), so a tighter request measures nothing more.
TIGHTER, TIGHTEST = 100.0, 1e-14


def cmd_simulate(args) -> int:
    import numpy as np

    from crosscheck.runtime.output import Outputs
    from reference import NumericModel, models
    from reference.integrate.driver import simulate

    out = output_dir(args.out)  # an unusable --out fails now, not after the run
    model = models.get(args.name)
    nm = NumericModel(model, args.formulation, assignments(args.set))
    q0, u0 = given_state(nm, args)
    times = _times(args)
    rtol = args.rtol
    atol = rtol * 1e-2 if args.atol is None else args.atol
    kw = dict(method=args.method, integrator=args.integrator, t_eval=times, t0=args.t)
    tr = simulate(nm, q0, u0, float(times[-1]), rtol=rtol, atol=atol, **kw)
    _refuse_singular_crossing(tr)
    tight_rtol = max(rtol / TIGHTER, TIGHTEST)
    tight = simulate(nm, q0, u0, float(times[-1]), rtol=tight_rtol, atol=atol / TIGHTER, **kw)
    X = np.hstack([tr.q, tr.u])
    Xt = np.hstack([tight.q, tight.u])
    estimate = float(np.max(np.abs(X - Xt)) / max(float(np.max(np.abs(Xt))), 1.0))
    arrays = _arrays(nm, tr)
    info = _info(args, nm, tr, rtol, atol, tight_rtol, estimate)
    with Outputs(out) as staged:
        staged.stage(f"{model.name}.csv", _csv(arrays))
        staged.stage_bytes(f"{model.name}.npz", _npz(arrays))
        from crosscheck.runtime import jsonio

        staged.stage(f"{model.name}.json", jsonio.dumps(info))
        paths = staged.commit()
    print(
        f"crosscheck simulate: {model.name} over [{times[0]:g}, {times[-1]:g}] s, "
        f"{len(times)} outputs, {args.method}/{args.integrator} at rtol {rtol:g}; "
        f"error estimate {estimate:.2e} (against rtol {tight_rtol:g}) -> "
        + ", ".join(str(p) for p in paths.values())
    )
    return 0


def _refuse_singular_crossing(tr) -> None:
    """A run that stepped across a pose where the constraint rows lose rank (the rank
    monitor saw a row direction reverse) has no unique motion past it: refused, not written."""
    crossed = tr.stats.get("rank_crossings_t") or []
    if crossed:
        raise ModelInputError(
            f"the run crosses a singular pose in its step ending at t = {min(crossed):.6g} s "
            "(the constraint rows lose rank there and the motion past it is not unique); give "
            "an end time before it"
        )


def _times(args):
    """The output times: --times as given (increasing, from --t on), else --points evenly
    spaced over [--t, --t + --t-end]."""
    import numpy as np

    if args.times is not None:
        times = float_list(args.times, "--times") or []
        bad = [x for x in times if not math.isfinite(x)]
        if not times or bad:
            raise ModelInputError("--times: give finite output times, comma-separated")
        if times[0] < args.t or any(b <= a for a, b in itertools.pairwise(times)):
            raise ModelInputError(
                f"--times must increase strictly and start at or after --t ({args.t:g})"
            )
        if len(times) > MAX_POINTS:
            raise ModelInputError(f"--times: at most {MAX_POINTS} output times")
        return np.array(times, float)
    if args.points > MAX_POINTS:
        raise ModelInputError(f"--points {args.points}: at most {MAX_POINTS}")
    return np.linspace(args.t, args.t + args.t_end, args.points)


def _arrays(nm, tr) -> dict:
    """Every output's state, multipliers and residuals, with the columns' names."""
    import numpy as np

    model = nm.model
    lam = np.array([nm.forward(q, u, float(t)).multipliers for t, q, u in _rows(tr)], float)
    pos, vel = tr.residuals()
    rows = model.constraint_names or tuple(f"c{j + 1}" for j in range(model.n_constraints))
    nc = len(model.configuration_constraints)
    return {
        "t": np.asarray(tr.t, float),
        "q": np.asarray(tr.q, float),
        "u": np.asarray(tr.u, float),
        "multipliers": lam.reshape(len(tr.t), -1),
        "position_residuals": pos,
        "velocity_residuals": vel,
        "names": {
            "q": [str(s) for s in model.coordinates],
            "u": [str(s) for s in model.speeds],
            "multipliers": list(rows),
            "position_residuals": [f"position_residual[{r}]" for r in rows[:nc]],
            "velocity_residuals": [f"velocity_residual[{r}]" for r in rows],
        },
    }


def _rows(tr):
    return zip(tr.t, tr.q, tr.u, strict=True)


def _csv(a: dict) -> str:
    keys = ("q", "u", "multipliers", "position_residuals", "velocity_residuals")
    header = ["t", *(n for k in keys for n in a["names"][k])]
    lines = [",".join(header)]
    for i, t in enumerate(a["t"]):
        row = [t, *(x for k in keys for x in a[k][i])]
        lines.append(",".join(repr(float(x)) for x in row))
    return "\n".join(lines) + "\n"


def _npz(a: dict) -> bytes:
    import numpy as np

    buf = io.BytesIO()
    names = {f"{k}_names": np.array(v) for k, v in a["names"].items()}
    np.savez(buf, **{k: v for k, v in a.items() if k != "names"}, **names)
    return buf.getvalue()


def _info(args, nm, tr, rtol, atol, tight_rtol, estimate) -> dict:
    from crosscheck.runtime.provenance import meta

    drift = tr.energy_drift()
    return {
        "meta": meta(sys.argv[1:]),
        "model": nm.model.name,
        "source": nm.model.source,
        "formulation": nm.formulation,
        "parameters": nm.params,
        "method": args.method,
        "integrator": args.integrator,
        "rtol": rtol,
        "atol": atol,
        "t0": float(tr.t[0]),
        "t_end": float(tr.t[-1]),
        "outputs": len(tr.t),
        "error_estimate": estimate,
        "error_estimate_method": (
            f"max |x - x_tight| / max(max |x_tight|, 1) over the outputs, x = (q, u), x_tight "
            f"from the same run at rtol {tight_rtol:g}, atol {atol / TIGHTER:g}"
        ),
        "energy_drift": drift,
        "energy_drift_method": (
            "max |E - E(0) - W| / max(|E|, 1), W the work of loads and moving constraints"
            if drift is not None
            else "not available: the model does not conserve energy and its work was not kept"
        ),
        "nsteps": tr.nsteps,
        "nfev": tr.nfev,
        "wall_s": tr.wall_s,
    }


def register(sub) -> None:
    s = sub.add_parser(
        "simulate",
        help="write a model's reference trajectory (CSV, NPZ, JSON) with an error estimate",
        description="Integrate a model with the reference and write DIR/NAME.csv, .npz and "
        ".json: t, q, u, multipliers and residuals at the output times, the method, the "
        "tolerances and an error estimate against a run at a hundredth of them.",
    )
    s.add_argument("name", help="model name (see `crosscheck models`)")
    s.add_argument("--formulation", default=None, help="lagrange | dalembert | kane")
    s.add_argument(
        "--set", action="append", default=[], metavar="NAME=VALUE", help="override a parameter"
    )
    add_state(s, "to start from")
    s.add_argument(
        "--t-end", type=horizon, default=5.0, help="length of the run in seconds (default 5)"
    )
    s.add_argument(
        "--points", type=positive_int, default=101, help="evenly spaced outputs (default 101)"
    )
    s.add_argument(
        "--times", default=None, help="output times, comma-separated (instead of --points)"
    )
    s.add_argument(
        "--method", choices=sorted(METHODS), default="projection", help="constraint treatment"
    )
    s.add_argument("--integrator", default="DOP853", help="scipy integrator (default DOP853)")
    s.add_argument("--rtol", type=_tolerance, default=1e-10, help="relative tolerance")
    s.add_argument("--atol", type=_tolerance, default=None, help="absolute (default rtol/100)")
    s.add_argument("--out", default="out/simulate", help="directory for the three files")
    add_model_files(s, project=False)
    s.set_defaults(func=cmd_simulate)


def _tolerance(text: str) -> float:
    import argparse

    value = finite_float(text)
    if not 1e-15 <= value < 1:
        raise argparse.ArgumentTypeError(f"{value:g}: give a tolerance in [1e-15, 1)")
    return value
