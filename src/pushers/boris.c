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
 * beside the field's instead of in the kick's dependency chain. */
#define BORIS_STASH_                                                                            \
    gcp_boris_ts_(bx, by, bz, 0.5 * q * dt / m, IG0, &K[0][i], &K[1][i], &K[2][i], &K[3][i])
#define BORIS_KICK2_ gcp_boris_rotate_ts_(&U, &V, &W, K[0][i], K[1][i], K[2][i], K[3][i])
GCP_FO_FUSED_DEFINE_SPLIT_(boris, gcp_push_boris, gcp_push_boris_B_ig, 1, BORIS_STASH_,
                           BORIS_KICK2_, 1)

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
