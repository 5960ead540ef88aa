"""Probe: what a call into compiled code costs from Python, numba's dispatch against a plain
CPython extension function (benchmarks/reference_speed.md, "Why C beside numba").

Both compute pendulum_xy's u' and lambda from (q, u, t) into a preallocated out. The C one is
a METH_FASTCALL function taking its arrays through the buffer protocol (format and size
checked in C); it is written to a temporary directory and built with the system's C compiler.

    python benchmarks/c_crossing_probe.py
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
import sysconfig
import tempfile
import time
import timeit
from pathlib import Path

import numpy as np
from numba import njit

C_SOURCE = r"""
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
/* f(q, u, t, out): read q,u (float64 buffers), write out; returns status int */
static PyObject* fwd(PyObject* self, PyObject* const* args, Py_ssize_t nargs) {
    if (nargs != 4) { PyErr_SetString(PyExc_TypeError, "4 args"); return NULL; }
    Py_buffer bq, bu, bo;
    if (PyObject_GetBuffer(args[0], &bq, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0) return NULL;
    if (PyObject_GetBuffer(args[1], &bu, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0) {
        PyBuffer_Release(&bq);
        return NULL;
    }
    if (PyObject_GetBuffer(args[3], &bo, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_WRITABLE) < 0) {
        PyBuffer_Release(&bq);
        PyBuffer_Release(&bu);
        return NULL;
    }
    double t = PyFloat_AsDouble(args[2]);
    int st = 0;
    if (bq.format[0] != 'd' || bu.format[0] != 'd' || bo.format[0] != 'd'
        || bq.len != 16 || bu.len != 16 || bo.len != 32) st = 1;
    else {
        const double *q = bq.buf, *u = bu.buf; double *o = bo.buf;
        double L2 = q[0]*q[0] + q[1]*q[1];
        double lam = -(u[0]*u[0]+u[1]*u[1] - 9.81*q[1]) / L2;
        o[0] = lam*q[0]; o[1] = -9.81 + lam*q[1]; o[2] = lam; o[3] = 1.0 + t*0;
    }
    PyBuffer_Release(&bq); PyBuffer_Release(&bu); PyBuffer_Release(&bo);
    return PyLong_FromLong(st);
}
static PyMethodDef M[] = {{"fwd", (PyCFunction)(void(*)(void))fwd, METH_FASTCALL, ""}, {NULL}};
static struct PyModuleDef D = {PyModuleDef_HEAD_INIT, "fastcall", NULL, -1, M};
PyMODINIT_FUNC PyInit_fastcall(void) { return PyModule_Create(&D); }
"""


@njit(cache=False, error_model="numpy")
def numba_forward(q, u, t, out):
    if q.shape[0] != 2 or u.shape[0] != 2:
        return 1
    L2 = q[0] * q[0] + q[1] * q[1]
    lam = -(u[0] * u[0] + u[1] * u[1] - 9.81 * q[1]) / L2
    out[0] = lam * q[0]
    out[1] = -9.81 + lam * q[1]
    out[2] = lam
    out[3] = 1.0
    return 0


def build(directory: Path):
    """Compile the C source into an extension module and import it; (module, seconds)."""
    src = directory / "fastcall.c"
    src.write_text(C_SOURCE)
    target = directory / ("fastcall" + sysconfig.get_config_var("EXT_SUFFIX"))
    include = sysconfig.get_paths()["include"]
    t0 = time.perf_counter()
    cmd = ["gcc", "-O2", "-shared", "-fPIC", f"-I{include}", str(src), "-o", str(target)]
    subprocess.run(cmd, check=True)
    seconds = time.perf_counter() - t0
    spec = importlib.util.spec_from_file_location("fastcall", target)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod, seconds


def main() -> None:
    q, u, out = np.array([0.6, -0.8]), np.array([0.3, 0.2]), np.empty(4)
    with tempfile.TemporaryDirectory() as tmp:
        mod, seconds = build(Path(tmp))
        print(f"gcc -O2: {seconds:.2f} s")
        ref = np.empty(4)
        numba_forward(q, u, 0.0, ref)
        assert mod.fwd(q, u, 0.0, out) == 0 and np.array_equal(out, ref), (out, ref)
        assert mod.fwd(q.astype(np.int64), u, 0.0, out) == 1  # wrong format: refused
        for name, f in (
            ("C METH_FASTCALL", lambda: mod.fwd(q, u, 0.0, out)),
            ("numba @njit", lambda: numba_forward(q, u, 0.0, out)),
        ):
            n = 200_000
            best = min(timeit.repeat(f, number=n, repeat=7)) / n
            print(f"{name:16s} {best * 1e6:.3f} us per call (min of 7 x {n}, through a lambda)")


if __name__ == "__main__":
    sys.exit(main())
