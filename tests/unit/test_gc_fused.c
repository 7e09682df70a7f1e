/* The fused gc-rk4 step (src/pushers/gc_rk4_fused.c) against the block
 * step it replaces.
 *
 * For each closed-form field (the dipole without corotation, uniform B,
 * uniform B and E), a block of N = 300 guiding centres (two full tiles
 * and a partial one) is pushed twice: in the model itself, where the fused
 * step runs, and in a callback field that calls the model's own eval (no
 * closed form: the block step, the model's numbers).  Lanes leave the
 * domain at different steps (tiles stop early and are run again to the
 * block's step), one starts non-finite, in the dipole a second push stops
 * lanes at the start of a step by the adiabaticity test (a tile stops
 * before that step; when it is the first step of a call, the block step
 * takes it), and a sampler every 7 steps records the live lanes (and once
 * without a sampler: the whole push in one call of the fused step).
 *
 * The fused step evaluates the right-hand side in another arrangement (|B|
 * and B.grad B in closed form, B*_par = |B| in a curl-free field): each
 * evaluation differs from the block step's by a few ulp, so the states are
 * compared to a derived tolerance (at `tolerance` below), while statuses,
 * stop times, step counts, lane order and the sample count must be equal.
 * Cost: 0.5 s (both tests). */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include <criterion/criterion.h>

#include "gcpush/field.h"
#include "gcpush/field_kernels.h"
#include "gcpush/gc.h"
#include "gcpush/particles.h"
#include "gcpush/pusher.h"
#include "pushers/gc_rk4_priv.h"

#define N 300
#define NSTEPS 400
#define EVERY 7
#define NSAMPLES (NSTEPS / EVERY)

static int wrapped_eval(double t, const double x[3], struct gcp_field_sample *out, void *ctx)
{
    return gcp_field_eval(ctx, t, x, out);
}

/* The live lanes at each sample: time, count, index and state. */
struct trace {
    int calls;
    double t[NSAMPLES];
    size_t n[NSAMPLES];
    size_t index[NSAMPLES][N];
    double s[NSAMPLES][4][N];
};
static void sample(const struct gcp_block *b, double t, void *ctx)
{
    struct trace *tr = ctx;
    cr_assert_lt(tr->calls, NSAMPLES);
    const int c = tr->calls++;
    tr->t[c] = t, tr->n[c] = b->n_active;
    const double *a[4] = {b->x, b->y, b->z, b->ppar};
    for (size_t i = 0; i < b->n_active; i++) {
        tr->index[c][i] = b->index[i];
        for (int k = 0; k < 4; k++) tr->s[c][k][i] = a[k][i];
    }
}

/* Deterministic lanes: positions spread over L about x0, p_par and
 * p_perp (mu at x0's |B|) from momentum p and pitch angles 20 .. 85 deg
 * of either sign; lane 17 non-finite. */
static void fill(struct gcp_block *b, const struct gcp_field *f, const double x0[3], double L,
                 double p)
{
    uint64_t s = 0x9E3779B97F4A7C15ull;
    struct gcp_field_sample fs = {.need = GCP_NEED_B};
    cr_assert_eq(gcp_field_eval(f, 0.0, x0, &fs), 0);
    const double B0 = sqrt(fs.B[0] * fs.B[0] + fs.B[1] * fs.B[1] + fs.B[2] * fs.B[2]);
    for (size_t i = 0; i < N; i++) {
        double r[4];
        for (int k = 0; k < 4; k++) {
            s = s * 6364136223846793005ull + 1442695040888963407ull;
            r[k] = (double)(s >> 11) * 0x1.0p-53 * 2.0 - 1.0;
        }
        b->x[i] = x0[0] + L * r[0], b->y[i] = x0[1] + L * r[1], b->z[i] = x0[2] + L * r[2];
        const double a = (20.0 + 65.0 * fabs(r[3])) * GCP_PI / 180.0;
        b->ppar[i] = (r[3] < 0 ? -p : p) * cos(a);
        b->mu[i] = (p * sin(a)) * (p * sin(a)) / (2.0 * GCP_M_PROTON * B0);
        b->status[i] = 0, b->steps[i] = 0, b->index[i] = i, b->t[i] = 0.0;
    }
    b->ppar[17] = NAN;
    b->n_active = N;
}

static void run(const struct gcp_field *f, const struct gcp_field *scene, const double x0[3],
                double L, double p, const struct gcp_push_opts *o, int64_t every,
                struct gcp_block *b, struct trace *tr)
{
    cr_assert_eq(gcp_block_alloc(b, N), 0);
    b->q = GCP_E_CHARGE, b->m = GCP_M_PROTON;
    fill(b, scene, x0, L, p);
    tr->calls = 0;
    const struct gcp_sampler s = {every, sample, tr};
    gcp_pusher_gc_rk4.advance(b, f, &gcp_pusher_gc_rk4, o, every ? &s : NULL);
}

