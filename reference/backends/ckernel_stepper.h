/* The compiled stepper of reference.integrate: scipy's DOP853 step (the loop of
   reference/integrate_rk.py's LeanDOP853, the same formulas in the same order) and its dense
   output, driving the module's own forward kernel, and the coordinate projection of
   integrate_projection.py after every accepted step and at every output time. Included by
   ckernel_runtime.h; reference/integrate_compiled.py drives it and owns every decision about
   when it may run.

   step(y, f, (t, t_bound, h_abs, max_step, error_exponent, deadline_s), (rtol, atol),
        (A, B, C, E3, E5, A_EXTRA, C_EXTRA, D), t_eval, pa, db,
        (mode, max_steps, a_offset, max_iter, work, rheonomic, p_offset, rates),
        (projection_tol, projection_fail, alpha, beta))
     y, f       the state (q, u[, W]) after the solver's start and its derivative (scipy
                computed both, and the first step size h_abs, in Python: LeanDOP853's start);
                W, with `work`, the work of the loads (energy output p_offset) and, where the
                model is `rheonomic`, of its moving constraints
     rtol, atol one per component of y
     A..D       the solver's own tableau arrays, flattened (scipy's, read from the solver)
     t_eval     sorted output times (None: none, every accepted step is the output)
     rates      1: q' = u; 0: q' = N(q, u, t) from the kinematics kernel
     mode       0: index1, y' = (q', u'); 1: projection (refreshing f after it); 2: projection
                reusing the unprojected f; 3: baumgarte, index1 with the rows' right side offset
                by -2 alpha (A u + a0) - beta^2 f(q, t)
     a_offset   where the velocity rows' A sits in the `matrices` output (-1: A is the position
                Jacobian, the models whose rows are all configuration rows)
   returns (status, T, Y, TE, YE, nfev, nsteps, min_pivot, projections, projection_iterations,
   t, y): T, Y every accepted (projected) step, TE, YE the states at t_eval; status
     0  t_bound reached
     1  the step size fell below 10 ulp of t (scipy's TOO_SMALL_STEP)
     2  max_steps accepted before t_bound       3  the wall-time deadline passed
     4  the stepper stopped at (t, y): a right side it does not take (a singular or undefined
        forward, a rank-deficient projection, a projection that did not converge); the
        caller re-runs on the Python stepper, which words the error */

#include <time.h>

enum { STEP_DONE, STEP_TOO_SMALL, STEP_MAX_STEPS, STEP_DEADLINE, STEP_DECLINED };

typedef struct {
    const kernel_t *fwd, *res, *pjac, *mat, *en, *kin;
    const double *pa, *db;
    double *fo, *ro, *jo, *mo, *jj, *eo, *ao, *ko; /* kernel outputs, J J^T */
    int rates; /* q' = u; else q' = N(q, u, t), the kinematics kernel */
    double two_alpha, beta2; /* Baumgarte's gains (integrate_index1._Baumgarte); alpha < 0: none */
    double *bo;              /* the b offsets of a Baumgarte right side */
    double pmin;
    long nfev, iters;
    int ny, work, rheonomic, p_offset; /* y = (q, u[, W]); W' = the power at eo[p_offset] */
    int a_offset, max_iter;
    double ptol, pfail;
} stepper_t;

static const double zeros[NU > 0 ? NU : 1];

/* y' = (q', u'(q, u, t)[, P]) into out, P the power of the loads and of rheonomic constraints
   (integrate_common._Problem.power); 0 where the forward is not defined or singular there. */
