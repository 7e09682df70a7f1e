/* The output file's rows (output_priv.h): each rank writes its runs of
 * consecutive ids in place, or, past ~1000 runs, its rows are first moved
 * so that it holds one block of consecutive ids; one H5Dwrite per dataset
 * and rank (independent, collective for chunked datasets); progress lines
 * for long writes. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "output_priv.h"

static int progress_on = 1;
void gcp_output_progress(int on) { progress_on = on; }

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
int64_t gcp_writer_spread_runs(void)
{
    const char *e = getenv("GCP_SPREAD_RUNS");
    return e && *e ? strtoll(e, NULL, 10) : 1024;
}

/* Rank k's first row: blocks of whole units (trajectory chunk rows) as
 * even as can be; the last unit may be short. */
static int64_t block_lo(int64_t N, int P, int k, int64_t unit)
{
    const int64_t units = (N + unit - 1) / unit;
    const int64_t lo = unit * (int64_t)((__int128)units * k / P);
    return lo < N ? lo : N;
}

/* n items in pieces of at most `most`, as even as can be: the piece. */
static int64_t even_piece(int64_t n, int64_t most)
{
    const int64_t pieces = (n + most - 1) / most;
    return pieces ? (n + pieces - 1) / pieces : 1;
}

int64_t gcp_writer_trajectory_rows(int64_t total) { return even_piece(total, 64); }

/* A buffer of the writer's (grown, kept across columns, freed in
 * gcp_writer_spread_free): a fresh malloc per column of the trajectories
 * is fresh pages, faulted in and zeroed each time (2 x 12 MB of them per
 * rank and column on the flagship). */
static void *scratch(void **buf, size_t *cap, size_t bytes)
{
    if (bytes > *cap) {
        free(*buf);
        *buf = gcp_io_alloc(bytes);
        *cap = *buf ? bytes : 0;
    }
    return *buf;
}

/* Plans the move: who sends which rows where, and where the received rows
 * go.  Every id 0..N-1 must arrive exactly once (restart_load and the push
 * guarantee it); otherwise w->bad. */
