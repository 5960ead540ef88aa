"""Consistency of a state with the constraints, and its projection onto the manifold
f(q, t) = 0, A u + a0 = 0 (a mixin of NumericModel, split out of reference/numeric/model.py for its
size)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from reference.errors import OffManifoldError

# A consistent state satisfies its constraints to round-off of the expressions (entries of size
# ~1 in SI): 1e-9 absolute (scaled by the state size) separates "consistent" from "off manifold"
# with a wide margin on both sides.
MANIFOLD_TOL = 1e-9


class ManifoldProjection:
    """NumericModel's check_consistent and project."""

    model: Any
    n: int
    nq: int
    _state: Callable[..., Any]  # NumericModel's methods used here
    _call: Callable[..., np.ndarray]
    residuals: Callable[..., Any]
    matrices: Callable[..., Any]

    def check_consistent(
        self, q: ArrayLike, u: ArrayLike, t: float = 0.0, tol: float = MANIFOLD_TOL
    ) -> None:
        """Refuse a state off the constraint manifold, saying by how much.

        Parameters
        ----------
        q, u : array_like
            The state.
        t : float, optional
            Time, default 0.
        tol : float, optional
            The largest |f(q, t)| (scaled by 1 + max |q|) and |A u + a0| (by 1 + max |u|)
            accepted, default MANIFOLD_TOL.

        Raises
        ------
        OffManifoldError
            A residual above the tolerance; the message gives both and the way out.
        """
        pos, vel = self.residuals(q, u, t)
        worst_p = float(np.max(np.abs(pos))) if pos.size else 0.0
        worst_v = float(np.max(np.abs(vel))) if vel.size else 0.0
        scale = 1.0 + float(np.max(np.abs(q)) if np.size(q) else 0.0)
        if worst_p > tol * scale or worst_v > tol * (1.0 + float(np.max(np.abs(u)))):
            raise OffManifoldError(
                f"{self.model.name}: state is off the constraint manifold: max |f(q,t)| = "
                f"{worst_p:.3e}, max |A u + a0| = {worst_v:.3e} (tolerance {tol:.0e}). "
                f"Give a consistent state or pass --project to project it onto the manifold."
            )

    def project(
        self, q: ArrayLike, u: ArrayLike, t: float = 0.0, tol: float = 1e-13, max_iter: int = 50
    ) -> tuple[np.ndarray, np.ndarray]:
        """The closest consistent state: Gauss-Newton on f(q, t) = 0 (minimum-norm steps in
        q), then the velocity projection u <- u - A^+ (A u + a0).

        Parameters
        ----------
        q, u : array_like
            The state to project.
        t : float, optional
            Time, default 0.
        tol : float, optional
            Gauss-Newton stops at |f| <= tol (1 + max |q|), default 1e-13.
        max_iter : int, optional
            Gauss-Newton steps allowed, default 50.

        Returns
        -------
        tuple of numpy.ndarray
            The projected (q, u).

        Raises
        ------
        ModelInputError
            A bad state (as NumericModel.forward).
        OffManifoldError
            Gauss-Newton did not converge (the constraints may have no solution near q).
        """
        q, u, t = self._state(q, u, t)
        q, u = np.array(q), np.array(u)
        cs_f = self.model.configuration_constraints
        n_pos = len(cs_f)
        for _ in range(max_iter):
            pos, _vel = self.residuals(q, u, t)
            if n_pos == 0 or np.max(np.abs(pos)) <= tol * (1 + np.max(np.abs(q))):
                break
            Aq = self._position_jacobian(q, t)
            dq, *_ = np.linalg.lstsq(Aq, -pos, rcond=None)
            q += dq
        else:
            raise OffManifoldError(
                f"{self.model.name}: projection onto f(q,t)=0 did not converge in {max_iter} "
                f"Gauss-Newton steps (residual {np.max(np.abs(pos)):.2e}); the constraints may "
                f"have no solution near this q (for example a slider-crank with l2 < l1 beyond "
                f"its reach)"
            )
        _, _, A, _ = self.matrices(q, u, t)
        _, vel = self.residuals(q, u, t)
        if A.shape[0]:  # minimum-norm correction: u <- u - A^+ (A u + a0)
            du, *_ = np.linalg.lstsq(A, -vel, rcond=None)
            u = u + du
        return np.asarray(q, float), np.asarray(u, float)

    def _position_jacobian(self, q: ArrayLike, t: float) -> np.ndarray:
        """df/dq (Eq. 4's a_jk of the configuration constraints), for the projection."""
        return self._call("position_jacobian", q, np.zeros(self.n), t).reshape(-1, self.nq)
