"""Exudyn's model of a user's MJCF file: the system built from MuJoCo's compiled model
(user_system.py), answered by Exudyn's implicit solver with the Richardson extrapolation of the
built-in models (engine_model.py), mapped to the reference through MuJoCo's state
(crosscheck.engines.user_file_model).

State maps: the tree's coordinates are qpos - qpos0 and its speeds qvel (hinges and slides); a
free joint's body has MuJoCo's qpos as its coordinates (position of the body frame, Euler
parameters = MuJoCo's quaternion) and the quaternion's rates p' = p (x) (0, w) / 2 as speeds;
a ball joint's body is turned by its parent frame's fixed rotation (p = q_F (x) q). The local
angular acceleration comes back as 2 vec(p* (x) p'') (p'* (x) p' is a scalar). A ball or free
joint built as tree links (a floating base) has the free joint's position and world velocity on
its slides, and on its turns zero angles (re-based to the state's rotation) with the local
angular velocity as rates; its angular acceleration comes back as G phi'' plus the rates' terms
(euler_links.py).

Multipliers: the equalities' generalized force -C_q^T lambda (Exudyn's sign) from Exudyn's own
C_q, the connectors' analytic Jacobians (the solver's system Jacobian before and after
ComputeJacobianAE), and its multipliers, on MuJoCo's qvel through the velocity map; then the
minimum-norm multipliers with that J^T lambda. ObjectJointGeneric's multipliers are not mapped
one by one: its rotation rows' sign and axis depend on which axes are constrained. A state
where the rows kept at the initial state (user_system.py) lost the rank of the file's rows is
refused with the figures, as is a state where Exudyn's KKT matrix is singular (its
initial-acceleration solve then falls back to zero accelerations).
"""

from __future__ import annotations

import exudyn as exu
import numpy as np

from crosscheck.engines.base import EngineForward, EngineUnsupported
from crosscheck.engines.compiled_model import mat_quat, quat_conj, quat_matrix, quat_mul
from crosscheck.engines.exudyn.engine_model import ExudynModel
from crosscheck.engines.exudyn.euler_links import (
    euler_columns,
    euler_rotation,
    euler_velocity_terms,
)
from crosscheck.engines.exudyn.trajectory import quiet
from crosscheck.engines.exudyn.user_system import SystemBuilder, rank_of, refusals
from crosscheck.engines.user_file_model import (
    QUATERNION_MASS,
    Frame,
    MultiplierAnswer,
    UserFileMaps,
)

__all__ = ["BUILT_FROM", "ExudynUserFile"]

BUILT_FROM = "Exudyn model built from MuJoCo's compiled model"
INIT = exu.ConfigurationType.Initial
OUT = exu.OutputVariableType


