"""The horizon trajectories are compared on when the reference reaches a singular pose (
the IFToMM A02 four-bars lying flat): cut just before the first such pose, said in a record."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from crosscheck.checks.trajectory.horizon import (
    HORIZON_MARGIN,
    HORIZON_QUANTUM,
    crossed,
    horizon_before,
    singular_time,
)
from crosscheck.cli import main
from crosscheck.user_models import load_model_file
from reference.errors import ModelInputError, SingularSystemError
from reference.integrate.driver import simulate
from reference.numeric.model import NumericModel

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "examples" / "a02"))
from nfourbar import mjcf


@pytest.mark.parametrize(
    ("t_sing", "t_end", "expected"),
    [(0.714354, 10.0, 0.707), (5.11319, 10.0, 5.062), (12.0, 10.0, 10.0), (0.0005, 1.0, None)],
)
def test_horizon_is_whole_milliseconds_short_of_the_pose(t_sing, t_end, expected):
    got = horizon_before(t_sing, t_end)
    if expected is None:
        assert got is None
        return
    assert got == pytest.approx(expected, abs=1e-12)
    assert got <= t_sing * (1 - HORIZON_MARGIN) + 1e-12
    assert abs(got / HORIZON_QUANTUM - round(got / HORIZON_QUANTUM)) < 1e-9


def test_only_a_singular_pose_with_its_time_cuts_the_horizon():
    err = SingularSystemError("at t = 1: singular")
    assert singular_time(err) is None  # no time: not a run that reached a pose
    err.t_singular = 1.0
    assert singular_time(err) == 1.0
    other = ModelInputError("bad")
    other.t_singular = 1.0  # type: ignore[attr-defined]
    assert singular_time(other) is None


class _Run:
    def __init__(self, stats):
        self.stats = stats


def test_a_step_across_the_pose_counts_like_a_refusal():
    crossed(_Run({}))  # no crossing: nothing raised
    with pytest.raises(SingularSystemError, match="lost rank between two accepted steps") as e:
        crossed(_Run({"rank_crossings_t": [2.5, 4.0]}))
    assert e.value.t_singular == 2.5


def test_a02_one_cell_is_compared_up_to_its_first_flat_pose(tmp_path, capsys):
    """At rtol 1e-12 the one-cell four-bar reaches its first flat pose at t = 0.708 s (the
    constraint rows lose rank: rank 1 of 2); the run compares the engines on [0, 0.701] s."""
    path = tmp_path / "a02_1.xml"
    path.write_text(mjcf(1))
    argv = ["run", "--model-file", str(path), "--engines", "pinocchio", "--states", "1"]
    code = main([*argv, "--t-end", "3", "--no-report", "--out", str(tmp_path / "out")])
    assert code == 0, capsys.readouterr().err
    records = json.loads((tmp_path / "out" / "results.json").read_text())["records"]
    traj = [r for r in records if r["check"] == "trajectory"]
    (horizon,) = [r for r in traj if r["quantity"] == "horizon"]
    assert horizon["skipped"] and horizon["t_requested"] == 3.0
    assert "lose rank" in horizon["reason"] and "not unique" in horizon["reason"]
    assert all(r["t_end"] == horizon["t_end"] == 0.701 for r in traj)
    pin = next(r for r in traj if r["engine"] == "pinocchio" and r["quantity"] == "state_error")
    assert pin["passed"] is True


# ---- the rank monitor on the two-cell chain, whose two cells lie flat at the same instant ----
# Flat, each cell's closure rows lose one rank: the chain of two loses two at once, two singular
# values of A pass through zero in the same step and det(A_k A_(k-1)^T) keeps its sign.
def _a02_flat_time(cells: int) -> float:
    """The exact time of the chain's first flat pose: every crank turns at theta' with the
    couplers translating, K theta'^2 + V cos(theta) = K + V (released at theta' = -1 rad/s),
    so t is the integral of d theta / |theta'| from 0 to pi/2."""
    from scipy.integrate import quad

    K = 0.5 * ((cells + 1) / 3 + cells)  # cranks about their pivots (m L^2 / 3), couplers
    V = 9.81 * ((cells + 1) * 0.5 + cells)  # crank centres at L/2, couplers at L
    t, _ = quad(lambda th: (1 + V / K * (1 - math.cos(th))) ** -0.5, 0, math.pi / 2)
    return t


