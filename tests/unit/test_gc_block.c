/* gc-rk4 over struct-of-arrays blocks (issue 12) against an independent
 * scalar RK4 written here on the kernels.h right-hand side (gcp_gc_rhs_at,
 * one field evaluation per point): the block pusher rearranges the
 * right-hand side (2 square roots and 1 division per lane instead of 2 and
 * 8) and evaluates the field in blocks, so the two agree to round-off, not
 * bit for bit.
 *
 * Tolerance.  Each right-hand-side evaluation differs by a few ulp (~1e-15
 * relative); over NSTEPS = 300 steps of a bounded, smooth orbit the
 * differences add (4 evaluations a step) and are at most mildly amplified by
 * the phase shear of a bounce-drift orbit over ~1 bounce: 300 x 4 x 1e-15 =
 * 1.2e-12, tolerance 1e-10 of the orbit scale (|X| for positions, the
 * momentum for p_par).  A real error (a wrong stage weight, offset or term)
 * is O(h) or O(1) relative, 1e-4 or more.  Fields: the dipole (vectorised
 * block evaluation), the corotating dipole (E), the tokamak (domain status),
 * and the mirror; and a lane outside the tokamak retires with LEFT_DOMAIN
 * at the start, as the scalar path says. */
#include <criterion/criterion.h>

#include "gcpush/field_kernels.h"
#include "test_gc_util.h"
#include "pushers/block_priv.h"
#include "pushers/gc_priv.h"

#define NSTEPS 300
#define NL 37 /* lanes: not a multiple of a vector width or of the chunk */
#define TOL 1e-10

static void scalar_rk4(const struct gcp_field *f, double q, double m, double dt, int nsteps,
                       double X[3], double *ppar, double mu)
{
    for (int k = 0; k < nsteps; k++) {
        const double t = k * dt;
        double y0[4] = {X[0], X[1], X[2], *ppar}, kk[4][4], y[4];
        double dX[3], dp;
        gcp_gc_rhs_at(f, t, q, m, X, *ppar, mu, dX, &dp);
        for (int d = 0; d < 3; d++) kk[0][d] = dX[d];
        kk[0][3] = dp;
        static const double c[3] = {0.5, 0.5, 1.0};
        for (int s = 0; s < 3; s++) {
            for (int d = 0; d < 4; d++) y[d] = y0[d] + c[s] * dt * kk[s][d];
            gcp_gc_rhs_at(f, t + c[s] * dt, q, m, y, y[3], mu, dX, &dp);
            for (int d = 0; d < 3; d++) kk[s + 1][d] = dX[d];
            kk[s + 1][3] = dp;
        }
        for (int d = 0; d < 4; d++)
            y0[d] += dt / 6.0 * (kk[0][d] + 2.0 * kk[1][d] + 2.0 * kk[2][d] + kk[3][d]);
        X[0] = y0[0], X[1] = y0[1], X[2] = y0[2], *ppar = y0[3];
    }
}

/* NL lanes around X0 (spread by `spread` [m] in x and z), kinetic energy T,
 * pitch angles 30..80 deg at the start point; dt [s]. */
