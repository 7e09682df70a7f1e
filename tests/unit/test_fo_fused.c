/* The fused full-orbit step (src/pushers/fo_fused_priv.h) against the
 * block step it replaces, bit for bit.
 *
 * For every full-orbit pusher of the registry and each closed-form field
 * (the dipole without corotation, uniform B, uniform B and E), a block of
 * N = 300 lanes (two full tiles and a partial one) is pushed twice: in the
 * model itself, where the fused step runs, and in a callback field that
 * calls the model's own eval (no closed form: the block step, the model's
 * numbers).  Lanes leave the domain at different steps (so tiles stop
 * early and are run again to the block's step), one starts non-finite,
 * and a sampler every 7 steps records the live lanes (and once without a
 * sampler: the whole push in one call of the fused step).  A slower dipole
 * scene (1.5e6 m/s within 1 R_E of 4 R_E: the tiles' lanes start >= 0.8
 * R_E from the bounds, ~16 steps' 2 d of gcp_fo_free_steps) runs boris's
 * dipole tile in stretches without the stop test, lanes still leaving at
 * distinct steps.  The fused step does
 * the same operations in the same order (the build keeps
 * -ffp-contract=off), so states, statuses, stop times, step counts and
 * every sample must be equal to the bit; any reordering of a sum shows up
 * as a differing last bit in some of the 300 x 400 lane-steps.
 * Once more as a PIC code streams a block (issue 12): one call per step
 * with the caller keeping the clock (GCP_BLOCK_CALLER_CLOCK), where the
 * fused step writes x and u only and the evolve layer classifies only
 * after a step in which a lane stopped: the same states, statuses, stop
 * times and lane order as the block step in one call; the live lanes' t
 * and steps untouched, a stopped lane's steps those of its last call (1).
 * Cost: 0.4 s. */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include <criterion/criterion.h>

#include "gcpush/field.h"
#include "gcpush/field_kernels.h"
#include "gcpush/particles.h"
#include "gcpush/pusher.h"
#include "pushers/fo_fused_priv.h"

#define N 300
#define NSTEPS 400
#define EVERY 7
#define VSLOW 1.5e6

static int wrapped_eval(double t, const double x[3], struct gcp_field_sample *out, void *ctx)
{
    return gcp_field_eval(ctx, t, x, out);
}

/* FNV-1a over the live lanes' state at each sample */
struct trace {
    uint64_t h;
    int calls;
};
static void mix(struct trace *tr, const void *p, size_t n)
{
    const unsigned char *c = p;
    for (size_t i = 0; i < n; i++) tr->h = (tr->h ^ c[i]) * 0x100000001B3ull;
}
static void sample(const struct gcp_block *b, double t, void *ctx)
{
    struct trace *tr = ctx;
    tr->calls++;
    mix(tr, &t, sizeof t);
    mix(tr, &b->n_active, sizeof b->n_active);
    const size_t n = b->n_active;
    const double *a[6] = {b->x, b->y, b->z, b->ux, b->uy, b->uz};
    for (int k = 0; k < 6; k++) mix(tr, a[k], n * sizeof(double));
    mix(tr, b->index, n * sizeof(size_t));
}

/* Deterministic lanes: positions spread over scale L about x0, speeds v,
 * directions from a fixed sequence; lane 17 non-finite. */
static void fill(struct gcp_block *b, const double x0[3], double L, double v)
{
    uint64_t s = 0x9E3779B97F4A7C15ull;
    for (size_t i = 0; i < N; i++) {
        double r[6];
        for (int k = 0; k < 6; k++) {
            s = s * 6364136223846793005ull + 1442695040888963407ull;
            r[k] = (double)(s >> 11) * 0x1.0p-53 * 2.0 - 1.0;
        }
        b->x[i] = x0[0] + L * r[0], b->y[i] = x0[1] + L * r[1], b->z[i] = x0[2] + L * r[2];
        b->ux[i] = v * r[3], b->uy[i] = v * r[4], b->uz[i] = v * r[5];
        b->status[i] = 0, b->steps[i] = 0, b->index[i] = i, b->t[i] = 0.0;
    }
    b->uy[17] = NAN;
    b->n_active = N;
}

