/* Full-orbit pusher "boris": the momentum update is gcp_push_boris() of
 * kernels.h (its equations and reference are there); the drift-kick-drift
 * step around it is shared (fo_step.c). */
#include "gcpush/kernels.h"
#include "gcpush/pusher.h"
#include "fo_fused_priv.h"

/* The fused tiles in pure B: t and s of the rotation (kernels.h
 * gcp_boris_ts_, from B and 1/gamma alone) in the tile's first loop with
 * the field, the rotation by them in the second (fo_fused_priv.h): the
 * operations of gcp_push_boris_B_ig, bit for bit, with the division for s
 * beside the field's instead of in the kick's dependency chain.  The
 * uniform tiles are split the same way (one loop a step ran its chain of
 * 1/gamma-, s, gamma+ and h/gamma+ lane after lane at ~1.1x the dipole's
 * cost, with half the dipole's square roots and divisions). */
#define BORIS_STASH_                                                                            \
    gcp_boris_ts_(bx, by, bz, 0.5 * q * dt / m, IG0, &K[0][i], &K[1][i], &K[2][i], &K[3][i])
#define BORIS_KICK2_ gcp_boris_rotate_ts_(&U, &V, &W, K[0][i], K[1][i], K[2][i], K[3][i])
/* In uniform E and B, gcp_push_boris's operations in the same split: the
 * first loop forms u- = u + qdt2m E, 1/gamma(u-) (gcp_boris_rotate_'s
 * expression), t and s; the second forms u- again from the same u (the
 * same bits), rotates it by the stashed t and s and adds the second half
 * kick. */
static inline void boris_eb_ts_(double ux, double uy, double uz, const double E[3], double bx,
                                double by, double bz, double qdt2m, double *tx, double *ty,
                                double *tz, double *s)
{
    const double vx = ux + qdt2m * E[0], vy = uy + qdt2m * E[1], vz = uz + qdt2m * E[2];
    gcp_boris_ts_(bx, by, bz, qdt2m, 1.0 / gcp_gamma_of_u(vx, vy, vz), tx, ty, tz, s);
}
static inline void boris_eb_kick2_(double *ux, double *uy, double *uz, const double E[3],
                                   double qdt2m, double tx, double ty, double tz, double s)
{
    double vx = *ux + qdt2m * E[0], vy = *uy + qdt2m * E[1], vz = *uz + qdt2m * E[2];
    gcp_boris_rotate_ts_(&vx, &vy, &vz, tx, ty, tz, s);
    *ux = vx + qdt2m * E[0];
    *uy = vy + qdt2m * E[1];
    *uz = vz + qdt2m * E[2];
}
#define BORIS_EB_STASH_                                                                         \
    boris_eb_ts_(ux[i], uy[i], uz[i], a->p + 3, bx, by, bz, 0.5 * q * dt / m, &K[0][i],         \
                 &K[1][i], &K[2][i], &K[3][i])
#define BORIS_EB_KICK2_                                                                         \
    boris_eb_kick2_(&U, &V, &W, a->p + 3, 0.5 * q * dt / m, K[0][i], K[1][i], K[2][i], K[3][i])
GCP_FO_FUSED_DEFINE_SPLIT_(boris, gcp_push_boris, gcp_push_boris_B_ig, 1, BORIS_STASH_,
                           BORIS_KICK2_, 1, BORIS_EB_STASH_, BORIS_EB_KICK2_, 1, 2)

const struct gcp_pusher_type gcp_pusher_boris = {
    .name = "boris",
    .doc = "Relativistic Boris (Boris 1970; Birdsall & Langdon 1991): exact |u| in pure B, volume preserving, gyrophase lags as 2 atan(omega dt/2)",
    .order = 2,
    .kind = GCP_FULL_ORBIT,
    .advance = gcp_block_advance_fo_opts,
    .kick = gcp_push_boris_batch,
    .kick_B = gcp_push_boris_B_batch,
    .fused = &gcp_fo_fused_boris_,
};
