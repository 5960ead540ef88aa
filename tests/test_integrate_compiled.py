"""reference.integrate.compiled: the C stepper runs what the Python stepper runs.

Tolerances and why:
- SAME_OUTPUT (relative to the run's rtol): the C loops sum the stages, the error estimate and
  the projection's normal equations in another order than numpy, so the error estimate (a
  difference of stages, ~rtol of their size) differs by round-off that reaches the step sizes
  as ~1e-7 relative changes (the exponent 1/8). Both runs are within the same tolerance of the
  true motion, so the bound is one rtol on the state's scale (1 + max |q|, |u|). Measured:
  `PYTHONPATH=$PWD python benchmarks/c_stepper_speed.py` prints the difference in those units
  (column "/ tol"), at most 0.06 of it at rtol 1e-10 over four models and three methods.
- nfev equal: the same steps are accepted and rejected on every model here (measured); a
  differing count would mean a different step-size control, not round-off.
"""

from __future__ import annotations

import numpy as np
import pytest

from reference import NumericModel, models
from reference.errors import ModelInputError, SingularSystemError
from reference.integrate.driver import IntegrationTimeout, simulate

RTOL = 1e-9
SAME_OUTPUT = 1.0  # in units of rtol * (1 + max |y|), see the module docstring

# one model per feature of the compiled right side and projection
FEATURES = {
    "pendulum_xy": "one position row",
    "slider_crank": "work of a load carried as W",
    "knife_edge": "a motion row: A from the matrices kernel",
    "pendulum_moving_support": "rheonomic: the constraint's power -lambda . a0",
    "double_pendulum_3d": "q' = N(q, u) from the kinematics kernel",
    "top_cartesian": "four rows: the Cholesky solve of J J^T",
}


def _nm(name):
    nm = NumericModel(models.get(name))
    if nm.backend != "c":
        pytest.skip(f"no C backend here ({nm.backend}): the C stepper is in the C module")
    return nm


@pytest.mark.parametrize("method", ["index1", "projection", "baumgarte"])
@pytest.mark.parametrize("name", sorted(FEATURES))
def test_c_stepper_outputs_match_the_python_stepper(name, method):
    nm = _nm(name)
    m = nm.model
    grid = np.linspace(0.0, 1.0, 41)
    runs = {
        st: simulate(
            nm, m.initial_q, m.initial_u, 1.0, method, rtol=RTOL, atol=RTOL, t_eval=grid, stepper=st
        )
        for st in ("python", "c")
    }
    py, c = runs["python"], runs["c"]
    assert c.stats["stepper"] == "c" and py.stats["stepper"] == "python"
    assert (c.nfev, c.nsteps) == (py.nfev, py.nsteps)
    assert c.stats["projections"] == py.stats["projections"]
    assert np.array_equal(c.t, py.t)
    scale = RTOL * (1.0 + max(np.max(np.abs(py.q)), np.max(np.abs(py.u))))
    assert np.max(np.abs(c.q - py.q)) <= SAME_OUTPUT * scale
    assert np.max(np.abs(c.u - py.u)) <= SAME_OUTPUT * scale
    if py.work is not None:
        assert np.max(np.abs(c.work - py.work)) <= SAME_OUTPUT * scale
    r = c.max_residual()
    if method == "projection":  # the projection's guarantee holds on the C path too
        assert r["position"] < 1e-12 and r["velocity"] < 1e-12


def test_c_stepper_records_every_accepted_step_and_lands_on_t_end():
    nm = _nm("slider_crank")
    m = nm.model
    py, c = (
        simulate(nm, m.initial_q, m.initial_u, 2.0, "projection", rtol=1e-10, atol=1e-10, stepper=s)
        for s in ("python", "c")
    )
    assert len(c.t) == len(py.t) == c.nsteps + 1 and c.t[-1] == 2.0
    assert np.max(np.abs(c.final_state - py.final_state)) < 1e-10 * (1 + np.max(np.abs(py.q)))