def _a02_two_cells_angles():
    """nfourbar.mjcf(2) in five absolute angles (cranks from the vertical, couplers from +x)
    with its four closure rows: no dependent row, so the KKT solve is unrolled and the run can
    take the C stepper (an MJCF import, with its dependent rows, always takes the Python one)."""
    import sympy as sp

    from reference.models.common import planar_body
    from reference.system import Model, Parameter, symbols, vec

    g = Parameter("g", 9.81, "m/s^2", "gravity", nonnegative=True)
    th, ps = symbols("theta0 theta1 theta2"), symbols("psi0 psi1")
    u = symbols("theta0_dot theta1_dot theta2_dot psi0_dot psi1_dot")
    q = (*th, *ps)
    tip = [vec(i - sp.sin(a), sp.cos(a), 0) for i, a in enumerate(th)]
    bodies = [
        planar_body(f"crank{i}", 1, sp.Rational(1, 12), (tip[i] + vec(i, 0, 0)) / 2, a, q, u)
        for i, a in enumerate(th)
    ]
    rows = []
    for i, a in enumerate(ps):
        e = vec(sp.cos(a), sp.sin(a), 0)
        bodies.append(planar_body(f"coupler{i}", 1, sp.Rational(1, 12), tip[i] + e / 2, a, q, u))
        gap = tip[i] + e - tip[i + 1]
        rows += [gap[0], gap[1]]
    return Model(
        name="a02_two_cells_angles",
        source="tests/test_trajectory_horizon.py",
        title="IFToMM A02, two cells, in absolute angles",
        parameters=(g,),
        coordinates=q,
        speeds=u,
        kinematics=u,
        bodies=tuple(bodies),
        gravity=vec(0, -g.symbol, 0),
        configuration_constraints=tuple(rows),
        constraint_names=("x0", "y0", "x1", "y1"),
        formulations=("kane",),
        initial_q=(0.0,) * 5,
        initial_u=(-1.0, -1.0, -1.0, 0.0, 0.0),
        energy_conserved=True,
    )


def _step_across(tr, t_pose: float) -> float:
    """The end of the accepted step that straddles t_pose: where the monitor must report."""
    k = int(np.searchsorted(tr.t, t_pose))
    assert 0 < k < len(tr.t), "the run did not reach the pose"
    return float(tr.t[k])


def test_a02_two_cells_flat_at_once_stop_the_reference_before_the_pose(tmp_path):
    """The reference's own run (projection, rtol 1e-12) of the MJCF chain steps across the flat
    pose (its nearest state is 0.6 ms past it, the KKT pivots never get small): the rank
    monitor alone must report it, and the horizon must then end before the pose."""
    path = tmp_path / "a02_2.xml"
    path.write_text(mjcf(2))
    nm = NumericModel(load_model_file(path)[0].model)
    t_pose = _a02_flat_time(2)
    m = nm.model
    tr = simulate(nm, m.initial_q, m.initial_u, 1.0, "projection", rtol=1e-12, atol=1e-12)
    with pytest.raises(SingularSystemError, match="lost rank between two accepted steps") as e:
        crossed(tr)
    # the report is the end of the step across the pose: the first state past it, no earlier
    # state (the pose's time is exact to quadrature, the run's timing error ~1e-11 s)
    assert e.value.t_singular == _step_across(tr, t_pose)
    # ... and within HORIZON_MARGIN of it, so the compared trajectories stop short of the pose
    cut = horizon_before(e.value.t_singular, 10.0)
    assert cut is not None and cut < t_pose


@pytest.mark.parametrize("stepper", ["c", "python"])
def test_rank_monitor_counts_two_rows_reversing_in_one_step(stepper):
    """Both steppers' monitors on the chain without dependent rows at rtol 1e-10, where steps
    straddle the flat pose (at 1e-11 and tighter they land on it and the KKT check refuses)."""
    nm = NumericModel(_a02_two_cells_angles())
    if stepper == "c" and nm.backend != "c":
        pytest.skip(f"no C backend here ({nm.backend}): the C stepper is in the C module")
    m = nm.model
    tr = simulate(
        nm, m.initial_q, m.initial_u, 1.0, "projection", rtol=1e-10, atol=1e-10, stepper=stepper
    )
    assert tr.stats["stepper"] == stepper
    # the first report is the end of the step across the pose (at this rtol ~60 ms long)
    assert tr.stats.get("rank_crossings_t", [])[:1] == [_step_across(tr, _a02_flat_time(2))]
