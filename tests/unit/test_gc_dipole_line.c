/* gc-gl2 / gc-gl4 in the dipole's field-line coordinates
 * (src/pushers/gc_gauss_dipole.c): what its physics tests elsewhere do not
 * show.  (Its symplecticity, order, long-run energy and P_phi, periods and
 * failure battery run in test_gc_symplectic.c, test_gc_order.c,
 * test_gc_basic.c and the other guiding-centre tests, which reach it
 * through gc-gl2 / gc-gl4 in the dipole.)
 *
 *  - The fused start-of-step check: the adiabaticity of
 *    gcp_gc_adiabaticity_of (B and grad B of the dipole's closed form at the
 *    point) in closed form on the line, compared squared.  Over 4000 points
 *    (L = 1.5 .. 8, latitude to 70 deg, protons and electrons 10 keV .. 100
 *    MeV, all pitch angles) the verdict at amax = e (1 + 1e-9) must be "go"
 *    and at e (1 - 1e-9) "stop": the two forms agree to round-off (~1e-15 of
 *    e), so a margin of 1e-9 passes any correct form and fails a wrong
 *    factor or power anywhere in it (tried: with the curvature term's
 *    (1 + s^2)^2 written (1 + s^2) the test fails).
 *  - The numbers do not depend on how the evolve layer slices the push:
 *    the lanes keep their canonical state and predictor history between
 *    calls, and phi' is wrapped at every step, so a push sampled every step
 *    (one step per call), every 7 steps, or never (one call) gives the same
 *    bits, with lanes that precipitate and turn non-adiabatic at
 *    different steps in different tiles (tiles that ran past the block's
 *    step are restored and run again). */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include <criterion/criterion.h>

#include "gcpush/field.h"
#include "gcpush/field_kernels.h"
#include "gcpush/gc.h"
#include "gcpush/particles.h"
#include "gcpush/pusher.h"
#include "pushers/gc_priv.h"
#include "pushers/gc_gauss_priv.h"
#include "test_gc_util.h"

static uint64_t rs = 0x9E3779B97F4A7C15ull;
static double urand(void)
{
    rs = rs * 6364136223846793005ull + 1442695040888963407ull;
    return (double)(rs >> 11) * 0x1.0p-53;
}

Test(gc_dipole_line, start_check_is_the_adiabaticity)
{
    struct gcp_field *f = gcp_field_dipole_create(GC_B0, 0, 0.0, 0.0);
    struct gcp_point_B form;
    cr_assert(gcp_field_point_B(f, &form) && form.form == GCP_POINT_B_DIPOLE);
    const double kd = form.p[0];
    int tested = 0;
    for (int n = 0; n < 4000; n++) {
        const int el = n & 1;
        const double q = el ? -GCP_E_CHARGE : GCP_E_CHARGE, m = el ? GCP_M_ELECTRON : GCP_M_PROTON;
        const double L = (1.5 + 6.5 * urand()) * GC_RE, lat = (2.0 * urand() - 1.0) * 70.0 * GCP_PI / 180.0;
        const double T = 1e4 * GCP_E_CHARGE * pow(1e4, urand()), a = GCP_PI * urand();
        const double s = sin(lat), W = 1.0 - s * s, g = sqrt(1.0 + 3.0 * s * s);
        const double X[3] = {L * W * sqrt(W), 0.0, L * W * s};
        double B[3], G[3][3];
        gcp_point_BG_dipole(kd, X[0], X[1], X[2], B, G);
        const double Bm = sqrt(B[0] * B[0] + B[1] * B[1] + B[2] * B[2]);
        const double p = gc_p_of_T(T, m), ppar = p * cos(a), mu = p * sin(a) * p * sin(a) / (2.0 * m * Bm);
        const double e = gcp_gc_adiabaticity_of(B, G, ppar, mu, q, m);
        const double mc = m * GCP_C_LIGHT;
        const double Q = (kd > 0 ? 1.0 : -1.0) * ppar * g / mc;
        const double beta = 2.0 * mu * fabs(kd) / (mc * GCP_C_LIGHT * L * L * L);
        const int go = gcp_gl_dipole_stops(kd, q, m, L, s, Q, beta, e * (1.0 + 1e-9));
        const int stop = gcp_gl_dipole_stops(kd, q, m, L, s, Q, beta, e * (1.0 - 1e-9));
        cr_expect(!go && stop, "L %.2f lat %.1f deg T %.3g eV pitch %.1f: e = %.6e, go %d stop %d",
                  L / GC_RE, lat * 180 / GCP_PI, T / GCP_E_CHARGE, a * 180 / GCP_PI, e, go, stop);
        tested++;
    }
    /* no check asked, and off the chart */
    cr_expect(!gcp_gl_dipole_stops(kd, GCP_E_CHARGE, GCP_M_PROTON, 4 * GC_RE, 0.5, 1.0, 1e-3, 0.0));
    cr_expect(gcp_gl_dipole_stops(kd, GCP_E_CHARGE, GCP_M_PROTON, 4 * GC_RE, 1.0, 1.0, 1e-3, 0.0));
    cr_expect(gcp_gl_dipole_stops(kd, GCP_E_CHARGE, GCP_M_PROTON, 4 * GC_RE, NAN, 1.0, 1e-3, 0.0));
    cr_expect_eq(tested, 4000);
    gcp_field_free(f);
}

#define NL 150
#define NST 3000

struct rec {
    int calls;
};
static void count(const struct gcp_block *b, double t, void *ctx)
{
    (void)b, (void)t;
    ((struct rec *)ctx)->calls++;
}

