"""Trajectories of an engine model with soft constraint rows: their characterized tolerances
(SOFT_*) and, where the engine has a stiffer version of its model, the runs at its
regularization's time constant tc and tc / 2 extrapolated to the rigid limit and judged against
the reference (``state_error_rigid_limit``), which sizes the soft run's state and energy
tolerances too.
"""

from __future__ import annotations

import numpy as np

from crosscheck.checks import tolerances as C
from crosscheck.checks.trajectory.measures import energy_measure, state_error

SOFT_STATE = C.Tolerance(
    5e-2,
    "characterization, not a physics bound (an engine whose soft model has no stiffer "
    "version, Capabilities.soft_limit): soft equality constraints make the trajectory "
    "follow slightly different dynamics; MuJoCo measured 6e-6 (pendulum) .. 1.1e-2 (top "
    "spinning at 60 rad/s) over 5 s, independent of the step",
)
# The rigid limit: MuJoCo's soft effect on a trajectory shrinks as its solref time constant tc
# shrinks; halving tc divided it by r = 2.7 (pendulum_xy, exercise_6_1) .. 9.8 (the free double
# pendulum) on every built-in model (p = log2 r >= 1.4). The runs at tc and tc/2 are
# extrapolated to tc -> 0 as if p = 2: x_lim = x(tc/2) + (x(tc/2) - x(tc)) / 3. For any r >= 2
# the extrapolation's error is at most 2x its correction |x(tc/2) - x(tc)| / 3 (its ratio to
# the correction is 3 / (r - 1) - 1, in [-1, 2]; measured 0.14..0.75), and the soft effect at
# tc at most 6x (3 r / (r - 1)). A physics error in the engine's model is not removed by the
# extrapolation: a 1 % mass error on the slider-crank leaves 4.1e-4 against a bound of 1.7e-4
# (docs/engines/mujoco.md has the table and the command).
SOFT_LIMIT_FACTOR = 2.0  # tc -> tc / 2
SOFT_LIMIT_ORDER = 2.0  # the order the extrapolation assumes (measured 1.4..3.3)
SOFT_LIMIT_SLACK = 2.0  # |error| <= 2 x correction for any measured order >= 1
SOFT_EFFECT_SLACK = 6.0  # |soft effect at tc| <= 6 x correction for any order >= 1
SOFT_DRIFT = C.Tolerance(
    1e-5,
    "MuJoCo's soft constraints settle at a violation set by solref (time constant "
    "0.02 s): measured 3.7e-7..2.2e-6 here, docs/engines/mujoco.md",
)
SOFT_VELOCITY_DRIFT = C.Tolerance(
    1e-3,
    "MuJoCo's soft constraints: the velocity violation is damped with solref's time "
    "constant (0.02 s), not removed; characterization (measured in crosscheck run, "
    "docs/engines/mujoco.md)",
)
SOFT_ENERGY = C.Tolerance(
    1e-2,
    "the soft constraints' damper (solref damping ratio 1) dissipates energy: "
    "characterization (docs/engines/mujoco.md: 6e-4 J of 7 J for the slider-crank, RK4)",
)


def soft_energy_tolerance(ctx, runs, stiff) -> C.Tolerance:
    """The soft run's energy error bounded like its state error: the damper's dissipation
    shrinks with tc (as tc^2 on slider_crank_split, docs/engines/mujoco.md), so at tc it is at
    most SOFT_EFFECT_SLACK x the extrapolation's correction |D(tc) - D(tc/2)| / 3."""
    d_tc, d_half_step = energy_measure(ctx, *runs[0][1:4]), energy_measure(ctx, *runs[1][1:4])
    d_stiff = energy_measure(ctx, stiff.t, stiff.q, stiff.u)
    w = 1.0 / (SOFT_LIMIT_FACTOR**SOFT_LIMIT_ORDER - 1.0)
    correction = w * abs(d_tc - d_stiff)
    step = abs(d_tc - d_half_step)
    return C.Tolerance(
        SOFT_EFFECT_SLACK * correction + 10 * step + 1e-10,
        f"the soft constraints' damper dissipates energy, less as tc shrinks: at tc it is <= "
        f"{SOFT_EFFECT_SLACK:g} x the correction |D(tc) - D(tc/{SOFT_LIMIT_FACTOR:g})| / 3 "
        f"({correction:.2e}) for any order >= 1, plus 10x the step-halving difference "
        f"({step:.1e})",
    )


def soft_limit(ctx, em, integrator, runs, h, step_err):
    """The rigid-limit record of a soft engine model, and the state and energy tolerances of
    its run at the suite's setting, from its runs at tc, steps h and h/2 (runs) and a run at
    tc / 2 (see SOFT_LIMIT_*); step_err is the step-halving state difference at tc."""
    stiff = em.stiffened(SOFT_LIMIT_FACTOR).simulate(
        ctx.q0, ctx.u0, ctx.grid, integrator=integrator, timestep=h
    )
    w = 1.0 / (SOFT_LIMIT_FACTOR**SOFT_LIMIT_ORDER - 1.0)
    qa, qb = np.unwrap(runs[0][2], axis=0), np.unwrap(stiff.q, axis=0)
    q_lim, u_lim = qb + w * (qb - qa), stiff.u + w * (stiff.u - runs[0][3])
    correction = w * float(np.max(state_error(runs[0][2], runs[0][3], stiff.q, stiff.u)))
    step = 10 * step_err + 1e-10
    limit_tol = C.Tolerance(
        SOFT_LIMIT_SLACK * correction + step,
        f"the runs at solref tc and tc/{SOFT_LIMIT_FACTOR:g} extrapolated to tc -> 0 (order "
        f"{SOFT_LIMIT_ORDER:g}): error <= {SOFT_LIMIT_SLACK:g} x the correction ({correction:.2e}) "
        f"for any measured order >= 1 (1.4..3.3 on the built-in models), plus 10x the step-"
        f"halving difference ({step_err:.1e}); a physics error is not extrapolated away",
    )
    state_tol = C.Tolerance(
        SOFT_EFFECT_SLACK * correction + limit_tol.value,
        f"the soft effect at this solref, <= {SOFT_EFFECT_SLACK:g} x the rigid-limit "
        f"correction ({correction:.2e}) for any order >= 1, plus the rigid-limit tolerance "
        f"({limit_tol.value:.2e}); the rigid-limit record judges the physics",
    )
    err = float(np.max(state_error(q_lim, u_lim, ctx.ref.q, ctx.ref.u)))
    label = f"{runs[0][0]}, solref tc and tc/{SOFT_LIMIT_FACTOR:g} extrapolated to tc -> 0"
    return (
        ("state_error_rigid_limit", err, limit_tol, label),
        state_tol,
        soft_energy_tolerance(ctx, runs, stiff),
    )
