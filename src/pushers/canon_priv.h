/* src/pushers/canon_priv.h -- canonical charts for guiding centres in
 * axisymmetric fields (private to src/pushers/; issue 11).
 *
 * Why.  The guiding-centre phase-space Lagrangian (Littlejohn 1983; Cary &
 * Brizard 2009)
 *     L = (q A + p_par b) . dX/dt - H(X, p_par),   H = gamma m c^2 (+ q Phi)
 * is non-canonical in (X, p_par): a symplectic Runge-Kutta method applied to
 * it in those coordinates is not symplectic for its two-form d theta.  In an
 * axisymmetric field there are coordinates (phi, eta, P_phi, P_eta) -- a
 * chart -- in which, up to an exact differential,
 *     theta = (q A + p_par b) . dX = P_phi dphi + P_eta deta,
 * so the motion is canonical:
 *     dphi/dt = dH/dP_phi, deta/dt = dH/dP_eta,
 *     dP_phi/dt = -dH/dphi = 0 (axisymmetry), dP_eta/dt = -dH/deta,
 * and any symplectic integrator for canonical Hamiltonian systems (Gauss-
 * Legendre collocation, ...) is symplectic for the guiding centre, with
 * P_phi = q psi + p_par R b_phi a discrete Noether invariant.
 *
 * The construction (orthogonal poloidal coordinates (s, eta) in the R-Z
 * plane, so that b has no covariant s component, and a gauge with A_s = 0):
 *   - curl-free axisymmetric fields (dipole, mirror): s = psi, eta = chi, the
 *     magnetic scalar potential (B = -grad chi); P_phi = q psi,
 *     P_chi = p_par b.dX/dchi = -p_par / |B|.
 *   - fields with B_phi and currents (tokamak, EQDSK, R-Z grids with psi):
 *     eta constant along the gradient lines of psi (Albert, Grassler,
 *     Kasilov, Markl & Schatzlmayr 2025 treat the general case).
 *
 * State layout: z[0] = phi [rad], z[1] = eta [chart unit],
 *               z[2] = P_phi [kg m^2/s], z[3] = P_eta [chart unit].
 * aux[2]: the chart's own non-canonical coordinates of the last point it
 * mapped (e.g. (s, p_par)), an in/out Newton guess that makes repeated
 * inversions cheap; to_canon sets it, from_canon and hamiltonian use and
 * update it.  Charts are static (no time dependence).
 */
#ifndef GCPUSH_CANON_PRIV_H
#define GCPUSH_CANON_PRIV_H

#include <stddef.h>
#include <stdint.h>

#include "gcpush/field.h"

/* The constants of one guiding centre. */
struct gcp_gc_consts {
    double q;  /* [C] charge (signed) */
    double m;  /* [kg] rest mass */
    double mu; /* [J/T] magnetic moment p_perp^2 / (2 m |B|) */
};

/* What lift_eval gives at a chart point p (see below). */
struct gcp_canon_lift {
    double Pphi, eta;   /* the canonical coordinates of p (P_phi = q psi, eta) */
    double H, dH[4];    /* [J] H at (p, P_eta) and dH/dz */
    double Bm, dBm[4];  /* [T] |B| at p and d|B|/dz */
    double dp[2][2];    /* dp_r / d(P_phi, eta)_c at p: a change of P_phi, eta -> of p */
};

/* What wlift_eval gives at a point of the chart's own non-canonical
 * coordinates (eta, w), w the aux layout (the flux chart: w = (s, p_par)). */
struct gcp_canon_wpoint {
    double P[2];       /* (P_phi, P_eta) of the point */
    double Pw[2][2];   /* d(P_phi, P_eta)/dw */
    double Pe[2];      /* d(P_phi, P_eta)/deta at fixed w */
    double H, dH[4];   /* [J] H and dH/dz at the point's z */
    double wscale[2];  /* scales of w (the solver's convergence test) */
    double own[20];    /* the chart's own numbers at the point, for a reuse (see wlift_eval) */
};

/* lift_eval over a block of points, struct of arrays (n entries each). */
struct gcp_canon_lift_soa {
    double *Pphi, *eta, *H, *dH1, *dH2, *dH3, *Bm, *dBm1, *dBm2;
    double *dp00, *dp01, *dp10, *dp11; /* dp[r][c] as in gcp_canon_lift */
};

