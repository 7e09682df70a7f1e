/* gc-rk45 and gc-rk8pd: adaptive GSL odeiv2 steppers on the relativistic
 * guiding-centre equations (kernels.h gcp_gc_rhs).
 *
 *   gc-rk45   gsl_odeiv2_step_rkf45 (Runge-Kutta-Fehlberg 4(5)),
 *             default tolerance GCP_GC_RK45_TOL = 1e-9
 *   gc-rk8pd  gsl_odeiv2_step_rk8pd (Prince-Dormand 8(7)),
 *             default tolerance GCP_GC_RK8PD_TOL = 1e-12 (reference runs)
 *
 * Scaling.  Each lane is integrated in the scaled variables
 *   y = (X / Ls, p_par / Ps),  Ls = |X(t0)|,  Ps = sqrt(p_par^2 + 2 m mu B)
 * (the orbit size and the total momentum at the start), with
 * gsl_odeiv2_control_y_new(tol, tol): the local error per step of every
 * component is kept below tol (1 + |y_i|), i.e. ~tol relative to the orbit
 * size and to the momentum, whatever the units.  opts->tolerance = 0 takes
 * the method's default.
 *
 * Each lane runs alone to t_end = t0 + nsteps dt (dt is its first trial
 * step), its `steps` counting accepted steps.  With a sampler every k steps,
 * every lane lands on t0 + j k dt (evolve's final-step clipping) and the
 * sampler sees the block there.  After every accepted step: the field's
 * domain (r_inner, r_outer, z_max like gcp_block_classify) and, with
 * opts->adiabaticity_max > 0, the adiabaticity.
 *
 * Failures, per lane, with its state restored to the last accepted step:
 *   - the right-hand side leaves the field's domain, is non-finite or hits
 *     B*_par <= 0 in a trial stage: that status (LEFT_DOMAIN, NONFINITE,
 *     NONADIABATIC, ...);
 *   - GSL returns an error, or the error control cannot be met with a step
 *     above round-off (h < 1e3 DBL_EPSILON (|t| + t_end - t0): GSL would
 *     then crawl on at 1 ulp per step): GCP_STEP_FAILED.
 */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_errno.h>
#include <gsl/gsl_odeiv2.h>

#include "gcpush/gc.h"
#include "gcpush/particles.h"
#include "block_priv.h"
#include "gc_priv.h"

struct lane_sys {
    const struct gcp_field *f;
    double q, m, mu, Ls, Ps;
    int status; /* why the right-hand side refused */
};

static int lane_rhs(double t, const double y[], double dydt[], void *params)
{
    struct lane_sys *c = params;
    const double X[3] = {y[0] * c->Ls, y[1] * c->Ls, y[2] * c->Ls};
    double dX[3], dp;
    const int st = gcp_gc_eval(c->f, t, c->q, c->m, X, y[3] * c->Ps, c->mu, 0.0, dX, &dp);
    if (st) {
        c->status = st;
        return GSL_EBADFUNC;
    }
    for (int d = 0; d < 3; d++) dydt[d] = dX[d] / c->Ls;
    dydt[3] = dp / c->Ps;
    return GSL_SUCCESS;
}

static int32_t lane_geo(const struct gcp_field *f, const double X[3])
{
    const double r2 = X[0] * X[0] + X[1] * X[1] + X[2] * X[2];
    if (!isfinite(r2)) return GCP_NONFINITE;
    if (r2 < f->r_inner * f->r_inner) return GCP_PRECIPITATED;
    if (r2 > f->r_outer * f->r_outer || fabs(X[2]) > f->z_max) return GCP_LEFT_DOMAIN;
    return 0;
}

struct adaptive_ws {
    gsl_odeiv2_step *step;
    gsl_odeiv2_control *ctrl;
    gsl_odeiv2_evolve *ev;
};

/* Integrates lane i from b->t[i] to t1; returns its status (0: reached t1). */
static int32_t lane_run(struct gcp_block *b, size_t i, const struct gcp_field *f,
                        const struct gcp_push_opts *o, struct adaptive_ws *w, double *h,
                        double t1, double t_span)
{
    struct lane_sys c = {f, b->q, b->m, b->mu[i], 1.0, 1.0, 0};
    const double X0[3] = {b->x[i], b->y[i], b->z[i]};
    struct gcp_field_sample smp = {.need = GCP_NEED_B};
    gcp_field_eval(f, b->t[i], X0, &smp);
    const double Bm = sqrt(smp.B[0] * smp.B[0] + smp.B[1] * smp.B[1] + smp.B[2] * smp.B[2]);
    const double Ls = sqrt(X0[0] * X0[0] + X0[1] * X0[1] + X0[2] * X0[2]);
    const double Ps = sqrt(b->ppar[i] * b->ppar[i] + 2.0 * b->m * b->mu[i] * Bm);
    c.Ls = Ls > 0.0 && isfinite(Ls) ? Ls : 1.0;
    c.Ps = Ps > 0.0 && isfinite(Ps) ? Ps : b->m;
    gsl_odeiv2_system sys = {lane_rhs, NULL, 4, &c};
    double y[4] = {X0[0] / c.Ls, X0[1] / c.Ls, X0[2] / c.Ls, b->ppar[i] / c.Ps};
    double t = b->t[i];
    gsl_odeiv2_step_reset(w->step);
    gsl_odeiv2_evolve_reset(w->ev);
    const double hmin_rel = 1e3 * DBL_EPSILON;
    int32_t status = 0;
    int64_t accepted = 0;
    while (t < t1) {
        double yg[4];
        memcpy(yg, y, sizeof y);
        const double tg = t;
        c.status = 0;
        const int rc = gsl_odeiv2_evolve_apply(w->ev, w->ctrl, w->step, &sys, &t, t1, h, y);
        const double taken = t - tg;
        if (rc != GSL_SUCCESS || !(taken > 0.0) ||
            (t < t1 && taken < hmin_rel * (fabs(t) + t_span))) {
            status = rc == GSL_EBADFUNC && c.status ? c.status : GCP_STEP_FAILED;
            memcpy(y, yg, sizeof y);
            t = tg;
            break;
        }
        accepted++;
        const double X[3] = {y[0] * c.Ls, y[1] * c.Ls, y[2] * c.Ls};
        status = lane_geo(f, X);
        if (!status && o->adiabaticity_max > 0.0) {
            double dX[3], dp;
            status = gcp_gc_eval(f, t, b->q, b->m, X, y[3] * c.Ps, b->mu[i], o->adiabaticity_max,
                             dX, &dp);
        }
        if (status) break;
    }
    b->x[i] = y[0] * c.Ls, b->y[i] = y[1] * c.Ls, b->z[i] = y[2] * c.Ls;
    b->ppar[i] = y[3] * c.Ps;
    b->t[i] = t;
    b->steps[i] += accepted;
    return status;
}

