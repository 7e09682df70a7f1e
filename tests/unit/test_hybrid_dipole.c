/* method = hybrid in Earth's dipole (issue 14): hysteresis, and the
 * gyro-averaged return to guiding centre. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include <criterion/criterion.h>

#include "gcpush/field.h"
#include "test_hybrid_util.h"

static struct gcp_field *earth(void);

/* A proton on the magnetic equator at L (B along +z there), kinetic energy W
 * [MeV], pitch a [deg]. */
static void proton_at(double L, double W, double a_deg, double x[3], double u[3])
{
    const double a = a_deg * GCP_PI / 180.0, d[3] = {0.0, sin(a), cos(a)};
    x[0] = L * GCP_EARTH_RADIUS, x[1] = x[2] = 0.0;
    hy_u_of(W * 1e6 * GCP_E_CHARGE, GCP_M_PROTON, d, u);
}

/* A proton on the dipole field line L at latitude frac x (its mirror
 * latitude), kinetic energy W [MeV], equatorial pitch a_eq [deg], moving
 * towards the equator: the local pitch follows from mu conservation,
 * sin^2 a = sin^2 a_eq B(lat)/B_eq, B(lat)/B_eq = sqrt(1 + 3 sin^2 lat)/cos^6 lat. */
static void proton_on_line(double L, double W, double a_eq_deg, double frac, double x[3], double u[3])
{
    const double s2 = pow(sin(a_eq_deg * GCP_PI / 180.0), 2);
    double lo = 0.0, hi = 1.5;
    for (int k = 0; k < 100; k++) {
        const double l = 0.5 * (lo + hi), c = cos(l);
        if (s2 * sqrt(1.0 + 3.0 * sin(l) * sin(l)) / pow(c, 6) < 1.0) lo = l;
        else hi = l;
    }
    const double lat = frac * lo, c = cos(lat), r = L * GCP_EARTH_RADIUS * c * c;
    x[0] = r * c, x[1] = 0.0, x[2] = r * sin(lat);
    struct gcp_field *f = earth();
    struct gcp_field_sample smp = {.need = GCP_NEED_B};
    gcp_field_eval(f, 0.0, x, &smp);
    gcp_field_free(f);
    const double Bm = sqrt(smp.B[0] * smp.B[0] + smp.B[1] * smp.B[1] + smp.B[2] * smp.B[2]);
    const double ratio = sqrt(1.0 + 3.0 * sin(lat) * sin(lat)) / pow(c, 6);
    const double sa = sqrt(s2 * ratio), ca = sqrt(1.0 - sa * sa);
    /* b lies in the x-z plane; yhat is perpendicular; towards the equator: -sign(z) along b_z */
    const double sgn = smp.B[2] * x[2] > 0.0 ? -1.0 : 1.0;
    double d[3];
    for (int k = 0; k < 3; k++) d[k] = sgn * ca * smp.B[k] / Bm + (k == 1 ? sa : 0.0);
    hy_u_of(W * 1e6 * GCP_E_CHARGE, GCP_M_PROTON, d, u);
}

static struct gcp_field *earth(void)
{
    return gcp_field_dipole_create(GCP_EARTH_B0, 0, GCP_EARTH_RADIUS + 1e5, 15 * GCP_EARTH_RADIUS);
}

/* Range of eps along the guiding-centre orbit (gc-rk8pd, no switching). */
struct eps_range {
    const struct gcp_field *f;
    double mu, lo, hi;
};

static int eps_cb(double t, const double X[3], double ppar, void *v)
{
    struct eps_range *c = v;
    double e;
    gcp_gc_adiabaticity(c->f, t, GCP_E_CHARGE, GCP_M_PROTON, X, ppar, c->mu, &e);
    c->lo = fmin(c->lo, e), c->hi = fmax(c->hi, e);
    return 0;
}

static void eps_along(const struct gcp_field *f, const double x[3], const double u[3], double T,
                      double *lo, double *hi)
{
    double X[3], ppar, mu, t = 0.0;
    gcp_gc_from_fo(f, 0.0, GCP_E_CHARGE, GCP_M_PROTON, x, u, X, &ppar, &mu);
    struct eps_range c = {f, mu, INFINITY, 0.0};
    const struct gcp_push_opts o = {.dt = 0.01, .nsteps = (int64_t)(T / 0.01), .tolerance = 1e-10};
    cr_assert_eq(gcp_gc_push(f, &gcp_pusher_gc_rk8pd, GCP_E_CHARGE, GCP_M_PROTON, &o, &t, X, &ppar,
                             mu, eps_cb, &c),
                 GCP_ALIVE);
    *lo = c.lo, *hi = c.hi;
}

