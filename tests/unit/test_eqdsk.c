/* Unit tests of the `eqdsk` model (fields/eqdsk.c) on the shipped DIII-D
 * equilibrium fields/data/diiid_184833.geqdsk (65 x 65, COCOS 7) and on a
 * synthetic g-file written here with run-together negative numbers.
 *
 * Tolerances, derived here.
 *
 * (E1) div B.  B_R = -(1/R) psi_Z, B_Z = (1/R) psi_R from one bicubic
 *   spline, B_phi = F(psi)/R: the cylindrical divergence is
 *   (-psi_ZR + psi_RZ)/R + 0 and psi_RZ, psi_ZR are the same sum of
 *   products of spline weights; only the Cartesian assembly rounds
 *   (~20 operations on terms <= |grad B|_F): TOL_DIV = 1e-12 |grad B|_F.
 *
 * (E2) grad B against centred differences of B with step d = 1e-4 h,
 *   h = 0.0266 m: as (G2) in test_grid.c, 1e-6 of S = |grad B|_F + |B|/h.
 *   Only at points inside the plasma away from the boundary, where F(psi)
 *   is smooth (at the last closed surface dF/dpsi jumps to 0).
 *
 * (E3) q from field-line tracing against the file's qpsi: the file's q is
 *   EFIT's own flux-surface integral on its (finer, internal) representation;
 *   our psi is a bicubic spline of the 65 x 65 psirz, whose relative error
 *   in grad psi is O((h/a)^3) ~ (0.027/0.6)^3 = 1e-4, and the tracing (RK4,
 *   800 steps per toroidal turn) is exact to ~1e-9.  The brief's 1% is a
 *   wide margin over both; measured differences are logged.
 *
 * (E4) Canonical toroidal momentum of a full orbit (Boris), p_phi = q psi +
 *   m R u_phi (psi = R A_phi).  The exact motion keeps it (the field is
 *   exactly axisymmetric: the spline lives in (R, Z)).  Boris keeps |u|; its
 *   gyro-phase error (theta = 2 atan(w dt/2) per step instead of w dt) is
 *   harmless, since every point of an exact gyration has the same p_phi.
 *   What changes p_phi is the O((w dt)^2) distortion of the discrete orbit
 *   by the field's variation across it, a displacement ~ (w dt)^2/12 rho
 *   (rho/L) across grad psi; with q |grad psi| = q R B_pol and rho = m v/(qB):
 *     |dp_phi| ~ (w dt)^2/12 (B_pol/B) (rho/L) m v R.
 *   Here B_pol/B <= 0.3, rho/L <= 0.03 (rho = 1 cm for a 10 keV deuteron at
 *   2 T, L ~ 0.3 m the scale of psi), so the estimate is 7.5e-4 (w dt)^2 m v R.
 *   Asserted: max |dp_phi| <= K (w dt)^2 m v R with K = 2e-3, second-order
 *   scaling (halving dt divides it by 4 +- 1.5), and the same maximum in the
 *   first and the second half of the run (no secular drift: ratio < 2).
 *   Boris is time-reversible and volume-preserving, so the error is a
 *   bounded oscillation.
 */
#include <criterion/criterion.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "fo_test_util.h"
#include "gcpush/error.h"
#include "gcpush/field.h"
#include "gcpush/grid.h"
#include "gcpush/particles.h"
#include "gcpush/pusher.h"

#define GFILE "fields/data/diiid_184833.geqdsk"
#define TOL_DIV 1e-12
#define TOL_FD 1e-6

static struct gcp_field *load(void)
{
    struct gcp_field *f = NULL;
    struct gcp_error err = {0, ""};
    int rc = gcp_field_eqdsk_load(GFILE, 0, &f, &err);
    cr_assert_eq(rc, 0, "%s", err.msg);
    return f;
}

static double frob(const double g[3][3])
{
    double s = 0.0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) s += g[i][j] * g[i][j];
    return sqrt(s);
}

static int eval_bg(const struct gcp_field *f, const double x[3], struct gcp_field_sample *s)
{
    memset(s, 0, sizeof *s);
    s->need = GCP_NEED_B | GCP_NEED_GRADB;
    return gcp_field_eval(f, 0.0, x, s);
}

