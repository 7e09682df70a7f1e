/* gcpush -- command line.
 *
 *   gcpush FILE.run            run the scene, write its HDF5 output
 *   gcpush --check FILE.run    validate the run file, run nothing
 *   gcpush --help | --version
 *
 * Same binary with and without mpirun.  Exit status: 0 success, 1 a run
 * that failed (I/O), 2 bad usage or a bad run file.  Messages come from rank
 * 0 only, one line each, naming file, line and key. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <mpi.h>

#include "gcpush/io.h"
#include "gcpush/run.h"
#include "par/par.h"

#ifndef GCP_VERSION
#define GCP_VERSION "unknown"
#endif
#ifndef GCP_GIT_HASH
#define GCP_GIT_HASH "unknown"
#endif

static void usage(FILE *to)
{
    fprintf(to,
            "usage: gcpush [--quiet] FILE.run     run a scene, write its HDF5 output\n"
            "       gcpush --check FILE.run       validate a run file without running it\n"
            "       gcpush --help | --version\n"
            "under MPI: mpirun -np N gcpush FILE.run (one output file, same result for any N)\n\n");
    fprintf(to, "fields:");
    for (const struct gcp_field_type *const *f = gcp_field_types(); *f; f++)
        fprintf(to, "\n  %-14s %s", (*f)->name, (*f)->doc);
    fprintf(to, "\nmethods:");
    for (const struct gcp_pusher_type *const *p = gcp_pusher_types(); *p; p++)
        fprintf(to, "\n  %-14s %s", (*p)->name, (*p)->doc);
    fprintf(to, "\n");
}

static double wall_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void summary(const struct gcp_scene *sc, const struct gcp_results *r, MPI_Comm comm,
                    int me, double wall)
{
    int64_t counts[GCP_STATUS_COUNT] = {0}, steps = 0;
    for (int64_t k = 0; k < r->n; k++) {
        if (r->status[k] >= 0 && r->status[k] < GCP_STATUS_COUNT) counts[r->status[k]]++;
        steps += r->steps[k];
    }
    MPI_Reduce(me ? counts : MPI_IN_PLACE, counts, GCP_STATUS_COUNT, MPI_INT64_T, MPI_SUM, 0, comm);
    MPI_Reduce(me ? &steps : MPI_IN_PLACE, &steps, 1, MPI_INT64_T, MPI_SUM, 0, comm);
    if (me) return;
    printf("%s: %lld particles, %.6g s (%s in %s), %.3g particle-steps/s\n", sc->name,
           (long long)sc->total, sc->duration, sc->pusher->name, sc->field_model,
           wall > 0 ? (double)steps / wall : 0.0);
    for (int s = 0; s < GCP_STATUS_COUNT; s++)
        if (counts[s]) printf("  %-13s %lld\n", gcp_status_name(s), (long long)counts[s]);
    printf("output: %s\n", sc->output);
}

int main(int argc, char **argv)
{
    MPI_Init(&argc, &argv);
    MPI_Comm comm = MPI_COMM_WORLD;
    int me, nranks;
    MPI_Comm_rank(comm, &me);
    MPI_Comm_size(comm, &nranks);

    int check = 0, quiet = 0, rc = 0;
    const char *path = NULL;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
            if (me == 0) usage(stdout);
            MPI_Finalize();
            return 0;
        } else if (strcmp(argv[i], "--version") == 0) {
            if (me == 0) printf("gcpush %s (%s)\n", GCP_VERSION, GCP_GIT_HASH);
            MPI_Finalize();
            return 0;
        } else if (strcmp(argv[i], "--check") == 0) {
            check = 1;
        } else if (strcmp(argv[i], "--quiet") == 0) {
            quiet = 1;
        } else if (argv[i][0] == '-' || path) {
            if (me == 0) {
                fprintf(stderr, "gcpush: unexpected argument '%s'\n", argv[i]);
                usage(stderr);
            }
            MPI_Finalize();
            return 2;
        } else {
            path = argv[i];
        }
    }
    if (!path) {
        if (me == 0) usage(stderr);
        MPI_Finalize();
        return 2;
    }

    struct gcp_error err = {0};
    struct gcp_scene *sc = NULL;
    rc = gcp_scene_load(path, &sc, &err);
    /* Every rank read the same file; agree on the outcome so no rank hangs. */
    int bad = rc != 0;
    MPI_Allreduce(MPI_IN_PLACE, &bad, 1, MPI_INT, MPI_MAX, comm);
    if (bad) {
        if (me == 0) fprintf(stderr, "gcpush: %s\n", rc ? err.msg : "a rank failed to read the run file");
        gcp_scene_free(sc);
        MPI_Finalize();
        return 2;
    }
    if (check) {
        if (me == 0 && !quiet) {
            printf("%s: ok: %lld particles, %s in %s for %.6g s\n", path, (long long)sc->total,
                   sc->pusher->name, sc->field_model, sc->duration);
            for (size_t k = 0; k < sc->npop; k++)
                printf("  [%s] %lld %s, %lld steps of %.6g s\n", sc->pops[k].name,
                       (long long)sc->pops[k].count, sc->pops[k].species.name,
                       (long long)sc->pops[k].nsteps, sc->pops[k].dt);
        }
        gcp_scene_free(sc);
        MPI_Finalize();
        return 0;
    }
    if ((rc = gcp_output_probe(sc, comm, &err))) {
        if (me == 0) fprintf(stderr, "gcpush: %s\n", err.msg);
        gcp_scene_free(sc);
        MPI_Finalize();
        return 2;
    }

    const double w0 = wall_now();
    struct gcp_results res;
    gcp_results_init(&res, sc->trajectory_samples);
    struct gcp_par_counter counter;
    if (gcp_par_counter_create(&counter, gcp_scene_chunk_count(sc), comm)) {
        if (me == 0) fprintf(stderr, "gcpush: MPI window creation failed\n");
        MPI_Abort(comm, 1);
    }
    rc = gcp_scene_push(sc, &res, gcp_par_counter_next, &counter, &err);
    gcp_par_counter_free(&counter);
    bad = rc != 0;
    MPI_Allreduce(MPI_IN_PLACE, &bad, 1, MPI_INT, MPI_MAX, comm);
    if (!bad && gcp_results_sort(&res)) bad = 1, rc = gcp_error_set(&err, GCP_ERR_NOMEM, "out of memory");
    MPI_Allreduce(MPI_IN_PLACE, &bad, 1, MPI_INT, MPI_MAX, comm);
    if (!bad) {
        rc = gcp_output_write(sc, &res, comm, &err);
        bad = rc != 0;
    }
    if (bad) {
        if (me == 0) fprintf(stderr, "gcpush: %s\n", rc ? err.msg : "a rank failed");
    } else if (!quiet) {
        summary(sc, &res, comm, me, wall_now() - w0);
    }
    gcp_results_free(&res);
    gcp_scene_free(sc);
    MPI_Finalize();
    return bad ? 1 : 0;
}
