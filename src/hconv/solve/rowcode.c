/* hconv.solve.rowcode: the compiled engine's row code, one fused pass per row.
 *
 * What it computes and what it leaves is hconv.solve.compiled's docstring; this file is its
 * arithmetic. Every operation is the numpy engine's (hconv.kernels.linsolve, .spectrum, .metrics,
 * hconv.solve.blocks), written in the same order with the same parentheses, so that `exact`'s
 * omega, cond and every status are the same bits. It must be compiled so that it rounds as
 * written (setup.py): no contraction into fused multiply-adds (-ffp-contract=off) and no
 * fast-math; -fno-math-errno and -fno-trapping-math only let the compiler vectorise sqrt and
 * turn branches into selects, which changes no result. The one fused multiply-add is the
 * residual's explicit fma() (chunk_body), the exact error of a product as Dekker's splits give it.
 * A row this code cannot settle is marked fallback and converted by the numpy engine.
 *
 * pmin and pmax keep the first argument unless the second compares smaller or greater (as
 * Python's min and max, which the row code was first written with); where a NaN makes them
 * differ from numpy's, the row is not finite and falls back either way.
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
#include <string.h>
#include <numpy/arrayobject.h>

/* The constants, from hconv's Python modules (hconv.solve.compiled passes them to configure()),
 * so that each is stated once, where the numpy engine states it. Codes are held as doubles: the
 * loops over rows compute in doubles only, which lets the compiler run several rows at once. */
static struct {
    double split, singular_limit, grid, safe, inv_safe, stop, tiny, s0, s1, s2, s3, s4, root_range, inv_root_range;
    double symmetry_rtol, triangle_rtol, ill_tol, eps, sqrt_eps, max;
    int max_refine_steps;
    double ok, singular, not_physical, ill_conditioned, inaccurate;
    int ready;
} K;

/* spectrum.ROOT_NEWTON_STEPS, a constant here so that the loop unrolls; configure() refuses
 * another value. */
#define NEWTON_STEPS 2
/* Rows per chunk: the chunk's scratch (35 numbers a row, 18 kB) stays in the L1 cache. */
#define CH 64
/* What the verdict says of a row: the numpy engine must convert it, it has no answer (singular),
 * or it has one. */
#define FALLBACK 0.0
#define NO_ANSWER 1.0
#define ANSWER 2.0

/* The loops over a chunk: inlined into chunk_body and it into each of its versions (chunk_avx512,
 * chunk_avx2, chunk_plain), so that each has them compiled for its own vectors. */
#if defined(__GNUC__)
#define HOT __attribute__((always_inline)) inline
#define NOINLINE __attribute__((noinline))
#else
#define HOT inline
#define NOINLINE
#endif
#if defined(_MSC_VER)
#define restrict __restrict
#endif

static inline double pmax(double a, double b) { return b > a ? b : a; }
static inline double pmin(double a, double b) { return b < a ? b : a; }

/* |v| is 0 or within the double-double residual's safe range (linsolve.in_safe_range) */
static inline int safe(double v)
{
    double m = fabs(v);
    return (m == 0.0) | ((m < K.safe) & (m > K.inv_safe));
}

/* omega finite and not on the grid of subnormal numbers (the numpy engine's `inaccurate`) */
static inline int final_w(double w0, double w1, double w2)
{
    double wmax = pmax(pmax(fabs(w0), fabs(w1)), fabs(w2));
    return ((w0 + w1 + w2) * 0.0 == 0.0) & ((wmax == 0) | (wmax >= K.grid));
}

/* One chunk's scratch, a column per quantity: the inputs; LDL^T's factors and answer; the
 * verdict's cond, status code, state and safe; a refinement's x, last correction c and whether
 * it goes on (X for the answer's, R for the reference's); the residual and whether the row's
 * answers are final. Columns of one struct, so that the compiler can prove them apart. */
typedef struct {
    double xx[CH], yy[CH], zz[CH], xy[CH], xz[CH], yz[CH], h0[CH], h1[CH], h2[CH];
    double d1[CH], d2[CH], d3[CH], l21[CH], l31[CH], l32[CH], w0[CH], w1[CH], w2[CH];
    double cond[CH], code[CH], state[CH], safe[CH];
    double x0[CH], x1[CH], x2[CH], xc[CH], xon[CH];
    double r0[CH], r1[CH], r2[CH], rc[CH], ron[CH];
    double res[CH], fin[CH], asym[CH];
} Chunk;

/* The numbers and the verdict of the m rows, with no branch. The numbers: LDL^T
 * (linsolve.ldlt_factor) and its answer (linsolve.ldlt_solve), the closed-form largest and
 * smallest principal moments (spectrum). The verdict: cond, the status code, and the state; each
 * test is the numpy engine's (blocks._convert_block, spectrum.eigenvalues), and a row that any of
 * them cannot settle is FALLBACK. */
