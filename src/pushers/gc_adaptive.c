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
 * step), its `steps` counting accepted steps, which the error control
 * alone chooses: only t_end clips a step.  With a sampler every k steps,
 * the sampler sees the block at t0 + j k dt with every lane's state there
 * from one extra step of the same stepper out of the accepted step that
 * contains that time (lane_run): sampling costs those extra steps but no
 * longer caps the step at the cadence (issue 13).  After every accepted
 * step: the field's domain (r_inner, r_outer, z_max like
 * gcp_block_classify) and, with opts->adiabaticity_max > 0, the
 * adiabaticity; a stop found beyond a sampling time is reported at the
 * first sampling time after it.
 *
 * Failures, per lane, with its state restored to the last accepted step:
 *   - the right-hand side leaves the field's domain, is non-finite or hits
 *     B*_par <= 0 in a trial stage: that status (LEFT_DOMAIN, NONFINITE,
 *     NONADIABATIC, ...);
 *   - GSL returns an error, or the error control cannot be met with a step
 *     above round-off (h < 1e3 DBL_EPSILON (|t| + t_end - t0): GSL would
 *     then crawl on at 1 ulp per step): GCP_STEP_FAILED.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_errno.h>
#include <gsl/gsl_odeiv2.h>

#include "gcpush/gc.h"
#include "gcpush/particles.h"
#include "block_priv.h"
#include "evolve_priv.h"
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

/* The integration state of one lane, kept between sampling times: the
 * step sequence belongs to the lane alone and follows the tolerance only
 * (issue 13: it used to stop at every sampling time, so the output cadence
 * capped the step).  y at t (scaled), the last accepted step's start
 * (ya at ta) for the samples inside it, the proposed next step h, the
 * scales, and a stop found beyond the last sampling time. */
struct lane_state {
    double y[4], ya[4];
    double t, ta, h, Ls, Ps;
    int32_t stop; /* status of a stop at t, reported at the next sampling time after it */
    int32_t why;  /* enum gcp_step_failure of a STEP_FAILED stop */
};

/* Starts lane i at b->t[i] with first trial step h. */
static void lane_init(struct lane_state *L, const struct gcp_block *b, size_t i,
                      const struct gcp_field *f, double h)
{
    const double X0[3] = {b->x[i], b->y[i], b->z[i]};
    struct gcp_field_sample smp = {.need = GCP_NEED_B};
    gcp_field_eval(f, b->t[i], X0, &smp);
    const double Bm = sqrt(smp.B[0] * smp.B[0] + smp.B[1] * smp.B[1] + smp.B[2] * smp.B[2]);
    const double Ls = sqrt(X0[0] * X0[0] + X0[1] * X0[1] + X0[2] * X0[2]);
    const double Ps = sqrt(b->ppar[i] * b->ppar[i] + 2.0 * b->m * b->mu[i] * Bm);
    L->Ls = Ls > 0.0 && isfinite(Ls) ? Ls : 1.0;
    L->Ps = Ps > 0.0 && isfinite(Ps) ? Ps : b->m;
    for (int d = 0; d < 3; d++) L->y[d] = X0[d] / L->Ls;
    L->y[3] = b->ppar[i] / L->Ps;
    memcpy(L->ya, L->y, sizeof L->y);
    L->t = L->ta = b->t[i];
    L->h = h;
    L->stop = 0;
    L->why = GCP_FAIL_NONE;
}

static void lane_put(struct gcp_block *b, size_t i, const struct lane_state *L, const double y[4])
{
    b->x[i] = y[0] * L->Ls, b->y[i] = y[1] * L->Ls, b->z[i] = y[2] * L->Ls;
    b->ppar[i] = y[3] * L->Ps;
}

/* Advances lane i until its state reaches t1 (or it stops), with steps
 * chosen by the error control alone: only t_end clips a step.  Puts the
 * lane's state at t1 into the block -- the integration state itself when
 * a step ended there, else one extra step of the same stepper from the
 * start of the step that passed t1, of length t1 - ta (shorter than an
 * accepted step, so within the tolerance; it does not touch the lane's
 * own sequence).  Returns the lane's status at t1: 0 when alive there, a
 * stop found before t1 (with the stop's state and time in the block). */
