/* Stiff and extreme cases (issue 7) that need a field or a check no run
 * file can express; the run-file ones are the runs/stiff/ files, checked by
 * tests/cli/test_stiff.sh.  Expected behaviour, per test:
 *
 *  exact_uniform_*    the exact solutions of sweep_exact.c agree with an
 *                     independent closed form (E = 0 helix) and with vay at a
 *                     tiny step (E x B at E/cB = 0.5; E/cB = 1.001, where the
 *                     energy grows without bound as the hyperbolic motion says);
 *  force_free_0999    a proton moving at the E x B velocity (E/cB = 0.999,
 *                     gamma = 22.4) feels no force: vay and higuera-cary keep u
 *                     to round-off at any step; boris does not (Vay 2008);
 *  cusp_null          a particle through the null of a cusp field B = B0 (x, y,
 *                     -2z)/L: full-orbit pushers carry on (ALIVE, finite, energy
 *                     kept); gc-rk4 with adiabaticity_max stops NONADIABATIC
 *                     before the null, with its state finite;
 *  dipole_centre      a particle aimed at the centre of a dipole without an
 *                     atmosphere: full orbit ends ALIVE or NONFINITE (never a
 *                     crash or a NaN under another status); the centre is a
 *                     singularity with |B| -> inf, not a null (rho/L_B ~ r^2 ->
 *                     0), so gc-rk4 is not NONADIABATIC there: it crosses or
 *                     stops with a status, its state finite;
 *  leaves_grid        a gridded field: full orbit and guiding centre leave it
 *                     with status LEFT_GRID, state finite;
 *  gc_huge_dt         gc-rk4 with dt = 1e4 gyro periods (several bounce periods
 *                     per step) in the dipole: a clear outcome for every particle
 *                     (a finite ALIVE state or a stopping status), never NaN. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fo_test_util.h"
#include "gcpush/gc.h"
#include "gcpush/grid.h"
#include "gcpush/sweep.h"

static int finite3(const double v[3]) { return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]); }

/* ---- exact solutions ---------------------------------------------------- */

Test(stiff, exact_uniform_helix)
{
    const double B[3] = {0, 0, 1e-3}, E[3] = {0, 0, 0};
    const double m = GCP_M_ELECTRON, q = -GCP_E_CHARGE;
    struct gcp_exact_uniform ex;
    cr_assert_eq(gcp_exact_uniform_init(&ex, B, E, q, m), 0);
    const double u = fo_u_of_ekin(FO_MEV, m), x0[3] = {1, 2, 3};
    const double u0[3] = {u * 0.8, 0.0, u * 0.6};
    const double g = sqrt(1 + u * u / (FO_C * FO_C)), w = q * 1e-3 / (g * m);
    for (double t = 0; t < 1e-6; t += 1.37e-7) {
        double x[3], uu[3], ph;
        cr_assert_eq(gcp_exact_uniform_state(&ex, x0, u0, t, x, uu, &ph), 0);
        /* u_perp rotates by -w t about z; x = x0 + (u_perp0 sin + u_perp0 x b (1 - cos))/(g w) */
        const double c = cos(w * t), s = sin(w * t);
        const double ux = u0[0] * c, uy = -u0[0] * s;
        cr_assert(fabs(uu[0] - ux) < 1e-12 * u && fabs(uu[1] - uy) < 1e-12 * u);
        cr_assert(fabs(uu[2] - u0[2]) < 1e-12 * u);
        const double rho = u0[0] / (g * w);
        cr_assert(fabs(x[0] - (x0[0] + rho * s)) < 1e-9 * fabs(rho));
        cr_assert(fabs(x[1] - (x0[1] - rho * (1 - c))) < 1e-9 * fabs(rho));
        cr_assert(fabs(x[2] - (x0[2] + u0[2] / g * t)) < 1e-9 * fabs(rho) + 1e-12);
    }
}

