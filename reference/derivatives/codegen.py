"""Straight-line code of the derivatives of the KKT solution, generated from the equations of
motion and cached on disk beside the forward code (reference.backends.codegen).

The forward answer z = (u', lambda) solves R(z; q, u, tau) = 0 with

    R = [ M(q) u' - f(q, u) - tau - A(q)^T lambda ]   (E: the dynamic rows)
        [ A(q) u' - b(q, u)                        ]   (C: the constraint rows)

and dR/dz = K = [[M, -A^T], [A, 0]], the KKT matrix. By the implicit function theorem

    dz/dx = -K^-1 dR/dx  (x = each q_k and each u_k),   dz/dtau = K^-1 [I; 0],

where dR/dx is R's partial derivative at the solution (u', lambda held fixed). The partial
derivatives E_x and C_x are differentiated symbolically here (sympy), their entries printed as
straight-line code with their common subexpressions shared, and the solve reuses the forward
solve's factors: the Cholesky factors of M and of the Schur complement S = A M^-1 A^T and
Y = M^-1 A^T (reference.backends.codegen's range-space method), one column per coordinate,
speed and generalized force. Where M is singular alone (Euler parameters), the forward code
factors M + rho A^T A; a right side (r1, r2) then becomes (r1 + rho A^T r2, r2), which leaves
the solution unchanged because A x = r2.

Two kinds of module, each its own cache entry:

- ``kkt`` (models whose forward solve is unrolled): ``derivatives(q, u, t, pa)`` with pa the
  forward kernel's parameters (the model's parameters, then the Schur references) returns
  u', lambda, the Jacobian of (u', lambda) with respect to (q, u, tau) row-major (rows u' then
  lambda, columns q, u, tau) and the pivot ratio, the forward part identical to the forward
  module's, expression for expression;
- ``residual`` (every model; the only kind where the KKT solve is numeric: dependent rows or
  a model past codegen.UNROLL_KKT_MAX): ``residual_jacobians(q, u, t, pa)`` with pa the
  parameters, then u', then lambda, returns P_x = d(M u' - f)/dx and L_x = d(A^T lambda)/dx
  (x = q, then u) at fixed u' and lambda, and C_x = d(A u' - b)/dx; the solve is then numeric
  (reference.derivatives.exact).

Both have ``velocity_jacobian(q, u, t, pa)``: d(A u + a0)/dq, which the consistent directions
need (a change of q moves the velocity rows).

A module is generated only when derivatives are asked for, so the forward code, its cache
entries and a run without derivatives are unchanged. The cache key is the forward entry's
(the model's content, the formulation, the derivation's sources, sympy) and this file's bytes.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

import sympy as sp

from reference.backends import cache, codegen
from reference.backends.codegen import (
    _augment,
    _chol_solve,
    _cholesky,
    _dot_terms,
    _header,
    _safe_symbols,
    _tidy,
    _Writer,
    kkt_entries,
)
from reference.eom import EquationsOfMotion

KINDS = ("kkt", "residual")
_SOURCE = Path(__file__)


def cache_stem(model: Any, formulation: str, kind: str) -> str:
    """The cache entry's file stem: the forward entry's key, the kind and a hash of this
    generator's source (an edit here misses the cache; the forward entries are untouched)."""
    if kind not in KINDS:
        raise ValueError(f"derivative module kind {kind!r}: one of {', '.join(KINDS)}")
    base = codegen.cache_key(model, formulation)
    h = hashlib.sha256(base.encode() + b"\0" + _SOURCE.read_bytes()).hexdigest()[:12]
    return f"{base}-d{kind}-{h}"


