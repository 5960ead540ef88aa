"""Where the reference stops at a singular pose: the horizon the trajectories are compared on.

At a pose where the constraint rows lose rank (the IFToMM A02 four-bars lying flat, a linkage at
its dead centre) the motion through it is not unique: the degrees of freedom jump, and which
branch the mechanism takes is not given by the equations. The reference refuses such a state
(SingularSystemError, with the time it reached it) rather than pick a branch. The trajectories
are then compared on the part of the run the reference vouches for, up to just before that
time, and a skipped record says how much of the requested horizon was left out and why.
"""

from __future__ import annotations

import math

from reference.errors import SingularSystemError

# Stop 1 % of the way short of the singular time: the reference refuses a state within about
# 1e-6 (relative) of the pose (redundant.RANK_RTOL, the KKT pivot ratio 1e-12 = (1e-6)^2), so
# at the speeds of a run that is microseconds before it; 1 % keeps every run, at every rtol,
# and every stage of its last step well clear of the pose.
HORIZON_MARGIN = 0.01
# Horizons are whole milliseconds: the engines' fixed-step ladder (1 ms and 0.5 ms) then ends
# exactly on them (crosscheck.checks.trajectory.check.step_ladder).
HORIZON_QUANTUM = 1e-3


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
