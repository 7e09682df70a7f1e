/* The fast arithmetic tier of boris (src/pushers/boris_fast.c; opt-in,
 * GCP_BLOCK_FAST_ARITH / [integrator] arithmetic = fast) against the IEEE
 * tier and against closed forms.
 *
 *  - its refined 1/sqrt and 1/x against long double over 1e-300 .. 1e300:
 *    two Newton steps from a 2^-14 estimate leave (3/2)(2^-28)^2 ~ 2^-55
 *    relative plus the last fused update's rounding (<= 1/2 ulp) and the
 *    residual's (one product rounded: <= 1/4 ulp): at most 1 ulp;
 *  - one step from the same state as the IEEE tile (the limit scene, 1 MeV
 *    protons at L = 3.5 .. 4.5, Omega dt = 0.05): |dx| <= 2 eps |x|,
 *    |du| <= 4 eps |u| (derived below), and not bit-identical (else the
 *    tier does not run and the test would compare IEEE with itself);
 *  - pure B: |u| kept to round-off over 20000 steps (a random walk of a few
 *    eps a step: <= 8 eps sqrt(N)), as the IEEE tile keeps it, where a
 *    method without the property -- the same rotation with s rounded to
 *    float, |u+| != |u-| by ~1e-8 a step -- fails the bound;
 *  - uniform B: the gyration's phase after N steps is Boris's closed form
 *    N 2 atan(Omega dt / 2 gamma) (Birdsall & Langdon sec. 15-4) to
 *    round-off, u_par and |u| kept;
 *  - a push in one call equals the same push one step a call (bit for bit:
 *    the tier recomputes 1/gamma from u on entry with the step's own
 *    expression), and the stop verdicts (inner bound, a non-finite lane)
 *    come at the same step as the IEEE tile's;
 *  - pushers without a fast tier (vay): the flag changes no bit.
 * Where the CPU has no AVX-512F there is no tier: the tests that need it
 * say so and check that the flag then changes nothing.  Cost: ~0.2 s. */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include <criterion/criterion.h>

#include "gcpush/field.h"
#include "gcpush/field_kernels.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "gcpush/pusher.h"
#include "gcpush/units.h"
#include "pushers/fo_fast_priv.h"

#define EPS DBL_EPSILON

static uint64_t rng_s = 0x243F6A8885A308D3ull;
static double urand(void)
{
    rng_s = rng_s * 6364136223846793005ull + 1442695040888963407ull;
    return (double)(rng_s >> 11) * 0x1.0p-53;
}

static int have_tier(void) { return gcp_arithmetic_fast_available(&gcp_pusher_boris); }

Test(boris_fast, primitives_within_one_ulp)
{
    enum { M = 4096 };
    static double in[M], rs[M], rc[M];
    for (int i = 0; i < M; i++) in[i] = pow(10.0, -300.0 + 600.0 * urand());
    in[0] = 1.0, in[1] = 2.0, in[2] = 1.0 + EPS, in[3] = 4.0 - 2.0 * EPS;
    if (gcp_fo_fast_prims(M, in, rs, rc) != 0) {
        cr_assert(!have_tier(), "no primitives, yet a fast tier");
        cr_log_warn("no AVX-512F: no fast tier to test");
        return;
    }
    double worst_rs = 0.0, worst_rc = 0.0;
    for (int i = 0; i < M; i++) {
        const long double x = in[i], ers = 1.0L / sqrtl(x), erc = 1.0L / x;
        /* in ulps of the exact value's binade */
        const double urs = ldexp(1.0, ilogb((double)ers) - 52), urc = ldexp(1.0, ilogb((double)erc) - 52);
        worst_rs = fmax(worst_rs, (double)fabsl((long double)rs[i] - ers) / urs);
        worst_rc = fmax(worst_rc, (double)fabsl((long double)rc[i] - erc) / urc);
    }
    cr_assert(worst_rs <= 1.0, "1/sqrt: %.3f ulp", worst_rs);
    cr_assert(worst_rc <= 1.0, "1/x: %.3f ulp", worst_rc);
}

/* The limit scene of bench_push (kernel (b)): n protons of 1 MeV on the
 * equator at L = 3.5 .. 4.5, pitch 30 .. 80 deg; *dt: Omega_eq(L=4) dt =
 * 0.05. */
