/* Runtime of the generated C kernels (reference/backends/c_source.py).

   Included by each generated module after its kernel bodies; the module defines NQ, NU, NP,
   NM (coordinates, speeds, parameters, constraint rows), MODULE_NAME and KERNEL_BODIES, one
   KERNEL(name, body, nout, is_forward) per generated function.

   What the module exports, per kernel F (the same signatures as reference/compiled.py's numba
   kernels, so NumericModel drives either):
     F(q, u, t, pa, [db,] out) -> status         checked single state (db: forward only)
     F_batch(Q, U, T, P, DB, OUT, ST)            every state of a batch; OpenMP threads if set
   and
     set_threads(k)                              threads of the batch loops (1: serial)
     bind(name, pa, db, forward_type, slow)      the checked (forward_type given) or raw
                                                 (forward_type None) forward call, with its
                                                 parameters copied in (see Bound below)
     step(...)                                   a whole DOP853 run on the forward kernel,
                                                 projected or not (ckernel_stepper.h)

   Arrays must be ndarrays of native float64, C-contiguous and aligned (out writable), of the
   right size; anything else is a TypeError, as numba's dispatch raises it, and the caller
   converts (reference/numeric.py). A bound call never raises for a state it cannot take on
   its fast path: it hands the same arguments to `slow` (NumericModel's Python method), which
   converts, validates and words every error as the other backends do. */
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>
#include <stddef.h>
#include <string.h>

enum { ST_OK = 0, ST_BAD_Q = 1, ST_BAD_U = 2, ST_NOT_FINITE = 3, ST_SINGULAR = 4, ST_NOT_DEFINED = 5 };

typedef int (*body_fn)(const double *, const double *, double, const double *, const double *,
                       double *);

typedef struct {
    const char *name;
    body_fn body;
    Py_ssize_t nout;
    int is_forward;
} kernel_t;

#define KERNEL(name, body, nout, fwd) {name, body, nout, fwd},
static const kernel_t KERNELS[] = {KERNEL_BODIES{NULL, NULL, 0, 0}};
#undef KERNEL

static int batch_threads = 1;

/* A native float64, C-contiguous, aligned 1-D ndarray (writable if asked); its data and length. */
static inline int vec(PyObject *o, int writable, double **data, Py_ssize_t *len)
{
    if (!PyArray_Check(o)) return 0;
    PyArrayObject *a = (PyArrayObject *)o;
    if (PyArray_NDIM(a) != 1 || PyArray_TYPE(a) != NPY_DOUBLE || !PyArray_ISNOTSWAPPED(a)
        || !PyArray_IS_C_CONTIGUOUS(a) || !PyArray_ISALIGNED(a)
        || (writable && !PyArray_ISWRITEABLE(a)))
        return 0;
    *data = (double *)PyArray_DATA(a);
    *len = PyArray_DIM(a, 0);
    return 1;
}

/* The same for a 2-D array of `cols` columns (any number of rows); its row count. */
static inline int mat(PyObject *o, int writable, Py_ssize_t cols, double **data, Py_ssize_t *rows)
{
    if (!PyArray_Check(o)) return 0;
    PyArrayObject *a = (PyArrayObject *)o;
    if (PyArray_NDIM(a) != 2 || PyArray_TYPE(a) != NPY_DOUBLE || !PyArray_ISNOTSWAPPED(a)
        || !PyArray_IS_C_CONTIGUOUS(a) || !PyArray_ISALIGNED(a)
        || (writable && !PyArray_ISWRITEABLE(a)) || PyArray_DIM(a, 1) < cols)
        return 0;
    *data = (double *)PyArray_DATA(a);
    *rows = PyArray_DIM(a, 0);
    return 1;
}

/* Sizes, then finiteness: one sum is finite exactly when every term is, unless finite terms
   overflow; only then are the terms looked at one by one. */
