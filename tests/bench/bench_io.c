/* HDF5 output rate: the library's collective writer (gcp_output_write, with
 * its chunked + shuffle/deflate trajectories) against writing the same bytes
 * with plain fwrite, on every rank of MPI_COMM_WORLD (run it with mpirun -np
 * 1 and 2).  Synthetic smooth orbits (gyration plus drift), so compression
 * sees data like a real run's.  Rates in MB/s of uncompressed payload. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include <mpi.h>

#include "gcpush/io.h"
#include "gcpush/run.h"

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int main(int argc, char **argv)
{
    MPI_Init(&argc, &argv);
    int me, nr;
    MPI_Comm_rank(MPI_COMM_WORLD, &me);
    MPI_Comm_size(MPI_COMM_WORLD, &nr);
    const long N = argc > 1 ? atol(argv[1]) : 2000, S = argc > 2 ? atol(argv[2]) : 1000;
    char text[1024];
    snprintf(text, sizeof text,
             "[scene]\nname = io\nfield = uniform\nduration = 1 s\n[field]\nB = 0 0 1 T\n"
             "[particles]\nspecies = proton\ncount = %ld\nenergy = 1 keV\nposition = 0 0 0 m\n"
             "direction = 1 0 0\n[integrator]\nmethod = boris\ndt = 0.001 s\n[output]\n"
             "file = /tmp/gcp_bench_io.h5\ntrajectory = %ld samples\ncompression = %s\n", N, S,
             argc > 3 ? argv[3] : "1");
    struct gcp_error err = {0};
    struct gcp_scene *sc;
    if (gcp_scene_parse("bench.run", text, &sc, &err)) {
        fprintf(stderr, "%s\n", err.msg);
        MPI_Abort(MPI_COMM_WORLD, 1);
    }
    struct gcp_results r;
    gcp_results_init(&r, sc->trajectory_samples, 0);
    const int64_t S1 = r.S;
    /* this rank's share: a contiguous slice of ids */
    const int64_t lo = N * me / nr, hi = N * (me + 1) / nr;
    gcp_results_reserve(&r, hi - lo);
    for (int64_t i = lo; i < hi; i++) {
        const int64_t k = i - lo;
        r.id[k] = i, r.pop[k] = 0, r.status[k] = 0, r.steps[k] = 1000, r.cpu[k] = 0, r.t[k] = 1;
        for (int d = 0; d < 3; d++) r.x0[3 * k + d] = r.u0[3 * k + d] = r.x[3 * k + d] = r.u[3 * k + d] = d;
        r.traj_count[k] = S1;
        for (int64_t j = 0; j < S1; j++) {
            const double t = 1e-3 * (double)j, ph = 2.0 * 3.14159 * t * (1.0 + 1e-3 * (double)i);
            const size_t q = (size_t)(k * S1 + j);
            r.traj_t[q] = t;
            r.traj_x[3 * q] = 0.01 * cos(ph) + 1e-3 * t, r.traj_x[3 * q + 1] = 0.01 * sin(ph);
            r.traj_x[3 * q + 2] = 0.1 * t;
            r.traj_u[3 * q] = -4e5 * sin(ph), r.traj_u[3 * q + 1] = 4e5 * cos(ph);
            r.traj_u[3 * q + 2] = 1e4;
        }
    }
    r.n = hi - lo;
    const double traj_bytes = (double)N * (double)S1 * 7.0 * 8.0;

    MPI_Barrier(MPI_COMM_WORLD);
    double t0 = now();
    if (gcp_output_write(sc, &r, MPI_COMM_WORLD, &err)) {
        if (me == 0) fprintf(stderr, "%s\n", err.msg);
        MPI_Abort(MPI_COMM_WORLD, 1);
    }
    MPI_Barrier(MPI_COMM_WORLD);
    const double t_h5 = now() - t0;

    /* the same trajectory payload with fwrite, one file per rank */
    char path[64];
    snprintf(path, sizeof path, "/tmp/gcp_bench_io.%d.bin", me);
    MPI_Barrier(MPI_COMM_WORLD);
    t0 = now();
    FILE *fp = fopen(path, "wb");
    fwrite(r.traj_t, sizeof(double), (size_t)(r.n * S1), fp);
    fwrite(r.traj_x, sizeof(double), (size_t)(3 * r.n * S1), fp);
    fwrite(r.traj_u, sizeof(double), (size_t)(3 * r.n * S1), fp);
    fclose(fp);
    MPI_Barrier(MPI_COMM_WORLD);
    const double t_fw = now() - t0;
    remove(path);
    if (me == 0) {
        FILE *f = fopen(sc->output, "rb");
        fseek(f, 0, SEEK_END);
        const double fsize = (double)ftell(f);
        fclose(f);
        printf("  %d rank(s), %ld particles x %lld samples: %.0f MB of trajectories, compression %s\n",
               nr, N, (long long)S1, traj_bytes / 1e6, argc > 3 ? argv[3] : "1");
        printf("    gcp_output_write (whole file, compressed to %.0f MB): %7.1f MB/s\n",
               fsize / 1e6, traj_bytes / 1e6 / t_h5);
        printf("    fwrite of the same trajectory bytes:                 %7.1f MB/s   ratio %.2f\n",
               traj_bytes / 1e6 / t_fw, t_fw / t_h5);
        remove(sc->output);
    }
    gcp_results_free(&r);
    gcp_scene_free(sc);
    MPI_Finalize();
    return 0;
}