static double psiN_at(const struct gcp_field *f, const struct gcp_eqdsk_info *in, double R,
                      double Z)
{
    double psi;
    const double x[3] = {R, 0, Z};
    gcp_field_psi(f, x, &psi);
    /* gcp_field_psi is s_pol psi_file with s_pol = +1 for COCOS 7 */
    return (psi - in->simag) / (in->sibry - in->simag);
}

/* R on the outboard midplane Z = zmaxis where psi_N = target (bisection). */
static double R_of_psiN(const struct gcp_field *f, const struct gcp_eqdsk_info *in, double t)
{
    double a = in->rmaxis, b = in->rmaxis + 0.55;
    for (int k = 0; k < 80; k++) {
        const double m = 0.5 * (a + b);
        if (psiN_at(f, in, m, in->zmaxis) < t)
            a = m;
        else
            b = m;
    }
    return 0.5 * (a + b);
}

static uint64_t lcg = 42u;
static double urand(double lo, double hi)
{
    lcg = lcg * 6364136223846793005ull + 1442695040888963407ull;
    return lo + (hi - lo) * (double)(lcg >> 11) * (1.0 / 9007199254740992.0);
}

Test(eqdsk, reads_the_diiid_file_and_identifies_cocos_7)
{
    struct gcp_field *f = load();
    struct gcp_eqdsk_info in;
    cr_assert_eq(gcp_field_eqdsk_info(f, &in), 0);
    cr_assert_eq(in.nw, 65);
    cr_assert_eq(in.nh, 65);
    cr_assert_eq(in.cocos, 7, "COCOS %d", in.cocos);
    cr_assert_float_eq(in.rmaxis, 1.76355052, 1e-8);
    cr_assert_float_eq(in.current, -1.08213512e6, 1.0);
    cr_assert_float_eq(in.zbmin, -1.162, 2e-3);
    /* at the axis: B_phi = fpol(0)/rmaxis = -3.51735/1.76355 = -1.9945 T (README),
     * B_pol ~ 0 (the spline's axis is within a fraction of a cell of rmaxis) */
    const double x[3] = {in.rmaxis, 0, in.zmaxis};
    struct gcp_field_sample s;
    cr_assert_eq(eval_bg(f, x, &s), 0);
    cr_assert_float_eq(s.B[1], -1.9945, 1e-3, "B_phi on axis %g", s.B[1]);
    cr_assert_lt(hypot(s.B[0], s.B[2]), 0.01, "B_pol on axis %g T", hypot(s.B[0], s.B[2]));
    /* COCOS 7 with I_p < 0: B_Z > 0 on the outboard midplane (current along -phi) */
    const double xo[3] = {in.rmaxis + 0.3, 0, in.zmaxis};
    eval_bg(f, xo, &s);
    cr_assert_gt(s.B[2], 0.0, "outboard B_Z = %g", s.B[2]);
    /* Ampere around a flux surface recovers the sign of the current */
    cr_assert_float_eq(gcp_field_eqdsk_q(f, 0.0), 2.09, 0.01);
    /* outside the grid */
    const double xx[3] = {3.0, 0, 0};
    cr_assert_eq(eval_bg(f, xx, &s), GCP_LEFT_GRID);
    gcp_field_free(f);
}

