/* gcp_field_flux_potential: the (psi, chi) pair of the curl-free
 * axisymmetric models, which the curl-free canonical chart
 * (src/pushers/canon_curlfree.c) is built on.  The formulas live with each
 * model (dipole.c, mirror.c); this file only knows which models have one, so
 * that no code outside fields/ asks which model it holds. */
#include "field_priv.h"

int gcp_field_flux_potential(const struct gcp_field *f, const double x[3], double *psi,
                             double *chi)
{
    if (f->type == &gcp_field_dipole) return gcp_dipole_flux_potential(f, x, psi, chi);
    if (f->type == &gcp_field_mirror) return gcp_mirror_flux_potential(f, x, psi, chi);
    return GCP_ERR_UNKNOWN;
}