static size_t adaptive_advance(struct gcp_block *b, const struct gcp_field *f,
                               const struct gcp_push_opts *o, const struct gcp_sampler *s,
                               const gsl_odeiv2_step_type *T, double tol_default)
{
    size_t n = gcp_gc_block_begin(b, f, o);
    if (n == 0) return 0;
    const double tol = o->tolerance > 0.0 ? o->tolerance : tol_default;
    struct adaptive_ws w = {gsl_odeiv2_step_alloc(T, 4), gsl_odeiv2_control_y_new(tol, tol),
                            gsl_odeiv2_evolve_alloc(4)};
    double *hs = malloc(b->n * sizeof(double));
    if (!w.step || !w.ctrl || !w.ev || !hs) {
        for (size_t i = 0; i < n; i++) b->status[i] = GCP_STEP_FAILED;
        n = gcp_block_retire(b, n, o->t0, 0);
    }
    gsl_error_handler_t *old = gsl_set_error_handler_off();
    const int64_t every = s && s->fn && s->every > 0 ? s->every : 0;
    const int64_t chunk = every ? every : (o->nsteps > 0 ? o->nsteps : 1);
    const double t_end = o->t0 + (double)o->nsteps * o->dt;
    for (size_t i = 0; i < n; i++) {
        hs[i] = o->dt;
        b->t[i] = o->t0;
    }
    for (int64_t k = 0; k < o->nsteps && n > 0; k += chunk) {
        const int64_t kn = k + chunk < o->nsteps ? k + chunk : o->nsteps;
        const double t1 = kn == o->nsteps ? t_end : o->t0 + (double)kn * o->dt;
        for (size_t i = 0; i < n; i++)
            b->status[i] = lane_run(b, i, f, o, &w, &hs[i], t1, t_end - o->t0);
        /* retire stopped lanes, each with its own t and steps (already set) */
        size_t i = 0;
        while (i < n) {
            if (b->status[i] != GCP_ALIVE) {
                gcp_block_swap_lanes(b, i, n - 1);
                const double th = hs[i];
                hs[i] = hs[n - 1], hs[n - 1] = th;
                n--;
            } else {
                i++;
            }
        }
        b->n_active = n;
        if (every && n > 0) s->fn(b, t1, s->ctx);
    }
    gsl_set_error_handler(old);
    free(hs);
    if (w.ev) gsl_odeiv2_evolve_free(w.ev);
    if (w.ctrl) gsl_odeiv2_control_free(w.ctrl);
    if (w.step) gsl_odeiv2_step_free(w.step);
    b->n_active = n;
    return n;
}

static size_t gc_rk45_advance(struct gcp_block *b, const struct gcp_field *f,
                              const struct gcp_pusher_type *p, const struct gcp_push_opts *o,
                              const struct gcp_sampler *s)
{
    (void)p;
    return adaptive_advance(b, f, o, s, gsl_odeiv2_step_rkf45, GCP_GC_RK45_TOL);
}

static size_t gc_rk8pd_advance(struct gcp_block *b, const struct gcp_field *f,
                               const struct gcp_pusher_type *p, const struct gcp_push_opts *o,
                               const struct gcp_sampler *s)
{
    (void)p;
    return adaptive_advance(b, f, o, s, gsl_odeiv2_step_rk8pd, GCP_GC_RK8PD_TOL);
}

const struct gcp_pusher_type gcp_pusher_gc_rk45 = {
    .name = "gc-rk45",
    .doc = "guiding centre, GSL Runge-Kutta-Fehlberg 4(5), adaptive (tolerance, default 1e-9)",
    .adaptive = 1,
    .order = 4,
    .kind = GCP_GUIDING_CENTRE,
    .kick = NULL,
    .advance = gc_rk45_advance,
};

const struct gcp_pusher_type gcp_pusher_gc_rk8pd = {
    .name = "gc-rk8pd",
    .doc = "guiding centre, GSL Prince-Dormand 8(7), adaptive (tolerance, default 1e-12)",
    .adaptive = 1,
    .order = 8,
    .kind = GCP_GUIDING_CENTRE,
    .kick = NULL,
    .advance = gc_rk8pd_advance,
};