class ExudynUserFile(SystemBuilder, UserFileMaps, ExudynModel):
    """Exudyn's model of a user's MJCF file (see the module docstring)."""

    def __init__(self, model_name: str, params: dict | None = None, simulation: bool = False):
        self.model_name = model_name
        self._load(model_name, params)
        refused = refusals(self.cm)
        if refused:
            raise EngineUnsupported(
                f"{model_name}: Exudyn's model of the file: " + "; ".join(refused)
            )
        self.gravity = tuple(float(g) for g in self.cm.gravity)
        self.mass_matrix_note = QUATERNION_MASS
        ExudynModel.__init__(self, model_name, dict(params or {}), simulation)
        self.constrained_solve = bool(self.cm.equalities)
        sd = self.mbs.systemData
        self._eq_ae = [int(i) for obj in self.eq_objects for i in sd.GetObjectLTGAE(obj)]

    # ---- state maps: MuJoCo's (qpos, qvel) <-> Exudyn's coordinates -----------------------
    def _slots(self, node: int) -> list[int]:
        return list(self.mbs.systemData.GetNodeLTGODE2(node))

    @staticmethod
    def _euler_slots(slots, first: int) -> list[int]:
        """A tree ball or free joint's coordinates: the three slides' (free) and the turns'."""
        return [slots[k] for k in range(max(first - 3, 0), first + 3)][-6:]

    def _engine_state(self, qpos, qvel) -> tuple[np.ndarray, np.ndarray]:
        n = self.mbs.systemData.ODE2Size()
        qe, ve = np.zeros(n), np.zeros(n)
        if self.links:
            slots = self._slots(self.tree_node)
            for k, lk in enumerate(self.links):
                jt = self.cm.joint(lk.joint)
                if jt.kind in ("hinge", "slide"):
                    qe[slots[k]], ve[slots[k]] = qpos[jt.qposadr] - jt.qpos0, qvel[jt.dofadr]
            for j, first in self.euler.items():
                joint, at = self.cm.joint(j), self._euler_slots(slots, first[0])
                a, d = joint.qposadr, joint.dofadr
                if joint.kind == "free":
                    qe[at[:3]], ve[at[:3]] = qpos[a : a + 3], qvel[d : d + 3]
                    a, d = a + 3, d + 3
                self.rebase(j, quat_matrix(qpos[a : a + 4]))  # the angles are zero here
                ve[at[-3:]] = qvel[d : d + 3]  # G(0) = I
        for j, (node, _, _) in self.ep.items():
            joint, slots = self.cm.joint(j), self._slots(node)
            a, d = joint.qposadr, joint.dofadr
            if joint.kind == "free":
                pos, quat = qpos[a : a + 3], qpos[a + 3 : a + 7]
                vel, w = qvel[d : d + 3], qvel[d + 3 : d + 6]
            else:  # ball: the body's world pose from its parent frame's (fixed)
                RF, pF = self.ball_frames[j]
                quat = quat_mul(mat_quat(RF), qpos[a : a + 4])
                R, w = quat_matrix(quat), qvel[d : d + 3]
                pos = pF + RF @ joint.anchor - R @ joint.anchor
                vel = -R @ np.cross(w, joint.anchor)
            qe[slots] = np.concatenate([pos, quat])
            ve[slots] = np.concatenate([vel, 0.5 * quat_mul(quat, [0.0, *w])])
        return qe, ve

    def _mj_state(self, qe, ve) -> tuple[np.ndarray, np.ndarray]:
        qe, ve = np.asarray(qe, float), np.asarray(ve, float)
        qpos, qvel = np.zeros(self.cm.nq), np.zeros(self.cm.nv)
        if self.links:
            slots = self._slots(self.tree_node)
            for k, lk in enumerate(self.links):
                jt = self.cm.joint(lk.joint)
                if jt.kind in ("hinge", "slide"):
                    qpos[jt.qposadr], qvel[jt.dofadr] = qe[slots[k]] + jt.qpos0, ve[slots[k]]
            for j, first in self.euler.items():
                joint, at = self.cm.joint(j), self._euler_slots(slots, first[0])
                a, d = joint.qposadr, joint.dofadr
                if joint.kind == "free":
                    qpos[a : a + 3], qvel[d : d + 3] = qe[at[:3]], ve[at[:3]]
                    a, d = a + 3, d + 3
                phi = qe[at[-3:]]
                qpos[a : a + 4] = mat_quat(self.euler_base[j] @ euler_rotation(phi))
                qvel[d : d + 3] = euler_columns(phi) @ ve[at[-3:]]
        for j, (node, _, _) in self.ep.items():
            joint, slots = self.cm.joint(j), self._slots(node)
            a, d = joint.qposadr, joint.dofadr
            pos, quat, quat_t = qe[slots][:3], qe[slots][3:], ve[slots][3:]
            w = 2.0 * quat_mul(quat_conj(quat), quat_t)[1:]
            if joint.kind == "free":
                qpos[a : a + 7] = np.concatenate([pos, quat])
                qvel[d : d + 6] = np.concatenate([ve[slots][:3], w])
            else:
                qpos[a : a + 4] = quat_mul(quat_conj(mat_quat(self.ball_frames[j][0])), quat)
                qvel[d : d + 3] = w
        return qpos, qvel

    def _qacc(self, qe, ve, ae) -> np.ndarray:
        """MuJoCo's qacc from Exudyn's accelerations: the tree's as they are; a rigid body's
        local angular acceleration 2 vec(p* (x) p'') (p'* (x) p' is a scalar), its position's
        acceleration in world axes."""
        qacc = np.zeros(self.cm.nv)
        if self.links:
            slots = self._slots(self.tree_node)
            for k, lk in enumerate(self.links):
                if self.cm.joint(lk.joint).kind in ("hinge", "slide"):
                    qacc[self.cm.joint(lk.joint).dofadr] = ae[slots[k]]
            for j, first in self.euler.items():
                joint, at = self.cm.joint(j), self._euler_slots(slots, first[0])
                d = joint.dofadr
                if joint.kind == "free":
                    qacc[d : d + 3] = ae[at[:3]]
                    d += 3
                phi, phid = qe[at[-3:]], ve[at[-3:]]
                qacc[d : d + 3] = euler_columns(phi) @ ae[at[-3:]] + euler_velocity_terms(phi, phid)
        for j, (node, _, _) in self.ep.items():
            joint, slots = self.cm.joint(j), self._slots(node)
            alpha = 2.0 * quat_mul(quat_conj(qe[slots][3:]), ae[slots][3:])[1:]
            d = joint.dofadr
            if joint.kind == "free":
                qacc[d : d + 3] = ae[slots][:3]
                d += 3
            qacc[d : d + 3] = alpha
        return qacc

    def _acc_to_reference(self, qe, ve, ae):
        qpos, qvel = self.recall(qe, *self._mj_state(qe, ve))
        return self.reference_accelerations(
            qpos, qvel, self._qacc(np.asarray(qe), np.asarray(ve), np.asarray(ae))
        )

    # ---- kinematics, rows, multipliers ---------------------------------------------------
    def _set_coordinates(self, qe, ve) -> None:
        sd = self.mbs.systemData
        ref = np.asarray(sd.GetODE2Coordinates(configuration=exu.ConfigurationType.Reference))
        sd.SetODE2Coordinates((np.asarray(qe, float) - ref).tolist(), configuration=INIT)
        sd.SetODE2Coordinates_t(np.asarray(ve, float).tolist(), configuration=INIT)

    def _frame(self, marker: int) -> Frame:
        out = self.mbs.GetMarkerOutput
        return (
            np.asarray(out(marker, OUT.RotationMatrix, configuration=INIT)).reshape(3, 3),
            np.asarray(out(marker, OUT.Position, configuration=INIT)),
            np.asarray(out(marker, OUT.AngularVelocity, configuration=INIT)),
            np.asarray(out(marker, OUT.Velocity, configuration=INIT)),
        )

    def _side_frames(self, qpos, qvel) -> list[tuple[Frame, Frame]]:
        self._set_coordinates(*self._engine_state(qpos, qvel))
        return [(self._frame(m0), self._frame(m1)) for m0, m1 in self.side_markers]

    def _position_rows(self, qe, t: float) -> np.ndarray:
        """MuJoCo's equality rows and the rigid bodies' Euler-parameter norms at qe."""
        qe = np.asarray(qe, float)
        rows = [self.row_residuals(self._mj_state(qe, np.zeros_like(qe))[0])]
        rows += [
            [qe[s][3:] @ qe[s][3:] - 1.0] for s in (self._slots(n) for n, _, _ in self.ep.values())
        ]
        return np.concatenate(rows) if rows else np.zeros(0)

    def _equality_jacobian(self, qe, ve) -> np.ndarray:
        """C_q of the equalities' connectors at qe (rows: their AE coordinates, in
        ``_eq_ae`` order), Exudyn's own: the solver's system Jacobian before and after
        ComputeJacobianAE (which adds [0 C_q^T; C_q 0], the connectors' analytic Jacobians)."""
        key = np.asarray(qe, float).tobytes()
        if getattr(self, "_cq", (None,))[0] != key:
            self._set_state(qe, ve, 0.0)
            with quiet():
                self.solver.InitializeSolver(self.mbs, self.settings)  # type: ignore[call-arg,misc]
            before = np.array(self.solver.GetSystemJacobian())
            self.solver.ComputeJacobianAE(self.mbs, 1.0, 0.0, 0.0, False)
            added = np.asarray(self.solver.GetSystemJacobian()) - before
            self._cq = (key, added[self.n_engine :, : self.n_engine][self._eq_ae])
        return self._cq[1]

    def _multipliers(self, qe, ve, ae, lam_e):
        """The equalities' generalized force -C_q^T lambda (Exudyn's sign) on MuJoCo's qvel
        (power: N^T force, v_e = N qvel), then the reference's terms; a state where the kept
        rows lost the full rows' rank is refused."""
        qpos, _ = self.recall(qe, *self._mj_state(qe, ve))
        force = -self._equality_jacobian(qe, ve).T @ np.asarray(lam_e, float)[self._eq_ae]
        N = self.velocity_map(qpos)
        self._answer: MultiplierAnswer = self.multiplier_answer(qpos, force=N.T @ force)
        if self.cm.rows:
            frames = self.frames_by_equality(qpos, np.zeros(self.cm.nv))
            kept = rank_of(self._engine_axes(self.rows_jacobian(qpos), frames)[self.kept])
            if kept < self._answer.rank:
                raise EngineUnsupported(
                    f"{self.model_name}: the rows Exudyn keeps (independent at the initial "
                    f"state) have rank {kept} here, the file's rows {self._answer.rank}: the "
                    "dependent directions moved"
                )
        return self._answer.multipliers

    def _engine_answer(self, qe, ve, t: float, epsilon: float):
        """ExudynModel's call, with Exudyn's console output off and its fallback refused: with
        a singular KKT matrix InitializeSolver writes zero accelerations and multipliers."""
        with quiet():
            ae, lam = super()._engine_answer(qe, ve, t, epsilon)
        if self.n_engine and not np.any(ae) and not np.any(lam):
            self.solver.ComputeODE2RHS(self.mbs)
            rhs = np.asarray(self.solver.GetSystemResidual())[: self.n_engine]
            if np.any(rhs):
                raise EngineUnsupported(
                    f"{self.model_name}: Exudyn's KKT matrix is singular at this state (its "
                    "initial-acceleration solve fell back to zero accelerations)"
                )
        return ae, lam

    def forward(self, q, u, t: float = 0.0) -> EngineForward:
        ef = super().forward(q, u, t)
        ef.raw["rows_kept"] = int(np.sum(self.kept))
        ef.raw["model_source"] = BUILT_FROM
        return self.apply_multipliers(ef, self._answer)

    def _engine_mass_matrix(self, qe) -> np.ndarray:
        """Exudyn's system mass matrix at qe (the tree's, the rigid bodies', the armature's)."""
        self._set_state(qe, np.zeros(self.n_engine), 0.0)
        with quiet():
            self.solver.InitializeSolver(self.mbs, self.settings)  # type: ignore[call-arg,misc]
        self.solver.ComputeMassMatrix(self.mbs)
        return np.array(self.solver.GetSystemMassMatrix())  # type: ignore[misc]

    def _energy_engine(self, qe, ve) -> tuple[float, float]:
        """K = v^T M v / 2 with Exudyn's mass matrix (armature included); V = -sum m g . c
        over the mass centres (markers), the bodies fixed to the world, and the joint springs'
        k (q - q_ref)^2 / 2."""
        v = np.asarray(ve, float)
        K = 0.5 * float(v @ self._engine_mass_matrix(qe) @ v)
        self._set_state(qe, ve, 0.0)
        g = np.asarray(self.gravity)
        V = self.static_potential
        for mass, marker in self.com_markers:
            V -= mass * float(
                g @ np.asarray(self.mbs.GetMarkerOutput(marker, OUT.Position, configuration=INIT))
            )
        qpos, _ = self._mj_state(qe, ve)
        for j in self.cm.joints:
            if j.kind in ("hinge", "slide") and j.stiffness:
                V += 0.5 * j.stiffness * (qpos[j.qposadr] - j.springref) ** 2
        return K, V
