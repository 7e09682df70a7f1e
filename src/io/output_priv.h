/* Private to the output writer (output.c writes the groups, output_rows.c
 * moves and writes the rows). */
#ifndef GCPUSH_OUTPUT_PRIV_H
#define GCPUSH_OUTPUT_PRIV_H

#include <stdint.h>

#include <hdf5.h>
#include <mpi.h>

#include "gcpush/io.h"
#include "io_priv.h"

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
    int move_all;            /* every column moved (past gcp_writer_spread_runs runs), else
                              * only the chunked trajectories' */
    int64_t unit;            /* blocks are whole units of rows (trajectory chunk rows), 0: 1 */
    int64_t lo, hi;
    int *scount, *sdispl, *rcount, *rdispl; /* rows to / from each rank */
    int64_t *place;          /* received row j goes to row place[j] - lo */
    void *out;               /* a column's block */
    size_t out_cap;          /* its bytes */
    size_t widest;           /* bytes of the widest row `out` holds nr of */
    /* the received rows' places as runs of consecutive rows: those from
     * rank k are runs run0[k] .. run0[k+1]-1, run i at row run_at[i] - lo,
     * run_len[i] rows; run_disp, req, rtype: space for their exchange */
    int *run0, *run_len;
    int64_t *run_at;
    MPI_Aint *run_disp;
    MPI_Request *req;
    MPI_Datatype *rtype;
    const char *output;      /* for progress lines */
    double t0, last;         /* wall clock: write start, last progress line */
    int ndone;               /* datasets written */
    int64_t *evcnt;          /* the event tables' shared counts (output_events_priv.h), or NULL */
    void *evbuf;             /* with evcnt: their row buffers, evcap rows */
    int64_t evcap;
};

static inline double wall(void) { return MPI_Wtime(); }

/* Runs of consecutive ids per rank above which rows are moved. */
int64_t gcp_writer_spread_runs(void);
/* Plans the move of the rows (sets w->spread); w->bad on failure. */
void gcp_writer_spread_plan(struct writer *w);
void gcp_writer_spread_free(struct writer *w);
/* Creates dataset `name` of shape {total, d1, d2} (rank 1..3) with creation
 * properties dcpl and writes this rank's rows from data (collective). */
void gcp_writer_rows(struct writer *w, hid_t loc, const char *name, hid_t type, int rank,
                     hsize_t d1, hsize_t d2, const void *data, hid_t dcpl);
/* Rows per trajectory chunk of a file of `total` particles. */
int64_t gcp_writer_trajectory_rows(int64_t total);
/* Chunked, shuffled and deflated creation properties for trajectories. */
hid_t gcp_writer_trajectory_dcpl(const struct gcp_results *r, int64_t total, int rank, int level);
/* A small dataset written by rank 0 alone (others select nothing). */
void gcp_writer_rank0(struct writer *w, hid_t loc, const char *name, hid_t type, hsize_t n,
                      const void *data, int me);

#endif
