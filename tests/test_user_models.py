"""Users' own models: MJCF files into the reference, dependent constraint rows,
force elements, and the model-file loader. Real MuJoCo, no mocks.

The MJCF checks compare the reference's accelerations, mapped to MuJoCo's qacc, with MuJoCo's
rigid answer (crosscheck.engines.mujoco.mjcf_rigid: the exact KKT solve from MuJoCo's own M,
qfrc_smooth, equality Jacobians and J-dot v), at the file's initial state and at seeded random
states projected onto the constraint manifold.

TOL_MJCF = 1e-9 relative to max(1, max|qacc|), the bar for MJCF files. Measured (kane, lagrange,
`PYTHONPATH=$PWD python -m pytest -q tests/test_user_models.py -k mjcf -s` prints the figures):
pendulum_hinge 6e-16, double_pendulum 1.2e-15, fourbar_connect 4e-15, fourbar_tilted 2e-15,
fourbar_sites 4e-15, weld_sites 6e-16; slow tests: gripper 5e-15, spatial_mix 1e-14, so the
bar has five orders of margin above round-off and far below any modelling error (a wrong
armature, anchor or axis shows at 1e-3..1).
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import mujoco
import numpy as np
import pytest
import sympy as sp

from crosscheck.engines.mujoco.mjcf_rigid import agreement, rigid_forward, sample_states
from crosscheck.user_models import (
    describe,
    entry_point_models,
    load_all,
    load_model_file,
)
from reference.errors import (
    InconsistentConstraintError,
    ModelFileError,
    OffManifoldError,
    RedundantConstraintError,
    UnsupportedModelError,
)
from reference.mjcf.loader import import_mjcf, qvel_from_rates, rates_from_qvel
from reference.models import get
from reference.numeric import redundant
from reference.numeric.model import NumericModel

DATA = Path(__file__).with_name("data")
TOL_MJCF = 1e-9


@cache
def imported(stem: str):
    return import_mjcf(DATA / f"{stem}.xml")


@cache
def numeric(stem: str, formulation: str) -> NumericModel:
    return NumericModel(imported(stem).model, formulation)


def worst_error(stem: str, formulation: str, count: int = 4) -> float:
    rows = agreement(imported(stem), numeric(stem, formulation), count)
    worst = max(r["error"] for r in rows)
    print(f"\n{stem} / {formulation}: worst relative qacc error {worst:.1e}")
    return worst


def states(imp, count: int):
    return sample_states(imp, count)


# ---- MJCF into the reference --------------------------------------------------------------------
@pytest.mark.parametrize("stem", ["pendulum_hinge", "double_pendulum", "fourbar_connect"])
@pytest.mark.parametrize("formulation", ["kane", "lagrange"])
def test_mjcf_accelerations_equal_mujoco_rigid(stem, formulation):
    assert worst_error(stem, formulation) < TOL_MJCF


@pytest.mark.parametrize("stem, rank, rows", [("fourbar_sites", 2, 3), ("weld_sites", 1, 6)])
def test_mjcf_site_semantic_connect_and_weld(stem, rank, rows):
    """connect and weld between sites (site_xpos, site_quat); the weld between two hinged
    links keeps one of its six rows independent."""
    nm = numeric(stem, "kane")
    assert (nm.rank, nm.m) == (rank, rows)
    assert worst_error(stem, "kane") < TOL_MJCF


def test_mjcf_tilted_loop_in_a_frame():
    """The four-bar inside a tilted <frame>: skew compiled axes, and a dependent connect row
    that is a combination of the others (singular value 7e-18 relative), not a zero row."""
    assert numeric("fourbar_tilted", "kane").rank == 2
    assert worst_error("fourbar_tilted", "kane") < TOL_MJCF


@pytest.mark.slow
def test_mjcf_ten_body_gripper():
    """Two slider-crank loops closed by connect on a plunger, two joint couplings, springs,
    dampers, armature: 9 coordinates, 8 rows of rank 6 (derivation ~1 min cold)."""
    nm = numeric("gripper", "kane")
    assert (nm.rank, nm.m) == (6, 8)
    assert worst_error("gripper", "kane") < TOL_MJCF


@pytest.mark.slow
def test_mjcf_every_joint_and_equality_type():
    """Free and ball joints (quaternions with their norm rows), slide spring, armature,
    damping, weld and a quadratic joint coupling (derivation ~3 min cold). Where its generated
    code is nested deeper than the C printer recurses, NumericModel keeps it on the pure-Python
    path (the same numbers)."""
    assert worst_error("spatial_mix", "kane") < TOL_MJCF


def test_mjcf_unconstrained_pendulum_equals_mj_forward():
    """No constraints: MuJoCo's own qacc is exact, and equals the reference's."""
    imp, nm = imported("pendulum_hinge"), numeric("pendulum_hinge", "kane")
    for qpos, qvel in states(imp, 3):
        d = mujoco.MjData(imp.mj)
        d.qpos[:], d.qvel[:] = qpos, qvel
        mujoco.mj_forward(imp.mj, d)
        fw = nm.forward(qpos, rates_from_qvel(imp.joints, qpos, qvel))
        assert abs(fw.accelerations[0] - d.qacc[0]) < TOL_MJCF * max(1.0, abs(d.qacc[0]))


def test_mjcf_passive_elements_enter_the_reference():
    """The pendulum's spring, damper and armature change its acceleration (they are read)."""
    model = imported("pendulum_hinge").model
    assert model.potential != 0 and model.loads and not model.energy_conserved
    assert any(b.name.startswith("armature:") for b in model.bodies)