Test(eqdsk, divergence_free_and_gradB_consistent)
{
    struct gcp_field *f = load();
    struct gcp_eqdsk_info in;
    gcp_field_eqdsk_info(f, &in);
    const double h = in.rdim / (in.nw - 1);
    int n = 0;
    double divmax = 0.0;
    while (n < 200) {
        const double R = urand(1.1, 2.3), Z = urand(-1.0, 1.0), ph = urand(-3, 3);
        const double pn = psiN_at(f, &in, R, Z);
        if (!(pn > 0.02 && pn < 0.95)) continue;
        n++;
        const double x[3] = {R * cos(ph), R * sin(ph), Z};
        struct gcp_field_sample s, sp, sm;
        cr_assert_eq(eval_bg(f, x, &s), 0);
        const double g = frob(s.gradB), div = s.gradB[0][0] + s.gradB[1][1] + s.gradB[2][2];
        divmax = fmax(divmax, fabs(div) / g);
        cr_assert_leq(fabs(div), TOL_DIV * g, "div B = %g at R=%g Z=%g (|grad B| %g)", div, R, Z, g);
        const double d = 1e-4 * h;
        for (int j = 0; j < 3; j++) {
            double xp[3] = {x[0], x[1], x[2]}, xm[3] = {x[0], x[1], x[2]};
            xp[j] += d;
            xm[j] -= d;
            eval_bg(f, xp, &sp);
            eval_bg(f, xm, &sm);
            for (int i = 0; i < 3; i++) {
                const double fd = (sp.B[i] - sm.B[i]) / (xp[j] - xm[j]);
                cr_assert_leq(fabs(fd - s.gradB[i][j]), TOL_FD * (g + fo_norm(s.B) / h),
                              "dB%d/dx%d: %g vs %g", i, j, s.gradB[i][j], fd);
            }
        }
    }
    cr_log_info("eqdsk: max |div B| / |grad B| over 200 points: %.2e", divmax);
    gcp_field_free(f);
}

/* Field line in the toroidal angle: dR/dphi = R B_R / B_phi, dZ/dphi =
 * R B_Z / B_phi (phi = atan2(y, x); the line advances in phi with the sign
 * of B_phi, irrelevant for |q|).  RK4 in phi. */
static void fl_rhs(const struct gcp_field *f, const double y[2], double d[2])
{
    const double x[3] = {y[0], 0, y[1]};
    struct gcp_field_sample s;
    memset(&s, 0, sizeof s);
    s.need = GCP_NEED_B;
    gcp_field_eval(f, 0, x, &s);
    d[0] = y[0] * s.B[0] / s.B[1];
    d[1] = y[0] * s.B[2] / s.B[1];
}

static double q_traced(const struct gcp_field *f, const struct gcp_eqdsk_info *in, double R0)
{
    double y[2] = {R0, in->zmaxis}, th = 0.0, phi = 0.0;
    const double h = 2.0 * GCP_PI / 800.0;
    double th_prev = atan2(y[1] - in->zmaxis, y[0] - in->rmaxis);
    for (int k = 0; k < 800 * 20; k++) {
        double k1[2], k2[2], k3[2], k4[2], t[2];
        fl_rhs(f, y, k1);
        for (int i = 0; i < 2; i++) t[i] = y[i] + 0.5 * h * k1[i];
        fl_rhs(f, t, k2);
        for (int i = 0; i < 2; i++) t[i] = y[i] + 0.5 * h * k2[i];
        fl_rhs(f, t, k3);
        for (int i = 0; i < 2; i++) t[i] = y[i] + h * k3[i];
        fl_rhs(f, t, k4);
        double yn[2];
        for (int i = 0; i < 2; i++) yn[i] = y[i] + h / 6.0 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
        const double thn = atan2(yn[1] - in->zmaxis, yn[0] - in->rmaxis);
        double dth = thn - th_prev;
        dth -= 2.0 * GCP_PI * round(dth / (2.0 * GCP_PI));
        if (fabs(th + dth) >= 2.0 * GCP_PI) { /* one poloidal turn within this step */
            const double w = (2.0 * GCP_PI - fabs(th)) / fabs(dth);
            return (phi + w * h) / (2.0 * GCP_PI);
        }
        th += dth, th_prev = thn, phi += h;
        y[0] = yn[0], y[1] = yn[1];
    }
    cr_assert_fail("field line did not close a poloidal turn");
    return NAN;
}

Test(eqdsk, q_from_field_line_tracing_matches_qpsi)
{
    struct gcp_field *f = load();
    struct gcp_eqdsk_info in;
    gcp_field_eqdsk_info(f, &in);
    const double targets[3] = {0.3, 0.5, 0.8};
    for (int k = 0; k < 3; k++) {
        const double R0 = R_of_psiN(f, &in, targets[k]);
        const double qt = q_traced(f, &in, R0), qf = gcp_field_eqdsk_q(f, targets[k]);
        cr_log_info("eqdsk q at psi_N = %.1f (R = %.4f m): traced %.5f, file %.5f, rel. "
                    "difference %.2e",
                    targets[k], R0, qt, qf, qt / qf - 1.0);
        cr_assert_lt(fabs(qt / qf - 1.0), 0.01, "psi_N %.1f: q traced %g, file %g", targets[k],
                     qt, qf);
    }
    gcp_field_free(f);
}

