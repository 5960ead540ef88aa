"""Compile EquationsOfMotion to straight-line Python, once, cached on disk by model content.

The generated module has no loops and no branches, so the same source runs on Python floats
(with the `math` namespace: the fast single-state path) and on numpy arrays of states (the
batched path). The KKT system

    [ M  -A^T ] [u'    ]   [f]
    [ A   0   ] [lambda] = [b]

is solved by the range-space method: Cholesky of M, Y = M^-1 A^T, y = M^-1 f, Cholesky of the
Schur complement S = A Y, lambda = S^-1 (b - A y), u' = y + Y lambda. Entries that are
structurally zero (a block-diagonal M, sparse A) are skipped while writing the code, which is
where the speed comes from. When M is singular in the chosen coordinates but positive definite
on the null space of A (Euler parameters: omega = 2 E eps' annihilates eps), M is replaced by
M + rho A^T A and f by f + rho A^T b, which leaves the solution unchanged because A u' = b.

Every pivot is divided by its original diagonal entry and the minimum is returned, so callers can
refuse a (nearly) singular M or S, that is, a kinematic singularity or redundant constraints.
"""

from __future__ import annotations

import hashlib
import math
from pathlib import Path
from typing import Any

import numpy as np
import sympy as sp

from reference.backends import body_sums, cache
from reference.backends.summed_source import summed_functions
from reference.backends.writer import Writer as _Writer
from reference.backends.writer import header as _header
from reference.backends.writer import safe_symbols as _safe_symbols
from reference.eom import EquationsOfMotion, SummedEquations
from reference.formulations import derivation_path
from reference.formulations.lagrange import kinetic_energy, potential_energy

# The derivation cache must miss whenever any source that shapes the derived equations or the
# generated code changes (a hand-bumped version number is easily forgotten). These
# are the modules the derivation runs through; the model modules are covered by
# Model.content_hash(), which hashes the declared expressions themselves.
_PACKAGE = Path(__file__).resolve().parents[1]  # reference/
DERIVATION_SOURCES = (
    "system.py",
    "constraints.py",
    "eom.py",
    "dag.py",
    "backends/codegen.py",
    "backends/writer.py",
    "backends/summed_source.py",
    "formulations/*.py",
)


def derivation_sources_hash() -> str:
    """sha256 over the derivation's source files (relative name and bytes, in sorted order)."""
    global _SOURCES_HASH
    if _SOURCES_HASH is None:
        files = sorted({f for pat in DERIVATION_SOURCES for f in _PACKAGE.glob(pat)})
        h = hashlib.sha256()
        for f in files:
            h.update(f.relative_to(_PACKAGE).as_posix().encode() + b"\0")
            h.update(f.read_bytes() + b"\0")
        _SOURCES_HASH = h.hexdigest()
    return _SOURCES_HASH


_SOURCES_HASH: str | None = None


def cache_dir() -> Path:
    """The derivation cache's directory (reference.backends.cache: a private temporary one
    where the configured one cannot be written)."""
    return cache.directory()


def cache_key(model, formulation: str) -> str:
    """File stem of a cache entry: the formulation (a readable prefix) and a hash of the
    model's content, the formulation, its derivation path (reference.formulations), the
    derivation's sources and sympy. The model's name is not in it: a renamed or re-imported
    model reuses its derivation; the generated file's first line names the model it was
    first derived for."""
    h = hashlib.sha256(
        f"{model.content_hash()}|{formulation}|{derivation_path(model)}|"
        f"{derivation_sources_hash()}|{sp.__version__}".encode()
    )
    return f"{formulation}-{h.hexdigest()[:16]}"


# The unrolled solve (Cholesky of M and of the Schur complement written out entry by entry)
# grows with the cube of the KKT size, and trigsimp of its entries with the model. Measured
# with the IFToMM A02 N-four-bar (examples/a02, n + m = 5N + 1 rows) on the shared 2-core
# machine: N = 5 (26 rows) took 93 s to derive and generate unrolled, 11 s without the
# unrolled forward (docs/scaling.md has the commands and the figures). Past
# this many rows forward() is solved numerically per state from the generated M, A, f, b
# (reference.numeric.redundant's rank-revealing solve: 1.8 ms per state at N = 5). The largest
# built-in model (double_pendulum_3d, 18 rows) and the ten-body gripper (17) stay below it.
UNROLL_KKT_MAX = 24

