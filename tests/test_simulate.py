"""`crosscheck simulate`: the reference's trajectory written to take away (CSV, NPZ, JSON) with
an error estimate, the same numbers as the Python API's."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from reference import NumericModel, models
from reference.integrate.driver import simulate
from tests.support import cli


def test_the_three_files_hold_the_trajectory_the_api_computes(tmp_path):
    out = tmp_path / "sim"
    r = cli("simulate", "slider_crank", "--t-end", "0.5", "--points", "6", "--out", out)
    assert r.returncode == 0, r.stderr
    info = json.loads((out / "slider_crank.json").read_text())
    with open(out / "slider_crank.csv") as fh:
        rows = list(csv.reader(fh))
    z = np.load(out / "slider_crank.npz")
    assert rows[0][:5] == ["t", "theta1", "theta2", "theta1_dot", "theta2_dot"]
    assert len(rows) == 1 + 6 and info["outputs"] == 6
    table = np.array(rows[1:], float)
    assert np.array_equal(table[:, 0], z["t"]) and np.array_equal(table[:, 1:3], z["q"])
    # the same run through the Python API: the same floats
    nm = NumericModel(models.get("slider_crank"))
    q0, u0 = nm.model.initial_q, nm.model.initial_u
    grid = np.linspace(0, 0.5, 6)
    tr = simulate(nm, q0, u0, 0.5, rtol=1e-10, atol=1e-12, t_eval=grid)
    assert np.array_equal(z["q"], tr.q) and np.array_equal(z["u"], tr.u)
    # the multipliers are the reference's at each written state
    for t, q, u, lam in zip(z["t"], z["q"], z["u"], z["multipliers"], strict=True):
        assert np.array_equal(lam, nm.forward(q, u, t).multipliers)
    # the estimate is the tighter run's difference: within what rtol 1e-10 can give over 0.5 s
    # (each step's local error <= rtol; 1e3 rtol bounds the accumulation, measured 1.8e-11)
    assert 0 < info["error_estimate"] <= 1e3 * info["rtol"]
    assert np.max(np.abs(z["position_residuals"])) < 1e-12  # projected every step


def test_output_times_as_given(tmp_path):
    r = cli("simulate", "pendulum_xy", "--times", "0,0.25,1.5", "--out", tmp_path)
    assert r.returncode == 0, r.stderr
    assert np.array_equal(np.load(tmp_path / "pendulum_xy.npz")["t"], [0, 0.25, 1.5])


@pytest.mark.parametrize(
    "argv,fragment",
    [
        (["--times", "0,0.5,0.5"], "--times must increase strictly"),
        (["--times", "0,nan"], "finite output times"),
        (["--rtol", "0"], "give a tolerance in [1e-15, 1)"),
        (["--points", "1000001"], "at most 100000"),
        (["--q", "0,2"], "off the constraint manifold"),
    ],
)
def test_bad_input_is_one_line_and_nothing_written(tmp_path, argv, fragment):
    r = cli("simulate", "pendulum_xy", *argv, "--out", tmp_path / "sim")
    assert r.returncode == 2 and fragment in r.stderr and r.stderr.count("\n") == 1, r.stderr
    assert not (tmp_path / "sim").exists() or not list((tmp_path / "sim").iterdir())


def test_a_run_across_a_singular_pose_is_refused_not_written(tmp_path):
    """The IFToMM A02 chain of two four-bars lies flat at 0.714 s: the motion past it is not
    unique, so a run across it writes nothing and says where; one that stops before it runs."""
    import importlib.util

    from tests.support import ROOT

    spec = importlib.util.spec_from_file_location("nfourbar", ROOT / "examples/a02/nfourbar.py")
    nfourbar = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(nfourbar)
    xml = tmp_path / "a02.xml"
    xml.write_text(nfourbar.mjcf(2))
    out = tmp_path / "sim"
    r = cli("simulate", "a02", "--model-file", xml, "--t-end", "2", "--out", out)
    assert r.returncode == 2 and "crosses a singular pose" in r.stderr, r.stderr
    assert not out.exists() or not list(out.iterdir())
    r = cli("simulate", "a02", "--model-file", xml, "--t-end", "0.7", "--out", out)
    assert r.returncode == 0, r.stderr