HOT static void numbers_chunk(Chunk *restrict s, int m, double cond_limit)
{
    for (int j = 0; j < m; j++) {
        double xx = s->xx[j], yy = s->yy[j], zz = s->zz[j], xy = s->xy[j], xz = s->xz[j], yz = s->yz[j];
        double h0 = s->h0[j], h1 = s->h1[j], h2 = s->h2[j];
        /* LDL^T */
        double d1 = xx;
        double l21 = xy / d1;
        double l31 = xz / d1;
        double d2 = yy - l21 * xy;
        double t = yz - l31 * xy;
        double l32 = t / d2;
        double d3 = zz - l31 * xz;
        d3 -= t * l32;
        /* the largest moment within ROOT_RANGE and its error bound (spectrum._largest_root):
         * cos(acos(r)/3) = 1/2 + u*t with u = sqrt(1 + r) and t the root of
         * t^2 + (2u/3) t^3 = 1/6, from the fit ROOT_START and Newton steps (no trigonometry) */
        double q = (xx + yy + zz) * (1.0 / 3.0);
        double aq = xx - q, bq = yy - q, cq = zz - q;
        double p = sqrt((aq * aq + bq * bq + cq * cq + 2.0 * (xy * xy + xz * xz + yz * yz)) * (1.0 / 6.0));
        double ip = 1.0 / (p > 0 ? p : 1.0);
        double det = aq * (bq * cq - yz * yz) - xy * (xy * cq - yz * xz) + xz * (xy * yz - bq * xz);
        double r = pmin(pmax(det * (0.5 * ip * ip * ip), -1.0), 1.0);
        double u = sqrt(1.0 + r);
        double tt = K.s0 + u * (K.s1 + u * (K.s2 + u * (K.s3 + u * K.s4)));
        double k = (2.0 / 3.0) * u;
        for (int i = 0; i < NEWTON_STEPS; i++) {
            double t2 = tt * tt;
            tt -= (t2 + k * t2 * tt - (1.0 / 6.0)) / (2.0 * tt + 3.0 * k * t2);
        }
        double hi = q + p * (1.0 + 2.0 * (u * tt));
        double hi_err = p * pmin(K.sqrt_eps, 16.0 * K.eps / sqrt(pmax(1.0 - r * r, K.eps))) + 8.0 * K.eps * fabs(q);
        /* the smallest, from the pivots (spectrum.smallest_root) */
        double tr = xx + yy + zz;
        double inv = 1.0 / hi;
        double sm = (tr - hi) * inv;
        double pr = (d1 * inv) * (d2 * inv) * (d3 * inv);
        double root = sqrt(pmax(sm * sm - 4.0 * pr, 0.0));
        double lo = (2.0 * pr / (sm + root)) * hi;
        /* LDL^T's answer */
        double y1 = h0;
        double y2 = h1 - l21 * y1;
        double y3 = h2 - l31 * y1;
        y3 -= l32 * y2;
        double w2 = y3 / d3;
        double w1 = y2 / d2;
        w1 -= l32 * w2;
        double w0 = y1 / d1;
        w0 -= l21 * w1;
        w0 -= l31 * w2;

        /* x*0 is 0 for a finite x and NaN for NaN or an infinity (max and comparisons skip a NaN) */
        int finite = (xx + yy + zz + xy + xz + yz + h0 + h1 + h2) * 0.0 == 0.0;
        double big = pmax(pmax(pmax(fabs(xx), fabs(yy)), pmax(fabs(zz), fabs(xy))), pmax(fabs(xz), fabs(yz)));
        int usable = finite & (big >= K.inv_root_range) & (big <= K.root_range);
        usable &= (pmin(pmin(d1, d2), d3) > 0) & (fabs(l32) <= K.max); /* positive definite: LDL^T is stable */
        /* where the closed form cannot decide, the numpy engine asks LAPACK */
        usable &= (fabs(lo) <= K.max) & (lo > 0) & (fabs(2.0 * hi - tr) > 1e-9 * tr + 4.0 * hi_err);
        double mid = tr - hi - lo;
        double a0 = fabs(lo), a1 = fabs(mid), a2 = fabs(hi);
        double top = pmax(a0, a2);
        double small = pmin(pmin(a0, a1), a2);
        double ratio = top / (small > 0 ? small : 1.0); /* no division on a branch: rows go together */
        double cond = small > 0 ? ratio : INFINITY;
        /* statuses in status.PRECEDENCE's order: a later write wins */
        double code = cond > cond_limit ? K.ill_conditioned : K.ok;
        code = hi - mid - lo > K.triangle_rtol * (a0 + a1 + a2) ? K.not_physical : code;
        int singular = small <= K.singular_limit * top;
        code = singular ? K.singular : code;
        /* overflow, or omega on the grid of subnormal numbers: the numpy engine's rules */
        int w_ok = final_w(w0, w1, w2);
        double state = usable ? (singular ? NO_ANSWER : (w_ok ? ANSWER : FALLBACK)) : FALLBACK;
        int sf = safe(xx) & safe(yy) & safe(zz) & safe(xy) & safe(xz) & safe(yz) & safe(h0) & safe(h1) & safe(h2);
        s->d1[j] = d1, s->d2[j] = d2, s->d3[j] = d3, s->l21[j] = l21, s->l31[j] = l31, s->l32[j] = l32;
        s->w0[j] = w0, s->w1[j] = w1, s->w2[j] = w2;
        s->cond[j] = cond, s->code[j] = code, s->state[j] = state, s->safe[j] = sf ? 1.0 : 0.0;
    }
}

/* s - (a . x) in double the precision, for x split into xh + xl: one row of
 * linsolve.residual_dd, operation for operation */
