"""The generated module of a model on the sums path (reference.eom.SummedEquations).

The same functions as reference.backends.codegen's module (matrices, kinematics, residuals,
position_jacobian, energy; no unrolled forward: NumericModel solves the KKT system per state,
reference.numeric.redundant), with two differences that keep every expression small:

- matrices computes the entries of the bodies' partial velocities and weights, the forces and
  A, b straight-line, and forms M and f from them numerically (reference.backends.body_sums:
  M = sum P^T W P, f = direct + sum Q^T w);
- the common subexpressions are eliminated on the expressions' graph as the derivation built
  it (reference.dag), with no expand or trigsimp, which cost what the written-out trees cost.

reference.backends.codegen puts the module together (its META: whether M needs the augmented
solve is judged on these functions' M at the generic configuration, as for the symbolic M).
"""

from __future__ import annotations

import sympy as sp

from reference.backends.writer import Writer, header, safe_symbols
from reference.dag import Calculus
from reference.eom import SummedEquations
from reference.formulations.lagrange import kinetic_energy, potential_energy


def _columns(P: sp.Matrix) -> tuple[int, ...]:
    """The speeds a term's partial velocities depend on (its nonzero columns)."""
    return tuple(k for k in range(P.shape[1]) if any(P[r, k] != 0 for r in range(3)))


def _values(terms, weight_size: int) -> tuple[list, list[tuple[int, ...]]]:
    """Each term's nonzero columns of P row by row, then its weight's entries
    (reference.backends.body_sums.SumTables' layout); and the columns."""
    values, columns = [], []
    for P, W in terms:
        cols = _columns(P)
        values += [P[r, c] for r in range(3) for c in cols]
        values += list(W)[:weight_size]
        columns.append(cols)
    return values, columns


def _function(name: str, eom: SummedEquations, groups: list[list], rename: dict) -> list[str]:
    """A generated function returning `groups` (lists of expressions)."""
    w = Writer()
    codes = w.graph_block([e for g in groups for e in g], rename) if any(groups) else []
    out, k = [], 0
    for g in groups:
        out.append("[" + ", ".join(codes[k : k + len(g)]) + "]")
        k += len(g)
    return header(name, eom) + w.lines + [f"    return {', '.join(out)},", ""]


def _matrices(eom: SummedEquations, rename: dict) -> tuple[list[str], str]:
    """matrices(): the terms' entries, then M and f summed by `_sums`; and the module-level
    line that builds the sums' tables."""
    n = len(eom.model.speeds)
    inertia, i_cols = _values(eom.sums.inertia, 9)
    forces, f_cols = _values(eom.sums.forces, 3)
    direct = list(eom.sums.direct)
    A, b = list(eom.A), list(eom.b)
    w = Writer()
    codes = iter(w.graph_block(inertia + forces + direct + A + b, rename))
    take = lambda k: ", ".join(next(codes) for _ in range(k))
    lines = header("matrices", eom) + w.lines
    lines.append(
        f"    _M, _f = _sums(_SUMS, [{take(len(inertia))}], [{take(len(forces))}], "
        f"[{take(len(direct))}])"
    )
    M = ", ".join(f"_M[{k}]" for k in range(n * n))
    f = ", ".join(f"_f[{k}]" for k in range(n))
    lines += [f"    return [{M}], [{f}], [{take(len(A))}], [{take(len(b))}],", ""]
    return lines, f"_SUMS = _sum_tables({n}, {tuple(i_cols)!r}, {tuple(f_cols)!r})"


def _energy_groups(eom: SummedEquations) -> list[list]:
    """K, V and the loads' power; dE/dq, dE/du, dE/dt of E = K + V."""
    m = eom.model
    calc = Calculus(m.coordinates, m.kinematics, m.t)
    K, V = kinetic_energy(m), potential_energy(m)
    nq, n = len(m.coordinates), len(m.speeds)
    grad = calc.gradient(K + V, [*m.coordinates, *m.speeds, m.t])
    return [[K, V, m.load_power()], grad[:nq], grad[nq : nq + n], grad[nq + n :]]


def summed_functions(eom: SummedEquations) -> str:
    """Python source of the sums' tables and of matrices, kinematics, residuals,
    position_jacobian and energy of a model on the sums path."""
    m = eom.model
    rename = safe_symbols(eom)
    cs = eom.constraints
    body, tables = _matrices(eom, rename)
    body += _function("kinematics", eom, [list(m.kinematics)], rename)
    velocity_rows = cs.A * sp.Matrix(m.speeds) + cs.a0
    body += _function("residuals", eom, [list(cs.f), list(velocity_rows)], rename)
    body += _function("position_jacobian", eom, [list(cs.A_q)], rename)
    body += _function("energy", eom, _energy_groups(eom), rename)
    return "\n".join([tables, "", *body]) + "\n"
