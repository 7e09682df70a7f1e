/* fields/flux_priv.h -- what the canonical flux charts (src/pushers/
 * canon_flux*.c, issue 11) need from an axisymmetric model with a flux
 * function, without knowing which model it is.  Not installed.
 *
 * Conventions: cylindrical (R, phi, Z), right-handed (Rhat x phihat = Zhat);
 * psi = R A_phi [Wb/rad] as in gcp_field_psi, B_pol = grad psi x grad phi.
 */
#ifndef GCPUSH_FLUX_PRIV_H
#define GCPUSH_FLUX_PRIV_H

#include <stddef.h>

#include "gcpush/field.h"

/* psi and its R, Z derivatives up to second order at (R, Z):
 * out = {psi, psi_R, psi_Z, psi_RR, psi_RZ, psi_ZZ} [Wb/rad, /m, /m^2].
 * 0, GCP_LEFT_GRID / GCP_LEFT_DOMAIN outside the model's domain (values are
 * still finite), or GCP_ERR_STATE for a model without a flux function. */
int gcp_field_psi_RZ(const struct gcp_field *f, double R, double Z, double out[6]);

/* gcp_field_psi_RZ and gcp_field_eval of B and grad B at (R, 0, Z)
 * together (s->need set here): the same numbers as the two calls, from one
 * evaluation of psi where the model's B comes from its psi (G-EQDSK: one
 * spline locate and evaluation instead of two), else the two calls.
 * Returns psi's status, *fst the field's. */
int gcp_field_psi_B_RZ(const struct gcp_field *f, double R, double Z, double out[6],
                       struct gcp_field_sample *s, int *fst);
/* gcp_field_psi_B_RZ (the same numbers) and B's second-order Taylor data
 * in the R-Z plane at phi = 0: Bd[i] = (B_i, d/dR, d/dZ, d2/dR2, d2/dRdZ,
 * d2/dZ2) of (B_R, B_phi, B_Z) (the flux chart's analytic Jacobian).
 * Returns -1, evaluating nothing, where the model has none (only G-EQDSK's
 * biseptic psi has: fields/eqdsk.c, which holds this dispatch). */
int gcp_field_psi_B_RZ3(const struct gcp_field *f, double R, double Z, double out[6],
                        struct gcp_field_sample *s, int *fst, double Bd[3][6]);

/* k such that the model's psi is C^k (its derivatives up to k continuous):
 * 2 for a grid's bicubic psi, 6 for G-EQDSK's septic spline,
 * GCP_PSI_ANALYTIC for closed forms; 0 for a model without psi.  Tables
 * built from psi (the flux chart's, src/pushers/canon_flux_num.c) take it
 * to choose their own smoothness. */
#define GCP_PSI_ANALYTIC 1000
int gcp_field_psi_continuity(const struct gcp_field *f);

/* Where the model's closed flux surfaces are, when it knows: a guess of the
 * magnetic axis (R_axis, Z_axis) [m] and psi_edge [Wb/rad], the flux of the
 * last closed surface (the plasma boundary).  0 or GCP_ERR_STATE. */
int gcp_field_flux_surfaces(const struct gcp_field *f, double *R_axis, double *Z_axis,
                            double *psi_edge);

/* One point of an orthogonal poloidal chart (s, eta) of the R-Z plane:
 * eta is constant along the gradient lines of psi (so dX/ds is along
 * grad psi), and A_eta is the covariant eta component of a vector potential
 * in the gauge A_s = 0, A = psi grad phi + A_eta grad eta, i.e.
 *   dA_eta/ds = J B^phi = (Z_s R_e - R_s Z_e) B_phi,
 * J = dX/ds . (dX/deta x dX/dphi) the Jacobian of (s, eta, phi).
 * Suffixes _s, _e are partial derivatives with respect to s and eta. */
struct gcp_polchart_pt {
    double R, Z;                       /* [m] */
    double R_s, Z_s, R_e, Z_e;         /* [m/s-unit], [m/eta-unit] */
    double R_ss, Z_ss, R_se, Z_se, R_ee, Z_ee; /* second derivatives */
    double A, A_s, A_e;                /* A_eta [T m^2/eta-unit] and derivatives */
    double psi, psi_s, psi_e;          /* psi(X(s, eta)) [Wb/rad] and derivatives */
};

