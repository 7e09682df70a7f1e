/* method = hybrid (issue 14): a particle that stays adiabatic is the plain
 * guiding-centre run bit for bit; a particle crossing the weak-field ring of
 * the mirror switches to full orbit and back with its energy kept to the
 * pushers' own bounds; hysteresis keeps a particle whose eps hovers at the
 * threshold from flipping; the gyro-averaged return carries no O(eps) kick. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <criterion/criterion.h>

#include "gcpush/field.h"
#include "test_hybrid_util.h"

static const char *const electron_run =
    "[scene]\nname = e\nfield = dipole\nduration = 3 bounce\nseed = 5\n"
    "[particles]\nspecies = electron\ncount = 5\nenergy = 1 MeV\nL = 4\n"
    "pitch = 20 deg .. 90 deg\n"
    "[integrator]\n%s\ndt = 0.02 bounce\n"
    "[output]\nfile = unused.h5\ntrajectory = %s\n";

/* 1 MeV electrons at L = 4 have eps = rho/L_B ~ 1e-3, two orders below
 * switch_to_fo = 0.1: they never switch, and the hybrid pushes them with the
 * very calls of the plain run, so every number is identical (not close). */
static void same_as_plain(const char *gc, const char *traj)
{
    char plain[1024], hyb[1024], m1[64], m2[96];
    snprintf(m1, sizeof m1, "method = %s", gc);
    snprintf(m2, sizeof m2, "method = hybrid\ngc = %s", gc);
    snprintf(plain, sizeof plain, electron_run, m1, traj);
    snprintf(hyb, sizeof hyb, electron_run, m2, traj);
    struct gcp_scene *sp, *sh;
    struct gcp_results rp, rh;
    hy_run_text(plain, &sp, &rp);
    hy_run_text(hyb, &sh, &rh);
    cr_assert_eq(rp.n, 5);
    cr_assert_eq(rh.n, 5);
    for (int64_t k = 0; k < rp.n; k++) {
        cr_assert_eq(rh.hy_switches[k], 0, "particle %lld switched", (long long)k);
        cr_assert_eq(rh.hy_mode[k], GCP_MODE_GC);
        cr_assert_eq(rh.hy_t_fo[k], 0.0);
        cr_assert_eq(rp.status[k], GCP_ALIVE);
        cr_assert_eq(rh.status[k], GCP_ALIVE);
        cr_assert_eq(rh.steps[k], rp.steps[k]);
        cr_assert_eq(memcmp(&rh.t[k], &rp.t[k], sizeof(double)), 0);
        cr_assert_eq(memcmp(&rh.Xf[3 * k], &rp.x[3 * k], 3 * sizeof(double)), 0,
                     "%s particle %lld: X differs", gc, (long long)k);
        cr_assert_eq(memcmp(&rh.ppar[k], &rp.ppar[k], sizeof(double)), 0);
        cr_assert_eq(memcmp(&rh.mu[k], &rp.mu[k], sizeof(double)), 0);
        cr_assert_eq(memcmp(&rh.X0[3 * k], &rp.X0[3 * k], 3 * sizeof(double)), 0);
        /* the full-orbit form of the final state is a particle with that guiding centre */
        double X[3], pp, mu;
        gcp_gc_from_fo(sh->field, rh.t[k], sh->pops[0].species.charge, sh->pops[0].species.mass,
                       &rh.x[3 * k], &rh.u[3 * k], X, &pp, &mu);
        for (int d = 0; d < 3; d++) cr_assert_float_eq(X[d], rh.Xf[3 * k + d], 1e-6 * 4 * GCP_EARTH_RADIUS);
        if (rp.S) {
            cr_assert_eq(rh.traj_count[k], rp.traj_count[k]);
            const int64_t c = rp.traj_count[k];
            cr_assert_gt(c, 10);
            cr_assert_eq(memcmp(&rh.traj_x[3 * k * rp.S], &rp.traj_x[3 * k * rp.S],
                                (size_t)(3 * c) * sizeof(double)), 0);
            cr_assert_eq(memcmp(&rh.traj_ppar[k * rp.S], &rp.traj_ppar[k * rp.S],
                                (size_t)c * sizeof(double)), 0);
            for (int64_t j = 0; j < c; j++) cr_assert_eq(rh.traj_mode[k * rp.S + j], GCP_MODE_GC);
        }
    }
    cr_assert_eq(rh.ev.n, 0);
    gcp_results_free(&rp);
    gcp_results_free(&rh);
    gcp_scene_free(sp);
    gcp_scene_free(sh);
}

Test(hybrid, adiabatic_electron_is_the_plain_gc_run)
{
    same_as_plain("gc-rk4", "every 5 steps");
    same_as_plain("gc-rk4", "none");
    same_as_plain("gc-midpoint-pphi", "none");
    same_as_plain("gc-rk45", "none");
}

/* ---- the weak-field ring of the mirror ------------------------------------
 * Bz = B0 (1 + (z^2 - r^2/2)/Lm^2) vanishes on the ring r = sqrt(2) Lm, z = 0.
 * The field line through (r, z) = (0.813, 0.8) m (B0 = 1 T, Lm = 1 m) crosses
 * the equator at r = 1.3 m where |B| = 0.155 T; a 4.8 keV proton started
 * there towards the equator (pitch 120 deg) has rho(1 T) = 1 cm, eps ~ 0.02
 * at the start and ~0.3 at the equator: it must go full orbit through the
 * equator and come back as a guiding centre before its mirror point. */
struct energy_watch {
    const struct gcp_hybrid *h;
    const struct gcp_field *f;
    double W0, dWmax;
    int last_mode, gc_after_fo;
};

