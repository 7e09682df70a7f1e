/* gcpush/field_kernels.h -- closed-form point field kernels (issue 12).
 *
 * Kernel layer (below fields/): the B (and E) of a field model that is one
 * closed formula, as a static inline function of the point, with the
 * model's numbers in a small struct.  A field model that is exactly one of
 * these forms says so through gcp_field_type.point_B (field.h): it fills a
 * struct gcp_point_B with the form id and its parameters.  A pusher can
 * then fuse drift, field and kick into one loop per (form, kick), chosen
 * once per push outside the inner loop (src/pushers/fo_fused_priv.h), or
 * the stages of gc-rk4 into one loop per stage and form
 * (src/pushers/gc_rk4_fused.c, which takes the dipole's |B|, B x (B.grad B)
 * and B.(B.grad B) below).  The forms are vacuum fields (curl B = 0), which the fused
 * guiding-centre right-hand side uses (B*_par = |B|): a form of a field
 * with currents needs its own right-hand side there.
 *
 * Which layer knows what (docs/DESIGN.md, "Point field kernels"):
 *  - this header knows formulas, not models: "a centred dipole c (-3 z x +
 *    r^2 zhat)/r^5", "a constant B and E";
 *  - fields/ knows which of its models (and which instances: a dipole
 *    without corotation, any uniform field) is one of these forms, and
 *    checks in the conformance battery that the form gives the model's own
 *    eval bit for bit (tests/unit/test_conformance.c);
 *  - pushers/ see a form id, never a model: a new model with a closed form
 *    exports a form and gets the fused loop; a model without one (grids,
 *    callbacks, time-dependent fields) exports none and keeps the block
 *    evaluation path.
 *
 * The arithmetic is that of the models' own eval, operation for operation
 * (the build keeps -ffp-contract=off), so a fused push gives the same bits
 * as the block push.  No errno: sqrt of r^2 >= 1 (floored). */
#ifndef GCPUSH_FIELD_KERNELS_H
#define GCPUSH_FIELD_KERNELS_H

#include <math.h>

#include "kernels.h" /* GCP_HD: __host__ __device__ under CUDA (tests/bench/cuda) */

/* The forms (0: none, the model is not one closed formula). */
enum gcp_point_B_form {
    GCP_POINT_B_NONE = 0,
    GCP_POINT_B_UNIFORM = 1, /* B = (p[0], p[1], p[2]) [T], E = (p[3], p[4], p[5]) [V/m] */
    GCP_POINT_B_DIPOLE = 2,  /* B = p[0] (-3 z x_vec + r^2 zhat) / r^5, p[0] = B0 R_E^3 [T m^3],
                                r^2 floored at GCP_POINT_DIPOLE_R2_MIN; E = 0 */
    GCP_POINT_B_NFORMS = 3
};

/* A static field given by one form: what gcp_field_type.point_B fills. */
struct gcp_point_B {
    int form;       /* enum gcp_point_B_form */
    int has_E;      /* [bool] E != 0 (UNIFORM only) */
    int has_A;      /* [bool] the model's own A is the form's closed form
                       (gcp_point_A_dipole): its gauge, not just its curl */
    double p[6];    /* the form's parameters, above */
};

/* [m^2] the dipole's floor of r^2: x = 0 gives finite numbers instead of
 * 0 * inf = NaN; it only changes points with r < 1 m, deep inside the
 * Earth (fields/dipole.c's DIPOLE_R2_MIN, the same number). */
#define GCP_POINT_DIPOLE_R2_MIN 1.0

/* Centred dipole, moment along -z (Jackson, Classical Electrodynamics, 3rd
 * ed., eq. 5.56, with m = -zhat, c = B0 R_E^3):
 *   B = c (-3 z x_vec + r^2 zhat) / r^5,
 *   Bx = -3 c z x / r^5,  By = -3 c z y / r^5,  Bz = c (r^2 - 3 z^2) / r^5,
 * in the operations and order of fields/dipole.c's dipole_B (bit-identical). */
static inline GCP_HD void gcp_point_B_dipole(double c, double x, double y, double z, double *bx,
                                      double *by, double *bz)
{
    double r2 = x * x + y * y + z * z;
    r2 = r2 > GCP_POINT_DIPOLE_R2_MIN ? r2 : GCP_POINT_DIPOLE_R2_MIN;
    const double c5 = c / (r2 * r2 * sqrt(r2));
    const double m3z = -3.0 * c5 * z;
    *bx = m3z * x;
    *by = m3z * y;
    *bz = c5 * (r2 - 3.0 * z * z);
}

/* The dipole's vector potential (the model's gauge: A = a (-y, x, 0),
 * a = -c/r^3, so psi = R A_phi = -c R^2/r^3 is constant on a field line),
 * in the operations and order of fields/dipole.c's dipole_potential
 * (bit-identical): 1 square root and 1 division. */
static inline GCP_HD void gcp_point_A_dipole(double c, double x, double y, double z, double A[3])
{
    double r2 = x * x + y * y + z * z;
    r2 = r2 > GCP_POINT_DIPOLE_R2_MIN ? r2 : GCP_POINT_DIPOLE_R2_MIN;
    const double r = sqrt(r2), ir3 = 1.0 / (r2 * r);
    const double a = -c * ir3;
    A[0] = -a * y;
    A[1] = a * x;
    A[2] = 0.0;
}

