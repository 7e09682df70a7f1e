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

int gcp_field_flux_potential_rz(const struct gcp_field *f, size_t n, const double *R,
                                const double *Z, double *psi, double *chi)
{
    if (f->type == &gcp_field_dipole) {
        gcp_dipole_flux_potential_rz(f, n, R, Z, psi, chi);
        return 0;
    }
    for (size_t k = 0; k < n; k++) {
        const double x[3] = {R[k], 0.0, Z[k]};
        const int st = gcp_field_flux_potential(f, x, &psi[k], &chi[k]);
        if (st) return st;
    }
    return 0;
}
