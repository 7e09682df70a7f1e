/* The output file: one HDF5 file per run, written collectively by every rank
 * through MPI-IO (parallel HDF5).  Layout: DESIGN.md, "HDF5 output".
 *
 * Each rank holds its rows sorted by particle id.  Under MPI the rows are
 * moved first (one Alltoallv per column) so that each rank holds one block
 * of consecutive ids, and one collective H5Dwrite per dataset puts every
 * block in place (struct writer).  The file is
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

#include "gcpush/io.h"
#include "io_priv.h"
#include "output_priv.h"


struct writer {
    hid_t file;
    hid_t dxpl;              /* collective transfer */
    hid_t dxpl_ind;          /* independent transfer */
    const struct gcp_results *r;
    int compression;         /* trajectory deflate level, 0: none */
    int64_t total;           /* rows in the file */
    int bad;                 /* a call failed on this rank */
    /* Under MPI the rows are first moved so that rank k holds the ids
     * [lo, hi) = [k N / P, (k+1) N / P): each rank then writes one
     * hyperslab.  A selection of one hyperslab per run of consecutive ids
     * (self-scheduled 64-particle chunks: ~78 000 of them per rank for 1e7
     * particles) made HDF5's selection and collective write quadratic. */
    MPI_Comm comm;
    int spread;              /* rows moved (more than one rank) */
    int64_t lo, hi;
    int *scount, *sdispl, *rcount, *rdispl; /* rows to / from each rank */
    int64_t *place;          /* received row j goes to row place[j] - lo */
    const char *output;      /* for progress lines */
    double t0, last;         /* wall clock: write start, last progress line */
    int ndone;               /* datasets written */
};

static int progress_on = 1;
void gcp_output_progress(int on) { progress_on = on; }

static double wall(void) { return MPI_Wtime(); }

/* A progress line on rank 0 every 10 s of a write longer than 5 s. */
static void write_progress(struct writer *w, const char *name)
{
    w->ndone++;
    if (!progress_on) return;
    int me;
    MPI_Comm_rank(w->comm, &me);
    const double now = wall();
    if (me || now - w->t0 < 5.0 || now - w->last < 10.0) return;
    fprintf(stderr, "writing %s: %d datasets (last %s), %.0f s\n", w->output, w->ndone, name,
            now - w->t0);
    fflush(stderr);
    w->last = now;
}

/* Runs per rank above which rows are moved; GCP_SPREAD_RUNS overrides it
 * (tests force the move on small runs with 0).  The OR of one hyperslab per
 * run costs HDF5 time quadratic in the runs: 1e7 particles on 2 ranks took
 * 370 s with rows in place against 20 s moved (21.5 s on 1 rank), measured
 * on the idle 2-core build machine; below ~1000 runs either way is fast. */
static int64_t spread_runs(void)
{
    const char *e = getenv("GCP_SPREAD_RUNS");
    return e && *e ? strtoll(e, NULL, 10) : 1024;
}

static int64_t block_lo(int64_t N, int P, int k) { return (int64_t)((__int128)N * k / P); }

/* Plans the move: who sends which rows where, and where the received rows
 * go.  Every id 0..N-1 must arrive exactly once (restart_load and the push
 * guarantee it); otherwise w->bad. */