static int32_t switches_of(const struct gcp_field *f, const double x[3], const double u[3],
                           double to_fo, double to_gc, double T)
{
    const struct gcp_hybrid_opts ho = {&gcp_pusher_gc_rk4, &gcp_pusher_boris, to_fo, to_gc, 0.05, 3};
    struct gcp_hybrid *h;
    struct gcp_block b;
    hy_push_one(f, &ho, GCP_E_CHARGE, GCP_M_PROTON, x, u, 0.01, (int64_t)(T / 0.01), NULL, NULL,
                &h, &b);
    cr_assert_eq(b.status[0], GCP_ALIVE);
    struct gcp_hybrid_lane_info info;
    gcp_hybrid_info(h, 0, &info);
    gcp_hybrid_free(h);
    gcp_block_free(&b);
    return info.switches;
}

/* A 10 MeV proton at L = 4, equatorial pitch 45 deg: eps = 0.071 at its
 * mirror points and 0.116 at the equator, twice per bounce.  With the
 * threshold in the middle (0.095) and the return at 0.05, below anything
 * the orbit reaches, it goes full orbit at the first equator and stays: one
 * switch in 4 bounces.  The control, the same threshold with a 5% gap
 * (return at 0.09), must flip back and forth (>= 4 switches): the count is
 * a real count of a real flip-flop, not a constant. */
Test(hybrid_dipole, hysteresis_counts_flips)
{
    struct gcp_field *f = earth();
    double x[3], u[3], lo, hi;
    proton_on_line(4.0, 10.0, 45.0, 0.9, x, u);
    const double T = 10.0; /* s: ~4 bounce periods of 2.4 s */
    eps_along(f, x, u, T, &lo, &hi);
    const double to_fo = 0.5 * (lo + hi);
    cr_assert(lo < to_fo && to_fo < hi && lo > 0.05, "setup: eps %g .. %g", lo, hi);
    const int32_t n_hyst = switches_of(f, x, u, to_fo, 0.05, T);
    const int32_t n_ctrl = switches_of(f, x, u, to_fo, 0.95 * to_fo, T);
    cr_assert_geq(n_hyst, 1, "eps crossed %g: it must switch", to_fo);
    cr_assert_leq(n_hyst, 2, "hovering at the threshold: %d switches", n_hyst);
    cr_assert_geq(n_ctrl, 4, "control without hysteresis: only %d switches", n_ctrl);
    cr_log_info("eps %.4g .. %.4g, switch_to_fo %.4g: %d switches with hysteresis, %d without", lo,
                hi, to_fo, n_hyst, n_ctrl);
    gcp_field_free(f);
}

/* ---- the gyro-averaged switches --------------------------------------------
 * A 5 MeV proton at L = 4, equatorial pitch 30 deg: eps = 0.029 at its mirror
 * points, 0.080 at the equator.  With switch_to_fo = 0.06 and switch_to_gc =
 * 0.04 it is a full orbit around each equator crossing and a guiding centre
 * near its mirror points: two switches per half-bounce.  mu is an adiabatic
 * invariant of the true orbit (a pure Boris run of this proton keeps its
 * gyro-averaged mu to 4e-4 per equator crossing).  The zeroth-order mu of
 * the first-order guiding centre, p_perp^2/(2 m B(X)), swings about it with
 * the gyrophase by delta_1 = c1 eps (c1 ~ 4 here: at 30 deg a small turn of b
 * moves much of p_par into p_perp); a switch built on one instantaneous
 * sample kicks mu by up to delta_1.  Averaged over whole gyrations (FO -> GC)
 * and with the trial-gyration correction (GC -> FO) the kick per
 * GC -> FO -> GC cycle is second order, c2 eps^2, so kick / delta_1 = O(eps)
 * where unaveraged switches give O(1).  Asserted: the largest change of mu
 * between consecutive returns is below 2 eps delta_1 (eps = switch_to_fo =
 * 0.06, where the full-orbit stretches begin); measured 0.089 delta_1 (mu
 * moves by at most 2.2% per cycle, -0.7% on average: the O(eps^2) terms of
 * the second-order transformation, not modelled); with the plain
 * gcp_fo_from_gc start instead it was ~0.25 delta_1 and mu ran away so far
 * that the proton stopped coming back. */
