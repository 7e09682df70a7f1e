/* Unit tests of the `igrf` model (fields/igrf.c) with the IGRF-14 table
 * fields/data/igrf14coeffs.txt.
 *
 * Tolerances, derived here.
 *
 * (I1) Dipole terms.  With nmax = 1 the field is a centred dipole of moment
 *   along -(g11, h11, g10): |B| = B0 = sqrt(g10^2 + g11^2 + h11^2) on the
 *   dipole equator at r = a and 2 B0 at the dipole poles; ~30 roundings:
 *   TOL 1e-13 relative.
 *
 * (I2) Published values.  The geocentric test table of
 *   JuliaSpace/SatelliteToolboxGeomagneticField.jl (test/IGRF14_test_
 *   geocentric.txt), produced with IAGA's own Fortran program igrf14syn:
 *   date, r [km], colatitude, east longitude [deg], X (north), Y (east),
 *   Z (down) [nT], printed to 1e-5 nT.  Asserted within 1 nT (the brief).
 *   igrf14syn keeps its coefficient arrays in default (single precision)
 *   REALs, 7 digits of ~5e4 nT: differences of ~1e-2 nT are expected and
 *   measured (9.5e-3 nT, logged).
 *
 * (I3) Independent evaluation: the same series with GSL's Schmidt
 *   Legendre functions and their derivatives (gsl_sf_legendre_deriv_array_e,
 *   no Condon-Shortley phase) and the textbook B_r = -dV/dr,
 *   B_theta = -(1/r) dV/dtheta, B_phi = -(1/(r sin theta)) dV/dphi: two
 *   different recurrences summing ~100 terms of alternating sign whose
 *   sizes are <= 3 |B| (the dipole dominates): agreement to ~1e-13 of |B|
 *   expected; TOL 1e-9 relative (the figure).
 *
 * (I4) grad B against centred differences with step d = 1e-4 r:
 *   truncation d^2/6 |B'''| <= d^2/6 * (n+1)(n+2)(n+3) |B|/r^3 with n <= 13
 *   (degree-n terms vary as r^-(n+2)): 1e-8/6 * 4080 |B|/r = 7e-6 |B|/r for
 *   the highest degree, whose share of |B| at r >= a is < 1e-3: so
 *   < 1e-8 |B|/r in all; round-off eps |B| / d = 2e-12 |B|/r.  TOL 1e-7 of
 *   S = |grad B|_F + |B|/r.
 *
 * (I5) curl B = 0 and div B = 0: grad B = -Q H Q^T with H symmetric by
 *   construction, so the antisymmetric part is round-off (~1e-15 of
 *   |grad B|); the trace is the spherical Laplacian of V evaluated term by
 *   term, sums of <= 100 terms each <= ~3 |grad B|: TOL 1e-12 |grad B|_F.
 */
#include <criterion/criterion.h>
#include <gsl/gsl_sf_legendre.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/field.h"
#include "gcpush/grid.h"
#include "gcpush/particles.h"

#define IGRF_FILE "fields/data/igrf14coeffs.txt"
#define A_REF 6371.2e3
#define DEG (GCP_PI / 180.0)

static struct gcp_igrf_coeffs coeffs(double epoch)
{
    struct gcp_igrf_coeffs c;
    struct gcp_error err = {0, ""};
    int rc = gcp_igrf_coeffs_at(IGRF_FILE, epoch, &c, &err);
    cr_assert_eq(rc, 0, "%s", err.msg);
    return c;
}

static int eval_bg(const struct gcp_field *f, const double x[3], struct gcp_field_sample *s)
{
    memset(s, 0, sizeof *s);
    s->need = GCP_NEED_B | GCP_NEED_GRADB;
    return gcp_field_eval(f, 0.0, x, s);
}

static double norm3(const double v[3]) { return sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }
static double frob(const double g[3][3])
{
    double s = 0.0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) s += g[i][j] * g[i][j];
    return sqrt(s);
}

static void sph_to_cart(double r, double colat, double elon, double x[3])
{
    x[0] = r * sin(colat) * cos(elon);
    x[1] = r * sin(colat) * sin(elon);
    x[2] = r * cos(colat);
}

