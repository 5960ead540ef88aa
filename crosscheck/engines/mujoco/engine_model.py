"""MuJoCo machinery shared by every engine model: the MJCF conventions and text helpers,
forward (its soft-constraint recovery in soft_recovery.py), energy, mass matrix, trajectories.
The conventions are in the package's adapter docstring."""

from __future__ import annotations

import copy
import hashlib
import time
from pathlib import Path

import mujoco
import numpy as np

from crosscheck.checks.tolerances import Tolerance
from crosscheck.engines.base import EngineForward, EngineModel, EngineTrajectory, EngineUnsupported
from crosscheck.engines.building import check_state
from crosscheck.engines.mujoco.soft_recovery import full_M, predict_soft, soft_recovery

SOLIMP = (0.9999, 0.9999, 0.001, 0.5, 2.0)
SOLREF = (0.02, 1.0)
# relative mass/inertia of the bodies the reference does not have (light rods, the light frame)
LIGHT = 1e-12
# MuJoCo's fixed-step integrators; the first is the one `crosscheck run` uses for trajectories
INTEGRATORS = {
    "RK4": mujoco.mjtIntegrator.mjINT_RK4,
    "Euler": mujoco.mjtIntegrator.mjINT_EULER,
    "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
    "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
}
MJCF_DIR = Path(__file__).with_name("mjcf")
MUJOCO_EXACT = Tolerance(
    1e-11,
    "an exact answer in MuJoCo (a tree, no equality rows) against the reference's: "
    "round-off plus the bias of the 1e-12 relative mass or inertia MuJoCo's light bodies "
    "get (it rejects massless ones): measured <= 1.0e-12 (pendulum_angle's light rod, "
    "frame_bar's light frame) over 2000 random parameter sets and states per model "
    "(crosscheck sweep pendulum_angle slider_crank_free double_pendulum_3d top_euler "
    "frame_bar exercise_6_2 --engines mujoco --samples 2000 --seed 4, and --seed 5); "
    "10x",
)
# the models whose light regularization is amplified past MUJOCO_EXACT (adapter.exact_tolerance)
MUJOCO_LIGHT_EXACT = Tolerance(
    1e-10,
    "Exercise 6.4's slender bar has no axial inertia; MuJoCo rejects a zero principal "
    "inertia, so it gets 1e-12 m l^2, and the disk's spin makes that bias reach 3.7e-11 "
    "(crosscheck sweep exercise_6_4 --engines mujoco --samples 2000 --seed 4; 4.54e-11 "
    "at seed 5); the reference given the same inertia agrees to 2.8e-14 "
    "(tests/test_mujoco_bounds.py), so that inertia is the whole gap; 2x over 4.5e-11",
)


def num(x: float) -> str:
    """A float written so MuJoCo reads back the same double (repr round-trips)."""
    return repr(float(x))


def vec(*xs) -> str:
    return " ".join(num(x) for x in xs)


# ---- MJCF text ---------------------------------------------------------------------------------


def document(
    name: str,
    gravity,
    bodies: str,
    equality: str = "",
    note: str = "",
    solref=SOLREF,
    solimp=SOLIMP,
    timestep: float = 1e-3,
    wrap: bool = True,
) -> str:
    """The MJCF document; `bodies` go inside the static top-level body "frame" (wrap=True) or
    directly under <worldbody> (MuJoCo 4.0 accepts free joints only on top-level bodies)."""
    eq = f"\n  <equality>\n{equality}  </equality>" if equality else ""
    comment = f"  <!-- {note} -->\n" if note else ""
    if wrap:
        bodies = (
            '    <body name="frame">\n'
            '      <inertial pos="0 0 0" mass="0" diaginertia="0 0 0"/>\n'
            + bodies
            + "    </body>\n"
        )
    else:
        bodies = "\n".join(
            line[2:] if line.startswith("  ") else line for line in bodies.split("\n")
        )
    return f"""<mujoco model="{name}">
{comment}  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>
  <option gravity="{vec(*gravity)}" timestep="{num(timestep)}" integrator="Euler" solver="Newton"
          tolerance="1e-15" iterations="1000">
    <flag contact="disable" energy="enable"/>
  </option>
  <default>
    <geom contype="0" conaffinity="0" group="1" rgba="0.6 0.6 0.7 1"/>
    <equality solref="{vec(*solref)}" solimp="{vec(*solimp)}"/>
    <site size="0.01"/>
  </default>
  <worldbody>
    <site name="origin" pos="0 0 0"/>
{bodies}  </worldbody>{eq}
</mujoco>
"""


