/* gcpush/grid.h -- gridded and real fields: the `grid`, `eqdsk` and `igrf`
 * models, and the sampler that puts any field onto a grid.  Grid files
 * (HDF5, format in fields/README.md) are the io layer's: gcpush/grid_file.h
 * reads and writes them; the `grid` model gets a file's data through a
 * gcp_grid_reader (field.h).
 *
 * Memory: a gridded field holds one copy of its spline coefficients per
 * field object (read once per process; threads share the object, which is
 * read-only after creation).  Sharing one copy between the ranks of a node
 * (MPI-3 shared windows) is a later step.
 *
 * SI units throughout: lengths [m], B [T], E [V/m], psi [Wb/rad].
 */
#ifndef GCPUSH_GRID_H
#define GCPUSH_GRID_H

#include <stddef.h>

#include "error.h"
#include "field.h"
#include "api.h"
GCP_API_BEGIN

#ifdef __cplusplus
extern "C" {
#endif

enum gcp_grid_geometry {
    GCP_GRID_AXISYMMETRIC = 2, /* 2D (R, Z), fields independent of phi */
    GCP_GRID_CARTESIAN = 3     /* 3D (x, y, z) */
};

enum gcp_grid_interp {
    GCP_INTERP_CUBIC = 0, /* cubic B-spline: C2, value error O(h^4) (default) */
    GCP_INTERP_LINEAR = 1 /* bi/trilinear: C0, value error O(h^2), faster */
};

/* What a grid file holds, in memory.  Arrays are node values in C order of
 * the HDF5 datasets: axisymmetric (nZ, nR), R fastest: v[iR + nR iZ];
 * Cartesian (nz, ny, nx), x fastest: v[ix + nx (iy + ny iz)]. */
struct gcp_grid_data {
    enum gcp_grid_geometry geometry;
    size_t n[3];        /* nodes along (R, Z, -) or (x, y, z) */
    double origin[3];   /* [m] first node */
    double spacing[3];  /* [m] node spacing (> 0) */
    double *B[3];       /* [T] (BR, Bphi, BZ) or (Bx, By, Bz); BR, BZ may be NULL when psi is given */
    double *E[3];       /* [V/m] (ER, Ephi, EZ) or (Ex, Ey, Ez), all NULL when absent */
    double *psi;        /* [Wb/rad] poloidal flux per radian (axisymmetric only), may be NULL:
                           B_R = -(1/R) dpsi/dZ, B_Z = +(1/R) dpsi/dR  (psi = R A_phi) */
    double r_inner;     /* [m] precipitation radius of the source field (0: none) */
    double r_outer;     /* [m] outer radius (inf: none) */
    double z_max;       /* [m] |z| bound (inf: none) */
};

/* Sampling request for gcp_grid_sample. */
struct gcp_grid_spec {
    enum gcp_grid_geometry geometry;
    size_t n[3];        /* nodes per axis, >= 5 each (axisymmetric: n[2] unused) */
    double lo[3], hi[3];/* [m] first and last node per axis (R, Z) or (x, y, z) */
    double t;           /* [s] time at which a time-dependent source is sampled */
};

/* Frees the arrays of d (a reader's or gcp_grid_sample's) and sets them NULL. */
void gcp_grid_data_free(struct gcp_grid_data *d);

/* Samples src on the grid of spec into *out (free with gcp_grid_data_free;
 * gcp_grid_sample_write, grid_file.h, writes it to a grid file).  Nodes
 * inside the source's r_inner (e.g. inside the Earth, where a dipole is
 * singular) take the source's value at the radial projection onto the
 * sphere r = r_inner: a finite, continuous fill the particles never visit
 * (they precipitate at r_inner).  The source's r_inner, r_outer, z_max go
 * with the grid.  Non-finite source values are an error naming the node.
 * 0, or a negative code with err set and *out empty. */
int gcp_grid_sample(const struct gcp_field *src, const struct gcp_grid_spec *spec,
                    struct gcp_grid_data *out, struct gcp_error *err);

/* The `grid` model from data in memory (copied: d may be freed after).
 * use_psi: axisymmetric only; B_R, B_Z from the spline of psi (exactly
 * divergence-free) instead of from BR, BZ.  NULL with err set on failure. */
struct gcp_field *gcp_field_grid_create(const struct gcp_grid_data *d,
                                        enum gcp_grid_interp interp, int use_psi,
                                        struct gcp_error *err);
/* The `grid` model from the grid file `path` as `read` gives it (use_psi:
 * -1 chooses psi only when the file has psi and lacks BR or BZ).  read is
 * gcp_grid_read (grid_file.h) for HDF5 files, which gcp_field_grid_load
 * passes; NULL is refused with an error naming the file. */
int gcp_field_grid_load_with(const char *path, gcp_grid_reader read, enum gcp_grid_interp interp,
                             int use_psi, struct gcp_field **out, struct gcp_error *err);

/* Poloidal flux per radian psi = R A_phi [Wb/rad] at x for axisymmetric
 * models that know it (grid with psi, eqdsk), so that the canonical
 * toroidal momentum is p_phi = q psi + m R u_phi.  0, GCP_LEFT_GRID outside
 * the grid, or GCP_ERR_STATE when the model has no psi. */
int gcp_field_psi(const struct gcp_field *f, const double x[3], double *psi);

/* ---- G-EQDSK tokamak equilibria (fields/eqdsk.c) ---------------------- */

struct gcp_eqdsk_info {
    int nw, nh;               /* R and Z nodes */
    double rleft, rdim;       /* [m] grid R start and width */
    double zmid, zdim;        /* [m] grid Z centre and height */
    double rmaxis, zmaxis;    /* [m] magnetic axis */
    double simag, sibry;      /* [Wb/rad] psi on axis and at the boundary, as in the file */
    double rcentr, bcentr;    /* [m], [T] vacuum field reference */
    double current;           /* [A] plasma current */
    int cocos;                /* identified (or given) COCOS index, 1..8 */
    double zbmin, zbmax;      /* [m] Z extent of the last closed flux surface */
};

/* Reads a g-file.  cocos = 0 identifies the convention from the signs of
 * the current, the field and dpsi (see eqdsk.c); 1..8 imposes one. */
int gcp_field_eqdsk_load(const char *path, int cocos, struct gcp_field **out,
                         struct gcp_error *err);
int gcp_field_eqdsk_info(const struct gcp_field *f, struct gcp_eqdsk_info *info);
/* The file's profiles at normalised flux psi_N = (psi - simag)/(sibry - simag)
 * in [0, 1] (cubic spline; clamped): q, F = R B_phi [T m], pressure [Pa]. */
double gcp_field_eqdsk_q(const struct gcp_field *f, double psiN);
double gcp_field_eqdsk_F(const struct gcp_field *f, double psiN);

/* ---- IGRF (fields/igrf.c) --------------------------------------------- */

#define GCP_IGRF_NMAX 13
/* The Gauss coefficients [T] of one epoch: g[n][m], h[n][m], n <= nmax. */
struct gcp_igrf_coeffs {
    int nmax;
    double epoch;   /* decimal year */
    double g[GCP_IGRF_NMAX + 1][GCP_IGRF_NMAX + 1];
    double h[GCP_IGRF_NMAX + 1][GCP_IGRF_NMAX + 1];
};

/* Reads the IGRF table (igrf14coeffs.txt format) and forms the coefficients
 * at epoch (decimal year, 1900 <= epoch <= 2030): linear interpolation
 * between the 5-year epochs, the secular-variation column after the last
 * one.  0 or a negative code (err names the file and the problem). */
int gcp_igrf_coeffs_at(const char *path, double epoch, struct gcp_igrf_coeffs *c,
                       struct gcp_error *err);
/* The field of coefficients c (truncated at degree nmax <= c->nmax; 0: all)
 * in geocentric Cartesian coordinates (x to 0 deg longitude on the equator,
 * z to the geographic north pole), reference radius GCP_EARTH_RADIUS.
 * r_inner, r_outer: as the dipole's (0, inf: none).  NULL when out of memory. */
struct gcp_field *gcp_field_igrf_create(const struct gcp_igrf_coeffs *c, int nmax,
                                        double r_inner, double r_outer);

#ifdef __cplusplus
}
#endif
GCP_API_END
#endif /* GCPUSH_GRID_H */
