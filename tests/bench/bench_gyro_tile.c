/* bench_gyro_tile -- issue 12: the invariant observer's gyro tile against
 * the plain tile, alone.
 *
 * tests/bench/observer.sh times whole runs, where the observer's cost is
 * the gyro tile (the per-step sums and the gyrations' closes,
 * fo_fused_priv.h / fo_gyro_priv.h) plus the observer's pass over the
 * records (src/diag/invariants_fo.c) and its streams; this times the two
 * relativistic Boris dipole tiles of gcp_pusher_boris.fused on the same
 * lanes, with nothing around them: observer.sh's scene (protons of 1 MeV
 * at the equator, L = 3.5 .. 4.5, pitch 30 .. 90 deg, random gyrophase;
 * dt = 0.05 of the shortest gyro period at the start, as the scene's
 * "0.05 gyro"; r_inner = R_E + 100 km), calls of 128 steps (the fused
 * step's GCP_FO_GYRO_STEPS, fo_step.c) over tiles of GCP_FO_TILE lanes,
 * every gyration begun at step 0 as fo_step.c's fo_gyro_begin begins it.
 *
 * Prints the thread CPU per lane-step of each (median of REPS runs, the
 * two alternating), their ratio, the records per lane-step, and an FNV
 * hash of the gyro tile's final x, u, sums and every record: the same hash
 * before and after a change of the gyro tile is the bit-identity check of
 * its output.
 *   make && make -s -C tests/bench BUILD=../../build ../../build/bench/bench_gyro_tile
 *   taskset -c 0 build/bench/bench_gyro_tile [calls [reps]]
 * (defaults 20 calls, 7 reps; 2048 lanes). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "gcpush/pusher.h"
#include "gcpush/units.h"
#include "fo_fused_priv.h"

#define LANES 2048
#define KCALL 128
#define MAXREPS 64

static double cpu_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static uint64_t rng_state = 88172645463325252ull;
static double urand(void)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return (double)(rng_state >> 11) * (1.0 / 9007199254740992.0);
}

static uint64_t fnv(uint64_t h, const void *p, size_t n)
{
    const unsigned char *c = p;
    for (size_t i = 0; i < n; i++) h = (h ^ c[i]) * 1099511628211ull;
    return h;
}

static double *darr(void)
{
    double *p = calloc(LANES, sizeof(double));
    if (!p) abort();
    return p;
}

static int cmp_d(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv)
{
    const int ncall = argc > 1 ? atoi(argv[1]) : 20;
    int reps = argc > 2 ? atoi(argv[2]) : 7;
    if (ncall < 1 || reps < 1) return 2;
    if (reps > MAXREPS) reps = MAXREPS;
    const struct gcp_fo_fused *fz = gcp_pusher_boris.fused;
    if (!fz || !fz->gyro[GCP_POINT_B_DIPOLE] || !fz->tile[GCP_POINT_B_DIPOLE][0]) return 1;
    const double RE = GCP_EARTH_RADIUS, c = GCP_EARTH_B0 * RE * RE * RE;
    const double q = GCP_E_CHARGE, m = GCP_M_PROTON, cl = GCP_C_LIGHT;
    const double gam = 1.0 + 1e6 * q / (m * cl * cl), u = cl * sqrt(gam * gam - 1.0);
    static double X0[6][LANES];
    double Tmin = INFINITY;
    for (int i = 0; i < LANES; i++) {
        const double L = 3.5 + urand(), ph = 2 * GCP_PI * urand();
        const double pa = (30.0 + 60.0 * urand()) * GCP_PI / 180.0, g = 2 * GCP_PI * urand();
        const double ex = cos(ph), ey = sin(ph); /* radial; b is along z at the equator */
        X0[0][i] = L * RE * ex, X0[1][i] = L * RE * ey, X0[2][i] = 0.0;
        X0[3][i] = u * sin(pa) * (cos(g) * ex - sin(g) * ey);
        X0[4][i] = u * sin(pa) * (cos(g) * ey + sin(g) * ex);
        X0[5][i] = u * cos(pa);
        const double B = GCP_EARTH_B0 / (L * L * L), T = 2 * GCP_PI * gam * m / (q * B);
        Tmin = T < Tmin ? T : Tmin;
    }
    const double dt = 0.05 * Tmin, rin = RE + 100e3;
    struct gcp_fo_tile_args A = {.q = q, .m = m, .dt = dt, .h = 0.5 * dt, .rin2 = rin * rin,
                                 .rout2 = INFINITY, .zmax = INFINITY, .p = {c}};
    double *s[6], *hg = darr();
    for (int k = 0; k < 6; k++) s[k] = darr();
    struct gcp_fo_gyro g = {.nlanes = LANES, .tele = fz->gyro_tele, .cap = (int64_t)LANES * KCALL};
    g.init = (int64_t *)darr(), g.left = (int64_t *)darr(), g.kstart = (int64_t *)darr();
    g.w0 = darr(), g.jc = darr();
    for (int j = 0; j < 9; j++) g.sum[j] = darr();
    for (int j = 0; j < 3; j++) g.e2[j] = darr();
    g.rec = calloc((size_t)g.cap, sizeof *g.rec); /* zeroed: the hash reads its padding */
    if (!g.rec) abort();
    double tb[MAXREPS], tg[MAXREPS];
    uint64_t hash = 0;
    double nrec = 0;
    for (int rep = 0; rep < reps; rep++) {
        for (int gy = 0; gy < 2; gy++) {
            for (int k = 0; k < 6; k++) memcpy(s[k], X0[k], sizeof X0[k]);
            for (int i = 0; gy && i < LANES; i++) { /* fo_step.c fo_gyro_begin */
                double F[3];
                gcp_point_B_dipole(c, s[0][i], s[1][i], s[2][i], &F[0], &F[1], &F[2]);
                const double ui[3] = {s[3][i], s[4][i], s[5][i]};
                double e2[3];
                gcp_fo_gyro_mid_e2(q, 1.0, F, ui, e2);
                gcp_fo_gyro_mid_start(&g, (size_t)i, 0, 1.0, e2, ui);
            }
            uint64_t h = 1469598103934665603ull;
            double t = cpu_s(), nr = 0;
            for (int call = 0; call < ncall; call++) {
                const int hm = (call ? GCP_FO_HG_IN : 0) | GCP_FO_HG_OUT;
                int32_t stopped = 0;
                g.nrec = 0;
                for (size_t i0 = 0; i0 < LANES; i0 += GCP_FO_TILE) {
                    double *const a[6] = {s[0] + i0, s[1] + i0, s[2] + i0,
                                          s[3] + i0, s[4] + i0, s[5] + i0};
                    const int64_t k =
                        gy ? fz->gyro[GCP_POINT_B_DIPOLE](a[0], a[1], a[2], a[3], a[4], a[5],
                                                          hg + i0, hm, GCP_FO_TILE, KCALL, &A,
                                                          &stopped, &g, i0, 0.0,
                                                          (int64_t)call * KCALL)
                           : fz->tile[GCP_POINT_B_DIPOLE][0](a[0], a[1], a[2], a[3], a[4], a[5],
                                                             hg + i0, hm, GCP_FO_TILE, KCALL, &A,
                                                             &stopped);
                    if (k != KCALL || stopped) {
                        fprintf(stderr, "bench_gyro_tile: a lane stopped\n");
                        return 1;
                    }
                }
                if (gy) { /* the records' hash, its time left out */
                    const double t1 = cpu_s();
                    h = fnv(h, g.rec, (size_t)g.nrec * sizeof *g.rec);
                    nr += (double)g.nrec;
                    t += cpu_s() - t1;
                }
            }
            t = cpu_s() - t;
            if (!gy) {
                tb[rep] = t;
                continue;
            }
            tg[rep] = t;
            for (int k = 0; k < 6; k++) h = fnv(h, s[k], LANES * sizeof(double));
            for (int j = 0; j < 9; j++) h = fnv(h, g.sum[j], LANES * sizeof(double));
            hash = h, nrec = nr;
        }
    }
    qsort(tb, (size_t)reps, sizeof(double), cmp_d);
    qsort(tg, (size_t)reps, sizeof(double), cmp_d);
    const double ls = (double)LANES * KCALL * ncall;
    printf("gyro tile vs plain tile, boris dipole, %d lanes, %d calls of %d steps, median of %d\n",
           LANES, ncall, KCALL, reps);
    printf("plain %.3f ns/lane-step  gyro %.3f ns/lane-step  ratio %.3f  records/lane-step %.4f"
           "  hash %016llx\n",
           1e9 * tb[reps / 2] / ls, 1e9 * tg[reps / 2] / ls, tg[reps / 2] / tb[reps / 2],
           nrec / ls, (unsigned long long)hash);
    return 0;
}
