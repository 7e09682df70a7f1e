/* The `grid` field model: B (and E) interpolated from a uniform grid, 2D
 * axisymmetric (R, Z) or 3D Cartesian (x, y, z), with the spline core of
 * spline.c (see grid_priv.h for the interpolant and its error orders).
 *
 * 2D axisymmetric.  The grid holds the cylindrical components
 * (B_R, B_phi, B_Z)(R, Z).  At a point x: R = hypot(x, y), phi = atan2(y, x);
 * the components and their R, Z derivatives come from the spline and are
 * turned into Cartesian B and the Cartesian grad B with the 1/R terms of the
 * rotating basis (gcp_axi_to_cart in grid_priv.h).  With use_psi the
 * poloidal part comes from the spline of psi (psi = R A_phi [Wb/rad]):
 *   B_R = -(1/R) dpsi/dZ,  B_Z = (1/R) dpsi/dR,
 * so div B = (1/R) d(R B_R)/dR + dB_Z/dZ = (-psi_ZR + psi_RZ)/R = 0 exactly
 * (the mixed derivatives of one tensor-product spline commute), and grad B
 * uses the spline's second derivatives (continuous: the spline is C2).
 * Without psi the three components are interpolated directly, which is one
 * order more accurate in B (O(h^4) against O(h^3)) but divergence-free only
 * to interpolation accuracy.  Default: components when the file has them.
 *
 * 3D Cartesian: Bx, By, Bz interpolated directly; grad B[i][j] is the
 * derivative of the interpolant of B_i along x_j.
 *
 * Leaving the grid: a point outside the closed box of nodes (for 2D: R or Z
 * outside [R_first, R_last], [Z_first, Z_last]) gets GCP_LEFT_GRID; the
 * values returned with it are those at the nearest point of the box (finite,
 * never extrapolated), only there to keep the caller's arithmetic finite.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "field_priv.h"
#include "gcpush/particles.h"
#include "grid_priv.h"

/* ---- the grid model ------------------------------------------------------- */

/* Component slots in the spline. */
enum { C_BR = 0, C_BP = 1, C_BZ = 2, C_E0 = 3, C_PSI = 6 };

struct grid_params {
    struct gcp_spl spl;
    int geometry;  /* enum gcp_grid_geometry */
    int use_psi;   /* axisymmetric: poloidal B from psi */
    int has_E;
    int has_psi;   /* psi available for gcp_field_psi */
    int psi_slot;  /* component index of psi */
    int e_slot;    /* component index of the first E component */
    double Rmin;   /* [m] floor of R (the axis) */
};

static void grid_destroy(void *p)
{
    struct grid_params *g = p;
    if (!g) return;
    gcp_spl_free(&g->spl);
    free(g);
}

/* Axisymmetric: cylindrical components and their R, Z derivatives. */
static void grid_axi_comp(const struct grid_params *g, const struct gcp_spl_loc *loc, double R,
                          int grad, double b[3], double dR[3], double dZ[3])
{
    struct gcp_spl_out o;
    if (g->use_psi) {
        gcp_spl_eval(&g->spl, loc, g->psi_slot, grad ? 2 : 1, &o);
        const double iR = 1.0 / R;
        b[0] = -o.d[1] * iR;
        b[2] = o.d[0] * iR;
        if (grad) {
            dR[0] = -(o.dd[0][1] - o.d[1] * iR) * iR;
            dZ[0] = -o.dd[1][1] * iR;
            dR[2] = (o.dd[0][0] - o.d[0] * iR) * iR;
            dZ[2] = o.dd[0][1] * iR;
        }
        gcp_spl_eval(&g->spl, loc, C_BP, grad, &o);
        b[1] = o.f;
        dR[1] = o.d[0];
        dZ[1] = o.d[1];
        return;
    }
    for (int c = 0; c < 3; c++) {
        gcp_spl_eval(&g->spl, loc, c, grad, &o);
        b[c] = o.f;
        dR[c] = o.d[0];
        dZ[c] = o.d[1];
    }
}