/* Exact vs vay with a tiny step: E x B at E/cB = 0.5 and E/cB = 1.001. */
static void exact_vs_vay(double ratio, double tend, double tol)
{
    const double Bz = 1e-3, Ex = ratio * FO_C * Bz;
    const double B[3] = {0, 0, Bz}, E[3] = {Ex, 0, 0};
    const double m = GCP_M_PROTON, q = GCP_E_CHARGE;
    struct gcp_exact_uniform ex;
    cr_assert_eq(gcp_exact_uniform_init(&ex, B, E, q, m), 0);
    cr_assert_eq(ex.regime, ratio < 1 ? 1 : 2);
    struct gcp_field *f = gcp_field_uniform_create(B, E);
    const double u = fo_u_of_ekin(10 * FO_KEV, m);
    double x[3] = {0, 0, 0}, uu[3] = {u, 0, 0.3 * u}, t = 0;
    const double x0[3] = {0, 0, 0}, u0[3] = {u, 0, 0.3 * u};
    const int64_t n = 200000;
    const double dt = tend / (double)n;
    int st = gcp_orbit_push(f, gcp_pusher_lookup("vay"), q, m, &t, x, uu, dt, n, NULL, NULL);
    cr_assert_eq(st, GCP_ALIVE);
    double xe[3], ue[3];
    cr_assert_eq(gcp_exact_uniform_state(&ex, x0, u0, tend, xe, ue, NULL), 0);
    const double d = sqrt((x[0] - xe[0]) * (x[0] - xe[0]) + (x[1] - xe[1]) * (x[1] - xe[1]) +
                          (x[2] - xe[2]) * (x[2] - xe[2]));
    const double L = fo_norm(xe);
    cr_assert(d < tol * L, "E/cB = %g: |x - x_exact| = %g m of %g m", ratio, d, L);
    const double We = fo_ekin(ue, m), Wv = fo_ekin(uu, m);
    cr_assert(fabs(Wv - We) < tol * We, "E/cB = %g: W %g vs exact %g", ratio, Wv, We);
    if (ratio > 1) {
        /* no drift frame: the energy grows without bound; at late times
         * gamma m c^2 ~ q E' c t' grows linearly in t */
        double xe2[3], ue2[3];
        cr_assert_eq(gcp_exact_uniform_state(&ex, x0, u0, 2 * tend, xe2, ue2, NULL), 0);
        cr_assert(fo_ekin(ue2, m) > 1.5 * We);
    }
    gcp_field_free(f);
}

Test(stiff, exact_uniform_exb) { exact_vs_vay(0.5, 2e-4, 1e-6); }
Test(stiff, exact_uniform_superluminal) { exact_vs_vay(1.001, 2e-4, 1e-5); }

Test(stiff, exact_uniform_refuses)
{
    struct gcp_exact_uniform ex;
    const double B[3] = {0, 0, 1e-3};
    const double Epar[3] = {1, 0, 1}, Ec[3] = {FO_C * 1e-3, 0, 0};
    cr_assert_eq(gcp_exact_uniform_init(&ex, B, Epar, 1, 1), GCP_ERR_VALUE);
    cr_assert_eq(gcp_exact_uniform_init(&ex, B, Ec, 1, 1), GCP_ERR_VALUE);
}

/* ---- force-free motion at E/cB = 0.999 ---------------------------------- */

