/* fo-rk8pd: the full Lorentz equations under GSL's Prince-Dormand 8(7)
 * adaptive stepper, a reference for sweeps (issue 13) that shares nothing
 * with the methods it judges: no Boris splitting, no kernel of kernels.h
 * but gcp_gamma_of_u, no guiding-centre equation.
 *
 *   dx/dt = u / gamma,   du/dt = (q/m) (E + (u/gamma) x B),
 *   gamma = sqrt(1 + |u|^2/c^2),   u = gamma v [m/s].
 *
 * Scaling: y = (x / Ls, u / Us), Ls = max(|x0|, rho0) (the orbit size, or
 * the gyroradius when the orbit starts at the origin), Us = |u0|, with
 * gsl_odeiv2_control_y_new(tol, tol): the local error per step of every
 * component is below tol (1 + |y_i|), ~tol of the orbit size and of the
 * momentum.  Default tolerance GCP_FO_RK8PD_TOL = 1e-13.
 *
 * Not in the method registry (gcp_pusher_types): it is a reference, named
 * only by `[sweep] reference = fo-rk8pd TOL`, and a thousand times slower
 * per gyration than Boris.  Block contract as gc-rk45/gc-rk8pd: each lane
 * runs alone to t0 + nsteps dt, landing on every sampling time when a
 * sampler is attached (dt is the first trial step); after every accepted
 * step the field's domain (PRECIPITATED, LEFT_DOMAIN); a field status or a
 * non-finite value in a trial stage stops the lane with that status and
 * the state of its last accepted step; an error control that cannot be met
 * above round-off is STEP_FAILED. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_errno.h>
#include <gsl/gsl_odeiv2.h>

#include "gcpush/field.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "block_priv.h"
#include "evolve_priv.h"

struct fo_sys {
    const struct gcp_field *f;
    double qm, Ls, Us;
    unsigned need;
    int status;
};

static int fo_rhs(double t, const double y[], double dydt[], void *params)
{
    struct fo_sys *c = params;
    const double x[3] = {y[0] * c->Ls, y[1] * c->Ls, y[2] * c->Ls};
    const double u[3] = {y[3] * c->Us, y[4] * c->Us, y[5] * c->Us};
    struct gcp_field_sample s = {.need = c->need};
    const int st = gcp_field_eval(c->f, t, x, &s);
    if (st) {
        c->status = st;
        return GSL_EBADFUNC;
    }
    const double ig = 1.0 / gcp_gamma_of_u(u[0], u[1], u[2]);
    const double v[3] = {u[0] * ig, u[1] * ig, u[2] * ig};
    const double E[3] = {c->need & GCP_NEED_E ? s.E[0] : 0.0, c->need & GCP_NEED_E ? s.E[1] : 0.0,
                         c->need & GCP_NEED_E ? s.E[2] : 0.0};
    const double a[3] = {c->qm * (E[0] + v[1] * s.B[2] - v[2] * s.B[1]),
                         c->qm * (E[1] + v[2] * s.B[0] - v[0] * s.B[2]),
                         c->qm * (E[2] + v[0] * s.B[1] - v[1] * s.B[0])};
    for (int d = 0; d < 3; d++) {
        dydt[d] = v[d] / c->Ls;
        dydt[3 + d] = a[d] / c->Us;
    }
    for (int d = 0; d < 6; d++)
        if (!isfinite(dydt[d])) {
            c->status = GCP_NONFINITE;
            return GSL_EBADFUNC;
        }
    return GSL_SUCCESS;
}

/* Integrates lane i from b->t[i] to t1 with the trial step *h it keeps
 * between calls; returns its status (0: reached t1). */