static void watch_energy(const struct gcp_block *b, double t, void *vctx)
{
    struct energy_watch *c = vctx;
    if (b->n_active == 0 || !c->h) return;
    const double W = hy_p2(c->h, b, c->f, 0, t); /* energy <=> |p| here */
    if (c->W0 == 0.0) c->W0 = W;
    c->dWmax = fmax(c->dWmax, fabs(W / c->W0 - 1.0));
    const int mode = gcp_hybrid_mode(c->h, b->index[0]);
    if (mode == GCP_MODE_GC && c->last_mode == GCP_MODE_FO) c->gc_after_fo++;
    c->last_mode = mode;
}

Test(hybrid, mirror_null_ring_energy_across_switches)
{
    struct gcp_field *f = gcp_field_mirror_create(1.0, 1.0, 3.0, 0.0);
    const double x[3] = {0.813, 0.0, 0.8};
    struct gcp_field_sample s = {.need = GCP_NEED_B};
    gcp_field_eval(f, 0.0, x, &s);
    const double Bm = sqrt(s.B[0] * s.B[0] + s.B[1] * s.B[1] + s.B[2] * s.B[2]);
    const double b[3] = {s.B[0] / Bm, s.B[1] / Bm, s.B[2] / Bm};
    const double e1[3] = {b[2], 0.0, -b[0]}; /* b x yhat, unit since b_y = 0 */
    const double a = 120.0 * GCP_PI / 180.0, m = GCP_M_PROTON, q = GCP_E_CHARGE;
    double d[3], u[3];
    for (int k = 0; k < 3; k++) d[k] = cos(a) * b[k] + sin(a) * e1[k];
    hy_u_of(4.8e3 * GCP_E_CHARGE, m, d, u);
    const struct gcp_hybrid_opts ho = {&gcp_pusher_gc_rk8pd, &gcp_pusher_boris, 0.1, 0.05, 0.05, 1};
    struct energy_watch w = {0};
    w.f = f;
    struct gcp_hybrid *h = NULL;
    struct gcp_block blk;
    /* the watch needs the hybrid state before the first sample: no hy_push_one */
    cr_assert_eq(gcp_block_alloc(&blk, 1), 0);
    blk.q = q, blk.m = m;
    blk.x[0] = x[0], blk.y[0] = x[1], blk.z[0] = x[2];
    blk.ux[0] = u[0], blk.uy[0] = u[1], blk.uz[0] = u[2];
    cr_assert_eq(gcp_hybrid_create(&h, 1, &ho), 0);
    cr_assert_eq(gcp_block_start(&blk, f, 0.0), 1);
    gcp_hybrid_begin(h, &blk, f, 0.0, 0);
    w.h = h;
    w.last_mode = gcp_hybrid_mode(h, 0);
    cr_assert_eq(w.last_mode, GCP_MODE_GC, "the start is adiabatic");
    watch_energy(&blk, 0.0, &w);
    const struct gcp_push_opts o = {.t0 = 0.0, .dt = 20e-9, .nsteps = 500, .tolerance = 1e-12};
    const struct gcp_sampler smp = {1, watch_energy, &w};
    gcp_hybrid_advance(h, &blk, f, &o, &smp);
    cr_assert_eq(blk.status[0], GCP_ALIVE);
    struct gcp_hybrid_lane_info info;
    gcp_hybrid_info(h, 0, &info);
    const struct gcp_hybrid_switch *sw;
    const size_t nsw = gcp_hybrid_switches(h, &sw);
    cr_assert_eq((size_t)info.switches, nsw);
    cr_assert_geq(nsw, 2, "must switch to full orbit at the ring and back");
    cr_assert_geq(w.gc_after_fo, 1);
    for (size_t k = 0; k < nsw; k++) {
        cr_assert_eq(sw[k].dir, k % 2 ? -1 : +1);
        if (sw[k].dir > 0) cr_assert_gt(sw[k].eps, 0.1);
        else cr_assert_lt(sw[k].eps, 0.05);
        /* the ring is where the particle leaves the guiding-centre picture */
        if (sw[k].dir > 0) cr_assert_lt(fabs(sw[k].X[2]), 0.8);
    }
    cr_assert_float_eq(info.t_gc + info.t_fo, 500 * 20e-9, 1e-18);
    cr_assert_gt(info.t_fo, 0.0);
    /* Energy bound, on p^2 (relative p^2 error = 2 x relative |p| error).
     * Boris keeps |u| in a static B up to round-off: each rotation is
     * orthogonal to a few ulp, <= 8 eps_mach = 1e-15 per step, linearly
     * accumulated over < 10^5 steps: 2e-10 in p^2.  gc-rk8pd at tolerance
     * 1e-12: local error <= 1e-12 per accepted step relative to the state,
     * < 10^3 accepted steps here: 2e-9 in p^2.  The transformations keep p^2
     * (GC -> FO: p = p_par b + p_perp e, |p|^2 = p_par^2 + 2 m mu B; FO -> GC:
     * the averaged (p_par, mu) rescaled to the particle's |p|), where an
     * unmatched average would be off by O(eps^2) ~ 1e-3 (the events' dp2).
     * Sum: 2.2e-9 (measured: 1.1e-11 over 6 switches, 667 steps). */
    cr_assert_lt(blk.steps[0], 100000);
    cr_log_info("%zu switches, %lld steps, p^2 moved by %.3g", nsw, (long long)blk.steps[0], w.dWmax);
    cr_assert_lt(w.dWmax, 2.2e-9, "p^2 moved by %.3g across %zu switches", w.dWmax, nsw);
    gcp_hybrid_free(h);
    gcp_block_free(&blk);
    gcp_field_free(f);
}
