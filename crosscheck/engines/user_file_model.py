"""What the Exudyn and OpenSim models of a user's MJCF file share: MuJoCo's state as the
engine-neutral one, the file's equality rows evaluated with the engine's own kinematics, and
the multipliers and generalized constraint forces in the reference's convention.

States. The reference model of a file (reference.mjcf.loader) is written in MuJoCo's qpos with
the coordinate rates as speeds; its state maps to MuJoCo's (qpos, qvel) and back through the
loader's own maps (``qvel_from_rates``, ``rates_from_qvel``), and an engine's accelerations,
mapped to MuJoCo's qacc, become the reference's u' through ``rate_derivatives`` (the
quaternion rates' second derivatives) at the reference's own qpos (a quaternion read back from
an engine's rotation may come back as its opposite, which encodes the same rotation but
flips the rates).

Rows. The reference's constraint rows are MuJoCo's equality rows in MuJoCo's order (connect:
p1 - p2 in world axes, 3 rows; weld: the same and, with torquescale ts, ts/2 R2^T (w1 - w2) at
the manifold, the rotation rows' rate; none for ts = 0; joint: q1 - q1_0 - poly(q2 - q2_0)),
then one quaternion-norm row per ball or free joint. Each engine gives the world pose and
motion of the two frames of every connect and weld from its own kinematics
(``_side_frames``); the rows' values, their rates and their Jacobian J in MuJoCo's qvel follow
here, never from MuJoCo or the reference.

Multipliers. Each engine gives the equalities' generalized constraint force on MuJoCo's qvel
from its own Jacobian and multipliers (never per-connector conventions). The multipliers of
MuJoCo's rows are the minimum-norm lambda with that J^T lambda (pinv of J^T): unique where the
rows are independent, the reference's convention where they are dependent (a planar loop closed
by a 3-D connect; reference.numeric.redundant). J^T lambda itself is the generalized constraint
force (EngineForward.constraint_forces, on qvel with H: u = H qvel, so the reference's A^T
lambda is compared as H^T A^T lambda, which drops the component along each quaternion that
its norm row's multiplier absorbs). The quaternion-norm rows have no engine force: their
multipliers (which depend on the formulation) are left out. The mass matrix is compared the
same way: N^T M_e N on qvel (v_e = N qvel), in the reference's speeds where they are qvel
(hinges and slides), else through H.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from crosscheck.engines.base import EngineForward, EngineUnsupported
from crosscheck.engines.compiled_model import CompiledModel, Equality, describe

__all__ = [
    "NORM_ROWS_NOTE",
    "QUATERNION_MASS",
    "RANK_RTOL",
    "Frame",
    "MultiplierAnswer",
    "UserFileMaps",
]

# Singular values of J below this times the largest are a dependent direction: the four-bar's
# out-of-plane direction is ~1e-17 of the others, the test files' independent ones above 1e-3
# (the rank cut Pinocchio's model of a file uses, crosscheck.engines.pinocchio.user_file)
RANK_RTOL = 1e-10
NORM_ROWS_NOTE = (
    "the quaternion norm rows of the file's ball and free joints are left out: their "
    "multipliers depend on the formulation and have no engine counterpart"
)
# where mass_matrix gives None: the file's quaternion coordinates
QUATERNION_MASS = (
    "quaternion coordinates: the engine's M is compared on MuJoCo's qvel, H^T M H with the "
    "reference's speeds u = H qvel (mass_matrix_in_engine_speeds)"
)

# (R, p, w, v): a frame's world rotation and origin, angular velocity and origin velocity
Frame = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


@dataclass
class MultiplierAnswer:
    """An engine's constraint forces in the reference's terms at one state: the multipliers
    of every reference row (the quaternion-norm rows' 0 and not answered), the rows answered
    (None: all), the generalized constraint force J^T lambda on MuJoCo's qvel with H (the
    reference's speeds u = H qvel, EngineForward.speed_map), the rows' rank and
    max |J^T lambda - force| (the engine's force outside the rows' span)."""

    multipliers: np.ndarray | None
    rows: tuple[int, ...] | None
    constraint_forces: np.ndarray | None
    speed_map: np.ndarray | None
    rank: int
    residual: float


def _vee(E: np.ndarray) -> np.ndarray:
    """vee((E - E^T) / 4): the reference's weld rotation residual (reference.mjcf.loader)."""
    return np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]]) / 4


def _poly(c: np.ndarray, x: float) -> tuple[float, float]:
    """A joint equality's polynomial and its derivative at x."""
    return (
        float(sum(c[k] * x**k for k in range(5))),
        float(sum(k * c[k] * x ** (k - 1) for k in range(1, 5))),
    )


