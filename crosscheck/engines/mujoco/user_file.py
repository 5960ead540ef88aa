"""MuJoCo's model of a user's MJCF file: the file as MuJoCo compiles it.

The reference model of an MJCF file (reference.mjcf.loader) is written in the file's own joint
coordinates, qpos in MuJoCo's order, so the state maps are the identity on positions; the
speeds are the coordinate rates, which equal MuJoCo's qvel on hinges and slides and map to the
local angular velocity on ball and free joints (reference.mjcf.loader.rates_from_qvel /
qvel_from_rates). The answer is MuJoCo's own soft one from mj_forward, with the rigid answer
recovered from it and the impedance prediction, exactly as for the built-in models
(machinery.MjEngineModel.forward). The file's physics is not touched (solref, solimp, timestep,
gravity, armature, springs); two numerical settings are: the constraint solver's tolerance
(1e-15, 1000 iterations, so the soft solve the recovery starts from is converged, as in the
built-in files) and the energy flag (d.energy for the energy check).

Actuators: the file's own, at the reference model's stated controls (d.ctrl; activations 0),
so MuJoCo computes their forces itself (reference.mjcf.actuators gives the same load to the
reference).

Multipliers: the reference's rows are MuJoCo's equality rows in MuJoCo's order (connect 3,
weld 6, joint 1), except a weld with torquescale 0, whose three rotation rows are zero in
MuJoCo and absent in the reference, and the sign of a weld's rotation rows, which in MuJoCo
follows the sign its relative quaternion happens to have (UserFileModel._weld_sign). Where
the rows are dependent (a planar loop closed by a 3-D connect) only the generalized constraint
force J^T f is unique; the engine's forces are then reported as the minimum-norm multipliers
with the same J^T f (pinv(J^T) J^T f, the reference's convention,
reference.numeric.redundant), so comparing them compares J^T f, which is compared too
(``constraint_forces``, in MuJoCo's speeds: the reference's A^T lambda is mapped there by H^T,
u = H qvel). A file with ball or free joints also has quaternion norm rows, last in the
reference, whose multipliers depend on the formulation and have no MuJoCo counterpart: they
alone are left out (``multiplier_rows``). The mass matrix of such a file is compared in
MuJoCo's own speeds (``mass_matrix_in_engine_speeds``).
"""

from __future__ import annotations

import mujoco
import numpy as np

from crosscheck.engines.base import EngineUnsupported
from crosscheck.engines.mujoco.engine_model import SOLIMP, SOLREF, MjEngineModel
from crosscheck.engines.mujoco.soft_recovery import dense_efc_J, full_M
from reference.mjcf.actuators import actuator_name

JNT = mujoco.mjtJoint
# MuJoCo's constraint solver on a user's file: the built-in files' setting (machinery.document),
# so the soft solve the rigid recovery starts from is converged to round-off
SOLVER_TOLERANCE = 1e-15
SOLVER_ITERATIONS = 1000
QUATERNION_NOTE = (
    "the quaternion norm rows of the file's ball and free joints are left out: their "
    "multipliers depend on the formulation and have no engine counterpart"
)
OMISSION_NOTE = (
    "MuJoCo's joint equality model: its aref has no J-dot v on joint equality rows (here "
    "{rows}: polycoef of degree 2 or more), so its soft solve aims at J qacc = 0 there, not "
    "at -J-dot v = poly''(q2) v2^2; the rigid recovery targets -J-dot v and the soft "
    "prediction keeps MuJoCo's omission: |J-dot v| up to {size:.3g} at the checked states, "
    "an acceleration error of {effect:.2g} (scaled) in MuJoCo's model that its "
    "stabilization has to pull back"
)
QUATERNION_MASS = (
    "in the engine's own speeds (angular velocities, not quaternion rates): H^T M H against "
    "the engine's M, H the map of its speeds to the reference's at the state"
)


def speed_map(joints, qpos, nv: int) -> np.ndarray:
    """H with the rates u = H qvel at qpos (reference.mjcf.loader.rates_from_qvel is linear in
    qvel); G H = I at unit quaternions."""
    from reference.mjcf.loader import rates_from_qvel

    return np.column_stack([rates_from_qvel(joints, qpos, e) for e in np.eye(nv)])


def equality_rows(imp) -> tuple[int, ...]:
    """The reference's rows that have engine counterparts: all but the quaternion norm rows
    (last in the reference's rows)."""
    norms = {name for name, _why in imp.model.formulation_dependent_rows}
    return tuple(i for i, n in enumerate(imp.model.constraint_names) if n not in norms)


def user_import(model_name: str):
    """The MJCF import of a registered user model, or EngineUnsupported saying why not."""
    from reference import models

    if model_name not in models.user_names():
        raise EngineUnsupported(f"{model_name!r} is not a user model")
    src = models.user_source(model_name)
    if src is None or not hasattr(src, "mj"):
        raise EngineUnsupported(
            f"{model_name} comes from {models.origin(model_name)}, a Python model: the engines "
            "check MJCF files (MuJoCo compiles the file, and Pinocchio's, Exudyn's and "
            "OpenSim's models of it are built from MuJoCo's compiled model); write the "
            "mechanism as MJCF to check it in them"
        )
    return src