static void dipole_scene(struct gcp_block *b, size_t n, double *dt)
{
    const double RE = GCP_EARTH_RADIUS, mc2 = GCP_M_PROTON * GCP_C_LIGHT * GCP_C_LIGHT;
    const double g = 1.0 + 1.602176634e-13 / mc2, u = GCP_C_LIGHT * sqrt(g * g - 1.0);
    cr_assert_eq(gcp_block_alloc(b, n), 0);
    b->q = GCP_E_CHARGE, b->m = GCP_M_PROTON;
    for (size_t i = 0; i < n; i++) {
        const double L = 3.5 + urand(), lon = 2.0 * GCP_PI * urand();
        const double a = (30.0 + 50.0 * urand()) * GCP_PI / 180.0, ph = 2.0 * GCP_PI * urand();
        b->x[i] = L * RE * cos(lon), b->y[i] = L * RE * sin(lon), b->z[i] = 0.0;
        b->ux[i] = u * sin(a) * cos(ph), b->uy[i] = u * sin(a) * sin(ph), b->uz[i] = u * cos(a);
        b->status[i] = 0, b->steps[i] = 0, b->index[i] = i, b->t[i] = 0.0;
    }
    b->n_active = n;
    *dt = 0.05 * g * GCP_M_PROTON / (GCP_E_CHARGE * GCP_EARTH_B0 / 64.0);
}

static void copy_state(struct gcp_block *d, const struct gcp_block *s)
{
    const size_t n = s->n_active;
    memcpy(d->x, s->x, n * sizeof(double)), memcpy(d->y, s->y, n * sizeof(double));
    memcpy(d->z, s->z, n * sizeof(double)), memcpy(d->ux, s->ux, n * sizeof(double));
    memcpy(d->uy, s->uy, n * sizeof(double)), memcpy(d->uz, s->uz, n * sizeof(double));
    memcpy(d->index, s->index, n * sizeof(size_t));
    d->n_active = n;
}

/* One step from the same states: the tiers agree to a few ulp.  x: each
 * tier rounds each coordinate twice (x + u hg, twice; 1/2 ulp each) and
 * the drifts u hg, ~1e-3 of |x| here, differ by a few ulp of themselves:
 * |dx| <= 2 eps |x|.  u: u+ = u- + s (u' x t) rounds its last sum once in
 * each tier (1/2 ulp each: 1 eps |u|), and the correction s (u' x t), of
 * size ~2 |t| |u| (|t| ~ 0.03 at Omega dt = 0.05), differs by its own
 * few-ulp differences -- t from (1/r)^5 (5 x 1 ulp of 1/r, 4 products)
 * against c/(r^4 sqrt r2), and fused against separate roundings: ~15 eps
 * of 2 |t| |u| = 1 eps |u|: |du| <= 2 eps |u|, bounded at 4 (the
 * roundings' worst alignment). */
