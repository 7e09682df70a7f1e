/* Full-orbit pusher "vay": the momentum update is gcp_push_vay() of
 * kernels.h (its equations and reference are there); the drift-kick-drift
 * step around it is shared (fo_step.c). */
#include "gcpush/kernels.h"
#include "gcpush/pusher.h"
#include "fo_fused_priv.h"

/* The kick with E = 0 for the fused step: literal zeros, the numbers the
 * block step's zeroed E arrays give. */
static inline void vay_B_(double *ux, double *uy, double *uz, double Bx, double By, double Bz,
                         double q, double m, double dt)
{
    gcp_push_vay(ux, uy, uz, 0.0, 0.0, 0.0, Bx, By, Bz, q, m, dt);
}
GCP_FO_FUSED_DEFINE(vay, gcp_push_vay, vay_B_, 0)

const struct gcp_pusher_type gcp_pusher_vay = {
    .name = "vay",
    .doc = "Vay (2008): correct E x B drift and force-free motion at any gamma",
    .order = 2,
    .kind = GCP_FULL_ORBIT,
    .advance = gcp_block_advance_fo_opts,
    .kick = gcp_push_vay_batch,
    .fused = &gcp_fo_fused_vay_,
};
