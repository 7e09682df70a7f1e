/* Full-orbit pusher "boris-zu": the momentum update is gcp_push_boris_zu() of
 * kernels.h (its equations and reference are there); the drift-kick-drift
 * step around it is shared (fo_step.c). */
#include "gcpush/kernels.h"
#include "gcpush/pusher.h"
#include "fo_fused_priv.h"

/* The kick with E = 0 for the fused step: literal zeros, the numbers the
 * block step's zeroed E arrays give. */
static inline void boris_zu_B_(double *ux, double *uy, double *uz, double Bx, double By, double Bz,
                         double q, double m, double dt)
{
    gcp_push_boris_zu(ux, uy, uz, 0.0, 0.0, 0.0, Bx, By, Bz, q, m, dt);
}
GCP_FO_FUSED_DEFINE(boris_zu, gcp_push_boris_zu, boris_zu_B_, 0)

const struct gcp_pusher_type gcp_pusher_boris_zu = {
    .name = "boris-zu",
    .doc = "Boris with the exact gyro-angle (Zenitani & Umeda 2018): correct gyrophase at any omega_c dt (drifts keep Boris error (omega dt)^2/12)",
    .order = 2,
    .kind = GCP_FULL_ORBIT,
    .advance = gcp_block_advance_fo_opts,
    .kick = gcp_push_boris_zu_batch,
    .fused = &gcp_fo_fused_boris_zu_,
};
