"""Pinocchio 4.1.0's MJCF parser on the MuJoCo adapter's files (crosscheck/engines/mujoco/mjcf/).
Real Pinocchio and MuJoCo, no mocks. (The Pinocchio adapter's timing hook is tested in
tests/test_engine_pinocchio.py.)

The suite keeps one MJCF per model, fed to MuJoCo and to Pinocchio through its MJCF parser
where that parser is right. Here every file is parsed (pin.buildModelFromMJCF for the trees,
pin.buildModelAndLegacyConstraintsFromMJCF for the loops: RigidConstraintModels that
constraintDynamics takes), gravity is set by hand, and the parsed model's accelerations are
compared at mapped states with (a) MuJoCo on the same file (engine coordinates), (b) the
Pinocchio adapter's in-code model and (c) the reference, both in reference coordinates. Where
the parser is wrong, the failure is asserted as it is today, so that a Pinocchio upgrade that
fixes or changes it fails here and is looked at (the in-code models stay in use either way).

Coordinates of a parsed model: joints in MJCF body order with the MJCF joint names; hinges and
slides q = qpos, v = qvel; ball joints (x, y, z, w) = MuJoCo's (w, x, y, z), v = qvel (child
frame); free joints q = [p, xyzw], v = [R^T p', omega local] (MuJoCo: [p', omega local]),
their spatial acceleration a gives MuJoCo's classical qacc[0:3] = R (a_lin + omega x v_lin).

Tolerances (tests.support.scaled_error: relative to max(1, max|reference value|)):
- TOL_SAME_FILE = 1e-11: parsed Pinocchio vs MuJoCo's unconstrained mj_forward on the same
  file: the same numbers in, two algorithms (ABA vs CRB + LDL), round-off only; the 3-D double
  pendulum's small axial inertia amplifies it to ~4e-13 (docs/engines/pinocchio.md).
- TOL_RIGID = 1e-9: loops, parsed Pinocchio (exact KKT) vs the rigid answer recovered from
  MuJoCo's soft solve, whose floor is 1e-11 to 2e-10 (tests/test_engine_mujoco.py).
- TOL_INCODE = 1e-11: parsed vs the in-code Pinocchio model, and vs the reference: the MJCF
  holds light bodies of 1e-12 relative mass/inertia that the in-code model lacks (pendulum rod,
  Example 3's frame F, Exercise 6.1's slider A, Exercise 6.4's axial inertia): ~1e-12.
"""

from __future__ import annotations

import json
from functools import cache

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from crosscheck.engines.mujoco.adapter import MJCF_DIR, MujocoAdapter, mjcf
from crosscheck.engines.pinocchio.adapter import PROX_REDUNDANT, PinocchioAdapter
from reference.models import get
from reference.numeric.model import NumericModel
from tests.support import max_abs, scaled_error, states

TOL_SAME_FILE = 1e-11
TOL_RIGID = 1e-9
TOL_INCODE = 1e-11

MJ, PIN = MujocoAdapter(), PinocchioAdapter()

# (reference model, engine variant, MJCF file stem)
TREES = [
    ("pendulum_angle", None, "pendulum_angle"),
    ("slider_crank_free", None, "slider_crank_free"),
    ("double_pendulum_3d", "tree", "double_pendulum_3d_tree"),
    ("frame_bar", None, "frame_bar"),
    ("top_euler", None, "top_euler"),
    ("exercise_6_2", None, "exercise_6_2"),
    ("exercise_6_4", None, "exercise_6_4"),
]
LOOPS = [
    ("slider_crank", None, "slider_crank"),
    ("slider_crank_split", None, "slider_crank_split"),
    ("exercise_6_1", None, "exercise_6_1"),
    ("top_cartesian", None, "top_cartesian"),
]  # free body + body-based connect to world


# ---- helpers ---------------------------------------------------------------------------------
@cache
def reference(name: str) -> NumericModel:
    return NumericModel(get(name))


@cache
def engines(name: str, variant):
    return MJ.build(name, None, variant), PIN.build(name, None, variant)


def _quat_R(xyzw) -> np.ndarray:
    x, y, z, w = xyzw
    return pin.Quaternion(w, x, y, z).toRotationMatrix()


def _mj_joint(mm, pin_name: str) -> int:
    # two slides in one body parse as one JointModelComposite named "Composite_<first joint>"
    j = mujoco.mj_name2id(mm, mujoco.mjtObj.mjOBJ_JOINT, pin_name.replace("Composite_", ""))
    assert j >= 0, pin_name
    return j


