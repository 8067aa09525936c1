/* hconv.solve.rowcode's arithmetic: the chunk code, one fused pass over the rows of a chunk
 * (chunk_body), and the constants it computes with. Included once, by rowcode.c, which compiles
 * chunk_body once per instruction set and holds the Python functions; its header comment states
 * the conventions (rounding as written, the numpy engine's operations in their order, shapes). */
#ifndef HCONV_ROWMATH_H
#define HCONV_ROWMATH_H

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
/* Rows per chunk: the chunk's scratch (51 numbers a row, 26 kB) stays in the L1 cache. */
#define CH 64
/* What the verdict says of a row: the numpy engine must convert it, it has no answer (singular),
 * or it has one. A row whose verdict waits on the largest moment's exact error bound holds
 * NO_ANSWER or ANSWER plus UNSURE until that bound decides it (numbers_chunk). */
#define FALLBACK 0.0
#define NO_ANSWER 1.0
#define ANSWER 2.0
#define UNSURE 4.0

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
 * answers are final; the largest moment's p, r, q and value, for its exact error bound; and the
 * outputs of a streamed chunk, as they go to memory (chunk_body). Columns of one struct, so that
 * the compiler can prove them apart. */
typedef struct {
    double xx[CH], yy[CH], zz[CH], xy[CH], xz[CH], yz[CH], h0[CH], h1[CH], h2[CH];
    double d1[CH], d2[CH], d3[CH], l21[CH], l31[CH], l32[CH], w0[CH], w1[CH], w2[CH], i1[CH], i2[CH], i3[CH];
    double cond[CH], code[CH], state[CH], safe[CH];
    double x0[CH], x1[CH], x2[CH], xc[CH], xon[CH];
    double r0[CH], r1[CH], r2[CH], rc[CH], ron[CH];
    double res[CH], fin[CH], asym[CH];
    double ep[CH], er[CH], eq[CH], ehi[CH];
    double ow[3 * CH], ocond[CH], ores[CH];
    uint8_t ocode[CH];
    npy_bool ofb[CH];
} Chunk;
/* Copies `bytes` (a multiple of 64) from src to dst (64-byte aligned) with stores that bypass the
 * caches; a store fence must follow before another thread reads dst (rowcode.c's rows()). */
typedef void (*StreamFn)(void *restrict dst, const void *restrict src, size_t bytes);

/* The numbers and the verdict of the m rows, with no branch. The numbers: LDL^T
 * (linsolve.ldlt_factor) and its answer (linsolve.ldlt_solve), the closed-form largest and
 * smallest principal moments (spectrum). The verdict: cond, the status code, and the state; each
 * test is the numpy engine's (blocks._convert_block, spectrum.eigenvalues), and a row that any of
 * them cannot settle is FALLBACK. */
HOT static void numbers_chunk(Chunk *restrict s, int m, double cond_limit, int more)
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
        usable &= (fabs(lo) <= K.max) & (lo > 0);
        /* where the closed form cannot decide, the numpy engine asks LAPACK: the margin must
         * beat 1e-9 tr + 4 hi_err. hi_err is at most p SQRT_EPS + 8 EPS |q|: its min is at
         * most SQRT_EPS, p is not negative (a square root; NaN only in rows that fall back
         * anyway, lo being NaN too), and rounding to nearest keeps the order of every step. So
         * a margin above that bound beats hi_err's too; the exact bound, a square root and a
         * division a row, waits for the rare rows the cheap one leaves unsure (the loop after
         * this one). */
        int clear = fabs(2.0 * hi - tr) > 1e-9 * tr + 4.0 * (p * K.sqrt_eps + 8.0 * K.eps * fabs(q));
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
        state = state != FALLBACK && !clear ? state + UNSURE : state;
        /* only the residual and refinement ask whether a row is in the safe range */
        int sf = more && safe(xx) & safe(yy) & safe(zz) & safe(xy) & safe(xz) & safe(yz) & safe(h0) & safe(h1) & safe(h2);
        s->d1[j] = d1, s->d2[j] = d2, s->d3[j] = d3, s->l21[j] = l21, s->l31[j] = l31, s->l32[j] = l32;
        if (more) /* for the refinement steps: a multiplication each where a division costs several */
            s->i1[j] = 1.0 / d1, s->i2[j] = 1.0 / d2, s->i3[j] = 1.0 / d3;
        s->w0[j] = w0, s->w1[j] = w1, s->w2[j] = w2;
        s->cond[j] = cond, s->code[j] = code, s->state[j] = state, s->safe[j] = sf ? 1.0 : 0.0;
        s->ep[j] = p, s->er[j] = r, s->eq[j] = q, s->ehi[j] = hi;
    }
    int unsure = 0;
    for (int j = 0; j < m; j++)
        unsure += s->state[j] >= UNSURE;
    if (unsure == 0)
        return;
    for (int j = 0; j < m; j++) {
        /* spectrum._largest_root's error bound, and eigenvalues' test with it */
        double p = s->ep[j], r = s->er[j], q = s->eq[j], hi = s->ehi[j], tr = s->xx[j] + s->yy[j] + s->zz[j];
        double hi_err = p * pmin(K.sqrt_eps, 16.0 * K.eps / sqrt(pmax(1.0 - r * r, K.eps))) + 8.0 * K.eps * fabs(q);
        double state = s->state[j];
        int decided = fabs(2.0 * hi - tr) > 1e-9 * tr + 4.0 * hi_err;
        s->state[j] = state >= UNSURE ? (decided ? state - UNSURE : FALLBACK) : state;
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
    double dx2 = y3 * s->i3[j];
    double dx1 = y2 * s->i2[j];
    dx1 -= l32 * dx2;
    double dx0 = y1 * s->i1[j];
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
                s->X0[j] = o ? v0 : s->X0[j];                                                                \
                s->X1[j] = o ? v1 : s->X1[j];                                                                \
                s->X2[j] = o ? v2 : s->X2[j];                                                                \
                s->XC[j] = o ? c_next : c;                                                                   \
                int on = (c_next < 0.25 * c) & (c_next * c_next > K.stop * c) & (c_next > K.tiny);           \
                s->ON[j] = o & on ? 1.0 : 0.0;                                                               \
            }                                                                                                \
        }                                                                                                    \
    }