static void spread_plan(struct writer *w)
{
    const struct gcp_results *r = w->r;
    int me, P;
    MPI_Comm_rank(w->comm, &me);
    MPI_Comm_size(w->comm, &P);
    const int64_t N = w->total;
    w->lo = block_lo(N, P, me);
    w->hi = block_lo(N, P, me + 1);
    w->scount = calloc((size_t)P, sizeof(int));
    w->sdispl = calloc((size_t)P, sizeof(int));
    w->rcount = calloc((size_t)P, sizeof(int));
    w->rdispl = calloc((size_t)P, sizeof(int));
    int bad = !w->scount || !w->sdispl || !w->rcount || !w->rdispl;
    for (int64_t i = 0, k = 0; i < r->n && !bad; i++) {
        /* rows are sorted by id, so each rank's rows are one contiguous run */
        while (k + 1 < P && r->id[i] >= block_lo(N, P, (int)k + 1)) k++;
        w->scount[k]++;
    }
    MPI_Allreduce(MPI_IN_PLACE, &bad, 1, MPI_INT, MPI_MAX, w->comm);
    if (bad) {
        w->bad = 1;
        return;
    }
    MPI_Alltoall(w->scount, 1, MPI_INT, w->rcount, 1, MPI_INT, w->comm);
    int64_t nr = 0;
    for (int k = 0; k < P; k++) {
        w->sdispl[k] = k ? w->sdispl[k - 1] + w->scount[k - 1] : 0;
        w->rdispl[k] = (int)nr;
        nr += w->rcount[k];
    }
    w->place = malloc((size_t)(nr ? nr : 1) * sizeof *w->place);
    unsigned char *seen = calloc((size_t)(w->hi - w->lo ? w->hi - w->lo : 1), 1);
    bad = !w->place || !seen || nr != w->hi - w->lo;
    MPI_Allreduce(MPI_IN_PLACE, &bad, 1, MPI_INT, MPI_MAX, w->comm);
    if (!bad) {
        MPI_Alltoallv(r->id, w->scount, w->sdispl, MPI_INT64_T, w->place, w->rcount, w->rdispl,
                      MPI_INT64_T, w->comm);
        for (int64_t j = 0; j < nr && !bad; j++) {
            const int64_t q = w->place[j] - w->lo;
            bad = q < 0 || q >= nr || seen[q];
            if (!bad) seen[q] = 1;
        }
    }
    free(seen);
    w->bad |= bad;
    w->spread = 1;
}

static void spread_free(struct writer *w)
{
    free(w->scount);
    free(w->sdispl);
    free(w->rcount);
    free(w->rdispl);
    free(w->place);
}

/* This rank's block of rows [lo, hi) of a column whose rows (`row` bytes
 * each) are `data` in the rank's order: malloc'ed, or NULL on failure. */
static void *spread_column(struct writer *w, const void *data, size_t row)
{
    const int64_t nr = w->hi - w->lo;
    char *in = malloc((size_t)(nr ? nr : 1) * row), *out = malloc((size_t)(nr ? nr : 1) * row);
    int bad = !in || !out;
    MPI_Allreduce(MPI_IN_PLACE, &bad, 1, MPI_INT, MPI_MAX, w->comm);
    if (bad) {
        free(in);
        free(out);
        return NULL;
    }
    MPI_Datatype t;
    MPI_Type_contiguous((int)row, MPI_BYTE, &t);
    MPI_Type_commit(&t);
    MPI_Alltoallv(data, w->scount, w->sdispl, t, in, w->rcount, w->rdispl, t, w->comm);
    MPI_Type_free(&t);
    for (int64_t j = 0; j < nr; j++)
        memcpy(out + (size_t)(w->place[j] - w->lo) * row, in + (size_t)j * row, row);
    free(in);
    return out;
}

/* Selects this rank's rows (runs of consecutive ids) in a dataset space of
 * dims {total, d1, d2} (rank 1..3). */
static void select_rows(hid_t fspace, const struct gcp_results *r, int rank, const hsize_t *dims)
{
    H5Sselect_none(fspace);
    int64_t k = 0;
    while (k < r->n) {
        int64_t e = k + 1;
        while (e < r->n && r->id[e] == r->id[e - 1] + 1) e++;
        hsize_t start[3] = {(hsize_t)r->id[k], 0, 0};
        hsize_t count[3] = {(hsize_t)(e - k), rank > 1 ? dims[1] : 1, rank > 2 ? dims[2] : 1};
        H5Sselect_hyperslab(fspace, H5S_SELECT_OR, start, NULL, count, NULL);
        k = e;
    }
}

/* Creates dataset `name` of shape {total, tail...} and writes this rank's
 * rows from `data` (rows in id order, contiguous). */
