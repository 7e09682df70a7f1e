/* E x B drift and the force-free case, over the battery of full-orbit
 * pushers.
 *
 * Fields: B = B0 z, E = E0 y (uniform, E.B = 0, E < c B), so the drift is
 *   v_E = E x B / B^2 = (E0 / B0) x = V x.
 * Particle: a proton (B0 = 1 T) started with u = (-0.3, 1.2, 0.4) gamma_E V:
 * it gyrates (in the drift frame with speed ~ V) and moves along B.
 *
 * How the drift is measured to 1e-6 (to ~1e-12 in fact):
 * (1) The drift frame.  In the frame moving with V (gamma_E =
 *     1/sqrt(1 - V^2/c^2)) the field is purely magnetic, E' = 0,
 *     B' = (B0 / gamma_E) z, and the exact motion is a gyration about a fixed
 *     guiding centre X' = x' + (m / (q B'^2)) u' x B'.  A lab event (t, x, u)
 *     maps to x' = gamma_E (x - V t), u'_x = gamma_E (u_x - V gamma),
 *     u'_{y,z} = u_{y,z}; X' is constant along the exact world line whatever
 *     event is used, and the lab guiding centre moves as
 *     x_gc(t) = X'_x / gamma_E + V t.  So the drift error of a pusher is the
 *     rate of change of X' along its orbit:
 *       v_x - V = (dX'_x/dt) / gamma_E,   v_y = dX'_y/dt,
 *     exact at any gamma, no gyro-averaging theory involved.
 * (2) The rate is read as the weighted Birkhoff average (fo_test_util.h) of
 *     the per-step increments of X'.  A pusher's X' also wobbles, bounded,
 *     at the gyro-frequency (its discrete orbit is not an exact circle about
 *     X'); an end-point difference over ~400 gyro-periods would leave that
 *     wobble / T ~ 1e-7 ... 1e-6 (measured with the plain difference: up to
 *     5e-7 relative), while the smooth-weighted average suppresses it faster
 *     than any power of T: the measured v_y/V, which is 0 for every pusher
 *     by symmetry, comes out at 1e-16, which is the measurement floor.
 */
#include <criterion/criterion.h>

#include "fo_test_util.h"

struct exb_case {
    const char *label;
    double beta_E;  /* V / c */
    double u0[3];   /* initial u in units of gamma_E V */
};

/* Proton in B0 = 1 T. */
#define EXB_B0 1.0

struct exb_result {
    double rel_x; /* (v_meas - V) / V */
    double rel_y; /* v_meas,y / V */
};

/* Drift-frame guiding centre (x and y components) of the lab state. */
static void drift_frame_gc(double V, double gE, double q, double m, double t, const double x[3],
                           const double u[3], double *Xx, double *Xy)
{
    const double g = fo_gamma(u);
    const double xp = gE * (x[0] - V * t);
    const double upx = gE * (u[0] - V * g);
    const double upy = u[1];
    const double Bp = EXB_B0 / gE;
    *Xx = xp + m * upy / (q * Bp);
    *Xy = x[1] - m * upx / (q * Bp);
}

struct exb_acc {
    double V, gE, q, m, Xx, Xy, t;
    struct fo_birkhoff bx, by;
};

static int exb_cb(double t, const double x[3], const double u[3], void *ctx)
{
    struct exb_acc *a = ctx;
    double Xx, Xy;
    drift_frame_gc(a->V, a->gE, a->q, a->m, t, x, u, &Xx, &Xy);
    const double h = t - a->t;
    fo_birkhoff_add(&a->bx, (Xx - a->Xx) / (a->gE * h));
    fo_birkhoff_add(&a->by, (Xy - a->Xy) / h);
    a->Xx = Xx, a->Xy = Xy, a->t = t;
    return 0;
}