/* (E4) */
struct pphi_acc {
    const struct gcp_field *f;
    double q, m, p0, maxdev[2];
    int64_t n, N;
};

static double pphi_of(const struct pphi_acc *a, const double x[3], const double u[3])
{
    double psi;
    gcp_field_psi(a->f, x, &psi);
    return a->q * psi + a->m * (x[0] * u[1] - x[1] * u[0]); /* m R u_phi = m (x u_y - y u_x) */
}

static int pphi_cb(double t, const double x[3], const double u[3], void *ctx)
{
    (void)t;
    struct pphi_acc *a = ctx;
    const double d = fabs(pphi_of(a, x, u) - a->p0);
    const int half = a->n * 2 >= a->N;
    if (d > a->maxdev[half]) a->maxdev[half] = d;
    a->n++;
    return 0;
}

static void run_pphi(const struct gcp_field *f, const struct gcp_eqdsk_info *in, double xi,
                     double wdt, double nsteps_at_w1, double out[3])
{
    const double m = 2.013553 * GCP_AMU, q = GCP_E_CHARGE, T = 10e3 * GCP_E_CHARGE;
    const double u = fo_u_of_ekin(T, m);
    const double X[3] = {R_of_psiN(f, in, 0.5), 0, in->zmaxis};
    struct gcp_field_sample s;
    memset(&s, 0, sizeof s);
    s.need = GCP_NEED_B;
    gcp_field_eval(f, 0, X, &s);
    const double Bm = fo_norm(s.B), b[3] = {s.B[0] / Bm, s.B[1] / Bm, s.B[2] / Bm};
    double e[3];
    const double Rh[3] = {1, 0, 0};
    fo_cross(b, Rh, e);
    const double en = fo_norm(e);
    double uv[3], x[3];
    for (int i = 0; i < 3; i++) uv[i] = u * (xi * b[i] + sqrt(1 - xi * xi) * e[i] / en);
    cr_assert_eq(fo_place_at_gc(f, q, m, X, uv, x), 0);
    const double wc = q * Bm / (m * fo_gamma(uv));
    const double dt = wdt / wc;
    struct pphi_acc a = {f, q, m, 0, {0, 0}, 0, 0};
    a.p0 = pphi_of(&a, x, uv);
    a.N = (int64_t)(nsteps_at_w1 / wdt);
    double t = 0;
    const int st = gcp_orbit_push(f, &gcp_pusher_boris, q, m, &t, x, uv, dt, a.N, pphi_cb, &a);
    cr_assert_eq(st, 0, "status %d", st);
    const double scale = wdt * wdt * m * u * X[0];
    out[0] = fmax(a.maxdev[0], a.maxdev[1]) / scale; /* in units of (w dt)^2 m v R */
    out[1] = a.maxdev[0];
    out[2] = a.maxdev[1];
}

Test(eqdsk, full_orbit_keeps_canonical_toroidal_momentum)
{
    struct gcp_field *f = load();
    struct gcp_eqdsk_info in;
    gcp_field_eqdsk_info(f, &in);
    /* trapped (v_par/v = 0.15 at the outboard midplane, psi_N = 0.5) and
     * passing (0.9); 2 x 10^4 gyro-radians at w dt = 0.2: a few bounces */
    const double xis[2] = {0.15, 0.9};
    for (int k = 0; k < 2; k++) {
        double r1[3], r2[3];
        run_pphi(f, &in, xis[k], 0.2, 2e4, r1);
        run_pphi(f, &in, xis[k], 0.1, 2e4, r2);
        const double ratio = r1[0] * 0.04 / (r2[0] * 0.01);
        cr_log_info("eqdsk p_phi (v_par/v = %.2f): max |dp_phi| / ((w dt)^2 m v R) = %.3e at "
                    "w dt = 0.2, %.3e at 0.1; dt^2 ratio %.2f; halves %.3g / %.3g",
                    xis[k], r1[0], r2[0], ratio, r2[1], r2[2]);
        cr_assert_lt(r1[0], 2e-3);
        cr_assert_lt(r2[0], 2e-3);
        cr_assert(ratio > 2.5 && ratio < 5.5, "p_phi error ratio %.2f for dt/2, expected 4", ratio);
        cr_assert_lt(r2[2], 2.0 * r2[1], "secular drift: %g then %g", r2[1], r2[2]);
    }
    gcp_field_free(f);
}

