"""Pinocchio machinery shared by every engine model: the solvers (aba, the KKT solve with
textbook rows, constraintDynamics), the state maps' hooks, residual checks, energy, mass
matrix, trajectories. The conventions are in the package's adapter docstring."""

from __future__ import annotations

import hashlib
import time

import numpy as np
import pinocchio as pin

from crosscheck.engines.base import (
    EngineForward,
    EngineModel,
    EngineTrajectory,
    EngineUnsupported,
)
from crosscheck.engines.building import check_state
from crosscheck.engines.pinocchio.ode import JointLayout, joint_layout, normalized, right_hand_side

# the error-controlled integrators the trajectories use (solve_ivp methods, see ivp_method)
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

Y_UP = np.array([0.0, 1.0, 0.0])


def lamina(I_zz: float) -> np.ndarray:
    """Full central inertia of a planar body whose reference inertia is only I_zz."""
    return np.diag([0.5 * I_zz, 0.5 * I_zz, I_zz])


def quat_to_R(qxyzw) -> np.ndarray:
    """Rotation (local -> world) of a Pinocchio quaternion stored (x, y, z, w)."""
    x, y, z, w = qxyzw
    return pin.Quaternion(w, x, y, z).toRotationMatrix()


def R_to_quat(R) -> np.ndarray:
    """(x, y, z, w) of a rotation matrix, Pinocchio's (Eigen's) coefficient order."""
    return pin.Quaternion(np.asarray(R, float)).coeffs().copy()


def at(x, y, z) -> pin.SE3:
    return pin.SE3(np.eye(3), np.array([x, y, z], float))


def _prox(settings) -> pin.ProximalSettings:
    acc, mu, it = settings
    return pin.ProximalSettings(float(acc), float(mu), int(it))


def check_integrator(integrator: str, rtol: float | None) -> None:
    """One of INTEGRATORS (scipy's solve_ivp methods, all error-controlled) and its rtol > 0."""
    if integrator not in INTEGRATORS:
        raise ValueError(f"unknown integrator {integrator!r}; valid: {', '.join(INTEGRATORS)}")
    if rtol is None or not rtol > 0:
        raise ValueError(f"{integrator} controls its error: give rtol > 0, got {rtol!r}")


def ivp_method(integrator: str):
    """The solve_ivp method for one of INTEGRATORS: DOP853 is the reference's LeanDOP853,
    scipy's DOP853 (tableau, error control, steps, dense output) without scipy's Python around
    each stage, which costs as much as Pinocchio's forward call on these models."""
    # imported here: scipy.integrate is a second of imports the command line's process, which
    # only checks the engine names before handing models to workers, does not need
    from reference.integrate.rk import LeanDOP853

    return {"DOP853": LeanDOP853}[integrator]


def ivp_trajectory(sol, rows, integrator: str, rtol, t_start: float, raw: dict) -> EngineTrajectory:
    """The EngineTrajectory of a solve_ivp solution (rtol = atol) from its rows, one per output
    time: (q, u, violation, velocity violation, energy) in reference terms."""
    Q, U, viol, vviol, E = ([r[k] for r in rows] for k in range(5))
    return EngineTrajectory(
        t=sol.t,
        q=np.array(Q),
        u=np.array(U),
        violation=np.array(viol),
        velocity_violation=np.array(vviol),
        energy=np.array(E),
        integrator=integrator,
        setting={"rtol": rtol, "atol": rtol},
        wall_s=time.perf_counter() - t_start,
        steps=int(sol.nfev),
        failure=None if sol.success else str(sol.message),
        raw=raw,
    )


