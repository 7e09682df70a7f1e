/* The observer's gyro-average inside the fused full-orbit step (issue 12,
 * gcp_block_advance_fo_gyro, src/pushers/fo_gyro_priv.h: raw sums of each
 * step's middle, formed into X, p_par, mu once a gyration).
 *
 * The fused step takes up to 128 steps a call; a call that a lane's stop
 * cuts short is restored and run again, and the records of a call reach
 * the observer after it.  None of that may change a number: the same push
 * with one step a call (gcp_fo_gyro.max_steps = 1, the sampler called
 * every step) must give the same events bit for bit -- the tolerance is
 * zero.  Each test also checks that the fused path was taken (the sampler
 * was called far less often than once a step).  Against the observer's
 * own per-step pass (another gyro-average: the first-order guiding centre
 * of every step, the field at it, the trapezoid rule; fields without a
 * fused step use it), the dipole's mu must agree to O(eps^2), eps = rho /
 * L_B: both are the gyration-averaged zeroth-order moment, equal to the
 * first-order invariant to O(eps^2) in a vacuum field
 * (test_invariants_fo_mu.c for each against an independent reference). */
#include <math.h>
#include <string.h>

#include <criterion/criterion.h>

#include "gcpush/field.h"
#include "gcpush/invariants.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "gcpush/pusher.h"
#include "pushers/fo_gyro_priv.h" /* struct gcp_fo_gyro.max_steps */

#define RE GCP_EARTH_RADIUS
#define B0 GCP_EARTH_B0
#define DEG (GCP_PI / 180.0)
#define MEV (1e6 * GCP_E_CHARGE)

struct counted {
    struct gcp_observer *o;
    int64_t calls;
};

static void counted_sample(const struct gcp_block *b, double t, void *ctx)
{
    struct counted *c = ctx;
    c->calls++;
    gcp_observer_sample(b, t, c->o);
}

/* Protons of energy W at L = Lmin .. Lmax on the equator, pitch
 * pmin .. pmax (a grid over the n lanes), gyrophase varied. */
static void fill(struct gcp_block *b, size_t n, double W, double Lmin, double Lmax, double pmin,
                 double pmax)
{
    const double m = GCP_M_PROTON, c = GCP_C_LIGHT;
    const double gamma = 1.0 + W / (m * c * c), u = c * sqrt(gamma * gamma - 1.0);
    b->q = GCP_E_CHARGE, b->m = m;
    for (size_t i = 0; i < n; i++) {
        const double s = n > 1 ? (double)i / (double)(n - 1) : 0.0;
        const double L = Lmin + s * (Lmax - Lmin), a = pmin + (1.0 - s) * (pmax - pmin);
        const double ph = 2.399963 * (double)i; /* golden angle: phases spread */
        b->x[i] = L * RE, b->y[i] = 0, b->z[i] = 0;
        /* B is along -z on the equator: u_par along z, u_perp in x-y */
        b->ux[i] = u * sin(a) * cos(ph), b->uy[i] = u * sin(a) * sin(ph);
        b->uz[i] = u * cos(a);
    }
    b->n_active = n;
}

/* The dipole scene of the dipole tests (atmosphere at 100 km, outer
 * boundary 15 R_E): b0 allocated and filled as fill() (n lanes), and *dt
 * 0.05 of the gyro-period on the equator at L = 4 of lane 0's gamma. */
static struct gcp_field *dipole_scene(struct gcp_block *b0, size_t n, double W, double Lmin,
                                      double Lmax, double pmin, double pmax, double *dt)
{
    struct gcp_field *f = gcp_field_dipole_create(B0, 0, RE + 100e3, 15.0 * RE);
    cr_assert_not_null(f);
    cr_assert_eq(gcp_block_alloc(b0, n), 0);
    fill(b0, n, W, Lmin, Lmax, pmin, pmax);
    const double Beq = B0 / 64.0, m = GCP_M_PROTON;
    const double gamma = gcp_gamma_of_u(b0->ux[0], b0->uy[0], b0->uz[0]);
    *dt = 0.05 * 2 * GCP_PI * gamma * m / (GCP_E_CHARGE * Beq);
    return f;
}

/* Pushes the block b0 (n lanes) with boris for nsteps of dt under a fresh
 * observer (mu K L, cadence sample_dt): fused = 0, the observer's per-step
 * pass; 1, gcp_block_advance_fo_gyro one step a call; 2, the same with its
 * own calls; the sorted events in *ev, sampler calls returned. */
