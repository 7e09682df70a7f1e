/* Full orbits in Earth's dipole against exact references computed here by
 * quadrature (GSL), over the battery of full-orbit pushers:
 *   - the equatorial Stormer problem (claim 4): radial period, azimuthal
 *     advance per radial period, drift period; gamma and P_phi kept;
 *   - the bounce motion off the equator (claim 5): mirror latitude and
 *     bounce period of a 1 MeV electron at L = 4, pitch 30 deg.
 *
 * Dipole of fields/dipole.c: moment along -z, B_z(equator) = +B0 (R_E/r)^3,
 * A_phi = -B0 R_E^3 sin(theta) / r^2 (so (1/r) d(r A_phi)/dr = B_z on the
 * equator).  K = B0 R_E^3 below.
 */
#include <criterion/criterion.h>
#include <gsl/gsl_errno.h>
#include <gsl/gsl_integration.h>
#include <gsl/gsl_roots.h>

#include "fo_test_util.h"

#define K_DIP (FO_B0 * FO_RE * FO_RE * FO_RE) /* [T m^3] */

/* ------------------------------------------------------------------------
 * The equatorial (Stormer) reference.
 *
 * In the equatorial plane a particle with velocity in the plane stays there
 * (B is along z there and the Lorentz force is in the plane).  Its energy
 * (|p| = p, gamma) and canonical angular momentum
 *   P_phi = r (p_phi + q A_phi) = r p_phi - q K / r
 * are constants, so p_phi(r) = (P_phi + q K / r) / r and
 *   p_r^2 = p^2 - p_phi(r)^2.
 * Start: r0, p_phi(r0) = +p (velocity along +phi_hat, a radial turning
 * point).  Then r^2 p_phi(r) = N(r) = p r r0 + q K (r0 - r) / r0 and
 *   p r^2 - N = (r - r0)(p r + q K / r0),
 *   p r^2 + N = p (r - r_near)(r - r_far),
 * so p^2 r^4 - N^2 = -p (r - r1)(r2 - r)(r - r_far)(p r + q K / r0), where
 * {r1, r2} = {r0, r_near} is the allowed radial range (the other turning
 * point r_near is the near root of p r^2 + (p r0 - qK/r0) r + q K = 0; r_far
 * is far away or negative).  With r = rm + h sin(th), rm = (r1+r2)/2,
 * h = (r2-r1)/2, the inverse-square-root end-point singularities cancel
 * exactly:  dr / p_r = dth / sqrt(G(r)),
 *   G(r) = -p (r - r_far)(p r + q K / r0) / r^4  (> 0 on [r1, r2]),
 * and over one radial period (r1 -> r2 -> r1)
 *   T_r  = 2 gamma m  Int_{-pi/2}^{pi/2} dth / sqrt(G),
 *   dphi = 2 Int_{-pi/2}^{pi/2} p_phi(r) / (r sqrt(G)) dth,
 * (dphi/dt = p_phi / (gamma m r), dr/dt = p_r / (gamma m)).  The integrands
 * are analytic in th; GSL's qag (61-point Gauss-Kronrod) gets them to
 * ~1e-15.  dphi is the net azimuth gained per radial period: the gyration
 * does not encircle the axis (rho << r), so no 2 pi branch enters; it is
 * the drift increment, > 0 (eastward) for electrons, < 0 for protons.
 * Drift period T_d = 2 pi T_r / |dphi|.
 * ------------------------------------------------------------------------ */
struct stormer {
    double q, m, p, gamma, r0;
    double r1, r2, rfar, rm, h;
    double Tr, dphi, Td; /* [s], [rad], [s] */
};

static double stormer_G(const struct stormer *s, double r)
{
    const double r2 = r * r;
    return -s->p * (r - s->rfar) * (s->p * r + s->q * K_DIP / s->r0) / (r2 * r2);
}

static double stormer_pphi(const struct stormer *s, double r)
{
    return (s->p * r * s->r0 + s->q * K_DIP * (s->r0 - r) / s->r0) / (r * r);
}

static double integrand_T(double th, void *ctx)
{
    const struct stormer *s = ctx;
    const double r = s->rm + s->h * sin(th);
    return 1.0 / sqrt(stormer_G(s, r));
}

static double integrand_phi(double th, void *ctx)
{
    const struct stormer *s = ctx;
    const double r = s->rm + s->h * sin(th);
    return stormer_pphi(s, r) / (r * sqrt(stormer_G(s, r)));
}

