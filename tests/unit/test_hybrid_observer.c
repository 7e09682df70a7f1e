/* The invariant observer on method = hybrid (issue 14). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <criterion/criterion.h>

#include "gcpush/field.h"
#include "gcpush/invariants.h"
#include "test_hybrid_util.h"

static struct gcp_field *earth(void)
{
    return gcp_field_dipole_create(GCP_EARTH_B0, 0, GCP_EARTH_RADIUS + 1e5, 15 * GCP_EARTH_RADIUS);
}

/* A proton on the dipole field line L at latitude frac x (its mirror
 * latitude), kinetic energy W [MeV], equatorial pitch a_eq [deg], gyrophase
 * ph, moving towards the equator (mu conservation for the local pitch). */
static void proton_on_line(const struct gcp_field *f, double L, double W, double a_eq_deg,
                           double frac, double ph, double x[3], double u[3])
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
    struct gcp_field_sample smp = {.need = GCP_NEED_B};
    gcp_field_eval(f, 0.0, x, &smp);
    const double Bm = sqrt(smp.B[0] * smp.B[0] + smp.B[1] * smp.B[1] + smp.B[2] * smp.B[2]);
    double b[3] = {smp.B[0] / Bm, smp.B[1] / Bm, smp.B[2] / Bm};
    const double ratio = sqrt(1.0 + 3.0 * sin(lat) * sin(lat)) / pow(c, 6);
    const double sa = sqrt(s2 * ratio), ca = sqrt(1.0 - sa * sa);
    const double sgn = smp.B[2] * x[2] > 0.0 ? -1.0 : 1.0;
    /* e1 = yhat, e2 = b x e1: both perpendicular to b (b in the x-z plane) */
    const double e1[3] = {0, 1, 0}, e2[3] = {b[1] * e1[2] - b[2] * e1[1], b[2] * e1[0] - b[0] * e1[2],
                                            b[0] * e1[1] - b[1] * e1[0]};
    double d[3];
    for (int k = 0; k < 3; k++) d[k] = sgn * ca * b[k] + sa * (cos(ph) * e1[k] + sin(ph) * e2[k]);
    hy_u_of(W * 1e6 * GCP_E_CHARGE, GCP_M_PROTON, d, u);
}

/* Pushes n protons (x, u) with the observer (bounce, mu, L); method = hybrid
 * (ho) or the full-orbit method fo at dt. */
static void observe_n(const struct gcp_field *f, const struct gcp_hybrid_opts *ho,
                      const struct gcp_pusher_type *fo, size_t n, double (*x)[3], double (*u)[3],
                      double dt, int64_t nsteps, struct gcp_events *ev)
{
    struct gcp_block b;
    cr_assert_eq(gcp_block_alloc(&b, n), 0);
    b.q = GCP_E_CHARGE, b.m = GCP_M_PROTON;
    for (size_t i = 0; i < n; i++) {
        b.x[i] = x[i][0], b.y[i] = x[i][1], b.z[i] = x[i][2];
        b.ux[i] = u[i][0], b.uy[i] = u[i][1], b.uz[i] = u[i][2];
    }
    cr_assert_eq(gcp_block_start(&b, f, 0.0), n);
    struct gcp_hybrid *h = NULL;
    if (ho) {
        cr_assert_eq(gcp_hybrid_create(&h, n, ho), 0);
        gcp_hybrid_begin(h, &b, f, 0.0, 0);
    }
    struct gcp_observer *o;
    const struct gcp_observer_opts oo = {.invariants = GCP_INV_MU | GCP_INV_K, .events = GCP_EVT_BOUNCE};
    cr_assert_eq(gcp_observer_create(&o, n, f, ho ? &gcp_pusher_hybrid : fo, &oo), 0);
    gcp_observer_begin(o, &b, 0.0, 0, ev);
    const struct gcp_push_opts po = {.t0 = 0.0, .dt = dt, .nsteps = nsteps};
    if (ho) {
        const struct gcp_hybrid_observer hob = {gcp_observer_sample_mode, o};
        gcp_hybrid_set_observer(h, &hob);
        gcp_hybrid_observe(h, &b, 0.0);
        gcp_hybrid_advance(h, &b, f, &po, NULL);
    } else {
        const struct gcp_sampler smp = {1, gcp_observer_sample, o};
        fo->advance(&b, f, fo, &po, &smp);
    }
    cr_assert_eq(gcp_observer_end(o, &b), 0);
    cr_assert_eq(gcp_events_sort(ev), 0);
    gcp_observer_free(o);
    gcp_hybrid_free(h);
    gcp_block_free(&b);
}

