/* Guiding-centre drifts from full orbits, over the battery of full-orbit
 * pushers: gradient drift on the dipole equator, and curvature + gradient
 * drift in a curved vacuum field, each against the first-order
 * guiding-centre formula within 1 %.
 *
 * Measurement: the mean drift rate is the weighted Birkhoff average
 * (fo_test_util.h) of the per-step displacement (azimuth turned, or z
 * gained) divided by dt, over ~200 gyro-periods.  The gyration, which is
 * 1e3 .. 1e6 times the drift per gyro-period, averages out faster than any
 * power of the run length, so the measurement error is far below 1e-6 and
 * the comparison tests the physics and the pusher.
 *
 * The particle is placed with its first-order guiding centre at the chosen
 * point (fo_place_at_gc) and with its gyro-radius vector perpendicular to
 * grad B and the curvature (u_perp along them): there the gyrophase
 * dependent first-order corrections to mu (rho . grad ln B, rho . kappa)
 * vanish (see test_fo_dipole.c, claim 5b, for their measured size when
 * they do not).
 */
#include <criterion/criterion.h>

#include "fo_test_util.h"

/* ------------------------------------------------------------------------
 * Claim 3a: equatorial gradient drift in the dipole.
 *
 * On the equator of the dipole B = B0 (R_E/r)^3 z, grad B = -3 B / r r_hat,
 * and there is no curvature term for a particle with v_par = 0:
 *   v_d = (gamma m v_perp^2 / (2 q B)) (B x grad B) / B^2
 *       = -(3 gamma m v^2 / (2 q B r)) phi_hat,
 *   omega_d = v_d / r = -3 p v / (2 q B r^2)
 * (protons west, electrons east), with r the guiding-centre radius.
 *
 * Accuracy of first-order GC theory: corrections are powers of
 * eps = rho / L_B = 3 rho / r; on the equator the O(eps) term averages
 * out over the gyration (it is odd in the gyrophase), leaving O(eps^2):
 * test_fo_dipole.c's exact Stormer quadrature gives -1.2e-3 at eps = 0.12
 * (10 MeV proton), i.e. ~0.08 eps^2.  Particles here: a 1 MeV electron
 * (eps = 1.1e-3) and a 100 keV proton (eps = 1.1e-2) at 4 R_E: expected
 * GC error ~1e-7 and ~1e-5.  Pushers at omega_c dt = 0.05: drift-rate
 * errors <= 0.11 (omega dt)^2 = 3e-4 (test_fo_dipole.c, claim 4c).
 * Tolerance per pusher: drift_tol.
 * ------------------------------------------------------------------------ */
/* Tolerance on a measured drift rate (issue 13, was 1 %): the first-order
 * guiding-centre theory's O(eps^2) (the O(eps) part is removed by the
 * start with the gyro-radius vector normal to grad B; 2 eps^2 leaves room
 * for its coefficient, 0.3 measured for the proton here) plus the
 * pusher's own drift error, c (omega dt)^2: Boris and Vay reproduce the
 * drifts (c = 0: measured <= 4e-7 beyond the GC term), boris-zu's drifts
 * are slow by (theta/2) cot(theta/2) = 1 - theta^2/12 (c = 1/12, the
 * kernel's own derivation), Higuera-Cary's gyrating drifts carry
 * ~0.11 (omega dt)^2 (measured here and in test_fo_dipole claim 4c; c =
 * 0.12). */
static double drift_tol(const struct gcp_pusher_type *p, double eps, double wdt)
{
    const double c = fo_is(p, "boris-zu") ? 1.0 / 12.0 : fo_is(p, "higuera-cary") ? 0.12 : 0.0;
    return 2.0 * eps * eps + c * wdt * wdt;
}

struct eq_acc {
    double x0, y0, t0;
    struct fo_birkhoff b;
};

static int eq_cb(double t, const double x[3], const double u[3], void *ctx)
{
    (void)u;
    struct eq_acc *a = ctx;
    fo_birkhoff_add(&a->b, fo_angle_between(a->x0, a->y0, x[0], x[1]) / (t - a->t0));
    a->x0 = x[0], a->y0 = x[1], a->t0 = t;
    return 0;
}

