/* gcp_gc_potential: the vector potential a guiding-centre method needs,
 * through the field type (fields/<model>.c, `potential`, with the
 * derivations there).  Gridded axisymmetric fields with a flux but no
 * potential member (grid with psi, eqdsk) give the toroidal component
 * A_phi = psi / R, which is all that p_phi and the drift-shell flux need;
 * their poloidal components (from B_phi) are not known here, so no dA:
 * gc-midpoint-pphi, which needs the whole A, refuses them. */
#include <math.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/field.h"
#include "gcpush/gc.h"
#include "gcpush/grid.h"

int gcp_gc_potential(const struct gcp_field *f, double t, const double x[3], double A[3],
                     double dA[3][3], double *phi)
{
    double psi, R;
    if (gcp_field_caps(f) & GCP_CAP_A) return gcp_field_potential(f, t, x, A, dA, phi);
    if (!dA && gcp_field_psi(f, x, &psi) == 0 && (R = hypot(x[0], x[1])) > 0) {
        const double Aphi = psi / R;
        A[0] = -Aphi * x[1] / R, A[1] = Aphi * x[0] / R, A[2] = 0.0;
        if (phi) *phi = 0.0;
        return 0;
    }
    return GCP_ERR_UNKNOWN;
}