HOT static double dot_row(double s, double a0, double a1, double a2, double x0, double x1, double x2,
                             double xh0, double xh1, double xh2, double xl0, double xl1, double xl2, int fused)
{
    double c, ah, al, p, e, s_new, bb, q, err;
#define TERM(a, x, xh, xl)                                                                                   \
    p = (a) * (x);                                                                                           \
    if (fused) /* the product's error, exactly (no rounding but the one of p) */                             \
        e = fma((a), (x), -p);                                                                               \
    else {                                                                                                   \
        c = K.split * (a);                                                                                   \
        ah = c - (c - (a));                                                                                  \
        al = (a) - ah;                                                                                       \
        e = ah * (xh) - p;                                                                                   \
        e += ah * (xl);                                                                                      \
        e += al * (xh);                                                                                      \
        e += al * (xl);                                                                                      \
    }                                                                                                        \
    s_new = s - p;                                                                                           \
    bb = s_new - s;                                                                                          \
    q = s - (s_new - bb);                                                                                    \
    bb += p;                                                                                                 \
    q -= bb;                                                                                                 \
    s = s_new
    TERM(a0, x0, xh0, xl0);
    err = q - e;
    TERM(a1, x1, xh1, xl1);
    q -= e;
    err += q;
    TERM(a2, x2, xh2, xl2);
    q -= e;
    err += q;
#undef TERM
    return err + s;
}

/* One step of linsolve._refine for row j from x: x corrected by the LDL^T solve of its
 * double-double residual, and the correction's size relative to x, squared (*c). */
HOT static void refine_step(const Chunk *restrict s, int j, double *x0, double *x1, double *x2, double *c, int fused)
{
    double xx = s->xx[j], yy = s->yy[j], zz = s->zz[j], xy = s->xy[j], xz = s->xz[j], yz = s->yz[j];
    double v0 = *x0, v1 = *x1, v2 = *x2, t;
    t = K.split * v0;
    double xh0 = t - (t - v0), xl0 = v0 - xh0;
    t = K.split * v1;
    double xh1 = t - (t - v1), xl1 = v1 - xh1;
    t = K.split * v2;
    double xh2 = t - (t - v2), xl2 = v2 - xh2;
    double r0 = dot_row(s->h0[j], xx, xy, xz, v0, v1, v2, xh0, xh1, xh2, xl0, xl1, xl2, fused);
    double r1 = dot_row(s->h1[j], xy, yy, yz, v0, v1, v2, xh0, xh1, xh2, xl0, xl1, xl2, fused);
    double r2 = dot_row(s->h2[j], xz, yz, zz, v0, v1, v2, xh0, xh1, xh2, xl0, xl1, xl2, fused);
    double l21 = s->l21[j], l31 = s->l31[j], l32 = s->l32[j];
    double y1 = r0;
    double y2 = r1 - l21 * y1;
    double y3 = r2 - l31 * y1;
    y3 -= l32 * y2;
    double dx2 = y3 / s->d3[j];
    double dx1 = y2 / s->d2[j];
    dx1 -= l32 * dx2;
    double dx0 = y1 / s->d1[j];
    dx0 -= l21 * dx1;
    dx0 -= l31 * dx2;
    v0 += dx0;
    v1 += dx1;
    v2 += dx2;
    double cc = dx0 * dx0 + dx1 * dx1 + dx2 * dx2;
    cc /= v0 * v0 + v1 * v1 + v2 * v2;
    *x0 = v0, *x1 = v1, *x2 = v2, *c = cc;
}

#define REFINE_CHUNK(name, F0, F1, F2, X0, X1, X2, XC, ON)                                                 \
    HOT static void name(Chunk *restrict s, int m, int fused)                                                  \
    {                                                                                                        \
        for (int j = 0; j < m; j++) {                                                                        \
            double v0 = s->F0[j], v1 = s->F1[j], v2 = s->F2[j], c;                                           \
            refine_step(s, j, &v0, &v1, &v2, &c, fused);                                                         \
            int go = (s->state[j] == ANSWER) & (s->safe[j] == 1.0) & (c < 0.25) & (c * c > K.stop) &         \
                     (c > K.tiny);                                                                           \
            s->X0[j] = v0, s->X1[j] = v1, s->X2[j] = v2, s->XC[j] = c, s->ON[j] = go ? 1.0 : 0.0;           \
        }                                                                                                    \
        for (int round = 1; round < K.max_refine_steps; round++) {                                           \
            int going = 0;                                                                                   \
            for (int j = 0; j < m; j++)                                                                      \
                going += s->ON[j] == 1.0;                                                                    \
            if (going == 0)                                                                                  \
                break;                                                                                       \
            for (int j = 0; j < m; j++) {                                                                    \
                double v0 = s->X0[j], v1 = s->X1[j], v2 = s->X2[j], c = s->XC[j], c_next;                   \
                refine_step(s, j, &v0, &v1, &v2, &c_next, fused);                                                \
                int o = s->ON[j] == 1.0;                                                                     \
                double ratio = c_next / c;                                                                   \
                s->X0[j] = o ? v0 : s->X0[j];                                                                \
                s->X1[j] = o ? v1 : s->X1[j];                                                                \
                s->X2[j] = o ? v2 : s->X2[j];                                                                \
                s->XC[j] = o ? c_next : c;                                                                   \
                s->ON[j] = o & (ratio < 0.25) & (c_next * ratio > K.stop) & (c_next > K.tiny) ? 1.0 : 0.0;   \
            }                                                                                                \
        }                                                                                                    \
    }
/* linsolve._refine of every row from F into X, its stopping rule applied to each row alone: after
 * the first step, a row goes on while its correction shrinks fourfold and the next is predicted
 * above STOP; each round takes a step on every row and keeps it where the row goes on (so the
 * loops have no branch), and rounds stop when no row goes on. Rows without an answer or with
 * inputs outside the safe range take no further step. One function per pair of columns, so that
 * the compiler sees them apart: from LDL^T's answer into X, and from X into R. */