/* every < 0: streaming, one call a step from t0 = k dt, the caller's clock */
static void run(const struct gcp_field *f, const struct gcp_pusher_type *p, const double x0[3],
                double L, double v, double dt, int64_t every, struct gcp_block *b,
                struct trace *tr)
{
    cr_assert_eq(gcp_block_alloc(b, N), 0);
    b->q = GCP_E_CHARGE, b->m = GCP_M_PROTON;
    fill(b, x0, L, v);
    *tr = (struct trace){0xCBF29CE484222325ull, 0};
    const struct gcp_sampler s = {every, sample, tr};
    gcp_block_start(b, f, 0.0);
    if (every >= 0) {
        gcp_block_advance_fo(b, f, p, 0.0, dt, NSTEPS, every ? &s : NULL);
        return;
    }
    b->flags = GCP_BLOCK_CALLER_CLOCK;
    for (int64_t k = 0; k < NSTEPS; k++) gcp_block_advance_fo(b, f, p, (double)k * dt, dt, 1, NULL);
}

static void compare(const char *what, const struct gcp_field *model,
                    const struct gcp_pusher_type *p, const double x0[3], double L, double v,
                    double dt, int64_t every)
{
    struct gcp_field *twin = gcp_field_callback_create(wrapped_eval, (void *)model, model->has_E);
    cr_assert_not_null(twin);
    twin->r_inner = model->r_inner, twin->r_outer = model->r_outer, twin->z_max = model->z_max;
    struct gcp_point_B form, none;
    cr_assert(gcp_field_point_B(model, &form), "%s: no closed form", what);
    cr_assert(!gcp_field_point_B(twin, &none), "%s: the twin has a closed form", what);
    /* the fused step does run for this (form, pusher): else the test compares
     * the block step with itself */
    cr_assert(p->fused && p->fused->tile[form.form][form.has_E], "%s %s: no fused kernel", what,
              p->name);
    struct gcp_block a, b;
    struct trace ta, tb;
    const int streaming = every < 0;
    run(model, p, x0, L, v, dt, every, &a, &ta);
    run(twin, p, x0, L, v, dt, streaming ? 0 : every, &b, &tb);
    size_t stopped = 0, distinct_stops = 0;
    int64_t last = -1;
    cr_expect_eq(a.n_active, b.n_active, "%s %s: live %zu, block step %zu", what, p->name,
                 a.n_active, b.n_active);
    for (size_t i = 0; i < N; i++) {
        const double *da[7] = {a.x, a.y, a.z, a.ux, a.uy, a.uz, a.t};
        const double *db[7] = {b.x, b.y, b.z, b.ux, b.uy, b.uz, b.t};
        /* streaming: a live lane's clock is the caller's (t and steps as
         * filled), a stopped lane's t its stop time, its steps its last call's */
        const int clock = !streaming || b.status[i] != GCP_ALIVE;
        for (int k = 0; k < 6 + clock; k++)
            cr_expect(memcmp(&da[k][i], &db[k][i], sizeof(double)) == 0,
                      "%s %s: lane %zu array %d: %.17g, block step %.17g", what, p->name, i, k,
                      da[k][i], db[k][i]);
        if (!clock) cr_expect(a.t[i] == 0.0 && a.steps[i] == 0, "%s %s: lane %zu clock", what,
                              p->name, i);
        cr_expect_eq(a.status[i], b.status[i], "%s %s: lane %zu status", what, p->name, i);
        if (!streaming)
            cr_expect_eq(a.steps[i], b.steps[i], "%s %s: lane %zu steps", what, p->name, i);
        else if (clock)
            cr_expect_eq(a.steps[i], b.steps[i] > 0, "%s %s: lane %zu steps", what, p->name, i);
        cr_expect_eq(a.index[i], b.index[i], "%s %s: lane %zu index", what, p->name, i);
        if (b.status[i] != GCP_ALIVE && b.steps[i] > 0) {
            stopped++;
            if (b.steps[i] != last) distinct_stops++, last = b.steps[i];
        }
    }
    cr_expect_eq(ta.calls, every > 0 ? NSTEPS / every : 0, "%s %s: %d samples", what, p->name,
                 ta.calls);
    cr_expect_eq(ta.calls, tb.calls);
    cr_expect_eq(ta.h, tb.h, "%s %s: the samples differ", what, p->name);
    /* the scene exercises early tile stops: lanes leave mid-push at several steps */
    cr_expect(stopped >= 5 && stopped < N / 2 && distinct_stops >= 3,
              "%s %s: %zu lanes stopped mid-push (%zu distinct steps)", what, p->name, stopped,
              distinct_stops);
    cr_log_info("%s %s: %zu lanes stopped mid-push at %zu distinct steps, %d samples", what,
                p->name, stopped, distinct_stops, ta.calls);
    gcp_block_free(&a);
    gcp_block_free(&b);
    gcp_field_free(twin);
}

