/* Claim 6: each kernel's batch form (kernels.h NAME_batch, and the pusher
 * registry's kick, compiled in its own translation unit) gives results
 * bit-identical (memcmp) to the scalar kernel called per particle, over
 * random inputs that include E = 0, B = 0, tiny and huge omega dt, and
 * gamma from 1 + 5e-7 to 1e4.
 *
 * Why bit-identical and not "close": the batch forms are the scalar kernel
 * in a loop, so any difference is a compiler transformation that changes
 * arithmetic (FMA contraction, reassociation, a vectorised sqrt/sin/cos
 * that rounds differently).  The build's ISO -std=c11 keeps
 * -ffp-contract=off, and the test is compiled with the project's -O3
 * -march=native, i.e. exactly where the vectoriser is most aggressive.
 * There is no tolerance to derive: the claim is equality of bits.
 */
#include <criterion/criterion.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "gcpush/pusher.h"

typedef void (*scalar_fn)(double *, double *, double *, double, double, double, double, double,
                          double, double, double, double);
typedef void (*batch_fn)(size_t, double *, double *, double *, const double *, const double *,
                         const double *, const double *, const double *, const double *, double,
                         double, double);

static const struct {
    const char *name; /* registry name */
    scalar_fn scalar;
    batch_fn batch;
} kernels[] = {
    {"boris", gcp_push_boris, gcp_push_boris_batch},
    {"boris-zu", gcp_push_boris_zu, gcp_push_boris_zu_batch},
    {"boris-nr", gcp_push_boris_nr, gcp_push_boris_nr_batch},
    {"vay", gcp_push_vay, gcp_push_vay_batch},
    {"higuera-cary", gcp_push_higuera_cary, gcp_push_higuera_cary_batch},
};
#define NK (sizeof kernels / sizeof kernels[0])

/* splitmix64: a fixed, portable stream (the test is reproducible). */
static uint64_t rng_state;
static uint64_t rng_next(void)
{
    uint64_t z = (rng_state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}
static double rng_uniform(void) { return (double)(rng_next() >> 11) * 0x1.0p-53; } /* [0,1) */
static double rng_sym(void) { return 2.0 * rng_uniform() - 1.0; }                   /* [-1,1) */
static double rng_log(double lo, double hi) { return lo * pow(hi / lo, rng_uniform()); }

#define NP 4099 /* not a multiple of any vector width: exercises loop tails */

struct inputs {
    double ux[NP], uy[NP], uz[NP], Ex[NP], Ey[NP], Ez[NP], Bx[NP], By[NP], Bz[NP];
};

/* Random particles and fields for species (q, m) and step dt: |u| log-
 * uniform over [1e-3 c, 1e4 c] (gamma - 1 from 5e-7 to 1e4), |B| such that
 * omega_c dt = |q| B dt / m is log-uniform over [1e-4, 1e3]; every 8th
 * particle has E = 0, every 8th (offset 3) B = 0, every 8th (offset 5)
 * both; |E| up to 2 c |B| (so E > cB too), or a plain scale when B = 0. */
static void fill(struct inputs *in, double q, double m, double dt)
{
    for (size_t i = 0; i < NP; i++) {
        const double umag = rng_log(1e-3, 1e4) * GCP_C_LIGHT;
        double d[3] = {rng_sym(), rng_sym(), rng_sym()};
        double n = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) + 1e-300;
        in->ux[i] = umag * d[0] / n, in->uy[i] = umag * d[1] / n, in->uz[i] = umag * d[2] / n;
        const double Bmag = rng_log(1e-4, 1e3) * m / (fabs(q) * dt);
        d[0] = rng_sym(), d[1] = rng_sym(), d[2] = rng_sym();
        n = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) + 1e-300;
        in->Bx[i] = Bmag * d[0] / n, in->By[i] = Bmag * d[1] / n, in->Bz[i] = Bmag * d[2] / n;
        const double Emag = 2.0 * GCP_C_LIGHT * Bmag * rng_uniform();
        d[0] = rng_sym(), d[1] = rng_sym(), d[2] = rng_sym();
        n = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) + 1e-300;
        in->Ex[i] = Emag * d[0] / n, in->Ey[i] = Emag * d[1] / n, in->Ez[i] = Emag * d[2] / n;
        const int sel = (int)(i % 8);
        if (sel == 0 || sel == 5) in->Ex[i] = in->Ey[i] = in->Ez[i] = 0.0;
        if (sel == 3 || sel == 5) {
            in->Bx[i] = in->By[i] = in->Bz[i] = 0.0;
            if (sel == 3) { /* E with no B: a scale of its own */
                const double E0 = rng_log(1e-6, 1e2) * m * GCP_C_LIGHT / (fabs(q) * dt);
                in->Ex[i] = E0 * rng_sym(), in->Ey[i] = E0 * rng_sym(), in->Ez[i] = E0 * rng_sym();
            }
        }
    }
}

