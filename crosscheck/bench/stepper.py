"""The compiled stepper against the Python stepper, timed in one process (bench.json
"stepper"; benchmarks/reference_speed.md "The compiled stepper").

One record per model x method x outputs: simulate() over the model's work-precision horizon at
rtol = atol RTOL, on the Python stepper and on the C one (reference.integrate.compiled), in
interleaved rounds (the minimum of each). "steps": every accepted step recorded, the motion only
(the work-precision runs); "grid": GRID_POINTS output times with the work integral where the
model carries it (the trajectory checks' reference runs). Fields: model, method, outputs, rtol,
python_wall_s, c_wall_s, speedup (python / c), nfev_python, nfev_c, max_difference (max
|y_python - y_c| over the outputs at the same times, or at t_end for "steps", whose step times
differ by round-off), state_scale (1 + the largest |q|, |u| of the Python run: max_difference /
(rtol state_scale) is the difference in units of the tolerance), stepper (what the C run
actually ran: "c", or "python" with the reason where the run does not qualify, e.g. a model on
another backend).
"""

from __future__ import annotations

import numpy as np

from crosscheck.bench.workprecision import QUICK_MODELS, horizon
from reference import NumericModel, models
from reference.integrate.driver import simulate

RTOL = 1e-10
METHODS = ("index1", "projection", "baumgarte")
GRID_POINTS = 201
ROUNDS = {True: 3, False: 7}


def _difference(label: str, py, c) -> float:
    if label == "steps":
        return float(np.max(np.abs(py.final_state - c.final_state)))
    return float(max(np.max(np.abs(py.q - c.q)), np.max(np.abs(py.u - c.u))))


def stepper_record(nm: NumericModel, method: str, label: str, rounds: int) -> dict:
    """One model, method and output kind: both steppers timed in `rounds` interleaved rounds."""
    name, start = nm.model.name, (nm.model.initial_q, nm.model.initial_u)
    T = horizon(name)
    kw = {"energy": "none"} if label == "steps" else {"t_eval": np.linspace(0.0, T, GRID_POINTS)}
    rec: dict = {"model": name, "method": method, "outputs": label, "rtol": RTOL}
    walls: dict = {"python": [], "auto": []}
    runs = {}
    try:
        for _ in range(rounds):
            for stepper in walls:
                tr = simulate(nm, *start, T, method, rtol=RTOL, atol=RTOL, stepper=stepper, **kw)
                walls[stepper].append(tr.wall_s)
                runs[stepper] = tr
    except Exception as exc:  # recorded, never hidden
        rec["failed"] = f"{type(exc).__name__}: {exc}"
        return rec
    py, c = runs["python"], runs["auto"]
    rec.update(
        python_wall_s=min(walls["python"]),
        c_wall_s=min(walls["auto"]),
        speedup=min(walls["python"]) / min(walls["auto"]),
        nfev_python=py.nfev,
        nfev_c=c.nfev,
        max_difference=_difference(label, py, c),
        state_scale=1.0 + float(max(np.max(np.abs(py.q)), np.max(np.abs(py.u)))),
        stepper=c.stats.get("stepper"),
    )
    return rec


def stepper_records(names, quick: bool) -> list[dict]:
    """stepper_record for every model (quick: QUICK_MODELS among them), method and output kind."""
    out = []
    for name in names:
        if quick and name not in QUICK_MODELS:
            continue
        nm = NumericModel(models.get(name))
        for method in METHODS:
            for label in ("steps", "grid"):
                out.append(stepper_record(nm, method, label, ROUNDS[quick]))
    return out