/* |a - b| within tol (NaN equal to NaN: the non-finite lane). */
static int near(double a, double b, double tol)
{
    return (isnan(a) && isnan(b)) || fabs(a - b) <= tol;
}

static struct trace ta, tb, tc;

static void compare(const char *what, const struct gcp_field *model, const double x0[3], double L,
                    double p, const struct gcp_push_opts *o, int64_t every, int want_nonadiabatic)
{
    struct gcp_field *twin = gcp_field_callback_create(wrapped_eval, (void *)model, model->has_E);
    cr_assert_not_null(twin);
    twin->r_inner = model->r_inner, twin->r_outer = model->r_outer, twin->z_max = model->z_max;
    struct gcp_point_B form, none;
    cr_assert(gcp_field_point_B(model, &form), "%s: no closed form", what);
    cr_assert(!gcp_field_point_B(twin, &none), "%s: the twin has a closed form", what);
    /* the fused step does run for this form: else the test compares the
     * block step with itself */
    cr_assert(gcp_rk4_fused_tile(form.form, form.has_E), "%s: no fused step", what);
    struct gcp_block a, b;
    run(model, model, x0, L, p, o, every, &a, &ta);
    run(twin, model, x0, L, p, o, every, &b, &tb);
    /* The tolerance.  Each right-hand-side evaluation of the fused step
     * differs from the block step's by a few ulp (different operations,
     * none that amplifies an error: 1/|B| and 1/gamma come from one
     * division), say 16 eps = 3.6e-15 relative.  Over the push these add
     * up to at most 16 eps of the distance travelled (each step adds h
     * dX/dt, off by 16 eps), and the bounce and drift carry a difference
     * forward with a phase error that grows with the number of periods
     * (3 bounces: a factor ~ 2 pi x 3 ~ 20): 7e-14 of the travel, taken as
     * 1e-12 of the largest travel |X_end - X_0| (of |p| for p_par).
     * Measured: up to 7e-14.  A push with dt 1e-9 longer differs by ~1e-9
     * of the travel, and is checked to fail it (below). */
    double travel = 0.0, pmax = 0.0;
    for (size_t i = 0; i < N; i++) {
        if (!isfinite(b.ppar[i])) continue;
        pmax = fmax(pmax, fabs(b.ppar[i]));
    }
    pmax = fmax(pmax, p);
    {
        struct gcp_block c;
        cr_assert_eq(gcp_block_alloc(&c, N), 0);
        fill(&c, model, x0, L, p);
        for (size_t i = 0; i < N; i++) {
            const size_t j = b.index[i];
            if (!isfinite(b.x[i] + b.y[i] + b.z[i]) || j == 17) continue;
            travel = fmax(travel, hypot(hypot(b.x[i] - c.x[j], b.y[i] - c.y[j]), b.z[i] - c.z[j]));
        }
        gcp_block_free(&c);
    }
    const double tolx = 1e-12 * travel, tolp = 1e-12 * pmax;
    if (!every) {
        /* the tolerance can fail: the block step with dt 1e-9 longer */
        struct gcp_push_opts o2 = *o;
        o2.dt = o->dt * (1.0 + 1e-9);
        struct gcp_block d;
        run(twin, model, x0, L, p, &o2, 0, &d, &tc);
        size_t outside = 0, live = 0;
        for (size_t i = 0; i < N; i++) {
            if (d.status[i] != GCP_ALIVE || b.status[i] != GCP_ALIVE) continue;
            live++;
            outside += !near(d.x[i], b.x[i], tolx) || !near(d.y[i], b.y[i], tolx) ||
                       !near(d.z[i], b.z[i], tolx);
        }
        cr_expect(live > 0 && outside > live / 2, "%s: dt 1e-9 longer: %zu of %zu lanes outside",
                  what, outside, live);
        gcp_block_free(&d);
    }
    size_t stopped = 0, nonadiabatic = 0, distinct_stops = 0;
    int64_t last = -1;
    double worst = 0.0;
    cr_expect_eq(a.n_active, b.n_active, "%s: live %zu, block step %zu", what, a.n_active,
                 b.n_active);
    for (size_t i = 0; i < N; i++) {
        const double *da[4] = {a.x, a.y, a.z, a.ppar};
        const double *db[4] = {b.x, b.y, b.z, b.ppar};
        for (int k = 0; k < 4; k++) {
            const double tol = k < 3 ? tolx : tolp;
            cr_expect(near(da[k][i], db[k][i], tol), "%s: lane %zu array %d: %.17g, block %.17g",
                      what, i, k, da[k][i], db[k][i]);
            if (isfinite(da[k][i] - db[k][i])) worst = fmax(worst, fabs(da[k][i] - db[k][i]) / tol);
        }
        cr_expect(memcmp(&a.t[i], &b.t[i], sizeof(double)) == 0, "%s: lane %zu t", what, i);
        cr_expect_eq(a.status[i], b.status[i], "%s: lane %zu status %d, block %d", what, i,
                     a.status[i], b.status[i]);
        cr_expect_eq(a.steps[i], b.steps[i], "%s: lane %zu steps", what, i);
        cr_expect_eq(a.index[i], b.index[i], "%s: lane %zu index", what, i);
        if (a.status[i] != GCP_ALIVE && a.steps[i] > 0) {
            stopped++;
            nonadiabatic += a.status[i] == GCP_NONADIABATIC;
            if (a.steps[i] != last) distinct_stops++, last = a.steps[i];
        }
    }
    cr_expect_eq(ta.calls, every ? NSTEPS / every : 0, "%s: %d samples", what, ta.calls);
    cr_expect_eq(ta.calls, tb.calls);
    for (int c = 0; c < ta.calls && c < tb.calls; c++) {
        cr_expect_eq(ta.t[c], tb.t[c]);
        cr_expect_eq(ta.n[c], tb.n[c], "%s: sample %d: %zu live, block %zu", what, c, ta.n[c],
                     tb.n[c]);
        for (size_t i = 0; i < ta.n[c] && i < tb.n[c]; i++) {
            cr_expect_eq(ta.index[c][i], tb.index[c][i]);
            for (int k = 0; k < 4; k++)
                cr_expect(near(ta.s[c][k][i], tb.s[c][k][i], k < 3 ? tolx : tolp),
                          "%s: sample %d lane %zu array %d", what, c, i, k);
        }
    }
    /* the scene exercises early tile stops: lanes leave mid-push at several steps */
    cr_expect(stopped >= 5 && stopped < N / 2 && distinct_stops >= 3,
              "%s: %zu lanes stopped mid-push (%zu distinct steps)", what, stopped, distinct_stops);
    if (want_nonadiabatic)
        cr_expect_geq(nonadiabatic, 3, "%s: %zu lanes stopped by the start-of-step check", what,
                      nonadiabatic);
    cr_log_info("%s, every %d: %zu lanes stopped mid-push at %zu distinct steps (%zu "
                "non-adiabatic), %d samples, largest difference %.3g of the tolerance",
                what, (int)every, stopped, distinct_stops, nonadiabatic, ta.calls, worst);
    gcp_block_free(&a);
    gcp_block_free(&b);
    gcp_field_free(twin);
}