def lamina(I_zz: float) -> str:
    """diaginertia of a planar body whose reference inertia is only I_zz: (I/2, I/2, I), a
    valid rigid-body inertia (perpendicular-axis theorem); hinges about Z never excite the
    in-plane components."""
    return vec(0.5 * I_zz, 0.5 * I_zz, I_zz)


# ---- helpers -----------------------------------------------------------------------------------


def quat_to_R(qwxyz) -> np.ndarray:
    R = np.zeros(9)
    qq = np.asarray(qwxyz, float)
    mujoco.mju_quat2Mat(R, qq / np.linalg.norm(qq))
    return R.reshape(3, 3)


def R_to_quat(R) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.asarray(R, float).reshape(9))
    return q / np.linalg.norm(q)


def _warnings(d) -> dict:
    """MuJoCo's warning counters that fired during a run (name -> count). An unstable step
    (mjWARN_BADQACC) makes MuJoCo reset the state and go on, so a trajectory that hit one is
    not a trajectory of the model: callers must flag it, not compare it silently."""
    out = {}
    for name, w in mujoco.mjtWarning.__members__.items():
        if name == "mjNWARNING":
            continue
        n = int(d.warning[int(w)].number)
        if n:
            out[name] = n
    return out


# ---- shared machinery --------------------------------------------------------------------------


