/* The spline core (fields/spline.c, grid_priv.h): the septic kind that
 * G-EQDSK psi, F(psi) and the flux chart's table use, against closed forms.
 *   Reproduction: the septic interpolant reproduces every polynomial of
 *   degree <= 7 (its space holds them, and the 9-point end differences are
 *   exact for degree 8), so value, first and second derivatives of a
 *   degree-7 tensor polynomial come back to round-off; the quintic does not
 *   (degree 5: the same test fails it).
 *   Order: the value error of an interpolating spline of odd degree k is
 *   O(h^(k+1)), the j-th derivative's O(h^(k+1-j)).  Halving h divides the
 *   septic's errors by 2^8, 2^7, 2^6. */
#include <criterion/criterion.h>
#include <math.h>
#include <string.h>

#include "grid_priv.h"

/* p(x) q(y) + x^7 / 7 - y^6 / 3 + x y: a 2D polynomial of degree 7 per axis */
static void poly7(double x, double y, double *f, double d[2], double dd[3])
{
    const double p = 1 - x + 0.5 * x * x * x - 0.2 * pow(x, 7);
    const double px = -1 + 1.5 * x * x - 1.4 * pow(x, 6), pxx = 3 * x - 8.4 * pow(x, 5);
    const double q = 2 + y * y - 0.3 * pow(y, 5) + 0.1 * pow(y, 7);
    const double qy = 2 * y - 1.5 * pow(y, 4) + 0.7 * pow(y, 6), qyy = 2 - 6 * y * y * y + 4.2 * pow(y, 5);
    *f = p * q + pow(x, 7) / 7 - pow(y, 6) / 3 + x * y;
    d[0] = px * q + pow(x, 6) + y;
    d[1] = p * qy - 2 * pow(y, 5) + x;
    dd[0] = pxx * q + 6 * pow(x, 5);
    dd[1] = px * qy + 1;
    dd[2] = p * qyy - 10 * pow(y, 4);
}

/* Worst error of value, d, dd (each relative to the field's max of that
 * quantity) of a 2D spline of kind over [-1, 1.2] x [-0.9, 1.1] with n x n
 * nodes, at 997 points. */
static void poly_error(int kind, size_t n, double err[3])
{
    const double x0[2] = {-1.0, -0.9}, h[2] = {2.2 / (double)(n - 1), 2.0 / (double)(n - 1)};
    double *v = malloc(n * n * sizeof *v);
    for (size_t j = 0; j < n; j++)
        for (size_t i = 0; i < n; i++) {
            double d[2], dd[3];
            poly7(x0[0] + (double)i * h[0], x0[1] + (double)j * h[1], &v[i + n * j], d, dd);
        }
    struct gcp_spl s;
    struct gcp_error e = {0};
    const size_t nn[2] = {n, n};
    const double *data[1] = {v};
    cr_assert_eq(gcp_spl_build(&s, 2, kind, nn, x0, h, 1, data, &e), 0, "%s", e.msg);
    double emax[3] = {0, 0, 0}, fmax_[3] = {0, 0, 0};
    for (int k = 0; k < 997; k++) {
        const double x[2] = {x0[0] + 2.2 * fmod(0.6180339887 * k, 1.0),
                             x0[1] + 2.0 * fmod(0.7548776662 * k + 0.1, 1.0)};
        struct gcp_spl_loc loc;
        struct gcp_spl_out o;
        cr_assert_eq(gcp_spl_locate(&s, x, 2, &loc), 0);
        gcp_spl_eval(&s, &loc, 0, 2, &o);
        double f, d[2], dd[3];
        poly7(x[0], x[1], &f, d, dd);
        emax[0] = fmax(emax[0], fabs(o.f - f));
        emax[1] = fmax(emax[1], fmax(fabs(o.d[0] - d[0]), fabs(o.d[1] - d[1])));
        emax[2] = fmax(emax[2], fmax(fmax(fabs(o.dd[0][0] - dd[0]), fabs(o.dd[0][1] - dd[1])),
                                     fabs(o.dd[1][1] - dd[2])));
        fmax_[0] = fmax(fmax_[0], fabs(f));
        fmax_[1] = fmax(fmax_[1], fmax(fabs(d[0]), fabs(d[1])));
        fmax_[2] = fmax(fmax_[2], fmax(fmax(fabs(dd[0]), fabs(dd[1])), fabs(dd[2])));
    }
    for (int a = 0; a < 3; a++) err[a] = emax[a] / fmax_[a];
    gcp_spl_free(&s);
    free(v);
}

