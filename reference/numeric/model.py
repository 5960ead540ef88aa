"""Numeric evaluation of a model: forward dynamics (u', lambda), residuals, energy, projection.

`NumericModel` wraps the compiled code of reference.backends.codegen with validation: parameters are
checked once at construction, states on every public call (sizes, finiteness), and a KKT solve
whose pivots collapse raises instead of returning a wrong number.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from reference.backends import codegen
from reference.backends import numba_backend as compiled
from reference.constraints import check_independent
from reference.errors import ModelInputError, SingularSystemError
from reference.formulations import derive
from reference.numeric import redundant
from reference.numeric.batch import BatchedForward
from reference.numeric.manifold import MANIFOLD_TOL, ManifoldProjection  # noqa: F401  (MANIFOLD_TOL: public here)
from reference.system import Model

# A pivot of M or of the Schur complement S below this fraction of its original diagonal entry
# means the KKT matrix is singular to working precision: 1e-12 leaves 4 digits of a double's 16
# for the answer, the least a validation suite can call a number.
PIVOT_RATIO_MIN = 1e-12

_ND = np.ndarray
_empty = np.empty
_new = object.__new__  # a Forward built by slot stores: no dataclass __init__ call (hot path)


def resolve_parameters(model: Model, overrides: dict | None = None) -> dict[str, float]:
    """The model's parameter values with `overrides`, checked: names, finiteness, signs."""
    overrides = dict(overrides or {})
    names = [p.name for p in model.parameters]
    unknown = sorted(set(overrides) - set(names))
    if unknown:
        raise ModelInputError(
            f"unknown parameter(s) {unknown} for model {model.name!r}; valid: {', '.join(names)}"
        )
    values, problems = {}, []
    for p in model.parameters:
        v = overrides.get(p.name, p.default)
        try:
            v = float(v)
        except (TypeError, ValueError):
            problems.append(f"{p.name}={v!r} is not a number")
            continue
        if not math.isfinite(v):
            problems.append(f"{p.name}={v} is not finite")
        elif p.positive and v <= 0:
            problems.append(f"{p.name}={v} must be > 0 ({p.description})")
        elif p.nonnegative and v < 0:
            problems.append(f"{p.name}={v} must be >= 0 ({p.description})")
        values[p.name] = v
    if problems:
        raise ModelInputError(f"model {model.name!r}: " + "; ".join(problems))
    return values


def _floats(x: Any) -> list[float]:
    """Values as a list of Python floats (the compiled code is fastest on plain floats)."""
    if type(x) is np.ndarray:
        if x.ndim == 1 and x.dtype == np.float64:  # the common case, kept cheap
            return x.tolist()
        return x.astype(float, copy=False).reshape(-1).tolist()
    return [float(v) for v in x]


@dataclass(slots=True)  # slots: a cheaper construction on the checked call's hot path
class Forward:
    accelerations: np.ndarray  # u'
    multipliers: np.ndarray  # lambda, constraint order (minimum norm when rows are dependent)
    pivot_ratio: float
    rank: int | None = None  # rank of A where the model allows dependent rows, else None