static inline int check_state(const double *q, Py_ssize_t nq, const double *u, Py_ssize_t nu,
                              double t)
{
    if (nq != NQ) return ST_BAD_Q;
    if (nu != NU) return ST_BAD_U;
    double s = t;
    for (int i = 0; i < NQ; ++i) s += q[i];
    for (int i = 0; i < NU; ++i) s += u[i];
    if (!isfinite(s)) {
        if (!isfinite(t)) return ST_NOT_FINITE;
        for (int i = 0; i < NQ; ++i)
            if (!isfinite(q[i])) return ST_NOT_FINITE;
        for (int i = 0; i < NU; ++i)
            if (!isfinite(u[i])) return ST_NOT_FINITE;
    }
    return ST_OK;
}

static inline int as_time(PyObject *o, double *t)
{
    if (PyFloat_CheckExact(o)) {
        *t = PyFloat_AS_DOUBLE(o);
        return 1;
    }
    if (!PyFloat_Check(o) && !PyLong_Check(o)) return 0;
    *t = PyFloat_AsDouble(o);
    if (*t == -1.0 && PyErr_Occurred()) {
        PyErr_Clear();
        return 0;
    }
    return 1;
}

static PyObject *bad_arguments(const kernel_t *k)
{
    PyErr_Format(PyExc_TypeError,
                 "%s: takes native float64 C-contiguous vectors q (%d), u (%d), a number t, "
                 "pa (%d)%s and a writable out (%zd)",
                 k->name, NQ, NU, NP + NM, k->is_forward ? ", db (m)" : "", k->nout);
    return NULL;
}

/* F(q, u, t, pa, [db,] out) -> status: the kernel signature (self: a capsule of its kernel_t). */
static PyObject *call_single(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    const kernel_t *k = (const kernel_t *)PyCapsule_GetPointer(self, NULL);
    if (k == NULL) return NULL;
    const int na = k->is_forward ? 6 : 5;
    double *q, *u, *pa, *db = NULL, *out, t;
    Py_ssize_t nq, nu, npa, ndb = 0, nout;
    if (nargs != na || !vec(args[0], 0, &q, &nq) || !vec(args[1], 0, &u, &nu)
        || !as_time(args[2], &t) || !vec(args[3], 0, &pa, &npa) || npa < NP + NM
        || (k->is_forward && (!vec(args[4], 0, &db, &ndb) || ndb < NM))
        || !vec(args[na - 1], 1, &out, &nout) || nout < k->nout)
        return bad_arguments(k);
    int st = check_state(q, nq, u, nu, t);
    if (st == ST_OK) st = k->body(q, u, t, pa, db, out);
    return PyLong_FromLong(st);
}

#ifdef HAS_FORWARD4
/* Four states of a batch whose checks passed, on forward_body4 (one vector lane per state):
   gather (parameters and b offsets per state where the batch has one row each; shared ones
   come splatted once per batch, in ps and ds), compute, scatter, and judge each lane as the
   scalar kernel judges its state.
   Compiled for AVX2 only (a baseline clone doubled the build time for a 2-lane gain); a CPU
   without AVX2 runs the scalar kernel state by state (call_batch asks the CPU). */
__attribute__((target("avx2"))) static void
forward_block(const double *Q, const double *U, const double *T, Py_ssize_t nT, const double *P,
              Py_ssize_t sP, const double *DB, Py_ssize_t sDB, const vd *ps, const vd *ds,
              double *OUT, Py_ssize_t sOUT, int64_t *ST, Py_ssize_t i)
{
    vd qv[NQ > 0 ? NQ : 1], uv[NU > 0 ? NU : 1], pv[NP + NM > 0 ? NP + NM : 1],
        dv[NM > 0 ? NM : 1], out[FORWARD_NOUT], tv;
    for (int k = 0; k < NQ; ++k)
        for (int j = 0; j < LANES; ++j) qv[k][j] = Q[(i + j) * NQ + k];
    for (int k = 0; k < NU; ++k)
        for (int j = 0; j < LANES; ++j) uv[k][j] = U[(i + j) * NU + k];
    if (ps == NULL)
        for (int k = 0; k < NP + NM; ++k)
            for (int j = 0; j < LANES; ++j) pv[k][j] = P[(i + j) * sP + k];
    if (ds == NULL)
        for (int k = 0; k < NM; ++k)
            for (int j = 0; j < LANES; ++j) dv[k][j] = DB[(i + j) * sDB + k];
    for (int j = 0; j < LANES; ++j) tv[j] = T[nT > 1 ? i + j : 0];
    forward_body4(qv, uv, tv, ps ? ps : pv, ds ? ds : dv, out);
    for (int j = 0; j < LANES; ++j) {
        double *o = OUT + (i + j) * sOUT;
        int fin = 1;
        for (int k = 0; k < FORWARD_NOUT; ++k) o[k] = out[k][j];
        for (int k = 0; k < FORWARD_NOUT - 1; ++k) fin &= isfinite(o[k]) != 0;
        const double piv = o[FORWARD_NOUT - 1];
        ST[i + j] = piv > PIVOT_MIN ? (fin ? ST_OK : ST_NOT_DEFINED) : ST_SINGULAR;
    }
}
#endif

