/* Full-orbit pusher "higuera-cary": the momentum update is gcp_push_higuera_cary() of
 * kernels.h (its equations and reference are there); the drift-kick-drift
 * step around it is shared (fo_step.c). */
#include "gcpush/kernels.h"
#include "gcpush/pusher.h"

const struct gcp_pusher_type gcp_pusher_higuera_cary = {
    .name = "higuera-cary",
    .doc = "Higuera & Cary (2017): volume preserving, exact force-free motion at any gamma",
    .order = 2,
    .kind = GCP_FULL_ORBIT,
    .advance = gcp_block_advance_fo_opts,
    .kick = gcp_push_higuera_cary_batch,
};