static double quad(double (*fn)(double, void *), void *ctx, double a, double b)
{
    gsl_set_error_handler_off(); /* report, never abort() */
    gsl_integration_workspace *w = gsl_integration_workspace_alloc(200);
    cr_assert_not_null(w);
    gsl_function F = {fn, ctx};
    double res, err;
    /* Absolute-error target from the integrand's gross size: max |f| over
     * a few points times the interval, times 1e-13 (~500 eps, what a
     * 61-point rule can certify).  dphi's net value is ~1e-3 of its gross
     * integral for the electron, so this is 1e-10 of the net: far below
     * the 1e-6 comparisons. */
    double fmax_ = 0.0;
    for (int i = 0; i <= 8; i++) fmax_ = fmax(fmax_, fabs(fn(a + (b - a) * (i + 0.5) / 9.5, ctx)));
    const double scale = fmax_ * (b - a);
    const int st = gsl_integration_qag(&F, a, b, 1e-13 * scale, 0.0, 200, GSL_INTEG_GAUSS61, w,
                                       &res, &err);
    gsl_integration_workspace_free(w);
    cr_assert_eq(st, 0, "GSL qag failed: %s (result %.17g, error %.3e, scale %.3e)",
                 gsl_strerror(st), res, err, scale);
    cr_assert(err <= 1e-13 * scale, "quadrature error %.3e of %.3e", err, res);
    return res;
}

static void stormer_reference(struct stormer *s, double q, double m, double T_kin, double r0)
{
    s->q = q, s->m = m, s->r0 = r0;
    const double u = fo_u_of_ekin(T_kin, m);
    s->p = m * u;
    s->gamma = sqrt(1.0 + u * u * GCP_INV_C2);
    const double b = s->p * r0 - q * K_DIP / r0, c0 = q * K_DIP;
    const double rnear = -2.0 * c0 / (b + copysign(sqrt(b * b - 4.0 * s->p * c0), b));
    s->rfar = c0 / (s->p * rnear);
    s->r1 = fmin(r0, rnear), s->r2 = fmax(r0, rnear);
    s->rm = 0.5 * (s->r1 + s->r2), s->h = 0.5 * (s->r2 - s->r1);
    s->Tr = 2.0 * s->gamma * m * quad(integrand_T, s, -0.5 * GCP_PI, 0.5 * GCP_PI);
    s->dphi = 2.0 * quad(integrand_phi, s, -0.5 * GCP_PI, 0.5 * GCP_PI);
    s->Td = 2.0 * GCP_PI * s->Tr / fabs(s->dphi);
}

/* ------------------------------------------------------------------------
 * Measuring the Stormer orbit (the pusher's discrete orbit).
 *
 * The drift per radial period is tiny against the gyration: for the 1 MeV
 * electron, dphi ~ 1.4e-6 rad while the azimuth swings by +-rho/r ~ 4e-4 rad
 * within each period, so turning-point sampling would need the turning
 * times to ~1e-13 s.  Instead the mean rates are read as weighted Birkhoff
 * averages (fo_test_util.h) along the discrete orbit, which is a
 * quasi-periodic orbit of a near-integrable map (rotation numbers: the
 * radial frequency * dt, and the drift): per step,
 *   omega_d  = < dphi_n > / dt,   dphi_n the azimuth turned in step n
 *              (atan2 of cross and dot of successive positions);
 *   omega_r  = < dth_n > / dt,    th the angle of the radial phase point
 *              ((r - rm)/h, u_r/|u|) about (0, 0), which lies inside the
 *              loop the orbit traces in that plane (a rotation number does
 *              not depend on the point or the scaling chosen);
 * then T_r = 2 pi / omega_r, dphi per T_r = omega_d T_r, T_d = 2 pi /
 * omega_d.  The smooth weight makes the error of these averages fall faster
 * than any power of the number of periods: over 150 radial periods the
 * drift period from the first half of the run agrees with the full run's
 * to ~1e-11 (asserted < 1e-8 in claim 4b).
 * ------------------------------------------------------------------------ */
struct storm_acc {
    const struct stormer *s;
    double x0, y0, th0, t0, Pphi0, u0;
    struct fo_birkhoff bphi, bth, bphi_half;
    double dPphi_max, du_max, zmax;
};

static double radial_angle(const struct stormer *s, const double x[3], const double u[3])
{
    const double r = hypot(x[0], x[1]);
    const double ur = (x[0] * u[0] + x[1] * u[1]) / r;
    return atan2(ur / fo_norm(u), (r - s->rm) / s->h);
}