/* Relative changes of the bounce-averaged mu between successive bounces of
 * each particle (ids 0..n-1): their mean square and mean fourth power. */
static int64_t jumps(const struct gcp_events *ev, int n, double *m2, double *m4, int64_t *n_fo)
{
    int64_t cnt = 0;
    *m2 = *m4 = 0;
    if (n_fo) *n_fo = 0;
    for (int i = 0; i < n; i++) {
        double prev = NAN;
        for (int64_t k = 0; k < ev->n; k++) {
            const struct gcp_event *e = &ev->e[k];
            if (e->id != i || e->kind != GCP_EVENT_BOUNCE) continue;
            const double mu = e->v[GCP_BOUNCE_MU];
            if (n_fo && e->status == GCP_MODE_FO) (*n_fo)++;
            if (isfinite(prev)) {
                const double r = mu / prev - 1.0;
                *m2 += r * r, *m4 += r * r * r * r, cnt++;
            }
            prev = mu;
        }
    }
    if (cnt) *m2 /= (double)cnt, *m4 /= (double)cnt;
    return cnt;
}

/* Per-bounce changes of mu, the observer's bounce-averaged mu (GCP_BOUNCE_MU),
 * of 16 protons (gyrophases 2 pi i / 16, starting at 0.9 of the mirror
 * latitude towards the equator) over 12 bounce periods, pushed with method =
 * hybrid (gc-rk4 / boris, switch_to_fo 0.1, switch_to_gc 0.05, the GC step
 * 0.01 bounce) and with pure Boris (0.05 of the start's gyro-period). */
struct jump_stats {
    double rms, sigma; /* RMS of mu_{k+1}/mu_k - 1; its standard error */
    int64_t n, n_fo, n_gc_mu, n_switch;
};

static void jump_stats_of(double W, double L, double a_eq, int hybrid, struct jump_stats *js)
{
    struct gcp_field *f = earth();
    enum { N = 16 };
    double x[N][3], u[N][3];
    for (int i = 0; i < N; i++) proton_on_line(f, L, W, a_eq, 0.9, 2 * GCP_PI * i / N, x[i], u[i]);
    const struct gcp_species sp = {"proton", GCP_E_CHARGE, GCP_M_PROTON};
    double Tg, Tb;
    cr_assert_eq(gcp_period_of(f, "dipole", &sp, x[0], u[0], GCP_PERIOD_GYRO, &Tg), 0);
    cr_assert_eq(gcp_period_of(f, "dipole", &sp, x[0], u[0], GCP_PERIOD_BOUNCE, &Tb), 0);
    const struct gcp_hybrid_opts ho = {.gc = &gcp_pusher_gc_rk4, .fo = &gcp_pusher_boris,
                                       .to_fo = 0.1, .to_gc = 0.05, .fo_dt = 0.05, .seed = 7};
    struct gcp_events ev = {0};
    const double dt = hybrid ? 0.01 * Tb : 0.05 * Tg;
    observe_n(f, hybrid ? &ho : NULL, &gcp_pusher_boris, N, x, u, dt, (int64_t)(12 * Tb / dt), &ev);
    double m2, m4;
    memset(js, 0, sizeof *js);
    js->n = jumps(&ev, N, &m2, &m4, &js->n_fo);
    cr_assert_gt(js->n, 100);
    /* the standard error of an RMS from n samples: var(r^2) / (4 n <r^2>^2) */
    js->rms = sqrt(m2);
    js->sigma = js->rms * sqrt((m4 / (m2 * m2) - 1.0) / (4.0 * (double)js->n));
    for (int64_t k = 0; k < ev.n + ev.ns; k++) {
        const struct gcp_event e = gcp_events_get(&ev, k);
        js->n_gc_mu += e.kind == GCP_EVENT_MU && e.status == GCP_MODE_GC;
        js->n_switch += e.kind == GCP_EVENT_BOUNCE && e.status == GCP_MODE_GC;
    }
    gcp_events_free(&ev);
    gcp_field_free(f);
}