static int rhs(stepper_t *s, double t, const double *y, double *out)
{
    ++s->nfev;
    const double *db = s->db;
    if (s->two_alpha >= 0.0) { /* A u' = b - 2 alpha (A u + a0) - beta^2 f(q, t), f: mc rows */
        if (s->res->body(y, y + NQ, t, s->pa, s->db, s->ao) != ST_OK) return 0;
        const int mc = (int)s->res->nout - NM;
        for (int j = 0; j < NM; ++j)
            s->bo[j] = -s->two_alpha * s->ao[mc + j] - (j < mc ? s->beta2 * s->ao[j] : 0.0);
        db = s->bo;
    }
    const int st = s->fwd->body(y, y + NQ, t, s->pa, db, s->fo);
    const double piv = s->fo[NU + NM];
    if (st != ST_OK || !(piv > PIVOT_MIN)) return 0;
    if (piv < s->pmin) s->pmin = piv;
    if (s->rates) {
        for (int i = 0; i < NQ; ++i) out[i] = y[NQ + i];
    } else {
        if (s->kin->body(y, y + NQ, t, s->pa, s->db, s->ko) != ST_OK) return 0;
        for (int i = 0; i < NQ; ++i) out[i] = s->ko[i];
    }
    for (int i = 0; i < NU; ++i) out[NQ + i] = s->fo[i];
    if (s->work) {
        if (s->en->body(y, y + NQ, t, s->pa, s->db, s->eo) != ST_OK) return 0;
        double P = s->eo[s->p_offset];
        if (s->rheonomic && NM) { /* - lambda . a0, a0 = A u + a0 at u = 0 */
            if (s->res->body(y, zeros, t, s->pa, s->db, s->ao) != ST_OK) return 0;
            const double *a0 = s->ao + (s->res->nout - NM);
            double acc = 0.0;
            for (int i = 0; i < NM; ++i) acc += s->fo[NU + i] * a0[i];
            P -= acc;
        }
        out[NQ + NU] = P;
    }
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
    double t, t_bound, h_abs, max_step, exponent, deadline;
    const double *rtol, *atol; /* one per component of y */
    const double *A, *B, *C, *E3, *E5, *AX, *CX, *D, *te;
    int ns, nx, nd, mode; /* stages, extra stages of the dense output, its rows of D */
    Py_ssize_t nte;       /* output times (0: every accepted step is an output) */
    long max_steps;
} run_t;

/* One attempt of LeanDOP853._stage_sweep and _error_norm: K filled, y_new, f_new = K[ns];
   the error norm, or -1 where a stage's right side was declined (stop at *ty). */
static double sweep(stepper_t *s, const run_t *r, double t, const double *y, double h,
                    double *K, double *ys, double *y_new, double *stop_t)
{
    const int ns = r->ns, ny = s->ny;
    for (int st = 1; st < ns; ++st) {
        for (int i = 0; i < ny; ++i) {
            double a = 0.0;
            for (int j = 0; j < st; ++j) a += (h * r->A[st * ns + j]) * K[j * ny + i];
            ys[i] = y[i] + a;
        }
        if (!rhs(s, t + r->C[st] * h, ys, K + st * ny)) {
            *stop_t = t + r->C[st] * h;
            return -1.0;
        }
    }
    for (int i = 0; i < ny; ++i) {
        double a = 0.0;
        for (int j = 0; j < ns; ++j) a += r->B[j] * K[j * ny + i];
        y_new[i] = y[i] + h * a;
    }
    if (!rhs(s, t + h, y_new, K + ns * ny)) {
        memcpy(ys, y_new, sizeof(double) * ny);
        *stop_t = t + h;
        return -1.0;
    }
    double e5 = 0.0, e3 = 0.0;
    for (int i = 0; i < ny; ++i) {
        double a5 = 0.0, a3 = 0.0;
        for (int j = 0; j <= ns; ++j) {
            a5 += r->E5[j] * K[j * ny + i];
            a3 += r->E3[j] * K[j * ny + i];
        }
        const double ay = fabs(y[i]), an = fabs(y_new[i]);
        const double sc = r->atol[i] + (ay > an ? ay : an) * r->rtol[i];
        a5 /= sc;
        a3 /= sc;
        e5 += a5 * a5;
        e3 += a3 * a3;
    }
    if (e5 == 0.0 && e3 == 0.0) return 0.0;
    return fabs(h) * e5 / sqrt((e5 + 0.01 * e3) * ny);
}

typedef struct {
    double *T, *Y;
    Py_ssize_t n, cap;
    int ny;
} record_t;

static int record(record_t *rec, double t, const double *y)
{
    const int ny = rec->ny;
    if (rec->n == rec->cap) {
        const Py_ssize_t cap = rec->cap ? 2 * rec->cap : 256;
        double *T = realloc(rec->T, cap * sizeof(double));
        if (T == NULL) return 0;
        rec->T = T;
        double *Y = realloc(rec->Y, cap * ny * sizeof(double));
        if (Y == NULL) return 0;
        rec->Y = Y;
        rec->cap = cap;
    }
    rec->T[rec->n] = t;
    memcpy(rec->Y + rec->n * ny, y, sizeof(double) * ny);
    ++rec->n;
    return 1;
}