static double canonical_pphi(const struct stormer *s, const double x[3], const double u[3])
{
    const double r = hypot(x[0], x[1]);
    return s->m * (x[0] * u[1] - x[1] * u[0]) - s->q * K_DIP / r;
}

static int storm_cb(double t, const double x[3], const double u[3], void *ctx)
{
    struct storm_acc *a = ctx;
    const double h = t - a->t0;
    const double dphi = fo_angle_between(a->x0, a->y0, x[0], x[1]);
    const double th = radial_angle(a->s, x, u);
    double dth = th - a->th0;
    dth -= 2.0 * GCP_PI * round(dth / (2.0 * GCP_PI));
    fo_birkhoff_add(&a->bphi, dphi / h);
    fo_birkhoff_add(&a->bphi_half, dphi / h);
    fo_birkhoff_add(&a->bth, dth / h);
    a->x0 = x[0], a->y0 = x[1], a->th0 = th, a->t0 = t;
    const double dP = fabs(canonical_pphi(a->s, x, u) - a->Pphi0);
    if (dP > a->dPphi_max) a->dPphi_max = dP;
    const double du = fabs(fo_norm(u) / a->u0 - 1.0);
    if (du > a->du_max) a->du_max = du;
    if (fabs(x[2]) > a->zmax) a->zmax = fabs(x[2]);
    return 0;
}

struct storm_meas {
    double Tr, dphi, Td;  /* measured */
    double Td_half;       /* from the first half of the run only */
    double dPphi_rel;     /* max |P_phi - P_phi0| / (r0 p) */
    double du_rel;        /* max ||u|/|u0| - 1| */
    double zmax;          /* [m] */
    int64_t nsteps;
};

/* Pushes the Stormer particle for `periods` radial periods at
 * omega_c(r0) dt = wdt. */
static struct storm_meas stormer_measure(const struct gcp_pusher_type *p, const struct stormer *s,
                                         double wdt, double periods)
{
    struct gcp_field *f = gcp_field_dipole_create(FO_B0, 0, 0.0, INFINITY);
    cr_assert_not_null(f);
    const double wc = fabs(s->q) * FO_B0 * pow(FO_RE / s->r0, 3) / (s->gamma * s->m);
    const double dt = wdt / wc;
    const int64_t n = (int64_t)ceil(periods * s->Tr / dt);
    double x[3] = {s->r0, 0.0, 0.0}, u[3] = {0.0, s->p / s->m, 0.0}, t = 0.0;
    struct storm_acc a = {.s = s, .x0 = x[0], .y0 = x[1], .t0 = 0.0, .u0 = fo_norm(u)};
    a.th0 = radial_angle(s, x, u);
    a.Pphi0 = canonical_pphi(s, x, u);
    fo_birkhoff_init(&a.bphi, n);
    fo_birkhoff_init(&a.bth, n);
    fo_birkhoff_init(&a.bphi_half, n / 2);
    const int st = gcp_orbit_push(f, p, s->q, s->m, &t, x, u, dt, n, storm_cb, &a);
    cr_assert_eq(st, GCP_ALIVE, "%s: status %d", p->name, st);
    cr_assert_eq(a.bphi.n, n);
    gcp_field_free(f);
    struct storm_meas r;
    const double wd = fo_birkhoff_mean(&a.bphi), wr = fabs(fo_birkhoff_mean(&a.bth));
    r.Tr = 2.0 * GCP_PI / wr;
    r.dphi = wd * r.Tr;
    r.Td = 2.0 * GCP_PI / fabs(wd);
    r.Td_half = 2.0 * GCP_PI / fabs(fo_birkhoff_mean(&a.bphi_half));
    r.dPphi_rel = a.dPphi_max / (s->r0 * s->p);
    r.du_rel = a.du_max;
    r.zmax = a.zmax;
    r.nsteps = n;
    return r;
}

struct storm_species {
    const char *label;
    double q, m, T;
};
static const struct storm_species proton10 = {"10 MeV proton", GCP_E_CHARGE, GCP_M_PROTON,
                                              10.0 * FO_MEV};
static const struct storm_species electron1 = {"1 MeV electron", -GCP_E_CHARGE, GCP_M_ELECTRON,
                                               1.0 * FO_MEV};

