"""The output times of the trajectory check: one grid for the reference and every engine run,
and the fixed-step engines' ladder of a step and its half, both ending exactly on the horizon."""

from __future__ import annotations

import math

import numpy as np

N_OUT = 251  # output grid: 20 ms spacing over 5 s, fine enough for the plots
FIXED_STEPS = (1e-3, 5e-4)  # engines' fixed-step integrators: a step and its half
# how close t_end / h must be to a whole number for t_end to count as a multiple of the step:
# far above the float error of 5.0 / 1e-3 (~1e-16 relative), far below any step a user means
GRID_SLACK = 1e-9


def step_ladder(t_end: float) -> tuple[float, float]:
    """The two fixed steps for a horizon: FIXED_STEPS when t_end is a whole number of the
    coarse step, otherwise the largest h <= FIXED_STEPS[0] that divides t_end (and h / 2).

    Both rungs must end exactly at t_end and share output times, or their trajectories (and the
    halving estimate between them) would be on different grids; a horizon shorter than the
    coarse step (1e-9 s) gets a single step of t_end."""
    h0, h1 = FIXED_STEPS
    n = round(t_end / h0)
    if n >= 1 and abs(n * h0 - t_end) <= GRID_SLACK * t_end:
        return h0, h1
    n = max(1, math.ceil(t_end / h0 - GRID_SLACK))
    h = t_end / n
    return h, h * h1 / h0


def output_grid(t_end: float) -> np.ndarray:
    """The output times, common to the reference and every engine run: at most N_OUT times on
    the coarse step of step_ladder (so both rungs land on them), plus t_end itself (the last
    interval may be shorter)."""
    h0, _ = step_ladder(t_end)
    n = max(1, round(t_end / h0))
    if n % (N_OUT - 1) == 0:  # 5 s: the plain 20 ms grid
        return np.linspace(0.0, t_end, N_OUT)
    every = math.ceil(n / (N_OUT - 1))
    steps = sorted(set(range(0, n + 1, every)) | {n})
    return np.linspace(0.0, t_end, n + 1)[steps]