Test(stiff, force_free_0999)
{
    const double Bz = 1e-3, Ex = 0.999 * FO_C * Bz;
    const double B[3] = {0, 0, Bz}, E[3] = {Ex, 0, 0};
    struct gcp_field *f = gcp_field_uniform_create(B, E);
    const double vd = -Ex / Bz; /* E x B / B^2 along -y */
    const double gd = 1.0 / sqrt(1 - (vd / FO_C) * (vd / FO_C));
    const double m = GCP_M_PROTON, q = GCP_E_CHARGE;
    const double wdt[] = {0.1, 10.0, 1e3};
    for (int k = 0; k < 3; k++) {
        const double dt = wdt[k] * m / (q * Bz);
        FO_FOREACH(p)
        {
            double x[3] = {0, 0, 0}, u[3] = {0, gd * vd, 0}, t = 0;
            int st = gcp_orbit_push(f, p, q, m, &t, x, u, dt, 1000, NULL, NULL);
            cr_assert_eq(st, GCP_ALIVE, "%s", p->name);
            cr_assert(finite3(x) && finite3(u), "%s", p->name);
            const double rel = fabs(u[1] - gd * vd) / fabs(gd * vd) + fabs(u[0] / (gd * vd));
            if (fo_is(p, "vay") || fo_is(p, "higuera-cary"))
                cr_assert(rel < 1e-9, "%s omega dt = %g: force-free u drifted by %g", p->name,
                          wdt[k], rel);
            else if (wdt[k] >= 10)
                /* boris and boris-zu share Boris's electric half-kicks: the
                 * u- they rotate is not the force-free u, so the particle
                 * gyrates about the drift (measured rel 7.8 and 20 at
                 * omega dt = 10): the property is the scheme's, not the test's */
                cr_assert(rel > 1e-3, "%s is documented to fail here (rel %g)", p->name, rel);
        }
    }
    gcp_field_free(f);
}

/* ---- field nulls -------------------------------------------------------- */

struct cusp { double B0, L; };

static int cusp_eval(double t, const double x[3], struct gcp_field_sample *s, void *ctx)
{
    (void)t;
    const struct cusp *c = ctx;
    const double k = c->B0 / c->L;
    s->B[0] = k * x[0], s->B[1] = k * x[1], s->B[2] = -2 * k * x[2];
    if (s->need & GCP_NEED_GRADB) {
        memset(s->gradB, 0, sizeof s->gradB);
        s->gradB[0][0] = k, s->gradB[1][1] = k, s->gradB[2][2] = -2 * k;
    }
    if (s->need & GCP_NEED_E) s->E[0] = s->E[1] = s->E[2] = 0;
    return 0;
}

Test(stiff, cusp_null)
{
    struct cusp c = {1e-4, 1e3};
    struct gcp_field *f = gcp_field_callback_create(cusp_eval, &c, 0);
    cr_assert_not_null(f);
    const double m = GCP_M_PROTON, q = GCP_E_CHARGE;
    const double u = fo_u_of_ekin(FO_KEV, m);
    /* start at z = L/2, slightly off axis, heading down through the null */
    const double xs[3] = {1.0, 0.5, 0.5 * c.L}, us[3] = {0.02 * u, 0, -u};
    const double v = u / sqrt(1 + u * u / (FO_C * FO_C));
    const double T = 1.2 * c.L / v, dt = 0.05 * m / (q * c.B0); /* 0.05/omega at z = L/2 */
    const int64_t n = (int64_t)(T / dt);
    FO_FOREACH(p)
    {
        double x[3], uu[3], t = 0;
        memcpy(x, xs, sizeof x);
        memcpy(uu, us, sizeof uu);
        int st = gcp_orbit_push(f, p, q, m, &t, x, uu, dt, n, NULL, NULL);
        cr_assert_eq(st, GCP_ALIVE, "%s: %s", p->name, gcp_status_name(st));
        cr_assert(finite3(x) && finite3(uu), "%s", p->name);
        cr_assert(x[2] < 0, "%s: went through the null (z = %g)", p->name, x[2]);
        cr_assert(fabs(fo_norm(uu) - fo_norm(us)) < 1e-10 * fo_norm(us), "%s energy", p->name);
    }
    /* guiding centre: stops NONADIABATIC before the null */
    double X[3], ppar, mu;
    cr_assert_eq(gcp_gc_from_fo(f, 0, q, m, xs, us, X, &ppar, &mu), 0);
    struct gcp_push_opts o = {.dt = dt, .nsteps = n, .adiabaticity_max = 0.1};
    double t = 0;
    int st = gcp_gc_push(f, &gcp_pusher_gc_rk4, q, m, &o, &t, X, &ppar, mu, NULL, NULL);
    cr_assert_eq(st, GCP_NONADIABATIC, "gc-rk4 through a null: %s", gcp_status_name(st));
    cr_assert(finite3(X) && isfinite(ppar));
    cr_assert(fo_norm(X) > 1.0, "stopped at |X| = %g m, not before the null", fo_norm(X));
    gcp_field_free(f);
}

