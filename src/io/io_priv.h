/* Private to io/: the column table of struct gcp_results, checkpoints. */
#ifndef GCPUSH_IO_PRIV_H
#define GCPUSH_IO_PRIV_H

#include <stddef.h>
#include <stdint.h>

#include "gcpush/io.h"

#define GCP_RESULTS_MAX_COLUMNS 24

struct gcp_results_column {
    const char *name;  /* the struct member's name */
    void **data;       /* address of the member (the array pointer) */
    size_t elem;       /* bytes per element */
    int64_t per_row;   /* elements per row */
};

/* Fills c with the columns r has (trajectory columns only when r->S > 0). */
size_t gcp_results_columns(struct gcp_results *r, struct gcp_results_column *c);

#endif