REFINE_CHUNK(refine_w_into_x, w0, w1, w2, x0, x1, x2, xc, xon)
REFINE_CHUNK(refine_x_into_r, x0, x1, x2, r0, r1, r2, rc, ron)
#undef REFINE_CHUNK

/* metrics.relative_error for one row */
static inline double relative_error(double x0, double x1, double x2, double r0, double r1, double r2)
{
    double d0 = x0 - r0, d1 = x1 - r1, d2 = x2 - r2;
    double unit = pmax(pmax(fabs(r0), fabs(r1)), fabs(r2));
    unit = ((unit > 0) & (unit <= K.max)) ? unit : 1.0;
    d0 /= unit, d1 /= unit, d2 /= unit, r0 /= unit, r1 /= unit, r2 /= unit;
    double num = sqrt(d0 * d0 + d1 * d1 + d2 * d2);
    double den = sqrt(r0 * r0 + r1 * r1 + r2 * r2);
    double ratio = num / (den > 0 ? den : 1.0);
    return den > 0 ? ratio : (num == 0 ? 0.0 : num * INFINITY);
}

/* refined's answer and the residual of the m rows: omega into X (refined) or left in W, the
 * residual, and whether both are final (fin: 1.0; 0.0 sends the row to the numpy engine). The
 * residual's reference is a refinement of its own: from LDL^T's answer for exact (the first
 * correction is that answer's error), from the refined answer for refined. */
HOT static void finish_chunk(Chunk *restrict s, int m, int refined, int diagnostics, int fused)
{
    refine_w_into_x(s, m, fused);
    if (refined && diagnostics)
        refine_x_into_r(s, m, fused);
    /* one loop per case, naming its columns, so that the compiler sees them apart */
#define FINISH(A0, A1, A2, B0, B1, B2)                                                                       \
    for (int j = 0; j < m; j++) {                                                                            \
        int fin = final_w(s->A0[j], s->A1[j], s->A2[j]) & safe(s->B0[j]) & safe(s->B1[j]) & safe(s->B2[j]);  \
        s->res[j] = relative_error(s->A0[j], s->A1[j], s->A2[j], s->B0[j], s->B1[j], s->B2[j]);             \
        s->fin[j] = fin ? 1.0 : 0.0;                                                                         \
    }
    if (!refined) { /* exact with the residual: omega stays LDL^T's, the reference is X */
        FINISH(w0, w1, w2, x0, x1, x2)
    } else if (diagnostics) {
        FINISH(x0, x1, x2, r0, r1, r2)
    } else {
        for (int j = 0; j < m; j++) {
            s->res[j] = NAN;
            s->fin[j] = final_w(s->x0[j], s->x1[j], s->x2[j]) ? 1.0 : 0.0;
        }
    }
#undef FINISH
}

/* Nine row-major numbers v: the six of their symmetric part into row j of s, and whether they are
 * not symmetric (forms._sym3_of_nine's test; NaN rows fall back too), with no branch, so that a
 * loop over rows vectorises. */
HOT static void sym_of_nine(Chunk *restrict s, int j, const double *v)
{
    double v0 = v[0], v1 = v[1], v2 = v[2], v3 = v[3], v4 = v[4], v5 = v[5], v6 = v[6], v7 = v[7], v8 = v[8];
    double skew = pmax(pmax(fabs(v1 - v3), fabs(v2 - v6)), fabs(v5 - v7));
    double scale = pmax(pmax(pmax(fabs(v0), fabs(v1)), pmax(fabs(v2), fabs(v3))),
                        pmax(pmax(fabs(v4), fabs(v5)), pmax(fabs(v6), fabs(v7))));
    scale = pmax(scale, fabs(v8));
    s->xx[j] = v0, s->yy[j] = v4, s->zz[j] = v8;
    s->xy[j] = 0.5 * (v1 + v3), s->xz[j] = 0.5 * (v2 + v6), s->yz[j] = 0.5 * (v5 + v7);
    s->asym[j] = (skew > K.symmetry_rtol * scale) | (skew != skew) ? 1.0 : 0.0;
}

typedef struct {
    const char *Ib, *Hb;
    npy_intp Is0, Is1, Hs0, Hs1;
    int nine, refined, diagnostics;
    double cond_limit;
    double *w, *cond, *residual;
    uint8_t *code;
    npy_bool *fallback;
} Job;

/* m rows of nine numbers each, together (an (N, 3, 3) stack as numpy holds it), into s: each
 * number first into a column of its own (v3, v6, v7 in d1..d3, not yet used), a strided loop
 * that vectorises where a row at a time does not, then as sym_of_nine. */
HOT static void nine_rows(Chunk *restrict s, int m, const double *restrict rows)
{
#define COLUMN(col, k)                                                                                       \
    for (int j = 0; j < m; j++)                                                                              \
        s->col[j] = rows[9 * j + (k)];
    COLUMN(xx, 0) COLUMN(xy, 1) COLUMN(xz, 2) COLUMN(d1, 3) COLUMN(yy, 4) COLUMN(yz, 5) COLUMN(d2, 6)
    COLUMN(d3, 7) COLUMN(zz, 8)
#undef COLUMN
    for (int j = 0; j < m; j++) {
        double v[9] = {s->xx[j], s->xy[j], s->xz[j], s->d1[j], s->yy[j], s->yz[j], s->d2[j], s->d3[j], s->zz[j]};
        sym_of_nine(s, j, v);
    }
}