static void check_field(const struct gcp_field *f, const char *name, const double X0[3],
                        double spread, double T, double dt, int outside_lane)
{
    const double q = GCP_E_CHARGE, m = GCP_M_PROTON, p = gc_p_of_T(T, m);
    struct gcp_block b;
    cr_assert_eq(gcp_block_alloc(&b, NL), 0);
    b.q = q, b.m = m;
    double X[NL][3], P[NL], MU[NL];
    for (int i = 0; i < NL; i++) {
        const double a = (30.0 + 50.0 * i / (NL - 1)) * GCP_PI / 180.0;
        X[i][0] = X0[0] + spread * (i % 5) / 5.0;
        X[i][1] = X0[1];
        X[i][2] = X0[2] + spread * (i % 3) / 7.0;
        if (i == outside_lane) X[i][0] += 100.0; /* far outside any domain */
        const double B = gc_Bmag(f, X[i]);
        P[i] = p * cos(a);
        MU[i] = (p * sin(a)) * (p * sin(a)) / (2.0 * m * B);
        b.x[i] = X[i][0], b.y[i] = X[i][1], b.z[i] = X[i][2];
        b.ppar[i] = P[i], b.mu[i] = MU[i];
    }
    b.n_active = NL;
    const struct gcp_push_opts o = {0.0, dt, NSTEPS, 0.0, 0.0};
    const size_t live = gcp_pusher_gc_rk4.advance(&b, f, &gcp_pusher_gc_rk4, &o, NULL);
    cr_assert_eq(live, (size_t)(outside_lane >= 0 ? NL - 1 : NL), "%s: %zu live", name, live);
    for (size_t l = 0; l < NL; l++) {
        const size_t i = b.index[l];
        if ((int)i == outside_lane) {
            cr_assert_eq(b.status[l], GCP_LEFT_DOMAIN, "%s: outside lane status %d", name,
                         b.status[l]);
            cr_assert_eq(b.steps[l], 0);
            continue;
        }
        cr_assert_eq(b.status[l], GCP_ALIVE, "%s: lane %zu status %d", name, i, b.status[l]);
        scalar_rk4(f, q, m, dt, NSTEPS, X[i], &P[i], MU[i]);
        const double scale = sqrt(X[i][0] * X[i][0] + X[i][1] * X[i][1] + X[i][2] * X[i][2]);
        const double got[3] = {b.x[l], b.y[l], b.z[l]};
        for (int d = 0; d < 3; d++)
            cr_assert_leq(fabs(got[d] - X[i][d]), TOL * scale,
                          "%s: lane %zu X%d block %.17g scalar %.17g", name, i, d, got[d],
                          X[i][d]);
        cr_assert_leq(fabs(b.ppar[l] - P[i]), TOL * p, "%s: lane %zu p_par block %.17g scalar %.17g",
                      name, i, b.ppar[l], P[i]);
    }
    gcp_block_free(&b);
}

Test(gc_block, rk4_block_equals_scalar_rk4)
{
    const double MeV = 1e6 * GCP_E_CHARGE;
    /* dipole, 1 MeV protons at L = 4 (+0.5), dt = 1/1000 of the bounce period (~6.7 s) */
    struct gcp_field *dip = gcp_field_dipole_create(GC_B0, 0, GC_RE + 100e3, 15.0 * GC_RE);
    check_field(dip, "dipole", (const double[3]){4.0 * GC_RE, 0.0, 0.0}, 0.5 * GC_RE, MeV, 6.7e-3,
                -1);
    gcp_field_free(dip);
    struct gcp_field *cor = gcp_field_dipole_create(GC_B0, 1, GC_RE + 100e3, 15.0 * GC_RE);
    check_field(cor, "dipole+corotation", (const double[3]){4.0 * GC_RE, 0.0, 0.0}, 0.5 * GC_RE,
                MeV, 6.7e-3, -1);
    gcp_field_free(cor);
    /* tokamak R0 = 3 m, a = 1 m, 10 keV protons at R = 3.3 m; one lane outside */
    struct gcp_field *tok = gcp_field_tokamak_create(2.5, 3.0, 1.0, 1.1, 3.5);
    check_field(tok, "tokamak", (const double[3]){3.3, 0.0, 0.0}, 0.2, 1e-2 * MeV, 2e-8, 5);
    gcp_field_free(tok);
    /* mirror B0 = 0.1 T, Lm = 1 m, 10 keV protons near the axis */
    struct gcp_field *mir = gcp_field_mirror_create(0.1, 1.0, 5.0, 2.0);
    check_field(mir, "mirror", (const double[3]){0.05, 0.0, 0.0}, 0.05, 1e-2 * MeV, 2e-8, -1);
    gcp_field_free(mir);
}

/* gcp_gc_block_begin in a closed-form field (the dipole, a uniform B and E)
 * takes its verdicts from one vectorised loop per form instead of
 * gcp_gc_eval per lane (gc_common.c): each lane must end with the status
 * the per-lane path gives -- gcp_gc_eval's verdict in fstatus, then
 * gcp_block_classify, formed here on a copy -- exactly.  Lanes: ordinary
 * ones, non-finite X and p_par, mu < 0, X at the dipole's centre (r^2
 * floored), outside r_outer and inside r_inner; with amax > 0 lanes
 * that only the adiabaticity verdict stops (a begin that skipped it would
 * leave them alive: the count check below); and B = 0, where every
 * finite lane's derivative is not (NONFINITE, ranked before the
 * NONADIABATIC that B*_par = 0 gives too). */
