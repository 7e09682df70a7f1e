/* gcpush/results.h -- per-rank result rows of a scene, in memory.
 *
 * The run layer's engine fills them (gcp_scene_push, run.h; the sweep), the
 * io layer writes them (gcp_output_write, io.h) and saves them to and loads
 * them from checkpoints.  Nothing here touches a file, MPI or HDF5.
 */
#ifndef GCPUSH_RESULTS_H
#define GCPUSH_RESULTS_H

#include <stdint.h>

#include "error.h"
#include "invariants.h"
#include "api.h"
GCP_API_BEGIN

#ifdef __cplusplus
extern "C" {
#endif

struct gcp_results {
    int64_t n, cap;        /* rows held, rows allocated */
    int64_t S;             /* trajectory samples per particle (0: none) */
    int gc;                /* [bool] guiding-centre rows: X in x, p_par and mu instead of u */
    int64_t *id;           /* particle id of each row */
    int32_t *pop;          /* population index */
    double *x0, *u0;       /* [m], [m/s] initial state (n x 3) */
    double *t;             /* [s] final time */
    double *x, *u;         /* [m], [m/s] final state (n x 3); guiding centre: x is X, no u */
    double *X0, *ppar0, *mu0; /* [m], [kg m/s], [J/T] initial guiding centre (gc only) */
    double *ppar, *mu;     /* [kg m/s], [J/T] final guiding centre (gc only) */
    int32_t *status;       /* enum gcp_status */
    int32_t *step_failure; /* enum gcp_step_failure: why a STEP_FAILED particle failed, else 0 */
    int64_t *steps;        /* steps taken */
    double *cpu;           /* [s] CPU time per particle */
    double *traj_t;        /* [s] (n x S), NaN after count */
    double *traj_x, *traj_u; /* [m], [m/s] (n x S x 3); traj_u full orbit only */
    double *traj_ppar;     /* [kg m/s] (n x S), guiding centre only */
    int64_t *traj_count;   /* valid samples per particle */
    double *L0;            /* [1] dipole L of the initial guiding centre (NaN off a dipole) */
    double *aeq0;          /* [rad] initial equatorial pitch angle (dipole mapping) */
    double *alc0;          /* [rad] loss cone at L0 for the field's atmosphere */
    int hybrid;            /* [bool] method = hybrid rows: x, u and X0, ppar0, mu0, ppar, mu, plus: */
    double *Xf;            /* [m] final guiding centre (n x 3) (x is the particle) */
    int32_t *hy_mode;      /* final mode: 0 guiding centre, 1 full orbit */
    int32_t *hy_switches;  /* switches (both directions) */
    double *hy_t_gc, *hy_t_fo; /* [s] time pushed as guiding centre, as full orbit */
    int8_t *traj_mode;     /* (n x S) mode of each sample, -1 after count */
    double rank_cpu;       /* [s] CPU time of this rank's pushing */
    struct gcp_events ev;  /* invariant and loss events of these rows (invariants.h) */
};

/* gc: rows of a guiding-centre pusher (the columns differ).  Set r->hybrid
 * before the first reserve for hybrid rows. */
void gcp_results_init(struct gcp_results *r, int64_t samples, int gc);
/* Bytes of one row of results with `samples` trajectory samples; *largest
 * (when not NULL) gets the widest column's bytes per row. */
int64_t gcp_results_row_bytes(int64_t samples, int gc, int64_t *largest);
/* Makes room for `more` rows; returns 0 or GCP_ERR_NOMEM. */
int gcp_results_reserve(struct gcp_results *r, int64_t more);
/* Sorts rows by particle id (the writer needs them in file order). */
int gcp_results_sort(struct gcp_results *r);
/* Appends src's rows to dst (same sample count); 0, GCP_ERR_NOMEM or GCP_ERR_STATE. */
int gcp_results_append(struct gcp_results *dst, const struct gcp_results *src);
void gcp_results_free(struct gcp_results *r);

/* Keeps only rows i with keep[i] != 0. */
void gcp_results_drop(struct gcp_results *r, const unsigned char *keep);

#ifdef __cplusplus
}
#endif
GCP_API_END
#endif /* GCPUSH_RESULTS_H */