/* scipy's DOP853 dense output of the step (t_old, y_old) -> (t_old + h, y, f), evaluated at
   every output time in the step (the interpolant of Dop853DenseOutput, term by term), each
   projected in projection mode as integrate_projection's dense_state does; 0 where a stage
   or a projection is declined (*stop_t, ys: where). */
static int dense_outputs(stepper_t *s, const run_t *r, double t_old, const double *y_old,
                         double h, const double *y, const double *f, double *K, double *ys,
                         Py_ssize_t *k_eval, record_t *out, double *stop_t)
{
    const int ns = r->ns, rows = ns + 1 + r->nx, nf = 3 + r->nd, ny = s->ny;
    for (int x = 0; x < r->nx; ++x) {
        const int st = ns + 1 + x;
        const double *a = r->AX + x * rows;
        for (int i = 0; i < ny; ++i) {
            double d = 0.0;
            for (int j = 0; j < st; ++j) d += a[j] * K[j * ny + i];
            ys[i] = y_old[i] + d * h;
        }
        if (!rhs(s, t_old + r->CX[x] * h, ys, K + st * ny)) {
            *stop_t = t_old + r->CX[x] * h;
            return 0;
        }
    }
    double F[nf * ny];
    for (int i = 0; i < ny; ++i) {
        const double dy = y[i] - y_old[i], f_old = K[i];
        F[i] = dy;
        F[ny + i] = h * f_old - dy;
        F[2 * ny + i] = 2 * dy - h * (f[i] + f_old);
        for (int d = 0; d < r->nd; ++d) {
            double a = 0.0;
            for (int j = 0; j < rows; ++j) a += r->D[d * rows + j] * K[j * ny + i];
            F[(3 + d) * ny + i] = h * a;
        }
    }
    const double t_new = t_old + h;
    while (*k_eval < r->nte && r->te[*k_eval] <= t_new) {
        const double tk = r->te[*k_eval], x = (tk - t_old) / h;
        for (int i = 0; i < ny; ++i) {
            double v = 0.0;
            for (int k = nf - 1; k >= 0; --k) {
                v += F[k * ny + i];
                v *= (nf - 1 - k) % 2 == 0 ? x : 1 - x;
            }
            ys[i] = v + y_old[i];
        }
        if (r->mode && !project(s, tk, ys)) {
            *stop_t = tk;
            return 0;
        }
        if (!record(out, tk, ys)) return -1;
        ++*k_eval;
    }
    return 1;
}

/* The solver loop of reference.integrate._Run with LeanDOP853._step_impl inside (scipy's
   step-size control: SAFETY 0.9, factors 0.2..10, no growth right after a rejection). */
