/* method = hybrid against pure full orbits (issue 14): 10-50 MeV protons at
 * L = 4-6, where guiding-centre theory is at or past its edge (eps = 0.1 ..
 * 0.5 at the equator).  The hybrid pushes them as full orbits where eps >
 * 0.1 and as guiding centres where their mirror points reach eps < 0.05; its
 * bounce and drift periods, equatorial pitch angles after 10-40 bounces and
 * losses must agree with Boris runs of the same particles within the
 * statistical error of the ensemble. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <criterion/criterion.h>

#include "gcpush/field.h"
#include "test_hybrid_util.h"

/* Upward equator crossings of the guiding centre (z from - to +, linear
 * interpolation between samples) and the unwrapped azimuth there. */
struct crossings {
    const struct gcp_field *f;
    const struct gcp_hybrid *h; /* NULL: full-orbit samples */
    int have;
    double tp, zp, php;         /* previous sample */
    double phi_unw, phi_last;   /* unwrapped azimuth */
    int n;
    double t1, phi1, tn, phin;  /* first and last crossing */
    double alpha;               /* [rad] equatorial pitch angle at the last crossing */
};

/* Pitch angle at guiding centre X: sin^2 a = 2 m mu B / p^2. */
static double pitch_at(const struct gcp_field *f, double t, const double X[3], double ppar, double mu)
{
    struct gcp_field_sample s = {.need = GCP_NEED_B};
    gcp_field_eval(f, t, X, &s);
    const double w = 2.0 * GCP_M_PROTON * mu * sqrt(s.B[0] * s.B[0] + s.B[1] * s.B[1] + s.B[2] * s.B[2]);
    return asin(sqrt(w / (ppar * ppar + w)));
}

static void crossing_sample(struct crossings *c, double t, const double X[3], double ppar, double mu)
{
    double phi = atan2(X[1], X[0]);
    if (c->have) {
        double d = phi - c->phi_last;
        d -= 2.0 * GCP_PI * floor((d + GCP_PI) / (2.0 * GCP_PI));
        c->phi_unw += d;
    } else {
        c->phi_unw = phi;
    }
    c->phi_last = phi;
    if (c->have && c->zp < 0.0 && X[2] >= 0.0) {
        const double fr = -c->zp / (X[2] - c->zp);
        const double tc = c->tp + fr * (t - c->tp), pc = c->php + fr * (c->phi_unw - c->php);
        if (c->n++ == 0) c->t1 = tc, c->phi1 = pc;
        c->tn = tc, c->phin = pc;
        c->alpha = pitch_at(c->f, t, X, ppar, mu); /* the sample just past the equator */
    }
    c->have = 1;
    c->tp = t, c->zp = X[2], c->php = c->phi_unw;
}

static int fo_cb(double t, const double x[3], const double u[3], void *vctx)
{
    struct crossings *c = vctx;
    double X[3], pp, mu;
    if (gcp_gc_from_fo(c->f, t, GCP_E_CHARGE, GCP_M_PROTON, x, u, X, &pp, &mu)) return 1;
    crossing_sample(c, t, X, pp, mu);
    return 0;
}

static void hy_cb(const struct gcp_block *b, double t, void *vctx)
{
    struct crossings *c = vctx;
    if (b->n_active == 0 || !c->h) return;
    double X[3] = {b->x[0], b->y[0], b->z[0]}, pp = b->ppar[0], mu = b->mu[0];
    if (gcp_hybrid_mode(c->h, b->index[0]) == GCP_MODE_FO) {
        const double x[3] = {b->x[0], b->y[0], b->z[0]}, u[3] = {b->ux[0], b->uy[0], b->uz[0]};
        if (gcp_gc_from_fo(c->f, t, b->q, b->m, x, u, X, &pp, &mu)) return;
    }
    crossing_sample(c, t, X, pp, mu);
}

/* Bounce period = mean interval between upward crossings; drift period
 * 2 pi / (azimuth rate between the first and last crossing). */
