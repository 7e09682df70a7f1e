/* Private to gc_sundman.c and its tests: the time transformation of the
 * symplectic adaptive methods gc-gl2-sundman / gc-gl4-sundman (issue 11). */
#ifndef GCPUSH_GC_SUNDMAN_PRIV_H
#define GCPUSH_GC_SUNDMAN_PRIV_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

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

/* gc-gl2/gl4-sundman in the dipole's line coordinates, fused
 * (gc_sundman_dipole.c): 0 with the live lane count in *live when it
 * pushed, -1 when the field is not the dipole form without E (the chart's
 * per-lane path then pushes). */
int gcp_sundman_dipole_advance(struct gcp_block *b, const struct gcp_field *f,
                               const struct gcp_push_opts *o, const struct gcp_sampler *smp,
                               const struct gl_tableau *tab, size_t *live);
/* Its s-step on the extended state y = (phi', s, t, P_phi, P_s, p_t) of
 * the dipole k for tests (S stages; c04: w^4 = c04 W^3/g; plain: the step
 * in t of size w(s0) ds instead); *H the energy at the end; 0 or -1. */
int gcp_sundman_dipole_step(double k, double q, double m, double mu, double c04, int S, double ds,
                            int plain, double y[6], double *H);
/* n such s-steps, the predictor from the last step as the pusher's grid
 * steps, fn(y, H, ctx) after each; 0 or -1 (y at the last good step). */
int gcp_sundman_dipole_run(double k, double q, double m, double mu, double c04, int S, double ds,
                           int plain, double y[6], int64_t n,
                           void (*fn)(const double y[6], double H, void *ctx), void *ctx);

#endif