# trigsimp pays for itself (slider-crank: 219 -> 94 operations, 1 s once, then cached) but its
# cost grows steeply with expression size, so larger entries are only expanded or left as they are.
TIDY_MAX_OPS = 200


_TIDIED: dict = {}


def _tidy(e):
    """Cheap algebraic cleanup before code generation (sin^2 + cos^2, collected constants).

    Memoized per expression within the process: the formulations of one model (and models that
    share bodies, slider_crank and slider_crank_free) hand it the same entries of M, f, A and b,
    and trigsimp is most of a cold derivation (measured in docs/compiled.md)."""
    e = sp.sympify(e)
    if e.is_number or e.is_Symbol:
        return e
    hit = _TIDIED.get(e)
    if hit is None:
        hit = _TIDIED[e] = _tidy_uncached(e)
    return hit


def _tidy_uncached(e):
    """The smallest (by operation count) of e, its expansion and, where the expansion is
    small enough for trigsimp to be affordable, the trigsimp of it: kept only where it pays."""
    ex = sp.expand(e)
    options = [e, ex]
    if sp.count_ops(ex) <= TIDY_MAX_OPS:
        options.append(sp.trigsimp(ex))
    return min(reversed(options), key=sp.count_ops)  # ties: the simplified form


def _mul(a: str, b: str) -> str | None:
    if a == "0" or b == "0":
        return None
    return f"{a}*{b}"


def _dot_terms(pairs) -> list[str]:
    return [t for t in (_mul(a, b) for a, b in pairs) if t is not None]


def _cholesky(
    w: _Writer, Mc: list[list[str]], pivots: list[str], reference: list[str] | None = None
) -> tuple[list[list[str]], list[str]]:
    """Lower-triangular L with L L^T = Mc, skipping structural zeros, and the reciprocals of its
    diagonal; records pivot ratios (each pivot over `reference[j]`, by default the original
    diagonal entry). One reciprocal per pivot, then multiplications: a division costs 4-10
    multiplications, and the solves divide by each pivot n + m times."""
    n = len(Mc)
    L = [["0"] * n for _ in range(n)]
    inv = ["0"] * n
    for j in range(n):
        terms = _dot_terms((L[j][k], L[j][k]) for k in range(j))
        d = Mc[j][j] if not terms else f"{Mc[j][j]} - ({' + '.join(terms)})"
        dv = w.assign(d)
        if reference is not None:
            pivots.append(f"{dv}/{reference[j]}")
        else:
            pivots.append(f"{dv}/{Mc[j][j]}" if Mc[j][j] != "0" else dv)
        L[j][j] = w.assign(f"sqrt({dv})")
        inv[j] = w.assign(f"1.0/{L[j][j]}")
        for i in range(j + 1, n):
            terms = _dot_terms((L[i][k], L[j][k]) for k in range(j))
            if Mc[i][j] == "0" and not terms:
                continue
            num = Mc[i][j] if Mc[i][j] != "0" else "0"
            num = num if not terms else f"{num} - ({' + '.join(terms)})"
            L[i][j] = w.assign(f"({num})*{inv[j]}")
    return L, inv


def _chol_solve(w: _Writer, chol: tuple[list[list[str]], list[str]], rhs: list[str]) -> list[str]:
    """Solve L L^T x = rhs with forward and back substitution, skipping zeros."""
    L, inv = chol
    n = len(L)
    z = ["0"] * n
    for i in range(n):
        terms = _dot_terms((L[i][k], z[k]) for k in range(i))
        if rhs[i] == "0" and not terms:
            continue
        num = rhs[i] if not terms else f"{rhs[i]} - ({' + '.join(terms)})"
        z[i] = w.assign(f"({num})*{inv[i]}")
    x = ["0"] * n
    for i in reversed(range(n)):
        terms = _dot_terms((L[k][i], x[k]) for k in range(i + 1, n))
        if z[i] == "0" and not terms:
            continue
        num = z[i] if not terms else f"{z[i]} - ({' + '.join(terms)})"
        x[i] = w.assign(f"({num})*{inv[i]}")
    return x