/* A 30 MeV proton at L = 5, equatorial pitch 20 deg (rho / R_c ~ 0.3 at the
 * equator): field-line curvature scatters mu at each equator crossing, by
 * 38% RMS per bounce in the pure Boris run.  The hybrid run's observer
 * follows it across the switches -- gyro-averaged on the full-orbit
 * stretches, the GC's own mu on the guiding-centre ones -- and must show the
 * same jumps: the two RMS values (16 particles x ~10 bounces, phases
 * independent: the hybrid draws its gyrophase at each switch, Boris's is
 * scrambled by the scattering itself) agree within 3 standard errors of their
 * difference (each ~0.02 absolute, from the sample's fourth moment).  A
 * 1 MeV proton on the same line (rho / R_c ~ 0.05) is the control: its mu
 * changes by < 1e-3 per bounce in both runs, so the jumps are the
 * scattering, not the observer.
 * The switches' own kicks, which the observer reports as they are, were
 * measured with it: see switch_cycle_keeps_mu_to_first_order below. */
Test(hybrid_observer, curvature_scattering_mu_jumps_as_boris)
{
    struct jump_stats h, b, hc, bc;
    jump_stats_of(30.0, 5.0, 20.0, 1, &h);
    jump_stats_of(30.0, 5.0, 20.0, 0, &b);
    cr_log_info("30 MeV, L = 5, 20 deg: RMS mu jump per bounce hybrid %.4f +- %.4f (%lld jumps; "
                "%lld equator rows in GC mode), boris %.4f +- %.4f (%lld)", h.rms, h.sigma,
                (long long)h.n, (long long)h.n_gc_mu, b.rms, b.sigma, (long long)b.n);
    /* the hybrid run went both ways: rows from GC steps and from gyrations */
    cr_assert_gt(h.n_fo, 10);
    cr_assert_gt(h.n_gc_mu + h.n_switch, 10);
    cr_assert(fabs(h.rms - b.rms) < 3.0 * hypot(h.sigma, b.sigma),
              "RMS mu jump: hybrid %.4f +- %.4f, boris %.4f +- %.4f", h.rms, h.sigma, b.rms, b.sigma);
    jump_stats_of(1.0, 5.0, 20.0, 1, &hc);
    jump_stats_of(1.0, 5.0, 20.0, 0, &bc);
    cr_log_info("control 1 MeV: hybrid %.2e, boris %.2e", hc.rms, bc.rms);
    cr_assert(hc.rms < 1e-3 && bc.rms < 1e-3 && b.rms > 100 * bc.rms);
}

/* Issue 14's regime where the switches themselves scattered mu: a 20 MeV
 * proton at L = 5, equatorial pitch 25 deg.  With single-gyration windows
 * the hybrid's RMS per-bounce mu jump was 1.4 x Boris's (0.203 +- 0.018
 * against 0.143 +- 0.009 here: 2.9 standard errors of the difference, 3.7
 * in the run); with the two-gyration windows it is 0.154 +- 0.012
 * (0.7).  Same statistics and bound as the 30 MeV test above. */
Test(hybrid_observer, curvature_scattering_20mev_agrees_with_boris)
{
    struct jump_stats h, b;
    jump_stats_of(20.0, 5.0, 25.0, 1, &h);
    jump_stats_of(20.0, 5.0, 25.0, 0, &b);
    cr_log_info("20 MeV, L = 5, 25 deg: RMS mu jump per bounce hybrid %.4f +- %.4f (%lld), boris "
                "%.4f +- %.4f (%lld)", h.rms, h.sigma, (long long)h.n, b.rms, b.sigma, (long long)b.n);
    cr_assert(fabs(h.rms - b.rms) < 3.0 * hypot(h.sigma, b.sigma),
              "RMS mu jump: hybrid %.4f +- %.4f, boris %.4f +- %.4f", h.rms, h.sigma, b.rms, b.sigma);
}

/* Per-lane record of the GC -> FO -> GC cycles: the GC state at the last
 * GC step before a switch to FO, and the relative change of mu over each
 * cycle against its first-order bound. */
enum { CYC_N = 16 };
struct cycles {
    const struct gcp_field *f;
    double to_fo, to_gc;
    int in_fo[CYC_N], have[CYC_N];
    double mu[CYC_N], ppar[CYC_N], X[CYC_N][3];
    double sum2, sum, n;
};