/* F_batch(Q, U, T, P, DB, OUT, ST): state i reads row i of Q, U and OUT, and row i of T, P,
   DB where those have one row per state (else their one row); ST[i] = its status. */
static PyObject *call_batch(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    const kernel_t *k = (const kernel_t *)PyCapsule_GetPointer(self, NULL);
    if (k == NULL) return NULL;
    double *Q, *U, *T, *P, *DB, *OUT;
    Py_ssize_t nQ, nU, nT, nP, nDB, nOUT;
    if (nargs != 7 || !mat(args[0], 0, NQ, &Q, &nQ) || !mat(args[1], 0, NU, &U, &nU)
        || !vec(args[2], 0, &T, &nT) || !mat(args[3], 0, NP + NM, &P, &nP)
        || !mat(args[4], 0, NM, &DB, &nDB) || !mat(args[5], 1, k->nout, &OUT, &nOUT)
        || !PyArray_Check(args[6]) || PyArray_TYPE((PyArrayObject *)args[6]) != NPY_INT64
        || PyArray_NDIM((PyArrayObject *)args[6]) != 1
        || !PyArray_IS_C_CONTIGUOUS((PyArrayObject *)args[6])
        || !PyArray_ISWRITEABLE((PyArrayObject *)args[6]))
        return bad_arguments(k);
    const Py_ssize_t N = nQ;
    if (nU != N || nOUT != N || PyArray_DIM((PyArrayObject *)args[6], 0) != N
        || (nT != 1 && nT != N) || (nP != 1 && nP != N) || (nDB != 1 && nDB != N)
        || PyArray_DIM((PyArrayObject *)args[0], 1) != NQ
        || PyArray_DIM((PyArrayObject *)args[1], 1) != NU) {
        PyErr_Format(PyExc_ValueError, "%s_batch: inconsistent batch shapes", k->name);
        return NULL;
    }
    int64_t *ST = (int64_t *)PyArray_DATA((PyArrayObject *)args[6]);
    const Py_ssize_t sP = PyArray_DIM((PyArrayObject *)args[3], 1);
    const Py_ssize_t sDB = PyArray_DIM((PyArrayObject *)args[4], 1);
    const Py_ssize_t sOUT = PyArray_DIM((PyArrayObject *)args[5], 1);
    const int nth = batch_threads;
#ifdef HAS_FORWARD4
    /* blocks of four on the vector body, the parameters shared or one row per state */
    const int four = k->is_forward && __builtin_cpu_supports("avx2");
#else
    const int four = 0;
#endif
    const Py_ssize_t nblocks = (N + LANES - 1) / LANES;
#ifdef HAS_FORWARD4
    /* shared parameters and b offsets: splatted once for every block */
    vd ps[NP + NM > 0 ? NP + NM : 1], ds[NM > 0 ? NM : 1];
    if (four) {
        for (int k = 0; k < NP + NM; ++k)
            for (int j = 0; j < LANES; ++j) ps[k][j] = P[k];
        for (int k = 0; k < NM; ++k)
            for (int j = 0; j < LANES; ++j) ds[k][j] = DB[k];
    }
    const vd *psh = nP == 1 ? ps : NULL, *dsh = nDB == 1 ? ds : NULL;
#endif
    Py_BEGIN_ALLOW_THREADS
#pragma omp parallel for schedule(static) num_threads(nth) if (nth > 1)
    for (Py_ssize_t blk = 0; blk < nblocks; ++blk) {
        const Py_ssize_t i0 = blk * LANES, i1 = i0 + LANES < N ? i0 + LANES : N;
        int st[LANES], all_ok = four && i1 - i0 == LANES;
        for (Py_ssize_t i = i0; i < i1; ++i) {
            st[i - i0] = check_state(Q + i * NQ, NQ, U + i * NU, NU, T[nT > 1 ? i : 0]);
            all_ok = all_ok && st[i - i0] == ST_OK;
        }
#ifdef HAS_FORWARD4
        if (all_ok) {
            forward_block(Q, U, T, nT, P, sP, DB, sDB, psh, dsh, OUT, sOUT, ST, i0);
            continue;
        }
#endif
        for (Py_ssize_t i = i0; i < i1; ++i) {
            if (st[i - i0] == ST_OK)
                st[i - i0] = k->body(Q + i * NQ, U + i * NU, T[nT > 1 ? i : 0],
                                     P + (nP > 1 ? i : 0) * sP, DB + (nDB > 1 ? i : 0) * sDB,
                                     OUT + i * sOUT);
            ST[i] = st[i - i0];
        }
    }
    Py_END_ALLOW_THREADS
    return PyLong_FromLong(0);
}