static int32_t fo_lane(const struct gcp_evolve *ev, void *ctx, struct gcp_block *b, size_t i,
                       double t1, void *lane)
{
    (void)ctx;
    const struct gcp_field *f = ev->f;
    double *h = lane;
    struct fo_sys c = {f, b->q / b->m, 1.0, 1.0, GCP_NEED_B | (ev->has_E ? GCP_NEED_E : 0u), 0};
    const double x0[3] = {b->x[i], b->y[i], b->z[i]}, u0[3] = {b->ux[i], b->uy[i], b->uz[i]};
    struct gcp_field_sample smp = {.need = GCP_NEED_B};
    gcp_field_eval(f, b->t[i], x0, &smp);
    const double Bm = sqrt(smp.B[0] * smp.B[0] + smp.B[1] * smp.B[1] + smp.B[2] * smp.B[2]);
    const double Us = sqrt(u0[0] * u0[0] + u0[1] * u0[1] + u0[2] * u0[2]);
    const double rho = Bm > 0.0 ? Us / (fabs(c.qm) * Bm) : 0.0;
    const double Ls = fmax(sqrt(x0[0] * x0[0] + x0[1] * x0[1] + x0[2] * x0[2]), rho);
    c.Ls = Ls > 0.0 && isfinite(Ls) ? Ls : 1.0;
    c.Us = Us > 0.0 && isfinite(Us) ? Us : GCP_C_LIGHT;
    gsl_odeiv2_system sys = {fo_rhs, NULL, 6, &c};
    double y[6];
    for (int d = 0; d < 3; d++) y[d] = x0[d] / c.Ls, y[3 + d] = u0[d] / c.Us;
    double t = b->t[i];
    gsl_odeiv2_step_reset(ev->gsl_step);
    gsl_odeiv2_evolve_reset(ev->gsl_evolve);
    int32_t status = 0;
    int64_t accepted = 0;
    while (t < t1) {
        int32_t why = GCP_FAIL_NONE;
        status = gcp_evolve_adaptive_step(ev, &sys, &t, t1, h, y, &c.status, &why);
        if (status) {
            if (status == GCP_STEP_FAILED) gcp_lane_fail(b, i, why);
            break;
        }
        accepted++;
        const double x[3] = {y[0] * c.Ls, y[1] * c.Ls, y[2] * c.Ls};
        if ((status = gcp_point_domain_status(f, x))) break;
    }
    b->x[i] = y[0] * c.Ls, b->y[i] = y[1] * c.Ls, b->z[i] = y[2] * c.Ls;
    b->ux[i] = y[3] * c.Us, b->uy[i] = y[4] * c.Us, b->uz[i] = y[5] * c.Us;
    b->t[i] = t;
    b->steps[i] += accepted;
    return status;
}

static int fo_lane_init(const struct gcp_evolve *ev, void *ctx, const struct gcp_block *b,
                        size_t i, void *lane)
{
    (void)ctx, (void)b, (void)i;
    *(double *)lane = ev->o->dt; /* the first trial step */
    return 0;
}

static size_t fo_rk8pd_advance(struct gcp_block *b, const struct gcp_field *f,
                               const struct gcp_pusher_type *p, const struct gcp_push_opts *o,
                               const struct gcp_sampler *s)
{
    (void)p;
    const struct gcp_adaptive_stepper st = {
        .gc = 0,
        .lane_size = sizeof(double),
        .type = gsl_odeiv2_step_rk8pd,
        .dim = 6,
        .tol_default = GCP_FO_RK8PD_TOL,
        .init = fo_lane_init,
        .run = fo_lane,
    };
    return gcp_evolve_adaptive(b, f, o, s, &st, NULL);
}

const struct gcp_pusher_type gcp_pusher_fo_rk8pd = {
    .name = "fo-rk8pd",
    .doc = "full orbit, GSL Prince-Dormand 8(7) on the Lorentz equations, adaptive "
           "(tolerance, default 1e-13); sweep reference only",
    .adaptive = 1,
    .order = 8,
    .kind = GCP_FULL_ORBIT,
    .kick = NULL,
    .advance = fo_rk8pd_advance,
};
