/* Private to io/: the column table of struct gcp_results, checkpoints. */
#ifndef GCPUSH_IO_PRIV_H
#define GCPUSH_IO_PRIV_H

#include <stddef.h>
#include <stdint.h>

#include "gcpush/io.h"

#define GCP_RESULTS_MAX_COLUMNS 32

struct gcp_results_column {
    const char *name;  /* the struct member's name */
    void **data;       /* address of the member (the array pointer) */
    size_t elem;       /* bytes per element */
    int64_t per_row;   /* elements per row */
};

/* Fills c with the columns r has (trajectory columns only when r->S > 0). */
size_t gcp_results_columns(struct gcp_results *r, struct gcp_results_column *c);

/* Storage of `bytes` for result columns and the writer's buffers, freed
 * with free(): from 2 MiB on aligned to 2 MiB and offered to the kernel
 * for transparent huge pages (results.c). */
void *gcp_io_alloc(size_t bytes);

/* HDF5 attributes common to the output files (h5attr.c); loc and type are
 * hid_t values (int64_t here, so this header needs no hdf5.h).  A failure
 * sets *bad. */
void gcp_h5_attr_str(int *bad, int64_t loc, const char *name, const char *value);
void gcp_h5_attr_num(int *bad, int64_t loc, const char *name, int64_t type, const void *v);
/* File creation and access properties (hid_t) for sc's output: dense
 * attribute storage when the run file text is too long for a compact one. */
void gcp_h5_plists(const struct gcp_scene *sc, int64_t fcpl, int64_t fapl);
/* The root attributes of every gcpush output file (DESIGN.md, HDF5 output). */
void gcp_h5_root_attrs(int *bad, int64_t file, const struct gcp_scene *sc, int nranks);

#endif
