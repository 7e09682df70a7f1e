/* The tensor-product spline core shared by the gridded models (grid.c,
 * eqdsk.c) and the flux chart's table (src/pushers/canon_flux_num.c,
 * canon_flux_table.c): the interpolants, their error
 * orders and the storage layout are described in grid_priv.h. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_linalg.h>

#include "grid_priv.h"
#include "spl_inline.h"

/* ---- spline core -------------------------------------------------------- */

/* Interpolating cubic B-spline of one grid line: f[0..n-1] with stride fs
 * in, coefficients c[-1..n] (n + 2 values, stride cs) out; tmp has n
 * doubles.  Equations in grid_priv.h; the Thomas algorithm on
 *   row 0:    4 c0 + 2 c1          = 6 f0 + 2 hd0
 *   row i:    c_{i-1} + 4 c_i + c_{i+1} = 6 f_i
 *   row n-1:  2 c_{n-2} + 4 c_{n-1}    = 6 f_{n-1} - 2 hd1
 * then c_{-1} = c1 - 2 hd0, c_n = c_{n-2} + 2 hd1 (the clamped slopes). */
static void spl_line(size_t n, const double *f, size_t fs, double *c, size_t cs, double *tmp)
{
#define F(i) f[(size_t)(i) * fs]
#define C(i) c[(size_t)((i) + 1) * cs]
    const double hd0 = (-25.0 * F(0) + 48.0 * F(1) - 36.0 * F(2) + 16.0 * F(3) - 3.0 * F(4)) / 12.0;
    const double hd1 = (25.0 * F(n - 1) - 48.0 * F(n - 2) + 36.0 * F(n - 3) - 16.0 * F(n - 4) +
                        3.0 * F(n - 5)) / 12.0;
    /* forward sweep: tmp = modified super-diagonal, C(i) = modified rhs */
    double beta = 4.0;
    tmp[0] = 2.0 / beta;
    C(0) = (6.0 * F(0) + 2.0 * hd0) / beta;
    for (size_t i = 1; i < n; i++) {
        const double sub = (i == n - 1) ? 2.0 : 1.0;
        const double sup = 1.0;
        const double rhs = (i == n - 1) ? 6.0 * F(n - 1) - 2.0 * hd1 : 6.0 * F(i);
        beta = 4.0 - sub * tmp[i - 1];
        tmp[i] = sup / beta;
        C(i) = (rhs - sub * C(i - 1)) / beta;
    }
    for (size_t i = n - 1; i-- > 0;) C(i) -= tmp[i] * C(i + 1);
    C(-1) = C(1) - 2.0 * hd0;
    C((long)n) = C(n - 2) + 2.0 * hd1;
#undef F
#undef C
}

/* The interpolating quintic B-spline of one grid line (grid_priv.h): f[0..n-1]
 * (stride fs) in, c[-2..n+1] (n + 4 values, stride cs) out, with the LU of
 * the line's (n + 4)^2 matrix (spl5_matrix) given.  Unknowns in the order
 * c_{-2} .. c_{n+1}; rows: h^2 f''(0), h f'(0), the n interpolation rows,
 * h f'(n-1), h^2 f''(n-1); the end values are 7-point one-sided differences
 *   h f'(0)    = (-147 f0 + 360 f1 - 450 f2 + 400 f3 - 225 f4 + 72 f5 - 10 f6) / 60,
 *   h^2 f''(0) = (812 f0 - 3132 f1 + 5265 f2 - 5080 f3 + 2970 f4 - 972 f5 + 137 f6) / 180,
 * mirrored (f' with the opposite sign) at the other end.  The spline's own
 *   h f'(x_i)    = (-c_{i-2} - 10 c_{i-1} + 10 c_{i+1} + c_{i+2}) / 24,
 *   h^2 f''(x_i) = (c_{i-2} + 2 c_{i-1} - 6 c_i + 2 c_{i+1} + c_{i+2}) / 6. */
