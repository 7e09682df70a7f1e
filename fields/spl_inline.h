/* fields/spl_inline.h -- the uniform B-spline's per-axis weights and the 2D
 * stencil contractions of spline.c (grid_priv.h's gcp_spl), as inlines:
 * gcp_spl_locate and gcp_spl_eval are built from them, and callers that
 * evaluate one kind of table in a hot loop (the flux chart's, src/pushers/
 * canon_flux_num.c) use them with the stencil's size a constant and one
 * locate for several components.  The same expressions in the same order
 * as gcp_spl_locate / gcp_spl_eval: the same numbers.  Not installed. */
#ifndef GCPUSH_SPL_INLINE_H
#define GCPUSH_SPL_INLINE_H

#include "grid_priv.h"

#define GCP_SPL_INLINE static inline __attribute__((always_inline))

/* Axis a of x: the cell's offset into coef and t in [0, 1] (clamped to the
 * box; returns 1 when x was outside or NaN). */
GCP_SPL_INLINE int gcp_spl_cell(const struct gcp_spl *s, int a, double x, size_t *off, double *t)
{
    int out = 0;
    double u = (x - s->x0[a]) * s->inv_h[a];
    if (!(u >= 0.0)) { /* also NaN */
        out = 1;
        u = 0.0;
    } else if (u > s->umax[a]) {
        out = 1;
        u = s->umax[a];
    }
    size_t i = (size_t)u;
    if (i > s->n[a] - 2) i = s->n[a] - 2;
    *t = u - (double)i;
    *off = i * s->stride[a];
    return out;
}

/* The uniform quintic B-spline's six pieces on [0, 1] (times 120), their
 * first and second derivatives (times 1/h, 1/h^2) up to order. */
GCP_SPL_INLINE void gcp_spl_w5(double t, double ih, int order, double *w, double *dw,
                               double *ddw)
{
    const double t2 = t * t, t3 = t2 * t, t4 = t3 * t, t5 = t4 * t, omt = 1.0 - t;
    const double o2 = omt * omt, o4 = o2 * o2, c = 1.0 / 120.0;
    w[0] = c * o4 * omt;
    w[1] = c * (5 * t5 - 20 * t4 + 20 * t3 + 20 * t2 - 50 * t + 26);
    w[2] = c * (-10 * t5 + 30 * t4 - 60 * t2 + 66);
    w[3] = c * (10 * t5 - 20 * t4 - 20 * t3 + 20 * t2 + 50 * t + 26);
    w[4] = c * (-5 * t5 + 5 * t4 + 10 * t3 + 10 * t2 + 5 * t + 1);
    w[5] = c * t5;
    if (order >= 1) {
        const double ci = c * ih;
        dw[0] = -5 * ci * o4;
        dw[1] = ci * (25 * t4 - 80 * t3 + 60 * t2 + 40 * t - 50);
        dw[2] = ci * (-50 * t4 + 120 * t3 - 120 * t);
        dw[3] = ci * (50 * t4 - 80 * t3 - 60 * t2 + 40 * t + 50);
        dw[4] = ci * (-25 * t4 + 20 * t3 + 30 * t2 + 20 * t + 5);
        dw[5] = 5 * ci * t4;
    }
    if (order >= 2) {
        const double ci2 = c * ih * ih;
        ddw[0] = 20 * ci2 * o2 * omt;
        ddw[1] = ci2 * (100 * t3 - 240 * t2 + 120 * t + 40);
        ddw[2] = ci2 * (-200 * t3 + 360 * t2 - 120);
        ddw[3] = ci2 * (200 * t3 - 240 * t2 - 120 * t + 40);
        ddw[4] = ci2 * (-100 * t3 + 60 * t2 + 60 * t + 20);
        ddw[5] = 20 * ci2 * t3;
    }
}

/* The uniform septic B-spline's eight pieces on [0, 1], times 5040:
 * P[k][m] is the coefficient of t^k in piece m, which multiplies
 * c_{i-3+m} (B_7 from its truncated-power form, e.g. de Boor, A Practical
 * Guide to Splines, ch. IX); P1, P2 those of the first and second
 * derivatives.  Horner with the eight pieces side by side (each lane in a
 * fixed order: the loop over m vectorises). */