/* (X north, Y east, Z down) of a Cartesian B at colatitude th, longitude ph */
static void to_xyz_local(const double B[3], double th, double ph, double out[3])
{
    const double er[3] = {sin(th) * cos(ph), sin(th) * sin(ph), cos(th)};
    const double et[3] = {cos(th) * cos(ph), cos(th) * sin(ph), -sin(th)};
    const double ep[3] = {-sin(ph), cos(ph), 0.0};
    const double Br = B[0] * er[0] + B[1] * er[1] + B[2] * er[2];
    const double Bt = B[0] * et[0] + B[1] * et[1] + B[2] * et[2];
    const double Bp = B[0] * ep[0] + B[1] * ep[1] + B[2] * ep[2];
    out[0] = -Bt, out[1] = Bp, out[2] = -Br;
}

static uint64_t lcg = 7u;
static double urand(double lo, double hi)
{
    lcg = lcg * 6364136223846793005ull + 1442695040888963407ull;
    return lo + (hi - lo) * (double)(lcg >> 11) * (1.0 / 9007199254740992.0);
}

Test(igrf, table_values_and_epoch_rules)
{
    struct gcp_igrf_coeffs c = coeffs(2020.0);
    cr_assert_eq(c.nmax, 13);
    cr_assert_float_eq(c.g[1][0], -29403.41e-9, 1e-16);
    cr_assert_float_eq(c.g[1][1], -1451.37e-9, 1e-16);
    cr_assert_float_eq(c.h[1][1], 4653.35e-9, 1e-16);
    /* linear interpolation between 2020.0 and 2025.0 */
    struct gcp_igrf_coeffs c25 = coeffs(2025.0), cm = coeffs(2022.5);
    cr_assert_float_eq(c25.g[1][0], -29350.0e-9, 1e-16);
    for (int n = 1; n <= 13; n++)
        for (int m = 0; m <= n; m++) {
            cr_assert_float_eq(cm.g[n][m], 0.5 * (c.g[n][m] + c25.g[n][m]), 1e-18);
            cr_assert_float_eq(cm.h[n][m], 0.5 * (c.h[n][m] + c25.h[n][m]), 1e-18);
        }
    /* after 2025: secular variation, g10 SV = +12.6 nT/yr */
    struct gcp_igrf_coeffs c27 = coeffs(2027.0);
    cr_assert_float_eq(c27.g[1][0], (-29350.0 + 2.0 * 12.6) * 1e-9, 1e-16);
    /* 1900 edge and refusals */
    struct gcp_igrf_coeffs c00 = coeffs(1900.0);
    cr_assert_float_eq(c00.g[1][0], -31543e-9, 1e-16);
    struct gcp_error err = {0, ""};
    cr_assert_lt(gcp_igrf_coeffs_at(IGRF_FILE, 1899.9, &c, &err), 0);
    cr_assert_not_null(strstr(err.msg, "outside"), "%s", err.msg);
    cr_assert_not_null(strstr(err.msg, "1900.0 .. 2030.0"), "%s", err.msg);
    struct gcp_error e2 = {0, ""};
    cr_assert_lt(gcp_igrf_coeffs_at(IGRF_FILE, 2030.1, &c, &e2), 0);
    struct gcp_error e3 = {0, ""};
    cr_assert_lt(gcp_igrf_coeffs_at("/nonexistent/igrf.txt", 2020.0, &c, &e3), 0);
    cr_assert_not_null(strstr(e3.msg, "/nonexistent/igrf.txt"), "%s", e3.msg);
}

/* (I1) */
Test(igrf, degree_one_is_the_tilted_dipole)
{
    struct gcp_igrf_coeffs c = coeffs(2020.0);
    struct gcp_field *f = gcp_field_igrf_create(&c, 1, 0.0, INFINITY);
    const double g10 = c.g[1][0], g11 = c.g[1][1], h11 = c.h[1][1];
    const double B0 = sqrt(g10 * g10 + g11 * g11 + h11 * h11);
    cr_assert_float_eq(B0, 29805e-9, 1e-9, "B0 = %.3f nT", B0 * 1e9);
    /* dipole axis: the moment is along (g11, h11, g10) (southward, g10 < 0);
     * m = -(g11, h11, g10)/B0 points to the geomagnetic north pole */
    const double m[3] = {-g11 / B0, -h11 / B0, -g10 / B0};
    /* two unit vectors perpendicular to m */
    double e1[3] = {m[1], -m[0], 0.0};
    const double n1 = norm3(e1);
    for (int i = 0; i < 3; i++) e1[i] /= n1;
    const double e2[3] = {m[1] * e1[2] - m[2] * e1[1], m[2] * e1[0] - m[0] * e1[2],
                          m[0] * e1[1] - m[1] * e1[0]};
    for (int k = 0; k < 12; k++) {
        const double a = 2.0 * GCP_PI * k / 12.0;
        double x[3];
        for (int i = 0; i < 3; i++) x[i] = A_REF * (cos(a) * e1[i] + sin(a) * e2[i]);
        struct gcp_field_sample s;
        eval_bg(f, x, &s);
        cr_assert_float_eq(norm3(s.B) / B0, 1.0, 1e-13, "|B| on the dipole equator %.6f nT",
                           norm3(s.B) * 1e9);
    }
    double xp[3];
    for (int i = 0; i < 3; i++) xp[i] = A_REF * m[i];
    struct gcp_field_sample s;
    eval_bg(f, xp, &s);
    cr_assert_float_eq(norm3(s.B) / B0, 2.0, 1e-13);
    cr_log_info("IGRF 2020 degree 1: B0 = %.3f nT; geomagnetic north pole (-moment direction) "
                "at colatitude %.3f deg, east longitude %.3f deg",
                B0 * 1e9, acos(m[2]) / DEG, atan2(m[1], m[0]) / DEG);
    gcp_field_free(f);
}

