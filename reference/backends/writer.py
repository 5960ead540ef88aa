"""The writer of generated straight-line code that both generated modules share
(reference.backends.codegen's and summed_source's): the models' symbols renamed to names no
model can use, each function's header, and blocks of common subexpressions.
"""

from __future__ import annotations

import sympy as sp
from sympy.printing.lambdarepr import LambdaPrinter

from reference.eom import EquationsOfMotion, SummedEquations


def _is_zero(e) -> bool:
    e = sp.sympify(e)
    return e == 0 or sp.expand(e) == 0


class Writer:
    """Accumulates straight-line code; names are '_'-prefixed so no model symbol can collide."""

    def __init__(self):
        self.lines: list[str] = []
        self.printer = LambdaPrinter({"fully_qualified_modules": False})
        self.n = 0

    def expr(self, e) -> str:
        return self.printer.doprint(e)

    def assign(self, code: str) -> str:
        name = f"_v{self.n}"
        self.n += 1
        self.lines.append(f"    {name} = {code}")
        return name

    def cse_block(self, exprs: list) -> list[str]:
        """Common subexpressions of all `exprs`; returns their code strings (name, '0' or
        literal)."""
        exprs = [sp.sympify(e) for e in exprs]
        repl, reduced = sp.cse(exprs, symbols=sp.numbered_symbols(f"_s{self.n}_"))
        self.n += 1
        for sym, sub in repl:
            self.lines.append(f"    {sym} = {self.expr(sub)}")
        return ["0" if _is_zero(r) else self.expr(r) for r in reduced]

    def graph_block(self, exprs: list, rename: dict) -> list[str]:
        """cse_block for expressions that share their subexpressions as a graph
        (reference.dag): the elimination runs on the graph in the arguments' own order (the
        canonical order counts every argument's tree: 610 of 870 s on Cassie), the symbols are
        renamed after it (xreplace walks trees; the pieces are small by then), nothing is
        expanded, and sums print in their own order too."""
        exprs = [sp.sympify(e) for e in exprs]
        repl, reduced = sp.cse(exprs, symbols=sp.numbered_symbols(f"_s{self.n}_"), order="none")
        self.n += 1
        printer = LambdaPrinter({"fully_qualified_modules": False, "order": "none"})
        for sym, sub in repl:
            self.lines.append(f"    {sym} = {printer.doprint(sub.xreplace(rename))}")
        return ["0" if r is sp.S.Zero else printer.doprint(r.xreplace(rename)) for r in reduced]


def safe_symbols(eom: EquationsOfMotion | SummedEquations) -> dict:
    """Every coordinate, speed, parameter and t renamed _q0.., _u0.., _p0.., _t."""
    m = eom.model
    rename = {s: sp.Symbol(f"_q{i}", real=True) for i, s in enumerate(m.coordinates)}
    rename.update({s: sp.Symbol(f"_u{i}", real=True) for i, s in enumerate(m.speeds)})
    rename.update({s: sp.Symbol(f"_p{i}", real=True) for i, s in enumerate(m.parameter_symbols)})
    rename[m.t] = sp.Symbol("_t", real=True)
    return rename


def header(
    name: str, eom: EquationsOfMotion | SummedEquations, npa: int | None = None
) -> list[str]:
    """A generated function's first lines: its signature and its arguments unpacked, _p
    holding `npa` numbers (None: the model's parameters)."""
    m = eom.model
    npa = len(m.parameters) if npa is None else npa
    lines = [f"def {name}(_q, _u, _t, _p):"]
    if m.coordinates:
        lines.append("    " + ", ".join(f"_q{i}" for i in range(len(m.coordinates))) + ", = _q")
    if m.speeds:
        lines.append("    " + ", ".join(f"_u{i}" for i in range(len(m.speeds))) + ", = _u")
    if npa:
        lines.append("    " + ", ".join(f"_p{i}" for i in range(npa)) + ", = _p")
    return lines
