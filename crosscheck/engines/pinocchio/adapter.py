"""Pinocchio 4.1 adapter: the reference models built in code, solved by Pinocchio's own algorithms.

Why in code and not from the MJCF the MuJoCo adapter uses: checked file by file in
tests/test_pinocchio_mjcf.py (pin 4.1.0). With gravity set by hand (the parser ignores
``<option gravity>``: always (0, 0, -9.81)) and the springs and dampers passed as tau (joint
stiffness is not parsed; damping lands in model.damping, which aba does not apply), the parser
is right on every tree file (pendulum_angle, slider_crank_free, double_pendulum_3d_tree,
frame_bar, top_euler, exercise_6_2, exercise_6_4: aba equals MuJoCo on the same file to 1e-12
and this module's models to the files' 1e-12 light bodies) and, through
``buildModelAndLegacyConstraintsFromMJCF`` (CONTACT_3D in the LOCAL frame) and
constraintDynamics, on slider_crank, slider_crank_split, exercise_6_1 and top_cartesian
(accelerations and forces as here). It is wrong where it matters elsewhere: with two free
bodies (double_pendulum_3d_free) it parses only the first top-level body and rebinds the
connects silently (sorted by name, the missing body and a world site becoming the universe
with an uninitialized placement); a site-based connect to a world site crashes it (SIGSEGV);
and pendulum_xy's light rod, which the file needs because MuJoCo's tendon equality lacks
J-dot v, parses right but makes the Delassus matrix so ill-conditioned (1e12) that
constraintDynamics is 1e-4 off. The models stay built in code, with the textbook rows where a
file has a workaround, so nothing depends on patching a parse; the tests keep the parser
honest and fail when an upgrade changes any of the above.

Engine frames and coordinates (the maps are written out in each class's docstring):
- Planar models use the engine world with X right, Y UP, gravity (0, -g, 0), hinges about +Z.
  Models written with Y DOWN in the reference (Example 1, the moving support, Exercise 6.2) get
  y_ref = -y_engine in their maps; Example 2, Note 2 / Exercise 6.3 and Exercise 6.1 are Y up in
  both. The 3-D models use the reference's own axes (N2 up for Example 4, N3 / Z up for the
  tops and Exercise 6.4), gravity set by hand (``model.gravity``).
- Bodies that are planar bars in the reference carry only I_zz. In the engine each gets the full
  inertia of a planar lamina, diag(I_zz/2, I_zz/2, I_zz) (perpendicular-axis theorem, a valid
  rigid-body inertia). Hinges about Z and slides in X/Y never excite the in-plane components, so
  they do not change any planar answer (tests/test_engine_pinocchio.py checks this by changing
  them). 3-D bodies get exactly the reference's inertias.
- Point masses (the pendulum bob, the slider, the blocks) get NO rotational inertia: each one
  either translates on prismatic joints (the joint-space inertia is its mass) or sits off the
  axis of the hinge that carries it (m L^2 > 0), so Pinocchio never needs one and the engine
  model has exactly the reference's mass distribution. Exercise 6.4's bar keeps its zero axial
  inertia too (the disk's inertia keeps the mass matrix definite).
- Loads: constant torques/forces go to tau; springs, dampers and loads that turn with a body are
  evaluated per state (``_applied``), and the springs' potential is added to V. Only the moving
  support is rheonomic: its explicit time terms enter the constraint row; t is unused elsewhere.

Solvers (ENGINES.md section 2.3, re-verified in the tests):
- no constraints, or a minimal-coordinate tree (joint reactions from rnea): ``pin.aba``;
- rows that are not point coincidences (x^2 + y^2 = L^2, the rheonomic moving support, the
  nonholonomic knife edge): ``pin.forwardDynamics(model, data, q, v, tau, J, gamma)`` with the
  textbook row J and gamma = Jdot v + (explicit time terms), an exact KKT solve whose
  data.lambda_c has the textbook sign: M a + nle = tau + J^T lambda, J a + gamma = 0;
- point coincidences (loop closures, free bodies held at points): ``RigidConstraintModel``
  CONTACT_3D in LOCAL_WORLD_ALIGNED with ``pin.constraintDynamics``. A planar loop gives 3 rows
  of which the out-of-plane one is identically zero, so the Delassus matrix is singular and the
  plain Cholesky (mu = 0) returns NaN; ProximalSettings(1e-12, 1e-8, 50) (PROX_REDUNDANT)
  converges to the exact minimum-norm answer in 3 proximal iterations. Full-rank 3-D rows use
  the exact one-step Cholesky (PROX_EXACT). contact_force is the force that joint2's body
  applies to joint1's body at the anchor, world-oriented.
  Pinocchio's own ``prox.absolute_residual`` is NOT a KKT residual (it stays O(10) even when the
  answer is exact to 1e-15) and ``relative_residual`` after one iteration is |lambda|_inf, so
  forward() reports independent residuals: primal |J a + gamma|_inf (anchor classical
  accelerations) and dual |rnea(q, v, a, f_ext) - tau|_inf (Pinocchio's inverse dynamics with
  the constraint forces applied).

Engine variants: Example 4 and Exercise 6.7 have two engine models each ("free": free bodies
held by point constraints, the textbook's own form; "tree": ball joints, joint reactions from
rnea). ``PinocchioAdapter.variants(name)`` lists them, the first is build's default, and
``build(name, params, variant=...)`` selects one (forward's raw["variant"] says which).

Every EngineModel here also has ``mass_matrix(q)`` and ``forcing(q, u, t)`` (the reference's M
and f where the coordinates map linearly, else None), ``constraint_violation`` /
``velocity_violation`` (engine-side drift measures), ``simulate(...)`` (scipy's solve_ivp on
Pinocchio's forward dynamics in the ENGINE's coordinates) and ``timed_forward(q, u)``, the hook
``crosscheck bench`` times (the state mapped once; the callable makes only forward()'s native
Pinocchio call, shared with forward through ``_engine_call``).
"""
from __future__ import annotations

import math
import time
from typing import Optional

import numpy as np
import pinocchio as pin
from scipy.integrate import solve_ivp

from ..base import (Capabilities, EngineAdapter, EngineForward, EngineModel, EngineTrajectory,
                    EngineUnsupported)

__all__ = ["PinocchioAdapter", "PROX_REDUNDANT", "PROX_EXACT", "INTEGRATORS"]

# scipy's error-controlled integrators the trajectories use (solve_ivp methods)
INTEGRATORS = ("DOP853",)

# Proximal settings (absolute_accuracy, mu, max_iter).
# Planar loops: the out-of-plane row of a CONTACT_3D closure is zero, the Delassus matrix is
# singular; mu = 1e-8 regularizes each factorization and the proximal iterations remove its
# O(mu) bias geometrically (the 3-argument form sets absolute and relative accuracy to 1e-12:
# stop when |d lambda|_inf <= 1e-12, 3 iterations on the slider-cranks).
PROX_REDUNDANT = (1e-12, 1e-8, 50)
# Full-rank rows (the 3-D double pendulum and the top as free bodies): mu = 0 and one iteration
# is the plain Cholesky KKT solve, exact to round-off.
PROX_EXACT = (1e-12, 0.0, 1)

_Y = np.array([0.0, 1.0, 0.0])


def _lamina(I_zz: float) -> np.ndarray:
    """Full central inertia of a planar body whose reference inertia is only I_zz."""
    return np.diag([0.5 * I_zz, 0.5 * I_zz, I_zz])


def _quat_to_R(qxyzw) -> np.ndarray:
    """Rotation (local -> world) of a Pinocchio quaternion stored (x, y, z, w)."""
    x, y, z, w = qxyzw
    return pin.Quaternion(w, x, y, z).toRotationMatrix()


def _R_to_quat(R) -> np.ndarray:
    """(x, y, z, w) of a rotation matrix, Pinocchio's (Eigen's) coefficient order."""
    return pin.Quaternion(np.asarray(R, float)).coeffs().copy()


def _quat_rate(qxyzw, omega_local) -> np.ndarray:
    """d/dt of a unit quaternion (x, y, z, w) for the local angular velocity: q (x) (w, 0) / 2."""
    v, w = np.asarray(qxyzw[:3]), qxyzw[3]
    return 0.5 * np.concatenate([w * omega_local + np.cross(v, omega_local),
                                 [-(v @ omega_local)]])


def _E(e) -> np.ndarray:
    """The textbook's E(eps) (omega = 2 E eps', eps4 scalar); linear in eps."""
    e1, e2, e3, e4 = e
    return np.array([[e4, e3, -e2, -e1], [-e3, e4, e1, -e2], [e2, -e1, e4, -e3]])


def _R313(a, b, c) -> np.ndarray:
    """The textbook's 3-1-3 matrix (N components -> body components), Example 4."""
    C1, S1, C2, S2, C3, S3 = (math.cos(a), math.sin(a), math.cos(b), math.sin(b),
                              math.cos(c), math.sin(c))
    return np.array([[C1 * C3 - S1 * C2 * S3, S1 * C3 + C1 * C2 * S3, S2 * S3],
                     [-C1 * S3 - S1 * C2 * C3, -S1 * S3 + C1 * C2 * C3, S2 * C3],
                     [S1 * S2, -C1 * S2, C2]])


def _angles313(Rnb) -> np.ndarray:
    """3-1-3 angles of an N -> body matrix, on the branch theta2 in [0, pi] (the reference's
    sampler keeps theta2 in [0.3, pi - 0.3]), theta1, theta3 in (-pi, pi]."""
    b = math.acos(max(-1.0, min(1.0, Rnb[2, 2])))
    a = math.atan2(Rnb[2, 0], -Rnb[2, 1])
    c = math.atan2(Rnb[0, 2], Rnb[1, 2])
    return np.array([a, b, c])


def _prox(settings) -> pin.ProximalSettings:
    acc, mu, it = settings
    return pin.ProximalSettings(float(acc), float(mu), int(it))