def generic_state(model, params: dict) -> dict:
    """A generic configuration near the initial one: q, u, t and the parameters' values by
    symbol (the state at which M's singularity is judged)."""
    rng = np.random.default_rng(12345)
    subs = {
        s: float(v) + 0.1 * rng.standard_normal()
        for s, v in zip(model.coordinates, model.initial_q, strict=True)
    }
    subs.update({s: float(v) for s, v in zip(model.speeds, model.initial_u, strict=True)})
    subs.update({p.symbol: params[p.name] for p in model.parameters})
    subs[model.t] = 0.3
    return subs


def needs_augmentation(eom: EquationsOfMotion, params: dict) -> bool:
    """True when M is singular on its own (checked numerically at a generic configuration)."""
    M = np.array(eom.M.xreplace(generic_state(eom.model, params)).evalf(), dtype=float)
    return singular_alone(M)


def singular_alone(M: np.ndarray) -> bool:
    """True when the numeric M (at a generic configuration) has a null space of its own."""
    ev = np.linalg.eigvalsh(0.5 * (M + M.T))
    # A generic M of the unit's models has a condition number below 1e8 (point masses carry no
    # inertia, but they get no rotational speed either); an exact null space shows up at 1e-16.
    return ev[0] <= 1e-12 * max(abs(ev[-1]), 1e-300)


def _augment(w, Mc: list, fc: list, Ac: list, bc: list, n: int, mc: int) -> None:
    """M + rho A^T A and f + rho A^T b in place (for a model whose M is singular alone)."""
    # rho scales A^T A to the size of M so the augmented matrix stays well conditioned
    trM = " + ".join(Mc[i][i] for i in range(n) if Mc[i][i] != "0") or "1"
    sA = " + ".join(f"{a}*{a}" for row in Ac for a in row if a != "0") or "1"
    rho = w.assign(f"(({trM})/{n})/(({sA})/{mc})")
    for i in range(n):
        for j in range(i, n):
            terms = _dot_terms((Ac[k][i], Ac[k][j]) for k in range(mc))
            if terms:
                base = Mc[i][j] if Mc[i][j] != "0" else "0"
                Mc[i][j] = w.assign(f"{base} + {rho}*({' + '.join(terms)})")
                Mc[j][i] = Mc[i][j]
        terms = _dot_terms((Ac[k][i], bc[k]) for k in range(mc))
        if terms:
            fc[i] = w.assign(f"{fc[i]} + {rho}*({' + '.join(terms)})")


def kkt_entries(w: _Writer, eom: EquationsOfMotion, X) -> tuple[list, list, list, list]:
    """M (both triangles), f, A and b of `eom` as one CSE'd block in `w`: M's, f's and A's
    entries assigned to variables (each evaluated once), b's left as expressions for the
    caller to offset; "0" where an entry is zero."""
    n, mc = len(eom.model.speeds), eom.A.shape[0]
    M = eom.M  # read once: on the sums path each read writes the sum out
    flat = [M[i, j] for i in range(n) for j in range(i, n)]
    flat += list(eom.f) + list(eom.A) + list(eom.b)
    it = iter(w.cse_block([X(_tidy(e)) for e in flat]))
    upper: list[list[Any]] = [["0"] * n for _ in range(n)]
    for i in range(n):
        for j in range(i, n):
            upper[i][j] = next(it)
    fc = [next(it) for _ in range(n)]
    Ac = [[next(it) for _ in range(n)] for _ in range(mc)]
    bc = [next(it) for _ in range(mc)]
    mat = lambda c: c if c == "0" else w.assign(c)
    Mc: list[list[Any]] = [
        [mat(upper[i][j]) if j >= i else None for j in range(n)] for i in range(n)
    ]
    for i in range(n):
        for j in range(i):
            Mc[i][j] = Mc[j][i]
    return Mc, [mat(c) for c in fc], [[mat(c) for c in row] for row in Ac], bc


