/* The invariant and event observer (contract and physics: invariants.h).
 *
 * Per lane, indexed by the lane's original index b->index[i] (stable under
 * the stepper's lane swaps), the observer keeps:
 *   - full orbit: the gyro-average in progress (phase swept by the
 *     gyroradius vector x - X, trapezoid integrals of X, p_par, mu, p^2);
 *   - the guiding-centre stream: the previous sample, the current
 *     half-bounce (J integral, the three samples around min |B|), the
 *     current bounce (mirror points, J, the mu integral), the drift contour
 *     in progress (azimuth, oint A . dl);
 *   - the last live position and time (loss interpolation).
 *
 * Accuracy of the stream integrals (GC samples every dt):
 *   mirror point: p_par is linear in t through the mirror point: linear
 *     interpolation of its zero, error O(dt^2);
 *   J = int p_par^2 / (gamma m) dt: f = p_par^2/(gamma m) ~ c (t - t_m)^2 at
 *     the mirror points, so the end pieces are integrated exactly for that
 *     model (f(t_1) (t_1 - t_m) / 3) and the trapezoid between samples gets
 *     the Euler-Maclaurin end correction -(h^2/12) [f'(t_n) - f'(t_1)] with
 *     f'(t) = 2 f / (t - t_m): error O(h^4) relative instead of O(h^2);
 *   equator: the vertex of the parabola through the three samples around the
 *     smallest |B(X)|; quantities there by quadratic Lagrange interpolation
 *     of scalars that are exactly constant on an axisymmetric drift shell
 *     (psi = R A_phi, p_phi), so L* of a dipole is not degraded by the
 *     interpolation;
 *   Phi: trapezoid in the azimuth of A . dX/dphi around the contour of
 *     equator points = sum over contour segments of
 *     (psi_a + psi_b)/2 dphi + <A_R> dR + <A_z> dz; in an axisymmetric
 *     field (A = A_phi phihat) it reduces to 2 pi psi for a closed contour,
 *     whatever the spacing of the points.  The last segment is cut where
 *     the azimuth has turned by exactly 2 pi (linear in the segment).
 *
 * Files: invariants.c (the stream, the sampler), invariants_events.c (the
 * event storage and its sort), invariants_fo.c
 * (the full-orbit gyro-average, the loss-cone classification),
 * invariants_samples.c (what particles that do not bounce get: cadence
 * samples, the stream's drift contour, the reasons a quantity is missing). */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/field_kernels.h"
#include "gcpush/gc.h"
#include "gcpush/invariants.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "invariants_priv.h"

void gcp_obs_emit(struct gcp_observer *o, const struct lane *L, struct gcp_event *e)
{
    if (e->kind != GCP_EVENT_LOSS) e->status = L ? L->mode : 0;
    if (gcp_events_push(o->out, e)) o->nomem = 1;
}

void gcp_obs_emit_scalar(struct gcp_observer *o, const struct lane *L, int64_t id, int32_t kind,
                         double t, double v)
{
    const struct gcp_scalar_event e = {.id = id, .kind = kind, .status = L ? L->mode : 0, .t = t,
                                       .v = v};
    if (gcp_events_push_scalar(o->out, &e)) o->nomem = 1;
}

double gcp_observer_reference_B0(const struct gcp_field *f)
{
    /* the field's own centred-dipole B0 where it has dipole coordinates */
    const double B0 = gcp_field_dipole_B0(f);
    return B0 > 0.0 ? B0 : GCP_EARTH_B0;
}

