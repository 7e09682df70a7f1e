/* leave_out -- the bare pusher on a scene's particles: the same initial
 * states, blocks of GCP_CHUNK lanes, step and step count as gcpush, but
 * nothing around the push (no results, no output).  Prints the CPU seconds
 * of the pushing (CLOCK_PROCESS_CPUTIME_ID), best of 3.
 *   usage: leave_out FILE.run        (used by tests/bench/leave_out.sh) */
#include <stdio.h>
#include <string.h>
#include <time.h>

#include <mpi.h>

#include "gcpush/run.h"

static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int main(int argc, char **argv)
{
    MPI_Init(&argc, &argv);
    struct gcp_error err = {0};
    struct gcp_scene *sc;
    if (argc != 2 || gcp_scene_load(argv[1], &sc, &err)) {
        fprintf(stderr, "leave_out: %s\n", argc != 2 ? "usage: leave_out FILE.run" : err.msg);
        MPI_Finalize();
        return 2;
    }
    struct gcp_block b;
    gcp_block_alloc(&b, GCP_CHUNK);
    double best = 1e300;
    for (int rep = 0; rep < 3; rep++) {
        double spent = 0.0;
        for (int64_t c = 0; c < gcp_scene_chunk_count(sc); c++) {
            int64_t first, count;
            gcp_scene_chunk(sc, c, &first, &count);
            int pop = 0;
            for (int64_t i = 0; i < count; i++) {
                double x[3], u[3];
                gcp_scene_initial_state(sc, first + i, &pop, x, u);
                b.x[i] = x[0], b.y[i] = x[1], b.z[i] = x[2];
                b.ux[i] = u[0], b.uy[i] = u[1], b.uz[i] = u[2];
                b.index[i] = (size_t)i, b.status[i] = 0, b.steps[i] = 0, b.t[i] = 0;
            }
            b.n = b.n_active = (size_t)count;
            b.q = sc->pops[pop].species.charge;
            b.m = sc->pops[pop].species.mass;
            const double c0 = cpu_now();
            gcp_block_start(&b, sc->field, 0.0);
            gcp_block_advance_fo(&b, sc->field, sc->pusher, 0.0, sc->pops[pop].dt,
                                 sc->pops[pop].nsteps, NULL);
            spent += cpu_now() - c0;
        }
        if (spent < best) best = spent;
    }
    printf("%.6f\n", best);
    gcp_block_free(&b);
    gcp_scene_free(sc);
    MPI_Finalize();
    return 0;
}