class _PinModel(EngineModel):
    """Shared machinery; subclasses build the engine model and write the maps."""

    engine = "pinocchio"
    # reference coordinates (nq) and speeds (n); subclasses set them
    nq_ref: int
    n_ref: int
    solver = "aba"  # "aba" | "kkt" (forwardDynamics with J, gamma) | "constraint"
    prox_settings = PROX_REDUNDANT
    variant: Optional[str] = None
    up = np.array([0.0, 1.0, 0.0])  # engine world "up"; gravity is -g up (g = 0 if no "g")
    # why mass_matrix returns None (one sentence, shown in results), set on every such class
    mass_matrix_note: Optional[str] = None

    def __init__(self, model_name: str, params: dict[str, float]):
        self.model_name = model_name
        self.params = dict(params)
        self.model = pin.Model()
        g = float(params.get("g", 0.0))
        self.model.gravity = pin.Motion(np.concatenate([-g * self.up, np.zeros(3)]))
        self.cms = pin.StdVec_RigidConstraintModel()
        self.cds = pin.StdVec_RigidConstraintData()
        self._build()
        self.data = self.model.createData()
        if len(self.cms):
            for cm in self.cms:
                self.cds.append(cm.createData())
            pin.initConstraintDynamics(self.model, self.data, self.cms, self.cds)
        self.prox = _prox(self.prox_settings)
        self.tau = self._tau()

    # ---- hooks ---------------------------------------------------------------------------
    def _build(self) -> None:
        raise NotImplementedError

    def _tau(self) -> np.ndarray:
        return np.zeros(self.model.nv)

    def to_engine_state(self, q, u):
        raise NotImplementedError

    def from_engine_state(self, qe, ve):
        raise NotImplementedError

    def _acc_to_reference(self, qe, ve, ae) -> np.ndarray:
        raise NotImplementedError

    def _multipliers(self, qe, ve, ae, lam_engine) -> np.ndarray:
        return np.zeros(0)

    def _applied(self, qe, ve, t) -> np.ndarray:
        """Generalized applied forces tau in engine coordinates (constant unless overridden:
        springs, dampers, loads that turn with a body)."""
        return self.tau

    def _kkt_rows(self, qe, ve, t):
        """(J, gamma) for the 'kkt' solver: J a + gamma = 0 is the textbook's A u' = b."""
        raise NotImplementedError

    def _qdot(self, qe, ve) -> np.ndarray:
        """Engine coordinate rates from engine velocities: identity for hinges and slides;
        for the quaternion (x, y, z, w) of a spherical or free-flyer joint, whose velocity is
        the LOCAL angular velocity, q' = q (x) (omega, 0) / 2; the free flyer's position rate
        is R v_linear (its linear velocity is in the local frame, ENGINES.md 2.2)."""
        if self.model.nq == self.model.nv:
            return ve
        out = np.empty(self.model.nq)
        for jm in self.model.joints[1:]:
            iq, iv, kind = jm.idx_q, jm.idx_v, jm.shortname()
            if kind == "JointModelSpherical":
                out[iq:iq + 4] = _quat_rate(qe[iq:iq + 4], ve[iv:iv + 3])
            elif kind == "JointModelFreeFlyer":
                out[iq:iq + 3] = _quat_to_R(qe[iq + 3:iq + 7]) @ ve[iv:iv + 3]
                out[iq + 3:iq + 7] = _quat_rate(qe[iq + 3:iq + 7], ve[iv + 3:iv + 6])
            else:
                out[iq:iq + jm.nq] = ve[iv:iv + jm.nv]
        return out

    def _normalize(self, qe) -> np.ndarray:
        """Engine configuration on its manifold: unit quaternions (the integrator's drift of
        |q| is removed before every evaluation and in the output; |q| itself is not a
        constraint of the engine). Identity for hinges and slides."""
        if self.model.nq == self.model.nv:
            return qe
        qe = np.array(qe, float)
        for jm in self.model.joints[1:]:
            iq, kind = jm.idx_q, jm.shortname()
            if kind == "JointModelSpherical":
                qe[iq:iq + 4] /= np.linalg.norm(qe[iq:iq + 4])
            elif kind == "JointModelFreeFlyer":
                qe[iq + 3:iq + 7] /= np.linalg.norm(qe[iq + 3:iq + 7])
        return qe

    def constraint_violation(self, qe, t: float = 0.0) -> float:
        """Position-level constraint violation in the engine, in length units: the largest
        anchor mismatch of the point constraints (0 without constraints)."""
        if not len(self.cms):
            return 0.0
        pin.forwardKinematics(self.model, self.data, qe)
        worst = 0.0
        for cm in self.cms:
            p1 = self._anchor_position(cm.joint1_id, cm.joint1_placement)
            p2 = self._anchor_position(cm.joint2_id, cm.joint2_placement)
            worst = max(worst, float(np.max(np.abs(p1 - p2))))
        return worst

    # M and f in reference coordinates when q_engine = P q_ref (+ const) with P invertible
    _P: Optional[np.ndarray] = None

    # ---- engine-level dynamics -------------------------------------------------------------
    def _engine_call(self, qe, ve, t=0.0):
        """The engine's native forward call at the engine state (qe, ve) as a zero-argument
        callable; its inputs (tau, and J, gamma for the 'kkt' solver) are evaluated here, once.
        _solve and timed_forward both go through it, so the timed call is forward()'s call."""
        m, d = self.model, self.data
        tau = self._applied(qe, ve, t)
        if self.solver == "aba":
            return lambda: pin.aba(m, d, qe, ve, tau)
        if self.solver == "kkt":
            J, gamma = self._kkt_rows(qe, ve, t)
            return lambda: pin.forwardDynamics(m, d, qe, ve, tau, J, gamma)
        cms, cds, prox = self.cms, self.cds, self.prox
        return lambda: pin.constraintDynamics(m, d, qe, ve, tau, cms, cds, prox)

    def _solve(self, qe, ve, t=0.0):
        """Engine accelerations and the engine's raw constraint forces (array, maybe empty)."""
        a = self._engine_call(qe, ve, t)().copy()
        if self.solver == "aba":
            return a, np.zeros(0)
        if self.solver == "kkt":
            return a, self.data.lambda_c.copy()
        return a, np.concatenate([cd.contact_force.linear for cd in self.cds])

    def timed_forward(self, q, u, t: float = 0.0):
        """Timing hook for `crosscheck bench`: checks and maps the reference state once and
        returns a zero-argument callable that performs only forward()'s native Pinocchio call
        at that state (aba, forwardDynamics(J, gamma) or constraintDynamics, with tau and the
        rows evaluated once). It returns Pinocchio's acceleration array as the call gives it
        (it may alias data.ddq: copy it to keep it); it equals forward()'s
        raw["engine_accelerations"]. No mapping, residuals or force recovery inside."""
        q, u = self._check(q, u, t)
        qe, ve = self.to_engine_state(q, u)
        return self._engine_call(np.array(qe, float), np.array(ve, float), t)

    def _anchor_position(self, joint, placement) -> np.ndarray:
        if joint == 0:
            return placement.translation.copy()
        return (self.data.oMi[joint] * placement).translation.copy()

    def _anchor_velocity(self, joint, placement) -> np.ndarray:
        """World velocity of a point fixed in a joint frame (after forwardKinematics with v)."""
        if joint == 0:
            return np.zeros(3)
        v = placement.actInv(self.data.v[joint])
        return (self.data.oMi[joint] * placement).rotation @ v.linear

    def _anchor_classical_acc(self, joint, placement) -> np.ndarray:
        """World classical acceleration of a point fixed in a joint frame (after FK with a)."""
        if joint == 0:
            return np.zeros(3)
        v = placement.actInv(self.data.v[joint])
        a = placement.actInv(self.data.a[joint])
        acc_local = a.linear + np.cross(v.angular, v.linear)
        return (self.data.oMi[joint] * placement).rotation @ acc_local

    def _constraint_residuals(self, qe, ve, ae, lam, t=0.0):
        """Independent checks of the engine's own solve.

        primal: |J a + gamma|_inf, here the mismatch of the two anchors' classical accelerations
        (point constraints) or J a + gamma (user rows);
        dual: |rnea(q, v, a, f_ext) - tau|_inf with the constraint forces applied as external
        forces: Pinocchio's inverse dynamics must give back the applied torques.
        Returns (primal, dual, fext-augmented rnea data reaction forces computed).
        """
        m, d = self.model, self.data
        tau = self._applied(qe, ve, t)
        if self.solver == "kkt":
            J, gamma = self._kkt_rows(qe, ve, t)
            primal = float(np.max(np.abs(J @ ae + gamma)))
            tau_id = pin.rnea(m, d, qe, ve, ae)
            dual = float(np.max(np.abs(tau_id - tau - J.T @ lam)))
            return primal, dual
        pin.forwardKinematics(m, d, qe, ve, ae)
        primal = 0.0
        for cm in self.cms:
            a1 = self._anchor_classical_acc(cm.joint1_id, cm.joint1_placement)
            a2 = self._anchor_classical_acc(cm.joint2_id, cm.joint2_placement)
            primal = max(primal, float(np.max(np.abs(a1 - a2))))
        tau_id = self._rnea_with_constraint_forces(qe, ve, ae, lam)
        dual = float(np.max(np.abs(tau_id - tau)))
        return primal, dual

    def _rnea_with_constraint_forces(self, qe, ve, ae, lam) -> np.ndarray:
        """Pinocchio's inverse dynamics rnea(q, v, a, f_ext) with the point constraints' forces
        applied as external forces: lam[3k:3k+3] (contact_force of constraint k, world axes)
        on joint1's body at its anchor and its opposite on joint2's body at its anchor.
        Returns tau (a copy); afterwards data.f[i] is the wrench that body i's parent applies
        to it through joint i (local frame of joint i), i.e. the joint reactions, and
        data.oMi holds the placements at qe."""
        m, d = self.model, self.data
        pin.forwardKinematics(m, d, qe, ve, ae)
        fext = pin.StdVec_Force()
        for _ in range(m.njoints):
            fext.append(pin.Force.Zero())
        for k, cm in enumerate(self.cms):
            f = np.asarray(lam[3 * k:3 * k + 3], float)
            for joint, placement, sign in ((cm.joint1_id, cm.joint1_placement, 1.0),
                                           (cm.joint2_id, cm.joint2_placement, -1.0)):
                if joint == 0:
                    continue
                p = self._anchor_position(joint, placement)
                f_world = pin.Force(sign * f, np.cross(p, sign * f))
                fext[joint] = fext[joint] + d.oMi[joint].actInv(f_world)
        return pin.rnea(m, d, qe, ve, ae, fext).copy()

    def _spring_potential(self, qe) -> float:
        """Potential of the reference's springs in engine coordinates (0 without springs)."""
        return 0.0

    def velocity_violation(self, qe, ve, t: float = 0.0) -> float:
        """Velocity-level constraint violation in the engine: |J v + a0| of the user rows, or
        the largest anchor velocity mismatch of the point constraints (0 without constraints).
        For a nonholonomic row this is the only level at which the constraint exists."""
        if self.solver == "kkt":
            return float(np.max(np.abs(self._velocity_rows(qe, ve, t))))
        if not len(self.cms):
            return 0.0
        pin.forwardKinematics(self.model, self.data, qe, ve)
        return max(float(np.max(np.abs(
            self._anchor_velocity(cm.joint1_id, cm.joint1_placement)
            - self._anchor_velocity(cm.joint2_id, cm.joint2_placement)))) for cm in self.cms)

    def _velocity_rows(self, qe, ve, t):
        """J v + a0 for the 'kkt' solver (J from _kkt_rows; scleronomic: a0 = 0)."""
        J, _ = self._kkt_rows(qe, ve, t)
        return J @ ve

    def _energy_engine(self, qe, ve) -> tuple[float, float]:
        """Kinetic energy from Pinocchio; potential -sum m_i g . c_i computed here from the body
        positions, datum at the world origin = the reference's datum (the pivot, point A), plus
        the reference's springs (computePotentialEnergy has gravity only, same datum)."""
        m, d = self.model, self.data
        K = float(pin.computeKineticEnergy(m, d, qe, ve))
        pin.forwardKinematics(m, d, qe)
        gvec = m.gravity.linear
        V = self._spring_potential(qe)
        for i in range(1, m.njoints):
            Y = m.inertias[i]
            c = d.oMi[i].act(Y.lever)
            V -= Y.mass * float(gvec @ c)
        return K, V

    # ---- the EngineModel interface ---------------------------------------------------------
    def _check(self, q, u=None, t: float = 0.0):
        """Sizes and finiteness of a reference state, as the reference checks them."""
        from reference.errors import ModelInputError

        q = np.asarray(q, dtype=float).reshape(-1)
        if q.size != self.nq_ref:
            raise ModelInputError(f"{self.model_name} (pinocchio): expected {self.nq_ref} "
                                  f"coordinates, got {q.size}")
        if u is not None:
            u = np.asarray(u, dtype=float).reshape(-1)
            if u.size != self.n_ref:
                raise ModelInputError(f"{self.model_name} (pinocchio): expected {self.n_ref} "
                                      f"speeds, got {u.size}")
        if not (np.all(np.isfinite(q)) and (u is None or np.all(np.isfinite(u)))
                and math.isfinite(t)):
            raise ModelInputError(f"{self.model_name} (pinocchio): state contains NaN or "
                                  f"infinite values")
        return q, u

    def forward(self, q, u, t: float = 0.0) -> EngineForward:
        q, u = self._check(q, u, t)
        qe, ve = self.to_engine_state(q, u)
        ae, lam_e = self._solve(qe, ve, t)
        raw = {"engine_q": qe, "engine_v": ve, "engine_accelerations": ae,
               "engine_forces": lam_e, "solver": self.solver}
        if self.solver == "constraint":
            raw["iterations"] = int(self.prox.iter)
            raw["prox_absolute_residual"] = float(self.prox.absolute_residual)
            raw["prox_relative_residual"] = float(self.prox.relative_residual)
            raw["prox_settings"] = tuple(self.prox_settings)
        else:
            raw["iterations"] = 1 if self.solver == "kkt" else 0  # direct solve / no solve
        lam = self._multipliers(qe, ve, ae, lam_e)
        self._extra_raw(qe, ve, ae, lam_e, raw)
        if self.solver != "aba":
            raw["primal_residual"], raw["dual_residual"] = self._constraint_residuals(
                qe, ve, ae, lam_e, t)
        if self.variant is not None:
            raw["variant"] = self.variant
        return EngineForward(self._acc_to_reference(qe, ve, ae), lam, raw,
                             multipliers_note=raw.get("multipliers_note"),
                             iterations=int(raw["iterations"]))

    def _extra_raw(self, qe, ve, ae, lam_e, raw) -> None:
        pass

    @property
    def constrained_solve(self) -> bool:  # type: ignore[override]
        return self.solver != "aba"

    def energy(self, q, u) -> tuple[float, float]:
        q, u = self._check(q, u)
        qe, ve = self.to_engine_state(q, u)
        return self._energy_engine(qe, ve)

    def mass_matrix(self, q) -> Optional[np.ndarray]:
        """Engine mass matrix in reference coordinates (P^T M_e P), or None when the engine's
        coordinates are not a linear bijection of the reference's."""
        if self._P is None:
            return None
        q, _ = self._check(q)
        qe, _ = self.to_engine_state(q, np.zeros(self.n_ref))
        Me = pin.crba(self.model, self.data, qe).copy()
        Me = np.triu(Me) + np.triu(Me, 1).T  # crba fills the upper triangle
        return self._P.T @ Me @ self._P

    def forcing(self, q, u, t: float = 0.0) -> Optional[np.ndarray]:
        """The reference's f (applied generalized forces minus velocity products) from the
        engine: P^T (tau - nle), or None where the coordinates do not map linearly."""
        if self._P is None:
            return None
        q, u = self._check(q, u, t)
        qe, ve = self.to_engine_state(q, u)
        nle = pin.nonLinearEffects(self.model, self.data, qe, ve)
        return self._P.T @ (self._applied(qe, ve, t) - nle)

    def simulate(self, q0, u0, t_eval, *, integrator: str, rtol: Optional[float] = None,
                 timestep: Optional[float] = None) -> EngineTrajectory:
        """Integrate Pinocchio's forward dynamics with scipy's solve_ivp (method `integrator`,
        rtol = atol = `rtol`) in engine coordinates from t = 0 to t_eval[-1].

        The engine state is [q_e, v_e] (quaternions renormalized before every evaluation and
        in the output; their rates from the local angular velocity, see _qdot); the output is
        mapped to reference (q, u) at t_eval.

        No constraint stabilization (no projection, no Baumgarte, the RigidConstraintModel
        correctors stay 0): run for 5 s from each model's initial state, the constraint drift
        of every constrained model stayed within ~10x the integrator tolerance (tolerances 1e-8
        and 1e-10, DOP853), the index-1 drift expected from the tolerance alone, so a
        stabilization would only hide what the comparison should show. The trajectory's
        violation (position level) and velocity_violation record it per output time, energy
        the engine's K + V; wall_s is the whole call (integration and mapping).
        """
        if integrator not in INTEGRATORS:
            raise ValueError(f"unknown integrator {integrator!r}; valid: {', '.join(INTEGRATORS)}")
        if rtol is None or not rtol > 0:
            raise ValueError(f"{integrator} controls its error: give rtol > 0, got {rtol!r}")
        t_start = time.perf_counter()
        t_eval = np.asarray(t_eval, dtype=float)
        q0, u0 = self._check(q0, u0)
        qe0, ve0 = self.to_engine_state(q0, u0)
        nq = self.model.nq
        y0 = np.concatenate([qe0, ve0])

        def rhs(t, y):
            qe = self._normalize(y[:nq])
            ve = y[nq:]
            a, _ = self._solve(qe, ve, t)
            return np.concatenate([self._qdot(qe, ve), a])

        sol = solve_ivp(rhs, (0.0, float(t_eval[-1])), y0, method=integrator, rtol=rtol,
                        atol=rtol, t_eval=t_eval)
        Q, U, viol, vviol, E = [], [], [], [], []
        for t, y in zip(sol.t, sol.y.T):
            qe = self._normalize(y[:nq])
            ve = y[nq:]
            q, u = self.from_engine_state(qe, ve)
            Q.append(q)
            U.append(u)
            viol.append(self.constraint_violation(qe, t))
            vviol.append(self.velocity_violation(qe, ve, t))
            E.append(sum(self._energy_engine(qe, ve)))
        return EngineTrajectory(
            t=sol.t, q=np.array(Q), u=np.array(U), violation=np.array(viol),
            velocity_violation=np.array(vviol), energy=np.array(E), integrator=integrator,
            setting={"rtol": rtol, "atol": rtol}, wall_s=time.perf_counter() - t_start,
            steps=int(sol.nfev), failure=None if sol.success else str(sol.message),
            raw={"engine_states": sol.y.T.copy(), "stabilization": "none"})