/* Septic: round-off of the LU solve and of the sums, ~1e-15 of the value
 * times the conditioning of the end rows (the 9-point weights reach 2.4e2)
 * and h^-j for the j-th derivative: measured 1.8e-15, 3.8e-14, 2.0e-13 at
 * n = 12 (h ~ 0.2); bounds 1e-13, 1e-12, 1e-11.  The quintic on the same
 * data: measured 1.1e-4, 3.3e-3, 1.4e-2; > 1e-8 asserted. */
Test(spline, septic_reproduces_degree_7)
{
    double e7[3], e5[3];
    poly_error(GCP_SPL_SEPTIC, 12, e7);
    poly_error(GCP_SPL_QUINTIC, 12, e5);
    cr_log_info("degree-7 polynomial, 12 x 12 nodes: septic errors %.1e %.1e %.1e, quintic %.1e "
                "%.1e %.1e (value, d, dd; relative)",
                e7[0], e7[1], e7[2], e5[0], e5[1], e5[2]);
    cr_expect_lt(e7[0], 1e-13);
    cr_expect_lt(e7[1], 1e-12);
    cr_expect_lt(e7[2], 1e-11);
    for (int a = 0; a < 3; a++) cr_expect_gt(e5[a], 1e-8, "quintic reproduced degree 7 (%d)", a);
}

/* 1D: f = sin(3x) + exp(x/2) on [0, 2], n = 21 and 41 nodes: worst errors
 * of f, f', f'' over 2001 points, their ratios against 2^8, 2^7, 2^6 within
 * 20% (the h^2-relative next terms, largest in the end cells whose
 * one-sided data carry larger constants, still show at n = 21; measured
 * 271, 138, 70). */
Test(spline, septic_order_8)
{
    double err[2][3];
    for (int r = 0; r < 2; r++) {
        const size_t n = r ? 41 : 21;
        const double h = 2.0 / (double)(n - 1), x0 = 0.0;
        double *v = malloc(n * sizeof *v);
        for (size_t i = 0; i < n; i++) {
            const double x = (double)i * h;
            v[i] = sin(3 * x) + exp(0.5 * x);
        }
        struct gcp_spl s;
        struct gcp_error e = {0};
        const double *data[1] = {v};
        cr_assert_eq(gcp_spl_build(&s, 1, GCP_SPL_SEPTIC, &n, &x0, &h, 1, data, &e), 0, "%s",
                     e.msg);
        err[r][0] = err[r][1] = err[r][2] = 0;
        for (int k = 0; k <= 2000; k++) {
            const double x = 2.0 * k / 2000.0;
            double du, ddu;
            const double f = gcp_spl1_eval(&s, 0, x / h, &du, &ddu);
            err[r][0] = fmax(err[r][0], fabs(f - sin(3 * x) - exp(0.5 * x)));
            err[r][1] = fmax(err[r][1], fabs(du / h - 3 * cos(3 * x) - 0.5 * exp(0.5 * x)));
            err[r][2] = fmax(err[r][2], fabs(ddu / (h * h) + 9 * sin(3 * x) - 0.25 * exp(0.5 * x)));
        }
        gcp_spl_free(&s);
        free(v);
    }
    const double want[3] = {256, 128, 64};
    for (int a = 0; a < 3; a++) {
        const double ratio = err[0][a] / err[1][a];
        cr_log_info("septic 1D: derivative %d error %.2e -> %.2e, ratio %.1f (want %.0f)", a,
                    err[0][a], err[1][a], ratio, want[a]);
        cr_expect(fabs(ratio / want[a] - 1) < 0.2, "derivative %d: ratio %.1f, want %.0f", a,
                  ratio, want[a]);
    }
}

/* Fewer than 9 nodes on an axis: refused, naming the kind. */
Test(spline, septic_needs_9_nodes)
{
    double v[8] = {0};
    const size_t n = 8;
    const double x0 = 0.0, h = 1.0;
    const double *data[1] = {v};
    struct gcp_spl s;
    struct gcp_error e = {0};
    cr_expect_eq(gcp_spl_build(&s, 1, GCP_SPL_SEPTIC, &n, &x0, &h, 1, data, &e), GCP_ERR_VALUE);
    cr_expect(strstr(e.msg, "septic") != NULL, "%s", e.msg);
}