static int grid_eval(const struct gcp_field *f, double t, const double x[3],
                     struct gcp_field_sample *s)
{
    (void)t;
    const struct grid_params *g = f->params;
    const int grad = (s->need & GCP_NEED_GRADB) != 0;
    struct gcp_spl_loc loc;
    int out;
    if (g->geometry == GCP_GRID_AXISYMMETRIC) {
        double c, sn;
        const double R = gcp_axi_R(x[0], x[1], g->Rmin, &c, &sn);
        const double p[2] = {R, x[2]};
        /* B from psi takes psi's first derivatives, grad B its second: the
         * basis must be located one order up (a full orbit asks for B
         * only; located at order 0 it read undefined derivatives, and every
         * particle of a psi-only grid went NONFINITE: issue 13) */
        out = gcp_spl_locate(&g->spl, p, g->use_psi ? grad + 1 : grad, &loc);
        double b[3], dR[3] = {0}, dZ[3] = {0};
        grid_axi_comp(g, &loc, R, grad, b, dR, dZ);
        gcp_axi_to_cart(c, sn, R, b, dR, dZ, s->B, s->gradB, grad);
        if (s->need & GCP_NEED_E) {
            if (g->has_E) {
                struct gcp_spl_out o;
                double e[3];
                for (int k = 0; k < 3; k++) {
                    gcp_spl_eval(&g->spl, &loc, g->e_slot + k, 0, &o);
                    e[k] = o.f;
                }
                s->E[0] = e[0] * c - e[1] * sn;
                s->E[1] = e[0] * sn + e[1] * c;
                s->E[2] = e[2];
            } else {
                s->E[0] = s->E[1] = s->E[2] = 0.0;
            }
        }
    } else {
        out = gcp_spl_locate(&g->spl, x, grad, &loc);
        struct gcp_spl_out o;
        for (int k = 0; k < 3; k++) {
            gcp_spl_eval(&g->spl, &loc, k, grad, &o);
            s->B[k] = o.f;
            if (grad)
                for (int j = 0; j < 3; j++) s->gradB[k][j] = o.d[j];
        }
        if (s->need & GCP_NEED_E) {
            for (int k = 0; k < 3; k++) {
                if (g->has_E) {
                    gcp_spl_eval(&g->spl, &loc, g->e_slot + k, 0, &o);
                    s->E[k] = o.f;
                } else {
                    s->E[k] = 0.0;
                }
            }
        }
    }
    return out ? GCP_LEFT_GRID : 0;
}


/* Keys: file (required), interpolation = cubic | linear (default cubic),
 * use_psi = yes | no (default: only when the file has psi and no BR/BZ). */
enum { GK_FILE, GK_INTERP, GK_PSI };
static const struct gcp_field_key grid_keys[] = {
    {"file", GCP_KEY_STRING, 0, 1, {0, 0, 0}, NULL, "HDF5 grid file (fields/README.md)"},
    {"interpolation", GCP_KEY_STRING, 0, 0, {0, 0, 0}, "cubic", "cubic | linear"},
    {"use_psi", GCP_KEY_FLAG, 0, 0, {0, 0, 0}, NULL, "poloidal B from psi (default: when no BR/BZ)"},
    {NULL, 0, 0, 0, {0, 0, 0}, NULL, NULL}};

static int grid_build(struct gcp_field_args *a, struct gcp_field **out, struct gcp_error *err)
{
    const char *interp = a->text[GK_INTERP];
    const int use_psi = a->given[GK_PSI] ? (a->v[GK_PSI][0] != 0.0) : -1;
    enum gcp_grid_interp ip;
    if (strcmp(interp, "cubic") == 0)
        ip = GCP_INTERP_CUBIC;
    else if (strcmp(interp, "linear") == 0)
        ip = GCP_INTERP_LINEAR;
    else
        return gcp_field_key_error(a, GK_INTERP, err, GCP_ERR_VALUE,
                                   "expected cubic or linear, got '%s'", interp);
    struct gcp_error e2 = {0, ""};
    const int rc = gcp_field_grid_load_with(a->text[GK_FILE], a->grid_read, ip, use_psi, out, &e2);
    if (rc) return gcp_field_key_error(a, GK_FILE, err, rc, "%s", e2.msg);
    return 0;
}

