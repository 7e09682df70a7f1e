/* The full-orbit mu of the observer outside the dipole (issue 13): in a
 * magnetic mirror and in the analytic tokamak (a trapped, banana proton).
 *
 * What the observer reports for a full orbit (src/diag/invariants.c): at
 * each equator point, the zeroth-order magnetic moment p_perp^2/(2 m |B|)
 * evaluated at the first-order guiding centre X = x - b x p/(qB), averaged
 * over a gyration.  That average is the adiabatic invariant to O(eps^2),
 * eps = rho / L_B: the O(eps) difference between the zeroth-order and the
 * first-order mu oscillates with the gyrophase and averages out (Northrop
 * 1963).  Independent reference, built here from the initial state with
 * nothing of the observer: the raw p_perp^2/(2 m |B(x)|) at the particle,
 * pushed one step at a time, averaged over its first gyration.
 *
 * Claims, per field: the events' spread is below eps^2 (the reported mu is
 * steady); the raw moment the observer does not report --
 * p_perp^2/(2 m |B(x)|) at one instant -- swings by O(eps) over a
 * gyration, > 10 eps^2 here, so the average is what makes it steady; and
 * against the reference:
 *  - mirror (a vacuum field, b . curl b = 0, like the dipole): within
 *    5 eps^2 (the O(eps^2) terms' coefficient; measured 0.5 eps^2);
 *  - tokamak (a field with parallel current, b . curl b = mu0 J_par / B
 *    != 0): the zeroth-order moment averaged at the particle and the one
 *    averaged at the guiding centre differ at O(eps) (measured 0.15 eps,
 *    steady along the orbit): within eps.  Attributed, not verified
 *    separately, to the gyro-average of the first-order correction mu_1,
 *    which has v_par b . curl b / omega_c terms that vanish only in vacuum
 *    fields (Northrop 1963); either average then differs from the
 *    first-order invariant at O(eps) there.  The observer's mu
 *    is therefore named for what it is (README): the gyration-averaged
 *    zeroth-order moment at the first-order guiding centre, the
 *    first-order invariant to O(eps^2) only where b . curl b = 0. */
#include <criterion/criterion.h>
#include <math.h>
#include <string.h>

#include "gcpush/field.h"
#include "gcpush/gc.h"
#include "gcpush/invariants.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "gcpush/pusher.h"

struct raw_acc {
    const struct gcp_field *f;
    double m, sum, lo, hi;
    int64_t n;
};

static int raw_cb(double t, const double x[3], const double u[3], void *ctx)
{
    struct raw_acc *a = ctx;
    struct gcp_field_sample s = {.need = GCP_NEED_B};
    gcp_field_eval(a->f, t, x, &s);
    const double B = sqrt(s.B[0] * s.B[0] + s.B[1] * s.B[1] + s.B[2] * s.B[2]);
    const double up = (u[0] * s.B[0] + u[1] * s.B[1] + u[2] * s.B[2]) / B;
    const double mu = a->m * (u[0] * u[0] + u[1] * u[1] + u[2] * u[2] - up * up) / (2.0 * B);
    a->sum += mu, a->n++;
    a->lo = fmin(a->lo, mu), a->hi = fmax(a->hi, mu);
    return 0;
}

/* Pushes (x0, u0) with boris for nsteps of dt under the observer (mu and
 * bounce events); checks the mu events against the reference. */