static void spl5_matrix(size_t n, gsl_matrix *A)
{
    const size_t N = n + 4;
    gsl_matrix_set_zero(A);
    static const double d2[5] = {1.0 / 6, 2.0 / 6, -1.0, 2.0 / 6, 1.0 / 6};
    static const double d1[5] = {-1.0 / 24, -10.0 / 24, 0.0, 10.0 / 24, 1.0 / 24};
    static const double v[5] = {1.0 / 120, 26.0 / 120, 66.0 / 120, 26.0 / 120, 1.0 / 120};
    for (size_t k = 0; k < 5; k++) {
        gsl_matrix_set(A, 0, k, d2[k]);
        gsl_matrix_set(A, 1, k, d1[k]);
        gsl_matrix_set(A, N - 2, n - 1 + k, d1[k]);
        gsl_matrix_set(A, N - 1, n - 1 + k, d2[k]);
        for (size_t i = 0; i < n; i++) gsl_matrix_set(A, i + 2, i + k, v[k]);
    }
}

static void spl5_line(size_t n, const double *f, double *c, size_t cs, const gsl_matrix *LU,
                      const gsl_permutation *perm, gsl_vector *rhs)
{
    static const double e1[7] = {-147.0 / 60, 360.0 / 60, -450.0 / 60, 400.0 / 60,
                                 -225.0 / 60, 72.0 / 60,  -10.0 / 60};
    static const double e2[7] = {812.0 / 180,  -3132.0 / 180, 5265.0 / 180, -5080.0 / 180,
                                 2970.0 / 180, -972.0 / 180,  137.0 / 180};
    double a1 = 0, a2 = 0, b1 = 0, b2 = 0;
    for (size_t k = 0; k < 7; k++) {
        a1 += e1[k] * f[k], a2 += e2[k] * f[k];
        b1 -= e1[k] * f[n - 1 - k], b2 += e2[k] * f[n - 1 - k];
    }
    const size_t N = n + 4;
    gsl_vector_set(rhs, 0, a2);
    gsl_vector_set(rhs, 1, a1);
    for (size_t i = 0; i < n; i++) gsl_vector_set(rhs, i + 2, f[i]);
    gsl_vector_set(rhs, N - 2, b1);
    gsl_vector_set(rhs, N - 1, b2);
    gsl_linalg_LU_svx(LU, perm, rhs);
    for (size_t k = 0; k < N; k++) c[k * cs] = gsl_vector_get(rhs, k);
}

/* The interpolating septic B-spline of one grid line (grid_priv.h), the
 * quintic's construction one degree pair up: f[0..n-1] in, c[-3..n+2]
 * (n + 6 values, stride cs) out, with the LU of the line's (n + 6)^2 matrix
 * (spl7_matrix) given.  Unknowns c_{-3} .. c_{n+2}; rows: h^3 f'''(0),
 * h^2 f''(0), h f'(0), the n interpolation rows, h f'(n-1), h^2 f''(n-1),
 * h^3 f'''(n-1).  The spline's own values at node i, on c_{i-3} .. c_{i+3}
 * (the septic B-spline and its derivatives at the integers):
 *   f         = (1, 120, 1191, 2416, 1191, 120, 1) / 5040,
 *   h f'      = (-1, -56, -245, 0, 245, 56, 1) / 720,
 *   h^2 f''   = (1, 24, 15, -80, 15, 24, 1) / 120,
 *   h^3 f'''  = (-1, -8, 19, 0, -19, 8, 1) / 24.
 * The end values are the 9-point one-sided differences, exact for degree 8
 * (the weights solve sum_j a_j j^p = k! [p = k], p = 0..8; Fornberg, Math.
 * Comp. 51 (1988) 699), so each h^k f^(k) is O(h^9) accurate, like the
 * spline's value:
 *   h f'(0)     = (-761/280, 8, -14, 56/3, -35/2, 56/5, -14/3, 8/7, -1/8) . f[0..8],
 *   h^2 f''(0)  = (29531/5040, -962/35, 621/10, -4006/45, 691/8, -282/5, 2143/90,
 *                  -206/35, 363/560) . f[0..8],
 *   h^3 f'''(0) = (-801/80, 349/6, -18353/120, 2391/10, -1457/6, 4891/30, -561/8,
 *                  527/30, -469/240) . f[0..8],
 * mirrored at the other end (the odd derivatives with the opposite sign). */