int gcp_observer_create(struct gcp_observer **out, size_t nlanes, const struct gcp_field *f,
                        const struct gcp_pusher_type *p, const struct gcp_observer_opts *opts)
{
    *out = NULL;
    struct gcp_observer *o = calloc(1, sizeof *o);
    if (!o) return GCP_ERR_NOMEM;
    const size_t n = nlanes ? nlanes : 1;
    o->lane = calloc(n, sizeof *o->lane);
    o->Bx = calloc(n, sizeof(double));
    o->By = calloc(n, sizeof(double));
    o->Bz = calloc(n, sizeof(double));
    o->fst = calloc(n, sizeof(int32_t));
    o->sq = calloc(n, sizeof *o->sq);
    /* the full-orbit scratch and struct gyro, in one allocation */
    struct gcp_fo_gyro *g = &o->g;
    double **v[] = {&o->Xx, &o->Xy, &o->Xz, &o->Cx, &o->Cy, &o->Cz, &o->Vpp, &o->Vmu, &o->Vp2,
                    &g->rho[0], &g->rho[1], &g->rho[2], &g->e1[0], &g->e1[1], &g->e1[2],
                    &g->e2[0], &g->e2[1], &g->e2[2], &g->acc[0], &g->acc[1], &g->acc[2],
                    &g->acc[3], &g->acc[4], &g->acc[5], &g->prev[0], &g->prev[1], &g->prev[2],
                    &g->prev[3], &g->prev[4], &g->prev[5], &g->t0, &g->tprev,
                    &g->sum[0], &g->sum[1], &g->sum[2], &g->sum[3], &g->sum[4], &g->sum[5],
                    &g->sum[6], &g->sum[7], &g->sum[8], &g->w0, &g->jc,
                    &o->xprev[0], &o->xprev[1], &o->xprev[2], &o->tprev,
                    &o->Gb, &o->Gp2, &o->Gjd,
                    &o->hot.J, &o->hot.mub, &o->hot.Bmin, &o->hot.tnext,
                    &o->hot.cx, &o->hot.cy};
    const size_t nv = sizeof v / sizeof v[0], nr = 3 * GCP_OBS_RING_NV;
    o->gmem = calloc((nv + nr) * n, sizeof(double));
    o->gflags = calloc(10 * n, sizeof(int64_t));
    int fail = !o->gmem || !o->gflags;
    if (!fail) {
        for (size_t k = 0; k < nv; k++) *v[k] = o->gmem + k * n;
        for (size_t k = 0; k < nr; k++)
            o->hot.r[k / GCP_OBS_RING_NV][k % GCP_OBS_RING_NV] = o->gmem + (nv + k) * n;
        g->init = o->gflags, g->left = o->gflags + n, o->special = o->gflags + 2 * n;
        o->active = o->gflags + 3 * n;
        o->hot.have = o->gflags + 4 * n, o->hot.next = o->gflags + 5 * n;
        o->hot.hprev = o->gflags + 6 * n, o->hot.az = o->gflags + 7 * n;
        o->hot.slow = o->gflags + 8 * n;
        g->kstart = o->gflags + 9 * n;
    }
    if (fail || !o->lane || !o->sq || !o->Bx || !o->By || !o->Bz || !o->fst) {
        gcp_observer_free(o);
        return GCP_ERR_NOMEM;
    }
    o->f = f;
    o->p = p;
    o->opts = *opts;
    o->nlanes = n;
    o->g.nlanes = n;
    o->gc = p->kind == GCP_GUIDING_CENTRE;
    o->hybrid = p->kind == GCP_HYBRID;
    o->want_bounce = (opts->invariants & (GCP_INV_J | GCP_INV_K)) || (opts->events & GCP_EVT_BOUNCE);
    o->want_drift = (opts->invariants & GCP_INV_L) || (opts->events & GCP_EVT_DRIFT);
    o->want_eq = o->want_drift ||
                 (opts->invariants & (GCP_INV_MU | GCP_INV_ENERGY | GCP_INV_PPHI));
    o->stream = o->want_bounce || o->want_eq;
    if (!(opts->sample_dt > 0)) o->opts.sample_dt = 0.0;
    o->B0 = opts->B0 > 0 ? opts->B0 : gcp_observer_reference_B0(f);
    struct gcp_point_B form;
    if (gcp_field_point_B(f, &form) && form.form == GCP_POINT_B_DIPOLE) {
        o->pdip = o->gc, o->pc = form.p[0];
        /* A's gauge is the model's: the form's only where the model says so */
        o->pdipA = form.has_A;
    }
    *out = o;
    return 0;
}

void gcp_observer_free(struct gcp_observer *o)
{
    if (!o) return;
    for (size_t i = 0; o->sq && i < o->nlanes; i++) free(o->sq[i].p);
    free(o->sq);
    free(o->lane);
    free(o->Bx);
    free(o->By);
    free(o->Bz);
    free(o->fst);
    free(o->gmem);
    free(o->gflags);
    free(o->g.rec);
    free(o->rmem);
    free(o);
}