static int grid_psi(const struct gcp_field *f, const double x[3], double *psi);

const struct gcp_field_type gcp_field_grid = {
    .name = "grid",
    .doc = "B (and E) interpolated from an HDF5 grid file (2D R-Z or 3D x-y-z): file, "
           "[interpolation = cubic|linear], [use_psi]",
    .eval = grid_eval,
    /* per point the spline costs ~100 ns, so the generic loop over eval
     * (one indirect call each) is as fast as a specialised one */
    .eval_block = gcp_field_eval_block_generic,
    .destroy = grid_destroy,
    .caps = GCP_CAP_B | GCP_CAP_GRADB | GCP_CAP_E | GCP_CAP_PSI | GCP_CAP_AXISYM,
    .psi = grid_psi,
    .keys = grid_keys,
    .build = grid_build,
};

struct gcp_field *gcp_field_grid_create(const struct gcp_grid_data *d,
                                        enum gcp_grid_interp interp, int use_psi,
                                        struct gcp_error *err)
{
    const int axi = d->geometry == GCP_GRID_AXISYMMETRIC;
    if (!axi && d->geometry != GCP_GRID_CARTESIAN) {
        gcp_error_set(err, GCP_ERR_VALUE, "grid: unknown geometry %d", (int)d->geometry);
        return NULL;
    }
    if (use_psi && !(axi && d->psi)) {
        gcp_error_set(err, GCP_ERR_VALUE, "grid: use_psi needs an axisymmetric grid with psi");
        return NULL;
    }
    if (use_psi && interp == GCP_INTERP_LINEAR) {
        gcp_error_set(err, GCP_ERR_VALUE,
                      "grid: B from psi needs second derivatives of psi; use cubic "
                      "interpolation (linear gives a piecewise constant B and no grad B)");
        return NULL;
    }
    if (!d->B[1] || (!use_psi && (!d->B[0] || !d->B[2]))) {
        gcp_error_set(err, GCP_ERR_VALUE, "grid: B components missing");
        return NULL;
    }
    struct gcp_field *f = gcp_field_alloc(&gcp_field_grid, 0);
    struct grid_params *g = calloc(1, sizeof *g);
    if (!f || !g) {
        free(f);
        free(g);
        gcp_error_set(err, GCP_ERR_NOMEM, "grid: out of memory");
        return NULL;
    }
    f->params = g;
    g->geometry = d->geometry;
    g->use_psi = use_psi != 0;
    const double *comp[GCP_SPL_MAXCOMP];
    int nc = 0;
    comp[nc++] = use_psi ? d->B[1] : d->B[0]; /* slot 0 unused in psi mode: Bphi twice */
    comp[nc++] = d->B[1];
    comp[nc++] = use_psi ? d->B[1] : d->B[2];
    g->has_E = d->E[0] && d->E[1] && d->E[2];
    if (g->has_E) {
        g->e_slot = nc;
        for (int k = 0; k < 3; k++) comp[nc++] = d->E[k];
    }
    if (axi && d->psi) {
        g->has_psi = 1;
        g->psi_slot = nc;
        comp[nc++] = d->psi;
    }
    const int nd = axi ? 2 : 3;
    int rc = gcp_spl_build(&g->spl, nd, interp == GCP_INTERP_LINEAR ? GCP_SPL_LINEAR : GCP_SPL_CUBIC,
                           d->n, d->origin, d->spacing, nc, comp, err);
    if (rc) {
        gcp_field_free(f);
        return NULL;
    }
    if (use_psi) { /* drop the two placeholder copies */
        free(g->spl.coef[C_BR]);
        free(g->spl.coef[C_BZ]);
        g->spl.coef[C_BR] = g->spl.coef[C_BZ] = NULL;
    }
    g->Rmin = axi ? 1e-9 * d->spacing[0] : 0.0;
    f->has_E = g->has_E;
    f->axisymmetric = axi;
    if (!g->has_psi) f->caps_off |= GCP_CAP_PSI;
    f->r_inner = d->r_inner > 0.0 ? d->r_inner : 0.0;
    f->r_outer = d->r_outer > 0.0 ? d->r_outer : INFINITY;
    f->z_max = d->z_max > 0.0 ? d->z_max : INFINITY;
    return f;
}

