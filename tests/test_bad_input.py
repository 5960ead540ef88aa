"""The bad-input table: every command refuses bad input with one line and exit 2,
before any work, and leaves nothing in its output directory. Exit 1 is kept for "a check
failed"; nothing here may produce it."""

from __future__ import annotations

import json

import pytest

from crosscheck.cli import main

OUT = "{out}"  # replaced by the test's own output directory
MALFORMED = "{malformed}"  # a results.json whose first record has no model name
A_FILE = "{file}"  # an existing plain file
LONG = "{tmp}/" + "x" * 300  # one name longer than any file system allows


def _call(argv: list[str]) -> int:
    try:  # the argument rules refuse at parse time (SystemExit), the registries in the command
        return main(argv)
    except SystemExit as exc:
        return int(exc.code)


CASES = [
    # run
    (["run", "pendulum_angle", "--t-end", "inf", "--out", OUT], 2, "not a finite horizon"),
    (["run", "pendulum_angle", "--t-end", "nan", "--out", OUT], 2, "not a finite horizon"),
    (["run", "pendulum_angle", "--t-end", "0", "--out", OUT], 2, "must be > 0"),
    (["run", "pendulum_angle", "--t-end", "1e9", "--out", OUT], 2, "longer than"),
    (["run", "pendulum_angle", "--engines", ",", "--out", OUT], 2, "names nothing"),
    (["run", "pendulum_angle", "--engines", "mujoco,,pinocchio", "--out", OUT], 2, "empty name"),
    (["run", "pendulum_angle", "--engines", "mujoco,mujoco", "--out", OUT], 2, "more than once"),
    (["run", "pendulum_angle", "--engines", "ode", "--out", OUT], 2, "unknown engine 'ode'"),
    (["run", "pendulum_angle", "--states", "0", "--out", OUT], 2, "--states: 0 must be at least 1"),
    (["run", "pendulum_angle", "--states", "-3", "--out", OUT], 2, "-3 must be at least 1"),
    (["run", "pendulum_angle", "--states", "2.5", "--out", OUT], 2, "not a whole number"),
    (
        ["run", "pendulum_angle", "pendulum_angle", "--out", OUT],
        2,
        "model pendulum_angle given more than once",
    ),
    (["run", "no_such_model", "--out", OUT], 2, "unknown model"),
    (["run", "pendulum_angle", "--perturb", "mujoco:m=x", "--out", OUT], 2, "ENGINE:PARAM=REL"),
    (
        ["run", "slider_crank", "--perturb", "mujoco:m2=nan", "--out", OUT],
        2,
        "m2=nan is not finite",
    ),
    (["run", "slider_crank", "--perturb", "mujoco:m2=-2", "--out", OUT], 2, "must be > 0"),
    (["run", "slider_crank", "--perturb", "mujoco:mass=1", "--out", OUT], 2, "no parameter 'mass'"),
    (["sweep", "slider_crank", "--perturb", "mujoco:m2=nan", "--out", OUT], 2, "is not finite"),
    # bench
    (
        ["bench", "pendulum_angle", "--engines", "ode", "--quick", "--out", OUT],
        2,
        "unknown engine 'ode'",
    ),
    (["bench", "pendulum_angle", "--engines", ",", "--quick", "--out", OUT], 2, "names nothing"),
    (["bench", "pendulum_angle", "pendulum_angle", "--quick", "--out", OUT], 2, "more than once"),
    (["bench", "no_such_model", "--quick", "--out", OUT], 2, "unknown model"),
    # sweep
    (["sweep", "pendulum_xy", "--engines", ",", "--out", OUT], 2, "names nothing"),
    (["sweep", "pendulum_xy", "--engines", "ode", "--out", OUT], 2, "unknown engine 'ode'"),
    (["sweep", "pendulum_xy", "pendulum_xy", "--out", OUT], 2, "more than once"),
    (["sweep", "pendulum_xy", "--samples", "-3", "--out", OUT], 2, "must be at least 1"),
    (["sweep", "pendulum_xy", "--max-seconds", "inf", "--out", OUT], 2, "seconds > 0"),
    # eval
    (["eval", "slider_crank", "--t", "inf"], 2, "--t: inf is not finite"),
    (["eval", "slider_crank", "--t", "x"], 2, "'x' is not a number"),
    (["eval", "no_such_model"], 2, "unknown model"),
    # --out checked before any work: an existing file, a place nobody can write, a long name
    *[
        ([cmd, *extra, "--out", bad], 2, fragment)
        for cmd, extra in (
            ("run", ["pendulum_angle", "--instantaneous"]),
            ("bench", ["pendulum_angle", "--quick"]),
            ("sweep", ["pendulum_xy", "--samples", "2", "--workers", "1"]),
            ("report", ["--results", "{results}"]),
        )
        for bad, fragment in (
            (A_FILE, "is an existing file, not a directory"),
            ("/proc/crosscheck/out", "cannot write there"),
            (LONG, "255"),
        )
    ],
    # report and gate
    (["report", "--results", MALFORMED, "--out", OUT], 2, "record 0 has no 'model' name"),
    (["report", "--results", "{tmp}/missing.json", "--out", OUT], 2, "not found"),
    (["gate", "--baseline", MALFORMED, "--results", MALFORMED], 2, "record 0 has no 'model'"),
    (
        ["gate", "--baseline", "{tmp}/new.json", "--results", MALFORMED, "--update"],
        2,
        "record 0 has no 'model'",
    ),
    (
        [
            "gate",
            "--baseline",
            "/proc/crosscheck/baseline.json",
            "--results",
            "{results}",
            "--update",
        ],
        2,
        "--baseline '/proc/crosscheck': cannot write there",
    ),
    (["gate", "--baseline", "{tmp}", "--results", "{results}", "--update"], 2, "is a directory"),
    (
        ["gate", "--baseline", "{results}", "--results", "{results}", "--factor", "x"],
        2,
        "invalid float value",
    ),
]


@pytest.mark.parametrize("argv,code,fragment", CASES, ids=[" ".join(c[0][:4])[:60] for c in CASES])
def test_bad_input_one_line_exit_code_no_leftovers(tmp_path, capsys, argv, code, fragment):
    (tmp_path / "file").write_text("not a directory")
    (tmp_path / "results.json").write_text(json.dumps({"meta": {}, "records": []}))
    malformed = tmp_path / "malformed.json"
    malformed.write_text(
        json.dumps(
            {
                "meta": {},
                "records": [
                    {
                        "engine": "mujoco",
                        "check": "trajectory",
                        "quantity": "state_error",
                        "error": 1.0,
                        "tolerance": 2.0,
                        "passed": True,
                    }
                ],
            }
        )
    )
    out = tmp_path / "out"
    argv = [
        a.replace(OUT, str(out))
        .replace(MALFORMED, str(malformed))
        .replace(A_FILE, str(tmp_path / "file"))
        .replace("{results}", str(tmp_path / "results.json"))
        .replace("{tmp}", str(tmp_path))
        for a in argv
    ]
    got = _call(argv)
    _, err = capsys.readouterr()
    assert got == code, err
    assert fragment in err, err
    assert err.startswith("crosscheck: error:") and err.count("\n") == 1, err
    assert "Traceback" not in err
    assert not out.exists() or not any(out.iterdir()), sorted(out.iterdir())
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "file",
        "malformed.json",
        "results.json",
    ]  # nothing written
    assert (tmp_path / "file").read_text() == "not a directory"