static struct exb_result run_exb(const struct gcp_pusher_type *p, const struct exb_case *c,
                                 double wdt, int64_t nsteps, struct exb_result *plain)
{
    const double q = GCP_E_CHARGE, m = GCP_M_PROTON;
    const double V = c->beta_E * FO_C;
    const double gE = 1.0 / sqrt(1.0 - c->beta_E * c->beta_E);
    const double B[3] = {0.0, 0.0, EXB_B0}, E[3] = {0.0, V * EXB_B0, 0.0};
    struct gcp_field *f = gcp_field_uniform_create(B, E);
    cr_assert_not_null(f);
    double x[3] = {0.0, 0.0, 0.0}, u[3], t = 0.0;
    for (int i = 0; i < 3; i++) u[i] = c->u0[i] * gE * V;
    /* Lab-time gyrofrequency: omega' = q B' / (gamma' m) in the drift
     * frame, slowed by gamma_E in lab time. */
    const double gp = gE * (fo_gamma(u) - V * u[0] * GCP_INV_C2);
    const double w_lab = q * EXB_B0 / (gE * gE * gp * m);
    const double dt = wdt / w_lab;
    struct exb_acc a = {.V = V, .gE = gE, .q = q, .m = m, .t = 0.0};
    fo_birkhoff_init(&a.bx, nsteps);
    fo_birkhoff_init(&a.by, nsteps);
    drift_frame_gc(V, gE, q, m, t, x, u, &a.Xx, &a.Xy);
    const double X0 = a.Xx, Y0 = a.Xy;
    const int st = gcp_orbit_push(f, p, q, m, &t, x, u, dt, nsteps, exb_cb, &a);
    cr_assert_eq(st, GCP_ALIVE, "%s: status %d", p->name, st);
    cr_assert_eq(a.bx.n, nsteps);
    gcp_field_free(f);
    if (plain) {
        plain->rel_x = (a.Xx - X0) / (gE * t) / V;
        plain->rel_y = (a.Xy - Y0) / t / V;
    }
    struct exb_result r = {fo_birkhoff_mean(&a.bx) / V, fo_birkhoff_mean(&a.by) / V};
    return r;
}

static const struct exb_case nonrel = {"non-relativistic, V/c = 3.3e-4", 1e5 / GCP_C_LIGHT,
                                       {-0.3, 1.2, 0.4}};
static const struct exb_case rel = {"relativistic, E/cB = 0.9", 0.9, {-0.3, 1.2, 0.4}};

/* number of steps covering ~400 gyro-periods at lab omega dt = wdt */
static int64_t steps_for(double wdt) { return (int64_t)(2.0 * GCP_PI * 400.0 / wdt); }

/* Claim 2a: non-relativistic drift (V/c = 3.3e-4) within 1e-6 of E x B/B^2
 * for boris, vay, higuera-cary at omega_c dt = 0.5 and 0.05; and boris-zu
 * follows its own drift law.
 *
 * Tolerance: 1e-6 is the bound; the expected errors are far below
 * it: Boris and Vay are exact for the non-relativistic E x B drift (the
 * Boris fixed point u* = (1 - R)^-1 (1 + R) (q dt / 2m) E has |u*| = E/B
 * exactly because the Boris angle satisfies tan(alpha/2) = omega dt / 2),
 * left with relativistic corrections O((V/c)^2 (omega dt)^2) ~ 1e-8;
 * measured: boris 3.5e-9, vay 2e-14, higuera-cary 2e-8.
 * boris-zu turns by alpha = omega dt but keeps Boris's half-kicks, so its
 * fixed point is |u*| = (q dt E / 2m) cot(alpha/2): its drift is
 *   V (omega dt / 2) cot(omega dt / 2) = V (1 - (omega dt)^2 / 12 - ...),
 * 2.1e-2 low at omega dt = 0.5 -- checked against that law to 1e-6 (the
 * relativistic correction again ~1e-8), which documents that boris-zu's
 * exact gyrophase costs the E x B drift (library note in the report). */
Test(fo_exb, nonrelativistic_drift_every_pusher)
{
    const double wdts[] = {0.5, 0.05};
    int runs = 0;
    FO_FOREACH(p)
    {
        for (int k = 0; k < 2; k++) {
            const struct exb_result r = run_exb(p, &nonrel, wdts[k], steps_for(wdts[k]), NULL);
            double expect = 0.0;
            if (fo_is(p, "boris-zu")) {
                const double h = 0.5 * wdts[k];
                expect = h * cos(h) / sin(h) - 1.0;
            }
            cr_log_info("ExB non-rel %-13s omega dt %g: (v-V)/V = %.3e (law %.3e), v_y/V = %.3e",
                        p->name, wdts[k], r.rel_x, expect, r.rel_y);
            cr_expect(fabs(r.rel_x - expect) < 1e-6,
                      "%s omega dt %g: drift (v-V)/V = %.3e, expected %.3e within 1e-6", p->name,
                      wdts[k], r.rel_x, expect);
            cr_expect(fabs(r.rel_y) < 1e-6, "%s: v_y/V = %.3e", p->name, r.rel_y);
            runs++;
        }
    }
    cr_assert_geq(runs, 8);
}

