/* hconv.solve._rows: the compiled engine's row code, one fused pass per row.
 *
 * What it computes and what it leaves is hconv.solve.compiled's docstring; this file is its
 * arithmetic. Every operation is the numpy engine's (hconv.kernels.linsolve, .spectrum, .metrics,
 * hconv.solve.blocks), written in the same order with the same parentheses, so that `exact`'s
 * omega, cond and every status are the same bits. It must be compiled so that it rounds as
 * written: no contraction into fused multiply-adds (-ffp-contract=off) and no fast-math
 * (setup.py). A row this code cannot settle is marked fallback and converted by the numpy engine.
 *
 * min and max here are Python's (the first argument unless the second compares greater or
 * smaller), which hconv's row code was specified in; where a NaN makes them differ from numpy's,
 * the row is not finite and falls back either way.
 *
 * Shapes, as hconv.solve.convert's internal layout: I is (k, N) in its form's value order (six
 * numbers xx yy zz xy xz yz, or nine row-major), H (3, N) [kg m^2/s], any strides; outputs
 * contiguous: w (N, 3) [rad/s], cond, code (uint8), residual, fallback (bool) (N,).
 */
#define PY_SSIZE_T_CLEAN
#ifndef NPY_NO_DEPRECATED_API
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#endif
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <numpy/arrayobject.h>

/* The constants, from hconv's Python modules (hconv.solve.compiled passes them to configure()),
 * so that each is stated once, where the numpy engine states it. */
static struct {
    double split, singular_limit, grid, safe, stop, tiny, s0, s1, s2, s3, s4, root_range;
    double symmetry_rtol, triangle_rtol, ill_tol, eps, sqrt_eps, max;
    int newton_steps, max_refine_steps;
    uint8_t ok, singular, not_physical, ill_conditioned, inaccurate;
    int ready;
} K;

static inline double pmax(double a, double b) { return b > a ? b : a; }
static inline double pmin(double a, double b) { return b < a ? b : a; }

typedef struct {
    double d1, d2, d3, l21, l31, l32;
} Factors;

/* linsolve.ldlt_factor */
static inline Factors ldlt(double xx, double yy, double zz, double xy, double xz, double yz)
{
    Factors f;
    f.d1 = xx;
    f.l21 = xy / f.d1;
    f.l31 = xz / f.d1;
    f.d2 = yy - f.l21 * xy;
    double t = yz - f.l31 * xy;
    f.l32 = t / f.d2;
    f.d3 = zz - f.l31 * xz;
    f.d3 -= t * f.l32;
    return f;
}

/* linsolve.ldlt_solve, one right-hand side */
static inline void ldlt_solve(const Factors *f, double h0, double h1, double h2, double x[3])
{
    double y1 = h0;
    double y2 = h1 - f->l21 * y1;
    double y3 = h2 - f->l31 * y1;
    y3 -= f->l32 * y2;
    double x2 = y3 / f->d3;
    double x1 = y2 / f->d2;
    x1 -= f->l32 * x2;
    double x0 = y1 / f->d1;
    x0 -= f->l21 * x1;
    x0 -= f->l31 * x2;
    x[0] = x0;
    x[1] = x1;
    x[2] = x2;
}

/* spectrum._largest_root within ROOT_RANGE: the largest eigenvalue and its error bound.
 * cos(acos(r)/3) = 1/2 + u*t with u = sqrt(1 + r) and t the root of t^2 + (2u/3) t^3 = 1/6,
 * from the fit ROOT_START and Newton steps (spectrum.py says why there is no trigonometry). */
static inline double largest_root(double xx, double yy, double zz, double xy, double xz, double yz, double *err)
{
    double q = (xx + yy + zz) * (1.0 / 3.0);
    double aq = xx - q, bq = yy - q, cq = zz - q;
    double p = sqrt((aq * aq + bq * bq + cq * cq + 2.0 * (xy * xy + xz * xz + yz * yz)) * (1.0 / 6.0));
    double ip = 1.0 / (p > 0 ? p : 1.0);
    double det = aq * (bq * cq - yz * yz) - xy * (xy * cq - yz * xz) + xz * (xy * yz - bq * xz);
    double r = pmin(pmax(det * (0.5 * ip * ip * ip), -1.0), 1.0);
    double u = sqrt(1.0 + r);
    double t = K.s0 + u * (K.s1 + u * (K.s2 + u * (K.s3 + u * K.s4)));
    double k = (2.0 / 3.0) * u;
    for (int i = 0; i < K.newton_steps; i++) {
        double t2 = t * t;
        t -= (t2 + k * t2 * t - (1.0 / 6.0)) / (2.0 * t + 3.0 * k * t2);
    }
    double hi = q + p * (1.0 + 2.0 * (u * t));
    *err = p * pmin(K.sqrt_eps, 16.0 * K.eps / sqrt(pmax(1.0 - r * r, K.eps))) + 8.0 * K.eps * fabs(q);
    return hi;
}

