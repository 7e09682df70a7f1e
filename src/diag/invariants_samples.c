/* What the observer gives particles that do not bounce (issue 13; contract:
 * gcpush/invariants.h):
 *   - samples: mu, energy, p_phi at t0 + k sample_dt for a particle with no
 *     equator point, linear in t between two stream samples (exact for the
 *     constants they are meant to show; O(h^2) otherwise, h the stream
 *     spacing: dt, or a gyration for full orbits);
 *   - the stream's drift contour: the guiding centre at the same grid times
 *     (linear in t), and wherever its azimuth moved by pi/4 since the last
 *     point (no aliasing when the azimuth turns faster than the cadence), so the azimuth's turns -- drift-phase crossings,
 *     independent of bounces -- give a drift period and Phi = |oint A . dl|
 *     for a particle whose equator points make no turn (a full orbit at
 *     pitch ~90 deg, whose gyro-averaged p_par flips sign with noise and
 *     finds a |B| minimum only now and then; a passing orbit).  In an
 *     axisymmetric field psi = R A_phi is constant on a field line, so the
 *     contour need not lie on the equator for Phi = 2 pi psi; elsewhere it
 *     is the flux through the guiding centre's own (non-bouncing) orbit;
 *   - the reasons: per particle, why an asked quantity has no row. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/gc.h"
#include "gcpush/invariants.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "invariants_priv.h"

/* A recorded point (t, X) of the stream contour into L->cst. */
static void stream_point_in(struct gcp_observer *o, struct lane *L, int64_t id, double t,
                            const double X[3])
{
    struct cpoint P = {.t = t, .z = X[2]};
    /* the azimuth from the last point's (no atan2 but at every 64th) */
    P.phi = gcp_obs_azimuth_from(&L->cst, L->cst.prev.phi, X);
    gcp_obs_contour_of(o, t, X, &P.R, &P.psi, &P.AR, &P.Az);
    gcp_obs_drift_point(o, L, &L->cst, id, P, GCP_CONTOUR_STREAM);
}

void gcp_obs_stream_flush(struct gcp_observer *o, struct lane *L, size_t li)
{
    const double *q = o->sq[li].p;
    const int64_t id = o->id0 + (int64_t)li;
    for (int k = 0; k < L->nq; k++) stream_point_in(o, L, id, q[4 * k], q + 4 * k + 1);
    L->nq = 0;
}

/* 1 when lane L's recorded stream points (none yet in L->cst) cannot make
 * the contour turn by 2 pi, so that they would give no drift row
 * (gcp_obs_drift_point's test |phi - phi0| >= 2 pi), known without their
 * potentials: the azimuth turned between successive points a, b is
 * theta = atan(u), u = (a x b)/(a . b) where a . b > 0, and
 * |atan u| <= |u|, so |phi - phi0| <= sum |u| (1e-3 too large at the
 * cadence's ~0.065 rad a point, up to 27% at the pi/4 points of a fast
 * azimuth).  A sum below 2 pi - 1e-6 (the rounding of the sum and of the
 * contour's own azimuths is ~1e-13) decides; else, or a . b <= 0, the
 * points go into the contour. */
static int stream_no_turn(const struct gcp_observer *o, const struct lane *L, size_t li)
{
    const double *q = o->sq[li].p;
    double sum = 0.0;
    for (int k = 1; k < L->nq; k++) {
        const double *a = q + 4 * (k - 1) + 1, *b = q + 4 * k + 1;
        const double c = a[0] * b[1] - a[1] * b[0], d = a[0] * b[0] + a[1] * b[1];
        if (!(d > 0)) return 0;
        sum += fabs(c) / d;
    }
    return sum < 2.0 * GCP_PI - 1e-6;
}

/* Points a lane's record holds at most: past them it goes into L->cst
 * (bounds the memory of a long push at 32 KiB a lane). */
#define SQ_MAX 1024

/* The stream contour's point at time t (X linear between a and s).  Most
 * lanes' stream rows are dropped at the end (their equator contour makes a
 * turn: gcp_obs_finish), so a point is only recorded here, (t, X); its
 * potential, azimuth and drift_point wait for gcp_obs_stream_flush, which
 * gcp_obs_finish calls only where the rows are kept (issue 12).  The same
 * points go through the same expressions in the same order: the rows are
 * those of a point taken into the contour at once. */
