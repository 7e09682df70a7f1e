/* Full-orbit pusher "boris": the momentum update is gcp_push_boris() of
 * kernels.h (its equations and reference are there); the drift-kick-drift
 * step around it is shared (fo_step.c). */
#include "gcpush/kernels.h"
#include "gcpush/pusher.h"
#include "fo_fused_priv.h"

GCP_FO_FUSED_DEFINE(boris, gcp_push_boris, gcp_push_boris_B_ig, 1)

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