/* linsolve._refine of every row from F into X, its stopping rule applied to each row alone: after
 * the first step, a row goes on while its correction shrinks fourfold and the next is predicted
 * above STOP; each round takes a step on every row and keeps it where the row goes on (so the
 * loops have no branch), and rounds stop when no row goes on. The ratio of the corrections
 * c_next / c is compared by products (c_next < c/4, c_next^2 > STOP c; c > TINY > 0 in a row
 * that goes on), which saves a division a round; a step's correction is the residual's solve
 * with the pivots' reciprocals (numbers_chunk), a multiplication where a division costs several.
 * Both can move a decision or a correction by a rounding, no more (refined is within 2 eps of
 * the numpy engine's, not its bits). Rows without an answer or with
 * inputs outside the safe range take no further step. One function per pair of columns, so that
 * the compiler sees them apart: from LDL^T's answer into X, and from X into R. */
REFINE_CHUNK(refine_w_into_x, w0, w1, w2, x0, x1, x2, xc, xon)
REFINE_CHUNK(refine_x_into_r, x0, x1, x2, r0, r1, r2, rc, ron)
#undef REFINE_CHUNK

/* metrics.relative_error for one row, scaled by the reciprocal of its unit where metrics divides
 * by the unit: one division where there were six. Both norms take the same factor, so its
 * rounding leaves the ratio as it was but for a rounding of each product; the unit is 0 or at
 * least SAFE's reciprocal in every row that keeps its residual (fin), so the reciprocal is
 * finite there. */
static inline double relative_error(double x0, double x1, double x2, double r0, double r1, double r2)
{
    double d0 = x0 - r0, d1 = x1 - r1, d2 = x2 - r2;
    double unit = pmax(pmax(fabs(r0), fabs(r1)), fabs(r2));
    unit = ((unit > 0) & (unit <= K.max)) ? unit : 1.0;
    double iu = 1.0 / unit;
    d0 *= iu, d1 *= iu, d2 *= iu, r0 *= iu, r1 *= iu, r2 *= iu;
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
    int stream; /* outputs too large to stay in the caches: stream whole chunks (chunk_body) */
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

#define ALIGNED(p) (((uintptr_t)(p) & 63) == 0)
/* Rows start..start+m (m <= CH) of the job, through one chunk's scratch. With `fused`, the
 * residual's products have their errors from fma() rather than from Dekker's splits: within the
 * safe range, which every row that keeps its answer is in (linsolve.in_safe_range's rule), both
 * are that error exactly, so the bits are the same; fma() only where the CPU has it (a library
 * fma without it costs far more than the splits). With `stream` (not NULL), a whole chunk whose
 * outputs start on cache lines is stored into the chunk's own columns, then streamed to the
 * outputs: a store to a line that is not in the cache first reads it from memory, which the
 * streaming stores skip. */
HOT static void chunk_body(const Job *jb, Chunk *restrict s, npy_intp start, int m, int fused, StreamFn stream)
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
    int more = jb->refined || jb->diagnostics;
    if (more) /* a constant in each call, so that each has only the work it needs */
        numbers_chunk(s, m, jb->cond_limit, 1);
    else
        numbers_chunk(s, m, jb->cond_limit, 0);
    if (more)
        finish_chunk(s, m, jb->refined, jb->diagnostics, fused);
    const double *a0 = jb->refined ? s->x0 : s->w0, *a1 = jb->refined ? s->x1 : s->w1;
    const double *a2 = jb->refined ? s->x2 : s->w2;
    double *w = jb->w + 3 * start, *cond = jb->cond + start, *res = jb->residual + (jb->diagnostics ? start : 0);
    uint8_t *code = jb->code + start;
    npy_bool *fallback = jb->fallback + start;
    if (stream && m == CH && ALIGNED(w) && ALIGNED(cond) && ALIGNED(code) && ALIGNED(fallback) &&
        (!jb->diagnostics || ALIGNED(res))) {
        store_chunk(s, m, a0, a1, a2, s->ow, s->ocond, s->ores, s->ocode, s->ofb, more, jb->diagnostics);
        stream(w, s->ow, sizeof s->ow), stream(cond, s->ocond, sizeof s->ocond);
        stream(code, s->ocode, sizeof s->ocode), stream(fallback, s->ofb, sizeof s->ofb);
        if (jb->diagnostics)
            stream(res, s->ores, sizeof s->ores);
    } else
        store_chunk(s, m, a0, a1, a2, w, cond, res, code, fallback, more, jb->diagnostics);
}
#endif /* HCONV_ROWMATH_H */
