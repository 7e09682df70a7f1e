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

/* Open MPI's start-up where every rank is on this node (transport.c):
 * called before MPI_Init, it asks for the ob1 point-to-point layer (no
 * probing for network hardware), the self and vader (shared memory)
 * transports, the collective and one-sided components that one node
 * uses, no hwloc plugins (PCI, OpenGL, OpenCL devices, libxml2), a yield
 * of the core while waiting in MPI, the run-time components an application
 * process selects anyway (GCP_PAR_RTE) and, in a
 * process started without mpirun, for no helper daemon and a private
 * session directory (GCP_PAR_SESSION) -- each only where
 * neither the environment nor Open MPI's parameter files choose already,
 * and never under a launcher that does not say all ranks share the node.
 * Returns what it set (GCP_PAR_* bits); nothing with another MPI.
 * gcp_par_local_defaults_for is its decision alone: environment lookups
 * through `get`, the parameter files `files` (NULL-terminated). */
enum {
    GCP_PAR_OB1 = 1,
    GCP_PAR_ISOLATED = 2,
    GCP_PAR_BTL = 4,   /* btl = self,vader */
    GCP_PAR_COLL = 8,  /* coll = basic,libnbc,self,tuned */
    GCP_PAR_OSC = 16,  /* osc = sm */
    GCP_PAR_HWLOC = 32, /* HWLOC_PLUGINS_BLACKLIST: no I/O device or XML plugins */
    GCP_PAR_YIELD = 64, /* mpi_yield_when_idle = 1 */
    /* the run-time layer's components an application process selects
     * anyway, so that the others are not loaded (transport.c) */
    GCP_PAR_STATE = 128,   /* state = app */
    GCP_PAR_ERRMGR = 256,  /* errmgr = default_app */
    GCP_PAR_SCHIZO = 512,  /* schizo = orte */
    GCP_PAR_SHMEM = 1024,  /* shmem = mmap */
    GCP_PAR_REACHABLE = 2048, /* reachable = weighted (only TCP asks it; with GCP_PAR_BTL only) */
    /* a singleton whose user chose no session directory: a private one,
     * removed at exit (transport.c; gcp_par_abort instead of MPI_Abort) */
    GCP_PAR_SESSION = 4096,
    GCP_PAR_RTE = GCP_PAR_STATE | GCP_PAR_ERRMGR | GCP_PAR_SCHIZO | GCP_PAR_SHMEM | GCP_PAR_REACHABLE,
    GCP_PAR_ONE_NODE = GCP_PAR_OB1 | GCP_PAR_BTL | GCP_PAR_COLL | GCP_PAR_OSC | GCP_PAR_HWLOC |
                       GCP_PAR_YIELD | GCP_PAR_RTE
};
typedef const char *(*gcp_par_getenv)(void *ctx, const char *name);
unsigned gcp_par_local_defaults(void);
unsigned gcp_par_local_defaults_for(gcp_par_getenv get, void *ctx, const char *const *files);
/* After MPI_Init: TCP_NODELAY on this process's TCP connections to this
 * host (the PMIx server's), whose small one-way messages in MPI_Finalize
 * otherwise wait out the server's delayed acknowledgement (transport.c). */
void gcp_par_nodelay(void);
/* MPI_Abort, after removing a singleton's private session directory
 * (GCP_PAR_SESSION), which MPI_Abort would leave: it exits without atexit. */
void gcp_par_abort(MPI_Comm comm, int code);

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
