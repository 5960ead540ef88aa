"""Numeric evaluation of a model: forward dynamics (u', lambda), residuals, energy, projection.

`NumericModel` runs a model's generated code (reference.backends.codegen) on the kernels of its
backend (reference.backends.select: C where a compiler works, else the generated Python) with
validation: parameters are checked once at construction, states on every checked call (sizes,
finiteness), and a KKT solve whose pivots collapse raises instead of returning a wrong number.

Forward dynamics has one checked call and one fast one:

- ``forward(q, u, t)``: the checked call; a Forward record, or an error naming the problem;
- ``forward_fast(q, u, t, db=None, out=None)``: the integrators' and benchmarks' call; u',
  lambda and the pivot ratio (or the same written into `out`), NaN in and NaN out, no raise on
  a singular matrix (the caller tests the ratio); only what the kernel checks cheaply (sizes,
  an expression not defined at the state) raises;
- ``forward_batch(Q, U, t)``: N states in one checked call (reference.numeric.batch).

The other generated functions have their checked calls (matrices, kinematics, residuals,
energy) and, for the integrators, `fast_function(name)`.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from reference.backends import codegen, select
from reference.backends.kernels import NOT_FINITE, OK, PIVOT_RATIO_MIN, SINGULAR, Kernels
from reference.backends.python_kernels import PythonKernels
from reference.constraints import check_independent
from reference.errors import ModelInputError, SingularSystemError
from reference.formulations import derive
from reference.numeric import redundant
from reference.numeric.batch import BatchedForward
from reference.numeric.manifold import MANIFOLD_TOL, ManifoldProjection
from reference.numeric.validate import StateValidation, resolve_parameters
from reference.system import Model

__all__ = ["MANIFOLD_TOL", "PIVOT_RATIO_MIN", "Forward", "NumericModel", "resolve_parameters"]

_ND = np.ndarray
_empty = np.empty
_new = object.__new__  # a Forward built by slot stores: no dataclass __init__ call (hot path)


@dataclass(slots=True)  # slots: a cheaper construction on the checked call's hot path
class Forward:
    """Forward dynamics at one state: what NumericModel.forward returns.

    Parameters
    ----------
    accelerations : numpy.ndarray
        u', one entry per speed.
    multipliers : numpy.ndarray
        lambda, one entry per constraint row in the model's order (the minimum-norm one where
        the rows are dependent).
    pivot_ratio : float
        The smallest pivot of the KKT solve over its reference (> PIVOT_RATIO_MIN here).
    rank : int or None
        The rank of A where the model allows dependent rows, else None.
    """

    accelerations: np.ndarray
    multipliers: np.ndarray
    pivot_ratio: float
    rank: int | None = None


class NumericModel(BatchedForward, ManifoldProjection, StateValidation):
    """A model's equations of motion, evaluated for one formulation and one parameter set.

    Parameters
    ----------
    model : Model
        The model (validated here).
    formulation : str, optional
        'lagrange', 'dalembert' or 'kane'; default the model's first.
    params : dict, optional
        Parameter values replacing the model's defaults (resolve_parameters).
    backend : {None, 'python'}, optional
        'python' keeps this model on the generated Python code whatever CROSSCHECK_BACKEND
        says: for a model evaluated at a few states only, where a C build (about a second)
        would cost more than it saves. None takes the setting (reference.backends.select).

    Raises
    ------
    ModelInputError
        A bad model, formulation, parameter value or backend name; CROSSCHECK_BACKEND=c
        without a working C compiler.
    SingularSystemError
        The KKT matrix is singular at the model's initial state (the parameters or the
        constraint rows are wrong).
    """

    def __init__(
        self,
        model: Model,
        formulation: str | None = None,
        params: dict | None = None,
        backend: str | None = None,
    ):
        if backend not in (None, "python"):
            raise ModelInputError(
                f"backend {backend!r}: a model can ask for 'python' (the uncompiled path) or "
                "None (the setting); the compiled backend is chosen by CROSSCHECK_BACKEND"
            )
        model.validate()
        self.model = model
        self.formulation = formulation or model.formulations[0]
        self.params = resolve_parameters(model, params)
        self.p = tuple(self.params[p.name] for p in model.parameters)
        # the code (and its choice of an augmented solve) depends on the model only: it is
        # generated once with the declared defaults, and the parameters are arguments
        scalar, batched, self.source = codegen.load_compiled(
            lambda: derive(model, self.formulation),
            model,
            self.formulation,
            resolve_parameters(model),
        )
        self.cache_path = scalar["__cache_path__"]  # the derivation cache entry
        meta = scalar["META"]
        self.n = len(model.speeds)
        self.nq = len(model.coordinates)
        self.m = meta["m"]
        self._augmented = meta["augmented"]
        self.redundant = bool(getattr(model, "redundant_constraints", False))
        # a numeric KKT solve per state: dependent rows allowed, or a model too large for the
        # unrolled solve (codegen.UNROLL_KKT_MAX); either way the rank-revealing solve
        self.numeric_kkt = meta.get("kkt") == "numeric"
        self._numeric = self.redundant or self.numeric_kkt
        dims = (self.nq, self.n, len(self.p), self.m)
        self._py = PythonKernels(scalar, batched, self.source, dims)
        self.rank = self.m  # rank of A at the initial state (below m only if redundant)
        self._last_rank: int | None = None  # rank of A at the last numeric solve
        self.sref = self._schur_reference()
        self._k: Kernels = select.kernels(self._py, self.source, self.cache_path.stem, backend)
        self._nlam = self.n + self.m
        self._nf = self._nlam + 1
        self._pack()

    def _pack(self) -> None:
        """What the calls read, for this parameter set: the kernels' parameters `_pa` (the
        parameters, then the Schur references), no b offsets `_db0`, the forward kernel `_kf`
        (the numeric solve where there is no unrolled one), and the checked and fast forward
        calls as the backend binds them (on C one C call each, which hands any state it cannot
        take on its fast path to _forward_checked / _forward_fast_checked unchanged)."""
        k = self._k
        self._pa = k.pack(self.p, self.sref)
        self._db0 = k.zero_db
        if self._numeric:
            self._kf: Callable[..., int] = self._numeric_forward
            self._checked, self._fast = self._forward_checked, self._forward_fast_checked
        else:
            self._kf = k.function("forward")
            self._checked, self._fast = k.bind(
                self._pa, self._db0, Forward, self._forward_checked, self._forward_fast_checked
            )

    @property
    def backend(self) -> str:
        """'c' or 'python': the backend this model's calls run on."""
        return self._k.name

    @property
    def kernels(self) -> Kernels:
        """This model's kernels (reference.backends.kernels): the unchecked layer beneath the
        calls here, for the compiled stepper and the benchmarks."""
        return self._k

    @property
    def kernel_parameters(self) -> np.ndarray:
        """The kernels' `pa` for this parameter set: the parameters, then the Schur
        references."""
        return self._pa

    def with_params(self, params: dict | None) -> NumericModel:
        """The same model and code with other parameter values.

        The code depends on the model only and the values are arguments, so nothing is read or
        built again (2-30 ms saved). The Schur references are recomputed.

        Parameters
        ----------
        params : dict or None
            Parameter values replacing the model's defaults (not this model's values).

        Returns
        -------
        NumericModel
            A new model sharing this one's kernels.

        Raises
        ------
        ModelInputError
            A bad parameter name or value.
        SingularSystemError
            The KKT matrix is singular at the initial state with these values.
        """
        nm = copy.copy(self)
        nm.params = resolve_parameters(self.model, params)
        nm.p = tuple(nm.params[p.name] for p in self.model.parameters)
        nm.sref = nm._schur_reference()
        nm._pack()
        return nm

    def _schur_reference(self) -> tuple[float, ...]:
        """Diagonal of S = A M^-1 A^T at the model's initial state: the scale against which
        the Schur pivots are judged (a pose where a row of A collapses has S_jj -> 0)."""
        if self.m == 0:
            return ()
        q, u = list(map(float, self.model.initial_q)), list(map(float, self.model.initial_u))
        py, n, m = self._py, self.n, self.m
        out = np.empty(py.total["matrices"])
        st = py.function("matrices")(q, u, 0.0, py.pack(self.p, (1.0,) * m), out)
        if st:
            self._fail(st, q, u)
        nn, nf, na = n * n, n * n + n, n * n + n + m * n
        M, A = out[:nn].reshape(n, n), out[nf:na].reshape(m, n)
        if self._augmented:
            M = M + A.T @ A * (np.trace(M) / n) / max((A * A).sum() / m, 1e-300)
        names = self.model.constraint_names or tuple(f"c{j + 1}" for j in range(m))
        if not self.redundant:
            check_independent(A, names, where=f"the initial state of {self.model.name}")
        if self._numeric:  # remember the rank, solve numerically (reference.numeric.redundant)
            self.rank, _s = redundant.numerical_rank(A)
            return (1.0,) * m
        S = A @ np.linalg.solve(M, A.T)
        d = np.diag(S).copy()
        if not np.all(np.isfinite(d)) or np.any(d <= 0):
            raise SingularSystemError(
                f"{self.model.name}: the KKT matrix is singular at the model's initial state "
                f"(diag of A M^-1 A^T = {d}); check the parameters and the constraint rows"
            )
        return tuple(float(x) for x in d)

    # ---- forward dynamics ----------------------------------------------------------------
    def forward(self, q: ArrayLike, u: ArrayLike, t: float = 0.0) -> Forward:
        """u' and lambda at one state (Eqs. 5-9 with A u' = b), checked.

        Parameters
        ----------
        q : array_like
            The coordinates, one number each.
        u : array_like
            The speeds, one number each.
        t : float, optional
            Time (rheonomic constraints and loads), default 0.

        Returns
        -------
        Forward
            u', lambda and the pivot ratio, in fresh arrays.

        Raises
        ------
        ModelInputError
            Wrong sizes, values that are not numbers, NaN or infinity (the message names the
            coordinates or speeds expected).
        SingularSystemError
            The KKT matrix is singular at this state (a kinematic singularity, redundant
            rows), or the derived equations are not defined there (gimbal lock); the message
            says which and how to move past it.
        """
        # through a local: `self._checked(...)` compiles to a method load, which Python 3.11
        # cannot specialize for an instance attribute (measured 15-25 ns more per call)
        checked = self._checked
        return checked(q, u, t)  # type: ignore[no-any-return]

    def forward_fast(
        self, q: ArrayLike, u: ArrayLike, t: float = 0.0, db: Any = None, out: Any = None
    ) -> Any:
        """u', lambda and the pivot ratio at one state, with only the kernel's own checks:
        the integrators' and benchmarks' call.

        Parameters
        ----------
        q, u : array_like
            The state; float64 vectors are the fast case (anything else is converted first).
        t : float, optional
            Time, default 0.
        db : array_like, optional
            An offset of the constraint rows' right side, A u' = b + db (Baumgarte's terms).
        out : numpy.ndarray, optional
            A writable C-contiguous float64 vector of n + m + 1: u' | lambda | the ratio are
            written into it and it is returned.

        Returns
        -------
        tuple or numpy.ndarray
            (u', lambda, pivot ratio), the vectors fresh views of one array; or `out`. A state
            with NaN or infinity gives NaN; a singular KKT matrix gives its ratio (test it
            against PIVOT_RATIO_MIN) and no raise.

        Raises
        ------
        ModelInputError
            Wrong sizes, values that are not numbers, a short `db`, an `out` the kernel cannot
            write (each would otherwise read or write past an array's end).
        SingularSystemError
            The derived equations are not defined at this state (gimbal lock).
        """
        fast = self._fast  # a local, as in forward
        return fast(q, u, t, db, out)

    def _solve(self, q: Any, u: Any, t: Any, db: Any, out: Any) -> tuple:
        """The forward kernel at one state, its inputs converted where it refuses them: the
        state as the kernel took it, and the kernel's status. A refused `out` is an error."""
        kf = self._kf
        if not self._k.takes_sequences and (type(q) is not _ND or type(u) is not _ND):
            q, u, t = self._arrays(q, u, t)
        try:
            st = kf(q, u, t, self._pa, db, out)
        except TypeError:  # not float64 vectors and a number, or an `out` it cannot write
            if not self._out_ok(out):
                raise self._bad_out(out) from None
            q, u, t = self._arrays(q, u, t)
            st = kf(q, u, t, self._pa, db, out)
        return q, u, t, st

    def _forward_checked(self, q: ArrayLike, u: ArrayLike, t: float = 0.0) -> Forward:
        """forward off the bound call: every conversion, check and error message."""
        out = _empty(self._nf)
        q, u, t, st = self._solve(q, u, t, self._db0, out)
        if st:
            self._fail(st, q, u, out)
        n, nl = self.n, self._nlam
        f = _new(Forward)
        f.accelerations, f.multipliers, f.pivot_ratio, f.rank = (
            out[:n],
            out[n:nl],
            out.item(nl),
            self._last_rank if self._numeric else None,
        )
        return f

    def _forward_fast_checked(
        self, q: ArrayLike, u: ArrayLike, t: float = 0.0, db: Any = None, out: Any = None
    ) -> Any:
        """forward_fast off the bound call: conversions, the size checks, NaN out."""
        if db is not None and len(db) < self.m:  # a kernel would read past its end
            raise ModelInputError(
                f"{self.model.name}: db offsets the {self.m} constraint rows' right side; "
                f"got {len(db)} values"
            )
        if out is None:
            buf = _empty(self._nf)
        elif type(out) is _ND and out.shape == (self._nf,):  # the rest: the kernel's checks
            buf = out
        else:  # a kernel writes the first n + m + 1 entries of a longer one
            raise self._bad_out(out)
        q, u, t, st = self._solve(q, u, t, self._db0 if db is None else np.asarray(db, float), buf)
        if st and st != SINGULAR:
            if st != NOT_FINITE:
                self._fail(st, q, u)
            buf[:] = np.nan  # NaN in, NaN out (the caller's ratio test)
        if out is not None:
            return out
        n, nl = self.n, self._nlam
        return buf[:n], buf[n:nl], buf.item(nl)

    def _numeric_forward(self, q: Any, u: Any, t: Any, pa: Any, db: Any, out: Any) -> int:
        """The forward kernel of a model whose KKT solve is numeric: M, f, A, b from the
        backend's matrices kernel, then reference.numeric.redundant's rank-revealing solve."""
        if not self._out_ok(out):  # as the kernels refuse what they cannot write
            raise TypeError("out must be a writable C-contiguous float64 vector of n + m + 1")
        mats = _empty(self._k.total["matrices"])
        st = self._k.function("matrices")(q, u, t, pa, mats)
        if st:
            return st  # type: ignore[no-any-return]
        n, m = self.n, self.m
        nn, nf, na = n * n, n * n + n, n * n + n + m * n
        ud, lam, piv, self._last_rank = redundant.solve(
            mats[:nn].reshape(n, n),
            mats[nn:nf],
            mats[nf:na].reshape(m, n),
            mats[na:] + np.asarray(db, float)[:m],
            rank_expected=self.rank,
            augment=self._augmented,
            where=self.model.name,
        )
        out[:n], out[n : n + m], out[n + m] = ud, lam, piv
        return OK if piv > PIVOT_RATIO_MIN else SINGULAR

    # ---- the other generated functions -------------------------------------------------
    def _call(self, name: str, q: ArrayLike, u: ArrayLike, t: float) -> np.ndarray:
        """The kernel of generated function `name` at one state, checked: its output array."""
        k = self._k
        out = _empty(k.total[name])
        f = k.function(name)
        if not k.takes_sequences and (type(q) is not _ND or type(u) is not _ND):
            q, u, t = self._arrays(q, u, t)
        try:
            st = f(q, u, t, self._pa, out)
        except TypeError:  # not float64 vectors and a number: convert, then call
            q, u, t = self._arrays(q, u, t)
            st = f(q, u, t, self._pa, out)
        if st:
            self._fail(st, q, u)
        return out

    def fast_function(self, name: str) -> Callable[..., tuple]:
        """The integrators' call of generated function `name`, with only the kernel's checks.

        Parameters
        ----------
        name : str
            'matrices', 'kinematics', 'residuals', 'position_jacobian' or 'energy'.

        Returns
        -------
        callable
            f(q, u, t) -> the function's output groups, views of one fresh float64 array
            (NaN where the state holds NaN or infinity). It raises ModelInputError for wrong
            sizes and SingularSystemError where the expressions are not defined at the state.

        Raises
        ------
        KeyError
            No generated function `name` (no 'forward' where the KKT solve is numeric).
        """
        k = self._k
        f, total, offs = k.function(name), k.total[name], k.offsets[name]
        pa, arrays, convert = self._pa, self._arrays, not k.takes_sequences

        def call(q: Any, u: Any, t: float) -> tuple:
            out = _empty(total)
            if convert and (type(q) is not _ND or type(u) is not _ND):
                q, u, t = arrays(q, u, t)
            try:
                st = f(q, u, t, pa, out)
            except TypeError:  # not float64 vectors and a number: convert, then call
                q, u, t = arrays(q, u, t)
                st = f(q, u, t, pa, out)
            if st:
                if st != NOT_FINITE:
                    self._fail(st, q, u)
                out[:] = np.nan
            return tuple(out[a:b] for a, b in offs)

        return call

    def matrices(self, q: ArrayLike, u: ArrayLike, t: float = 0.0) -> tuple[np.ndarray, ...]:
        """M, f, A, b at one state: M u' - f = A^T lambda, A u' = b.

        Parameters
        ----------
        q, u : array_like
            The state.
        t : float, optional
            Time, default 0.

        Returns
        -------
        tuple of numpy.ndarray
            M (n x n), f (n), A (m x n), b (m), views of one fresh array.

        Raises
        ------
        ModelInputError
            A bad state (as forward).
        SingularSystemError
            The expressions are not defined at this state.
        """
        n, m = self.n, self.m
        out = self._call("matrices", q, u, t)
        nn, nf, na = n * n, n * n + n, n * n + n + m * n
        return (out[:nn].reshape(n, n), out[nn:nf], out[nf:na].reshape(m, n), out[na:])

    def kinematics(self, q: ArrayLike, u: ArrayLike, t: float = 0.0) -> np.ndarray:
        """q' = N(q, u, t), checked.

        Parameters
        ----------
        q, u : array_like
            The state.
        t : float, optional
            Time, default 0.

        Returns
        -------
        numpy.ndarray
            One rate per coordinate.

        Raises
        ------
        ModelInputError
            A bad state (as forward).
        SingularSystemError
            The expressions are not defined at this state.
        """
        return self._call("kinematics", q, u, t)

    def residuals(
        self, q: ArrayLike, u: ArrayLike, t: float = 0.0
    ) -> tuple[np.ndarray, np.ndarray]:
        """The constraints' residuals at one state, checked.

        Parameters
        ----------
        q, u : array_like
            The state.
        t : float, optional
            Time, default 0.

        Returns
        -------
        tuple of numpy.ndarray
            The position residuals f(q, t) and the velocity residuals A u + a0.

        Raises
        ------
        ModelInputError
            A bad state (as forward).
        SingularSystemError
            The expressions are not defined at this state.
        """
        out = self._call("residuals", q, u, t)
        k = self._k.sizes["residuals"][0]
        return out[:k], out[k:]

    def energy(self, q: ArrayLike, u: ArrayLike, t: float = 0.0) -> tuple[float, float]:
        """Kinetic and potential energy at one state (gravity from the bodies plus the model's
        springs), checked.

        Parameters
        ----------
        q, u : array_like
            The state.
        t : float, optional
            Time, default 0.

        Returns
        -------
        tuple of float
            (K, V).

        Raises
        ------
        ModelInputError
            A bad state (as forward).
        SingularSystemError
            The expressions are not defined at this state.
        """
        out = self._call("energy", q, u, t)
        return float(out[0]), float(out[1])

    def power_balance(self, q: ArrayLike, u: ArrayLike, t: float = 0.0) -> dict[str, float]:
        """The work-energy terms at one state, checked.

        Parameters
        ----------
        q, u : array_like
            The state.
        t : float, optional
            Time, default 0.

        Returns
        -------
        dict
            'dE_dt' (the exact rate of E = K + V along the motion), 'load_power' (of the
            applied loads), 'constraint_power' (u . A^T lambda = -lambda . a0 on the manifold:
            zero for scleronomic constraints) and 'energy' (K + V).

        Raises
        ------
        ModelInputError, SingularSystemError
            As forward.
        """
        q, u, t = self._state(q, u, t)
        en = self._call("energy", q, u, t)  # K, V, P | dE/dq | dE/du | dE/dt
        _kvp, (a, b), (c, d), (e, _e) = self._k.offsets["energy"]
        K, V, P = en[0], en[1], en[2]
        fw = self.forward(q, u, t)
        qdot = self.kinematics(q, u, t)
        un = np.asarray(u)
        dE = float(np.dot(en[a:b], qdot) + np.dot(en[c:d], fw.accelerations) + en[e])
        _, _, A, _ = self.matrices(q, u, t)
        P_c = float(fw.multipliers @ (A @ un)) if self.m else 0.0
        return {
            "dE_dt": dE,
            "load_power": float(P),
            "constraint_power": P_c,
            "energy": float(K + V),
        }