def load(eom_factory, model: Any, formulation: str, kind: str, augmented: bool) -> tuple:
    """(scalar namespace, batched namespace, source, path) of a derivative module, generated
    only on a cache miss (eom_factory() derives the equations then). `augmented` is the forward
    module's choice (META['augmented']), so both factor the same matrix."""
    path = codegen.cache_dir() / f"{cache_stem(model, formulation, kind)}.py"
    # read only when whole, as the forward entries (reference.backends.cache)
    src = cache.entry(path, lambda: generate(eom_factory(), kind, augmented))
    code = cache.code_object(src, path)
    scalar, batched = codegen._namespace(False), codegen._namespace(True)
    exec(code, scalar)
    exec(code, batched)
    return scalar, batched, src, path


# ---- the symbolic partial derivatives ------------------------------------------------------
def partials(eom: EquationsOfMotion, ud: list, lam: list) -> dict[str, sp.Matrix]:
    """R's partial derivatives in the model's symbols, with u' = `ud` and lambda = `lam`
    (symbols) held fixed: P_x = d(M u' - f)/dx, L_x = d(A^T lambda)/dx and C_x = d(A u' -
    b)/dx for x = q and x = u, and V_q = d(A u + a0)/dq. The entries of M, f, A and b are the
    forward code's (tidied), so the two modules differentiate the same expressions."""
    m = eom.model
    n, mc = len(m.speeds), eom.A.shape[0]
    # read once: on the sums path (SummedEquations) each read of M or f writes the sum out
    Mw, fw = eom.M, eom.f
    M = sp.Matrix(n, n, lambda i, j: _tidy(Mw[min(i, j), max(i, j)]))
    f = sp.Matrix([_tidy(e) for e in fw])
    A = sp.Matrix(mc, n, lambda i, j: _tidy(eom.A[i, j])) if mc else sp.zeros(0, n)
    b = sp.Matrix([_tidy(e) for e in eom.b]) if mc else sp.zeros(0, 1)
    udm, lamm = sp.Matrix(ud), sp.Matrix(lam) if mc else sp.zeros(0, 1)
    P = M * udm - f
    L = A.T * lamm if mc else sp.zeros(n, 1)
    C = A * udm - b if mc else sp.zeros(0, 1)
    cs = eom.constraints
    V = cs.A * sp.Matrix(m.speeds) + cs.a0 if mc else sp.zeros(0, 1)
    out = {}
    for name, x in (("q", m.coordinates), ("u", m.speeds)):
        out[f"P_{name}"] = P.jacobian(list(x))
        out[f"L_{name}"] = L.jacobian(list(x))
        out[f"C_{name}"] = C.jacobian(list(x)) if mc else sp.zeros(0, len(x))
    out["V_q"] = V.jacobian(list(m.coordinates)) if mc else sp.zeros(0, len(m.coordinates))
    return out


def _flat(mat: sp.Matrix) -> list:
    """Row-major entries."""
    return [mat[i, j] for i in range(mat.shape[0]) for j in range(mat.shape[1])]


def _groups(w: _Writer, groups: list[list]) -> list[str]:
    """One CSE block over every group's expressions; the return line's lists."""
    flat = [e for g in groups for e in g]
    codes = w.cse_block(flat) if flat else []
    out, k = [], 0
    for g in groups:
        out.append("[" + ", ".join(codes[k : k + len(g)]) + "]")
        k += len(g)
    return out


def _velocity_source(eom: EquationsOfMotion, X, npa: int) -> list[str]:
    """velocity_jacobian(): d(A u + a0)/dq, row-major."""
    w = _Writer()
    V = partials_velocity(eom)
    ret = _groups(w, [[X(e) for e in _flat(V)]])
    return _header("velocity_jacobian", eom, npa) + w.lines + [f"    return {ret[0]},", ""]


def partials_velocity(eom: EquationsOfMotion) -> sp.Matrix:
    """d(A u + a0)/dq in the model's symbols (zero rows: no constraints)."""
    m = eom.model
    cs = eom.constraints
    if not cs.m:
        return sp.zeros(0, len(m.coordinates))
    return (cs.A * sp.Matrix(m.speeds) + cs.a0).jacobian(list(m.coordinates))


