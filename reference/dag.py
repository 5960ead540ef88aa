"""Expressions as shared graphs: derivatives, time derivatives, free symbols, sizes and a
content digest that visit each distinct subexpression once.

A robot's kinematics written body after body (a child's rotation is its parent's times its
joint's) is a graph in which every body's expressions reuse its parent's: the bodies of the
Cassie robot hold about 3000 distinct subexpressions in their velocities, but more than 10^5
operations per velocity component once written out as trees. sympy's diff, xreplace, srepr,
count_ops and free_symbols walk the written-out tree, so they cost what the tree costs; the
functions here remember what they computed for each subexpression, so they cost what the graph
costs. The results are sympy expressions (each built from its arguments' results, so they
share as the inputs do), equal to sympy's own as functions of the symbols, though not always
of the same form.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable, Sequence
from typing import Any

import sympy as sp

_ZERO = sp.S.Zero


def _entries(items: Iterable[Any]) -> list:
    """The expressions among `items`, a matrix as its entries."""
    out: list = []
    for i in items:
        if isinstance(i, sp.MatrixBase):
            out.extend(i)
        elif isinstance(i, sp.Basic):
            out.append(i)
    return out


def _fill(roots: Iterable[sp.Basic], table: dict, compute, descend=None) -> None:
    """table[x] = compute(x) for every node x below `roots` not yet in `table`, each after its
    arguments (iteratively: a deep graph would pass Python's recursion limit); `descend(c)`
    False leaves argument c out."""
    for root in roots:
        if root in table:
            continue
        stack = [(root, False)]
        while stack:
            x, done = stack.pop()
            if done:
                if x not in table:
                    table[x] = compute(x)
                continue
            if x in table:
                continue
            stack.append((x, True))
            stack.extend(
                (c, False) for c in x.args if c not in table and (descend is None or descend(c))
            )


def _nodes(exprs: Iterable[Any]) -> list:
    """Every distinct node of the expressions (or matrices), each after its arguments."""
    order: dict = {}
    _fill(_entries(exprs), order, lambda x: len(order))
    return sorted(order, key=order.__getitem__)


def free_symbols(exprs: Iterable[Any]) -> set:
    """The symbols the expressions (or matrices) depend on, each node visited once."""
    return {x for x in _nodes(exprs) if isinstance(x, sp.Symbol)}


def tree_size(exprs: Iterable[Any]) -> int:
    """The size of the expressions (or matrices) written out as trees, what sympy's tree walks,
    expand and trigsimp pay for: their operations (sums, products, powers, functions, each
    one however many arguments it has), counted on the graph."""
    size: dict = {}
    _fill(_entries(exprs), size, lambda x: (1 if x.args else 0) + sum(size[c] for c in x.args))
    return sum(size[x] for x in _entries(exprs))


def digest(items: Sequence[Any]) -> str:
    """sha256 of the items (expressions, matrices, strings, None, numbers), each distinct
    subexpression written once: a node is its class and the numbers of its arguments, an atom
    its srepr. Equal for equal structures in every process (sympy orders arguments
    canonically), unlike hash()."""
    h = hashlib.sha256()
    index: dict = {}

    def write(x):
        if x.args:
            text = f"{type(x).__name__}({','.join(str(index[c]) for c in x.args)})"
        else:
            text = sp.srepr(x)
        h.update(text.encode() + b"\n")
        return len(index)

    _fill(_entries(items), index, write)
    for i in items:
        if isinstance(i, sp.MatrixBase):
            text = f"Matrix{i.shape}[{','.join(str(index[c]) for c in i)}]"
        elif isinstance(i, sp.Basic):
            text = str(index[i])
        else:
            text = repr(i)
        h.update(f"item {text}\n".encode())
    return h.hexdigest()


class Calculus:
    """Partial and time derivatives of a model's expressions, remembered per subexpression.

    Parameters
    ----------
    coordinates : sequence of sympy Symbol
        q.
    kinematics : sequence of sympy expressions
        q' = N(q, u, t), one per coordinate.
    t : sympy Symbol
        Time.

    One instance serves one derivation: its tables hold every subexpression it has seen.
    """

    def __init__(self, coordinates: Sequence, kinematics: Sequence, t: sp.Symbol):
        self._rates_of = dict(zip(coordinates, kinematics, strict=True))
        self.t = t
        self._free: dict = {}
        self._rate: dict = {}
        self._diff: dict = {}

    def free(self, e: sp.Basic) -> frozenset:
        """The symbols of `e`."""
        table = self._free
        if e not in table:
            _fill(
                [e],
                table,
                lambda x: (
                    frozenset((x,))
                    if isinstance(x, sp.Symbol)
                    else frozenset().union(*(table[c] for c in x.args))
                ),
            )
        return table[e]  # type: ignore[no-any-return]

    def diff(self, e: Any, x: sp.Symbol) -> Any:
        """d e / d x (a matrix: entry by entry)."""
        if isinstance(e, sp.MatrixBase):
            return e.applyfunc(lambda c: self.diff(c, x))
        e = sp.sympify(e)
        if x not in self.free(e):
            return _ZERO
        table = self._diff.setdefault(x, {})
        if e not in table:
            has_x = lambda c: x in self.free(c)
            d = lambda c: table[c] if has_x(c) else _ZERO
            _fill([e], table, lambda n: self._chain(n, d, x), has_x)
        return table[e]

    def rate(self, e: Any) -> Any:
        """The time derivative of `e` with q' = N(q, u, t) and no u' terms (the velocity
        products: d/dt at u' = 0). A matrix: entry by entry."""
        if isinstance(e, sp.MatrixBase):
            return e.applyfunc(self.rate)
        e = sp.sympify(e)
        table = self._rate
        if e not in table:
            _fill([e], table, lambda n: self._chain(n, table.__getitem__, None))
        return table[e]

    def gradient(self, e: Any, xs: Sequence[sp.Symbol]) -> list:
        """d e / d x for every x of `xs`, in one pass from e down (reverse mode: each node's
        adjoint is the sum over its parents of theirs times the parent's derivative in it),
        which costs one graph of e where `diff` costs one per x."""
        e = sp.sympify(e)
        order: dict = {}
        _fill([e], order, lambda x: len(order), lambda c: bool(self.free(c)))
        # The adjoints are built unevaluated: sympy would flatten a sum of sums and distribute
        # a number over a sum, writing the shared adjoints out path by path (exponentially many
        # on a robot); unevaluated, each refers to its parents' as the graph does.
        terms: dict = {e: [sp.S.One]}
        for node in sorted(order, key=order.__getitem__, reverse=True):  # parents first
            parts = terms.pop(node, [])
            adjoint = parts[0] if len(parts) == 1 else sp.Add(*parts, evaluate=False)
            terms[node] = adjoint if parts else _ZERO  # final: every parent came before
            if not parts or isinstance(node, sp.Symbol):
                continue
            for arg, local in self._local_derivatives(node):
                term = adjoint if local is sp.S.One else sp.Mul(adjoint, local, evaluate=False)
                terms.setdefault(arg, []).append(term)
        return [terms.get(x, _ZERO) if x in order else _ZERO for x in xs]

    def _local_derivatives(self, e: sp.Basic) -> list[tuple[sp.Basic, sp.Basic]]:
        """(argument, d e / d argument) of one node, for its arguments that have symbols."""
        args = e.args
        moving = [i for i, a in enumerate(args) if self.free(a)]
        if e.is_Add:
            return [(args[i], sp.S.One) for i in moving]
        if e.is_Mul:
            return [(args[i], sp.Mul(*args[:i], *args[i + 1 :])) for i in moving]
        if e.is_Pow:
            base, exp = args
            local = {0: exp * base ** (exp - 1), 1: e * sp.log(base)}
            return [(args[i], local[i]) for i in moving]
        if isinstance(e, sp.Function):
            return [(args[i], e.fdiff(i + 1)) for i in moving]
        # anything else: sympy's rule for the node, in each of its symbols
        return [(x, sp.diff(e, x)) for x in self.free(e)]

    def jacobian(self, exprs: sp.MatrixBase, xs: Sequence) -> sp.Matrix:
        """The matrix d exprs_i / d xs_k."""
        return sp.Matrix(len(exprs), len(xs), lambda i, k: self.diff(exprs[i], xs[k]))

    def _chain(self, e: sp.Basic, d, x: sp.Symbol | None) -> sp.Basic:
        """One node's derivative from its arguments' (`d`): the partial derivative in x, or
        the time derivative (x None) where a coordinate's is its rate and t's is 1."""
        if isinstance(e, sp.Symbol):
            if x is not None:
                return sp.S.One if e == x else _ZERO
            return self._rates_of.get(e, sp.S.One if e == self.t else _ZERO)
        if not self.free(e):  # a number (is_number would walk the tree)
            return _ZERO
        if e.is_Add:
            return sp.Add(*[d(a) for a in e.args])
        if e.is_Mul:
            terms = []
            for i, a in enumerate(e.args):
                da = d(a)
                if da is not _ZERO:
                    terms.append(sp.Mul(*e.args[:i], da, *e.args[i + 1 :]))
            return sp.Add(*terms)
        if e.is_Pow:
            base, exp = e.args
            db, de = d(base), d(exp)
            out = exp * base ** (exp - 1) * db if db is not _ZERO else _ZERO
            return out + e * sp.log(base) * de if de is not _ZERO else out
        if isinstance(e, sp.Function):
            terms = [(i, d(a)) for i, a in enumerate(e.args)]
            return sp.Add(*[e.fdiff(i + 1) * da for i, da in terms if da is not _ZERO])
        # anything else (a Piecewise, a Derivative): sympy's own rule on this node
        if x is not None:
            return sp.diff(e, x)
        rates = [sp.diff(e, q) * r for q, r in self._rates_of.items()]
        return sp.diff(e, self.t) + sp.Add(*rates)

    def replace(self, e: Any, mapping: dict) -> Any:
        """`e` with the symbols of `mapping` replaced (xreplace, each node once; a matrix:
        entry by entry)."""
        if isinstance(e, sp.MatrixBase):
            return e.applyfunc(lambda c: self.replace(c, mapping))
        table: dict = dict(mapping)

        def rebuild(x: sp.Basic) -> sp.Basic:
            args = [table.get(c, c) for c in x.args]
            return (
                x.func(*args) if any(a is not c for a, c in zip(args, x.args, strict=True)) else x
            )

        keys = set(mapping)
        _fill([sp.sympify(e)], table, rebuild, lambda c: bool(keys & self.free(c)))
        return table.get(e, e)
