/* gcpush -- command line.
 *
 *   gcpush [--quiet] [--force] FILE.run  run the scene, write its HDF5 output
 *                                 (--force: replace an existing output)
 *   gcpush --check FILE.run       validate the run file, run nothing
 *   gcpush --restart OUT.h5       continue a killed or interrupted run from its checkpoints
 *   gcpush --help | --version
 *
 * Same binary with and without mpirun.  Exit status: 0 success, 1 a run that
 * failed (I/O), 2 bad usage or a bad run file, 3 interrupted (SIGINT,
 * SIGTERM or SIGUSR1: a checkpoint was written).  Messages come from rank 0 only, one
 * line each, naming file, line and key. */
#define _XOPEN_SOURCE 700 /* realpath */
#define _DEFAULT_SOURCE /* madvise, MADV_HUGEPAGE */
#include <limits.h>
#include <stdint.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#include <sys/mman.h>
#ifdef __GLIBC__
#include <malloc.h>
#endif

#include <mpi.h>

#include "gcpush/grid_file.h"
#include "gcpush/io.h"
#include "gcpush/run.h"
#include "gcpush/sweep.h"
#include "par/par.h"

#ifndef GCP_VERSION
#define GCP_VERSION "unknown"
#endif
#ifndef GCP_GIT_HASH
#define GCP_GIT_HASH "unknown"
#endif

enum { EXIT_RUN_FAILED = 1, EXIT_BAD_INPUT = 2, EXIT_INTERRUPTED = 3 };

static volatile sig_atomic_t stop_requested = 0; /* the signal's number, 0 for none */
/* the driver polls it as a volatile int (struct gcp_schedule.stop) */
_Static_assert(sizeof(sig_atomic_t) == sizeof(int), "sig_atomic_t is not an int here");
static void on_signal(int sig)
{
    stop_requested = sig;
}

/* SIGUSR1 too: mpirun forwards it to every rank, whereas it answers
 * SIGINT/SIGTERM by killing the job after a short grace period. */
static const int stop_signals[] = {SIGINT, SIGTERM, SIGUSR1};

/* Caught from the first line of main, before MPI_Init: a signal that came
 * during start-up (a 2-rank MPI_Init under load took over a second, the
 * scene and checks as long again) killed the rank by its default action,
 * and mpirun then aborted the whole job; now it is only noted, and the push
 * answers it at its first slice (a checkpoint, exit status 3).  Called
 * again after MPI_Init in case MPI installed handlers of its own. */
static void catch_stop_signals(void)
{
    struct sigaction sa = {.sa_handler = on_signal};
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESTART;
    for (size_t i = 0; i < sizeof stop_signals / sizeof *stop_signals; i++)
        sigaction(stop_signals[i], &sa, NULL);
}

/* Paths that write no checkpoint (--check, grid, a sweep, --help):
 * the signals' default action again, and a signal noted during start-up
 * acts now, as it would have when it came. */
static void default_stop_signals(void)
{
    for (size_t i = 0; i < sizeof stop_signals / sizeof *stop_signals; i++)
        signal(stop_signals[i], SIG_DFL);
    if (stop_requested) raise(stop_requested);
}

