"""Bad input as a hostile user gives it, through the command line in this process: every case
exits 2 with exactly one line on stderr naming the problem, and writes nothing. The table holds
the cases that once ended in a traceback, a wrong exit status or a misleading message, and a
sample of those refused from the start; the Python API's own cases follow it."""

from __future__ import annotations

import math

import pytest

from tests.support import cli

HUGE = "99999999999999999999"

# files the cases read, written into the test's directory by _files
FILES = {
    "world.xml": "<mujoco><worldbody/></mujoco>",
    "geoms.xml": '<mujoco><worldbody><geom type="plane" size="1 1 1"/></worldbody></mujoco>',
    "welded.xml": (
        '<mujoco><worldbody><body><geom size="0.1" mass="1"/></body></worldbody></mujoco>'
    ),
    "exit0.py": "import sys\nsys.exit(0)\n",
    "exit3.py": "import sys\nsys.exit(3)\n",
    "hook_exits.py": "def models():\n    raise SystemExit(0)\n",
    "a_file": "not a directory",
}

SWEEP = ("sweep", "pendulum_xy", "--engines", "mujoco", "--samples", "2")

# (argv with {dir} for the test's directory and {out} for the output it must not write,
#  what the one line must say)
CASES = {
    # misleading messages, now naming the real cause
    "perturb by 0": (
        ("run", "pendulum_xy", "--engines", "mujoco", "--perturb", "mujoco:m=0"),
        "0 changes nothing",
    ),
    "perturb by -0.0": (
        ("sweep", "pendulum_xy", "--engines", "mujoco", "--perturb", "mujoco:m=-0.0"),
        "0 changes nothing",
    ),
    "parameter that overflows": (("eval", "pendulum_xy", "--set", "m=1e308"), "overflow"),
    "parameter that overflows, 3-D": (("eval", "top_euler", "--set", "m=1e308"), "overflow"),
    # world-body-only files: tracebacks before
    "run: world body only": (("run", "--model-file", "{dir}/world.xml"), "no moving body"),
    "eval: world body only": (("eval", "--model-file", "{dir}/world.xml"), "no moving body"),
    "bench: world body only": (
        ("bench", "--quick", "--model-file", "{dir}/world.xml"),
        "no moving body",
    ),
    "run: geoms only": (("run", "--model-file", "{dir}/geoms.xml"), "no moving body"),
    "models: welded body": (("models", "--model-file", "{dir}/welded.xml"), "no moving body"),
    # a model file that exits: exit 0 or 3 having done nothing, before
    "sys.exit(0) at import": (("run", "--model-file", "{dir}/exit0.py"), "sys.exit(0)"),
    "sys.exit(3) at import": (("run", "--model-file", "{dir}/exit3.py"), "sys.exit(3)"),
    "models() exits": (("eval", "--model-file", "{dir}/hook_exits.py"), "sys.exit(0)"),
    # sensitivity's inputs
    "sensitivity --engines ,": (("sensitivity", "--engines", ","), "names nothing"),
    "sensitivity --states 0": (("sensitivity", "--states", "0"), "at least 1"),
    "sensitivity --states huge": (("sensitivity", "--states", HUGE), "more than 10,000"),
    "sensitivity --out a file": (
        ("sensitivity", "pendulum_xy", "--out", "{dir}/a_file"),
        "is an existing file",
    ),
    "sensitivity unknown engine": (("sensitivity", "--engines", "nosuch"), "unknown engine"),
    # counts without a bound, before
    "run --states huge": (("run", "pendulum_xy", "--states", HUGE), "more than 10,000"),
    "run --jobs huge": (("run", "pendulum_xy", "--jobs", HUGE), "more than 1,024"),
    "sweep --workers huge": ((*SWEEP, "--workers", HUGE), "more than 1,024"),
    "sweep --chunk huge": ((*SWEEP, "--chunk", HUGE), "more than 10,000,000"),
    "sweep --samples huge": (("sweep", "pendulum_xy", "--samples", HUGE), "with --index"),
    "sweep --index huge": ((*SWEEP, "--index", HUGE), "2**53"),
    "sweep --worst huge": ((*SWEEP, "--worst", HUGE), "more than 10,000,000"),
    # a sample of the cases refused from the start
    "unknown model": (("run", "no_such_model"), "no_such_model"),
    "run --engines ,": (("run", "--engines", ","), "names nothing"),
    "run --states 0": (("run", "--states", "0"), "at least 1"),
    "run --t-end inf": (("run", "--t-end", "inf"), "not a finite horizon"),
    "run --t-end 0": (("run", "--t-end", "0"), "must be > 0"),
    "run --out a file": (("run", "pendulum_xy", "--out", "{dir}/a_file"), "is an existing file"),
    "perturb an unknown parameter": (
        ("run", "pendulum_xy", "--engines", "mujoco", "--perturb", "mujoco:nosuch=1e-6"),
        "nosuch",
    ),
    "perturb malformed": (("run", "--perturb", "mujoco"), "ENGINE:PARAM=REL"),
    "eval NaN state": (("eval", "pendulum_xy", "--q", "nan,1"), "NaN"),
    "eval wrong count": (("eval", "pendulum_xy", "--q", "1"), "pendulum_xy"),
    "no such model file": (("run", "--model-file", "{dir}/missing.xml"), "no such file"),
    "report without results": (
        ("report", "--results", "{dir}/missing.json"),
        "missing.json",
    ),
    "simulate --points 0": (("simulate", "pendulum_xy", "--points", "0"), "at least 1"),
}