Test(boris_fast, one_step_within_a_few_ulp_of_ieee)
{
    struct gcp_field *f = gcp_field_dipole_create(GCP_EARTH_B0, 0, GCP_EARTH_RADIUS + 100e3,
                                                  15.0 * GCP_EARTH_RADIUS);
    cr_assert_not_null(f);
    enum { NL = 1000 };
    struct gcp_block a, b;
    double dt;
    dipole_scene(&a, NL, &dt);
    cr_assert_eq(gcp_block_alloc(&b, NL), 0);
    b.q = a.q, b.m = a.m;
    double worst_x = 0.0, worst_u = 0.0;
    int differ = 0;
    for (int rep = 0; rep < 20; rep++) { /* 20 states along the orbits */
        copy_state(&b, &a);
        for (size_t i = 0; i < NL; i++) b.status[i] = 0, b.steps[i] = 0, b.t[i] = 0.0;
        gcp_block_start(&b, f, 0.0);
        b.flags = GCP_BLOCK_FAST_ARITH;
        cr_assert_eq(gcp_block_advance_fo(&b, f, &gcp_pusher_boris, 0.0, dt, 1, NULL), NL);
        gcp_block_start(&a, f, 0.0);
        cr_assert_eq(gcp_block_advance_fo(&a, f, &gcp_pusher_boris, 0.0, dt, 1, NULL), NL);
        for (size_t i = 0; i < NL; i++) {
            const double X = hypot(hypot(a.x[i], a.y[i]), a.z[i]);
            const double U = hypot(hypot(a.ux[i], a.uy[i]), a.uz[i]);
            const double dx = hypot(hypot(a.x[i] - b.x[i], a.y[i] - b.y[i]), a.z[i] - b.z[i]);
            const double du =
                hypot(hypot(a.ux[i] - b.ux[i], a.uy[i] - b.uy[i]), a.uz[i] - b.uz[i]);
            worst_x = fmax(worst_x, dx / (EPS * X));
            worst_u = fmax(worst_u, du / (EPS * U));
            differ |= dx != 0.0 || du != 0.0;
        }
        /* the next state: 50 IEEE steps on */
        cr_assert_eq(gcp_block_advance_fo(&a, f, &gcp_pusher_boris, 0.0, dt, 50, NULL), NL);
    }
    cr_log_info("one step, fast vs IEEE: |dx| <= %.2f eps |x|, |du| <= %.2f eps |u|", worst_x,
                worst_u);
    cr_assert(worst_x <= 2.0, "|dx| = %.2f eps |x|", worst_x);
    cr_assert(worst_u <= 4.0, "|du| = %.2f eps |u|", worst_u);
    /* bit-identical would mean the tier did not run */
    cr_assert_eq(differ, have_tier(), "fast tier %s, yet the steps %s", have_tier() ? "on" : "off",
                 differ ? "differ" : "agree");
    gcp_block_free(&a), gcp_block_free(&b);
    gcp_field_free(f);
}

/* max over lanes of | |u|/|u0| - 1 | after nsteps steps of the dipole
 * scene, with the block flags given. */
static double speed_drift(unsigned flags, int64_t nsteps)
{
    struct gcp_field *f = gcp_field_dipole_create(GCP_EARTH_B0, 0, GCP_EARTH_RADIUS + 100e3,
                                                  15.0 * GCP_EARTH_RADIUS);
    struct gcp_block b;
    double dt;
    rng_s = 0x13198A2E03707344ull;
    dipole_scene(&b, 256, &dt);
    double u0[256];
    for (size_t i = 0; i < 256; i++) u0[i] = hypot(hypot(b.ux[i], b.uy[i]), b.uz[i]);
    gcp_block_start(&b, f, 0.0);
    b.flags = flags;
    cr_assert_eq(gcp_block_advance_fo(&b, f, &gcp_pusher_boris, 0.0, dt, nsteps, NULL), 256);
    double worst = 0.0;
    for (size_t i = 0; i < 256; i++) {
        const size_t k = b.index[i];
        worst = fmax(worst, fabs(hypot(hypot(b.ux[i], b.uy[i]), b.uz[i]) / u0[k] - 1.0));
    }
    gcp_block_free(&b);
    gcp_field_free(f);
    return worst;
}

/* A rotation without the property: Boris's with s = 2/(1 + t^2) rounded
 * to float, so |u+|^2 = |u-|^2 (1 + O(t^2 1e-8)) -- the step a method
 * whose rotation is not exactly orthogonal takes. */
static double speed_drift_float_s(int64_t nsteps)
{
    struct gcp_field *f = gcp_field_dipole_create(GCP_EARTH_B0, 0, GCP_EARTH_RADIUS + 100e3,
                                                  15.0 * GCP_EARTH_RADIUS);
    struct gcp_point_B form;
    cr_assert(gcp_field_point_B(f, &form) && form.form == GCP_POINT_B_DIPOLE);
    const double c = form.p[0];
    gcp_field_free(f);
    struct gcp_block b;
    double dt;
    rng_s = 0x13198A2E03707344ull;
    dipole_scene(&b, 16, &dt);
    const double h = 0.5 * dt, qdt2m = 0.5 * b.q * dt / b.m;
    double worst = 0.0;
    for (size_t i = 0; i < 16; i++) {
        double x[3] = {b.x[i], b.y[i], b.z[i]}, u[3] = {b.ux[i], b.uy[i], b.uz[i]};
        const double u0 = hypot(hypot(u[0], u[1]), u[2]);
        for (int64_t k = 0; k < nsteps; k++) {
            const double ig = 1.0 / gcp_gamma_of_u(u[0], u[1], u[2]);
            for (int j = 0; j < 3; j++) x[j] += u[j] * h * ig;
            double B[3], t[3];
            gcp_point_B_dipole(c, x[0], x[1], x[2], &B[0], &B[1], &B[2]);
            for (int j = 0; j < 3; j++) t[j] = qdt2m * ig * B[j];
            const double s = (float)(2.0 / (1.0 + t[0] * t[0] + t[1] * t[1] + t[2] * t[2]));
            gcp_boris_rotate_ts_(&u[0], &u[1], &u[2], t[0], t[1], t[2], s);
            const double ig1 = 1.0 / gcp_gamma_of_u(u[0], u[1], u[2]);
            for (int j = 0; j < 3; j++) x[j] += u[j] * h * ig1;
        }
        worst = fmax(worst, fabs(hypot(hypot(u[0], u[1]), u[2]) / u0 - 1.0));
    }
    gcp_block_free(&b);
    return worst;
}