static void cycles_obs(const struct gcp_block *v, double t, int mode, void *vctx)
{
    struct cycles *c = vctx;
    for (size_t j = 0; j < v->n_active; j++) {
        const size_t k = v->index[j];
        if (mode == GCP_MODE_FO) {
            c->in_fo[k] = 1;
            continue;
        }
        if (c->in_fo[k] && c->have[k]) {
            /* A first-order pair of transformations leaves O(eps^2 p) in
             * p_par at each switch (eps = switch_to_fo going out,
             * switch_to_gc coming back); with the energy fixed that moves mu
             * by d mu / mu = 2 p_par d p_par / p_perp^2. */
            struct gcp_field_sample s = {.need = GCP_NEED_B};
            gcp_field_eval(c->f, t, c->X[k], &s);
            const double B = sqrt(s.B[0] * s.B[0] + s.B[1] * s.B[1] + s.B[2] * s.B[2]);
            const double pperp2 = 2.0 * v->m * c->mu[k] * B;
            const double p = sqrt(pperp2 + c->ppar[k] * c->ppar[k]);
            const double bound =
                2.0 * fabs(c->ppar[k]) * p * (c->to_fo * c->to_fo + c->to_gc * c->to_gc) / pperp2;
            const double r = (v->mu[j] / c->mu[k] - 1.0) / bound;
            c->sum2 += r * r, c->sum += r, c->n++;
        }
        c->in_fo[k] = 0, c->have[k] = 1;
        c->mu[k] = v->mu[j], c->ppar[k] = v->ppar[j];
        c->X[k][0] = v->x[j], c->X[k][1] = v->y[j], c->X[k][2] = v->z[j];
    }
}

/* Issue 14: a 5 MeV proton at L = 6, equatorial pitch 25 deg (eps 0.19 at
 * the equator) switches to FO at eps = 0.1 on the way in and back at 0.05
 * on the way out, once per half bounce.  Boris keeps its mu to a few
 * percent per crossing; the hybrid's mu moved by -12% +- 16% per
 * GC -> FO -> GC cycle (each switch averaged over one gyration, where the
 * gyrophase oscillation of the instantaneous guiding centre does not
 * cancel, and the way in corrected once).  The change of each cycle, in
 * units of its first-order bound (cycles_obs), must have an RMS below 1
 * over the 16 protons x 3 bounces (it was 1.2, with a mean of -1.0). */
Test(hybrid_observer, switch_cycle_keeps_mu_to_first_order)
{
    struct gcp_field *f = earth();
    double x[CYC_N][3], u[CYC_N][3];
    for (int i = 0; i < CYC_N; i++)
        proton_on_line(f, 6.0, 5.0, 25.0, 0.9, 2 * GCP_PI * i / CYC_N, x[i], u[i]);
    const struct gcp_species sp = {"proton", GCP_E_CHARGE, GCP_M_PROTON};
    double Tb;
    cr_assert_eq(gcp_period_of(f, "dipole", &sp, x[0], u[0], GCP_PERIOD_BOUNCE, &Tb), 0);
    const struct gcp_hybrid_opts ho = {.gc = &gcp_pusher_gc_rk4, .fo = &gcp_pusher_boris,
                                       .to_fo = 0.1, .to_gc = 0.05, .fo_dt = 0.05, .seed = 7};
    struct gcp_block b;
    cr_assert_eq(gcp_block_alloc(&b, CYC_N), 0);
    b.q = GCP_E_CHARGE, b.m = GCP_M_PROTON;
    for (int i = 0; i < CYC_N; i++) {
        b.x[i] = x[i][0], b.y[i] = x[i][1], b.z[i] = x[i][2];
        b.ux[i] = u[i][0], b.uy[i] = u[i][1], b.uz[i] = u[i][2];
    }
    cr_assert_eq(gcp_block_start(&b, f, 0.0), CYC_N);
    struct gcp_hybrid *h = NULL;
    cr_assert_eq(gcp_hybrid_create(&h, CYC_N, &ho), 0);
    gcp_hybrid_begin(h, &b, f, 0.0, 0);
    struct cycles c = {.f = f, .to_fo = ho.to_fo, .to_gc = ho.to_gc};
    const struct gcp_hybrid_observer hob = {cycles_obs, &c};
    gcp_hybrid_set_observer(h, &hob);
    gcp_hybrid_observe(h, &b, 0.0);
    const double dt = 0.01 * Tb;
    const struct gcp_push_opts po = {.t0 = 0.0, .dt = dt, .nsteps = (int64_t)(3 * Tb / dt)};
    gcp_hybrid_advance(h, &b, f, &po, NULL);
    const double rms = sqrt(c.sum2 / c.n), mean = c.sum / c.n;
    cr_log_info("5 MeV, L = 6, 25 deg: %.0f cycles, mu change / first-order bound: RMS %.2f, "
                "mean %+.2f", c.n, rms, mean);
    cr_assert_gt(c.n, 30);
    cr_assert_lt(rms, 1.0, "mu change per cycle / bound: RMS %.2f, mean %+.2f", rms, mean);
    gcp_hybrid_free(h);
    gcp_block_free(&b);
    gcp_field_free(f);
}
