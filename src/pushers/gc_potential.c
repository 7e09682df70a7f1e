/* Vector potentials A (and the electrostatic potential phi) of the built-in
 * analytic fields, for gc-midpoint-pphi's phase-space Lagrangian and for p_phi.
 *
 * Temporary home: these belong in the field files as an optional
 *   int (*potential)(const struct gcp_field *, double t, const double x[3],
 *                    double A[3], double dA[3][3], double *phi);
 * member of struct gcp_field_type.  Until then they read the models'
 * parameter structs, whose layouts are copied below (the tests check
 * curl A = B and -grad phi = E against each model's own eval, so a layout
 * change there is caught).  Keyed by the field type.
 *
 * Derivations (cylindrical R, phi, Z; B = curl A; the axisymmetric ones use
 * the gauge A = A_phi phihat (+ A_R Rhat), regular on the axis):
 *   uniform:  A = (1/2) B x x,  dA_i/dx_l = (1/2) eps_ijl B_j;  phi = -E.x.
 *   dipole:   A_phi = -c R / r^3, c = B0 R_E^3, i.e. A = a (-y, x, 0) with
 *             a = -c / r^3, da/dx_j = 3 c x_j / r^5.  (1/R) d(R A_phi)/dR =
 *             c (R^2 - 2 z^2)/r^5 = Bz, -dA_phi/dz = -3 c R z / r^5 = B_R.
 *             Corotation E = -(Omega x r) x B = -grad(Omega R A_phi):
 *             phi = Omega R A_phi = Omega psi.
 *   mirror:   Bz = B0 + k (z^2 - R^2/2), B_R = -k R z, k = B0/Lm^2:
 *             A_phi = (R/2) [B0 + k (z^2 - R^2/4)]: (1/R) d(R A_phi)/dR =
 *             B0 + k z^2 - k R^2/2 = Bz, -dA_phi/dz = -k R z = B_R.
 *             A = a (-y, x, 0), a = [B0 + k (z^2 - R^2/4)]/2.
 *   tokamak:  B_phi = B0 R0 / R from A_R = B0 R0 Z / R (curl_phi = dA_R/dZ
 *             = B0 R0/R; curl_R = curl_Z = 0), and B_pol = grad psi x grad phi
 *             = curl(psi grad phi) from A_phi = psi / R, with
 *             psi(r) = int_0^r B0 r'/q(r') dr' = (B0/(2 dq)) ln(1 + dq r^2/q0)
 *             (= B0 r^2/(2 q0) for dq = 0), r^2 = (R - R0)^2 + Z^2.
 *             Cartesian: A_x = (g x - psi y)/R^2, A_y = (g y + psi x)/R^2,
 *             A_z = 0, g = B0 R0 z; dpsi/dx = F w x, dpsi/dy = F w y,
 *             dpsi/dz = F z, F = B0/q(r), w = (R - R0)/R.
 */
#include <math.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/field.h"
#include "gcpush/gc.h"
#include "gcpush/grid.h"

/* ---- copies of the models' parameter structs (fields/<model>.c) ---- */
struct gcpot_uniform { double B[3], E[3]; };
struct gcpot_dipole { double c, omega; };
struct gcpot_mirror { double B0, Lm, k; };
struct gcpot_tokamak { double B0, R0, a, q0, qa, a2, dq, qmin, B0R0, R2min; };

/* A = a (-y, x, 0) with a(x) and its gradient da: A and dA. */
static void axial_form(const double x[3], double a, const double da[3], double A[3],
                       double dA[3][3])
{
    A[0] = -a * x[1];
    A[1] = a * x[0];
    A[2] = 0.0;
    if (!dA) return;
    for (int j = 0; j < 3; j++) {
        dA[0][j] = -x[1] * da[j];
        dA[1][j] = x[0] * da[j];
        dA[2][j] = 0.0;
    }
    dA[0][1] -= a;
    dA[1][0] += a;
}

static void pot_uniform(const struct gcpot_uniform *p, const double x[3], double A[3],
                        double dA[3][3], double *phi)
{
    const double *B = p->B;
    A[0] = 0.5 * (B[1] * x[2] - B[2] * x[1]);
    A[1] = 0.5 * (B[2] * x[0] - B[0] * x[2]);
    A[2] = 0.5 * (B[0] * x[1] - B[1] * x[0]);
    if (dA) {
        dA[0][0] = 0.0, dA[0][1] = -0.5 * B[2], dA[0][2] = 0.5 * B[1];
        dA[1][0] = 0.5 * B[2], dA[1][1] = 0.0, dA[1][2] = -0.5 * B[0];
        dA[2][0] = -0.5 * B[1], dA[2][1] = 0.5 * B[0], dA[2][2] = 0.0;
    }
    if (phi) *phi = -(p->E[0] * x[0] + p->E[1] * x[1] + p->E[2] * x[2]);
}

