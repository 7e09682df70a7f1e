/* Guiding-centre helpers shared by the GC pushers, and the public GC API
 * that is not a pusher: full orbit <-> guiding centre transformation,
 * adiabaticity, energy, p_phi, and the single-particle push gcp_gc_push.
 * Equations and conventions: include/gcpush/gc.h and kernels.h. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/field_kernels.h"
#include "gcpush/gc.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "block_priv.h"
#include "gc_priv.h"

static double dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void cross3(const double a[3], const double b[3], double c[3])
{
    const double c0 = a[1] * b[2] - a[2] * b[1];
    const double c1 = a[2] * b[0] - a[0] * b[2];
    const double c2 = a[0] * b[1] - a[1] * b[0];
    c[0] = c0, c[1] = c1, c[2] = c2;
}

/* eps = max(rho_perp |grad B|/B, rho |kappa|),
 * kappa_i = b_j d_j b_i = (G b)_i / B - b_i (b.grad B) / B. */
double gcp_gc_adiabaticity_sample(const struct gcp_field_sample *s, double ppar, double mu, double q,
                              double m)
{
    return gcp_gc_adiabaticity_of(s->B, s->gradB, ppar, mu, q, m);
}

int gcp_gc_eval(const struct gcp_field *f, double t, double q, double m, const double X[3],
            double ppar, double mu, double amax, double dX[3], double *dp)
{
    struct gcp_field_sample s = {.need = gc_need(f)};
    const int st = gcp_field_eval(f, t, X, &s);
    const double Bspar = gcp_gc_rhs(s.B, s.gradB, f->has_E ? s.E : NULL, ppar, mu, q, m, dX, dp);
    if (st) return st;
    if (!isfinite(dX[0] + dX[1] + dX[2] + *dp)) return GCP_NONFINITE;
    const double Bm = sqrt(dot3(s.B, s.B));
    if (!(Bspar > 0.0) || !(Bm > 0.0)) return GCP_NONADIABATIC;
    if (amax > 0.0 && !(gcp_gc_adiabaticity_sample(&s, ppar, mu, q, m) <= amax))
        return GCP_NONADIABATIC;
    return 0;
}

/* gcp_gc_eval's verdicts over the lanes [0, n) where the field is the
 * closed form `form` of field_kernels.h (its B, grad B and E are the
 * model's eval bit for bit, and the model's status there is 0): the same
 * operations (gcp_gc_rhs, the adiabaticity of gcp_gc_adiabaticity_of, the
 * same order of tests, selected without a branch), with no field call
 * per lane, so the loop vectorises; ~65 ns a lane in the dipole through
 * gcp_gc_eval, which a push of 122 steps a lane pays at ~0.5 ns a step.
 * form and withE are constants at each call (adia too in the dipole). */
static inline __attribute__((always_inline)) void
begin_form(int form, int withE, int adia, const double *restrict p, const struct gcp_block *b,
           int32_t *restrict fst, size_t n, double amax)
{
    const double *restrict x = b->x, *restrict y = b->y, *restrict z = b->z;
    const double *restrict pp = b->ppar, *restrict mu = b->mu;
    const double q = b->q, m = b->m;
    for (size_t i = 0; i < n; i++) {
        double B[3], G[3][3], E[3] = {0.0, 0.0, 0.0};
        if (form == GCP_POINT_B_DIPOLE) {
            gcp_point_BG_dipole(p[0], x[i], y[i], z[i], B, G);
        } else {
            B[0] = p[0], B[1] = p[1], B[2] = p[2];
            for (int a = 0; a < 3; a++) G[a][0] = G[a][1] = G[a][2] = 0.0;
            if (withE) E[0] = p[3], E[1] = p[4], E[2] = p[5];
        }
        double dX[3], dp;
        const double Bspar = gcp_gc_rhs(B, G, withE ? E : NULL, pp[i], mu[i], q, m, dX, &dp);
        const int32_t nonfinite = !(fabs(dX[0] + dX[1] + dX[2] + dp) <= DBL_MAX);
        const double Bm = sqrt(dot3(B, B));
        int32_t bad = !(Bspar > 0.0) | !(Bm > 0.0);
        if (adia) bad |= !(gcp_gc_adiabaticity_of(B, G, pp[i], mu[i], q, m) <= amax);
        fst[i] = nonfinite * GCP_NONFINITE + (1 - nonfinite) * bad * GCP_NONADIABATIC;
    }
}

