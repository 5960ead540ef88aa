/* The compiled stepper of reference.integrate (issue 13): scipy's DOP853 step (the loop of
   reference/integrate_rk.py's LeanDOP853, the same formulas in the same order) driving the
   module's own forward kernel, and the coordinate projection of integrate_projection.py after
   every accepted step. Included by ckernel_runtime.h; reference/integrate_compiled.py drives it
   and owns every decision about when it may run.

   step(y, f, (t, t_bound, h_abs, max_step, rtol, atol, error_exponent, deadline_s),
        (A, B, C, E3, E5), pa, db, (mode, max_steps, a_offset, max_iter),
        (projection_tol, projection_fail))
     y, f       the state after the solver's start and its derivative (scipy computed both,
                and the first step size h_abs, in Python: the same start as LeanDOP853's)
     A..E5      the solver's own tableau arrays (scipy's, read from the solver: never copied)
     mode       0: index1, y' = (u, u'); 1: projection (refreshing f after it); 2: projection
                reusing the unprojected f
     a_offset   where the velocity rows' A sits in the `matrices` output (-1: A is the position
                Jacobian, the models whose rows are all configuration rows)
   returns (status, T, Y, nfev, nsteps, min_pivot, projections, projection_iterations, t, y):
   T and Y every accepted (projected) step; status
     0  t_bound reached
     1  the step size fell below 10 ulp of t (scipy's TOO_SMALL_STEP)
     2  max_steps accepted before t_bound       3  the wall-time deadline passed
     4  the stepper stopped at (t, y): a right side it does not take (a singular or undefined
        forward, a rank-deficient projection, a projection that did not converge); the
        caller re-runs on the Python stepper, which words the error */

#include <time.h>

enum { STEP_DONE = 0, STEP_TOO_SMALL = 1, STEP_MAX_STEPS = 2, STEP_DEADLINE = 3, STEP_DECLINED = 4 };
#define NY (NQ + NU)

typedef struct {
    const kernel_t *fwd, *res, *pjac, *mat;
    const double *pa, *db;
    double *fo, *ro, *jo, *mo, *jj; /* kernel outputs, J J^T */
    double pmin;
    long nfev, iters;
    int a_offset, max_iter;
    double ptol, pfail;
} stepper_t;

/* y' = (u, u'(q, u, t)) into out; 0 where the forward is not defined or singular there. */
static int rhs(stepper_t *s, double t, const double *y, double *out)
{
    ++s->nfev;
    const int st = s->fwd->body(y, y + NQ, t, s->pa, s->db, s->fo);
    const double piv = s->fo[NU + NM];
    if (st != ST_OK || !(piv > PIVOT_MIN)) return 0;
    if (piv < s->pmin) s->pmin = piv;
    for (int i = 0; i < NU; ++i) out[i] = y[NQ + i];
    for (int i = 0; i < NU; ++i) out[NQ + i] = s->fo[i];
    return 1;
}

/* x <- x - J^T (J J^T)^-1 r for J (rows x cols, row-major): the minimum-norm correction of
   integrate_common._min_norm_correction (one row: r / |J|^2 as there; more: a Cholesky
   factor of J J^T). 0 where J J^T is not positive definite. */
static int min_norm_step(double *x, const double *J, int rows, int cols, const double *r,
                         double *JJ)
{
    if (rows == 1) {
        double jj = 0.0;
        for (int k = 0; k < cols; ++k) jj += J[k] * J[k];
        if (!(jj > 0.0) || !isfinite(jj)) return 0;
        const double c = r[0] / jj;
        for (int k = 0; k < cols; ++k) x[k] += -c * J[k];
        return 1;
    }
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j <= i; ++j) {
            double a = 0.0;
            for (int k = 0; k < cols; ++k) a += J[i * cols + k] * J[j * cols + k];
            JJ[i * rows + j] = a;
        }
    for (int j = 0; j < rows; ++j) { /* L L^T in the lower triangle */
        double d = JJ[j * rows + j];
        for (int k = 0; k < j; ++k) d -= JJ[j * rows + k] * JJ[j * rows + k];
        if (!(d > 0.0) || !isfinite(d)) return 0;
        d = sqrt(d);
        JJ[j * rows + j] = d;
        for (int i = j + 1; i < rows; ++i) {
            double a = JJ[i * rows + j];
            for (int k = 0; k < j; ++k) a -= JJ[i * rows + k] * JJ[j * rows + k];
            JJ[i * rows + j] = a / d;
        }
    }
    double z[rows];
    for (int i = 0; i < rows; ++i) { /* L z = r, then L^T z = z */
        double a = r[i];
        for (int k = 0; k < i; ++k) a -= JJ[i * rows + k] * z[k];
        z[i] = a / JJ[i * rows + i];
    }
    for (int i = rows - 1; i >= 0; --i) {
        double a = z[i];
        for (int k = i + 1; k < rows; ++k) a -= JJ[k * rows + i] * z[k];
        z[i] = a / JJ[i * rows + i];
    }
    for (int k = 0; k < cols; ++k) {
        double a = 0.0;
        for (int i = 0; i < rows; ++i) a += J[i * cols + k] * z[i];
        x[k] -= a;
    }
    return 1;
}

