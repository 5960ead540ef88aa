"""How the reference and the engines scale on the IFToMM A02 N-four-bar (issue 11 item 9).

For each N: the generated MJCF (examples/a02/nfourbar.py) is imported, the reference derives
it cold (a fresh derivation cache) and warm (read back from that cache), and then, at the
release state and at seeded random states of the parallelogram motion (a state the
reference refuses as singular would be listed and skipped), every
engine that loads the file gives u': the reference (Kane; the unrolled or the numeric KKT
solve, codegen.UNROLL_KKT_MAX), Pinocchio (a model built from MuJoCo's compiled one, the
suite's user-file adapter), MuJoCo's rigid answer (crosscheck.engines.mujoco.mjcf_rigid) and
its soft answer.
Per engine: the time of one forward call and the largest |u' - u'_ref| / max(1, |u'_ref|).
Then 10 s from the release state:
MuJoCo's own simulation (its default semi-implicit Euler, 1 ms) and the reference's DOP853 with
projection (within a wall budget; it stops at a singular position when the rank test refuses
one), each with its mechanical-energy drift and its largest loop-closure residual, measured
with the reference's own energy and residual functions, and its largest error in B0's x
against the exact parallelogram motion (a one-dof equation, exact_b0_x). And Pinocchio's 10 s
as the suite runs its trajectories (DOP853 on its forward dynamics, no stabilization, the
reference's rtol; within its own wall budget, or how it stopped), with the same figures.
Rows of other N already in --out are kept.

    PYTHONPATH=$PWD python examples/a02/scaling.py                 # N = 1 2 5 10 20 40
    PYTHONPATH=$PWD python examples/a02/scaling.py --n 1,2 --out /tmp/s.json

Figures: benchmarks/scaling.md. A state's accelerations all vanish at the release pose (the cranks
upright), so the per-state errors are taken at random states as well.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

# One BLAS thread: the matrices here are at most 201 rows, and with two threads on the shared
# 2-core machine under load one SVD of A (120 x 81) took 308 ms against 8 ms with one
# (numpy's scipy-openblas; measured with np.linalg.svd on random matrices). Set before numpy.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))  # nfourbar beside this file
sys.path.insert(0, str(HERE.parent.parent))  # the checkout, for reference and crosscheck

STATES = 3  # random states beside the release state (parallelogram_states)
TIMING_S = 0.3  # wall time over which one forward call is averaged, per engine
T_END = 10.0  # the benchmark's horizon
REFERENCE_RTOL = 1e-8  # DOP853 + projection; the suite's trajectory default
EXACT_RTOL = 1e-12  # the one-dof parallelogram equation (exact_b0_x): 1e4 below the above
# B0's x error above which a 10 s run is counted as off the parallelogram motion
# (branch_figures): 80x the reference's worst (1.2e-5 m, N = 1, rtol 1e-8, scaling.json) and
# 1/2000 of the 2 m a run off the branch or far behind reaches
BRANCH_ERROR_M = 1e-3
# Pinocchio's 10 s run (pinocchio_run): the reference's rtol, so the two integrations differ
# in the constraint handling (projection or none), not in the error control
PINOCCHIO_RTOL = REFERENCE_RTOL


def per_call(fn, budget: float = TIMING_S) -> float:
    """Mean seconds of fn() over about `budget` seconds (at least 3 calls)."""
    fn()
    k, t0 = 0, time.perf_counter()
    while k < 3 or time.perf_counter() - t0 < budget:
        fn()
        k += 1
    return (time.perf_counter() - t0) / k


def build(n: int, work: Path) -> dict:
    """Write and import the file, derive cold then warm; the import and the reference model."""
    from nfourbar import mjcf

    from crosscheck.engines.pinocchio.user_file import UserFilePinModel
    from crosscheck.user_models import load_model_file, register_all
    from reference.numeric.model import NumericModel

    path = work / f"a02_nfourbar_{n}.xml"
    path.write_text(mjcf(n))
    os.environ["CROSSCHECK_CACHE_DIR"] = str(work / f"cache_{n}")  # cold: nothing cached
    t0 = time.perf_counter()
    um = load_model_file(path)[0]
    register_all([um])
    t1 = time.perf_counter()
    nm = NumericModel(um.model, "kane")
    t2 = time.perf_counter()
    NumericModel(um.model, "kane")  # warm: the generated code read back from the cache
    t3 = time.perf_counter()
    return {
        "path": path,
        "um": um,
        "nm": nm,
        "pin": UserFilePinModel(um.name),  # the suite's user-file adapter
        "row": {
            "N": n,
            "links": 2 * n + 1,
            "n": nm.n,
            "m": nm.m,
            "rank": nm.rank,
            "kkt_rows": nm.n + nm.m,
            "kkt_solve": "numeric" if nm.numeric_kkt else "unrolled",
            "backend": nm.backend,
            "import_s": t1 - t0,
            "derive_cold_s": t2 - t1,
            "derive_warm_s": t3 - t2,
        },
    }


def timings(nm, pin, m, qpos, qvel, u) -> dict:
    """Seconds per forward call of each engine at one state."""
    import mujoco

    from crosscheck.engines.mujoco.mjcf_rigid import rigid_forward

    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = qpos, qvel
    return {
        "reference": per_call(lambda: nm.forward(qpos, u)),
        "pinocchio": per_call(lambda: pin.forward(qpos, u)),
        "mujoco_rigid": per_call(lambda: rigid_forward(m, qpos, qvel)),
        "mujoco_soft": per_call(lambda: mujoco.mj_forward(m, d)),
    }


def parallelogram_states(n: int, count: int, seed: int = 7):
    """The release state, then `count` seeded random states of the parallelogram motion
    (every crank at theta, every coupler at -theta relative to it, rates theta' and
    -theta'), theta ~ U(-pi, pi) kept 0.2 rad away from the horizontal poses +-pi/2, where
    the rows lose rank. Random joint angles projected onto the loops instead (mjcf_rigid
    .sample_states) mostly land near a flat cell for N >= 10 (every one for N = 20)."""
    rng = np.random.default_rng(seed)
    yield np.zeros(2 * n + 1), np.array([-1.0, 1.0] * n + [-1.0])
    k = 0
    while k < count:
        th, w = rng.uniform(-np.pi, np.pi), rng.standard_normal()
        if abs(abs(th) - np.pi / 2) < 0.2:
            continue
        k += 1
        yield np.array([th, -th] * n + [th]), np.array([w, -w] * n + [w])


def engines_at_states(b: dict) -> dict:
    """Per engine: seconds per forward call and worst relative u' error against the reference."""
    from crosscheck.engines.mujoco.mjcf_rigid import rigid_forward
    from reference.errors import SingularSystemError
    from reference.mjcf.loader import rates_from_qvel

    imp, nm, pin = b["um"].mjcf, b["nm"], b["pin"]
    m = imp.mj
    err = {"pinocchio": 0.0, "mujoco_rigid": 0.0, "mujoco_soft": 0.0}
    cost: dict = {}
    refused = []
    for k, (qpos, qvel) in enumerate(parallelogram_states(b["row"]["N"], STATES)):
        u = rates_from_qvel(imp.joints, qpos, qvel)  # hinges: the identity
        try:
            ref = nm.forward(qpos, u).accelerations
        except SingularSystemError as exc:  # a random state projected near a flat cell
            refused.append(str(exc).split(";")[0])
            continue
        scale = max(1.0, float(np.max(np.abs(ref))))
        rigid = rigid_forward(m, qpos, qvel)
        got = {
            "pinocchio": pin.forward(qpos, u).accelerations,
            "mujoco_rigid": rigid.qacc,
            "mujoco_soft": rigid.qacc_soft,
        }
        for key, acc in got.items():
            err[key] = max(err[key], float(np.max(np.abs(acc - ref))) / scale)
        if k == 0:  # timings at the release state
            cost = timings(nm, pin, m, qpos, qvel, u)
    return {
        "forward_s": cost,
        "max_rel_error_vs_reference": err,
        "states_compared": STATES + 1 - len(refused),
        "states_refused": refused,
    }


def exact_b0_x(n: int, times) -> np.ndarray:
    """B0's x on the parallelogram motion, from its one-dof equation: every crank at theta,
    every coupler translating, so K = I theta'^2 / 2 with I = (N + 1) / 3 + N (cranks about
    their pivots, couplers as point masses at speed theta') and V = g ((N + 1) / 2 + N)
    cos(theta); theta'' = g ((N + 1) / 2 + N) sin(theta) / I (Lagrange), theta(0) = 0,
    theta'(0) = -1. Integrated with DOP853 at rtol EXACT_RTOL: the benchmark's reference
    solution for any N, independent of the constraint handling being tested."""
    from scipy.integrate import solve_ivp

    inertia, torque = (n + 1) / 3.0 + n, 9.81 * ((n + 1) / 2.0 + n)
    sol = solve_ivp(
        lambda t, y: [y[1], torque * np.sin(y[0]) / inertia],
        (0.0, T_END),
        [0.0, -1.0],
        method="DOP853",
        rtol=EXACT_RTOL,
        atol=EXACT_RTOL,
        t_eval=times,
    )
    return -np.sin(sol.y[0])


def b0_errors(n: int, times, Q) -> np.ndarray:
    """|B0_x - exact| at the output times (B0_x = -sin of crank 0's angle)."""
    return np.abs(-np.sin(np.asarray(Q)[:, 0]) - exact_b0_x(n, times))


def branch_figures(times, Q, err) -> dict:
    """Whether a run left the parallelogram motion or only lags it: its largest B0 error
    `err`, the first output time at which that is over BRANCH_ERROR_M, and the largest spread
    of the cranks' angles (all equal on the parallelogram motion, however late; wrapped to
    (-pi, pi])."""
    over = np.flatnonzero(err > BRANCH_ERROR_M)
    cranks = np.asarray(Q)[:, 0::2]
    spread = np.angle(np.exp(1j * (cranks - cranks[:, :1])))
    return {
        "B0_x_max_error_m": float(np.max(err)),
        "B0_x_error_over_1mm_from_s": float(np.asarray(times)[over[0]]) if len(over) else None,
        "max_crank_spread_rad": float(np.max(np.abs(spread))),
    }


def drift(nm, Q, U) -> dict:
    """Mechanical-energy drift and loop-closure residual along states (reference functions)."""
    E = np.array([sum(nm.energy(q, u)) for q, u in zip(Q, U, strict=True)])
    res = max(
        float(np.max(np.abs(nm.residuals(q, u)[0]), initial=0.0)) for q, u in zip(Q, U, strict=True)
    )
    return {"energy_drift_J": float(np.max(np.abs(E - E[0]))), "max_loop_residual_m": res}


def run_figures(nm, times, Q, U, t_reached: float) -> dict:
    """The figures of a 10 s run from its output states (reference coordinates: qpos, rates):
    where it got to, B0's x there and its largest error, energy drift, loop residual."""
    return {
        "t_reached": t_reached,
        "B0_x_end": float(-np.sin(np.asarray(Q)[-1][0])),
        **branch_figures(times, Q, b0_errors(nm.n // 2, times, Q)),
        **drift(nm, Q, U),
    }


def mujoco_run(b: dict) -> dict:
    """MuJoCo's own 10 s from the keyframe (its integrator and step as in the file)."""
    import mujoco

    imp, nm = b["um"].mjcf, b["nm"]
    m = imp.mj
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    steps = round(T_END / m.opt.timestep)
    every = max(1, steps // 400)  # 400 output points, the benchmark's own sampling
    Q, U = [d.qpos.copy()], [d.qvel.copy()]
    t0 = time.perf_counter()
    for k in range(steps):
        mujoco.mj_step(m, d)
        if (k + 1) % every == 0:
            Q.append(d.qpos.copy())
            U.append(d.qvel.copy())
    wall = time.perf_counter() - t0
    times = np.arange(len(Q)) * every * m.opt.timestep
    return {"wall_s": wall, **run_figures(nm, times, Q, U, float(d.time))}


def reference_run(b: dict, wall: float) -> dict:
    """The reference's DOP853 + projection for 10 s within `wall` seconds, or how it stopped."""
    from reference.integrate.driver import simulate

    nm = b["nm"]
    q0, u0 = nm.model.initial_q, nm.model.initial_u
    t0 = time.perf_counter()
    try:
        tr = simulate(
            nm,
            q0,
            u0,
            T_END,
            "projection",
            rtol=REFERENCE_RTOL,
            atol=REFERENCE_RTOL * 1e-2,
            t_eval=np.linspace(0, T_END, 401),
            max_wall_s=wall,
        )
    except Exception as exc:  # a singular position or the wall budget: reported, not raised
        return {
            "wall_s": time.perf_counter() - t0,
            "stopped": f"{type(exc).__name__}: {(str(exc).splitlines() or [''])[0][:300]}",
        }
    return {
        "wall_s": time.perf_counter() - t0,
        "nfev": int(tr.nfev),
        **run_figures(nm, tr.t, tr.q, tr.u, float(tr.t[-1])),
    }


class WallBudget:
    """`fn` that raises TimeoutError once `wall` seconds have passed since the first call:
    solve_ivp has no wall bound, and a run that stalls at a singular pose must not hang."""

    def __init__(self, fn, wall: float):
        self.fn, self.wall, self.calls, self.t0 = fn, wall, 0, None

    def __call__(self, *args, **kwargs):
        self.t0 = self.t0 or time.perf_counter()
        if time.perf_counter() - self.t0 > self.wall:
            raise TimeoutError(f"wall budget of {self.wall} s spent after {self.calls} calls")
        self.calls += 1
        return self.fn(*args, **kwargs)


def pinocchio_run(b: dict, pin, wall: float) -> dict:
    """Pinocchio's 10 s as the suite runs its trajectories (UserFilePinModel.simulate: DOP853
    on its forward dynamics, index 1, no stabilization) within `wall` seconds, or how it
    stopped: a failed step (an underflow at a singular pose) is a finding, reported with the
    last output time reached."""
    nm = b["nm"]
    setting = {
        "integrator": "DOP853 (scipy solve_ivp), index 1, no constraint stabilization",
        "rtol": PINOCCHIO_RTOL,
        "atol": PINOCCHIO_RTOL,
    }
    pin.forward = guard = WallBudget(pin.forward, wall)  # simulate's rhs calls self.forward
    t0 = time.perf_counter()
    try:
        tr = pin.simulate(
            nm.model.initial_q,
            nm.model.initial_u,
            np.linspace(0, T_END, 401),
            integrator="DOP853",
            rtol=PINOCCHIO_RTOL,
        )
    except Exception as exc:  # the wall budget or an engine error: reported, not raised
        return {
            **setting,
            "wall_s": time.perf_counter() - t0,
            "nfev": guard.calls,
            "t_reached": None,  # raised inside solve_ivp's rhs, which is not told t
            "stopped": f"{type(exc).__name__}: {(str(exc).splitlines() or [''])[0][:300]}",
        }
    finally:
        del pin.forward  # the class's method again
    row = {**setting, "wall_s": tr.wall_s, "nfev": int(tr.steps)}
    if tr.failure:  # solve_ivp stopped early: the figures cover the output times it reached
        row["stopped"] = tr.failure
    return {**row, **run_figures(nm, tr.t, tr.q, tr.u, float(tr.t[-1]))}


def write_rows(path: Path, head: dict, rows: list[dict]) -> None:
    """Write `rows` into the JSON at `path`, keeping its rows of other N (a run of some N
    must not lose the others' figures, N = 40 alone costs 7 min); rows sorted by N. A kept
    file keeps its header (its command measured the rows without their own "command")."""
    old = json.loads(path.read_text()) if path.exists() else {**head, "rows": []}
    fresh = {r["N"] for r in rows}
    kept = [r for r in old["rows"] if r["N"] not in fresh]
    out = {**old, "rows": sorted(kept + rows, key=lambda r: r["N"])}
    path.write_text(json.dumps(out, indent=1) + "\n")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", default="1,2,5,10,20,40", help="cell counts, comma-separated")
    ap.add_argument("--out", default=str(HERE / "scaling.json"))
    ap.add_argument(
        "--wall",
        type=float,
        default=60.0,
        help="wall seconds for each reference 10 s run (default 60)",
    )
    ap.add_argument(
        "--pin-wall",
        type=float,
        default=300.0,
        help="wall seconds for each Pinocchio 10 s run (default 300)",
    )
    args = ap.parse_args(argv)
    from reference.backends import codegen

    command = "PYTHONPATH=$PWD python examples/a02/scaling.py " + " ".join(
        argv if argv is not None else sys.argv[1:]
    )
    head = {
        "benchmark": "IFToMM A02 N-four-bar, 10 s",
        "command": command,
        "unroll_kkt_max": codegen.UNROLL_KKT_MAX,
    }
    rows: list[dict] = []
    with tempfile.TemporaryDirectory(prefix="a02_") as tmp:
        for n in (int(x) for x in args.n.split(",")):
            b = build(n, Path(tmp))
            row = {
                **b["row"],
                "command": command,
                **engines_at_states(b),
                "mujoco_10s": mujoco_run(b),
                "reference_10s": reference_run(b, args.wall),
                "pinocchio_10s": pinocchio_run(b, b["pin"], args.pin_wall),
            }
            rows.append(row)
            print(json.dumps(row), flush=True)
            # written after every N: the large ones take minutes, the small ones are kept
            write_rows(Path(args.out), head, rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