/* The closed forms' verdicts (begin_form), one loop per form; 0 where the
 * field has no form this covers. */
static int begin_forms(const struct gcp_block *b, const struct gcp_field *f, size_t n,
                       double amax)
{
    struct gcp_point_B form;
    if (!gcp_field_point_B(f, &form) || form.has_E != (f->has_E != 0)) return 0;
    int32_t *fst = b->fstatus;
    const int adia = amax > 0.0;
    if (form.form == GCP_POINT_B_DIPOLE && !form.has_E) {
        if (adia) begin_form(GCP_POINT_B_DIPOLE, 0, 1, form.p, b, fst, n, amax);
        else begin_form(GCP_POINT_B_DIPOLE, 0, 0, form.p, b, fst, n, amax);
    } else if (form.form == GCP_POINT_B_UNIFORM) {
        /* rare (a uniform field's guiding centre): the test of amax stays in the loop */
        if (form.has_E) begin_form(GCP_POINT_B_UNIFORM, 1, adia, form.p, b, fst, n, amax);
        else begin_form(GCP_POINT_B_UNIFORM, 0, adia, form.p, b, fst, n, amax);
    } else {
        return 0;
    }
    return 1;
}

size_t gcp_gc_block_begin(struct gcp_block *b, const struct gcp_field *f, const struct gcp_push_opts *o)
{
    size_t n = b->n_active;
    const int ok = isfinite(o->dt) && o->dt > 0.0 && o->nsteps >= 0 && isfinite(o->t0);
    const int formed = ok && begin_forms(b, f, n, o->adiabaticity_max);
    for (size_t i = 0; i < n && !formed; i++) {
        const double X[3] = {b->x[i], b->y[i], b->z[i]};
        double dX[3], dp;
        /* the GC verdict rides in fstatus: classify ranks a non-finite
         * state above it, and it above the geometric bounds */
        b->fstatus[i] = ok ? gcp_gc_eval(f, o->t0, b->q, b->m, X, b->ppar[i], b->mu[i],
                                     o->adiabaticity_max, dX, &dp)
                           : GCP_STEP_FAILED;
        if (!ok) b->step_failure[i] = GCP_FAIL_BAD_OPTIONS;
    }
    if (gcp_block_classify(b, n, f, 1)) n = gcp_block_retire(b, n, o->t0, 0);
    b->n_active = n;
    return n;
}

/* ------------------------------------------------------------------------ */

int gcp_gc_rhs_at(const struct gcp_field *f, double t, double q, double m, const double X[3],
                  double ppar, double mu, double dXdt[3], double *dppar)
{
    struct gcp_field_sample s = {.need = gc_need(f)};
    const int st = gcp_field_eval(f, t, X, &s);
    gcp_gc_rhs(s.B, s.gradB, f->has_E ? s.E : NULL, ppar, mu, q, m, dXdt, dppar);
    return st;
}

int gcp_gc_adiabaticity(const struct gcp_field *f, double t, double q, double m,
                        const double X[3], double ppar, double mu, double *eps)
{
    struct gcp_field_sample s = {.need = gc_need(f)};
    const int st = gcp_field_eval(f, t, X, &s);
    double dX[3], dp;
    const double Bspar = gcp_gc_rhs(s.B, s.gradB, f->has_E ? s.E : NULL, ppar, mu, q, m, dX, &dp);
    *eps = Bspar > 0.0 ? gcp_gc_adiabaticity_sample(&s, ppar, mu, q, m) : INFINITY;
    return st;
}

int gcp_gc_has_potential(const struct gcp_field *f)
{
    /* the analytic models give phi with their A (gc_potential.c); a grid,
     * an EQDSK or a callback field with E gives none (the grid's flux path
     * of gcp_gc_potential sets phi = 0, true only without E) */
    if (!f->has_E) return 1;
    return (gcp_field_caps(f) & GCP_CAP_A) != 0;
}

