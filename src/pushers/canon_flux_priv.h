/* src/pushers/canon_flux_priv.h -- the flux charts (canon_flux.c, the
 * algebra; canon_flux_num.c, the tabulated chart).  Private to src/pushers/. */
#ifndef GCPUSH_CANON_FLUX_PRIV_H
#define GCPUSH_CANON_FLUX_PRIV_H

#include <stddef.h>

#include "canon_priv.h"
#include "flux_priv.h"

/* What the analytic Jacobian of the collocation solve needs beyond a map
 * with the field (canon_flux.c flux_wlift_eval_df): the chart's third
 * derivatives of X, the second of A_eta, psi's R-Z derivatives and B's
 * second-order data in the R-Z plane (fields/flux_priv.h
 * gcp_field_psi_B_RZ3).  ok = 0: not available at that point. */
struct flux_d3 {
    int ok;
    double R3[4], Z3[4]; /* X_sss, X_sse, X_see, X_eee */
    double A2[3];        /* A_ss, A_se, A_ee */
    double ps[6];        /* psi, psi_R, psi_Z, psi_RR, psi_RZ, psi_ZZ */
    double Bd[3][6];     /* (B_R, B_phi, B_Z): value, d/dR, d/dZ, d2/dR2, d2/dRdZ, d2/dZ2 */
};

/* The data of a "flux-orthogonal" gcp_canon_chart. */
struct gcp_flux_chart {
    const struct gcp_field *field; /* not owned */
    struct gcp_polchart pc;        /* the orthogonal poloidal chart */
    void *owned;                   /* pc.ctx when the chart built it (tabulated), else NULL */
    void (*free_ctx)(void *owned);
    /* Optional (NULL: none): pc.map_field with *d3 (the same numbers in pt
     * and fs; d3->ok = 0 where it has none) */
    int (*map_field3)(const void *ctx, double s, double eta, struct gcp_polchart_pt *pt,
                      struct gcp_field_sample *fs, struct flux_d3 *d3);
};

/* The canonical chart of an axisymmetric field with a flux function and
 * closed flux surfaces (tokamak, eqdsk, grid with psi): the model's exact
 * orthogonal chart when it has one, else a tabulated one.  0, or
 * GCP_ERR_STATE with `why` filled when it does not apply. */
int gcp_canon_chart_flux_create(const struct gcp_field *f, struct gcp_canon_chart *out, char *why,
                                size_t whylen);

/* Builds the tabulated orthogonal chart of f into c->pc (c->owned,
 * c->free_ctx set).  0, or GCP_ERR_STATE / GCP_ERR_NOMEM with why filled. */
int gcp_flux_num_build(const struct gcp_field *f, struct gcp_flux_chart *c, char *why,
                       size_t whylen);

/* The covariant residual h_s = b . dX/ds of the chart at (s, eta) (zero for
 * an exact chart): a measure of the tabulated chart's error.  0 or a status. */
int gcp_flux_chart_hs(const struct gcp_canon_chart *cc, const struct gcp_gc_consts *k, double s,
                      double eta, double ppar, double *h_s);

#endif
