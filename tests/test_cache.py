"""Derive once: the compiled code is cached on disk by model content, across processes."""
from __future__ import annotations

import os
import subprocess
import sys

from reference import codegen, models

SCRIPT = """
import sys
import reference.numeric as numeric
if sys.argv[1] == "forbid":
    def refuse(*a, **k):
        raise SystemExit("derivation attempted although the cache holds this model")
    numeric.derive = refuse
from reference import models, NumericModel
nm = NumericModel(models.get("slider_crank"), "kane")
print(repr(nm.forward(nm.model.initial_q, nm.model.initial_u).multipliers[0]))
"""


def _run(mode, cache):
    env = dict(os.environ, CROSSCHECK_CACHE_DIR=str(cache))
    return subprocess.run([sys.executable, "-c", SCRIPT, mode], env=env, capture_output=True,
                          text=True, timeout=300)


def test_second_process_reads_the_cache(tmp_path):
    first = _run("derive", tmp_path)
    assert first.returncode == 0, first.stderr
    assert list(tmp_path.glob("slider_crank-kane-*.py")), "first process wrote no cache entry"
    second = _run("forbid", tmp_path)
    assert second.returncode == 0, second.stderr
    assert second.stdout == first.stdout


def test_cache_key_follows_model_content():
    import dataclasses
    model = models.get("slider_crank")
    changed = dataclasses.replace(model, configuration_constraints=(
        2 * model.configuration_constraints[0],))
    assert codegen.cache_key(model, "lagrange") != codegen.cache_key(changed, "lagrange")
    assert codegen.cache_key(model, "lagrange") != codegen.cache_key(model, "kane")
    assert codegen.cache_key(model, "lagrange") == codegen.cache_key(models.get("slider_crank"),
                                                                      "lagrange")