static void check_mu_path(const char *what, const struct gcp_field *f, double q, double m,
                          const double x0[3], const double u0[3], double dt, int64_t nsteps,
                          double eps, double tol_ref, int fused)
{
    /* reference: the raw moment over the first gyration */
    struct gcp_field_sample s = {.need = GCP_NEED_B};
    cr_assert_eq(gcp_field_eval(f, 0, x0, &s), 0);
    const double B = sqrt(s.B[0] * s.B[0] + s.B[1] * s.B[1] + s.B[2] * s.B[2]);
    const double Tg = 2 * GCP_PI * gcp_gamma_of_u(u0[0], u0[1], u0[2]) * m / (fabs(q) * B);
    struct raw_acc ra = {f, m, 0, INFINITY, -INFINITY, 0};
    double x[3], u[3], t = 0;
    memcpy(x, x0, sizeof x), memcpy(u, u0, sizeof u);
    raw_cb(0, x, u, &ra);
    cr_assert_eq(gcp_orbit_push(f, &gcp_pusher_boris, q, m, &t, x, u, dt,
                                (int64_t)lround(Tg / dt) - 1, raw_cb, &ra), GCP_ALIVE);
    const double mubar = ra.sum / (double)ra.n;
    const double raw_swing = (ra.hi - ra.lo) / mubar;

    /* the observer on the same orbit */
    struct gcp_block b;
    cr_assert_eq(gcp_block_alloc(&b, 1), 0);
    b.q = q, b.m = m;
    b.x[0] = x0[0], b.y[0] = x0[1], b.z[0] = x0[2];
    b.ux[0] = u0[0], b.uy[0] = u0[1], b.uz[0] = u0[2];
    gcp_block_start(&b, f, 0.0);
    struct gcp_observer *o;
    const struct gcp_observer_opts oo = {.invariants = GCP_INV_MU, .events = GCP_EVT_BOUNCE};
    cr_assert_eq(gcp_observer_create(&o, 1, f, &gcp_pusher_boris, &oo), 0);
    struct gcp_events ev = {0};
    gcp_observer_begin(o, &b, 0.0, 0, &ev);
    const struct gcp_sampler smp = {1, gcp_observer_sample, o};
    const struct gcp_push_opts po = {.t0 = 0.0, .dt = dt, .nsteps = nsteps};
    if (fused) {
        struct gcp_fo_gyro *g = gcp_observer_fo_gyro(o);
        cr_assert_not_null(g);
        gcp_block_advance_fo_gyro(&b, f, &gcp_pusher_boris, &po, &smp, g);
    } else {
        gcp_pusher_boris.advance(&b, f, &gcp_pusher_boris, &po, &smp);
    }
    cr_assert_eq(gcp_observer_end(o, &b), 0);
    cr_assert_eq(b.status[0], GCP_ALIVE, "%s: status %d", what, b.status[0]);
    double lo = INFINITY, hi = -INFINITY, worst = 0;
    int n = 0;
    for (int64_t k = 0; k < ev.ns; k++) {
        if (ev.s[k].kind != GCP_EVENT_MU) continue;
        const double v = ev.s[k].v;
        lo = fmin(lo, v), hi = fmax(hi, v);
        worst = fmax(worst, fabs(v / mubar - 1));
        n++;
    }
    cr_log_info("%s: eps %.2e, %d mu events: spread %.2e, worst vs reference %.2e; raw swing "
                "over a gyration %.2e", what, eps, n, (hi - lo) / mubar, worst, raw_swing);
    cr_assert_geq(n, 4, "%s: %d mu events", what, n);
    cr_assert_lt((hi - lo) / mubar, eps * eps, "%s: mu spread %.3g", what, (hi - lo) / mubar);
    cr_assert_lt(worst, tol_ref, "%s: mu vs reference %.3g (tolerance %.3g)", what, worst,
                 tol_ref);
    cr_assert_gt(raw_swing, 10 * eps * eps, "%s: the raw moment swings by only %.3g", what,
                 raw_swing);
    gcp_events_free(&ev);
    gcp_observer_free(o);
    gcp_block_free(&b);
}

static void check_mu(const char *what, const struct gcp_field *f, double q, double m,
                     const double x0[3], const double u0[3], double dt, int64_t nsteps,
                     double eps, double tol_ref)
{
    check_mu_path(what, f, q, m, x0, u0, dt, nsteps, eps, tol_ref, 0);
}

/* 10 keV proton in the bottle B0 = 1 T, Lm = 0.5 m, 5 cm off the axis,
 * pitch 60 deg (loss cone 26.6 deg), five bounces at 0.05 gyro.  eps =
 * rho / Lm with rho = p / (q B0) = 1.4 cm. */
Test(invariants_fo_mu, mirror)
{
    struct gcp_field *f = gcp_field_mirror_create(1.0, 0.5, 1.0, 1.0);
    const double q = GCP_E_CHARGE, m = GCP_M_PROTON, W = 1e4 * GCP_E_CHARGE;
    const double p = sqrt(W * (W + 2 * m * GCP_C_LIGHT * GCP_C_LIGHT)) / GCP_C_LIGHT;
    const double a = 60 * GCP_PI / 180, um = p / m;
    const double x0[3] = {0.05, 0, 0}, u0[3] = {0, um * sin(a), um * cos(a)};
    const double Tg = 2 * GCP_PI * m / (q * 1.0), vz = um * cos(a);
    const double Tb = 2 * GCP_PI * 0.5 / (um * sin(a)) * 1.0; /* ~ 2 pi Lm / v_perp */
    (void)vz;
    check_mu("mirror", f, q, m, x0, u0, 0.05 * Tg, (int64_t)(5 * Tb / (0.05 * Tg)),
             p / (q * 1.0) / 0.5, 5 * pow(p / (q * 1.0) / 0.5, 2));
    gcp_field_free(f);
}

/* 10 keV proton on a banana orbit in the analytic tokamak of
 * runs/sweep-tokamak.run (B0 = 2 T, R0 = 3 m, a = 1 m, q = 1 .. 3),
 * started on the outboard midplane at R = 3.5 m, pitch 80 deg (trapped),
 * three bounces at 0.05 gyro.  eps = rho |grad B| / B = rho / R. */
