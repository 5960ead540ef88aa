"""A whole integration in compiled code: the DOP853 stepper of ckernel_stepper.h.

Where a run qualifies (why_not), `simulate` hands the solver loop to the model's C module: the
same scipy DOP853 step (LeanDOP853's formulas, scipy's tableau read from the solver, the start
and first step size computed by scipy in Python), the right side straight from the forward
kernel (for `baumgarte` with its offset of the rows' right side, with the work integral W where
the run carries it), and for `projection` the Gauss-Newton and velocity projection of
integrate_projection after every accepted step. It returns what the Python loop records: every
accepted step, or the states at t_eval from scipy's dense output (projected in projection
mode), nfev, nsteps, the smallest pivot ratio, the projection counts; the rank-loss monitor of
integrate._Run runs afterwards on the accepted states (one batched Jacobian call).

Errors keep the Python stepping's words: where the C loop meets a state it does not take (a
singular or undefined forward, a projection that fails) it stops, and the run is made again
on the Python stepper, which raises what it always raised. The step-size underflow and the
max_steps / max_wall_s bounds are raised here with the Python loop's messages.

The two steppers agree within the run's tolerance, not to the bit: numpy sums the stages, the
error estimate and the normal equations in another order than the C loops, and the error
estimate carries that round-off into the step sizes (measured: tests/test_integrate_compiled.py,
benchmarks/reference_speed.md "The compiled stepper").
"""

from __future__ import annotations

import math
import os
import time
from functools import cache

import numpy as np
import scipy.integrate as si

from reference.errors import ModelInputError
from reference.integrate.common import (
    PROJECTION_FAIL,
    PROJECTION_MAX_ITER,
    PROJECTION_TOL,
    direction_reversed,
)

# the simulate(stepper=...) values; CROSSCHECK_STEPPER sets the default
STEPPERS = ("auto", "c", "python")
# ckernel_stepper.h's statuses
DONE, TOO_SMALL, MAX_STEPS, DEADLINE, DECLINED = range(5)
COMPILED_METHODS = {"index1": 0, "projection": 1, "baumgarte": 3}


def setting(stepper: str | None) -> str:
    """The stepper asked for: the argument, else CROSSCHECK_STEPPER, else 'auto'."""
    want = stepper or os.environ.get("CROSSCHECK_STEPPER", "").strip().lower() or "auto"
    if want not in STEPPERS:
        raise ModelInputError(f"stepper {want!r}: valid values are {', '.join(STEPPERS)}")
    return want


def why_not(run, integrator: str, method: str) -> str | None:
    """Why this run cannot take the compiled stepper, or None when it can."""
    nm = run.nm
    if nm.kernels.stepper is None:
        return f"the model runs on the {nm.backend} backend (the stepper is in the C module)"
    if not nm.kernels.has("forward"):
        return "the model's KKT solve is numeric (the stepper runs the unrolled forward kernel)"
    if integrator != "DOP853":
        return f"integrator {integrator} (the compiled stepper is DOP853's)"
    if method not in COMPILED_METHODS:
        return f"method {method} (compiled: {', '.join(COMPILED_METHODS)})"
    if _tableau() is None:
        import scipy

        return f"scipy {scipy.__version__}: DOP853's tableau is not where the stepper reads it"
    return None


def run_compiled(run, y, t0: float, t_end: float, stepper: str) -> bool:
    """Integrate `run` (an integrate._Run) from (t0, y) to t_end on the C stepper: True when it
    did, False when the Python loop must (not eligible, or the C loop stopped at a state it
    does not take; prob.stats["stepper"] says which and why)."""
    prob = run.prob
    reason = why_not(run, run.integrator, run.method)
    if reason is not None:
        if stepper == "c":
            raise ModelInputError(f"{run.nm.model.name}: stepper='c' cannot run: {reason}")
        prob.stats["stepper"] = f"python ({reason})"
        return False
    nm, k = run.nm, run.nm.kernels
    step = k.stepper
    assert step is not None  # why_not said so
    run._tolerances(len(y))  # W's tolerances, where it is carried (as the Python loop's)
    # scipy's start (f0, the first step size) from scipy's own DOP853: LeanDOP853's extra set-up
    # is for its Python stages, which do not run here
    solver = si.DOP853(prob.fun, t0, y, t_end, **run.opts)
    deadline = math.inf
    if run.max_wall_s is not None:
        deadline = run.max_wall_s - (time.perf_counter() - run.t_start)
    mode = COMPILED_METHODS[run.method]
    if mode == 1 and not prob.refresh:
        mode = 2
    baumgarte = (prob.alpha, prob.beta) if mode == 3 else (0.0, 0.0)
    a_offset = -1 if prob.mc == prob.m and prob.rates else k.offsets["matrices"][2][0]
    tableau = _tableau()
    te = None if run.te is None else np.ascontiguousarray(run.te[run.k_eval :], float)
    ny = len(solver.y)
    options = (
        mode,
        -1 if run.max_steps is None else int(run.max_steps),
        a_offset,
        PROJECTION_MAX_ITER,
        int(run.bookkeeping),
        int(prob.rheonomic),
        k.offsets["energy"][0][0] + 2,  # the power of the loads (Problem.power)
        int(prob.rates),
    )
    status, T, Y, TE, YE, nfev, nsteps, pmin, nproj, niter, t_stop, _y = step(
        np.ascontiguousarray(solver.y, float),
        np.ascontiguousarray(solver.f, float),
        (
            float(t0),
            float(t_end),
            float(solver.h_abs),
            float(solver.max_step),
            float(solver.error_exponent),
            deadline,
        ),
        tuple(
            np.ascontiguousarray(np.broadcast_to(v, ny), float) for v in (solver.rtol, solver.atol)
        ),
        tableau,
        te,
        nm.kernel_parameters,
        k.zero_db,
        options,
        (PROJECTION_TOL, PROJECTION_FAIL, *baumgarte),
    )
    if status == DECLINED:  # the Python loop redoes the run and words the error
        prob.stats["stepper"] = f"python (the C stepper stopped at t = {t_stop:.6g})"
        return False
    prob.stats["stepper"] = "c"
    _record(run, (T, Y) if te is None else (TE, YE), solver.nfev + nfev, nsteps, pmin)
    prob.stats["projections"] += nproj
    prob.stats["projection_iterations"] += niter
    _monitor(run, T, Y[:, : prob.nq])
    _raise_bounds(run, status, t_stop, t_end, solver.TOO_SMALL_STEP)
    return True


