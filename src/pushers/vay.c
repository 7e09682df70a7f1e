/* Full-orbit pusher "vay": the momentum update is gcp_push_vay() of
 * kernels.h (its equations and reference are there); the drift-kick-drift
 * step around it is shared (fo_step.c). */
#include "gcpush/kernels.h"
#include "gcpush/pusher.h"

const struct gcp_pusher_type gcp_pusher_vay = {
    .name = "vay",
    .doc = "Vay (2008): correct E x B drift and force-free motion at any gamma",
    .order = 2,
    .kind = GCP_FULL_ORBIT,
    .advance = gcp_block_advance_fo_opts,
    .kick = gcp_push_vay_batch,
};