GCP_SPL_INLINE void gcp_spl_w7(double t, double ih, int order, double *w, double *dw,
                               double *ddw)
{
    static const double P[8][8] = {
        {1, 120, 1191, 2416, 1191, 120, 1, 0},
        {-7, -392, -1715, 0, 1715, 392, 7, 0},
        {21, 504, 315, -1680, 315, 504, 21, 0},
        {-35, -280, 665, 0, -665, 280, 35, 0},
        {35, 0, -315, 560, -315, 0, 35, 0},
        {-21, 84, -105, 0, 105, -84, 21, 0},
        {7, -42, 105, -140, 105, -42, 7, 0},
        {-1, 7, -21, 35, -35, 21, -7, 1}};
    static const double P1[7][8] = {
        {-7, -392, -1715, 0, 1715, 392, 7, 0},
        {42, 1008, 630, -3360, 630, 1008, 42, 0},
        {-105, -840, 1995, 0, -1995, 840, 105, 0},
        {140, 0, -1260, 2240, -1260, 0, 140, 0},
        {-105, 420, -525, 0, 525, -420, 105, 0},
        {42, -252, 630, -840, 630, -252, 42, 0},
        {-7, 49, -147, 245, -245, 147, -49, 7}};
    static const double P2[6][8] = {
        {42, 1008, 630, -3360, 630, 1008, 42, 0},
        {-210, -1680, 3990, 0, -3990, 1680, 210, 0},
        {420, 0, -3780, 6720, -3780, 0, 420, 0},
        {-420, 1680, -2100, 0, 2100, -1680, 420, 0},
        {210, -1260, 3150, -4200, 3150, -1260, 210, 0},
        {-42, 294, -882, 1470, -1470, 882, -294, 42}};
    const double c = 1.0 / 5040.0, ci = c * ih, ci2 = ci * ih;
    double v[8], dv[8], ddv[8];
    for (int m = 0; m < 8; m++) v[m] = P[7][m];
    for (int k = 6; k >= 0; k--)
        for (int m = 0; m < 8; m++) v[m] = v[m] * t + P[k][m];
    for (int m = 0; m < 8; m++) w[m] = c * v[m];
    if (order >= 1) {
        for (int m = 0; m < 8; m++) dv[m] = P1[6][m];
        for (int k = 5; k >= 0; k--)
            for (int m = 0; m < 8; m++) dv[m] = dv[m] * t + P1[k][m];
        for (int m = 0; m < 8; m++) dw[m] = ci * dv[m];
    }
    if (order >= 2) {
        for (int m = 0; m < 8; m++) ddv[m] = P2[5][m];
        for (int k = 4; k >= 0; k--)
            for (int m = 0; m < 8; m++) ddv[m] = ddv[m] * t + P2[k][m];
        for (int m = 0; m < 8; m++) ddw[m] = ci2 * ddv[m];
    }
}

/* The septic pieces' third derivatives (times 1/h^3): P3[k] = (k + 1) P2[k + 1]
 * of gcp_spl_w7's tables.  For the analytic Jacobian of the flux chart's
 * collocation solve (src/pushers/canon_flux.c), which needs the table's
 * third derivatives. */
GCP_SPL_INLINE void gcp_spl_w7_3(double t, double ih, double *dddw)
{
    static const double P3[5][8] = {
        {-210, -1680, 3990, 0, -3990, 1680, 210, 0},
        {840, 0, -7560, 13440, -7560, 0, 840, 0},
        {-1260, 5040, -6300, 0, 6300, -5040, 1260, 0},
        {840, -5040, 12600, -16800, 12600, -5040, 840, 0},
        {-210, 1470, -4410, 7350, -7350, 4410, -1470, 210}};
    const double c3 = ih * ih * ih / 5040.0;
    double v[8];
    for (int m = 0; m < 8; m++) v[m] = P3[4][m];
    for (int k = 3; k >= 0; k--)
        for (int m = 0; m < 8; m++) v[m] = v[m] * t + P3[k][m];
    for (int m = 0; m < 8; m++) dddw[m] = c3 * v[m];
}