void gcp_writer_spread_plan(struct writer *w)
{
    const struct gcp_results *r = w->r;
    int me, P;
    MPI_Comm_rank(w->comm, &me);
    MPI_Comm_size(w->comm, &P);
    const int64_t N = w->total;
    const int64_t unit = w->unit > 0 ? w->unit : 1;
    w->lo = block_lo(N, P, me, unit);
    w->hi = block_lo(N, P, me + 1, unit);
    w->scount = calloc((size_t)P, sizeof(int));
    w->sdispl = calloc((size_t)P, sizeof(int));
    w->rcount = calloc((size_t)P, sizeof(int));
    w->rdispl = calloc((size_t)P, sizeof(int));
    int bad = !w->scount || !w->sdispl || !w->rcount || !w->rdispl;
    for (int64_t i = 0, k = 0; i < r->n && !bad; i++) {
        /* rows are sorted by id, so each rank's rows are one contiguous run */
        while (k + 1 < P && r->id[i] >= block_lo(N, P, (int)k + 1, unit)) k++;
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
    /* the block's buffer, once, for the widest row moved (a trajectory
     * row, or the 32-byte species name), reused by every column: it is
     * the one fresh memory of the move (first touches cost ~13 us a 4 KiB
     * page in the build VM; one buffer per column size and one for the
     * received rows were 2-3x as much, ~9 MB per rank of the flagship) */
    struct gcp_results_column c[GCP_RESULTS_MAX_COLUMNS];
    const size_t nc = gcp_results_columns((struct gcp_results *)r, c);
    size_t widest = 32;
    for (size_t k = 0; k < nc; k++) {
        const size_t row = (size_t)c[k].per_row * c[k].elem;
        widest = row > widest ? row : widest;
    }
    if (!bad && !scratch(&w->out, &w->out_cap, (size_t)(nr ? nr : 1) * widest)) bad = 1;
    w->widest = widest;
    /* runs of consecutive places among each rank's rows (its rows come in
     * id order), the same for every column */
    w->run0 = malloc((size_t)(P + 1) * sizeof *w->run0);
    w->run_len = malloc((size_t)(nr ? nr : 1) * sizeof *w->run_len);
    w->run_at = malloc((size_t)(nr ? nr : 1) * sizeof *w->run_at);
    w->run_disp = malloc((size_t)(nr ? nr : 1) * sizeof *w->run_disp);
    w->req = malloc((size_t)(2 * P) * sizeof *w->req);
    w->rtype = malloc((size_t)P * sizeof *w->rtype);
    bad |= !w->run0 || !w->run_len || !w->run_at || !w->run_disp || !w->req || !w->rtype;
    for (int k = 0, runs = 0; k < P && !bad; k++) {
        w->run0[k] = runs;
        for (int j = w->rdispl[k]; j < w->rdispl[k] + w->rcount[k]; j++) {
            if (j > w->rdispl[k] && w->place[j] == w->place[j - 1] + 1) {
                w->run_len[runs - 1]++;
                continue;
            }
            w->run_at[runs] = w->place[j];
            w->run_len[runs++] = 1;
        }
        w->run0[k + 1] = runs;
    }
    w->bad |= bad;
    w->spread = 1;
}

void gcp_writer_spread_free(struct writer *w)
{
    free(w->scount);
    free(w->sdispl);
    free(w->rcount);
    free(w->rdispl);
    free(w->place);
    free(w->out);
    free(w->run0);
    free(w->run_len);
    free(w->run_at);
    free(w->run_disp);
    free(w->req);
    free(w->rtype);
    w->out = NULL;
    w->out_cap = 0;
}

/* This rank's block of rows [lo, hi) of a column whose rows (`row` bytes
 * each) are `data` in the rank's order: the writer's buffer w->out (valid
 * until the next column), or NULL on failure.  The rows that stay on this
 * rank are copied straight to their place; the others are received
 * straight into theirs (a datatype per sending rank: its runs of
 * consecutive places), not into a buffer of their own and then copied. */
static void *spread_column(struct writer *w, const void *data, size_t row)
{
    int me, P;
    MPI_Comm_rank(w->comm, &me);
    MPI_Comm_size(w->comm, &P);
    const int64_t nr = w->hi - w->lo;
    if (row > w->widest) { /* not planned for (the same on every rank: `row` is the column's) */
        int bad = !scratch(&w->out, &w->out_cap, (size_t)(nr ? nr : 1) * row);
        MPI_Allreduce(MPI_IN_PLACE, &bad, 1, MPI_INT, MPI_MAX, w->comm);
        if (bad) return NULL;
        w->widest = row;
    }
    char *out = w->out;
    MPI_Datatype rowt;
    MPI_Type_contiguous((int)row, MPI_BYTE, &rowt);
    MPI_Type_commit(&rowt);
    int nreq = 0, ntypes = 0;
    for (int k = 0; k < P; k++) {
        if (k == me || w->rcount[k] == 0) continue;
        const int r0 = w->run0[k], runs = w->run0[k + 1] - r0;
        for (int i = r0; i < r0 + runs; i++)
            w->run_disp[i] = (MPI_Aint)((size_t)(w->run_at[i] - w->lo) * row);
        MPI_Type_create_hindexed(runs, w->run_len + r0, w->run_disp + r0, rowt, &w->rtype[ntypes]);
        MPI_Type_commit(&w->rtype[ntypes]);
        MPI_Irecv(out, 1, w->rtype[ntypes++], k, 0, w->comm, &w->req[nreq++]);
    }
    for (int k = 0; k < P; k++)
        if (k != me && w->scount[k])
            MPI_Isend((const char *)data + (size_t)w->sdispl[k] * row, w->scount[k], rowt, k, 0,
                      w->comm, &w->req[nreq++]);
    /* this rank's own rows, while the others' are under way */
    const int64_t *pl = w->place + w->rdispl[me];
    const char *own = (const char *)data + (size_t)w->sdispl[me] * row;
    for (int j = 0; j < w->rcount[me]; j++)
        memcpy(out + (size_t)(pl[j] - w->lo) * row, own + (size_t)j * row, row);
    if (nreq) MPI_Waitall(nreq, w->req, MPI_STATUSES_IGNORE);
    for (int k = 0; k < ntypes; k++) MPI_Type_free(&w->rtype[k]);
    MPI_Type_free(&rowt);
    return out;
}

/* Selects this rank's rows (runs of consecutive ids) in a dataset space of
 * dims {total, d1, d2} (rank 1..3). */
static void select_rows(hid_t fspace, const struct gcp_results *r, int rank, const hsize_t *dims)
{
    H5Sselect_none(fspace);
    int64_t k = 0;
    /* the first run SET, not OR'ed onto none: a single run (one rank's
     * sorted rows) stays a regular hyperslab, which HDF5 maps onto chunks
     * block by block instead of element by element */
    H5S_seloper_t op = H5S_SELECT_SET;
    while (k < r->n) {
        int64_t e = k + 1;
        while (e < r->n && r->id[e] == r->id[e - 1] + 1) e++;
        hsize_t start[3] = {(hsize_t)r->id[k], 0, 0};
        hsize_t count[3] = {(hsize_t)(e - k), rank > 1 ? dims[1] : 1, rank > 2 ? dims[2] : 1};
        H5Sselect_hyperslab(fspace, op, start, NULL, count, NULL);
        op = H5S_SELECT_OR;
        k = e;
    }
}

/* Creates dataset `name` of shape {total, tail...} and writes this rank's
 * rows from `data` (rows in id order, contiguous). */
void gcp_writer_rows(struct writer *w, hid_t loc, const char *name, hid_t type, int rank,
                     hsize_t d1, hsize_t d2, const void *data, hid_t dcpl)
{
    hsize_t dims[3] = {(hsize_t)w->total, d1, d2};
    const hsize_t per_row = (rank > 1 ? d1 : 1) * (rank > 2 ? d2 : 1);
    int64_t nrows = w->r->n;
    const int moved = w->spread && (w->move_all || dcpl != H5P_DEFAULT);
    if (moved) {
        data = spread_column(w, data, per_row * H5Tget_size(type));
        if (!data) w->bad = 1;
        nrows = w->hi - w->lo;
    }
    hid_t fspace = H5Screate_simple(rank, dims, NULL);
    hid_t dset = H5Dcreate2(loc, name, type, fspace, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    if (moved) {
        hsize_t start[3] = {(hsize_t)w->lo, 0, 0};
        hsize_t count[3] = {(hsize_t)nrows, rank > 1 ? d1 : 1, rank > 2 ? d2 : 1};
        if (nrows) H5Sselect_hyperslab(fspace, H5S_SELECT_SET, start, NULL, count, NULL);
        else H5Sselect_none(fspace);
    } else {
        select_rows(fspace, w->r, rank, dims);
    }
    /* the rows in memory in the dataset's own shape {nrows, d1, d2}: where
     * the file selection is one block, HDF5 then sees the two selections of
     * the same shape and maps a chunked dataset's chunks in whole blocks; a
     * flat memory space made it walk every element (H5S_select_iterate:
     * ~1e6 calls for the flagship's trajectory x on one rank) */
    hsize_t mdims[3] = {(hsize_t)nrows, d1, d2};
    hsize_t one = 1;
    const hsize_t mcount = (hsize_t)nrows * per_row;
    hid_t mspace = mcount ? H5Screate_simple(rank, mdims, NULL) : H5Screate_simple(1, &one, NULL);
    if (!mcount) H5Sselect_none(mspace);
    /* every rank calls H5Dwrite (collective), with a dummy buffer if the
     * move failed: w->bad then fails the whole file */
    static const char dummy[64];
    /* a rank with no rows has no buffer (NULL data) and nothing to write; a
     * NULL buffer with rows is a failed move (already counted above) */
    if (!data) {
        H5Sselect_none(fspace);
        H5Sselect_none(mspace);
        if (nrows == 0 && !moved) data = dummy;
    }
    /* contiguous datasets: independent writes, each rank's runs of rows
     * with its own pwrites.  A collective write's two-phase exchange cost
     * 2 ranks about 20 ms a dataset (0.33 s of /particles, 0.97 s of the
     * event tables of tests/bench/mpi_scaling.sh, under load) against 2 ms
     * for all independent ones, for the same bytes.  Chunked (filtered)
     * datasets need the collective write. */
    const hid_t dxpl = dcpl == H5P_DEFAULT ? w->dxpl_ind : w->dxpl;
    if (dset < 0 || H5Dwrite(dset, type, mspace, fspace, dxpl, data ? data : dummy) < 0 ||
        !data)
        w->bad = 1;
    H5Sclose(mspace);
    H5Sclose(fspace);
    if (dset >= 0) H5Dclose(dset);
    write_progress(w, name);
}

/* Trajectories are large and smooth: chunked (up to 64 particles x 1024
 * samples), with byte shuffle + deflate at the run file's level ([output]
 * compression, default 1), which parallel HDF5 applies in collective
 * writes.  The chunks tile the dataset in pieces as even as can be (the
 * flagship's 90 x 4133 are 45 x 827, not 64 x 1024): HDF5 reads back,
 * inflates and rewrites a chunk that the write does not cover whole, which
 * an edge chunk never is, and 64 x 1024 left every chunk row of the
 * flagship's with one. */
hid_t gcp_writer_trajectory_dcpl(const struct gcp_results *r, int64_t total, int rank, int level)
{
    hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    if (total == 0) return dcpl;
    hsize_t chunk[3] = {(hsize_t)gcp_writer_trajectory_rows(total),
                        (hsize_t)even_piece(r->S, 1024), 3};
    H5Pset_chunk(dcpl, rank, chunk);
    if (level > 0 && H5Zfilter_avail(H5Z_FILTER_DEFLATE)) {
        H5Pset_shuffle(dcpl);
        H5Pset_deflate(dcpl, (unsigned)level);
    }
    return dcpl;
}

/* A small dataset written by rank 0 alone (others select nothing). */
void gcp_writer_rank0(struct writer *w, hid_t loc, const char *name, hid_t type, hsize_t n,
                      const void *data, int me)
{
    hid_t fspace = H5Screate_simple(1, &n, NULL);
    hid_t dset = H5Dcreate2(loc, name, type, fspace, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    hid_t mspace = H5Screate_simple(1, &n, NULL);
    if (me != 0) {
        H5Sselect_none(fspace);
        H5Sselect_none(mspace);
    }
    if (dset < 0 || H5Dwrite(dset, type, mspace, fspace, w->dxpl_ind, data) < 0) w->bad = 1;
    H5Sclose(mspace);
    H5Sclose(fspace);
    if (dset >= 0) H5Dclose(dset);
}
