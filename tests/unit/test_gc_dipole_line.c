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
#include "test_gc_slicing.h"

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

/* test_gc_slicing.h's scene.  Measured: 42 of 150 protons stop (9
 * precipitate, 33 non-adiabatic), 11 of 150 electrons (precipitate). */
Test(gc_dipole_line, slicing_leaves_the_numbers, .timeout = 120)
{
    gc_sl_check(&gcp_pusher_gc_gl2, 3000, 0);
    gc_sl_check(&gcp_pusher_gc_gl4, 3000, 0);
}

/* The same in one tile (64 lanes, an engine's chunk), where the pusher
 * leaves its lane storage behind the tile while no lane stops and writes
 * it back only before the start check or a retirement (gc_gauss_dipole.c
 * dgl_steps): lanes stop both ways (precipitated after a step,
 * non-adiabatic at a step's start), sampled every step and every 7. */
Test(gc_dipole_line, slicing_leaves_the_numbers_in_one_tile, .timeout = 120)
{
    gc_sl_check_n(&gcp_pusher_gc_gl2, 3000, 0, 64);
    gc_sl_check_n(&gcp_pusher_gc_gl4, 3000, 0, 64);
}
