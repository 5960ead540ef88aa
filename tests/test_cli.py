"""The CLI contract: names, JSON fields, exit codes, one-line errors."""

from __future__ import annotations

import json

import pytest

from crosscheck.cli import main


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_models_json_fields(capsys):
    code, out, _ = _run(capsys, "models", "--json")
    assert code == 0
    listed = {d["name"]: d for d in json.loads(out)}
    sc = listed["slider_crank"]
    for key in (
        "name",
        "source",
        "coordinates",
        "speeds",
        "parameters",
        "constraints",
        "formulations",
    ):
        assert key in sc
    assert sc["source"] == "Example 2(b)"
    assert sc["coordinates"] == ["theta1", "theta2"]
    assert sc["parameters"]["l2"] == pytest.approx(0.8)
    assert sc["constraints"][0]["holonomic"] == "holonomic"


def test_models_table(capsys):
    code, out, _ = _run(capsys, "models")
    assert code == 0 and "slider_crank_split" in out and "Exercise 6.3" in out


def test_eval_json_matches_addendum(capsys):
    # theta = 0.3, theta' = 1 on L = 0.8: T = m L w^2 + m g cos(theta) = -lambda L
    import math

    L, th, w, m, g = 0.8, 0.3, 1.0, 1.5, 9.81
    q = f"{L * math.sin(th)!r},{L * math.cos(th)!r}"
    u = f"{L * w * math.cos(th)!r},{-L * w * math.sin(th)!r}"
    code, out, _ = _run(capsys, "eval", "pendulum_xy", "--q", q, "--u", u, "--json")
    assert code == 0
    d = json.loads(out)
    assert set(d) >= {"accelerations", "multipliers", "residuals"}
    T = -d["multipliers"][0] * L
    assert T == pytest.approx(m * L * w**2 + m * g * math.cos(th), rel=1e-12)
    assert abs(d["residuals"]["position"][0]) < 1e-15