/* (I2) rows of IGRF14_test_geocentric.txt (JuliaSpace, from igrf14syn) */
static const double published[][7] = {
    /* date, r km, colat, elong, X, Y, Z [nT] */
    {1900.0, 6610.46, 68.00, 165.11, 27405.59329, 3074.66838, 17132.54518},
    {1949.3, 6738.43, 89.92, 55.30, 28321.59739, -1639.20107, -9689.29713},
    {1965.7, 7836.25, 81.83, 21.80, 16945.03391, -1451.88229, -218.15707},
    {1985.1, 7386.16, 0.05, 0.32, 664.68242, -1268.46751, 37518.62935},
    {1996.3, 7182.31, 60.09, 245.54, 17479.90924, 3436.58553, 26985.73892},
    {2012.2, 6455.32, 4.81, 190.69, 716.25521, 404.85533, 54898.32179},
    {2019.6, 7239.98, 41.70, 23.47, 14510.71642, 1050.50604, 30315.14930},
    {2027.9, 6518.00, 45.06, 138.29, 23401.96250, -4296.86589, 42525.97951},
};

Test(igrf, matches_published_igrf14syn_values)
{
    double worst = 0.0;
    for (size_t k = 0; k < sizeof published / sizeof published[0]; k++) {
        const double *row = published[k];
        struct gcp_igrf_coeffs c = coeffs(row[0]);
        struct gcp_field *f = gcp_field_igrf_create(&c, 0, 0.0, INFINITY);
        const double th = row[2] * DEG, ph = row[3] * DEG;
        double x[3], loc[3];
        sph_to_cart(row[1] * 1e3, th, ph, x);
        struct gcp_field_sample s;
        eval_bg(f, x, &s);
        to_xyz_local(s.B, th, ph, loc);
        for (int i = 0; i < 3; i++) {
            const double d = fabs(loc[i] * 1e9 - row[4 + i]);
            worst = fmax(worst, d);
            cr_assert_lt(d, 1.0, "%.1f r=%.2f km colat %.2f lon %.2f: %c = %.5f nT, published %.5f",
                         row[0], row[1], row[2], row[3], "XYZ"[i], loc[i] * 1e9, row[4 + i]);
        }
        gcp_field_free(f);
    }
    cr_log_info("IGRF against igrf14syn (8 points, 1900 .. 2027.9): max |difference| %.2e nT",
                worst);
}

/* (I3) */
static void gsl_field(const struct gcp_igrf_coeffs *c, double r, double th, double ph,
                      double Bsph[3])
{
    const int L = c->nmax;
    const size_t n = gsl_sf_legendre_array_n((size_t)L);
    double P[n], dP[n];
    const double x = cos(th);
    cr_assert_eq(gsl_sf_legendre_deriv_array_e(GSL_SF_LEGENDRE_SCHMIDT, (size_t)L, x, 1.0, P, dP), 0);
    double Vr = 0, Vt = 0, Vp = 0;
    for (int l = 1; l <= L; l++) {
        const double A = A_REF * pow(A_REF / r, l + 1);
        for (int m = 0; m <= l; m++) {
            const size_t i = gsl_sf_legendre_array_index((size_t)l, (size_t)m);
            const double T = c->g[l][m] * cos(m * ph) + c->h[l][m] * sin(m * ph);
            const double Tp = m * (-c->g[l][m] * sin(m * ph) + c->h[l][m] * cos(m * ph));
            Vr += -(l + 1) / r * A * T * P[i];
            Vt += A * T * (-sin(th)) * dP[i];
            Vp += A * Tp * P[i];
        }
    }
    Bsph[0] = -Vr, Bsph[1] = -Vt / r, Bsph[2] = -Vp / (r * sin(th));
}

