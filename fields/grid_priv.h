/* fields/grid_priv.h -- the tensor-product spline core (spline.c) shared by
 * the gridded models (grid.c, eqdsk.c) and the flux chart's table.  Not
 * installed.
 *
 * A `gcp_spl` holds ncomp scalar fields on one uniform grid of nd = 1, 2 or
 * 3 axes.  Axis 0 varies fastest in memory (x or R), then axis 1 (y or Z),
 * then axis 2 (z): node (i0, i1, i2) of component c is
 * data[c][i0 + n0 (i1 + n1 i2)], the C order of an HDF5 dataset of shape
 * (n2, n1, n0).
 *
 * Cubic (default): the interpolating cubic B-spline, C2 across cells.
 *   f(u) = sum_k c_k beta3(u - k),  u = (x - x0)/h,
 * with coefficients c_{-1} .. c_n per axis fixed by the n interpolation
 * conditions (c_{i-1} + 4 c_i + c_{i+1}) / 6 = f_i and two end conditions
 * ("clamped": the spline slope at the end nodes equals the fourth-order
 * one-sided difference  h f'_0 = (-25 f0 + 48 f1 - 36 f2 + 16 f3 - 3 f4)/12,
 * mirrored at the other end), solved per grid line with the Thomas algorithm
 * (diagonally dominant, stable), axis by axis (the 1D operator is linear, so
 * the tensor product is exact).  Interpolation error O(h^4) in the value,
 * O(h^3) in first and O(h^2) in second derivatives, everywhere including
 * the end cells (the end slopes are O(h^4) accurate).  Derivatives are the
 * analytic derivatives of the same piecewise polynomial.
 *
 * Quintic: the interpolating quintic B-spline, C4 across cells, for fields
 * whose second derivatives enter a Hamiltonian's gradient (psi of an
 * equilibrium: grad B is psi's second derivatives, so a C2 psi leaves
 * kinks in the guiding-centre flow).  Coefficients c_{-2} .. c_{n+1}:
 *   (c_{i-2} + 26 c_{i-1} + 66 c_i + 26 c_{i+1} + c_{i+2}) / 120 = f_i
 * and four end conditions: the spline's h f' and h^2 f'' at the end nodes
 * equal the 7-point one-sided differences (sixth- and fifth-order), a
 * banded system solved by LU once per axis.  Needs n >= 7 nodes.
 * Error O(h^6) in the value, O(h^{6-k}) in the k-th derivative.
 *
 * Septic: the interpolating septic B-spline, C6 across cells, for the same
 * use where a method's error expansion needs the flow's derivatives up to
 * fourth order continuous (gc-gl4 in a G-EQDSK equilibrium: the flow holds
 * psi's second derivatives, so C6 psi leaves it C4; fields/eqdsk.c).
 * Coefficients c_{-3} .. c_{n+2}:
 *   (c_{i-3} + 120 c_{i-2} + 1191 c_{i-1} + 2416 c_i + 1191 c_{i+1}
 *    + 120 c_{i+2} + c_{i+3}) / 5040 = f_i
 * and six end conditions: h f', h^2 f'', h^3 f''' at the end nodes equal
 * the 9-point one-sided differences (exact for degree 8), solved by LU once
 * per axis.  Needs n >= 9 nodes.  Error O(h^8) in the value, O(h^{8-k}) in
 * the k-th derivative.  Cost: 8 coefficients per axis against 6.
 *
 * Linear: the multilinear interpolant of the node values (C0; its gradient
 * is the exact, piecewise constant, gradient of that interpolant).
 *
 * Domain: the closed box of the nodes.  A point outside is evaluated at the
 * nearest point of the box (finite values, never extrapolated) and flagged.
 */
#ifndef GCPUSH_GRID_PRIV_H
#define GCPUSH_GRID_PRIV_H

#include <stddef.h>

#include <math.h>

#include "gcpush/error.h"

#define GCP_SPL_MAXCOMP 8

enum gcp_spl_kind { GCP_SPL_CUBIC = 0, GCP_SPL_LINEAR = 1, GCP_SPL_QUINTIC = 2, GCP_SPL_SEPTIC = 3 };

struct gcp_spl {
    int nd;                 /* axes: 1, 2 or 3 */
    int kind;               /* enum gcp_spl_kind */
    int ncomp;              /* scalar fields held */
    size_t n[3];            /* nodes per axis (1 for unused axes) */
    size_t m[3];            /* stored points per axis: n + 2 (cubic), n + 4 (quintic),
                             * n + 6 (septic), n (linear); 1 unused */
    size_t stride[3];       /* memory stride of each axis in coef */
    double x0[3];           /* [m] first node */
    double h[3];            /* [m] spacing */
    double inv_h[3];        /* [1/m] */
    double umax[3];         /* n - 1: the last node in grid units */
    double *coef[GCP_SPL_MAXCOMP]; /* B-spline coefficients, or node values (linear) */
};

/* Builds the interpolant of ncomp fields given at the nodes (layout above);
 * data is only read.  Needs n >= 5 nodes on every used axis for the cubic
 * kind, n >= 7 for quintic, n >= 9 for septic, n >= 2 for linear.  0 or GCP_ERR_NOMEM / GCP_ERR_VALUE (err set). */
int gcp_spl_build(struct gcp_spl *s, int nd, int kind, const size_t n[], const double x0[],
                  const double h[], int ncomp, const double *const data[], struct gcp_error *err);
void gcp_spl_free(struct gcp_spl *s);

