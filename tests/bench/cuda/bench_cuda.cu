/* bench_cuda.cu -- gcpush's header-only kernels (include/gcpush/kernels.h)
 * under CUDA: particle-steps/s of the relativistic Boris push and of gc-rk4
 * in Earth's dipole on the GPU, against the same source compiled for the
 * host CPU (one core) on the same machine, and a check that both give the
 * same trajectories.
 *
 * What runs on the device is what a PIC code embedding kernels.h would run:
 * one thread per particle, the state in registers for a whole launch of
 * many steps, the kick gcp_push_boris_B and the right-hand side gcp_gc_rhs
 * from kernels.h unchanged (GCP_HD makes them __host__ __device__).  The
 * dipole's B is the kernel layer's gcp_point_B_dipole (field_kernels.h,
 * bit-identical to fields/dipole.c); its grad-B tensor for the guiding
 * centre is written here operation for operation as fields/dipole.c's.
 *
 * Scenes: those of ../shared/limit kernels (b) and (c) and of
 * tests/bench/bench_push.c `limit`: 1 MeV protons on the equator at
 * L = 3.5 .. 4.5, equatorial pitch 30 .. 80 deg.  Boris: synchronised
 * drift-kick-drift (as src/pushers/fo_step.c), Omega_eq(L=4) dt = 0.05.
 * gc-rk4: classical RK4 on (X, p_par), dt = T_b(L=4, 45 deg)/1000.
 *
 * Agreement: with --fmad=false (the Makefile's choice, as the library keeps
 * -ffp-contract=off) every operation is an IEEE double operation on both
 * sides (CUDA's double sqrt and division are correctly rounded), so device
 * and host trajectories are expected bit-identical; the check prints the
 * largest relative difference of the final positions.
 *
 * Usage: bench_cuda [n_particles [seconds_per_figure]]
 * Output rows start with "cuda-"; tests/bench/cuda.sh prints them. */
#include <cuda_runtime.h>

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "gcpush/field_kernels.h"
#include "gcpush/kernels.h"

#define RE 6.3712e6          /* R_E [m], as gcpush/units.h GCP_EARTH_RADIUS */
#define B0 3.12e-5           /* equatorial surface field [T], GCP_EARTH_B0 */
#define QP 1.602176634e-19   /* proton charge [C] */
#define MP 1.67262192369e-27 /* proton mass [kg] */
#define PI 3.14159265358979323846