/* ---- a synthetic g-file ----------------------------------------------------- */

/* Writes a 33 x 33 g-file with format (5e16.9): negative numbers fill all
 * 16 columns and run together ("-1.000000000e-01-5.500000000e-02"), which a
 * reader splitting on white space gets wrong.  psi = c ((R - 1.5)^2 + Z^2)
 * - 0.1, F = 3 T m, current > 0, bcentr > 0, q > 0 and psi increasing:
 * COCOS 1, where B_pol = grad(phi) x grad(psi):
 *   B_R = (1/R) dpsi/dZ = 2 c Z / R,  B_Z = -(1/R) dpsi/dR = -2 c (R - 1.5)/R.
 * psi is quadratic, so the bicubic spline reproduces it exactly (G1 of
 * test_grid.c), but the file keeps 10 significant digits: psi (~0.1) is
 * rounded by <= 5e-11, and B_pol, a derivative over h = 1/32 m (the
 * spline's derivative weights sum to ~2/h in magnitude), by <= 5e-11 * 64
 * / R = 3e-9 T: TOL 1e-8 T.  trunc > 0 cuts the file after that many
 * psirz values; garbage puts letters into one field. */
static const char *write_gfile(const char *name, int trunc, int garbage)
{
    static char path[512];
    snprintf(path, sizeof path, "/tmp/gcp_eqdsk_%ld_%s", (long)getpid(), name);
    FILE *fp = fopen(path, "w");
    cr_assert_not_null(fp);
    const int n = 33;
    const double c = 0.5, rleft = 1.0, rdim = 1.0, zdim = 1.2;
    fprintf(fp, "%-48s%4d%4d%4d\n", "  SYNTHETIC test 0", 3, n, n);
    double hdr[20] = {rdim, zdim, 1.5, rleft, 0.0, 1.5, 0.0, -0.1, -0.055, 2.0,
                      1e6, -0.1, -1.0, 1.5, -1.0, 0.0, -1.0, -0.055, -1.0, -1.0};
    int col = 0;
#define PUT(v)                                                \
    do {                                                      \
        fprintf(fp, "%16.9e", (v));                           \
        if (++col == 5) fprintf(fp, "\n"), col = 0;           \
    } while (0)
#define END() do { if (col) fprintf(fp, "\n"); col = 0; } while (0)
    for (int i = 0; i < 20; i++) PUT(hdr[i]);
    END();
    for (int i = 0; i < n; i++) PUT(3.0);                     /* fpol */
    END();
    for (int i = 0; i < n; i++) PUT(1e4 * (1.0 - i / 32.0));  /* pres */
    END();
    for (int i = 0; i < n; i++) PUT(-0.5);                    /* ffprim */
    END();
    for (int i = 0; i < n; i++) PUT(-2e4);                    /* pprime */
    END();
    int k = 0;
    for (int j = 0; j < n && !(trunc && k >= trunc); j++)
        for (int i = 0; i < n && !(trunc && k >= trunc); i++, k++) {
            const double R = rleft + rdim * i / (n - 1), Z = -0.6 + zdim * j / (n - 1);
            if (garbage && k == 100) {
                fprintf(fp, "   x.y00000000e+00");
                if (++col == 5) fprintf(fp, "\n"), col = 0;
                continue;
            }
            PUT(c * ((R - 1.5) * (R - 1.5) + Z * Z) - 0.1);
        }
    END();
    if (!trunc) {
        for (int i = 0; i < n; i++) PUT(1.0 + 2.0 * i / 32.0); /* qpsi */
        END();
        fprintf(fp, "%5d%5d\n", 4, 0);
        const double bb[8] = {1.2, 0.0, 1.5, 0.3, 1.8, 0.0, 1.5, -0.3};
        for (int i = 0; i < 8; i++) PUT(bb[i]);
        END();
    }
#undef PUT
#undef END
    fclose(fp);
    return path;
}

