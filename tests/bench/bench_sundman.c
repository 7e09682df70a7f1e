/* Issue 11: CPU time of gc-gl4-sundman against the best fixed gc-gl4 step
 * for the drift phase, in the dipole (both fused in the field line's
 * coordinates: gc_gauss_dipole.c, gc_sundman_dipole.c).
 *
 * test_gc_sundman.c's drift-phase scene: 1 MeV electrons at L = 4
 * mirroring at 62.9, 75.1 and 82.0 deg; the azimuth at t = 3 T_b against
 * gc-rk8pd at tolerance 1e-13; the fewest steps per bounce (scanned up
 * from 10 by 4%) at which that setting and the next NEXT_OK finer ones
 * all give the phase to 1e-4 / 1e-6 of the drift over the 3 bounces.  At
 * each method's setting a block of 64 such electrons (spread in longitude:
 * the same orbit, the same work per lane) is pushed to 3 T_b, REPS times,
 * alternating the methods; CPU time per particle (median), the steps per
 * particle, CPU time per step, and the ratio fixed / sundman. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "gcpush/field.h"
#include "gcpush/gc.h"
#include "gcpush/particles.h"
#include "gcpush/pusher.h"
#include "test_gc_util.h"

#define NEXT_OK 3
#define NS 200
#define REPS 7
#define NBLK 64

static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

#define orb gc_dip_orbit /* test_gc_util.h */

/* n electrons of the orbit, longitude spread; pushed by p with dt, nsteps;
 * status of lane 0, its azimuth, steps of all lanes; CPU seconds */
static double push(const struct orb *o, const struct gcp_pusher_type *p, double dt, int64_t nsteps,
                   double tol, size_t n, double *phi, int64_t *steps, int *st)
{
    struct gcp_block b;
    if (gcp_block_alloc(&b, n)) exit(1);
    b.q = o->q, b.m = o->m;
    for (size_t i = 0; i < n; i++) {
        const double lon = 2.0 * GCP_PI * (double)i / (double)n;
        b.x[i] = o->X[0] * cos(lon), b.y[i] = o->X[0] * sin(lon), b.z[i] = 0.0;
        b.ppar[i] = o->ppar, b.mu[i] = o->mu, b.status[i] = 0, b.steps[i] = 0, b.t[i] = 0.0;
        b.index[i] = i;
    }
    b.n_active = n;
    const struct gcp_push_opts op = {0.0, dt, nsteps, tol, 0.0};
    const double t0 = cpu_now();
    p->advance(&b, o->f, p, &op, NULL);
    const double cpu = cpu_now() - t0;
    size_t i0 = 0;
    for (size_t i = 0; i < n; i++)
        if (b.index[i] == 0) i0 = i;
    *st = b.status[i0];
    *phi = atan2(b.y[i0], b.x[i0]);
    *steps = 0;
    for (size_t i = 0; i < n; i++) *steps += b.steps[i];
    gcp_block_free(&b);
    return cpu;
}

/* the fewest steps per bounce N (test_gc_sundman.c sd_fewest_phase) */
static void fewest(const struct orb *o, const struct gcp_pusher_type *p, double phi_ref,
                   const double *err, int nerr, double *Nbest)
{
    double e[NS], Ns[NS];
    int m = 0;
    for (double N = 10.0; N <= 2000.0 && m < NS; N *= 1.04, m++) {
        const int64_t nsteps = (int64_t)(3.0 * N);
        double phi;
        int64_t st;
        int s;
        Ns[m] = N, e[m] = INFINITY;
        push(o, p, 3.0 * o->Tb / (double)nsteps, nsteps, 0.0, 1, &phi, &st, &s);
        if (!s) e[m] = fabs(remainder(phi - phi_ref, 2.0 * GCP_PI));
    }
    for (int j = 0; j < nerr; j++) {
        Nbest[j] = NAN;
        for (int i = 0; i + NEXT_OK < m && isnan(Nbest[j]); i++) {
            int ok = 1;
            for (int d = 0; d <= NEXT_OK; d++) ok &= e[i + d] <= err[j];
            if (ok) Nbest[j] = Ns[i];
        }
    }
}

static int cmp(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(void)
{
    const double lat_deg[3] = {62.9, 75.1, 82.0}, rel[2] = {1e-4, 1e-6};
    const struct gcp_pusher_type *P[2] = {&gcp_pusher_gc_gl4, &gcp_pusher_gc_gl4_sundman};
    printf("Issue 11: drift phase at 3 T_b, 1 MeV e- at L = 4, block of %d, CPU time (median of "
           "%d, alternating)\n", NBLK, REPS);
    printf("  %-6s %-6s %-15s %8s %10s %12s %10s %8s\n", "mirror", "phase", "method", "N/bounce",
           "steps/p", "us/particle", "us/step", "fixed/sd");
    for (int o = 0; o < 3; o++) {
        struct orb O;
        if (gc_dip_electron(&O, GC_PITCH_OF_MIRROR(lat_deg[o]))) return 1;
        double phi_ref;
        int64_t st;
        int s;
        push(&O, &gcp_pusher_gc_rk8pd, 3.0 * O.Tb, 1, 1e-13, 1, &phi_ref, &st, &s);
        const double dphi = 2.0 * GCP_PI * 3.0 * O.Tb / O.Td;
        const double err[2] = {rel[0] * dphi, rel[1] * dphi};
        double Nb[2][2];
        for (int k = 0; k < 2; k++) fewest(&O, P[k], phi_ref, err, 2, Nb[k]);
        for (int j = 0; j < 2; j++) {
            double cpu[2][REPS], med[2];
            int64_t steps[2] = {0, 0};
            for (int r = 0; r < REPS; r++)
                for (int k = 0; k < 2; k++) {
                    const int64_t nsteps = (int64_t)(3.0 * Nb[k][j]);
                    double phi;
                    cpu[k][r] = push(&O, P[k], 3.0 * O.Tb / (double)nsteps, nsteps, 0.0, NBLK, &phi,
                                     &steps[k], &s);
                }
            for (int k = 0; k < 2; k++) {
                qsort(cpu[k], REPS, sizeof(double), cmp);
                med[k] = cpu[k][REPS / 2];
            }
            for (int k = 0; k < 2; k++)
                printf("  %-6.1f %-6.0e %-15s %8.0f %10.0f %12.1f %10.3f %8s\n", O.latm * 180 / GCP_PI,
                       rel[j], P[k]->name, Nb[k][j], (double)steps[k] / NBLK, 1e6 * med[k] / NBLK,
                       1e6 * med[k] / (double)steps[k], k ? "" : "");
            printf("  %-6s %-6s %-15s %8s %10.2f %12.2f %10.2f   (fixed / sundman: steps, CPU, "
                   "CPU per step)\n", "", "", "ratio", "", (double)steps[0] / (double)steps[1],
                   med[0] / med[1], (med[0] / (double)steps[0]) / (med[1] / (double)steps[1]));
        }
        gcp_field_free(O.f);
    }
    return 0;
}
