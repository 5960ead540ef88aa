"""C source of the generated code: the same expressions as reference.backends.codegen's
Python module, printed as C functions that a C compiler builds into a CPython extension.

Why C: a CPython METH_FASTCALL function costs about 0.12 us to call, where a numba kernel,
the compiled backend before it, cost about 0.20 us before any arithmetic, and gcc builds a
model's straight-line code in about a second where numba's type inference took 10-20 s
(benchmarks/reference_speed.md, "Why C"). The expressions are printed from the same ast the
Python path runs, operation for operation and in the same order (every binary operation
parenthesized, no -ffast-math, no FMA contraction), with libm's sin, cos, sqrt and pow as
CPython calls them, so the results equal the Python path's, with one exception: gcc computes
pow(x, 2.0) as x*x, correctly rounded, where CPython's x**2 calls libm's pow, which rounds
differently in about 7 of 10^4 squares (tests/test_backends.py).

Each generated function F becomes `static int F_body(qa, ua, t, pa, db, out)`: inputs read
from double arrays by index (pa = the parameters, then the Schur references), outputs written
group after group into `out`, a status returned (reference.backends.kernels' codes). The
Python-facing wrappers, argument checks and batch loops are the hand-written runtime,
reference/backends/ckernel_runtime.h, which the generated file includes after its bodies. forward
also gets `forward_body4`, the same expressions on four states at once (one SIMD lane per state),
which the batch loop runs on blocks of four.
"""

from __future__ import annotations

import ast
import math
from pathlib import Path

from reference.backends.kernels import NOT_DEFINED, OK, SINGULAR, output_groups

RUNTIME = Path(__file__).with_name("ckernel_runtime.h")
LANES = Path(__file__).with_name("ckernel_lanes.h")
STEPPER = Path(__file__).with_name("ckernel_stepper.h")
# every header a module includes: each is part of the built file's digest
# (reference.backends.c_build)
HEADERS = (RUNTIME, LANES, STEPPER)

_BINOPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/"}
_FUNCTIONS = {"sin", "cos", "tan", "sqrt", "exp", "log", "atan2", "asin", "acos", "atan"}
_CONSTANTS = {"pi": repr(math.pi)}


class UnsupportedExpression(ValueError):
    """The generated code holds a construct this printer does not translate (the model then
    runs on the Python backend, the same expressions)."""


class _Printer:
    """C text of one generated function's expressions; names map to C locals."""

    def __init__(self, npar: int):
        self.npar = npar

    def expr(self, e: ast.expr) -> str:
        if isinstance(e, ast.BinOp):
            a, b = self.expr(e.left), self.expr(e.right)
            if isinstance(e.op, ast.Pow):  # CPython's float ** computes libm's pow as well
                return f"pow({a}, {b})"
            op = _BINOPS.get(type(e.op))
            if op is None:
                raise UnsupportedExpression(f"operator {type(e.op).__name__}")
            return f"({a} {op} {b})"
        if isinstance(e, ast.UnaryOp):
            if isinstance(e.op, ast.USub):
                return f"(-{self.expr(e.operand)})"
            if isinstance(e.op, ast.UAdd):
                return self.expr(e.operand)
            raise UnsupportedExpression(f"unary {type(e.op).__name__}")
        if isinstance(e, ast.Constant):
            if isinstance(e.value, bool) or not isinstance(e.value, int | float):
                raise UnsupportedExpression(f"constant {e.value!r}")
            # a double literal: 1/2 is 0.5 in Python and must not become C's integer division
            return f"({float(e.value)!r})"
        if isinstance(e, ast.Name):
            return _CONSTANTS.get(e.id, e.id)
        if isinstance(e, ast.Subscript) and isinstance(e.value, ast.Name):
            k = e.slice.value if isinstance(e.slice, ast.Constant) else None
            if e.value.id == "_sref" and isinstance(k, int):
                return f"pa[{self.npar + k}]"  # the Schur references travel after the parameters
            if e.value.id == "_db" and isinstance(k, int):
                return f"db[{k}]"
            raise UnsupportedExpression(f"subscript {ast.unparse(e)}")
        if isinstance(e, ast.Call) and isinstance(e.func, ast.Name):
            args = [self.expr(a) for a in e.args]
            if e.func.id == "_min":  # the pivot ratio: a NaN-propagating minimum
                code = args[0]
                for a in args[1:]:
                    code = f"nmin({code}, {a})"
                return code
            if e.func.id in _FUNCTIONS and not e.keywords:
                return f"{e.func.id}({', '.join(args)})"
            raise UnsupportedExpression(f"function {e.func.id}")
        raise UnsupportedExpression(type(e).__name__)