/* The dipole's B and its gradient G_ij = dB_i/dx_j (what the guiding
 * centre needs: gcp_gc_rhs), differentiating B above:
 *   G_ij = -3 c/r^5 [ z d_ij + x_i d_jz + x_j d_iz - 5 z x_i x_j / r^2 ],
 * symmetric (curl B = 0) and traceless (div B = 0), written out per
 * component, G_ij = a (-zf x_i x_j [+ z if i = j] [+ x_i if j = z]
 * [+ x_j if i = z]) with a = -3 c/r^5, zf = 5 z/r^2, in the operations and
 * order of fields/dipole.c's eval and block evaluation (bit-identical).
 * 1 square root and 2 divisions. */
static inline GCP_HD void gcp_point_BG_dipole(double c, double x, double y, double z,
                                              double B[3], double G[3][3])
{
    double r2 = x * x + y * y + z * z;
    r2 = r2 > GCP_POINT_DIPOLE_R2_MIN ? r2 : GCP_POINT_DIPOLE_R2_MIN;
    const double c5 = c / (r2 * r2 * sqrt(r2));
    const double a = -3.0 * c5, zf = 5.0 * z / r2;
    B[0] = a * z * x;
    B[1] = a * z * y;
    B[2] = c5 * (r2 - 3.0 * z * z);
    const double px = -zf * x, py = -zf * y, pz = -zf * z;
    G[0][0] = a * (px * x + z);
    G[0][1] = a * (px * y);
    G[0][2] = a * (px * z + x);
    G[1][0] = a * (py * x);
    G[1][1] = a * (py * y + z);
    G[1][2] = a * (py * z + y);
    G[2][0] = a * (pz * x + x);
    G[2][1] = a * (pz * y + y);
    G[2][2] = a * (((pz * z + z) + z) + z);
}

/* What the guiding-centre right-hand side of a curl-free field needs
 * (src/pushers/gc_rk4_fused.c), in the dipole's closed form: B, |B|, and of
 * H = B.grad B (H_j = B_i dB_i/dx_j = grad(|B|^2)_j/2 = |B| grad|B|) the
 * products C = B x H and P = B.H.  From |B|^2 = c^2 (r^2 + 3 z^2)/r^8,
 * with c5 = c/r^5:
 *   |B| = |c5| r sqrt(r^2 + 3 z^2),
 *   H = -3 c5^2 ((r^2 + 4 z^2) x, (r^2 + 4 z^2) y, 4 z^2 z),
 *   C = B x H = -3 c5^3 r^2 (r^2 + z^2) (-y, x, 0)   (azimuthal),
 *   P = B.H = 3 c5^3 z r^2 (3 r^2 + 5 z^2),
 * and B as gcp_point_B_dipole, bit for bit.  2 square roots (|B|'s runs
 * beside r's) and 1 division; 17 multiplications (B with the full
 * gradient and the products formed from it: 37 + 9 and 2 divisions).
 * |B|, C and P equal those formed from the model's B and grad B to
 * round-off, not bit for bit (tests/unit/test_gc_fused.c). */
static inline GCP_HD void gcp_point_gc_dipole(double c, double x, double y, double z, double B[3],
                                              double *Bm, double C[3], double *P)
{
    const double zz = z * z;
    double r2 = x * x + y * y + zz;
    r2 = r2 > GCP_POINT_DIPOLE_R2_MIN ? r2 : GCP_POINT_DIPOLE_R2_MIN;
    const double r = sqrt(r2), q = sqrt(r2 + 3.0 * zz);
    const double c5 = c / (r2 * r2 * r);
    const double m3 = -3.0 * c5, m3z = m3 * z;
    B[0] = m3z * x;
    B[1] = m3z * y;
    B[2] = c5 * (r2 - 3.0 * z * z);
    *Bm = fabs(c5) * (r * q);
    const double k3r2 = m3 * c5 * c5 * r2, K = k3r2 * (r2 + zz); /* -3 c5^3 r^2 (r^2 + z^2) */
    C[0] = -(K * y);
    C[1] = K * x;
    C[2] = 0.0;
    *P = -(k3r2 * z) * (3.0 * r2 + 5.0 * zz);
}

/* Any form at one point: B [T] and E [V/m] (zeros where the form has
 * none).  A switch per call: for checks and scalar use; the fused loops
 * instantiate one form each instead. */
static inline GCP_HD void gcp_point_B_eval(const struct gcp_point_B *f, double x, double y, double z,
                                    double B[3], double E[3])
{
    E[0] = E[1] = E[2] = 0.0;
    switch (f->form) {
    case GCP_POINT_B_UNIFORM:
        B[0] = f->p[0], B[1] = f->p[1], B[2] = f->p[2];
        E[0] = f->p[3], E[1] = f->p[4], E[2] = f->p[5];
        break;
    case GCP_POINT_B_DIPOLE:
        gcp_point_B_dipole(f->p[0], x, y, z, &B[0], &B[1], &B[2]);
        break;
    default:
        B[0] = B[1] = B[2] = 0.0;
    }
}

/* The same with grad B [T/m] (zero for the uniform form). */
static inline GCP_HD void gcp_point_BG_eval(const struct gcp_point_B *f, double x, double y,
                                            double z, double B[3], double G[3][3], double E[3])
{
    gcp_point_B_eval(f, x, y, z, B, E);
    for (int i = 0; i < 3; i++) G[i][0] = G[i][1] = G[i][2] = 0.0;
    if (f->form == GCP_POINT_B_DIPOLE) gcp_point_BG_dipole(f->p[0], x, y, z, B, G);
}

#endif /* GCPUSH_FIELD_KERNELS_H */
