/* Private to io/: the event tables' writer (output_events.c), called by the
 * output writer (output.c). */
#ifndef GCPUSH_OUTPUT_EVENTS_PRIV_H
#define GCPUSH_OUTPUT_EVENTS_PRIV_H

#include <stddef.h>
#include <stdint.h>

#include <hdf5.h>

#include "gcpush/io.h"

/* What the event tables need of the output writer. */
struct gcp_ev_writer {
    hid_t file;
    hid_t dxpl;                   /* transfer of the rows (independent) */
    const struct gcp_results *r;
    int64_t total;                /* particles in the file */
    int bad;                      /* a call failed on this rank */
    int64_t *cnt;                 /* every table's counts (gcp_output_event_counts), or
                                   * NULL: each table allocates and agrees on its own */
    void *buf;                    /* with cnt: row buffers for bufcap rows */
    int64_t bufcap;
};

/* Collective: the per-particle counts of every event kind (kind k:
 * [k total, (k + 1) total)) summed over ranks, and in *buf the row buffers
 * of the largest table of this rank (*bufcap rows), all allocations agreed
 * on in the one Allreduce; NULL (and *buf NULL) where an allocation failed
 * on a rank or the counts would pass 64 MiB (then each table counts and
 * agrees on its own).  Free both. */
int64_t *gcp_output_event_counts(const struct gcp_results *r, int64_t total, void **buf,
                                 int64_t *bufcap, MPI_Comm comm);

/* One table: id, t, then the named value slots (count values from slot). */
struct gcp_ev_col {
    const char *name;
    int slot, rank;     /* first value slot; dataset rank (1: (M), 2: (M,d1), 3: (M,d1,d2)) */
    hsize_t d1, d2;
    const char *units;
    int undef_enum;     /* values are enum gcp_undefined: an int32 HDF5 enum column */
};

/* Table `name` under parent of the events of kind: id, t, then the columns;
 * with_status: 0 no int column, 1 "status" (losses: enum gcp_status), 2
 * "mode" (method = hybrid: the mode of the sample that closed the row).
 * Collective. */
void gcp_output_event_table(struct gcp_ev_writer *w, hid_t parent, const char *name, int kind,
                            const struct gcp_ev_col *cols, size_t ncols, int with_status,
                            MPI_Comm comm);
/* The /invariants group of sc's [diagnostics].  Collective. */
void gcp_output_invariants(struct gcp_ev_writer *w, const struct gcp_scene *sc, MPI_Comm comm);

#endif