static int64_t run(const struct gcp_field *f, const struct gcp_block *b0, size_t n, double dt,
                   int64_t nsteps, double sample_dt, int fused, struct gcp_events *ev,
                   int64_t *alive)
{
    struct gcp_block b;
    cr_assert_eq(gcp_block_alloc(&b, n), 0);
    b.q = b0->q, b.m = b0->m;
    memcpy(b.x, b0->x, n * sizeof(double)), memcpy(b.y, b0->y, n * sizeof(double));
    memcpy(b.z, b0->z, n * sizeof(double)), memcpy(b.ux, b0->ux, n * sizeof(double));
    memcpy(b.uy, b0->uy, n * sizeof(double)), memcpy(b.uz, b0->uz, n * sizeof(double));
    b.n_active = n;
    gcp_block_start(&b, f, 0.0);
    struct gcp_observer *o;
    const struct gcp_observer_opts oo = {.invariants = GCP_INV_MU | GCP_INV_K | GCP_INV_L,
                                         .events = GCP_EVT_LOSS};
    cr_assert_eq(gcp_observer_create(&o, n, f, &gcp_pusher_boris, &oo), 0);
    gcp_observer_set_sample_dt(o, sample_dt);
    gcp_observer_begin(o, &b, 0.0, 100, ev);
    struct counted c = {o, 0};
    const struct gcp_sampler smp = {1, counted_sample, &c};
    /* two pushes, as the engine's slices: the second starts where the first ended */
    const int64_t k1 = nsteps / 3;
    for (int part = 0; part < 2; part++) {
        const double t0 = part ? (double)k1 * dt : 0.0;
        const struct gcp_push_opts po = {.t0 = t0, .dt = dt, .nsteps = part ? nsteps - k1 : k1};
        if (fused) {
            struct gcp_fo_gyro *g = gcp_observer_fo_gyro(o);
            cr_assert_not_null(g);
            g->max_steps = fused == 1 ? 1 : 0;
            gcp_block_advance_fo_gyro(&b, f, &gcp_pusher_boris, &po, &smp, g);
        } else {
            gcp_pusher_boris.advance(&b, f, &gcp_pusher_boris, &po, &smp);
        }
    }
    cr_assert_eq(gcp_observer_end(o, &b), 0);
    gcp_events_sort(ev);
    *alive = (int64_t)b.n_active;
    gcp_observer_free(o);
    gcp_block_free(&b);
    return c.calls;
}

static void same_events(const char *what, const struct gcp_events *a, const struct gcp_events *b)
{
    cr_assert_eq(a->n, b->n, "%s: %lld events per step, %lld fused", what, (long long)a->n,
                 (long long)b->n);
    cr_assert_eq(a->ns, b->ns, "%s: %lld scalar events per step, %lld fused", what,
                 (long long)a->ns, (long long)b->ns);
    int64_t kinds[16] = {0};
    for (int64_t k = 0; k < a->n + a->ns; k++) {
        const struct gcp_event xe = gcp_events_get(a, k), ye = gcp_events_get(b, k);
        const struct gcp_event *x = &xe, *y = &ye;
        cr_assert(memcmp(x, y, sizeof *x) == 0,
                  "%s: event %lld (id %lld kind %d t %.17g) differs from the fused one "
                  "(id %lld kind %d t %.17g, v0 %.17g vs %.17g)",
                  what, (long long)k, (long long)x->id, x->kind, x->t, (long long)y->id, y->kind,
                  y->t, x->v[0], y->v[0]);
        if (x->kind >= 0 && x->kind < 16) kinds[x->kind]++;
    }
    cr_log_info("%s: %lld events, bit-identical (mu %lld, bounce %lld, drift %lld, samples "
                "%lld, loss %lld)",
                what, (long long)(a->n + a->ns), (long long)kinds[GCP_EVENT_MU],
                (long long)kinds[GCP_EVENT_BOUNCE], (long long)kinds[GCP_EVENT_DRIFT],
                (long long)kinds[GCP_EVENT_SAMPLE], (long long)kinds[GCP_EVENT_LOSS]);
}

/* The push of b0 fused one step a call and with its own calls (run),
 * whose events must be the same bit for bit; the latter's events in *eb
 * (the caller frees them), the sampler calls of each in c[0] (one step),
 * c[1] (fused), the live lanes at the end of each in alive[0], alive[1]. */