class _LanePrinter(_Printer):
    """The same expressions on four states at once (GCC vector extensions, one lane per
    state): every +, -, *, / is the same IEEE operation per lane, so each lane's result equals
    the scalar kernel's. The parameters, Schur references and b offsets are lanes too (a sweep
    gives each state its own; shared ones are splatted by the runtime); constants stay
    scalars, which meet a vector by GCC's broadcast. Functions run per lane (ckernel_lanes.h);
    x**2 is x*x, as gcc compiles the scalar kernel's pow(x, 2.0)."""

    def __init__(self, npar: int, lanes: set[str]):
        super().__init__(npar)
        self.lanes = lanes  # names holding one value per state

    def lane(self, e: ast.expr) -> tuple[str, bool]:
        """C text of `e` and whether it is a vector (depends on the state)."""
        if isinstance(e, ast.BinOp):
            (a, va), (b, vb) = self.lane(e.left), self.lane(e.right)
            if isinstance(e.op, ast.Pow):
                if not (va or vb):
                    return f"pow({a}, {b})", False
                if isinstance(e.right, ast.Constant) and e.right.value == 2:
                    return f"v_sq({a})", True
                return f"v_pow({_splat(a, va)}, {_splat(b, vb)})", True
            op = _BINOPS.get(type(e.op))
            if op is None:
                raise UnsupportedExpression(f"operator {type(e.op).__name__}")
            return f"({a} {op} {b})", va or vb
        if isinstance(e, ast.UnaryOp) and isinstance(e.op, ast.USub | ast.UAdd):
            a, va = self.lane(e.operand)
            return (f"(-{a})" if isinstance(e.op, ast.USub) else a), va
        if isinstance(e, ast.Name):
            return self.expr(e), e.id in self.lanes
        if isinstance(e, ast.Call) and isinstance(e.func, ast.Name):
            args = [self.lane(a) for a in e.args]
            if not any(v for _, v in args):
                return self.expr(e), False
            if e.func.id == "_min":
                code = _splat(*args[0])
                for a, va in args[1:]:
                    code = f"v_nmin({code}, {_splat(a, va)})"
                return code, True
            if e.func.id in _FUNCTIONS and not e.keywords:
                return f"v_{e.func.id}({', '.join(_splat(a, v) for a, v in args)})", True
            raise UnsupportedExpression(f"function {e.func.id}")
        if isinstance(e, ast.Subscript):  # Schur references and b offsets: pa[k], db[k]
            return self.expr(e), True
        return self.expr(e), False  # constants


def _sincos_pairs(fn: ast.FunctionDef) -> dict[str, tuple[str, str]]:
    """Names assigned exactly sin(x) and cos(x) of the same state-dependent x, each assigned
    once: name -> (sin name, cos name). gcc fuses such a pair into one sincos call in the
    scalar kernel, not across the vector body's per-lane loops, so the printer pairs them
    (glibc's sincos returns sin's and cos's values)."""
    seen: dict[str, dict[str, str]] = {}
    count: dict[str, int] = {}
    for st in fn.body:
        if isinstance(st, ast.Assign) and isinstance(st.targets[0], ast.Name):
            name = st.targets[0].id
            count[name] = count.get(name, 0) + 1
            v = st.value
            if (
                isinstance(v, ast.Call)
                and isinstance(v.func, ast.Name)
                and v.func.id in ("sin", "cos")
                and len(v.args) == 1
                and isinstance(v.args[0], ast.Name)
            ):
                seen.setdefault(v.args[0].id, {}).setdefault(v.func.id, name)
    pairs = {}
    for both in seen.values():
        if len(both) == 2 and count[both["sin"]] == count[both["cos"]] == 1:
            pair = (both["sin"], both["cos"])
            pairs[pair[0]] = pairs[pair[1]] = pair
    return pairs


