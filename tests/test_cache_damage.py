"""The derivation cache is a cache: a damaged entry (truncated, garbage, empty, another key's
content, a truncated built extension) is reported in one line and derived or built again, and
a cache location that cannot be used gives way to a private temporary one, with one line.
Every test runs in a private cache (the cold tier)."""

from __future__ import annotations

import os

import numpy as np
import pytest

from reference import NumericModel, models
from reference.backends import c_build, cache
from reference.derivatives.exact import DerivativeModel

MODEL = "pendulum_xy"


def _answer(nm: NumericModel) -> np.ndarray:
    q, u = nm.model.initial_q, nm.model.initial_u
    return nm.forward(q, u).accelerations


def _warnings(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("crosscheck: warning:")]


DAMAGE = {
    "truncated": lambda text, other: text[: len(text) // 2],
    "garbage": lambda text, other: "\x00\x17 not python at all )(\n" * 40,
    "empty": lambda text, other: "",
    "valid Python, not an entry": lambda text, other: "META = {}\n",
    "another key's entry": lambda text, other: other,
    "last line cut": lambda text, other: text[:-3],
}


@pytest.mark.parametrize("damage", list(DAMAGE))
def test_a_damaged_entry_is_said_and_derived_again(damage, fresh_cache, capsys, monkeypatch):
    monkeypatch.setenv("CROSSCHECK_BACKEND", "python")
    model = models.get(MODEL)
    want = _answer(NumericModel(model, "kane"))
    other = NumericModel(model, "lagrange").cache_path.read_text()
    entry = NumericModel(model, "kane").cache_path
    capsys.readouterr()
    entry.write_text(DAMAGE[damage](entry.read_text(), other))
    nm = NumericModel(model, "kane")
    assert np.array_equal(_answer(nm), want)
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith("crosscheck: warning: derivation cache entry") and "damaged" in line
    assert str(entry) in line
    assert cache.unseal(entry.stem, entry.read_text()) is not None, "not replaced by a whole one"
    NumericModel(model, "kane")
    assert capsys.readouterr().err == "", "the replaced entry is damaged again"
    assert not list(fresh_cache.glob("*.tmp"))


def test_a_damaged_derivative_entry_is_derived_again(fresh_cache, capsys, monkeypatch):
    monkeypatch.setenv("CROSSCHECK_BACKEND", "python")
    nm = NumericModel(models.get(MODEL), "kane")
    q, u = nm.model.initial_q, nm.model.initial_u
    want = DerivativeModel(nm).at(q, u).jacobian
    entries = sorted(fresh_cache.glob("*-d*.py"))
    capsys.readouterr()
    for entry in entries:
        entry.write_text(entry.read_text()[:200])
    got = DerivativeModel(NumericModel(models.get(MODEL), "kane")).at(q, u).jacobian
    lines = _warnings(capsys.readouterr().err)
    assert lines and all("damaged" in line for line in lines)
    assert np.array_equal(got, want, equal_nan=True)
    assert all(
        cache.unseal(e.stem, e.read_text()) is not None for e in entries if e.name in "".join(lines)
    )


def test_a_damaged_compiled_form_is_compiled_again(fresh_cache, capsys, monkeypatch):
    monkeypatch.setenv("CROSSCHECK_BACKEND", "python")
    model = models.get(MODEL)
    want = _answer(NumericModel(model, "kane"))
    (code,) = fresh_cache.glob("kane-*.code")
    blob = code.read_bytes()
    code.write_bytes(blob[:-40] + bytes(40))  # the stamp intact, the payload altered
    assert np.array_equal(_answer(NumericModel(model, "kane")), want)
    assert code.read_bytes() == blob


_LOAD = """
import sys
from reference import NumericModel, models
nm = NumericModel(models.get(sys.argv[1]), "kane")
print(nm.backend, repr(nm.forward(nm.model.initial_q, nm.model.initial_u).accelerations[0]))
"""


@pytest.mark.skipif(not c_build.available(), reason="no working C compiler")
@pytest.mark.parametrize("damage", ("truncated", "zeroed", "unrecorded and cut"))
def test_a_damaged_built_module_is_never_loaded(damage, child, fresh_cache):
    """A truncated extension was a bus error (exit 135) when loaded: its recorded digest
    differs, so it is built again instead, with one line."""
    env = {"CROSSCHECK_BACKEND": "c"}
    first = child.python(_LOAD, MODEL, env=env, timeout=300)
    assert first.returncode == 0, first.stderr
    assert first.stdout.startswith("c ")
    (so,) = fresh_cache.glob("kane-*_c_*.so")
    data = so.read_bytes()
    if damage == "truncated":
        so.write_bytes(data[: len(data) // 3])
    elif damage == "zeroed":
        so.write_bytes(data[:4096] + bytes(len(data) - 4096))
    else:  # built before digests were recorded, then cut short: its ELF layout says so
        so.with_name(so.name + ".sha256").unlink()
        so.write_bytes(data[: len(data) - 512])
    again = child.python(_LOAD, MODEL, env=env, timeout=300)
    assert again.returncode == 0, again.stderr
    assert again.stdout == first.stdout
    (line,) = _warnings(again.stderr)
    assert "damaged" in line and so.name in line
    assert cache.built_intact(so) is True


@pytest.mark.skipif(not c_build.available(), reason="no working C compiler")
def test_a_whole_module_built_before_digests_is_taken_and_recorded(child, fresh_cache):
    env = {"CROSSCHECK_BACKEND": "c"}
    assert child.python(_LOAD, MODEL, env=env, timeout=300).returncode == 0
    (so,) = fresh_cache.glob("kane-*_c_*.so")
    sidecar = so.with_name(so.name + ".sha256")
    sidecar.unlink()
    mtime = so.stat().st_mtime_ns
    again = child.python(_LOAD, MODEL, env=env, timeout=300)
    assert again.returncode == 0 and again.stderr == "", again.stderr
    assert so.stat().st_mtime_ns == mtime and sidecar.exists()


def _location(kind: str, tmp_path) -> str:
    if kind == "a file":
        (tmp_path / "cache").write_text("not a directory")
        return str(tmp_path / "cache")
    if kind == "below a file":
        (tmp_path / "f").write_text("")
        return str(tmp_path / "f" / "cache")
    ro = tmp_path / "read-only"
    ro.mkdir()
    ro.chmod(0o500)
    return str(ro)


@pytest.mark.parametrize("kind", ("a file", "below a file", "read-only"))
def test_an_unusable_location_gives_way_to_a_private_cache(
    kind, tmp_path, fresh_cache, capsys, monkeypatch
):
    if kind == "read-only" and os.geteuid() == 0:
        pytest.skip("root writes into a read-only directory")
    monkeypatch.setenv("CROSSCHECK_BACKEND", "python")
    root = _location(kind, tmp_path)
    monkeypatch.setenv("CROSSCHECK_CACHE_DIR", root)
    nm = NumericModel(models.get(MODEL), "kane")
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith(f"crosscheck: warning: the derivation cache {root} cannot be used")
    assert "CROSSCHECK_CACHE_DIR" in line
    private = nm.cache_path.parent
    assert private != tmp_path and os.environ["CROSSCHECK_CACHE_DIR"] == str(private)
    assert nm.cache_path.exists()
    NumericModel(models.get(MODEL), "lagrange")
    assert capsys.readouterr().err == "", "said more than once"


def test_a_command_on_an_unusable_cache_runs_and_says_so_once(tmp_path, fresh_cache):
    from tests.support import cli

    (tmp_path / "cache").write_text("")
    os.environ["CROSSCHECK_CACHE_DIR"] = str(tmp_path / "cache")  # restored by fresh_cache
    out = cli("eval", MODEL)
    assert out.returncode == 0, out.stderr
    assert len(_warnings(out.stderr)) == 1