static int32_t lane_run(const struct gcp_evolve *ev, void *ctx, struct gcp_block *b, size_t i,
                        double t1, void *lane)
{
    (void)ctx;
    struct lane_state *L = lane;
    const struct gcp_field *f = ev->f;
    const struct gcp_push_opts *o = ev->o;
    struct lane_sys c = {f, b->q, b->m, b->mu[i], L->Ls, L->Ps, 0};
    gsl_odeiv2_system sys = {lane_rhs, NULL, 4, &c};
    int64_t accepted = 0;
    gsl_odeiv2_step_reset(ev->gsl_step);
    gsl_odeiv2_evolve_reset(ev->gsl_evolve);
    while (!L->stop && L->t < t1) {
        const double tg = L->t;
        double yg[4];
        memcpy(yg, L->y, sizeof yg);
        L->stop = gcp_evolve_adaptive_step(ev, &sys, &L->t, ev->t_end, &L->h, L->y, &c.status,
                                           &L->why);
        if (L->stop) break;
        accepted++;
        memcpy(L->ya, yg, sizeof yg);
        L->ta = tg;
        const double X[3] = {L->y[0] * L->Ls, L->y[1] * L->Ls, L->y[2] * L->Ls};
        L->stop = gcp_point_domain_status(f, X);
        if (!L->stop && o->adiabaticity_max > 0.0) {
            double dX[3], dp;
            L->stop = gcp_gc_eval(f, L->t, b->q, b->m, X, L->y[3] * L->Ps, b->mu[i],
                                  o->adiabaticity_max, dX, &dp);
        }
    }
    b->steps[i] += accepted;
    if (L->stop == GCP_STEP_FAILED) b->step_failure[i] = L->why;
    if (L->stop && L->t <= t1) { /* stopped before (or at) t1: that state */
        lane_put(b, i, L, L->y);
        b->t[i] = L->t;
        return L->stop;
    }
    b->t[i] = t1;
    if (L->t == t1) {
        lane_put(b, i, L, L->y);
        return 0;
    }
    /* t1 inside the last step [ta, t]: the state there by a step from ta */
    double ys[4], yerr[4];
    memcpy(ys, L->ya, sizeof ys);
    c.status = 0;
    gsl_odeiv2_step_reset(ev->gsl_step);
    if (gsl_odeiv2_step_apply(ev->gsl_step, L->ta, t1 - L->ta, ys, yerr, NULL, NULL, &sys) !=
        GSL_SUCCESS) {
        /* the stages were evaluated inside an accepted step: cannot fail
         * but through the field; report it as the lane's stop */
        L->stop = c.status ? c.status : GCP_STEP_FAILED;
        if (L->stop == GCP_STEP_FAILED) b->step_failure[i] = GCP_FAIL_SOLVER_ERROR;
        lane_put(b, i, L, L->ya);
        b->t[i] = L->ta;
        return L->stop;
    }
    lane_put(b, i, L, ys);
    return 0;
}

static int lane_start(const struct gcp_evolve *ev, void *ctx, const struct gcp_block *b, size_t i,
                      void *lane)
{
    (void)ctx;
    lane_init(lane, b, i, ev->f, ev->o->dt);
    return 0;
}

static size_t adaptive_advance(struct gcp_block *b, const struct gcp_field *f,
                               const struct gcp_push_opts *o, const struct gcp_sampler *s,
                               const gsl_odeiv2_step_type *T, double tol_default)
{
    const struct gcp_adaptive_stepper st = {
        .gc = 1,
        .lane_size = sizeof(struct lane_state),
        .type = T,
        .dim = 4,
        .tol_default = tol_default,
        .init = lane_start,
        .run = lane_run,
    };
    return gcp_evolve_adaptive(b, f, o, s, &st, NULL);
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
