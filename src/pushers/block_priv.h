/* Private to the pushers: block lane management (block.c). */
#ifndef GCPUSH_BLOCK_PRIV_H
#define GCPUSH_BLOCK_PRIV_H

#include <stddef.h>
#include <stdint.h>

#include <float.h>
#include <math.h>

#include "gcpush/particles.h"
#include "gcpush/pusher.h"

/* Swaps every per-lane array entry of lanes i and j. */
void gcp_block_swap_lanes(struct gcp_block *b, size_t i, size_t j);

/* The status of one lane from r^2, |momentum|^2 (any finite measure of it),
 * z and the field's own verdict fs0, as arithmetic selects so the loops
 * vectorise.  NONFINITE > field verdict > PRECIPITATED > LEFT_DOMAIN.
 * !(|a| <= DBL_MAX) is true for NaN and Inf without a call.  Shared by
 * gcp_block_classify and the fused full-orbit steps (fo_fused_priv.h),
 * which classify inside their loop with the same verdicts. */
static inline int32_t gcp_lane_status(double r2, double p2, double z, int32_t fs0, double rin2,
                                      double rout2, double zmax)
{
    const int32_t nonfinite = !(fabs(r2 + p2) <= DBL_MAX);
    const int32_t below = r2 < rin2;
    const int32_t outside = (r2 > rout2) | (fabs(z) > zmax);
    const int32_t geo = below * GCP_PRECIPITATED + (1 - below) * outside * GCP_LEFT_DOMAIN;
    const int32_t fs = fs0 + (fs0 == 0) * geo;
    return nonfinite * GCP_NONFINITE + (1 - nonfinite) * fs;
}

/* Whether gcp_lane_status(r2, p2, z, 0, rin2, rout2, zmax) != 0, as one
 * predicate (the fused steps' per-step test: which status comes later from
 * gcp_block_classify; fewer operations than the status itself).  For
 * finite r2 + p2, !(r2 < rin2) is r2 >= rin2. */
static inline int32_t gcp_lane_stops(double r2, double p2, double z, double rin2, double rout2,
                                     double zmax)
{
    return !((fabs(r2 + p2) <= DBL_MAX) & (r2 >= rin2) & (r2 <= rout2) & (fabs(z) <= zmax));
}

/* Sets the status of each of the first n lanes, without branches:
 * NONFINITE (position, or u for full orbit / p_par and mu for guiding
 * centre when gc != 0) beats the field's verdict in b->fstatus (LEFT_GRID,
 * LEFT_DOMAIN), which beats PRECIPITATED (|x| < r_inner) and LEFT_DOMAIN
 * (|x| > r_outer or |z| > z_max).  Returns non-zero when any lane stopped. */
int32_t gcp_block_classify(struct gcp_block *b, size_t n, const struct gcp_field *f, int gc);

/* Moves lanes with status != ALIVE behind the live ones, stamping their
 * time t_stop and adding steps_done to their steps; returns the live count. */
size_t gcp_block_retire(struct gcp_block *b, size_t n, double t_stop, int64_t steps_done);

/* Issue 11: the reason a stepper gives for a lane it fails.  Sets lane i
 * of b to GCP_STEP_FAILED with `reason` (enum gcp_step_failure) and returns
 * GCP_STEP_FAILED, so a per-lane step can end with
 *   return gcp_lane_fail(b, i, GCP_FAIL_NO_CONVERGENCE);
 * (its caller writes the returned status; the reason rides with the lane
 * through retirement to the output and the log). */
static inline int gcp_lane_fail(struct gcp_block *b, size_t i, int reason)
{
    b->step_failure[i] = reason;
    return GCP_STEP_FAILED;
}

/* At retirement: a STEP_FAILED lane with no reason gets UNSPECIFIED, a
 * lane that stopped otherwise keeps NONE (a reason of a step that later
 * succeeded, e.g. after a restart, is dropped). */
static inline void gcp_lane_failure_default(struct gcp_block *b, size_t i)
{
    if (b->status[i] != GCP_STEP_FAILED) b->step_failure[i] = GCP_FAIL_NONE;
    else if (b->step_failure[i] == GCP_FAIL_NONE) b->step_failure[i] = GCP_FAIL_UNSPECIFIED;
}

/* Ends a push of k steps: the n live lanes get t = t_end and k more steps
 * (unless the caller keeps their clock: GCP_BLOCK_CALLER_CLOCK). */
void gcp_block_finish(struct gcp_block *b, size_t n, double t_end, int64_t k);


/* The field's bounds at one point x [m] (the scalar form of the block's
 * classification): NONFINITE, PRECIPITATED (|x| < r_inner), LEFT_DOMAIN
 * (|x| > r_outer or |z| > z_max), or 0.  Shared by the per-lane steppers
 * (gc-rk45/rk8pd, the Sundman methods, the fo-rk8pd reference). */
static inline int32_t gcp_point_domain_status(const struct gcp_field *f, const double x[3])
{
    const double r2 = x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
    if (!isfinite(r2)) return GCP_NONFINITE;
    if (r2 < f->r_inner * f->r_inner) return GCP_PRECIPITATED;
    if (r2 > f->r_outer * f->r_outer || fabs(x[2]) > f->z_max) return GCP_LEFT_DOMAIN;
    return 0;
}

#endif
