/* Full-orbit pusher "higuera-cary": the momentum update is gcp_push_higuera_cary() of
 * kernels.h (its equations and reference are there); the drift-kick-drift
 * step around it is shared (fo_step.c). */
#include "gcpush/kernels.h"
#include "gcpush/pusher.h"
#include "fo_fused_priv.h"

/* The kick with E = 0 for the fused step: literal zeros, the numbers the
 * block step's zeroed E arrays give. */
static inline void higuera_cary_B_(double *ux, double *uy, double *uz, double Bx, double By, double Bz,
                         double q, double m, double dt)
{
    gcp_push_higuera_cary(ux, uy, uz, 0.0, 0.0, 0.0, Bx, By, Bz, q, m, dt);
}
GCP_FO_FUSED_DEFINE(higuera_cary, gcp_push_higuera_cary, higuera_cary_B_, 0)

const struct gcp_pusher_type gcp_pusher_higuera_cary = {
    .name = "higuera-cary",
    .doc = "Higuera & Cary (2017): volume preserving, exact force-free motion at any gamma",
    .order = 2,
    .kind = GCP_FULL_ORBIT,
    .advance = gcp_block_advance_fo_opts,
    .kick = gcp_push_higuera_cary_batch,
    .fused = &gcp_fo_fused_higuera_cary_,
};