Test(eqdsk, synthetic_file_run_together_numbers_and_cocos_1)
{
    const char *p = write_gfile("ok.geqdsk", 0, 0);
    FILE *fp = fopen(p, "r");
    char line[256];
    cr_assert_not_null(fgets(line, sizeof line, fp));
    cr_assert_not_null(fgets(line, sizeof line, fp));
    cr_assert_not_null(fgets(line, sizeof line, fp));
    cr_assert_not_null(strstr(line, "e-01-5.5"), "numbers run together: %s", line);
    fclose(fp);
    struct gcp_field *f = NULL;
    struct gcp_error err = {0, ""};
    cr_assert_eq(gcp_field_eqdsk_load(p, 0, &f, &err), 0, "%s", err.msg);
    struct gcp_eqdsk_info in;
    gcp_field_eqdsk_info(f, &in);
    cr_assert_eq(in.cocos, 1, "COCOS %d", in.cocos);
    cr_assert_float_eq(in.simag, -0.1, 1e-15);
    cr_assert_float_eq(in.sibry, -0.055, 1e-15);
    for (int t = 0; t < 50; t++) {
        const double R = urand(1.05, 1.95), Z = urand(-0.5, 0.5), ph = urand(-3, 3);
        const double x[3] = {R * cos(ph), R * sin(ph), Z};
        struct gcp_field_sample s;
        cr_assert_eq(eval_bg(f, x, &s), 0);
        const double bR = 2 * 0.5 * Z / R, bZ = -2 * 0.5 * (R - 1.5) / R, bp = 3.0 / R;
        const double want[3] = {bR * cos(ph) - bp * sin(ph), bR * sin(ph) + bp * cos(ph), bZ};
        for (int i = 0; i < 3; i++)
            cr_assert_leq(fabs(s.B[i] - want[i]), 1e-8, "B%d: %.16g vs %.16g", i, s.B[i],
                          want[i]);
    }
    gcp_field_free(f);
    /* the same file read as COCOS 3 (sigma_Bp = -1): B_pol reverses */
    cr_assert_eq(gcp_field_eqdsk_load(p, 3, &f, &err), 0, "%s", err.msg);
    const double x[3] = {1.8, 0, 0.0};
    struct gcp_field_sample s;
    eval_bg(f, x, &s);
    cr_assert_float_eq(s.B[2], 2 * 0.5 * 0.3 / 1.8, 1e-8);
    gcp_field_free(f);
    remove(p);
}

Test(eqdsk, malformed_files_are_refused)
{
    struct gcp_field *f = NULL;
    struct gcp_error err = {0, ""};
    cr_assert_lt(gcp_field_eqdsk_load("/nonexistent/g.eqdsk", 0, &f, &err), 0);
    cr_assert_not_null(strstr(err.msg, "/nonexistent/g.eqdsk: cannot open"), "%s", err.msg);
    const char *p = write_gfile("trunc.geqdsk", 500, 0);
    struct gcp_error e2 = {0, ""};
    cr_assert_lt(gcp_field_eqdsk_load(p, 0, &f, &e2), 0);
    cr_assert_null(f);
    cr_assert_not_null(strstr(e2.msg, "psirz"), "%s", e2.msg);
    cr_assert_not_null(strstr(e2.msg, p), "%s", e2.msg);
    remove(p);
    p = write_gfile("garbage.geqdsk", 0, 1);
    struct gcp_error e3 = {0, ""};
    cr_assert_lt(gcp_field_eqdsk_load(p, 0, &f, &e3), 0);
    cr_assert_not_null(strstr(e3.msg, "cannot read a number"), "%s", e3.msg);
    cr_assert_not_null(strstr(e3.msg, "psirz"), "%s", e3.msg);
    remove(p);
}