/* |u| in pure B: each step's rotation keeps |u| to a few roundings
 * (~4 eps a step, random in sign), so after N steps the drift is a random
 * walk, <= 8 eps sqrt(N) with a margin of ~2 over its largest lane. */
Test(boris_fast, speed_kept_in_pure_B)
{
    const int64_t N = 20000;
    const double bound = 8.0 * EPS * sqrt((double)N);
    const double ieee = speed_drift(0u, N), fast = speed_drift(GCP_BLOCK_FAST_ARITH, N);
    const double loose = speed_drift_float_s(N);
    cr_log_info("| |u|/|u0| - 1 | after %lld steps: IEEE %.3g, fast %.3g, float s %.3g (bound %.3g)",
                (long long)N, ieee, fast, loose, bound);
    cr_assert(ieee <= bound, "IEEE: %.3g", ieee);
    cr_assert(fast <= bound, "fast: %.3g", fast);
    cr_assert(loose > bound, "a rotation that is not orthogonal passes: %.3g", loose);
}

/* Uniform B along z: from u = (u_perp, 0, u_par) the phase after N steps is
 * N 2 atan(Omega dt / 2 gamma) (Omega = q B / m), u_par and |u| kept; the
 * closed form's own rounding and the N steps' (~4 eps each, a random walk)
 * leave |phase error| <= 1e-12 rad for N = 2000. */
Test(boris_fast, gyration_phase_closed_form)
{
    const double B = 1.0, q = GCP_E_CHARGE, m = GCP_M_PROTON;
    struct gcp_field *f = gcp_field_uniform_create((const double[3]){0, 0, B}, (const double[3]){0, 0, 0});
    cr_assert_not_null(f);
    enum { NL = 40 };
    struct gcp_block b;
    cr_assert_eq(gcp_block_alloc(&b, NL), 0);
    b.q = q, b.m = m;
    const double up = 0.3 * GCP_C_LIGHT, upar = 0.1 * GCP_C_LIGHT;
    const double gam = gcp_gamma_of_u(up, 0.0, upar), Om = q * B / m;
    const double dt = 0.2 * gam / Om; /* Omega dt / gamma = 0.2 */
    for (size_t i = 0; i < NL; i++) {
        b.x[i] = (double)i, b.y[i] = 0.0, b.z[i] = 0.0;
        b.ux[i] = up, b.uy[i] = 0.0, b.uz[i] = upar;
        b.status[i] = 0, b.steps[i] = 0, b.index[i] = i, b.t[i] = 0.0;
    }
    b.n_active = NL;
    const int64_t N = 2000;
    gcp_block_start(&b, f, 0.0);
    b.flags = GCP_BLOCK_FAST_ARITH;
    cr_assert_eq(gcp_block_advance_fo(&b, f, &gcp_pusher_boris, 0.0, dt, N, NULL), NL);
    /* q > 0 turns u clockwise about +z: phase -N 2 atan(Omega dt / 2 gamma) */
    const double want = remainder(-2.0 * (double)N * atan(0.5 * Om * dt / gam), 2.0 * GCP_PI);
    for (size_t i = 0; i < NL; i++) {
        const double ph = atan2(b.uy[i], b.ux[i]);
        cr_assert(fabs(remainder(ph - want, 2.0 * GCP_PI)) <= 1e-12, "lane %zu: phase %.17g, want %.17g",
                  i, ph, want);
        cr_assert(fabs(b.uz[i] / upar - 1.0) <= 4.0 * EPS, "u_par moved: %.3g", b.uz[i] / upar - 1.0);
        cr_assert(fabs(hypot(b.ux[i], b.uy[i]) / up - 1.0) <= 8.0 * EPS * sqrt((double)N));
    }
    gcp_block_free(&b);
    gcp_field_free(f);
}