def test_fourbar_connect_has_a_dependent_row_and_minimum_norm_multipliers():
    imp, nm = imported("fourbar_connect"), numeric("fourbar_connect", "kane")
    assert (nm.m, nm.rank) == (3, 2)
    q, u = np.array(imp.model.initial_q), np.array(imp.model.initial_u)
    fw = nm.forward(q, u + 0.7)  # any speeds: A u = 0 is not needed for u' and lambda
    M, f, A, _b = nm.matrices(q, u + 0.7)
    assert fw.rank == 2
    np.testing.assert_allclose(M @ fw.accelerations - f, A.T @ fw.multipliers, atol=1e-10)
    # minimum norm: lambda has no component along the left null space of A
    U, _s, _ = np.linalg.svd(A)
    assert abs(U[:, 2] @ fw.multipliers) < 1e-12 * max(1.0, np.linalg.norm(fw.multipliers))
    # and equals MuJoCo's rigid minimum-norm force on the same rows (connect: the same rows)
    rigid = rigid_forward(imp.mj, q, qvel_from_rates(imp.joints, q, u + 0.7, imp.mj.nv))
    assert rigid.rank == 2
    np.testing.assert_allclose(fw.multipliers, rigid.multipliers, rtol=1e-9, atol=1e-9)


def test_fourbar_integrates_with_dependent_rows():
    """forward_fast and forward_batch take the redundant path too (integrators use them)."""
    imp, nm = imported("fourbar_connect"), numeric("fourbar_connect", "kane")
    q, u = list(imp.model.initial_q), list(imp.model.initial_u)
    ud, lam, piv = nm.forward_fast(q, u, 0.0)
    UD, _LAM, _piv = nm.forward_batch(np.array([q, q]), np.array([u, u]))
    np.testing.assert_allclose(UD[1], ud, rtol=1e-13, atol=1e-13)
    assert piv > 1e-12 and len(lam) == 3


def test_redundant_solver_refuses_contradicting_rows():
    M, f = np.eye(2), np.zeros(2)
    A = np.array([[1.0, 0.0], [2.0, 0.0]])  # the second row repeats the first ...
    ud, lam, _piv, r = redundant.solve(
        M, f, A, np.array([1.0, 2.0]), rank_expected=1, augment=False
    )
    assert r == 1 and ud[0] == pytest.approx(1.0)
    np.testing.assert_allclose(lam, np.array([1.0, 2.0]) / 5.0)  # minimum norm
    with pytest.raises(InconsistentConstraintError, match="contradict"):
        redundant.solve(M, f, A, np.array([1.0, 0.0]), rank_expected=1, augment=False)


def test_builtin_models_still_refuse_dependent_rows():
    """The unit's models keep rank(A) = m: a built-in with a repeated row is refused."""
    from dataclasses import replace

    base = get("pendulum_xy")
    twice = replace(
        base,
        name="pendulum_xy_twice",
        configuration_constraints=base.configuration_constraints * 2,
        constraint_names=("rod", "rod_again"),
    )
    with pytest.raises(RedundantConstraintError, match="rod_again"):
        NumericModel(twice)


# ---- refused files ------------------------------------------------------------------------------
def _write(tmp_path, body: str, extra: str = "", name: str = "m.xml") -> Path:
    p = tmp_path / name
    p.write_text(f"""<mujoco><default><geom contype="0" conaffinity="0"/></default>
      <worldbody><body name="b" pos="0 0 1"><joint name="j" type="hinge" axis="0 1 0"/>
      <geom name="g" size="0.1" mass="1"/>{body}</body></worldbody>{extra}</mujoco>""")
    return p


