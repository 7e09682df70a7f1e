/* src/pushers/canon_flux_priv.h -- the flux charts (canon_flux.c, the
 * algebra; canon_flux_num.c, the tabulated chart).  Private to src/pushers/. */
#ifndef GCPUSH_CANON_FLUX_PRIV_H
#define GCPUSH_CANON_FLUX_PRIV_H

#include <stddef.h>

#include "canon_priv.h"
#include "flux_priv.h"

/* The data of a "flux-orthogonal" gcp_canon_chart. */
struct gcp_flux_chart {
    const struct gcp_field *field; /* not owned */
    struct gcp_polchart pc;        /* the orthogonal poloidal chart */
    void *owned;                   /* pc.ctx when the chart built it (tabulated), else NULL */
    void (*free_ctx)(void *owned);
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