/* The sums run over the coefficients less the stencil's first one, c0
 * (exact: the weights sum to 1, their derivatives to 0), so that their
 * round-off is eps times the variation of the field over the stencil, not
 * eps times its offset: a second derivative of a field f with |f| >> the
 * variation over the stencil h |f'| would otherwise carry a relative error
 * eps |f| / (h^2 |f''|) (measured: 1e-12 in R_ee of the flux chart's table
 * of R ~ 1.7 m on an eta grid of 2 pi / 512; 2e-14 with the offset taken
 * out, tests/unit/test_gc_symplectic_flux.c). */

/* 2D, K x K stencil at co (row stride s1), axis 0 contracted first, row by
 * row (the generic order of gcp_spl_eval). */
GCP_SPL_INLINE void gcp_spl2_eval_k(int K, const double *co, size_t s1, const double *w0,
                                    const double *dw0, const double *ddw0, const double *w1,
                                    const double *dw1, const double *ddw1, int order,
                                    struct gcp_spl_out *o)
{
    const double c0 = co[0];
    double f = 0, d0 = 0, d1 = 0, d00 = 0, d01 = 0, d11 = 0;
    for (int b = 0; b < K; b++) {
        const double *rr = co + b * s1;
        double r[8];
        for (int a = 0; a < K; a++) r[a] = rr[a] - c0;
        double v = 0, v0 = 0, v00 = 0;
        for (int a = 0; a < K; a++) v += w0[a] * r[a];
        f += w1[b] * v;
        if (order >= 1) {
            for (int a = 0; a < K; a++) v0 += dw0[a] * r[a];
            d0 += w1[b] * v0;
            d1 += dw1[b] * v;
        }
        if (order >= 2) {
            for (int a = 0; a < K; a++) v00 += ddw0[a] * r[a];
            d00 += w1[b] * v00;
            d01 += dw1[b] * v0;
            d11 += ddw1[b] * v;
        }
    }
    o->f = c0 + f;
    o->d[0] = d0;
    o->d[1] = d1;
    o->dd[0][0] = d00;
    o->dd[0][1] = o->dd[1][0] = d01;
    o->dd[1][1] = d11;
}

/* 2D septic: the 8 x 8 stencil contracted along axis 1 first, all eight
 * columns at once (u[a] += w1[b] r[a] over the rows b), then along axis 0
 * (length-8 sums over a).  Each sum runs in a fixed order (u[a]: rows b =
 * 0 .. 7; the axis-0 sums: a = 0 .. 7, from 0), so the numbers do not
 * depend on how it is vectorised; the same sums as the generic loop in
 * another order: equal to round-off, not bit for bit.  Why: the generic
 * order (eight dependent sums per row, row by row) is latency bound, and
 * the septic's 64 coefficients made it 1.6x the quintic's 36
 * (tests/bench/bench_eqdsk_eval.c).
 * Written with 8-wide vectors (GCC/Clang vector extensions, as
 * src/pushers/boris_fast.c): left to the vectoriser, GCC 12 (-O3
 * -march=native) paired rows two by two in 128-bit registers with scalar
 * adds, and an evaluation of the flux chart's table (three components,
 * order 2) took 1.6x what these take (a row is one 64-byte load and one
 * multiply and add per output; the axis-0 sums of one component run side
 * by side in the lanes of one vector, each lane in the scalar order). */
typedef double gcp_spl_v8 __attribute__((vector_size(64), aligned(8)));

/* The order-2 sums' lanes (f - c0, d0, d1, d00, d01, d11) into o (by
 * pointer: a 64-byte vector argument changes the ABI without AVX-512). */
GCP_SPL_INLINE void gcp_spl_out8(struct gcp_spl_out *o, double c0, const gcp_spl_v8 *acc)
{
    o->f = c0 + (*acc)[0];
    o->d[0] = (*acc)[1];
    o->d[1] = (*acc)[2];
    o->dd[0][0] = (*acc)[3];
    o->dd[0][1] = o->dd[1][0] = (*acc)[4];
    o->dd[1][1] = (*acc)[5];
}

/* Row b of the stencil less c0, into *r (by pointer: a 64-byte vector
 * passed or returned by value has no stable ABI without AVX-512, and the
 * DEBUG build, without -march=native, warns (-Wpsabi)). */
GCP_SPL_INLINE void gcp_spl_row8(const double *rr, double c0, gcp_spl_v8 *r)
{
    __builtin_memcpy(r, rr, sizeof *r);
    *r -= c0;
}