def _quat_mul(a, b) -> np.ndarray:
    out = np.zeros(4)
    mujoco.mju_mulQuat(out, np.asarray(a, float), np.asarray(b, float))
    return out


def rate_derivatives(joints, qpos, qvel, qacc) -> np.ndarray:
    """The reference's u' (second derivatives of the coordinates) from MuJoCo's qacc: identity
    on hinges and slides; for a quaternion q with local omega, q' = q (x) (0, w) / 2 and
    q'' = (q' (x) (0, w) + q (x) (0, w')) / 2 (affine in qacc at a state)."""
    out = np.zeros(len(qpos))
    for ji in joints:
        a, d = ji.qposadr, ji.dofadr
        if ji.type in (int(JNT.mjJNT_HINGE), int(JNT.mjJNT_SLIDE)):
            out[a] = qacc[d]
            continue
        if ji.type == int(JNT.mjJNT_FREE):
            out[a : a + 3] = qacc[d : d + 3]
            a, d = a + 3, d + 3
        q = np.asarray(qpos[a : a + 4], float)
        w, wd = np.array([0.0, *qvel[d : d + 3]]), np.array([0.0, *qacc[d : d + 3]])
        qd = 0.5 * _quat_mul(q, w)
        out[a : a + 4] = 0.5 * (_quat_mul(qd, w) + _quat_mul(q, wd))
    return out