static void usage(FILE *to)
{
    fprintf(to,
            "usage: gcpush [--quiet] [--force] FILE.run  run a scene, write its HDF5 output\n"
            "                                     (--force: replace an existing output file)\n"
            "       gcpush --check FILE.run       validate a run file without running it\n"
            "       gcpush [--force] --restart OUT.h5  continue an interrupted run from its checkpoints\n"
            "       gcpush grid FILE.run          sample a field onto a grid file (fields/README.md)\n"
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

/* ---- the schedule: shared counter, progress, checkpoints ---------------- */

struct run_ctx {
    const struct gcp_scene *sc;
    struct gcp_par_counter counter;
    int64_t *todo;         /* chunk indices to push, in the order handed out */
    int me, quiet, tty;
    double t0, last_print, last_ckpt;
    int64_t total;         /* particles this run pushes */
    int ckpt_failed;
    struct gcp_error ckpt_err;
};

static int64_t next_chunk(void *vctx)
{
    struct run_ctx *c = vctx;
    if (stop_requested) return -1;
    const double w0 = gcp_phase_clock();
    int64_t k = gcp_par_counter_take(&c->counter);
    gcp_phase_wait(w0);
    return k < 0 ? -1 : c->todo[k];
}

/* The order chunks are handed out in: the costliest first (longest
 * processing time first), so that the chunks left when the ranks run out of
 * work are the cheapest and the last rank to finish keeps the others
 * waiting for less.  A chunk's cost is estimated as its particles times its
 * population's steps (gc-gl4 costs about the same per particle-step across
 * the flagship's populations: 0.47-0.62 us); equal costs keep the chunks'
 * order.  The order changes which rank pushes what, never a result. */
struct costed { double cost; int64_t chunk; };
static int by_cost(const void *a, const void *b)
{
    const struct costed *x = a, *y = b;
    if (x->cost != y->cost) return x->cost > y->cost ? -1 : 1;
    return (x->chunk > y->chunk) - (x->chunk < y->chunk);
}
/* Returns 0, or -1 out of memory. */
static int order_by_cost(const struct gcp_scene *sc, int64_t *items, int64_t n)
{
    struct costed *c = malloc((size_t)(n ? n : 1) * sizeof *c);
    if (!c) return -1;
    for (int64_t i = 0; i < n; i++) {
        int64_t first, count;
        gcp_scene_chunk(sc, items[i], &first, &count);
        c[i] = (struct costed){0.0, items[i]};
        for (size_t k = 0; k < sc->npop; k++)
            if (first < sc->pops[k].first_id + sc->pops[k].count) {
                c[i].cost = (double)count * (double)sc->pops[k].nsteps;
                break;
            }
    }
    qsort(c, (size_t)n, sizeof *c, by_cost);
    for (int64_t i = 0; i < n; i++) items[i] = c[i].chunk;
    free(c);
    return 0;
}

static void progress(struct run_ctx *c, int final)
{
    int64_t done, steps;
    gcp_par_counter_totals(&c->counter, &done, &steps);
    const double el = wall_now() - c->t0;
    const double rate = el > 0 ? (double)steps / el : 0.0;
    const double eta = done > 0 ? el * (double)(c->total - done) / (double)done : 0.0;
    fprintf(stderr, "%s%lld / %lld particles, %.3g particle-steps/s, %.0f s elapsed, ETA %.0f s%s",
            c->tty ? "\r" : "", (long long)done, (long long)c->total, rate, el, eta,
            c->tty && !final ? "   " : "\n");
    fflush(stderr);
}

static void chunk_done(void *vctx, struct gcp_results *res, int64_t particles, int64_t steps)
{
    struct run_ctx *c = vctx;
    gcp_par_counter_report(&c->counter, particles, steps);
    const double now = wall_now();
    /* progress: on rank 0, for runs past a few seconds; a line per 10 s when
     * stderr is a file, a refreshed line per second on a terminal */
    if (c->me == 0 && !c->quiet && now - c->t0 > 3.0 &&
        now - c->last_print > (c->tty ? 1.0 : 10.0)) {
        progress(c, 0);
        c->last_print = now;
    }
    if (c->sc->checkpoint_every > 0 && now - c->last_ckpt > c->sc->checkpoint_every) {
        if (gcp_checkpoint_write(c->sc, res, c->me, &c->ckpt_err)) c->ckpt_failed = 1;
        c->last_ckpt = now;
    }
}

/* The first error of the lowest failing rank, on every rank (so rank 0,
 * which prints, says what went wrong where).  Returns whether any failed. */
static int agree_error(int failed, struct gcp_error *err, MPI_Comm comm)
{
    int me, who;
    MPI_Comm_rank(comm, &me);
    int mine = failed ? me : INT_MAX;
    MPI_Allreduce(&mine, &who, 1, MPI_INT, MPI_MIN, comm);
    if (who == INT_MAX) return 0;
    MPI_Bcast(err, (int)sizeof *err, MPI_BYTE, who, comm);
    if (!err->code) err->code = GCP_ERR_IO;
    return 1;
}

/* After restart_load's dedup (rows sorted by id, each once, each chunk on one
 * rank): every chunk held must be whole, since gcpush checkpoints only whole
 * chunks; a chunk with holes would come out as rows of id 0, t 0, ALIVE. */
static int chunks_whole(const struct gcp_scene *sc, const struct gcp_results *res,
                        struct gcp_error *err)
{
    for (int64_t i = 0; i < res->n;) {
        const int64_t c = gcp_scene_chunk_of(sc, res->id[i]);
        int64_t j = i + 1, first, count;
        while (j < res->n && gcp_scene_chunk_of(sc, res->id[j]) == c) j++;
        gcp_scene_chunk(sc, c, &first, &count);
        if (j - i != count)
            return gcp_error_set(err, GCP_ERR_IO,
                                 "%s.ckpt.*: particles %lld .. %lld (one chunk): %lld of %lld in "
                                 "the checkpoints; they are corrupt (remove them to start over)",
                                 sc->output, (long long)first, (long long)(first + count - 1),
                                 (long long)(j - i), (long long)count);
        i = j;
    }
    return 0;
}

/* On restart: load the checkpoints (file i on rank i % nranks), keep one copy
 * of each chunk (the lowest rank holding it), and list the chunks left. */
static int restart_load(const struct gcp_scene *sc, struct gcp_results *res, char **files,
                        size_t nfiles, MPI_Comm comm, int me, int nranks, int64_t **todo,
                        int64_t *ntodo, struct gcp_error *err)
{
    int rc = 0;
    for (size_t i = (size_t)me; i < nfiles && !rc; i += (size_t)nranks)
        rc = gcp_checkpoint_load(files[i], sc, res, err);
    if (agree_error(rc != 0, err, comm)) return err->code;
    const int64_t nchunks = gcp_scene_chunk_count(sc);
    /* owner[c] = lowest rank holding chunk c, or nranks when nobody does */
    int *owner = malloc((size_t)nchunks * sizeof *owner);
    unsigned char *keep = malloc((size_t)(res->n ? res->n : 1));
    if (!owner || !keep) {
        free(owner);
        free(keep);
        return gcp_error_set(err, GCP_ERR_NOMEM, "out of memory");
    }
    for (int64_t k = 0; k < nchunks; k++) owner[k] = nranks;
    for (int64_t i = 0; i < res->n; i++) owner[gcp_scene_chunk_of(sc, res->id[i])] = me;
    MPI_Allreduce(MPI_IN_PLACE, owner, (int)nchunks, MPI_INT, MPI_MIN, comm);
    for (int64_t i = 0; i < res->n; i++) keep[i] = owner[gcp_scene_chunk_of(sc, res->id[i])] == me;
    gcp_results_drop(res, keep);
    /* a chunk appears once per rank file, but a rank may hold it twice when
     * two old files landed on it: drop repeats of an id */
    gcp_results_sort(res);
    for (int64_t i = 0; i < res->n; i++) keep[i] = i == 0 || res->id[i] != res->id[i - 1];
    gcp_results_drop(res, keep);
    free(keep);
    if (agree_error(chunks_whole(sc, res, err) != 0, err, comm)) {
        free(owner);
        return err->code;
    }
    *ntodo = 0;
    *todo = malloc((size_t)(nchunks ? nchunks : 1) * sizeof **todo);
    if (!*todo) {
        free(owner);
        return gcp_error_set(err, GCP_ERR_NOMEM, "out of memory");
    }
    for (int64_t k = 0; k < nchunks; k++)
        if (owner[k] == nranks) (*todo)[(*ntodo)++] = k;
    free(owner);
    return 0;
}

/* steps: particle-steps pushed by this run (not those loaded on restart). */
static void summary(const struct gcp_scene *sc, const struct gcp_results *r, MPI_Comm comm,
                    int me, int64_t steps, double wall)
{
    int64_t counts[GCP_STATUS_COUNT] = {0};
    for (int64_t k = 0; k < r->n; k++)
        if (r->status[k] >= 0 && r->status[k] < GCP_STATUS_COUNT) counts[r->status[k]]++;
    MPI_Reduce(me ? counts : MPI_IN_PLACE, counts, GCP_STATUS_COUNT, MPI_INT64_T, MPI_SUM, 0, comm);
    if (me) return;
    printf("%s: %lld particles, %.6g s (%s in %s), %.3g particle-steps/s\n", sc->name,
           (long long)sc->total, sc->duration, sc->pusher->name, sc->field_model,
           wall > 0 ? (double)steps / wall : 0.0);
    for (int s = 0; s < GCP_STATUS_COUNT; s++)
        if (counts[s]) printf("  %-13s %lld\n", gcp_status_name(s), (long long)counts[s]);
    printf("output: %s\n", sc->output);
}

/* Issue 11: one line on stderr per particle of this rank that ended
 * STEP_FAILED, with its id, the method, the time and the reason (in the
 * output as /particles/final/step_failure), the first GCP_FAILED_LOG_MAX
 * of them and then a count, so a run where every particle fails leaves a
 * readable log. */
#define GCP_FAILED_LOG_MAX 100
static void log_step_failures(const struct gcp_scene *sc, const struct gcp_results *r)
{
    int64_t shown = 0, more = 0;
    for (int64_t k = 0; k < r->n; k++) {
        if (r->status[k] != GCP_STEP_FAILED) continue;
        if (shown++ >= GCP_FAILED_LOG_MAX) {
            more++;
            continue;
        }
        fprintf(stderr, "gcpush: particle %lld STEP_FAILED (%s) at t = %.9g s: %s (%s)\n",
                (long long)r->id[k], sc->pusher->name, r->t[k],
                gcp_step_failure_name(r->step_failure[k]),
                gcp_step_failure_doc(r->step_failure[k]));
    }
    if (more)
        fprintf(stderr, "gcpush: ... and %lld more STEP_FAILED particles on this rank "
                        "(reasons in /particles/final/step_failure)\n", (long long)more);
}

/* Peak bytes one of nranks ranks holds: its rows in arrays grown by
 * doubling (up to twice the rows), plus the larger of the sort's copy of
 * one column with its permutation and the parallel write's two copies of
 * one column.  Events are not counted (a few per particle and orbit). */
static double memory_per_rank(const struct gcp_scene *sc, int nranks)
{
    int64_t widest;
    const int64_t row = gcp_results_row_bytes(sc->trajectory_samples,
                                              sc->pusher->kind == GCP_GUIDING_CENTRE, &widest);
    const int64_t chunks = gcp_scene_chunk_count(sc);
    const double rows = (double)((chunks + nranks - 1) / nranks) * (double)gcp_scene_chunk_size(sc);
    double cap = 256;
    while (cap < rows) cap *= 2;
    const double sort = rows * (double)(widest + 8), write = 2.0 * (double)sc->total / nranks * (double)widest;
    return cap * (double)row + (sort > write ? sort : write) + 64e6; /* + code, MPI, HDF5 */
}

/* MemAvailable of /proc/meminfo in bytes; 0 when unknown. */
static double memory_available(void)
{
    FILE *fp = fopen("/proc/meminfo", "r");
    if (!fp) return 0;
    char line[256];
    double kb = 0;
    while (fgets(line, sizeof line, fp))
        if (sscanf(line, "MemAvailable: %lf kB", &kb) == 1) break;
    fclose(fp);
    return kb * 1024.0;
}

/* Refuses, before anything runs, a run whose ranks on this node need more
 * memory than the node has available: a run at the trajectory cap needed
 * ~25 GB and failed only at its end.  All ranks agree. */
static int memory_check(const struct gcp_scene *sc, MPI_Comm comm, struct gcp_error *err)
{
    int nranks, local;
    MPI_Comm_size(comm, &nranks);
    MPI_Comm node;
    MPI_Comm_split_type(comm, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node);
    MPI_Comm_size(node, &local);
    MPI_Comm_free(&node);
    const double need = memory_per_rank(sc, nranks), avail = memory_available();
    int bad = avail > 0 && need * local > avail;
    MPI_Allreduce(MPI_IN_PLACE, &bad, 1, MPI_INT, MPI_MAX, comm);
    if (!bad) return 0;
    return gcp_error_set(err, GCP_ERR_VALUE,
                         "%s: the run needs about %.3g GB per rank (%.3g GB for the %d rank(s) on "
                         "this node), which has %.3g GB available: run fewer particles or "
                         "trajectory samples ([output] trajectory), or on more ranks on more nodes",
                         sc->path, need / 1e9, need * local / 1e9, local, avail / 1e9);
}

/* Whether paths a and b name the same file, existing or not: their
 * directories resolved (`--restart ./ck.h5` of a run that wrote ck.h5). */
static int same_path(const char *a, const char *b)
{
    if (strcmp(a, b) == 0) return 1;
    char ra[PATH_MAX], rb[PATH_MAX], da[PATH_MAX], db[PATH_MAX];
    const char *sa = strrchr(a, '/'), *sb = strrchr(b, '/');
    snprintf(da, sizeof da, "%.*s", sa ? (int)(sa - a) + 1 : 1, sa ? a : ".");
    snprintf(db, sizeof db, "%.*s", sb ? (int)(sb - b) + 1 : 1, sb ? b : ".");
    if (!realpath(da, ra) || !realpath(db, rb)) return 0;
    return strcmp(ra, rb) == 0 && strcmp(sa ? sa + 1 : a, sb ? sb + 1 : b) == 0;
}

/* Loads the scene: from the run file, or on restart from the text saved in
 * the checkpoints.  All ranks agree on the outcome. */
static int load_scene(const char *arg, int restart, struct gcp_scene **sc, char ***files,
                      size_t *nfiles, MPI_Comm comm, struct gcp_error *err)
{
    int rc;
    *files = NULL;
    *nfiles = 0;
    if (!restart) {
        rc = gcp_scene_load_with(arg, &gcp_io_readers, sc, err);
    } else if ((rc = gcp_checkpoint_list(arg, files, nfiles)) == 0 && *nfiles == 0) {
        rc = gcp_error_set(err, GCP_ERR_IO, "%s: no checkpoint to restart from (%s.ckpt.*)", arg,
                           arg);
    } else if (rc == 0) {
        char *text, *path;
        if (!(rc = gcp_checkpoint_read_text((*files)[0], &text, &path, err))) {
            rc = gcp_scene_parse_with(path, text, &gcp_io_readers, sc, err);
            if (!rc && !same_path((*sc)->output, arg))
                rc = gcp_error_set(err, GCP_ERR_VALUE,
                                   "%s: the checkpoint's run file writes '%s', not '%s'",
                                   (*files)[0], (*sc)->output, arg);
            free(text);
            free(path);
        }
    }
    int bad = rc != 0;
    MPI_Allreduce(MPI_IN_PLACE, &bad, 1, MPI_INT, MPI_MAX, comm);
    return bad ? (rc ? rc : GCP_ERR_IO) : 0;
}

static void free_list(char **files, size_t n)
{
    for (size_t i = 0; i < n; i++) free(files[i]);
    free(files);
}

/* glibc returns a freed block of 128 KiB up (at first: the threshold then
 * follows the largest freed) to the kernel, and trims the heap's top past
 * 128 KiB free; the next allocation of that size is fresh pages again, each
 * a fault that zeroes it (~16 us in a paravirtualised VM).  The output
 * write allocates and frees a buffer per chunk and dataset (HDF5's chunk
 * and deflate buffers, the rows' move): keeping freed memory in the heap up
 * to blocks of 32 MiB (glibc's largest mmap threshold) and never trimming
 * it below 1 GiB cut the flagship's faults from 10.6k to 8.0k and its CPU by
 * 0.03-0.04 s per rank.  A batch program: peak memory is what counts, and
 * memory freed before it is reused, not returned. */
static void keep_freed_memory(void)
{
#ifdef __GLIBC__
    mallopt(M_MMAP_THRESHOLD, 32 << 20);
    mallopt(M_TRIM_THRESHOLD, 1 << 30);
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    /* The heap in transparent huge pages: a rank's heap (MPI_Init's, the
     * events, the sort's scratch, HDF5's chunk and deflate buffers) is
     * otherwise touched a 4 KiB page at a time, ~2500 faults of ~13 us
     * each per rank of the flagship, where one 2 MiB fault zeroes the same
     * memory in 0.2-2 ms.  The heap is grown once by 256 MiB (untouched,
     * so no memory is used until written, and kept: nothing is trimmed)
     * and that span marked for huge pages. */
    const uintptr_t huge = (uintptr_t)2 << 20;
    const uintptr_t lo = (uintptr_t)sbrk(0);
    mallopt(M_TOP_PAD, 256 << 20);
    void *p = malloc(1 << 20);
    const int grown = p != NULL; /* p is not read once freed */
    free(p);
    mallopt(M_TOP_PAD, 128 << 10); /* glibc's default again */
    const uintptr_t a = (lo + huge - 1) & ~(huge - 1), e = (uintptr_t)sbrk(0) & ~(huge - 1);
    if (grown && e > a) (void)madvise((void *)a, e - a, MADV_HUGEPAGE); /* a hint */
#endif
#endif
}

int main(int argc, char **argv)
{
    catch_stop_signals();
    keep_freed_memory();
    gcp_phase_start(); /* GCPUSH_TIMING=1: a line per rank on stderr at the end */
    gcp_par_local_defaults(); /* all ranks on this node: no network probing (README) */
    MPI_Init(&argc, &argv);
    gcp_par_nodelay(); /* MPI_Finalize's messages to the launcher without a 40 ms stall (README) */
    catch_stop_signals();
    gcp_phase_mark("init");
    MPI_Comm comm = MPI_COMM_WORLD;
    int me, nranks;
    MPI_Comm_rank(comm, &me);
    MPI_Comm_size(comm, &nranks);

    int check = 0, quiet = 0, restart = 0, force = 0;
    const char *arg = NULL;
    if (argc == 3 && strcmp(argv[1], "grid") == 0) {
        default_stop_signals();
        struct gcp_error gerr = {0};
        char out[1024];
        int grc = me == 0 ? gcp_grid_command(argv[2], out, sizeof out, &gerr) : 0;
        MPI_Bcast(&grc, 1, MPI_INT, 0, comm);
        if (me == 0) {
            if (grc) fprintf(stderr, "gcpush: %s\n", gerr.msg);
            else printf("grid: %s\n", out);
        }
        MPI_Finalize();
        return grc ? EXIT_BAD_INPUT : 0;
    }
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
        } else if (strcmp(argv[i], "--restart") == 0) {
            restart = 1;
        } else if (strcmp(argv[i], "--force") == 0) {
            force = 1;
        } else if (argv[i][0] == '-' || arg) {
            if (me == 0) {
                fprintf(stderr, "gcpush: unexpected argument '%s'\n", argv[i]);
                usage(stderr);
            }
            MPI_Finalize();
            return EXIT_BAD_INPUT;
        } else {
            arg = argv[i];
        }
    }
    if (!arg || (check && restart)) {
        if (me == 0) usage(stderr);
        MPI_Finalize();
        return EXIT_BAD_INPUT;
    }

    struct gcp_error err = {0};
    struct gcp_scene *sc = NULL;
    char **files;
    size_t nfiles;
    int rc = load_scene(arg, restart, &sc, &files, &nfiles, comm, &err);
    gcp_phase_mark("scene");
    if (rc) {
        if (me == 0) fprintf(stderr, "gcpush: %s\n", err.code ? err.msg : "a rank failed to read the run file");
        gcp_scene_free(sc);
        free_list(files, nfiles);
        MPI_Finalize();
        return EXIT_BAD_INPUT;
    }
    /* rows of a state file that are not finite: one line, then those particles end NONFINITE */
    for (size_t k = 0; me == 0 && k < sc->npop; k++)
        if (sc->pops[k].file[0] && sc->pops[k].init.nonfinite)
            fprintf(stderr, "gcpush: warning: %s: %lld of its %lld initial states are not finite "
                    "(those particles end NONFINITE)\n", sc->pops[k].file,
                    (long long)sc->pops[k].init.nonfinite, (long long)sc->pops[k].count);
    /* arithmetic = fast where this CPU, build or method has no fast step: say so */
    if (me == 0 && sc->fast_arith && !gcp_arithmetic_fast_runs(sc->pusher, sc->field))
        fprintf(stderr, "gcpush: note: [integrator] arithmetic = fast: no fast step for '%s' in "
                "field '%s' on this CPU and build (the fast tier is boris with AVX-512F in the "
                "dipole and uniform B); the IEEE step runs (the output's attribute arithmetic = "
                "ieee)\n", sc->pusher->name, sc->field_model);
    if (!restart && gcp_sweep_wanted(sc)) { /* [sweep]: error against run time (sweep.h) */
        default_stop_signals();
        /* a sweep's output is not replaced without --force either */
        int exists = !check && me == 0 && !force && access(sc->output, F_OK) == 0;
        MPI_Bcast(&exists, 1, MPI_INT, 0, comm);
        int st = EXIT_BAD_INPUT;
        if (exists) {
            if (me == 0)
                fprintf(stderr, "gcpush: %s: [output] file: '%s' exists: remove it or run with "
                        "--force to replace it\n", sc->path, sc->output);
        } else
            st = gcp_sweep_main(sc, check, quiet);
        gcp_scene_free(sc);
        MPI_Finalize();
        return st;
    }
    if (check) {
        default_stop_signals();
        if (me == 0 && !quiet) {
            printf("%s: ok: %lld particles, %s in %s for %.6g s\n", arg, (long long)sc->total,
                   sc->pusher->name, sc->field_model, sc->duration);
            for (size_t k = 0; k < sc->npop; k++)
                printf("  [%s] %lld %s%s%s, %lld steps of %.6g s\n", sc->pops[k].name,
                       (long long)sc->pops[k].count, sc->pops[k].species.name,
                       sc->pops[k].file[0] ? " from " : "", sc->pops[k].file,
                       (long long)sc->pops[k].nsteps, sc->pops[k].dt);
            printf("  memory: about %.3g GB on 1 rank, %.3g GB per rank on 4, %.3g GB per rank on 16 "
                   "(%.3g GB available here)\n",
                   memory_per_rank(sc, 1) / 1e9, memory_per_rank(sc, 4) / 1e9,
                   memory_per_rank(sc, 16) / 1e9, memory_available() / 1e9);
        }
        gcp_scene_free(sc);
        MPI_Finalize();
        return 0;
    }
    /* an existing output is replaced only when asked: found at the end of
     * a long run, a finished result was overwritten without a word */
    int exists = me == 0 && !force && access(sc->output, F_OK) == 0;
    MPI_Bcast(&exists, 1, MPI_INT, 0, comm);
    if (exists)
        rc = gcp_error_set(&err, GCP_ERR_VALUE,
                           "%s: [output] file: '%s' exists: remove it or run with --force to "
                           "replace it", sc->path, sc->output);
    if (rc || (rc = memory_check(sc, comm, &err)) || (rc = gcp_output_probe(sc, comm, &err))) {
        if (me == 0) fprintf(stderr, "gcpush: %s\n", err.msg);
        gcp_scene_free(sc);
        free_list(files, nfiles);
        MPI_Finalize();
        return EXIT_BAD_INPUT;
    }
    gcp_phase_mark("checks");
    gcp_output_progress(!quiet);
    struct gcp_results res;
    gcp_results_init(&res, sc->trajectory_samples, sc->pusher->kind == GCP_GUIDING_CENTRE);
    res.hybrid = sc->hybrid;
    struct run_ctx ctx = {.sc = sc, .me = me, .quiet = quiet, .tty = isatty(2)};
    int64_t nitems = gcp_scene_chunk_count(sc);
    ctx.total = sc->total;
    if (restart) {
        rc = restart_load(sc, &res, files, nfiles, comm, me, nranks, &ctx.todo, &nitems, &err);
        /* a state file read again must still hold the states the checkpoints started from */
        int changed = !rc && gcp_initfile_check_results(sc, &res, &err) != 0;
        MPI_Allreduce(MPI_IN_PLACE, &changed, 1, MPI_INT, MPI_MAX, comm);
        if (!rc && changed)
            rc = err.code ? err.code
                          : gcp_error_set(&err, GCP_ERR_STATE,
                                          "a [particles] file no longer holds the initial states "
                                          "the checkpoints started from (restore it, or start "
                                          "the run afresh)");
        if (rc) {
            if (me == 0) fprintf(stderr, "gcpush: %s\n", err.code ? err.msg : "a rank failed to load its checkpoint");
            gcp_results_free(&res);
            gcp_scene_free(sc);
            free_list(files, nfiles);
            MPI_Finalize();
            return EXIT_RUN_FAILED;
        }
        /* what a run killed while writing left behind (a 1.8 GB output
         * temporary once): this restart writes its own, so remove them */
        char **stale;
        size_t nstale;
        if (me == 0 && gcp_output_stale_list(sc->output, &stale, &nstale) == 0) {
            for (size_t i = 0; i < nstale; i++)
                if (remove(stale[i]) == 0 && !quiet)
                    printf("restart: removed %s, left by the interrupted run\n", stale[i]);
            free_list(stale, nstale);
        }
        int64_t have = res.n;
        MPI_Allreduce(MPI_IN_PLACE, &have, 1, MPI_INT64_T, MPI_SUM, comm);
        ctx.total = sc->total - have;
        if (me == 0 && !quiet)
            printf("restart: %lld particles from %zu checkpoint file(s), %lld to push\n",
                   (long long)have, nfiles, (long long)ctx.total);
    }
    if (!ctx.todo && (ctx.todo = malloc((size_t)(nitems ? nitems : 1) * sizeof *ctx.todo)))
        for (int64_t k = 0; k < nitems; k++) ctx.todo[k] = k;
    /* every rank must hand out the same order */
    int unordered = !ctx.todo || order_by_cost(sc, ctx.todo, nitems) != 0;
    MPI_Allreduce(MPI_IN_PLACE, &unordered, 1, MPI_INT, MPI_MAX, comm);
    if (unordered) {
        if (me == 0) fprintf(stderr, "gcpush: out of memory for the list of chunks\n");
        gcp_par_abort(comm, EXIT_RUN_FAILED);
    }
    if (gcp_par_counter_create(&ctx.counter, nitems, comm)) {
        if (me == 0) fprintf(stderr, "gcpush: MPI window creation failed\n");
        gcp_par_abort(comm, EXIT_RUN_FAILED);
    }
    ctx.t0 = ctx.last_print = ctx.last_ckpt = wall_now();
    gcp_phase_mark("setup");
    const struct gcp_schedule sched = {next_chunk, chunk_done, &ctx,
                                       (const volatile int *)&stop_requested};
    rc = gcp_scene_push(sc, &res, &sched, &err);
    if (me == 0 && !quiet && ctx.last_print > ctx.t0) progress(&ctx, 1);
    gcp_phase_mark("push");
    gcp_phase_busy(res.rank_cpu);
    /* Each rank sorts its own rows before the barrier: a rank done early
     * sorts while the last chunk is still pushed elsewhere, instead of
     * after it (a sort that ends up unused, the run having failed or been
     * stopped on another rank, only reorders rows a checkpoint takes in
     * any order). */
    const int sort_rc = rc == 0 && !stop_requested ? gcp_results_sort(&res) : 0;
    gcp_phase_mark("sort");
    int64_t pushed, steps_run;
    MPI_Barrier(comm);
    gcp_phase_mark("idle"); /* waiting for the last chunk of another rank */
    gcp_par_counter_totals(&ctx.counter, &pushed, &steps_run);
    gcp_par_counter_free(&ctx.counter);
    free(ctx.todo);

    int flags[3] = {rc != 0, (int)stop_requested, ctx.ckpt_failed};
    MPI_Allreduce(MPI_IN_PLACE, flags, 3, MPI_INT, MPI_MAX, comm);
    int status = 0;
    if (flags[0]) {
        if (me == 0) fprintf(stderr, "gcpush: %s\n", rc ? err.msg : "a rank failed");
        status = EXIT_RUN_FAILED;
    } else if (flags[1]) {
        /* interrupted: save what is done, leave no output */
        struct gcp_error cerr = {0};
        int bad = gcp_checkpoint_write(sc, &res, me, &cerr) != 0;
        MPI_Allreduce(MPI_IN_PLACE, &bad, 1, MPI_INT, MPI_MAX, comm);
        if (me == 0)
            fprintf(stderr, bad ? "gcpush: interrupted; writing the checkpoint failed\n"
                                : "gcpush: interrupted; checkpoint written, continue with: "
                                  "gcpush --restart %s\n",
                    sc->output);
        status = EXIT_INTERRUPTED;
    } else {
        if (flags[2] && me == 0)
            fprintf(stderr, "gcpush: warning: a periodic checkpoint failed (%s)\n",
                    ctx.ckpt_err.code ? ctx.ckpt_err.msg : "on another rank");
        rc = sort_rc;
        if (rc == 0) log_step_failures(sc, &res);
        int bad = rc != 0;
        MPI_Allreduce(MPI_IN_PLACE, &bad, 1, MPI_INT, MPI_MAX, comm);
        gcp_phase_mark("sorted");
        if (!bad) rc = gcp_output_write(sc, &res, comm, &err);
        if (bad || rc) {
            if (me == 0) fprintf(stderr, "gcpush: %s\n", rc ? err.msg : "out of memory on a rank");
            status = EXIT_RUN_FAILED;
        } else {
            /* the output is complete: its checkpoints are obsolete */
            MPI_Barrier(comm);
            if (me == 0) {
                char **old;
                size_t nold;
                if (gcp_checkpoint_list(sc->output, &old, &nold) == 0) {
                    for (size_t i = 0; i < nold; i++) remove(old[i]);
                    free_list(old, nold);
                }
            }
            if (!quiet) summary(sc, &res, comm, me, steps_run, wall_now() - ctx.t0);
        }
    }
    gcp_phase_mark("end");
    gcp_results_free(&res);
    gcp_scene_free(sc);
    free_list(files, nfiles);
    gcp_phase_mark("free");
    MPI_Finalize();
    gcp_phase_mark("finalize");
    gcp_phase_report(me, nranks);
    return status;
}