/* Claim 4a: the reference itself.  The turning points are roots of
 * |p_phi(r)| = p, and the quadratures must agree with an independent check:
 * first-order guiding-centre theory (gradient drift on the equator,
 * omega_d = 3 gamma m v^2 / (2 q B r^2) at the guiding-centre radius rm)
 * must match dphi / T_r to O(rho/L) ~ 3 rho / r: 1.2e-3 for the electron,
 * 0.12 for the proton (rho/r = 0.037), so within 3 (3 rho/r) + 1e-3.  (A
 * sign or factor-2 error in the reference would fail this.) */
Test(fo_dipole, stormer_reference_consistent)
{
    const struct storm_species *sp[] = {&proton10, &electron1};
    for (int i = 0; i < 2; i++) {
        struct stormer s;
        stormer_reference(&s, sp[i]->q, sp[i]->m, sp[i]->T, 4.0 * FO_RE);
        cr_assert(fabs(fabs(stormer_pphi(&s, s.r1)) / s.p - 1.0) < 1e-12);
        cr_assert(fabs(fabs(stormer_pphi(&s, s.r2)) / s.p - 1.0) < 1e-12);
        cr_assert(stormer_G(&s, s.r1) > 0.0 && stormer_G(&s, s.r2) > 0.0);
        const double v = s.p / (s.gamma * s.m), B = FO_B0 * pow(FO_RE / s.rm, 3);
        const double wd_gc = -3.0 * s.gamma * s.m * v * v / (2.0 * s.q * B * s.rm * s.rm);
        const double rho = s.p / (fabs(s.q) * B);
        const double rel = (s.dphi / s.Tr) / wd_gc - 1.0;
        cr_log_info("%s: r in [%.7f, %.7f] R_E, T_r = %.10e s, dphi = %.10e rad, T_d = %.10e s; "
                    "GC theory differs by %.3e (3 rho/r = %.2e)",
                    sp[i]->label, s.r1 / FO_RE, s.r2 / FO_RE, s.Tr, s.dphi, s.Td, rel,
                    3.0 * rho / s.rm);
        cr_expect(fabs(rel) < 3.0 * (3.0 * rho / s.rm) + 1e-3,
                  "%s: Stormer quadrature drift %.6e vs GC %.6e", sp[i]->label, s.dphi / s.Tr,
                  wd_gc);
        cr_expect(s.dphi * s.q < 0.0, "%s: drift direction (protons west, electrons east)",
                  sp[i]->label);
    }
}

/* Claim 4b: at converged dt (omega_c(r0) dt = 1.5e-3) every pusher gives
 * the radial period T_r, the azimuth gained per radial period dphi, and the
 * drift period T_d = 2 pi T_r / |dphi| of both particles within 1e-6 of
 * the quadratures.
 *
 * Tolerance: 1e-6 is the bound.  Expected: the second-order error
 * C (omega dt)^2 with the coefficients measured in claim 4c (C <= 0.11 for
 * T_r, dphi and T_d of every pusher and particle) gives <= 2.5e-7 at
 * omega dt = 1.5e-3; the Birkhoff measurement (over 150 radial periods)
 * and the quadrature contribute ~1e-9 (the boris/vay drift period of the
 * electron, whose dt^2 terms cancel, sits at 5e-10). */
Test(fo_dipole, stormer_converged_every_pusher)
{
    const struct storm_species *sp[] = {&proton10, &electron1};
    int runs = 0;
    for (int i = 0; i < 2; i++) {
        struct stormer s;
        stormer_reference(&s, sp[i]->q, sp[i]->m, sp[i]->T, 4.0 * FO_RE);
        FO_FOREACH(p)
        {
            const struct storm_meas r = stormer_measure(p, &s, 1.5e-3, 150.0);
            const double eTr = r.Tr / s.Tr - 1.0, eph = r.dphi / s.dphi - 1.0,
                         eTd = r.Td / s.Td - 1.0;
            cr_log_info("Stormer %s %-13s (%lld steps): T_r %+.2e, dphi %+.2e, T_d %+.2e "
                        "(T_d = %.9g s, ref %.9g s)",
                        sp[i]->label, p->name, (long long)r.nsteps, eTr, eph, eTd, r.Td, s.Td);
            cr_expect(fabs(eTr) < 1e-6, "%s %s: T_r off by %.3e", sp[i]->label, p->name, eTr);
            cr_expect(fabs(eph) < 1e-6, "%s %s: dphi off by %.3e", sp[i]->label, p->name, eph);
            cr_expect(fabs(eTd) < 1e-6, "%s %s: drift period off by %.3e", sp[i]->label,
                      p->name, eTd);
            /* the measurement's own error: half the run vs all of it;
             * 1e-8 keeps it 100x below the 1e-6 being tested */
            cr_expect(fabs(r.Td_half / r.Td - 1.0) < 1e-8,
                      "%s %s: Birkhoff average not converged (half run differs by %.3e)",
                      sp[i]->label, p->name, r.Td_half / r.Td - 1.0);
            runs++;
        }
    }
    cr_assert_geq(runs, 8);
}

