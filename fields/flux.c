/* The flux-function accessors of fields/flux_priv.h: one dispatch on the
 * model, here inside fields/, so that the canonical charts never ask which
 * model they have. */
#include "flux_priv.h"

#include "field_priv.h"
#include "gcpush/particles.h"
#include "grid_priv.h"

int gcp_field_psi_RZ(const struct gcp_field *f, double R, double Z, double out[6])
{
    if (f->type == &gcp_field_tokamak) return gcp_tokamak_psi_RZ(f, R, Z, out);
    if (f->type == &gcp_field_eqdsk) return gcp_eqdsk_psi_RZ2(f, R, Z, out);
    if (f->type == &gcp_field_grid) return gcp_grid_psi_RZ(f, R, Z, out);
    return GCP_ERR_STATE;
}

int gcp_field_psi_B_RZ(const struct gcp_field *f, double R, double Z, double out[6],
                       struct gcp_field_sample *s, int *fst)
{
    if (f->type == &gcp_field_eqdsk) return gcp_eqdsk_psi_B_RZ(f, R, Z, out, s, fst);
    const double X[3] = {R, 0.0, Z};
    s->need = GCP_NEED_B | GCP_NEED_GRADB;
    *fst = gcp_field_eval(f, 0.0, X, s);
    return gcp_field_psi_RZ(f, R, Z, out);
}

int gcp_field_psi_continuity(const struct gcp_field *f)
{
    if (f->type == &gcp_field_tokamak) return GCP_PSI_ANALYTIC;
    if (f->type == &gcp_field_eqdsk) return gcp_eqdsk_psi_continuity(f);
    double x0[2], h[2];
    size_t n[2];
    /* a grid's psi: the bicubic spline (C2), or the bilinear (C0) */
    if (f->type == &gcp_field_grid) return gcp_grid_psi_lattice(f, x0, h, n) ? 0 : 2;
    return 0;
}

int gcp_field_flux_surfaces(const struct gcp_field *f, double *R_axis, double *Z_axis,
                            double *psi_edge)
{
    if (f->type == &gcp_field_tokamak) return gcp_tokamak_flux_surfaces(f, R_axis, Z_axis, psi_edge);
    if (f->type == &gcp_field_eqdsk) return gcp_eqdsk_flux_surfaces(f, R_axis, Z_axis, psi_edge);
    if (f->type == &gcp_field_grid) return gcp_grid_flux_surfaces(f, R_axis, Z_axis, psi_edge);
    return GCP_ERR_STATE;
}

int gcp_field_polchart(const struct gcp_field *f, struct gcp_polchart *out)
{
    if (f->type == &gcp_field_tokamak) return gcp_tokamak_polchart(f, out);
    return GCP_ERR_STATE;
}
