/* gcpush/hybrid.h -- automatic guiding-centre <-> full-orbit switching
 * (issue 14; `method = hybrid` in a run file).
 *
 * Each lane carries a mode.  A guiding-centre (GC) lane is pushed by the
 * chosen GC method with adiabaticity_max = to_fo: the step that would start
 * with eps = gcp_gc_adiabaticity() above to_fo is not taken, and the lane
 * becomes a full orbit (FO) there.  An FO lane is pushed by the chosen FO
 * method in chunks that end on the GC step grid t0 + k dt; at each chunk end
 * eps is measured at the first-order guiding centre of the particle
 * (gcp_gc_from_fo), and once it is below to_gc (< to_fo: hysteresis) the
 * lane gyro-averages its guiding centre over at least one whole gyration and
 * then becomes a GC lane again.
 *
 * GC -> FO (at the start of the GC step that would break the threshold):
 *   x, u = gcp_fo_from_gc(X, p_par, mu, phase), the first-order inverse
 *   transformation, with the gyrophase drawn by a counter-based hash of
 *   (run seed, particle id, number of switches so far) -- uniform in
 *   [0, 2 pi), independent of how particles are spread over ranks.  That
 *   particle's gyro-averaged guiding centre is off by O(eps) with the phase,
 *   so a trial with the FO method over the window the way back uses (two
 *   whole gyrations) measures the offset against the GC trajectory's own
 *   average over the same window, and the particle is made again from the
 *   corrected state, mu set to keep the GC energy; repeated until the
 *   averaged p_par matches to 1e-4 p (a fixed point: the gyro-average of
 *   the particle is the guiding centre's).
 * FO step: dt_fo = fo_dt x (local gyro-period 2 pi gamma m / |q B(x)|),
 *   re-set at every chunk start from B at the particle (a whole number of
 *   FO steps fills each chunk, so FO chunks end exactly on the GC grid).
 * FO -> GC: X, p_par, mu of gcp_gc_from_fo sampled after every FO step of
 *   the averaging window, integrated (trapezoid) from the window start to
 *   the last completed gyration (gyrophase of x - X swept by 2 pi K, K >= 2,
 *   interpolated within the step), divided by its length: the
 *   gyro-average, free of the O(eps) gyrophase oscillation of the
 *   instantaneous transformation (Northrop 1963; Cary & Brizard 2009
 *   sec. IV).  A fast proton's gyration spans a radian of field line, so
 *   the average is not the GC at the mid-time (it lies inside the arc):
 *   the GC state at the window start whose own trajectory has that average
 *   is found (fixed point, 3 passes), pushed with the GC method to the
 *   chunk end, and mu is set so that the GC
 *   energy equals the particle's (the average of p_par^2 exceeds the square
 *   of the average by the O(eps^2) variance of the gyrophase oscillation,
 *   which is perpendicular energy; its relative size is kept in the switch
 *   record as dp2), and the lane switches if eps there is below to_gc.
 * What is left: both directions are first-order, so a GC -> FO -> GC cycle
 *   moves mu by O(eps^2) (second-order guiding-centre terms), which with
 *   the energy fixed is d mu / mu ~ 2 p_par p (eps_fo^2 + eps_gc^2) /
 *   p_perp^2: large at small pitch angles.  Up to 1.4% per cycle for a
 *   5 MeV proton at L = 4, pitch 30 deg, cycling between eps = 0.04 and
 *   0.06 (tests/unit/test_hybrid_dipole.c); -6% +- 7% per cycle (0.7 of
 *   that bound RMS; single-gyration windows: -12% +- 16%) for a 5 MeV
 *   proton at L = 6, 25 deg, with the default thresholds
 *   (tests/unit/test_hybrid_observer.c).
 *
 * All decisions depend on the particle alone (lanes never interact), so the
 * result of a particle is the same in any block and on any rank count.  A
 * particle that never switches is pushed by exactly the same calls as in a
 * plain GC run (one GC advance per trajectory interval or per slice), so its
 * result is bit for bit the plain run's.
 */
#ifndef GCPUSH_HYBRID_H
#define GCPUSH_HYBRID_H

#include <stddef.h>
#include <stdint.h>

#include "field.h"
#include "pusher.h"
#include "api.h"
GCP_API_BEGIN