class MjEngineModel(EngineModel):
    """One MuJoCo model of one reference model; subclasses write the XML and the maps."""

    engine = "mujoco"
    nq_ref: int
    n_ref: int
    light_bodies: tuple[str, ...] = ()  # bodies absent from the reference: energy subtracted
    variant: str | None = None
    # q_engine_velocity = P u_ref exactly (constant P): M and f map as P^T M P, P^T f
    _P: np.ndarray | None = None
    # solve the rigid recovery's KKT with the rows scaled to unit norm (soft_recovery.kkt_lstsq):
    # a user's file may have rows of very different sizes; the generated models' are alike
    equilibrate_rows = False
    # recover the rigid answer for MuJoCo's aref without its stabilization terms
    # (soft_recovery._stabilization): a user's file may set a stiff solref that amplifies the
    # round-off of a consistent state's residuals; the generated models' is mild
    remove_stabilization = False

    def __init__(self, model_name: str, params: dict[str, float], solref=SOLREF, solimp=SOLIMP):
        self.model_name = model_name
        self.params = dict(params)
        if not hasattr(self, "nq_ref"):  # the reference's sizes, for the state check
            from reference import models

            ref = models.get(model_name)
            self.nq_ref, self.n_ref = len(ref.coordinates), len(ref.speeds)
        self.solref, self.solimp = tuple(solref), tuple(solimp)
        self.xml = self._xml(solref=self.solref, solimp=self.solimp)
        self.m = mujoco.MjModel.from_xml_string(self.xml)
        self.d = mujoco.MjData(self.m)
        self.soft_constraints = self.m.neq > 0
        self.applied = self._applied()
        self._light_ids = [
            mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_BODY, b) for b in self.light_bodies
        ]
        self._post_build()

    # the compiled model's arrays that carry its physics (fingerprint)
    _PHYSICS_FIELDS = (
        "body_mass",
        "body_inertia",
        "body_pos",
        "body_quat",
        "body_ipos",
        "body_iquat",
        "jnt_type",
        "jnt_pos",
        "jnt_axis",
        "jnt_stiffness",
        "qpos_spring",
        "dof_damping",
        "dof_armature",
        "eq_type",
        "eq_obj1id",
        "eq_obj2id",
        "eq_data",
        "site_pos",
        "site_quat",
        "geom_size",
    )

    def fingerprint(self) -> str:
        """SHA-256 of the compiled model's physics (masses, inertias, body/joint/site
        placements, springs, dampers, equality data, gravity) and the applied loads."""
        h = hashlib.sha256()
        for name in self._PHYSICS_FIELDS:
            h.update(name.encode())
            h.update(np.ascontiguousarray(getattr(self.m, name), float).tobytes())
        h.update(np.asarray(self.m.opt.gravity, float).tobytes())
        h.update(np.asarray(self.applied, float).tobytes())
        return h.hexdigest()

    # ---- hooks ---------------------------------------------------------------------------
    def _xml(self, **kw) -> str:
        raise NotImplementedError

    def _post_build(self) -> None:
        pass

    def _load_model(self):
        """A new MjModel compiled from the model's source (XML text or file)."""
        return mujoco.MjModel.from_xml_string(self.xml)

    # solref time constants are divided by this (stiffened(); 1: the model as written)
    _stiffness = 1.0

    def _fresh_model(self):
        """A new MjModel of the same model (trajectories run on their own copy), with the
        soft rows' time constants divided by ``_stiffness``."""
        m = self._load_model()
        if self._stiffness != 1.0:
            m.eq_solref[:, 0] /= self._stiffness
        return m

    def stiffened(self, factor: float) -> MjEngineModel:
        """The same model with every equality's solref time constant divided by factor
        (damping ratio kept): the soft effect on a trajectory shrinks as the time constant
        squared (docs/engines/mujoco.md), which the rigid-limit record extrapolates."""
        if self.m.neq == 0:
            raise EngineUnsupported("no equality rows: nothing to stiffen")
        if np.any(self.m.eq_solref[:, 0] <= 0):
            raise EngineUnsupported(
                "solref given as a direct stiffness (negative): its time constant cannot be scaled"
            )
        other = copy.copy(self)
        other._stiffness = self._stiffness * float(factor)
        if self.solref:  # the generated models' setting (a user's file keeps its own per row)
            other.solref = (self.solref[0] / float(factor), *self.solref[1:])
        other.m = other._fresh_model()
        other.d = mujoco.MjData(other.m)
        return other

    def predict_soft(self, q, u, reference_accelerations):
        """MuJoCo's raw soft (accelerations, multipliers) predicted from the reference's
        accelerations and the documented solref/solimp impedance (soft_recovery.py)."""
        return predict_soft(self, q, u, reference_accelerations)

    def _applied(self) -> np.ndarray:
        """qfrc_applied: the reference's constant loads as engine generalized forces."""
        return np.zeros(self.m.nv)

    def to_engine_state(self, q, u):
        raise NotImplementedError

    def from_engine_state(self, qe, ve):
        raise NotImplementedError

    def _acc_to_reference(self, qe, ve, ae) -> np.ndarray:
        """Engine qacc -> reference u' (affine in ae at a given state)."""
        raise NotImplementedError

    def _multipliers(self, qe, ve, ae, f) -> np.ndarray:
        """Engine equality forces f (nefc rows) -> reference lambda (affine in f)."""
        return np.zeros(0)

    def _extra_raw(self, raw) -> None:
        """Model-specific raw quantities after mj_forward (self.d holds the state)."""

    def _jdot_v(self) -> np.ndarray | None:
        """J-dot v of the equality rows from mj_jacDot (connect rows only, else None): the
        anchors are the sites (site-based) or eq_data[0:3] / eq_data[3:6] in the bodies' frames
        (body-based)."""
        m, d = self.m, self.d
        out = []
        for e in range(m.neq):
            if m.eq_type[e] != mujoco.mjtEq.mjEQ_CONNECT:
                return None
            rows = np.zeros(3)
            for k, sign in ((0, 1.0), (1, -1.0)):
                obj = (m.eq_obj1id, m.eq_obj2id)[k][e]
                if m.eq_objtype[e] == mujoco.mjtObj.mjOBJ_SITE:
                    body, point = m.site_bodyid[obj], d.site_xpos[obj].copy()
                else:
                    body = obj
                    anchor = m.eq_data[e, 3 * k : 3 * k + 3]
                    point = d.xpos[body] + d.xmat[body].reshape(3, 3) @ anchor
                if body == 0:
                    continue
                jd = np.zeros((3, m.nv))
                mujoco.mj_jacDot(m, d, jd, None, np.asarray(point, float), int(body))
                rows += sign * jd @ d.qvel
            out.append(rows)
        return np.concatenate(out) if out else np.zeros(0)

    @staticmethod
    def _affine_gain(fun, x0) -> np.ndarray:
        """The linear part of an affine map (exact: unit-step differences)."""
        y0 = np.asarray(fun(np.array(x0, float)), float)
        cols = []
        for i in range(len(x0)):
            x = np.array(x0, float)
            x[i] += 1.0
            cols.append(np.asarray(fun(x), float) - y0)
        return np.array(cols).T.reshape(y0.size, len(x0))

    # ---- engine evaluation -------------------------------------------------------------------
    def _set(self, qe, ve, m=None, d=None):
        m = m or self.m
        d = d or self.d
        d.qpos[:] = qe
        d.qvel[:] = ve
        d.qfrc_applied[:] = self.applied
        d.time = 0.0

    def _check(self, q, u=None, t: float = 0.0):
        """Sizes and finiteness of a reference state, as the reference checks them."""
        return check_state(f"{self.model_name} ({self.engine})", self.nq_ref, self.n_ref, q, u, t)

    def forward(self, q, u, t: float = 0.0) -> EngineForward:
        """mj_forward at the mapped state; the RAW soft answer mapped to the reference, with the
        de-regularized (rigid) answer and the impedance-based error prediction in raw."""
        m, d = self.m, self.d
        q, u = self._check(q, u, t)
        qe, ve = self.to_engine_state(q, u)
        self._set(qe, ve)
        mujoco.mj_forward(m, d)
        qe, ve = d.qpos.copy(), d.qvel.copy()
        qacc = d.qacc.copy()
        nefc = d.nefc
        raw: dict = {
            "engine_q": qe,
            "engine_v": ve,
            "engine_accelerations": qacc,
            "nefc": nefc,
            "solver_niter": int(d.solver_niter[0]),
            "sparse_jacobian": bool(mujoco.mj_isSparse(m)),
        }
        if self.variant is not None:
            raw["variant"] = self.variant
        acc = self._acc_to_reference(qe, ve, qacc)
        if nefc == 0:
            self._extra_raw(raw)  # may call mj_rnePostConstraint (cfrc_int): do it first
            lam = self._multipliers(qe, ve, qacc, np.zeros(0))
            raw.update(
                rigid_accelerations=acc.copy(),
                rigid_multipliers=None if lam is None else np.array(lam, float),
            )
            return self._answer(acc, lam, raw)
        if not np.all(d.efc_type[:nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY):
            raise RuntimeError(f"{self.model_name}: unexpected non-equality constraint rows")
        lam = self._soft_recovery(qe, ve, qacc, acc, raw)
        self._extra_raw(raw)
        return self._answer(acc, lam, raw)

    def derivatives(self, q, u, t, directions):
        """MuJoCo's own derivatives of its soft accelerations (mjd_transitionFD) along the
        reference's consistent directions (crosscheck/engines/mujoco/derivatives.py); a model
        without soft rows has none to give (its answer is differenced)."""
        from crosscheck.engines.linearization import derivatives_along
        from crosscheck.engines.mujoco import derivatives as md

        if self.m.neq == 0:
            raise EngineUnsupported("no soft rows: the exact answer is differenced")
        q, u = self._check(q, u, t)
        return derivatives_along(md.maps(self), q, u, directions, forces=False, answer="soft")

    def _soft_recovery(self, qe, ve, qacc, acc, raw) -> np.ndarray:
        """The mapped multipliers of MuJoCo's soft answer at the state in self.d; fills raw
        with the rigid answer recovered from it and its checks (soft_recovery.py)."""
        return soft_recovery(self, qe, ve, qacc, acc, raw)

    @staticmethod
    def _answer(acc, lam, raw) -> EngineForward:
        """The typed answer; raw keeps the same arrays for diagnostics and the engine tests."""
        return EngineForward(
            acc,
            lam,
            raw,
            multipliers_note=raw.get("multipliers_note"),
            rigid_accelerations=raw["rigid_accelerations"],
            rigid_multipliers=raw["rigid_multipliers"],
            predicted_acceleration_error=raw.get("predicted_acceleration_error"),
            predicted_multiplier_error=raw.get("predicted_multiplier_error"),
        )

    def timed_forward(self, q, u):
        """Timing hook for `crosscheck bench`: maps the reference state once (and sets
        qfrc_applied) and returns a zero-argument callable that performs only what forward()
        asks of MuJoCo at that state: write qpos/qvel, mj_forward. It returns d.qacc, a LIVE
        view that the next MuJoCo call on this model overwrites (copy it to keep it); it equals
        forward()'s raw["engine_accelerations"]. No mapping, no recovery, no checks inside."""
        qe, ve = self.to_engine_state(q, u)
        m, d = self.m, self.d
        self._set(qe, ve)
        qe, ve = np.array(qe, float), np.array(ve, float)

        def call():
            d.qpos[:] = qe
            d.qvel[:] = ve
            mujoco.mj_forward(m, d)
            return d.qacc

        return call

    def _light_energy(self, m, d) -> tuple[float, float]:
        """(K, V) of the light bodies (absent from the reference), after mj_forward."""
        K = V = 0.0
        g = m.opt.gravity
        for b in self._light_ids:
            vel = np.zeros(6)
            mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, b, vel, 1)  # local, at com
            K += 0.5 * m.body_mass[b] * float(vel[3:] @ vel[3:])
            K += 0.5 * float(vel[:3] @ (m.body_inertia[b] * vel[:3]))
            V -= m.body_mass[b] * float(g @ d.xipos[b])
        return K, V

    def energy(self, q, u) -> tuple[float, float]:
        """(K, V) from d.energy after mj_forward at the mapped state.

        Datum: MuJoCo's potential is -sum_b m_b g . xipos_b plus the joint springs'
        1/2 k (q - springref)^2 (Exercises 6.1, 6.2, 6.4; springref = the reference's
        unstretched position, so this is the reference's spring potential), zero at the world
        origin; the MJCF world frame is the reference's inertial frame and the reference's
        V = -sum m g . r_G + springs has the same datum (the pivot O / point A), so no constant
        is needed. The light bodies' energy (1e-12 relative) is subtracted."""
        qe, ve = self.to_engine_state(q, u)
        self._set(qe, ve)
        mujoco.mj_forward(self.m, self.d)
        return self._energy_after_forward(self.m, self.d)

    def _energy_after_forward(self, m, d) -> tuple[float, float]:
        V, K = (float(x) for x in d.energy)
        Kl, Vl = self._light_energy(m, d)
        return K - Kl, V - Vl

    def mass_matrix(self, q) -> np.ndarray | None:
        """Engine M in reference coordinates (P^T M_e P) where the engine speeds are a constant
        linear map of the reference's (else None)."""
        if self._P is None:
            return None
        qe, ve = self.to_engine_state(q, np.zeros(self.n_ref))
        self._set(qe, ve)
        mujoco.mj_forward(self.m, self.d)
        return self._P.T @ full_M(self.m, self.d) @ self._P

    def forcing(self, q, u, t: float = 0.0) -> np.ndarray | None:
        """The reference's f (M u' - f = A^T lambda) from MuJoCo: P^T qfrc_smooth, qfrc_smooth =
        qfrc_applied + qfrc_passive - qfrc_bias, or None where the coordinates do not map."""
        if self._P is None:
            return None
        qe, ve = self.to_engine_state(q, u)
        self._set(qe, ve)
        mujoco.mj_forward(self.m, self.d)
        return self._P.T @ self.d.qfrc_smooth

    def violation(self) -> float:
        """max |efc_pos| of the equality rows at the current data (after mj_forward)."""
        return float(np.max(np.abs(self.d.efc_pos[: self.d.nefc]))) if self.d.nefc else 0.0

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
        """Run mj_step from the mapped initial state for round(t_eval[-1] / timestep) steps,
        recording the state at the steps nearest to t_eval (increasing times >= 0 on the step
        grid); the steps between two records are one mj_step(nstep=...) call.

        A fresh MjModel/MjData (same XML) with opt.timestep and opt.integrator set, so forward()
        is not disturbed. At each recorded step the state is read, mapped to the reference,
        and mj_forward is called before reading d.energy and efc_pos (d.energy is lagged after
        mj_step: it belongs to the start of the step, or to the last RK4 stage). mj_forward
        recomputes only derived quantities, so the trajectory is unchanged by it. wall_s is
        the stepping loop (with the recording); steps the mj_step calls.
        """
        if integrator not in INTEGRATORS:
            raise ValueError(f"unknown integrator {integrator!r}; valid: {', '.join(INTEGRATORS)}")
        t_eval = np.asarray(t_eval, dtype=float)
        if timestep is None or not (timestep > 0 and t_eval.size and t_eval[-1] >= 0):
            raise ValueError(
                f"{integrator} takes a fixed step: give timestep > 0 and t_eval "
                f"ending at t >= 0 (got timestep {timestep!r})"
            )
        if t_eval[0] < 0 or np.any(np.diff(t_eval) <= 0):
            raise ValueError("t_eval must be increasing times >= 0")
        marks = np.rint(t_eval / timestep).astype(int)
        if np.max(np.abs(marks * timestep - t_eval)) > 1e-9 * max(1.0, float(t_eval[-1])):
            raise ValueError(f"t_eval is not on the {timestep:g} s step grid")
        m = self._fresh_model()
        m.opt.timestep = float(timestep)
        m.opt.integrator = INTEGRATORS[integrator]
        d = mujoco.MjData(m)
        qe, ve = self.to_engine_state(q0, u0)
        self._set(qe, ve, m, d)
        n_steps, record_at = int(marks[-1]), set(marks.tolist())
        T, Q, U, E, Vi, Vv = [], [], [], [], [], []

        def record():
            mujoco.mj_forward(m, d)
            q, u = self.from_engine_state(d.qpos.copy(), d.qvel.copy())
            T.append(d.time)
            Q.append(q)
            U.append(u)
            E.append(sum(self._energy_after_forward(m, d)))
            Vi.append(float(np.max(np.abs(d.efc_pos[: d.nefc]))) if d.nefc else 0.0)
            Vv.append(float(np.max(np.abs(d.efc_vel[: d.nefc]))) if d.nefc else 0.0)

        t0 = time.perf_counter()
        done = 0
        for mark in sorted(record_at):
            if mark > done:  # the steps between two records in one call (MuJoCo's own loop)
                mujoco.mj_step(m, d, nstep=mark - done)
                done = mark
            record()
        wall = time.perf_counter() - t0
        return EngineTrajectory(
            t=np.array(T),
            q=np.array(Q),
            u=np.array(U),
            violation=np.array(Vi),
            velocity_violation=np.array(Vv),
            energy=np.array(E),
            integrator=integrator,
            setting={"timestep": float(timestep)},
            wall_s=wall,
            steps=n_steps,
            warnings=_warnings(d),
            raw={"solref": self.solref, "solimp": self.solimp},
        )