/* ---- the guiding-centre stream ---------------------------------------- */

double gcp_obs_gamma_m(const struct gcp_observer *o, double p2)
{
    return sqrt(o->m * o->m + p2 / (GCP_C_LIGHT * GCP_C_LIGHT));
}

double gcp_obs_energy(const struct gcp_observer *o, double p2)
{
    const double c2 = GCP_C_LIGHT * GCP_C_LIGHT, mc2 = o->m * c2;
    /* W = p^2 c^2 / (E + m c^2): no cancellation at small energies */
    return p2 * c2 / (gcp_obs_gamma_m(o, p2) * c2 + mc2);
}

/* p_par v_par = p_par^2 / (gamma m) [kg m^2/s^2... per s]: the J integrand. */
static double jdot(const struct gcp_observer *o, const struct gsample *s)
{
    return s->ppar * s->ppar / gcp_obs_gamma_m(o, s->p2);
}

static void lagrange3(double t0, double t1, double t2, double t, double w[3])
{
    w[0] = (t - t1) * (t - t2) / ((t0 - t1) * (t0 - t2));
    w[1] = (t - t0) * (t - t2) / ((t1 - t0) * (t1 - t2));
    w[2] = (t - t0) * (t - t1) / ((t2 - t0) * (t2 - t1));
}

/* The vector-potential quantities of a contour point at X, R = |X_perp|:
 * psi = R A_phi, A_R, A_z. */
static void contour_A(const struct gcp_observer *o, double t, const double X[3], double R,
                      double *psi, double *AR, double *Az)
{
    double A[3];
    /* the dipole's closed form inline: the ~3 evaluations an equator point
     * takes cost a quarter of the observer through the field's calls */
    if (o->pdipA) gcp_point_A_dipole(o->pc, X[0], X[1], X[2], A);
    if ((!o->pdipA && gcp_gc_potential(o->f, t, X, A, NULL, NULL)) || !(R > 0)) {
        *psi = *AR = *Az = NAN;
        return;
    }
    const double Aphi = (-A[0] * X[1] + A[1] * X[0]) / R;
    *psi = R * Aphi;
    *AR = (A[0] * X[0] + A[1] * X[1]) / R;
    *Az = A[2];
}

/* Contour quantities of a position but its azimuth (the caller's:
 * gcp_obs_azimuth_from), R = |X_perp| as a square root (hypot guards
 * against an overflow that a position in metres cannot reach). */
void gcp_obs_contour_of(const struct gcp_observer *o, double t, const double X[3], double *R,
                        double *psi, double *AR, double *Az)
{
    *R = sqrt(X[0] * X[0] + X[1] * X[1]);
    contour_A(o, t, X, *R, psi, AR, Az);
}

double gcp_obs_azimuth_from(struct contour *c, double ref, const double X[3])
{
    const double phi = c->n % GCP_OBS_AZ_ANCHOR == 0
                           ? atan2(X[1], X[0])
                           : gcp_obs_wrap_pi(ref + gcp_obs_azimuth_step(c->aref_x, X));
    c->aref_x[0] = X[0], c->aref_x[1] = X[1];
    return phi;
}

double gcp_obs_wrap_pi(double a)
{
    while (a > GCP_PI) a -= 2.0 * GCP_PI;
    while (a <= -GCP_PI) a += 2.0 * GCP_PI;
    return a;
}