static void run_pair(const char *what, const struct gcp_field *f, const struct gcp_block *b0,
                     size_t n, double dt, int64_t nsteps, double sample_dt, struct gcp_events *eb,
                     int64_t c[2], int64_t alive[2])
{
    struct gcp_events ea = {0};
    c[0] = run(f, b0, n, dt, nsteps, sample_dt, 1, &ea, &alive[0]);
    c[1] = run(f, b0, n, dt, nsteps, sample_dt, 2, eb, &alive[1]);
    same_events(what, &ea, eb);
    gcp_events_free(&ea);
}

/* The mean mu event of lane id in ev (NAN: none), their count in *n. */
static double mean_mu(const struct gcp_events *ev, int64_t id, int *n)
{
    double s = 0;
    *n = 0;
    for (int64_t k = 0; k < ev->n + ev->ns; k++) {
        const struct gcp_event e = gcp_events_get(ev, k);
        if (e.id != id || e.kind != GCP_EVENT_MU) continue;
        s += e.v[0], (*n)++;
    }
    return *n ? s / *n : NAN;
}

/* Trapped protons, none lost: the fused path the whole push, with mirror
 * points, bounces, equator points and (at L 4.5, 2 MeV: a drift period of
 * ~5 min) drift turns; 37 lanes, so the tile has a vector remainder. */
Test(invariants_fo_fused, dipole_trapped_bit_identical)
{
    const size_t n = 37;
    struct gcp_block b0;
    double dt;
    struct gcp_field *f = dipole_scene(&b0, n, 2.0 * MEV, 4.0, 4.5, 30 * DEG, 90 * DEG, &dt);
    const int64_t nsteps = (int64_t)(330.0 / dt);
    struct gcp_events eb = {0};
    int64_t c[2], alive[2];
    run_pair("trapped", f, &b0, n, dt, nsteps, 5.0, &eb, c, alive);
    cr_assert_eq(c[0], nsteps, "one step a call: the sampler sees every step");
    cr_assert_lt(c[1], nsteps / 50, "fused: %lld sampler calls for %lld steps", (long long)c[1],
                 (long long)nsteps);
    cr_assert_eq(alive[0], (int64_t)n);
    cr_assert_eq(alive[1], (int64_t)n);
    int drift = 0;
    for (int64_t k = 0; k < eb.n; k++) drift += eb.e[k].kind == GCP_EVENT_DRIFT;
    cr_assert_gt(drift, 0, "a drift turn in the push");
    /* against the per-step pass: each lane's mean mu within 5 eps^2 (the
     * O(eps^2) coefficient of test_invariants_fo_mu.c), eps = rho / L_B =
     * p / (q B_eq) / (L R_E / 3) = 3 p L^2 / (q B0 R_E) of the lane's L
     * (fill(): 0.049 at L = 4 .. 0.062 at L = 4.5) */
    struct gcp_events ea = {0};
    int64_t alive_s;
    run(f, &b0, n, dt, nsteps, 5.0, 0, &ea, &alive_s);
    const double W = 2.0 * MEV, mc2 = GCP_M_PROTON * GCP_C_LIGHT * GCP_C_LIGHT;
    const double p = sqrt(W * (W + 2 * mc2)) / GCP_C_LIGHT;
    double worst = 0;
    int lanes = 0;
    for (size_t i = 0; i < n; i++) {
        int na, nb;
        const double ma = mean_mu(&ea, 100 + (int64_t)i, &na);
        const double mb = mean_mu(&eb, 100 + (int64_t)i, &nb);
        if (!na || !nb) continue;
        const double L = 4.0 + 0.5 * (double)i / (double)(n - 1);
        const double eps = 3.0 * p * L * L / (GCP_E_CHARGE * B0 * RE);
        worst = fmax(worst, fabs(mb / ma - 1) / (eps * eps)), lanes++;
    }
    cr_log_info("trapped: mean mu fused vs per step over %d lanes: worst %.2f eps^2", lanes,
                worst);
    cr_assert_geq(lanes, (int)n / 2);
    cr_assert_lt(worst, 5.0, "mu fused vs per step: %.3g eps^2", worst);
    gcp_events_free(&ea);
    gcp_events_free(&eb);
    gcp_block_free(&b0);
    gcp_field_free(f);
}

