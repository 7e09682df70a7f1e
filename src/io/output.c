/* The output file: one HDF5 file per run, written collectively by every rank
 * through MPI-IO (parallel HDF5).  Layout: DESIGN.md, "HDF5 output".
 *
 * Each rank holds its rows sorted by particle id and writes them in place
 * (past ~1000 runs of ids per rank the rows are moved first, one exchange
 * per column, so that each rank holds one block of consecutive ids: struct
 * writer, output_rows.c; the trajectories are moved always).  Datasets, groups and attributes are created
 * collectively; the rows of contiguous datasets go in with independent
 * writes (each rank's own pwrites), only the chunked, deflated
 * trajectories with collective ones.  The file is
 * written under a temporary name and renamed by rank 0 only when every rank
 * succeeded; otherwise the temporary file is removed. */
#define _GNU_SOURCE /* fallocate (Linux) */
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <hdf5.h>

#include "output_priv.h"
#include "output_events_priv.h"
#include "par/par.h"

static void write_rows(struct writer *w, hid_t loc, const char *name, hid_t type, int rank,
                       hsize_t d1, hsize_t d2, const void *data)
{
    gcp_writer_rows(w, loc, name, type, rank, d1, d2, data, H5P_DEFAULT);
}

static void attr_str(struct writer *w, hid_t loc, const char *name, const char *value)
{
    gcp_h5_attr_str(&w->bad, loc, name, value);
}

static void attr_num(struct writer *w, hid_t loc, const char *name, hid_t type, const void *v)
{
    gcp_h5_attr_num(&w->bad, loc, name, type, v);
}