int gcp_gc_energy(const struct gcp_field *f, double t, double q, double m, const double X[3],
                  double ppar, double mu, double *H)
{
    /* H = gamma m c^2 + q phi needs phi wherever there is an E: without a
     * potential it is unknown, not phi = 0 (issue 13) */
    if (!gcp_gc_has_potential(f)) {
        *H = NAN;
        return GCP_ERR_UNKNOWN;
    }
    struct gcp_field_sample s = {.need = GCP_NEED_B};
    const int st = gcp_field_eval(f, t, X, &s);
    const double Bm = sqrt(dot3(s.B, s.B));
    double A[3], phi = 0.0;
    if (f->has_E && gcp_gc_potential(f, t, X, A, NULL, &phi)) {
        *H = NAN;
        return GCP_ERR_UNKNOWN;
    }
    *H = gcp_gc_gamma(ppar, mu, Bm, m) * m * GCP_C_LIGHT * GCP_C_LIGHT + q * phi;
    return st;
}

int gcp_gc_pphi(const struct gcp_field *f, double t, double q, const double X[3], double ppar,
                double *pphi)
{
    struct gcp_field_sample s = {.need = GCP_NEED_B};
    const int st = gcp_field_eval(f, t, X, &s);
    double A[3];
    if (gcp_gc_potential(f, t, X, A, NULL, NULL)) {
        *pphi = NAN;
        return GCP_ERR_UNKNOWN;
    }
    const double Bm = sqrt(dot3(s.B, s.B));
    /* R V_phi = x V_y - y V_x for V = q A + p_par b */
    const double Vx = q * A[0] + ppar * s.B[0] / Bm, Vy = q * A[1] + ppar * s.B[1] / Bm;
    *pphi = X[0] * Vy - X[1] * Vx;
    return st;
}

/* ---- full orbit <-> guiding centre ---- */

static int field_b(const struct gcp_field *f, double t, const double x[3], double b[3],
                   double *Bm)
{
    struct gcp_field_sample s = {.need = GCP_NEED_B};
    const int st = gcp_field_eval(f, t, x, &s);
    *Bm = sqrt(dot3(s.B, s.B));
    for (int i = 0; i < 3; i++) b[i] = s.B[i] / *Bm;
    return st;
}

int gcp_gc_from_fo(const struct gcp_field *f, double t, double q, double m, const double x[3],
                   const double u[3], double X[3], double *ppar, double *mu)
{
    const double p[3] = {m * u[0], m * u[1], m * u[2]};
    double b[3], Bm, rho[3];
    int st = field_b(f, t, x, b, &Bm);
    cross3(b, p, rho);
    for (int i = 0; i < 3; i++) X[i] = x[i] - rho[i] / (q * Bm);
    const int st2 = field_b(f, t, X, b, &Bm);
    if (!st) st = st2;
    const double pp = dot3(p, b);
    *ppar = pp;
    *mu = fmax(dot3(p, p) - pp * pp, 0.0) / (2.0 * m * Bm);
    return st;
}