static const struct {
    double q, m;
} species[] = {{-GCP_E_CHARGE, GCP_M_ELECTRON}, {GCP_E_CHARGE, GCP_M_PROTON}, {1.0, 1.0}};

/* Scalar reference: the kernel per particle on copies of u. */
static void scalar_ref(scalar_fn f, const struct inputs *in, double q, double m, double dt,
                       double *ux, double *uy, double *uz)
{
    memcpy(ux, in->ux, sizeof in->ux);
    memcpy(uy, in->uy, sizeof in->uy);
    memcpy(uz, in->uz, sizeof in->uz);
    for (size_t i = 0; i < NP; i++)
        f(&ux[i], &uy[i], &uz[i], in->Ex[i], in->Ey[i], in->Ez[i], in->Bx[i], in->By[i],
          in->Bz[i], q, m, dt);
}

static size_t first_diff(const double *a, const double *b, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (memcmp(&a[i], &b[i], sizeof(double)) != 0) return i;
    return n;
}

static void check_equal(const char *what, const char *name, const double *a, const double *b,
                        const double *c, const double *ra, const double *rb, const double *rc)
{
    const int ok = memcmp(a, ra, NP * sizeof(double)) == 0 &&
                   memcmp(b, rb, NP * sizeof(double)) == 0 &&
                   memcmp(c, rc, NP * sizeof(double)) == 0;
    if (!ok) {
        size_t i = first_diff(a, ra, NP);
        if (i == NP) i = first_diff(b, rb, NP);
        if (i == NP) i = first_diff(c, rc, NP);
        cr_assert_fail("%s %s differs from the scalar kernel at particle %zu: "
                       "(%.17g %.17g %.17g) vs (%.17g %.17g %.17g)",
                       what, name, i, a[i], b[i], c[i], ra[i], rb[i], rc[i]);
    }
}

/* Each kernel, three species, three step sizes, several rounds of random
 * inputs: NAME_batch vs NAME per particle, memcmp. Also the results are
 * finite (the inputs are, and no kernel divides by zero at B = 0 or E = 0),
 * so the comparison is between numbers, not NaN payloads. */
Test(kernels_batch, header_batch_bit_identical_to_scalar)
{
    static struct inputs in;
    static double ux[NP], uy[NP], uz[NP], rx[NP], ry[NP], rz[NP];
    rng_state = 0x5EEDull;
    int calls = 0;
    for (size_t k = 0; k < NK; k++)
        for (size_t s = 0; s < sizeof species / sizeof species[0]; s++)
            for (int r = 0; r < 3; r++) {
                const double dt = rng_log(1e-12, 1.0);
                fill(&in, species[s].q, species[s].m, dt);
                scalar_ref(kernels[k].scalar, &in, species[s].q, species[s].m, dt, rx, ry, rz);
                memcpy(ux, in.ux, sizeof ux), memcpy(uy, in.uy, sizeof uy),
                    memcpy(uz, in.uz, sizeof uz);
                kernels[k].batch(NP, ux, uy, uz, in.Ex, in.Ey, in.Ez, in.Bx, in.By, in.Bz,
                                 species[s].q, species[s].m, dt);
                for (size_t i = 0; i < NP; i++)
                    cr_assert(isfinite(rx[i]) && isfinite(ry[i]) && isfinite(rz[i]),
                              "%s: non-finite result at %zu", kernels[k].name, i);
                check_equal("batch", kernels[k].name, ux, uy, uz, rx, ry, rz);
                calls++;
            }
    cr_assert_eq(calls, (int)(NK * 3 * 3));
}