#ifdef __cplusplus
extern "C" {
#endif

enum gcp_hybrid_mode { GCP_MODE_GC = 0, GCP_MODE_FO = 1 };

struct gcp_hybrid_opts {
    const struct gcp_pusher_type *gc; /* kind GCP_GUIDING_CENTRE */
    const struct gcp_pusher_type *fo; /* kind GCP_FULL_ORBIT */
    double to_fo;    /* [1] eps above which a GC lane becomes a full orbit */
    double to_gc;    /* [1] eps below which a full orbit returns (0 < to_gc < to_fo) */
    double fo_dt;    /* [gyro periods] FO step, of the local gyro-period (0 < fo_dt <= 0.25) */
    uint64_t seed;   /* run seed: gyrophase draws */
};

/* One switch. */
struct gcp_hybrid_switch {
    int64_t id;       /* particle id */
    double t;         /* [s] */
    double X[3];      /* [m] guiding centre at the switch */
    double eps;       /* [1] adiabaticity there */
    int32_t dir;      /* +1: GC -> FO, -1: FO -> GC */
    double dp2;       /* [1] FO -> GC: relative p^2 change of the energy rescaling (0 for GC -> FO) */
};

/* Per-particle totals. */
struct gcp_hybrid_lane_info {
    int32_t mode;     /* enum gcp_hybrid_mode now */
    int32_t switches; /* switches so far (both directions) */
    double t_gc, t_fo;/* [s] time pushed in each mode */
};

struct gcp_hybrid;

/* Pusher type of `method = hybrid` (name, doc, kind GCP_HYBRID), for the
 * scene and the output's attributes.  Its .advance has no state to work
 * with and stops every lane STEP_FAILED: push with gcp_hybrid_advance().
 * Not in gcp_pusher_types(): it is no stand-alone method. */
extern const struct gcp_pusher_type gcp_pusher_hybrid;

/* Advances the live lanes of b (started with gcp_hybrid_begin) by
 * o->nsteps GC steps of o->dt from o->t0 (o->tolerance: the GC method's,
 * if adaptive; o->adiabaticity_max is ignored: the thresholds are h's).
 * The sampler (may be NULL) is called every s->every steps with every live
 * lane at that time, GC lanes holding X, p_par, mu and FO lanes x, u (see
 * gcp_hybrid_mode).  Statuses, retirement and the return value as
 * gcp_block_advance_fo. */
size_t gcp_hybrid_advance(struct gcp_hybrid *h, struct gcp_block *b, const struct gcp_field *f,
                          const struct gcp_push_opts *o, const struct gcp_sampler *s);

/* State for blocks of up to nlanes lanes; 0 or GCP_ERR_NOMEM / GCP_ERR_VALUE
 * (options out of range). */
int gcp_hybrid_create(struct gcp_hybrid **out, size_t nlanes, const struct gcp_hybrid_opts *o);
void gcp_hybrid_free(struct gcp_hybrid *h);

/* Starts block b (full-orbit states in x, u, after gcp_block_start) at t0;
 * lane i is particle id0 + b->index[i].  Lanes whose first-order guiding
 * centre has eps <= to_fo become GC lanes (x, y, z := X; ppar, mu set: the
 * same transformation as a plain GC run's start); the others start as full
 * orbits from their own x, u.  Forgets the previous block's switches. */
void gcp_hybrid_begin(struct gcp_hybrid *h, struct gcp_block *b, const struct gcp_field *f,
                      double t0, int64_t id0);

/* A per-step observer (the invariant observer: gcp_observer_sample_mode):
 * fn(v, t, mode, ctx) after every GC step of the GC lanes (mode GCP_MODE_GC,
 * lanes holding X, p_par, mu) and every FO step of the FO lanes (mode
 * GCP_MODE_FO, lanes holding x, u), with the lanes of one push live in v
 * (v->index[i]: the stable index, as the block's b->index).  The GC method
 * is then pushed with a sampler of every = 1, as a plain GC run with an
 * observer is, so a lane that never switches is observed as in that run.
 * fn = NULL: none (the default). */
struct gcp_hybrid_observer {
    void (*fn)(const struct gcp_block *v, double t, int mode, void *ctx);
    void *ctx;
};
void gcp_hybrid_set_observer(struct gcp_hybrid *h, const struct gcp_hybrid_observer *obs);
/* Calls the observer with the live lanes of b at time t (both modes): the
 * start, after gcp_hybrid_begin and the observer's own begin. */
void gcp_hybrid_observe(struct gcp_hybrid *h, const struct gcp_block *b, double t);

/* Mode and totals of the lane with stable index `index` (b->index[i]). */
int gcp_hybrid_mode(const struct gcp_hybrid *h, size_t index);
void gcp_hybrid_info(const struct gcp_hybrid *h, size_t index, struct gcp_hybrid_lane_info *out);

/* The switches of this block since gcp_hybrid_begin (in the order made). */
size_t gcp_hybrid_switches(const struct gcp_hybrid *h, const struct gcp_hybrid_switch **sw);
/* 0, or GCP_ERR_NOMEM when a switch record could not be stored (the push
 * itself went on). */
int gcp_hybrid_status(const struct gcp_hybrid *h);

/* Both representations of lane i of b at its time b->t[i]: a GC lane's
 * x, u from gcp_fo_from_gc with the gyrophase its next switch would draw; an
 * FO lane's X, p_par, mu from gcp_gc_from_fo (instantaneous, first order).
 * What cannot be computed (e.g. outside the field's domain) is NaN.
 * Returns the lane's mode. */
int gcp_hybrid_final(const struct gcp_hybrid *h, const struct gcp_block *b,
                     const struct gcp_field *f, size_t i, double x[3], double u[3], double X[3],
                     double *ppar, double *mu);

/* The gyrophase [rad] of switch n of particle id under seed: uniform in
 * [0, 2 pi), a pure function of its arguments. */
double gcp_hybrid_phase(uint64_t seed, int64_t id, int64_t n);

#ifdef __cplusplus
}
#endif
GCP_API_END
#endif /* GCPUSH_HYBRID_H */
