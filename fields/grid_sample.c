/* The `grid` model's data in memory: the sampler that puts any field onto a
 * grid (gcp_grid_sample), and the release of grid data.  Files are the io
 * layer's (src/io/grid_file.c: the HDF5 reader and writer, and
 * gcp_grid_sample_write, which writes what this samples); fields/ never
 * includes hdf5.h. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/field.h"
#include "gcpush/grid.h"

static const char *const AXI_AX[3] = {"R", "Z", NULL};
static const char *const CART_AX[3] = {"x", "y", "z"};

void gcp_grid_data_free(struct gcp_grid_data *d)
{
    if (!d) return;
    for (int k = 0; k < 3; k++) {
        free(d->B[k]);
        free(d->E[k]);
        d->B[k] = d->E[k] = NULL;
    }
    free(d->psi);
    d->psi = NULL;
}

/* ---- the sampler ---------------------------------------------------------- */

int gcp_grid_sample(const struct gcp_field *src, const struct gcp_grid_spec *spec,
                    struct gcp_grid_data *out, struct gcp_error *err)
{
    memset(out, 0, sizeof *out);
    const int axi = spec->geometry == GCP_GRID_AXISYMMETRIC;
    if (!axi && spec->geometry != GCP_GRID_CARTESIAN)
        return gcp_error_set(err, GCP_ERR_VALUE, "grid sample: unknown geometry");
    const int nd = axi ? 2 : 3;
    const char *const *ax = axi ? AXI_AX : CART_AX;
    struct gcp_grid_data d;
    memset(&d, 0, sizeof d);
    d.geometry = spec->geometry;
    size_t total = 1;
    for (int k = 0; k < nd; k++) {
        if (spec->n[k] < 5)
            return gcp_error_set(err, GCP_ERR_VALUE,
                                 "grid sample: axis %s needs at least 5 nodes, got %zu", ax[k],
                                 spec->n[k]);
        if (!(spec->hi[k] > spec->lo[k] && isfinite(spec->lo[k]) && isfinite(spec->hi[k])))
            return gcp_error_set(err, GCP_ERR_VALUE,
                                 "grid sample: axis %s: need finite %s_min < %s_max, got %g .. %g",
                                 ax[k], ax[k], ax[k], spec->lo[k], spec->hi[k]);
        if (axi && k == 0 && spec->lo[0] < 0.0)
            return gcp_error_set(err, GCP_ERR_VALUE, "grid sample: R_min must be >= 0, got %g",
                                 spec->lo[0]);
        d.n[k] = spec->n[k];
        d.origin[k] = spec->lo[k];
        d.spacing[k] = (spec->hi[k] - spec->lo[k]) / (double)(spec->n[k] - 1);
        total *= spec->n[k];
    }
    d.n[2] = axi ? 1 : d.n[2];
    d.r_inner = src->r_inner;
    d.r_outer = src->r_outer;
    d.z_max = src->z_max;
    int fail = 0;
    for (int k = 0; k < 3; k++) {
        fail |= !(d.B[k] = malloc(total * sizeof(double)));
        if (src->has_E) fail |= !(d.E[k] = malloc(total * sizeof(double)));
    }
    if (fail) {
        gcp_grid_data_free(&d);
        return gcp_error_set(err, GCP_ERR_NOMEM, "grid sample: out of memory");
    }
    const double rin = src->r_inner;
    for (size_t l = 0; l < total; l++) {
        size_t i0 = l % d.n[0], r = l / d.n[0];
        size_t i1 = r % d.n[1], i2 = r / d.n[1];
        double x[3];
        if (axi) {
            x[0] = d.origin[0] + (double)i0 * d.spacing[0];
            x[1] = 0.0;
            x[2] = d.origin[1] + (double)i1 * d.spacing[1];
        } else {
            x[0] = d.origin[0] + (double)i0 * d.spacing[0];
            x[1] = d.origin[1] + (double)i1 * d.spacing[1];
            x[2] = d.origin[2] + (double)i2 * d.spacing[2];
        }
        const double r0 = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
        if (rin > 0.0 && r0 < rin) { /* inside the source's inner boundary: project */
            if (r0 > 0.0)
                for (int k = 0; k < 3; k++) x[k] *= rin / r0;
            else
                x[0] = rin, x[1] = x[2] = 0.0;
        }
        struct gcp_field_sample s;
        memset(&s, 0, sizeof s);
        s.need = GCP_NEED_B | (src->has_E ? GCP_NEED_E : 0u);
        (void)gcp_field_eval(src, spec->t, x, &s); /* the source's domain status is not used */
        for (int k = 0; k < 3; k++) {
            d.B[k][l] = s.B[k]; /* at phi = 0: (Bx, By, Bz) = (BR, Bphi, BZ) */
            if (src->has_E) d.E[k][l] = s.E[k];
            if (!isfinite(s.B[k]) || (src->has_E && !isfinite(s.E[k]))) {
                gcp_grid_data_free(&d);
                return gcp_error_set(err, GCP_ERR_VALUE,
                                     "grid sample: field '%s' is not finite at node (%zu, %zu, "
                                     "%zu), x = (%g, %g, %g) m",
                                     src->type->name, i0, i1, i2, x[0], x[1], x[2]);
            }
        }
    }
    *out = d;
    return 0;
}