static void periods(const struct crossings *c, double *Tb, double *Td)
{
    *Tb = c->n >= 3 ? (c->tn - c->t1) / (c->n - 1) : NAN;
    *Td = c->n >= 3 ? 2.0 * GCP_PI * (c->tn - c->t1) / fabs(c->phin - c->phi1) : NAN;
}

/* The ensemble of the issue: 10-50 MeV protons (log-uniform), L = 4-6,
 * equatorial pitch 20-70 deg, on a Kronecker (golden-ratio) sequence so the
 * three are spread without a random generator. */
#define NP 48

static void member(int k, double *W, double *L, double *a)
{
    const double g1 = 0.7548776662466927, g2 = 0.5698402909980532, g3 = 0.4098414;
    const double f1 = fmod(0.5 + g1 * k, 1.0), f2 = fmod(0.5 + g2 * k, 1.0), f3 = fmod(0.5 + g3 * k, 1.0);
    *W = 10.0 * pow(5.0, f1);
    *L = 4.0 + 2.0 * f2;
    *a = (20.0 + 50.0 * f3) * GCP_PI / 180.0;
}

Test(hybrid_periods, protons_agree_with_full_orbits)
{
    struct gcp_field *f = gcp_field_dipole_create(GCP_EARTH_B0, 0, GCP_EARTH_RADIUS + 1e5,
                                                  15 * GCP_EARTH_RADIUS);
    const struct gcp_hybrid_opts ho = {&gcp_pusher_gc_rk4, &gcp_pusher_boris,
                                       0.1, 0.05, 0.05, 42};
    double db[NP], dd[NP], da[NP];
    int n = 0, switched = 0, lost_f = 0, lost_h = 0;
    double fo_time = 0.0, all_time = 0.0;
    for (int k = 0; k < NP; k++) {
        double Wm, L, a;
        member(k, &Wm, &L, &a);
        const double d[3] = {0.0, sin(a), cos(a)}, x[3] = {L * GCP_EARTH_RADIUS, 0.0, 0.0};
        double u[3];
        hy_u_of(Wm * 1e6 * GCP_E_CHARGE, GCP_M_PROTON, d, u);
        const double T = 40.0; /* s: 10-40 bounces, 1/3 to 2 drift orbits */
        /* full orbit: Boris at 0.05 of the initial (equatorial, longest) gyro-period */
        const double B = GCP_EARTH_B0 / (L * L * L);
        const double Tg = 2.0 * GCP_PI * gcp_gamma_of_u(u[0], u[1], u[2]) * GCP_M_PROTON /
                          (GCP_E_CHARGE * B);
        struct crossings cf = {.f = f};
        double t = 0.0, xx[3] = {x[0], x[1], x[2]}, uu[3] = {u[0], u[1], u[2]};
        const int64_t nf = (int64_t)ceil(T / (0.05 * Tg));
        const int stf = gcp_orbit_push(f, &gcp_pusher_boris, GCP_E_CHARGE, GCP_M_PROTON, &t, xx,
                                       uu, T / (double)nf, nf, fo_cb, &cf);
        /* hybrid: GC step 0.01 s (~1/100 to 1/300 of a bounce) */
        struct crossings ch = {.f = f};
        struct gcp_hybrid *h;
        struct gcp_block b;
        cr_assert_eq(gcp_block_alloc(&b, 1), 0);
        b.q = GCP_E_CHARGE, b.m = GCP_M_PROTON;
        b.x[0] = x[0], b.y[0] = x[1], b.z[0] = x[2];
        b.ux[0] = u[0], b.uy[0] = u[1], b.uz[0] = u[2];
        cr_assert_eq(gcp_hybrid_create(&h, 1, &ho), 0);
        gcp_block_start(&b, f, 0.0);
        gcp_hybrid_begin(h, &b, f, 0.0, k);
        ch.h = h;
        hy_cb(&b, 0.0, &ch);
        const struct gcp_push_opts o = {.t0 = 0.0, .dt = 0.01, .nsteps = (int64_t)(T / 0.01)};
        const struct gcp_sampler smp = {1, hy_cb, &ch};
        gcp_hybrid_advance(h, &b, f, &o, &smp);
        const int sth = b.status[0];
        struct gcp_hybrid_lane_info info;
        gcp_hybrid_info(h, 0, &info);
        switched += info.switches > 0;
        fo_time += info.t_fo, all_time += info.t_fo + info.t_gc;
        gcp_hybrid_free(h);
        gcp_block_free(&b);
        lost_f += stf != GCP_ALIVE, lost_h += sth != GCP_ALIVE;
        double Tbf, Tdf, Tbh, Tdh;
        periods(&cf, &Tbf, &Tdf);
        periods(&ch, &Tbh, &Tdh);
        if (stf != GCP_ALIVE || sth != GCP_ALIVE || !isfinite(Tbf + Tbh + Tdf + Tdh)) continue;
        db[n] = Tbh / Tbf - 1.0;
        dd[n] = Tdh / Tdf - 1.0;
        da[n] = ch.alpha - cf.alpha;
        n++;
    }
    /* mean and standard error of the per-particle differences */
    double mb = 0.0, md = 0.0, ma = 0.0, sb = 0.0, sd = 0.0, sa = 0.0;
    for (int k = 0; k < n; k++) mb += db[k] / n, md += dd[k] / n, ma += da[k] / n;
    for (int k = 0; k < n; k++)
        sb += (db[k] - mb) * (db[k] - mb) / (n - 1), sd += (dd[k] - md) * (dd[k] - md) / (n - 1),
        sa += (da[k] - ma) * (da[k] - ma) / (n - 1);
    const double seb = sqrt(sb / n), sed = sqrt(sd / n), sea = sqrt(sa / n);
    /* The hybrid must really switch in this ensemble (those whose mirror
     * points reach eps < switch_to_gc); most of these protons are past the
     * guiding-centre edge everywhere and stay full orbits. */
    cr_assert_geq(switched, 4, "only %d of %d protons switched", switched, NP);
    cr_assert_lt(fo_time, all_time);
    /* Agreement within the statistical error.  Per particle the two runs
     * differ by chaos: at eps = 0.1-0.5 each equator crossing scatters the
     * pitch angle by an amount that depends on the gyrophase, so even two
     * Boris runs at different steps end with bounce periods up to 20% apart
     * (k = 7 here: no switch, 17%).  The ensemble means must agree: |mean of
     * T_hybrid/T_fo - 1| <= 3 standard errors (99.7% for a normal mean) plus
     * the guiding-centre model's systematic error on its stretches,
     * O(eps^2) <= switch_to_fo^2 = 1%.  Losses (precipitation) are counts:
     * they must agree within 3 Poisson standard deviations. */
    cr_assert_geq(n, NP - 6);
    cr_assert_leq(fabs(mb), 3.0 * seb + 0.01, "bounce periods: mean difference %.3g +- %.3g", mb, seb);
    cr_assert_leq(fabs(md), 3.0 * sed + 0.01, "drift periods: mean difference %.3g +- %.3g", md, sed);
    /* the equatorial pitch angle after 10-40 bounces (sampled within 0.01 rad
     * of latitude of the equator: B/B_eq - 1 < 5e-4, a bias far below the
     * scatter) within 3 standard errors */
    cr_assert_leq(fabs(ma), 3.0 * sea, "pitch after N bounces: mean difference %.3g +- %.3g rad", ma, sea);
    cr_assert_leq(abs(lost_h - lost_f), 3.0 * sqrt(lost_h + lost_f + 1.0), "lost: hybrid %d, full orbit %d",
                  lost_h, lost_f);
    /* measured (deterministic): 45 compared, 6 switched, 2 + 2 lost, full-orbit
     * share 0.994, bounce 2.3e-4 +- 7.7e-3, drift 9.8e-4 +- 3.1e-3, pitch
     * 1.2 +- 2.0 deg */
    cr_log_info("%d compared, %d switched, lost: Boris %d hybrid %d, full-orbit share %.3f, "
                "bounce %.2e +- %.2e, drift %.2e +- %.2e, pitch %.2e +- %.2e deg",
                n, switched, lost_f, lost_h, fo_time / all_time, mb, seb, md, sed,
                ma * 180 / GCP_PI, sea * 180 / GCP_PI);
    gcp_field_free(f);
}