class PinEngineModel(EngineModel):
    """Shared machinery; subclasses build the engine model and write the maps."""

    engine = "pinocchio"
    # reference coordinates (nq) and speeds (n); subclasses set them
    nq_ref: int
    n_ref: int
    solver = "aba"  # "aba" | "kkt" (forwardDynamics with J, gamma) | "constraint"
    prox_settings = PROX_REDUNDANT
    variant: str | None = None
    up = np.array([0.0, 1.0, 0.0])  # engine world "up"; gravity is -g up (g = 0 if no "g")
    # why mass_matrix returns None (one sentence, shown in results), set on every such class
    mass_matrix_note: str | None = None

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

    @property
    def layout(self) -> JointLayout:
        """Where each joint's coordinates and velocities sit in q_e, v_e (read once)."""
        if "_layout" not in self.__dict__:
            self._layout = joint_layout(self.model)
        return self._layout

    def fingerprint(self) -> str:
        """SHA-256 of the built model's physics: joint types and placements, every body's
        mass, lever and inertia, gravity, the point constraints' joints and anchors, and the
        loads (and the 'kkt' solver's rows) at a fixed probe state, which is how the loads read
        from parameters at run time (springs, dampers, turning forces) enter it."""
        h = hashlib.sha256()

        def add(x) -> None:
            h.update(np.ascontiguousarray(np.asarray(x, float)).tobytes())

        m = self.model
        for jm, placement in zip(m.joints, m.jointPlacements, strict=True):
            h.update(jm.shortname().encode())
            add(placement.homogeneous)
        for inertia in m.inertias:
            add([inertia.mass])
            add(inertia.lever)
            add(inertia.inertia)
        add(m.gravity.vector)
        for cm in self.cms:
            h.update(f"{cm.joint1_id},{cm.joint2_id}".encode())
            add(cm.joint1_placement.homogeneous)
            add(cm.joint2_placement.homogeneous)
        # a probe away from the neutral configuration (a spring at rest exerts no force)
        ve = np.linspace(0.3, 0.7, m.nv)
        qe = pin.integrate(m, pin.neutral(m), 0.5 * ve)
        add(self._applied(qe, ve, 0.7))
        if self.solver == "kkt":
            for x in self._kkt_rows(qe, ve, 0.7):
                add(x)
        return h.hexdigest()

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
    _P: np.ndarray | None = None

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
            f = np.asarray(lam[3 * k : 3 * k + 3], float)
            for joint, placement, sign in (
                (cm.joint1_id, cm.joint1_placement, 1.0),
                (cm.joint2_id, cm.joint2_placement, -1.0),
            ):
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
        return max(
            float(
                np.max(
                    np.abs(
                        self._anchor_velocity(cm.joint1_id, cm.joint1_placement)
                        - self._anchor_velocity(cm.joint2_id, cm.joint2_placement)
                    )
                )
            )
            for cm in self.cms
        )

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
        return check_state(f"{self.model_name} ({self.engine})", self.nq_ref, self.n_ref, q, u, t)

    def forward(self, q, u, t: float = 0.0) -> EngineForward:
        q, u = self._check(q, u, t)
        qe, ve = self.to_engine_state(q, u)
        ae, lam_e = self._solve(qe, ve, t)
        raw = {
            "engine_q": qe,
            "engine_v": ve,
            "engine_accelerations": ae,
            "engine_forces": lam_e,
            "solver": self.solver,
        }
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
                qe, ve, ae, lam_e, t
            )
        if self.variant is not None:
            raw["variant"] = self.variant
        return EngineForward(
            self._acc_to_reference(qe, ve, ae),
            lam,
            raw,
            multipliers_note=raw.get("multipliers_note"),
            iterations=int(raw["iterations"]),
        )

    def _extra_raw(self, qe, ve, ae, lam_e, raw) -> None:
        pass

    def derivatives(self, q, u, t, directions):
        """Pinocchio's analytical derivatives along the reference's consistent directions
        (crosscheck/engines/pinocchio/derivatives.py); the 'kkt' solver has none."""
        from crosscheck.engines.linearization import derivatives_along
        from crosscheck.engines.pinocchio import derivatives as pd

        if self.solver == "kkt":
            raise EngineUnsupported(pd.KKT_ROWS)
        q, u = self._check(q, u, t)
        return derivatives_along(pd.maps(self, t), q, u, directions)

    @property
    def constrained_solve(self) -> bool:  # type: ignore[override]
        return self.solver != "aba"

    def energy(self, q, u) -> tuple[float, float]:
        q, u = self._check(q, u)
        qe, ve = self.to_engine_state(q, u)
        return self._energy_engine(qe, ve)

    def mass_matrix(self, q) -> np.ndarray | None:
        """Engine mass matrix in reference coordinates (P^T M_e P), or None when the engine's
        coordinates are not a linear bijection of the reference's."""
        if self._P is None:
            return None
        q, _ = self._check(q)
        qe, _ = self.to_engine_state(q, np.zeros(self.n_ref))
        Me = pin.crba(self.model, self.data, qe).copy()
        Me = np.triu(Me) + np.triu(Me, 1).T  # crba fills the upper triangle
        return self._P.T @ Me @ self._P

    def forcing(self, q, u, t: float = 0.0) -> np.ndarray | None:
        """The reference's f (applied generalized forces minus velocity products) from the
        engine: P^T (tau - nle), or None where the coordinates do not map linearly."""
        if self._P is None:
            return None
        q, u = self._check(q, u, t)
        qe, ve = self.to_engine_state(q, u)
        nle = pin.nonLinearEffects(self.model, self.data, qe, ve)
        return self._P.T @ (self._applied(qe, ve, t) - nle)

    def simulate(
        self,
        q0,
        u0,
        t_eval,
        *,
        integrator: str,
        rtol: float | None = None,
        timestep: float | None = None,
    ) -> EngineTrajectory:
        """Integrate Pinocchio's forward dynamics with scipy's solve_ivp (on ivp_method's
        stepper for `integrator`, rtol = atol = `rtol`) in engine coordinates from t = 0 to
        t_eval[-1].

        The engine state is [q_e, v_e] (crosscheck/engines/pinocchio/ode.py: quaternions
        renormalized before every evaluation and in the output, since |q| is not a constraint
        of the engine; their rates from the local angular velocity, a free flyer's position
        rate R v_linear, docs/engines/pinocchio.md); the output is mapped to reference (q, u)
        at t_eval.

        No constraint stabilization (no projection, no Baumgarte, the RigidConstraintModel
        correctors stay 0): run for 5 s from each model's initial state, the constraint drift
        of every constrained model stayed within ~10x the integrator tolerance (tolerances 1e-8
        and 1e-10, DOP853), the index-1 drift expected from the tolerance alone, so a
        stabilization would only hide what the comparison should show. The trajectory's
        violation (position level) and velocity_violation record it per output time, energy
        the engine's K + V; wall_s is the whole call (integration and mapping).
        """
        from scipy.integrate import solve_ivp  # imported here, as in ivp_method

        check_integrator(integrator, rtol)
        t_start = time.perf_counter()
        t_eval = np.asarray(t_eval, dtype=float)
        q0, u0 = self._check(q0, u0)
        qe0, ve0 = self.to_engine_state(q0, u0)
        nq = self.model.nq
        y0 = np.concatenate([qe0, ve0])

        sol = solve_ivp(
            right_hand_side(self.layout, lambda qe, ve, t: self._engine_call(qe, ve, t)()),
            (0.0, float(t_eval[-1])),
            y0,
            method=ivp_method(integrator),
            rtol=rtol,
            atol=rtol,
            t_eval=t_eval,
        )
        rows = []
        for t, y in zip(sol.t, sol.y.T, strict=True):
            qe = normalized(self.layout, y[:nq])
            ve = y[nq:]
            rows.append(
                (
                    *self.from_engine_state(qe, ve),
                    self.constraint_violation(qe, t),
                    self.velocity_violation(qe, ve, t),
                    sum(self._energy_engine(qe, ve)),
                )
            )
        return ivp_trajectory(
            sol,
            rows,
            integrator,
            rtol,
            t_start,
            {"engine_states": sol.y.T.copy(), "stabilization": "none"},
        )