static PyObject *set_threads(PyObject *self, PyObject *arg)
{
    long k = PyLong_AsLong(arg);
    if (k == -1 && PyErr_Occurred()) return NULL;
    batch_threads = k < 1 ? 1 : (int)k;
    Py_RETURN_NONE;
}

/* ---- Bound: forward(q, u, t) or forward_raw(q, u, t, db=None, out=None) in one C call --- */
typedef struct {
    PyObject_HEAD
    vectorcallfunc vectorcall;
    const kernel_t *k;
    double pa[NP + 2 * NM + 1]; /* parameters, Schur references, then the b offsets */
    PyObject *forward_type; /* NULL: the raw call */
    PyObject *slow;         /* the Python method taking the same arguments */
} Bound;

static PyObject *s_accelerations, *s_multipliers, *s_pivot_ratio, *s_rank, *s_db, *s_out;

static PyObject *vector_of(const double *x, Py_ssize_t n)
{
    npy_intp dim = n;
    PyObject *a = PyArray_SimpleNew(1, &dim, NPY_DOUBLE);
    if (a != NULL && n) memcpy(PyArray_DATA((PyArrayObject *)a), x, n * sizeof(double));
    return a;
}

/* The Forward record: allocated by its type, its slots stored (no Python __init__ runs). */
static PyObject *forward_record(Bound *b, const double *buf)
{
    PyTypeObject *tp = (PyTypeObject *)b->forward_type;
    PyObject *f = tp->tp_alloc(tp, 0);
    if (f == NULL) return NULL;
    PyObject *ud = vector_of(buf, NU), *lam = vector_of(buf + NU, NM);
    PyObject *piv = PyFloat_FromDouble(buf[NU + NM]);
    int bad = ud == NULL || lam == NULL || piv == NULL
              || PyObject_SetAttr(f, s_accelerations, ud) < 0
              || PyObject_SetAttr(f, s_multipliers, lam) < 0
              || PyObject_SetAttr(f, s_pivot_ratio, piv) < 0
              || PyObject_SetAttr(f, s_rank, Py_None) < 0;
    Py_XDECREF(ud);
    Py_XDECREF(lam);
    Py_XDECREF(piv);
    if (bad) {
        Py_DECREF(f);
        return NULL;
    }
    return f;
}