/* Claim 4c: the errors fall as dt^order (2 for every pusher here): from
 * omega dt = 0.04 to 0.02 the errors of T_r, dphi and T_d divide by 4.
 *
 * Tolerance: e(dt) = C dt^2 (1 + D dt^2 + ...), so the ratio is
 * 4 (1 + (3/4) D (omega dt)^2) = 4 (1 + 1.2e-3 D) at omega dt = 0.04; with
 * D up to ~10 that is 1.2 %; the measurement floor (~1e-9, claim 4b) is
 * kept below 1 % of the errors used, by using only errors > 1e-7 at the
 * finer dt (the boris/vay drift period of the electron, whose leading
 * errors of T_r and dphi cancel, stays at the floor and is skipped; its
 * T_r and dphi are checked).  Ratio within 4 (1 +- 0.03). */
Test(fo_dipole, stormer_second_order_every_pusher)
{
    const struct storm_species *sp[] = {&proton10, &electron1};
    int checked = 0;
    for (int i = 0; i < 2; i++) {
        struct stormer s;
        stormer_reference(&s, sp[i]->q, sp[i]->m, sp[i]->T, 4.0 * FO_RE);
        FO_FOREACH(p)
        {
            const struct storm_meas a = stormer_measure(p, &s, 0.04, 300.0);
            const struct storm_meas b = stormer_measure(p, &s, 0.02, 300.0);
            const double ea[3] = {a.Tr / s.Tr - 1.0, a.dphi / s.dphi - 1.0, a.Td / s.Td - 1.0};
            const double eb[3] = {b.Tr / s.Tr - 1.0, b.dphi / s.dphi - 1.0, b.Td / s.Td - 1.0};
            const char *what[3] = {"T_r", "dphi", "T_d"};
            const double want = pow(2.0, p->order);
            int n = 0;
            for (int k = 0; k < 3; k++) {
                if (fabs(eb[k]) < 1e-7) continue;
                const double ratio = ea[k] / eb[k];
                cr_log_info("Stormer %s %-13s %-4s: e(0.04) = %+.4e, e(0.02) = %+.4e, ratio %.4f",
                            sp[i]->label, p->name, what[k], ea[k], eb[k], ratio);
                cr_expect(fabs(ratio / want - 1.0) < 0.03,
                          "%s %s %s: error ratio %.4f, expected %g +- 3%%", sp[i]->label,
                          p->name, what[k], ratio, want);
                n++;
            }
            cr_expect_geq(n, 2, "%s %s: fewer than two errors above the floor", sp[i]->label,
                          p->name);
            checked += n;
        }
    }
    cr_assert_geq(checked, 16);
}

/* Claim 4d: along the equatorial orbit every pusher keeps gamma (|u|) to
 * rounding, keeps the particle in the plane exactly, and keeps P_phi to
 * O((omega dt)^2) without secular drift.
 *
 * Tolerances: |u|: each kick is a rotation of u (E = 0), so, as in uniform
 * B, |u| moves by at most ~2 eps per step: 4 N eps.  z: on z = 0 the field
 * is exactly along z (Bx = By = -3 c z x / r^5 = 0) and u_z = 0 stays
 * exactly 0, so z == 0.0 exactly.  P_phi: none of these pushers conserves
 * the discrete momentum map exactly; as second-order, time-reversible
 * schemes their P_phi error is a bounded O((omega dt)^2) oscillation
 * (coefficients measured 0.013 boris/vay, 0.17 boris-zu, 0.22
 * higuera-cary, in units of r0 p); bound: (omega dt)^2 r0 p, 4x the
 * largest.  A secular drift of even O((omega dt)^3) per step would give
 * N (omega dt)^3 ~ 150 * 157 * 6.4e-5 = 1.5 over the run and fail. */