static int run_steps(stepper_t *s, run_t *r, double *y, double *f, double *K, double *ys,
                     record_t *rec, record_t *out, long *nsteps, long *projections,
                     double *stop_t)
{
    const double SAFETY = 0.9, MIN_FACTOR = 0.2, MAX_FACTOR = 10.0;
    const int ny = s->ny;
    double y_new[ny], y_old[ny];
    double t = r->t, h_abs = r->h_abs;
    Py_ssize_t k_eval = 0;
    while (t - r->t_bound < 0) {
        const double min_step = 10 * fabs(nextafter(t, INFINITY) - t);
        h_abs = h_abs > min_step ? h_abs : min_step;
        h_abs = h_abs < r->max_step ? h_abs : r->max_step;
        int rejected = 0;
        double t_new, h;
        for (;;) {
            if (h_abs < min_step) {
                *stop_t = t;
                memcpy(ys, y, sizeof(double) * ny);
                return STEP_TOO_SMALL;
            }
            t_new = t + h_abs;
            if (t_new - r->t_bound > 0) t_new = r->t_bound;
            h = t_new - t;
            h_abs = fabs(h);
            memcpy(K, f, sizeof(double) * ny);
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
        const double t_old = t;
        t = t_new;
        memcpy(y_old, y, sizeof(double) * ny);
        memcpy(y, y_new, sizeof(double) * ny);
        memcpy(f, K + r->ns * ny, sizeof(double) * ny);
        ++*nsteps;
        if (k_eval < r->nte && r->te[k_eval] <= t) { /* before projecting, as _Run._step */
            const int ok = dense_outputs(s, r, t_old, y_old, h, y, f, K, ys, &k_eval, out,
                                         stop_t);
            if (ok <= 0) return ok < 0 ? -1 : STEP_DECLINED;
        }
        if (r->mode) {
            if (!project(s, t, y)) {
                *stop_t = t;
                memcpy(ys, y, sizeof(double) * ny);
                return STEP_DECLINED;
            }
            ++*projections;
            if (r->mode == 1 && !rhs(s, t, y, f)) {
                *stop_t = t;
                memcpy(ys, y, sizeof(double) * ny);
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

/* A record's times and states as new arrays (T: n, Y: n x ny); 0 with an exception set. */
static int as_arrays(const record_t *rec, PyObject **T, PyObject **Y)
{
    const int ny = rec->ny;
    npy_intp dims[2] = {rec->n, ny};
    *T = PyArray_SimpleNew(1, dims, NPY_DOUBLE);
    *Y = *T ? PyArray_SimpleNew(2, dims, NPY_DOUBLE) : NULL;
    if (*Y == NULL) {
        Py_CLEAR(*T);
        return 0;
    }
    if (rec->n) {
        memcpy(PyArray_DATA((PyArrayObject *)*T), rec->T, rec->n * sizeof(double));
        memcpy(PyArray_DATA((PyArrayObject *)*Y), rec->Y, rec->n * ny * sizeof(double));
    }
    return 1;
}

static int vec_of(PyObject *o, Py_ssize_t n, double **d)
{
    Py_ssize_t len;
    return vec(o, 0, d, &len) && len >= n;
}

static PyObject *step(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    double *y0, *f0, *pa, *db, *rtol, *atol;
    Py_ssize_t ny = 0, nf = 0, nrt = 0, nat = 0, nte = 0;
    run_t r = {0};
    stepper_t s = {0};
    PyObject *tab;
    if (nargs != 10 || !vec(args[0], 0, &y0, &ny) || !vec(args[1], 0, &f0, &nf)
        || !PyArg_ParseTuple(args[2], "dddddd", &r.t, &r.t_bound, &r.h_abs, &r.max_step,
                             &r.exponent, &r.deadline)
        || !PyTuple_Check(args[3]) || PyTuple_GET_SIZE(args[3]) != 2
        || !vec(PyTuple_GET_ITEM(args[3], 0), 0, &rtol, &nrt)
        || !vec(PyTuple_GET_ITEM(args[3], 1), 0, &atol, &nat)
        || !PyTuple_Check(tab = args[4]) || PyTuple_GET_SIZE(tab) != 8
        || (args[5] != Py_None && !vec(args[5], 0, (double **)&r.te, &nte))
        || !vec_of(args[6], NP + NM, &pa) || !vec_of(args[7], NM, &db)
        || !PyArg_ParseTuple(args[8], "iliiiiii", &r.mode, &r.max_steps, &s.a_offset,
                             &s.max_iter, &s.work, &s.rheonomic, &s.p_offset, &s.rates)
        || !PyArg_ParseTuple(args[9], "dddd", &s.ptol, &s.pfail, &s.two_alpha, &s.beta2)) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_TypeError, "step(y, f, times, (rtol, atol), tableau, t_eval, "
                                             "pa, db, options, tolerances): see "
                                             "ckernel_stepper.h");
        return NULL;
    }
    s.work = s.work != 0;
    if (r.mode == 3) {
        r.mode = 0; /* no projection */
        s.two_alpha *= 2.0, s.beta2 *= s.beta2;
    } else {
        s.two_alpha = -1.0;
    }
    s.ny = (int)ny;
    if (ny != NQ + NU + s.work || nf != ny || nrt != ny || nat != ny) {
        PyErr_SetString(PyExc_ValueError, "step: y, f, rtol and atol are (q, u[, W]) long");
        return NULL;
    }
    r.rtol = rtol, r.atol = atol;
    double *tv[8];
    Py_ssize_t tl[8];
    for (int i = 0; i < 8; ++i)
        if (!vec(PyTuple_GET_ITEM(tab, i), 0, tv + i, tl + i)) {
            PyErr_SetString(PyExc_TypeError, "step: the tableau is eight float64 vectors");
            return NULL;
        }
    r.ns = (int)tl[1], r.nx = (int)tl[6];
    const Py_ssize_t rows = r.ns + 1 + r.nx;
    r.nd = rows ? (int)(tl[7] / rows) : 0;
    if (tl[0] != (Py_ssize_t)r.ns * r.ns || tl[2] != r.ns || tl[3] != r.ns + 1
        || tl[4] != r.ns + 1 || tl[5] != r.nx * rows || tl[7] != r.nd * rows) {
        PyErr_SetString(PyExc_ValueError, "step: A (s x s), B (s), C (s), E3, E5 (s + 1), "
                                          "A_EXTRA (x x (s + 1 + x)), C_EXTRA (x), D (d x "
                                          "(s + 1 + x))");
        return NULL;
    }
    r.A = tv[0], r.B = tv[1], r.C = tv[2], r.E3 = tv[3], r.E5 = tv[4];
    r.AX = tv[5], r.CX = tv[6], r.D = tv[7], r.nte = nte;
    PyObject *fn = PyUnicode_FromString("forward"), *rn = PyUnicode_FromString("residuals");
    PyObject *jn = PyUnicode_FromString("position_jacobian"),
             *mn = PyUnicode_FromString("matrices"), *en = PyUnicode_FromString("energy"),
             *kn = PyUnicode_FromString("kinematics");
    s.fwd = fn ? kernel_named(fn) : NULL;
    s.res = s.fwd && rn ? kernel_named(rn) : NULL;
    s.pjac = s.res && jn ? kernel_named(jn) : NULL;
    s.mat = s.pjac && mn ? kernel_named(mn) : NULL;
    s.en = s.mat && en ? kernel_named(en) : NULL;
    s.kin = s.en && kn ? kernel_named(kn) : NULL;
    Py_XDECREF(fn), Py_XDECREF(rn), Py_XDECREF(jn), Py_XDECREF(mn), Py_XDECREF(en);
    Py_XDECREF(kn);
    if (s.kin == NULL) return NULL;
    if (s.p_offset < 0 || s.p_offset >= s.en->nout || s.a_offset + NM * NU > s.mat->nout) {
        PyErr_SetString(PyExc_ValueError, "step: p_offset or a_offset outside its kernel's output");
        return NULL;
    }
    s.pa = pa, s.db = db, s.pmin = INFINITY;
    r.deadline += now_s();
    const size_t need = (size_t)(rows * ny + 3 * ny + s.fwd->nout + 2 * s.res->nout
                                 + s.pjac->nout + s.mat->nout + s.en->nout + s.kin->nout
                                 + NM + (NM + NQ) * (NM + NQ));
    double *work = malloc(need * sizeof(double));
    if (work == NULL) return PyErr_NoMemory();
    double *K = work, *ys = K + rows * ny, *y = ys + ny, *f = y + ny; /* K: rows x ny */
    s.fo = f + ny, s.ro = s.fo + s.fwd->nout, s.jo = s.ro + s.res->nout;
    s.mo = s.jo + s.pjac->nout, s.eo = s.mo + s.mat->nout, s.ao = s.eo + s.en->nout;
    s.ko = s.ao + s.res->nout, s.bo = s.ko + s.kin->nout, s.jj = s.bo + NM;
    memcpy(y, y0, sizeof(double) * ny);
    memcpy(f, f0, sizeof(double) * ny);
    record_t rec = {.ny = s.ny}, out = {.ny = s.ny};
    long nsteps = 0, projections = 0;
    double stop_t = r.t;
    int status;
    Py_BEGIN_ALLOW_THREADS
    status = run_steps(&s, &r, y, f, K, ys, &rec, &out, &nsteps, &projections, &stop_t);
    Py_END_ALLOW_THREADS
    PyObject *result = NULL;
    if (status < 0) {
        PyErr_NoMemory();
    } else {
        PyObject *T = NULL, *Y = NULL, *TE = NULL, *YE = NULL, *at = NULL;
        if (as_arrays(&rec, &T, &Y) && as_arrays(&out, &TE, &YE)
            && (at = vector_of(ys, ny)) != NULL)
            result = Py_BuildValue("iNNNNlldlldN", status, T, Y, TE, YE, s.nfev, nsteps, s.pmin,
                                   projections, s.iters, stop_t, at);
        else
            Py_XDECREF(T), Py_XDECREF(Y), Py_XDECREF(TE), Py_XDECREF(YE);
    }
    free(rec.T), free(rec.Y), free(out.T), free(out.Y), free(work);
    return result;
}