/* An exact orthogonal poloidal chart the model knows in closed form. */
struct gcp_polchart {
    const void *ctx;  /* the model's parameters (not owned) */
    /* (s, eta) -> point.  0, or GCP_LEFT_DOMAIN for s outside [0, s_max]
     * (the point is still filled, finite). */
    int (*map)(const void *ctx, double s, double eta, struct gcp_polchart_pt *pt);
    /* (R, Z) -> (s, eta), eta in (-pi, pi].  0 or GCP_LEFT_DOMAIN. */
    int (*locate)(const void *ctx, double R, double Z, double *s, double *eta);
    /* Optional (NULL: map, then gcp_field_eval): map with the field's B and
     * grad B at the point into *fs (the same numbers), the field evaluated
     * with psi.  Returns map's status, or the field's where map's is 0. */
    int (*map_field)(const void *ctx, double s, double eta, struct gcp_polchart_pt *pt,
                     struct gcp_field_sample *fs);
    double s_max;     /* [s-unit] edge of the chart */
    const char *what; /* "(r, theta) about the magnetic axis", for messages */
};

/* The model's closed-form chart: 0, or GCP_ERR_STATE when it has none. */
int gcp_field_polchart(const struct gcp_field *f, struct gcp_polchart *out);

/* The analytic tokamak's closed form (fields/tokamak.c), for a pusher that
 * fuses the algebra of its exact chart (src/pushers/gc_gauss_tokamak.c):
 * B = B0 R0/R phihat + grad psi x grad phi, psi' (r) = B0 r/q(r),
 * q(r) = q0 + dq r^2, r the distance to the axis (R0, 0), the plasma r <= a;
 * the chart of gcp_field_polchart is (r, theta) about (R0, 0).  1 with *out
 * filled when f is that model, else 0. */
struct gcp_flux_tokamak {
    double B0, R0, a, q0, dq; /* [T], [m], [m], [1], [1/m^2] */
};
int gcp_field_flux_tokamak(const struct gcp_field *f, struct gcp_flux_tokamak *out);

/* Per-model implementations (dispatched from flux.c). */
int gcp_tokamak_psi_RZ(const struct gcp_field *f, double R, double Z, double out[6]);
int gcp_tokamak_polchart(const struct gcp_field *f, struct gcp_polchart *out);
int gcp_tokamak_flux_surfaces(const struct gcp_field *f, double *Ra, double *Za, double *pe);
int gcp_eqdsk_psi_RZ2(const struct gcp_field *f, double R, double Z, double out[6]);
int gcp_eqdsk_psi_B_RZ(const struct gcp_field *f, double R, double Z, double out[6],
                       struct gcp_field_sample *s, int *fst);
int gcp_eqdsk_flux_surfaces(const struct gcp_field *f, double *Ra, double *Za, double *pe);
int gcp_eqdsk_psi_continuity(const struct gcp_field *f);
int gcp_grid_psi_RZ(const struct gcp_field *f, double R, double Z, double out[6]);
int gcp_grid_psi_lattice(const struct gcp_field *f, double x0[2], double h[2], size_t n[2]);
int gcp_grid_flux_surfaces(const struct gcp_field *f, double *Ra, double *Za, double *pe);

/* sum_k c[k] t^k, k < 32, by Estrin's scheme (pairs, then pairs of pairs
 * with t^2, t^4, t^8, t^16): five dependent multiply-adds where Horner's
 * rule chains 32 (the tokamak's A_theta series was its chart map's
 * latency); the rounding is Horner's order of magnitude (|t| < 1/4, terms
 * falling).  One copy for fields/tokamak.c and the pushers' closed-form
 * tokamak solve (src/pushers/gc_gauss_tokamak.c), which must agree. */
static inline __attribute__((always_inline)) double gcp_estrin32(const double c[32], double t)
{
    double a[16];
    const double t2 = t * t, t4 = t2 * t2, t8 = t4 * t4, t16 = t8 * t8;
    for (int i = 0; i < 16; i++) a[i] = c[2 * i] + c[2 * i + 1] * t;
    for (int i = 0; i < 8; i++) a[i] = a[2 * i] + a[2 * i + 1] * t2;
    for (int i = 0; i < 4; i++) a[i] = a[2 * i] + a[2 * i + 1] * t4;
    for (int i = 0; i < 2; i++) a[i] = a[2 * i] + a[2 * i + 1] * t8;
    return a[0] + a[1] * t16;
}
/* The 32 coefficients F(0) .. F(31) of such a series, as an initialiser. */
#define GCP_SERIES_8(F, k) F(k), F(k + 1), F(k + 2), F(k + 3), F(k + 4), F(k + 5), F(k + 6), F(k + 7)
#define GCP_SERIES_32(F) GCP_SERIES_8(F, 0), GCP_SERIES_8(F, 8), GCP_SERIES_8(F, 16), GCP_SERIES_8(F, 24)

#endif