@pytest.mark.parametrize(
    "body, extra, match",
    [
        (
            '<site name="s1"/>',
            '<actuator><position name="mot" site="s1" kp="2"/></actuator>',
            "actuator 'mot' has a site transmission",
        ),
        (
            '<site name="s1"/>',
            (
                '<tendon><fixed name="ten" stiffness="3"><joint joint="j" coef="1"/>'
                "</fixed></tendon>"
            ),
            "tendon 'ten'",
        ),
        ("", '<default><joint frictionloss="0.1"/></default>', "joint 'j' has dry friction"),
        ("", '<option density="1.2"/>', "fluid forces"),
    ],
)
def test_unsupported_elements_are_named(tmp_path, body, extra, match):
    p = _write(tmp_path, body, extra)
    with pytest.raises(UnsupportedModelError, match=match):
        import_mjcf(p)


def test_joint_limit_is_monitored_not_refused(tmp_path):
    """A limit acts at the end of the range only: the file is accepted and the limit watched
    (tests/test_mjcf_unilateral.py checks the states and trajectories around it)."""
    p = tmp_path / "lim.xml"
    p.write_text("""<mujoco><worldbody><body><joint name="knee" range="-1 1"/>
      <geom size=".1" contype="0" conaffinity="0"/></body></worldbody></mujoco>""")
    assert import_mjcf(p).monitor.present.joint_limits == ("knee",)


def test_malformed_and_rejected_files(tmp_path):
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><body></worldbody></mujoco>")
    with pytest.raises(ModelFileError, match=r"MuJoCo rejects the file: .*XML"):
        load_model_file(bad)
    rejected = tmp_path / "rejected.xml"
    rejected.write_text('<mujoco><worldbody><body><joint type="warp"/></body></worldbody></mujoco>')
    with pytest.raises(ModelFileError, match="warp"):
        load_model_file(rejected)
    with pytest.raises(ModelFileError, match="no such file"):
        load_model_file(tmp_path / "missing.xml")
    txt = tmp_path / "model.txt"
    txt.write_text("x")
    with pytest.raises(ModelFileError, match="unknown model file type"):
        load_model_file(txt)


def test_off_manifold_keyframe_is_refused_then_projected(tmp_path):
    text = (
        (DATA / "fourbar_connect.xml")
        .read_text()
        .replace("</mujoco>", '<keyframe><key qpos="0.1 0 0"/></keyframe></mujoco>')
    )
    p = tmp_path / "fourbar_key.xml"
    p.write_text(text)
    with pytest.raises(OffManifoldError, match=r"keyframe 0.*project=True"):
        import_mjcf(p)
    imp = import_mjcf(p, project=True)
    nm = numeric("fourbar_connect", "kane")  # same equations, so the same compiled code
    nm.check_consistent(imp.model.initial_q, imp.model.initial_u)
    assert "projected" in imp.model.geometry_note


def test_off_manifold_keyframe_velocity_is_refused(tmp_path):
    text = (
        (DATA / "fourbar_connect.xml")
        .read_text()
        .replace("</mujoco>", '<keyframe><key qpos="0 0 0" qvel="1 0 0"/></keyframe></mujoco>')
    )
    p = tmp_path / "fourbar_vel.xml"
    p.write_text(text)
    with pytest.raises(OffManifoldError, match="velocities"):
        import_mjcf(p)
    imp = import_mjcf(p, project=True)
    numeric("fourbar_connect", "kane").check_consistent(imp.model.initial_q, imp.model.initial_u)


# ---- Python model files and entry points --------------------------------------------------------
def test_python_model_file_loads_with_origin():
    ums = load_model_file(DATA / "user_mechanism.py")
    assert [u.name for u in ums] == ["tethered_mass", "driven_pendulum"]
    assert all(u.kind == "python" and u.origin == "user_mechanism.py:models()" for u in ums)
    row = describe(ums[0])
    assert row["coordinates"] == ["x", "y"] and row["origin"] == "user_mechanism.py:models()"
    xml = describe(load_model_file(DATA / "fourbar_connect.xml")[0])
    assert xml["kind"] == "mjcf" and xml["constraints"] == ["Q_x", "Q_y", "Q_z"]


@pytest.mark.parametrize(
    "source, match",
    [
        ("raise RuntimeError('boom')", "raised RuntimeError while loading: boom"),
        ("x = 1", r"defines no models\(\) function"),
        ("def models():\n    return []", "returned no models"),
        ("def models():\n    return [1]", "returned int"),
        ("def models():\n    raise KeyError('k')", r"models\(\) raised KeyError"),
    ],
)
def test_bad_python_files(tmp_path, source, match):
    p = tmp_path / "user.py"
    p.write_text(source)
    with pytest.raises(ModelFileError, match=match):
        load_model_file(p)