/* |v| is 0 or within the double-double residual's safe range (linsolve.in_safe_range) */
static inline int safe(double v)
{
    double m = fabs(v);
    return (m == 0.0) | ((m < K.safe) & (m > 1.0 / K.safe));
}

static inline void split(double a, double *hi, double *lo)
{
    double c = K.split * a;
    *hi = c - (c - a);
    *lo = a - *hi;
}

/* s - (a . x) in double the precision: one row of linsolve.residual_dd, operation for operation */
static inline double dot_row(double s, const double a[3], const double x[3], const double xh[3], const double xl[3])
{
    double err = 0.0;
    for (int j = 0; j < 3; j++) {
        double ah, al;
        split(a[j], &ah, &al);
        double p = a[j] * x[j];
        double e = ah * xh[j] - p;
        e += ah * xl[j];
        e += al * xh[j];
        e += al * xl[j];
        double s_new = s - p;
        double bb = s_new - s;
        double q = s - (s_new - bb);
        bb += p;
        q -= bb;
        if (j == 0) {
            err = q - e;
        } else {
            q -= e;
            err += q;
        }
        s = s_new;
    }
    return err + s;
}

typedef struct {
    double xx, yy, zz, xy, xz, yz, h0, h1, h2;
} Row;

/* One step of linsolve._refine: x corrected by the solve of its double-double residual;
 * returns the correction's size relative to x, squared. */
static inline double refine_step(const Row *a, const Factors *f, double x[3])
{
    double xh[3], xl[3], r[3], dx[3];
    for (int j = 0; j < 3; j++)
        split(x[j], &xh[j], &xl[j]);
    const double r0[3] = {a->xx, a->xy, a->xz}, r1[3] = {a->xy, a->yy, a->yz}, r2[3] = {a->xz, a->yz, a->zz};
    r[0] = dot_row(a->h0, r0, x, xh, xl);
    r[1] = dot_row(a->h1, r1, x, xh, xl);
    r[2] = dot_row(a->h2, r2, x, xh, xl);
    ldlt_solve(f, r[0], r[1], r[2], dx);
    x[0] += dx[0];
    x[1] += dx[1];
    x[2] += dx[2];
    double c = dx[0] * dx[0] + dx[1] * dx[1] + dx[2] * dx[2];
    c /= x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
    return c;
}

/* The rest of linsolve._refine after its first step (which gave x and c), with its stopping rule
 * applied to this row alone: stop when the next correction is predicted below STOP, or when a
 * correction fails to shrink fourfold (that step is kept). */
static inline void refine_on(const Row *a, const Factors *f, double x[3], double c)
{
    if (!(c < 0.25))
        return;
    double pred = c * c;
    for (int i = 1; i < K.max_refine_steps; i++) {
        if (!(pred > K.stop && c > K.tiny))
            break;
        double prev = c;
        c = refine_step(a, f, x);
        double ratio = c / prev;
        if (!(ratio < 0.25))
            break;
        pred = c * ratio;
    }
}

/* metrics.relative_error for one row */
static inline double relative_error(const double x[3], const double rr[3])
{
    double d0 = x[0] - rr[0], d1 = x[1] - rr[1], d2 = x[2] - rr[2];
    double r0 = rr[0], r1 = rr[1], r2 = rr[2];
    double unit = pmax(pmax(fabs(r0), fabs(r1)), fabs(r2));
    unit = ((unit > 0) & (unit <= K.max)) ? unit : 1.0;
    d0 /= unit, d1 /= unit, d2 /= unit, r0 /= unit, r1 /= unit, r2 /= unit;
    double num = sqrt(d0 * d0 + d1 * d1 + d2 * d2);
    double den = sqrt(r0 * r0 + r1 * r1 + r2 * r2);
    double ratio = num / (den > 0 ? den : 1.0);
    return den > 0 ? ratio : (num == 0 ? 0.0 : num * INFINITY);
}

/* omega finite and not on the grid of subnormal numbers (the numpy engine's `inaccurate`) */
static inline int final_w(const double w[3])
{
    double wmax = pmax(pmax(fabs(w[0]), fabs(w[1])), fabs(w[2]));
    return ((w[0] + w[1] + w[2]) * 0.0 == 0.0) & ((wmax == 0) | (wmax >= K.grid));
}