void gcp_obs_drift_point(struct gcp_observer *o, struct lane *L, struct contour *c, int64_t id,
                         struct cpoint P, int which)
{
    if (!isfinite(P.psi)) L->psi_nan = 1;
    if (c->n == 0) {
        c->phi0 = P.phi;
        c->t0 = P.t;
        c->acc = 0.0;
        c->prev = P;
        c->n = 1;
        return;
    }
    const struct cpoint *a = &c->prev;
    const double dphi = gcp_obs_wrap_pi(P.phi - a->phi);
    P.phi = a->phi + dphi; /* unwrapped */
    const double seg = 0.5 * (a->psi + P.psi) * dphi + 0.5 * (a->AR + P.AR) * (P.R - a->R) +
                       0.5 * (a->Az + P.Az) * (P.z - a->z);
    const double turned = P.phi - c->phi0;
    if (fabs(turned) >= 2.0 * GCP_PI && dphi != 0.0) {
        const double sgn = turned > 0 ? 1.0 : -1.0;
        const double th = (sgn * 2.0 * GCP_PI - (a->phi - c->phi0)) / dphi;
        const double tc = a->t + th * (P.t - a->t);
        const double Phi = fabs(c->acc + th * seg);
        struct gcp_event e = {.id = id, .kind = GCP_EVENT_DRIFT, .t = tc};
        e.v[GCP_DRIFT_PERIOD] = tc - c->t0;
        e.v[GCP_DRIFT_LSTAR] = 2.0 * GCP_PI * o->B0 * GCP_EARTH_RADIUS * GCP_EARTH_RADIUS / Phi;
        e.v[GCP_DRIFT_PHI] = Phi;
        e.v[GCP_DRIFT_CONTOUR] = which;
        gcp_obs_emit(o, L, &e);
        if (which == GCP_CONTOUR_EQUATOR) L->n_drift_eq++;
        else L->n_drift_st++;
        c->acc = (1.0 - th) * seg;
        c->phi0 += sgn * 2.0 * GCP_PI;
        c->t0 = tc;
    } else {
        c->acc += seg;
    }
    c->prev = P;
    c->n++;
}

/* The equator point of the half-bounce that just closed (e0, e1, e2). */
static void equator(struct gcp_observer *o, struct lane *L, int64_t id)
{
    L->had_eq = 1;
    const struct gsample *s[3] = {&L->e0, &L->e1, &L->e2};
    const double t0 = s[0]->t, t1 = s[1]->t, t2 = s[2]->t;
    const double a = (t1 - t0) * (s[1]->B - s[2]->B), c = (t1 - t2) * (s[1]->B - s[0]->B);
    const double den = a - c;
    double te = t1;
    if (den != 0.0) te = t1 - 0.5 * ((t1 - t0) * a - (t1 - t2) * c) / den;
    if (!(te >= t0 && te <= t2)) te = t1;
    double w[3];
    lagrange3(t0, t1, t2, te, w);
    double mu = 0, p2 = 0;
    for (int k = 0; k < 3; k++) {
        mu += w[k] * s[k]->mu;
        p2 += w[k] * s[k]->p2;
    }
    if (o->opts.invariants & GCP_INV_MU) gcp_obs_emit_scalar(o, L, id, GCP_EVENT_MU, te, mu);
    if (o->opts.invariants & GCP_INV_ENERGY)
        gcp_obs_emit_scalar(o, L, id, GCP_EVENT_ENERGY, te, gcp_obs_energy(o, p2));
    if (o->opts.invariants & GCP_INV_PPHI) {
        double v = 0;
        for (int k = 0; k < 3; k++) {
            double pp;
            gcp_gc_pphi(o->f, s[k]->t, o->q, s[k]->X, s[k]->ppar, &pp);
            v += w[k] * pp;
        }
        gcp_obs_emit_scalar(o, L, id, GCP_EVENT_PPHI, te, v);
    }
    if (o->want_drift) {
        /* the azimuth of the middle sample (from the last equator point's:
         * gcp_obs_azimuth_from), and the others' from it; R = |X_perp| as a
         * square root (hypot guards against overflow that a position in
         * metres cannot reach) */
        double dphi[3], R[3], psi[3], AR[3], Az[3];
        const double phi1 = gcp_obs_azimuth_from(&L->ceq, L->ceq.aref, s[1]->X);
        L->ceq.aref = phi1;
        for (int k = 0; k < 3; k++) {
            dphi[k] = k == 1 ? 0.0 : gcp_obs_azimuth_step(s[1]->X, s[k]->X);
            R[k] = sqrt(s[k]->X[0] * s[k]->X[0] + s[k]->X[1] * s[k]->X[1]);
            contour_A(o, s[k]->t, s[k]->X, R[k], &psi[k], &AR[k], &Az[k]);
        }
        struct cpoint P = {.t = te};
        for (int k = 0; k < 3; k++) {
            const double ph = phi1 + dphi[k];
            P.phi += w[k] * ph;
            P.R += w[k] * R[k];
            P.z += w[k] * s[k]->X[2];
            P.psi += w[k] * psi[k];
            P.AR += w[k] * AR[k];
            P.Az += w[k] * Az[k];
        }
        P.phi = gcp_obs_wrap_pi(P.phi);
        gcp_obs_drift_point(o, L, &L->ceq, id, P, GCP_CONTOUR_EQUATOR);
    }
}