class UserFileModel(MjEngineModel):
    """MuJoCo's compiled model of a user's MJCF file, identity state maps (see the module)."""

    equilibrate_rows = True  # a weld with a tiny torquescale, or none (zero rows)
    remove_stabilization = True  # a stiff solref (1e-4 s) amplifies the residuals' round-off

    def __init__(self, model_name: str, params: dict | None = None, solref=SOLREF, solimp=SOLIMP):
        self.model_name = model_name
        self.params = dict(params or {})
        self.imp = user_import(model_name)
        self.solref, self.solimp = (), ()  # the file's own, per equality (eq_solref/eq_solimp)
        self.m = self._fresh_model()
        self.d = mujoco.MjData(self.m)
        self.xml = ""  # the file itself is the model: `path`
        self.path = self.imp.path
        self.soft_constraints = self.m.neq > 0
        self.applied = np.zeros(self.m.nv)
        controls = self.imp.actuation.controls
        self.ctrl = np.array(
            [controls.get(actuator_name(self.m, a), 0.0) for a in range(self.m.nu)], float
        )
        self._light_ids = []
        ref = self.imp.model
        self.nq_ref, self.n_ref = len(ref.coordinates), len(ref.speeds)
        self._quaternions = any(
            ji.type in (int(JNT.mjJNT_BALL), int(JNT.mjJNT_FREE)) for ji in self.imp.joints
        )
        self._rows = equality_rows(self.imp)
        self._m_ref = len(ref.constraint_names)
        self._P = None if self._quaternions else np.eye(self.m.nv)
        self.solver = "MuJoCo (the file's solref/solimp, Newton to 1e-15)"
        self.constrained_solve = self.m.neq > 0
        # over this model's forward calls: the equalities whose J-dot v MuJoCo's aref left
        # out (soft_recovery.omitted_jdot_v), its largest size and its largest effect
        self.omitted_rows: set[str] = set()
        self.omitted_max = self.omission_effect_max = 0.0

    def _load_model(self):
        m = mujoco.MjModel.from_xml_path(self.imp.path)
        m.opt.tolerance = SOLVER_TOLERANCE
        m.opt.iterations = SOLVER_ITERATIONS
        m.opt.enableflags |= int(mujoco.mjtEnableBit.mjENBL_ENERGY)
        return m

    def _set(self, qe, ve, m=None, d=None):
        super()._set(qe, ve, m, d)
        d = d or self.d
        d.ctrl[:] = self.ctrl  # the stated controls; activations start (and stay) at 0
        d.act[:] = 0.0

    def to_engine_state(self, q, u):
        from reference.mjcf.loader import qvel_from_rates

        q = np.asarray(q, float)
        return q.copy(), qvel_from_rates(self.imp.joints, q, np.asarray(u, float), self.m.nv)

    def from_engine_state(self, qe, ve):
        from reference.mjcf.loader import rates_from_qvel

        qe = np.asarray(qe, float)
        return qe.copy(), rates_from_qvel(self.imp.joints, qe, np.asarray(ve, float))

    def _acc_to_reference(self, qe, ve, ae) -> np.ndarray:
        return rate_derivatives(self.imp.joints, qe, ve, ae)

    def _weld_sign(self, e: int) -> float:
        """The sign of MuJoCo's rotation rows of weld e at the state in self.d: it takes the
        vector part of conj(q2) q1 relpose, which at a consistent state is +1 or -1 as a
        quaternion (q and -q are one rotation), and its Jacobian flips with it; the reference's
        rows, vee(E - E^T)/4, have no such sign."""
        m, d = self.m, self.d
        q1, q2 = np.zeros(4), np.zeros(4)
        if m.eq_objtype[e] == mujoco.mjtObj.mjOBJ_SITE:
            for out, site in ((q1, m.eq_obj1id[e]), (q2, m.eq_obj2id[e])):
                mujoco.mju_mulQuat(out, d.xquat[m.site_bodyid[site]], m.site_quat[site])
        else:
            mujoco.mju_mulQuat(q1, d.xquat[m.eq_obj1id[e]], m.eq_data[e, 6:10])
            q2[:] = d.xquat[m.eq_obj2id[e]]
        conj, rel = np.zeros(4), np.zeros(4)
        mujoco.mju_negQuat(conj, q2)
        mujoco.mju_mulQuat(rel, conj, q1)
        return -1.0 if rel[0] < 0 else 1.0

    def _reference_efc_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """The efc rows (of the state in self.d) answering the reference's equality rows, in
        order, and the sign of each: every row of each active equality, but only the position
        rows of a weld with torquescale 0 (its rotation rows are zero), a weld's rotation rows
        with _weld_sign."""
        m, d = self.m, self.d
        kind = np.asarray(d.efc_type[: d.nefc])
        ids = np.asarray(d.efc_id[: d.nefc])
        out, signs = [], []
        for e in range(m.neq):
            rows = np.flatnonzero((kind == mujoco.mjtConstraint.mjCNSTR_EQUALITY) & (ids == e))
            sign = np.ones(len(rows))
            if m.eq_type[e] == mujoco.mjtEq.mjEQ_WELD and rows.size:
                if float(m.eq_data[e, 10]) == 0.0:
                    rows, sign = rows[:3], sign[:3]
                else:
                    sign[3:] = self._weld_sign(e)
            out.extend(rows.tolist())
            signs.extend(sign.tolist())
        return np.asarray(out, int), np.asarray(signs, float)

    def _multipliers(self, qe, ve, ae, f):
        f = np.asarray(f, float)
        out = np.zeros(self._m_ref)  # the quaternion norm rows: no MuJoCo force (left out)
        if f.size:
            J = dense_efc_J(self.m, self.d)
            # the minimum-norm forces with MuJoCo's J^T f: unique where rows are dependent
            f = np.linalg.pinv(J.T, rcond=1e-12) @ (J.T @ f)
            rows, signs = self._reference_efc_rows()
            out[list(self._rows)] = signs * f[rows]
        return out

    def _generalized(self, forces) -> np.ndarray | None:
        """J^T f in MuJoCo's speeds, from its J at the state in self.d."""
        if forces is None or not np.size(forces):
            return None
        return dense_efc_J(self.m, self.d).T @ np.asarray(forces, float)

    def _note_omission(self, raw) -> None:
        """Keep the size of the J-dot v MuJoCo's aref left out at this state (joint rows)."""
        omitted = np.asarray(raw.get("aref_omitted_jdot_v", ()), float)
        if not np.any(omitted):
            return
        for i in np.flatnonzero(omitted):
            e = int(self.d.efc_id[i])
            name = mujoco.mj_id2name(self.m, mujoco.mjtObj.mjOBJ_EQUALITY, e)
            self.omitted_rows.add(name or f"equality {e}")
        self.omitted_max = max(self.omitted_max, float(np.max(np.abs(omitted))))
        self.omission_effect_max = max(self.omission_effect_max, raw["aref_omission_effect"])

    def omission_note(self) -> str:
        """What the soft records add where MuJoCo's aref left a joint equality's J-dot v out
        at the states seen ("" where it did not)."""
        if not self.omitted_rows:
            return ""
        return OMISSION_NOTE.format(
            rows=", ".join(sorted(self.omitted_rows)),
            size=self.omitted_max,
            effect=self.omission_effect_max,
        )

    def forward(self, q, u, t: float = 0.0):
        ef = super().forward(q, u, t)
        self._note_omission(ef.raw)
        qe = ef.raw["engine_q"]
        ef.constraint_forces = self._generalized(ef.raw.get("engine_forces"))
        ef.rigid_constraint_forces = self._generalized(ef.raw.get("rigid_engine_forces"))
        ef.speed_map = speed_map(self.imp.joints, qe, self.m.nv)
        if self._quaternions:
            ef.multiplier_rows = self._rows
            ef.multipliers_note = QUATERNION_NOTE
        ef.raw["model_file"] = self.path
        return ef

    def mass_matrix_in_engine_speeds(self, q):
        """MuJoCo's M (mj_fullM) and H (u = H qvel), for a file with quaternions."""
        if not self._quaternions:
            return None
        qe, ve = self.to_engine_state(q, np.zeros(self.n_ref))
        self._set(qe, ve)
        mujoco.mj_forward(self.m, self.d)
        return full_M(self.m, self.d), speed_map(self.imp.joints, qe, self.m.nv)

    def fingerprint(self) -> str:
        """SHA-256 of the file and the stated controls."""
        import hashlib
        from pathlib import Path

        h = hashlib.sha256(Path(self.path).read_bytes())
        h.update(self.ctrl.tobytes())
        return h.hexdigest()