/* m rows of three numbers each, together, into h0..h2: by columns, as nine_rows */
HOT static void three_rows(Chunk *restrict s, int m, const double *restrict rows)
{
    for (int j = 0; j < m; j++)
        s->h0[j] = rows[3 * j];
    for (int j = 0; j < m; j++)
        s->h1[j] = rows[3 * j + 1];
    for (int j = 0; j < m; j++)
        s->h2[j] = rows[3 * j + 2];
}

/* The m rows' answers from their scratch (omega from a0..a2: LDL^T's or refined's) into the
 * outputs: a row without an answer gets NaN, a row the numpy engine must convert is marked
 * fallback. One loop per case, with no branch in it, so that it vectorises. */
HOT static void store_chunk(Chunk *restrict s, int m, const double *restrict a0, const double *restrict a1,
                            const double *restrict a2, double *restrict w, double *restrict cond,
                            double *restrict residual, uint8_t *restrict code_out, npy_bool *restrict fallback,
                            int more, int diagnostics)
{
    /* With the residual, first in doubles only, into columns the chunk is done with (d1..d3
     * omega, xc the code, rc whether lost), then omega's rows of three and the bytes: one loop
     * with everything was the slower there (measured; docs/measurements.md), and the faster
     * without the residual. */
#define STORE(MORE, DIAGNOSTICS, W0, W1, W2, CODE, LOST)                                                     \
    for (int j = 0; j < m; j++) {                                                                            \
        double state = s->state[j];                                                                          \
        int answered = state == ANSWER;                                                                      \
        double code = s->code[j];                                                                            \
        int lost = (s->asym[j] == 1.0) | (state == FALLBACK);                                                \
        if (MORE) /* refinement needs safe inputs, and its answer must pass the checks again */              \
            lost |= answered & ((s->safe[j] != 1.0) | (s->fin[j] != 1.0));                                   \
        double b0 = a0[j], b1 = a1[j], b2 = a2[j]; /* loaded whatever the row: no branch */                  \
        W0 = answered ? b0 : NAN;                                                                            \
        W1 = answered ? b1 : NAN;                                                                            \
        W2 = answered ? b2 : NAN;                                                                            \
        if (DIAGNOSTICS) {                                                                                   \
            double res = answered ? s->res[j] : NAN;                                                         \
            residual[j] = res;                                                                               \
            /* inaccurate takes a row only from ok: it comes after the statuses set above */                 \
            code = (res > K.ill_tol) & (code == K.ok) ? K.inaccurate : code;                                 \
        }                                                                                                    \
        CODE = (int)code; /* through int: a conversion to a byte that vectorises */                         \
        LOST = lost;                                                                                         \
        if (!(DIAGNOSTICS))                                                                                  \
            cond[j] = s->cond[j];                                                                            \
    }
    if (diagnostics) {
        STORE(1, 1, s->d1[j], s->d2[j], s->d3[j], s->xc[j], s->rc[j])
        for (int j = 0; j < m; j++)
            w[3 * j] = s->d1[j], w[3 * j + 1] = s->d2[j], w[3 * j + 2] = s->d3[j];
        for (int j = 0; j < m; j++)
            cond[j] = s->cond[j];
        for (int j = 0; j < m; j++)
            code_out[j] = (uint8_t)(int)s->xc[j];
        for (int j = 0; j < m; j++)
            fallback[j] = (npy_bool)(int)s->rc[j];
    } else if (more)
        STORE(1, 0, w[3 * j], w[3 * j + 1], w[3 * j + 2], code_out[j], fallback[j])
    else
        STORE(0, 0, w[3 * j], w[3 * j + 1], w[3 * j + 2], code_out[j], fallback[j])
#undef STORE
}

/* Rows start..start+m (m <= CH) of the job, through one chunk's scratch. With `fused`, the
 * residual's products have their errors from fma() rather than from Dekker's splits: within the
 * safe range, which every row that keeps its answer is in (linsolve.in_safe_range's rule), both
 * are that error exactly, so the bits are the same; fma() only where the CPU has it (a library
 * fma without it costs far more than the splits). */
