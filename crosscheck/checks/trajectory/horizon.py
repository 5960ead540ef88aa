"""Where the reference stops at a singular pose, or where a contact or limit starts to act: the
horizon the trajectories are compared on.

At a pose where the constraint rows lose rank (the IFToMM A02 four-bars lying flat, a linkage at
its dead centre) the motion through it is not unique: the degrees of freedom jump, and which
branch the mechanism takes is not given by the equations. The reference refuses such a state
(SingularSystemError, with the time it reached it) rather than pick a branch. The trajectories
are then compared on the part of the run the reference vouches for, up to just before that
time, and a skipped record says how much of the requested horizon was left out and why.

A user's MJCF file may hold contacts, joint and tendon limits and actuator force clamps, which
the reference does not model and which act only at some states (reference.mjcf.unilateral).
The trajectories start where none acts, and they are compared up to just before the first one
does: the reference's motion is checked every millisecond (first_activation), and the horizon
ends as before a singular pose, with the record naming the contact pair or joint and the time.
"""

from __future__ import annotations

import math

import numpy as np

from crosscheck.checks.records import Record, record
from reference.errors import SingularSystemError

# Stop 1 % of the way short of the singular time: the reference refuses a state within about
# 1e-6 (relative) of the pose (redundant.RANK_RTOL, the KKT pivot ratio 1e-12 = (1e-6)^2), so
# at the speeds of a run that is microseconds before it; 1 % keeps every run, at every rtol,
# and every stage of its last step well clear of the pose.
HORIZON_MARGIN = 0.01
# Horizons are whole milliseconds: the engines' fixed-step ladder (1 ms and 0.5 ms) then ends
# exactly on them (crosscheck.checks.trajectory.check.step_ladder).
HORIZON_QUANTUM = 1e-3
# the first window, in quanta, of the run that looks for contacts and limits (first_activation)
FIRST_WINDOW = 16


def singular_time(exc: BaseException) -> float | None:
    """The time at which a run reached a singular pose, if that is why it failed."""
    t = getattr(exc, "t_singular", None)
    return float(t) if isinstance(exc, SingularSystemError) and t is not None else None


def crossed(run) -> None:
    """Raise SingularSystemError at the first singular pose a reference run stepped across
    without evaluating near it (the rank monitor, Trajectory.stats['rank_crossings_t']): that
    a step happened to straddle the pose, instead of landing on it, must not decide the
    horizon."""
    times = run.stats.get("rank_crossings_t")
    if times:
        err = SingularSystemError(
            f"the constraint Jacobian lost rank between two accepted steps at t = "
            f"{times[0]:.6g} (the rank monitor): the run crossed a singular pose"
        )
        err.t_singular = float(times[0])
        raise err


def horizon_before(t_singular: float, t_end: float) -> float | None:
    """The horizon to compare on when the reference stops at t_singular: whole milliseconds,
    HORIZON_MARGIN short of it; None when nothing would be left."""
    t_cut = math.floor(min(t_singular * (1.0 - HORIZON_MARGIN), t_end) / HORIZON_QUANTUM)
    return round(t_cut * HORIZON_QUANTUM, 9) if t_cut >= 1 else None  # 0.701, not 0.70100..01


def horizon_reason(t_cut: float, t_end: float, t_singular: float, message: str) -> str:
    """Why the trajectories stop at t_cut, for the skipped record."""
    return (
        f"trajectories compared on [0, {t_cut:g}] s of the requested {t_end:g} s: the "
        f"reference reaches a singular pose at t = {t_singular:.6g} s, where the constraint "
        f"rows lose rank and the motion past it is not unique ({message})"
    )