static void spl7_matrix(size_t n, gsl_matrix *A)
{
    const size_t N = n + 6;
    gsl_matrix_set_zero(A);
    static const double d3[7] = {-1.0 / 24, -8.0 / 24, 19.0 / 24, 0.0,
                                 -19.0 / 24, 8.0 / 24, 1.0 / 24};
    static const double d2[7] = {1.0 / 120,  24.0 / 120, 15.0 / 120, -80.0 / 120,
                                 15.0 / 120, 24.0 / 120, 1.0 / 120};
    static const double d1[7] = {-1.0 / 720,  -56.0 / 720, -245.0 / 720, 0.0,
                                 245.0 / 720, 56.0 / 720,  1.0 / 720};
    static const double v[7] = {1.0 / 5040,    120.0 / 5040, 1191.0 / 5040, 2416.0 / 5040,
                                1191.0 / 5040, 120.0 / 5040, 1.0 / 5040};
    for (size_t k = 0; k < 7; k++) {
        gsl_matrix_set(A, 0, k, d3[k]);
        gsl_matrix_set(A, 1, k, d2[k]);
        gsl_matrix_set(A, 2, k, d1[k]);
        gsl_matrix_set(A, N - 3, n - 1 + k, d1[k]);
        gsl_matrix_set(A, N - 2, n - 1 + k, d2[k]);
        gsl_matrix_set(A, N - 1, n - 1 + k, d3[k]);
        for (size_t i = 0; i < n; i++) gsl_matrix_set(A, i + 3, i + k, v[k]);
    }
}

static void spl7_line(size_t n, const double *f, double *c, size_t cs, const gsl_matrix *LU,
                      const gsl_permutation *perm, gsl_vector *rhs)
{
    static const double e1[9] = {-761.0 / 280, 8.0,       -14.0,   56.0 / 3, -35.0 / 2,
                                 56.0 / 5,     -14.0 / 3, 8.0 / 7, -1.0 / 8};
    static const double e2[9] = {29531.0 / 5040, -962.0 / 35, 621.0 / 10,
                                 -4006.0 / 45,   691.0 / 8,   -282.0 / 5,
                                 2143.0 / 90,    -206.0 / 35, 363.0 / 560};
    static const double e3[9] = {-801.0 / 80, 349.0 / 6,   -18353.0 / 120,
                                 2391.0 / 10, -1457.0 / 6, 4891.0 / 30,
                                 -561.0 / 8,  527.0 / 30,  -469.0 / 240};
    double a1 = 0, a2 = 0, a3 = 0, b1 = 0, b2 = 0, b3 = 0;
    for (size_t k = 0; k < 9; k++) {
        a1 += e1[k] * f[k], a2 += e2[k] * f[k], a3 += e3[k] * f[k];
        b1 -= e1[k] * f[n - 1 - k], b2 += e2[k] * f[n - 1 - k], b3 -= e3[k] * f[n - 1 - k];
    }
    const size_t N = n + 6;
    gsl_vector_set(rhs, 0, a3);
    gsl_vector_set(rhs, 1, a2);
    gsl_vector_set(rhs, 2, a1);
    for (size_t i = 0; i < n; i++) gsl_vector_set(rhs, i + 3, f[i]);
    gsl_vector_set(rhs, N - 3, b1);
    gsl_vector_set(rhs, N - 2, b2);
    gsl_vector_set(rhs, N - 1, b3);
    gsl_linalg_LU_svx(LU, perm, rhs);
    for (size_t k = 0; k < N; k++) c[k * cs] = gsl_vector_get(rhs, k);
}