# ======================================================================================
# Example 1: the simple pendulum (reference Y DOWN; engine Y UP)
# ======================================================================================
class _SameCoordinates:
    """Engine coordinates and speeds are the reference's, in the same order and meaning."""

    def to_engine_state(self, q, u):
        return (np.array(q, float).reshape(self.model.nq).copy(),
                np.array(u, float).reshape(self.model.nv).copy())

    def from_engine_state(self, qe, ve):
        return np.array(qe, float).copy(), np.array(ve, float).copy()

    def _acc_to_reference(self, qe, ve, ae):
        return ae.copy()


class PendulumAngle(_SameCoordinates, _PinModel):
    """Example 1(a). One hinge RZ at the origin; the bob (mass m, no inertia) at (0, -L, 0) in
    the hinge frame, so the engine angle is the reference's theta (from the downward vertical)
    with positions (L sin, -L cos) = (x_ref, -y_ref). Plain ABA; the reference has no multipliers.
    raw["rod_tension"] is the force of the pivot on the rod+bob body along the rod, read from
    rnea's data.f[1] (parent on body, local frame): local +y points from the bob to the pivot."""

    nq_ref = n_ref = 1
    solver = "aba"
    _P = np.eye(1)

    def _build(self):
        p = self.params
        j = self.model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "theta")
        self.model.appendBodyToJoint(
            j, pin.Inertia(p["m"], np.array([0.0, -p["L"], 0.0]), np.zeros((3, 3))),
            pin.SE3.Identity())

    def _extra_raw(self, qe, ve, ae, lam_e, raw):
        pin.rnea(self.model, self.data, qe, ve, ae)
        raw["rod_tension"] = float(self.data.f[1].linear @ _Y)


