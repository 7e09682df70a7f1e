/* Private: MPI work sharing. */
#ifndef GCPUSH_PAR_H
#define GCPUSH_PAR_H

#include <stdint.h>

#include <mpi.h>

/* A shared counter of work items 0 .. n-1 (MPI-3 one-sided atomics on rank
 * 0's window): every rank takes the next item when it is free, so ranks
 * that draw cheap particles take more; no rank only hands out work. */
struct gcp_par_counter {
    MPI_Win win;
    int64_t *base;  /* the counter itself (rank 0), else NULL */
    int64_t n;      /* items */
};

int gcp_par_counter_create(struct gcp_par_counter *c, int64_t n, MPI_Comm comm);
/* The next item, or -1 when all are taken (usable as gcp_next_chunk_fn). */
int64_t gcp_par_counter_next(void *counter);
void gcp_par_counter_free(struct gcp_par_counter *c);

#endif