/* integrate_projection._Projection.project: Gauss-Newton on f(q, t) = 0, then u onto
   A u + a0 = 0 with the velocity residual at the final q. 0 where it cannot. */
static int project(stepper_t *s, double t, double *y)
{
    static const double zeros[NU > 0 ? NU : 1];
    double *q = y, *u = y + NQ, qmax = 0.0, err = 0.0;
    const int mc = (int)s->res->nout - NM;
    for (int i = 0; i < NQ; ++i) qmax = fabs(q[i]) > qmax ? fabs(q[i]) : qmax;
    const double tol = s->ptol * (1.0 + qmax);
    for (int it = 0;; ++it) {
        if (s->res->body(q, u, t, s->pa, s->db, s->ro) != ST_OK) return 0;
        err = 0.0;
        for (int i = 0; i < mc; ++i) err = fabs(s->ro[i]) > err ? fabs(s->ro[i]) : err;
        if (err <= tol || it == s->max_iter) break;
        if (s->pjac->body(q, zeros, t, s->pa, s->db, s->jo) != ST_OK
            || !min_norm_step(q, s->jo, mc, NQ, s->ro, s->jj))
            return 0;
        ++s->iters;
    }
    if (!(err <= s->pfail)) return 0;
    const double *A = s->jo;
    if (s->a_offset < 0) {
        if (s->pjac->body(q, zeros, t, s->pa, s->db, s->jo) != ST_OK) return 0;
    } else {
        if (s->mat->body(q, u, t, s->pa, s->db, s->mo) != ST_OK) return 0;
        A = s->mo + s->a_offset;
    }
    return NM == 0 || min_norm_step(u, A, NM, NU, s->ro + mc, s->jj);
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

typedef struct {
    double t, t_bound, h_abs, max_step, rtol, atol, exponent, deadline;
    const double *A, *B, *C, *E3, *E5;
    int ns, mode;
    long max_steps;
} run_t;

/* One attempt of LeanDOP853._stage_sweep and _error_norm: K filled, y_new, f_new = K[ns];
   the error norm, or -1 where a stage's right side was declined (stop at *ty). */
static double sweep(stepper_t *s, const run_t *r, double t, const double *y, double h,
                    double *K, double *ys, double *y_new, double *stop_t)
{
    const int ns = r->ns;
    for (int st = 1; st < ns; ++st) {
        for (int i = 0; i < NY; ++i) {
            double a = 0.0;
            for (int j = 0; j < st; ++j) a += (h * r->A[st * ns + j]) * K[j * NY + i];
            ys[i] = y[i] + a;
        }
        if (!rhs(s, t + r->C[st] * h, ys, K + st * NY)) {
            *stop_t = t + r->C[st] * h;
            return -1.0;
        }
    }
    for (int i = 0; i < NY; ++i) {
        double a = 0.0;
        for (int j = 0; j < ns; ++j) a += r->B[j] * K[j * NY + i];
        y_new[i] = y[i] + h * a;
    }
    if (!rhs(s, t + h, y_new, K + ns * NY)) {
        memcpy(ys, y_new, sizeof(double) * NY);
        *stop_t = t + h;
        return -1.0;
    }
    double e5 = 0.0, e3 = 0.0;
    for (int i = 0; i < NY; ++i) {
        double a5 = 0.0, a3 = 0.0;
        for (int j = 0; j <= ns; ++j) {
            a5 += r->E5[j] * K[j * NY + i];
            a3 += r->E3[j] * K[j * NY + i];
        }
        const double ay = fabs(y[i]), an = fabs(y_new[i]);
        const double sc = r->atol + (ay > an ? ay : an) * r->rtol;
        a5 /= sc;
        a3 /= sc;
        e5 += a5 * a5;
        e3 += a3 * a3;
    }
    if (e5 == 0.0 && e3 == 0.0) return 0.0;
    return fabs(h) * e5 / sqrt((e5 + 0.01 * e3) * NY);
}

typedef struct {
    double *T, *Y;
    Py_ssize_t n, cap;
} record_t;

static int record(record_t *rec, double t, const double *y)
{
    if (rec->n == rec->cap) {
        const Py_ssize_t cap = rec->cap ? 2 * rec->cap : 256;
        double *T = realloc(rec->T, cap * sizeof(double));
        if (T == NULL) return 0;
        rec->T = T;
        double *Y = realloc(rec->Y, cap * NY * sizeof(double));
        if (Y == NULL) return 0;
        rec->Y = Y;
        rec->cap = cap;
    }
    rec->T[rec->n] = t;
    memcpy(rec->Y + rec->n * NY, y, sizeof(double) * NY);
    ++rec->n;
    return 1;
}

/* The solver loop of reference.integrate._Run with LeanDOP853._step_impl inside (scipy's
   step-size control: SAFETY 0.9, factors 0.2..10, no growth right after a rejection). */
static int run_steps(stepper_t *s, run_t *r, double *y, double *f, double *K, double *ys,
                     record_t *rec, long *nsteps, long *projections, double *stop_t)
{
    const double SAFETY = 0.9, MIN_FACTOR = 0.2, MAX_FACTOR = 10.0;
    double y_new[NY];
    double t = r->t, h_abs = r->h_abs;
    while (t - r->t_bound < 0) {
        const double min_step = 10 * fabs(nextafter(t, INFINITY) - t);
        h_abs = h_abs > min_step ? h_abs : min_step;
        h_abs = h_abs < r->max_step ? h_abs : r->max_step;
        int rejected = 0;
        double t_new, h;
        for (;;) {
            if (h_abs < min_step) {
                *stop_t = t;
                memcpy(ys, y, sizeof(double) * NY);
                return STEP_TOO_SMALL;
            }
            t_new = t + h_abs;
            if (t_new - r->t_bound > 0) t_new = r->t_bound;
            h = t_new - t;
            h_abs = fabs(h);
            memcpy(K, f, sizeof(double) * NY);
            const double err = sweep(s, r, t, y, h, K, ys, y_new, stop_t);
            if (err < 0.0) return STEP_DECLINED;
            if (err < 1.0) {
                double factor = MAX_FACTOR;
                if (err != 0.0) {
                    factor = SAFETY * pow(err, r->exponent);
                    factor = factor < MAX_FACTOR ? factor : MAX_FACTOR;
                }
                h_abs *= rejected ? (factor < 1.0 ? factor : 1.0) : factor;
                break;
            }
            const double shrink = SAFETY * pow(err, r->exponent);
            h_abs *= shrink > MIN_FACTOR ? shrink : MIN_FACTOR; /* Python's max(0.2, x) */
            rejected = 1;
        }
        t = t_new;
        memcpy(y, y_new, sizeof(double) * NY);
        memcpy(f, K + r->ns * NY, sizeof(double) * NY);
        ++*nsteps;
        if (r->mode) {
            if (!project(s, t, y)) {
                *stop_t = t;
                memcpy(ys, y, sizeof(double) * NY);
                return STEP_DECLINED;
            }
            ++*projections;
            if (r->mode == 1 && !rhs(s, t, y, f)) {
                *stop_t = t;
                memcpy(ys, y, sizeof(double) * NY);
                return STEP_DECLINED;
            }
        }
        if (!record(rec, t, y)) return -1;
        const int running = t - r->t_bound < 0;
        *stop_t = t;
        if (running && r->max_steps >= 0 && *nsteps >= r->max_steps) return STEP_MAX_STEPS;
        if (running && now_s() > r->deadline) return STEP_DEADLINE;
    }
    return STEP_DONE;
}

static int vec_of(PyObject *o, Py_ssize_t n, double **d)
{
    Py_ssize_t len;
    return vec(o, 0, d, &len) && len >= n;
}

static PyObject *step(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    double *y0, *f0, *pa, *db;
    run_t r = {0};
    stepper_t s = {0};
    PyObject *tab, *opt, *tol;
    if (nargs != 8 || !vec_of(args[0], NY, &y0) || !vec_of(args[1], NY, &f0)
        || !PyArg_ParseTuple(args[2], "dddddddd", &r.t, &r.t_bound, &r.h_abs, &r.max_step,
                             &r.rtol, &r.atol, &r.exponent, &r.deadline)
        || !PyTuple_Check(tab = args[3]) || PyTuple_GET_SIZE(tab) != 5
        || !vec_of(args[4], NP + NM, &pa) || !vec_of(args[5], NM, &db)
        || !PyArg_ParseTuple(opt = args[6], "ilii", &r.mode, &r.max_steps, &s.a_offset,
                             &s.max_iter)
        || !PyArg_ParseTuple(tol = args[7], "dd", &s.ptol, &s.pfail)) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_TypeError, "step(y, f, times, tableau, pa, db, options, "
                                             "tolerances): see ckernel_stepper.h");
        return NULL;
    }
    double *tv[5];
    Py_ssize_t tl[5];
    for (int i = 0; i < 5; ++i)
        if (!vec(PyTuple_GET_ITEM(tab, i), 0, tv + i, tl + i)) {
            PyErr_SetString(PyExc_TypeError, "step: the tableau is five float64 vectors");
            return NULL;
        }
    r.ns = (int)tl[1];
    if (tl[0] != (Py_ssize_t)r.ns * r.ns || tl[2] != r.ns || tl[3] != r.ns + 1
        || tl[4] != r.ns + 1) {
        PyErr_SetString(PyExc_ValueError, "step: A (s x s), B (s), C (s), E3, E5 (s + 1)");
        return NULL;
    }
    r.A = tv[0], r.B = tv[1], r.C = tv[2], r.E3 = tv[3], r.E5 = tv[4];
    PyObject *fn = PyUnicode_FromString("forward"), *rn = PyUnicode_FromString("residuals");
    PyObject *jn = PyUnicode_FromString("position_jacobian"),
             *mn = PyUnicode_FromString("matrices");
    s.fwd = kernel_named(fn);
    s.res = s.fwd ? kernel_named(rn) : NULL;
    s.pjac = s.res ? kernel_named(jn) : NULL;
    s.mat = s.pjac ? kernel_named(mn) : NULL;
    Py_XDECREF(fn), Py_XDECREF(rn), Py_XDECREF(jn), Py_XDECREF(mn);
    if (s.mat == NULL) return NULL;
    s.pa = pa, s.db = db, s.pmin = INFINITY;
    r.deadline += now_s();
    const size_t need = (size_t)((r.ns + 1) * NY + NY + NY + s.fwd->nout + s.res->nout
                                 + s.pjac->nout + s.mat->nout + (NM + NQ) * (NM + NQ));
    double *work = malloc(need * sizeof(double));
    if (work == NULL) return PyErr_NoMemory();
    double *K = work, *ys = K + (r.ns + 1) * NY, *y = ys + NY, *f = y + NY;
    s.fo = f + NY, s.ro = s.fo + s.fwd->nout, s.jo = s.ro + s.res->nout;
    s.mo = s.jo + s.pjac->nout, s.jj = s.mo + s.mat->nout;
    memcpy(y, y0, sizeof(double) * NY);
    memcpy(f, f0, sizeof(double) * NY);
    record_t rec = {0};
    long nsteps = 0, projections = 0;
    double stop_t = r.t;
    int status;
    Py_BEGIN_ALLOW_THREADS
    status = run_steps(&s, &r, y, f, K, ys, &rec, &nsteps, &projections, &stop_t);
    Py_END_ALLOW_THREADS
    PyObject *result = NULL;
    if (status < 0) {
        PyErr_NoMemory();
    } else {
        npy_intp dims[2] = {rec.n, NY};
        PyObject *T = PyArray_SimpleNew(1, dims, NPY_DOUBLE);
        PyObject *Y = PyArray_SimpleNew(2, dims, NPY_DOUBLE);
        PyObject *at = vector_of(ys, NY);
        if (T && Y && at) {
            if (rec.n) {
                memcpy(PyArray_DATA((PyArrayObject *)T), rec.T, rec.n * sizeof(double));
                memcpy(PyArray_DATA((PyArrayObject *)Y), rec.Y, rec.n * NY * sizeof(double));
            }
            result = Py_BuildValue("iNNlldlldN", status, T, Y, s.nfev, nsteps, s.pmin,
                                   projections, s.iters, stop_t, at);
        } else {
            Py_XDECREF(T), Py_XDECREF(Y), Py_XDECREF(at);
        }
    }
    free(rec.T), free(rec.Y), free(work);
    return result;
}