def _splat(code: str, vector: bool) -> str:
    return code if vector else f"splat({code})"


def _lane_body(fn: ast.FunctionDef, dims: tuple[int, int, int]) -> list[str]:
    """`forward_body4`: forward on four states (q, u, t, parameters, b offsets: one vector
    lane per state), outputs and the pivot ratio into `out` as vectors; the runtime gathers,
    scatters and judges."""
    nq, n, npar = dims
    lanes = {f"_q{i}" for i in range(nq)} | {f"_u{i}" for i in range(n)} | {"_t"}
    lanes |= {f"_p{i}" for i in range(npar)}
    pr = _LanePrinter(npar, lanes)
    lines = _prologue(
        "static inline __attribute__((always_inline)) void forward_body4("
        "const vd *restrict qa, const vd *restrict ua, vd _t, const vd *restrict pa, "
        "const vd *restrict db, vd *restrict out)",
        "vd",
        dims,
        "vd",
    )
    declared: dict[str, bool] = {}
    pairs = _sincos_pairs(fn)
    ret = None
    for st in fn.body:
        if isinstance(st, ast.Return):
            ret = st
        elif isinstance(st, ast.Assign) and isinstance(st.targets[0], ast.Tuple):
            continue
        elif isinstance(st, ast.Assign) and isinstance(st.targets[0], ast.Name):
            name = st.targets[0].id
            pair = pairs.get(name)
            if pair is not None and pair[0] not in declared:  # the first of the two
                arg, vec = pr.lane(st.value.args[0])  # type: ignore[attr-defined]
                # (either assignment's argument: _sincos_pairs matched them by name)
                if not vec:  # of a constant: two plain scalar calls, as any other
                    pairs.pop(pair[0])
                    pairs.pop(pair[1])
                    pair = None
            if pair is not None:  # sin and cos of one angle: one sincos per lane
                if pair[0] not in declared:
                    lines.append(f"    vd {pair[0]}, {pair[1]};")
                    lines.append(f"    v_sincos({arg}, &{pair[0]}, &{pair[1]});")
                    declared.update({pair[0]: True, pair[1]: True})
                    lanes.update(pair)
                continue
            code, vec = pr.lane(st.value)
            if name in declared:
                if declared[name] != vec:  # a name changing kind: keep the scalar batch loop
                    raise UnsupportedExpression(f"{name} reassigned across kinds")
                lines.append(f"    {name} = {code};")
            else:
                declared[name] = vec
                lines.append(f"    {'vd' if vec else 'double'} {name} = {code};")
            if vec:
                lanes.add(name)
        else:
            raise UnsupportedExpression(f"statement {type(st).__name__} in {fn.name}")
    groups, piv = output_groups(ret) if ret is not None else ([], None)
    k = 0
    for g in groups:
        for e in g:
            lines.append(f"    out[{k}] = {_splat(*pr.lane(e))};")
            k += 1
    lines.append(f"    out[{k}] = {_splat(*pr.lane(piv)) if piv is not None else 'splat(1.0)'};")
    lines.append("}")
    return lines


def _prologue(
    signature: str, state_type: str, dims: tuple[int, int, int], param_type: str = "double"
) -> list[str]:
    """A body's signature and its loads: q, u and the parameters by index (of type
    `state_type` / `param_type`: one state's doubles or one vector lane per state)."""
    nq, n, npar = dims
    lines = [signature, "{", "    (void)qa; (void)ua; (void)_t; (void)pa; (void)db;"]
    lines += [f"    const {state_type} _q{i} = qa[{i}];" for i in range(nq)]
    lines += [f"    const {state_type} _u{i} = ua[{i}];" for i in range(n)]
    lines += [f"    const {param_type} _p{i} = pa[{i}];" for i in range(npar)]
    return lines