HOT static void chunk_body(const Job *jb, Chunk *restrict s, npy_intp start, int m, int fused)
{
#define AT(base, s0, s1, k, i) (*(const double *)((base) + (k) * (s0) + (i) * (s1)))
    if (jb->nine && jb->Is0 == sizeof(double) && jb->Is1 == 9 * sizeof(double)) {
        /* an (N, 3, 3) stack as numpy holds it: each row's nine numbers together */
        nine_rows(s, m, (const double *)jb->Ib + 9 * start);
    } else if (jb->nine) {
        for (int j = 0; j < m; j++) {
            double v[9];
            for (int k = 0; k < 9; k++)
                v[k] = AT(jb->Ib, jb->Is0, jb->Is1, k, start + j);
            sym_of_nine(s, j, v);
        }
    } else {
        for (int j = 0; j < m; j++) {
            npy_intp i = start + j;
            s->xx[j] = AT(jb->Ib, jb->Is0, jb->Is1, 0, i), s->yy[j] = AT(jb->Ib, jb->Is0, jb->Is1, 1, i);
            s->zz[j] = AT(jb->Ib, jb->Is0, jb->Is1, 2, i), s->xy[j] = AT(jb->Ib, jb->Is0, jb->Is1, 3, i);
            s->xz[j] = AT(jb->Ib, jb->Is0, jb->Is1, 4, i), s->yz[j] = AT(jb->Ib, jb->Is0, jb->Is1, 5, i);
            s->asym[j] = 0.0;
        }
    }
    if (jb->Hs0 == sizeof(double) && jb->Hs1 == 3 * sizeof(double)) {
        three_rows(s, m, (const double *)jb->Hb + 3 * start); /* an (N, 3) H as numpy holds it */
    } else {
        for (int j = 0; j < m; j++) {
            npy_intp i = start + j;
            s->h0[j] = AT(jb->Hb, jb->Hs0, jb->Hs1, 0, i);
            s->h1[j] = AT(jb->Hb, jb->Hs0, jb->Hs1, 1, i);
            s->h2[j] = AT(jb->Hb, jb->Hs0, jb->Hs1, 2, i);
        }
    }
#undef AT
    numbers_chunk(s, m, jb->cond_limit);
    int more = jb->refined || jb->diagnostics;
    if (more)
        finish_chunk(s, m, jb->refined, jb->diagnostics, fused);
    const double *a0 = jb->refined ? s->x0 : s->w0, *a1 = jb->refined ? s->x1 : s->w1;
    const double *a2 = jb->refined ? s->x2 : s->w2;
    store_chunk(s, m, a0, a1, a2, jb->w + 3 * start, jb->cond + start, jb->residual + (jb->diagnostics ? start : 0),
                jb->code + start, jb->fallback + start, more, jb->diagnostics);
}

/* chunk_body compiled once per instruction set: wider vectors where the CPU has them, and fma
 * where it has that, chosen when the module loads (an x86-64 wheel must run on any x86-64).
 * More rows at once, the same operations on each, so the same bits; no multiply-add is fused but
 * the residual's explicit fma(). */
typedef void (*ChunkFn)(const Job *, Chunk *restrict, npy_intp, int);
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
__attribute__((target("avx512f,fma"))) NOINLINE static void chunk_avx512(const Job *jb, Chunk *restrict s,
                                                                          npy_intp start, int m)
{
    chunk_body(jb, s, start, m, 1);
}
__attribute__((target("avx2,fma"))) NOINLINE static void chunk_avx2(const Job *jb, Chunk *restrict s, npy_intp start,
                                                                   int m)
{
    chunk_body(jb, s, start, m, 1);
}
NOINLINE static void chunk_plain(const Job *jb, Chunk *restrict s, npy_intp start, int m)
{
    chunk_body(jb, s, start, m, 0);
}
/* the versions this CPU runs, the first the one used */
static int kernels_of_cpu(const char *names[3], ChunkFn fns[3])
{
    int k = 0;
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("fma"))
        names[k] = "avx512f,fma", fns[k++] = chunk_avx512;
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"))
        names[k] = "avx2,fma", fns[k++] = chunk_avx2;
    names[k] = "default", fns[k++] = chunk_plain;
    return k;
}
#else
NOINLINE static void chunk_plain(const Job *jb, Chunk *restrict s, npy_intp start, int m)
{
#if defined(FP_FAST_FMA) /* fma is an instruction on this target (aarch64, or x86 built for one with it) */
    chunk_body(jb, s, start, m, 1);
#else
    chunk_body(jb, s, start, m, 0);
#endif
}
static int kernels_of_cpu(const char *names[3], ChunkFn fns[3])
{
    names[0] = "default", fns[0] = chunk_plain;
    return 1;
}
#endif
static ChunkFn convert_chunk;

static int get(PyObject *c, const char *name, double *out)
{
    PyObject *v = PyDict_GetItemString(c, name);
    if (!v) {
        PyErr_Format(PyExc_KeyError, "rowcode.configure: %s missing", name);
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
    if (steps != NEWTON_STEPS) {
        PyErr_Format(PyExc_ValueError, "rowcode.configure: ROOT_NEWTON_STEPS is %g; this build has %d", steps,
                     NEWTON_STEPS);
        return -1;
    }
    K.max_refine_steps = (int)refine_steps;
    K.inv_safe = 1.0 / K.safe;
    K.inv_root_range = 1.0 / K.root_range;
    K.ok = codes[0], K.singular = codes[1], K.not_physical = codes[2];
    K.ill_conditioned = codes[3], K.inaccurate = codes[4];
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
        PyErr_Format(PyExc_ValueError, "rowcode.convert: %s has the wrong shape or dtype", name);
        return -1;
    }
    if (writable && !(PyArray_IS_C_CONTIGUOUS(a) && PyArray_ISWRITEABLE(a))) {
        PyErr_Format(PyExc_ValueError, "rowcode.convert: %s must be contiguous and writable", name);
        return -1;
    }
    return 0;
}