void gcp_spl_free(struct gcp_spl *s)
{
    if (!s) return;
    for (int c = 0; c < GCP_SPL_MAXCOMP; c++) {
        free(s->coef[c]);
        s->coef[c] = NULL;
    }
}

int gcp_spl_build(struct gcp_spl *s, int nd, int kind, const size_t n[], const double x0[],
                  const double h[], int ncomp, const double *const data[], struct gcp_error *err)
{
    memset(s, 0, sizeof *s);
    if (nd < 1 || nd > 3 || ncomp < 1 || ncomp > GCP_SPL_MAXCOMP)
        return gcp_error_set(err, GCP_ERR_STATE, "spline: bad dimensions");
    s->nd = nd;
    s->kind = kind;
    s->ncomp = ncomp;
    if (kind < GCP_SPL_CUBIC || kind > GCP_SPL_SEPTIC)
        return gcp_error_set(err, GCP_ERR_STATE, "spline: bad kind %d", kind);
    static const size_t nmins[] = {5, 2, 7, 9}, pads[] = {2, 0, 4, 6};
    const size_t nmin = nmins[kind], pad = pads[kind];
    static const char *const kname[] = {"cubic", "linear", "quintic", "septic"};
    size_t total = 1, stride = 1;
    for (int a = 0; a < 3; a++) {
        if (a < nd) {
            if (n[a] < nmin)
                return gcp_error_set(err, GCP_ERR_VALUE,
                                     "axis %d has %zu nodes; %s interpolation needs at least %zu",
                                     a, n[a], kname[kind], nmin);
            if (!(h[a] > 0.0 && isfinite(h[a]) && isfinite(x0[a])))
                return gcp_error_set(err, GCP_ERR_VALUE,
                                     "axis %d: spacing must be positive and finite, got %g", a,
                                     h[a]);
            s->n[a] = n[a];
            s->m[a] = n[a] + pad;
            s->x0[a] = x0[a];
            s->h[a] = h[a];
            s->inv_h[a] = 1.0 / h[a];
            s->umax[a] = (double)(n[a] - 1);
        } else {
            s->n[a] = s->m[a] = 1;
        }
        s->stride[a] = stride;
        stride *= s->m[a];
        total *= s->m[a];
    }
    const size_t nmax = s->m[0] > s->m[1] ? (s->m[0] > s->m[2] ? s->m[0] : s->m[2])
                                          : (s->m[1] > s->m[2] ? s->m[1] : s->m[2]);
    double *tmp = malloc(nmax * sizeof *tmp);
    double *line = malloc(nmax * sizeof *line);
    if (!tmp || !line) goto nomem;
    for (int c = 0; c < ncomp; c++) {
        double *co = s->coef[c] = calloc(total, sizeof(double));
        if (!co) goto nomem;
        const double *d = data[c];
        const size_t o = pad / 2; /* offset of node 0 in the padded array */
        const size_t o1 = nd > 1 ? o : 0, o2 = nd > 2 ? o : 0;
        for (size_t k = 0; k < s->n[2]; k++)
            for (size_t j = 0; j < s->n[1]; j++)
                for (size_t i = 0; i < s->n[0]; i++)
                    co[(i + o) + s->stride[1] * (j + o1) + s->stride[2] * (k + o2)] =
                        d[i + s->n[0] * (j + s->n[1] * k)];
        if (kind == GCP_SPL_LINEAR) continue;
        /* axis by axis; before pass a, axes > a hold data only at interior
         * (node) positions, axes < a everywhere */
        for (int a = 0; a < nd; a++) {
            const size_t na = s->n[a], sa = s->stride[a];
            size_t lo[3], hi[3];
            for (int b = 0; b < 3; b++) {
                const int padded = b < nd && b != a;
                lo[b] = (padded && b > a) ? o : 0;
                hi[b] = (padded && b > a) ? s->n[b] + o : s->m[b];
                if (b == a) lo[b] = 0, hi[b] = 1;
            }
            gsl_matrix *A = NULL;
            gsl_permutation *perm = NULL;
            gsl_vector *rhs = NULL;
            if (kind == GCP_SPL_QUINTIC || kind == GCP_SPL_SEPTIC) {
                int sgn;
                A = gsl_matrix_alloc(na + pad, na + pad);
                perm = gsl_permutation_alloc(na + pad);
                rhs = gsl_vector_alloc(na + pad);
                if (!A || !perm || !rhs) {
                    if (A) gsl_matrix_free(A);
                    if (perm) gsl_permutation_free(perm);
                    if (rhs) gsl_vector_free(rhs);
                    goto nomem;
                }
                if (kind == GCP_SPL_QUINTIC)
                    spl5_matrix(na, A);
                else
                    spl7_matrix(na, A);
                gsl_linalg_LU_decomp(A, perm, &sgn);
            }
            for (size_t k = lo[2]; k < hi[2]; k++)
                for (size_t j = lo[1]; j < hi[1]; j++)
                    for (size_t i = lo[0]; i < hi[0]; i++) {
                        double *p = co + i * s->stride[0] + j * s->stride[1] + k * s->stride[2];
                        for (size_t q = 0; q < na; q++) line[q] = p[(q + o) * sa];
                        if (kind == GCP_SPL_SEPTIC)
                            spl7_line(na, line, p, sa, A, perm, rhs);
                        else if (A)
                            spl5_line(na, line, p, sa, A, perm, rhs);
                        else
                            spl_line(na, line, 1, p, sa, tmp);
                    }
            if (A) {
                gsl_matrix_free(A);
                gsl_permutation_free(perm);
                gsl_vector_free(rhs);
            }
        }
    }
    free(tmp);
    free(line);
    return 0;
nomem:
    free(tmp);
    free(line);
    gcp_spl_free(s);
    return gcp_error_set(err, GCP_ERR_NOMEM, "spline: out of memory");
}

