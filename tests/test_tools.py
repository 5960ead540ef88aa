"""The tools in scripts/ and the measurement scripts in benchmarks/: each runs on a small case.

The benchmark scripts print figures that docs/ and benchmarks/*.md quote (benchmarks/README.md
says which); run here on one small model, they must finish and print rows of the expected form.
Where a script prints a figure a tolerance rests on, the test also checks the side of the bound
that figure has to be on, so a regression shows here as well as in `crosscheck run`.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SCRIPTS, BENCHMARKS = ROOT / "scripts", ROOT / "benchmarks"


def _run(child, args, timeout=120, env=None, **kw) -> subprocess.CompletedProcess:
    return child.program(*args, timeout=timeout, env=env, **kw)


def _bench(child, script, *args, timeout=120, env=None) -> str:
    """Run benchmarks/<script> with `args`; its stdout (it must exit 0)."""
    r = child.run(BENCHMARKS / script, *args, timeout=timeout, env=env)
    assert r.returncode == 0, f"{script} exited {r.returncode}:\n{r.stdout}\n{r.stderr}"
    return r.stdout


def _has_c_compiler() -> bool:
    from reference.backends import c_build

    return c_build.available()


needs_cc = pytest.mark.skipif(not _has_c_compiler(), reason="no working C compiler here")


# ---- scripts/ ----------------------------------------------------------------------------------


def test_install_test_deps_says_why_when_it_cannot_install(tmp_path, child):
    """Neither Chromium nor apt-get on PATH: it says the browser test will be skipped, exit 0."""
    empty = tmp_path / "bin"
    empty.mkdir()
    bash = shutil.which("bash")
    r = _run(child, [bash, SCRIPTS / "install-test-deps"], env={"PATH": str(empty)}, timeout=30)
    assert r.returncode == 0, r.stderr
    assert "browser test of the report will be skipped" in r.stderr


def test_install_test_deps_is_quiet_when_chromium_is_there(tmp_path, child):
    bindir = tmp_path / "bin"
    bindir.mkdir()
    chromium = bindir / "chromium"
    chromium.write_text("#!/bin/sh\nexit 0\n")
    chromium.chmod(0o755)
    bash = shutil.which("bash")
    r = _run(child, [bash, SCRIPTS / "install-test-deps"], env={"PATH": str(bindir)}, timeout=30)
    assert (r.returncode, r.stdout, r.stderr) == (0, "", "")


def _results(path: Path, records: list[dict]) -> Path:
    path.write_text(json.dumps({"meta": {}, "records": records}))
    return path


def _record(model, quantity, error, passed=True, tolerance=1e-11) -> dict:
    return {
        "model": model,
        "formulation": "lagrange",
        "engine": "pinocchio",
        "check": "instantaneous",
        "quantity": quantity,
        "error": error,
        "tolerance": tolerance,
        "passed": passed,
        "skipped": passed is None,
    }


def test_compare_results_counts_status_and_error_differences(tmp_path, child):
    a = _results(
        tmp_path / "a.json",
        [
            _record("pendulum_xy", "accelerations", 1e-15),
            _record("pendulum_xy", "multipliers", 2e-15),
            _record("slider_crank", "accelerations", 3e-15),
        ],
    )
    b = _results(
        tmp_path / "b.json",
        [
            _record("pendulum_xy", "accelerations", 1e-15),
            _record("pendulum_xy", "multipliers", 7e-13),
            _record("slider_crank", "accelerations", None, passed=None, tolerance=None),
        ],
    )
    r = _run(child, [sys.executable, SCRIPTS / "compare_results.py", a, b])
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines[0] == "3 records: 1 differ in status, 2 in error"
    # (7e-13 - 2e-15) / 1e-11 of the tolerance, in the multipliers record
    assert lines[1].startswith("largest error difference: 0.0698 of the tolerance")
    assert "'multipliers'" in lines[1]


def test_compare_results_refuses_files_of_different_records(tmp_path, child):
    a = _results(tmp_path / "a.json", [_record("pendulum_xy", "accelerations", 1e-15)])
    b = _results(tmp_path / "b.json", [])
    r = _run(child, [sys.executable, SCRIPTS / "compare_results.py", a, b])
    assert r.returncode != 0 and "different record counts: 1 and 0" in r.stderr
    c = _results(tmp_path / "c.json", [_record("slider_crank", "accelerations", 1e-15)])
    r = _run(child, [sys.executable, SCRIPTS / "compare_results.py", a, c])
    assert r.returncode != 0 and "records out of order" in r.stderr
    r = _run(child, [sys.executable, SCRIPTS / "compare_results.py", a])
    assert r.returncode != 0 and "record by record" in r.stderr  # the usage


# ---- benchmarks/: the figures the tolerances rest on ---------------------------------------


def _row(out: str, model: str) -> list[float]:
    """The numbers of a table row `model variant x y ...` printed by a benchmark script."""
    line = next(line for line in out.splitlines() if line.startswith(model + " "))
    return [float(x) for x in line.split()[2:]]


def test_drift_guarantee_holds_with_projection_and_not_without(child):
    """With projection |f| stays within PROJECTION_TOL (1 + |q|) (ratio <= 1) and A u + a0 at
    round-off; index1 at the same rtol drifts past both (docs/tolerances.md)."""
    out = _bench(child, "drift_guarantee.py", "pendulum_xy")
    rows = {}
    for line in out.splitlines():
        words = line.split()
        rows[words[1]] = (float(words[3]), float(words[5]))  # |f| ratio, |A u + a0| ratio
    assert rows["projection"][0] <= 1.0 and rows["projection"][1] <= 16, out
    assert rows["index1"][0] > 1.0, out


def test_mujoco_soft_predict_is_within_soft_prediction(child):
    from crosscheck.checks.tolerances import SOFT_PREDICTION

    out = _bench(child, "mujoco_soft.py", "predict", "3", "pendulum_xy")
    _miss, ratio, _pmin, _pmax, _lmiss, lam_ratio, _lmin, _lmax = _row(out, "pendulum_xy")
    assert ratio <= SOFT_PREDICTION.value and lam_ratio <= SOFT_PREDICTION.value, out


def test_mujoco_soft_limit_extrapolation_error_within_its_slack(child):
    from crosscheck.checks.trajectory.soft import SOFT_LIMIT_SLACK

    out = _bench(child, "mujoco_soft.py", "limit", "pendulum_xy")
    _s02, _s01, _s005, r, _limit, lim_over_corr, _step = _row(out, "pendulum_xy")
    assert r >= 2 and -1 <= lim_over_corr <= SOFT_LIMIT_SLACK, out


def test_mujoco_soft_energy_table(child):
    out = _bench(child, "mujoco_soft.py", "energy")
    rows = [line for line in out.splitlines() if line.strip()]
    assert len(rows) == 6 and all(line.count("h=") == 4 for line in rows), out


def test_opensim_agreement_on_one_model(child):
    pytest.importorskip("opensim")
    out = _bench(child, "opensim_agreement.py", "2", "0", "pendulum_xy")
    row = next(line for line in out.splitlines() if line.startswith("| pendulum_xy"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    acc, lam, tol = float(cells[1]), float(cells[2]), float(cells[3])
    assert acc <= tol and lam <= tol, out


def test_opensim_trajectories_on_one_model(child):
    pytest.importorskip("opensim")
    out = _bench(child, "opensim_agreement.py", "--trajectories", "exercise_6_1")
    rows = [line for line in out.splitlines() if line.startswith("| exercise_6_1")]
    assert len(rows) == 2, out  # RungeKuttaMerson at 1e-10 and CPodes at 1e-8
    merson = [c.strip() for c in rows[0].strip("|").split("|")]
    assert float(merson[3]) < 1e-7 and float(merson[4]) < 1e-7, out  # SIM_TOL of the tests


def test_opensim_integrators_on_one_model(child):
    pytest.importorskip("opensim")
    out = _bench(
        child, "opensim_integrators.py", "pendulum_xy", "--integrators", "RungeKuttaMerson"
    )
    assert "pendulum_xy" in out and "state_error" in out and "one integrate call" in out, out


# ---- benchmarks/: the compiled reference ------------------------------------------------------


@needs_cc
def test_c_stepper_speed_quick(child):
    """The C stepper's outputs within one rtol of the Python stepper's ("/ tol" <= 1)."""
    out = _bench(child, "c_stepper_speed.py", "--quick", "pendulum_xy")
    rows = [line for line in out.splitlines() if line.startswith("pendulum_xy")]
    assert len(rows) == 6, out  # index1, projection, baumgarte x steps, grid
    for line in rows:
        assert line.split()[-1] == "c", line
        assert float(line.split()[-2]) <= 1.0, line


@needs_cc
def test_backend_equality_on_one_model(child):
    out = _bench(child, "backend_equality.py", "pendulum_xy", env={"CROSSCHECK_BACKEND": "c"})
    assert re.search(r"pendulum_xy +c against python: (\d+) / \1 outputs equal", out), out


@needs_cc
def test_c_build_times_on_one_model(child):
    out = _bench(child, "c_build_times.py", "pendulum_xy")
    assert re.search(r"^\d+ modules: build [\d.]+ s in all", out, re.M), out


@needs_cc
def test_c_batch_lanes_equal_to_the_single_call(child):
    out = _bench(child, "c_batch_lanes.py", "pendulum_xy")
    assert "equal to the single call to the bit: True" in out, out


@needs_cc
def test_c_flag_probe_on_one_model(child):
    out = _bench(child, "c_flag_probe.py", "pendulum_xy")
    assert out.count("us per call") == 15, out  # five flag sets, three rounds


def test_parent_imports(child):
    out = _bench(child, "parent_imports.py", "--engines", "pinocchio")
    assert out.startswith("parser ") and "scipy.integrate loaded: False" in out, out


def test_run_phases_on_two_models(tmp_path, child):
    r = _run(
        child,
        [
            sys.executable,
            BENCHMARKS / "run_phases.py",
            "--",
            "pendulum_angle",
            "pendulum_xy",
            "--engines",
            "pinocchio",
            "--instantaneous",
            "--jobs",
            "2",
            "--out",
            tmp_path / "out",
            "--no-report",
        ],
    )
    assert r.returncode == 0, r.stderr
    for phase in ("hand-out starts", "meta work starts", "last model back", "results written"):
        assert phase in r.stderr, r.stderr


def test_engine_simulate_times_on_one_model(tmp_path, child):
    out = _bench(
        child,
        "engine_simulate_times.py",
        "pendulum_angle",
        "--engines",
        "pinocchio",
        "--t-end",
        "0.2",
        "--out",
        tmp_path / "out",
        "--no-report",
    )
    assert "PinEngineModel" in out and "reference (" in out, out


def test_startup_times_on_one_model(child):
    out = _bench(child, "startup_times.py", "--jobs", "1", "--models", "pendulum_angle")
    rows = [line.split() for line in out.splitlines()[1:]]
    assert [r[0] for r in rows] == ["cold", "warm"], out
    assert all(r[3] == "True" for r in rows), out  # the same records cold and warm


@pytest.mark.slow  # four small runs, two of them in a fresh derivation cache
def test_warm_ab_in_a_clone(tmp_path, child):
    """warm_ab.py makes a git worktree of the earlier commit: run it (this checkout's version
    of it) in a clone, so the test leaves the checkout's own repository alone."""
    clone = tmp_path / "clone"
    r = _run(child, ["git", "clone", "-q", ROOT, clone], timeout=120)
    if r.returncode != 0:
        pytest.skip(f"cannot clone the checkout: {r.stderr.strip()}")
    (clone / "benchmarks").mkdir(exist_ok=True)
    shutil.copy(BENCHMARKS / "warm_ab.py", clone / "benchmarks" / "warm_ab.py")
    args = ["HEAD", "--reps", "1", "--", "pendulum_angle", "--engines", "pinocchio"]
    r = _run(
        child,
        [sys.executable, clone / "benchmarks" / "warm_ab.py", *args, "--instantaneous"],
        timeout=600,
        env={"PYTHONPATH": None},  # each worktree's own code, as the script sets it
    )
    assert r.returncode == 0, r.stdout + r.stderr
    assert "rep 1: A" in r.stdout and "B median" in r.stdout, r.stdout


