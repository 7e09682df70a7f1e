/* Private to the pushers: the evolve layer (evolve.c), GSL's
 * step < evolve < driver split applied to blocks of lanes.
 *
 * A stepper supplies only its step over the live lanes of a block (a kick
 * with its drifts, the stages of a Runge-Kutta method, or one implicit
 * solve per lane); gcp_evolve owns everything around it, once for every
 * method:
 *
 *   begin      options checked (dt > 0 and finite, nsteps >= 0, t0 finite;
 *              else every live lane STEP_FAILED / BAD_OPTIONS), guiding
 *              centres classified at t0 (gcp_gc_block_begin: non-finite,
 *              the field's domain, B*_par > 0, adiabaticity)
 *   init       each lane's solver state (lane_size bytes per lane)
 *   per step   start-of-step check (the stepper's `start`: a verdict per
 *              lane in b->fstatus, classified and retired at (t, k)),
 *              the step, lanes the step failed retired at (t, k) with the
 *              state of the start of the step, classification of the rest
 *              (non-finite, the field's verdict, the bounds) retired at
 *              (t + h, k + 1), lane states carried along, the sampler every
 *              `every` steps, and at the end gcp_block_finish.
 *
 * The field's need bits and has_E are fixed when the evolve is built
 * (struct gcp_evolve), so no stepper re-checks them per lane or per stage.
 *
 * A new guiding-centre method is one file: its lane state, `init`, and
 * `step_lane` (or the block form `step`), one `struct gcp_stepper`, a call
 * of gcp_evolve from its gcp_pusher_type.advance, and one line in the
 * registry (fo_step.c all_pushers). */
#ifndef GCPUSH_EVOLVE_PRIV_H
#define GCPUSH_EVOLVE_PRIV_H

#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

#include <gsl/gsl_odeiv2.h>

#include "gcpush/field.h"
#include "gcpush/particles.h"
#include "gcpush/pusher.h"
#include "block_priv.h"
#include "gc_priv.h"

/* What every hook sees: fixed for the whole push. */
struct gcp_evolve {
    const struct gcp_field *f;
    const struct gcp_push_opts *o;
    unsigned need;        /* field need bits: B, grad B (guiding centre), E when has_E */
    int has_E;            /* [bool] the field has an electric field */
    void *work;           /* the stepper's block scratch (work_size bytes), or NULL */
    /* adaptive methods (gcp_evolve_adaptive) only: */
    double t_end;         /* [s] t0 + nsteps dt, where every lane ends */
    gsl_odeiv2_step *gsl_step;     /* the method's stepper, one per push */
    gsl_odeiv2_control *gsl_control; /* the error control: y_new(tol, tol) */
    gsl_odeiv2_evolve *gsl_evolve;
};