class NumericModel(BatchedForward, ManifoldProjection):
    """Compiled numeric model for one formulation and one parameter set."""

    def __init__(
        self,
        model: Model,
        formulation: str | None = None,
        params: dict | None = None,
        backend: str | None = None,
    ):
        """``backend="python"`` keeps this model on the uncompiled path whatever the setting
        (reference.backends.numba_backend.backend): for a model evaluated at a few states only,
        where a compile would cost more than it saves (1-2 s of the C compiler per module,
        scripts/c_build_times.py). None takes the setting."""
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
        self._scalar, self._batched, self.source = codegen.load_compiled(
            lambda: derive(model, self.formulation),
            model,
            self.formulation,
            resolve_parameters(model),
        )
        self.n = len(model.speeds)
        self.nq = len(model.coordinates)
        self.m = self._scalar["META"]["m"]
        self.redundant = bool(getattr(model, "redundant_constraints", False))
        # a numeric KKT solve per state: dependent rows allowed, or a model too large for the
        # unrolled solve (codegen.UNROLL_KKT_MAX); either way the rank-revealing solve
        self.numeric_kkt = self._scalar["META"].get("kkt") == "numeric"
        self._numeric = self.redundant or self.numeric_kkt
        self.rank = self.m  # rank of A at the initial state (below m only if redundant)
        self.sref = self._schur_reference()
        self._no_db = (0.0,) * self.m
        self._k = self._kernels(backend or compiled.backend())
        # every single-state kernel compiled or loaded here (the batch kernels on first use)
        # (no forward kernel where the solve is numeric: dependent rows or a large model)
        self._kf: Any = None if self._numeric or self._k is None else self._k.get("forward")
        if self._k is not None:  # the other single-state kernels too: a first-use compile
            for name in compiled.FUNCTIONS:  # must not land inside a timed or wall-bounded
                if name in self._k.sizes:  # call (simulate's max_wall_s, a benchmark loop)
                    self._k.get(name)
        self._nlam = self.n + self.m
        self._pack()

    def _kernels(self, which: str) -> Any:
        """The compiled kernels of this model's code on backend `which`: C
        (reference.backends.c_build), else numba, else None (the pure-Python path). A model the C
        printer cannot translate, or a compiler that rejects it, takes numba; the reason is in
        bench.json's `compiled`."""
        if which == "python" or codegen.numeric_kkt(self.n, self.m):
            # numba's compile of a large model's long straight-line M, A code costs more than
            # the run (docs/scaling.md); a small model with dependent rows keeps its kernels
            # for M, A, residuals and energy (its forward is the numeric solve either way)
            return None
        path = self._scalar["__cache_path__"]
        args = (self.source, path.stem, path.parent, self.nq, self.n, len(self.p), self.m)
        if which == "c":
            from reference.backends import c_build as cbuild
            from reference.backends import c_source as ckernels

            try:
                return cbuild.load_kernels(*args, PIVOT_RATIO_MIN)
            except (cbuild.BuildError, ckernels.UnsupportedExpression, RecursionError) as exc:
                compiled.TIMINGS.setdefault(path.stem, {})["c_error"] = str(exc)
                if not compiled.numba_available():
                    return None
        try:
            return compiled.load_kernels(*args, PIVOT_RATIO_MIN)
        except RecursionError:
            # expressions nested deeper than Python's ast printer goes (a large user model):
            # this model stays on the pure-Python path, the same numbers, only slower
            return None

    def _pack(self) -> None:
        """Parameters and Schur references as one array (the kernels' _pa), zero b offsets,
        `_fast`: what the compiled forward calls read, one attribute to unpack instead of
        six (None where forward has no kernel: the Python backend or a numeric KKT solve),
        and on the C backend `_cforward`/`_craw`: the checked and raw calls bound to these
        parameters, one C call each (reference/backends/ckernel_runtime.h; any state they cannot
        take on their fast path goes to `_forward_checked`/`_forward_raw_checked` unchanged)."""
        self._pa = np.array(self.p + self.sref, float)
        self._db0 = np.zeros(max(self.m, 1))
        self._nf = self.n + self.m + 1
        kf = None if self._numeric else self._kf
        self._fast = None if kf is None else (kf, self._nf, self._pa, self._db0, self.n, self._nlam)
        bind = getattr(self._k, "bind", None) if kf is not None else None
        self._cforward = (
            None if bind is None else bind(self._pa, self._db0, Forward, self._forward_checked)
        )
        self._craw = (
            None if bind is None else bind(self._pa, self._db0, None, self._forward_raw_checked)
        )

    @property
    def backend(self) -> str:
        """'c', 'numba' or 'python': what this model's calls run."""
        if self._k is None:
            return "python"
        return "c" if hasattr(self._k, "bind") else "numba"

    def with_params(self, params: dict | None) -> NumericModel:
        """The same compiled model with other parameter values, without reading and compiling
        the code again (2-30 ms): the code depends on the model only, the values are
        arguments. The Schur reference is recomputed, so a singular parameter set raises here
        exactly as in the constructor."""
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
        M, _f, A, _b = self._scalar["matrices"](q, u, 0.0, self.p)
        M = np.array(M, float).reshape(self.n, self.n)
        A = np.array(A, float).reshape(self.m, self.n)
        if self._scalar["META"]["augmented"]:
            M = M + A.T @ A * (np.trace(M) / self.n) / max((A * A).sum() / self.m, 1e-300)
        names = self.model.constraint_names or tuple(f"c{j + 1}" for j in range(self.m))
        if not self.redundant:
            check_independent(A, names, where=f"the initial state of {self.model.name}")
        if self._numeric:  # remember the rank, solve numerically (reference.numeric.redundant)
            self.rank, _s = redundant.numerical_rank(A)
            return (1.0,) * self.m
        S = A @ np.linalg.solve(M, A.T)
        d = np.diag(S).copy()
        if not np.all(np.isfinite(d)) or np.any(d <= 0):
            raise SingularSystemError(
                f"{self.model.name}: the KKT matrix is singular at the model's initial state "
                f"(diag of A M^-1 A^T = {d}); check the parameters and the constraint rows"
            )
        return tuple(float(x) for x in d)

    # ---- validation --------------------------------------------------------------------
    def _state(self, q: ArrayLike, u: ArrayLike, t: float) -> tuple[list, list, float]:
        """Validated state as Python float lists (cheap: this runs on every public call)."""
        try:
            ql, ul, t = _floats(q), _floats(u), float(t)
        except (TypeError, ValueError) as exc:
            raise ModelInputError(
                f"{self.model.name}: state values must be numbers ({exc})"
            ) from None
        if len(ql) != self.nq:
            raise ModelInputError(
                f"{self.model.name}: expected {self.nq} coordinates "
                f"({', '.join(s.name for s in self.model.coordinates)}), got {len(ql)}"
            )
        if len(ul) != self.n:
            raise ModelInputError(
                f"{self.model.name}: expected {self.n} speeds "
                f"({', '.join(s.name for s in self.model.speeds)}), got {len(ul)}"
            )
        if not math.isfinite(sum(ql) + sum(ul) + t) and not (
            all(map(math.isfinite, ql)) and all(map(math.isfinite, ul)) and math.isfinite(t)
        ):
            raise ModelInputError(f"{self.model.name}: state contains NaN or infinite values")
        return ql, ul, t

    def _arrays(self, q: ArrayLike, u: ArrayLike, t: float) -> tuple[np.ndarray, np.ndarray, float]:
        """(q, u, t) as the kernels take them: writable contiguous float64 vectors and a float
        (the slow path: the kernels accept only that signature, anything else is converted
        here). Sizes and finiteness are checked inside the kernel (compiled.STATUS)."""
        try:
            return (
                np.array(q, dtype=float).reshape(-1),
                np.array(u, dtype=float).reshape(-1),
                float(t),
            )
        except (TypeError, ValueError) as exc:
            raise ModelInputError(
                f"{self.model.name}: state values must be numbers ({exc})"
            ) from None

    def _fail(self, status: int, q: ArrayLike, u: ArrayLike, out: Any = None) -> None:
        """The error of a kernel's nonzero status, worded as on the pure-Python path."""
        if status in (compiled.BAD_Q_SIZE, compiled.BAD_U_SIZE, compiled.NOT_FINITE):
            self._state(q, u, 0.0)  # raises the size or finiteness error
            raise ModelInputError(f"{self.model.name}: state contains NaN or infinite values")
        if status == compiled.SINGULAR:
            raise SingularSystemError(self._singular_message(q, float(out[-1])))
        if status == compiled.NOT_DEFINED:
            raise self._undefined(q)
        raise RuntimeError(f"{self.model.name}: compiled kernel returned status {status}")

    def _call(self, name: str, q: ArrayLike, u: ArrayLike, t: float) -> Any:
        """Run the checked kernel `name` at one state: its flat output array."""
        out = np.empty(self._k.total[name])
        f = self._k.get(name)
        if type(q) is not _ND or type(u) is not _ND:
            q, u, t = self._arrays(q, u, t)
        try:
            st = f(q, u, t, self._pa, out)
        except TypeError:  # not float64 vectors and a float: convert, then call
            q, u, t = self._arrays(q, u, t)
            st = f(q, u, t, self._pa, out)
        if st:
            self._fail(st, q, u)
        return out

    # ---- single state ------------------------------------------------------------------
    def forward(self, q: ArrayLike, u: ArrayLike, t: float = 0.0) -> Forward:
        """u' and lambda at one state (Eqs. 5-9 with A u' = b)."""
        cf = self._cforward
        if cf is not None:  # one C call; any state it cannot take goes to _forward_checked
            return cf(q, u, t)  # type: ignore[no-any-return]
        return self._forward_checked(q, u, t)

    def _forward_checked(self, q: ArrayLike, u: ArrayLike, t: float = 0.0) -> Forward:
        """forward through the kernel-signature call or the Python path: every conversion,
        check and error message."""
        fast = self._fast
        if fast is not None:  # the compiled kernel; dependent rows take the rank-revealing solve
            kf, nf, pa, db0, n, nl = fast
            out = _empty(nf)
            if type(q) is not _ND or type(u) is not _ND:  # lists: convert first (a failed
                q, u, t = self._arrays(q, u, t)  # dispatch costs numba ~1 ms to explain)
            try:
                st = kf(q, u, t, pa, db0, out)
            except TypeError:  # not float64 vectors and a float: convert, then call
                q, u, t = self._arrays(q, u, t)
                st = kf(q, u, t, pa, db0, out)
            if st:
                self._fail(st, q, u, out)
            f = _new(Forward)
            f.accelerations, f.multipliers, f.pivot_ratio, f.rank = (
                out[:n],
                out[n:nl],
                out.item(nl),
                None,
            )
            return f
        q, u, t = self._state(q, u, t)
        if self._numeric:
            ud, lam, piv = self.forward_raw(q, u, t)
            if not piv > PIVOT_RATIO_MIN:
                raise SingularSystemError(self._singular_message(q, piv))
            return Forward(
                np.asarray(ud, float), np.asarray(lam, float), float(piv), self._last_rank
            )
        try:
            ud, lam, piv = self._scalar["forward"](q, u, t, self.p, self.sref, self._no_db)
        except ValueError:  # sqrt of a negative pivot
            piv = -1.0
        except ZeroDivisionError:  # a zero pivot, or a coordinate singularity in M, f, A, b
            self.matrices(q, u, t)  # raises the latter's error
            piv = -1.0
        if not piv > PIVOT_RATIO_MIN:
            raise SingularSystemError(self._singular_message(q, piv))
        return Forward(np.array(ud, dtype=float), np.array(lam, dtype=float), float(piv))

    def forward_raw(
        self, q: ArrayLike, u: ArrayLike, t: float, db: Any = None, out: Any = None
    ) -> Any:
        """Fast path for integrators: (u', lambda, pivot ratio) without raising on a singular
        KKT matrix (the caller tests the ratio); NaN in, NaN out. Sizes are still checked (an
        unchecked compiled read past an array's end would return garbage). `db` offsets the
        constraint rows' right side: A u' = b + db (Baumgarte). Lists or float64 vectors in;
        fresh vectors out on the compiled backend, lists on the Python one. With `out` (a
        writable float64 vector of n + m + 1, as forward_into's): u' | lambda | the ratio are
        written into it and `out` itself is returned, on either backend."""
        cr = self._craw
        if cr is not None:  # one C call; anything it cannot take goes to _forward_raw_checked
            return cr(q, u, t, db, out)
        return self._forward_raw_checked(q, u, t, db, out)

    def _forward_raw_checked(
        self, q: ArrayLike, u: ArrayLike, t: float, db: Any = None, out: Any = None
    ) -> Any:
        """forward_raw through the kernel-signature call or the Python path."""
        if db is not None and len(db) < self.m:  # a kernel would read past its end
            raise ModelInputError(
                f"{self.model.name}: db offsets the {self.m} constraint rows' right side; "
                f"got {len(db)} values"
            )
        fast = self._fast
        if fast is None:
            return self._forward_raw_other(q, u, t, db, out)
        kf, nf, pa, db0, n, nl = fast
        buf = _empty(nf) if out is None else out
        db = db0 if db is None else np.asarray(db, float)
        if type(q) is not _ND or type(u) is not _ND:
            q, u, t = self._arrays(q, u, t)
        try:
            # numba's kernel does not check its output's size: it would write past the end of
            # a shorter one (its type, dimensions, layout and writability: numba's dispatch;
            # the C kernel checks all of these and raises TypeError)
            if buf is out and len(out) != nf:
                raise self._bad_out(out)
            st = kf(q, u, t, pa, db, buf)
        except TypeError:  # lists (the Python path's inputs), or a bad `out`
            if out is not None and self._out_ok(out) is False:
                raise self._bad_out(out) from None
            q, u, t = self._arrays(q, u, t)
            st = kf(q, u, t, pa, db, buf)
        if st and st != compiled.SINGULAR:
            if st != compiled.NOT_FINITE:
                self._fail(st, q, u)
            buf[:] = np.nan  # as the Python path: NaN in, NaN out (the caller's ratio test)
        if out is not None:
            return out
        return buf[:n], buf[n:nl], buf.item(nl)

    def _forward_raw_other(self, q: Any, u: Any, t: float, db: Any, out: Any) -> Any:
        """forward_raw off the kernel: the rank-revealing solve or the generated Python."""
        if out is not None and not self._out_ok(out):
            raise self._bad_out(out)
        if self._numeric:
            res = self._forward_redundant(q, u, t, db)
        else:
            res = self._scalar["forward"](
                q, u, t, self.p, self.sref, self._no_db if db is None else db
            )
        if out is None:
            return res
        n, nl = self.n, self._nlam
        out[:n], out[n:nl], out[nl] = res
        return out

    def _out_ok(self, out: Any) -> bool:
        """A caller's output array the kernel can write: float64, C-contiguous, aligned,
        writable, n + m + 1 long."""
        return (
            type(out) is _ND
            and out.dtype == np.float64
            and out.shape == (self._nf,)
            and bool(out.flags.c_contiguous and out.flags.aligned and out.flags.writeable)
        )

    def _bad_out(self, out: Any) -> ModelInputError:
        what = f"{type(out).__name__} {getattr(out, 'dtype', '')} of shape {np.shape(out)}" + (
            "" if not isinstance(out, _ND) or out.flags.writeable else ", read-only"
        )
        return ModelInputError(
            f"{self.model.name}: out must be a writable C-contiguous float64 vector of "
            f"n + m + 1 = {self._nf} (u', lambda, pivot ratio), got {what}; allocate it with "
            f"numpy.empty({self._nf})"
        )

    def forward_into(self, q: ArrayLike, u: ArrayLike, t: float, out: np.ndarray) -> int:
        """The bare compiled forward: u', lambda and the pivot ratio written into `out`
        (float64, n + m + 1: out[:n] = u', out[n:n+m] = lambda, out[-1] = the ratio), a
        status returned (reference.backends.numba_backend: 0 ok, 4 singular; sizes and finiteness
        are checked in the kernel). q, u: float64 vectors (the kernel's argument checks, C's or
        numba's dispatch, look at the types; anything else is a ModelInputError). The
        compiled backend only, and a model whose solve is unrolled (not numeric_kkt)."""
        if self._kf is None:
            raise ModelInputError(
                f"{self.model.name}: forward_into needs the compiled unrolled forward; this model "
                f"has {'no compiled backend' if self._k is None else 'a numeric KKT solve'} "
                f"(use forward or forward_raw)"
            )
        try:
            if len(out) != self._nf:  # the kernel would write past the end of a shorter one
                raise self._bad_out(out)
            return self._kf(q, u, t, self._pa, self._db0, out)
        except TypeError:
            if not self._out_ok(out):
                raise self._bad_out(out) from None
            raise ModelInputError(
                f"{self.model.name}: forward_into takes q, u as float64 vectors and t as a "
                f"number (got {type(q).__name__}, {type(u).__name__}, {type(t).__name__}); "
                f"convert them with numpy.asarray(x, float) or call forward_raw"
            ) from None

    def raw_function(self, name: str) -> Callable[..., Any]:
        """f(q, u, t, p) -> the output groups of generated function `name` (residuals,
        kinematics, energy, matrices, position_jacobian): the integrators' unchecked calls.
        On the compiled backend the groups are views of one output array and `p` must be
        this model's own parameter tuple (the kernel reads the packed copy, self._pa)."""
        if self._k is None:
            return self._scalar[name]
        f, total, offs, pa = self._k.get(name), self._k.total[name], self._k.offsets[name], self._pa
        arrays = self._arrays

        def call(q: Any, u: Any, t: float, p: Any = None) -> tuple:
            out = np.empty(total)
            if type(q) is not _ND or type(u) is not _ND:
                q, u, t = arrays(q, u, t)
            try:
                st = f(q, u, t, pa, out)
            except TypeError:  # lists: convert, then call
                q, u, t = arrays(q, u, t)
                st = f(q, u, t, pa, out)
            if st and st != compiled.NOT_FINITE:  # NaN in, NaN out, as the Python path
                self._fail(st, q, u)
            return tuple(out[a:b] for a, b in offs)

        return call

    def _forward_redundant(self, q: Any, u: Any, t: float, db: Any = None) -> Any:
        """forward_raw for models with dependent rows (reference.numeric.redundant): lists out."""
        M, f, A, b = self._scalar_call("matrices", q, u, t)
        n, m = self.n, self.m
        b = np.array(b, float) + (np.asarray(db, float) if db is not None else 0.0)
        ud, lam, piv, self._last_rank = redundant.solve(
            np.array(M, float).reshape(n, n),
            np.array(f, float),
            np.array(A, float).reshape(m, n),
            b,
            rank_expected=self.rank,
            augment=self._scalar["META"]["augmented"],
            where=self.model.name,
        )
        return ud.tolist(), lam.tolist(), piv

    def _undefined(self, q: ArrayLike) -> SingularSystemError:
        return SingularSystemError(
            f"{self.model.name}: the derived equations are not defined at q = "
            f"{np.round(np.asarray(q, float), 6).tolist()} (a division by zero: a coordinate "
            f"singularity such as gimbal lock of Euler angles, where these coordinates cannot "
            f"express the motion). Move the state away from this pose, or describe the body "
            f"with singularity-free coordinates (Euler parameters)."
        )

    def _scalar_call(self, name: str, q: list, u: list, t: float, *extra: Any) -> Any:
        """A pure-Python generated function; its ZeroDivisionError is the coordinate
        singularity the compiled kernels report as NOT_DEFINED."""
        try:
            return self._scalar[name](q, u, t, self.p, *extra)
        except ZeroDivisionError:
            raise self._undefined(q) from None

    def _singular_message(self, q: ArrayLike, piv: float) -> str:
        at = np.round(np.asarray(q, float), 6).tolist()
        return (
            f"{self.model.name}: the KKT matrix is singular at q = {at} "
            f"(pivot ratio {piv:.1e} <= {PIVOT_RATIO_MIN:.0e}): the constraint rows are "
            f"dependent there (a kinematic singularity or redundant constraints) or M is not "
            f"definite on their null space. Move the state away from this pose or remove "
            f"the redundant constraints."
        )

    def matrices(self, q: ArrayLike, u: ArrayLike, t: float = 0.0) -> tuple[np.ndarray, ...]:
        """M (n x n), f (n), A (m x n), b (m) at a state: the EquationsOfMotion contract."""
        n, m = self.n, self.m
        if self._k is not None:
            out = self._call("matrices", q, u, t)
            nn, nf, na = n * n, n * n + n, n * n + n + m * n
            return (out[:nn].reshape(n, n), out[nn:nf], out[nf:na].reshape(m, n), out[na:])
        q, u, t = self._state(q, u, t)
        M, f, A, b = self._scalar_call("matrices", q, u, t)
        return (
            np.array(M, float).reshape(n, n),
            np.array(f, float),
            np.array(A, float).reshape(m, n),
            np.array(b, float),
        )

    def kinematics(self, q: ArrayLike, u: ArrayLike, t: float = 0.0) -> np.ndarray:
        if self._k is not None:
            return self._call("kinematics", q, u, t)
        q, u, t = self._state(q, u, t)
        return np.array(self._scalar_call("kinematics", q, u, t)[0], float)

    def residuals(
        self, q: ArrayLike, u: ArrayLike, t: float = 0.0
    ) -> tuple[np.ndarray, np.ndarray]:
        """Position residuals f(q, t) and velocity residuals A u + a0."""
        if self._k is not None:
            out = self._call("residuals", q, u, t)
            k = self._k.sizes["residuals"][0]
            return out[:k], out[k:]
        q, u, t = self._state(q, u, t)
        pos, vel = self._scalar_call("residuals", q, u, t)
        return np.array(pos, float), np.array(vel, float)

    def energy(self, q: ArrayLike, u: ArrayLike, t: float = 0.0) -> tuple[float, float]:
        """Kinetic and potential energy (gravity from the bodies plus the model's springs)."""
        if self._k is not None:
            out = self._call("energy", q, u, t)
            return float(out[0]), float(out[1])
        q, u, t = self._state(q, u, t)
        (K, V, _P), *_ = self._scalar_call("energy", q, u, t)
        return float(K), float(V)

    def power_balance(self, q: ArrayLike, u: ArrayLike, t: float = 0.0) -> dict[str, float]:
        """Work-energy terms at a state: dE/dt (exact gradient of E = K + V along the motion),
        the power of the applied loads, and the power of the constraint forces
        u . A^T lambda = -lambda . a0 on the manifold (zero for scleronomic constraints)."""
        q, u, t = self._state(q, u, t)
        (K, V, P), dEdq, dEdu, (dEdt,) = self._scalar["energy"](q, u, t, self.p)
        fw = self.forward(q, u, t)
        qdot = self.kinematics(q, u, t)
        u = np.asarray(u)
        dE = float(np.dot(dEdq, qdot) + np.dot(dEdu, fw.accelerations) + dEdt)
        _, _, A, _ = self.matrices(q, u, t)
        P_c = float(fw.multipliers @ (A @ u)) if self.m else 0.0
        return {
            "dE_dt": dE,
            "load_power": float(P),
            "constraint_power": P_c,
            "energy": float(K + V),
        }