static void begin_case(const struct gcp_field *f, const char *name, double amax, int want_nonad)
{
    enum { N = 41 };
    const double q = GCP_E_CHARGE, m = GCP_M_PROTON, p = gc_p_of_T(1e6 * GCP_E_CHARGE, m);
    struct gcp_block b, c;
    cr_assert_eq(gcp_block_alloc(&b, N), 0);
    cr_assert_eq(gcp_block_alloc(&c, N), 0);
    b.q = c.q = q, b.m = c.m = m;
    for (int i = 0; i < N; i++) {
        const double L = 2.0 + 0.2 * i, a = (10.0 + 2.0 * i) * GCP_PI / 180.0;
        b.x[i] = L * GC_RE * cos(0.3 * i), b.y[i] = L * GC_RE * sin(0.3 * i);
        b.z[i] = 0.1 * GC_RE * (i % 3);
        const double X[3] = {b.x[i], b.y[i], b.z[i]};
        b.ppar[i] = p * cos(a);
        const double B = gc_Bmag(f, X);
        b.mu[i] = (p * sin(a)) * (p * sin(a)) / (2.0 * m * (B > 0.0 ? B : 1e-5));
    }
    b.x[3] = NAN, b.ppar[5] = INFINITY, b.mu[7] = -b.mu[7];
    b.x[9] = b.y[9] = b.z[9] = 0.0;           /* the centre */
    b.x[11] = 20.0 * GC_RE, b.x[13] = 0.5 * GC_RE; /* outside, inside */
    b.mu[15] = 0.0, b.ppar[15] = 0.0;         /* at rest */
    b.n_active = N;
    /* the per-lane path on a copy */
    for (int i = 0; i < N; i++) {
        c.x[i] = b.x[i], c.y[i] = b.y[i], c.z[i] = b.z[i], c.ppar[i] = b.ppar[i];
        c.mu[i] = b.mu[i];
        const double X[3] = {b.x[i], b.y[i], b.z[i]};
        double dX[3], dp;
        c.fstatus[i] = gcp_gc_eval(f, 0.0, q, m, X, b.ppar[i], b.mu[i], amax, dX, &dp);
    }
    c.n_active = N;
    gcp_block_classify(&c, N, f, 1);
    const struct gcp_push_opts o = {0.0, 1e-3, 10, 0.0, amax};
    gcp_gc_block_begin(&b, f, &o);
    int nonad = 0;
    for (size_t l = 0; l < N; l++) {
        const size_t i = b.index[l];
        cr_assert_eq(b.status[l], c.status[i], "%s amax %g: lane %zu status %d, per lane %d",
                     name, amax, i, b.status[l], c.status[i]);
        nonad += b.status[l] == GCP_NONADIABATIC;
    }
    cr_assert(want_nonad ? nonad > 0 : nonad == 0, "%s amax %g: %d lanes NONADIABATIC", name, amax,
              nonad);
    gcp_block_free(&b);
    gcp_block_free(&c);
}

Test(gc_block, begin_verdicts_in_closed_forms_are_the_per_lane_ones)
{
    struct gcp_field *dip = gcp_field_dipole_create(GC_B0, 0, GC_RE + 100e3, 15.0 * GC_RE);
    struct gcp_point_B form;
    cr_assert(gcp_field_point_B(dip, &form) && form.form == GCP_POINT_B_DIPOLE);
    begin_case(dip, "dipole", 0.0, 0);
    begin_case(dip, "dipole", 0.02, 1); /* 1 MeV protons: eps ~ 0.01 .. 0.1 over L = 2 .. 10 */
    gcp_field_free(dip);
    struct gcp_field *uni = gcp_field_uniform_create((const double[3]){1e-6, 2e-6, 3e-5},
                                                     (const double[3]){1e-3, 0.0, 2e-4});
    begin_case(uni, "uniform E and B", 0.0, 0);
    gcp_field_free(uni);
    struct gcp_field *zero = gcp_field_uniform_create((const double[3]){0.0, 0.0, 0.0},
                                                      (const double[3]){0.0, 0.0, 0.0});
    begin_case(zero, "B = 0", 0.0, 0);
    gcp_field_free(zero);
}
