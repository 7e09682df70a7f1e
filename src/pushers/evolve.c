/* The evolve layer: the one block loop of every fixed-step pusher
 * (contract in evolve_priv.h).  Steppers: the full-orbit drift-kick-drift
 * (fo_step.c), gc-rk4 (gc_rk4.c), the per-lane implicit guiding-centre
 * methods (gc_lanes.c: gc-gl2, gc-gl4, gc-midpoint-pphi); and, with its
 * own slicing at the sampling times and the GSL error control, the adaptive
 * methods whose lanes choose their own steps (gc_adaptive.c: gc-rk45,
 * gc-rk8pd; fo_rk8pd.c) and the Sundman methods, whose lanes run on their
 * own clocks with no GSL stepper (gc_sundman.c). */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_errno.h>

#include "gcpush/particles.h"
#include "block_priv.h"
#include "evolve_priv.h"
#include "gc_priv.h"

size_t gcp_evolve_retire(struct gcp_block *b, unsigned char *L, size_t sz, unsigned char *tmp,
                         size_t n, double t, int64_t steps)
{
    size_t i = 0;
    while (i < n) {
        if (b->status[i] != GCP_ALIVE) {
            b->t[i] = t;
            b->steps[i] += steps;
            gcp_lane_failure_default(b, i);
            gcp_block_swap_lanes(b, i, n - 1);
            const int32_t fs = b->fstatus[i];
            b->fstatus[i] = b->fstatus[n - 1], b->fstatus[n - 1] = fs;
            if (sz) {
                memcpy(tmp, L + i * sz, sz);
                memcpy(L + i * sz, L + (n - 1) * sz, sz);
                memcpy(L + (n - 1) * sz, tmp, sz);
            }
            n--;
        } else {
            i++;
        }
    }
    return n;
}

size_t gcp_evolve_fail_all(struct gcp_block *b, size_t n, double t0, int reason)
{
    for (size_t i = 0; i < n; i++) b->status[i] = gcp_lane_fail(b, i, reason);
    b->n_active = gcp_block_retire(b, n, t0, 0);
    return b->n_active;
}

int32_t gcp_evolve_gc_check(const struct gcp_evolve *ev, void *ctx, struct gcp_block *b, size_t n,
                            double t, int first)
{
    (void)ctx;
    if (first) return 0;
    const double q = b->q, m = b->m, amax = ev->o->adiabaticity_max;
    int32_t any = 0;
    for (size_t i = 0; i < n; i++) {
        const double X[3] = {b->x[i], b->y[i], b->z[i]};
        double dX[3], dp;
        b->fstatus[i] = gcp_gc_eval(ev->f, t, q, m, X, b->ppar[i], b->mu[i], amax, dX, &dp);
        any |= b->fstatus[i];
    }
    return any;
}

size_t gcp_evolve(struct gcp_block *b, const struct gcp_field *f, const struct gcp_push_opts *o,
                  const struct gcp_sampler *s, const struct gcp_stepper *st, void *ctx)
{
    return gcp_evolve_inline(b, f, o, s, st, ctx);
}

/* ------------------------------------------------------------------------
 * Adaptive methods (evolve_priv.h gcp_evolve_adaptive). */

/* Retires stopped lanes, each with the time and steps its run wrote,
 * carrying the lane states along. */
static size_t adaptive_retire(struct gcp_block *b, unsigned char *L, size_t sz, unsigned char *tmp,
                              size_t n)
{
    size_t i = 0;
    while (i < n) {
        if (b->status[i] != GCP_ALIVE) {
            gcp_lane_failure_default(b, i);
            gcp_block_swap_lanes(b, i, n - 1);
            memcpy(tmp, L + i * sz, sz);
            memcpy(L + i * sz, L + (n - 1) * sz, sz);
            memcpy(L + (n - 1) * sz, tmp, sz);
            n--;
        } else {
            i++;
        }
    }
    return n;
}

#define ADAPTIVE_DIM_MAX 8

