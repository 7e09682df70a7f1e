/* bench_push -- `make bench`: how fast gcpush pushes, against the machine
 * and against the minimal hand-written loop.  Single core, wall clock, the
 * best of REPS repetitions of each measurement (the minimum rejects other
 * processes' interference; it is what the hardware can do).
 *
 * Part 1 (issue 2): the library's block stepper, gcp_block_advance_fo with
 *   the `boris` pusher, in uniform B and in Earth's dipole, resident regime
 *   (one block pushed many steps per call), against a hand-written fused
 *   drift-kick-drift Boris loop over the same struct-of-arrays block
 *   compiled with the same flags.  Reports ns per particle-step, the ratio
 *   (goal <= 1.5) and particle-steps/s in uniform B (goal >= 1e8 per core).
 *   The hand loop computes the same thing, operation for operation: the
 *   program checks that it lands on the library's result bit for bit.
 *
 * Part 2 (issue 8): the header-only kernels of kernels.h.
 *   Streaming regime: N = 1e7 particles, one step per particle per sweep,
 *   with fields gathered into arrays (the PIC situation).  GB/s moved,
 *   counting the bytes each pass must read and write (the STREAM
 *   convention: no write-allocate traffic), against a STREAM triad
 *   a = b + s c on arrays of the same size measured in the same run
 *   (goal >= 80%).
 *   Resident regime: a block that stays in cache, many sweeps: ns per
 *   particle-step of gcp_push_boris_batch + gcp_drift_batch against the
 *   hand-written fused kick + drift loop (goal <= 1.1x).
 *
 * Streaming (issue 12): the library's block push, gcp_block_advance_fo,
 *   one step per call over 1e7 particles, as a fraction of the memory
 *   floor measured on the same arrays in the same run (part_stream).
 *
 * Part 3 (issue 11): guiding-centre methods, cost per step against gc-rk4.
 *
 * Usage: bench_push [scale]   (scale < 1 shortens every measurement, for smoke tests)
 *        bench_push gc        (part 3 alone: the guiding-centre methods of issue 11)
 *        bench_push stream [scale]  (the issue-12 streaming part alone) */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "gcpush/field.h"
#include "gcpush/gc.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "gcpush/pusher.h"
#include "block_priv.h" /* src/pushers: gcp_block_classify, for the stepper breakdown */

#define REPS 5
#define QP 1.602176634e-19     /* proton charge [C] */
#define MP 1.67262192369e-27   /* proton mass [kg] */
#define RE GCP_EARTH_RADIUS
#define INV_C2 (1.0 / (GCP_C_LIGHT * GCP_C_LIGHT))

static double scale = 1.0;

/* Wall clock, or with GCP_BENCH_CPU set the process's CPU time (on a
 * shared, loaded machine: time slices taken by others do not count). */
