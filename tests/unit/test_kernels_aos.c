/* The array-of-structs adapters of kernels.h (NAME_aos, NAME_strided,
 * gcp_drift_aos) give bit-identical results to the scalar kernels (and to
 * gcp_drift_batch): each is the scalar kernel called per particle, and the
 * build keeps -ffp-contract=off (ISO -std=c11), so vectorising the loop
 * must not change a bit.  The comparison is memcmp of the doubles, not a
 * tolerance.
 *
 * Particles: N = 1037 (not a multiple of any vector width, so the loops'
 * remainders are exercised) with u from 1e-3 c to gamma ~ 1e3, E up to
 * 1e9 V/m, B up to 10 T with a zero-B lane every 17th (boris-zu's b = 0
 * path), electrons and protons, omega_c dt from ~1e-4 to ~1e3. */
#include <criterion/criterion.h>
#include <stdint.h>
#include <string.h>

#include "gcpush/kernels.h"

#define N 1037
#define NSTEP 5
#define STRIDE 7 /* struct { double x[3], u[3], w; } */

struct particle7 {
    double x[3], u[3], w;
};

static uint64_t rng_state = 0x9E3779B97F4A7C15ull;
static double urand(void) /* splitmix64 -> [0, 1) */
{
    uint64_t z = (rng_state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return (double)(z >> 11) * (1.0 / 9007199254740992.0);
}
static double srand_(double scale) { return scale * (2.0 * urand() - 1.0); }

static double x0[3][N], u0[3][N], E[3][N], B[3][N];

static void fill(void)
{
    rng_state = 0x9E3779B97F4A7C15ull;
    for (size_t i = 0; i < N; i++) {
        const double umag = GCP_C_LIGHT * pow(10.0, -3.0 + 6.0 * urand());
        const double emag = pow(10.0, 9.0 * urand());
        const double bmag = (i % 17 == 0) ? 0.0 : pow(10.0, -4.0 + 5.0 * urand());
        for (int k = 0; k < 3; k++) {
            x0[k][i] = srand_(1e3);
            u0[k][i] = srand_(umag);
            E[k][i] = srand_(emag);
            B[k][i] = (i % 17 == 0) ? 0.0 : srand_(bmag);
        }
    }
}

typedef void (*scalar_fn)(double *, double *, double *, double, double, double, double, double,
                          double, double, double, double);
typedef void (*aos_fn)(size_t, struct gcp_particle_aos *, const double *, const double *,
                       const double *, const double *, const double *, const double *, double,
                       double, double);
typedef void (*strided_fn)(size_t, double *, size_t, const double *, const double *, size_t,
                           double, double, double);

static void check_kernel(const char *name, scalar_fn scalar, aos_fn aos, strided_fn strided)
{
    static double ref[3][N];
    static struct gcp_particle_aos pa[N];
    static struct particle7 p7[N];
    static double eb[N][6]; /* per-particle gathered fields, Ex Ey Ez Bx By Bz */
    cr_assert_eq(sizeof(struct particle7), STRIDE * sizeof(double));
    cr_assert_eq(sizeof(struct gcp_particle_aos), 6 * sizeof(double));
    fill();
    for (size_t i = 0; i < N; i++) {
        for (int k = 0; k < 3; k++) {
            ref[k][i] = u0[k][i];
            p7[i].x[k] = x0[k][i];
            p7[i].u[k] = u0[k][i];
            eb[i][k] = E[k][i];
            eb[i][3 + k] = B[k][i];
        }
        p7[i].w = 1.0;
        pa[i] = (struct gcp_particle_aos){x0[0][i], x0[1][i], x0[2][i],
                                          u0[0][i], u0[1][i], u0[2][i]};
    }
    for (int s = 0; s < NSTEP; s++) {
        /* electrons on even steps, protons on odd ones; dt fixed */
        const double q = (s & 1) ? 1.602176634e-19 : -1.602176634e-19;
        const double m = (s & 1) ? 1.67262192369e-27 : 9.1093837015e-31;
        const double dt = 1e-10;
        for (size_t i = 0; i < N; i++)
            scalar(&ref[0][i], &ref[1][i], &ref[2][i], E[0][i], E[1][i], E[2][i], B[0][i],
                   B[1][i], B[2][i], q, m, dt);
        aos(N, pa, E[0], E[1], E[2], B[0], B[1], B[2], q, m, dt);
        strided(N, p7[0].u, STRIDE, &eb[0][0], &eb[0][3], 6, q, m, dt);
    }
    size_t bad_aos = 0, bad_str = 0, nonfinite = 0;
    for (size_t i = 0; i < N; i++) {
        const double a[3] = {pa[i].ux, pa[i].uy, pa[i].uz};
        for (int k = 0; k < 3; k++) {
            bad_aos += memcmp(&a[k], &ref[k][i], sizeof(double)) != 0;
            bad_str += memcmp(&p7[i].u[k], &ref[k][i], sizeof(double)) != 0;
            nonfinite += !isfinite(ref[k][i]);
        }
        /* positions and the extra member untouched */
        cr_assert(pa[i].x == x0[0][i] && pa[i].y == x0[1][i] && pa[i].z == x0[2][i]);
        cr_assert(p7[i].x[0] == x0[0][i] && p7[i].w == 1.0);
    }
    cr_assert_eq(nonfinite, 0, "%s: non-finite reference", name);
    cr_assert_eq(bad_aos, 0, "%s_aos: %zu of %d components differ from the scalar kernel", name,
                 bad_aos, 3 * N);
    cr_assert_eq(bad_str, 0, "%s_strided: %zu of %d components differ from the scalar kernel",
                 name, bad_str, 3 * N);
}

#define KERNEL_TEST_(NAME)                                                              \
    Test(kernels_aos, NAME) { check_kernel(#NAME, NAME, NAME##_aos, NAME##_strided); }

KERNEL_TEST_(gcp_push_boris)
KERNEL_TEST_(gcp_push_boris_zu)
KERNEL_TEST_(gcp_push_boris_nr)
KERNEL_TEST_(gcp_push_vay)
KERNEL_TEST_(gcp_push_higuera_cary)

/* gcp_drift_aos against gcp_drift_batch, with h = dt and dt/2. */
Test(kernels_aos, drift)
{
    static struct gcp_particle_aos pa[N];
    static double x[3][N];
    fill();
    for (size_t i = 0; i < N; i++) {
        pa[i] = (struct gcp_particle_aos){x0[0][i], x0[1][i], x0[2][i],
                                          u0[0][i], u0[1][i], u0[2][i]};
        for (int k = 0; k < 3; k++) x[k][i] = x0[k][i];
    }
    const double hs[2] = {1e-9, 0.5e-9};
    for (int s = 0; s < 2; s++) {
        gcp_drift_batch(N, x[0], x[1], x[2], u0[0], u0[1], u0[2], hs[s]);
        gcp_drift_aos(N, pa, hs[s]);
    }
    size_t bad = 0;
    for (size_t i = 0; i < N; i++) {
        const double a[3] = {pa[i].x, pa[i].y, pa[i].z};
        for (int k = 0; k < 3; k++) bad += memcmp(&a[k], &x[k][i], sizeof(double)) != 0;
        cr_assert(x[0][i] != x0[0][i] || u0[0][i] == 0.0, "drift moved nothing");
    }
    cr_assert_eq(bad, 0, "gcp_drift_aos: %zu of %d components differ from gcp_drift_batch", bad,
                 3 * N);
}