class PendulumXY(_PinModel):
    """Example 1(b). Slides PX (x_e) then PY (y_e) carrying the bob; y_ref = -y_e, x_ref = x_e.
    The distance constraint (x^2 + y^2 - L^2)/2 = 0 is the same function in both coordinate
    sets, so with J = [x_e, y_e] and gamma = xdot_e^2 + ydot_e^2 data.lambda_c is the textbook
    lambda itself (lambda = -T/L)."""

    nq_ref = n_ref = 2
    solver = "kkt"
    _P = np.diag([1.0, -1.0])  # q_e = P q_ref

    def _build(self):
        jx = self.model.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "x")
        jy = self.model.addJoint(jx, pin.JointModelPY(), pin.SE3.Identity(), "y")
        self.model.appendBodyToJoint(
            jy, pin.Inertia(self.params["m"], np.zeros(3), np.zeros((3, 3))), pin.SE3.Identity())

    def _kkt_rows(self, qe, ve, t):
        return qe.reshape(1, 2).copy(), np.array([ve @ ve])

    def to_engine_state(self, q, u):
        return self._P @ np.asarray(q, float), self._P @ np.asarray(u, float)

    def from_engine_state(self, qe, ve):
        return self._P @ np.asarray(qe, float), self._P @ np.asarray(ve, float)

    def _acc_to_reference(self, qe, ve, ae):
        return self._P @ ae

    def _multipliers(self, qe, ve, ae, lam_e):
        return lam_e.copy()

    def _extra_raw(self, qe, ve, ae, lam_e, raw):
        raw["rod_tension"] = float(-lam_e[0] * self.params["L"])

    def constraint_violation(self, qe, t: float = 0.0):
        """| |p| - L |: the rod's length error."""
        return abs(float(np.hypot(qe[0], qe[1])) - self.params["L"])


# ======================================================================================
# Example 2 and Note 2 / Exercise 6.3: the slider-crank (Y UP in both)
# ======================================================================================
class _SliderCrankBase(_PinModel):
    def _tau(self):
        tau = np.zeros(self.model.nv)
        tau[0] = self.params["T"]  # the crank hinge is joint 1 (q index 0) in every variant
        return tau

    def _crank(self):
        p = self.params
        j1 = self.model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "theta1")
        self.model.appendBodyToJoint(
            j1, pin.Inertia(p["m1"], np.array([p["r1"], 0.0, 0.0]), _lamina(p["I_G1"])),
            pin.SE3.Identity())
        return j1


class SliderCrankFree(_SliderCrankBase):
    """Example 2(a), the slider row removed. Crank hinge (theta1) and rod hinge at B relative to
    the crank (phi2 = theta2 - theta1); the end mass m3 is a point mass fixed on the rod at C
    (it does not turn, so lumping it into the rod body is exact). q_e = P q_ref with
    P = [[1, 0], [-1, 1]]. Plain ABA."""

    nq_ref = n_ref = 2
    solver = "aba"
    _P = np.array([[1.0, 0.0], [-1.0, 1.0]])
    _Pinv = np.array([[1.0, 0.0], [1.0, 1.0]])

    def _build(self):
        p = self.params
        j1 = self._crank()
        j2 = self.model.addJoint(j1, pin.JointModelRZ(),
                                 pin.SE3(np.eye(3), np.array([p["l1"], 0.0, 0.0])), "phi2")
        self.model.appendBodyToJoint(
            j2, pin.Inertia(p["m2"], np.array([p["r2"], 0.0, 0.0]), _lamina(p["I_G2"])),
            pin.SE3.Identity())
        self.model.appendBodyToJoint(
            j2, pin.Inertia(p["m3"], np.array([p["l2"], 0.0, 0.0]), np.zeros((3, 3))),
            pin.SE3.Identity())

    def to_engine_state(self, q, u):
        return self._P @ np.asarray(q, float), self._P @ np.asarray(u, float)

    def from_engine_state(self, qe, ve):
        return self._Pinv @ np.asarray(qe, float), self._Pinv @ np.asarray(ve, float)

    def _acc_to_reference(self, qe, ve, ae):
        return self._Pinv @ ae


class SliderCrank(_SliderCrankBase):
    """Example 2(b). Engine tree: crank hinge (theta1), rod hinge at B relative to the crank
    (phi2 = theta2 - theta1), slider on a root slide PX (x_s, the world x of C) carrying m3.
    Loop closure: CONTACT_3D at C, joint1 = rod (anchor (l2, 0, 0)), joint2 = slider (origin),
    LOCAL_WORLD_ALIGNED; rows x, y, z of which z is identically zero (ProximalSettings for a
    singular Delassus matrix, PROX_REDUNDANT).

    Force map. contact_force lambda_c is the force of the slider on the rod at C (world axes).
    The reference lumps m3 at C on the rod and its single row l1 S1 + l2 S2 = y_C = 0 makes its
    lambda the vertical force of the guide at C. In the engine the guide acts on the slider
    through the PX joint: the slider's vertical equation, with its vertical acceleration 0,
    reads N - m3 g - lambda_c,y = 0, hence

        lambda_ref = N = lambda_c,y + m3 g.

    raw["guide_force_rnea"] is N read independently from Pinocchio's rnea with the constraint
    forces applied as external forces (the y component of the PX joint's transmitted force).
    The horizontal component lambda_c,x is internal to the reference's lumped rod+m3 body.

    Coordinates: 2 reference (theta1, theta2) vs 3 engine (theta1, phi2, x_s); x_s = l1 C1 +
    l2 C2 follows from the closure, so mass_matrix/forcing return None (the reference's M also
    carries m3's vertical motion that the guide removes in the engine)."""

    nq_ref = n_ref = 2
    solver = "constraint"
    prox_settings = PROX_REDUNDANT
    mass_matrix_note = ("the engine's coordinates (theta1, phi2, x_slider) do not map one to one "
                        "onto the reference's (theta1, theta2): x_slider follows from the loop "
                        "closure, and the reference's M carries the vertical motion of m3 that "
                        "the engine's guide removes")

    def _build(self):
        p = self.params
        j1 = self._crank()
        j2 = self.model.addJoint(j1, pin.JointModelRZ(),
                                 pin.SE3(np.eye(3), np.array([p["l1"], 0.0, 0.0])), "phi2")
        self.model.appendBodyToJoint(
            j2, pin.Inertia(p["m2"], np.array([p["r2"], 0.0, 0.0]), _lamina(p["I_G2"])),
            pin.SE3.Identity())
        j3 = self.model.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "x_slider")
        self.model.appendBodyToJoint(
            j3, pin.Inertia(p["m3"], np.zeros(3), np.zeros((3, 3))), pin.SE3.Identity())
        self.j_rod, self.j_slider = j2, j3
        self.cms.append(pin.RigidConstraintModel(
            pin.ContactType.CONTACT_3D, self.model,
            j2, pin.SE3(np.eye(3), np.array([p["l2"], 0.0, 0.0])),
            j3, pin.SE3.Identity(), pin.ReferenceFrame.LOCAL_WORLD_ALIGNED))

    def to_engine_state(self, q, u):
        p = self.params
        th1, th2 = np.asarray(q, float)
        w1, w2 = np.asarray(u, float)
        xs = p["l1"] * math.cos(th1) + p["l2"] * math.cos(th2)
        xs_dot = -p["l1"] * math.sin(th1) * w1 - p["l2"] * math.sin(th2) * w2
        return np.array([th1, th2 - th1, xs]), np.array([w1, w2 - w1, xs_dot])

    def from_engine_state(self, qe, ve):
        return np.array([qe[0], qe[0] + qe[1]]), np.array([ve[0], ve[0] + ve[1]])

    def _acc_to_reference(self, qe, ve, ae):
        return np.array([ae[0], ae[0] + ae[1]])

    def _multipliers(self, qe, ve, ae, lam_e):
        return np.array([lam_e[1] + self.params["m3"] * self.params["g"]])

    def _extra_raw(self, qe, ve, ae, lam_e, raw):
        d = self.data
        self._rnea_with_constraint_forces(qe, ve, ae, lam_e)
        # transmitted force of the world on the slider through the PX joint, world axes
        N = d.oMi[self.j_slider].rotation @ d.f[self.j_slider].linear
        raw["guide_force_rnea"] = float(N[1])
        raw["force_on_rod_at_C"] = lam_e[0:3].copy()


class SliderCrankSplit(_SameCoordinates, _SliderCrankBase):
    """Note 2 / Exercise 6.3, coordinates (theta1, x, theta2) with theta2 measured from C to B
    and r2 = |C G2|. Engine tree: crank hinge (theta1), root slide PX (x) carrying m3, rod hinge
    on the slider at C (the slider does not turn, so the rod's hinge angle is the absolute
    theta2); the rod's mass center at (r2, 0, 0) in its frame. q_e = q_ref exactly.
    Loop closure at B: CONTACT_3D, joint1 = crank (anchor (l1, 0, 0)), joint2 = rod (anchor
    (l2, 0, 0)), LOCAL_WORLD_ALIGNED, rows B_crank - B_rod. The reference's rows are
    f1 = l1 C1 - l2 C2 - x and f2 = l1 S1 - l2 S2: the same difference, so (lambda1, lambda2) =
    contact_force[0:2] = the force of the rod on the crank at B; the z row is identically 0."""

    nq_ref = n_ref = 3
    solver = "constraint"
    prox_settings = PROX_REDUNDANT
    _P = np.eye(3)

    def _build(self):
        p = self.params
        j1 = self._crank()
        j2 = self.model.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "x")
        self.model.appendBodyToJoint(
            j2, pin.Inertia(p["m3"], np.zeros(3), np.zeros((3, 3))), pin.SE3.Identity())
        j3 = self.model.addJoint(j2, pin.JointModelRZ(), pin.SE3.Identity(), "theta2")
        self.model.appendBodyToJoint(
            j3, pin.Inertia(p["m2"], np.array([p["r2"], 0.0, 0.0]), _lamina(p["I_G2"])),
            pin.SE3.Identity())
        self.cms.append(pin.RigidConstraintModel(
            pin.ContactType.CONTACT_3D, self.model,
            j1, pin.SE3(np.eye(3), np.array([p["l1"], 0.0, 0.0])),
            j3, pin.SE3(np.eye(3), np.array([p["l2"], 0.0, 0.0])),
            pin.ReferenceFrame.LOCAL_WORLD_ALIGNED))

    def _multipliers(self, qe, ve, ae, lam_e):
        return lam_e[0:2].copy()