int gcp_fo_from_gc(const struct gcp_field *f, double t, double q, double m, const double X[3],
                   double ppar, double mu, double phase, double x[3], double u[3])
{
    double b[3], Bm;
    int st = field_b(f, t, X, b, &Bm);
    if (st) return st;
    const double a[3] = {fabs(b[2]) > 0.9 ? 1.0 : 0.0, 0.0, fabs(b[2]) > 0.9 ? 0.0 : 1.0};
    double e1[3], e2[3];
    cross3(b, a, e1);
    const double ne = sqrt(dot3(e1, e1));
    for (int i = 0; i < 3; i++) e1[i] /= ne;
    cross3(b, e1, e2);
    const double pperp = sqrt(2.0 * m * fmax(mu, 0.0) * Bm);
    const double c = cos(phase), s = sin(phase);
    double p[3];
    for (int i = 0; i < 3; i++) p[i] = ppar * b[i] + pperp * (c * e1[i] + s * e2[i]);
    /* x = X + b(x) x p / (q B(x)): fixed point, contraction ~ rho/L_B */
    double xk[3] = {X[0], X[1], X[2]};
    int conv = 0;
    for (int it = 0; it < 100 && !conv; it++) {
        double bk[3], Bk, r[3];
        st = field_b(f, t, xk, bk, &Bk);
        if (st) return st;
        cross3(bk, p, r);
        double d2 = 0.0, r2 = 0.0;
        for (int i = 0; i < 3; i++) {
            const double xn = X[i] + r[i] / (q * Bk);
            d2 += (xn - xk[i]) * (xn - xk[i]);
            r2 += (xn - X[i]) * (xn - X[i]);
            xk[i] = xn;
        }
        if (!isfinite(d2)) return GCP_NONFINITE;
        /* converged to a few ulp of the position: far from the origin (X ~ 1e7 m in
         * the dipole) the update cannot get below the spacing of doubles at X, which
         * 1e-18 |X| (the old floor) asked for, so ~1% of the calls never converged */
        conv = d2 <= 1e-30 * r2 + 4e-30 * dot3(X, X);
    }
    if (!conv) return GCP_STEP_FAILED;
    for (int i = 0; i < 3; i++) {
        x[i] = xk[i];
        u[i] = p[i] / m;
    }
    return 0;
}

/* ---- single-particle push ---- */

struct push_ctx {
    gcp_gc_step_cb cb;
    void *ctx;
    int stopped;
    double t, X[3], ppar;
};

static void push_sampler(const struct gcp_block *b, double t, void *vctx)
{
    struct push_ctx *c = vctx;
    if (c->stopped || b->n_active == 0) return;
    const double X[3] = {b->x[0], b->y[0], b->z[0]};
    if (c->cb(t, X, b->ppar[0], c->ctx)) {
        c->stopped = 1;
        c->t = t;
        memcpy(c->X, X, sizeof X);
        c->ppar = b->ppar[0];
    }
}

int gcp_gc_push(const struct gcp_field *f, const struct gcp_pusher_type *p, double q, double m,
                const struct gcp_push_opts *o, double *t, double X[3], double *ppar, double mu,
                gcp_gc_step_cb cb, void *ctx)
{
    if (!p || p->kind != GCP_GUIDING_CENTRE) return GCP_STEP_FAILED;
    struct gcp_block b;
    if (gcp_block_alloc(&b, 1)) return GCP_STEP_FAILED;
    b.q = q;
    b.m = m;
    b.x[0] = X[0], b.y[0] = X[1], b.z[0] = X[2];
    b.ppar[0] = *ppar;
    b.mu[0] = mu;
    b.t[0] = *t;
    struct push_ctx pc = {cb, ctx, 0, 0.0, {0, 0, 0}, 0.0};
    const struct gcp_sampler smp = {1, push_sampler, &pc};
    /* With a callback: chunks, so that a stop request ends the push soon
     * (the state returned is the one the callback stopped at). */
    const int64_t chunk = cb ? 256 : (o->nsteps > 0 ? o->nsteps : 1);
    int status = GCP_ALIVE;
    double tt = *t;
    int64_t k = 0;
    do {
        struct gcp_push_opts oo = *o;
        oo.t0 = tt;
        oo.nsteps = o->nsteps - k < chunk ? o->nsteps - k : chunk;
        b.n_active = 1;
        p->advance(&b, f, p, &oo, cb ? &smp : NULL);
        tt = b.t[0];
        status = b.status[0];
        k += oo.nsteps;
    } while (status == GCP_ALIVE && !pc.stopped && k < o->nsteps);
    if (pc.stopped) {
        *t = pc.t;
        memcpy(X, pc.X, sizeof pc.X);
        *ppar = pc.ppar;
        status = GCP_ALIVE;
    } else {
        *t = tt;
        X[0] = b.x[0], X[1] = b.y[0], X[2] = b.z[0];
        *ppar = b.ppar[0];
    }
    gcp_block_free(&b);
    return status;
}