def test_a_singular_pose_raises_the_python_steppers_error():
    """The C loop stops at the singular stage; the run is made again on the Python stepper,
    whose error (with the time) is what the caller gets."""
    P = {"l1": 0.3, "l2": 0.3, "r2": 0.15, "I_G2": 2.0 * 0.09 / 12}
    nm = NumericModel(models.get("slider_crank"), params=P)
    msgs = []
    for st in ("python", "auto"):
        with pytest.raises(SingularSystemError, match=r"at t = 0\.\d+.*singular") as e:
            simulate(
                nm, [0.5, -0.5], [8.0, -8.0], 1.0, "index1", rtol=1e-12, atol=1e-12, stepper=st
            )
        msgs.append(str(e.value))
    assert msgs[0] == msgs[1]


def test_bounds_are_kept_with_the_python_steppers_words():
    nm = _nm("slider_crank")
    m = nm.model
    for st in ("python", "c"):
        with pytest.raises(IntegrationTimeout, match=r"reached max_steps = 5 at t = "):
            simulate(nm, m.initial_q, m.initial_u, 2.0, "projection", max_steps=5, stepper=st)
        with pytest.raises(IntegrationTimeout, match=r"exceeded max_wall_s = 1e-09 s"):
            simulate(nm, m.initial_q, m.initial_u, 2.0, "index1", max_wall_s=1e-9, stepper=st)


def test_stepper_c_names_what_it_cannot_run():
    nm = _nm("slider_crank")
    m = nm.model
    with pytest.raises(ModelInputError, match="integrator RK45"):
        simulate(nm, m.initial_q, m.initial_u, 0.1, "index1", integrator="RK45", stepper="c")
    with pytest.raises(ModelInputError, match="method nullspace"):
        simulate(nm, m.initial_q, m.initial_u, 0.1, "nullspace", stepper="c")
    with pytest.raises(ModelInputError, match="valid values are auto, c, python"):
        simulate(nm, m.initial_q, m.initial_u, 0.1, "index1", stepper="fortran")
    # auto takes the Python stepper where the C one does not apply, and says so
    tr = simulate(nm, m.initial_q, m.initial_u, 0.1, "nullspace")
    assert (
        tr.stats["stepper"] == "python (method nullspace (compiled: index1, projection, baumgarte))"
    )


def test_the_environment_sets_the_default(monkeypatch):
    nm = _nm("pendulum_xy")
    m = nm.model
    monkeypatch.setenv("CROSSCHECK_STEPPER", "python")
    assert simulate(nm, m.initial_q, m.initial_u, 0.5, "index1").stats["stepper"] == "python"
    monkeypatch.setenv("CROSSCHECK_STEPPER", "auto")
    assert simulate(nm, m.initial_q, m.initial_u, 0.5, "index1").stats["stepper"] == "c"


def test_the_bench_records_both_steppers_side_by_side():
    """bench.json "stepper": one record per model, method and output kind; the figures are
    timings (not judged here), the record says what ran and how far the two runs are apart."""
    from crosscheck.bench.stepper import stepper_record

    nm = _nm("pendulum_xy")
    rec = stepper_record(nm, "projection", "grid", rounds=1)
    assert rec["stepper"] == "c" and rec["nfev_python"] == rec["nfev_c"]
    assert rec["python_wall_s"] > 0 and rec["c_wall_s"] > 0
    assert rec["max_difference"] <= SAME_OUTPUT * rec["rtol"] * rec["state_scale"]
    bad = stepper_record(nm, "no-such-method", "steps", rounds=1)
    assert "unknown method" in bad["failed"]


def test_a_scipy_without_the_tableau_takes_the_python_stepper(monkeypatch):
    """The stepper reads scipy's DOP853 coefficients from the class; a scipy that moved them
    gets the Python stepper (and a reason), not a crash or a wrong table."""
    import scipy.integrate as si

    from reference.integrate import compiled as integrate_compiled

    nm = _nm("pendulum_xy")
    m = nm.model
    integrate_compiled._tableau.cache_clear()
    monkeypatch.setattr(si.DOP853, "D", si.DOP853.D[:, :-1])  # a table of another shape
    try:
        tr = simulate(nm, m.initial_q, m.initial_u, 0.5, "index1")
        assert tr.stats["stepper"].startswith("python (scipy ")
        with pytest.raises(ModelInputError, match="tableau is not where the stepper reads it"):
            simulate(nm, m.initial_q, m.initial_u, 0.5, "index1", stepper="c")
    finally:
        monkeypatch.undo()
        integrate_compiled._tableau.cache_clear()
