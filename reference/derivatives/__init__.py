"""Exact derivatives of the forward answer (u', lambda) with respect to the coordinates, the
speeds and the applied generalized forces: generated code (codegen), its evaluation (exact),
the slow obvious path beside it (differences) and the directions along which two sets of
equations must agree (directions)."""

from reference.derivatives.exact import BLOCKS, DerivativeModel, Derivatives

__all__ = ["BLOCKS", "DerivativeModel", "Derivatives"]