static PyObject *bound_call(PyObject *self, PyObject *const *args, size_t nargsf, PyObject *kw)
{
    Bound *b = (Bound *)self;
    const Py_ssize_t nargs = PyVectorcall_NARGS(nargsf);
    const int raw = b->forward_type == NULL;
    PyObject *db = Py_None, *outobj = Py_None;
    if (nargs > 3) db = args[3];
    if (nargs > 4) outobj = args[4];
    if (kw != NULL) {
        for (Py_ssize_t j = 0; j < PyTuple_GET_SIZE(kw); ++j) {
            PyObject *name = PyTuple_GET_ITEM(kw, j);
            if (name == s_db || PyUnicode_Compare(name, s_db) == 0) db = args[nargs + j];
            else if (name == s_out || PyUnicode_Compare(name, s_out) == 0)
                outobj = args[nargs + j];
            else
                goto slow;
        }
    }
    double *q, *u, *out = NULL, t = 0.0, local[NU + NM + 1];
    Py_ssize_t nq, nu, nout;
    if (nargs < (raw ? 3 : 2) || nargs > (raw ? 5 : 3) || db != Py_None
        || !vec(args[0], 0, &q, &nq) || !vec(args[1], 0, &u, &nu)
        || (nargs > 2 && !as_time(args[2], &t)))
        goto slow;
    if (outobj != Py_None && (!vec(outobj, 1, &out, &nout) || nout != NU + NM + 1)) goto slow;
    if (check_state(q, nq, u, nu, t) != ST_OK) goto slow;
    double *buf = out != NULL ? out : local;
    const int st = b->k->body(q, u, t, b->pa, b->pa + NP + NM, buf);
    /* a singular pose is a number to the raw call (the caller tests the ratio), an error to
       the checked call; an undefined expression is an error to both: the slow path words it */
    if (st != ST_OK && !(raw && st == ST_SINGULAR)) goto slow;
    if (!raw) return forward_record(b, buf);
    if (out != NULL) return Py_NewRef(outobj);
    PyObject *ud = vector_of(buf, NU), *lam = vector_of(buf + NU, NM);
    PyObject *piv = PyFloat_FromDouble(buf[NU + NM]);
    if (ud == NULL || lam == NULL || piv == NULL) {
        Py_XDECREF(ud);
        Py_XDECREF(lam);
        Py_XDECREF(piv);
        return NULL;
    }
    PyObject *res = PyTuple_Pack(3, ud, lam, piv);
    Py_DECREF(ud);
    Py_DECREF(lam);
    Py_DECREF(piv);
    return res;
slow:
    return PyObject_Vectorcall(b->slow, args, nargsf, kw);
}

static int bound_traverse(PyObject *self, visitproc visit, void *arg)
{
    Bound *b = (Bound *)self;
    Py_VISIT(b->forward_type);
    Py_VISIT(b->slow);
    return 0;
}

static int bound_clear(PyObject *self)
{
    Bound *b = (Bound *)self;
    Py_CLEAR(b->forward_type);
    Py_CLEAR(b->slow);
    return 0;
}

static void bound_dealloc(PyObject *self)
{
    PyObject_GC_UnTrack(self);
    bound_clear(self);
    Py_TYPE(self)->tp_free(self);
}

static PyTypeObject BoundType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "ckernel.Bound",
    .tp_basicsize = sizeof(Bound),
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_GC | Py_TPFLAGS_HAVE_VECTORCALL,
    .tp_vectorcall_offset = offsetof(Bound, vectorcall),
    .tp_call = PyVectorcall_Call,
    .tp_traverse = bound_traverse,
    .tp_clear = bound_clear,
    .tp_dealloc = bound_dealloc,
    .tp_doc = "forward dynamics of one model and parameter set in one C call",
};

static const kernel_t *kernel_named(PyObject *name)
{
    const char *s = PyUnicode_AsUTF8(name);
    if (s == NULL) return NULL;
    for (const kernel_t *k = KERNELS; k->name != NULL; ++k)
        if (strcmp(k->name, s) == 0) return k;
    PyErr_Format(PyExc_KeyError, "no kernel %s", s);
    return NULL;
}