int gcp_field_grid_load_with(const char *path, gcp_grid_reader read, enum gcp_grid_interp interp,
                             int use_psi, struct gcp_field **out, struct gcp_error *err)
{
    struct gcp_grid_data d;
    *out = NULL;
    /* fields/ reads no files (HDF5 is the io layer's): without a reader the
     * program asked for none, which is its mistake, not the file's */
    if (!read)
        return gcp_error_set(err, GCP_ERR_STATE,
                             "%s: this program reads no grid files (hand it a gcp_grid_reader: "
                             "gcp_grid_read or gcp_io_readers, gcpush/grid_file.h)",
                             path);
    int rc = read(path, &d, err);
    if (rc) return rc;
    if (use_psi < 0)
        use_psi = d.geometry == GCP_GRID_AXISYMMETRIC && d.psi && (!d.B[0] || !d.B[2]);
    if (!use_psi && (!d.B[0] || !d.B[2])) {
        gcp_grid_data_free(&d);
        return gcp_error_set(err, GCP_ERR_VALUE, "%s: datasets BR and BZ are missing (and no psi)",
                             path);
    }
    struct gcp_error e2 = {0, ""};
    *out = gcp_field_grid_create(&d, interp, use_psi, &e2);
    gcp_grid_data_free(&d);
    if (!*out) return gcp_error_set(err, e2.code ? e2.code : GCP_ERR_NOMEM, "%s: %s", path, e2.msg);
    return 0;
}

/* psi (GCP_CAP_PSI only where the file has it: caps_off otherwise). */
static int grid_psi(const struct gcp_field *f, const double x[3], double *psi)
{
    const struct grid_params *g = f->params;
    if (!g->has_psi) return GCP_ERR_STATE;
    const double p[2] = {hypot(x[0], x[1]), x[2]};
    struct gcp_spl_loc loc;
    struct gcp_spl_out o;
    const int out = gcp_spl_locate(&g->spl, p, 0, &loc);
    gcp_spl_eval(&g->spl, &loc, g->psi_slot, 0, &o);
    *psi = o.f;
    return out ? GCP_LEFT_GRID : 0;
}

/* psi with its R, Z derivatives (fields/flux_priv.h): cubic grids only (a
 * linear interpolant has no second derivatives to give). */
#include "flux_priv.h"

int gcp_grid_psi_RZ(const struct gcp_field *f, double R, double Z, double out[6])
{
    const struct grid_params *g = f->params;
    if (!g->has_psi || g->spl.kind != GCP_SPL_CUBIC) return GCP_ERR_STATE;
    const double p[2] = {R, Z};
    struct gcp_spl_loc loc;
    struct gcp_spl_out o;
    const int outside = gcp_spl_locate(&g->spl, p, 2, &loc);
    gcp_spl_eval(&g->spl, &loc, g->psi_slot, 2, &o);
    out[0] = o.f;
    out[1] = o.d[0];
    out[2] = o.d[1];
    out[3] = o.dd[0][0];
    out[4] = o.dd[0][1];
    out[5] = o.dd[1][1];
    return outside ? GCP_LEFT_GRID : 0;
}

/* The node lattice of an axisymmetric grid with a cubic psi (for
 * grid_flux.c): first node, spacing [m] and node count per axis (R, Z).
 * 0 or GCP_ERR_STATE. */
int gcp_grid_psi_lattice(const struct gcp_field *f, double x0[2], double h[2], size_t n[2])
{
    const struct grid_params *g = f->params;
    if (!g->has_psi || g->spl.kind != GCP_SPL_CUBIC || g->geometry != GCP_GRID_AXISYMMETRIC)
        return GCP_ERR_STATE;
    for (int a = 0; a < 2; a++) x0[a] = g->spl.x0[a], h[a] = g->spl.h[a], n[a] = g->spl.n[a];
    return 0;
}