Test(stiff, dipole_centre)
{
    /* no atmosphere, no outer bound: nothing stops the particle but the centre */
    struct gcp_field *f = gcp_field_dipole_create(GCP_EARTH_B0, 0, 0.0, INFINITY);
    const double m = GCP_M_PROTON, q = GCP_E_CHARGE;
    const double u = fo_u_of_ekin(10 * FO_MEV, m);
    const double offs[] = {0.0, 1e3};
    for (int k = 0; k < 2; k++) {
        const double xs[3] = {offs[k], 0, 2 * GCP_EARTH_RADIUS}, us[3] = {0, 0, -u};
        FO_FOREACH(p)
        {
            double x[3], uu[3], t = 0;
            memcpy(x, xs, sizeof x);
            memcpy(uu, us, sizeof uu);
            int st = gcp_orbit_push(f, p, q, m, &t, x, uu, 1e-3, 1000, NULL, NULL);
            cr_assert(st == GCP_ALIVE || st == GCP_NONFINITE, "%s: %s", p->name,
                      gcp_status_name(st));
            if (st == GCP_ALIVE) cr_assert(finite3(x) && finite3(uu), "%s", p->name);
        }
    }
    /* Guiding centre (gc-rk4), with an answer to check, not any status:
     * on the axis (offset 0) b = -z exactly and mu = 0, so the exact GC
     * motion is X_z = z0 - v t straight through the centre (|B| ~ r^-3 is
     * no null: rho / L_B ~ r^2 -> 0), p_par constant; RK4 integrates a
     * constant velocity exactly, so z is kept to round-off of the sum of
     * steps (1000 additions of 4.3e4 m: ~1e3 eps |z| = 1e-12 relative,
     * tolerance 1e-11).  Off the axis by 1 km, mu = p^2 sin^2(alpha)/(2 m B)
     * is small but not zero: the particle mirrors where |B| = p^2/(2 m mu)
     * (562 T, ~31 km from the centre), comes back with p_par reversed and
     * its kinetic energy kept, i.e. gamma(p_par, mu, |B(X)|) = gamma0.
     * At dt = 1e-6 s (43 m steps against the 10 km scale of |B| at the
     * mirror: rho_B = r/3) RK4's energy error is ~(43 m / 10 km)^4 = 3e-10;
     * tolerance 1e-8.  (At dt = 1e-3 s, 44 km steps over a 31 km mirror,
     * gc-rk4 comes back ALIVE with 2.4 times the momentum: a fixed step
     * that does not resolve the motion is not detected -- see issue 13's
     * note; the test does not cover that case.) */
    double X[3], ppar, mu;
    const double xs0[3] = {0, 0, 2 * GCP_EARTH_RADIUS}, us0[3] = {0, 0, -u};
    cr_assert_eq(gcp_gc_from_fo(f, 0, q, m, xs0, us0, X, &ppar, &mu), 0);
    cr_assert_eq(mu, 0.0, "on the axis mu = %g", mu);
    struct gcp_push_opts o = {.dt = 1e-3, .nsteps = 1000, .adiabaticity_max = 0.1};
    double t = 0;
    int st = gcp_gc_push(f, &gcp_pusher_gc_rk4, q, m, &o, &t, X, &ppar, mu, NULL, NULL);
    cr_assert_eq(st, GCP_ALIVE, "gc-rk4 on the axis: %s", gcp_status_name(st));
    const double v = u / sqrt(1 + u * u / (FO_C * FO_C));
    const double zex = xs0[2] - v * t;
    cr_assert(X[0] == 0 && X[1] == 0 && fabs(X[2] - zex) < 1e-11 * fabs(zex),
              "on the axis: X = (%g %g %.15g), exact z = %.15g", X[0], X[1], X[2], zex);
    cr_assert(fabs(ppar - m * u) < 1e-14 * m * u, "p_par changed: %g vs %g", ppar, m * u);

    const double xs1[3] = {1e3, 0, 2 * GCP_EARTH_RADIUS};
    cr_assert_eq(gcp_gc_from_fo(f, 0, q, m, xs1, us0, X, &ppar, &mu), 0);
    cr_assert(mu > 0 && ppar > 0, "off the axis: mu %g p_par %g", mu, ppar);
    struct gcp_field_sample s0 = {.need = GCP_NEED_B};
    cr_assert_eq(gcp_field_eval(f, 0, X, &s0), 0);
    const double g0 = gcp_gc_gamma(ppar, mu, fo_norm(s0.B), m);
    struct gcp_push_opts o1 = {.dt = 1e-6, .nsteps = 600000, .adiabaticity_max = 0.1};
    t = 0;
    st = gcp_gc_push(f, &gcp_pusher_gc_rk4, q, m, &o1, &t, X, &ppar, mu, NULL, NULL);
    cr_assert_eq(st, GCP_ALIVE, "gc-rk4 off the axis: %s", gcp_status_name(st));
    cr_assert(ppar < 0 && X[2] > GCP_EARTH_RADIUS, "not mirrored: p_par %g z %g", ppar, X[2]);
    struct gcp_field_sample s1 = {.need = GCP_NEED_B};
    cr_assert_eq(gcp_field_eval(f, t, X, &s1), 0);
    const double g1 = gcp_gc_gamma(ppar, mu, fo_norm(s1.B), m);
    cr_assert(fabs(g1 / g0 - 1) < 1e-8, "energy after the mirror: gamma %.15g vs %.15g", g1, g0);
    gcp_field_free(f);
}

