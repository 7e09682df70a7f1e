/* Private: MPI work sharing and progress counters. */
#ifndef GCPUSH_PAR_H
#define GCPUSH_PAR_H

#include <stdint.h>

#include <mpi.h>

/* Shared counters in rank 0's window (MPI-3 one-sided atomics):
 *   [0] next work item, [1] particles done, [2] particle-steps done.
 * Every rank takes the next item when it is free, so ranks that draw cheap
 * particles take more; no rank only hands out work. */
struct gcp_par_counter {
    MPI_Win win;
    int64_t *base;  /* the counters (rank 0), else NULL */
    int64_t n;      /* work items */
};

int gcp_par_counter_create(struct gcp_par_counter *c, int64_t n, MPI_Comm comm);
/* The next item, or -1 when all are taken. */
int64_t gcp_par_counter_take(struct gcp_par_counter *c);
/* Adds finished particles and steps to the shared totals. */
void gcp_par_counter_report(struct gcp_par_counter *c, int64_t particles, int64_t steps);
/* Reads the totals (any rank; cheap on rank 0). */
void gcp_par_counter_totals(struct gcp_par_counter *c, int64_t *particles, int64_t *steps);
void gcp_par_counter_free(struct gcp_par_counter *c);

/* Per-rank phase timing, on only with GCPUSH_TIMING=1 in the environment
 * (phases.c); every call is a no-op otherwise.  gcp_phase_start first
 * (before MPI_Init: the first phase runs from the process's start); each
 * gcp_phase_mark(name) closes the phase begun at the previous mark (name:
 * a string literal); gcp_phase_wait(t) adds the wall time since
 * t = gcp_phase_clock() to the waits in the shared counter; gcp_phase_busy
 * adds the CPU seconds spent pushing chunks; gcp_phase_report prints this
 * rank's line on stderr. */
void gcp_phase_start(void);
int gcp_phase_on(void);
void gcp_phase_mark(const char *name);
double gcp_phase_clock(void);
void gcp_phase_wait(double since);
void gcp_phase_busy(double cpu_seconds);
void gcp_phase_report(int me, int nranks);

#endif