static void stream_point(struct gcp_observer *o, struct lane *L, int64_t id, const struct gsample *a,
                         const struct gsample *s, double t)
{
    const double th = s->t > a->t ? (t - a->t) / (s->t - a->t) : 1.0;
    double X[3];
    for (int k = 0; k < 3; k++) X[k] = a->X[k] + th * (s->X[k] - a->X[k]);
    const size_t li = (size_t)(L - o->lane);
    L->st_n++;
    L->st_t = t;
    /* the direction of its azimuth, for azimuth_moved (cos, sin of the
     * point's phi to rounding, which that test's margin covers; R as
     * gcp_obs_contour_of's) */
    const double R = sqrt(X[0] * X[0] + X[1] * X[1]);
    L->cst.cprev = R > 0 ? X[0] / R : 1.0;
    L->cst.sprev = R > 0 ? X[1] / R : 0.0;
    if (o->st_eager) {
        stream_point_in(o, L, id, t, X);
        return;
    }
    if (L->nq == o->sq[li].cap) {
        const int cap = L->nq ? 2 * L->nq : 64;
        double *p = cap <= SQ_MAX ? realloc(o->sq[li].p, (size_t)cap * 4 * sizeof(double)) : NULL;
        if (p) {
            o->sq[li].p = p, o->sq[li].cap = cap;
        } else {
            /* full (or no memory): into the contour now */
            gcp_obs_stream_flush(o, L, li);
            stream_point_in(o, L, id, t, X);
            return;
        }
    }
    double *q = o->sq[li].p + 4 * L->nq++;
    q[0] = t, q[1] = X[0], q[2] = X[1], q[3] = X[2];
}

/* |wrap(atan2(X_y, X_x) - prev.phi)| > pi/4, the test of every stream
 * sample (a guiding centre's every step): the angle d between X and the
 * direction (cos, sin) of prev.phi has |d| <= pi/4 exactly when
 * X.e >= |X x e| (cos d >= |sin d|), which takes no atan2.  Where the two
 * sides are within 1e-9 |X| of each other (rounding of cos, sin and atan2
 * is ~1e-16 |X|) the atan2 test decides, so the verdict is always the
 * atan2 test's own. */
static int azimuth_moved(struct gcp_observer *o, struct lane *L, const double X[3])
{
    const struct contour *c = &L->cst;
    const double dot = X[0] * c->cprev + X[1] * c->sprev;
    const double crs = X[1] * c->cprev - X[0] * c->sprev;
    const double margin = 1e-9 * (fabs(X[0]) + fabs(X[1]));
    if (dot - fabs(crs) > margin) return 0;
    if (fabs(crs) - dot > margin) return 1;
    /* the last point's phi: its recorded points into the contour first */
    gcp_obs_stream_flush(o, L, (size_t)(L - o->lane));
    return fabs(gcp_obs_wrap_pi(atan2(X[1], X[0]) - c->prev.phi)) > 0.25 * GCP_PI;
}

void gcp_obs_cadence(struct gcp_observer *o, struct lane *L, int64_t id, const struct gsample *s)
{
    const double T = o->opts.sample_dt;
    const unsigned inv = o->opts.invariants;
    const struct gsample *a = &L->s1;
    /* once it has an equator point, its rows would be dropped at the end: none made */
    if (T > 0 && !L->had_eq && (inv & (GCP_INV_MU | GCP_INV_ENERGY | GCP_INV_PPHI))) {
        for (;;) {
            /* t0 + k T, not a running sum: the grid does not drift with k */
            const double tk = o->t0 + (double)L->s_k * T;
            if (tk > s->t) break;
            L->s_k++;
            if (!L->have_s1 || tk <= a->t) continue; /* grid times before the first sample */
            const double th = (tk - a->t) / (s->t - a->t);
            struct gcp_event e = {.id = id, .kind = GCP_EVENT_SAMPLE, .t = tk};
            e.v[0] = e.v[1] = e.v[2] = NAN;
            if (inv & GCP_INV_MU) e.v[0] = a->mu + th * (s->mu - a->mu);
            if (inv & GCP_INV_ENERGY) e.v[1] = gcp_obs_energy(o, a->p2 + th * (s->p2 - a->p2));
            if (inv & GCP_INV_PPHI) {
                double pa = NAN, pb = NAN;
                gcp_gc_pphi(o->f, a->t, o->q, a->X, a->ppar, &pa);
                gcp_gc_pphi(o->f, s->t, o->q, s->X, s->ppar, &pb);
                e.v[2] = pa + th * (pb - pa);
            }
            gcp_obs_emit(o, L, &e);
        }
    }
    /* the stream contour, until the equator contour has made a turn (its
     * rows would be dropped then) */
    if (!o->want_drift || L->n_drift_eq || !(T > 0)) return;
    for (;;) {
        const double tk = o->t0 + (double)L->d_k * T;
        if (tk > s->t) break;
        L->d_k++;
        if (L->have_s1 && tk > a->t) stream_point(o, L, id, a, s, tk);
    }
    /* a fast azimuth (a tokamak transit, a drift faster than the cadence)
     * would alias: a point wherever the azimuth moved by pi/4 since the last */
    if (L->st_n && L->st_t < s->t && azimuth_moved(o, L, s->X))
        stream_point(o, L, id, s, s, s->t);
}