Test(fo_fused, equals_block_step_every_pusher_every_form)
{
    const double RE = GCP_EARTH_RADIUS;
    /* dipole: 10 MeV-class protons (v = 4e7 m/s) within 1 R_E of 5.5 R_E, in a
     * shell 2 .. 6 R_E: some precipitate or leave within the 400 steps of
     * 0.05 s (omega_c dt ~ 0.1-1 there, the same scene for every pusher) */
    struct gcp_field *dip = gcp_field_dipole_create(GCP_EARTH_B0, 0, 2.0 * RE, 6.0 * RE);
    /* uniform: 1 T along (0.3, 0.4, sqrt(0.75)), domain |x| < 2 m, |z| < 1 m;
     * 1e6 m/s protons (omega_c dt = 0.1) within 0.9 m of the origin */
    const double B[3] = {0.3, 0.4, sqrt(0.75)}, E[3] = {0.0, 4e4, -2e4};
    struct gcp_field *uni = gcp_field_uniform_create(B, NULL);
    struct gcp_field *uniE = gcp_field_uniform_create(B, E);
    cr_assert(dip && uni && uniE);
    uni->r_outer = uniE->r_outer = 2.0;
    uni->z_max = uniE->z_max = 1.0;
    const double xd[3] = {5.5 * RE, 0.0, 0.0}, xu[3] = {0.0, 0.0, 0.0};
    const double xs[3] = {4.0 * RE, 0.0, 0.0};
    const double dtu = 0.1 * GCP_M_PROTON / GCP_E_CHARGE;
    int n = 0;
    for (const struct gcp_pusher_type *const *pp = gcp_pusher_types(); *pp; pp++) {
        if ((*pp)->kind != GCP_FULL_ORBIT) continue;
        /* with a sampler (up to EVERY steps at once), without (the whole
         * push at once, tiles stopped early and run again), and streaming
         * (every = -1: one call a step, the caller's clock) */
        for (int64_t every = -1; every <= EVERY; every += every < 0 ? 1 : EVERY) {
            compare("dipole", dip, *pp, xd, RE, 4e7, 0.05, every);
            compare("dipole, slow", dip, *pp, xs, RE, VSLOW, 0.05, every);
            compare("uniform B", uni, *pp, xu, 0.9, 1e6, dtu, every);
            compare("uniform B and E", uniE, *pp, xu, 0.9, 1e6, dtu, every);
        }
        n++;
    }
    cr_expect_geq(n, 4, "full-orbit pushers in the registry: %d", n);
    gcp_field_free(dip);
    gcp_field_free(uni);
    gcp_field_free(uniE);
}
