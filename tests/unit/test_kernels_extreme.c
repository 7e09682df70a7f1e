/* Extreme steps in a pure magnetic field (issue 13): every Boris-family
 * kernel, scalar and batch form, keeps |u| over 1e4 steps for gamma from
 * 1 to 1e9 and omega_c dt from 1e-3 to 1e6, with no non-finite value.
 *
 * Why |u| must be kept: in pure B the exact motion keeps |u|, and each of
 * the four schemes keeps it in exact arithmetic too (Boris, boris-zu and
 * Higuera-Cary rotate u; Vay solves its quartic for the gamma of the old
 * u, Vay 2008 eq. 11).  What is left is round-off.
 *
 * Tolerance, derived: N * 2 eps = 4.4e-12 relative after N = 1e4 steps.
 * A step multiplies |u| by (1 + d), d the rounding of its ~10 operations
 * (each <= eps/2 = 1.1e-16).  In a fixed field at a fixed step every step
 * applies the same rounded rotation coefficients (s, t, or cos and sin,
 * whose c^2 + s^2 - 1 is a fixed ~eps), so d does not average out: |u|
 * drifts linearly, N |d|.  What an exact rotation achieves is therefore
 * ~N eps, not sqrt(N) eps: measured, the unchanged Boris kernel reaches
 * 2.4e-12 (protons, |u| = 1e-3 c, omega_c dt = 1e6) and boris-zu 3.4e-12
 * (|u| = 1e6 c, omega_c dt = 10, pitch 30 deg), i.e. 1.1 and 1.5 eps per
 * step; the bound allows 2 eps per step.  (The issue asked for 1e-12; the
 * ideal rotation in double precision does not keep that over 1e4 steps.)
 * What fails it, and did before issue 13: the gamma root written as
 * (sigma + sqrt(sigma^2 + 4 (tau^2 + u*^2))) / 2 with sigma << 0 (gamma
 * -> 0 at u* = 0, t = tau / 0: higuera-cary non-finite at omega_c dt >= 1e3
 * for gamma >= 1e3), sigma = 1 + |u'|^2 - tau^2 formed from Vay's half-
 * rotated u' (|u'| ~ tau: eps (omega_c dt)^2 per step, vay 5e-3 at
 * omega_c dt = 1e6), and Higuera-Cary's u_bar x t with u_bar nearly
 * parallel to t (eps omega_c dt per step: 2e-9 at pitch 30 deg).
 *
 * The grid: |u|/c in {1e-3, 1, 1e3, 1e6, 1e9} (gamma 1 + 5e-7 .. 1e9),
 * omega_c dt = |q| B dt / (gamma m) in {1e-3, 1e-1, 1, 10, 1e3, 1e6}, two
 * pitch angles (90 deg: u* = u.tau/c = 0, the 0/0 trap of the root, and
 * 30 deg), B along an oblique axis (so dot products round), protons and
 * electrons.  The batch form pushes all cases of one species as one
 * batch of particles, each with its own B. */
#include <criterion/criterion.h>
#include <criterion/parameterized.h>
#include <float.h>
#include <stdio.h>
#include <string.h>

#include "gcpush/kernels.h"
#include "gcpush/particles.h"

typedef void (*scalar_fn)(double *, double *, double *, double, double, double, double, double,
                          double, double, double, double);
typedef void (*batch_fn)(size_t, double *, double *, double *, const double *, const double *,
                         const double *, const double *, const double *, const double *, double,
                         double, double);

static const struct {
    const char *name;
    scalar_fn scalar;
    batch_fn batch;
} KERNELS[] = {
    {"boris", gcp_push_boris, gcp_push_boris_batch},
    {"boris-zu", gcp_push_boris_zu, gcp_push_boris_zu_batch},
    {"vay", gcp_push_vay, gcp_push_vay_batch},
    {"higuera-cary", gcp_push_higuera_cary, gcp_push_higuera_cary_batch},
};

/* Parameters are copied into the test's worker process: plain data only
 * (an index and a flag, no pointers). */
struct kcase {
    int kernel; /* index into KERNELS */
    int batch;  /* 0: scalar form, 1: NAME_batch */
};

static const double U_OVER_C[] = {1e-3, 1.0, 1e3, 1e6, 1e9};
static const double OMEGA_DT[] = {1e-3, 1e-1, 1.0, 10.0, 1e3, 1e6};
static const double PITCH_DEG[] = {90.0, 30.0};
#define NU (sizeof U_OVER_C / sizeof U_OVER_C[0])
#define NW (sizeof OMEGA_DT / sizeof OMEGA_DT[0])
#define NPI (sizeof PITCH_DEG / sizeof PITCH_DEG[0])
#define NC (NU * NW * NPI)
#define NSTEPS 10000
#define TOL (NSTEPS * 2.0 * DBL_EPSILON) /* 4.4e-12: see the top */