Test(fo_dipole, stormer_invariants_every_pusher)
{
    const struct storm_species *sp[] = {&proton10, &electron1};
    const double wdt = 0.04;
    int runs = 0;
    for (int i = 0; i < 2; i++) {
        struct stormer s;
        stormer_reference(&s, sp[i]->q, sp[i]->m, sp[i]->T, 4.0 * FO_RE);
        FO_FOREACH(p)
        {
            const struct storm_meas r = stormer_measure(p, &s, wdt, 150.0);
            cr_log_info("Stormer %s %-13s: max |d|u|/|u|| %.2e, max |dP_phi|/(r0 p) %.2e, "
                        "max |z| %g",
                        sp[i]->label, p->name, r.du_rel, r.dPphi_rel, r.zmax);
            cr_expect(r.du_rel < 4.0 * (double)r.nsteps * FO_EPS, "%s %s: |u| drifted by %.3e",
                      sp[i]->label, p->name, r.du_rel);
            cr_expect(r.zmax == 0.0, "%s %s: left the equatorial plane (%g m)", sp[i]->label,
                      p->name, r.zmax);
            cr_expect(r.dPphi_rel < wdt * wdt, "%s %s: P_phi moved by %.3e r0 p > (omega dt)^2",
                      sp[i]->label, p->name, r.dPphi_rel);
            runs++;
        }
    }
    cr_assert_geq(runs, 8);
}

/* ------------------------------------------------------------------------
 * Bounce motion off the equator (claim 5).
 *
 * Guiding-centre reference for a particle of equatorial pitch angle a on
 * the field line r = L R_E cos^2(lat):  ds = L R_E cos(l) sqrt(1 + 3 sin^2 l) dl,
 * B(l)/B_eq = sqrt(1 + 3 sin^2 l) / cos^6 l, and with mu and |p| kept,
 * v_par = v sqrt(1 - sin^2(a) B/B_eq).  The mirror latitude lm solves
 *   cos^6(lm) = sin^2(a) sqrt(1 + 3 sin^2 lm),
 * and the bounce period (four quarter bounces) is
 *   T_b = 4 Int_0^lm ds / v_par = (4 L R_E / v) T(sin a),
 *   T(y) = Int_0^lm cos(l) sqrt(1 + 3 sin^2 l) / sqrt(1 - y^2 sqrt(1 + 3 sin^2 l) / cos^6 l) dl.
 * (Normalisation check: T(0) is the field line's half length over L R_E,
 * Int_0^1 sqrt(1 + 3 x^2) dx = 1 + asinh(sqrt 3) / (2 sqrt 3) = 1.38017...,
 * asserted below.)  The inverse-square-root singularity at lm is removed by
 * l = lm sin(psi): dl = lm cos(psi) dpsi and 1 - B/B_m ~ (pi/2 - psi)^2 cancel.
 * ------------------------------------------------------------------------ */
static double mirror_fn(double l, void *ctx)
{
    const double y2 = *(const double *)ctx, c = cos(l), s = sin(l);
    return c * c * c * c * c * c - y2 * sqrt(1.0 + 3.0 * s * s);
}

static double mirror_latitude(double sina)
{
    double y2 = sina * sina;
    gsl_set_error_handler_off();
    gsl_root_fsolver *rs = gsl_root_fsolver_alloc(gsl_root_fsolver_brent);
    cr_assert_not_null(rs);
    gsl_function F = {mirror_fn, &y2};
    double lo = 0.0, hi = 0.5 * GCP_PI, l = 0.25 * GCP_PI;
    cr_assert_eq(gsl_root_fsolver_set(rs, &F, lo, hi), 0);
    for (int it = 0; it < 200; it++) {
        gsl_root_fsolver_iterate(rs);
        l = gsl_root_fsolver_root(rs);
        lo = gsl_root_fsolver_x_lower(rs), hi = gsl_root_fsolver_x_upper(rs);
        if (gsl_root_test_interval(lo, hi, 0.0, 4.0 * FO_EPS) == GSL_SUCCESS) break;
    }
    gsl_root_fsolver_free(rs);
    return l;
}

struct bounce_ctx {
    double y2, lm;
};

static double bounce_integrand(double psi, void *ctx)
{
    const struct bounce_ctx *b = ctx;
    const double l = b->lm * sin(psi), c = cos(l), s = sin(l);
    const double w = sqrt(1.0 + 3.0 * s * s);
    const double c6 = c * c * c * c * c * c;
    const double arg = 1.0 - b->y2 * w / c6;
    return b->lm * cos(psi) * c * w / sqrt(arg > 0.0 ? arg : 0.0);
}