# commands whose argv takes --out: each case gets one that must stay absent
TAKES_OUT = {"run", "bench", "sweep", "sensitivity", "report", "simulate"}


@pytest.fixture
def files(tmp_path):
    for name, text in FILES.items():
        (tmp_path / name).write_text(text)
    return tmp_path


def _argv(template, directory) -> list[str]:
    argv = [str(a).replace("{dir}", str(directory)) for a in template]
    if argv[0] in TAKES_OUT and "--out" not in argv:
        argv += ["--out", str(directory / "out")]
    return argv


@pytest.mark.parametrize("case", list(CASES))
def test_bad_input_is_one_line_exit_2_and_nothing_written(case, files):
    template, says = CASES[case]
    before = sorted(p.name for p in files.rglob("*"))
    res = cli(*_argv(template, files))
    lines = res.stderr.splitlines()
    assert res.returncode == 2, (res.returncode, res.stderr[-2000:])
    assert len(lines) == 1, res.stderr
    assert lines[0].startswith("crosscheck: error: "), lines[0]
    assert says in lines[0], lines[0]
    assert "Traceback" not in res.stderr
    assert sorted(p.name for p in files.rglob("*")) == before, "something was written"
    assert (files / "a_file").read_text() == FILES["a_file"]


@pytest.mark.parametrize(
    "kwargs, says",
    [
        ({"states": 0}, "states=0"),
        ({"states": int(HUGE)}, "states="),
        ({"t_end": math.inf, "trajectories": True}, "t_end=inf"),
        ({"t_end": math.nan, "trajectories": True}, "t_end=nan"),
        ({"t_end": 0, "trajectories": True}, "t_end=0"),
        ({"engines": ","}, "engines=','"),
        ({"engines": []}, "engines=[]"),
    ],
)
def test_the_api_refuses_bad_arguments_in_one_line(kwargs, says):
    import crosscheck
    from reference.errors import ModelInputError

    with pytest.raises(ModelInputError) as e:
        crosscheck.check("pendulum_xy", **({"engines": "mujoco"} | kwargs))
    assert says in str(e.value) and "\n" not in str(e.value)


def test_the_api_reads_a_string_as_engine_names():
    import crosscheck

    records = crosscheck.check("pendulum_xy", "mujoco", states=1)
    assert {r["engine"] for r in records} <= {"reference", "mujoco"}
    assert any(r["engine"] == "mujoco" for r in records)


@pytest.mark.parametrize("name", ("world.xml", "geoms.xml", "exit0.py", "exit3.py"))
def test_the_api_refuses_a_file_with_nothing_to_check(name, files):
    import crosscheck
    from reference.errors import ModelFileError

    with pytest.raises(ModelFileError) as e:
        crosscheck.check(files / name, "mujoco")
    assert "\n" not in str(e.value) and name in str(e.value)


def test_the_sweep_bound_is_the_command_lines():
    from crosscheck.commands.arguments import MAX_SAMPLES
    from crosscheck.sweep import config

    assert config.MAX_SAMPLES == MAX_SAMPLES