def _forward_source(eom: EquationsOfMotion, augment: bool, X) -> list[str]:
    """forward(): u', lambda and the smallest pivot ratio, by Cholesky of M and of the Schur
    complement A M^-1 A^T, with every entry a CSE'd expression."""
    n, mc = len(eom.model.speeds), eom.A.shape[0]
    out: list[str] = []
    w = _Writer()
    Mc, fc, Ac, bc = kkt_entries(w, eom, X)
    # A u' = b + _db: the caller's offset of the constraint rows' right side (zeros, or the
    # Baumgarte terms -2 alpha (A u + a0) - beta^2 f), so stabilization costs no extra solve
    bc = [
        w.assign(f"{c} + _db[{k}]") if c != "0" else w.assign(f"_db[{k}]") for k, c in enumerate(bc)
    ]
    if augment and mc:
        _augment(w, Mc, fc, Ac, bc, n, mc)
    pivots: list[str] = []
    L = _cholesky(w, Mc, pivots)
    y = _chol_solve(w, L, fc)
    if mc:
        Y = [_chol_solve(w, L, [Ac[k][i] for i in range(n)]) for k in range(mc)]  # columns
        S = [["0"] * mc for _ in range(mc)]
        for k in range(mc):
            for l in range(k, mc):
                terms = _dot_terms((Ac[k][i], Y[l][i]) for i in range(n))
                if terms:
                    S[k][l] = S[l][k] = w.assign(" + ".join(terms))
        r = []
        for k in range(mc):
            terms = _dot_terms((Ac[k][i], y[i]) for i in range(n))
            r.append(w.assign(f"{bc[k]} - ({' + '.join(terms)})") if terms else bc[k])
        # S's pivots are measured against S's diagonal at a generic configuration (_sref, set
        # by the caller): at a singular pose S itself collapses, so its own diagonal would hide it
        lam = _chol_solve(w, _cholesky(w, S, pivots, [f"_sref[{k}]" for k in range(mc)]), r)
        ud = []
        for i in range(n):
            terms = _dot_terms((Y[k][i], lam[k]) for k in range(mc))
            ud.append(y[i] if not terms else w.assign(f"{y[i]} + {' + '.join(terms)}"))
    else:
        lam, ud = [], y
    piv = f"_min({', '.join(pivots)})" if len(pivots) > 1 else (pivots[0] if pivots else "1.0")
    out += [h.replace("_p):", "_p, _sref, _db=_ZEROS):") for h in _header("forward", eom)]
    out += w.lines
    out.append(f"    return [{', '.join(ud)}], [{', '.join(lam)}], {piv}")
    out.append("")
    return out


def numeric_kkt(n: int, m: int) -> bool:
    """True when a model's KKT system (n + m rows) is past UNROLL_KKT_MAX: its forward() is
    not unrolled, the solve is numeric (NumericModel, reference.numeric.redundant)."""
    return n + m > UNROLL_KKT_MAX


def generate_source(eom: EquationsOfMotion, augment: bool) -> str:
    """Python source for forward, matrices, kinematics, residuals and energy of one model
    (no forward for a model past UNROLL_KKT_MAX or with dependent rows: META['kkt'] says
    which)."""
    m = eom.model
    rn = _safe_symbols(eom)
    X = lambda e: sp.sympify(e).xreplace(rn)
    n, mc = len(m.speeds), eom.A.shape[0]
    # dependent rows (an MJCF import) are always solved numerically (NumericModel,
    # reference.numeric.redundant): an unrolled forward would be generated and never called
    redundant = bool(getattr(m, "redundant_constraints", False))
    kkt = "numeric" if numeric_kkt(n, mc) or redundant else "unrolled"
    tag = derivation_sources_hash()[:12]
    src = [
        f"# generated by reference.backends.codegen ({tag}), "
        f"first for {m.name} / {eom.formulation}",
        f"META = {{'n': {n}, 'm': {mc}, 'augmented': {augment}, 'kkt': {kkt!r}}}",
        "",
    ]

    # forward: u', lambda, min pivot ratio
    if kkt == "unrolled":
        src += _forward_source(eom, augment, X)

    def simple(name, exprs_groups):
        w2 = _Writer()
        flat2 = [X(e) for g in exprs_groups for e in g]
        codes = w2.cse_block(flat2) if flat2 else []
        out, k = [], 0
        for g in exprs_groups:
            out.append("[" + ", ".join(codes[k : k + len(g)]) + "]")
            k += len(g)
        return _header(name, eom) + w2.lines + [f"    return {', '.join(out)},", ""]

    src += simple("matrices", [list(eom.M), list(eom.f), list(eom.A), list(eom.b)])
    src += simple("kinematics", [list(m.kinematics)])
    cs = eom.constraints
    src += simple("residuals", [list(cs.f), list(cs.A * sp.Matrix(m.speeds) + cs.a0)])
    E = kinetic_energy(m) + potential_energy(m)
    src += simple("position_jacobian", [list(cs.A_q)])
    src += simple(
        "energy",
        [
            [kinetic_energy(m), potential_energy(m), m.load_power()],
            [sp.diff(E, s) for s in m.coordinates],
            [sp.diff(E, s) for s in m.speeds],
            [sp.diff(E, m.t)],
        ],
    )
    return "\n".join(src) + "\n"


