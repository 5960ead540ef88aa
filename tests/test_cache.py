"""Derive once: the compiled code is cached on disk by model content, across processes."""

from __future__ import annotations

import os

from reference import models
from reference.backends import codegen

SCRIPT = """
import sys
import reference.numeric.model as numeric
if sys.argv[1] == "forbid":
    def refuse(*a, **k):
        raise SystemExit("derivation attempted although the cache holds this model")
    numeric.derive = refuse
import dataclasses
from reference import models, NumericModel
model = models.get("slider_crank")
if len(sys.argv) > 2:  # a renamed copy: the same content under another name
    model = dataclasses.replace(model, name=sys.argv[2])
nm = NumericModel(model, "kane")
print(repr(nm.forward(nm.model.initial_q, nm.model.initial_u).multipliers[0]))
"""


def test_second_process_reads_the_cache(child, fresh_cache):
    first = child.python(SCRIPT, "derive", timeout=300)
    assert first.returncode == 0, first.stderr
    assert list(fresh_cache.glob("kane-*.py")), "first process wrote no cache entry"
    second = child.python(SCRIPT, "forbid", timeout=300)
    assert second.returncode == 0, second.stderr
    assert second.stdout == first.stdout


def test_renamed_model_reuses_the_derivation(child, fresh_cache):
    """The name is not physics. A renamed copy of a model (or the same MJCF
    file imported under another name) reads the entry its original wrote: the second process
    refuses to derive and still gives the same multiplier."""
    first = child.python(SCRIPT, "derive", timeout=300)
    assert first.returncode == 0, first.stderr
    renamed = child.python(SCRIPT, "forbid", "my_renamed_slider_crank", timeout=300)
    assert renamed.returncode == 0, renamed.stderr
    assert renamed.stdout == first.stdout


def test_mjcf_reimport_under_another_name_has_the_same_key(tmp_path):
    import shutil

    from reference.mjcf.loader import import_mjcf

    src = os.path.join(os.path.dirname(__file__), "data", "fourbar_connect.xml")
    copy = tmp_path / "my_copy_of_the_fourbar.xml"
    shutil.copy(src, copy)
    a, b = import_mjcf(src).model, import_mjcf(copy).model
    assert a.name != b.name
    assert codegen.cache_key(a, "kane") == codegen.cache_key(b, "kane")


def test_cache_key_follows_model_content():
    import dataclasses

    model = models.get("slider_crank")
    changed = dataclasses.replace(
        model, configuration_constraints=(2 * model.configuration_constraints[0],)
    )
    assert codegen.cache_key(model, "lagrange") != codegen.cache_key(changed, "lagrange")
    assert codegen.cache_key(model, "lagrange") != codegen.cache_key(model, "kane")
    assert codegen.cache_key(model, "lagrange") == codegen.cache_key(
        models.get("slider_crank"), "lagrange"
    )


KEY_SCRIPT = """
from reference import models
from reference.backends import codegen
print(codegen.__file__)
print(codegen.cache_key(models.get("slider_crank"), "kane"))
"""


def _key_and_entries(child, pkg_root, cache):
    """The cache key seen by a process that imports `reference` from `pkg_root`, and the cache
    entries that process leaves after building the model once."""
    env = {"PYTHONPATH": pkg_root}
    key = child.python(KEY_SCRIPT, env=env, timeout=300, cwd=pkg_root)
    assert key.returncode == 0, key.stderr
    where, key = key.stdout.split()
    assert where.startswith(str(pkg_root)), f"the copy was not imported: {where}"
    run = child.python(SCRIPT, "derive", env=env, timeout=300, cwd=pkg_root)
    assert run.returncode == 0, run.stderr
    return key, sorted(p.name for p in cache.glob("kane-*.py"))


def test_editing_a_formulation_misses_the_cache(tmp_path, child, fresh_cache):
    """A warm cache must not hide an edit of the derivation's source. A copy of
    the package with one formulation edited (a comment is enough: the key hashes the files, so
    any edit counts) gets another key, and building the model there derives a new entry."""
    import shutil

    import reference

    src = os.path.dirname(reference.__file__)
    original, edited = tmp_path / "original", tmp_path / "edited"
    for root in (original, edited):
        shutil.copytree(src, root / "reference", ignore=shutil.ignore_patterns("__pycache__"))
    proj = edited / "reference" / "formulations" / "projection.py"
    proj.write_text(proj.read_text() + "# edited\n")
    assert "# edited" in proj.read_text(), "the edit did not apply: the test proves nothing"
    key0, entries0 = _key_and_entries(child, original, fresh_cache)
    key1, entries1 = _key_and_entries(child, edited, fresh_cache)
    assert key0 != key1
    assert f"{key0}.py" in entries0 and f"{key1}.py" in entries1
    # each derivation leaves its source (key-prefixed): the edited copy adds its own and
    # reuses none of the original's
    assert set(entries0) < set(entries1), "the original's entry was lost"
    assert all(e.startswith(key1) for e in set(entries1) - set(entries0)), entries1
    assert not [e for e in entries0 if e.startswith(key1)], "the copies share an entry"


def test_compiled_entry_is_kept_beside_its_source(tmp_path, monkeypatch):
    """codegen._code_object keeps compile()'s result beside the entry: a second load does not
    compile; an entry whose source changed, or a damaged file, is compiled again (and the
    code runs the new source), never loaded stale."""
    import builtins

    entry = tmp_path / "kane-0123456789abcdef.py"
    entry.write_text("X = 1\n")
    first = codegen._code_object(entry.read_text(), entry)
    (kept,) = tmp_path.glob("kane-0123456789abcdef.*.code")
    calls = []
    real_compile = builtins.compile
    monkeypatch.setattr(
        builtins, "compile", lambda *a, **k: calls.append(a[1]) or real_compile(*a, **k)
    )

    def x_of(code) -> int:
        namespace: dict = {}
        exec(code, namespace)
        return namespace["X"]

    assert x_of(codegen._code_object("X = 1\n", entry)) == x_of(first) == 1 and calls == []
    assert x_of(codegen._code_object("X = 2\n", entry)) == 2 and calls == [str(entry)]
    kept.write_bytes(kept.read_bytes()[:40])  # cut short after its stamp
    assert x_of(codegen._code_object("X = 2\n", entry)) == 2 and len(calls) == 2
    assert x_of(codegen._code_object("X = 2\n", entry)) == 2 and len(calls) == 2
    assert not list(tmp_path.glob("*.tmp"))