# ======================================================================================
# Example 3: rotating light frame F and bar B (no gravity)
# ======================================================================================
class FrameBar(_PinModel):
    """Example 3. Engine tree: hinge RZ (phi) carrying the light frame F (no body: F is light),
    then hinge RY (theta) about the arm n2 placed at (0, d, 0) in F, carrying the bar with its
    mass center at the joint origin and central principal inertias diag(I1, I2, I3) along the
    joint axes e1, e2 = n2, e3 (the reference's R = rot_z(phi) rot_y(theta)). No gravity.
    tau = (M_phi, M_theta): the motor on F about k and the motor on B about n2.

    Speeds: the reference's three dependent body-fixed omega components vs the engine's two
    joint rates: omega = phi' k + theta' e2 = (-S phi', theta', C phi') and, inversely,
    theta' = omega2, phi' = -S omega1 + C omega3 (exact on omega1 C + omega3 S = 0). The
    reference's u' are the bar's body-fixed angular acceleration components, read from
    Pinocchio's data.a of the bar joint (local frame = bar frame) after forwardKinematics.

    Multiplier: lambda is the n1 component of the bearing moment of the ground on F about O
    (reference docstring); rnea's data.f[1] is the wrench of the ground on F at O in F's axes
    (n1, n2, k), so lambda = data.f[1].angular[0] (its k component is the motor torque)."""

    nq_ref, n_ref = 2, 3
    solver = "aba"
    mass_matrix_note = ("the reference's three body-fixed angular velocity components are "
                        "dependent speeds (tied by omega1 C + omega3 S = 0) and do not map one "
                        "to one onto the engine's two joint rates (phi', theta')")

    def _build(self):
        p = self.params
        j1 = self.model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "phi")
        j2 = self.model.addJoint(j1, pin.JointModelRY(),
                                 pin.SE3(np.eye(3), np.array([0.0, p["d"], 0.0])), "theta")
        self.model.appendBodyToJoint(
            j2, pin.Inertia(p["m"], np.zeros(3), np.diag([p["I1"], p["I2"], p["I3"]])),
            pin.SE3.Identity())
        self.j_bar = j2

    def _tau(self):
        return np.array([self.params["M_phi"], self.params["M_theta"]])

    def to_engine_state(self, q, u):
        phi, th = np.asarray(q, float)
        w1, w2, w3 = np.asarray(u, float)
        return np.array([phi, th]), np.array([-math.sin(th) * w1 + math.cos(th) * w3, w2])

    def from_engine_state(self, qe, ve):
        th = float(qe[1])
        return (np.array(qe, float).copy(),
                np.array([-math.sin(th) * ve[0], ve[1], math.cos(th) * ve[0]]))

    def _acc_to_reference(self, qe, ve, ae):
        pin.forwardKinematics(self.model, self.data, qe, ve, ae)
        return self.data.a[self.j_bar].angular.copy()

    def _multipliers(self, qe, ve, ae, lam_e):
        pin.rnea(self.model, self.data, qe, ve, ae)
        return np.array([self.data.f[1].angular[0]])


# ======================================================================================
# Example 4: the 3-D double pendulum (N2 up in the reference and in the engine)
# ======================================================================================
def _at(x, y, z) -> pin.SE3:
    return pin.SE3(np.eye(3), np.array([x, y, z], float))


class _DoublePendulumBase(_PinModel):
    """Shared maps of Example 4. The engine world is the reference's N (X = N1, Y = N2 up,
    Z = N3), gravity (0, -g, 0). Each link's engine frame is its n_i frame, so its rotation
    (local -> world) is B_i = R313(theta_i)^T and its body-fixed omega is the reference's w_i.
    Links are full 3-D bodies here: inertias diag(I_11, I_22, I_33) exactly as the reference.

    Reference speeds u = (w1, w2, v_G1, v_G2); multipliers
    lambda = (F_O - F_A, F_A), F_O the ground's force on link 1 at O, F_A the force of link 1
    on link 2 at A (both N components; see the reference docstring and EQUATIONS.md)."""

    nq_ref, n_ref = 6, 12

    def _links(self):
        p = self.params
        return (pin.Inertia(p["m1"], np.zeros(3), np.diag([p["I1_11"], p["I1_22"], p["I1_33"]])),
                pin.Inertia(p["m2"], np.zeros(3), np.diag([p["I2_11"], p["I2_22"], p["I2_33"]])))

    def _rotations(self, q):
        q = np.asarray(q, float)
        return _R313(*q[0:3]).T, _R313(*q[3:6]).T


class DoublePendulumFree(_DoublePendulumBase):
    """Example 4 as the textbook writes it: two free bodies (FreeFlyer joints with their origin
    at G_i and axes n_i) and two point constraints, solved by constraintDynamics with the exact
    KKT (PROX_EXACT: 6 independent rows). Constraint O: joint1 = link 1 at (0, l1/2, 0),
    joint2 = the world at O; its contact_force is F_O. Constraint A: joint1 = link 2 at
    (0, l2/2, 0), joint2 = link 1 at (0, -l1/2, 0); its contact_force is the force of link 1 on
    link 2 at A = F_A. Engine velocity per link: (B^T v_G, w) (local linear velocity of the
    origin G, local omega); the engine's spatial acceleration gives
    v_G' = B (a_lin + omega x v_lin) and w' = a_ang. The speed map is linear for a fixed q,
    ve = P(q) u, so mass_matrix returns P^T M_e P; forcing is None (P depends on q)."""

    variant = "free"
    solver = "constraint"
    prox_settings = PROX_EXACT

    def _build(self):
        p = self.params
        I1, I2 = self._links()
        j1 = self.model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "link1")
        self.model.appendBodyToJoint(j1, I1, pin.SE3.Identity())
        j2 = self.model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "link2")
        self.model.appendBodyToJoint(j2, I2, pin.SE3.Identity())
        LWA, C3 = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED, pin.ContactType.CONTACT_3D
        self.cms.append(pin.RigidConstraintModel(
            C3, self.model, j1, _at(0, p["l1"] / 2, 0), 0, pin.SE3.Identity(), LWA))
        self.cms.append(pin.RigidConstraintModel(
            C3, self.model, j2, _at(0, p["l2"] / 2, 0), j1, _at(0, -p["l1"] / 2, 0), LWA))

    def _P_of(self, B1, B2) -> np.ndarray:
        P = np.zeros((12, 12))
        P[0:3, 6:9] = B1.T
        P[3:6, 0:3] = np.eye(3)
        P[6:9, 9:12] = B2.T
        P[9:12, 3:6] = np.eye(3)
        return P

    def to_engine_state(self, q, u):
        p = self.params
        B1, B2 = self._rotations(q)
        u = np.asarray(u, float)
        e2 = np.array([0.0, 1.0, 0.0])
        rG1 = -p["l1"] / 2 * B1 @ e2
        rG2 = -p["l1"] * B1 @ e2 - p["l2"] / 2 * B2 @ e2
        qe = np.concatenate([rG1, _R_to_quat(B1), rG2, _R_to_quat(B2)])
        return qe, self._P_of(B1, B2) @ u

    def from_engine_state(self, qe, ve):
        B1, B2 = _quat_to_R(qe[3:7]), _quat_to_R(qe[10:14])
        q = np.concatenate([_angles313(B1.T), _angles313(B2.T)])
        return q, self._P_of(B1, B2).T @ np.asarray(ve, float)  # P is orthogonal

    def _acc_to_reference(self, qe, ve, ae):
        out = np.empty(12)
        for k, (iq, iv) in enumerate(((0, 0), (7, 6))):
            B = _quat_to_R(qe[iq + 3:iq + 7])
            vl, w = ve[iv:iv + 3], ve[iv + 3:iv + 6]
            out[3 * k:3 * k + 3] = ae[iv + 3:iv + 6]
            out[6 + 3 * k:9 + 3 * k] = B @ (ae[iv:iv + 3] + np.cross(w, vl))
        return out

    def _multipliers(self, qe, ve, ae, lam_e):
        F_O, F_A = lam_e[0:3], lam_e[3:6]
        return np.concatenate([F_O - F_A, F_A])

    def mass_matrix(self, q):
        q, _ = self._check(q)
        qe, _ = self.to_engine_state(q, np.zeros(12))
        Me = pin.crba(self.model, self.data, qe).copy()
        Me = np.triu(Me) + np.triu(Me, 1).T
        P = self._P_of(*self._rotations(q))
        return P.T @ Me @ P

    def forcing(self, q, u, t: float = 0.0):
        return None