/* The pusher registry's kick (compiled in src/pushers/, another
 * translation unit with its own inlining and vectorisation decisions) is
 * the same batch function: bit-identical to the scalar kernel inlined
 * here.  Every registered full-orbit pusher must be one of the table's. */
Test(kernels_batch, registry_kick_bit_identical_to_scalar)
{
    static struct inputs in;
    static double ux[NP], uy[NP], uz[NP], rx[NP], ry[NP], rz[NP];
    rng_state = 0xB0215ull;
    int found = 0;
    for (const struct gcp_pusher_type *const *pp = gcp_pusher_types(); *pp; pp++) {
        const struct gcp_pusher_type *p = *pp;
        if (p->kind != GCP_FULL_ORBIT) continue;
        size_t k = 0;
        while (k < NK && strcmp(kernels[k].name, p->name) != 0) k++;
        cr_assert_lt(k, NK, "full-orbit pusher %s has no scalar kernel in this test", p->name);
        cr_assert_not_null(p->kick, "%s: no kick", p->name);
        for (size_t s = 0; s < sizeof species / sizeof species[0]; s++) {
            const double dt = rng_log(1e-12, 1.0);
            fill(&in, species[s].q, species[s].m, dt);
            scalar_ref(kernels[k].scalar, &in, species[s].q, species[s].m, dt, rx, ry, rz);
            memcpy(ux, in.ux, sizeof ux), memcpy(uy, in.uy, sizeof uy), memcpy(uz, in.uz, sizeof uz);
            p->kick(NP, ux, uy, uz, in.Ex, in.Ey, in.Ez, in.Bx, in.By, in.Bz, species[s].q,
                    species[s].m, dt);
            check_equal("registry kick", p->name, ux, uy, uz, rx, ry, rz);
        }
        found++;
    }
    cr_assert_geq(found, 4, "only %d full-orbit pushers registered", found);
}

/* Edge cases by construction, not by chance: E = 0 and B = 0 together
 * (u unchanged, exactly, for every kernel), and omega dt = pi exactly
 * for boris-zu (cos = -1) -- still bit-identical batch vs scalar. */