/* A mirror point between s1 and s at fraction th. */
static void mirror(struct gcp_observer *o, struct lane *L, int64_t id, const struct gsample *s,
                   double fs, double th)
{
    const struct gsample *a = &L->s1;
    const double tm = a->t + th * (s->t - a->t);
    double xm[3];
    for (int k = 0; k < 3; k++) xm[k] = a->X[k] + th * (s->X[k] - a->X[k]);
    const double mum = a->mu + th * (s->mu - a->mu);
    /* B_m = p^2 / (2 m mu) where p_par = 0 (interpolating a near-constant) */
    const double Bma = a->mu > 0 ? a->p2 / (2.0 * o->m * a->mu) : NAN;
    const double Bmb = s->mu > 0 ? s->p2 / (2.0 * o->m * s->mu) : NAN;
    const double Bm = Bma + th * (Bmb - Bma);
    L->n_mirror++;
    const double lat = asin(xm[2] / sqrt(gcp_obs_dot3(xm, xm)));
    /* close the half-bounce: end piece and Euler-Maclaurin correction */
    const double h = s->t - a->t, fa = L->jd1, da = tm - a->t;
    double Jh = L->J_acc;
    if (da > 0) Jh += fa * da / 3.0 + h * h / 12.0 * 2.0 * fa / da;
    /* the mu integral: the piece up to the mirror point */
    L->mub += 0.5 * (a->mu + mum) * (tm - a->t);
    if (L->half_valid && L->eq_valid && !L->eq_need_next && o->want_eq) equator(o, L, id);
    if (L->nm >= 1 && L->half_valid) {
        L->Jb += Jh;
        const int k = L->nm - 1;
        L->lat[k] = lat;
        L->Bm[k] = Bm;
        memcpy(L->xm[k], xm, sizeof xm);
        L->nm++;
        if (L->nm == 3) {
            const double T = tm - L->tb0;
            const double mubar = L->mub / T;
            struct gcp_event e = {.id = id, .kind = GCP_EVENT_BOUNCE, .t = tm};
            e.v[GCP_BOUNCE_PERIOD] = T;
            e.v[GCP_BOUNCE_J] = L->Jb;
            e.v[GCP_BOUNCE_K] = L->Jb / (2.0 * sqrt(2.0 * o->m * mubar));
            e.v[GCP_BOUNCE_LAT] = L->lat[0];
            e.v[GCP_BOUNCE_LAT + 1] = L->lat[1];
            e.v[GCP_BOUNCE_BM] = L->Bm[0];
            e.v[GCP_BOUNCE_BM + 1] = L->Bm[1];
            memcpy(&e.v[GCP_BOUNCE_X], L->xm[0], 3 * sizeof(double));
            memcpy(&e.v[GCP_BOUNCE_X + 3], L->xm[1], 3 * sizeof(double));
            e.v[GCP_BOUNCE_MU] = mubar;
            L->n_bounce++;
            if (o->want_bounce) gcp_obs_emit(o, L, &e);
            L->nm = 1;
        }
    } else {
        L->nm = 1;
    }
    if (L->nm == 1) {
        L->tb0 = tm;
        L->Jb = 0.0;
        L->mub = 0.0;
    }
    /* open the next half at the mirror point: start piece from s */
    const double ds = s->t - tm;
    L->J_acc = ds > 0 ? fs * ds / 3.0 + h * h / 12.0 * 2.0 * fs / ds : 0.0;
    L->mub += 0.5 * (mum + s->mu) * (s->t - tm);
    L->half_valid = 1;
    L->eq_Bmin = INFINITY;
    L->eq_valid = L->eq_need_next = 0;
    L->eq_has_prev = 0;
}