/* T(y) for y = sin(a) with mirror latitude lm (pi/2 for y = 0). */
static double bounce_T(double sina, double lm)
{
    struct bounce_ctx b = {sina * sina, lm};
    gsl_set_error_handler_off();
    gsl_integration_workspace *w = gsl_integration_workspace_alloc(200);
    cr_assert_not_null(w);
    gsl_function F = {bounce_integrand, &b};
    double res, err;
    const int st = gsl_integration_qag(&F, 0.0, 0.5 * GCP_PI, 0.0, 1e-11, 200, GSL_INTEG_GAUSS61,
                                       w, &res, &err);
    gsl_integration_workspace_free(w);
    cr_assert_eq(st, 0, "GSL qag: %s", gsl_strerror(st));
    return res;
}

#define BOUNCE_L 4.0
#define BOUNCE_PITCH_DEG 30.0

/* Claim 5a: the bounce reference's normalisation: T(0) equals the closed
 * form 1 + asinh(sqrt 3)/(2 sqrt 3) to 1e-10 (quadrature tolerance 1e-11
 * relative), and the mirror latitude solves its equation. */
Test(fo_dipole, bounce_reference_normalised)
{
    const double T0 = bounce_T(0.0, 0.5 * GCP_PI);
    const double exact = 1.0 + asinh(sqrt(3.0)) / (2.0 * sqrt(3.0));
    cr_log_info("T(0) = %.15f, closed form %.15f", T0, exact);
    cr_assert(fabs(T0 / exact - 1.0) < 1e-10, "T(0) = %.15g, expected %.15g", T0, exact);
    const double y = sin(BOUNCE_PITCH_DEG * GCP_PI / 180.0);
    const double lm = mirror_latitude(y);
    double y2 = y * y;
    cr_assert(fabs(mirror_fn(lm, &y2)) < 1e-14);
    cr_log_info("a_eq = 30 deg: lm = %.10f deg, T(0.5) = %.12f", lm * 180.0 / GCP_PI,
                bounce_T(y, lm));
}

struct bounce_acc {
    double zprev, tprev;
    double tc[3];
    int nc;
    double latmax;
};

static int bounce_cb(double t, const double x[3], const double u[3], void *ctx)
{
    (void)u;
    struct bounce_acc *a = ctx;
    if (a->zprev < 0.0 && x[2] >= 0.0 && a->nc < 3)
        a->tc[a->nc++] = a->tprev + (t - a->tprev) * (0.0 - a->zprev) / (x[2] - a->zprev);
    const double lat = fabs(fo_latitude(x));
    if (lat > a->latmax) a->latmax = lat;
    a->zprev = x[2], a->tprev = t;
    return a->nc >= 2; /* two upward equator crossings: one full bounce between */
}

/* Claim 5b: a 1 MeV electron at L = 4 with equatorial pitch angle 30 deg,
 * started with its guiding centre on the equator at L R_E, mirrors at the
 * root lm of cos^6 = sin^2(a) sqrt(1 + 3 sin^2) within 0.05 deg, and
 * bounces with the period (4 L R_E / v) T(sin a) within 2e-3, for every
 * pusher.
 *
 * Set-up: x = X - (m/(qB^2)) B x u with B at X (fo_place_at_gc): the
 * guiding centre is at X to first order; the neglected O(rho^2/L_B) ~
 * (9.7 km)^2 / 8.5e6 m ~ 10 m shifts L by 4e-7, and lm does not depend on
 * L at all.  The initial gyrophase matters at first order: the
 * first-order corrections to the adiabatic invariant mu (terms in
 * rho . grad ln B and rho . kappa, kappa the field-line curvature, both
 * radial on the equator) change the mirror field by O(rho/L) as
 * cos(gyrophase).  Measured (boris, this particle): with the gyro-radius
 * vector radial, lm moves by +0.0486 / -0.0362 deg (phase 0 / 180 deg) and
 * T_b by +-1.05e-4, linear in rho (0.1, 1, 4 MeV: +0.011, +0.049, +0.153
 * deg) -- the first-order guiding-centre error, right at the 0.05 deg
 * tolerance; with it azimuthal (90 / 270 deg) those terms vanish and both
 * give +0.0061 deg, T_b within 2e-7; the mean over the four phases is also
 * +0.0062 deg.  So the particle starts with u_perp along the radius (its
 * gyro-radius vector azimuthal), where mu = p_perp^2/(2 m B(X)) holds to
 * O((rho/L)^2).  Step: omega_c dt = 0.05 at the mirror point
 * (B_m = 4 B_eq), 0.0125 at the equator.
 *
 * Measured quantities: T_b = time between two successive upward equator
 * crossings (linear interpolation in the step: at the equator z(t) has
 * z'' ~ 0, and B is along z there so the gyration does not move z); lm =
 * max |latitude| of the particle over the bounce, which exceeds the guiding
 * centre's by at most the gyro-radius at the mirror point projected on the
 * latitude direction: rho_m/r_m * 2 sin(lm)/sqrt(1+3 sin^2 lm) =
 * 2.43 km / 1.79e7 m * 0.79 = 1.08e-4 rad = 0.0062 deg (what is measured).
 *
 * Tolerances (derived, issue 13; were 0.05 deg and 2e-3): lm within
 * 1e-4 deg of lm + the projection above (computed here), i.e. the
 * neglected O((rho/L)^2) = (9.7 km / 8.5e6 m)^2 = 1.3e-6 rad = 7.5e-5 deg
 * of the first-order guiding centre; T_b within 2e-6 of the theory: the
 * same O((rho/L)^2) ~ 1.3e-6 relative, the pushers' O((omega dt)^2)
 * errors of the bounce motion being smaller (measured: all four within
 * 8.3e-8).  Measured: lm offset +0.0061 deg for every pusher. */