const char *gcp_undefined_name(int why)
{
    static const char *const names[GCP_UNDEF_COUNT] = {
        "DEFINED", "NOT_ASKED", "NO_MIRROR", "NO_BOUNCE", "NO_EQUATOR", "NO_TURN", "NO_POTENTIAL"};
    return why >= 0 && why < GCP_UNDEF_COUNT ? names[why] : "UNKNOWN";
}

void gcp_obs_finish(struct gcp_observer *o, const struct gcp_block *b)
{
    /* The rows the lane's other rows replace, known only now: cadence
     * samples of a lane with an equator point, stream-contour drift rows of
     * a lane whose equator contour made a turn (the block's events are
     * out->e[ev_begin..n), in order). */
    struct gcp_events *ev = o->out;
    /* the stream contour's recorded points, where its rows are kept */
    for (size_t i = 0; i < b->n; i++) {
        const size_t li = b->index[i];
        struct lane *L = &o->lane[li];
        if (!o->active[li] || L->n_drift_eq || !L->nq) continue;
        /* a contour that makes no turn gives no row: only whether the
         * field gives a potential there (psi_nan, the L* reason), asked of
         * its first point -- the fields that give none give it nowhere */
        if (!L->cst.n && stream_no_turn(o, L, li)) {
            const double *X = o->sq[li].p + 1;
            double R, psi, AR, Az;
            gcp_obs_contour_of(o, o->sq[li].p[0], X, &R, &psi, &AR, &Az);
            if (!isfinite(psi)) L->psi_nan = 1;
            o->st_skipped += L->nq;
            L->nq = 0;
        } else {
            gcp_obs_stream_flush(o, L, li);
        }
    }
    int64_t w = o->ev_begin;
    for (int64_t k = o->ev_begin; k < ev->n; k++) {
        const struct gcp_event *e = &ev->e[k];
        const int64_t li = e->id - o->id0;
        const struct lane *L = li >= 0 && (size_t)li < o->nlanes ? &o->lane[li] : NULL;
        const int drop = L && ((e->kind == GCP_EVENT_SAMPLE && L->had_eq) ||
                               (e->kind == GCP_EVENT_DRIFT && L->n_drift_eq &&
                                e->v[GCP_DRIFT_CONTOUR] == GCP_CONTOUR_STREAM));
        if (!drop) ev->e[w++] = *e;
    }
    ev->n = w;
    /* why an asked quantity has no row */
    const unsigned inv = o->opts.invariants;
    const int want_mu = (inv & (GCP_INV_MU | GCP_INV_ENERGY | GCP_INV_PPHI)) != 0;
    for (size_t i = 0; i < b->n; i++) {
        const size_t li = b->index[i];
        struct lane *L = &o->lane[li];
        if (!o->active[li]) continue;
        struct gcp_event e = {.id = o->id0 + (int64_t)li, .kind = GCP_EVENT_UNDEFINED, .t = b->t[i]};
        const int nomirror = L->n_mirror == 0;
        const int drifted = L->n_drift_eq + L->n_drift_st > 0;
        e.v[GCP_UNDEF_BOUNCE] = !o->want_bounce ? GCP_UNDEF_NOT_ASKED
                                : L->n_bounce ? GCP_UNDEF_NONE
                                : nomirror    ? GCP_UNDEF_NO_MIRROR
                                              : GCP_UNDEF_NO_BOUNCE;
        e.v[GCP_UNDEF_EQUATOR] = !want_mu ? GCP_UNDEF_NOT_ASKED
                                 : L->had_eq ? GCP_UNDEF_NONE
                                             : GCP_UNDEF_NO_EQUATOR;
        e.v[GCP_UNDEF_DRIFT] = !o->want_drift ? GCP_UNDEF_NOT_ASKED
                               : drifted      ? GCP_UNDEF_NONE
                                              : GCP_UNDEF_NO_TURN;
        e.v[GCP_UNDEF_LSTAR] = !o->want_drift ? GCP_UNDEF_NOT_ASKED
                               : L->psi_nan   ? GCP_UNDEF_NO_POTENTIAL
                               : drifted      ? GCP_UNDEF_NONE
                                              : GCP_UNDEF_NO_TURN;
        int any = 0;
        for (int k = 0; k < 4; k++) any |= e.v[k] > GCP_UNDEF_NOT_ASKED;
        if (any) gcp_obs_emit(o, L, &e);
    }
}