/* Lanes in the loss cone precipitate within the push: the fused call in
 * which a lane stops is run again to the step before the stop, the
 * stopping step is a plain one with the per-step pass, and the block
 * (no longer dense after the retirement) goes on per step: the same
 * events one step a call, the losses' interpolated crossings included. */
Test(invariants_fo_fused, dipole_losses_bit_identical)
{
    const size_t n = 16;
    struct gcp_block b0;
    double dt;
    struct gcp_field *f = dipole_scene(&b0, n, 1.0 * MEV, 3.5, 4.5, 1 * DEG, 60 * DEG, &dt);
    const int64_t nsteps = (int64_t)(20.0 / dt);
    struct gcp_events eb = {0};
    int64_t c[2], alive[2];
    run_pair("losses", f, &b0, n, dt, nsteps, 1.0, &eb, c, alive);
    cr_assert_lt(alive[0], (int64_t)n, "a lane precipitated");
    cr_assert_eq(alive[0], alive[1]);
    cr_assert_lt(c[1], nsteps, "fused: %lld sampler calls for %lld steps", (long long)c[1],
                 (long long)nsteps);
    gcp_events_free(&eb);
    gcp_block_free(&b0);
    gcp_field_free(f);
}

/* Uniform B (an independent reference): no mirror point, so mu comes as
 * cadence samples of the gyro-averaged stream; in a uniform field
 * p_par = p.b and p_perp^2 = p^2 - p_par^2 are constants of the exact
 * motion and of Boris (a rotation about b: |u| and u.b kept to
 * round-off), so mu = m^2 u_perp^2 / (2 m B) exactly.  What remains is
 * round-off: |u| random-walks by ~sqrt(N) ulp over N ~ 2000 steps
 * (~1e-14), the cancellation in p^2 - p_par^2 multiplies it by
 * p^2 / p_perp^2 = 1/sin^2(60 deg) = 1.33, the trapezoid average and the
 * linear interpolation add a few ulp: 1e-12 relative is ~50x that.  The
 * fused run must also equal the one of one step a call bit for bit. */
Test(invariants_fo_fused, uniform_mu_analytic)
{
    const double Bz = 1e-6, Bv[3] = {0, 0, Bz}, E[3] = {0, 0, 0};
    struct gcp_field *f = gcp_field_uniform_create(Bv, E);
    cr_assert_not_null(f);
    const size_t n = 9;
    struct gcp_block b0;
    cr_assert_eq(gcp_block_alloc(&b0, n), 0);
    const double m = GCP_M_PROTON, q = GCP_E_CHARGE, u = 1e7, a = 60 * DEG;
    b0.q = q, b0.m = m;
    for (size_t i = 0; i < n; i++) {
        const double ph = 2.399963 * (double)i;
        b0.x[i] = 1e3 * (double)i, b0.y[i] = 0, b0.z[i] = 0;
        b0.ux[i] = u * sin(a) * cos(ph), b0.uy[i] = u * sin(a) * sin(ph), b0.uz[i] = u * cos(a);
    }
    b0.n_active = n;
    const double gamma = gcp_gamma_of_u(b0.ux[0], b0.uy[0], b0.uz[0]);
    const double Tg = 2 * GCP_PI * gamma * m / (q * Bz);
    const double dt = 0.05 * Tg;
    const int64_t nsteps = 2000;
    struct gcp_events eb = {0};
    int64_t c[2], alive[2];
    run_pair("uniform", f, &b0, n, dt, nsteps, 3.0 * Tg, &eb, c, alive);
    cr_assert_lt(c[1], nsteps / 50);
    const double mu = m * m * u * sin(a) * u * sin(a) / (2.0 * m * Bz);
    double worst = 0;
    int ns = 0;
    for (int64_t k = 0; k < eb.n; k++) {
        if (eb.e[k].kind != GCP_EVENT_SAMPLE) continue;
        worst = fmax(worst, fabs(eb.e[k].v[0] / mu - 1.0));
        ns++;
    }
    cr_log_info("uniform: %d mu samples, worst relative error %.2e", ns, worst);
    cr_assert_geq(ns, (int)n * 20);
    cr_assert_lt(worst, 1e-12, "mu vs analytic: %.3e", worst);
    gcp_events_free(&eb);
    gcp_block_free(&b0);
    gcp_field_free(f);
}