static void write_rows_dcpl(struct writer *w, hid_t loc, const char *name, hid_t type, int rank,
                            hsize_t d1, hsize_t d2, const void *data, hid_t dcpl)
{
    hsize_t dims[3] = {(hsize_t)w->total, d1, d2};
    const hsize_t per_row = (rank > 1 ? d1 : 1) * (rank > 2 ? d2 : 1);
    void *block = NULL;
    int64_t nrows = w->r->n;
    if (w->spread) {
        block = spread_column(w, data, per_row * H5Tget_size(type));
        if (!block) w->bad = 1;
        data = block;
        nrows = w->hi - w->lo;
    }
    hid_t fspace = H5Screate_simple(rank, dims, NULL);
    hid_t dset = H5Dcreate2(loc, name, type, fspace, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    if (w->spread) {
        hsize_t start[3] = {(hsize_t)w->lo, 0, 0};
        hsize_t count[3] = {(hsize_t)nrows, rank > 1 ? d1 : 1, rank > 2 ? d2 : 1};
        if (nrows) H5Sselect_hyperslab(fspace, H5S_SELECT_SET, start, NULL, count, NULL);
        else H5Sselect_none(fspace);
    } else {
        select_rows(fspace, w->r, rank, dims);
    }
    hsize_t mdims = (hsize_t)nrows * per_row;
    hsize_t one = 1;
    hid_t mspace = H5Screate_simple(1, mdims ? &mdims : &one, NULL);
    if (!mdims) H5Sselect_none(mspace);
    /* every rank calls H5Dwrite (collective), with a dummy buffer if the
     * move failed: w->bad then fails the whole file */
    static const char dummy[64];
    /* a rank with no rows has no buffer (NULL data) and nothing to write; a
     * NULL buffer with rows is a failed move (already counted above) */
    if (!data) {
        H5Sselect_none(fspace);
        H5Sselect_none(mspace);
        if (nrows == 0 && !w->spread) data = dummy;
    }
    /* one contiguous block per rank: independent writes, one pwrite each,
     * without the two-phase exchange of a collective write; chunked
     * (filtered) datasets need the collective one */
    const hid_t dxpl = w->spread && dcpl == H5P_DEFAULT ? w->dxpl_ind : w->dxpl;
    if (dset < 0 || H5Dwrite(dset, type, mspace, fspace, dxpl, data ? data : dummy) < 0 ||
        !data)
        w->bad = 1;
    H5Sclose(mspace);
    H5Sclose(fspace);
    if (dset >= 0) H5Dclose(dset);
    free(block);
    write_progress(w, name);
}

static void write_rows(struct writer *w, hid_t loc, const char *name, hid_t type, int rank,
                       hsize_t d1, hsize_t d2, const void *data)
{
    write_rows_dcpl(w, loc, name, type, rank, d1, d2, data, H5P_DEFAULT);
}

/* Trajectories are large and smooth: chunked (64 particles x up to 1024
 * samples), with byte shuffle + deflate at the run file's level ([output]
 * compression, default 1), which parallel HDF5 applies in collective writes. */
static hid_t trajectory_dcpl(const struct gcp_results *r, int64_t total, int rank, int level)
{
    hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    if (total == 0) return dcpl;
    hsize_t chunk[3] = {(hsize_t)(total < 64 ? total : 64),
                        (hsize_t)(r->S < 1024 ? r->S : 1024), 3};
    H5Pset_chunk(dcpl, rank, chunk);
    if (level > 0 && H5Zfilter_avail(H5Z_FILTER_DEFLATE)) {
        H5Pset_shuffle(dcpl);
        H5Pset_deflate(dcpl, (unsigned)level);
    }
    return dcpl;
}

/* A small dataset written by rank 0 alone (others select nothing). */
static void write_rank0(struct writer *w, hid_t loc, const char *name, hid_t type, hsize_t n,
                        const void *data, int me)
{
    hid_t fspace = H5Screate_simple(1, &n, NULL);
    hid_t dset = H5Dcreate2(loc, name, type, fspace, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    hid_t mspace = H5Screate_simple(1, &n, NULL);
    if (me != 0) {
        H5Sselect_none(fspace);
        H5Sselect_none(mspace);
    }
    if (dset < 0 || H5Dwrite(dset, type, mspace, fspace, w->dxpl, data) < 0) w->bad = 1;
    H5Sclose(mspace);
    H5Sclose(fspace);
    if (dset >= 0) H5Dclose(dset);
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
    H5Gclose(gf);
    H5Gclose(g);
}

static void write_trajectories(struct writer *w)
{
    const struct gcp_results *r = w->r;
    hid_t g = group(w, w->file, "trajectories");
    const hsize_t S = (hsize_t)r->S;
    hid_t d2 = trajectory_dcpl(r, w->total, 2, w->compression);
    hid_t d3 = trajectory_dcpl(r, w->total, 3, w->compression);
    write_rows_dcpl(w, g, "t", H5T_NATIVE_DOUBLE, 2, S, 0, r->traj_t, d2);
    write_rows_dcpl(w, g, "x", H5T_NATIVE_DOUBLE, 3, S, 3, r->traj_x, d3);
    if (r->gc || r->hybrid) write_rows_dcpl(w, g, "ppar", H5T_NATIVE_DOUBLE, 2, S, 0, r->traj_ppar, d2);
    if (!r->gc) write_rows_dcpl(w, g, "u", H5T_NATIVE_DOUBLE, 3, S, 3, r->traj_u, d3);
    if (r->hybrid) write_rows_dcpl(w, g, "mode", H5T_NATIVE_INT8, 2, S, 0, r->traj_mode, d2);
    H5Pclose(d2);
    H5Pclose(d3);
    write_rows(w, g, "count", H5T_NATIVE_INT64, 1, 0, 0, r->traj_count);
    H5Gclose(g);
}

/* The event tables (output_events.c) with this writer's file, transfer and rows. */
static struct gcp_ev_writer ev_writer(const struct writer *w)
{
    return (struct gcp_ev_writer){w->file, w->dxpl, w->r, w->total, 0};
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
        write_rank0(w, g, "rank_cpu_seconds", H5T_NATIVE_DOUBLE, (hsize_t)nranks, rank_cpu, me);
        write_rank0(w, g, "rank_particles", H5T_NATIVE_INT64, (hsize_t)nranks, rank_n, me);
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
    int64_t ev = r->ev.n;
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
     * copies and collectives (measured slower at 3e6 particles on 2 ranks) */
    int64_t runs = 0;
    for (int64_t k = 0; k < r->n; k++) runs += k == 0 || r->id[k] != r->id[k - 1] + 1;
    MPI_Allreduce(MPI_IN_PLACE, &runs, 1, MPI_INT64_T, MPI_MAX, comm);
    if (nranks > 1 && runs > spread_runs()) spread_plan(&w);
    MPI_Allreduce(MPI_IN_PLACE, &w.bad, 1, MPI_INT, MPI_MAX, comm);
    if (w.bad) {
        spread_free(&w);
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
        spread_free(&w);
        return gcp_error_set(err, GCP_ERR_IO, "%s: cannot create '%s'", sc->output, tmp);
    }
    const int64_t need = size_bound(r, sc->total, comm);
    const int nospace = reserve_space(tmp, need, comm);
    if (nospace) {
        H5Fclose(w.file);
        spread_free(&w);
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
    w.dxpl_ind = H5Pcreate(H5P_DATASET_XFER);
    H5Pset_dxpl_mpio(w.dxpl_ind, H5FD_MPIO_INDEPENDENT);

    gcp_h5_root_attrs(&w.bad, w.file, sc, nranks);
    write_particles(&w, sc);
    if (r->S) write_trajectories(&w);
    if (sc->invariants || sc->events) write_events(&w, sc, comm);
    if (r->hybrid) write_hybrid(&w, comm);
    write_timing(&w, comm, me, nranks);
    write_units(&w);

    H5Pclose(w.dxpl);
    H5Pclose(w.dxpl_ind);
    spread_free(&w);
    if (H5Fclose(w.file) < 0) w.bad = 1;
    MPI_Allreduce(MPI_IN_PLACE, &w.bad, 1, MPI_INT, MPI_MAX, comm);
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