Test(fo_drifts, dipole_equatorial_gradB_every_pusher)
{
    struct {
        const char *label;
        double q, m, T;
    } sp[] = {{"1 MeV electron", -GCP_E_CHARGE, GCP_M_ELECTRON, 1.0 * FO_MEV},
              {"100 keV proton", GCP_E_CHARGE, GCP_M_PROTON, 100.0 * FO_KEV}};
    struct gcp_field *f = gcp_field_dipole_create(FO_B0, 0, FO_RE, INFINITY);
    cr_assert_not_null(f);
    const double rgc = 4.0 * FO_RE;
    const double B = FO_B0 * pow(FO_RE / rgc, 3);
    int runs = 0;
    for (int i = 0; i < 2; i++) {
        const double umag = fo_u_of_ekin(sp[i].T, sp[i].m);
        const double gam = sqrt(1.0 + umag * umag * GCP_INV_C2);
        const double p = sp[i].m * umag, v = umag / gam;
        const double wd_gc = -3.0 * p * v / (2.0 * sp[i].q * B * rgc * rgc);
        const double wc = fabs(sp[i].q) * B / (gam * sp[i].m);
        const double dt = 0.05 / wc;
        const int64_t n = (int64_t)(200.0 * 2.0 * GCP_PI / 0.05);
        FO_FOREACH(pu)
        {
            /* u_perp radial, so the gyro-radius vector is azimuthal */
            const double X[3] = {rgc, 0.0, 0.0};
            double u[3] = {umag, 0.0, 0.0}, x[3], t = 0.0;
            cr_assert_eq(fo_place_at_gc(f, sp[i].q, sp[i].m, X, u, x), 0);
            struct eq_acc a = {.x0 = x[0], .y0 = x[1], .t0 = 0.0};
            fo_birkhoff_init(&a.b, n);
            const int st = gcp_orbit_push(f, pu, sp[i].q, sp[i].m, &t, x, u, dt, n, eq_cb, &a);
            cr_assert_eq(st, GCP_ALIVE, "%s: status %d", pu->name, st);
            const double wd = fo_birkhoff_mean(&a.b);
            const double rel = wd / wd_gc - 1.0;
            cr_log_info("grad-B %s %-13s: omega_d = %.6e rad/s, GC %.6e, rel %+.3e",
                        sp[i].label, pu->name, wd, wd_gc, rel);
            const double eps = 3.0 * p / (fabs(sp[i].q) * B) / rgc; /* rho / L_B */
            const double tol = drift_tol(pu, eps, 0.05);
            cr_expect(fabs(rel) < tol, "%s %s: drift rate %.6e vs GC %.6e (%.3e, tolerance %.2e)",
                      sp[i].label, pu->name, wd, wd_gc, rel, tol);
            runs++;
        }
    }
    gcp_field_free(f);
    cr_assert_geq(runs, 8);
}

/* ------------------------------------------------------------------------
 * Claim 3b: curvature + gradient drift in a curved vacuum field.
 *
 * Field: the vacuum toroidal field B = B0 R0 / R phi_hat (curl-free,
 * divergence-free: a straight current on the z axis), given through the
 * public callback field.  Its field lines are circles of radius R, so the
 * curvature vector is kappa = -R_hat / R, and grad B = -B R_hat / R: the
 * two drifts add, both vertical:
 *   v_d = (gamma m / (q B)) (v_par^2 + v_perp^2 / 2) (b x grad B) / B
 *       = (gamma m / (q B R)) (v_par^2 + v_perp^2 / 2) z_hat
 * (curvature drift gamma m v_par^2 (R_c x B) / (q R_c^2 B^2), gradient drift
 * gamma m v_perp^2 (B x grad B) / (2 q B^3)).
 *
 * Cases: pitch angle 45 deg (both drifts) and 0 deg (a purely parallel
 * particle: pure curvature drift; it starts on its field line and picks up
 * only a gyration of radius ~ v_d / omega_c), for a 10 keV proton
 * (B0 = 1 T, R0 = 10 m: rho/R = 1.4e-3) and a 1 MeV electron (B0 = 0.01 T,
 * R0 = 500 m: rho/R = 9.5e-4).
 *
 * Accuracy of first-order GC theory: the next corrections are
 * O(eps) = O(rho / R) relative at most, ~1.5e-3 here (and the
 * gyrophase-dependent part is removed by the start, file comment); the
 * pushers' O((omega dt)^2) ~ 0.1 * 0.0025 = 2.5e-4 at omega dt = 0.05.
 * Measured: the GC term is ~1e-6, i.e. O(eps^2) (the gyrophase-dependent
 * O(eps) part is removed by the start).  Tolerance per pusher: drift_tol.
 * ------------------------------------------------------------------------ */
struct torus {
    double B0R0;
};