def _residual_source(eom: EquationsOfMotion, X) -> list[str]:
    """residual_jacobians(): P_q, L_q, C_q, P_u, L_u, C_u at u' = _p[npar:npar + n] and
    lambda = _p[npar + n:], each row-major."""
    m = eom.model
    npar, n, mc = len(m.parameters), len(m.speeds), eom.A.shape[0]
    ud = [sp.Symbol(f"_p{npar + i}", real=True) for i in range(n)]
    lam = [sp.Symbol(f"_p{npar + n + j}", real=True) for j in range(mc)]
    # the model's symbols are renamed by X; u' and lambda are already the code's names
    d = partials(eom, ud, lam)
    order = ("P_q", "L_q", "C_q", "P_u", "L_u", "C_u")
    w = _Writer()
    ret = _groups(w, [[X(e) for e in _flat(d[k])] for k in order])
    return (
        _header("residual_jacobians", eom, npar + n + mc)
        + w.lines
        + [
            f"    return {', '.join(ret)},",
            "",
        ]
    )


def generate(eom: EquationsOfMotion, kind: str, augmented: bool) -> str:
    """Python source of one derivative module (see the module docstring)."""
    m = eom.model
    rn = _safe_symbols(eom)
    X = lambda e: sp.sympify(e).xreplace(rn)
    n, mc, npar = len(m.speeds), eom.A.shape[0], len(m.parameters)
    src = [
        f"# generated by reference.derivatives.codegen, first for {m.name} / {eom.formulation}",
        f"META = {{'n': {n}, 'm': {mc}, 'augmented': {augmented}, 'kind': {kind!r}}}",
        "",
    ]
    if kind == "kkt":
        src += _kkt_source(eom, augmented, X)
        src += _velocity_source(eom, X, npar + mc)
    else:
        src += _residual_source(eom, X)
        src += _velocity_source(eom, X, npar + n + mc)
    return "\n".join(src) + "\n"


# ---- the unrolled solve ----------------------------------------------------------------------
class _Kkt:
    """The forward solve written out (as reference.backends.codegen._forward_source writes it:
    the same expressions in the same order), its factors kept for more right sides."""

    def __init__(self, w: _Writer, eom: EquationsOfMotion, augmented: bool, X):
        n, mc, npar = len(eom.model.speeds), eom.A.shape[0], len(eom.model.parameters)
        self.w, self.n, self.m = w, n, mc
        Mc, fc, self.A, bc = kkt_entries(w, eom, X)
        bc = [c if c == "0" else w.assign(c) for c in bc]
        self.rho: str | None = None
        if augmented and mc:
            self.rho = f"_v{w.n}"  # _augment's first assignment is rho
            _augment(w, Mc, fc, self.A, bc, n, mc)
        pivots: list[str] = []
        self.L = _cholesky(w, Mc, pivots)
        self.Y: list[list[str]] = []
        self.Ls: tuple | None = None
        if mc:
            self.Y = [_chol_solve(w, self.L, [self.A[k][i] for i in range(n)]) for k in range(mc)]
            S = [["0"] * mc for _ in range(mc)]
            for k in range(mc):
                for l in range(k, mc):
                    terms = _dot_terms((self.A[k][i], self.Y[l][i]) for i in range(n))
                    if terms:
                        S[k][l] = S[l][k] = w.assign(" + ".join(terms))
            refs = [f"_p{npar + k}" for k in range(mc)]  # the Schur references follow
            self.Ls = _cholesky(w, S, pivots, refs)
        self.pivot = f"_min({', '.join(pivots)})" if len(pivots) > 1 else pivots[0]
        self.ud, self.lam = self.solve(fc, bc, augmented_rhs=True)

    def solve(self, r1: list[str], r2: list[str], augmented_rhs: bool = False) -> tuple:
        """x, y with M x - A^T y = r1, A x = r2 (code strings, '0' for a structural zero).
        `augmented_rhs`: r1 already holds rho A^T r2 (the forward's f, which _augment changed)."""
        w, n, mc = self.w, self.n, self.m
        if self.rho is not None and not augmented_rhs:
            r1 = list(r1)
            for i in range(n):
                terms = _dot_terms((self.A[k][i], r2[k]) for k in range(mc))
                if terms:
                    base = r1[i] if r1[i] != "0" else "0"
                    r1[i] = w.assign(f"{base} + {self.rho}*({' + '.join(terms)})")
        y = _chol_solve(w, self.L, r1)
        if not mc:
            return y, []
        r = []
        for k in range(mc):
            terms = _dot_terms((self.A[k][i], y[i]) for i in range(n))
            if not terms:
                r.append(r2[k])
            elif r2[k] == "0":
                r.append(w.assign(f"-({' + '.join(terms)})"))
            else:
                r.append(w.assign(f"{r2[k]} - ({' + '.join(terms)})"))
        assert self.Ls is not None
        lam = _chol_solve(w, self.Ls, r)
        x = []
        for i in range(n):
            terms = _dot_terms((self.Y[k][i], lam[k]) for k in range(mc))
            if not terms:
                x.append(y[i])
            else:
                x.append(
                    w.assign(f"{y[i]} + {' + '.join(terms)}" if y[i] != "0" else " + ".join(terms))
                )
        return x, lam