Test(gc_fused, near_block_step_every_form)
{
    const double RE = GCP_EARTH_RADIUS, MP = GCP_M_PROTON, C = GCP_C_LIGHT;
    /* dipole: 1 MeV protons within 0.5 R_E of (4 R_E, 0, 0) (bounce period
     * ~ 7 s), 400 steps of 0.05 s (3 bounces); |z| < 1.6 R_E: lanes of small
     * pitch angle leave at their first pass of it.  With adiabaticity_max =
     * 0.038 (rho/L_B ~ 0.03-0.06 here, largest at the equator), lanes that
     * start off the equator below it stop at the start of a step on their
     * way to the equator. */
    struct gcp_field *dip = gcp_field_dipole_create(GCP_EARTH_B0, 0, RE, 15.0 * RE);
    cr_assert(dip);
    dip->z_max = 1.6 * RE;
    const double g = 1.0 + 1.602176634e-13 / (MP * C * C), pd = MP * C * sqrt(g * g - 1.0);
    const double xd[3] = {4.0 * RE, 0.0, 0.0};
    /* uniform: 1 T along (0.3, 0.4, sqrt(0.75)), domain |x| < 2 m; 1e6 m/s
     * protons within 0.9 m of the origin move up to 5 mm along B a step */
    const double B[3] = {0.3, 0.4, sqrt(0.75)}, E[3] = {0.0, 4e4, -2e4};
    struct gcp_field *uni = gcp_field_uniform_create(B, NULL);
    struct gcp_field *uniE = gcp_field_uniform_create(B, E);
    cr_assert(uni && uniE);
    uni->r_outer = uniE->r_outer = 2.0;
    const double xu[3] = {0.0, 0.0, 0.0}, pu = MP * 1e6;
    const struct gcp_push_opts od = {0.0, 0.05, NSTEPS, 0.0, 0.0};
    /* the start-of-step adiabaticity test stops some lanes mid-push */
    const struct gcp_push_opts oda = {0.0, 0.05, NSTEPS, 0.0, 0.038};
    const struct gcp_push_opts ou = {0.0, 5e-9, NSTEPS, 0.0, 0.0};
    /* with a sampler (up to EVERY steps at once) and without (the whole
     * push at once, tiles stopped early and run again) */
    for (int64_t every = 0; every <= EVERY; every += EVERY) {
        compare("dipole", dip, xd, 0.5 * RE, pd, &od, every, 0);
        compare("dipole, adiabaticity", dip, xd, 0.5 * RE, pd, &oda, every, 1);
        compare("uniform B", uni, xu, 0.9, pu, &ou, every, 0);
        compare("uniform B and E", uniE, xu, 0.9, pu, &ou, every, 0);
    }
    gcp_field_free(dip);
    gcp_field_free(uni);
    gcp_field_free(uniE);
}