void gcp_obs_stream_sample_jd(struct gcp_observer *o, struct lane *L, int64_t id,
                              const struct gsample *s, double jd)
{
    int first_of_half = !L->have_s1;
    if (L->have_s1) {
        const struct gsample *a = &L->s1;
        if ((a->ppar > 0) != (s->ppar > 0)) {
            const double dp = a->ppar - s->ppar;
            const double th = dp != 0.0 ? a->ppar / dp : 1.0;
            mirror(o, L, id, s, jd, fmin(fmax(th, 0.0), 1.0));
            first_of_half = 1;
        } else {
            L->J_acc += 0.5 * (L->jd1 + jd) * (s->t - a->t);
            L->mub += 0.5 * (a->mu + s->mu) * (s->t - a->t);
        }
    }
    gcp_obs_cadence(o, L, id, s);
    if (o->want_eq) {
        if (s->B < L->eq_Bmin) {
            L->eq_Bmin = s->B;
            L->e0 = L->s1;
            L->e1 = *s;
            L->eq_has_prev = !first_of_half;
            L->eq_need_next = 1;
            L->eq_valid = 0;
        } else if (L->eq_need_next) {
            L->e2 = *s;
            L->eq_need_next = 0;
            L->eq_valid = L->eq_has_prev;
        }
    }
    L->s1 = *s;
    L->jd1 = jd;
    L->have_s1 = 1;
}

void gcp_obs_stream_sample(struct gcp_observer *o, struct lane *L, int64_t id,
                           const struct gsample *s)
{
    gcp_obs_stream_sample_jd(o, L, id, s, jdot(o, s));
}

/* ---- losses ------------------------------------------------------------ */

static void loss(struct gcp_observer *o, struct lane *L, int64_t id, const struct gcp_block *b,
                 size_t i)
{
    L->loss_done = 1;
    if (!(o->opts.events & GCP_EVT_LOSS)) return;
    const double xe[3] = {b->x[i], b->y[i], b->z[i]};
    const size_t li = b->index[i];
    /* the last live position: the ring's latest sample where the last
     * step went through the quiet pass and sampled this lane (observe_live
     * then skips xprev); a lane retires at the first sampling after it
     * stops, so that sample was its last live one */
    const int ring = o->hot.pos && o->hot.have[li];
    double *const *r = o->hot.r[o->hot.cur];
    const double xp[3] = {ring ? r[1][li] : o->xprev[0][li], ring ? r[2][li] : o->xprev[1][li],
                          ring ? r[3][li] : o->xprev[2][li]};
    const double tp = ring ? o->hot.rt[o->hot.cur] : o->tprev[li];
    struct gcp_event e = {.id = id, .kind = GCP_EVENT_LOSS, .status = b->status[i], .t = b->t[i]};
    memcpy(e.v, xe, sizeof xe);
    /* the crossing of the sphere r = r_inner (or r_outer) within the last
     * step, linear in the step: r(th) ~ |xprev + th (xe - xprev)| */
    double rs = NAN;
    if (b->status[i] == GCP_PRECIPITATED) rs = o->f->r_inner;
    if (b->status[i] == GCP_LEFT_DOMAIN && isfinite(o->f->r_outer)) rs = o->f->r_outer;
    const double r0 = sqrt(gcp_obs_dot3(xp, xp)), r1 = sqrt(gcp_obs_dot3(xe, xe));
    if (isfinite(rs) && tp < b->t[i] && (r0 - rs) * (r1 - rs) <= 0 && r0 != r1) {
        /* solve |xprev + th d|^2 = rs^2 for th in [0, 1] */
        double d[3];
        for (int k = 0; k < 3; k++) d[k] = xe[k] - xp[k];
        const double A = gcp_obs_dot3(d, d), B = 2.0 * gcp_obs_dot3(xp, d), C = r0 * r0 - rs * rs;
        const double disc = sqrt(fmax(B * B - 4.0 * A * C, 0.0));
        double th = (r1 < r0) ? (-B - disc) / (2.0 * A) : (-B + disc) / (2.0 * A);
        if (!(th >= 0.0 && th <= 1.0)) th = (r0 - rs) / (r0 - r1);
        for (int k = 0; k < 3; k++) e.v[k] = xp[k] + th * d[k];
        e.t = tp + th * (b->t[i] - tp);
    }
    gcp_obs_emit(o, L, &e);
}


/* ---- the sampler ------------------------------------------------------- */

/* The live lanes of b at time t; gc: they hold guiding centres (X, p_par,
 * mu), else particles (x, u); mode: the tag of their events (method =
 * hybrid: enum gcp_hybrid_mode; a lane whose mode changed starts a new
 * gyro-average, and its stream goes on). */