/* ---- leaving a grid ----------------------------------------------------- */

Test(stiff, leaves_grid)
{
    struct gcp_grid_data d;
    memset(&d, 0, sizeof d);
    d.geometry = GCP_GRID_CARTESIAN;
    const size_t n = 6, N = n * n * n;
    for (int i = 0; i < 3; i++) {
        d.n[i] = n;
        d.origin[i] = -1.0;
        d.spacing[i] = 0.4;
        d.B[i] = calloc(N, sizeof(double));
    }
    for (size_t k = 0; k < N; k++) d.B[2][k] = 1e-2;
    d.r_inner = 0, d.r_outer = INFINITY, d.z_max = INFINITY;
    struct gcp_error err = {0};
    struct gcp_field *f = gcp_field_grid_create(&d, GCP_INTERP_CUBIC, 0, &err);
    cr_assert_not_null(f, "%s", err.msg);
    const double m = GCP_M_PROTON, q = GCP_E_CHARGE, u = fo_u_of_ekin(FO_KEV, m);
    FO_FOREACH(p)
    {
        double x[3] = {0, 0, 0}, uu[3] = {0.3 * u, 0, u}, t = 0;
        int st = gcp_orbit_push(f, p, q, m, &t, x, uu, 1e-8, 100000, NULL, NULL);
        cr_assert_eq(st, GCP_LEFT_GRID, "%s: %s", p->name, gcp_status_name(st));
        cr_assert(finite3(x) && finite3(uu));
    }
    double X[3], ppar, mu;
    const double x0[3] = {0, 0, 0}, u0[3] = {0.3 * u, 0, u};
    cr_assert_eq(gcp_gc_from_fo(f, 0, q, m, x0, u0, X, &ppar, &mu), 0);
    struct gcp_push_opts o = {.dt = 1e-8, .nsteps = 100000};
    double t = 0;
    int st = gcp_gc_push(f, &gcp_pusher_gc_rk4, q, m, &o, &t, X, &ppar, mu, NULL, NULL);
    cr_assert_eq(st, GCP_LEFT_GRID, "gc-rk4: %s", gcp_status_name(st));
    cr_assert(finite3(X) && isfinite(ppar));
    gcp_field_free(f);
    for (int i = 0; i < 3; i++) free(d.B[i]);
}