/* The dipole's point forms against the model's own evaluation at points
 * over 1.2 .. 8 R_E and all latitudes: B and grad B of gcp_point_BG_dipole
 * bit for bit (the fused step's adiabaticity test must give the block
 * step's verdicts), A of gcp_point_A_dipole bit for bit (the invariant
 * observer's drift contour takes it for the model's potential); |B|, C = B x H and P = B.H (H = B.grad B) of
 * gcp_point_gc_dipole against those formed from the model's B and grad B,
 * to round-off: each side is ~10 correctly rounded operations from the
 * same point, so 32 eps relative to |B| and to |B| |H|. */
Test(gc_fused, dipole_point_forms)
{
    const double RE = GCP_EARTH_RADIUS;
    struct gcp_field *f = gcp_field_dipole_create(GCP_EARTH_B0, 0, RE, 15.0 * RE);
    cr_assert(f);
    struct gcp_point_B form;
    cr_assert(gcp_field_point_B(f, &form) && form.form == GCP_POINT_B_DIPOLE);
    double worst = 0.0;
    for (int i = 0; i < 200; i++) {
        const double r = RE * (1.2 + 6.8 * (i % 17) / 16.0), lat = GCP_PI * (i / 200.0 - 0.5);
        const double lon = 0.7 * i;
        const double x[3] = {r * cos(lat) * cos(lon), r * cos(lat) * sin(lon), r * sin(lat)};
        struct gcp_field_sample s = {.need = GCP_NEED_B | GCP_NEED_GRADB};
        cr_assert_eq(gcp_field_eval(f, 0.0, x, &s), 0);
        double B[3], G[3][3], Bc[3], Bm, C[3], P;
        gcp_point_BG_dipole(form.p[0], x[0], x[1], x[2], B, G);
        gcp_point_gc_dipole(form.p[0], x[0], x[1], x[2], Bc, &Bm, C, &P);
        cr_expect(memcmp(B, s.B, sizeof B) == 0 && memcmp(Bc, s.B, sizeof Bc) == 0,
                  "point %d: B not bit for bit", i);
        cr_expect(memcmp(G, s.gradB, sizeof G) == 0, "point %d: grad B not bit for bit", i);
        double A[3], A0[3];
        gcp_point_A_dipole(form.p[0], x[0], x[1], x[2], A);
        cr_assert_eq(gcp_field_potential(f, 0.0, x, A0, NULL, NULL), 0);
        cr_expect(memcmp(A, A0, sizeof A) == 0, "point %d: A not bit for bit", i);
        const double *b = s.B;
        const double Bm0 = sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
        double H[3];
        for (int j = 0; j < 3; j++)
            H[j] = b[0] * s.gradB[0][j] + b[1] * s.gradB[1][j] + b[2] * s.gradB[2][j];
        const double C0[3] = {b[1] * H[2] - b[2] * H[1], b[2] * H[0] - b[0] * H[2],
                              b[0] * H[1] - b[1] * H[0]};
        const double P0 = b[0] * H[0] + b[1] * H[1] + b[2] * H[2];
        const double tolB = 32.0 * DBL_EPSILON * Bm0;
        const double tolH = 32.0 * DBL_EPSILON * Bm0 * sqrt(H[0] * H[0] + H[1] * H[1] + H[2] * H[2]);
        cr_expect(fabs(Bm - Bm0) <= tolB, "point %d: |B| %.17g, model %.17g", i, Bm, Bm0);
        cr_expect(fabs(P - P0) <= tolH, "point %d: B.H %.17g, model %.17g", i, P, P0);
        worst = fmax(worst, fmax(fabs(Bm - Bm0) / tolB, fabs(P - P0) / tolH));
        for (int j = 0; j < 3; j++) {
            cr_expect(fabs(C[j] - C0[j]) <= tolH, "point %d: (B x H)%d %.17g, model %.17g", i, j,
                      C[j], C0[j]);
            worst = fmax(worst, fabs(C[j] - C0[j]) / tolH);
        }
    }
    cr_log_info("dipole point forms: largest |B|, B x H, B.H difference %.3g of the tolerance",
                worst);
    gcp_field_free(f);
}