/* Derivatives wanted from gcp_spl_eval: 0 value only, 1 value and first
 * derivatives, 2 also second derivatives (zero for linear). */
struct gcp_spl_out {
    double f;        /* value */
    double d[3];     /* df/dx_a [1/m] */
    double dd[3][3]; /* d2f/dx_a dx_b [1/m^2] (order 2) */
};

/* Locates x (nd coordinates) in the grid: fills the per-axis cell and
 * weights in *loc, returns 1 when x lies outside the closed box (the
 * weights are then those of the nearest point of the box), 0 inside.
 * A NaN coordinate counts as outside. */
struct gcp_spl_loc {
    size_t base;        /* offset of the first coefficient of the stencil */
    double w[3][8];     /* weights per axis (4 cubic, 6 quintic, 8 septic, 2 linear) */
    double dw[3][8];    /* d/dx of the weights [1/m] */
    double ddw[3][8];   /* d2/dx2 [1/m^2] */
};
int gcp_spl_locate(const struct gcp_spl *s, const double *x, int order, struct gcp_spl_loc *loc);

/* Value (and derivatives up to order) of component c at a located point. */
void gcp_spl_eval(const struct gcp_spl *s, const struct gcp_spl_loc *loc, int c, int order,
                  struct gcp_spl_out *out);

/* ---- 1D splines on a uniform grid (profiles, e.g. F(psi)) ------------- */

/* f at u in [0, n-1] grid units (clamped to the range), with f' and f''
 * with respect to u (divide by h, h^2 for physical units). */
double gcp_spl1_eval(const struct gcp_spl *s, int c, double u, double *du, double *ddu);


/* ---- models and shared helpers ----------------------------------------- */

#include "gcpush/field.h"
#include "gcpush/grid.h"

extern const struct gcp_field_type gcp_field_grid;
extern const struct gcp_field_type gcp_field_eqdsk;
extern const struct gcp_field_type gcp_field_igrf;

/* gcp_field_eqdsk_load with the spline kind of psi and of the profiles
 * given: GCP_SPL_SEPTIC (what gcp_field_eqdsk_load uses) or GCP_SPL_QUINTIC
 * (the interpolant of before, kept for the test that shows it loses gc-gl4's
 * order, tests/unit/test_gc_symplectic_flux.c). */
int gcp_eqdsk_load_kind(const char *path, int cocos, int kind, struct gcp_field **out,
                        struct gcp_error *err);

/* psi of an eqdsk field at (R, Z) (the eqdsk type's psi member). */
int gcp_eqdsk_psi_RZ(const struct gcp_field *f, double R, double Z, double *psi);

/* Cylindrical (R, phi, Z) components and their R, Z derivatives at the
 * point (x, y, z) with R = hypot(x, y) > 0, cos phi = c, sin phi = s, to
 * Cartesian B and grad B.  With Bx = bR c - bp s, By = bR s + bp c, Bz = bZ
 * and dR/dx = c, dR/dy = s, dc/dx = s^2/R, dc/dy = ds/dx = -c s/R,
 * ds/dy = c^2/R (the rotating basis gives the 1/R terms):
 *   dBx/dx = c (bR_R c - bp_R s) + s (bR s + bp c)/R
 *   dBx/dy = s (bR_R c - bp_R s) - c (bR s + bp c)/R
 *   dBy/dx = c (bR_R s + bp_R c) - s (bR c - bp s)/R
 *   dBy/dy = s (bR_R s + bp_R c) + c (bR c - bp s)/R
 *   dBx/dz = bR_Z c - bp_Z s,  dBy/dz = bR_Z s + bp_Z c,
 *   dBz/dx = bZ_R c,  dBz/dy = bZ_R s,  dBz/dz = bZ_Z.
 * (Check: the trace is bR_R + bR/R + bZ_Z, the cylindrical divergence.) */
static inline void gcp_axi_to_cart(double c, double s, double R, const double b[3],
                                   const double dR[3], const double dZ[3], double B[3],
                                   double G[3][3], int want_grad)
{
    B[0] = b[0] * c - b[1] * s;
    B[1] = b[0] * s + b[1] * c;
    B[2] = b[2];
    if (!want_grad) return;
    const double iR = 1.0 / R;
    const double px = dR[0] * c - dR[1] * s; /* d(Bx)/dR at fixed phi */
    const double py = dR[0] * s + dR[1] * c; /* d(By)/dR at fixed phi */
    const double ax = B[1] * iR;             /* (bR s + bp c)/R */
    const double ay = B[0] * iR;             /* (bR c - bp s)/R */
    G[0][0] = c * px + s * ax;
    G[0][1] = s * px - c * ax;
    G[0][2] = dZ[0] * c - dZ[1] * s;
    G[1][0] = c * py - s * ay;
    G[1][1] = s * py + c * ay;
    G[1][2] = dZ[0] * s + dZ[1] * c;
    G[2][0] = dR[2] * c;
    G[2][1] = dR[2] * s;
    G[2][2] = dZ[2];
}

/* R = hypot(x, y) floored at Rmin > 0 (a point on the axis takes phi = 0);
 * returns R and sets c, s. */
static inline double gcp_axi_R(double x, double y, double Rmin, double *c, double *s)
{
    double R = sqrt(x * x + y * y);
    if (R < Rmin) {
        *c = 1.0;
        *s = 0.0;
        return Rmin;
    }
    *c = x / R;
    *s = y / R;
    return R;
}

#endif