/* ---- guiding centre with a step far above the gyro period ---------------- */

/* Dipole L of a point: r = L R_E cos^2(latitude). */
static double dipole_L(const double X[3])
{
    const double r = fo_norm(X);
    return r * r * r / ((X[0] * X[0] + X[1] * X[1]) * GCP_EARTH_RADIUS);
}

/* 1 keV electrons at L = 4 with dt = 1000 gyro periods: the guiding centre
 * needs the bounce resolved, not the gyration (T_b / T_g = 5.5e4 .. 8.3e4
 * here, so 55..83 steps per bounce).  Over two bounce periods the exact GC
 * motion keeps the field line (in a dipole the drift is azimuthal: L is
 * constant) and the energy.  RK4's local error is ~(omega_b h)^5 / 5! of
 * the orbit's scale, omega_b h = 2 pi / 55 = 0.114: 1.6e-7 per step,
 * ~2e-5 after 2 x 55 steps: tolerance 2e-5 on dL/L and dgamma/gamma
 * (measured 5e-6 and 4e-8 at pitch 0.3 rad).  (At 1e4 gyro periods, 5..8
 * steps per bounce, gc-rk4 returns ALIVE with L off by O(1): an unresolved
 * fixed step is not detected -- see issue 13's note.) */
Test(stiff, gc_huge_dt)
{
    struct gcp_field *f = gcp_field_dipole_create(GCP_EARTH_B0, 0, GCP_EARTH_RADIUS + 1e5,
                                                  15 * GCP_EARTH_RADIUS);
    const double m = GCP_M_ELECTRON, q = -GCP_E_CHARGE;
    const double u = fo_u_of_ekin(FO_KEV, m);
    const double pitch[] = {0.3, 0.8, 1.4};
    for (int k = 0; k < 3; k++) {
        const double x0[3] = {4 * GCP_EARTH_RADIUS, 0, 0};
        const double u0[3] = {0, u * sin(pitch[k]), u * cos(pitch[k])};
        double X[3], ppar, mu, Tg, Tb;
        cr_assert_eq(gcp_gc_from_fo(f, 0, q, m, x0, u0, X, &ppar, &mu), 0);
        struct gcp_species sp = {"electron", q, m};
        cr_assert_eq(gcp_period_of(f, "dipole", &sp, x0, u0, GCP_PERIOD_GYRO, &Tg), 0);
        cr_assert_eq(gcp_period_of(f, "dipole", &sp, x0, u0, GCP_PERIOD_BOUNCE, &Tb), 0);
        cr_assert_gt(Tb / Tg, 5e4, "bounce not slow enough: T_b/T_g = %g", Tb / Tg);
        struct gcp_field_sample s = {.need = GCP_NEED_B};
        cr_assert_eq(gcp_field_eval(f, 0, X, &s), 0);
        const double g0 = gcp_gc_gamma(ppar, mu, fo_norm(s.B), m), L0 = dipole_L(X);
        struct gcp_push_opts o = {.dt = 1e3 * Tg, .nsteps = (int64_t)(2 * Tb / (1e3 * Tg))};
        double t = 0;
        int st = gcp_gc_push(f, &gcp_pusher_gc_rk4, q, m, &o, &t, X, &ppar, mu, NULL, NULL);
        cr_assert_eq(st, GCP_ALIVE, "pitch %g: %s", pitch[k], gcp_status_name(st));
        cr_assert_eq(gcp_field_eval(f, t, X, &s), 0);
        const double dg = gcp_gc_gamma(ppar, mu, fo_norm(s.B), m) / g0 - 1;
        const double dL = dipole_L(X) / L0 - 1;
        cr_assert(fabs(dL) < 2e-5 && fabs(dg) < 2e-5, "pitch %g: dL/L %g, dgamma/gamma %g",
                  pitch[k], dL, dg);
    }
    gcp_field_free(f);
}