typedef struct {
    double w[3], cond, residual;
    uint8_t code;
    int fallback;
} Out;

/* One symmetric row: blocks._convert_block's answers for it, or fallback. */
static void convert_row(const Row *a, int refined, int diagnostics, double cond_limit, Out *o)
{
    o->fallback = 1;
    o->w[0] = o->w[1] = o->w[2] = o->cond = o->residual = NAN;
    o->code = K.ok;
    double xx = a->xx, yy = a->yy, zz = a->zz, xy = a->xy, xz = a->xz, yz = a->yz;
    /* the numbers: LDL^T, the closed-form largest and smallest principal moments, LDL^T's answer */
    Factors f = ldlt(xx, yy, zz, xy, xz, yz);
    double hi_err;
    double hi = largest_root(xx, yy, zz, xy, xz, yz, &hi_err);
    double tr = xx + yy + zz;
    double inv = 1.0 / hi;
    double s = (tr - hi) * inv;
    double p = (f.d1 * inv) * (f.d2 * inv) * (f.d3 * inv);
    double root = sqrt(pmax(s * s - 4.0 * p, 0.0));
    double lo = (2.0 * p / (s + root)) * hi;
    double w[3];
    ldlt_solve(&f, a->h0, a->h1, a->h2, w);

    /* the verdict: each test is the numpy engine's; a row any of them cannot settle falls back */
    /* x*0 is 0 for a finite x and NaN for NaN or an infinity (max and comparisons skip a NaN) */
    int finite = (xx + yy + zz + xy + xz + yz + a->h0 + a->h1 + a->h2) * 0.0 == 0.0;
    double big = pmax(pmax(pmax(fabs(xx), fabs(yy)), pmax(fabs(zz), fabs(xy))), pmax(fabs(xz), fabs(yz)));
    int usable = finite & (big >= 1.0 / K.root_range) & (big <= K.root_range);
    usable &= (pmin(pmin(f.d1, f.d2), f.d3) > 0) & (fabs(f.l32) <= K.max); /* positive definite */
    /* where the closed form cannot decide, the numpy engine asks LAPACK */
    usable &= (fabs(lo) <= K.max) & (lo > 0) & (fabs(2.0 * hi - tr) > 1e-9 * tr + 4.0 * hi_err);
    if (!usable)
        return;
    double mid = tr - hi - lo;
    double a0 = fabs(lo), a1 = fabs(mid), a2 = fabs(hi);
    double top = pmax(a0, a2);
    double small = pmin(pmin(a0, a1), a2);
    double cond = small > 0 ? top / small : INFINITY;
    /* statuses in status.PRECEDENCE's order: a later write wins */
    uint8_t code = cond > cond_limit ? K.ill_conditioned : K.ok;
    if (hi - mid - lo > K.triangle_rtol * (a0 + a1 + a2))
        code = K.not_physical;
    if (small <= K.singular_limit * top) {
        o->cond = cond; /* no answer, so no residual either */
        o->code = K.singular;
        o->fallback = 0;
        return;
    }
    if (!final_w(w))
        return;
    double res = NAN;
    if (refined || diagnostics) {
        if (!(safe(xx) & safe(yy) & safe(zz) & safe(xy) & safe(xz) & safe(yz) & safe(a->h0) & safe(a->h1) &
              safe(a->h2)))
            return;
        double x[3] = {w[0], w[1], w[2]};
        refine_on(a, &f, x, refine_step(a, &f, x)); /* from LDL^T's answer */
        if (refined) {
            w[0] = x[0], w[1] = x[1], w[2] = x[2];
            if (!final_w(w))
                return;
            if (diagnostics) /* the reference starts again from the refined answer */
                refine_on(a, &f, x, refine_step(a, &f, x));
        }
        if (diagnostics) {
            if (!(safe(x[0]) & safe(x[1]) & safe(x[2])))
                return;
            res = relative_error(w, x);
            /* inaccurate takes a row only from ok: it comes after the statuses above */
            if (res > K.ill_tol && code == K.ok)
                code = K.inaccurate;
        }
    }
    o->w[0] = w[0], o->w[1] = w[1], o->w[2] = w[2];
    o->cond = cond;
    o->code = code;
    o->residual = res;
    o->fallback = 0;
}

/* Nine row-major numbers: the six of their symmetric part; returns whether they are not symmetric
 * (forms._sym3_of_nine's test; NaN rows fall back too). */
