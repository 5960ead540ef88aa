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

Multipliers: the reference's rows are MuJoCo's equality rows in MuJoCo's order (connect 3,
weld 6, joint 1). Where the rows are dependent (a planar loop closed by a 3-D connect) only the
generalized constraint force J^T f is unique; the engine's forces are then reported as the
minimum-norm multipliers with the same J^T f (pinv(J^T) J^T f, the reference's convention,
reference.numeric.redundant), so comparing them compares J^T f. A file with ball or free joints has
quaternion norm rows whose multipliers depend on the formulation and have no MuJoCo
counterpart: its multipliers are not compared (accelerations are).
"""

from __future__ import annotations

import mujoco
import numpy as np

from crosscheck.engines.base import EngineUnsupported
from crosscheck.engines.mujoco.engine_model import SOLIMP, SOLREF, MjEngineModel
from crosscheck.engines.mujoco.soft_recovery import dense_efc_J

JNT = mujoco.mjtJoint
# MuJoCo's constraint solver on a user's file: the built-in files' setting (machinery.document),
# so the soft solve the rigid recovery starts from is converged to round-off
SOLVER_TOLERANCE = 1e-15
SOLVER_ITERATIONS = 1000
QUATERNION_NOTE = (
    "the file has ball or free joints: their quaternion norm rows' multipliers "
    "depend on the formulation and have no MuJoCo counterpart"
)


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
        self._light_ids = []
        ref = self.imp.model
        self.nq_ref, self.n_ref = len(ref.coordinates), len(ref.speeds)
        self._quaternions = any(
            ji.type in (int(JNT.mjJNT_BALL), int(JNT.mjJNT_FREE)) for ji in self.imp.joints
        )
        self._norm_rows = sum(
            ji.type in (int(JNT.mjJNT_BALL), int(JNT.mjJNT_FREE)) for ji in self.imp.joints
        )
        self._P = None if self._quaternions else np.eye(self.m.nv)
        if self._quaternions:
            self.mass_matrix_note = (
                "quaternion coordinates: MuJoCo's speeds (local angular "
                "velocities) are not a constant linear map of the rates"
            )
        self.solver = "MuJoCo (the file's solref/solimp, Newton to 1e-15)"
        self.constrained_solve = self.m.neq > 0

    def _load_model(self):
        m = mujoco.MjModel.from_xml_path(self.imp.path)
        m.opt.tolerance = SOLVER_TOLERANCE
        m.opt.iterations = SOLVER_ITERATIONS
        m.opt.enableflags |= int(mujoco.mjtEnableBit.mjENBL_ENERGY)
        return m

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

    def _multipliers(self, qe, ve, ae, f):
        f = np.asarray(f, float)
        if f.size:
            J = dense_efc_J(self.m, self.d)
            # the minimum-norm forces with MuJoCo's J^T f: unique where rows are dependent
            f = np.linalg.pinv(J.T, rcond=1e-12) @ (J.T @ f)
        # the quaternion norm rows (last in the reference) have no MuJoCo force: zeros here,
        # and forward() withholds the multipliers of such a model
        return np.concatenate([f, np.zeros(self._norm_rows)])

    def forward(self, q, u, t: float = 0.0):
        ef = super().forward(q, u, t)
        if self._quaternions:
            ef.multipliers = ef.rigid_multipliers = ef.predicted_multiplier_error = None
            ef.multipliers_note = QUATERNION_NOTE
        ef.raw["model_file"] = self.path
        return ef

    def fingerprint(self) -> str:
        import hashlib
        from pathlib import Path

        return hashlib.sha256(Path(self.path).read_bytes()).hexdigest()