def summed_module(eom: SummedEquations, params: dict) -> str:
    """The module of a model on the sums path (reference.backends.summed_source's functions)
    with its META: the KKT solve numeric, and augmented where the generated M is singular
    alone at the generic configuration (as needs_augmentation judges a symbolic M)."""
    m = eom.model
    code = summed_functions(eom)
    ns = _namespace(False)
    exec(compile(code, "<summed module>", "exec"), ns)
    at = generic_state(m, params)
    state = [[at[s] for s in group] for group in (m.coordinates, m.speeds, m.parameter_symbols)]
    M = np.array(ns["matrices"](state[0], state[1], at[m.t], state[2])[0], float)
    n = len(m.speeds)
    augmented = bool(singular_alone(M.reshape(n, n)))
    meta = {"n": n, "m": eom.A.shape[0], "augmented": augmented, "kkt": "numeric", "sums": True}
    return (
        f"# generated by reference.backends.codegen ({derivation_sources_hash()[:12]}), first "
        f"for {m.name} / {eom.formulation}, as sums over the bodies "
        f"(reference.backends.summed_source)\nMETA = {meta!r}\n\n{code}"
    )


class _Zeros:
    """Default offset of b in forward: zero for every row."""

    def __getitem__(self, k):
        return 0.0


def _namespace(batched: bool) -> dict:
    if batched:
        from functools import reduce

        return {
            "sin": np.sin,
            "cos": np.cos,
            "tan": np.tan,
            "sqrt": np.sqrt,
            "exp": np.exp,
            "log": np.log,
            "atan2": np.arctan2,
            "pi": np.pi,
            "abs": np.abs,
            "_min": lambda *a: reduce(np.minimum, a),
            "_ZEROS": _Zeros(),
            **body_sums.namespace(True),
        }
    return {
        "sin": math.sin,
        "cos": math.cos,
        "tan": math.tan,
        "sqrt": math.sqrt,
        "exp": math.exp,
        "log": math.log,
        "atan2": math.atan2,
        "pi": math.pi,
        "abs": abs,
        "_min": min,
        "_ZEROS": _Zeros(),
        **body_sums.namespace(False),
    }


_code_object = cache.code_object  # the name reference.derivatives.codegen reads


def load_compiled(eom_factory, model, formulation: str, params: dict):
    """Return (scalar namespace, batched namespace, source), deriving only on a cache miss.

    `eom_factory()` is called only when the cache has no whole entry for this model content.
    """
    path = cache_dir() / f"{cache_key(model, formulation)}.py"

    def generate() -> str:
        eom = eom_factory()
        if isinstance(eom, SummedEquations):
            return summed_module(eom, params)
        return generate_source(eom, needs_augmentation(eom, params))

    src = cache.entry(path, generate)
    code = cache.code_object(src, path)
    scalar, batched = _namespace(False), _namespace(True)
    exec(code, scalar)
    exec(code, batched)
    scalar["__cache_path__"] = path
    return scalar, batched, src