Test(kernels_batch, edge_cases)
{
    double ux[5] = {1e3, -2e7, 3e8, 0.0, 5e12}, uy[5] = {2e3, 0.0, -1e8, 0.0, -1e11},
           uz[5] = {-7e2, 1e7, 0.0, 0.0, 3e10};
    const double z[5] = {0};
    for (size_t k = 0; k < NK; k++) {
        double a[5], b[5], c[5];
        memcpy(a, ux, sizeof a), memcpy(b, uy, sizeof b), memcpy(c, uz, sizeof c);
        kernels[k].batch(5, a, b, c, z, z, z, z, z, z, GCP_E_CHARGE, GCP_M_PROTON, 1e-6);
        cr_assert(memcmp(a, ux, sizeof a) == 0 && memcmp(b, uy, sizeof b) == 0 &&
                      memcmp(c, uz, sizeof c) == 0,
                  "%s: E = B = 0 changed u", kernels[k].name);
    }
    /* omega dt = pi for a slow proton in boris-zu (gamma = 1 + 5.6e-14) */
    const double q = GCP_E_CHARGE, m = GCP_M_PROTON, B = 1.0;
    const double dt = GCP_PI * m / (q * B);
    double a[1] = {1.0}, b[1] = {2.0}, c[1] = {3.0}, Bz[1] = {B}, zero[1] = {0.0};
    double sa = 1.0, sb = 2.0, sc = 3.0;
    gcp_push_boris_zu_batch(1, a, b, c, zero, zero, zero, zero, zero, Bz, q, m, dt);
    gcp_push_boris_zu(&sa, &sb, &sc, 0.0, 0.0, 0.0, 0.0, 0.0, B, q, m, dt);
    cr_assert(memcmp(&a[0], &sa, 8) == 0 && memcmp(&b[0], &sb, 8) == 0 &&
              memcmp(&c[0], &sc, 8) == 0);
    /* and the half turn itself: u_perp reversed to ~1e-15 relative */
    cr_assert(fabs(sa + 1.0) < 1e-13 && fabs(sb + 2.0) < 1e-13 && sc == 3.0,
              "boris-zu half turn: (%.17g %.17g %.17g)", sa, sb, sc);
}

/* The pure-magnetic Boris kick (used by the stepper when a scene has no E)
 * is gcp_push_boris with the E half-kicks left out: the same floating-point
 * operations on the same values, so every component is equal (==, which
 * also equates -0 and +0: adding the zero E can turn -0 into +0) for any
 * input, including huge omega dt and B = 0. */
Test(kernels_batch, boris_B_equals_boris_with_zero_E)
{
    const double q = 1.602176634e-19, m = 1.67262192369e-27;
    double ux[64], uy[64], uz[64], bx[64], by[64], bz[64];
    double vx[64], vy[64], vz[64];
    unsigned long long st = 12345;
    for (int i = 0; i < 64; i++) {
        double r[6];
        for (int k = 0; k < 6; k++) {
            st = st * 6364136223846793005ULL + 1442695040888963407ULL;
            r[k] = (double)(st >> 11) * 0x1.0p-53 - 0.5;
        }
        ux[i] = vx[i] = 3e8 * r[0], uy[i] = vy[i] = 3e8 * r[1], uz[i] = vz[i] = 3e8 * r[2];
        bx[i] = (i % 9 == 0) ? 0.0 : pow(10.0, 4.0 * r[3]) * r[4];
        by[i] = (i % 9 == 0) ? 0.0 : r[5];
        bz[i] = (i % 9 == 0) ? 0.0 : 1.0 + r[3];
    }
    const double zero[64] = {0};
    double wx[64], wy[64], wz[64], nx[64], ny[64], nz[64];
    memcpy(wx, ux, sizeof wx), memcpy(wy, uy, sizeof wy), memcpy(wz, uz, sizeof wz);
    memcpy(nx, ux, sizeof nx), memcpy(ny, uy, sizeof ny), memcpy(nz, uz, sizeof nz);
    for (int step = 0; step < 5; step++) {
        gcp_push_boris_B_batch(64, ux, uy, uz, bx, by, bz, q, m, 1e-6);
        gcp_push_boris_batch(64, vx, vy, vz, zero, zero, zero, bx, by, bz, q, m, 1e-6);
        /* and the non-relativistic pair (boris-nr's kick_B and kick) */
        gcp_push_boris_nr_B_batch(64, wx, wy, wz, bx, by, bz, q, m, 1e-6);
        gcp_push_boris_nr_batch(64, nx, ny, nz, zero, zero, zero, bx, by, bz, q, m, 1e-6);
    }
    for (int i = 0; i < 64; i++) {
        cr_assert(ux[i] == vx[i] && uy[i] == vy[i] && uz[i] == vz[i], "lane %d differs", i);
        cr_assert(wx[i] == nx[i] && wy[i] == ny[i] && wz[i] == nz[i], "nr: lane %d differs", i);
    }
}
