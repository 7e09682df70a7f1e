/* Full-orbit pusher "boris-nr": the non-relativistic Boris push (Boris
 * 1970; Birdsall & Langdon 1991, secs. 4-3, 4-4), the push of electrostatic
 * and non-relativistic ion PIC codes.  The kick is gcp_push_boris_nr() of
 * kernels.h (its equations there); the drift-kick-drift step around it is
 * shared (fo_step.c) with the drift x += u dt/2 (no gamma).
 *
 * State: u = v [m/s], the Newtonian velocity; as p = m v, u is p/m for
 * every full-orbit method alike, so the run's initial states (momentum from
 * the kinetic energy by the relativistic relation, the same arrays as for
 * boris) and its output (/particles/initial and final u) mean the same
 * numbers: the same particle, with the same momentum, gyroradius and magnetic
 * moment.  Its Newtonian energy m u^2 / 2 is the run's energy E times
 * 1 + E / (2 m c^2), and its gyrofrequency |q B| / m is gamma times the
 * relativistic one: both differences are of order v^2/c^2, the model's own
 * error -- valid only where that is below the accuracy asked for
 * (tests/unit/test_boris_nr.c shows the factor gamma at 1 GeV). */
#include "gcpush/kernels.h"
#include "gcpush/pusher.h"
#include "fo_fused_priv.h"

GCP_FO_FUSED_DEFINE_NEWTONIAN(boris_nr, gcp_push_boris_nr, gcp_push_boris_nr_B)

const struct gcp_pusher_type gcp_pusher_boris_nr = {
    .name = "boris-nr",
    .doc = "Non-relativistic Boris (Boris 1970; Birdsall & Langdon 1991): u = v, valid for v << c; exact |v| in pure B, exact E x B drift, gyrophase lags as 2 atan(Omega dt/2)",
    .order = 2,
    .kind = GCP_FULL_ORBIT,
    .advance = gcp_block_advance_fo_opts,
    .kick = gcp_push_boris_nr_batch,
    .kick_B = gcp_push_boris_nr_B_batch,
    .fused = &gcp_fo_fused_boris_nr_,
    .newtonian = 1,
};