/* Claim 2b: relativistic (E/cB = 0.9, gamma_E = 2.29) drift of a gyrating
 * particle within 1e-6 of E x B/B^2 for vay at a coarse step (mean lab
 * omega dt = 0.0125 and 0.00625; the local omega dt = qB dt/(gamma m) swings
 * by ~ +-(gamma_E beta_E beta') around the mean along the gyration).
 *
 * Tolerance: 1e-6 is the bound.  Measured: |v-V|/V ~ 1e-11, the
 * round-off of the increments summed over 2e5 .. 4e5 steps (N eps ~ 1e-10):
 * Vay's drift is exact for a gyrating particle, not only in the force-free
 * limit. */
Test(fo_exb, relativistic_drift_vay)
{
    const struct gcp_pusher_type *p = gcp_pusher_lookup("vay");
    cr_assert_not_null(p);
    const double wdts[] = {0.0125, 0.00625};
    for (int k = 0; k < 2; k++) {
        const struct exb_result r = run_exb(p, &rel, wdts[k], steps_for(wdts[k]), NULL);
        cr_log_info("ExB rel vay omega dt %g: (v-V)/V = %.3e, v_y/V = %.3e", wdts[k], r.rel_x,
                    r.rel_y);
        cr_expect(fabs(r.rel_x) < 1e-6, "vay: (v-V)/V = %.3e", r.rel_x);
        cr_expect(fabs(r.rel_y) < 1e-6, "vay: v_y/V = %.3e", r.rel_y);
    }
}

/* Claim 2c: for the other pushers the relativistic drift of a gyrating
 * particle is off by O(dt^2): halving dt divides the error by 2^order = 4.
 *
 * Tolerance on the ratio: e(dt) = C dt^2 (1 + D dt^2 + ...), so
 * e(dt)/e(dt/2) = 4 (1 + (3/4) D dt^2 + ...); the local omega dt reaches
 * ~10x the mean 0.0125 at the slow end of the gyration, so D dt^2 can be a
 * few 1e-2; the measurement error of e is ~1e-12 against e >= 1e-6.  The
 * ratio must lie in 4 (1 +- 0.05) (measured: 4.02 boris, 4.00 boris-zu,
 * 4.02 higuera-cary). */
Test(fo_exb, relativistic_drift_second_order)
{
    int runs = 0;
    FO_FOREACH(p)
    {
        if (fo_is(p, "vay")) continue; /* exact: claim 2b */
        const struct exb_result r1 = run_exb(p, &rel, 0.0125, steps_for(0.0125), NULL);
        const struct exb_result r2 = run_exb(p, &rel, 0.00625, steps_for(0.00625), NULL);
        const double ratio = r1.rel_x / r2.rel_x;
        const double want = pow(2.0, p->order);
        cr_log_info("ExB rel %-13s: e(0.0125) = %.4e, e(0.00625) = %.4e, ratio %.4f (2^%d)",
                    p->name, r1.rel_x, r2.rel_x, ratio, p->order);
        cr_expect(fabs(r1.rel_x) > 1e-8, "%s: error %.3e is at the measurement floor", p->name,
                  r1.rel_x);
        cr_expect(fabs(ratio / want - 1.0) < 0.05, "%s: error ratio %.4f, expected %g +- 5%%",
                  p->name, ratio, want);
        runs++;
    }
    cr_assert_geq(runs, 3);
}

/* Claim 2d: at converged dt (mean lab omega dt = 1e-3) every pusher --
 * higuera-cary included -- gives the relativistic drift within 1e-6.
 *
 * Tolerance: 1e-6 (the issue's); expected from claim 2c's coefficients
 * C = e / (omega dt)^2 = 0.046 (boris), 0.17 (boris-zu), 0.34
 * (higuera-cary): 4.6e-8, 1.7e-7, 3.4e-7 at omega dt = 1e-3; vay ~1e-11. */