struct gcp_canon_chart {
    const char *name;              /* "curl-free", "flux-orthogonal", ... */
    const struct gcp_field *field; /* not owned */
    void *data;                    /* the chart's own, freed by destroy */
    /* (X [m], p_par [kg m/s]) -> z; sets aux.  0 or a particle status. */
    int (*to_canon)(const struct gcp_canon_chart *c, const struct gcp_gc_consts *k,
                    const double X[3], double ppar, double z[4], double aux[2]);
    /* z -> (X, p_par).  0 or a particle status (GCP_LEFT_DOMAIN outside the
     * chart, GCP_STEP_FAILED when the inversion does not converge). */
    int (*from_canon)(const struct gcp_canon_chart *c, const struct gcp_gc_consts *k,
                      const double z[4], double aux[2], double X[3], double *ppar);
    /* H(z) [J] and dH/dz (dH[0] = dH/dphi = 0 in an axisymmetric field).
     * 0 or a particle status. */
    int (*hamiltonian)(const struct gcp_canon_chart *c, const struct gcp_gc_consts *k,
                       const double z[4], double aux[2], double *H, double dH[4]);
    void (*destroy)(void *data);
    /* Optional (NULL: not provided; added for the Sundman time transformation
     * of gc-gl2-sundman / gc-gl4-sundman): |B| [T] at z and d|B|/dz.
     * 0 or a particle status. */
    int (*field_strength)(const struct gcp_canon_chart *c, const struct gcp_gc_consts *k,
                          const double z[4], double aux[2], double *Bm, double dBm[4]);
    /* Optional (NULL: not provided; the collocation solver then inverts the
     * chart at every evaluation): everything at the chart's own point p (the
     * aux layout, e.g. (R, Z)) with P_eta, from ONE field evaluation, no
     * inversion -- the canonical coordinates the point has, H and dH/dz
     * there, |B| and d|B|/dz, and the chart's inverse Jacobian, which lets
     * gc_gauss.c solve for the stage points themselves (a Newton on the
     * stage equations and the chart equations together).  0 or a status. */
    int (*lift_eval)(const struct gcp_canon_chart *c, const struct gcp_gc_consts *k,
                     const double p[2], double Peta, struct gcp_canon_lift *out);
    /* With lift_eval: H and dH/dz at the point of o with another P_eta, from
     * o alone (no field evaluation).  0 or a status. */
    int (*lift_ham)(const struct gcp_canon_chart *c, const struct gcp_gc_consts *k,
                    const struct gcp_canon_lift *o, double Peta, double *H, double dH[4]);
    /* Optional (without lift_eval): everything at the chart's own point
     * (eta, w) forward, no inversion -- the canonical momenta the point has,
     * their derivatives in (w, eta), H and dH/dz there -- for the collocation
     * solver of gc_gauss_wlift.c, which solves for the stage points w too.
     * same: NULL, or an evaluation at the same eta and w[0] whose geometry
     * the chart may reuse (only w[1] differs).  0 or a status. */
    int (*wlift_eval)(const struct gcp_canon_chart *c, const struct gcp_gc_consts *k, double eta,
                      const double w[2], const struct gcp_canon_wpoint *same,
                      struct gcp_canon_wpoint *out);
    /* Optional (with wlift_eval): wlift_eval (same = NULL; the same numbers)
     * and the derivatives of F = (dH/dP_eta, -dH/deta) there, Fw[r][c] =
     * dF_r/dw_c at fixed eta and Fe[r] = dF_r/deta at fixed w, from the
     * chart's higher derivatives (the solver's Jacobian); *have = 0 where
     * it has none at that point.  0 or a status. */
    int (*wlift_eval_df)(const struct gcp_canon_chart *c, const struct gcp_gc_consts *k,
                         double eta, const double w[2], struct gcp_canon_wpoint *out,
                         double Fw[2][2], double Fe[2], int *have);
    /* Optional (with lift_eval): lift_eval at n points (R[j], Z[j]) with
     * P_eta Peta[j] and magnetic moment mu[j] (q, m of k), the same numbers
     * point by point; status[j] 0 or lift_eval's status.  The block solver
     * of gc_gauss_block.c evaluates all stage points of a block through it. */
    void (*lift_eval_block)(const struct gcp_canon_chart *c, const struct gcp_gc_consts *k,
                            size_t n, const double *mu, const double *R, const double *Z,
                            const double *Peta, const struct gcp_canon_lift_soa *o,
                            int32_t *status);
    /* Optional (with lift_eval_block): lift_ham at n samples of it, from
     * their |B| and d|B|/dz (Bm, dBm1, dBm2) at P_eta Peta[j], magnetic
     * moment mu[j]: dH/dz 1 .. 3 into dH1 .. dH3 (the same numbers as
     * lift_ham); status[j] 0 or lift_ham's status. */
    void (*lift_ham_block)(const struct gcp_canon_chart *c, const struct gcp_gc_consts *k,
                           size_t n, const double *mu, const double *Bm, const double *dBm1,
                           const double *dBm2, const double *Peta, double *dH1, double *dH2,
                           double *dH3, int32_t *status);
    /* Optional: from_canon at n states (SoA z0 .. z3, guesses aux0, aux1)
     * for those it maps at its first Newton iterate (done[j] = 1: X0 .. X2,
     * ppar and aux written, the same numbers as from_canon); the others
     * (done[j] = 0, their aux untouched) are from_canon's to map. */
    void (*from_canon_block)(const struct gcp_canon_chart *c, const struct gcp_gc_consts *k,
                             size_t n, const double *const z[4], double *aux0, double *aux1,
                             double *const X[3], double *ppar, int32_t *done);
};

/* Builds a chart for field f (the first constructor in canon_chart.c that
 * applies).  0, or GCP_ERR_STATE with `why` saying why no chart exists for
 * this field (e.g. "a 3-D field has no axisymmetry to make canonical"). */
int gcp_canon_chart_create(const struct gcp_field *f, struct gcp_canon_chart *out, char *why,
                           size_t whylen);
void gcp_canon_chart_destroy(struct gcp_canon_chart *c);

#endif
