"""An engine's own derivatives, in the reference's terms: the engine's Jacobians of its answer
in its own coordinates, carried through the state and answer maps' Jacobians.

A built engine model maps a reference state x = (q, u) to its own, x_e = Phi(x), answers
z_e = (a_e, lambda_e) = G(x_e, tau_e) there and maps the answer back, (u', lambda) =
Psi(x_e, z_e). Along a reference direction d, by the chain rule,

    d(u', lambda) = Psi_x dx_e + Psi_z dz_e,   dx_e = Phi_x d,   dz_e = G_x dx_e + G_tau dtau_e,

where G_x and G_tau are the engine's own derivatives (exact: Pinocchio's analytical ones; or
the engine's own finite differences: MuJoCo's mjd_transitionFD), and the maps' Jacobians
Phi_x d and Psi_x dx_e + Psi_z dz_e are the central differences (fourth order) of the maps
alone: of s -> Phi(x + s d), read in the engine's tangent space, and of s -> Psi(Phi(x + s d),
z_e + s dz_e). The maps are closed-form functions (rotations, trigonometry, Pinocchio's
kinematics), smooth and free of any solve, so their differences are accurate to about 1e-12;
the same stencil at twice the step estimates that error (`EngineDerivatives.map_error`). The
engine's applied forces that depend on the state (the adapters' springs and dampers) are
differenced with the maps: they are the adapter's, not the engine's, routine.

A generalized force tau on the reference's speeds does the same work as an engine force tau_e
on every admissible motion when T^T tau_e = tau, T = dv_e/du (the velocity map's Jacobian, exact
by a unit step: the map is linear in u). Where T is square and invertible, tau_e = T^-T tau is
the same force system and both u' and lambda are compared; otherwise (an engine with fewer or
more speeds) tau_e is the least-norm force with (T N)^T tau_e = N^T tau, N a basis of the
admissible speeds: it moves u' as tau does, but its constraint forces are another split, so
lambda's tau-derivatives are not compared (the notes say so).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

# the maps' difference step, in the units of a unit-norm reference direction (radians and
# metres of size 1): the fourth-order stencil's truncation h^4 |Phi^(5)| / 30 and round-off
# 1.5 eps |Phi| / h both sit near 1e-13 there
MAP_STEP = 1e-3
_WEIGHTS = ((1, 8.0), (-1, -8.0), (2, -1.0), (-2, 1.0))
# a velocity map whose Jacobian has a singular value below this (relative) is not a one to one
# map of speeds
SQUARE_RTOL = 1e-9


@dataclass
class EngineDerivatives:
    """An engine's own derivatives of its answer along consistent directions, in the
    reference's terms (``EngineModel.derivatives``).

    Parameters
    ----------
    blocks : dict
        'dq', 'du', 'dtau' -> (accelerations, multipliers): the derivative of u' (n x k) and
        of lambda (m x k, or None) along the block's k directions (the columns of
        reference.derivatives.directions.Directions; for 'dtau' the unit generalized forces
        on the reference's speeds). A block the engine cannot give is absent.
    method : str
        The engine routine the derivatives come from.
    map_error : float
        The estimated error the maps' linearization adds (scaled as scaled_error).
    notes : dict
        Block or 'multipliers_<block>' -> why it is not given.
    answer : {'exact', 'soft'}
        Which answer's derivatives these are: the engine's exact (rigid) one, judged against
        the reference's exact derivatives, or its raw soft one (MuJoCo), judged against the
        soft derivatives its impedance predicts.
    conditioning : float, optional
        EngineJacobians.conditioning.
    """

    blocks: dict[str, tuple[np.ndarray, np.ndarray | None]]
    method: str
    map_error: float = 0.0
    notes: dict[str, str] = field(default_factory=dict)
    answer: str = "exact"
    conditioning: float | None = None


@dataclass
class EngineJacobians:
    """An engine's answer at one of its states and its own derivatives there.

    Parameters
    ----------
    accelerations, forces : numpy.ndarray
        a_e (nv) and the engine's constraint forces lambda_e (maybe empty).
    da, dforces : dict
        'q' (tangent space), 'v', 'tau' -> the Jacobian of a_e (nv x nv) and of lambda_e
        (its size x nv; dforces empty where there are no forces).
    method : str
        The engine routine.
    conditioning : float, optional
        The condition number of the engine's own regularized solve, where it is worse than
        the reference's KKT matrix's (Pinocchio's proximal mu on dependent rows).
    """

    accelerations: np.ndarray
    forces: np.ndarray
    da: dict[str, np.ndarray]
    dforces: dict[str, np.ndarray]
    method: str
    conditioning: float | None = None


@dataclass
class EngineMaps:
    """What the linearization needs of an engine model: its state map, its tangent, its answer
    map and its state-dependent applied forces.

    Parameters
    ----------
    to_engine : callable
        (q, u) -> (q_e, v_e), the model's to_engine_state.
    tangent : callable
        (q_e0, q_e1) -> the tangent vector from q_e0 to q_e1 (Pinocchio's difference, MuJoCo's
        mj_differentiatePos; q_e1 - q_e0 in flat coordinates).
    back : callable
        (q_e, v_e, a_e, lambda_e) -> (u', lambda or None) in the reference's terms.
    applied : callable
        (q_e, v_e) -> the engine's applied generalized forces at that state.
    jacobians : callable
        (q_e, v_e) -> EngineJacobians at that state.
    fault : callable, optional
        EngineJacobians -> EngineJacobians: a planted error in one of the engine's own blocks
        (crosscheck.checks.derivatives.faults; the tests and `crosscheck sensitivity` only).
    """

    to_engine: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
    tangent: Callable[[np.ndarray, np.ndarray], np.ndarray]
    back: Callable[..., tuple[np.ndarray, np.ndarray | None]]
    applied: Callable[[np.ndarray, np.ndarray], np.ndarray]
    jacobians: Callable[[np.ndarray, np.ndarray], EngineJacobians]
    fault: Callable[[EngineJacobians], EngineJacobians] | None = None


def _stencil(g: Callable[[float], np.ndarray], h: float) -> np.ndarray:
    """The fourth-order central difference of g at 0 with step h."""
    return sum(w * np.asarray(g(k * h), float) for k, w in _WEIGHTS) / (12.0 * h)  # type: ignore


def _scaled(err: np.ndarray, value: np.ndarray) -> float:
    return float(np.max(np.abs(err)) / max(float(np.max(np.abs(value))), 1.0)) if err.size else 0.0


def _pack(acc: np.ndarray, lam: np.ndarray | None) -> np.ndarray:
    return np.concatenate([acc, lam if lam is not None else np.zeros(0)])


class _Linearized:
    """The engine's answer linearized at one reference state."""

    def __init__(self, maps: EngineMaps, q: np.ndarray, u: np.ndarray):
        self.maps, self.q, self.u = maps, q, u
        self.qe, self.ve = (np.asarray(x, float) for x in maps.to_engine(q, u))
        self.jac = maps.jacobians(self.qe, self.ve)
        if maps.fault is not None:
            self.jac = maps.fault(self.jac)
        acc, lam = maps.back(self.qe, self.ve, self.jac.accelerations, self.jac.forces)
        self.n = acc.size
        self.has_lam = lam is not None
        self.map_error = 0.0

    def engine_direction(self, dq: np.ndarray, du: np.ndarray, h: float) -> np.ndarray:
        """(dq_e, dv_e, dtau_applied) of a reference direction: the maps' differences."""
        mp, qe0 = self.maps, self.qe

        def g(s: float) -> np.ndarray:
            qe, ve = mp.to_engine(self.q + s * dq, self.u + s * du)
            qe, ve = np.asarray(qe, float), np.asarray(ve, float)
            return np.concatenate([mp.tangent(qe0, qe), ve, mp.applied(qe, ve)])

        return _stencil(g, h)

    def answer_derivative(self, dxe: np.ndarray, dze: np.ndarray, path, h: float) -> np.ndarray:
        """d/ds Psi(Phi(path(s)), z_e + s dz_e): the answer map's chain rule by differences
        (path None: the state held, only z_e moves)."""
        mp, jac = self.maps, self.jac
        na = jac.accelerations.size

        def g(s: float) -> np.ndarray:
            if path is None:
                qe, ve = self.qe, self.ve
            else:
                qe, ve = (np.asarray(x, float) for x in mp.to_engine(*path(s)))
            ae = jac.accelerations + s * dze[:na]
            fe = jac.forces + s * dze[na:]
            return _pack(*mp.back(qe, ve, ae, fe))

        d1, d2 = _stencil(g, h), _stencil(g, 2 * h)
        self.map_error = max(self.map_error, _scaled((d2 - d1) / 15.0, d1))
        return d1

    def engine_change(self, dxe: np.ndarray, taue: np.ndarray | None = None) -> np.ndarray:
        """dz_e = G_q dq_e + G_v dv_e + G_tau (dtau_applied + tau_e)."""
        jac, nv = self.jac, self.jac.accelerations.size
        dq, dv, dt = dxe[:nv], dxe[nv : 2 * nv], dxe[2 * nv :]
        if taue is not None:
            dt = dt + taue
        parts = [self._change(jac.da, dq, dv, dt)]
        if jac.forces.size:
            parts.append(self._change(jac.dforces, dq, dv, dt))
        return np.concatenate(parts)

    @staticmethod
    def _change(J: dict, dq: np.ndarray, dv: np.ndarray, dt: np.ndarray) -> np.ndarray:
        """J_q dq + J_v dv + J_tau dt; an engine without J_tau (MuJoCo's transitionFD) has no
        applied force that varies with the state."""
        out = J["q"] @ dq + J["v"] @ dv
        return out + J["tau"] @ dt if "tau" in J else out

    def split(self, cols: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray | None]:
        D = np.array(cols).T.reshape(-1, len(cols))
        return D[: self.n], (D[self.n :] if self.has_lam else None)


def derivatives_along(
    maps: EngineMaps,
    q: Any,
    u: Any,
    directions: Any,
    h: float = MAP_STEP,
    forces: bool = True,
    answer: str = "exact",
) -> EngineDerivatives:
    """The engine's own derivatives along the reference's consistent directions, in the
    reference's terms (see the module docstring).

    Parameters
    ----------
    maps : EngineMaps
    q, u : array_like
        A consistent reference state.
    directions : reference.derivatives.directions.Directions
    h : float, optional
        The maps' difference step.
    forces : bool, optional
        Whether the engine's Jacobians hold da/dtau (False: the 'dtau' block is left out).
    answer : {'exact', 'soft'}, optional
        Which answer the Jacobians are of (EngineDerivatives.answer).

    Returns
    -------
    EngineDerivatives
    """
    q, u = np.asarray(q, float), np.asarray(u, float)
    lin = _Linearized(maps, q, u)
    blocks: dict[str, tuple[np.ndarray, np.ndarray | None]] = {}
    for block in ("dq", "du"):
        DQ, DU = directions.state_directions(block)
        cols = []
        for k in range(DQ.shape[1]):
            dq, du = DQ[:, k], DU[:, k]
            dxe = lin.engine_direction(dq, du, h)
            dze = lin.engine_change(dxe)
            cols.append(
                lin.answer_derivative(dxe, dze, lambda s, dq=dq, du=du: (q + s * dq, u + s * du), h)
            )
        blocks[block] = lin.split(cols) if cols else (np.zeros((lin.n, 0)), None)
    notes: dict[str, str] = {}
    if not forces:
        return EngineDerivatives(
            blocks, lin.jac.method, lin.map_error, notes, answer, lin.jac.conditioning
        )
    taus, same_forces = engine_forces(maps, q, u, directions.speeds, lin.ve.size)
    cols = []
    for k in range(taus.shape[1]):
        dze = lin.engine_change(np.zeros(3 * lin.ve.size), taus[:, k])
        cols.append(lin.answer_derivative(np.zeros(0), dze, None, h))
    acc, lam = lin.split(cols)
    if not same_forces and lam is not None:
        lam = None
        notes["multipliers_dtau"] = (
            "the engine's speeds do not map one to one onto the reference's: a force with "
            "the same work on every admissible motion moves u' alike, but its constraint "
            "forces are another split"
        )
    blocks["dtau"] = (acc, lam)
    return EngineDerivatives(
        blocks, lin.jac.method, lin.map_error, notes, answer, lin.jac.conditioning
    )


def engine_forces(
    maps: EngineMaps, q: np.ndarray, u: np.ndarray, N: np.ndarray, nv: int
) -> tuple[np.ndarray, bool]:
    """The engine forces tau_e (nv x n, one column per unit generalized force on the
    reference's speeds) and whether they are the same force systems (T square)."""
    n = u.size
    v0 = np.asarray(maps.to_engine(q, u)[1], float)
    T = np.array([np.asarray(maps.to_engine(q, u + e)[1], float) - v0 for e in np.eye(n)]).T
    s = np.linalg.svd(T, compute_uv=False) if T.size else np.zeros(0)
    if T.shape[0] == T.shape[1] and s.size and s[-1] > SQUARE_RTOL * s[0]:
        return np.linalg.solve(T.T, np.eye(n)), True
    TN = T @ N
    return np.linalg.pinv(TN.T) @ N.T, False