def _body(fn: ast.FunctionDef, dims: tuple[int, int, int], pmin: float) -> tuple[list, list]:
    """Lines of `static int <name>_body(...)` and the function's output group sizes."""
    pr = _Printer(dims[2])
    lines = _prologue(
        f"static int {fn.name}_body(const double *restrict qa, const double *restrict ua, "
        "double _t, const double *restrict pa, const double *restrict db, "
        "double *restrict out)",
        "double",
        dims,
    )
    declared: set[str] = set()
    ret = None
    for st in fn.body:
        if isinstance(st, ast.Return):
            ret = st
        elif isinstance(st, ast.Assign) and isinstance(st.targets[0], ast.Tuple):
            continue  # the unpacking of _q, _u, _p: loaded above by index
        elif (
            isinstance(st, ast.Assign)
            and len(st.targets) == 1
            and isinstance(st.targets[0], ast.Name)
        ):
            name = st.targets[0].id
            decl = "" if name in declared else "double "
            declared.add(name)
            lines.append(f"    {decl}{name} = {pr.expr(st.value)};")
        else:
            raise UnsupportedExpression(f"statement {type(st).__name__} in {fn.name}")
    if ret is None:
        raise UnsupportedExpression(f"generated function {fn.name} has no return statement")
    groups, piv = output_groups(ret)
    k = 0
    for g in groups:
        for e in g:
            lines.append(f"    out[{k}] = {pr.expr(e)};")
            k += 1
    # one test per output: a NaN or infinity from finite inputs is a division by zero in the
    # derived expressions (a coordinate singularity), never a number handed on silently
    lines.append("    int fin = 1;")
    lines.append(f"    for (int j = 0; j < {k}; ++j) fin &= isfinite(out[j]) != 0;")
    if fn.name == "forward":
        lines.append(f"    const double piv = {pr.expr(piv) if piv is not None else '1.0'};")
        lines.append(f"    out[{k}] = piv;")
        # `piv > pmin` is false for NaN: a NaN pivot ratio is singular, as on the other paths
        lines.append(f"    return piv > {pmin!r} ? (fin ? {OK} : {NOT_DEFINED}) : {SINGULAR};")
    else:
        lines.append(f"    return fin ? {OK} : {NOT_DEFINED};")
    lines.append("}")
    return lines, [len(g) for g in groups]


MODULE_NAME = "@MODULE@"  # replaced by the built module's name (reference.backends.c_build)


def c_source(src: str, nq: int, n: int, npar: int, m: int, pmin: float) -> tuple[str, dict]:
    """The C module for a generated Python module, and each function's output group sizes.
    Raises UnsupportedExpression (or RecursionError for expressions nested too deep) where
    the printer cannot translate the code."""
    tree = ast.parse(src)
    out = [
        "/* generated by reference.backends.c_source from reference.backends.codegen's module: "
        "do not edit */",
        "#define PY_SSIZE_T_CLEAN",
        "#include <Python.h>",
        "#include <math.h>",
        f"#define NQ {nq}",
        f"#define NU {n}",
        f"#define NP {npar}",
        f"#define NM {m}",
        f"#define MODULE_NAME {MODULE_NAME}",
        f"#define PIVOT_MIN {pmin!r}",
        '#include "ckernel_lanes.h"',
    ]
    sizes = {}
    for fn in tree.body:
        if isinstance(fn, ast.FunctionDef):
            lines, sizes[fn.name] = _body(fn, (nq, n, npar), pmin)
            out += ["", *lines]
            if fn.name == "forward":
                try:
                    lane = _lane_body(fn, (nq, n, npar))
                    nout = sum(sizes["forward"]) + 1
                    out += ["", "#define HAS_FORWARD4 1", f"#define FORWARD_NOUT {nout}", *lane]
                except UnsupportedExpression:
                    pass  # the batch runs the scalar kernel state by state
    out += ["", "#define KERNEL_BODIES \\"]
    for name, gs in sizes.items():
        total = sum(gs) + (1 if name == "forward" else 0)
        out.append(f'    KERNEL("{name}", {name}_body, {total}, {int(name == "forward")}) \\')
    out += ["", '#include "ckernel_runtime.h"', ""]
    return "\n".join(out), sizes