Test(fo_dipole, bounce_mirror_latitude_and_period_every_pusher)
{
    const double q = -GCP_E_CHARGE, m = GCP_M_ELECTRON;
    const double a = BOUNCE_PITCH_DEG * GCP_PI / 180.0, y = sin(a);
    const double umag = fo_u_of_ekin(1.0 * FO_MEV, m);
    const double gam = sqrt(1.0 + umag * umag * GCP_INV_C2), v = umag / gam;
    const double lm = mirror_latitude(y);
    const double Tb = 4.0 * BOUNCE_L * FO_RE / v * bounce_T(y, lm);
    const double Beq = FO_B0 / (BOUNCE_L * BOUNCE_L * BOUNCE_L);
    const double dt = 0.05 / (fabs(q) * 4.0 * Beq / (gam * m));
    struct gcp_field *f = gcp_field_dipole_create(FO_B0, 0, FO_RE, INFINITY);
    cr_assert_not_null(f);
    /* the particle's latitude beyond its guiding centre's at the mirror
     * point: rho_m / r_m * 2 sin(lm) / sqrt(1 + 3 sin^2 lm) (see above) */
    const double rho_m = gam * m * v / (fabs(q) * Beq / (y * y));
    const double r_m = BOUNCE_L * FO_RE * cos(lm) * cos(lm);
    const double dlat_exp = rho_m / r_m * 2.0 * sin(lm) / sqrt(1.0 + 3.0 * sin(lm) * sin(lm)) *
                            180.0 / GCP_PI;
    int runs = 0;
    FO_FOREACH(p)
    {
        const double X[3] = {BOUNCE_L * FO_RE, 0.0, 0.0};
        /* u_perp radial: the gyro-radius vector is azimuthal (see above) */
        double u[3] = {umag * y, 0.0, umag * cos(a)}, x[3], t = 0.0;
        cr_assert_eq(fo_place_at_gc(f, q, m, X, u, x), 0);
        struct bounce_acc acc = {.zprev = x[2], .tprev = 0.0, .nc = 0, .latmax = 0.0};
        const int64_t nmax = (int64_t)(2.2 * Tb / dt);
        const int st = gcp_orbit_push(f, p, q, m, &t, x, u, dt, nmax, bounce_cb, &acc);
        cr_assert_eq(st, GCP_ALIVE, "%s: status %d", p->name, st);
        cr_assert_eq(acc.nc, 2, "%s: %d equator crossings", p->name, acc.nc);
        const double Tm = acc.tc[1] - acc.tc[0];
        const double dlat = (acc.latmax - lm) * 180.0 / GCP_PI;
        cr_log_info("bounce %-13s: lm %.5f deg (ref %.5f, diff %+.5f deg, expected %+.5f), "
                    "T_b %.8g s (ref %.8g s, rel %+.3e), first crossing at %.8g s",
                    p->name, acc.latmax * 180.0 / GCP_PI, lm * 180.0 / GCP_PI, dlat, dlat_exp,
                    Tm, Tb, Tm / Tb - 1.0, acc.tc[0]);
        cr_expect(fabs(dlat - dlat_exp) < 1e-4, "%s: mirror latitude off by %.5f deg, "
                  "expected %.5f deg", p->name, dlat, dlat_exp);
        cr_expect(fabs(Tm / Tb - 1.0) < 2e-6, "%s: bounce period off by %.3e", p->name,
                  Tm / Tb - 1.0);
        runs++;
    }
    gcp_field_free(f);
    cr_assert_geq(runs, 4);
}