/* bind(name, pa, db, forward_type, slow): pa and db are copied (the call owns its values). */
static PyObject *bind(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    double *pa, *db;
    Py_ssize_t npa, ndb;
    if (nargs != 5 || !vec(args[1], 0, &pa, &npa) || npa != NP + NM
        || !vec(args[2], 0, &db, &ndb) || ndb < NM || !PyCallable_Check(args[4])
        || (args[3] != Py_None && !PyType_Check(args[3]))) {
        PyErr_SetString(PyExc_TypeError, "bind(name, pa, db, forward_type or None, slow)");
        return NULL;
    }
    const kernel_t *k = kernel_named(args[0]);
    if (k == NULL) return NULL;
    if (!k->is_forward) {
        PyErr_SetString(PyExc_ValueError, "bind: only the forward kernel is bound");
        return NULL;
    }
    Bound *b = PyObject_GC_New(Bound, &BoundType);
    if (b == NULL) return NULL;
    b->vectorcall = bound_call;
    b->k = k;
    memcpy(b->pa, pa, (NP + NM) * sizeof(double));
    if (NM) memcpy(b->pa + NP + NM, db, NM * sizeof(double));
    b->forward_type = args[3] == Py_None ? NULL : Py_NewRef(args[3]);
    b->slow = Py_NewRef(args[4]);
    PyObject_GC_Track((PyObject *)b);
    return (PyObject *)b;
}

#include "ckernel_stepper.h"

static PyMethodDef module_methods[] = {
    {"set_threads", set_threads, METH_O, "threads of the batch loops (1: serial)"},
    {"bind", (PyCFunction)(void (*)(void))bind, METH_FASTCALL, "a bound forward call"},
    {"step", (PyCFunction)(void (*)(void))step, METH_FASTCALL, "a whole DOP853 run"},
    {NULL, NULL, 0, NULL},
};

static PyMethodDef single_def = {"kernel", (PyCFunction)(void (*)(void))call_single,
                                 METH_FASTCALL, "F(q, u, t, pa, [db,] out) -> status"};
static PyMethodDef batch_def = {"kernel_batch", (PyCFunction)(void (*)(void))call_batch,
                                METH_FASTCALL, "F_batch(Q, U, T, P, DB, OUT, ST)"};

#define STR2(x) #x
#define STR(x) STR2(x)
#define CAT2(a, b) a##b
#define CAT(a, b) CAT2(a, b)

static struct PyModuleDef module_def = {PyModuleDef_HEAD_INIT, STR(MODULE_NAME), NULL, -1,
                                        module_methods};

static int add_kernel(PyObject *mod, const kernel_t *k, PyMethodDef *def, const char *suffix)
{
    char name[128];
    snprintf(name, sizeof name, "%s%s", k->name, suffix);
    PyObject *cap = PyCapsule_New((void *)k, NULL, NULL);
    if (cap == NULL) return -1;
    PyObject *f = PyCFunction_NewEx(def, cap, NULL);
    Py_DECREF(cap);
    if (f == NULL) return -1;
    const int r = PyModule_AddObjectRef(mod, name, f);
    Py_DECREF(f);
    return r;
}

PyMODINIT_FUNC CAT(PyInit_, MODULE_NAME)(void)
{
    import_array();
    __builtin_cpu_init();
    if (PyType_Ready(&BoundType) < 0) return NULL;
    s_accelerations = PyUnicode_InternFromString("accelerations");
    s_multipliers = PyUnicode_InternFromString("multipliers");
    s_pivot_ratio = PyUnicode_InternFromString("pivot_ratio");
    s_rank = PyUnicode_InternFromString("rank");
    s_db = PyUnicode_InternFromString("db");
    s_out = PyUnicode_InternFromString("out");
    PyObject *mod = PyModule_Create(&module_def);
    if (mod == NULL) return NULL;
    for (const kernel_t *k = KERNELS; k->name != NULL; ++k)
        if (add_kernel(mod, k, &single_def, "") < 0 || add_kernel(mod, k, &batch_def, "_batch") < 0) {
            Py_DECREF(mod);
            return NULL;
        }
    PyObject *sizes = PyDict_New();
    if (sizes == NULL) {
        Py_DECREF(mod);
        return NULL;
    }
    for (const kernel_t *k = KERNELS; k->name != NULL; ++k) {
        PyObject *v = PyLong_FromSsize_t(k->nout);
        if (v == NULL || PyDict_SetItemString(sizes, k->name, v) < 0) {
            Py_XDECREF(v);
            Py_DECREF(sizes);
            Py_DECREF(mod);
            return NULL;
        }
        Py_DECREF(v);
    }
    const int r = PyModule_AddObjectRef(mod, "OUT_SIZES", sizes);
    Py_DECREF(sizes);
    if (r < 0) {
        Py_DECREF(mod);
        return NULL;
    }
    return mod;
}