def to_parsed(pm, mm, qpos, qvel):
    """MuJoCo (qpos, qvel) -> the parsed model's (q, v), joint by joint (matched by name)."""
    q, v = np.zeros(pm.nq), np.zeros(pm.nv)
    for jid in range(1, pm.njoints):
        jm, kind = pm.joints[jid], pm.joints[jid].shortname()
        j = _mj_joint(mm, pm.names[jid])
        a, b, iq, iv = mm.jnt_qposadr[j], mm.jnt_dofadr[j], jm.idx_q, jm.idx_v
        if kind == "JointModelSpherical":
            w, x, y, z = qpos[a : a + 4]
            q[iq : iq + 4] = [x, y, z, w]
            v[iv : iv + 3] = qvel[b : b + 3]
        elif kind == "JointModelFreeFlyer":
            w, x, y, z = qpos[a + 3 : a + 7]
            q[iq : iq + 3], q[iq + 3 : iq + 7] = qpos[a : a + 3], [x, y, z, w]
            v[iv : iv + 3] = _quat_R([x, y, z, w]).T @ qvel[b : b + 3]
            v[iv + 3 : iv + 6] = qvel[b + 3 : b + 6]
        else:
            q[iq : iq + jm.nq], v[iv : iv + jm.nv] = qpos[a : a + jm.nq], qvel[b : b + jm.nv]
    return q, v


def to_mujoco_acc(pm, mm, q, v, a):
    """The parsed model's accelerations in MuJoCo's qacc convention."""
    out = np.zeros(mm.nv)
    for jid in range(1, pm.njoints):
        jm, kind = pm.joints[jid], pm.joints[jid].shortname()
        b, iq, iv = mm.jnt_dofadr[_mj_joint(mm, pm.names[jid])], jm.idx_q, jm.idx_v
        if kind == "JointModelFreeFlyer":
            R = _quat_R(q[iq + 3 : iq + 7])
            out[b : b + 3] = R @ (a[iv : iv + 3] + np.cross(v[iv + 3 : iv + 6], v[iv : iv + 3]))
            out[b + 3 : b + 6] = a[iv + 3 : iv + 6]
        else:
            out[b : b + jm.nv] = a[iv : iv + jm.nv]
    return out


def to_parsed_tau(pm, mm, qfrc):
    """MuJoCo generalized forces -> the parsed model's tau (no loads on free joints here)."""
    tau = np.zeros(pm.nv)
    for jid in range(1, pm.njoints):
        jm, kind = pm.joints[jid], pm.joints[jid].shortname()
        b, iv = mm.jnt_dofadr[_mj_joint(mm, pm.names[jid])], jm.idx_v
        assert kind != "JointModelFreeFlyer" or max_abs(qfrc[b : b + 6]) == 0.0
        tau[iv : iv + jm.nv] = qfrc[b : b + jm.nv]
    return tau


@cache
def parsed(stem: str, constraints: bool):
    """The parsed model (gravity set by hand from the file's <option gravity>), its data and,
    for the loops, its RigidConstraintModels with their data (initConstraintDynamics done)."""
    path = str(MJCF_DIR / f"{stem}.xml")
    if constraints:
        pm, cms = pin.buildModelAndLegacyConstraintsFromMJCF(path)
    else:
        pm, cms = pin.buildModelFromMJCF(path), pin.StdVec_RigidConstraintModel()
    g = mujoco.MjModel.from_xml_path(path).opt.gravity
    pm.gravity = pin.Motion(np.array(g, float), np.zeros(3))
    pd = pm.createData()
    cds = pin.StdVec_RigidConstraintData()
    for c in cms:
        cds.append(c.createData())
    if len(cms):
        pin.initConstraintDynamics(pm, pd, cms, cds)
    return pm, pd, cms, cds