#define CK(call)                                                                            \
    do {                                                                                    \
        cudaError_t e_ = (call);                                                            \
        if (e_ != cudaSuccess) {                                                            \
            fprintf(stderr, "bench_cuda: %s: %s\n", #call, cudaGetErrorString(e_));         \
            exit(2);                                                                        \
        }                                                                                   \
    } while (0)

/* ---- the dipole: the kernel layer's closed forms (gcpush/field_kernels.h) ------- */

/* B: the kernel layer's closed-form dipole (gcpush/field_kernels.h), the
 * one gcpush's fused CPU loop uses. */
static __forceinline__ GCP_HD void dip_B(double c, double x, double y, double z, double B[3])
{
    gcp_point_B_dipole(c, x, y, z, &B[0], &B[1], &B[2]);
}

/* ---- one particle, many steps ------------------------------------------------ */

/* Synchronised drift-kick-drift Boris (src/pushers/fo_step.c):
 *   x += u (dt/2)/gamma,  u -> Boris kick with B(x),  x += u' (dt/2)/gamma'. */
static __forceinline__ GCP_HD void boris_steps(double s[6], double c, double q, double m, double dt,
                                      long nsteps)
{
    double x = s[0], y = s[1], z = s[2], ux = s[3], uy = s[4], uz = s[5];
    const double h = 0.5 * dt;
    double hg = h / gcp_gamma_of_u(ux, uy, uz);
    for (long k = 0; k < nsteps; k++) {
        x += ux * hg, y += uy * hg, z += uz * hg;
        double B[3];
        dip_B(c, x, y, z, B);
        gcp_push_boris_B(&ux, &uy, &uz, B[0], B[1], B[2], q, m, dt);
        hg = h / gcp_gamma_of_u(ux, uy, uz);
        x += ux * hg, y += uy * hg, z += uz * hg;
    }
    s[0] = x, s[1] = y, s[2] = z, s[3] = ux, s[4] = uy, s[5] = uz;
}

static __forceinline__ GCP_HD void gc_f(double c, const double y[4], double mu, double q, double m,
                               double k[4])
{
    double B[3], G[3][3];
    gcp_point_BG_dipole(c, y[0], y[1], y[2], B, G); /* B, grad B as fields/dipole.c */
    gcp_gc_rhs(B, G, NULL, y[3], mu, q, m, k, &k[3]);
}

/* Classical RK4 on y = (X, p_par), mu fixed (src/pushers/gc_rk4.c). */
static __forceinline__ GCP_HD void gc_rk4_steps(double s[4], double mu, double c, double q, double m,
                                       double dt, long nsteps)
{
    double y[4] = {s[0], s[1], s[2], s[3]};
    for (long n = 0; n < nsteps; n++) {
        double k[4], a[4], t[4];
        gc_f(c, y, mu, q, m, k);
        for (int j = 0; j < 4; j++) a[j] = k[j], t[j] = y[j] + 0.5 * dt * k[j];
        gc_f(c, t, mu, q, m, k);
        for (int j = 0; j < 4; j++) a[j] += 2.0 * k[j], t[j] = y[j] + 0.5 * dt * k[j];
        gc_f(c, t, mu, q, m, k);
        for (int j = 0; j < 4; j++) a[j] += 2.0 * k[j], t[j] = y[j] + dt * k[j];
        gc_f(c, t, mu, q, m, k);
        for (int j = 0; j < 4; j++) y[j] += dt / 6.0 * (a[j] + k[j]);
    }
    for (int j = 0; j < 4; j++) s[j] = y[j];
}

/* ---- device kernels: one thread per particle, SoA in global memory ---------- */
__global__ void boris_kernel(int n, double *x, double *y, double *z, double *ux, double *uy,
                             double *uz, double c, double q, double m, double dt, long nsteps)
{
    const int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    double s[6] = {x[i], y[i], z[i], ux[i], uy[i], uz[i]};
    boris_steps(s, c, q, m, dt, nsteps);
    x[i] = s[0], y[i] = s[1], z[i] = s[2], ux[i] = s[3], uy[i] = s[4], uz[i] = s[5];
}

__global__ void gc_rk4_kernel(int n, double *x, double *y, double *z, double *pp,
                              const double *mu, double c, double q, double m, double dt,
                              long nsteps)
{
    const int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    double s[4] = {x[i], y[i], z[i], pp[i]};
    gc_rk4_steps(s, mu[i], c, q, m, dt, nsteps);
    x[i] = s[0], y[i] = s[1], z[i] = s[2], pp[i] = s[3];
}

/* ---- scene --------------------------------------------------------------------- */
static uint64_t rng_state;
static double urand(void)
{
    rng_state = rng_state * 6364136223846793005ull + 1442695040888963407ull;
    return (double)(rng_state >> 11) * (1.0 / 9007199254740992.0);
}

struct scene {
    int n;
    double *a[7]; /* x y z ux uy uz (Boris) or x y z ppar mu (GC), host */
    double dt;
};

static void scene_init(struct scene *S, int n, int gc)
{
    rng_state = 0x13198A2E03707344ull;
    const double ek = 1.602176634e-13, mc2 = MP * GCP_C_LIGHT * GCP_C_LIGHT;
    const double g = 1.0 + ek / mc2, p = MP * GCP_C_LIGHT * sqrt(g * g - 1.0);
    S->n = n;
    for (int k = 0; k < 7; k++) S->a[k] = (double *)malloc((size_t)n * sizeof(double));
    for (int i = 0; i < n; i++) {
        const double L = 3.5 + urand(), lon = 2.0 * PI * urand();
        const double al = (30.0 + 50.0 * urand()) * PI / 180.0, ph = 2.0 * PI * urand();
        S->a[0][i] = L * RE * cos(lon), S->a[1][i] = L * RE * sin(lon), S->a[2][i] = 0.0;
        const double Beq = B0 / (L * L * L);
        if (gc) {
            S->a[3][i] = p * cos(al);
            S->a[4][i] = (p * sin(al)) * (p * sin(al)) / (2.0 * MP * Beq);
        } else {
            const double u = p / MP;
            S->a[3][i] = u * sin(al) * cos(ph), S->a[4][i] = u * sin(al) * sin(ph);
            S->a[5][i] = u * cos(al);
        }
    }
    const double v = p / (g * MP), L4 = 4.0 * RE;
    S->dt = gc ? 4.0 * L4 / v * (1.30 - 0.56 * sin(PI / 4.0)) / 1000.0
               : 0.05 * g * MP / (QP * B0 / 64.0);
}

static void scene_free(struct scene *S)
{
    for (int k = 0; k < 7; k++) free(S->a[k]);
}

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Host figure: the same step functions on one core, the particles of a
 * chunk stepped together (step loop outside, particle loop inside, the
 * state in struct-of-arrays) so that the compiler can vectorise across
 * particles as gcpush's CPU engine does; one particle at a time would be
 * bound by the latency of its sqrt/division chain instead. */
#define HOST_CHUNK 64
static double host_rate(struct scene *S, int gc, int nh, long nsteps)
{
    const double c = B0 * RE * RE * RE;
    const double t0 = now();
    for (int i0 = 0; i0 < nh; i0 += HOST_CHUNK) {
        const int m = nh - i0 < HOST_CHUNK ? nh - i0 : HOST_CHUNK;
        double st[6][HOST_CHUNK], mu[HOST_CHUNK];
        for (int j = 0; j < (gc ? 4 : 6); j++)
            for (int i = 0; i < m; i++) st[j][i] = S->a[j][i0 + i];
        for (int i = 0; i < m; i++) mu[i] = gc ? S->a[4][i0 + i] : 0.0;
        for (long k = 0; k < nsteps; k++) {
            if (gc) {
                for (int i = 0; i < m; i++) {
                    double s[4] = {st[0][i], st[1][i], st[2][i], st[3][i]};
                    gc_rk4_steps(s, mu[i], c, QP, MP, S->dt, 1);
                    st[0][i] = s[0], st[1][i] = s[1], st[2][i] = s[2], st[3][i] = s[3];
                }
            } else {
                for (int i = 0; i < m; i++) {
                    double s[6] = {st[0][i], st[1][i], st[2][i], st[3][i], st[4][i], st[5][i]};
                    boris_steps(s, c, QP, MP, S->dt, 1);
                    for (int j = 0; j < 6; j++) st[j][i] = s[j];
                }
            }
        }
        for (int j = 0; j < (gc ? 4 : 6); j++)
            for (int i = 0; i < m; i++) S->a[j][i0 + i] = st[j][i];
    }
    return (double)nh * (double)nsteps / (now() - t0);
}

/* Device figure: nsteps per launch, best of reps launches (the state moves
 * on between launches, as a run would). */
static double device_rate(struct scene *S, int gc, long nsteps, int reps, double **dev)
{
    const int n = S->n, nv = gc ? 5 : 6;
    const double c = B0 * RE * RE * RE;
    for (int k = 0; k < nv; k++) {
        CK(cudaMalloc((void **)&dev[k], (size_t)n * sizeof(double)));
        CK(cudaMemcpy(dev[k], S->a[k], (size_t)n * sizeof(double), cudaMemcpyHostToDevice));
    }
    const int tpb = 128, nb = (n + tpb - 1) / tpb;
    cudaEvent_t e0, e1;
    CK(cudaEventCreate(&e0));
    CK(cudaEventCreate(&e1));
    float best = 1e30f;
    for (int r = 0; r < reps; r++) {
        CK(cudaEventRecord(e0));
        if (gc)
            gc_rk4_kernel<<<nb, tpb>>>(n, dev[0], dev[1], dev[2], dev[3], dev[4], c, QP, MP,
                                       S->dt, nsteps);
        else
            boris_kernel<<<nb, tpb>>>(n, dev[0], dev[1], dev[2], dev[3], dev[4], dev[5], c, QP,
                                      MP, S->dt, nsteps);
        CK(cudaGetLastError());
        CK(cudaEventRecord(e1));
        CK(cudaEventSynchronize(e1));
        float ms;
        CK(cudaEventElapsedTime(&ms, e0, e1));
        if (ms < best) best = ms;
    }
    CK(cudaEventDestroy(e0));
    CK(cudaEventDestroy(e1));
    return (double)n * (double)nsteps / (1e-3 * best);
}

/* Same start, nsteps on the device and on the host for the first nh
 * particles: the largest |x_dev - x_host| / |x_host| of the positions. */
static double agreement(int gc, int n, int nh, long nsteps)
{
    struct scene D, H;
    scene_init(&D, n, gc);
    scene_init(&H, nh, gc);
    double *dev[7] = {0};
    const int nv = gc ? 5 : 6;
    const double c = B0 * RE * RE * RE;
    for (int k = 0; k < nv; k++) {
        CK(cudaMalloc((void **)&dev[k], (size_t)n * sizeof(double)));
        CK(cudaMemcpy(dev[k], D.a[k], (size_t)n * sizeof(double), cudaMemcpyHostToDevice));
    }
    const int tpb = 128, nb = (n + tpb - 1) / tpb;
    if (gc)
        gc_rk4_kernel<<<nb, tpb>>>(n, dev[0], dev[1], dev[2], dev[3], dev[4], c, QP, MP, D.dt,
                                   nsteps);
    else
        boris_kernel<<<nb, tpb>>>(n, dev[0], dev[1], dev[2], dev[3], dev[4], dev[5], c, QP, MP,
                                  D.dt, nsteps);
    CK(cudaGetLastError());
    CK(cudaDeviceSynchronize());
    for (int k = 0; k < 3; k++)
        CK(cudaMemcpy(D.a[k], dev[k], (size_t)nh * sizeof(double), cudaMemcpyDeviceToHost));
    host_rate(&H, gc, nh, nsteps);
    double worst = 0.0;
    for (int i = 0; i < nh; i++) {
        const double dx = D.a[0][i] - H.a[0][i], dy = D.a[1][i] - H.a[1][i],
                     dz = D.a[2][i] - H.a[2][i];
        const double r = sqrt(H.a[0][i] * H.a[0][i] + H.a[1][i] * H.a[1][i] +
                              H.a[2][i] * H.a[2][i]);
        const double e = sqrt(dx * dx + dy * dy + dz * dz) / r;
        if (!(e <= worst)) worst = e; /* NaN propagates as the worst */
    }
    for (int k = 0; k < nv; k++) CK(cudaFree(dev[k]));
    scene_free(&D);
    scene_free(&H);
    return worst;
}

int main(int argc, char **argv)
{
    const int n = argc > 1 ? atoi(argv[1]) : 1 << 20;
    const double secs = argc > 2 ? atof(argv[2]) : 0.3;
    int ndev = 0;
    if (cudaGetDeviceCount(&ndev) != cudaSuccess || ndev == 0) {
        printf("cuda-none no CUDA device here\n");
        return 0;
    }
    cudaDeviceProp prop;
    CK(cudaGetDeviceProperties(&prop, 0));
    printf("cuda-device %s, %d SMs, CUDA %d.%d capability\n", prop.name,
           prop.multiProcessorCount, prop.major, prop.minor);
    printf("cuda-header push n_particles gpu[steps/s] cpu1[steps/s] gpu/cpu1 "
           "gpu_vs_cpu_rel_diff\n");
    const char *names[2] = {"boris-dipole", "gc-rk4-dipole"};
    for (int gc = 0; gc < 2; gc++) {
        /* Host: enough particle-steps for ~secs/3 on one core (4e7 Boris,
         * 4e6 RK4 steps a second here, roughly). */
        struct scene H;
        const int nh = 256;
        scene_init(&H, nh, gc);
        const long hsteps = gc ? 2000 : 20000;
        host_rate(&H, gc, 8, hsteps / 10); /* warm-up */
        const double cpu = host_rate(&H, gc, nh, hsteps);
        scene_free(&H);
        /* Device: one short launch to size the steps per launch. */
        struct scene S;
        scene_init(&S, n, gc);
        double *dev[7] = {0};
        const double probe = device_rate(&S, gc, gc ? 20 : 200, 2, dev);
        for (int k = 0; k < 7; k++)
            if (dev[k]) {
                CK(cudaFree(dev[k]));
                dev[k] = NULL;
            }
        long steps = (long)(secs * probe / (double)n);
        if (steps < 10) steps = 10;
        const double gpu = device_rate(&S, gc, steps, 5, dev);
        for (int k = 0; k < 7; k++)
            if (dev[k]) CK(cudaFree(dev[k]));
        scene_free(&S);
        const double diff = agreement(gc, 4096, 256, gc ? 1000 : 10000);
        printf("cuda-row %s %d %.4g %.4g %.1f %.2g\n", names[gc], n, gpu, cpu, gpu / cpu, diff);
    }
    return 0;
}
