/* One bad particle gets a status; the rest of its block finishes untouched.
 *
 * A block of eight protons in uniform B: lane 2 starts with a NaN velocity,
 * lane 5 starts outside the domain, lane 6 drifts out of the mirror's
 * domain mid-run.  The others must end ALIVE with exactly the state they
 * reach when pushed alone (bit for bit: lanes never mix). */
#include <math.h>
#include <string.h>

#include <criterion/criterion.h>

#include "gcpush/field.h"
#include "gcpush/particles.h"
#include "gcpush/pusher.h"

#define N 8

static void fill(struct gcp_block *b, int i, double x, double vz, double vx)
{
    b->x[i] = x, b->y[i] = 0, b->z[i] = 0;
    b->ux[i] = vx, b->uy[i] = 1e5, b->uz[i] = vz;
}

Test(block_status, bad_lanes_retire_others_unchanged)
{
    /* mirror bottle, domain |z| < 1 m */
    struct gcp_field *f = gcp_field_mirror_create(1.0, 0.5, 1.0, INFINITY);
    cr_assert_not_null(f);
    const double q = GCP_E_CHARGE, m = GCP_M_PROTON;
    const double dt = 1e-9; /* omega_c dt ~ 0.1 at 1 T */
    const int64_t nsteps = 20000;
    struct gcp_block b;
    cr_assert_eq(gcp_block_alloc(&b, N), 0);
    b.q = q, b.m = m;
    for (int i = 0; i < N; i++) fill(&b, i, 1e-3 * i, 1e4, 0);
    b.ux[2] = NAN;              /* non-finite start */
    b.z[5] = 2.0;               /* starts outside |z| < 1 m */
    b.uz[6] = 3e6;              /* runs along B out of the bottle (loss cone) */
    cr_assert_eq(gcp_block_start(&b, f, 0.0), N - 2);
    const size_t live = gcp_block_advance_fo(&b, f, &gcp_pusher_boris, 0.0, dt, nsteps, NULL);
    cr_assert_eq(live, N - 3);

    /* undo the lane permutation */
    int32_t status[N];
    double x[N], t[N];
    int64_t steps[N];
    for (size_t k = 0; k < N; k++) {
        status[b.index[k]] = b.status[k];
        x[b.index[k]] = b.x[k];
        t[b.index[k]] = b.t[k];
        steps[b.index[k]] = b.steps[k];
    }
    cr_expect_eq(status[2], GCP_NONFINITE);
    cr_expect_eq(steps[2], 0);
    cr_expect_eq(status[5], GCP_LEFT_DOMAIN);
    cr_expect_eq(steps[5], 0);
    cr_expect_eq(status[6], GCP_LEFT_DOMAIN);
    /* 3e6 m/s along B crosses 1 m in ~0.33 us = ~330 steps, before the end */
    cr_expect(steps[6] > 100 && steps[6] < nsteps, "lane 6 left after %lld steps", (long long)steps[6]);
    cr_expect_float_eq(t[6], steps[6] * dt, 1e-15);

    /* every good lane equals the same particle pushed alone */
    for (int i = 0; i < N; i++) {
        if (i == 2 || i == 5 || i == 6) continue;
        cr_expect_eq(status[i], GCP_ALIVE, "lane %d", i);
        cr_expect_eq(steps[i], nsteps);
        double xs[3] = {1e-3 * i, 0, 0}, us[3] = {0, 1e5, 1e4}, ts = 0;
        int st = gcp_orbit_push(f, &gcp_pusher_boris, q, m, &ts, xs, us, dt, nsteps, NULL, NULL);
        cr_expect_eq(st, GCP_ALIVE);
        cr_expect(memcmp(&xs[0], &x[i], sizeof(double)) == 0, "lane %d differs from a lone push", i);
    }
    gcp_block_free(&b);
    gcp_field_free(f);
}