int gcp_spl_locate(const struct gcp_spl *s, const double *x, int order, struct gcp_spl_loc *loc)
{
    int out = 0;
    size_t base = 0;
    for (int a = 0; a < s->nd; a++) {
        size_t off;
        double t;
        out |= gcp_spl_cell(s, a, x[a], &off, &t);
        base += off;
        double *w = loc->w[a], *dw = loc->dw[a], *ddw = loc->ddw[a];
        const double ih = s->inv_h[a];
        if (s->kind == GCP_SPL_CUBIC) {
            const double t2 = t * t, t3 = t2 * t, omt = 1.0 - t;
            w[0] = omt * omt * omt / 6.0;
            w[1] = (3.0 * t3 - 6.0 * t2 + 4.0) / 6.0;
            w[2] = (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) / 6.0;
            w[3] = t3 / 6.0;
            if (order >= 1) {
                dw[0] = -0.5 * omt * omt * ih;
                dw[1] = (1.5 * t2 - 2.0 * t) * ih;
                dw[2] = (-1.5 * t2 + t + 0.5) * ih;
                dw[3] = 0.5 * t2 * ih;
            }
            if (order >= 2) {
                const double ih2 = ih * ih;
                ddw[0] = omt * ih2;
                ddw[1] = (3.0 * t - 2.0) * ih2;
                ddw[2] = (1.0 - 3.0 * t) * ih2;
                ddw[3] = t * ih2;
            }
        } else if (s->kind == GCP_SPL_QUINTIC) {
            gcp_spl_w5(t, ih, order, w, dw, ddw);
        } else if (s->kind == GCP_SPL_SEPTIC) {
            gcp_spl_w7(t, ih, order, w, dw, ddw);
        } else {
            w[0] = 1.0 - t;
            w[1] = t;
            w[2] = w[3] = 0.0;
            dw[0] = -ih;
            dw[1] = ih;
            dw[2] = dw[3] = 0.0;
            for (int k = 0; k < 4; k++) ddw[k] = 0.0;
        }
    }
    loc->base = base;
    return out;
}