static void pot_dipole(const struct gcpot_dipole *p, const double x[3], double A[3],
                       double dA[3][3], double *phi)
{
    double r2 = x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
    r2 = r2 > 1.0 ? r2 : 1.0; /* the field's own floor (fields/dipole.c) */
    const double r = sqrt(r2), ir3 = 1.0 / (r2 * r);
    const double a = -p->c * ir3;
    const double f5 = 3.0 * p->c * ir3 / r2;
    const double da[3] = {f5 * x[0], f5 * x[1], f5 * x[2]};
    axial_form(x, a, da, A, dA);
    if (phi) *phi = p->omega * (x[0] * A[1] - x[1] * A[0]); /* Omega R A_phi */
}

static void pot_mirror(const struct gcpot_mirror *p, const double x[3], double A[3],
                       double dA[3][3], double *phi)
{
    const double k = p->k;
    const double a = 0.5 * (p->B0 + k * (x[2] * x[2] - 0.25 * (x[0] * x[0] + x[1] * x[1])));
    const double da[3] = {-0.25 * k * x[0], -0.25 * k * x[1], k * x[2]};
    axial_form(x, a, da, A, dA);
    if (phi) *phi = 0.0;
}

static void pot_tokamak(const struct gcpot_tokamak *p, const double xv[3], double A[3],
                        double dA[3][3], double *phi)
{
    const double x = xv[0], y = xv[1], z = xv[2];
    double s = x * x + y * y;
    s = s > p->R2min ? s : p->R2min;
    const double R = sqrt(s), is = 1.0 / s;
    const double dR = R - p->R0;
    const double r2 = dR * dR + z * z;
    /* psi = B0 r^2/(2 q0) * log1p(v)/v, v = dq r^2 / q0 (-> 1 as v -> 0) */
    const double v = p->dq * r2 / p->q0;
    const double lv = v != 0.0 ? log1p(v) / v : 1.0;
    const double psi = p->B0 * r2 / (2.0 * p->q0) * lv;
    const double g = p->B0R0 * z;
    A[0] = (g * x - psi * y) * is;
    A[1] = (g * y + psi * x) * is;
    A[2] = 0.0;
    if (dA) {
        const double q = p->q0 + p->dq * r2; /* unclamped: exact inside the plasma */
        const double F = p->B0 / q, w = dR / R;
        const double px = F * w * x, py = F * w * y, pz = F * z;
        const double P = g * x - psi * y, Q = g * y + psi * x, is2 = is * is;
        dA[0][0] = (g - y * px) * is - 2.0 * x * P * is2;
        dA[0][1] = (-psi - y * py) * is - 2.0 * y * P * is2;
        dA[0][2] = (p->B0R0 * x - y * pz) * is;
        dA[1][0] = (psi + x * px) * is - 2.0 * x * Q * is2;
        dA[1][1] = (g + x * py) * is - 2.0 * y * Q * is2;
        dA[1][2] = (p->B0R0 * y + x * pz) * is;
        dA[2][0] = dA[2][1] = dA[2][2] = 0.0;
    }
    if (phi) *phi = 0.0;
}

int gcp_gc_potential(const struct gcp_field *f, double t, const double x[3], double A[3],
                     double dA[3][3], double *phi)
{
    (void)t;
    const struct gcp_field_type *ft = f->type;
    double psi, R;
    if (ft == &gcp_field_dipole)
        pot_dipole(f->params, x, A, dA, phi);
    else if (ft == &gcp_field_mirror)
        pot_mirror(f->params, x, A, dA, phi);
    else if (ft == &gcp_field_tokamak)
        pot_tokamak(f->params, x, A, dA, phi);
    else if (ft == &gcp_field_uniform)
        pot_uniform(f->params, x, A, dA, phi);
    else if (!dA && gcp_field_psi(f, x, &psi) == 0 && (R = hypot(x[0], x[1])) > 0) {
        /* gridded axisymmetric fields with a flux (grid with psi, eqdsk): the
         * toroidal component A_phi = psi / R, which is all that p_phi and the
         * drift-shell flux need.  The poloidal components (from B_phi) are not
         * known here, so no dA: gc-midpoint-pphi, which needs the whole A, refuses. */
        const double Aphi = psi / R;
        A[0] = -Aphi * x[1] / R, A[1] = Aphi * x[0] / R, A[2] = 0.0;
        if (phi) *phi = 0.0;
    } else
        return GCP_ERR_UNKNOWN;
    return 0;
}