def _structure_matches(pm, mm):
    """Same joints (by name) and dof order as MuJoCo, nothing dropped."""
    assert pm.nv == mm.nv
    names = [mujoco.mj_id2name(mm, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(mm.njnt)]
    parsed_names = []
    for n, jm in zip(pm.names[1:], pm.joints[1:], strict=True):
        if jm.shortname() == "JointModelComposite":  # its MuJoCo joints, consecutive
            j0 = _mj_joint(mm, n)
            parsed_names += names[j0 : j0 + jm.nv]
        else:
            parsed_names.append(n)
    assert parsed_names == names


# ======================================================================================
# the parser's defaults that every use must patch
# ======================================================================================
def test_parser_ignores_option_gravity():
    """<option gravity> is ignored: a Y-up file (gravity 0 -9.81 0) and a Y-down file
    (0 +9.81 0) both parse with Pinocchio's default (0, 0, -9.81); every test here sets it by
    hand from MuJoCo's reading of the same file."""
    for stem in ("slider_crank", "exercise_6_2", "pendulum_angle"):
        pm = pin.buildModelFromMJCF(str(MJCF_DIR / f"{stem}.xml"))
        assert np.array_equal(pm.gravity.linear, [0.0, 0.0, -9.81]), stem
        assert not np.array_equal(
            mujoco.MjModel.from_xml_path(str(MJCF_DIR / f"{stem}.xml")).opt.gravity,
            [0.0, 0.0, -9.81],
        )


# ======================================================================================
# trees: buildModelFromMJCF + aba
# ======================================================================================
@pytest.mark.parametrize("name,variant,stem", TREES, ids=[t[2] for t in TREES])
def test_tree_parsed_model_agrees(name, variant, stem):
    """ABA on the parsed tree at mapped states equals MuJoCo on the same file (qacc and the
    joint-space M), the in-code Pinocchio model and the reference (reference coordinates).
    The springs and dampers (Exercises 6.2, 6.4) are passed as tau = qfrc_applied +
    qfrc_passive: the parser keeps no stiffness and aba does not apply model.damping
    (test_parser_drops_joint_springs_and_aba_ignores_damping)."""
    emj, epn = engines(name, variant)
    pm, pd, _, _ = parsed(stem, False)
    _structure_matches(pm, emj.m)
    nm = reference(name)
    for q, u in states(reference(name), 6, seed=1):
        fm = emj.forward(q, u)
        qe, ve = fm.raw["engine_q"], fm.raw["engine_v"]
        qp, vp = to_parsed(pm, emj.m, qe, ve)
        tau = to_parsed_tau(pm, emj.m, emj.d.qfrc_applied + emj.d.qfrc_passive)
        a = pin.aba(pm, pd, qp, vp, tau).copy()
        a_mj = to_mujoco_acc(pm, emj.m, qp, vp, a)
        assert scaled_error(a_mj, fm.raw["engine_accelerations"]) <= TOL_SAME_FILE, (stem, q, u)
        M = pin.crba(pm, pd, qp)  # same velocity coordinates (ball joints: local omegas)
        M = np.triu(M) + np.triu(M, 1).T
        Mmj = np.zeros((emj.m.nv, emj.m.nv))
        mujoco.mj_fullM(emj.m, emj.d, Mmj)
        assert scaled_error(M, Mmj) <= TOL_SAME_FILE, (stem, M, Mmj)
        acc_ref = emj._acc_to_reference(qe, ve, a_mj)
        assert scaled_error(acc_ref, epn.forward(q, u).accelerations) <= TOL_INCODE, (stem, q, u)
        assert scaled_error(acc_ref, nm.forward(q, u).accelerations) <= TOL_INCODE, (stem, q, u)


@pytest.mark.parametrize(
    "name,stem,joint",
    [("exercise_6_2", "exercise_6_2", "x"), ("exercise_6_4", "exercise_6_4", "theta")],
)
def test_parser_drops_joint_springs_and_aba_ignores_damping(name, stem, joint):
    """Joint stiffness is not parsed (no such field in pin.Model) and joint damping is parsed
    into model.damping but aba does not apply it: aba with tau = qfrc_applied alone differs
    from MuJoCo by exactly M^-1 qfrc_passive (-k q - c q'). If a Pinocchio upgrade applied
    model.damping (or a parsed stiffness) inside aba, the tree test above would count it twice
    and this test would fail too."""
    emj, _ = engines(name, None)
    pm, pd, _, _ = parsed(stem, False)
    j = pm.getJointId(joint)
    c = reference(name).params["c"]
    assert pm.damping[pm.joints[j].idx_v] == c and c > 0
    assert not hasattr(pm, "stiffness")
    for q, u in states(reference(name), 3, seed=2):
        fm = emj.forward(q, u)
        qp, vp = to_parsed(pm, emj.m, fm.raw["engine_q"], fm.raw["engine_v"])
        passive = to_parsed_tau(pm, emj.m, emj.d.qfrc_passive)
        assert max_abs(passive) > 1e-3
        a_loads = pin.aba(pm, pd, qp, vp, to_parsed_tau(pm, emj.m, emj.d.qfrc_applied)).copy()
        a_all = pin.aba(
            pm, pd, qp, vp, to_parsed_tau(pm, emj.m, emj.d.qfrc_applied + emj.d.qfrc_passive)
        ).copy()
        M = pin.crba(pm, pd, qp)
        M = np.triu(M) + np.triu(M, 1).T
        assert max_abs(M @ (a_all - a_loads) - passive) <= 1e-12 * (1 + max_abs(passive))
        assert (
            scaled_error(to_mujoco_acc(pm, emj.m, qp, vp, a_all), fm.raw["engine_accelerations"])
            <= TOL_SAME_FILE
        )


# ======================================================================================
# loops: buildModelAndLegacyConstraintsFromMJCF + constraintDynamics
# ======================================================================================
@pytest.mark.parametrize("name,variant,stem", LOOPS, ids=[t[2] for t in LOOPS])
def test_loop_parsed_model_agrees(name, variant, stem):
    """The parsed connects are CONTACT_3D RigidConstraintModels in the LOCAL frame (not the
    in-code models' LOCAL_WORLD_ALIGNED), with MuJoCo's body1/site1 as joint1, so
    contact_force rotated by the joint1 anchor's rotation is MuJoCo's efc_force (the force on
    body1 at the anchor, world). constraintDynamics (PROX_REDUNDANT: the planar loops' z row
    is zero) on the parsed model equals MuJoCo's rigid recovery, the in-code Pinocchio model
    and the reference, accelerations and multipliers."""
    emj, epn = engines(name, variant)
    pm, pd, cms, cds = parsed(stem, True)
    _structure_matches(pm, emj.m)
    assert len(cms) == emj.m.neq == 1
    assert cms[0].type == pin.ContactType.CONTACT_3D
    assert cms[0].reference_frame == pin.ReferenceFrame.LOCAL
    nm = reference(name)
    prox = pin.ProximalSettings(*PROX_REDUNDANT)
    for q, u in states(reference(name), 6, seed=3):
        fm = emj.forward(q, u)
        qe, ve = fm.raw["engine_q"], fm.raw["engine_v"]
        qp, vp = to_parsed(pm, emj.m, qe, ve)
        tau = to_parsed_tau(pm, emj.m, emj.d.qfrc_applied + emj.d.qfrc_passive)
        a = pin.constraintDynamics(pm, pd, qp, vp, tau, cms, cds, prox).copy()
        assert prox.iter < PROX_REDUNDANT[2]
        pin.forwardKinematics(pm, pd, qp)
        c = cms[0]
        R1 = (pd.oMi[c.joint1_id] * c.joint1_placement).rotation
        f_world = R1 @ cds[0].contact_force.linear
        a_mj = to_mujoco_acc(pm, emj.m, qp, vp, a)
        assert scaled_error(a_mj, fm.raw["rigid_engine_accelerations"]) <= TOL_RIGID, (stem, q, u)
        assert scaled_error(f_world, fm.raw["rigid_engine_forces"][0:3]) <= TOL_RIGID, (stem, q, u)
        acc_ref = emj._acc_to_reference(qe, ve, a_mj)
        lam_ref = emj._multipliers(qe, ve, a_mj, f_world)
        fp, fr = epn.forward(q, u), nm.forward(q, u)
        assert scaled_error(acc_ref, fp.accelerations) <= TOL_INCODE, (stem, q, u)
        assert scaled_error(acc_ref, fr.accelerations) <= TOL_INCODE, (stem, q, u)
        assert scaled_error(lam_ref, fr.multipliers) <= TOL_INCODE, (stem, q, u)
        assert scaled_error(lam_ref, fp.multipliers) <= TOL_INCODE, (stem, q, u)


# ======================================================================================
# where the parser (or the file's form for it) is wrong: asserted as it is today
# ======================================================================================
def test_free_bodies_second_one_dropped_and_connects_silently_rebound(child):
    """double_pendulum_3d_free: MuJoCo 4.0 accepts free joints only on top-level bodies and
    Pinocchio parses only the first top-level body, so link2 is dropped (one FreeFlyer,
    nq = 7), no error. The connects come back sorted by name (A before O, the file has O
    first) and bound to the wrong joints without an error: A (link2's site -> link1's site)
    gets joint1 = 0, the universe, for the missing link2; O's world site gives joint2 = 0 with
    a placement read from uninitialized memory (values vary run to run, so only the joint ids
    are asserted; a subprocess protects pytest). In-code model kept (two FreeFlyers)."""
    path = MJCF_DIR / "double_pendulum_3d_free.xml"
    res = child.python(
        "import json, pinocchio as pin\n"
        f"m, cs = pin.buildModelAndLegacyConstraintsFromMJCF({str(path)!r})\n"
        "print(json.dumps({'nq': m.nq, 'nv': m.nv, 'names': list(m.names),\n"
        "  'joints': [j.shortname() for j in m.joints[1:]],\n"
        "  'pairs': [[c.joint1_id, c.joint2_id] for c in cs]}))\n"
    )
    assert res.returncode == 0, res.stderr
    out = json.loads(res.stdout.strip().splitlines()[-1])
    assert out == {
        "nq": 7,
        "nv": 6,
        "names": ["universe", "link1"],
        "joints": ["JointModelFreeFlyer"],
        "pairs": [[0, 1], [1, 0]],
    }
    mm = mujoco.MjModel.from_xml_path(str(path))
    assert mm.nv == 12 and mm.neq == 2  # what MuJoCo reads from the same file


def test_site_connect_to_a_world_site_crashes_the_parser(child):
    """The top as a free body held by a SITE-based connect to a world site (the form the other
    loops use) makes buildModelAndLegacyConstraintsFromMJCF crash (SIGSEGV), which is why the
    adapter's top_cartesian.xml uses a body-based connect (parsed correctly: the loop test).
    The crash is asserted in a subprocess: a fixed parser makes this test fail."""
    text = mjcf("top_cartesian")
    body_based = '<connect name="O" body1="top" anchor='
    assert body_based in text and 'site name="origin"' in text
    start = text.index(body_based)
    end = text.index("/>", start) + 2
    site_based = text[:start] + '<connect name="O" site1="O_top" site2="origin"/>' + text[end:]
    m = mujoco.MjModel.from_xml_string(site_based)  # MuJoCo takes it
    assert m.neq == 1 and m.eq_objtype[0] == mujoco.mjtObj.mjOBJ_SITE
    res = child.python(
        "import pinocchio as pin, tempfile, pathlib\n"
        "p = pathlib.Path(tempfile.mkdtemp()) / 'top.xml'\n"
        f"p.write_text({site_based!r})\n"
        "pin.buildModelAndLegacyConstraintsFromMJCF(str(p))\n"
        "print('parsed')\n"
    )
    assert res.returncode < 0 and "parsed" not in res.stdout, (res.returncode, res.stdout)


def test_light_rod_pendulum_parses_but_is_ill_conditioned_for_constraintDynamics():
    """pendulum_xy: the file's distance constraint is a light rod (1e-12 m, 1e-12 m L^2 on a
    hinge) connected to the bob, because MuJoCo's tendon equality lacks J-dot v. The parser
    reads it right (the bob's two slides become one JointModelComposite, the anchors coincide
    at consistent states), but the rod's 1e-12 inertia puts a 1e12 eigenvalue into the Delassus
    matrix J M^-1 J^T: constraintDynamics on the parsed LOCAL constraint (joint1 = the bob)
    converges in 3 iterations to an answer 1e-4 off. The in-code model keeps the textbook row
    x^2 + y^2 = L^2 through forwardDynamics (exact). Asserted: the parsed answer is off by more
    than 1e-6 relative (a better-conditioned solver in an upgrade would fail this test)."""
    emj, _ = engines("pendulum_xy", None)
    pm, pd, cms, cds = parsed("pendulum_xy", True)
    _structure_matches(pm, emj.m)
    assert [j.shortname() for j in pm.joints[1:]] == [
        "JointModelComposite",
        "JointModelRevoluteUnaligned",
    ]
    nm = reference("pendulum_xy")
    prox = pin.ProximalSettings(*PROX_REDUNDANT)
    worst = 0.0
    for q, u in states(reference("pendulum_xy"), 4, seed=4):
        qe, ve = emj.to_engine_state(q, u)
        qp, vp = to_parsed(pm, emj.m, qe, ve)
        pin.forwardKinematics(pm, pd, qp)
        c = cms[0]
        p1 = (pd.oMi[c.joint1_id] * c.joint1_placement).translation
        p2 = (pd.oMi[c.joint2_id] * c.joint2_placement).translation
        assert max_abs(p1 - p2) <= 1e-12  # the anchors are read right
        a = pin.constraintDynamics(pm, pd, qp, vp, np.zeros(pm.nv), cms, cds, prox)
        worst = max(worst, scaled_error(a[0:2], nm.forward(q, u).accelerations))
    assert worst > 1e-6, worst
