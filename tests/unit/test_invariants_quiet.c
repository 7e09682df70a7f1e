/* The guiding-centre observer's quiet pass (src/diag/invariants_quiet.c)
 * against its reference, the observer with every step of every lane sent
 * through gcp_obs_stream_sample_jd (o->hot.per_lane): the pass claims the
 * same events bit for bit, so the test compares them with memcmp, not to a
 * tolerance.  The scene exercises every way a step leaves the pass: mirror
 * points and the samples after |B| minima (bouncing protons), cadence times
 * (sample_dt of 16 steps: the samples rows of a particle at pitch 90 deg
 * that never mirrors, and the stream contour), a drift turn (10 MeV at
 * L = 6 drifts around in ~50 s), and a loss in the first bounce (pitch
 * 1.5 deg at L = 6, inside the loss cone of ~2.8 deg), after which the block's lanes are
 * no longer in index order (the pass's indexed form), and whose loss row
 * interpolates from the ring's last sample (the reference: from xprev).  A
 * second reference
 * run with one lane's mu moved by one ulp shows that the comparison sees a
 * last-bit difference.
 *
 * And the event storage (src/diag/invariants.c gcp_events_push): grown by
 * mremap past 2 MiB, every event kept, the storage 2 MiB aligned. */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include <criterion/criterion.h>

#include "diag/invariants_priv.h"
#include "gcpush/field.h"
#include "gcpush/invariants.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "gcpush/pusher.h"

#define RE GCP_EARTH_RADIUS
#define B0 GCP_EARTH_B0
#define DEG (GCP_PI / 180.0)
#define MEV (1e6 * GCP_E_CHARGE)

enum { NL = 8 };
static const double Ls[NL] = {3.0, 4.0, 4.5, 5.0, 6.0, 6.0, 6.0, 4.0};
static const double as[NL] = {20 * DEG, 35 * DEG, 50 * DEG, 65 * DEG, 80 * DEG, 40 * DEG, 1.5 * DEG,
                              90 * DEG};

/* The scene's events (sorted) with gc-rk4, every step observed; per_lane:
 * the reference; bump: lane 2's mu one ulp up.  *passes: steps through the
 * quiet pass. */
static void run_n(int per_lane, int bump, int eager, int nsteps, struct gcp_events *ev,
                  int64_t *passes, int64_t *skipped)
{
    const struct gcp_pusher_type *p = gcp_pusher_lookup("gc-rk4");
    cr_assert_not_null(p);
    struct gcp_field *f = gcp_field_dipole_create(B0, 0, RE + 100e3, 15.0 * RE);
    cr_assert_not_null(f);
    const double m = GCP_M_PROTON, q = GCP_E_CHARGE, W = 10 * MEV;
    const double mc2 = m * GCP_C_LIGHT * GCP_C_LIGHT;
    const double pm = sqrt(W * (W + 2.0 * mc2)) / GCP_C_LIGHT;
    struct gcp_block b;
    cr_assert_eq(gcp_block_alloc(&b, NL), 0);
    b.q = q, b.m = m;
    for (size_t i = 0; i < NL; i++) {
        const double Beq = B0 / (Ls[i] * Ls[i] * Ls[i]);
        b.x[i] = Ls[i] * RE, b.y[i] = 0.0, b.z[i] = 0.0;
        b.ppar[i] = as[i] == 90 * DEG ? 0.0 : pm * cos(as[i]);
        b.mu[i] = pm * pm * sin(as[i]) * sin(as[i]) / (2.0 * m * Beq);
    }
    if (bump) b.mu[2] = nextafter(b.mu[2], INFINITY);
    gcp_block_start(&b, f, 0.0);
    struct gcp_observer *o;
    const struct gcp_observer_opts oo = {
        .invariants = GCP_INV_MU | GCP_INV_J | GCP_INV_K | GCP_INV_L | GCP_INV_ENERGY | GCP_INV_PPHI,
        .events = GCP_EVT_BOUNCE | GCP_EVT_DRIFT | GCP_EVT_LOSS};
    cr_assert_eq(gcp_observer_create(&o, NL, f, p, &oo), 0);
    o->hot.per_lane = per_lane;
    o->st_eager = eager;
    /* ~45 steps a bounce (T_b ~ 2 s here), 1400 steps: > 1 drift at L = 6 */
    const double dt = 0.045;
    gcp_observer_set_sample_dt(o, 16 * dt);
    gcp_observer_begin(o, &b, 0.0, 0, ev);
    const struct gcp_sampler smp = {1, gcp_observer_sample, o};
    const struct gcp_push_opts po = {.t0 = 0.0, .dt = dt, .nsteps = nsteps};
    p->advance(&b, f, p, &po, &smp);
    cr_assert_eq(gcp_observer_end(o, &b), 0);
    *passes = o->hot.passes;
    if (skipped) *skipped = o->st_skipped;
    gcp_observer_free(o);
    gcp_block_free(&b);
    gcp_field_free(f);
    gcp_events_sort(ev);
}