static void observe_live(struct gcp_observer *o, const struct gcp_block *b, double t, int gc,
                         int32_t mode, int fo_done)
{
    const size_t n = b->n_active;
    /* method = hybrid: a lane whose mode changed starts a new gyration (the
     * one in progress, if any, is not finished); its stream goes on */
    for (size_t i = 0; o->hybrid && i < n; i++) {
        const size_t li = b->index[i];
        if (li >= o->nlanes || !o->active[li] || o->lane[li].mode == mode) continue;
        o->lane[li].mode = mode;
        o->g.init[li] = 0;
    }
    /* dense: the lanes' indices are still 0 .. n-1 and all begun (a block
     * before its first retirement), tested as one vectorised reduction */
    int dense = n <= o->nlanes;
    if (dense) {
        const size_t *restrict idx = b->index;
        const int64_t *restrict act = o->active;
        size_t off = 0;
        int64_t on = 1;
        for (size_t i = 0; i < n; i++) off |= idx[i] ^ i, on &= act[i];
        dense = off == 0 && on;
    }
    /* the quiet pass needs every live lane begun (always, after
     * gcp_observer_begin), and no other source of stream samples */
    int all = o->stream && gc && n && o->gc && !o->hybrid && !o->hot.per_lane;
    for (size_t i = 0; all && !dense && i < n; i++)
        all = b->index[i] < o->nlanes && o->active[b->index[i]];
    /* B at the lanes: in the quiet pass itself for the dipole's closed
     * form, or from the block where the step left it (GCP_BLOCK_B_AT_X) */
    if (o->stream && n && !fo_done && !(all && (o->pdip || (b->flags & GCP_BLOCK_B_AT_X)))) {
        memset(o->fst, 0, n * sizeof(int32_t));
        o->f->type->eval_block(o->f, t, n, b->x, b->y, b->z, o->Bx, o->By, o->Bz, NULL, NULL,
                               NULL, o->fst);
    }
    if (o->stream && !gc && n && !fo_done) gcp_obs_fo_block(o, b, t);
    if (o->stream && gc && n) {
        if (all) {
            gcp_obs_stream_quiet(o, b, t, n, dense);
            /* the ring holds the last live positions (loss) */
            o->hot.pos = 1;
            return;
        } else {
            /* |B|, p^2 and the J integrand of every lane in one vectorised
             * pass (the quiet pass's expressions: GCP_INV_C2), the rest
             * per lane */
            const double m = o->m;
            const double *restrict Bx = o->Bx, *restrict By = o->By, *restrict Bz = o->Bz;
            const double *restrict ppar = b->ppar, *restrict mu = b->mu;
            double *restrict Gb = o->Gb, *restrict Gp2 = o->Gp2, *restrict Gjd = o->Gjd;
            GCP_OBS_IVDEP
            for (size_t i = 0; i < n; i++) {
                Gb[i] = sqrt(Bx[i] * Bx[i] + By[i] * By[i] + Bz[i] * Bz[i]);
                Gp2[i] = ppar[i] * ppar[i] + 2.0 * m * mu[i] * Gb[i];
                Gjd[i] = ppar[i] * ppar[i] / sqrt(m * m + Gp2[i] * GCP_INV_C2);
            }
            const int hot = o->gc && !o->hybrid, c = (o->hot.cur + 1) % 3;
            o->hot.rt[c] = t;
            for (size_t i = 0; i < n; i++) {
                const size_t li = b->index[i];
                if (li >= o->nlanes || !o->active[li]) continue;
                const struct gsample s = {.t = t, .X = {b->x[i], b->y[i], b->z[i]},
                                          .ppar = ppar[i], .mu = mu[i], .B = Gb[i], .p2 = Gp2[i]};
                struct lane *L = &o->lane[li];
                if (hot) gcp_obs_hot_to_lane(o, L, li);
                gcp_obs_stream_sample_jd(o, L, o->id0 + (int64_t)li, &s, Gjd[i]);
                if (hot) gcp_obs_lane_to_hot(o, L, li, c);
            }
            if (hot) o->hot.cur = c;
        }
    }
    o->hot.pos = 0;
    /* the last live position (loss interpolation): densely, as a copy, while
     * the lanes' indices are still 0 .. n-1 and all begun (it cost as much
     * as half a fused boris step per lane as a per-lane loop) */
    if (dense) {
        memcpy(o->xprev[0], b->x, n * sizeof(double));
        memcpy(o->xprev[1], b->y, n * sizeof(double));
        memcpy(o->xprev[2], b->z, n * sizeof(double));
        for (size_t i = 0; i < n; i++) o->tprev[i] = t;
        return;
    }
    for (size_t i = 0; i < n; i++) {
        const size_t li = b->index[i];
        if (li >= o->nlanes || !o->active[li]) continue;
        o->xprev[0][li] = b->x[i], o->xprev[1][li] = b->y[i], o->xprev[2][li] = b->z[i];
        o->tprev[li] = t;
    }
}

