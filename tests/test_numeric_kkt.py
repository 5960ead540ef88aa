"""The numeric KKT path for large models: the IFToMM A02 N-four-bar.

Past codegen.UNROLL_KKT_MAX rows the reference does not unroll its KKT solve; it solves the
generated M, A, f, b per state with reference.numeric.redundant. Checked against MuJoCo's rigid
answer (crosscheck.engines.mujoco.mjcf_rigid) at TOL_MJCF of tests/test_user_models.py: 1e-9
relative, the suite's bar for MJCF files (measured: 6e-15 at these states for N = 5, printed by
`python -m crosscheck.engines.mujoco.mjcf_rigid FILE`; 1.9e-14 at the parallelogram states of
benchmarks/scaling.md).
"""

from __future__ import annotations

import sys
from pathlib import Path

from crosscheck.engines.mujoco.mjcf_rigid import agreement
from reference import models
from reference.backends import codegen
from reference.mjcf.loader import import_mjcf
from reference.numeric.model import NumericModel

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "examples" / "a02"))
from nfourbar import mjcf

TOL_MJCF = 1e-9


def _model(n: int, tmp_path):
    path = tmp_path / f"a02_{n}.xml"
    path.write_text(mjcf(n))
    imp = import_mjcf(path)
    return imp, NumericModel(imp.model, "kane")


def test_five_cells_take_the_numeric_path_and_agree_with_mujoco(tmp_path):
    imp, nm = _model(5, tmp_path)
    assert nm.n + nm.m == 26 > codegen.UNROLL_KKT_MAX
    assert nm.numeric_kkt and nm.backend == "python"
    assert "def forward(" not in nm.source  # nothing unrolled was generated
    assert (nm.rank, nm.m) == (10, 15)  # one dependent row per `connect`
    rows = agreement(imp, nm, 3)
    assert all(r["rank"] == r["mujoco_rank"] == 10 for r in rows)
    worst = max(r["error"] for r in rows)
    assert worst < TOL_MJCF, rows


def test_dependent_rows_generate_no_unrolled_forward(tmp_path):
    """One cell is small enough to unroll, but its rows are dependent: the numeric solve
    answers every state, so no unrolled forward is generated (or compiled) for it."""
    _imp, nm = _model(1, tmp_path)
    assert nm.n + nm.m <= codegen.UNROLL_KKT_MAX
    assert nm.numeric_kkt and "def forward(" not in nm.source
    assert (nm.rank, nm.m) == (2, 3)


def test_independent_rows_stay_unrolled():
    nm = NumericModel(models.get("slider_crank"))
    assert not nm.numeric_kkt and "def forward(" in nm.source