int32_t gcp_evolve_adaptive_step(const struct gcp_evolve *ev, gsl_odeiv2_system *sys, double *t,
                                 double t_lim, double *h, double *y, int *rhs_status,
                                 int32_t *why)
{
    const double hmin_rel = 1e3 * DBL_EPSILON, t_span = ev->t_end - ev->o->t0;
    double yg[ADAPTIVE_DIM_MAX];
    memcpy(yg, y, sys->dimension * sizeof(double));
    const double tg = *t;
    *rhs_status = 0;
    const int rc = gsl_odeiv2_evolve_apply(ev->gsl_evolve, ev->gsl_control, ev->gsl_step, sys, t,
                                           t_lim, h, y);
    const double taken = *t - tg;
    if (rc != GSL_SUCCESS || !(taken > 0.0) ||
        (*t < t_lim && taken < hmin_rel * (fabs(*t) + t_span))) {
        memcpy(y, yg, sys->dimension * sizeof(double));
        *t = tg;
        *why = rc != GSL_SUCCESS ? GCP_FAIL_SOLVER_ERROR : GCP_FAIL_STEP_UNDERFLOW;
        return rc == GSL_EBADFUNC && *rhs_status ? *rhs_status : GCP_STEP_FAILED;
    }
    return 0;
}

size_t gcp_evolve_adaptive(struct gcp_block *b, const struct gcp_field *f,
                           const struct gcp_push_opts *o, const struct gcp_sampler *s,
                           const struct gcp_adaptive_stepper *st, void *ctx)
{
    size_t n;
    if (st->gc) {
        n = gcp_gc_block_begin(b, f, o);
    } else {
        n = b->n_active;
        if (n && !(isfinite(o->dt) && o->dt > 0.0 && o->nsteps >= 0 && isfinite(o->t0)))
            n = gcp_evolve_fail_all(b, n, o->t0, GCP_FAIL_BAD_OPTIONS);
    }
    if (n == 0) return 0;
    const size_t sz = st->lane_size;
    const double tol = o->tolerance > 0.0 ? o->tolerance : st->tol_default;
    struct gcp_evolve ev = {
        .f = f,
        .o = o,
        .need = GCP_NEED_B | (st->gc ? GCP_NEED_GRADB : 0u) | (f->has_E ? GCP_NEED_E : 0u),
        .has_E = f->has_E,
        .t_end = o->t0 + (double)o->nsteps * o->dt,
        .gsl_step = st->type ? gsl_odeiv2_step_alloc(st->type, st->dim) : NULL,
        .gsl_control = st->type ? gsl_odeiv2_control_y_new(tol, tol) : NULL,
        .gsl_evolve = st->type ? gsl_odeiv2_evolve_alloc(st->dim) : NULL,
    };
    unsigned char *L = malloc((b->n + 1) * sz);
    const int gsl_ok = !st->type || (st->dim <= ADAPTIVE_DIM_MAX && ev.gsl_step &&
                                     ev.gsl_control && ev.gsl_evolve);
    if (!gsl_ok || !L) n = gcp_evolve_fail_all(b, n, o->t0, GCP_FAIL_NO_MEMORY);
    unsigned char *tmp = L ? L + b->n * sz : NULL;
    gsl_error_handler_t *old = gsl_set_error_handler_off();
    const int64_t every = s && s->fn && s->every > 0 ? s->every : 0;
    const int64_t chunk = every ? every : (o->nsteps > 0 ? o->nsteps : 1);
    int init_failed = 0;
    for (size_t i = 0; i < n; i++) {
        b->t[i] = o->t0;
        const int r = st->init(&ev, ctx, b, i, L + i * sz);
        if (r) b->status[i] = r, init_failed = 1;
    }
    if (init_failed) n = adaptive_retire(b, L, sz, tmp, n);
    for (int64_t k = 0; k < o->nsteps && n > 0; k += chunk) {
        const int64_t kn = k + chunk < o->nsteps ? k + chunk : o->nsteps;
        const double t1 = kn == o->nsteps ? ev.t_end : o->t0 + (double)kn * o->dt;
        if (st->run_lanes)
            st->run_lanes(&ev, ctx, b, n, t1, L);
        else
            for (size_t i = 0; i < n; i++) b->status[i] = st->run(&ev, ctx, b, i, t1, L + i * sz);
        n = adaptive_retire(b, L, sz, tmp, n);
        b->n_active = n;
        if (every && n > 0) s->fn(b, t1, s->ctx);
    }
    gsl_set_error_handler(old);
    free(L);
    if (ev.gsl_evolve) gsl_odeiv2_evolve_free(ev.gsl_evolve);
    if (ev.gsl_control) gsl_odeiv2_control_free(ev.gsl_control);
    if (ev.gsl_step) gsl_odeiv2_step_free(ev.gsl_step);
    b->n_active = n;
    return n;
}