void gcp_observer_begin(struct gcp_observer *o, const struct gcp_block *b, double t0,
                        int64_t id0, struct gcp_events *out)
{
    o->out = out;
    o->id0 = id0;
    o->t0 = t0;
    o->ev_begin = out->n;
    o->hot.pos = 0;
    o->q = b->q;
    o->m = b->m;
    for (size_t i = 0; i < b->n; i++) {
        const size_t li = b->index[i];
        if (li >= o->nlanes) continue;
        struct lane *L = &o->lane[li];
        memset(L, 0, sizeof *L);
        o->g.init[li] = 0; /* no gyration in progress */
        o->active[li] = 1;
        L->eq_Bmin = INFINITY;
        L->s_k = L->d_k = 1;
        gcp_obs_lane_to_hot(o, L, li, o->hot.cur);
        /* mu of every ring slot: a guiding centre's is constant (invariants_quiet.c gs_put) */
        for (int k = 0; o->gc && !o->hybrid && k < 3; k++) o->hot.r[k][5][li] = b->mu[i];
        o->xprev[0][li] = b->x[i], o->xprev[1][li] = b->y[i], o->xprev[2][li] = b->z[i];
        o->tprev[li] = t0;
    }
    /* method = hybrid: the mode of each lane comes with gcp_observer_sample_mode */
    if (!o->hybrid) observe_live(o, b, t0, o->gc, 0, 0);
}

void gcp_observer_sample(const struct gcp_block *b, double t, void *ctx)
{
    struct gcp_observer *o = ctx;
    /* lanes that stopped in this step: just past the live range */
    for (size_t i = b->n_active; i < b->n; i++) {
        const size_t li = b->index[i];
        struct lane *L = &o->lane[li];
        if (o->active[li] && !L->loss_done && b->status[i] != GCP_ALIVE)
            loss(o, L, o->id0 + (int64_t)li, b, i);
    }
    /* the steps a fused full-orbit step did the gyro-average work of
     * (gcp_observer_fo_gyro): their completed gyrations into the streams */
    const int fo_done = o->g.steps > 0;
    if (fo_done) gcp_obs_fo_records(o);
    o->g.steps = o->g.nrec = 0;
    if (!o->hybrid) observe_live(o, b, t, o->gc, 0, fo_done);
}

struct gcp_fo_gyro *gcp_observer_fo_gyro(struct gcp_observer *o)
{
    return o && o->stream && !o->gc && !o->hybrid ? &o->g : NULL;
}

void gcp_observer_sample_mode(const struct gcp_block *b, double t, int mode, void *ctx)
{
    struct gcp_observer *o = ctx;
    observe_live(o, b, t, mode == GCP_MODE_GC, mode, 0);
}

void gcp_observer_set_sample_dt(struct gcp_observer *o, double sample_dt)
{
    o->opts.sample_dt = sample_dt > 0 ? sample_dt : 0.0;
}

int gcp_observer_end(struct gcp_observer *o, const struct gcp_block *b)
{
    for (size_t i = 0; i < b->n; i++) {
        const size_t li = b->index[i];
        struct lane *L = &o->lane[li];
        if (o->active[li] && !L->loss_done && b->status[i] != GCP_ALIVE)
            loss(o, L, o->id0 + (int64_t)li, b, i);
    }
    /* rows the lane's other rows replace; the reasons for what is missing */
    if (o->out) gcp_obs_finish(o, b);
    for (size_t i = 0; i < b->n; i++) o->active[b->index[i]] = 0;
    const int bad = o->nomem;
    o->nomem = 0;
    return bad ? GCP_ERR_NOMEM : 0;
}