/* convert(I, nine, H, refined, diagnostics, cond_limit, w, cond, code, residual, fallback, start, stop):
 * rows start..stop of I and H into the same rows of the outputs (residual written with
 * diagnostics only), a chunk of CH rows at a time, without the GIL; returns how many of them are
 * fallback. */
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
        PyErr_SetString(PyExc_RuntimeError, "rowcode.convert: configure() first");
        return NULL;
    }
    if (PyArray_NDIM(H) != 2) {
        PyErr_SetString(PyExc_ValueError, "rowcode.convert: H must be (3, N)");
        return NULL;
    }
    npy_intp n = PyArray_DIM(H, 1);
    if (check(H, "H", 2, 3, n, NPY_FLOAT64, 0) || check(In, "I", 2, nine ? 9 : 6, n, NPY_FLOAT64, 0) ||
        check(w, "w", 2, n, 3, NPY_FLOAT64, 1) || check(cond, "cond", 1, n, 0, NPY_FLOAT64, 1) ||
        check(code, "code", 1, n, 0, NPY_UINT8, 1) || check(fallback, "fallback", 1, n, 0, NPY_BOOL, 1) ||
        check(residual, "residual", 1, diagnostics ? n : PyArray_DIM(residual, 0), 0, NPY_FLOAT64, 1))
        return NULL;
    if (start < 0 || stop > n || start > stop) {
        PyErr_SetString(PyExc_ValueError, "rowcode.convert: rows start..stop out of range");
        return NULL;
    }
    Job jb = {PyArray_BYTES(In), PyArray_BYTES(H), PyArray_STRIDE(In, 0), PyArray_STRIDE(In, 1),
              PyArray_STRIDE(H, 0), PyArray_STRIDE(H, 1), nine, refined, diagnostics, cond_limit,
              (double *)PyArray_DATA(w), (double *)PyArray_DATA(cond), (double *)PyArray_DATA(residual),
              (uint8_t *)PyArray_DATA(code), (npy_bool *)PyArray_DATA(fallback)};
    Chunk *s = PyMem_RawMalloc(sizeof(Chunk));
    if (!s)
        return PyErr_NoMemory();
    npy_intp lost = 0;
    Py_BEGIN_ALLOW_THREADS;
    for (npy_intp i = start; i < stop; i += CH)
        convert_chunk(&jb, s, i, (int)(stop - i < CH ? stop - i : CH));
    for (npy_intp i = start; i < stop; i++)
        lost += jb.fallback[i] != 0;
    Py_END_ALLOW_THREADS;
    PyMem_RawFree(s);
    return PyLong_FromSsize_t(lost);
}

/* one(I, nine, H, refined, diagnostics, cond_limit): one body, I (3, 3) or (6,) and H (3,)
 * contiguous float64 (else None: the caller takes the general path), converted with the GIL held
 * (a few microseconds): (w (3,), cond, code, residual, fallback), numpy scalars as a stacked
 * result's rows are, residual None without diagnostics. */
static PyObject *one(PyObject *self, PyObject *args)
{
    PyArrayObject *In, *H;
    int nine, refined, diagnostics;
    double cond_limit;
    if (!PyArg_ParseTuple(args, "O!pO!ppd", &PyArray_Type, &In, &nine, &PyArray_Type, &H, &refined, &diagnostics,
                          &cond_limit))
        return NULL;
    if (!K.ready || PyArray_TYPE(In) != NPY_FLOAT64 || PyArray_TYPE(H) != NPY_FLOAT64 ||
        !PyArray_IS_C_CONTIGUOUS(In) || !PyArray_IS_C_CONTIGUOUS(H) || PyArray_SIZE(H) != 3 ||
        PyArray_SIZE(In) != (nine ? 9 : 6))
        Py_RETURN_NONE;
    double w[3], cond, residual = NAN;
    uint8_t code;
    npy_bool fallback;
    Job jb = {PyArray_BYTES(In), PyArray_BYTES(H), sizeof(double), 0, sizeof(double), 0, nine, refined, diagnostics,
              cond_limit, w, &cond, &residual, &code, &fallback};
    Chunk s; /* about 23 kB of stack */
    convert_chunk(&jb, &s, 0, 1);
    npy_intp three = 3;
    PyObject *wa = PyArray_SimpleNew(1, &three, NPY_FLOAT64);
    if (!wa)
        return NULL;
    memcpy(PyArray_DATA((PyArrayObject *)wa), w, sizeof w);
    PyArray_Descr *f64 = PyArray_DescrFromType(NPY_FLOAT64), *u8 = PyArray_DescrFromType(NPY_UINT8);
    PyObject *c = PyArray_Scalar(&cond, f64, NULL), *k = PyArray_Scalar(&code, u8, NULL);
    PyObject *r = diagnostics ? PyArray_Scalar(&residual, f64, NULL) : (Py_INCREF(Py_None), Py_None);
    Py_DECREF(f64);
    Py_DECREF(u8);
    if (!c || !k || !r) {
        Py_XDECREF(c), Py_XDECREF(k), Py_XDECREF(r), Py_DECREF(wa);
        return NULL;
    }
    return Py_BuildValue("(NNNNO)", wa, c, k, r, fallback ? Py_True : Py_False);
}

/* stack(I, H, refined, diagnostics, cond_limit): a stack of bodies as numpy users hold it, I
 * (N, 3, 3) (its rows of three contiguous) or (N, 6) and H (N, 3), float64, converted on the
 * caller's thread into new arrays: (w (N, 3), cond, code, residual or None). None when a row is
 * left to the numpy engine, or for arrays of another layout: the caller then takes the general
 * path. For small stacks, whose cost is mostly the call's. */
