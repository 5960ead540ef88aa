"""MuJoCo's compiled doubles as exact sympy numbers: the reference derives its equations from
them symbolically, so no digit of the file's numbers is lost in code generation."""

from __future__ import annotations

import sympy as sp


def num(x: float) -> sp.Expr:
    """A compiled double as an exact sympy number (a short fraction when it is exactly one)."""
    x = float(x)
    if x == 0.0:
        return sp.Integer(0)
    r = sp.Rational(x).limit_denominator(10**6)
    return r if float(r) == x else sp.Rational(x)
