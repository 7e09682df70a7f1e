/* bench_floor -- `make bench`, issue 12: the part of a relativistic Boris
 * step in the dipole that no reordering removes while the arithmetic stays
 * IEEE (correctly rounded sqrt and division, the build's rule: DESIGN.md,
 * "Arithmetic").
 *
 * The fused step (src/pushers/fo_fused_priv.h with kernels.h's
 * gcp_push_boris_B_ig and field_kernels.h's gcp_point_B_dipole) makes, per
 * lane and step, two square roots and four divisions:
 *   r = sqrt(r^2)            c5 = c / (r^2 r^2 r)          (the dipole's B)
 *   1 / gamma-               s = 2 / (1 + t^2)             (the rotation)
 *   gamma+ = sqrt(1 + u^2)   hg = (dt/2) / gamma+          (the drift)
 * Double divisions and square roots issue to a divide/sqrt unit with a
 * small fraction of the multipliers' throughput, so these six, not the ~90
 * multiplications and additions around them, set a floor.  This loop makes the same six
 * operations per lane with the step's dependencies (each needs the one
 * before, as in the step) and ten multiplications and additions to feed
 * them, over 8192 lanes resident in L1/L2 as the push bench's block: its
 * time per lane is the floor of the step, measured in the same run as the
 * limit's kernel (b), whose reciprocal square roots are approximate
 * (vrsqrt14 and Newton steps: not correctly rounded, not the same bits on
 * another machine or a GPU).
 *
 * Prints one row, "floor-row boris-dipole-ieee <lanes> <ns>", read by
 * vs_limit.sh. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#define LANES 8192
#define REPS 5

static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double r2v[LANES], gv[LANES], uv[LANES];

/* One "step" of the six operations per lane.  The values stay O(1) (r^2 ~
 * 16, gamma ~ 1.001) so no lane reaches a subnormal or special case (the
 * unit's slow paths would make the floor look higher than it is). */
static void floor_step(size_t n, double c, double h)
{
    for (size_t i = 0; i < n; i++) {
        const double r2 = r2v[i];
        const double r = sqrt(r2);
        const double c5 = c / (r2 * r2 * r);
        const double ig = 1.0 / gv[i];
        const double t = c5 * ig;
        const double s = 2.0 / (1.0 + t * t);
        const double u = uv[i] * s;
        const double g1 = sqrt(1.0 + u * u);
        const double hg = h / g1;
        /* feed back so the loop is not hoisted: +/- 1e-300-sized changes */
        r2v[i] = r2 + hg * 1e-300;
        gv[i] = g1;
        uv[i] = 0.5 * u + 0.025;
    }
}

int main(int argc, char **argv)
{
    const long steps = argc > 1 ? atol(argv[1]) : 2000;
    for (size_t i = 0; i < LANES; i++) {
        r2v[i] = 12.0 + 8.0 * (double)i / LANES;
        gv[i] = 1.001;
        uv[i] = 0.05;
    }
    double best = INFINITY;
    for (int r = 0; r < REPS; r++) {
        const double t0 = cpu_now();
        for (long s = 0; s < steps; s++) floor_step(LANES, 0.3, 1e-3);
        best = fmin(best, cpu_now() - t0);
    }
    double sum = 0.0;
    for (size_t i = 0; i < LANES; i++) sum += gv[i];
    if (!(sum > 0.0)) return 1; /* keeps the results live */
    printf("floor-row boris-dipole-ieee %d %.3f\n", LANES, 1e9 * best / ((double)steps * LANES));
    return 0;
}
