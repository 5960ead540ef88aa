"""What NumericModel checks and how it words what it refuses (a mixin of NumericModel, split out
of reference/numeric/model.py for its size): the model's parameters, the state, the caller's
output array, and the error of each nonzero kernel status, worded the same on every backend."""

from __future__ import annotations

import math
from typing import Any, NoReturn

import numpy as np
from numpy.typing import ArrayLike

from reference.backends.kernels import (
    BAD_Q_SIZE,
    BAD_U_SIZE,
    NOT_DEFINED,
    NOT_FINITE,
    PIVOT_RATIO_MIN,
    SINGULAR,
)
from reference.backends.python_kernels import PythonKernels, as_floats
from reference.errors import ModelInputError, SingularSystemError
from reference.system import Model

_ND = np.ndarray

# a parameter this large overflows as soon as it is squared or multiplied by a few others
# (1e100 squared is 1e200; the equations' terms are products of several parameters)
HUGE = 1e100


def resolve_parameters(model: Model, overrides: dict | None = None) -> dict[str, float]:
    """The model's parameter values with `overrides`, checked.

    Parameters
    ----------
    model : Model
        The model whose declared parameters and defaults are read.
    overrides : dict, optional
        Parameter name -> value, replacing the defaults.

    Returns
    -------
    dict[str, float]
        Every parameter's value, in the model's order.

    Raises
    ------
    ModelInputError
        An unknown name, or a value that is not a finite number or breaks its parameter's sign
        (all the problems at once).
    """
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


class StateValidation:
    """NumericModel's checks of states and output arrays, and its errors."""

    model: Model
    n: int
    nq: int
    _nf: int
    params: dict[str, float]
    p: tuple[float, ...]
    _py: PythonKernels

    def _state(self, q: ArrayLike, u: ArrayLike, t: float) -> tuple[list, list, float]:
        """Validated state as Python float lists."""
        try:
            ql, ul, t = as_floats(q), as_floats(u), float(t)
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
        """(q, u, t) as every kernel takes them: writable contiguous float64 vectors and a float
        (a kernel refusing other inputs with TypeError gets these). Sizes and finiteness are
        the kernel's to check (its status)."""
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

    def _fail(self, status: int, q: ArrayLike, u: ArrayLike, out: Any = None) -> NoReturn:
        """The error of a kernel's nonzero status, worded alike on every backend."""
        if status in (BAD_Q_SIZE, BAD_U_SIZE, NOT_FINITE):
            self._state(q, u, 0.0)  # raises the size or finiteness error
            raise ModelInputError(f"{self.model.name}: state contains NaN or infinite values")
        if status == SINGULAR:
            raise SingularSystemError(self.singular_message(q, float(out[-1])))
        if status == NOT_DEFINED:
            raise self._overflow(q, u) or self._undefined(q)
        raise RuntimeError(f"{self.model.name}: kernel returned status {status}")

    def _overflow(self, q: ArrayLike, u: ArrayLike) -> SingularSystemError | None:
        """The error when the outputs are not finite because the numbers overflow (a
        parameter of 1e308), not because of a division by zero; None otherwise. Told apart on
        the generated Python code, where a division by zero raises and an overflow gives inf."""
        big = max(self.params.items(), key=lambda kv: abs(kv[1]), default=("", 0.0))
        overflow = abs(big[1]) >= HUGE
        if not overflow:
            try:
                ql, ul = (np.asarray(x, float).ravel().tolist() for x in (q, u))  # floats
                with np.errstate(all="ignore"):
                    groups = self._py._scalar["matrices"](ql, ul, 0.0, [*map(float, self.p)])
                overflow = not all(math.isfinite(x) for g in groups for x in g)
            except (ZeroDivisionError, ValueError):
                pass  # a division by zero, or sqrt or log outside its domain
            except OverflowError:
                overflow = True
        if not overflow:
            return None
        return SingularSystemError(
            f"{self.model.name}: the numbers overflow at q = "
            f"{np.round(np.asarray(q, float), 6).tolist()}: the equations' terms exceed the "
            f"largest double (1.8e308) and are not finite (largest parameter: {big[0]} = "
            f"{big[1]:g}); give the state and the parameters values of a physical size"
        )

    def _undefined(self, q: ArrayLike) -> SingularSystemError:
        return SingularSystemError(
            f"{self.model.name}: the derived equations are not defined at q = "
            f"{np.round(np.asarray(q, float), 6).tolist()} (a division by zero: a coordinate "
            f"singularity such as gimbal lock of Euler angles, where these coordinates cannot "
            f"express the motion). Move the state away from this pose, or describe the body "
            f"with singularity-free coordinates (Euler parameters)."
        )

    def singular_message(self, q: ArrayLike, piv: float) -> str:
        """What a singular KKT matrix at `q` means and how to get past it.

        Parameters
        ----------
        q : array_like
            The coordinates where the solve met the singular matrix.
        piv : float
            The pivot ratio the solve returned there.

        Returns
        -------
        str
            The message a SingularSystemError carries (the integrators prefix the time).
        """
        at = np.round(np.asarray(q, float), 6).tolist()
        return (
            f"{self.model.name}: the KKT matrix is singular at q = {at} "
            f"(pivot ratio {piv:.1e} <= {PIVOT_RATIO_MIN:.0e}): the constraint rows are "
            f"dependent there (a kinematic singularity or redundant constraints) or M is not "
            f"definite on their null space. Move the state away from this pose or remove "
            f"the redundant constraints."
        )

    def _out_ok(self, out: Any) -> bool:
        """A caller's output array the kernels can write: float64, C-contiguous, aligned,
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