/* A push in one call = the same push a step a call; stops at the same step
 * as the IEEE tile (a lane that reaches the inner bound, a non-finite one). */
Test(boris_fast, split_calls_and_stops)
{
    const double RE = GCP_EARTH_RADIUS;
    struct gcp_field *f = gcp_field_dipole_create(GCP_EARTH_B0, 0, 3.6 * RE, 15.0 * RE);
    enum { NL = 300, NS = 400 };
    struct gcp_block a, b, c;
    double dt;
    for (int k = 0; k < 3; k++) {
        struct gcp_block *p = k == 0 ? &a : k == 1 ? &b : &c;
        rng_s = 0x452821E638D01377ull;
        dipole_scene(p, NL, &dt);
        p->uy[17] = NAN;
        gcp_block_start(p, f, 0.0);
    }
    a.flags = b.flags = GCP_BLOCK_FAST_ARITH;
    gcp_block_advance_fo(&a, f, &gcp_pusher_boris, 0.0, dt, NS, NULL);
    for (int64_t k = 0; k < NS; k++)
        gcp_block_advance_fo(&b, f, &gcp_pusher_boris, (double)k * dt, dt, 1, NULL);
    gcp_block_advance_fo(&c, f, &gcp_pusher_boris, 0.0, dt, NS, NULL);
    cr_assert_eq(a.n_active, b.n_active);
    cr_assert(a.n_active < NL - 1, "no lane reached the inner bound: the stops go untested");
    for (size_t i = 0; i < NL; i++) {
        cr_assert_eq(a.index[i], b.index[i]);
        cr_assert(a.x[i] == b.x[i] && a.uz[i] == b.uz[i] && a.status[i] == b.status[i] &&
                      a.steps[i] == b.steps[i] && a.t[i] == b.t[i],
                  "lane %zu: one call and a call a step differ", i);
    }
    /* the IEEE tile: the same lanes stop at the same steps (the orbits
     * differ by round-off; a lane grazing the bound could flip, none here) */
    int64_t sa[NL], sc[NL];
    int32_t ta[NL], tc[NL];
    for (size_t i = 0; i < NL; i++)
        sa[a.index[i]] = a.steps[i], ta[a.index[i]] = a.status[i], sc[c.index[i]] = c.steps[i],
        tc[c.index[i]] = c.status[i];
    for (size_t i = 0; i < NL; i++)
        cr_assert(sa[i] == sc[i] && ta[i] == tc[i], "lane %zu: fast stops %d at %lld, IEEE %d at %lld",
                  i, ta[i], (long long)sa[i], tc[i], (long long)sc[i]);
    gcp_block_free(&a), gcp_block_free(&b), gcp_block_free(&c);
    gcp_field_free(f);
}

/* No fast tier for vay: the flag changes no bit. */
Test(boris_fast, other_pushers_unchanged)
{
    cr_assert(!gcp_arithmetic_fast_available(&gcp_pusher_vay));
    struct gcp_field *f = gcp_field_dipole_create(GCP_EARTH_B0, 0, GCP_EARTH_RADIUS + 100e3,
                                                  15.0 * GCP_EARTH_RADIUS);
    struct gcp_block a, b;
    double dt;
    rng_s = 7, dipole_scene(&a, 100, &dt);
    rng_s = 7, dipole_scene(&b, 100, &dt);
    gcp_block_start(&a, f, 0.0), gcp_block_start(&b, f, 0.0);
    b.flags = GCP_BLOCK_FAST_ARITH;
    gcp_block_advance_fo(&a, f, &gcp_pusher_vay, 0.0, dt, 200, NULL);
    gcp_block_advance_fo(&b, f, &gcp_pusher_vay, 0.0, dt, 200, NULL);
    cr_assert_eq(memcmp(a.x, b.x, 100 * sizeof(double)), 0);
    cr_assert_eq(memcmp(a.uz, b.uz, 100 * sizeof(double)), 0);
    gcp_block_free(&a), gcp_block_free(&b);
    gcp_field_free(f);
}