def _symbol(code: str):
    """A code name as a sympy symbol (or 0), to substitute into the partial derivatives."""
    return sp.Integer(0) if code == "0" else sp.Symbol(code, real=True)


def _kkt_source(eom: EquationsOfMotion, augmented: bool, X) -> list[str]:
    """derivatives(): the forward solve, R's partial derivatives at its answer, and one solve
    per coordinate, speed and generalized force."""
    m = eom.model
    nq, n, mc, npar = len(m.coordinates), len(m.speeds), eom.A.shape[0], len(m.parameters)
    w = _Writer()
    kkt = _Kkt(w, eom, augmented, X)
    ud_s = [sp.Symbol(f"_ud{i}", real=True) for i in range(n)]
    lam_s = [sp.Symbol(f"_lam{j}", real=True) for j in range(mc)]
    d = partials(eom, ud_s, lam_s)
    at = {s: _symbol(c) for s, c in zip(ud_s + lam_s, kkt.ud + kkt.lam, strict=True)}
    # dR/dx = [P_x - L_x; C_x]; the right side of each column is its negative
    cols: list[tuple[list, list]] = []
    for x, nx in (("q", nq), ("u", n)):
        E = d[f"P_{x}"] - d[f"L_{x}"]
        C = d[f"C_{x}"]
        for k in range(nx):
            cols.append(([-E[i, k] for i in range(n)], [-C[j, k] for j in range(mc)]))
    flat = [X(e).xreplace(at) for r1, r2 in cols for e in r1 + r2]
    codes = iter(w.cse_block(flat) if flat else [])
    mat = lambda c: c if c == "0" else w.assign(c)
    sol = []
    for _ in cols:
        r1 = [mat(next(codes)) for _ in range(n)]
        r2 = [mat(next(codes)) for _ in range(mc)]
        sol.append(kkt.solve(r1, r2))
    for k in range(n):  # d/dtau_k: the right side (e_k, 0)
        sol.append(kkt.solve(["1.0" if i == k else "0" for i in range(n)], ["0"] * mc))
    # the Jacobian stacked row-major: rows u' then lambda, columns q, u, tau (the solves' order)
    rows = [[x[i] for x, _y in sol] for i in range(n)]
    rows += [[y[j] for _x, y in sol] for j in range(mc)]
    groups: list[list[str]] = [kkt.ud, kkt.lam, [c for r in rows for c in r], [kkt.pivot]]
    ret = f"    return {', '.join('[' + ', '.join(g) + ']' for g in groups)},"
    return [*_header("derivatives", eom, npar + mc), *w.lines, ret, ""]