static inline int sym_of_nine(const double v[9], Row *a)
{
    double skew = pmax(pmax(fabs(v[1] - v[3]), fabs(v[2] - v[6])), fabs(v[5] - v[7]));
    double scale = pmax(pmax(pmax(fabs(v[0]), fabs(v[1])), pmax(fabs(v[2]), fabs(v[3]))),
                        pmax(pmax(fabs(v[4]), fabs(v[5])), pmax(fabs(v[6]), fabs(v[7]))));
    scale = pmax(scale, fabs(v[8]));
    a->xx = v[0], a->yy = v[4], a->zz = v[8];
    a->xy = 0.5 * (v[1] + v[3]), a->xz = 0.5 * (v[2] + v[6]), a->yz = 0.5 * (v[5] + v[7]);
    return skew > K.symmetry_rtol * scale || skew != skew;
}

static int get(PyObject *c, const char *name, double *out)
{
    PyObject *v = PyDict_GetItemString(c, name);
    if (!v) {
        PyErr_Format(PyExc_KeyError, "_rows.configure: %s missing", name);
        return -1;
    }
    *out = PyFloat_AsDouble(v);
    return PyErr_Occurred() ? -1 : 0;
}

static int configure_from(PyObject *c)
{
    double steps, refine_steps, codes[5];
    if (get(c, "SPLIT", &K.split) || get(c, "SINGULAR_LIMIT", &K.singular_limit) || get(c, "GRID", &K.grid) ||
        get(c, "SAFE", &K.safe) || get(c, "STOP", &K.stop) || get(c, "TINY", &K.tiny) || get(c, "S0", &K.s0) ||
        get(c, "S1", &K.s1) || get(c, "S2", &K.s2) || get(c, "S3", &K.s3) || get(c, "S4", &K.s4) ||
        get(c, "ROOT_RANGE", &K.root_range) || get(c, "SYMMETRY_RTOL", &K.symmetry_rtol) ||
        get(c, "TRIANGLE_RTOL", &K.triangle_rtol) || get(c, "ILL_CONDITIONED_TOL", &K.ill_tol) ||
        get(c, "EPS", &K.eps) || get(c, "SQRT_EPS", &K.sqrt_eps) || get(c, "MAX", &K.max) ||
        get(c, "ROOT_NEWTON_STEPS", &steps) || get(c, "MAX_REFINE_STEPS", &refine_steps) ||
        get(c, "OK", &codes[0]) || get(c, "SINGULAR", &codes[1]) || get(c, "NOT_PHYSICAL", &codes[2]) ||
        get(c, "ILL_CONDITIONED", &codes[3]) || get(c, "INACCURATE", &codes[4]))
        return -1;
    K.newton_steps = (int)steps;
    K.max_refine_steps = (int)refine_steps;
    K.ok = (uint8_t)codes[0], K.singular = (uint8_t)codes[1], K.not_physical = (uint8_t)codes[2];
    K.ill_conditioned = (uint8_t)codes[3], K.inaccurate = (uint8_t)codes[4];
    K.ready = 1;
    return 0;
}

static PyObject *configure(PyObject *self, PyObject *args)
{
    PyObject *c;
    if (!PyArg_ParseTuple(args, "O!", &PyDict_Type, &c))
        return NULL;
    if (configure_from(c) < 0)
        return NULL;
    Py_RETURN_NONE;
}

static int check(PyArrayObject *a, const char *name, int ndim, npy_intp d0, npy_intp d1, int type, int writable)
{
    if (PyArray_NDIM(a) != ndim || PyArray_TYPE(a) != type || PyArray_DIM(a, 0) != d0 ||
        (ndim == 2 && PyArray_DIM(a, 1) != d1)) {
        PyErr_Format(PyExc_ValueError, "_rows.convert: %s has the wrong shape or dtype", name);
        return -1;
    }
    if (writable && !(PyArray_IS_C_CONTIGUOUS(a) && PyArray_ISWRITEABLE(a))) {
        PyErr_Format(PyExc_ValueError, "_rows.convert: %s must be contiguous and writable", name);
        return -1;
    }
    return 0;
}

/* convert(I, nine, H, refined, diagnostics, cond_limit, w, cond, code, residual, fallback, start, stop):
 * rows start..stop of I and H into the same rows of the outputs (residual written with
 * diagnostics only), without the GIL. */