GCP_SPL_INLINE void gcp_spl2_eval8(const double *co, size_t s1, const double *w0,
                                   const double *dw0, const double *ddw0, const double *w1,
                                   const double *dw1, const double *ddw1, int order,
                                   struct gcp_spl_out *o)
{
    const double c0 = co[0];
    gcp_spl_v8 u = {0}, u1 = {0}, u11 = {0};
    if (order < 1) {
        for (int b = 0; b < 8; b++) {
            gcp_spl_v8 r;
            gcp_spl_row8(co + b * s1, c0, &r);
            u += w1[b] * r;
        }
        double f = 0;
        for (int a = 0; a < 8; a++) f += w0[a] * u[a];
        o->f = c0 + f;
        return;
    }
    if (order < 2) {
        for (int b = 0; b < 8; b++) {
            gcp_spl_v8 r;
            gcp_spl_row8(co + b * s1, c0, &r);
            u += w1[b] * r;
            u1 += dw1[b] * r;
        }
        /* lanes (f, d0, d1) */
        gcp_spl_v8 acc = {0};
        for (int a = 0; a < 8; a++) {
            const gcp_spl_v8 W = {w0[a], dw0[a], w0[a], 0, 0, 0, 0, 0};
            const gcp_spl_v8 U = {u[a], u[a], u1[a], 0, 0, 0, 0, 0};
            acc += W * U;
        }
        o->f = c0 + acc[0];
        o->d[0] = acc[1];
        o->d[1] = acc[2];
        return;
    }
    for (int b = 0; b < 8; b++) {
        gcp_spl_v8 r;
        gcp_spl_row8(co + b * s1, c0, &r);
        u += w1[b] * r;
        u1 += dw1[b] * r;
        u11 += ddw1[b] * r;
    }
    /* lanes (f, d0, d1, d00, d01, d11) */
    gcp_spl_v8 acc = {0};
    for (int a = 0; a < 8; a++) {
        const gcp_spl_v8 W = {w0[a], dw0[a], w0[a], ddw0[a], dw0[a], w0[a], 0, 0};
        const gcp_spl_v8 U = {u[a], u[a], u1[a], u[a], u1[a], u11[a], 0, 0};
        acc += W * U;
    }
    gcp_spl_out8(o, c0, &acc);
}

/* gcp_spl2_eval8 at order 2 (the same sums: the same numbers) and the third
 * derivatives ddd = (f_000, f_001, f_011, f_111) from the third-derivative
 * weights dddw0, dddw1 (gcp_spl_w7_3). */
GCP_SPL_INLINE void gcp_spl2_eval8_3(const double *co, size_t s1, const double *w0,
                                     const double *dw0, const double *ddw0, const double *dddw0,
                                     const double *w1, const double *dw1, const double *ddw1,
                                     const double *dddw1, struct gcp_spl_out *o, double ddd[4])
{
    const double c0 = co[0];
    gcp_spl_v8 u = {0}, u1 = {0}, u11 = {0}, u111 = {0};
    for (int b = 0; b < 8; b++) {
        gcp_spl_v8 r;
        gcp_spl_row8(co + b * s1, c0, &r);
        u += w1[b] * r;
        u1 += dw1[b] * r;
        u11 += ddw1[b] * r;
        u111 += dddw1[b] * r;
    }
    /* lanes (f, d0, d1, d00, d01, d11, d000, d001), then (d011, d111) */
    gcp_spl_v8 acc = {0}, acc3 = {0};
    for (int a = 0; a < 8; a++) {
        const gcp_spl_v8 W = {w0[a], dw0[a], w0[a], ddw0[a], dw0[a], w0[a], dddw0[a], ddw0[a]};
        const gcp_spl_v8 U = {u[a], u[a], u1[a], u[a], u1[a], u11[a], u[a], u1[a]};
        const gcp_spl_v8 W3 = {dw0[a], w0[a], 0, 0, 0, 0, 0, 0};
        const gcp_spl_v8 U3 = {u11[a], u111[a], 0, 0, 0, 0, 0, 0};
        acc += W * U;
        acc3 += W3 * U3;
    }
    gcp_spl_out8(o, c0, &acc);
    ddd[0] = acc[6], ddd[1] = acc[7], ddd[2] = acc3[0], ddd[3] = acc3[1];
}

#endif
