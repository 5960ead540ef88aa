"""The directions along which two sets of equations of the same system must have the same
derivatives: tangent to the state manifold f(q, t) = 0, A(q, t) u + a0(q, t) = 0.

Off the manifold each formulation (and each engine) extends the equations in its own way: a
quaternion's normalization row, a row scaled by a function of q, another choice of
coordinates. Two extensions that agree on the manifold have the same derivative along every
direction tangent to it, and only there. At a consistent state (q, u) those directions are

- q-directions: dq in the null space of the configuration rows' Jacobian f_q (for Euler
  parameters and quaternions: perpendicular to the parameters themselves, the tangent space of
  the unit sphere), each with the least change of the speeds that keeps the velocity rows
  satisfied, du = -A^+ (d(A u + a0)/dq) dq;
- u-directions: du in the null space of A (dq = 0);
- generalized forces tau: every direction (a force in the range of A^T changes only lambda).

The bases are orthonormal (from SVDs), so a derivative along them is a rotation of the
derivative on the tangent space, not a projection that could hide an entry.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from reference.derivatives.exact import DerivativeModel, Derivatives
from reference.numeric.redundant import RANK_RTOL


@dataclass(frozen=True)
class Directions:
    """Consistent directions at one state, as columns.

    Parameters
    ----------
    dq : numpy.ndarray
        nq x kq: the q-directions' coordinate parts (orthonormal).
    du_of_dq : numpy.ndarray
        n x kq: the speed change that goes with each q-direction.
    du : numpy.ndarray
        n x ku: the u-directions (orthonormal).
    whole : bool
        True: every coordinate and speed alone (whole_jacobians), not the manifold's tangent.
    admissible : numpy.ndarray or None
        An orthonormal basis of the admissible speeds, null(A) (None: the u-directions).
    """

    dq: np.ndarray
    du_of_dq: np.ndarray
    du: np.ndarray
    whole: bool = False
    admissible: np.ndarray | None = None

    @property
    def speeds(self) -> np.ndarray:
        """The admissible speeds' basis, null(A): what a generalized force acts on."""
        return self.du if self.admissible is None else self.admissible

    def whole_jacobians(self) -> Directions:
        """Every coordinate and every speed alone (the Jacobians' columns): for two sets of
        equations known to agree off the manifold as well (the same coordinates and rows)."""
        nq, n = self.dq.shape[0], self.du.shape[0]
        return Directions(np.eye(nq), np.zeros((n, nq)), np.eye(n), True, self.speeds)

    def state_directions(self, block: str) -> tuple[np.ndarray, np.ndarray]:
        """(dq, du) columns of the q-directions ('dq') or the u-directions ('du')."""
        if block == "dq":
            return self.dq, self.du_of_dq
        return np.zeros((self.dq.shape[0], self.du.shape[1])), self.du


def null_space(J: np.ndarray, width: int) -> np.ndarray:
    """An orthonormal basis of the null space of J (width columns where J has no rows), rank
    at reference.numeric.redundant.RANK_RTOL."""
    if J.shape[0] == 0:
        return np.eye(width)
    _u, s, vt = np.linalg.svd(J)
    r = int((s > RANK_RTOL * s[0]).sum()) if s.size and s[0] > 0 else 0
    return vt[r:].T.copy()


def consistent_directions(
    dm: DerivativeModel, q: ArrayLike, u: ArrayLike, t: float = 0.0
) -> Directions:
    """The q- and u-directions at a consistent state (see the module docstring).

    Parameters
    ----------
    dm : DerivativeModel
    q, u : array_like
        A consistent state.
    t : float, optional
        Time.

    Returns
    -------
    Directions
    """
    nm = dm.nm
    q, u = np.asarray(q, float), np.asarray(u, float)
    fq = nm._position_jacobian(q, t) if nm.model.configuration_constraints else np.zeros((0, nm.nq))
    dq = null_space(fq, nm.nq)
    _M, _f, A, _b = nm.matrices(q, u, t)
    if A.shape[0]:
        moved = dm.velocity_jacobian(q, u, t) @ dq
        du_of_dq = -np.linalg.lstsq(A, moved, rcond=RANK_RTOL)[0]
    else:
        du_of_dq = np.zeros((nm.n, dq.shape[1]))
    return Directions(dq, du_of_dq, null_space(A, nm.n))


def along(d: Derivatives, dirs: Directions, of: str, block: str) -> np.ndarray | None:
    """The derivative of `of` ('accelerations', 'multipliers' or 'constraint_forces') along
    the directions of `block` ('dq', 'du': the state directions; 'dtau': every generalized
    force), one column per direction; None where `of`'s derivatives are not given."""
    if block == "dtau":
        return d.block(of, "dtau")
    Jq, Ju = d.block(of, "dq"), d.block(of, "du")
    if Jq is None or Ju is None:
        return None
    dq, du = dirs.state_directions(block)
    return Jq @ dq + Ju @ du