static PyObject *convert(PyObject *self, PyObject *args)
{
    PyArrayObject *In, *H, *w, *cond, *code, *residual, *fallback;
    int nine, refined, diagnostics;
    double cond_limit;
    Py_ssize_t start, stop;
    if (!PyArg_ParseTuple(args, "O!pO!ppdO!O!O!O!O!nn", &PyArray_Type, &In, &nine, &PyArray_Type, &H, &refined,
                          &diagnostics, &cond_limit, &PyArray_Type, &w, &PyArray_Type, &cond, &PyArray_Type, &code,
                          &PyArray_Type, &residual, &PyArray_Type, &fallback, &start, &stop))
        return NULL;
    if (!K.ready) {
        PyErr_SetString(PyExc_RuntimeError, "_rows.convert: configure() first");
        return NULL;
    }
    if (PyArray_NDIM(H) != 2) {
        PyErr_SetString(PyExc_ValueError, "_rows.convert: H must be (3, N)");
        return NULL;
    }
    npy_intp n = PyArray_DIM(H, 1);
    if (check(H, "H", 2, 3, n, NPY_FLOAT64, 0) || check(In, "I", 2, nine ? 9 : 6, n, NPY_FLOAT64, 0) ||
        check(w, "w", 2, n, 3, NPY_FLOAT64, 1) || check(cond, "cond", 1, n, 0, NPY_FLOAT64, 1) ||
        check(code, "code", 1, n, 0, NPY_UINT8, 1) || check(fallback, "fallback", 1, n, 0, NPY_BOOL, 1) ||
        check(residual, "residual", 1, diagnostics ? n : PyArray_DIM(residual, 0), 0, NPY_FLOAT64, 1))
        return NULL;
    if (start < 0 || stop > n || start > stop) {
        PyErr_SetString(PyExc_ValueError, "_rows.convert: rows start..stop out of range");
        return NULL;
    }
    const char *Ib = PyArray_BYTES(In), *Hb = PyArray_BYTES(H);
    npy_intp Is0 = PyArray_STRIDE(In, 0), Is1 = PyArray_STRIDE(In, 1);
    npy_intp Hs0 = PyArray_STRIDE(H, 0), Hs1 = PyArray_STRIDE(H, 1);
    double *wp = (double *)PyArray_DATA(w), *cp = (double *)PyArray_DATA(cond);
    double *rp = (double *)PyArray_DATA(residual);
    uint8_t *kp = (uint8_t *)PyArray_DATA(code);
    npy_bool *fp = (npy_bool *)PyArray_DATA(fallback);
    Py_BEGIN_ALLOW_THREADS;
    for (npy_intp i = start; i < stop; i++) {
        Row a;
        Out o;
        int asym = 0;
#define AT(base, s0, s1, j) (*(const double *)((base) + (j) * (s0) + i * (s1)))
        if (nine) {
            double v[9];
            for (int j = 0; j < 9; j++)
                v[j] = AT(Ib, Is0, Is1, j);
            asym = sym_of_nine(v, &a);
        } else {
            a.xx = AT(Ib, Is0, Is1, 0), a.yy = AT(Ib, Is0, Is1, 1), a.zz = AT(Ib, Is0, Is1, 2);
            a.xy = AT(Ib, Is0, Is1, 3), a.xz = AT(Ib, Is0, Is1, 4), a.yz = AT(Ib, Is0, Is1, 5);
        }
        a.h0 = AT(Hb, Hs0, Hs1, 0), a.h1 = AT(Hb, Hs0, Hs1, 1), a.h2 = AT(Hb, Hs0, Hs1, 2);
#undef AT
        if (asym) {
            o.fallback = 1;
            o.w[0] = o.w[1] = o.w[2] = o.cond = o.residual = NAN;
            o.code = K.ok;
        } else {
            convert_row(&a, refined, diagnostics, cond_limit, &o);
        }
        wp[3 * i] = o.w[0], wp[3 * i + 1] = o.w[1], wp[3 * i + 2] = o.w[2];
        cp[i] = o.cond;
        kp[i] = o.code;
        fp[i] = (npy_bool)o.fallback;
        if (diagnostics)
            rp[i] = o.residual;
    }
    Py_END_ALLOW_THREADS;
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"configure", configure, METH_VARARGS, "configure(constants): the constants of hconv's Python modules."},
    {"convert", convert, METH_VARARGS,
     "convert(I, nine, H, refined, diagnostics, cond_limit, w, cond, code, residual, fallback, start, stop)"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_rows", "hconv's compiled row code.", -1, methods};

PyMODINIT_FUNC PyInit__rows(void)
{
    import_array();
    return PyModule_Create(&module);
}
