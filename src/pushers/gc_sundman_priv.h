/* Private to gc_sundman.c and its tests: the time transformation of the
 * symplectic adaptive methods gc-gl2-sundman / gc-gl4-sundman (issue 11). */
#ifndef GCPUSH_GC_SUNDMAN_PRIV_H
#define GCPUSH_GC_SUNDMAN_PRIV_H

#include <math.h>
#include <stddef.h>

#include "gc_gauss_priv.h"

/* w = (B_ref/|B|)^GCP_SUNDMAN_A (why 1/4: the comment of gc_sundman.c) */
#define GCP_SUNDMAN_A 0.25

/* w at the lane's state (gl_rhs of gc_gauss.c evaluates the same w at the
 * stages): 0 or a particle status.  aux: the chart guess, updated. */
static inline int gcp_sundman_w(const struct gl_ctx *C, const struct gcp_gc_consts *k,
                                const struct gl_lane *L, double aux[2], double *w)
{
    double Bm, dB[4];
    const int st = C->chart.field_strength(&C->chart, k, L->z, aux, &Bm, dB);
    *w = st ? NAN : pow(L->Bref / Bm, C->sundman_a);
    return st;
}

/* Lane i of block b at time t0 in extended phase space: the canonical state
 * (gcp_gl_init), t = t0, p_t = -H(z0), B_ref = |B(z0)| (w = 1 there).
 * 0 or a particle status. */
int gcp_sundman_lane_init(const struct gl_ctx *C, const struct gcp_block *b, size_t i, double t0,
                          struct gl_lane *L);

#endif