class DoublePendulumTree(_DoublePendulumBase):
    """Example 4 as a ball-joint tree: JointModelSpherical at O (link 1, frame n_1) and at A
    (placement (0, -l1, 0) in link 1; link 2 relative to link 1), mass centers at
    (0, -l_i/2, 0). Plain ABA; the six multipliers come from rnea's joint reactions:
    data.f[1] is the force of the ground on link 1 at O and data.f[2] the force of link 1 on
    link 2 at A, both in the joint's local frame, so F_O = B1 f[1].linear, F_A = B2 f[2].linear.
    Spherical q is the quaternion (x, y, z, w) of the child relative to the parent and v the
    relative omega in the child frame: q1 = quat(B1), q2 = quat(B1^T B2), v1 = w1,
    v2 = w2 - B2^T B1 w1. v_G and the accelerations are read from forwardKinematics."""

    variant = "tree"
    solver = "aba"
    mass_matrix_note = ("the reference's twelve speeds (w1, w2, v_G1, v_G2) are dependent (six "
                        "point-constraint rows) and do not map one to one onto the ball-joint "
                        "tree's six relative angular velocities")

    def _build(self):
        p = self.params
        I1, I2 = self._links()
        j1 = self.model.addJoint(0, pin.JointModelSpherical(), pin.SE3.Identity(), "O")
        self.model.appendBodyToJoint(
            j1, pin.Inertia(I1.mass, np.array([0.0, -p["l1"] / 2, 0.0]), I1.inertia),
            pin.SE3.Identity())
        j2 = self.model.addJoint(j1, pin.JointModelSpherical(), _at(0, -p["l1"], 0), "A")
        self.model.appendBodyToJoint(
            j2, pin.Inertia(I2.mass, np.array([0.0, -p["l2"] / 2, 0.0]), I2.inertia),
            pin.SE3.Identity())
        self.G = (_at(0, -p["l1"] / 2, 0), _at(0, -p["l2"] / 2, 0))

    def to_engine_state(self, q, u):
        B1, B2 = self._rotations(q)
        u = np.asarray(u, float)
        w1, w2 = u[0:3], u[3:6]
        qe = np.concatenate([_R_to_quat(B1), _R_to_quat(B1.T @ B2)])
        return qe, np.concatenate([w1, w2 - B2.T @ B1 @ w1])

    def from_engine_state(self, qe, ve):
        qe, ve = np.asarray(qe, float), np.asarray(ve, float)
        B1 = _quat_to_R(qe[0:4])
        B12 = _quat_to_R(qe[4:8])
        B2 = B1 @ B12
        q = np.concatenate([_angles313(B1.T), _angles313(B2.T)])
        pin.forwardKinematics(self.model, self.data, qe, ve)
        vG1 = self._anchor_velocity(1, self.G[0])
        vG2 = self._anchor_velocity(2, self.G[1])
        w1, w2 = ve[0:3], ve[3:6] + B12.T @ ve[0:3]
        return q, np.concatenate([w1, w2, vG1, vG2])

    def _acc_to_reference(self, qe, ve, ae):
        d = self.data
        pin.forwardKinematics(self.model, d, qe, ve, ae)
        return np.concatenate([d.a[1].angular, d.a[2].angular,
                               self._anchor_classical_acc(1, self.G[0]),
                               self._anchor_classical_acc(2, self.G[1])])

    def _multipliers(self, qe, ve, ae, lam_e):
        d = self.data
        pin.forwardKinematics(self.model, d, qe)
        pin.rnea(self.model, d, qe, ve, ae)
        F_O = d.oMi[1].rotation @ d.f[1].linear
        F_A = d.oMi[2].rotation @ d.f[2].linear
        return np.concatenate([F_O - F_A, F_A])


# ======================================================================================
# Exercises 6.5-6.7: the symmetric top with Euler parameters (N3 up)
# ======================================================================================
class _TopBase(_PinModel):
    """Shared maps. Engine world = the reference's N, gravity (0, 0, -g). The Euler parameters
    (eps1, eps2, eps3, eps4), eps4 scalar, ARE Pinocchio's quaternion coefficients (x, y, z, w):
    the reference's R(eps) = (e4^2 - ev.ev) 1 + 2 ev ev^T + 2 e4 skew(ev) is Eigen's
    toRotationMatrix, and omega = 2 E(eps) eps' is the body-fixed (LOCAL) angular velocity
    (both checked in the tests). Inversely eps' = E^T omega / 2 on |eps| = 1, eps . eps' = 0,
    and eps'' = (E(eps')^T omega + E(eps)^T omega') / 2."""

    up = np.array([0.0, 0.0, 1.0])

    def _top_inertia(self, lever):
        p = self.params
        return pin.Inertia(p["m"], np.asarray(lever, float), np.diag([p["I"], p["I"], p["I3"]]))

    @staticmethod
    def _eps_rates(eps, omega):
        return 0.5 * _E(eps).T @ omega

    @staticmethod
    def _eps_acc(eps, omega, omega_dot):
        eps_dot = 0.5 * _E(eps).T @ omega
        return 0.5 * (_E(eps_dot).T @ omega + _E(eps).T @ omega_dot)


class TopEuler(_TopBase):
    """Exercises 6.5/6.6. JointModelSpherical at O, the top's mass center at (0, 0, L) in its
    frame, central inertia diag(I, I, I3). Plain ABA. The reference's single row is the
    normalization eps . eps = 1, which the engine's quaternion coordinates satisfy by
    construction: there is no engine force for it. Its multiplier is not a force and depends
    on the formulation (0 for d'Alembert and Kane, 2V - 4K for Lagrange; reference docstring),
    so multipliers is None and raw carries both textbook values computed from the engine's
    K and V ("normalization_lambda_dalembert_kane", "normalization_lambda_lagrange")."""

    nq_ref = n_ref = 4
    solver = "aba"
    mass_matrix_note = ("the reference's M is over the four Euler-parameter rates, tied by the "
                        "normalization, which do not map one to one onto the ball joint's three "
                        "angular velocity components")

    def _build(self):
        j = self.model.addJoint(0, pin.JointModelSpherical(), pin.SE3.Identity(), "O")
        self.model.appendBodyToJoint(j, self._top_inertia([0.0, 0.0, self.params["L"]]),
                                     pin.SE3.Identity())

    def to_engine_state(self, q, u):
        eps = np.asarray(q, float).reshape(4)
        return eps.copy(), 2.0 * _E(eps) @ np.asarray(u, float)

    def from_engine_state(self, qe, ve):
        eps = np.asarray(qe, float).copy()
        return eps, self._eps_rates(eps, np.asarray(ve, float))

    def _acc_to_reference(self, qe, ve, ae):
        return self._eps_acc(qe, ve, ae)

    def _multipliers(self, qe, ve, ae, lam_e):
        return None

    def _extra_raw(self, qe, ve, ae, lam_e, raw):
        K, V = self._energy_engine(qe, ve)
        raw["normalization_lambda_dalembert_kane"] = 0.0
        raw["normalization_lambda_lagrange"] = 2.0 * V - 4.0 * K
        pin.forwardKinematics(self.model, self.data, qe)
        pin.rnea(self.model, self.data, qe, ve, ae)
        raw["socket_force"] = self.data.oMi[1].rotation @ self.data.f[1].linear


class _TopCartesianBase(_TopBase):
    """Exercise 6.7: reference q = (x, eps) with x the mass center G, u = (x', eps'); rows
    x - L R e3 = 0 (+1 on x) and the normalization. (lambda1, lambda2, lambda3) = F_O, the
    socket's force on the top at O (N components). lambda4 is not a force: for the two
    formulations this model declares (d'Alembert, Kane, both with the rates as speeds), summing
    eps_k times the eps equations gives 0 = -2 L F_O . (R e3) + lambda4 (the inertia terms
    vanish because E eps = 0, the x terms do not involve eps'), so lambda4 = 2 L F_O . (R e3),
    a function of the engine's force."""

    nq_ref = n_ref = 7

    def _lambda(self, F_O, eps):
        return np.concatenate([F_O, [2.0 * self.params["L"] * F_O @ (_quat_to_R(eps)[:, 2])]])


class TopCartesianFree(_TopCartesianBase):
    """Exercise 6.7 as one free body (FreeFlyer with its origin at G: engine q = (x, eps)
    exactly, the reference's order) held at O by a CONTACT_3D point constraint: joint1 = the
    top at (0, 0, -L), joint2 = the world at O, exact KKT (PROX_EXACT, 3 independent rows);
    contact_force = F_O. Engine v = (R^T x', omega)."""

    variant = "free"
    solver = "constraint"
    prox_settings = PROX_EXACT
    mass_matrix_note = ("the reference's seven speeds (x', eps') include the four Euler-parameter "
                        "rates tied by the normalization and do not map one to one onto the free "
                        "body's six (R^T x', omega)")

    def _build(self):
        j = self.model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "top")
        self.model.appendBodyToJoint(j, self._top_inertia([0.0, 0.0, 0.0]), pin.SE3.Identity())
        self.cms.append(pin.RigidConstraintModel(
            pin.ContactType.CONTACT_3D, self.model, j, _at(0, 0, -self.params["L"]),
            0, pin.SE3.Identity(), pin.ReferenceFrame.LOCAL_WORLD_ALIGNED))

    def to_engine_state(self, q, u):
        q, u = np.asarray(q, float), np.asarray(u, float)
        R = _quat_to_R(q[3:7])
        return q.copy(), np.concatenate([R.T @ u[0:3], 2.0 * _E(q[3:7]) @ u[3:7]])

    def from_engine_state(self, qe, ve):
        qe, ve = np.asarray(qe, float), np.asarray(ve, float)
        R = _quat_to_R(qe[3:7])
        return qe.copy(), np.concatenate([R @ ve[0:3], self._eps_rates(qe[3:7], ve[3:6])])

    def _acc_to_reference(self, qe, ve, ae):
        R = _quat_to_R(qe[3:7])
        xdd = R @ (ae[0:3] + np.cross(ve[3:6], ve[0:3]))
        return np.concatenate([xdd, self._eps_acc(qe[3:7], ve[3:6], ae[3:6])])

    def _multipliers(self, qe, ve, ae, lam_e):
        return self._lambda(lam_e[0:3], qe[3:7])


class TopCartesianTree(_TopCartesianBase):
    """Exercise 6.7 with the engine's minimal model (JointModelSpherical at O, as TopEuler):
    x and x' are read from forwardKinematics, F_O from rnea (data.f[1], ground on top at O)."""

    variant = "tree"
    solver = "aba"
    mass_matrix_note = ("the reference's seven speeds (x', eps') are dependent (point and "
                        "normalization rows) and do not map one to one onto the ball joint's "
                        "three angular velocity components")

    def _build(self):
        j = self.model.addJoint(0, pin.JointModelSpherical(), pin.SE3.Identity(), "O")
        self.model.appendBodyToJoint(j, self._top_inertia([0.0, 0.0, self.params["L"]]),
                                     pin.SE3.Identity())
        self.G = _at(0, 0, self.params["L"])

    def to_engine_state(self, q, u):
        q, u = np.asarray(q, float), np.asarray(u, float)
        return q[3:7].copy(), 2.0 * _E(q[3:7]) @ u[3:7]

    def from_engine_state(self, qe, ve):
        qe, ve = np.asarray(qe, float), np.asarray(ve, float)
        pin.forwardKinematics(self.model, self.data, qe, ve)
        x = self._anchor_position(1, self.G)
        xd = self._anchor_velocity(1, self.G)
        return np.concatenate([x, qe]), np.concatenate([xd, self._eps_rates(qe, ve)])

    def _acc_to_reference(self, qe, ve, ae):
        pin.forwardKinematics(self.model, self.data, qe, ve, ae)
        xdd = self._anchor_classical_acc(1, self.G)
        return np.concatenate([xdd, self._eps_acc(qe, ve, ae)])

    def _multipliers(self, qe, ve, ae, lam_e):
        pin.forwardKinematics(self.model, self.data, qe)
        pin.rnea(self.model, self.data, qe, ve, ae)
        F_O = self.data.oMi[1].rotation @ self.data.f[1].linear
        return self._lambda(F_O, qe)