def first_activation(nm, q0, u0, t_end: float, active, rtol: float):
    """Where the reference's run first reaches a contact, limit or force clamp.

    Parameters
    ----------
    nm : NumericModel
        The model.
    q0, u0 : array_like
        The consistent initial state.
    t_end : float
        The horizon, s.
    active : callable
        (q, u) -> what acts there (reference.mjcf.unilateral.Monitor.active).
    rtol : float
        The run's rtol = atol.

    Returns
    -------
    tuple of (float, str), or None
        The first output time, every HORIZON_QUANTUM, at which something acts, and what; None
        where nothing does before t_end or before the run reaches a singular pose (which
        the horizon's own runs then find).

    Notes
    -----
    The run is the reference's own (DOP853 with projection at ``rtol``) on a millisecond grid:
    the engines' fixed step, at which MuJoCo itself detects contacts, and the quantum the
    horizon is cut in; a contact that begins and ends between two milliseconds goes unseen by
    both. It goes in windows that double from FIRST_WINDOW, each from the last one's end, and
    stops at the first window where something acts: a robot that starts against a limit costs
    milliseconds of integration, not the whole horizon."""
    from reference.integrate.driver import simulate

    n_end = math.floor(t_end / HORIZON_QUANTUM + 1e-9)
    q, u, n0, width = q0, u0, 0, FIRST_WINDOW
    while True:
        n1 = min(n0 + width, n_end)
        t0, t1 = n0 * HORIZON_QUANTUM, (n1 * HORIZON_QUANTUM if n1 < n_end else t_end)
        grid = np.unique(np.append(np.arange(n0, n1 + 1) * HORIZON_QUANTUM, t1))
        grid = grid[(grid >= t0) & (grid <= t1)]
        try:
            run = simulate(nm, q, u, t1, "projection", rtol=rtol, atol=rtol, t_eval=grid, t0=t0)
        except SingularSystemError:
            return None
        for t, qi, ui in zip(run.t, run.q, run.u, strict=True):
            acts = active(qi, ui)
            if acts:
                more = f" and {len(acts) - 3} more" if len(acts) > 3 else ""
                return float(t), "; ".join(map(str, acts[:3])) + more
        if n1 >= n_end:
            return None
        q, u, n0, width = run.q[-1], run.u[-1], n1, 2 * width


def activation_reason(t_cut: float | None, t_end: float, t_act: float, what: str) -> str:
    """Why the trajectories stop at t_cut (None: nothing is left to compare)."""
    where = (
        f"trajectories compared on [0, {t_cut:g}] s of the requested {t_end:g} s"
        if t_cut is not None
        else f"no trajectory compared of the requested {t_end:g} s"
    )
    return (
        f"{where}: at t = {t_act:.6g} s the reference's motion reaches {what}, which the "
        f"reference does not model (its constraints are bilateral; the file's contacts and "
        f"limits act from there on, checked every {HORIZON_QUANTUM * 1e3:g} ms)"
    )


class NoHorizon(Exception):
    """A contact or limit acts within the first millisecond: nothing to compare (the reason)."""


def nothing_to_compare(name, formulation, adapters, t_end, reason) -> list[Record]:
    """The records of a model whose trajectories cannot be compared at all: the reference's
    horizon record with the reason, and every engine's skipped."""
    out = [
        record(
            name,
            formulation,
            "reference",
            "trajectory",
            "horizon",
            None,
            None,
            reason,
            t_requested=t_end,
        )
    ]
    return out + [
        record(
            name,
            formulation,
            a.name,
            "trajectory",
            "state_error",
            None,
            None,
            f"no reference trajectory to compare with ({reason})",
        )
        for a in adapters
    ]


def name_the_horizon(records: list[Record], t_end: float) -> list[Record]:
    """The reference's own records over a run it cannot vouch for (its error against the
    tighter run, its drifts, its energy) name the likely cause: the horizon. A mechanism
    that spins up gains speed, and with it error, until its run outgrows the bounds sized
    for the built-in models' motion; a shorter run is then the way to check it."""
    for r in records:
        if r["passed"] is False:
            r["reason"] += (
                f"; the reference cannot vouch for its own run over t_end = {t_end:g} s, and "
                f"the horizon is the likely cause (a mechanism that gains speed gains error "
                f"with it): rerun with a shorter --t-end"
            )
    return records