ParameterizedTestParameters(kernels_extreme, u_kept)
{
    static struct kcase cases[] = {{0, 0}, {0, 1}, {1, 0}, {1, 1}, {2, 0}, {2, 1}, {3, 0}, {3, 1}};
    return cr_make_param_array(struct kcase, cases, sizeof cases / sizeof cases[0]);
}

/* Initial u and the field of case c for species (q, m) and step dt. */
static void setup(size_t c, double q, double m, double dt, double u[3], double B[3])
{
    const size_t iu = c / (NW * NPI), iw = (c / NPI) % NW, ip = c % NPI;
    const double umag = U_OVER_C[iu] * GCP_C_LIGHT;
    const double gamma = sqrt(1.0 + U_OVER_C[iu] * U_OVER_C[iu]);
    const double Bmag = OMEGA_DT[iw] * gamma * m / (fabs(q) * dt);
    /* b = (1, 2, 3)/sqrt(14); e1, e2 complete an orthonormal frame */
    const double s14 = sqrt(14.0), s5 = sqrt(5.0), s70 = sqrt(70.0);
    const double b[3] = {1.0 / s14, 2.0 / s14, 3.0 / s14};
    const double e1[3] = {2.0 / s5, -1.0 / s5, 0.0};
    const double e2[3] = {3.0 / s70, 6.0 / s70, -5.0 / s70}; /* b x e1 */
    const double a = PITCH_DEG[ip] * GCP_PI / 180.0;
    for (int k = 0; k < 3; k++) {
        B[k] = Bmag * b[k];
        u[k] = umag * (cos(a) * b[k] + sin(a) * (0.6 * e1[k] + 0.8 * e2[k]));
    }
}

static double norm3(double x, double y, double z) { return sqrt(x * x + y * y + z * z); }

ParameterizedTest(struct kcase *kc, kernels_extreme, u_kept)
{
    const scalar_fn scalar = KERNELS[kc->kernel].scalar;
    const batch_fn batch = kc->batch ? KERNELS[kc->kernel].batch : NULL;
    static const struct {
        double q, m;
    } sp[] = {{GCP_E_CHARGE, GCP_M_PROTON}, {-GCP_E_CHARGE, GCP_M_ELECTRON}};
    const double dt = 1e-3;
    int bad = 0;
    double worst_all = 0.0;
    char first[256] = "";
    for (size_t s = 0; s < 2; s++) {
        double ux[NC], uy[NC], uz[NC], Bx[NC], By[NC], Bz[NC], u0[NC], worst[NC];
        const double zero[NC] = {0};
        for (size_t c = 0; c < NC; c++) {
            double u[3], B[3];
            setup(c, sp[s].q, sp[s].m, dt, u, B);
            ux[c] = u[0], uy[c] = u[1], uz[c] = u[2];
            Bx[c] = B[0], By[c] = B[1], Bz[c] = B[2];
            u0[c] = norm3(u[0], u[1], u[2]);
            worst[c] = 0.0;
        }
        for (int n = 0; n < NSTEPS; n++) {
            if (batch)
                batch(NC, ux, uy, uz, zero, zero, zero, Bx, By, Bz, sp[s].q, sp[s].m, dt);
            else
                for (size_t c = 0; c < NC; c++)
                    scalar(&ux[c], &uy[c], &uz[c], 0.0, 0.0, 0.0, Bx[c], By[c], Bz[c],
                              sp[s].q, sp[s].m, dt);
            for (size_t c = 0; c < NC; c++) {
                const double e = fabs(norm3(ux[c], uy[c], uz[c]) / u0[c] - 1.0);
                /* NaN compares false: count it as the worst error */
                if (!(e <= worst[c])) worst[c] = isfinite(e) ? e : INFINITY;
            }
        }
        for (size_t c = 0; c < NC; c++) {
            if (worst[c] <= TOL) continue;
            const size_t iu = c / (NW * NPI), iw = (c / NPI) % NW, ip = c % NPI;
            bad++;
            if (!(worst[c] <= worst_all)) {
                worst_all = worst[c];
                snprintf(first, sizeof first,
                         "%s (%s): %s |u|/c = %g, omega_c dt = %g, pitch %g deg: "
                         "max | |u|/|u0| - 1 | = %.3g over %d steps (tolerance %g)",
                         KERNELS[kc->kernel].name, kc->batch ? "batch" : "scalar", s ? "electron" : "proton", U_OVER_C[iu], OMEGA_DT[iw],
                         PITCH_DEG[ip], worst[c], NSTEPS, TOL);
            }
        }
    }
    cr_assert_eq(bad, 0, "%d of %zu cases fail; worst: %s", bad, 2 * NC, first);
}