struct mu_watch {
    const struct gcp_hybrid *h;
    const struct gcp_field *f;
    int last;
    double ret_lo, ret_hi, inst_lo, inst_hi;
    double mu_prev, kick; /* [J/T] mu at the last return; largest relative change between returns */
    int nret;
};

static void watch_mu(const struct gcp_block *b, double t, void *vctx)
{
    struct mu_watch *c = vctx;
    if (b->n_active == 0 || !c->h) return;
    const int mode = gcp_hybrid_mode(c->h, b->index[0]);
    if (mode == GCP_MODE_GC && c->last == GCP_MODE_FO) {
        c->ret_lo = fmin(c->ret_lo, b->mu[0]), c->ret_hi = fmax(c->ret_hi, b->mu[0]);
        if (c->nret++) c->kick = fmax(c->kick, fabs(b->mu[0] / c->mu_prev - 1.0));
        c->mu_prev = b->mu[0];
    } else if (mode == GCP_MODE_FO) {
        const double x[3] = {b->x[0], b->y[0], b->z[0]}, u[3] = {b->ux[0], b->uy[0], b->uz[0]};
        double X[3], pp, mu;
        gcp_gc_from_fo(c->f, t, b->q, b->m, x, u, X, &pp, &mu);
        c->inst_lo = fmin(c->inst_lo, mu), c->inst_hi = fmax(c->inst_hi, mu);
    }
    c->last = mode;
}

Test(hybrid_dipole, averaged_switches_have_no_first_order_kick)
{
    struct gcp_field *f = earth();
    double x[3], u[3];
    proton_at(4.0, 5.0, 30.0, x, u);
    const struct gcp_hybrid_opts ho = {&gcp_pusher_gc_rk4, &gcp_pusher_boris, 0.06, 0.04, 0.05, 11};
    struct mu_watch w = {NULL, f, GCP_MODE_GC, INFINITY, 0.0, INFINITY, 0.0, 0.0, 0.0, 0};
    struct gcp_block b;
    cr_assert_eq(gcp_block_alloc(&b, 1), 0);
    b.q = GCP_E_CHARGE, b.m = GCP_M_PROTON;
    b.x[0] = x[0], b.y[0] = x[1], b.z[0] = x[2];
    b.ux[0] = u[0], b.uy[0] = u[1], b.uz[0] = u[2];
    struct gcp_hybrid *h;
    cr_assert_eq(gcp_hybrid_create(&h, 1, &ho), 0);
    cr_assert_eq(gcp_block_start(&b, f, 0.0), 1);
    gcp_hybrid_begin(h, &b, f, 0.0, 0);
    w.h = h;
    w.last = gcp_hybrid_mode(h, 0);
    /* 20 s: ~7 bounces, 14 equator crossings; dt 0.01 s ~ 0.08 gyro-periods */
    const struct gcp_push_opts o = {.t0 = 0.0, .dt = 0.01, .nsteps = 2000};
    const struct gcp_sampler smp = {1, watch_mu, &w};
    gcp_hybrid_advance(h, &b, f, &o, &smp);
    cr_assert_eq(b.status[0], GCP_ALIVE, "status %d at t = %g", b.status[0], b.t[0]);
    cr_assert_geq(w.nret, 5, "returns to guiding centre: %d", w.nret);
    const double mid = 0.5 * (w.ret_lo + w.ret_hi);
    const double half_swing = 0.5 * (w.inst_hi - w.inst_lo) / mid;
    cr_assert_gt(half_swing, 0.1, "setup: the instantaneous mu swings by only %.3g", half_swing);
    cr_log_info("%d returns, largest mu kick per cycle %.3g, instantaneous half-swing %.3g", w.nret,
                w.kick, half_swing);
    cr_assert_lt(w.kick, 2.0 * 0.06 * half_swing, "mu kicked by %.3g per cycle (instantaneous swing %.3g)",
                 w.kick, half_swing);
    gcp_hybrid_free(h);
    gcp_block_free(&b);
    gcp_field_free(f);
}