static int torus_eval(double t, const double x[3], struct gcp_field_sample *s, void *ctx)
{
    (void)t;
    const struct torus *tf = ctx;
    const double R2 = x[0] * x[0] + x[1] * x[1];
    const double k = tf->B0R0 / R2;
    s->B[0] = -k * x[1];
    s->B[1] = k * x[0];
    s->B[2] = 0.0;
    if (s->need & GCP_NEED_GRADB) {
        const double k4 = tf->B0R0 / (R2 * R2);
        memset(s->gradB, 0, sizeof s->gradB);
        s->gradB[0][0] = 2.0 * k4 * x[0] * x[1];
        s->gradB[0][1] = k4 * (x[1] * x[1] - x[0] * x[0]);
        s->gradB[1][0] = k4 * (x[1] * x[1] - x[0] * x[0]);
        s->gradB[1][1] = -2.0 * k4 * x[0] * x[1];
    }
    if (s->need & GCP_NEED_E) s->E[0] = s->E[1] = s->E[2] = 0.0;
    return 0;
}

struct z_acc {
    double z0, t0;
    struct fo_birkhoff b;
};

static int z_cb(double t, const double x[3], const double u[3], void *ctx)
{
    (void)u;
    struct z_acc *a = ctx;
    fo_birkhoff_add(&a->b, (x[2] - a->z0) / (t - a->t0));
    a->z0 = x[2], a->t0 = t;
    return 0;
}

Test(fo_drifts, curvature_and_gradB_every_pusher)
{
    struct {
        const char *label;
        double q, m, T, B0, R0;
    } sp[] = {{"10 keV proton", GCP_E_CHARGE, GCP_M_PROTON, 10.0 * FO_KEV, 1.0, 10.0},
              {"1 MeV electron", -GCP_E_CHARGE, GCP_M_ELECTRON, 1.0 * FO_MEV, 0.01, 500.0}};
    const double pitches[] = {45.0, 0.0};
    int runs = 0;
    for (int i = 0; i < 2; i++) {
        struct torus tf = {sp[i].B0 * sp[i].R0};
        struct gcp_field *f = gcp_field_callback_create(torus_eval, &tf, 0);
        cr_assert_not_null(f);
        const double umag = fo_u_of_ekin(sp[i].T, sp[i].m);
        const double gam = sqrt(1.0 + umag * umag * GCP_INV_C2), v = umag / gam;
        const double wc = fabs(sp[i].q) * sp[i].B0 / (gam * sp[i].m);
        const double dt = 0.05 / wc;
        const int64_t n = (int64_t)(200.0 * 2.0 * GCP_PI / 0.05);
        for (int k = 0; k < 2; k++) {
            const double a = pitches[k] * GCP_PI / 180.0;
            const double vpar = v * cos(a), vperp = v * sin(a);
            const double vd_gc = gam * sp[i].m * (vpar * vpar + 0.5 * vperp * vperp) /
                                 (sp[i].q * sp[i].B0 * sp[i].R0);
            FO_FOREACH(pu)
            {
                /* guiding centre at (R0, 0, 0), where b = y_hat; u_perp
                 * radial (x), so the gyro-radius vector is vertical */
                const double X[3] = {sp[i].R0, 0.0, 0.0};
                double u[3] = {umag * sin(a), umag * cos(a), 0.0}, x[3], t = 0.0;
                cr_assert_eq(fo_place_at_gc(f, sp[i].q, sp[i].m, X, u, x), 0);
                struct z_acc za = {.z0 = x[2], .t0 = 0.0};
                fo_birkhoff_init(&za.b, n);
                const int st =
                    gcp_orbit_push(f, pu, sp[i].q, sp[i].m, &t, x, u, dt, n, z_cb, &za);
                cr_assert_eq(st, GCP_ALIVE, "%s: status %d", pu->name, st);
                const double vd = fo_birkhoff_mean(&za.b);
                const double rel = vd / vd_gc - 1.0;
                cr_log_info("curvature %s pitch %2.0f %-13s: v_d = %.6e m/s, GC %.6e, rel %+.3e",
                            sp[i].label, pitches[k], pu->name, vd, vd_gc, rel);
                const double eps = gam * sp[i].m * v / (fabs(sp[i].q) * sp[i].B0) / sp[i].R0;
                const double tol = drift_tol(pu, eps, 0.05);
                cr_expect(fabs(rel) < tol, "%s pitch %g %s: v_d %.6e vs GC %.6e (%.3e, tolerance "
                          "%.2e)", sp[i].label, pitches[k], pu->name, vd, vd_gc, rel, tol);
                runs++;
            }
        }
        gcp_field_free(f);
    }
    cr_assert_geq(runs, 16);
}
