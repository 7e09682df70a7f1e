/* src/pushers/canon_flux_num_priv.h -- the tabulated orthogonal chart's
 * table, shared by its evaluation and cache (canon_flux_num.c) and its
 * construction (canon_flux_table.c; the equations are in canon_flux_num.c's
 * header).  Private to src/pushers/. */
#ifndef GCPUSH_CANON_FLUX_NUM_PRIV_H
#define GCPUSH_CANON_FLUX_NUM_PRIV_H

#include <stddef.h>

#include "gcpush/field.h"
#include "grid_priv.h"

#define NRHO 128
#define NETA 512
#define NPAD 40       /* periodic padding each side */
#define PSIN_MAX 0.9  /* edge of the chart in psi_N */
#define RHO_REF 0.6

/* The table: immutable once built, shared (reference counted) by every
 * chart of fields with the same fingerprint (see the cache below). */
struct numchart {
    const struct gcp_field *f; /* during construction only (NULL after) */
    int refs;                  /* holders (charts and the cache), under cache_lock */
    struct gcp_spl spl; /* (rho, eta): 0 R, 1 Z, 2 A_eta */
    double Ra, Za;      /* [m] magnetic axis (of the field's psi) */
    double psia, dpsi;  /* [Wb/rad] psi on axis, psi_edge - psi_axis */
    double rho_max;
};

/* Builds the table of f's chart about the axis guess (Ra, Za) with edge
 * flux pe [Wb/rad] into *out (refs = 1).  0, or GCP_ERR_STATE /
 * GCP_ERR_NOMEM with why filled. */
int gcp_flux_num_table_build(const struct gcp_field *f, double Ra, double Za, double pe,
                             struct numchart **out, char *why, size_t whylen);

#endif