/* (the sums less c0: see spl_inline.h) */
void gcp_spl_eval(const struct gcp_spl *s, const struct gcp_spl_loc *loc, int c, int order,
                  struct gcp_spl_out *o)
{
    if (s->kind == GCP_SPL_SEPTIC && s->nd == 2) {
        gcp_spl2_eval8(s->coef[c] + loc->base, s->stride[1], loc->w[0], loc->dw[0], loc->ddw[0],
                       loc->w[1], loc->dw[1], loc->ddw[1], order, o);
        return;
    }
    const int K = s->kind == GCP_SPL_SEPTIC    ? 8
                  : s->kind == GCP_SPL_QUINTIC ? 6
                  : s->kind == GCP_SPL_CUBIC   ? 4
                                               : 2;
    const double *co = s->coef[c] + loc->base;
    const double c0 = co[0];
    if (s->nd == 1) {
        double f = 0, d = 0, dd = 0;
        for (int a = 0; a < K; a++) {
            const double ca = co[a] - c0;
            f += loc->w[0][a] * ca;
            d += loc->dw[0][a] * ca;
            dd += loc->ddw[0][a] * ca;
        }
        o->f = c0 + f;
        o->d[0] = d;
        o->dd[0][0] = dd;
        return;
    }
    if (s->nd == 2) {
        gcp_spl2_eval_k(K, co, s->stride[1], loc->w[0], loc->dw[0], loc->ddw[0], loc->w[1],
                        loc->dw[1], loc->ddw[1], order, o);
        return;
    }
    /* 3D: contract axis 0, then 1, then 2 (second derivatives not needed) */
    const size_t s1 = s->stride[1], s2 = s->stride[2];
    double f = 0, d0 = 0, d1 = 0, d2 = 0;
    for (int k = 0; k < K; k++) {
        double g = 0, g0 = 0, g1 = 0;
        for (int b = 0; b < K; b++) {
            const double *rr = co + b * s1 + k * s2;
            double r[8];
            for (int a = 0; a < K; a++) r[a] = rr[a] - c0;
            double v = 0, v0 = 0;
            for (int a = 0; a < K; a++) v += loc->w[0][a] * r[a];
            g += loc->w[1][b] * v;
            if (order >= 1) {
                for (int a = 0; a < K; a++) v0 += loc->dw[0][a] * r[a];
                g0 += loc->w[1][b] * v0;
                g1 += loc->dw[1][b] * v;
            }
        }
        f += loc->w[2][k] * g;
        if (order >= 1) {
            d0 += loc->w[2][k] * g0;
            d1 += loc->w[2][k] * g1;
            d2 += loc->dw[2][k] * g;
        }
    }
    o->f = c0 + f;
    o->d[0] = d0;
    o->d[1] = d1;
    o->d[2] = d2;
}

double gcp_spl1_eval(const struct gcp_spl *s, int c, double u, double *du, double *ddu)
{
    struct gcp_spl_loc loc;
    struct gcp_spl_out o;
    o.dd[0][0] = 0.0; /* set by the 1D branch; the compiler cannot see that nd is 1 */
    const double x = s->x0[0] + u * s->h[0];
    gcp_spl_locate(s, &x, 2, &loc);
    gcp_spl_eval(s, &loc, c, 2, &o);
    if (du) *du = o.d[0] * s->h[0];
    if (ddu) *ddu = o.dd[0][0] * s->h[0] * s->h[0];
    return o.f;
}