@pytest.mark.parametrize(
    "argv,needle",
    [
        (["eval", "nope"], "unknown model"),
        (["eval", "slider_crank", "--formulation", "hamilton"], "unknown formulation"),
        (["eval", "slider_crank", "--set", "mass=2"], "unknown parameter"),
        (["eval", "slider_crank", "--set", "m2=0"], "must be > 0"),
        (["eval", "slider_crank", "--set", "m2=nan"], "not finite"),
        (["eval", "slider_crank", "--q", "0.5"], "expected 2 coordinates"),
        (["eval", "slider_crank", "--q", "0.5,0.1", "--u", "1"], "expected 2 speeds"),
        (["eval", "slider_crank", "--q", "0.5,nan", "--u", "0,0"], "NaN"),
        (["eval", "slider_crank", "--q", "0.5,0.1", "--u", "0,0"], "off the constraint manifold"),
        (["eval", "slider_crank", "--q", "0.5,x"], "not a number"),
        (["run", "slider_crank", "--perturb", "bullet:m2=1"], "unknown engine"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(capsys, argv, needle):
    code, _, err = _run(capsys, *argv)
    assert code == 2
    assert needle in err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_off_manifold_project(capsys):
    code, out, _ = _run(
        capsys, "eval", "slider_crank", "--q", "0.5,0.1", "--u", "0,0", "--project", "--json"
    )
    assert code == 0
    d = json.loads(out)
    assert max(map(abs, d["residuals"]["position"])) < 1e-12


def test_singular_pose_is_refused(capsys):
    # l1 = l2 folds the slider-crank onto itself at theta1 = pi/2: the slider row's
    # coefficients l1 C1, l2 C2 both vanish and A loses rank
    import math

    code, _, err = _run(
        capsys,
        "eval",
        "slider_crank",
        "--set",
        "l2=0.3",
        "--q",
        f"{math.pi / 2!r},{-math.pi / 2!r}",
        "--u",
        "0,0",
    )
    assert code == 2 and "singular" in err


@pytest.mark.parametrize("engine", ["pinocchio", "mujoco"])
def test_run_fault_injection_fails(tmp_path, capsys, engine):
    code, _out, _err = _run(
        capsys,
        "run",
        "slider_crank",
        "--engines",
        engine,
        "--out",
        str(tmp_path),
        "--perturb",
        f"{engine}:m2=1e-6",
    )
    assert code == 1
    records = json.loads((tmp_path / "results.json").read_text())["records"]
    failed = {r["quantity"] for r in records if r["passed"] is False}
    assert {"accelerations", "multipliers"} <= failed


def test_run_clean_passes_and_records_contract(tmp_path, capsys):
    code, _out, err = _run(
        capsys, "run", "slider_crank", "--engines", "pinocchio,mujoco", "--out", str(tmp_path)
    )
    assert code == 0, err
    data = json.loads((tmp_path / "results.json").read_text())
    for key in ("command", "versions", "machine", "date"):
        assert key in data["meta"]
    for key in ("python", "numpy", "scipy", "sympy", "pin", "mujoco"):
        assert data["meta"]["versions"][key]
    for r in data["records"]:
        for key in (
            "model",
            "formulation",
            "engine",
            "check",
            "quantity",
            "error",
            "tolerance",
            "passed",
            "reason",
        ):
            assert key in r


def test_two_runs_give_identical_results(tmp_path, capsys):
    """Results are deterministic: only meta's date (and command) may differ between runs."""
    data = []
    for k in range(2):
        out = tmp_path / f"r{k}"
        code, _, err = _run(
            capsys, "run", "slider_crank", "top_euler", "--out", str(out), "--no-report"
        )
        assert code == 0, err
        data.append(json.loads((out / "results.json").read_text()))
    assert data[0]["records"] == data[1]["records"]
    assert data[0]["series"] == data[1]["series"]
    meta = [{k: v for k, v in d["meta"].items() if k not in ("date", "command")} for d in data]
    assert meta[0] == meta[1]


@pytest.mark.parametrize(
    "spaced,joined",
    [
        (["--q", "-0.5,0.2", "--u", "-1,0"], ["--q=-0.5,0.2", "--u=-1,0"]),
        (["--q", "-.5,0.2", "--u", "1,-0"], ["--q=-.5,0.2", "--u=1,-0"]),
        (
            ["--set", "T=-2", "--q", "-1e-1,0.3", "--t", "-0.5"],
            ["--set=T=-2", "--q=-1e-1,0.3", "--t=-0.5"],
        ),
    ],
)
def test_negative_values_after_an_option(capsys, spaced, joined):
    """`--q -0.5,0.2` is read as the value it looks like (argparse alone takes it for an option)
    and gives exactly what the `--q=-0.5,0.2` spelling gives."""
    code, out, err = _run(capsys, "eval", "slider_crank", *spaced, "--project", "--json")
    assert code == 0, err
    code2, out2, _ = _run(capsys, "eval", "slider_crank", *joined, "--project", "--json")
    assert code2 == 0 and json.loads(out) == json.loads(out2)


def test_a_negative_value_does_not_swallow_a_flag(capsys):
    """Only numbers are attached: `--q --json` still reports the missing value."""
    with pytest.raises(SystemExit) as exc:
        main(["eval", "slider_crank", "--q", "--json"])
    assert exc.value.code == 2
    assert "expected one argument" in capsys.readouterr().err


def test_default_paths_resolve_in_the_tests_own_directory(tmp_path, capsys):
    """conftest runs every test in its tmp_path: `crosscheck report` without --results looks
    for out/results.json there, not in the checkout."""
    from pathlib import Path

    assert Path.cwd() == tmp_path
    code, _, err = _run(capsys, "report")
    assert code == 2 and "out/results.json does not exist" in err


def test_the_program_loses_no_output_and_exits_with_the_commands_status(tmp_path, child):
    """The `crosscheck` program (gc frozen before the interpreter's teardown): what it printed
    into a pipe (block-buffered) arrives whole, and its exit status is the command's."""
    ok = child.crosscheck("models", "--json", timeout=120)
    assert ok.returncode == 0, ok.stderr
    assert "pendulum_angle" in {m["name"] for m in json.loads(ok.stdout)}
    bad = child.crosscheck("run", "no_such_model", "--out", tmp_path, timeout=120)
    assert bad.returncode == 2 and "unknown model 'no_such_model'" in bad.stderr


def test_a_profiled_program_still_writes_its_profile(tmp_path, child):
    """Under `python -m cProfile -o F -m crosscheck` (the profiling command of
    benchmarks/run_time.md) the program exits normally, so the profiler writes F."""
    import pstats

    prof = tmp_path / "models.prof"
    r = child.run("-m", "cProfile", "-o", prof, "-m", "crosscheck", "models", timeout=120)
    assert r.returncode == 0, r.stderr
    assert pstats.Stats(str(prof)).total_calls > 0


@pytest.mark.parametrize(("setting", "rendering"), [(None, False), ("glfw", True)])
def test_the_program_imports_mujoco_without_its_rendering(setting, rendering, child):
    """The `crosscheck` program sets MUJOCO_GL=disable unless the user set it: no command
    renders, and MuJoCo's OpenGL code brings the glfw package, which starts a Python process
    of its own at import. `crosscheck engines` imports every engine."""
    probe = (
        "import sys, atexit\n"
        "atexit.register(lambda: print('mujoco' in sys.modules, 'glfw' in sys.modules))\n"
        "sys.argv = ['crosscheck', 'engines']\n"
        "from crosscheck.cli import main\n"
        "main()\n"
    )
    r = child.python(probe, env={"MUJOCO_GL": setting}, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split()[-2:] == ["True", str(rendering)]


def test_engines_lists_every_registered_engine_with_what_it_can_do(capsys):
    from crosscheck.engines.registry import available_engines

    code, out, err = _run(capsys, "engines", "--json")
    assert code == 0, err
    listed = {e["name"]: e for e in json.loads(out)}
    assert set(available_engines()) <= set(listed)
    for name in available_engines():
        assert listed[name]["imports"] is True and listed[name]["version"], listed[name]
        assert listed[name]["models"], listed[name]
        assert {"multipliers", "exact", "integrators"} <= set(listed[name]["capabilities"])


def test_python_dash_m_crosscheck_is_the_program(capsys, monkeypatch):
    """`python -m crosscheck` runs crosscheck.cli.main and exits with its status."""
    import runpy
    import sys

    monkeypatch.setattr(sys, "argv", ["crosscheck", "eval", "no_such_model"])
    with pytest.raises(SystemExit) as exc:
        runpy.run_module("crosscheck", run_name="__main__")
    assert exc.value.code == 2 and "unknown model 'no_such_model'" in capsys.readouterr().err


def test_sweep_bench_measures_throughput_in_process(tmp_path, capsys):
    """`crosscheck sweep --bench` with a few samples: the throughput file is written with a
    figure per stage and the machine's own scaling."""
    code, out, err = _run(
        capsys, "sweep", "pendulum_angle", "--bench", "--samples", "20", "--out", str(tmp_path)
    )
    assert code == 0, err
    bench = json.loads((tmp_path / "sweep_bench.json").read_text())
    assert {"per_model_engine", "scaling", "machine_scaling"} <= set(bench)
    assert bench["per_model_engine"] and "sweep_bench.json" in out


def test_eval_without_a_name_evaluates_every_model_of_the_files(capsys):
    from tests.support import ROOT

    fourbar = str(ROOT / "tests" / "data" / "fourbar_connect.xml")
    code, out, err = _run(capsys, "eval", "--model-file", fourbar, "--json")
    assert code == 0, err
    (one,) = json.loads(out)
    assert one["model"] == "fourbar_connect" and len(one["accelerations"]) == 3
    code, _, err = _run(capsys, "eval")
    assert code == 2 and "give a model name" in err and err.count("\n") == 1