/* NL protons or electrons: trapped (L = 2 .. 6.2), every 7th inside the
 * loss cone (precipitates at 100 km within the push), every 9th proton of
 * 50-200 MeV (non-adiabatic at amax = 0.1, at once or after some steps,
 * where its gyroradius over the field's scale grows along its bounce).
 * Measured: 42 of 150 protons stop (9 precipitate, 33 non-adiabatic), 11
 * of 150 electrons (precipitate). */
static void fill(struct gcp_block *b, const struct gcp_field *f, int el)
{
    rs = 0x243F6A8885A308D3ull + (uint64_t)el;
    b->q = el ? -GCP_E_CHARGE : GCP_E_CHARGE, b->m = el ? GCP_M_ELECTRON : GCP_M_PROTON;
    for (size_t i = 0; i < NL; i++) {
        const double L = 2.0 + 4.2 * urand(), lon = 2.0 * GCP_PI * urand();
        const int hot = !el && (i % 9 == 0);
        const double T = (hot ? 5e7 : 1e5) * GCP_E_CHARGE * pow(hot ? 4.0 : 100.0, urand());
        const double a = (i % 7 == 0 ? 3.0 + 5.0 * urand() : 20.0 + 70.0 * urand()) * GCP_PI / 180.0;
        const double lat = 0.3 * (urand() - 0.5);
        const double s = sin(lat), W = 1.0 - s * s, R = L * GC_RE * W * sqrt(W);
        b->x[i] = R * cos(lon), b->y[i] = R * sin(lon), b->z[i] = L * GC_RE * W * s;
        const double X[3] = {b->x[i], b->y[i], b->z[i]};
        const double p = gc_p_of_T(T, b->m);
        b->ppar[i] = p * cos(a) * (i % 2 ? 1.0 : -1.0);
        b->mu[i] = p * sin(a) * p * sin(a) / (2.0 * b->m * gc_Bmag(f, X));
        b->status[i] = 0, b->steps[i] = 0, b->t[i] = 0.0, b->index[i] = i;
    }
    b->n_active = NL;
}

Test(gc_dipole_line, slicing_leaves_the_numbers, .timeout = 120)
{
    struct gcp_field *f = gcp_field_dipole_create(GC_B0, 0, GC_RE + 100e3, 0.0);
    f->r_outer = 6.2 * GC_RE;
    const struct gcp_pusher_type *P[2] = {&gcp_pusher_gc_gl2, &gcp_pusher_gc_gl4};
    for (int pk = 0; pk < 2; pk++)
        for (int el = 0; el < 2; el++) {
            struct gcp_block b[3];
            const int64_t every[3] = {0, 1, 7};
            struct rec r[3] = {{0}, {0}, {0}};
            for (int v = 0; v < 3; v++) {
                cr_assert_eq(gcp_block_alloc(&b[v], NL), 0);
                fill(&b[v], f, el);
                /* dt ~ 1/30 of a 1 MeV proton's bounce at L = 4 (electrons: 1/30 of 3 ms) */
                const struct gcp_push_opts o = {0.0, el ? 1e-4 : 0.05, NST, 0.0, 0.1};
                const struct gcp_sampler smp = {every[v], count, &r[v]};
                P[pk]->advance(&b[v], f, P[pk], &o, every[v] ? &smp : NULL);
            }
            size_t stopped = 0;
            int kinds[16] = {0};
            for (size_t i = 0; i < NL; i++) {
                stopped += b[0].status[i] != GCP_ALIVE;
                if (b[0].status[i] >= 0 && b[0].status[i] < 16) kinds[b[0].status[i]]++;
                for (int v = 1; v < 3; v++) {
                    cr_expect_eq(b[v].index[i], b[0].index[i], "%s: lane order", P[pk]->name);
                    cr_expect_eq(b[v].status[i], b[0].status[i], "%s lane %zu: status", P[pk]->name, i);
                    cr_expect_eq(b[v].steps[i], b[0].steps[i], "%s lane %zu: steps", P[pk]->name, i);
                    cr_expect(b[v].t[i] == b[0].t[i], "%s lane %zu: t", P[pk]->name, i);
                    cr_expect(b[v].x[i] == b[0].x[i] && b[v].y[i] == b[0].y[i] &&
                                  b[v].z[i] == b[0].z[i] && b[v].ppar[i] == b[0].ppar[i],
                              "%s lane %zu (every %lld): state differs", P[pk]->name, i,
                              (long long)every[v]);
                }
            }
            cr_log_info("%s %s: %zu of %d stopped (precipitated %d, left %d, non-adiabatic %d), "
                        "samples %d / %d", P[pk]->name, el ? "e-" : "p+", stopped, NL,
                        kinds[GCP_PRECIPITATED], kinds[GCP_LEFT_DOMAIN], kinds[GCP_NONADIABATIC],
                        r[1].calls, r[2].calls);
            /* the scene does what it is for: lanes stop, at different steps */
            cr_expect(stopped >= 10 && stopped < NL, "%s: %zu stopped", P[pk]->name, stopped);
            cr_expect(kinds[GCP_PRECIPITATED] > 0, "%s: none precipitated", P[pk]->name);
            if (!el) cr_expect(kinds[GCP_NONADIABATIC] > 0, "%s: none non-adiabatic", P[pk]->name);
            cr_expect_eq(r[1].calls, NST);
            for (int v = 0; v < 3; v++) gcp_block_free(&b[v]);
        }
    gcp_field_free(f);
}