def _rank(s: np.ndarray) -> int:
    return int(np.sum(s > RANK_RTOL * s[0])) if s.size and s[0] > 0 else 0


# HEAD's EngineForward may not have these fields yet: set only where it declares them
_FORWARD_FIELDS = {f.name for f in fields(EngineForward)}


class UserFileMaps:
    """Mixed into an engine's model of a user's MJCF file (before its EngineModel base): the
    state maps through MuJoCo's (qpos, qvel), the rows, the multipliers (module docstring).
    The engine class calls ``_load`` before building and implements ``_side_frames``."""

    model_name: str
    imp: object
    cm: CompiledModel
    nominal_cm: CompiledModel

    def _load(self, model_name: str, params: dict | None) -> None:
        """The file's import and compiled model; ``params`` are the perturbed numbers of
        ``compiled_model.perturbable`` (the engine's physics), the maps read the nominal ones."""
        from crosscheck.engines.mujoco.user_file import user_import

        self.imp = imp = user_import(model_name)
        m, path = imp.mj, imp.path  # type: ignore[attr-defined]
        actuation = getattr(imp, "actuation", None)
        self.cm = describe(m, path, params, actuation)
        self.nominal_cm = describe(m, path, None, actuation)
        ref = imp.model  # type: ignore[attr-defined]
        self.nq_ref, self.n_ref = len(ref.coordinates), len(ref.speeds)
        self.norm_rows = sum(j.kind in ("ball", "free") for j in self.cm.joints)
        self.m_ref = len(ref.constraint_names or ())
        if self.m_ref != self.cm.rows + self.norm_rows:
            raise EngineUnsupported(
                f"{model_name}: the reference has {self.m_ref} constraint rows, the compiled "
                f"model's equalities {self.cm.rows} and quaternion norms {self.norm_rows}"
            )
        self._mapped: tuple | None = None

    # ---- states ----------------------------------------------------------------------------
    def mj_state(self, q, u) -> tuple[np.ndarray, np.ndarray]:
        """MuJoCo's state of a reference state.

        Parameters
        ----------
        q, u : array_like
            The reference's coordinates (MuJoCo's qpos) and rates.

        Returns
        -------
        tuple of ndarray
            (qpos, qvel).
        """
        from reference.mjcf.loader import qvel_from_rates

        q = np.asarray(q, float)
        joints = self.imp.joints  # type: ignore[attr-defined]
        return q.copy(), qvel_from_rates(joints, q, np.asarray(u, float), self.cm.nv)

    def remember(self, qpos, qvel, qe) -> None:
        """The MuJoCo state an engine state was mapped from (``recall``)."""
        self._mapped = (np.array(qe, float), np.array(qpos, float), np.array(qvel, float))

    def recall(self, qe, qpos, qvel) -> tuple[np.ndarray, np.ndarray]:
        """The MuJoCo state qe was mapped from, when it was the last one mapped, else the one
        read back (qpos, qvel): the reference's own quaternion signs where it has them."""
        if self._mapped is not None and np.array_equal(self._mapped[0], np.asarray(qe, float)):
            return self._mapped[1], self._mapped[2]
        return qpos, qvel

    def reference_state(self, qpos, qvel) -> tuple[np.ndarray, np.ndarray]:
        """The reference's state of MuJoCo's (the inverse of ``mj_state``).

        Parameters
        ----------
        qpos, qvel : array_like

        Returns
        -------
        tuple of ndarray
            (q, u).
        """
        from reference.mjcf.loader import rates_from_qvel

        qpos = np.asarray(qpos, float)
        joints = self.imp.joints  # type: ignore[attr-defined]
        return qpos.copy(), rates_from_qvel(joints, qpos, np.asarray(qvel, float))

    def reference_accelerations(self, qpos, qvel, qacc) -> np.ndarray:
        """The reference's u' from MuJoCo's qacc.

        Parameters
        ----------
        qpos, qvel : array_like
            The state, with the reference's own quaternion signs (``recall``).
        qacc : array_like

        Returns
        -------
        ndarray
        """
        from crosscheck.engines.mujoco.user_file import rate_derivatives

        joints = self.imp.joints  # type: ignore[attr-defined]
        return rate_derivatives(joints, qpos, qvel, np.asarray(qacc, float))

    def speed_map(self, qpos) -> np.ndarray:
        """H with the reference's speeds u = H qvel at qpos (the loader's map is linear in
        qvel)."""
        from reference.mjcf.loader import rates_from_qvel

        joints = self.imp.joints  # type: ignore[attr-defined]
        cols = [rates_from_qvel(joints, qpos, e) for e in np.eye(self.cm.nv)]
        return np.column_stack(cols) if cols else np.zeros((self.n_ref, 0))

    def _engine_state(self, qpos, qvel) -> tuple[np.ndarray, np.ndarray]:
        """The engine's state of MuJoCo's (qpos, qvel) (each engine's map)."""
        raise NotImplementedError

    def _mj_state(self, qe, ve) -> tuple[np.ndarray, np.ndarray]:
        """MuJoCo's (qpos, qvel) of an engine state (each engine's map)."""
        raise NotImplementedError

    def to_engine_state(self, q, u):
        """The engine's state of a reference state, through MuJoCo's (remembered: ``recall``)."""
        qpos, qvel = self.mj_state(q, u)
        qe, ve = self._engine_state(qpos, qvel)
        self.remember(qpos, qvel, qe)
        return qe, ve

    def from_engine_state(self, qe, ve):
        """The reference's state of an engine state, through MuJoCo's."""
        return self.reference_state(*self._mj_state(np.asarray(qe, float), np.asarray(ve, float)))

    def velocity_map(self, qpos) -> np.ndarray:
        """N with the engine's speeds v_e = N qvel at qpos (its map is linear in qvel)."""
        cols = [self._engine_state(qpos, e)[1] for e in np.eye(self.cm.nv)]
        return np.column_stack(cols)

    def _engine_mass_matrix(self, qe) -> np.ndarray:
        """The engine's own mass matrix in its speeds at the engine state qe."""
        raise NotImplementedError

    def qvel_mass_matrix(self, q) -> tuple[np.ndarray, np.ndarray]:
        """The engine's mass matrix on MuJoCo's qvel.

        Parameters
        ----------
        q : array_like
            A reference configuration.

        Returns
        -------
        tuple of ndarray
            (N^T M_e N, H): M_e the engine's own (kinetic energy v_e^T M_e v_e / 2 with
            v_e = N qvel), H with the reference's speeds u = H qvel.
        """
        qpos, _ = self.mj_state(q, np.zeros(self.n_ref))
        N = self.velocity_map(qpos)
        qe, _ = self._engine_state(qpos, np.zeros(self.cm.nv))
        return N.T @ self._engine_mass_matrix(qe) @ N, self.speed_map(qpos)

    def mass_matrix(self, q) -> np.ndarray | None:
        """The engine's M in the reference's speeds where they are MuJoCo's qvel (hinges and
        slides only); None with quaternions (``mass_matrix_in_engine_speeds``)."""
        return None if self.norm_rows else self.qvel_mass_matrix(q)[0]

    def mass_matrix_in_engine_speeds(self, q):
        """With quaternions: the engine's M on MuJoCo's qvel and H (u = H qvel)."""
        return self.qvel_mass_matrix(q) if self.norm_rows else None

    # ---- the rows from the engine's kinematics -----------------------------------------------
    def _side_frames(self, qpos, qvel) -> list[tuple[Frame, Frame]]:
        """Per connect and weld (in ``cm.equalities`` order, joint equalities skipped), the two
        sides' frames at MuJoCo's state, from the engine's own kinematics."""
        raise NotImplementedError

    def frames_by_equality(self, qpos, qvel) -> dict[int, tuple[Frame, Frame]]:
        """``_side_frames`` by MuJoCo equality index."""
        rigid = [e.index for e in self.cm.equalities if e.kind != "joint"]
        return dict(zip(rigid, self._side_frames(qpos, qvel), strict=True))

    def row_residuals(self, qpos) -> np.ndarray:
        """The equality rows' values at ``qpos`` (zero on the manifold)."""
        frames = self.frames_by_equality(qpos, np.zeros(self.cm.nv))
        out: list = []
        for e in self.nominal_cm.equalities:
            if e.kind == "joint":
                out.append([self._joint_row(e, qpos)[0]])
                continue
            (R1, p1, _, _), (R2, p2, _, _) = frames[e.index]
            out.append(p1 - p2)
            if e.rows == 6:
                out.append(e.torquescale * _vee(R2.T @ R1))
        return np.concatenate(out) if out else np.zeros(0)

    def row_rates(self, qpos, qvel) -> np.ndarray:
        """The equality rows' rates J qvel at (qpos, qvel) (the weld's rotation rows at the
        manifold, where the reference's and MuJoCo's rows agree)."""
        frames = self.frames_by_equality(qpos, qvel)
        out: list = []
        for e in self.nominal_cm.equalities:
            if e.kind == "joint":
                out.append([self._joint_rate(e, qpos, qvel)])
                continue
            (_, _, w1, v1), (R2, _, w2, v2) = frames[e.index]
            out.append(v1 - v2)
            if e.rows == 6:
                out.append(0.5 * e.torquescale * R2.T @ (w1 - w2))
        return np.concatenate(out) if out else np.zeros(0)

    def rows_jacobian(self, qpos) -> np.ndarray:
        """The equality rows' Jacobian on MuJoCo's qvel, from the engine's kinematics.

        Parameters
        ----------
        qpos : array_like

        Returns
        -------
        ndarray
            J (rows, nv): the rows' rates are linear in qvel, so column k is the rate at the
            unit qvel e_k (``row_rates``).
        """
        nv = self.cm.nv
        cols = [self.row_rates(qpos, e) for e in np.eye(nv)]
        return np.column_stack(cols) if cols else np.zeros((self.cm.rows, 0))

    def _joint_row(self, e: Equality, qpos) -> tuple[float, float]:
        """A joint equality's value and the derivative of its polynomial at ``qpos``."""
        assert e.polycoef is not None
        j1 = self.nominal_cm.joint(e.joints[0])
        x1 = qpos[j1.qposadr] - j1.qpos0
        if e.joints[1] < 0:
            return float(x1 - e.polycoef[0]), 0.0
        j2 = self.nominal_cm.joint(e.joints[1])
        p, dp = _poly(e.polycoef, qpos[j2.qposadr] - j2.qpos0)
        return float(x1 - p), dp

    def _joint_rate(self, e: Equality, qpos, qvel) -> float:
        rate = float(qvel[self.nominal_cm.joint(e.joints[0]).dofadr])
        if e.joints[1] >= 0:
            rate -= self._joint_row(e, qpos)[1] * qvel[self.nominal_cm.joint(e.joints[1]).dofadr]
        return rate

    # ---- multipliers -------------------------------------------------------------------------
    def multiplier_answer(self, qpos, *, lam=None, force=None) -> MultiplierAnswer:
        """The reference's multipliers and generalized constraint force from the engine's.

        Parameters
        ----------
        qpos : array_like
            MuJoCo's qpos (the reference's quaternion signs).
        lam : array_like, optional
            The engine's forces in MuJoCo's rows (any solution with its J^T lambda).
        force : array_like, optional
            Or its generalized constraint force of the equalities on MuJoCo's qvel.

        Returns
        -------
        MultiplierAnswer
            The minimum-norm lambda with that J^T lambda (singular values of J below RANK_RTOL
            of the largest cut), zeros on the quaternion-norm rows, which are not answered.
        """
        rows = tuple(range(self.cm.rows)) if self.norm_rows else None
        if not self.cm.rows:
            return MultiplierAnswer(np.zeros(self.m_ref), rows, None, None, 0, 0.0)
        J = self.rows_jacobian(qpos)
        U, s, Vt = np.linalg.svd(J, full_matrices=False)
        r = _rank(s)
        if force is None:
            force = J.T @ np.asarray(lam, float)
        force = np.asarray(force, float)
        lam = U[:, :r] @ ((Vt[:r] @ force) / s[:r])
        residual = float(np.max(np.abs(J.T @ lam - force), initial=0.0))
        full = np.zeros(self.m_ref)
        full[: self.cm.rows] = lam
        return MultiplierAnswer(full, rows, J.T @ lam, self.speed_map(qpos), r, residual)

    def apply_multipliers(self, ef: EngineForward, answer: MultiplierAnswer) -> EngineForward:
        """Put the answer on an engine's EngineForward.

        Parameters
        ----------
        ef : EngineForward
        answer : MultiplierAnswer

        Returns
        -------
        EngineForward
            With the multipliers, the rows answered, J^T lambda and H (where EngineForward
            has the fields; without ``multiplier_rows`` the multipliers of a file with
            quaternion-norm rows are withheld with the note), and raw rank and residual.
        """
        ef.raw["rank"] = answer.rank
        ef.raw["force_residual"] = answer.residual
        if answer.rows is not None and "multiplier_rows" not in _FORWARD_FIELDS:
            ef.multipliers, ef.multipliers_note = None, NORM_ROWS_NOTE
            return ef
        ef.multipliers = answer.multipliers
        if answer.rows is not None:
            ef.multipliers_note = NORM_ROWS_NOTE
        if "multiplier_rows" in _FORWARD_FIELDS:
            ef.multiplier_rows = answer.rows
        if "speed_map" in _FORWARD_FIELDS:  # J^T lambda on qvel, compared through H
            ef.constraint_forces, ef.speed_map = answer.constraint_forces, answer.speed_map
        return ef