static hid_t group(struct writer *w, hid_t loc, const char *name)
{
    hid_t g = H5Gcreate2(loc, name, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    if (g < 0) w->bad = 1;
    return g;
}

static void write_particles(struct writer *w, const struct gcp_scene *sc)
{
    const struct gcp_results *r = w->r;
    hid_t g = group(w, w->file, "particles");
    write_rows(w, g, "id", H5T_NATIVE_INT64, 1, 0, 0, r->id);
    /* species name, charge and mass of each row, from its population */
    char (*names)[32] = calloc((size_t)(r->n ? r->n : 1), 32);
    double *q = malloc((size_t)(r->n ? r->n : 1) * sizeof *q);
    double *m = malloc((size_t)(r->n ? r->n : 1) * sizeof *m);
    double *dt = malloc((size_t)(r->n ? r->n : 1) * sizeof *dt);
    if (!names || !q || !m || !dt) {
        w->bad = 1;
    } else {
        for (int64_t k = 0; k < r->n; k++) {
            const struct gcp_species *sp = &sc->pops[r->pop[k]].species;
            snprintf(names[k], 32, "%s", sp->name);
            q[k] = sp->charge;
            m[k] = sp->mass;
            dt[k] = sc->pops[r->pop[k]].dt;
        }
    }
    hid_t st = H5Tcopy(H5T_C_S1);
    H5Tset_size(st, 32);
    H5Tset_strpad(st, H5T_STR_NULLTERM);
    write_rows(w, g, "species", st, 1, 0, 0, names);
    H5Tclose(st);
    write_rows(w, g, "charge", H5T_NATIVE_DOUBLE, 1, 0, 0, q);
    write_rows(w, g, "mass", H5T_NATIVE_DOUBLE, 1, 0, 0, m);
    write_rows(w, g, "dt", H5T_NATIVE_DOUBLE, 1, 0, 0, dt);
    free(dt);
    free(names);
    free(q);
    free(m);

    hid_t gi = group(w, g, "initial");
    write_rows(w, gi, "x", H5T_NATIVE_DOUBLE, 2, 3, 0, r->x0);
    write_rows(w, gi, "u", H5T_NATIVE_DOUBLE, 2, 3, 0, r->u0);
    if (r->gc || r->hybrid) { /* the guiding centre made from the full-orbit start above */
        write_rows(w, gi, "X", H5T_NATIVE_DOUBLE, 2, 3, 0, r->X0);
        write_rows(w, gi, "ppar", H5T_NATIVE_DOUBLE, 1, 0, 0, r->ppar0);
        write_rows(w, gi, "mu", H5T_NATIVE_DOUBLE, 1, 0, 0, r->mu0);
    }
    H5Gclose(gi);
    hid_t gf = group(w, g, "final");
    write_rows(w, gf, "t", H5T_NATIVE_DOUBLE, 1, 0, 0, r->t);
    if (r->gc) {
        write_rows(w, gf, "X", H5T_NATIVE_DOUBLE, 2, 3, 0, r->x);
        write_rows(w, gf, "ppar", H5T_NATIVE_DOUBLE, 1, 0, 0, r->ppar);
        write_rows(w, gf, "mu", H5T_NATIVE_DOUBLE, 1, 0, 0, r->mu);
    } else {
        write_rows(w, gf, "x", H5T_NATIVE_DOUBLE, 2, 3, 0, r->x);
        write_rows(w, gf, "u", H5T_NATIVE_DOUBLE, 2, 3, 0, r->u);
    }
    if (r->hybrid) { /* both forms for every particle (hybrid.h, gcp_hybrid_final) */
        write_rows(w, gf, "X", H5T_NATIVE_DOUBLE, 2, 3, 0, r->Xf);
        write_rows(w, gf, "ppar", H5T_NATIVE_DOUBLE, 1, 0, 0, r->ppar);
        write_rows(w, gf, "mu", H5T_NATIVE_DOUBLE, 1, 0, 0, r->mu);
    }
    /* an HDF5 enum over int32 (issue 13): h5dump, h5py and every HDF5
     * tool show the names; the values are the status codes */
    {
        hid_t et = H5Tenum_create(H5T_NATIVE_INT32);
        for (int32_t v = 0; v < GCP_STATUS_COUNT; v++)
            if (et < 0 || H5Tenum_insert(et, gcp_status_name(v), &v) < 0) w->bad = 1;
        if (et >= 0) {
            write_rows(w, gf, "status", et, 1, 0, 0, r->status);
            H5Tclose(et);
        }
    }
    /* the same table as a string attribute, for readers of the int32 form */
    {
        hid_t ds = H5Dopen2(gf, "status", H5P_DEFAULT);
        char names_attr[GCP_STATUS_COUNT * 16 + 1] = "";
        for (int s = 0; s < GCP_STATUS_COUNT; s++) {
            strcat(names_attr, gcp_status_name(s));
            if (s + 1 < GCP_STATUS_COUNT) strcat(names_attr, " ");
        }
        attr_str(w, ds, "names", names_attr);
        H5Dclose(ds);
    }
    /* why each STEP_FAILED particle failed (issue 11), an enum like status */
    {
        hid_t et = H5Tenum_create(H5T_NATIVE_INT32);
        for (int32_t v = 0; v < GCP_FAIL_COUNT; v++)
            if (et < 0 || H5Tenum_insert(et, gcp_step_failure_name(v), &v) < 0) w->bad = 1;
        if (et >= 0) {
            write_rows(w, gf, "step_failure", et, 1, 0, 0, r->step_failure);
            H5Tclose(et);
        }
    }
    H5Gclose(gf);
    H5Gclose(g);
}

static void write_trajectories(struct writer *w)
{
    const struct gcp_results *r = w->r;
    hid_t g = group(w, w->file, "trajectories");
    const hsize_t S = (hsize_t)r->S;
    hid_t d2 = gcp_writer_trajectory_dcpl(r, w->total, 2, w->compression);
    hid_t d3 = gcp_writer_trajectory_dcpl(r, w->total, 3, w->compression);
    gcp_writer_rows(w, g, "t", H5T_NATIVE_DOUBLE, 2, S, 0, r->traj_t, d2);
    gcp_writer_rows(w, g, "x", H5T_NATIVE_DOUBLE, 3, S, 3, r->traj_x, d3);
    if (r->gc || r->hybrid) gcp_writer_rows(w, g, "ppar", H5T_NATIVE_DOUBLE, 2, S, 0, r->traj_ppar, d2);
    if (!r->gc) gcp_writer_rows(w, g, "u", H5T_NATIVE_DOUBLE, 3, S, 3, r->traj_u, d3);
    if (r->hybrid) gcp_writer_rows(w, g, "mode", H5T_NATIVE_INT8, 2, S, 0, r->traj_mode, d2);
    H5Pclose(d2);
    H5Pclose(d3);
    write_rows(w, g, "count", H5T_NATIVE_INT64, 1, 0, 0, r->traj_count);
    H5Gclose(g);
}

/* The event tables (output_events.c) with this writer's file, transfer and rows. */
static struct gcp_ev_writer ev_writer(const struct writer *w)
{
    return (struct gcp_ev_writer){w->file, w->dxpl_ind, w->r, w->total, 0, w->evcnt, w->evbuf,
                                  w->evcap};
}

static void write_events(struct writer *w, const struct gcp_scene *sc, MPI_Comm comm)
{
    const unsigned inv = sc->invariants, evt = sc->events;
    struct gcp_ev_writer ew = ev_writer(w);
    if (inv || (evt & (GCP_EVT_BOUNCE | GCP_EVT_DRIFT))) gcp_output_invariants(&ew, sc, comm);
    w->bad |= ew.bad;
    if (evt & GCP_EVT_LOSS) {
        static const struct gcp_ev_col c[] = {{"x", 0, 2, 3, 0, "m", 0}};
        /* /losses: the table itself, plus the start classification per particle */
        struct gcp_ev_writer el = ev_writer(w);
        gcp_output_event_table(&el, w->file, "losses", GCP_EVENT_LOSS, c, 1, 1, comm);
        w->bad |= el.bad;
        hid_t g = H5Gopen2(w->file, "losses", H5P_DEFAULT);
        if (g < 0) {
            w->bad = 1;
            return;
        }
        hid_t gi = group(w, g, "initial");
        write_rows(w, gi, "L", H5T_NATIVE_DOUBLE, 1, 0, 0, w->r->L0);
        write_rows(w, gi, "alpha_eq", H5T_NATIVE_DOUBLE, 1, 0, 0, w->r->aeq0);
        write_rows(w, gi, "alpha_lc", H5T_NATIVE_DOUBLE, 1, 0, 0, w->r->alc0);
        H5Gclose(gi);
        H5Gclose(g);
    }
}

/* /hybrid (method = hybrid): per particle mode, switches, time in each mode;
 * the switch events, sorted by (id, t) like the /invariants tables. */
static void write_hybrid(struct writer *w, MPI_Comm comm)
{
    const struct gcp_results *r = w->r;
    hid_t g = group(w, w->file, "hybrid");
    write_rows(w, g, "mode", H5T_NATIVE_INT32, 1, 0, 0, r->hy_mode);
    write_rows(w, g, "switches", H5T_NATIVE_INT32, 1, 0, 0, r->hy_switches);
    write_rows(w, g, "t_gc", H5T_NATIVE_DOUBLE, 1, 0, 0, r->hy_t_gc);
    write_rows(w, g, "t_fo", H5T_NATIVE_DOUBLE, 1, 0, 0, r->hy_t_fo);
    static const struct gcp_ev_col c[] = {{"X", 0, 2, 3, 0, "m", 0},
                                      {"eps", 3, 1, 0, 0, "1", 0},
                                      {"direction", 4, 1, 0, 0, "+1 to full orbit, -1 to guiding centre", 0},
                                      {"dp2", 5, 1, 0, 0, "1", 0}};
    struct gcp_ev_writer ew = ev_writer(w);
    gcp_output_event_table(&ew, g, "events", GCP_EVENT_SWITCH, c, sizeof c / sizeof c[0], 0, comm);
    w->bad |= ew.bad;
    H5Gclose(g);
}

static void write_timing(struct writer *w, MPI_Comm comm, int me, int nranks)
{
    const struct gcp_results *r = w->r;
    hid_t g = group(w, w->file, "timing");
    write_rows(w, g, "cpu_seconds", H5T_NATIVE_DOUBLE, 1, 0, 0, r->cpu);
    write_rows(w, g, "steps", H5T_NATIVE_INT64, 1, 0, 0, r->steps);
    double *rank_cpu = calloc((size_t)nranks, sizeof *rank_cpu);
    int64_t *rank_n = calloc((size_t)nranks, sizeof *rank_n);
    if (!rank_cpu || !rank_n) {
        w->bad = 1;
    } else {
        MPI_Allgather(&r->rank_cpu, 1, MPI_DOUBLE, rank_cpu, 1, MPI_DOUBLE, comm);
        MPI_Allgather(&r->n, 1, MPI_INT64_T, rank_n, 1, MPI_INT64_T, comm);
        gcp_writer_rank0(w, g, "rank_cpu_seconds", H5T_NATIVE_DOUBLE, (hsize_t)nranks, rank_cpu, me);
        gcp_writer_rank0(w, g, "rank_particles", H5T_NATIVE_INT64, (hsize_t)nranks, rank_n, me);
        /* load imbalance (max - mean) / mean of the ranks' busy CPU seconds:
         * 0 is perfect; the share of the run the busiest rank kept the others waiting */
        double mx = 0.0, sum = 0.0;
        for (int k = 0; k < nranks; k++) {
            mx = rank_cpu[k] > mx ? rank_cpu[k] : mx;
            sum += rank_cpu[k];
        }
        const double imbalance = sum > 0 ? mx / (sum / nranks) - 1.0 : 0.0;
        attr_num(w, g, "load_imbalance", H5T_NATIVE_DOUBLE, &imbalance);
    }
    free(rank_cpu);
    free(rank_n);
    H5Gclose(g);
}

/* An upper bound of the output's size: every column uncompressed (deflate
 * never grows a chunk by more than ~0.1%), the event tables, and room for
 * metadata and chunk indices. */
static int64_t size_bound(const struct gcp_results *r, int64_t total, MPI_Comm comm)
{
    struct gcp_results_column c[GCP_RESULTS_MAX_COLUMNS];
    const size_t nc = gcp_results_columns((struct gcp_results *)r, c);
    int64_t row = 32 + 3 * 8; /* species, charge, mass, dt */
    for (size_t k = 0; k < nc; k++) row += c[k].per_row * (int64_t)c[k].elem;
    int64_t ev = r->ev.n + r->ev.ns;
    MPI_Allreduce(MPI_IN_PLACE, &ev, 1, MPI_INT64_T, MPI_SUM, comm);
    const double raw = (double)total * (double)row + (double)ev * (double)sizeof(struct gcp_event);
    return (int64_t)(raw * 1.02) + (4 << 20);
}

/* Reserves the output's disk space before anything is written (rank 0,
 * fallocate with the file size kept, so HDF5 sees its file unchanged and
 * trims what is left over at close).  A full disk in the middle of a
 * collective write left ranks out of step in HDF5 (a hang on 2 ranks, a
 * crash at MPI_Finalize on 1); refused here, every rank decides together
 * before the first write.  A file system without fallocate is not checked.
 * Returns 0, or errno's ENOSPC-like code (the same on every rank). */
static int reserve_space(const char *tmp, int64_t bytes, MPI_Comm comm)
{
    int me, code = 0;
    MPI_Comm_rank(comm, &me);
    if (me == 0) {
        const int fd = open(tmp, O_WRONLY);
        if (fd < 0) {
            code = errno;
        } else {
            if (fallocate(fd, FALLOC_FL_KEEP_SIZE, 0, (off_t)bytes) != 0 && errno != EOPNOTSUPP &&
                errno != ENOSYS)
                code = errno;
            close(fd);
        }
    }
    MPI_Bcast(&code, 1, MPI_INT, 0, comm);
    return code;
}

/* Gives back what reserve_space held past the end of the file (HDF5 leaves
 * the size alone, and compressed trajectories end far below the bound):
 * a truncate to the same size frees blocks past it (ext4, tmpfs). */
static void trim(const char *tmp)
{
    struct stat st;
    if (stat(tmp, &st) != 0) return;
    if (truncate(tmp, st.st_size) != 0) return; /* a failure costs only disk space */
}

/* Temporary name next to the output, unique per run (rank 0's pid). */
static void temp_name(const struct gcp_scene *sc, MPI_Comm comm, char *buf, size_t len)
{
    long pid = (long)getpid();
    MPI_Bcast(&pid, 1, MPI_LONG, 0, comm);
    snprintf(buf, len, "%s.tmp-%ld", sc->output, pid);
}

int gcp_output_probe(const struct gcp_scene *sc, MPI_Comm comm, struct gcp_error *err)
{
    int me;
    MPI_Comm_rank(comm, &me);
    char tmp[1100];
    temp_name(sc, comm, tmp, sizeof tmp);
    int ok = 1, code = 0;
    if (me == 0) {
        FILE *fp = fopen(tmp, "wb");
        if (!fp) {
            ok = 0;
            code = errno;
        } else {
            fclose(fp);
            remove(tmp);
        }
    }
    MPI_Bcast(&ok, 1, MPI_INT, 0, comm);
    MPI_Bcast(&code, 1, MPI_INT, 0, comm);
    if (!ok)
        return gcp_error_set(err, GCP_ERR_IO, "%s: [output] file: cannot write '%s': %s",
                             sc->path, sc->output, strerror(code));
    return 0;
}

/* Every dataset carries its unit (issue 13): a `units` attribute, added
 * here to the datasets written without one ("1": a count, an index, a
 * code, or dimensionless); the event-table columns already carry theirs.
 * Attributes cannot carry attributes: the one root attribute with a unit,
 * duration, gets a companion duration_units.  Collective: every rank walks
 * the same table. */
static void write_units(struct writer *w)
{
    static const char *const units[][2] = {
        {"particles/id", "1"}, {"particles/species", "1"}, {"particles/charge", "C"},
        {"particles/mass", "kg"}, {"particles/dt", "s"},
        {"particles/initial/x", "m"}, {"particles/initial/u", "m/s"},
        {"particles/initial/X", "m"}, {"particles/initial/ppar", "kg m/s"},
        {"particles/initial/mu", "J/T"},
        {"particles/final/t", "s"}, {"particles/final/x", "m"}, {"particles/final/u", "m/s"},
        {"particles/final/X", "m"}, {"particles/final/ppar", "kg m/s"},
        {"particles/final/mu", "J/T"}, {"particles/final/status", "1"},
        {"particles/final/step_failure", "1"},
        {"trajectories/t", "s"}, {"trajectories/x", "m"}, {"trajectories/u", "m/s"},
        {"trajectories/ppar", "kg m/s"}, {"trajectories/count", "1"},
        {"invariants/bounce/id", "1"}, {"invariants/drift/id", "1"}, {"invariants/mu/id", "1"},
        {"invariants/energy/id", "1"}, {"invariants/pphi/id", "1"}, {"invariants/samples/id", "1"},
        {"invariants/undefined/id", "1"}, {"invariants/undefined/bounce", "1"},
        {"invariants/undefined/equator", "1"}, {"invariants/undefined/drift", "1"},
        {"invariants/undefined/Lstar", "1"},
        {"losses/id", "1"}, {"losses/status", "1"}, {"losses/initial/L", "1"},
        {"losses/initial/alpha_eq", "rad"}, {"losses/initial/alpha_lc", "rad"},
        {"timing/cpu_seconds", "s"}, {"timing/steps", "1"}, {"timing/rank_cpu_seconds", "s"},
        {"timing/rank_particles", "1"},
    };
    for (size_t k = 0; k < sizeof units / sizeof units[0]; k++) {
        const char *path = units[k][0];
        /* every link on the way must exist (H5Lexists does not look past a
         * missing group) */
        char part[64];
        int ok = 1;
        for (const char *q = strchr(path, '/'); ok && q; q = strchr(q + 1, '/')) {
            snprintf(part, sizeof part, "%.*s", (int)(q - path), path);
            ok = H5Lexists(w->file, part, H5P_DEFAULT) > 0;
        }
        if (!ok || H5Lexists(w->file, path, H5P_DEFAULT) <= 0) continue;
        hid_t ds = H5Dopen2(w->file, path, H5P_DEFAULT);
        if (ds < 0) {
            w->bad = 1;
            continue;
        }
        if (H5Aexists(ds, "units") <= 0) attr_str(w, ds, "units", units[k][1]);
        H5Dclose(ds);
    }
    attr_str(w, w->file, "duration_units", "s");
}

int gcp_output_write(const struct gcp_scene *sc, const struct gcp_results *r, MPI_Comm comm,
                     struct gcp_error *err)
{
    int me, nranks;
    MPI_Comm_rank(comm, &me);
    MPI_Comm_size(comm, &nranks);
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL); /* errors are reported as messages, not stacks */
    char tmp[1100];
    temp_name(sc, comm, tmp, sizeof tmp);

    struct writer w = {.r = r, .total = sc->total, .compression = sc->compression, .comm = comm,
                       .output = sc->output, .t0 = wall()};
    w.last = w.t0;
    /* HDF5's OR of hyperslabs costs about the square of their number: past
     * ~32k runs of consecutive ids on a rank (2 M particles in 64-particle
     * chunks on 2 ranks) moving the rows is cheaper; below, it only adds
     * copies and collectives (measured slower at 3e6 particles on 2 ranks).
     * Trajectories are moved always, in blocks of whole chunk rows: each
     * chunk then comes from one rank, which deflates it, instead of being
     * gathered to one owner and then deflated there, and each rank's
     * selection is one hyperslab instead of a walk over every element
     * (2 ranks on the flagship: the trajectory write 0.27 -> 0.16 s, with
     * the chunk shape and the single collective transfer below). */
    int64_t runs = 0;
    for (int64_t k = 0; k < r->n; k++) runs += k == 0 || r->id[k] != r->id[k - 1] + 1;
    MPI_Allreduce(MPI_IN_PLACE, &runs, 1, MPI_INT64_T, MPI_MAX, comm);
    if (r->S) w.unit = gcp_writer_trajectory_rows(sc->total);
    /* Only the trajectories are moved where the runs are few: a contiguous
     * column goes in place with each rank's own pwrites, no collective,
     * where its move cost an Allreduce and an Alltoallv per column (~40 of
     * them on the flagship, each a wait for the slower rank). */
    w.move_all = runs > gcp_writer_spread_runs();
    if (nranks > 1 && (w.move_all || r->S)) gcp_writer_spread_plan(&w);
    MPI_Allreduce(MPI_IN_PLACE, &w.bad, 1, MPI_INT, MPI_MAX, comm);
    gcp_phase_mark("w-plan");
    if (w.bad) {
        gcp_writer_spread_free(&w);
        return gcp_error_set(err, GCP_ERR_STATE,
                             "%s: the ranks' rows are not particles 0..%lld each once (or out of "
                             "memory): nothing written",
                             sc->output, (long long)sc->total - 1);
    }
    hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
    H5Pset_fapl_mpio(fapl, comm, MPI_INFO_NULL);
    H5Pset_all_coll_metadata_ops(fapl, 1);
    H5Pset_coll_metadata_write(fapl, 1);
    hid_t fcpl = H5Pcreate(H5P_FILE_CREATE);
    gcp_h5_plists(sc, fcpl, fapl);
    w.file = H5Fcreate(tmp, H5F_ACC_TRUNC, fcpl, fapl);
    H5Pclose(fcpl);
    H5Pclose(fapl);
    int any_bad = w.file < 0;
    MPI_Allreduce(MPI_IN_PLACE, &any_bad, 1, MPI_INT, MPI_MAX, comm);
    if (any_bad) {
        if (w.file >= 0) H5Fclose(w.file);
        if (me == 0) remove(tmp);
        gcp_writer_spread_free(&w);
        return gcp_error_set(err, GCP_ERR_IO, "%s: cannot create '%s'", sc->output, tmp);
    }
    gcp_phase_mark("w-create");
    const int64_t need = size_bound(r, sc->total, comm);
    const int nospace = reserve_space(tmp, need, comm);
    gcp_phase_mark("w-reserve");
    if (nospace) {
        H5Fclose(w.file);
        gcp_writer_spread_free(&w);
        if (me == 0) remove(tmp);
        struct statvfs vfs;
        char dir[1100];
        snprintf(dir, sizeof dir, "%s", tmp);
        char *slash = strrchr(dir, '/');
        if (slash) slash[1] = '\0';
        else strcpy(dir, ".");
        const double avail = statvfs(dir, &vfs) == 0 ? (double)vfs.f_bavail * (double)vfs.f_frsize : -1.0;
        return gcp_error_set(err, GCP_ERR_IO,
                             "%s: the output needs up to %.3g MB, %s has %.3g MB free (%s): "
                             "nothing written",
                             sc->output, (double)need / 1e6, slash ? dir : ".", avail / 1e6,
                             strerror(nospace));
    }
    w.dxpl = H5Pcreate(H5P_DATASET_XFER);
    H5Pset_dxpl_mpio(w.dxpl, H5FD_MPIO_COLLECTIVE);
    /* all of a dataset's chunks in one collective transfer, not one round
     * per chunk (HDF5 picks the rounds below ~30 chunks per rank) */
    H5Pset_dxpl_mpio_chunk_opt(w.dxpl, H5FD_MPIO_CHUNK_ONE_IO);
    w.dxpl_ind = H5Pcreate(H5P_DATASET_XFER);
    H5Pset_dxpl_mpio(w.dxpl_ind, H5FD_MPIO_INDEPENDENT);

    /* every event table's counts and buffers, summed and agreed on once
     * for all of them (else each table agrees on its own) */
    if (sc->invariants || sc->events || r->hybrid)
        w.evcnt = gcp_output_event_counts(r, sc->total, &w.evbuf, &w.evcap, comm);
    gcp_h5_root_attrs(&w.bad, w.file, sc, nranks);
    write_particles(&w, sc);
    gcp_phase_mark("w-particles");
    if (r->S) write_trajectories(&w);
    gcp_phase_mark("w-traj");
    if (sc->invariants || sc->events) write_events(&w, sc, comm);
    gcp_phase_mark("w-events");
    if (r->hybrid) write_hybrid(&w, comm);
    write_timing(&w, comm, me, nranks);
    write_units(&w);
    gcp_phase_mark("w-timing+units");

    H5Pclose(w.dxpl);
    H5Pclose(w.dxpl_ind);
    free(w.evcnt);
    free(w.evbuf);
    gcp_writer_spread_free(&w);
    if (H5Fclose(w.file) < 0) w.bad = 1;
    MPI_Allreduce(MPI_IN_PLACE, &w.bad, 1, MPI_INT, MPI_MAX, comm);
    gcp_phase_mark("w-close");
    int renamed = 0, code = 0;
    if (me == 0) {
        if (w.bad) {
            remove(tmp);
        } else if (trim(tmp), rename(tmp, sc->output) == 0) {
            renamed = 1;
        } else {
            code = errno;
            remove(tmp);
        }
    }
    MPI_Bcast(&renamed, 1, MPI_INT, 0, comm);
    MPI_Bcast(&code, 1, MPI_INT, 0, comm);
    if (w.bad) return gcp_error_set(err, GCP_ERR_HDF5, "%s: writing the output failed", sc->output);
    if (!renamed)
        return gcp_error_set(err, GCP_ERR_IO, "%s: cannot rename the finished output: %s",
                             sc->output, strerror(code));
    return 0;
}