struct gcp_stepper {
    int gc;               /* [bool] guiding-centre state (X, p_par, mu) rather than (x, u) */
    size_t lane_size;     /* [bytes] of one lane's solver state (0: none) */
    /* [bytes] of block scratch for a block of nlanes lanes (NULL: none) */
    size_t (*work_size)(size_t nlanes);
    /* Optional: lane i's state at time t; 0 or a status (the lane retires at t0). */
    int (*init)(const struct gcp_evolve *ev, void *ctx, const struct gcp_block *b, size_t i,
                double t, void *lane);
    /* Optional: the live lanes [0, n) were renumbered (at the start and after
     * every retirement): per-lane scratch that is not carried must be redone. */
    void (*relanes)(const struct gcp_evolve *ev, void *ctx, struct gcp_block *b, size_t n);
    /* Optional: the check at the start of a step at t (first: k = 0, which
     * begin already checked for guiding centres).  Writes a verdict for each
     * of the n lanes into b->fstatus (0: go on) and returns non-zero when any
     * lane stops; the evolve layer classifies and retires those at (t, k)
     * and calls start again on the rest. */
    int32_t (*start)(const struct gcp_evolve *ev, void *ctx, struct gcp_block *b, size_t n,
                     double t, int first);
    /* The step of size h from t over the n live lanes (block form).  On
     * success a lane holds its new state and the field's status of the step
     * in b->fstatus; a lane the step cannot take keeps the state of the
     * start of the step and gets a non-zero b->status (STEP_FAILED with a
     * reason: gcp_lane_fail).  Returns non-zero when any lane failed. */
    int32_t (*step)(const struct gcp_evolve *ev, void *ctx, struct gcp_block *b, size_t n,
                    double t, double h);
    /* Optional, tried before `start` and `step`: up to kmax steps of size
     * h from t at once (issue 12: fused steps that keep a tile of lanes in
     * L1 for several steps, fo_fused_priv.h, gc_rk4_fused.c).  Returns kd,
     * 1 <= kd <= kmax, when it took them: every live lane has taken kd
     * steps, none would have stopped by `start` at steps 1 .. kd nor by
     * gcp_block_classify after steps 1 .. kd-1, and b->fstatus holds the
     * verdict of step kd -- the state lock-step would reach; 0 when it
     * cannot, the block untouched (then `start` and `step` run).
     * *stops = 0 (when it took them) says more: it tested every lane after
     * step kd with the classification's own test (gcp_lane_stops) and the
     * field gives no verdict, and none stops -- the layer then skips its
     * classification pass (the live lanes stay ALIVE), and b->fstatus need
     * not be written; a stepper that does not test sets *stops = 1.  Never
     * fails a lane.  The evolve layer bounds kmax by the push's end and the
     * next sampling step.  lanes: the lanes' states (lane i's at lanes +
     * i lane_size), or NULL where lane_size is 0. */
    int64_t (*steps)(const struct gcp_evolve *ev, void *ctx, struct gcp_block *b, size_t n,
                     double t, double h, int64_t kmax, int32_t *stops, unsigned char *lanes);
    /* [bool] `steps` bounds its own steps by a sampler of every step:
     * several when it does the sampler's per-step work itself (the invariant
     * observer's gyro-average: fo_gyro_priv.h), else one (fo_step.c). */
    int gyro;
    /* Or the same for one lane with its state (used when step is NULL):
     * returns 0 or the lane's status, as gcp_gc_lane_ops.step. */
    int (*step_lane)(const struct gcp_evolve *ev, void *ctx, struct gcp_block *b, size_t i,
                     double t, double h, void *lane);
    /* Or the block form with the lanes' states (lane i's at lanes + i
     * lane_size), used when step is NULL and this is not: as step. */
    int32_t (*step_lanes)(const struct gcp_evolve *ev, void *ctx, struct gcp_block *b, size_t n,
                          double t, double h, unsigned char *lanes);
};

/* Pushes the live lanes of b by up to o->nsteps fixed steps of o->dt from
 * o->t0 with stepper st (its context ctx); the gcp_advance_fn contract:
 * statuses set, stopped lanes retired with their time and steps, returns
 * the live lane count (b->n_active). */
size_t gcp_evolve(struct gcp_block *b, const struct gcp_field *f, const struct gcp_push_opts *o,
                  const struct gcp_sampler *s, const struct gcp_stepper *st, void *ctx);

/* gcp_block_retire's semantics, carrying the lanes' solver states (sz bytes
 * each, tmp: one lane of scratch) and the field's verdict fstatus along (a
 * step's failures retire before its classification reads it). */
size_t gcp_evolve_retire(struct gcp_block *b, unsigned char *L, size_t sz, unsigned char *tmp,
                         size_t n, double t, int64_t steps);
/* Every live lane fails before the first step with `reason`; returns 0. */
size_t gcp_evolve_fail_all(struct gcp_block *b, size_t n, double t0, int reason);

/* gcp_evolve's loop itself, for a stepper known at compile time (a static
 * const struct gcp_stepper): the compiler then inlines its hooks into the
 * loop, so the per-step cost of the layer is that of a hand-written loop
 * (64-lane blocks, the driver's, take ~200 ns a step). */