static PyObject *stack(PyObject *self, PyObject *args)
{
    PyArrayObject *In, *H;
    int refined, diagnostics;
    double cond_limit;
    if (!PyArg_ParseTuple(args, "O!O!ppd", &PyArray_Type, &In, &PyArray_Type, &H, &refined, &diagnostics,
                          &cond_limit))
        return NULL;
    if (!K.ready || PyArray_TYPE(In) != NPY_FLOAT64 || PyArray_TYPE(H) != NPY_FLOAT64 || PyArray_NDIM(H) != 2 ||
        PyArray_DIM(H, 1) != 3)
        Py_RETURN_NONE;
    npy_intp n = PyArray_DIM(H, 0);
    int nine = PyArray_NDIM(In) == 3;
    if (PyArray_DIM(In, 0) != n || n == 0)
        Py_RETURN_NONE;
    if (nine ? PyArray_DIM(In, 1) != 3 || PyArray_DIM(In, 2) != 3 || PyArray_STRIDE(In, 1) != 3 * PyArray_STRIDE(In, 2)
             : PyArray_NDIM(In) != 2 || PyArray_DIM(In, 1) != 6)
        Py_RETURN_NONE;
    npy_intp dims[2] = {n, 3};
    PyObject *w = PyArray_SimpleNew(2, dims, NPY_FLOAT64), *cond = PyArray_SimpleNew(1, dims, NPY_FLOAT64);
    PyObject *code = PyArray_SimpleNew(1, dims, NPY_UINT8);
    PyObject *res = diagnostics ? PyArray_SimpleNew(1, dims, NPY_FLOAT64) : (Py_INCREF(Py_None), Py_None);
    npy_bool *fallback = PyMem_RawMalloc(n * sizeof(npy_bool));
    Chunk *s = PyMem_RawMalloc(sizeof(Chunk));
    if (!w || !cond || !code || !res || !fallback || !s) {
        Py_XDECREF(w), Py_XDECREF(cond), Py_XDECREF(code), Py_XDECREF(res);
        PyMem_RawFree(fallback), PyMem_RawFree(s);
        return PyErr_NoMemory();
    }
    Job jb = {PyArray_BYTES(In), PyArray_BYTES(H), PyArray_STRIDE(In, PyArray_NDIM(In) - 1), PyArray_STRIDE(In, 0),
              PyArray_STRIDE(H, 1), PyArray_STRIDE(H, 0), nine, refined, diagnostics, cond_limit,
              (double *)PyArray_DATA((PyArrayObject *)w), (double *)PyArray_DATA((PyArrayObject *)cond),
              diagnostics ? (double *)PyArray_DATA((PyArrayObject *)res) : NULL,
              (uint8_t *)PyArray_DATA((PyArrayObject *)code), fallback};
    npy_intp lost = 0;
    Py_BEGIN_ALLOW_THREADS;
    for (npy_intp i = 0; i < n; i += CH)
        convert_chunk(&jb, s, i, (int)(n - i < CH ? n - i : CH));
    for (npy_intp i = 0; i < n; i++)
        lost += fallback[i] != 0;
    Py_END_ALLOW_THREADS;
    PyMem_RawFree(fallback), PyMem_RawFree(s);
    if (lost) {
        Py_DECREF(w), Py_DECREF(cond), Py_DECREF(code), Py_DECREF(res);
        Py_RETURN_NONE;
    }
    return Py_BuildValue("(NNNN)", w, cond, code, res);
}

/* kernels(): the names of the versions of the chunk code this CPU runs, the one in use first.
 * use(name): convert with that version from now on (tests compare their bits); returns None. */
static PyObject *kernels(PyObject *self, PyObject *args)
{
    const char *names[3];
    ChunkFn fns[3];
    int k = kernels_of_cpu(names, fns);
    PyObject *out = PyList_New(0);
    for (int i = 0; out && i < k; i++) {
        PyObject *name = PyUnicode_FromString(names[i]);
        if (!name || (fns[i] == convert_chunk ? PyList_Insert(out, 0, name) : PyList_Append(out, name)) < 0)
            Py_CLEAR(out);
        Py_XDECREF(name);
    }
    return out;
}

static PyObject *use(PyObject *self, PyObject *args)
{
    const char *want, *names[3];
    ChunkFn fns[3];
    if (!PyArg_ParseTuple(args, "s", &want))
        return NULL;
    int k = kernels_of_cpu(names, fns);
    for (int i = 0; i < k; i++)
        if (strcmp(names[i], want) == 0) {
            convert_chunk = fns[i];
            Py_RETURN_NONE;
        }
    PyErr_Format(PyExc_ValueError, "rowcode.use: this CPU has no version %s", want);
    return NULL;
}

static PyMethodDef methods[] = {
    {"kernels", kernels, METH_NOARGS, "kernels(): the versions of the chunk code this CPU runs, the one in use first."},
    {"use", use, METH_VARARGS, "use(name): convert with that version of the chunk code (for tests)."},
    {"stack", stack, METH_VARARGS, "stack(I, H, refined, diagnostics, cond_limit): a small stack, or None."},
    {"one", one, METH_VARARGS, "one(I, nine, H, refined, diagnostics, cond_limit): one body, or None."},
    {"configure", configure, METH_VARARGS, "configure(constants): the constants of hconv's Python modules."},
    {"convert", convert, METH_VARARGS,
     "convert(I, nine, H, refined, diagnostics, cond_limit, w, cond, code, residual, fallback, start, stop)"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "rowcode", "hconv's compiled row code.", -1, methods};

PyMODINIT_FUNC PyInit_rowcode(void)
{
    import_array();
    const char *names[3];
    ChunkFn fns[3];
    kernels_of_cpu(names, fns);
    convert_chunk = fns[0];
    return PyModule_Create(&module);
}