Test(invariants_fo_mu, tokamak_banana)
{
    struct gcp_field *f = gcp_field_tokamak_create(2.0, 3.0, 1.0, 1.0, 3.0);
    const double q = GCP_E_CHARGE, m = GCP_M_PROTON, W = 1e4 * GCP_E_CHARGE;
    const double p = sqrt(W * (W + 2 * m * GCP_C_LIGHT * GCP_C_LIGHT)) / GCP_C_LIGHT;
    const double x0[3] = {3.5, 0, 0};
    struct gcp_field_sample s = {.need = GCP_NEED_B};
    cr_assert_eq(gcp_field_eval(f, 0, x0, &s), 0);
    const double B = sqrt(s.B[0] * s.B[0] + s.B[1] * s.B[1] + s.B[2] * s.B[2]);
    double b[3] = {s.B[0] / B, s.B[1] / B, s.B[2] / B}, e[3] = {1, 0, 0}; /* R_hat is normal to b */
    const double a = 80 * GCP_PI / 180, um = p / m;
    double u0[3];
    for (int d = 0; d < 3; d++) u0[d] = um * (cos(a) * b[d] + sin(a) * e[d]);
    const double Tg = 2 * GCP_PI * m / (q * B);
    /* banana bounce period ~ 2 pi q R0 / (v sqrt(r / 2 R0)) for q(r) ~ 1.5 */
    const double Tb = 2 * GCP_PI * 1.5 * 3.0 / (um * sqrt(0.5 / 6.0));
    const double eps = p / (q * B) / 3.5;
    check_mu("tokamak", f, q, m, x0, u0, 0.05 * Tg, (int64_t)(3 * Tb / (0.05 * Tg)), eps, eps);
    gcp_field_free(f);
}

/* The dipole (a vacuum field, b . curl b = 0): a particle on the equator
 * at L = 4, pitch 50 deg, three bounces at 0.05 gyro, through the fused
 * full-orbit step's gyro-average (issue 12: the raw sums of the step's
 * middle, pushers/fo_gyro_priv.h) and through the observer's per-step
 * pass; the same claims and tolerances as the mirror's (spread < eps^2,
 * within 5 eps^2 of the independent reference, the raw moment swinging by
 * > 10 eps^2: a mu taken at one instant instead of gyro-averaged fails
 * the spread check).  eps = rho / L_B, L_B = r / 3 on the equator.
 * Bounce period ~ (4 L R_E / v)(1.30 - 0.56 sin a) (Hamlin et al. 1961). */
static void dipole_mu(const char *what, double q, double m, double W, int fused)
{
    const double RE = GCP_EARTH_RADIUS, L = 4.0, c = GCP_C_LIGHT;
    struct gcp_field *f = gcp_field_dipole_create(GCP_EARTH_B0, 0, RE + 100e3, 15.0 * RE);
    cr_assert_not_null(f);
    const double p = sqrt(W * (W + 2 * m * c * c)) / c, gamma = 1 + W / (m * c * c);
    const double Beq = GCP_EARTH_B0 / (L * L * L), a = 50 * GCP_PI / 180, um = p / m;
    /* B is along -z on the equator */
    const double x0[3] = {L * RE, 0, 0}, u0[3] = {0, um * sin(a), um * cos(a)};
    const double Tg = 2 * GCP_PI * gamma * m / (fabs(q) * Beq);
    const double v = p / (gamma * m), Tb = 4 * L * RE / v * (1.30 - 0.56 * sin(a));
    const double eps = p / (fabs(q) * Beq) / (L * RE / 3.0);
    check_mu_path(what, f, q, m, x0, u0, 0.05 * Tg, (int64_t)(3 * Tb / (0.05 * Tg)), eps,
                  5 * eps * eps, fused);
    gcp_field_free(f);
}

/* 1 MeV protons: eps = 0.035 */
Test(invariants_fo_mu, dipole_proton_fused)
{
    dipole_mu("dipole proton fused", GCP_E_CHARGE, GCP_M_PROTON, 1e6 * GCP_E_CHARGE, 1);
}

Test(invariants_fo_mu, dipole_proton_per_step)
{
    dipole_mu("dipole proton per step", GCP_E_CHARGE, GCP_M_PROTON, 1e6 * GCP_E_CHARGE, 0);
}

/* 10 MeV electrons (q < 0: the phase reference's sign), eps = 0.01 */
Test(invariants_fo_mu, dipole_electron_fused)
{
    dipole_mu("dipole electron fused", -GCP_E_CHARGE, GCP_M_ELECTRON, 1e7 * GCP_E_CHARGE, 1);
}

