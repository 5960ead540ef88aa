"""MJCF files the suite did not write, as they are: each is checked, or refused in one line for
physics that acts at every state. Real MuJoCo and Pinocchio, no mocks.

The files are in tests/data/real/, each with its provenance and licence in its header: MuJoCo's
own regression models (test/engine/testdata/: equality constraints with contacts left on,
actuators, off-manifold initial states, free bodies) and Pinocchio's closed-chain Cassie. The
quick test loads every one (no derivation); the slow one runs `crosscheck run --instantaneous`
on each file that is checked, every judged record passing (Cassie included: 35 coordinates, a
free base and four loops, derived on the sums path in about half a minute per formulation).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from crosscheck.cli import main
from reference.errors import UnsupportedModelError
from reference.mjcf.loader import import_mjcf

REAL = Path(__file__).with_name("data") / "real"
# file -> how it is loaded ("--project" where its initial state is off the manifold)
CHECKED = {
    "mujoco_armature_equivalence.xml": (),
    "mujoco_soft_weld.xml": (),
    "mujoco_connect.xml": ("--project",),
    "mujoco_weld.xml": ("--project",),
    "mujoco_sleep_equality.xml": (),
    "mujoco_tendon_dampratio.xml": (),
    "mujoco_force_slide_rotated.xml": (),
    "mujoco_ten_armature_1_equiv.xml": (),
    "pinocchio_cassie.xml": (),
}
# file -> what its one-line refusal says: physics that acts at every state
REFUSED = {
    "mujoco_dofless_weld.xml": "the contact acts at every consistent state",
    "mujoco_slider_crank.xml": "3 actuators have a slidercrank transmission",
    "mujoco_equality_site.xml": "fluid forces (option density/viscosity)",
}


def test_every_real_file_is_accounted_for():
    assert set(CHECKED) | set(REFUSED) == {p.name for p in REAL.glob("*.xml")}


# Cassie's import (35 coordinates, 2-3 s) is tested in tests/test_mjcf_unilateral.py
@pytest.mark.parametrize("name", sorted(set(CHECKED) - {"pinocchio_cassie.xml"}))
def test_checked_files_load(name):
    imp = import_mjcf(REAL / name, project="--project" in CHECKED[name])
    assert imp.model.constraint_names  # every one has equality rows
    text = (REAL / name).read_text()
    assert text.startswith("<!-- From ") and "Licen" in text.split("-->")[0]


@pytest.mark.parametrize("name", sorted(REFUSED))
def test_refused_files_say_why_in_one_line(name):
    with pytest.raises(UnsupportedModelError) as err:
        import_mjcf(REAL / name)
    assert REFUSED[name] in str(err.value) and "\n" not in str(err.value)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(CHECKED))
def test_checked_files_pass_in_both_engines(name, tmp_path):
    """Every judged instantaneous record of MuJoCo and Pinocchio passes (the formulations'
    record too, at its bar derived from cond(K) where that exceeds round-off: Cassie's); files
    with free bodies have judged multipliers on their equality rows (the norm rows alone left
    out)."""
    code = main(
        ["run", "--model-file", str(REAL / name), *CHECKED[name], "--engines",
         "mujoco,pinocchio", "--states", "4", "--instantaneous", "--no-report", "--out",
         str(tmp_path)]
    )  # fmt: skip
    records = json.loads((tmp_path / "results.json").read_text())["records"]
    assert code == 0, [r for r in records if r["passed"] is False]
    for engine in ("mujoco", "pinocchio"):
        (lam,) = [
            r
            for r in records
            if (r["check"], r["engine"], r["quantity"]) == ("instantaneous", engine, "multipliers")
        ]
        assert lam["passed"], lam["reason"]