# ======================================================================================
# Supplements: the knife edge (nonholonomic) and the moving support (rheonomic)
# ======================================================================================
class KnifeEdge(_SameCoordinates, _PinModel):
    """Knife edge / Chaplygin sled (horizontal plane, no gravity). Engine tree: slides PX (x),
    PY (y) carrying the contact point C, hinge RZ (theta) carrying the sled: mass center at
    (a, 0, 0) on the blade axis, planar-lamina inertia from I_G. q_e = q_ref. The nonholonomic
    row -S x' + C y' = 0 goes to forwardDynamics as the textbook row J = [-S, C, 0] with
    gamma = Jdot v = -(C x' + S y') theta', so data.lambda_c is the textbook lambda (the lateral
    force of the ground on the blade). Loads: P along the blade at C, tau = (P C, P S, 0), and T
    about Z. The constraint has no position level: constraint_violation is 0 and
    velocity_violation |-S x' + C y'| is the drift measure."""

    nq_ref = n_ref = 3
    solver = "kkt"
    _P = np.eye(3)

    def _build(self):
        p = self.params
        jx = self.model.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "x")
        jy = self.model.addJoint(jx, pin.JointModelPY(), pin.SE3.Identity(), "y")
        jt = self.model.addJoint(jy, pin.JointModelRZ(), pin.SE3.Identity(), "theta")
        self.model.appendBodyToJoint(
            jt, pin.Inertia(p["m"], np.array([p["a"], 0.0, 0.0]), _lamina(p["I_G"])),
            pin.SE3.Identity())

    def _applied(self, qe, ve, t):
        th = qe[2]
        return np.array([self.params["P"] * math.cos(th), self.params["P"] * math.sin(th),
                         self.params["T"]])

    def _kkt_rows(self, qe, ve, t):
        S, C = math.sin(qe[2]), math.cos(qe[2])
        J = np.array([[-S, C, 0.0]])
        return J, np.array([-(C * ve[0] + S * ve[1]) * ve[2]])

    def _multipliers(self, qe, ve, ae, lam_e):
        return lam_e.copy()

    def constraint_violation(self, qe, t: float = 0.0):
        return 0.0


class MovingSupport(PendulumXY):
    """Example 1(b) with the support moving x_s(t) = a sin(Omega t) along X (Y DOWN in the
    reference, Y up in the engine as PendulumXY). Rheonomic row f = ((x - x_s)^2 + y^2 - L^2)/2
    in engine coordinates: J = [x - x_s, y_e], and the acceleration-level row
    J a + (x' - x_s')^2 + y_e'^2 - (x - x_s) x_s'' = 0 gives gamma, including the explicit time
    terms; data.lambda_c is the textbook lambda (= -T/L). Velocity residual J v + a0 with
    a0 = -(x - x_s) x_s'."""

    def _support(self, t):
        a, W = self.params["a"], self.params["Omega"]
        return a * math.sin(W * t), a * W * math.cos(W * t), -a * W * W * math.sin(W * t)

    def _kkt_rows(self, qe, ve, t):
        xs, xsd, xsdd = self._support(t)
        J = np.array([[qe[0] - xs, qe[1]]])
        gamma = (ve[0] - xsd) ** 2 + ve[1] ** 2 - (qe[0] - xs) * xsdd
        return J, np.array([gamma])

    def _velocity_rows(self, qe, ve, t):
        xs, xsd, _ = self._support(t)
        return np.array([(qe[0] - xs) * (ve[0] - xsd) + qe[1] * ve[1]])

    def constraint_violation(self, qe, t: float = 0.0):
        xs, _, _ = self._support(t)
        return abs(float(np.hypot(qe[0] - xs, qe[1])) - self.params["L"])


# ======================================================================================
# Exercises 6.1, 6.2, 6.4 (geometry as assumed in the reference's docstrings)
# ======================================================================================
class Exercise61(_PinModel):
    """Exercise 6.1 (Y up): bar with end A on the X guide and end B on the Y guide, block P
    fixed to B. Engine: root slide PX (x, the massless end slider A, spring k and damper c on
    it), the bar hinged at A with its axis A -> B as the hinge frame's x axis (angle
    phi = theta + pi/2 from +X, mass center at (l/2, 0, 0), planar-lamina inertia from
    m l^2/12), root slide PY (y) carrying the block m_p with F pushing it down; loop closed at
    B between the bar end (l, 0, 0) and the block (CONTACT_3D, PROX_REDUNDANT: the z row is 0).
    q_e = (x, theta + pi/2, y). tau = (-k x - c x', 0, -F).

    Multipliers. The reference's (lambda1, lambda2) are generalized forces conjugate to x and
    y in its relaxed coordinates (the bar's mass center G = (x/2, y/2), theta free), yet they
    are fixed by the mechanism's forces. Let F_A, F_B be the forces on the bar at A and B
    (world axes). The bar's Newton equations m x''/2 = F_Ax + F_Bx, m y''/2 = F_Ay + F_By - m g,
    the massless slider's F_Ax = -k x - c x' and the block's m_p y'' = -F_By - m_p g - F, put
    into the reference's rows (1/4) m x'' + c x' + k x = lambda1 and
    ((1/4) m + m_p) y'' + ((1/2) m + m_p) g = lambda2 - F, give
        lambda1 = (F_Bx - F_Ax) / 2,   lambda2 = (F_Ay - F_By) / 2,
    and these satisfy its theta row too: the moment of F_A, F_B about G (A - G = (l/2)(S, -C),
    B - G = -(A - G)) is (l/2)(S (F_Ay - F_By) - C (F_Bx - F_Ax)) = l (-lambda1 C + lambda2 S).
    In the engine F_B = contact_force (the block's force on the bar at B) and F_A is the
    slider's force on the bar through the hinge: rnea's data.f of the bar joint with the
    closure force applied as an external force (_rnea_with_constraint_forces), rotated to
    world axes. raw["pin_A_force_momentum"] is F_A recomputed independently from the bar's
    momentum balance m a_G - m g_vec - F_B (a_G from forwardKinematics) and
    raw["spring_damper_force"] is tau_x = -k x - c x' (= F_Ax: the slider is massless).

    mass_matrix is None: the reference's M is that of its relaxed coordinates."""

    nq_ref = n_ref = 3
    solver = "constraint"
    prox_settings = PROX_REDUNDANT
    mass_matrix_note = ("the reference's M belongs to its relaxed dependent coordinates "
                        "(x, y, theta independent, the bar's mass center at (x/2, y/2)), which "
                        "no engine model of the mechanism has: the engine's (x, bar angle, y) "
                        "are tied by the closure at B")

    def _build(self):
        p = self.params
        jA = self.model.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "x")
        jb = self.model.addJoint(jA, pin.JointModelRZ(), pin.SE3.Identity(), "bar")
        self.model.appendBodyToJoint(
            jb, pin.Inertia(p["m"], np.array([p["l"] / 2, 0.0, 0.0]),
                            _lamina(p["m"] * p["l"] ** 2 / 12)), pin.SE3.Identity())
        jP = self.model.addJoint(0, pin.JointModelPY(), pin.SE3.Identity(), "y")
        self.model.appendBodyToJoint(
            jP, pin.Inertia(p["m_p"], np.zeros(3), np.zeros((3, 3))), pin.SE3.Identity())
        self.cms.append(pin.RigidConstraintModel(
            pin.ContactType.CONTACT_3D, self.model, jb, _at(p["l"], 0, 0), jP,
            pin.SE3.Identity(), pin.ReferenceFrame.LOCAL_WORLD_ALIGNED))
        self.j_bar = jb
        self.G = _at(p["l"] / 2, 0, 0)

    def _applied(self, qe, ve, t):
        p = self.params
        return np.array([-p["k"] * qe[0] - p["c"] * ve[0], 0.0, -p["F"]])

    def _spring_potential(self, qe):
        return 0.5 * self.params["k"] * qe[0] ** 2

    def to_engine_state(self, q, u):
        x, y, th = np.asarray(q, float)
        xd, yd, thd = np.asarray(u, float)
        return np.array([x, th + math.pi / 2, y]), np.array([xd, thd, yd])

    def from_engine_state(self, qe, ve):
        return (np.array([qe[0], qe[2], qe[1] - math.pi / 2]),
                np.array([ve[0], ve[2], ve[1]]))

    def _acc_to_reference(self, qe, ve, ae):
        return np.array([ae[0], ae[2], ae[1]])

    def _end_forces(self, qe, ve, ae, lam_e):
        """(F_A, F_B), the forces on the bar at A (the slider's, rnea) and at B (the block's,
        contact_force), world axes."""
        self._rnea_with_constraint_forces(qe, ve, ae, lam_e)
        d = self.data
        F_A = d.oMi[self.j_bar].rotation @ d.f[self.j_bar].linear
        return F_A, np.array(lam_e[0:3], float)

    def _multipliers(self, qe, ve, ae, lam_e):
        F_A, F_B = self._end_forces(qe, ve, ae, lam_e)
        return np.array([0.5 * (F_B[0] - F_A[0]), 0.5 * (F_A[1] - F_B[1])])

    def _extra_raw(self, qe, ve, ae, lam_e, raw):
        F_A, F_B = self._end_forces(qe, ve, ae, lam_e)
        raw["force_of_block_on_bar_at_B"] = F_B
        raw["pin_A_force_rnea"] = F_A
        pin.forwardKinematics(self.model, self.data, qe, ve, ae)
        a_G = self._anchor_classical_acc(self.j_bar, self.G)
        mb = self.params["m"]
        raw["pin_A_force_momentum"] = mb * a_G - mb * self.model.gravity.linear - F_B
        raw["spring_damper_force"] = float(self._applied(qe, ve, 0.0)[0])


