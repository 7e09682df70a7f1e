/* Private to the sweep (sweep.c runs the rows, sweep_measure.c measures
 * their errors). */
#ifndef GCPUSH_SWEEP_PRIV_H
#define GCPUSH_SWEEP_PRIV_H

#include <stddef.h>
#include <stdint.h>

#include "gcpush/invariants.h"
#include "gcpush/sweep.h"

/* The initial states of one population: full orbit and its guiding centre. */
struct gcp_sweep_states {
    size_t n;
    double *x0, *u0;          /* n x 3 */
    double *X0, *ppar0, *mu0; /* guiding centre of the initial state */
    int32_t *gc_ok;           /* [bool] gcp_gc_from_fo succeeded */
};

/* The final states of one push of a population. */
struct gcp_sweep_finals {
    double *x, *u;         /* full orbit: x, u; guiding centre: x = X, u[0] = p_par */
    int32_t *status;
    int64_t steps;
    double cpu;
    int gc;                /* [bool] a guiding-centre method */
};

/* Per particle, from the observer's events of one push: mean bounce and
 * drift periods [s] and the relative drift rates [1/s] of mu, K (bounce
 * events) and L* (drift events); NaN where not measured. */
struct gcp_sweep_inv {
    double Tb, Td;
    double mu_rate, K_rate, L_rate;
};

/* The events worth observing in field f (0: none), from its capabilities. */
unsigned gcp_sweep_events(const struct gcp_field *f);

/* out[0..n) from the events of particles id0 .. id0 + n - 1 in ev.
 * 0 or GCP_ERR_NOMEM. */
int gcp_sweep_inv_stats(const struct gcp_events *ev, int64_t id0, size_t n,
                        struct gcp_sweep_inv *out);

/* Fills the error columns of row (position, gyrophase, energy, invariant
 * drifts and phases, failed) from a run and the reference on population
 * pop: the largest over its particles (sweep.h).  ref_phase, run_phase:
 * accumulated gyrophases (uniform fields, full orbit) or NULL; run_inv,
 * ref_inv: invariant measures or NULL. */
void gcp_sweep_compare(const struct gcp_scene *sc, const struct gcp_population *pop,
                       const struct gcp_sweep_states *st, const struct gcp_sweep_finals *run,
                       const struct gcp_sweep_finals *ref, const double *ref_phase,
                       const double *run_phase, int phase_wrapped,
                       const struct gcp_sweep_inv *run_inv, const struct gcp_sweep_inv *ref_inv,
                       struct gcp_sweep_row *row);

#endif