def test_duplicate_and_builtin_names_are_refused():
    with pytest.raises(ModelFileError, match="already used"):
        load_all([DATA / "user_mechanism.py"] * 2, entry_points=False)
    with pytest.raises(ModelFileError, match="built-in"):
        load_all([DATA / "user_mechanism.py"], entry_points=False, builtin_names=["tethered_mass"])


def test_entry_point_group_is_read(tmp_path, monkeypatch):
    """A distribution on sys.path declaring [crosscheck.models] (a real .dist-info, found by
    importlib.metadata as an installed package's would be)."""
    (tmp_path / "userpkg_models.py").write_text((DATA / "user_mechanism.py").read_text())
    info = tmp_path / "userpkg-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: userpkg\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[crosscheck.models]\nmech = userpkg_models:models\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    found = entry_point_models()
    assert [u.name for u in found] == ["tethered_mass", "driven_pendulum"]
    assert found[0].origin == "entry point crosscheck.models:mech"


def test_registered_user_model_is_found_by_get():
    from crosscheck.user_models import register_all
    from reference import models

    ums = load_model_file(DATA / "user_mechanism.py") + load_model_file(
        DATA / "double_pendulum.xml"
    )
    assert register_all(ums) == ["tethered_mass", "driven_pendulum", "double_pendulum"]
    assert models.get("driven_pendulum") is ums[1].model
    assert models.origin("driven_pendulum") == "user_mechanism.py:models()"
    assert models.origin("pendulum_angle") == "built-in"
    assert models.user_source("double_pendulum").mj.nq == 2
    assert models.user_source("pendulum_angle") is None


# ---- force elements -----------------------------------------------------------------------------
def test_spring_damper_tether_against_hand_physics():
    model = load_model_file(DATA / "user_mechanism.py")[0].model
    p = {pp.name: pp.default for pp in model.parameters}
    for form in ("lagrange", "kane"):
        nm = NumericModel(model, form)
        q, u = np.array([0.8, 0.3]), np.array([-0.4, 1.5])
        L = np.linalg.norm(q)
        e = q / L
        tension = p["k"] * (L - p["L0"]) + p["c"] * (e @ u)
        expected = -tension * e / p["m"]
        np.testing.assert_allclose(nm.forward(q, u).accelerations, expected, rtol=1e-12)


def test_joint_damper_and_timed_torque_against_hand_physics():
    model = load_model_file(DATA / "user_mechanism.py")[1].model
    p = {pp.name: pp.default for pp in model.parameters}
    I = p["m"] * p["L"] ** 2
    for form in model.formulations:
        nm = NumericModel(model, form)
        for t, th, thd in ((0.0, 0.4, 0.0), (0.7, -1.1, 2.3)):
            expected = (
                -p["m"] * p["g"] * p["L"] * np.sin(th) - p["d"] * thd + p["A"] * np.sin(p["w"] * t)
            ) / I
            got = nm.forward([th], [thd], t).accelerations[0]
            assert got == pytest.approx(expected, rel=1e-12)
        bal = nm.power_balance([0.3], [1.1], 0.5)
        assert bal["dE_dt"] == pytest.approx(bal["load_power"], rel=1e-12)


def test_force_function_must_take_sympy_symbols():
    import math

    from reference.forces import applied_torque

    with pytest.raises(Exception, match="sympy"):
        applied_torque(
            "bad",
            (0, 0, sp.Symbol("w")),
            lambda t, q, u: (0, 0, math.sin(t)),
            coordinates=(),
            speeds=(),
        )


def test_fourbar_trajectory_with_dependent_rows():
    """The integrators' projections take minimum-norm steps through the dependent row; the
    nullspace method, which needs independent rows, says so. Measured over 2 s (projection):
    residuals 7e-16 / 3e-15, energy drift 5e-9 at rtol 1e-8 (the run's tolerances)."""
    from reference.errors import ModelInputError
    from reference.integrate.driver import simulate

    imp, nm = imported("fourbar_connect"), numeric("fourbar_connect", "kane")
    tr = simulate(nm, imp.model.initial_q, imp.model.initial_u, 2.0, method="projection")
    s = tr.summary()
    assert s["residual_position"] < 1e-12 and s["residual_velocity"] < 1e-12
    assert abs(s["energy_drift"]) < 1e-7
    with pytest.raises(ModelInputError, match="independent constraint rows"):
        simulate(nm, imp.model.initial_q, imp.model.initial_u, 0.1, method="nullspace")