static inline __attribute__((always_inline)) size_t
gcp_evolve_inline(struct gcp_block *b, const struct gcp_field *f, const struct gcp_push_opts *o,
                  const struct gcp_sampler *s, const struct gcp_stepper *st, void *ctx)
{
    const int gc = st->gc;
    /* begin: a guiding centre is classified at t0 (its verdict needs the
     * field); a full orbit was classified when its block was filled
     * (gcp_block_start) */
    size_t n = gc ? gcp_gc_block_begin(b, f, o) : b->n_active;
    /* the same options check as a guiding centre's (gcp_gc_block_begin):
     * dt = 0 would count steps that move nothing, a negative one push
     * backwards, NaN or inf overwrite the state with non-finite values */
    if (!gc && n && !(isfinite(o->dt) && o->dt > 0.0 && o->nsteps >= 0 && isfinite(o->t0)))
        n = gcp_evolve_fail_all(b, n, o->t0, GCP_FAIL_BAD_OPTIONS);
    if (n == 0) return 0;
    const size_t sz = st->lane_size;
    const size_t wsz = st->work_size ? st->work_size(b->n) : 0;
    unsigned char *L = sz ? malloc((b->n + 1) * sz) : NULL;
    /* cache-line aligned: steppers lay SoA scratch out in it */
    void *work = wsz ? aligned_alloc(64, (wsz + 63) / 64 * 64) : NULL;
    if ((sz && !L) || (wsz && !work)) {
        free(L);
        free(work);
        return gcp_evolve_fail_all(b, n, o->t0, GCP_FAIL_NO_MEMORY);
    }
    unsigned char *tmp = sz ? L + b->n * sz : NULL;
    const struct gcp_evolve ev = {
        .f = f,
        .o = o,
        .need = GCP_NEED_B | (gc ? GCP_NEED_GRADB : 0u) | (f->has_E ? GCP_NEED_E : 0u),
        .has_E = f->has_E,
        .work = work,
    };
    if (st->init) {
        int any = 0;
        for (size_t i = 0; i < n; i++) {
            const int r = st->init(&ev, ctx, b, i, o->t0, L + i * sz);
            if (r) b->status[i] = r, any = 1;
        }
        if (any) n = gcp_evolve_retire(b, L, sz, tmp, n, o->t0, 0);
    }
    if (st->relanes) st->relanes(&ev, ctx, b, n);
    const double h = o->dt;
    const int64_t every = s && s->fn ? s->every : 0;
    int64_t k = 0;
    for (; k < o->nsteps && n > 0; k++) {
        double t = o->t0 + (double)k * h;
        /* several steps at once: k and t move to the last of them, which
         * is then classified (and sampled) as any single step */
        int64_t kd = 0;
        int32_t stops = 1; /* 0: the stepper's `steps` found no lane to stop */
        if (st->steps) {
            int64_t kmax = o->nsteps - k;
            if (every && every - k % every < kmax && !(st->gyro && every == 1))
                kmax = every - k % every;
            kd = st->steps(&ev, ctx, b, n, t, h, kmax, &stops, L);
            if (kd > 1) k += kd - 1, t = o->t0 + (double)k * h;
        }
        /* the start of the step: stopped lanes leave with its state and time */
        if (kd == 0 && st->start) {
            while (n > 0 && st->start(&ev, ctx, b, n, t, k == 0)) {
                if (!gcp_block_classify(b, n, f, gc)) break;
                n = gcp_evolve_retire(b, L, sz, tmp, n, t, k);
                b->n_active = n;
                if (st->relanes) st->relanes(&ev, ctx, b, n);
            }
            if (n == 0) break;
        }
        int32_t failed = 0;
        if (kd > 0) {
            /* taken */
        } else if (st->step) {
            failed = st->step(&ev, ctx, b, n, t, h);
        } else if (st->step_lanes) {
            failed = st->step_lanes(&ev, ctx, b, n, t, h, L);
        } else {
            for (size_t i = 0; i < n; i++) {
                const int r = st->step_lane(&ev, ctx, b, i, t, h, L + i * sz);
                if (r) b->status[i] = r, failed = 1;
            }
        }
        int moved = 0;
        if (failed) n = gcp_evolve_retire(b, L, sz, tmp, n, t, k), moved = 1;
        if ((kd == 0 || stops) && gcp_block_classify(b, n, f, gc))
            n = gcp_evolve_retire(b, L, sz, tmp, n, t + h, k + 1), moved = 1;
        if (moved && st->relanes) st->relanes(&ev, ctx, b, n);
        b->n_active = n;
        if (every && (k + 1) % every == 0) s->fn(b, t + h, s->ctx);
    }
    gcp_block_finish(b, n, o->t0 + (double)k * h, k);
    free(L);
    free(work);
    return n;
}

