/* Full-orbit pusher "boris-zu": the momentum update is gcp_push_boris_zu() of
 * kernels.h (its equations and reference are there); the drift-kick-drift
 * step around it is shared (fo_step.c). */
#include "gcpush/kernels.h"
#include "gcpush/pusher.h"

const struct gcp_pusher_type gcp_pusher_boris_zu = {
    .name = "boris-zu",
    .doc = "Boris with the exact gyro-angle (Zenitani & Umeda 2018): correct gyrophase at any omega_c dt (drifts keep Boris error (omega dt)^2/12)",
    .order = 2,
    .kind = GCP_FULL_ORBIT,
    .advance = gcp_block_advance_fo_opts,
    .kick = gcp_push_boris_zu_batch,
};
