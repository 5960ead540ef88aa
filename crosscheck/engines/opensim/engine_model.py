"""Shared machinery of the OpenSim models: building blocks, state, forward, energy, trajectories.

Every model is built in code (no .osim files): bodies, joints, constraints and forces are created
with OpenSim's Python API and ``initSystem`` turns them into a Simbody system. One state is
answered by setting Q, U and t on the model's own ``SimTK::State`` and calling
``model.realizeAcceleration(state)``: Simbody then solves the constrained equations of motion

    M u' + G^T lambda_s = f,   G u' = b          (Simbody's sign: lambda_s on the LEFT)

exactly (a direct factorization; redundant rows, such as the out-of-plane row of a planar point
constraint, get zero multipliers), and ``state.getUDot()`` / ``state.getMultipliers()`` hold the
answers. The reference writes M u' = f + A^T lambda, so every multiplier map flips a sign and
rescales Simbody's row to the textbook's (each model's docstring writes its map; the tests check
each map against ``Constraint.calcConstraintForces``, the body forces the constraint applies).

Engine coordinates: OpenSim's CoordinateSet order (the order the joints' coordinates were
created); ``_q_index`` maps it onto Simbody's Q (and U) slots, so the maps never rely on
Simbody's internal ordering.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
import time
from collections.abc import Sequence
from typing import Any
from xml.etree import ElementTree

import numpy as np
import opensim as osim

from crosscheck.engines.base import EngineForward, EngineModel, EngineTrajectory, EngineUnsupported
from crosscheck.engines.building import check_state

__all__ = ["FIXED_STEP", "INTEGRATORS", "OsimModel", "custom_joint", "point_body", "vec3"]

osim.Logger.setLevelString("Off")  # initSystem's assembly messages are not results

# The Manager's integrators this suite drives (opensim.Manager.IntegratorMethod). All of them
# are Simbody's error-controlled integrators except ExplicitEuler, which takes a fixed step.
INTEGRATORS = {
    "RungeKuttaMerson": osim.Manager.IntegratorMethod_RungeKuttaMerson,
    "RungeKuttaFeldberg": osim.Manager.IntegratorMethod_RungeKuttaFeldberg,
    "RungeKutta3": osim.Manager.IntegratorMethod_RungeKutta3,
    "CPodes": osim.Manager.IntegratorMethod_CPodes,
    "Verlet": osim.Manager.IntegratorMethod_Verlet,
    "SemiExplicitEuler2": osim.Manager.IntegratorMethod_SemiExplicitEuler2,
    "ExplicitEuler": osim.Manager.IntegratorMethod_ExplicitEuler,
}
FIXED_STEP = ("ExplicitEuler",)

# XML elements of a model that do not enter its dynamics (left out of the fingerprint): the
# assembled starting configuration (coordinates' default values) and the display geometry
_NOT_DYNAMICS = {
    "default_value",
    "default_speed_value",
    "FrameGeometry",
    "attached_geometry",
    "Appearance",
}


def vec3(x=0.0, y=0.0, z=0.0) -> osim.Vec3:
    return osim.Vec3(float(x), float(y), float(z))


def point_body(name: str, mass: float) -> osim.Body:
    """A point mass: mass at the body origin, no rotational inertia."""
    return osim.Body(name, float(mass), vec3(), osim.Inertia(0.0))


def lamina(name: str, mass: float, com, I_zz: float) -> osim.Body:
    """A planar bar whose reference inertia is only I_zz: full central inertia
    diag(I_zz/2, I_zz/2, I_zz) (perpendicular-axis theorem; hinges about Z and slides in X, Y
    never excite the in-plane components)."""
    return osim.Body(
        name,
        float(mass),
        vec3(*com),
        osim.Inertia(0.5 * I_zz, 0.5 * I_zz, float(I_zz), 0.0, 0.0, 0.0),
    )


def custom_joint(name, parent, child, translations=(), rotations=(), parent_offset=(0, 0, 0)):
    """A CustomJoint whose coordinates act along exact unit axes (no rotated frames, so no
    cos(pi/2) round-off): ``translations`` / ``rotations`` are (coordinate, axis, scale, offset)
    tuples; the transform is linear in each coordinate (LinearFunction(scale, offset)); the
    joint's parent frame sits at ``parent_offset`` in the parent, its child frame at the child's
    origin."""
    st = osim.SpatialTransform()
    basis = ((1, 0, 0), (0, 1, 0), (0, 0, 1))
    for base, items in ((0, rotations), (3, translations)):
        for k, (coord, axis, scale, offset) in enumerate(items):
            ta = st.updTransformAxis(base + k)
            names = osim.ArrayStr()
            names.append(coord)
            ta.setCoordinateNames(names)
            ta.setAxis(vec3(*axis))
            f = osim.LinearFunction(float(scale), float(offset))
            ta.setFunction(f)
            f.thisown = False  # the transform axis owns it now
        # the unused axes of this kind (no coordinate) must not be collinear with the used
        # ones: OpenSim refuses the joint otherwise; give them the remaining basis vectors
        used = [tuple(float(a) for a in it[1]) for it in items]
        spare = [b for b in basis if b not in used]
        for k in range(len(items), 3):
            st.updTransformAxis(base + k).setAxis(vec3(*spare[k - len(items)]))
    return osim.CustomJoint(name, parent, vec3(*parent_offset), vec3(), child, vec3(), vec3(), st)


class OsimModel(EngineModel):
    """An OpenSim model of one reference model; subclasses build it and write the maps."""

    engine = "opensim"
    nq_ref: int
    n_ref: int
    up = (0.0, 1.0, 0.0)  # engine "up"; gravity is -g up
    multipliers_note: str | None = None  # why forward() returns multipliers None, if it does
    mass_matrix_note = (
        "not mapped: OpenSim's mass matrix is Simbody's (calcM) in its own "
        "coordinates; the comparison uses accelerations and multipliers"
    )

    def __init__(self, model_name: str, params: dict[str, float]):
        self.model_name = model_name
        self.params = dict(params)
        self.model = osim.Model()
        self.model.setName(model_name)
        g = float(params.get("g", 0.0))
        self.model.setGravity(vec3(*(-g * c for c in self.up)))
        self.defaults: dict[str, float] = {}
        self.springs: list[tuple[str, float]] = []  # (coordinate, k) of SpringGeneralizedForces
        self._build()
        if self.defaults:  # an assembled configuration, so initSystem's assembly is trivial
            self.model.finalizeFromProperties()
            cs = self.model.getCoordinateSet()
            for name, value in self.defaults.items():
                cs.get(name).setDefaultValue(float(value))
        self.state = self.model.initSystem()
        cs = self.model.getCoordinateSet()
        self.coords = [cs.get(i) for i in range(cs.getSize())]
        self.nq_e, self.nu_e = self.state.getNQ(), self.state.getNU()
        if self.nu_e != len(self.coords) or self.nq_e < self.nu_e:
            raise EngineUnsupported(
                f"{model_name}: opensim model has coupled coordinates this adapter does not map"
            )
        # Simbody's Q and U slots of each OpenSim coordinate. A BallJoint's three coordinates
        # are body-fixed X-Y-Z Euler angles (OpenSim runs Simbody's balls in Euler-angle mode:
        # R_FM = Rx Ry Rz, measured) in a 4-slot Q block whose last slot is unused; its three
        # speeds are the angular velocity of the child in the parent, parent axes.
        self.state.setQ(osim.Vector([float(i) for i in range(self.nq_e)]))
        self.state.setU(osim.Vector([float(i) for i in range(self.nu_e)]))
        self._q_index = np.array([round(c.getValue(self.state)) for c in self.coords])
        self._u_index = np.array([round(c.getSpeedValue(self.state)) for c in self.coords])
        self.n_multipliers = self.state.getNMultipliers()

    # ---- hooks -----------------------------------------------------------------------------
    def _build(self) -> None:
        raise NotImplementedError

    def _acc_to_reference(self, qe, ve, ae) -> np.ndarray:
        raise NotImplementedError

    def _multipliers(self, lam_s: np.ndarray) -> np.ndarray | None:
        """Reference multipliers from Simbody's (after realizeAcceleration)."""
        return np.zeros(0)

    def joint(self, name: str):
        """A joint of the built model, looked up by name: the Python handle of a joint created
        in _build is not reliable after initSystem (a CustomJoint's reaction read through it
        came back 1e-213, through the model's JointSet right)."""
        return self.model.getJointSet().get(name)

    # ---- the engine state ------------------------------------------------------------------
    def _set_state(self, qe, ve, t: float = 0.0) -> None:
        self._set_state_on(self.state, qe, ve, t)

    def _set_state_on(self, state, qe, ve, t) -> None:
        Q = np.zeros(self.nq_e)  # unused slots (a ball's fourth) stay 0
        U = np.empty(self.nu_e)
        Q[self._q_index] = qe
        U[self._u_index] = ve
        state.setTime(float(t))
        state.setQ(osim.Vector(Q.tolist()))
        state.setU(osim.Vector(U.tolist()))

    def _read(self, vector) -> np.ndarray:
        """A Simbody Q- or U-sized vector in OpenSim coordinate order."""
        out = np.asarray(vector.to_numpy(), float)
        return out[self._q_index] if out.size == self.nq_e else out[self._u_index]

    def _check(self, q, u=None, t: float = 0.0):
        """Sizes and finiteness of a reference state, as the reference checks them."""
        return check_state(f"{self.model_name} ({self.engine})", self.nq_ref, self.n_ref, q, u, t)

    # ---- the EngineModel interface -----------------------------------------------------------
    def forward(self, q, u, t: float = 0.0) -> EngineForward:
        q, u = self._check(q, u, t)
        qe, ve = self.to_engine_state(q, u)
        self._set_state(qe, ve, t)
        self.model.realizeAcceleration(self.state)
        ae = self._read(self.state.getUDot())
        lam_s = np.asarray(self.state.getMultipliers().to_numpy(), float).copy()
        raw = {
            "engine_q": np.asarray(qe, float),
            "engine_v": np.asarray(ve, float),
            "engine_accelerations": ae,
            "engine_multipliers": lam_s,
            "solver": "simbody realizeAcceleration (direct KKT factorization)",
        }
        if self.n_multipliers:
            # Simbody's own residuals at this state: the position-, velocity- and
            # acceleration-level constraint errors it evaluated (max norms)
            raw["qerr"] = float(np.max(np.abs(self.state.getQErr().to_numpy()), initial=0.0))
            raw["uerr"] = float(np.max(np.abs(self.state.getUErr().to_numpy()), initial=0.0))
            raw["udoterr"] = float(np.max(np.abs(self.state.getUDotErr().to_numpy()), initial=0.0))
        self._extra_raw(raw)
        lam = self._multipliers(lam_s)
        note = None
        if lam is None:  # e.g. the top's normalization: the model's class says why
            note = raw["multipliers_note"] = self.multipliers_note
        return EngineForward(
            self._acc_to_reference(qe, ve, ae), lam, raw, multipliers_note=note, iterations=1
        )

    def _extra_raw(self, raw: dict) -> None:
        pass

    def constraint_forces(self, n_bodies: int = 2):
        """Per constraint (after realizeAcceleration), the forces it APPLIES to its constrained
        bodies, ground axes, as a list [(torque, force), ...] in the constraint's body order
        (body1, body2; line body, follower; ...).

        OpenSim's Constraint.calcConstraintForces returns Simbody's G^T lambda, the forces on
        the LEFT of M u' + G^T lambda = f, i.e. the negated applied forces (measured: on the
        pendulum it points the bob's rod force away from the pivot); they are negated here.
        Used by the tests to check each multiplier map independently."""
        out = []
        for i in range(self.model.getConstraintSet().getSize()):
            c = self.model.getConstraintSet().get(i)
            bf = osim.VectorOfSpatialVec()
            mf = osim.Vector()
            c.calcConstraintForces(self.state, bf, mf)
            out.append(
                [
                    (
                        -np.array([bf.get(b).get(0).get(k) for k in range(3)]),
                        -np.array([bf.get(b).get(1).get(k) for k in range(3)]),
                    )
                    for b in range(n_bodies)
                ]
            )
        return out

    def energy(self, q, u) -> tuple[float, float]:
        """Kinetic and potential energy from OpenSim (Model.calcKineticEnergy /
        calcPotentialEnergy: gravity with its zero at the ground origin), plus the generalized
        springs' k q^2 / 2, which calcPotentialEnergy does not include."""
        q, u = self._check(q, u)
        qe, ve = self.to_engine_state(q, u)
        self._set_state(qe, ve)
        return self._energy_of(self.state)

    def _energy_of(self, state) -> tuple[float, float]:
        self.model.realizeVelocity(state)
        V = float(self.model.calcPotentialEnergy(state))
        cs = self.model.getCoordinateSet()
        V += sum(0.5 * k * cs.get(name).getValue(state) ** 2 for name, k in self.springs)
        return float(self.model.calcKineticEnergy(state)), V

    def timed_forward(self, q, u):
        """The state mapped and set once; the callable makes only realizeAcceleration (the state's
        acceleration cache is invalidated first, otherwise Simbody returns the cached answer)."""
        q, u = self._check(q, u)
        qe, ve = self.to_engine_state(q, u)
        self._set_state(qe, ve)
        s, m = self.state, self.model
        U = s.getU()

        def call():
            s.setU(U)  # invalidates the velocity stage and above, as a new state would
            m.realizeAcceleration(s)
            return s.getUDot()

        return call

    def fingerprint(self) -> str:
        """Digest of the built model as OpenSim writes it back (Model.printToXML): every
        body's mass, mass centre and inertia, every joint's type, coordinates' axes and
        functions and its offset frames, the constraints, the forces and prescribed motions,
        gravity. Left out: what is not dynamics (coordinates' default values, the display
        geometry) and the parameter dict itself, so a parameter the built model does
        not contain leaves the digest unchanged."""
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "model.osim")
            self.model.printToXML(path)
            root = ElementTree.parse(path).getroot()  # comments are dropped by the parser
        for parent in list(root.iter()):
            for child in list(parent):
                if child.tag in _NOT_DYNAMICS:
                    parent.remove(child)
        blob = type(self).__name__.encode() + ElementTree.tostring(root)
        return hashlib.sha256(blob).hexdigest()[:16]

    # ---- trajectories ------------------------------------------------------------------------
    def _manager(self, integrator: str, rtol: float | None, timestep: float | None):
        """An opensim.Manager on this model with the integrator set: a fixed step where a
        timestep is given, else the accuracy rtol (default 1e-8), used as the constraint
        tolerance too. Returns it with the setting the trajectory records."""
        manager = osim.Manager(self.model)
        manager.setIntegratorMethod(INTEGRATORS[integrator])
        setting: dict[str, Any] = {"integrator": integrator}
        if timestep is not None:
            manager.setIntegratorFixedStepSize(float(timestep))
            setting["timestep"] = float(timestep)
        else:
            acc = float(rtol) if rtol else 1e-8
            manager.setIntegratorAccuracy(acc)
            manager.setIntegratorConstraintTolerance(acc)
            setting["rtol"] = acc
        return manager, setting

    def simulate(
        self,
        q0,
        u0,
        t_eval: Sequence[float],
        *,
        integrator: str = "RungeKuttaMerson",
        rtol: float | None = None,
        timestep: float | None = None,
    ) -> EngineTrajectory:
        """Integrate with opensim.Manager and one of its integrators (INTEGRATORS).

        Adaptive integrators take ``rtol`` (Manager.setIntegratorAccuracy; default 1e-8);
        ExplicitEuler takes ``timestep`` (Manager.setIntegratorFixedStepSize). Simbody's
        integrators project (q, u) back onto the constraint manifold after every step (to the
        constraint tolerance, set equal to the accuracy): that is the engine's own method and
        is left on. The Manager stops at each output time (``integrate(t)``), so the outputs
        are steps of the integrator, not interpolants.
        """
        if integrator not in INTEGRATORS:
            raise ValueError(
                f"unknown opensim integrator {integrator!r}; valid: {', '.join(INTEGRATORS)}"
            )
        times = np.asarray(t_eval, dtype=float)
        if times.ndim != 1 or times.size == 0 or times[0] < 0 or np.any(np.diff(times) <= 0):
            raise ValueError("t_eval must be increasing times >= 0")
        fixed = integrator in FIXED_STEP
        if fixed and (timestep is None or not timestep > 0):
            raise ValueError(f"{integrator} is a fixed-step integrator: give timestep > 0")
        q0, u0 = self._check(q0, u0)
        qe, ve = self.to_engine_state(q0, u0)
        state = self.model.initializeState()
        self._set_state_on(state, qe, ve, 0.0)
        manager, setting = self._manager(integrator, rtol, timestep if fixed else None)
        # realized before the Manager takes it: an exactly consistent pendulum_xy state handed
        # over unrealized failed at t = 0 ("unable to advance time past 0"), realized it runs
        self.model.realizeAcceleration(state)
        manager.initialize(state)
        Q, U, viol, vviol, E, T = [], [], [], [], [], []
        wall = 0.0
        for t in times:
            if t > 0.0:
                t0 = time.perf_counter()
                state = manager.integrate(float(t))
                wall += time.perf_counter() - t0
            self.model.realizeVelocity(state)
            qe = self._read(state.getQ())
            ve = self._read(state.getU())
            q, u = self.from_engine_state(qe, ve)
            T.append(state.getTime())
            Q.append(q)
            U.append(u)
            viol.append(float(np.max(np.abs(state.getQErr().to_numpy()), initial=0.0)))
            vviol.append(float(np.max(np.abs(state.getUErr().to_numpy()), initial=0.0)))
            E.append(sum(self._energy_of(state)))
        # the Manager records one row per integrator step (plus the initial state and the end
        # of each integrate call); its SimTK::Integrator is not wrapped for Python
        self.last_states_table = manager.getStatesTable()  # every step's state, for subclasses
        steps = int(self.last_states_table.getNumRows()) - 1
        return EngineTrajectory(
            t=np.array(T),
            q=np.array(Q),
            u=np.array(U),
            violation=np.array(viol),
            velocity_violation=np.array(vviol),
            energy=np.array(E),
            integrator=integrator,
            setting=setting,
            wall_s=wall,
            steps=steps,
            raw={"projection": "simbody"},
        )
