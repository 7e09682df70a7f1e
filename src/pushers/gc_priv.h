/* Private to the guiding-centre pushers (src/pushers/gc_*.c). */
#ifndef GCPUSH_GC_PRIV_H
#define GCPUSH_GC_PRIV_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "gcpush/field.h"
#include "gcpush/gc.h"
#include "gcpush/pusher.h"

/* What a GC evaluation needs from the field. */
static inline unsigned gc_need(const struct gcp_field *f)
{
    return GCP_NEED_B | GCP_NEED_GRADB | (f->has_E ? GCP_NEED_E : 0u);
}

/* Adiabaticity measure (see gcp_gc_adiabaticity) from one field sample. */
double gcp_gc_adiabaticity_sample(const struct gcp_field_sample *s, double ppar, double mu, double q,
                              double m);

/* Its arithmetic, from B [T] and G_ij = dB_i/dx_j [T/m], without a branch
 * (|B| = 0 or NaN selects inf at the end), so that a loop of it
 * vectorises (the fused gc-rk4 step's start-of-step check): the same
 * numbers as gcp_gc_adiabaticity_sample, which calls it.
 *   eps = max(rho_perp |grad B|/B, rho |kappa|),
 *   kappa_i = b_j d_j b_i = (G b)_i / B - b_i (b.grad B) / B. */
static inline __attribute__((always_inline)) double
gcp_gc_adiabaticity_of(const double B[3], const double G[3][3], double ppar, double mu, double q,
                       double m)
{
    const double Bm = sqrt(B[0] * B[0] + B[1] * B[1] + B[2] * B[2]);
    const double b[3] = {B[0] / Bm, B[1] / Bm, B[2] / Bm};
    double gB[3], Gb[3], k[3];
    for (int j = 0; j < 3; j++) {
        gB[j] = b[0] * G[0][j] + b[1] * G[1][j] + b[2] * G[2][j];
        Gb[j] = G[j][0] * b[0] + G[j][1] * b[1] + G[j][2] * b[2];
    }
    const double bg = b[0] * gB[0] + b[1] * gB[1] + b[2] * gB[2];
    for (int i = 0; i < 3; i++) k[i] = (Gb[i] - b[i] * bg) / Bm;
    const double pperp2 = 2.0 * m * (mu > 0.0 ? mu : 0.0) * Bm;
    const double qB = fabs(q) * Bm;
    const double rho_perp = sqrt(pperp2) / qB;
    const double rho = sqrt(ppar * ppar + pperp2) / qB;
    const double e1 = rho_perp * sqrt(gB[0] * gB[0] + gB[1] * gB[1] + gB[2] * gB[2]) / Bm;
    const double e2 = rho * sqrt(k[0] * k[0] + k[1] * k[1] + k[2] * k[2]);
    const double e = e1 > e2 ? e1 : e2;
    return Bm > 0.0 ? e : INFINITY;
}

/* One GC evaluation at (t, X, ppar): field, right-hand side, and the
 * validity check.  Returns 0, the field's status, GCP_NONFINITE for a
 * non-finite right-hand side, or GCP_NONADIABATIC when B*_par <= 0 or
 * (amax > 0 and) the adiabaticity exceeds amax.  dX, dp are always written. */
int gcp_gc_eval(const struct gcp_field *f, double t, double q, double m, const double X[3],
            double ppar, double mu, double amax, double dX[3], double *dp);

/* Common start of every GC advance: checks the options (dt > 0 and finite,
 * nsteps >= 0: otherwise every live lane gets STEP_FAILED) and classifies
 * the live lanes (non-finite X, p_par, mu; the field's domain; adiabaticity
 * when amax > 0), retiring stopped ones at t0 with 0 steps.  Returns the
 * live lane count (b->n_active updated). */
size_t gcp_gc_block_begin(struct gcp_block *b, const struct gcp_field *f, const struct gcp_push_opts *o);

/* Per-lane one-step methods (implicit schemes that keep a solver state per
 * lane: gc-gl2, gc-gl4, gc-midpoint-pphi) run on the evolve layer
 * (evolve_priv.h) through gcp_gc_lanes_advance (gc_lanes.c):
 * gcp_gc_block_begin, then per step the validity check at the start of
 * the step (gcp_gc_eval with opts->adiabaticity_max; skipped at the first
 * step, which begin checked),
 * ops->step on every live lane, retirement with the lane states carried
 * along, the sampler, and gcp_block_finish.
 *   init: sets up *lane from block lane i at time t; 0 or a status.
 *   step: one step of size h from t; on success writes the new X, p_par
 *         into block lane i, the field status there into b->fstatus[i], and
 *         returns 0; otherwise leaves the block lane as it was (the state of
 *         the start of the step) and returns the lane's status
 *         (GCP_NONADIABATIC, ..., or GCP_STEP_FAILED, best with its reason:
 *         `return gcp_lane_fail(b, i, GCP_FAIL_NO_CONVERGENCE);`, block_priv.h;
 *         a STEP_FAILED lane without one ends UNSPECIFIED). */
struct gcp_gc_lane_ops {
    size_t lane_size; /* [bytes] of one lane's solver state */
    int (*init)(const void *ctx, const struct gcp_block *b, size_t i, double t, void *lane);
    int (*step)(const void *ctx, struct gcp_block *b, size_t i, double t, double h, void *lane);
    /* Optional (NULL: step lane by lane): the step of the n live lanes at
     * once, lane i's state at lanes + i lane_size (gcp_stepper.step_lanes). */
    int32_t (*step_block)(const void *ctx, struct gcp_block *b, size_t n, double t, double h,
                          unsigned char *lanes);
};
size_t gcp_gc_lanes_advance(struct gcp_block *b, const struct gcp_field *f,
                            const struct gcp_push_opts *o, const struct gcp_sampler *s,
                            const struct gcp_gc_lane_ops *ops, const void *ctx);

#endif