static void run(int per_lane, int bump, struct gcp_events *ev, int64_t *passes)
{
    run_n(per_lane, bump, 0, 1400, ev, passes, NULL);
}

static int64_t count_kind(const struct gcp_events *ev, int kind)
{
    int64_t n = 0;
    for (int64_t k = 0; k < ev->n + ev->ns; k++) n += gcp_events_get(ev, k).kind == kind;
    return n;
}

Test(invariants_quiet, pass_equals_per_lane_bit_for_bit)
{
    struct gcp_events a = {0}, r = {0}, x = {0};
    int64_t pa, pr, px;
    run(0, 0, &a, &pa);
    run(1, 0, &r, &pr);
    run(1, 1, &x, &px);
    /* the pass ran on every step of the quiet run, never in the references */
    cr_assert_eq(pa, 1401, "quiet pass on %lld steps", (long long)pa);
    cr_assert_eq(pr, 0);
    cr_assert_eq(px, 0);
    /* every path was taken */
    const int64_t nb = count_kind(&a, GCP_EVENT_BOUNCE), nm = count_kind(&a, GCP_EVENT_MU);
    const int64_t nd = count_kind(&a, GCP_EVENT_DRIFT), nl = count_kind(&a, GCP_EVENT_LOSS);
    const int64_t ns = count_kind(&a, GCP_EVENT_SAMPLE);
    cr_log_info("quiet: %lld events (%lld bounce, %lld mu, %lld drift, %lld loss, %lld samples)",
                (long long)a.n, (long long)nb, (long long)nm, (long long)nd, (long long)nl,
                (long long)ns);
    cr_assert(nb > 100 && nm > 200 && nd >= 1 && nl == 1 && ns > 50);
    cr_assert_eq(a.n, r.n);
    cr_assert_eq(a.ns, r.ns);
    cr_assert_eq(memcmp(a.e, r.e, (size_t)a.n * sizeof *a.e), 0,
                 "the quiet pass's events differ from the per-lane stream's");
    cr_assert_eq(memcmp(a.s, r.s, (size_t)a.ns * sizeof *a.s), 0,
                 "the quiet pass's mu rows differ from the per-lane stream's");
    /* one ulp of one lane's mu shows in the comparison, in both arrays */
    cr_assert(x.n != r.n || memcmp(x.e, r.e, (size_t)r.n * sizeof *r.e) != 0);
    cr_assert(x.ns != r.ns || memcmp(x.s, r.s, (size_t)r.ns * sizeof *r.s) != 0);
    gcp_events_free(&a);
    gcp_events_free(&r);
    gcp_events_free(&x);
}

