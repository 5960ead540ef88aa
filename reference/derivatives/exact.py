"""The exact derivatives of the forward answer (u', lambda) with respect to the coordinates q,
the speeds u and the applied generalized forces tau, at one state of a NumericModel.

The equations are reference.derivatives.codegen's (the implicit function theorem on
M u' - f - tau = A^T lambda, A u' = b). A model whose forward solve is unrolled gets one
generated kernel that solves and differentiates in one call (C where the forward model runs on
C); a model whose KKT solve is numeric (dependent rows, or past codegen.UNROLL_KKT_MAX) gets
the partial derivatives from generated code (on the sums path: complex steps of the forward
module, reference.derivatives.complex_step) and the solve here, on the independent rows:

    [ M    -A_r^T ] [du'/dx]     [ P_x - L_x   ]
    [ A_r   0     ] [dmu/dx ] = -[ U_r^T C_x   ],    dlambda/dx = U_r dmu/dx,

with A = U S V^T, A_r = U_r^T A and lambda = U_r mu (reference.numeric.redundant), U_r held at
the state's value; then d(A^T lambda)/dx = P_x + M du'/dx - dtau/dx (A^T lambda = M u' - f -
tau, whatever lambda's convention). Holding U_r leaves du'/dx exact along every direction on
which the rows stay dependent (where U_r moves, its change only adds a force in the range of
A_r^T, which moves mu, not u'): every direction tangent to the manifold. Where the dependent
combination is the same at every nearby state (a planar loop's identically zero out-of-plane
row), the Jacobians are exact in every direction and dlambda/dx = U_r dmu/dx is the minimum-norm
lambda's; where it moves with the state (a weld on a one-degree-of-freedom chain: five of its
six rows dependent, in a combination that turns with the chain), the rows are independent off
the manifold, where the equations have no solution: the Jacobians are then those of the
equations with the state's independent rows held, exact along the manifold only, and
dlambda/dx is not given.

Derivatives with respect to q are partial derivatives of the model's own equations, which are
defined off the constraint manifold as well; two formulations (or an engine) agree on them
only along directions tangent to the manifold (reference.derivatives.directions).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from reference.backends import select
from reference.backends.kernels import OK, PIVOT_RATIO_MIN, Kernels
from reference.backends.python_kernels import PythonKernels
from reference.derivatives import codegen as dcodegen
from reference.derivatives.complex_step import ComplexStep, unsupported
from reference.errors import SingularSystemError, UnsupportedModelError
from reference.formulations import derive
from reference.numeric.model import NumericModel
from reference.numeric.redundant import RANK_RTOL

# The dependent rows' combination moves with the state where |U_perp^T C_x| is above this times
# the scale of C_x (a row that becomes independent nearby): the minimum-norm lambda's derivative
# would need that combination's own. Round-off of C_x leaves ~1e-16 relative.
DEPENDENCY_RTOL = 1e-10

BLOCKS = ("dq", "du", "dtau")


@dataclass(slots=True)  # slots: a cheaper construction on the checked call
class Derivatives:
    """The forward answer at a state and its derivatives, stacked in one Jacobian whose blocks
    are views (dud_dq ... dforce_dtau, `block`).

    Parameters
    ----------
    accelerations, multipliers : numpy.ndarray
        u' (n) and lambda (m), as NumericModel.forward gives them.
    jacobian : numpy.ndarray
        (n + m) x (nq + 2n): rows u' then lambda, columns q, then u, then tau. Its lambda rows
        are NaN where lambda has no derivative (dependent rows whose dependency moves with the
        state: only A^T lambda has one); with dependent rows they are the minimum-norm
        lambda's.
    nq : int
        The number of coordinates (where the u-columns start).
    pivot_ratio : float
        The KKT solve's smallest pivot ratio.
    rank : int or None
        The rank of A where the model allows dependent rows.
    forces : numpy.ndarray or None
        n x (nq + 2n): d(A^T lambda), the generalized constraint force's derivatives, unique
        where lambda is not; given on the numeric path (None on the unrolled one).

    Notes
    -----
    The blocks dud_dq (n x nq), dud_du (n x n), dud_dtau (n x n), dlam_dq (m x nq), dlam_du,
    dlam_dtau and dforce_dq, dforce_du, dforce_dtau are views; dlam_* and dforce_* are None
    where they are not given.
    """

    accelerations: np.ndarray
    multipliers: np.ndarray
    jacobian: np.ndarray
    nq: int
    pivot_ratio: float
    rank: int | None = None
    forces: np.ndarray | None = None

    def block(self, of: str, by: str) -> np.ndarray | None:
        """One block: `of` 'accelerations', 'multipliers' or 'constraint_forces' (A^T
        lambda), `by` 'dq', 'du' or 'dtau'; None where it is not given."""
        n, nq = self.accelerations.size, self.nq
        cols = {"dq": slice(0, nq), "du": slice(nq, nq + n), "dtau": slice(nq + n, None)}[by]
        if of == "accelerations":
            return self.jacobian[:n, cols]
        if of == "constraint_forces":
            return None if self.forces is None else self.forces[:, cols]
        lam = self.jacobian[n:, cols]
        return None if lam.size and np.isnan(lam).any() else lam

    @property
    def dud_dq(self) -> np.ndarray:
        return self.jacobian[: self.accelerations.size, : self.nq]

    @property
    def dud_du(self) -> np.ndarray:
        n, nq = self.accelerations.size, self.nq
        return self.jacobian[:n, nq : nq + n]

    @property
    def dud_dtau(self) -> np.ndarray:
        n, nq = self.accelerations.size, self.nq
        return self.jacobian[:n, nq + n :]

    @property
    def dlam_dq(self) -> np.ndarray | None:
        return self.block("multipliers", "dq")

    @property
    def dlam_du(self) -> np.ndarray | None:
        return self.block("multipliers", "du")

    @property
    def dlam_dtau(self) -> np.ndarray | None:
        return self.block("multipliers", "dtau")

    @property
    def dforce_dq(self) -> np.ndarray | None:
        return self.block("constraint_forces", "dq")

    @property
    def dforce_du(self) -> np.ndarray | None:
        return self.block("constraint_forces", "du")

    @property
    def dforce_dtau(self) -> np.ndarray | None:
        return self.block("constraint_forces", "dtau")


# The largest model whose derivatives are differentiated symbolically: they write M and f out,
# so their cost grows with the model's size (model_size) as the symbolic path's does. Measured
# cold: the A02 chain 4-28 s from size 279 to 2204, the gripper (692) 6 s, spatial_mix (1034)
# 74 s; Pinocchio's Cassie (2.4e6) did not finish in 25 minutes. The bound is 10x the largest
# size measured to finish. A model on the sums path takes complex steps instead (any size);
# the bound stops only a symbolic path forced past it (CROSSCHECK_DERIVATION=symbolic).
DERIVATIVES_MAX_SIZE = 22_000


def _check_size(model) -> None:
    from reference.formulations import model_size

    size = model_size(model)
    if size > DERIVATIVES_MAX_SIZE:
        raise UnsupportedModelError(
            f"{model.name}: no exact derivatives for a model of size {size} (its bodies' "
            f"velocities and constraint rows as trees; the bound is {DERIVATIVES_MAX_SIZE}): "
            f"they differentiate M and f written out, which does not finish at this size; "
            f"derive on the sums path (complex-step derivatives) or run without --derivatives"
        )


class DerivativeModel:
    """The exact derivatives of one NumericModel's forward answer.

    Parameters
    ----------
    nm : NumericModel
        The model, formulation and parameters (its state checks and errors are used).
    kind : {None, 'kkt', 'residual'}, optional
        The generated module: None chooses 'kkt' where the forward solve is unrolled, else
        'residual' (the numeric solve here); 'residual' on an unrolled model gives the same
        derivatives by the other path (tests compare the two).
    backend : {None, 'python'}, optional
        'python' keeps the generated Python code; None takes the setting, as NumericModel.
    method : {None, 'symbolic', 'complex_step'}, optional
        How R's partial derivatives are taken: 'symbolic' differentiates M and f written out
        (reference.derivatives.codegen), 'complex_step' steps the forward module itself
        (reference.derivatives.complex_step; sums path only). None: complex steps where the
        forward module is summed, else symbolic.

    Notes
    -----
    The symbolic module is generated on the first use of a model and formulation and cached on
    disk (reference.derivatives.codegen); the forward model's code and cache are not touched.
    Complex steps generate nothing.
    """

    def __init__(
        self,
        nm: NumericModel,
        kind: str | None = None,
        backend: str | None = None,
        method: str | None = None,
    ):
        self.nm = nm
        self.kind = kind or ("residual" if nm._numeric else "kkt")
        if self.kind == "kkt" and nm._numeric:
            raise ValueError(f"{nm.model.name}: its KKT solve is numeric: use kind='residual'")
        self.method = method or ("complex_step" if nm._py.summed else "symbolic")
        self.n, self.nq, self.m = nm.n, nm.nq, nm.m
        self._nlam = self.n + self.m
        self._shape = (self.n + self.m, self.nq + 2 * self.n)
        self._steps: ComplexStep | None = None
        if self.method == "complex_step":
            self._complex_steps(nm)
        elif self.method == "symbolic":
            self._generated(nm, backend)
        else:
            raise ValueError(f"method {method!r}: 'symbolic' or 'complex_step'")

    def _complex_steps(self, nm: NumericModel) -> None:
        """R's partial derivatives by complex steps of the forward module (sums path)."""
        if self.kind != "residual" or not nm._py.summed:
            raise ValueError(f"{nm.model.name}: complex steps need a summed module's numeric solve")
        bad = unsupported(nm.source)
        if bad:
            raise UnsupportedModelError(
                f"{nm.model.name}: no complex-step derivatives through {', '.join(sorted(bad))} "
                f"(not analytic, or no complex version)"
            )
        self._steps = ComplexStep(nm)
        # no module of its own: the forward one is differentiated
        self.source, self.cache_path = nm.source, nm.cache_path
        self.kernels: Kernels = nm._py

    def _generated(self, nm: NumericModel, backend: str | None) -> None:
        """The symbolic partial derivatives' generated module (its own cache entry)."""
        model, f = nm.model, nm.formulation
        _check_size(model)
        scalar, batched, src, path = dcodegen.load(
            lambda: derive(model, f), model, f, self.kind, bool(nm._augmented)
        )
        self.source, self.cache_path = src, path
        npa = len(nm.p) + (self.m if self.kind == "kkt" else self.n + self.m)
        dims = (self.nq, self.n, npa, 0)
        py = PythonKernels(scalar, batched, src, dims)
        self.kernels = select.kernels(py, src, path.stem, backend)
        fname = "derivatives" if self.kind == "kkt" else "residual_jacobians"
        self._fn = self.kernels.function(fname)
        self._vj = self.kernels.function("velocity_jacobian")
        self._nout = self.kernels.total[fname]

    def for_model(self, nm: NumericModel) -> DerivativeModel:
        """The same generated code and kernels for another parameter set of the same model and
        formulation (NumericModel.with_params): nothing is read or built again.

        Parameters
        ----------
        nm : NumericModel
            The model at other parameter values.

        Returns
        -------
        DerivativeModel
        """
        if nm.cache_path != self.nm.cache_path:
            raise ValueError(f"{nm.model.name}: another model or formulation's code")
        other = copy.copy(self)
        other.nm = nm
        if self._steps is not None:  # the steps take the parameters from their model
            other._steps = ComplexStep(nm)
        return other

    @property
    def backend(self) -> str:
        """'c' or 'python': where the generated derivative code runs."""
        return self.kernels.name

    # ---- the unrolled path ------------------------------------------------------------------
    def fast(self, q: np.ndarray, u: np.ndarray, t: float = 0.0, out: np.ndarray | None = None):
        """The generated kernel's output at one state, unchecked but for the kernel's own
        checks ('kkt' modules only): u', lambda, the stacked Jacobian (Derivatives.jacobian,
        row-major), the pivot ratio; the benchmarks' call.

        Parameters
        ----------
        q, u : numpy.ndarray
            float64 vectors.
        t : float, optional
            Time.
        out : numpy.ndarray, optional
            A float64 vector to write into.

        Returns
        -------
        tuple
            (status, out).
        """
        if out is None:
            out = np.empty(self._nout)
        return self._fn(q, u, t, self.nm.kernel_parameters, out), out

    def at(self, q: ArrayLike, u: ArrayLike, t: float = 0.0) -> Derivatives:
        """The forward answer and its derivatives at one state, checked.

        Parameters
        ----------
        q, u : array_like
            The state (need not be consistent: the equations are defined off the manifold).
        t : float, optional
            Time, default 0.

        Returns
        -------
        Derivatives

        Raises
        ------
        ModelInputError
            A bad state (as NumericModel.forward).
        SingularSystemError
            The KKT matrix is singular at the state (as NumericModel.forward).
        """
        if type(q) is not np.ndarray or type(u) is not np.ndarray:
            q, u, t = self.nm._arrays(q, u, t)
        if self.kind == "kkt":
            return self._unrolled(q, u, t)
        return self._numeric(*self.nm._arrays(q, u, t))

    def _unrolled(self, q: np.ndarray, u: np.ndarray, t: float) -> Derivatives:
        out = np.empty(self._nout)
        try:
            st = self._fn(q, u, t, self.nm.kernel_parameters, out)
        except TypeError:  # not float64 vectors: converted, then called
            q, u, t = self.nm._arrays(q, u, t)
            st = self._fn(q, u, t, self.nm.kernel_parameters, out)
        piv = out.item(-1)
        if st != OK or not piv > PIVOT_RATIO_MIN:
            self.nm.forward(q, u, t)  # raises the forward's own error where it has one
            raise SingularSystemError(self.nm.singular_message(q, piv))
        n, nl = self.n, self._nlam
        return Derivatives(out[:n], out[n:nl], out[nl:-1].reshape(self._shape), self.nq, piv)

    # ---- the numeric path -------------------------------------------------------------------
    def residual_jacobians(
        self, q: np.ndarray, u: np.ndarray, t: float, ud: np.ndarray, lam: np.ndarray
    ) -> dict[str, np.ndarray]:
        """R's partial derivatives at (u', lambda) ('residual' modules): P_x, L_x, C_x for
        x = q and u (see reference.derivatives.codegen)."""
        if self._steps is not None:
            return self._steps.residual_jacobians(q, u, t, ud, lam)
        pa = np.concatenate([np.asarray(self.nm.p, float), ud, lam])
        out = np.empty(self._nout)
        st = self._fn(q, u, t, pa, out)
        if st != OK:
            self.nm.forward(q, u, t)
            raise SingularSystemError(self.nm.singular_message(q, float("nan")))
        n, nq, m = self.n, self.nq, self.m
        sizes = (n * nq, n * nq, m * nq, n * n, n * n, m * n)
        parts = np.split(out, np.cumsum(sizes)[:-1])
        keys = ("P_q", "L_q", "C_q", "P_u", "L_u", "C_u")
        cols = {"q": nq, "u": n}
        return {k: p.reshape(-1, cols[k[-1]]) for k, p in zip(keys, parts, strict=True)}

    def _numeric(self, q: np.ndarray, u: np.ndarray, t: float) -> Derivatives:
        nm, n, nq = self.nm, self.n, self.nq
        fw = nm.forward(q, u, t)
        ud, lam = fw.accelerations, fw.multipliers
        M, _f, A, _b = nm.matrices(q, u, t)
        J = self.residual_jacobians(q, u, t, ud, lam)
        P = np.hstack([J["P_q"], J["P_u"]])
        E = P - np.hstack([J["L_q"], J["L_u"]])
        Cx = np.hstack([J["C_q"], J["C_u"]])
        Ur, Ar, fixed = self._independent_rows(A, Cx)
        r = Ar.shape[0]
        K = np.block([[M, -Ar.T], [Ar, np.zeros((r, r))]])
        rhs = -np.vstack([E, Ur.T @ Cx])
        tau = np.vstack([np.eye(n), np.zeros((r, n))])
        X = np.linalg.solve(K, np.hstack([rhs, tau]))
        dud = X[:n]
        dlam = Ur @ X[n:] if fixed else np.full((self.m, X.shape[1]), np.nan)
        dforce = np.hstack([P, np.zeros((n, n))]) + M @ dud
        dforce[:, nq + n :] -= np.eye(n)
        stacked = np.vstack([dud, dlam])
        return Derivatives(ud, lam, stacked, nq, fw.pivot_ratio, fw.rank, dforce)

    def _independent_rows(self, A: np.ndarray, Cx: np.ndarray) -> tuple:
        """U_r and A_r = U_r^T A of A's independent rows (all of them without dependent rows),
        and whether the dependent combination stays put (U_perp^T C_x = 0: then lambda's
        derivative is the minimum-norm lambda's)."""
        m = A.shape[0]
        if m == 0:
            return np.zeros((0, 0)), np.zeros((0, self.n)), True
        U, s, _vt = np.linalg.svd(A)
        r = int((s > RANK_RTOL * s[0]).sum()) if s[0] > 0 else 0
        Ur = U[:, :r]
        fixed = True
        if r < m:
            moved = float(np.max(np.abs(U[:, r:].T @ Cx)))
            fixed = moved <= DEPENDENCY_RTOL * max(float(np.max(np.abs(Cx))), 1.0)
        return Ur, Ur.T @ A, fixed

    def velocity_jacobian(self, q: ArrayLike, u: ArrayLike, t: float = 0.0) -> np.ndarray:
        """d(A u + a0)/dq at a state (m x nq): how the velocity rows move with q.

        Parameters
        ----------
        q, u : array_like
            The state.
        t : float, optional
            Time, default 0.

        Returns
        -------
        numpy.ndarray
        """
        q, u, t = self.nm._arrays(q, u, t)
        if self._steps is not None:
            return self._steps.velocity_jacobian(q, u, t)
        pa = self.nm.kernel_parameters
        if self.kind == "residual":
            pa = np.concatenate([np.asarray(self.nm.p, float), np.zeros(self.n + self.m)])
        out = np.empty(self.kernels.total["velocity_jacobian"])
        st = self._vj(q, u, t, pa, out)
        if st != OK:
            self.nm.forward(q, u, t)
            raise SingularSystemError(self.nm.singular_message(q, float("nan")))
        return out.reshape(self.m, self.nq)