class Exercise62(_PinModel):
    """Exercise 6.2 (Y DOWN in the reference, Y up in the engine): block m1 on a root slide PX
    (x; spring k, damper c and F on it), the slender bar hinged at A = the block's origin,
    hanging along -Y_e at theta = 0 (mass center (0, -l/2, 0) in the hinge frame, so the hinge
    angle is theta), planar-lamina inertia from m2 l^2/12. Engine q = (x, theta); the
    reference's dependent (x_G, y_G) = G - A with y down: read from forwardKinematics
    (x_G = dX, y_G = -dY_e), and their accelerations from the classical accelerations of G
    and A. Multipliers: the force of the pin A on the bar = rnea's data.f of the bar joint
    (parent on child) in world axes, Y flipped: (lambda1, lambda2) = (F_x, -F_y_e)."""

    nq_ref = n_ref = 4
    solver = "aba"
    mass_matrix_note = ("the reference's M belongs to its relaxed dependent coordinates "
                        "(x, theta, x_G, y_G with the bar's mass center free of the bar angle), "
                        "which no engine model of the mechanism has: the engine has (x, theta)")

    def _build(self):
        p = self.params
        jb = self.model.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "x")
        self.model.appendBodyToJoint(
            jb, pin.Inertia(p["m1"], np.zeros(3), np.zeros((3, 3))), pin.SE3.Identity())
        jr = self.model.addJoint(jb, pin.JointModelRZ(), pin.SE3.Identity(), "theta")
        self.model.appendBodyToJoint(
            jr, pin.Inertia(p["m2"], np.array([0.0, -p["l"] / 2, 0.0]),
                            _lamina(p["m2"] * p["l"] ** 2 / 12)), pin.SE3.Identity())
        self.G = _at(0, -p["l"] / 2, 0)

    def _applied(self, qe, ve, t):
        p = self.params
        return np.array([p["F"] - p["c"] * ve[0] - p["k"] * qe[0], 0.0])

    def _spring_potential(self, qe):
        return 0.5 * self.params["k"] * qe[0] ** 2

    def to_engine_state(self, q, u):
        q, u = np.asarray(q, float), np.asarray(u, float)
        return q[0:2].copy(), u[0:2].copy()

    def from_engine_state(self, qe, ve):
        pin.forwardKinematics(self.model, self.data, qe, ve)
        dp = self._anchor_position(2, self.G) - self._anchor_position(1, pin.SE3.Identity())
        dv = self._anchor_velocity(2, self.G) - self._anchor_velocity(1, pin.SE3.Identity())
        return (np.array([qe[0], qe[1], dp[0], -dp[1]]),
                np.array([ve[0], ve[1], dv[0], -dv[1]]))

    def _acc_to_reference(self, qe, ve, ae):
        pin.forwardKinematics(self.model, self.data, qe, ve, ae)
        da = (self._anchor_classical_acc(2, self.G)
              - self._anchor_classical_acc(1, pin.SE3.Identity()))
        return np.array([ae[0], ae[1], da[0], -da[1]])

    def _multipliers(self, qe, ve, ae, lam_e):
        d = self.data
        pin.forwardKinematics(self.model, d, qe)
        pin.rnea(self.model, d, qe, ve, ae)
        F = d.oMi[2].rotation @ d.f[2].linear
        return np.array([F[0], -F[1]])


class Exercise64(_PinModel):
    """Exercise 6.4 (Z up): disk D on a hinge RZ at O (phi; inertia diag(m_d R^2/4, m_d R^2/4,
    m_d R^2/2), motor M_phi), the bar on a hinge RX at P = (0, R, 0) in the disk frame (theta;
    M_theta, spring k and damper c act between D and B, i.e. on this joint), mass center at
    (0, 0, -l/2) in the hinge frame, inertia diag(m l^2/12, m l^2/12, 0) exactly as the
    reference (the disk keeps the mass matrix definite). Engine q = (phi, theta); (y_G, z_G)
    are G's coordinates in the disk frame, from the hinge placement and rotation:
    r = P + Rx(theta) c, r' = w x (Rx c), r'' = w' x (Rx c) + w x (w x Rx c), w = (theta', 0, 0).
    Multipliers: force of the pin on the bar in disk axes: rnea's data.f[2] (parent on child,
    bar-hinge frame) rotated by Rx(theta): (lambda1, lambda2) = its (y, z) components."""

    nq_ref = n_ref = 4
    solver = "aba"
    up = np.array([0.0, 0.0, 1.0])
    mass_matrix_note = ("the reference's M belongs to its relaxed dependent coordinates "
                        "(phi, theta, y_G, z_G with the bar's mass center free of the bar "
                        "angle), which no engine model of the mechanism has: the engine has "
                        "(phi, theta)")

    def _build(self):
        p = self.params
        jd = self.model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "phi")
        Id = p["m_d"] * p["R"] ** 2
        self.model.appendBodyToJoint(
            jd, pin.Inertia(p["m_d"], np.zeros(3), np.diag([Id / 4, Id / 4, Id / 2])),
            pin.SE3.Identity())
        jb = self.model.addJoint(jd, pin.JointModelRX(), _at(0, p["R"], 0), "theta")
        Ib = p["m"] * p["l"] ** 2 / 12
        self.model.appendBodyToJoint(
            jb, pin.Inertia(p["m"], np.array([0.0, 0.0, -p["l"] / 2]), np.diag([Ib, Ib, 0.0])),
            pin.SE3.Identity())

    def _applied(self, qe, ve, t):
        p = self.params
        return np.array([p["M_phi"], p["M_theta"] - p["k"] * qe[1] - p["c"] * ve[1]])

    def _spring_potential(self, qe):
        return 0.5 * self.params["k"] * qe[1] ** 2

    def _G_disk(self, th, thd, thdd):
        c = self.model.inertias[2].lever
        P = self.model.jointPlacements[2].translation
        Rc = pin.utils.rotate("x", th) @ c
        w, wd = np.array([thd, 0.0, 0.0]), np.array([thdd, 0.0, 0.0])
        return (P + Rc, np.cross(w, Rc), np.cross(wd, Rc) + np.cross(w, np.cross(w, Rc)))

    def to_engine_state(self, q, u):
        q, u = np.asarray(q, float), np.asarray(u, float)
        return q[0:2].copy(), u[0:2].copy()

    def from_engine_state(self, qe, ve):
        r, rd, _ = self._G_disk(qe[1], ve[1], 0.0)
        return (np.array([qe[0], qe[1], r[1], r[2]]), np.array([ve[0], ve[1], rd[1], rd[2]]))

    def _acc_to_reference(self, qe, ve, ae):
        _, _, rdd = self._G_disk(qe[1], ve[1], ae[1])
        return np.array([ae[0], ae[1], rdd[1], rdd[2]])

    def _multipliers(self, qe, ve, ae, lam_e):
        d = self.data
        pin.rnea(self.model, d, qe, ve, ae)
        F = d.liMi[2].rotation @ d.f[2].linear  # disk axes
        return np.array([F[1], F[2]])


# ======================================================================================
# Registry
# ======================================================================================
_MODELS = {
    "pendulum_angle": PendulumAngle,
    "pendulum_xy": PendulumXY,
    "slider_crank": SliderCrank,
    "slider_crank_split": SliderCrankSplit,
    "slider_crank_free": SliderCrankFree,
    "frame_bar": FrameBar,
    # several engine models of one reference model: {variant: class}, the first is the default
    "double_pendulum_3d": {"free": DoublePendulumFree, "tree": DoublePendulumTree},
    "top_euler": TopEuler,
    "top_cartesian": {"free": TopCartesianFree, "tree": TopCartesianTree},
    "knife_edge": KnifeEdge,
    "pendulum_moving_support": MovingSupport,
    "exercise_6_1": Exercise61,
    "exercise_6_2": Exercise62,
    "exercise_6_4": Exercise64,
}

# models of the unit this engine cannot represent, with the reason shown in results
_UNSUPPORTED: dict[str, str] = {}


def _resolve(model_name: str, params: Optional[dict]) -> dict[str, float]:
    """The reference model's parameter values (defaults filled in, names and signs checked)."""
    from reference.models import get
    from reference.numeric import resolve_parameters

    return resolve_parameters(get(model_name), params)


def _user_names() -> list[str]:
    from reference.models import user_names
    return user_names()


class PinocchioAdapter(EngineAdapter):
    """EngineAdapter for Pinocchio 4.1 (models built in code; see the module docstring)."""

    name = "pinocchio"
    distribution = "pin"
    label = "Pinocchio"
    rank = 10
    capabilities = Capabilities(multipliers=True, exact=True, mass_matrix=True,
                                nonholonomic=True, integrators=INTEGRATORS, variants=True,
                                adaptive_integrators=INTEGRATORS)

    def models(self) -> tuple[str, ...]:
        from reference.models import user_names
        return (*_MODELS, *user_names())

    def unsupported(self) -> dict[str, str]:
        return dict(_UNSUPPORTED)

    def variants(self, model_name: str) -> tuple[Optional[str], ...]:
        """Engine variants of a model (the first is build's default); (None,) for one."""
        cls = _MODELS.get(model_name)
        return tuple(cls) if isinstance(cls, dict) else (None,)

    def build(self, model_name: str, params: Optional[dict[str, float]] = None,
              variant: Optional[str] = None):
        if model_name in _UNSUPPORTED:
            raise EngineUnsupported(_UNSUPPORTED[model_name])
        if model_name not in _MODELS and model_name in _user_names():
            from .user_file import UserFilePinModel
            if variant is not None:
                raise EngineUnsupported(f"{model_name}: a user's file has a single variant")
            return UserFilePinModel(model_name, params)
        if model_name not in _MODELS:
            raise EngineUnsupported(
                f"pinocchio adapter has no model {model_name!r} (mapped: {', '.join(_MODELS)})")
        cls = _MODELS[model_name]
        values = _resolve(model_name, params)
        if isinstance(cls, dict):  # several engine variants of one reference model
            key = variant or next(iter(cls))
            if key not in cls:
                raise EngineUnsupported(
                    f"{model_name}: unknown pinocchio variant {key!r}; valid: {', '.join(cls)}")
            return cls[key](model_name, values)
        if variant is not None:
            raise EngineUnsupported(f"{model_name}: pinocchio has a single variant here")
        return cls(model_name, values)