@cache
def _tableau() -> tuple | None:
    """scipy's DOP853 coefficients as the stepper reads them (flat float64, made once), or
    None where this scipy does not hold them in the shapes the stepper was written for (the
    class attributes of scipy 1.11-1.17): the run then takes the Python stepper."""
    try:
        A, B, C, E3, E5, AX, CX, D = (
            np.asarray(getattr(si.DOP853, a), float)
            for a in ("A", "B", "C", "E3", "E5", "A_EXTRA", "C_EXTRA", "D")
        )
    except (AttributeError, TypeError, ValueError):
        return None
    s, x = len(B), len(CX)
    shapes = [(s, s), (s,), (s,), (s + 1,), (s + 1,), (x, s + 1 + x), (x,), (len(D), s + 1 + x)]
    if [a.shape for a in (A, B, C, E3, E5, AX, CX, D)] != shapes:
        return None
    return tuple(np.ascontiguousarray(a).ravel() for a in (A, B, C, E3, E5, AX, CX, D))


def _record(run, outputs, nfev, nsteps, pmin) -> None:
    """The outputs (every accepted step, or the states at t_eval) as _Run.record keeps them."""
    prob, nq = run.prob, run.prob.nq
    T, Y = outputs
    run.nfev += nfev
    run.nsteps += nsteps
    run.k_eval += len(T) if run.te is not None else 0
    prob.pmin[0] = min(prob.pmin[0], pmin)
    run.T.extend(T.tolist())
    run.Q.extend(Y[:, :nq].tolist())
    run.U.extend(Y[:, nq : nq + prob.n].tolist())
    run.W.extend(Y[:, -1].tolist() if run.bookkeeping else [None] * len(T))


def _monitor(run, T, Q) -> None:
    """integrate._Run._orientation over the recorded states: a row direction of A reversed
    between two accepted steps (common.direction_reversed), with every A from one batched call
    of the position Jacobian."""
    prob, nm = run.prob, run.nm
    mc, nq, N = prob.mc, prob.nq, len(T)
    if not mc or not N:
        return
    k = nm.kernels
    out = np.empty((N, k.total["position_jacobian"]))
    st = np.empty(N, np.int64)
    k.batch("position_jacobian")(
        np.ascontiguousarray(Q),
        np.zeros((N, nm.n)),
        T,
        nm.kernel_parameters[None],
        k.zero_db[None],
        out,
        st,
    )
    A = out[:, : mc * nq].reshape(N, mc, nq)
    prev = np.asarray(run.A_last, float).reshape(1, mc, nq)
    both = np.concatenate([prev, A])
    C = np.einsum("kij,klj->kil", both[1:], both[:-1])
    if (st != 0).any() or not np.isfinite(C).all():  # not finite: the state-by-state monitor
        for t, q in zip(T, Q, strict=True):
            run._orientation(float(t), np.concatenate([q, np.zeros(nm.n)]))
        return
    run.rank_crossings.extend(float(t) for t in T[direction_reversed(C)])
    run.A_last = A[-1].ravel()


def _raise_bounds(run, status, t_stop, t_end, too_small_msg) -> None:
    """The Python loop's errors for a run the C loop stopped early (integrate._Run words them)."""
    if status == TOO_SMALL:
        raise run.failed(t_stop, too_small_msg)
    if status == MAX_STEPS:
        raise run.out_of_steps(t_stop, t_end)
    if status == DEADLINE:
        raise run.out_of_time(t_stop, t_end)
