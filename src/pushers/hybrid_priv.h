/* Private to method = hybrid (src/pushers/hybrid*.c): per-lane state and
 * the switch machinery shared by the stepper (hybrid.c) and the
 * transformations (hybrid_switch.c).  Contract: include/gcpush/hybrid.h. */
#ifndef GCPUSH_HYBRID_PRIV_H
#define GCPUSH_HYBRID_PRIV_H

#include <stddef.h>
#include <stdint.h>

#include "gcpush/hybrid.h"
#include "gcpush/pusher.h"

/* Averaging windows that have not completed one gyration after this many
 * chunks (a lane that no longer gyrates) are given up and reopened later. */
#define WINDOW_MAX_CHUNKS 64

/* Whole gyrations in an averaging window (both switches).  Over a single
 * gyration the O(eps) gyrophase oscillation of the instantaneous guiding
 * centre does not average out where B changes within the gyration: a
 * residual O(eps dB/B) in p_par, i.e. O(eps^2), which at small pitch angles
 * is large in mu (d mu / mu = -2 p_par d p_par / p_perp^2: +-15% for a 5 MeV
 * proton at L = 6, 25 deg, eps = 0.1).  Two gyrations halve it; three do
 * better still but keep a particle on full orbit for most of its bounce
 * (README, hybrid). */
#define WINDOW_GYRATIONS 2

struct hlane {
    int32_t mode, nsw;
    int64_t id;
    int64_t kpos;      /* grid index reached in this call */
    double tl;         /* [s] time of the lane (FO lanes may be off the grid) */
    double t_gc, t_fo; /* [s] totals */
    /* FO -> GC averaging window */
    int avg, K, nchunks;
    double ts, e1[3], e2[3], theta, th_prev, tprev;
    double gprev[5], acc[5], IK[5], tK; /* X[3], ppar, mu: previous sample, integrals */
};

struct gcp_hybrid {
    struct gcp_hybrid_opts o;
    size_t nlanes;
    struct hlane *lane;             /* by stable lane index */
    struct gcp_block sb;            /* sub-block of the lanes pushed together */
    size_t *ord;                    /* scratch: lane lists */
    int64_t *nsub;                  /* scratch: FO steps per chunk of each outer lane */
    struct gcp_hybrid_switch *sw;
    size_t nsw, capsw;
    struct gcp_hybrid_observer obs; /* per-step observer (fn NULL: none) */
    size_t *vidx;                   /* scratch: stable indices of a sub-block's lanes */
    int nomem;
};

static inline double hy_dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static inline struct hlane *lane_of(struct gcp_hybrid *h, const struct gcp_block *b, size_t i)
{
    return &h->lane[b->index[i]];
}

/* GC -> FO of lane i of b at time t (gyro-consistent start, the switch
 * recorded); on failure the lane gets the status and stops. */
void gcp_hybrid_to_fo(struct gcp_hybrid *h, struct gcp_block *b, const struct gcp_field *f,
                      size_t i, struct hlane *L, double t);

/* At the end of an FO chunk (time t, on the grid): opens, continues or
 * closes the averaging window of FO lane i; a closed window may switch the
 * lane to GC (dt_gc, tol: the GC method's step and tolerance). */
void gcp_hybrid_fo_decide(struct gcp_hybrid *h, struct gcp_block *b, const struct gcp_field *f,
                          size_t i, struct hlane *L, double t, double dt_gc, double tol);

/* Sampler of the FO sub-block pushes: feeds the lanes with an open window. */
struct gcp_hybrid_fo_ctx {
    struct gcp_hybrid *h;
    const struct gcp_block *b; /* the outer block (stable indices) */
    const struct gcp_field *f;
};
void gcp_hybrid_fo_sample(const struct gcp_block *s, double t, void *ctx);

#endif