Test(fo_exb, relativistic_drift_converged_every_pusher)
{
    int runs = 0;
    FO_FOREACH(p)
    {
        const struct exb_result r = run_exb(p, &rel, 1e-3, steps_for(1e-3) / 2, NULL);
        cr_log_info("ExB rel %-13s omega dt 1e-3: (v-V)/V = %.3e, v_y/V = %.3e", p->name,
                    r.rel_x, r.rel_y);
        cr_expect(fabs(r.rel_x) < 1e-6, "%s: (v-V)/V = %.3e at omega dt = 1e-3", p->name,
                  r.rel_x);
        cr_expect(fabs(r.rel_y) < 1e-6, "%s: v_y/V = %.3e", p->name, r.rel_y);
        runs++;
    }
    cr_assert_geq(runs, 4);
}

/* The force-free case of Vay (2008) as in WarpX's
 * Examples/Tests/particle_pusher: q = 1 C, m = 1 kg, B = 1 T z, the particle
 * at u = gamma v y with gamma = 20, E = -v x B = -v B x, dt = 0.01 s
 * (omega_c dt = q B dt / (gamma m) = 5e-4), 1e4 steps.  Exactly, E + v x B = 0
 * and the particle flies straight along y: x = z = 0.  Returns the largest
 * distance from the line over the run [m]. */
struct ff_acc {
    double dmax;
};
static int ff_cb(double t, const double x[3], const double u[3], void *ctx)
{
    (void)t, (void)u;
    struct ff_acc *a = ctx;
    const double d = hypot(x[0], x[2]);
    if (d > a->dmax) a->dmax = d;
    return 0;
}

static double force_free_deviation(const struct gcp_pusher_type *p)
{
    const double gam = 20.0;
    const double uy = sqrt(gam * gam - 1.0) * FO_C; /* u = gamma v */
    const double vy = uy / gam;
    const double B[3] = {0.0, 0.0, 1.0}, E[3] = {-vy * 1.0, 0.0, 0.0};
    struct gcp_field *f = gcp_field_uniform_create(B, E);
    cr_assert_not_null(f);
    double x[3] = {0.0, 0.0, 0.0}, u[3] = {0.0, uy, 0.0}, t = 0.0;
    struct ff_acc a = {0.0};
    const int st = gcp_orbit_push(f, p, 1.0, 1.0, &t, x, u, 0.01, 10000, ff_cb, &a);
    cr_assert_eq(st, GCP_ALIVE);
    gcp_field_free(f);
    return a.dmax;
}

/* Claim 2e: vay and higuera-cary keep the force-free particle within 1e-3 m
 * of its straight line over 1e4 steps (WarpX's tolerance; the particle
 * travels 3e10 m).
 *
 * Tolerance: both kicks have u = gamma V as an exact fixed point (Vay 2008,
 * HC 2017), so only round-off moves it: a momentum error du ~ eps u per
 * step starts a gyration of radius du / (q B / m) = eps * 6e9 / 1 ~ 1e-6 m,
 * accumulating to ~1e-4 m at worst over 1e4 steps (WarpX measured 1.0e-4
 * and 1.1e-4 m).  1e-3 m is WarpX's bound. */
Test(fo_exb, force_free_vay_higuera_cary_straight)
{
    const char *names[] = {"vay", "higuera-cary"};
    for (int i = 0; i < 2; i++) {
        const struct gcp_pusher_type *p = gcp_pusher_lookup(names[i]);
        cr_assert_not_null(p);
        const double d = force_free_deviation(p);
        cr_log_info("force-free %-13s: max distance from the line %.3e m", names[i], d);
        cr_expect(d < 1e-3, "%s: force-free particle left its line by %.3e m >= 1e-3 m",
                  names[i], d);
    }
}

/* Claim 2f: the Boris family is not force-free correct: u- = u + qdt E/2m
 * has a different gamma from u, so the magnetic rotation no longer cancels
 * the electric kicks and the particle starts to gyrate (WarpX measured
 * 2321 m for Boris).  Asserted: > 1 m, i.e. more than 1000x the Vay /
 * higuera-cary bound; boris-zu shares Boris's half-kicks and fails too. */
Test(fo_exb, force_free_boris_family_drifts)
{
    const char *names[] = {"boris", "boris-zu"};
    for (int i = 0; i < 2; i++) {
        const struct gcp_pusher_type *p = gcp_pusher_lookup(names[i]);
        cr_assert_not_null(p);
        const double d = force_free_deviation(p);
        cr_log_info("force-free %-13s: max distance from the line %.3e m", names[i], d);
        cr_expect(d > 1.0, "%s: force-free deviation only %.3e m", names[i], d);
    }
}