def test_pinocchio_loop_derivatives_shows_the_defect(child):
    """Pinocchio's constraint-dynamics derivatives against its own central differences: right
    on a loop to a world point and on Exercise 6.1's bar; wrong on the slider-crank until
    column 0's extra copies are taken out, and with the world first until the constraint
    Jacobian is reset (docs/engines/pinocchio.md; it says so when an upgrade fixes them)."""
    out = _bench(child, "pinocchio_loop_derivatives.py")
    err = {
        line[:55].strip(): max(float(x) for x in line.split()[-2:]) for line in out.splitlines()[1:]
    }
    assert err["3R arm tip to a world point"] < 1e-6, out
    assert err["bar on a slider to a root slider (exercise_6_1)"] < 1e-6, out
    assert err["2R arm tip to a root slider (slider_crank)"] > 1e-3, out
    assert err["... column 0's nv extra copies taken out"] < 1e-6, out
    assert err["the same, the world first (3rd call)"] > 1e-3, out
    assert err["... and column 0's extra copies taken out"] < 1e-6, out


def test_call_overhead_on_one_model(child):
    out = _bench(child, "call_overhead.py", "pendulum_xy", "--rounds", "2", "--number", "10")
    assert out.startswith("pendulum_xy (") and "over pinocchio:" in out, out


def test_derivation_paths_on_one_cell(child):
    """One cold and warm derivation on the sums path, the per-state costs against Pinocchio's
    adapter and its constraintDynamics (benchmarks/pinocchio_loops.py), and their agreement."""
    out = _bench(child, "derivation_paths.py", "a02:1", "--paths", "sums", "--budget", "120")
    derived, per_state = (json.loads(line) for line in out.splitlines())
    assert derived["cold"]["finished"] and derived["warm"]["finished"], derived
    assert set(per_state["cost_s"]) >= {"reference_forward", "pinocchio_constraint_dynamics"}
    assert max(per_state["error"].values()) < 1e-9, per_state


def test_mujoco_transition_fd_on_one_model(child):
    out = _bench(child, "mujoco_transition_fd.py", "pendulum_xy")
    assert out.count("pendulum_xy") == 3 and "predicted soft effect" in out, out


def test_derivative_speed_on_two_models(child):
    out = _bench(child, "derivative_speed.py", "pendulum_angle", "slider_crank")
    assert "computeConstraintDynamicsDerivatives" in out and "computeABADerivatives" in out, out