static double now(void)
{
    static int cpu = -1;
    if (cpu < 0) cpu = getenv("GCP_BENCH_CPU") != NULL;
    struct timespec ts;
    clock_gettime(cpu ? CLOCK_PROCESS_CPUTIME_ID : CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static uint64_t rng = 0x243F6A8885A308D3ull;
static double urand(void)
{
    uint64_t z = (rng += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return (double)(z >> 11) * (1.0 / 9007199254740992.0);
}

static double *dalloc(size_t n)
{
    double *p = aligned_alloc(64, ((n * sizeof(double) + 63) / 64) * 64);
    if (!p) {
        fprintf(stderr, "bench_push: out of memory\n");
        exit(1);
    }
    memset(p, 0, n * sizeof(double)); /* first touch outside the timings */
    return p;
}

static volatile double sink; /* keeps results alive */

/* Every timed sweep is a call the compiler may not inline: inlined into the
 * sweep loop, GCC -O3 may interchange the loops (-floop-interchange) and make
 * k sweeps one pass over memory, which would fake the streaming numbers. */
#define NOINLINE __attribute__((noinline))

/* ---------------------------------------------------------------------------
 * Scenes.  Uniform: B = 1e-3 T along z, 1 MeV protons, isotropic, dt = 0.05
 * gyro.  Dipole: 10 MeV protons on the equator at L = 3.5 .. 4.5, pitch
 * 30 .. 90 deg, dt = 0.05 of the equatorial gyro period at L = 4.
 * ------------------------------------------------------------------------- */
enum scene { UNIFORM, DIPOLE };
static const double B_UNI = 1e-3;

static void init_particles(enum scene sc, size_t n, double *x, double *y, double *z, double *ux,
                           double *uy, double *uz, double *dt)
{
    rng = 0x243F6A8885A308D3ull;
    const double ek = (sc == UNIFORM ? 1.0 : 10.0) * 1.602176634e-13; /* [J] */
    const double g = 1.0 + ek / (MP * GCP_C_LIGHT * GCP_C_LIGHT);
    const double u = GCP_C_LIGHT * sqrt(g * g - 1.0);
    for (size_t i = 0; i < n; i++) {
        if (sc == UNIFORM) {
            const double ct = 2.0 * urand() - 1.0, ph = 2.0 * GCP_PI * urand();
            const double st = sqrt(1.0 - ct * ct);
            x[i] = y[i] = z[i] = 0.0;
            ux[i] = u * st * cos(ph), uy[i] = u * st * sin(ph), uz[i] = u * ct;
        } else {
            const double L = 3.5 + urand(), lon = 2.0 * GCP_PI * urand();
            const double a = (30.0 + 60.0 * urand()) * GCP_PI / 180.0, ph = 2.0 * GCP_PI * urand();
            x[i] = L * RE * cos(lon), y[i] = L * RE * sin(lon), z[i] = 0.0;
            /* B is along +z on the equator: u_par along z, u_perp in the plane */
            ux[i] = u * sin(a) * cos(ph), uy[i] = u * sin(a) * sin(ph), uz[i] = u * cos(a);
        }
    }
    const double B = sc == UNIFORM ? B_UNI : GCP_EARTH_B0 / 64.0;
    *dt = 0.05 * 2.0 * GCP_PI * g * MP / (QP * B);
}

/* ---------------------------------------------------------------------------
 * The hand-written references.  Written as one would by hand for a fixed
 * scene: fused drift-kick-drift in one loop, the field inline, no status
 * checks; the operations are those of kernels.h / fields/dipole.c in the
 * same order, so the result is bit-identical to the library's.
 * ------------------------------------------------------------------------- */
static void hand_uniform(size_t n, double *restrict x, double *restrict y, double *restrict z,
                         double *restrict ux, double *restrict uy, double *restrict uz,
                         const double B[3], double q, double m, double dt, int64_t nsteps)
{
    /* general direction of B (constants in registers), no E: the scene has none */
    const double h = 0.5 * dt, qdt2m = 0.5 * q * dt / m;
    const double Bx = B[0], By = B[1], Bz = B[2];
    for (int64_t k = 0; k < nsteps; k++)
        for (size_t i = 0; i < n; i++) {
            double vx = ux[i], vy = uy[i], vz = uz[i];
            const double hg = h / sqrt(1.0 + (vx * vx + vy * vy + vz * vz) * INV_C2);
            const double px = x[i] + vx * hg, py = y[i] + vy * hg, pz = z[i] + vz * hg;
            const double ig = 1.0 / sqrt(1.0 + (vx * vx + vy * vy + vz * vz) * INV_C2);
            const double tx = qdt2m * ig * Bx, ty = qdt2m * ig * By, tz = qdt2m * ig * Bz;
            const double s = 2.0 / (1.0 + tx * tx + ty * ty + tz * tz);
            const double upx = vx + (vy * tz - vz * ty);
            const double upy = vy + (vz * tx - vx * tz);
            const double upz = vz + (vx * ty - vy * tx);
            vx = vx + s * (upy * tz - upz * ty);
            vy = vy + s * (upz * tx - upx * tz);
            vz = vz + s * (upx * ty - upy * tx);
            const double hg2 = h / sqrt(1.0 + (vx * vx + vy * vy + vz * vz) * INV_C2);
            x[i] = px + vx * hg2, y[i] = py + vy * hg2, z[i] = pz + vz * hg2;
            ux[i] = vx, uy[i] = vy, uz[i] = vz;
        }
}

static void hand_dipole(size_t n, double *restrict x, double *restrict y, double *restrict z,
                        double *restrict ux, double *restrict uy, double *restrict uz, double c,
                        double q, double m, double dt, int64_t nsteps)
{
    const double h = 0.5 * dt, qdt2m = 0.5 * q * dt / m;
    for (int64_t k = 0; k < nsteps; k++)
        for (size_t i = 0; i < n; i++) {
            double vx = ux[i], vy = uy[i], vz = uz[i];
            const double hg = h / sqrt(1.0 + (vx * vx + vy * vy + vz * vz) * INV_C2);
            const double px = x[i] + vx * hg, py = y[i] + vy * hg, pz = z[i] + vz * hg;
            double r2 = px * px + py * py + pz * pz;
            r2 = r2 > 1.0 ? r2 : 1.0;
            const double c5 = c / (r2 * r2 * sqrt(r2)), m3z = -3.0 * c5 * pz;
            const double ig = 1.0 / sqrt(1.0 + (vx * vx + vy * vy + vz * vz) * INV_C2);
            const double tx = qdt2m * ig * (m3z * px), ty = qdt2m * ig * (m3z * py);
            const double tz = qdt2m * ig * (c5 * (r2 - 3.0 * pz * pz));
            const double s = 2.0 / (1.0 + tx * tx + ty * ty + tz * tz);
            const double upx = vx + (vy * tz - vz * ty);
            const double upy = vy + (vz * tx - vx * tz);
            const double upz = vz + (vx * ty - vy * tx);
            vx = vx + s * (upy * tz - upz * ty);
            vy = vy + s * (upz * tx - upx * tz);
            vz = vz + s * (upx * ty - upy * tx);
            const double hg2 = h / sqrt(1.0 + (vx * vx + vy * vy + vz * vz) * INV_C2);
            x[i] = px + vx * hg2, y[i] = py + vy * hg2, z[i] = pz + vz * hg2;
            ux[i] = vx, uy[i] = vy, uz[i] = vz;
        }
}

/* ---------------------------------------------------------------------------
 * Part 1: library block stepper vs hand loop, resident.
 * ------------------------------------------------------------------------- */
struct p1_result {
    double ns_lib, ns_hand;
    double maxdiff; /* max |library - hand| over x and u after the check run, relative */
};

static struct p1_result part1(enum scene sc, size_t nb, int64_t total_steps)
{
    struct p1_result r = {INFINITY, INFINITY, 0.0};
    struct gcp_field *f = sc == UNIFORM
                              ? gcp_field_uniform_create((const double[3]){0, 0, B_UNI},
                                                         (const double[3]){0, 0, 0})
                              : gcp_field_dipole_create(GCP_EARTH_B0, 0, RE + 100e3, 15.0 * RE);
    struct gcp_block b;
    if (!f || gcp_block_alloc(&b, nb)) {
        fprintf(stderr, "bench_push: out of memory\n");
        exit(1);
    }
    double *hx = dalloc(nb), *hy = dalloc(nb), *hz = dalloc(nb);
    double *hux = dalloc(nb), *huy = dalloc(nb), *huz = dalloc(nb);
    double dt;
    const int64_t nsteps = (int64_t)fmax(1.0, scale * (double)total_steps / (double)nb);
    b.q = QP, b.m = MP;
    const double c = GCP_EARTH_B0 * RE * RE * RE;

    for (int rep = 0; rep < REPS; rep++) {
        init_particles(sc, nb, b.x, b.y, b.z, b.ux, b.uy, b.uz, &dt);
        b.n_active = nb;
        for (size_t i = 0; i < nb; i++) b.status[i] = 0, b.steps[i] = 0, b.index[i] = i;
        gcp_block_start(&b, f, 0.0);
        double t0 = now();
        size_t live = gcp_block_advance_fo(&b, f, &gcp_pusher_boris, 0.0, dt, nsteps, NULL);
        double t1 = now();
        if (live != nb) fprintf(stderr, "bench_push: %zu of %zu lanes stopped\n", nb - live, nb);
        r.ns_lib = fmin(r.ns_lib, 1e9 * (t1 - t0) / ((double)nb * (double)nsteps));

        init_particles(sc, nb, hx, hy, hz, hux, huy, huz, &dt);
        t0 = now();
        if (sc == UNIFORM)
            hand_uniform(nb, hx, hy, hz, hux, huy, huz, (const double[3]){0, 0, B_UNI}, QP, MP, dt,
                         nsteps);
        else
            hand_dipole(nb, hx, hy, hz, hux, huy, huz, c, QP, MP, dt, nsteps);
        t1 = now();
        r.ns_hand = fmin(r.ns_hand, 1e9 * (t1 - t0) / ((double)nb * (double)nsteps));
    }
    /* Same work?  After the last repetition both pushed the same particles
     * the same nsteps: compare (lanes were not reordered: none stopped). */
    for (size_t i = 0; i < nb; i++) {
        const double lx[6] = {b.x[i], b.y[i], b.z[i], b.ux[i], b.uy[i], b.uz[i]};
        const double hv[6] = {hx[i], hy[i], hz[i], hux[i], huy[i], huz[i]};
        const double sx = sqrt(hx[i] * hx[i] + hy[i] * hy[i] + hz[i] * hz[i]) + 1.0;
        const double su = sqrt(hux[i] * hux[i] + huy[i] * huy[i] + huz[i] * huz[i]);
        for (int k = 0; k < 6; k++)
            r.maxdiff = fmax(r.maxdiff, fabs(lx[k] - hv[k]) / (k < 3 ? sx : su));
    }
    free(hx), free(hy), free(hz), free(hux), free(huy), free(huz);
    gcp_block_free(&b);
    gcp_field_free(f);
    return r;
}

/* Where the stepper's time goes: each pass of gcp_block_advance_fo's step
 * timed on its own over the same resident block (ns per particle-step). */
static void part1_breakdown(enum scene sc, size_t nb)
{
    struct gcp_field *f = sc == UNIFORM
                              ? gcp_field_uniform_create((const double[3]){0, 0, B_UNI},
                                                         (const double[3]){0, 0, 0})
                              : gcp_field_dipole_create(GCP_EARTH_B0, 0, RE + 100e3, 15.0 * RE);
    struct gcp_block b;
    if (!f || gcp_block_alloc(&b, nb)) exit(1);
    double dt;
    b.q = QP, b.m = MP;
    init_particles(sc, nb, b.x, b.y, b.z, b.ux, b.uy, b.uz, &dt);
    gcp_block_start(&b, f, 0.0);
    const int64_t reps = (int64_t)fmax(1.0, scale * 2e7 / (double)nb);
    const double h = 0.5 * dt;
    double best[6];
    for (int k = 0; k < 6; k++) best[k] = INFINITY;
    volatile int32_t any = 0;
    for (int rep = 0; rep < REPS; rep++) {
        double t[7];
        t[0] = now();
        for (int64_t r = 0; r < reps; r++) {
            gcp_drift_batch(nb, b.x, b.y, b.z, b.ux, b.uy, b.uz, h);
            gcp_drift_batch(nb, b.x, b.y, b.z, b.ux, b.uy, b.uz, -h); /* undo: same cost */
        }
        t[1] = now();
        for (int64_t r = 0; r < reps; r++) {
            memset(b.fstatus, 0, nb * sizeof(int32_t));
            __asm__ volatile("" ::: "memory");
        }
        t[2] = now();
        for (int64_t r = 0; r < reps; r++)
            f->type->eval_block(f, 0.0, nb, b.x, b.y, b.z, b.Bx, b.By, b.Bz, NULL, NULL, NULL,
                                b.fstatus);
        t[3] = now();
        for (int64_t r = 0; r < reps; r++)
            gcp_pusher_boris.kick(nb, b.ux, b.uy, b.uz, b.Ex, b.Ey, b.Ez, b.Bx, b.By, b.Bz, b.q,
                                  b.m, r & 1 ? -dt : dt);
        t[4] = now();
        for (int64_t r = 0; r < reps; r++) any |= gcp_block_classify(&b, nb, f, 0);
        t[5] = now();
        for (int k = 0; k < 5; k++)
            best[k] = fmin(best[k], 1e9 * (t[k + 1] - t[k]) / ((double)reps * (double)nb));
    }
    printf("  %-9s %6zu %9.2f %9.2f %9.2f %9.2f %9.2f %9.2f\n",
           sc == UNIFORM ? "uniform" : "dipole", nb, best[0], best[1], best[2], best[3], best[4],
           best[0] + best[1] + best[2] + best[3] + best[4]);
    gcp_block_free(&b);
    gcp_field_free(f);
}

/* ---------------------------------------------------------------------------
 * Part 2: kernels.h, streaming and resident.
 * ------------------------------------------------------------------------- */
struct soa {
    size_t n;
    double *x, *y, *z, *ux, *uy, *uz, *Ex, *Ey, *Ez, *Bx, *By, *Bz;
};

static void soa_alloc(struct soa *s, size_t n)
{
    s->n = n;
    double **a[] = {&s->x, &s->y, &s->z, &s->ux, &s->uy, &s->uz,
                    &s->Ex, &s->Ey, &s->Ez, &s->Bx, &s->By, &s->Bz};
    for (size_t k = 0; k < 12; k++) *a[k] = dalloc(n);
    double dt;
    init_particles(UNIFORM, n, s->x, s->y, s->z, s->ux, s->uy, s->uz, &dt);
    for (size_t i = 0; i < n; i++) { /* gathered fields: a little E, B along z with noise */
        s->Ex[i] = 1e3 * (urand() - 0.5), s->Ey[i] = 1e3 * (urand() - 0.5), s->Ez[i] = 0.0;
        s->Bx[i] = 1e-5 * (urand() - 0.5), s->By[i] = 1e-5 * (urand() - 0.5), s->Bz[i] = B_UNI;
    }
}

static void soa_free(struct soa *s)
{
    double *a[] = {s->x, s->y, s->z, s->ux, s->uy, s->uz, s->Ex, s->Ey, s->Ez, s->Bx, s->By, s->Bz};
    for (size_t k = 0; k < 12; k++) free(a[k]);
}

/* STREAM triad, a = b + s c: 24 bytes per element. */
static NOINLINE void triad(size_t n, double *restrict a, const double *restrict b,
                  const double *restrict c, double s)
{
    for (size_t i = 0; i < n; i++) a[i] = b[i] + s * c[i];
}

/* One PIC step with the kernels: kick (reads u, E, B; writes u) then
 * position x += u/gamma dt (reads x, u; writes x). */
static NOINLINE void kernels_step(struct soa *s, double dt)
{
    gcp_push_boris_batch(s->n, s->ux, s->uy, s->uz, s->Ex, s->Ey, s->Ez, s->Bx, s->By, s->Bz, QP,
                         MP, dt);
    gcp_drift_batch(s->n, s->x, s->y, s->z, s->ux, s->uy, s->uz, dt);
}

static NOINLINE void kick_only(struct soa *s, double dt)
{
    gcp_push_boris_batch(s->n, s->ux, s->uy, s->uz, s->Ex, s->Ey, s->Ez, s->Bx, s->By, s->Bz, QP,
                         MP, dt);
}

/* The same step written by hand, fused (reads x, u, E, B; writes x, u). */
static void hand_step(size_t n, double *restrict x, double *restrict y, double *restrict z,
                      double *restrict ux, double *restrict uy, double *restrict uz,
                      const double *restrict Ex, const double *restrict Ey,
                      const double *restrict Ez, const double *restrict Bx,
                      const double *restrict By, const double *restrict Bz, double q, double m,
                      double dt)
{
    const double a = 0.5 * q * dt / m;
    for (size_t i = 0; i < n; i++) {
        const double ex = a * Ex[i], ey = a * Ey[i], ez = a * Ez[i];
        const double mx = ux[i] + ex, my = uy[i] + ey, mz = uz[i] + ez;
        const double ig = a / sqrt(1.0 + (mx * mx + my * my + mz * mz) * INV_C2);
        const double tx = ig * Bx[i], ty = ig * By[i], tz = ig * Bz[i];
        const double s = 2.0 / (1.0 + tx * tx + ty * ty + tz * tz);
        const double px = mx + (my * tz - mz * ty);
        const double py = my + (mz * tx - mx * tz);
        const double pz = mz + (mx * ty - my * tx);
        const double vx = mx + s * (py * tz - pz * ty) + ex;
        const double vy = my + s * (pz * tx - px * tz) + ey;
        const double vz = mz + s * (px * ty - py * tx) + ez;
        const double hg = dt / sqrt(1.0 + (vx * vx + vy * vy + vz * vz) * INV_C2);
        x[i] += vx * hg, y[i] += vy * hg, z[i] += vz * hg;
        ux[i] = vx, uy[i] = vy, uz[i] = vz;
    }
}

static NOINLINE void hand_step_soa(struct soa *s, double dt)
{
    hand_step(s->n, s->x, s->y, s->z, s->ux, s->uy, s->uz, s->Ex, s->Ey, s->Ez, s->Bx, s->By,
              s->Bz, QP, MP, dt);
}

static NOINLINE void aos_step(struct gcp_particle_aos *p, const struct soa *f, size_t n, double dt)
{
    gcp_push_boris_aos(n, p, f->Ex, f->Ey, f->Ez, f->Bx, f->By, f->Bz, QP, MP, dt);
    gcp_drift_aos(n, p, dt);
}

/* Part 3 (issue 11): guiding-centre methods, cost per particle-step in the
 * dipole against gc-rk4: a block of 64 protons, 1-10 MeV, L = 3.5 .. 4.5,
 * equatorial pitch 30 .. 85 deg, dt = 1/25 of the shortest bounce period
 * (~0.09 s: the coarse end of what the symplectic methods are run at), 250
 * steps per repetition (10 bounces: the per-advance set-up counts once). */
static void part_gc(void)
{
    const struct gcp_pusher_type *ps[] = {&gcp_pusher_gc_rk4, &gcp_pusher_gc_gl2,
                                          &gcp_pusher_gc_gl4, &gcp_pusher_gc_midpoint_pphi,
                                          &gcp_pusher_gc_gl4_sundman};
    const char *goal[] = {"", "(<= 3)", "(<= 6)", "", ""};
    struct gcp_field *f = gcp_field_dipole_create(GCP_EARTH_B0, 0, 0.0, 0.0);
    const size_t n = 64;
    const int64_t steps = 250; /* ~0.5 s a method: not scaled */
    struct gcp_block b;
    if (gcp_block_alloc(&b, n)) return;
    double X0[64][3], pp0[64], mu0[64];
    rng = 0x243F6A8885A308D3ull;
    for (size_t i = 0; i < n; i++) {
        const double T = 1e6 * QP * pow(10.0, urand()), L = 3.5 + urand();
        const double a = (30.0 + 55.0 * urand()) * GCP_PI / 180.0, lon = 2.0 * GCP_PI * urand();
        const double g = 1.0 + T / (MP * GCP_C_LIGHT * GCP_C_LIGHT);
        const double p = MP * GCP_C_LIGHT * sqrt(g * g - 1.0);
        X0[i][0] = L * RE * cos(lon), X0[i][1] = L * RE * sin(lon), X0[i][2] = 0.0;
        pp0[i] = p * cos(a);
        mu0[i] = p * sin(a) * p * sin(a) / (2.0 * MP * GCP_EARTH_B0 / (L * L * L));
    }
    /* 10 MeV at L = 3.5, 30 deg: T_b ~ 2.1 s; 1/25 of it */
    const struct gcp_push_opts o = {0.0, 2.1 / 25.0, steps, 0.0, 0.0};
    printf("Issue 11: guiding-centre methods in the dipole, block of %zu protons, dt = T_b/25\n", n);
    printf("  %-18s %14s %10s %8s\n", "method", "[us/step]", "x gc-rk4", "goal");
    double t_rk4 = NAN;
    for (size_t k = 0; k < sizeof ps / sizeof ps[0]; k++) {
        double best = INFINITY;
        size_t alive = 0;
        int64_t taken = 0; /* steps taken (the Sundman method's differ from `steps`) */
        for (int rep = 0; rep < REPS; rep++) {
            for (size_t i = 0; i < n; i++) {
                b.x[i] = X0[i][0], b.y[i] = X0[i][1], b.z[i] = X0[i][2];
                b.ppar[i] = pp0[i], b.mu[i] = mu0[i], b.status[i] = 0, b.steps[i] = 0;
                b.index[i] = i;
            }
            b.n_active = n;
            b.q = QP, b.m = MP;
            const double t0 = now();
            alive = ps[k]->advance(&b, f, ps[k], &o, NULL);
            best = fmin(best, now() - t0);
            taken = 0;
            for (size_t i = 0; i < n; i++) taken += b.steps[i];
        }
        const double us = 1e6 * best / (double)taken;
        if (k == 0) t_rk4 = us;
        printf("  %-18s %14.3f %10.2f %8s%s\n", ps[k]->name, us, us / t_rk4, goal[k],
               alive == n ? "" : "  (some lanes stopped)");
    }
    printf("\n");
    gcp_block_free(&b);
    gcp_field_free(f);
}

/* ---------------------------------------------------------------------------
 * Issue 12: the pushers against ../shared/limit's kernels (a), (b) and (c),
 * the same scenes, resident block.
 * (b), (c): 1 MeV protons on the equator at L = 3.5 .. 4.5, equatorial
 * pitch 30 .. 80 deg.  (b): relativistic Boris, Omega_eq(L=4) dt = 0.05.
 * (c): gc-rk4, dt = Tb(L=4, 45 deg)/1000 with the dipole bounce period
 * Tb = 4 L R_E / v (1.30 - 0.56 sin a) (Hamlin et al. 1961 fit).
 * (a): Boris in uniform B and E, limit_bench's scene in SI: |B| = 1 T along
 * (0.3, 0.4, sqrt(0.75)), Omega dt = 0.1, E perpendicular to B along
 * b x xhat with |E| = 0.05 V0 |B|, protons at x in [0, 1) m with each
 * velocity component uniform in [-V0, V0), V0 = 1e6 m/s (gamma - 1 ~ 1e-5:
 * kernel (a) is non-relativistic; gcpush's Boris is relativistic
 * throughout, 2 sqrt and 3 divisions a step that (a) does not have).
 * Prints ns per particle-step; tests/bench/vs_limit.sh divides by the
 * limit kernels measured in the same `make bench`.
 * ------------------------------------------------------------------------- */
enum limit_kind { LIMIT_BORIS_DIPOLE, LIMIT_GC_RK4_DIPOLE, LIMIT_BORIS_UNIFORM, LIMIT_NR_UNIFORM_B };
static const double LIMIT_A_V0 = 1e6; /* [m/s] */

static void init_limit_scene(struct gcp_block *b, size_t nb, enum limit_kind kind, double *dt)
{
    const int gc = kind == LIMIT_GC_RK4_DIPOLE;
    if (kind == LIMIT_BORIS_UNIFORM || kind == LIMIT_NR_UNIFORM_B) {
        rng = 0x452821E638D01377ull;
        for (size_t i = 0; i < nb; i++) {
            b->x[i] = urand(), b->y[i] = urand(), b->z[i] = urand();
            b->ux[i] = LIMIT_A_V0 * (2.0 * urand() - 1.0);
            b->uy[i] = LIMIT_A_V0 * (2.0 * urand() - 1.0);
            b->uz[i] = LIMIT_A_V0 * (2.0 * urand() - 1.0);
            b->status[i] = 0, b->steps[i] = 0, b->index[i] = i, b->t[i] = 0.0;
        }
        b->n_active = nb;
        *dt = 0.1 * MP / (QP * 1.0);
        return;
    }
    rng = 0x13198A2E03707344ull;
    const double ek = 1.602176634e-13, mc2 = MP * GCP_C_LIGHT * GCP_C_LIGHT;
    const double g = 1.0 + ek / mc2, p = MP * GCP_C_LIGHT * sqrt(g * g - 1.0);
    for (size_t i = 0; i < nb; i++) {
        const double L = 3.5 + urand(), lon = 2.0 * GCP_PI * urand();
        const double a = (30.0 + 50.0 * urand()) * GCP_PI / 180.0, ph = 2.0 * GCP_PI * urand();
        b->x[i] = L * RE * cos(lon), b->y[i] = L * RE * sin(lon), b->z[i] = 0.0;
        const double Beq = GCP_EARTH_B0 / (L * L * L);
        if (gc) {
            b->ppar[i] = p * cos(a); /* B along +z at the equator */
            b->mu[i] = (p * sin(a)) * (p * sin(a)) / (2.0 * MP * Beq);
        } else {
            const double u = p / MP;
            b->ux[i] = u * sin(a) * cos(ph), b->uy[i] = u * sin(a) * sin(ph);
            b->uz[i] = u * cos(a);
        }
        b->status[i] = 0, b->steps[i] = 0, b->index[i] = i, b->t[i] = 0.0;
    }
    b->n_active = nb;
    const double v = p / (g * MP), L4 = 4.0 * RE;
    *dt = gc ? 4.0 * L4 / v * (1.30 - 0.56 * sin(GCP_PI / 4.0)) / 1000.0
             : 0.05 * g * MP / (QP * GCP_EARTH_B0 / 64.0);
}

static struct gcp_field *limit_field(enum limit_kind kind)
{
    if (kind != LIMIT_BORIS_UNIFORM && kind != LIMIT_NR_UNIFORM_B)
        return gcp_field_dipole_create(GCP_EARTH_B0, 0, RE + 100e3, 15.0 * RE);
    const double bx = 0.3, by = 0.4, bz = sqrt(0.75);
    const double ey = bz, ez = -by, en = sqrt(ey * ey + ez * ez); /* b x xhat */
    const double e = kind == LIMIT_NR_UNIFORM_B ? 0.0 : 0.05 * LIMIT_A_V0 * 1.0;
    return gcp_field_uniform_create((const double[3]){bx, by, bz},
                                    (const double[3]){0.0, e * ey / en, e * ez / en});
}

static double limit_scene_arith(enum limit_kind kind, const struct gcp_pusher_type *p,
                                size_t nb, double total_steps, int arith)
{
    struct gcp_field *f = limit_field(kind);
    struct gcp_block b;
    if (!f || gcp_block_alloc(&b, nb)) exit(1);
    b.q = QP, b.m = MP;
    /* Many short repetitions (tens of ms), best of them, as limit_bench
     * does: on a shared machine a short one is more likely to run alone. */
    const int reps = (int)fmax(3.0, 30.0 * fmin(scale, 1.0));
    const int64_t nsteps = (int64_t)fmax(1.0, total_steps / (double)nb);
    double best = INFINITY, dt;
    for (int rep = 0; rep < reps; rep++) {
        init_limit_scene(&b, nb, kind, &dt);
        size_t live;
        const double t0 = now();
        if (kind == LIMIT_GC_RK4_DIPOLE) {
            const struct gcp_push_opts o = {0.0, dt, nsteps, 0.0, 0.0};
            live = gcp_pusher_gc_rk4.advance(&b, f, &gcp_pusher_gc_rk4, &o, NULL);
        } else {
            gcp_block_start(&b, f, 0.0);
            b.flags = arith ? GCP_BLOCK_FAST_ARITH : 0u;
            live = gcp_block_advance_fo(&b, f, p, 0.0, dt, nsteps, NULL);
        }
        const double t1 = now();
        if (live != nb) fprintf(stderr, "bench_push: %zu of %zu lanes stopped\n", nb - live, nb);
        best = fmin(best, 1e9 * (t1 - t0) / ((double)nb * (double)nsteps));
    }
    sink = b.x[0];
    gcp_block_free(&b);
    gcp_field_free(f);
    return best;
}

static double limit_scene(enum limit_kind kind, const struct gcp_pusher_type *p, size_t nb,
                          double total_steps)
{
    return limit_scene_arith(kind, p, nb, total_steps, 0);
}

/* ---------------------------------------------------------------------------
 * Issue 12, streaming: the library's block push as a PIC code calls it --
 * gcp_block_advance_fo with the `boris` pusher, one step per call, over one
 * block of N = 1e7 particles (so every call streams the whole state from
 * memory) -- against the memory floor measured in the same run on the same
 * arrays: the least a step can move is x and u read and written, 96 B per
 * particle, and the floor is a read-modify-write sweep of exactly those six
 * arrays in place (../shared/limit's kernel M, "pusher-traffic RMW":
 * u *= s, x += d u, here with s = 1 and d = 0 from volatiles, so it leaves
 * the state as it was).  A STREAM triad (a = b + s c, 24 B an element, on
 * the block's field scratch arrays) is printed beside it, as 96 B at the
 * triad's rate.  Each repetition times one floor sweep and the pushes
 * back to back, so load from other processes hits all alike; best of the
 * repetitions, in this thread's CPU time (cpu_now).  The fraction is floor
 * time / push time (goal >= 0.80).
 *
 * What bounds it: "PIC L2" is the same call, one step, on STREAM_NC lanes
 * of the scene that stay in L2, called n / STREAM_NC times a repetition --
 * the step's arithmetic with no memory traffic to wait for.  floor / PIC L2
 * is then the most "push PIC of floor" can reach even with every byte's
 * traffic hidden behind the arithmetic.  A step of one call recomputes
 * gamma(u) and the drift factor on entry (the block keeps no gamma array:
 * that would be 16 B a lane more than the floor moves), so IEEE relativistic
 * Boris does at least 2 square roots and 4 divisions a lane a call (uniform
 * B; E and the dipole's field add more), on a divide unit of a fraction of
 * the multipliers' throughput.  On the development machine (AMD EPYC,
 * 2026-11-24, loaded) floor / PIC L2 read 0.81-0.87 in uniform B, 0.71-0.82
 * in E and B and 0.66-0.69 in the dipole (idle `make bench` at 04:35 and
 * 07:11: 0.75-0.76, 0.65-0.70, 0.62-0.66): the goal asks for the memory
 * traffic hidden almost entirely behind the arithmetic, and in the dipole
 * is out of reach for the IEEE step however the traffic is scheduled.
 * Measured there (a stand-alone copy of the uniform-B tile) and not kept:
 * non-temporal stores of x and u (the push writes the lines it has just
 * read, so there is no read-for-ownership to save; they evict the line:
 * 15-35% slower, the same bits), 2 MiB pages for the six arrays (floor and
 * push alike unchanged), software prefetch one or more tiles ahead (1.4-1.6x
 * slower), one loop a lane instead of the tile's loops (its dependency chain
 * is longer than the out-of-order window hides: ~15% slower in L2, no gain
 * streaming), tiles of 32 or 64 lanes (within the noise) and of 512 (the
 * tile and its scratch fill L1: 1.5x slower).
 * ------------------------------------------------------------------------- */
static volatile double stream_keep_s = 1.0, stream_keep_d = 0.0;

/* This thread's CPU time: the streaming part runs on a machine shared with
 * other jobs, whose time slices wall clock would count (another process's
 * memory traffic still slows floor and push alike). */
static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static NOINLINE void stream_floor(size_t n, double *restrict x, double *restrict y,
                                  double *restrict z, double *restrict ux, double *restrict uy,
                                  double *restrict uz, double s, double d)
{
    for (size_t i = 0; i < n; i++) {
        const double U = ux[i] * s, V = uy[i] * s, W = uz[i] * s;
        ux[i] = U, uy[i] = V, uz[i] = W;
        x[i] += d * U, y[i] += d * V, z[i] += d * W;
    }
}

enum stream_scene { STREAM_UNIFORM_B, STREAM_UNIFORM_EB, STREAM_DIPOLE };
/* lanes of the cached block (6 x 32 KiB of x and u: in L2, not in L1) */
#define STREAM_NC ((size_t)4096)

static void stream_scene(enum stream_scene sc, size_t n, int reps)
{
    static const char *name[] = {"uniform B", "uniform E and B", "dipole"};
    struct gcp_field *f =
        sc == STREAM_UNIFORM_B
            ? gcp_field_uniform_create((const double[3]){0, 0, B_UNI}, (const double[3]){0, 0, 0})
            : limit_field(sc == STREAM_DIPOLE ? LIMIT_BORIS_DIPOLE : LIMIT_BORIS_UNIFORM);
    struct gcp_block b;
    if (!f || gcp_block_alloc(&b, n)) {
        fprintf(stderr, "bench_push: out of memory\n");
        exit(1);
    }
    b.q = QP, b.m = MP;
    double dt;
    if (sc == STREAM_UNIFORM_B) init_particles(UNIFORM, n, b.x, b.y, b.z, b.ux, b.uy, b.uz, &dt);
    else
        init_limit_scene(&b, n, sc == STREAM_DIPOLE ? LIMIT_BORIS_DIPOLE : LIMIT_BORIS_UNIFORM,
                         &dt);
    gcp_block_start(&b, f, 0.0);
    /* the same push on STREAM_NC of the same lanes, called n / STREAM_NC
     * times a repetition: the lane-steps of one streaming call with the
     * block in L2, what the step's arithmetic alone costs a lane -- the
     * streaming push can come no nearer the floor than floor / this */
    struct gcp_block c;
    if (gcp_block_alloc(&c, STREAM_NC)) {
        fprintf(stderr, "bench_push: out of memory\n");
        exit(1);
    }
    c.q = b.q, c.m = b.m;
    {
        double *src[] = {b.x, b.y, b.z, b.ux, b.uy, b.uz};
        double *dst[] = {c.x, c.y, c.z, c.ux, c.uy, c.uz};
        for (int k = 0; k < 6; k++) memcpy(dst[k], src[k], STREAM_NC * sizeof(double));
    }
    gcp_block_start(&c, f, 0.0);
    const long ncall = (long)((n + STREAM_NC - 1) / STREAM_NC);
    double t_floor = INFINITY, t_triad = INFINITY, t_push[2] = {INFINITY, INFINITY};
    double t_fast = INFINITY; /* push PIC with arithmetic = fast (GCP_BLOCK_FAST_ARITH) */
    double t_l2[2] = {INFINITY, INFINITY}; /* push PIC, fast: STREAM_NC lanes in L2 */
    const int fast = gcp_arithmetic_fast_available(&gcp_pusher_boris);
    double t = 0.0, tc = 0.0;
    /* repetition 0 is the warm-up: first touch of every array (page faults) */
    for (int rep = 0; rep <= reps; rep++) {
        double tk[6];
        tk[0] = cpu_now();
        stream_floor(n, b.x, b.y, b.z, b.ux, b.uy, b.uz, stream_keep_s, stream_keep_d);
        tk[1] = cpu_now();
        triad(n, b.Bx, b.By, b.Bz, stream_keep_s);
        tk[2] = cpu_now();
        /* the block's clocks kept per lane (the default), then the PIC
         * code's way: the caller keeps the clock (GCP_BLOCK_CALLER_CLOCK) */
        for (int k = 0; k < 2; k++) {
            b.flags = k ? GCP_BLOCK_CALLER_CLOCK : 0u;
            const size_t live = gcp_block_advance_fo(&b, f, &gcp_pusher_boris, t, dt, 1, NULL);
            tk[3 + k] = cpu_now();
            t += dt;
            if (live != n) fprintf(stderr, "bench_push: %zu of %zu lanes stopped\n", n - live, n);
        }
        tk[5] = tk[4];
        if (fast) {
            b.flags = GCP_BLOCK_CALLER_CLOCK | GCP_BLOCK_FAST_ARITH;
            const size_t live = gcp_block_advance_fo(&b, f, &gcp_pusher_boris, t, dt, 1, NULL);
            tk[5] = cpu_now();
            t += dt;
            if (live != n) fprintf(stderr, "bench_push: %zu of %zu lanes stopped\n", n - live, n);
        }
        double tl[3] = {0.0, 0.0, 0.0};
        tl[0] = cpu_now();
        for (int k = 0; k < 1 + fast; k++) {
            c.flags = GCP_BLOCK_CALLER_CLOCK | (k ? GCP_BLOCK_FAST_ARITH : 0u);
            for (long j = 0; j < ncall; j++, tc += dt)
                if (gcp_block_advance_fo(&c, f, &gcp_pusher_boris, tc, dt, 1, NULL) != STREAM_NC)
                    fprintf(stderr, "bench_push: lanes stopped in the L2 block\n");
            tl[1 + k] = cpu_now();
        }
        if (rep == 0) continue;
        t_l2[0] = fmin(t_l2[0], tl[1] - tl[0]);
        if (fast) t_l2[1] = fmin(t_l2[1], tl[2] - tl[1]);
        t_fast = fmin(t_fast, tk[5] - tk[4]);
        t_floor = fmin(t_floor, tk[1] - tk[0]);
        t_triad = fmin(t_triad, tk[2] - tk[1]);
        t_push[0] = fmin(t_push[0], tk[3] - tk[2]);
        t_push[1] = fmin(t_push[1], tk[4] - tk[3]);
    }
    const double nn = (double)n;
    printf("  %-16s %9.3f %9.3f %9.3f %9.3f %9.2f %9.2f %9.2f", name[sc], 1e9 * t_floor / nn,
           4e9 * t_triad / nn, 1e9 * t_push[0] / nn, 1e9 * t_push[1] / nn, t_floor / t_push[0],
           t_floor / t_push[1], 4.0 * t_triad / t_push[1]);
    if (fast) printf(" %9.3f %9.2f", 1e9 * t_fast / nn, t_floor / t_fast);
    const double nl = (double)ncall * STREAM_NC;
    printf(" %9.3f %9.2f", 1e9 * t_l2[0] / nl, (t_floor / nn) / (t_l2[0] / nl));
    if (fast) printf(" %9.3f %9.2f", 1e9 * t_l2[1] / nl, (t_floor / nn) / (t_l2[1] / nl));
    printf("\n");
    sink = b.x[n / 2] + b.Bx[n / 3] + c.x[STREAM_NC / 2];
    gcp_block_free(&c);
    gcp_block_free(&b);
    gcp_field_free(f);
}

static void part_stream(void)
{
    const size_t n = (size_t)fmax(1e5, 1e7 * fmin(scale, 1.0));
    const int reps = (int)fmax(3.0, 20.0 * fmin(scale, 1.0));
    printf("Issue 12: streaming, gcp_block_advance_fo (boris) one step per call over %zu "
           "particles,\n  against the memory floor of the same run (x, u read + written in "
           "place, 96 B),\n  best of %d, thread CPU time\n", n, reps);
    printf("  %-16s %9s %9s %9s %9s %9s %9s %9s %9s %9s %9s %9s %9s %9s\n", "", "floor",
           "triad", "push", "push PIC", "push", "push PIC", "push PIC", "PIC fast", "PIC fast",
           "PIC L2", "floor /", "fast L2", "floor /");
    printf("  %-16s %9s %9s %9s %9s %9s %9s %9s %9s %9s %9s %9s %9s %9s\n", "field", "96 B",
           "at 96 B", "", "", "of floor", "of floor", "of triad", "", "of floor", "", "PIC L2",
           "", "fast L2");
    printf("  %-16s %9s %9s %9s %9s %9s %9s %9s %9s %9s %9s %9s %9s %9s\n", "", "[ns]", "[ns]",
           "[ns]", "[ns]", "", "(>=0.80)", "", "[ns]", "(>=0.80)", "[ns]", "", "[ns]", "");
    for (int sc = STREAM_UNIFORM_B; sc <= STREAM_DIPOLE; sc++)
        stream_scene((enum stream_scene)sc, n, reps);
    printf("  (ns per particle; push: the block keeps each lane's t and steps, 24 B a lane more;\n"
           "   push PIC: the caller keeps the clock, GCP_BLOCK_CALLER_CLOCK, x and u only;\n"
           "   PIC fast: the same with arithmetic = fast, GCP_BLOCK_FAST_ARITH, not IEEE rounded;\n"
           "   PIC L2, fast L2: the same calls on %zu of the lanes, in L2: the step's arithmetic\n"
           "   alone; floor / PIC L2: the most push PIC of floor can be, traffic all hidden)\n\n",
           STREAM_NC);
}

/* fo_only: the full-orbit rows alone (a quick look at the Boris push). */
static void limit_rows(int fo_only)
{
    const size_t nbs[] = {1024, 8192};
    for (size_t k = 0; k < 2; k++) {
        printf("limit-row boris-uniform %zu %.3f\n", nbs[k],
               limit_scene(LIMIT_BORIS_UNIFORM, &gcp_pusher_boris, nbs[k], 1e7));
        printf("limit-row boris-dipole %zu %.3f\n", nbs[k],
               limit_scene(LIMIT_BORIS_DIPOLE, &gcp_pusher_boris, nbs[k], 1e7));
        /* the opt-in fast arithmetic ([integrator] arithmetic = fast:
         * AVX-512 rsqrt14/rcp14 + 2 Newton steps, not IEEE rounded) */
        if (gcp_arithmetic_fast_available(&gcp_pusher_boris)) {
            printf("limit-row boris-uniform-fast %zu %.3f\n", nbs[k],
                   limit_scene_arith(LIMIT_BORIS_UNIFORM, &gcp_pusher_boris, nbs[k], 1e7,
                                     1));
            printf("limit-row boris-dipole-fast %zu %.3f\n", nbs[k],
                   limit_scene_arith(LIMIT_BORIS_DIPOLE, &gcp_pusher_boris, nbs[k], 1e7,
                                     1));
        }
        /* boris-nr: kernel (a)'s own method in its scene (E and B), and with
         * E = 0; in the dipole against (b) (relativistic: more work than ours) */
        printf("limit-row nr-uniform %zu %.3f\n", nbs[k],
               limit_scene(LIMIT_BORIS_UNIFORM, &gcp_pusher_boris_nr, nbs[k], 1e7));
        printf("limit-row nr-uniform-B %zu %.3f\n", nbs[k],
               limit_scene(LIMIT_NR_UNIFORM_B, &gcp_pusher_boris_nr, nbs[k], 1e7));
        printf("limit-row nr-dipole %zu %.3f\n", nbs[k],
               limit_scene(LIMIT_BORIS_DIPOLE, &gcp_pusher_boris_nr, nbs[k], 1e7));
        if (!fo_only)
            printf("limit-row gc-rk4-dipole %zu %.3f\n", nbs[k],
                   limit_scene(LIMIT_GC_RK4_DIPOLE, &gcp_pusher_gc_rk4, nbs[k], 1e6));
    }
}

int main(int argc, char **argv)
{
    if (argc > 1 && (strcmp(argv[1], "limit") == 0 || strcmp(argv[1], "limit-fo") == 0)) {
        if (argc > 2) scale = atof(argv[2]);
        if (!(scale > 0.0)) scale = 1.0;
        limit_rows(strcmp(argv[1], "limit-fo") == 0);
        return 0;
    }
    if (argc > 1 && strcmp(argv[1], "stream") == 0) { /* the issue-12 streaming part alone */
        if (argc > 2) scale = atof(argv[2]);
        if (!(scale > 0.0)) scale = 1.0;
        part_stream();
        return 0;
    }
    if (argc > 1 && strcmp(argv[1], "gc") == 0) { /* part 3 alone */
        part_gc();
        return 0;
    }
    if (argc > 1) scale = atof(argv[1]);
    if (!(scale > 0.0)) scale = 1.0;
    printf("gcpush bench: single core, best of %d, wall clock (scale %g)\n\n", REPS, scale);

    /* ---------------- Part 1 ---------------- */
    printf("Issue 2: library block stepper (gcp_block_advance_fo, boris), resident regime\n");
    printf("  %-9s %6s %12s %12s %8s %13s %10s\n", "field", "block", "library", "hand loop",
           "ratio", "lib steps/s", "lib==hand");
    printf("  %-9s %6s %12s %12s %8s %13s %10s\n", "", "lanes", "[ns/step]", "[ns/step]",
           "(<=1.5)", "(>=1e8 unif)", "[rel]");
    const size_t blocks[] = {64, 1024};
    double uni_rate = 0.0;
    for (int sc = UNIFORM; sc <= DIPOLE; sc++)
        for (size_t k = 0; k < 2; k++) {
            const struct p1_result r = part1((enum scene)sc, blocks[k], 100000000);
            if (sc == UNIFORM) uni_rate = fmax(uni_rate, 1e9 / r.ns_lib);
            printf("  %-9s %6zu %12.2f %12.2f %8.2f %13.3g %10.1e\n",
                   sc == UNIFORM ? "uniform" : "dipole", blocks[k], r.ns_lib, r.ns_hand,
                   r.ns_lib / r.ns_hand, 1e9 / r.ns_lib, r.maxdiff);
        }
    printf("  uniform B: %.3g particle-steps/s per core (goal >= 1e8; TestParticle.jl 1.08e8)\n\n",
           uni_rate);
    printf("  where the library's step goes [ns/particle-step], each pass timed alone:\n");
    printf("  %-9s %6s %9s %9s %9s %9s %9s %9s\n", "field", "lanes", "2 drifts", "memset",
           "field", "kick", "classify", "sum");
    for (int sc = UNIFORM; sc <= DIPOLE; sc++) part1_breakdown((enum scene)sc, 1024);
    printf("\n");

    /* ---------------- Part 2: streaming ---------------- */
    const size_t N = (size_t)fmax(1e5, 1e7 * fmin(scale, 1.0));
    struct soa s;
    soa_alloc(&s, N);
    const int sweeps = 3;
    double dt;
    init_particles(UNIFORM, 1, s.x, s.y, s.z, s.ux, s.uy, s.uz, &dt);
    dt *= 1e-3;
    /* AoS copy of the same particles */
    struct gcp_particle_aos *pa = aligned_alloc(64, N * sizeof *pa);
    if (!pa) return 1;
    for (size_t i = 0; i < N; i++)
        pa[i] = (struct gcp_particle_aos){s.x[i], s.y[i], s.z[i], s.ux[i], s.uy[i], s.uz[i]};
    /* Interleaved: every repetition times the triad and each kernel back to
     * back, so a neighbour's load hits all of them alike; best of REPS each.
     * The triad runs over three arrays of N doubles (scratch: a copy of Ez). */
    double *ta = dalloc(N);
    double t_triad = INFINITY, t_kick_only = INFINITY, t_kick = INFINITY, t_hand = INFINITY;
    double t_aos = INFINITY;
    for (int rep = 0; rep < REPS; rep++) {
        double t0 = now();
        for (int k = 0; k < sweeps; k++) triad(N, ta, s.Ex, s.Ey, 1.0 + 1e-9 * k);
        double t1 = now();
        t_triad = fmin(t_triad, (t1 - t0) / sweeps);
        for (int k = 0; k < sweeps; k++) kick_only(&s, dt);
        t0 = now();
        t_kick_only = fmin(t_kick_only, (t0 - t1) / sweeps);
        for (int k = 0; k < sweeps; k++) kernels_step(&s, dt);
        t1 = now();
        t_kick = fmin(t_kick, (t1 - t0) / sweeps);
        for (int k = 0; k < sweeps; k++) hand_step_soa(&s, dt);
        t0 = now();
        t_hand = fmin(t_hand, (t0 - t1) / sweeps);
        for (int k = 0; k < sweeps; k++) aos_step(pa, &s, N, dt);
        t1 = now();
        t_aos = fmin(t_aos, (t1 - t0) / sweeps);
    }
    const double gb_triad = 24.0 * (double)N / t_triad * 1e-9;
    sink = ta[N / 2] + s.x[N / 3];
    free(ta);
    sink = pa[N / 2].x;
    free(pa);
    soa_free(&s);

    printf("Issue 8: kernels.h, streaming regime (%zu particles, one step per particle per sweep)\n",
           N);
    printf("  %-44s %9s %9s %9s %10s\n", "", "bytes", "ns per", "GB/s", "of triad");
    printf("  %-44s %9s %9s %9s %10s\n", "", "/particle", "particle", "", "(>=0.80)");
    const double nN = (double)N;
#define ROW(name, bytes, t)                                                                     \
    printf("  %-44s %9.0f %9.3f %9.2f %10.2f\n", name, (double)(bytes), 1e9 * (t) / nN,     \
           (bytes) * nN / (t) * 1e-9, (bytes) * nN / (t) * 1e-9 / gb_triad)
    ROW("STREAM triad a = b + s c (24 B/element)", 24, t_triad);
    /* kick: read u, E, B (9 doubles), write u (3) */
    ROW("gcp_push_boris_batch", 96, t_kick_only);
    /* + drift: read x, u (6), write x (3) */
    ROW("gcp_push_boris_batch + gcp_drift_batch", 96 + 72, t_kick);
    /* fused: read x, u, E, B (12), write x, u (6) */
    ROW("hand-fused kick + drift", 144, t_hand);
    /* AoS: kick reads/writes the 48-B struct lines and reads E, B; drift again */
    ROW("gcp_push_boris_aos + gcp_drift_aos", 48 + 48 + 48 + 96, t_aos);
#undef ROW
    printf("  (bytes: what each pass must read + write, STREAM convention)\n\n");
    part_stream();

    /* ---------------- Part 2: resident ---------------- */
    printf("Issue 8: kernels.h, resident regime (block in cache, many sweeps)\n");
    printf("  %6s %22s %22s %8s\n", "block", "batch kick+drift", "hand-fused", "ratio");
    printf("  %6s %22s %22s %8s\n", "lanes", "[ns/particle-step]", "[ns/particle-step]",
           "(<=1.1)");
    const size_t rblocks[] = {256, 4096};
    for (size_t k = 0; k < 2; k++) {
        struct soa r;
        soa_alloc(&r, rblocks[k]);
        const int sw = (int)fmax(1.0, scale * 1e8 / (double)rblocks[k]);
        double tk = INFINITY, th = INFINITY;
        for (int rep = 0; rep < REPS; rep++) { /* interleaved, best of REPS */
            double t0 = now();
            for (int k = 0; k < sw; k++) kernels_step(&r, dt);
            double t1 = now();
            for (int k = 0; k < sw; k++) hand_step_soa(&r, dt);
            tk = fmin(tk, (t1 - t0) / sw);
            th = fmin(th, (now() - t1) / sw);
        }
        sink = r.x[0];
        printf("  %6zu %22.3f %22.3f %8.2f\n", rblocks[k], 1e9 * tk / (double)rblocks[k],
               1e9 * th / (double)rblocks[k], tk / th);
        soa_free(&r);
    }
    printf("\n");
    part_gc();
    printf("CUDA: kernels.h on a GPU is tests/bench/cuda.sh's part of make bench.\n");
    return 0;
}
