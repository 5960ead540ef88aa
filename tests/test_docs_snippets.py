"""The documentation's Python snippets run as they are written.

Every ```python block of docs/ and the README runs in a child process, in a directory holding
the out/results.json of a small run (the snippets that read one). A block that defines
`models()` is a model file: it is written to a file and checked with `crosscheck run
--model-file` instead, which must pass.
"""

from __future__ import annotations

import re

import pytest

from tests.support import ROOT, cli

DOCS = [*sorted((ROOT / "docs").rglob("*.md")), ROOT / "README.md"]
BLOCK = re.compile(r"^```python\n(.*?)^```", re.M | re.S)


def _snippets():
    for path in DOCS:
        for k, m in enumerate(BLOCK.finditer(path.read_text())):
            line = path.read_text()[: m.start()].count("\n") + 1
            yield pytest.param(m.group(1), id=f"{path.relative_to(ROOT)}:{line}#{k}")


SNIPPETS = list(_snippets())


def test_the_docs_have_python_snippets():
    """The collection below is not empty by accident (a changed fence would hide them all)."""
    assert len(SNIPPETS) >= 3


@pytest.mark.parametrize("code", SNIPPETS)
def test_a_snippet_runs_as_written(code, child, tmp_path):
    if re.search(r"^def models\(", code, re.M):
        model_file = tmp_path / "snippet_models.py"
        model_file.write_text(code)
        out = child.crosscheck(
            "run", "--model-file", model_file, "--instantaneous", "--out", tmp_path / "check"
        )
        assert out.returncode == 0, out.stdout[-2000:] + out.stderr[-2000:]
        return
    made = cli("run", "pendulum_angle", "--instantaneous", "--out", tmp_path / "out")
    assert made.returncode == 0, made.stderr
    out = child.python(code, cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
