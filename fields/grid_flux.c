/* gcp_grid_flux_surfaces (fields/flux_priv.h): the magnetic axis and the
 * last closed flux surface of an R-Z grid with psi, found from the grid
 * itself, for the canonical flux chart (src/pushers/canon_flux_num.c). */
#include <math.h>

#include "flux_priv.h"
#include "gcpush/error.h"
#include "gcpush/particles.h"

/* Where the closed flux surfaces of a grid with psi are (a grid file records
 * neither axis nor boundary):
 *   axis: the interior node that is a strict extremum of psi among its 8
 *         neighbours and lies farthest in psi from the mean of the grid's
 *         border (the plasma's O-point, not a coil's or a corner's);
 *   edge: along 64 rays from that node, stepping a quarter of the smaller
 *         spacing, psi moves monotonically away from psi_axis until the
 *         grid ends or psi turns back (a separatrix, another extremum); the
 *         boundary flux is the value reached that is nearest psi_axis, so
 *         every surface inside it is closed within the grid.
 * 0, or GCP_ERR_STATE when there is no psi or no such extremum. */
int gcp_grid_flux_surfaces(const struct gcp_field *f, double *Ra, double *Za, double *pe)
{
    double o[2], hh[2];
    size_t nn[2];
    if (gcp_grid_psi_lattice(f, o, hh, nn)) return GCP_ERR_STATE;
    const size_t n0 = nn[0], n1 = nn[1];
    const double h0 = hh[0], h1 = hh[1], x0 = o[0], y0 = o[1];
    double node[6];
#define PSI_AT(i, j) (gcp_grid_psi_RZ(f, x0 + (double)(i) * h0, y0 + (double)(j) * h1, node), node[0])
    double border = 0.0;
    for (size_t i = 0; i < n0; i++) border += PSI_AT(i, 0) + PSI_AT(i, n1 - 1);
    for (size_t j = 1; j + 1 < n1; j++) border += PSI_AT(0, j) + PSI_AT(n0 - 1, j);
    border /= (double)(2 * n0 + 2 * (n1 - 2));
    double best = -1.0, psia = 0.0;
    for (size_t j = 1; j + 1 < n1; j++)
        for (size_t i = 1; i + 1 < n0; i++) {
            const double c = PSI_AT(i, j);
            int mx = 1, mn = 1;
            for (int dj = -1; dj <= 1; dj++)
                for (int di = -1; di <= 1; di++) {
                    if (!di && !dj) continue;
                    const double v = PSI_AT(i + di, j + dj);
                    mx &= c > v, mn &= c < v;
                }
            if ((mx || mn) && fabs(c - border) > best) {
                best = fabs(c - border), psia = c;
                *Ra = x0 + (double)i * h0, *Za = y0 + (double)j * h1;
            }
        }
#undef PSI_AT
    if (best < 0.0) return GCP_ERR_STATE;
    const double step = 0.25 * (h0 < h1 ? h0 : h1);
    double edge = INFINITY;
    for (int k = 0; k < 64; k++) {
        const double c = cos(k * GCP_PI / 32), s = sin(k * GCP_PI / 32);
        double prev = 0.0, t = step;
        for (;;) {
            const int out = gcp_grid_psi_RZ(f, *Ra + t * c, *Za + t * s, node);
            const double d = fabs(node[0] - psia);
            if (out || d < prev) break;
            prev = d, t += step;
        }
        if (prev < edge) edge = prev;
    }
    if (!(edge > 0.0 && isfinite(edge))) return GCP_ERR_STATE;
    /* the same sign as psi runs from the axis outward */
    gcp_grid_psi_RZ(f, *Ra + step, *Za, node);
    *pe = psia + (node[0] >= psia ? edge : -edge);
    return 0;
}