Test(igrf, matches_an_independent_gsl_evaluation)
{
    struct gcp_igrf_coeffs c = coeffs(2020.0);
    struct gcp_field *f = gcp_field_igrf_create(&c, 0, 0.0, INFINITY);
    double worst = 0.0;
    for (int k = 0; k < 50; k++) {
        const double r = urand(1.0, 6.0) * A_REF, th = urand(0.05, GCP_PI - 0.05),
                     ph = urand(-GCP_PI, GCP_PI);
        double x[3], Bs[3];
        sph_to_cart(r, th, ph, x);
        struct gcp_field_sample s;
        eval_bg(f, x, &s);
        gsl_field(&c, r, th, ph, Bs);
        double loc[3];
        to_xyz_local(s.B, th, ph, loc); /* (-B_theta, B_phi, -B_r) */
        const double mine[3] = {-loc[2], -loc[0], loc[1]};
        const double d[3] = {mine[0] - Bs[0], mine[1] - Bs[1], mine[2] - Bs[2]};
        const double rel = norm3(d) / norm3(Bs);
        worst = fmax(worst, rel);
        cr_assert_lt(rel, 1e-9, "relative difference %.3e at r = %g, theta = %g, phi = %g", rel, r,
                     th, ph);
    }
    cr_log_info("IGRF against GSL Schmidt Legendre evaluation: max relative difference %.2e",
                worst);
    gcp_field_free(f);
}

/* (I4), (I5) */
Test(igrf, gradB_is_consistent_curl_and_divergence_free)
{
    struct gcp_igrf_coeffs c = coeffs(2015.3);
    struct gcp_field *f = gcp_field_igrf_create(&c, 0, 0.0, INFINITY);
    double worst_fd = 0, worst_sym = 0, worst_div = 0;
    for (int k = 0; k < 60; k++) {
        /* include points within 1 degree of the geographic poles */
        const double th = k < 4 ? (k % 2 ? GCP_PI - 0.01 : 0.01) : urand(0.02, GCP_PI - 0.02);
        const double r = urand(1.0, 5.0) * A_REF, ph = urand(-GCP_PI, GCP_PI);
        double x[3];
        sph_to_cart(r, th, ph, x);
        struct gcp_field_sample s, sp, sm;
        eval_bg(f, x, &s);
        const double g = frob(s.gradB), S = g + norm3(s.B) / r, d = 1e-4 * r;
        for (int j = 0; j < 3; j++) {
            double xp[3] = {x[0], x[1], x[2]}, xm[3] = {x[0], x[1], x[2]};
            xp[j] += d;
            xm[j] -= d;
            eval_bg(f, xp, &sp);
            eval_bg(f, xm, &sm);
            for (int i = 0; i < 3; i++) {
                const double fd = (sp.B[i] - sm.B[i]) / (xp[j] - xm[j]);
                const double e = fabs(fd - s.gradB[i][j]) / S;
                worst_fd = fmax(worst_fd, e);
                cr_assert_lt(e, 1e-7, "dB%d/dx%d: %g vs %g (theta %g)", i, j, s.gradB[i][j], fd, th);
            }
        }
        for (int i = 0; i < 3; i++)
            for (int j = i + 1; j < 3; j++) {
                const double a = fabs(s.gradB[i][j] - s.gradB[j][i]) / g;
                worst_sym = fmax(worst_sym, a);
                cr_assert_lt(a, 1e-12, "curl B (%d,%d) = %g of |grad B|", i, j, a);
            }
        const double div = fabs(s.gradB[0][0] + s.gradB[1][1] + s.gradB[2][2]) / g;
        worst_div = fmax(worst_div, div);
        cr_assert_lt(div, 1e-12, "div B = %g of |grad B| at theta %g", div, th);
    }
    cr_log_info("IGRF grad B: max FD mismatch %.2e of S, max |curl B| %.2e, max |div B| %.2e of "
                "|grad B|",
                worst_fd, worst_sym, worst_div);
    gcp_field_free(f);
}
