/* Private to the result rows (src/run/results.c) and their writers in io/
 * (output, checkpoints): the column table of struct gcp_results and the
 * allocator of its columns. */
#ifndef GCPUSH_RESULTS_PRIV_H
#define GCPUSH_RESULTS_PRIV_H

#include <stddef.h>
#include <stdint.h>

#include "gcpush/results.h"

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
 * for transparent huge pages (results.c; named for its first user, io/). */
void *gcp_io_alloc(size_t bytes);

#endif