/* Adaptive methods whose lanes each choose their own steps (gc-rk45,
 * gc-rk8pd, fo-rk8pd; gc-gl2/gl4-sundman, whose lanes run on their own
 * clocks): the evolve layer owns begin (as above; a full orbit's options
 * are checked too), the lane states, the slicing of the push at the
 * sampling times t0 + j every dt (or one slice to t_end), retirement of
 * lanes that stopped (each with its own time and steps), the sampler, and
 * the GSL error control (gcp_evolve_adaptive_step: one accepted step, or a
 * failure with its reason; none when type is NULL).  The method supplies
 * init (its lane state at t0; b->t[i] = t0 already; 0 or the lane's status,
 * the lane then retires at t0) and run: lane i advanced to t1 (or its stop
 * before t1), its state, b->t[i] and b->steps[i] written; returns 0 (alive
 * at t1) or the lane's status (STEP_FAILED with a reason in
 * b->step_failure[i]). */
struct gcp_adaptive_stepper {
    int gc;                            /* [bool] guiding-centre state */
    size_t lane_size;                  /* [bytes] of one lane's state */
    const gsl_odeiv2_step_type *type;  /* GSL stepper; NULL: the method steps itself */
    size_t dim;                        /* ODE dimension (GSL) */
    double tol_default;                /* [1] when opts->tolerance is 0 */
    int (*init)(const struct gcp_evolve *ev, void *ctx, const struct gcp_block *b, size_t i,
                void *lane);
    int32_t (*run)(const struct gcp_evolve *ev, void *ctx, struct gcp_block *b, size_t i,
                   double t1, void *lane);
    /* Or, when set, the same for the n live lanes at once (lane i's state at
     * lanes + i lane_size): b->status[i], b->t[i], b->steps[i] written for
     * each (gc_sundman_dipole.c: tiles of lanes, each on its own clock). */
    void (*run_lanes)(const struct gcp_evolve *ev, void *ctx, struct gcp_block *b, size_t n,
                      double t1, unsigned char *lanes);
};
size_t gcp_evolve_adaptive(struct gcp_block *b, const struct gcp_field *f,
                           const struct gcp_push_opts *o, const struct gcp_sampler *s,
                           const struct gcp_adaptive_stepper *st, void *ctx);

/* The adaptive control: one accepted step of sys from *t towards t_lim
 * with trial step *h (gsl_odeiv2_evolve_apply under the error control).
 * Returns 0 with *t, *h, y advanced; or, with y and *t left as they were, the
 * right-hand side's refusal (*rhs_status, set by sys's function; reset to 0
 * here) or GCP_STEP_FAILED with *why = SOLVER_ERROR (GSL failed) or
 * STEP_UNDERFLOW (no step above round-off, h < 1e3 DBL_EPSILON (|t| +
 * t_end - t0), short of t_lim: GSL would crawl on at 1 ulp per step). */
int32_t gcp_evolve_adaptive_step(const struct gcp_evolve *ev, gsl_odeiv2_system *sys, double *t,
                                 double t_lim, double *h, double *y, int *rhs_status,
                                 int32_t *why);

/* The start-of-step check of the per-lane guiding-centre methods:
 * gcp_gc_eval at (t, X, p_par) with opts->adiabaticity_max (B*_par > 0,
 * finite right-hand side, the field's status, adiabaticity); skipped at
 * the first step, which begin checked. */
int32_t gcp_evolve_gc_check(const struct gcp_evolve *ev, void *ctx, struct gcp_block *b, size_t n,
                            double t, int first);
/* The same verdicts from a block evaluation (gc_rk4.c's vectorised stage
 * 1): the check of the block-solved methods (gc-gl2, gc-gl4). */
int32_t gcp_gc_check_block(const struct gcp_evolve *ev, void *ctx, struct gcp_block *b, size_t n,
                           double t, int first);

#endif