Test(invariants_quiet, events_grow_in_place_keep_every_event)
{
    struct gcp_events ev = {0};
    /* 23 MB of full rows and 4 MB of scalar rows (kinds 2, 3, 4 of 0 .. 6):
     * growth of each from malloc into a mapping, then mremaps */
    const int64_t n = 300000;
    for (int64_t k = 0; k < n; k++) {
        struct gcp_event e = {.id = k, .kind = (int32_t)(k % 7), .t = 0.5 * (double)k};
        e.v[gcp_event_scalar(e.kind) ? 0 : GCP_EVENT_NV - 1] = -(double)k;
        cr_assert_eq(gcp_events_push(&ev, &e), 0);
        if (ev.cap * (int64_t)sizeof e >= (int64_t)2 << 20)
            cr_assert_eq((uintptr_t)ev.e % ((uintptr_t)2 << 20), 0, "storage not 2 MiB aligned");
        if (ev.scap * (int64_t)sizeof *ev.s >= (int64_t)2 << 20)
            cr_assert_eq((uintptr_t)ev.s % ((uintptr_t)2 << 20), 0, "scalars not 2 MiB aligned");
    }
    cr_assert_eq(ev.n + ev.ns, n);
    /* k % 7 in 2 .. 4: three of each 7, and of the last n % 7 those past 2 */
    const int64_t r7 = n % 7;
    cr_assert_eq(ev.ns, 3 * (n / 7) + (r7 > 2 ? (r7 - 2 < 3 ? r7 - 2 : 3) : 0));
    int64_t bad = 0, ke = 0, ks = 0;
    for (int64_t k = 0; k < n; k++) {
        const int32_t kind = (int32_t)(k % 7);
        if (gcp_event_scalar(kind)) {
            const struct gcp_scalar_event *s = &ev.s[ks++];
            bad += s->id != k || s->kind != kind || s->t != 0.5 * (double)k || s->v != -(double)k;
            continue;
        }
        const struct gcp_event *e = &ev.e[ke++];
        bad += e->id != k || e->kind != kind || e->t != 0.5 * (double)k ||
               e->v[GCP_EVENT_NV - 1] != -(double)k || e->v[0] != 0.0;
    }
    cr_assert_eq(bad, 0, "%lld events changed by growth", (long long)bad);
    gcp_events_free(&ev);
    cr_assert_eq(ev.n + ev.ns, 0);
    cr_assert_null(ev.e);
    cr_assert_null(ev.s);
}

/* The stream drift contour's points are recorded and taken into the
 * contour only at the end (invariants_samples.c), and not at all where a
 * bound on their azimuth shows no turn: the same events bit for bit as the
 * contour taken point by point (st_eager), over 2200 steps (99 s: the
 * L = 4 lane at pitch 90 deg, which has no equator point, drifts around in
 * ~75 s: its stream contour's drift row) and 300 steps (~0.2 drift: no
 * turn, the points skipped).  One ulp of mu shows
 * (pass_equals_per_lane_bit_for_bit). */
Test(invariants_quiet, deferred_stream_contour_equals_eager_bit_for_bit)
{
    const int steps[2] = {2200, 300};
    for (int k = 0; k < 2; k++) {
        struct gcp_events a = {0}, r = {0};
        int64_t pa, pr, sa, sr;
        run_n(0, 0, 0, steps[k], &a, &pa, &sa);
        run_n(0, 0, 1, steps[k], &r, &pr, &sr);
        cr_log_info("%d steps: %lld drift rows, %lld stream points skipped", steps[k],
                    (long long)count_kind(&a, GCP_EVENT_DRIFT), (long long)sa);
        cr_assert_eq(sr, 0);
        cr_assert(sa > 0, "no contour was skipped");
        int64_t nst = 0; /* stream-contour drift rows (taken in at the end) */
        for (int64_t j = 0; j < a.n; j++)
            nst += a.e[j].kind == GCP_EVENT_DRIFT &&
                   a.e[j].v[GCP_DRIFT_CONTOUR] == GCP_CONTOUR_STREAM;
        cr_log_info("%d steps: %lld stream-contour drift rows", steps[k], (long long)nst);
        if (k == 0) cr_assert(nst >= 1);
        cr_assert_eq(a.n, r.n);
        cr_assert_eq(a.ns, r.ns);
        cr_assert_eq(memcmp(a.e, r.e, (size_t)a.n * sizeof *a.e), 0,
                     "the deferred stream contour's events differ from the eager one's");
        cr_assert_eq(memcmp(a.s, r.s, (size_t)a.ns * sizeof *a.s), 0);
        gcp_events_free(&a);
        gcp_events_free(&r);
    }
}
