/* method = hybrid: per-particle switching between a guiding-centre and a
 * full-orbit pusher (contract and physics: include/gcpush/hybrid.h).
 *
 * The existing pushers do the pushing, through their public advance
 * functions on sub-blocks gathered from the caller's block: this file only
 * decides who is pushed how far, transforms at the switches, and keeps the
 * books.  Within one call the time grid is t_k = t0 + k dt (dt the GC step);
 * the call is cut into segments that end where the sampler wants all lanes
 * (every `every` steps), and within a segment every lane advances on its
 * own: GC lanes in one GC advance to the segment end (stopping early only
 * when they break the threshold), FO lanes one grid interval at a time
 * (switch decisions at the interval ends), until all are at the segment end. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/gc.h"
#include "gcpush/hybrid.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "block_priv.h"

/* Averaging windows that have not completed one gyration after this many
 * chunks (a lane that no longer gyrates) are given up and reopened later. */
#define WINDOW_MAX_CHUNKS 64

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
    int nomem;
};

static double dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* SplitMix64 finaliser (Steele, Lea & Flood 2014) on a counter of
 * (seed, id, n): stateless, so any order of evaluation draws the same. */
static uint64_t mix64(uint64_t z)
{
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

double gcp_hybrid_phase(uint64_t seed, int64_t id, int64_t n)
{
    /* a stream of its own: the initial-state draws use seed * golden + id * 16 + k */
    const uint64_t z = mix64(mix64(seed ^ 0x6a09e667f3bcc909ULL) + (uint64_t)id * 0x9e3779b97f4a7c15ULL +
                             (uint64_t)n);
    return 2.0 * GCP_PI * ((double)(z >> 11) * 0x1.0p-53);
}

int gcp_hybrid_create(struct gcp_hybrid **out, size_t nlanes, const struct gcp_hybrid_opts *o)
{
    *out = NULL;
    if (!o->gc || o->gc->kind != GCP_GUIDING_CENTRE || !o->fo || o->fo->kind != GCP_FULL_ORBIT ||
        !(o->to_gc > 0.0 && o->to_gc < o->to_fo) || !(o->fo_dt > 0.0 && o->fo_dt <= 0.25))
        return GCP_ERR_VALUE;
    struct gcp_hybrid *h = calloc(1, sizeof *h);
    if (!h) return GCP_ERR_NOMEM;
    h->o = *o;
    h->nlanes = nlanes;
    const size_t m = nlanes ? nlanes : 1;
    h->lane = calloc(m, sizeof *h->lane);
    h->ord = calloc(m, sizeof *h->ord);
    h->nsub = calloc(m, sizeof *h->nsub);
    if (!h->lane || !h->ord || !h->nsub || gcp_block_alloc(&h->sb, m)) {
        gcp_hybrid_free(h);
        return GCP_ERR_NOMEM;
    }
    *out = h;
    return 0;
}

void gcp_hybrid_free(struct gcp_hybrid *h)
{
    if (!h) return;
    free(h->lane);
    free(h->ord);
    free(h->nsub);
    free(h->sw);
    gcp_block_free(&h->sb);
    free(h);
}

int gcp_hybrid_mode(const struct gcp_hybrid *h, size_t index)
{
    return index < h->nlanes ? h->lane[index].mode : GCP_MODE_GC;
}

void gcp_hybrid_info(const struct gcp_hybrid *h, size_t index, struct gcp_hybrid_lane_info *out)
{
    const struct hlane *L = &h->lane[index < h->nlanes ? index : 0];
    *out = (struct gcp_hybrid_lane_info){L->mode, L->nsw, L->t_gc, L->t_fo};
}

size_t gcp_hybrid_switches(const struct gcp_hybrid *h, const struct gcp_hybrid_switch **sw)
{
    *sw = h->sw;
    return h->nsw;
}

static void record_switch(struct gcp_hybrid *h, const struct hlane *L, double t, const double X[3],
                          double eps, int dir, double dp2)
{
    if (h->nsw == h->capsw) {
        const size_t cap = h->capsw ? 2 * h->capsw : 16;
        struct gcp_hybrid_switch *p = realloc(h->sw, cap * sizeof *p);
        if (!p) {
            h->nomem = 1;
            return;
        }
        h->sw = p;
        h->capsw = cap;
    }
    h->sw[h->nsw++] = (struct gcp_hybrid_switch){L->id, t, {X[0], X[1], X[2]}, eps, dir, dp2};
}

static struct hlane *lane_of(struct gcp_hybrid *h, const struct gcp_block *b, size_t i)
{
    return &h->lane[b->index[i]];
}

void gcp_hybrid_begin(struct gcp_hybrid *h, struct gcp_block *b, const struct gcp_field *f,
                      double t0, int64_t id0)
{
    h->nsw = 0;
    for (size_t i = 0; i < b->n; i++) {
        struct hlane *L = lane_of(h, b, i);
        memset(L, 0, sizeof *L);
        L->id = id0 + (int64_t)b->index[i];
        L->mode = GCP_MODE_FO;
        if (i >= b->n_active) continue;
        const double x[3] = {b->x[i], b->y[i], b->z[i]}, u[3] = {b->ux[i], b->uy[i], b->uz[i]};
        double X[3], ppar, mu, eps = INFINITY;
        int st = gcp_gc_from_fo(f, t0, b->q, b->m, x, u, X, &ppar, &mu);
        if (!st) st = gcp_gc_adiabaticity(f, t0, b->q, b->m, X, ppar, mu, &eps);
        if (st || !(eps <= h->o.to_fo)) continue;
        L->mode = GCP_MODE_GC;
        b->x[i] = X[0], b->y[i] = X[1], b->z[i] = X[2];
        b->ppar[i] = ppar;
        b->mu[i] = mu;
    }
}

/* ---- sub-blocks ---------------------------------------------------------- */

/* Copies outer lanes list[0..n) into the sub-block (index = outer lane). */
static void gather(struct gcp_block *s, const struct gcp_block *b, const size_t *list, size_t n)
{
    s->q = b->q, s->m = b->m;
    for (size_t j = 0; j < n; j++) {
        const size_t i = list[j];
        s->x[j] = b->x[i], s->y[j] = b->y[i], s->z[j] = b->z[i];
        s->ux[j] = b->ux[i], s->uy[j] = b->uy[i], s->uz[j] = b->uz[i];
        s->ppar[j] = b->ppar[i], s->mu[j] = b->mu[i];
        s->t[j] = b->t[i];
        s->status[j] = GCP_ALIVE;
        s->steps[j] = 0;
        s->index[j] = i;
    }
    s->n = s->n_active = n;
}

/* Sub-block lane j back to its outer lane (state, status, steps). */
static size_t scatter(struct gcp_block *b, const struct gcp_block *s, size_t j)
{
    const size_t i = s->index[j];
    b->x[i] = s->x[j], b->y[i] = s->y[j], b->z[i] = s->z[j];
    b->ux[i] = s->ux[j], b->uy[i] = s->uy[j], b->uz[i] = s->uz[j];
    b->ppar[i] = s->ppar[j], b->mu[i] = s->mu[j];
    b->status[i] = s->status[j];
    b->steps[i] += s->steps[j];
    b->t[i] = s->t[j];
    return i;
}

/* ---- switches ------------------------------------------------------------ */

static void window_open(struct hlane *L, const struct gcp_field *f, double t, const double x[3],
                        const double X[3], double ppar, double mu);
static void window_sample(struct hlane *L, double t, const double x[3], const double X[3],
                          double ppar, double mu);

struct trial_ctx {
    const struct gcp_field *f;
    double q, m;
    struct hlane w;
};

static int trial_step(double t, const double x[3], const double u[3], void *vctx)
{
    struct trial_ctx *c = vctx;
    double X[3], ppar, mu;
    if (gcp_gc_from_fo(c->f, t, c->q, c->m, x, u, X, &ppar, &mu)) return 1;
    window_sample(&c->w, t, x, X, ppar, mu);
    return c->w.K >= 1;
}

/* GC -> FO, gyro-consistent.  The particle gcp_fo_from_gc makes at phase
 * phi has the guiding centre's X, p_par, mu as its instantaneous first-order
 * guiding centre, but averaged over its gyration -- what the way back and
 * the observer see -- it is off by O(eps), with the sign of the gyrophase
 * (the first-order corrections that transformation leaves out).  One trial
 * gyration with the FO method measures the offset against the guiding
 * centre pushed to the same mid-time, and the particle is made again from
 * the state corrected by it (residual O(eps^2)), with mu set so that its
 * energy is the guiding centre's.  Returns 0 or a status; on a failed trial the
 * uncorrected particle stands. */
static int fo_start(const struct gcp_hybrid *h, const struct gcp_field *f, double t, double q,
                    double m, const double X[3], double ppar, double mu, double phase, double x[3],
                    double u[3])
{
    int st = gcp_fo_from_gc(f, t, q, m, X, ppar, mu, phase, x, u);
    if (st) return st;
    struct trial_ctx c = {.f = f, .q = q, .m = m};
    double X0[3], p0, mu0;
    if (gcp_gc_from_fo(f, t, q, m, x, u, X0, &p0, &mu0)) return 0;
    window_open(&c.w, f, t, x, X0, p0, mu0);
    struct gcp_field_sample s = {.need = GCP_NEED_B};
    if (gcp_field_eval(f, t, X, &s)) return 0;
    const double B = sqrt(dot3(s.B, s.B));
    const double Tg = 2.0 * GCP_PI * gcp_gamma_of_u(u[0], u[1], u[2]) * m / (fabs(q) * B);
    const double hs = h->o.fo_dt * Tg;
    double tt = t, xx[3] = {x[0], x[1], x[2]}, uu[3] = {u[0], u[1], u[2]};
    /* up to 1.5 local gyro-periods: one whole gyration where B changes by a third */
    gcp_orbit_push(f, h->o.fo, q, m, &tt, xx, uu, hs, (int64_t)ceil(1.5 / h->o.fo_dt), trial_step,
                   &c);
    if (c.w.K < 1 || !(c.w.tK > t)) return 0;
    const double w = c.w.tK - t;
    double Xr[3] = {X[0], X[1], X[2]}, pr = ppar, tr = t;
    const struct gcp_push_opts po = {.dt = 0.5 * w, .nsteps = 1};
    if (gcp_gc_push(f, h->o.gc, q, m, &po, &tr, Xr, &pr, mu, NULL, NULL)) return 0;
    double Xc[3];
    for (int d = 0; d < 3; d++) Xc[d] = X[d] + (Xr[d] - c.w.IK[d] / w);
    const double pc = ppar + (pr - c.w.IK[3] / w);
    /* the energy of the guiding centre, gamma m c^2 + q phi(X), at the
     * corrected centre Xc: all of the difference goes into mu, the
     * perpendicular energy (why: window_close) */
    double A[3], phX = 0.0, phc = 0.0;
    if (f->has_E && (gcp_gc_potential(f, t, X, A, NULL, &phX) ||
                     gcp_gc_potential(f, t, Xc, A, NULL, &phc)))
        phX = phc = 0.0;
    struct gcp_field_sample sc = {.need = GCP_NEED_B};
    if (gcp_field_eval(f, t, Xc, &sc)) return 0;
    const double mc = m * GCP_C_LIGHT;
    const double gam = gcp_gc_gamma(ppar, mu, B, m) + q * (phX - phc) / (mc * GCP_C_LIGHT);
    const double muc = 0.5 * ((gam * gam - 1.0) * mc * mc - pc * pc) / (m * sqrt(dot3(sc.B, sc.B)));
    double xc[3], uc[3];
    if (!(muc > 0.0) || gcp_fo_from_gc(f, t, q, m, Xc, pc, muc, phase, xc, uc)) return 0;
    for (int d = 0; d < 3; d++) x[d] = xc[d], u[d] = uc[d];
    return 0;
}

/* GC -> FO at time t from the lane's GC state. */
static void to_fo(struct gcp_hybrid *h, struct gcp_block *b, const struct gcp_field *f, size_t i,
                  struct hlane *L, double t)
{
    const double X[3] = {b->x[i], b->y[i], b->z[i]};
    double eps = INFINITY, x[3], u[3];
    gcp_gc_adiabaticity(f, t, b->q, b->m, X, b->ppar[i], b->mu[i], &eps);
    const double phase = gcp_hybrid_phase(h->o.seed, L->id, L->nsw);
    const int st = fo_start(h, f, t, b->q, b->m, X, b->ppar[i], b->mu[i], phase, x, u);
    b->t[i] = t;
    if (st) { /* no particle for this guiding centre (e.g. the iteration diverged) */
        b->status[i] = st;
        return;
    }
    b->x[i] = x[0], b->y[i] = x[1], b->z[i] = x[2];
    b->ux[i] = u[0], b->uy[i] = u[1], b->uz[i] = u[2];
    L->mode = GCP_MODE_FO;
    L->avg = 0;
    record_switch(h, L, t, X, eps, +1, 0.0);
    L->nsw++;
}

/* Opens the averaging window of an FO lane at time t (its first sample). */
static void window_open(struct hlane *L, const struct gcp_field *f, double t, const double x[3],
                        const double X[3], double ppar, double mu)
{
    struct gcp_field_sample s = {.need = GCP_NEED_B};
    gcp_field_eval(f, t, X, &s);
    const double Bm = sqrt(dot3(s.B, s.B));
    const double bh[3] = {s.B[0] / Bm, s.B[1] / Bm, s.B[2] / Bm};
    const double rho[3] = {x[0] - X[0], x[1] - X[1], x[2] - X[2]};
    /* e1 along the gyroradius now, e2 = b x e1: the phase starts at 0 */
    const double rr = dot3(rho, bh);
    double e1[3] = {rho[0] - rr * bh[0], rho[1] - rr * bh[1], rho[2] - rr * bh[2]};
    const double ne = sqrt(dot3(e1, e1));
    for (int d = 0; d < 3; d++) L->e1[d] = e1[d] / ne;
    L->e2[0] = bh[1] * L->e1[2] - bh[2] * L->e1[1];
    L->e2[1] = bh[2] * L->e1[0] - bh[0] * L->e1[2];
    L->e2[2] = bh[0] * L->e1[1] - bh[1] * L->e1[0];
    L->avg = ne > 0.0 && isfinite(ne);
    L->K = L->nchunks = 0;
    L->ts = L->tprev = L->tK = t;
    L->theta = L->th_prev = 0.0;
    const double g[5] = {X[0], X[1], X[2], ppar, mu};
    memcpy(L->gprev, g, sizeof g);
    memset(L->acc, 0, sizeof L->acc);
    memset(L->IK, 0, sizeof L->IK);
}

/* One sample of the window after an FO step: trapezoid integral of the
 * guiding centre, and the time and integral at each completed gyration
 * (phase of x - X in the (e1, e2) plane unwrapped step by step; the crossing
 * of 2 pi K is interpolated linearly within the step). */
static void window_sample(struct hlane *L, double t, const double x[3], const double X[3],
                          double ppar, double mu)
{
    const double rho[3] = {x[0] - X[0], x[1] - X[1], x[2] - X[2]};
    const double th = atan2(dot3(rho, L->e2), dot3(rho, L->e1));
    double d = th - L->th_prev;
    d -= 2.0 * GCP_PI * floor((d + GCP_PI) / (2.0 * GCP_PI));
    const double a0 = fabs(L->theta), a1 = fabs(L->theta + d);
    const double g[5] = {X[0], X[1], X[2], ppar, mu};
    const double h = t - L->tprev;
    const int k1 = (int)floor(a1 / (2.0 * GCP_PI));
    if (k1 > L->K && a1 > a0) {
        const double fr = (2.0 * GCP_PI * k1 - a0) / (a1 - a0);
        for (int c = 0; c < 5; c++) {
            const double gw = L->gprev[c] + fr * (g[c] - L->gprev[c]);
            L->IK[c] = L->acc[c] + 0.5 * fr * h * (L->gprev[c] + gw);
        }
        L->tK = L->tprev + fr * h;
        L->K = k1;
    }
    for (int c = 0; c < 5; c++) L->acc[c] += 0.5 * h * (L->gprev[c] + g[c]);
    memcpy(L->gprev, g, sizeof g);
    L->theta += d;
    L->th_prev = th;
    L->tprev = t;
}

struct fo_sampler_ctx {
    struct gcp_hybrid *h;
    const struct gcp_block *b; /* the outer block (stable indices) */
    const struct gcp_field *f;
};

static void fo_sample(const struct gcp_block *s, double t, void *vctx)
{
    struct fo_sampler_ctx *c = vctx;
    for (size_t j = 0; j < s->n_active; j++) {
        struct hlane *L = lane_of(c->h, c->b, s->index[j]);
        if (!L->avg) continue;
        const double x[3] = {s->x[j], s->y[j], s->z[j]}, u[3] = {s->ux[j], s->uy[j], s->uz[j]};
        double X[3], ppar, mu;
        if (gcp_gc_from_fo(c->f, t, s->q, s->m, x, u, X, &ppar, &mu)) {
            L->avg = 0; /* lost its guiding centre: no window */
            continue;
        }
        window_sample(L, t, x, X, ppar, mu);
    }
}

/* FO -> GC of lane i at time t, from the completed window: the average at
 * the window's mid-time, pushed to t with the GC method, then the energy
 * matched to the particle's.  Returns 1 if the lane switched. */
static int window_close(struct gcp_hybrid *h, struct gcp_block *b, const struct gcp_field *f,
                        size_t i, struct hlane *L, double t, double dt_gc, double tol)
{
    L->avg = 0;
    const double w = L->tK - L->ts;
    if (!(w > 0.0)) return 0;
    double X[3] = {L->IK[0] / w, L->IK[1] / w, L->IK[2] / w};
    double ppar = L->IK[3] / w, mu = L->IK[4] / w;
    double tt = 0.5 * (L->ts + L->tK);
    const double span = t - tt;
    const double ns = ceil(span / dt_gc);
    const struct gcp_push_opts po = {.dt = span / (ns < 1.0 ? 1.0 : ns),
                                     .nsteps = ns < 1.0 ? 1 : (int64_t)ns,
                                     .tolerance = tol};
    if (gcp_gc_push(f, h->o.gc, b->q, b->m, &po, &tt, X, &ppar, mu, NULL, NULL)) return 0;
    /* energy of the particle: gamma m c^2 + q phi(x); of the GC: the same at X */
    const double mc = b->m * GCP_C_LIGHT;
    const double x[3] = {b->x[i], b->y[i], b->z[i]};
    const double u2 = b->ux[i] * b->ux[i] + b->uy[i] * b->uy[i] + b->uz[i] * b->uz[i];
    double A[3], phx = 0.0, phX = 0.0;
    const int pot = gcp_gc_potential(f, t, x, A, NULL, &phx) == 0 &&
                    gcp_gc_potential(f, t, X, A, NULL, &phX) == 0;
    double dp2 = 0.0;
    if (pot || !f->has_E) {
        if (!pot) phx = phX = 0.0;
        const double gam = sqrt(1.0 + u2 / (GCP_C_LIGHT * GCP_C_LIGHT)) + b->q * (phx - phX) / (mc * GCP_C_LIGHT);
        struct gcp_field_sample s = {.need = GCP_NEED_B};
        if (gcp_field_eval(f, t, X, &s)) return 0;
        const double pt2 = (gam * gam - 1.0) * mc * mc;
        const double pc2 = ppar * ppar + 2.0 * b->m * mu * sqrt(dot3(s.B, s.B));
        if (!(pt2 > 0.0 && pc2 > 0.0)) return 0;
        dp2 = pt2 / pc2 - 1.0;
        /* p^2 = <p_par0^2> + <p_perp0^2> at every sample, so the average falls
         * short of p^2 by var(p_par0): the gyrophase oscillation of p_par0,
         * which is gyration seen in a tilted frame.  That share belongs to the
         * perpendicular energy: mu takes it all (scaling p_par too would bleed
         * cos^2(pitch) dp2 of mu per return, a secular pitch-angle drift). */
        mu = 0.5 * (pt2 - ppar * ppar) / (b->m * sqrt(dot3(s.B, s.B)));
        if (!(mu > 0.0)) return 0;
    }
    double eps = INFINITY;
    if (gcp_gc_adiabaticity(f, t, b->q, b->m, X, ppar, mu, &eps) || !(eps < h->o.to_gc)) return 0;
    b->x[i] = X[0], b->y[i] = X[1], b->z[i] = X[2];
    b->ppar[i] = ppar;
    b->mu[i] = mu;
    L->mode = GCP_MODE_GC;
    record_switch(h, L, t, X, eps, -1, dp2);
    L->nsw++;
    return 1;
}

/* At the end of an FO chunk (time t, on the grid): open, continue or close
 * the averaging window. */
static void fo_decide(struct gcp_hybrid *h, struct gcp_block *b, const struct gcp_field *f,
                      size_t i, struct hlane *L, double t, double dt_gc, double tol)
{
    if (L->avg) {
        if (L->K >= 1) window_close(h, b, f, i, L, t, dt_gc, tol);
        else if (++L->nchunks > WINDOW_MAX_CHUNKS) L->avg = 0;
        return;
    }
    const double x[3] = {b->x[i], b->y[i], b->z[i]}, u[3] = {b->ux[i], b->uy[i], b->uz[i]};
    double X[3], ppar, mu, eps = INFINITY;
    if (gcp_gc_from_fo(f, t, b->q, b->m, x, u, X, &ppar, &mu) ||
        gcp_gc_adiabaticity(f, t, b->q, b->m, X, ppar, mu, &eps) || !(eps < h->o.to_gc))
        return;
    window_open(L, f, t, x, X, ppar, mu);
}

/* ---- the two kinds of push ------------------------------------------------ */

static double grid_t(const struct gcp_push_opts *o, int64_t k) { return o->t0 + (double)k * o->dt; }

/* All GC lanes at grid index k0, in one GC advance to K1. */
static void push_gc(struct gcp_hybrid *h, struct gcp_block *b, const struct gcp_field *f,
                    const struct gcp_push_opts *o, int64_t k0, int64_t K1, size_t n)
{
    size_t m = 0;
    for (size_t i = 0; i < n; i++) {
        const struct hlane *L = lane_of(h, b, i);
        if (!b->status[i] && L->mode == GCP_MODE_GC && L->kpos == k0) h->ord[m++] = i;
    }
    struct gcp_block *s = &h->sb;
    gather(s, b, h->ord, m);
    const double t0 = grid_t(o, k0);
    struct gcp_push_opts go = {.t0 = t0, .dt = o->dt, .nsteps = K1 - k0,
                               .tolerance = o->tolerance, .adiabaticity_max = h->o.to_fo};
    h->o.gc->advance(s, f, h->o.gc, &go, NULL);
    const double t1 = grid_t(o, K1);
    for (size_t j = 0; j < m; j++) {
        const size_t i = scatter(b, s, j);
        struct hlane *L = lane_of(h, b, i);
        if (b->status[i] == GCP_ALIVE) {
            L->t_gc += t1 - t0;
            L->kpos = K1;
            L->tl = t1;
            continue;
        }
        L->t_gc += b->t[i] - t0;
        if (b->status[i] != GCP_NONADIABATIC) continue; /* a real stop */
        b->status[i] = GCP_ALIVE;
        const double tf = b->t[i];
        to_fo(h, b, f, i, L, tf);
        /* the grid interval holding tf (fixed-step methods stop on the grid) */
        int64_t k = k0 + (int64_t)floor((tf - t0) / o->dt * (1.0 + 1e-12));
        if (k < k0) k = k0;
        if (k >= K1) k = K1 - 1;
        L->kpos = k;
        L->tl = tf;
    }
}

/* Steps of the FO chunk of lane i from L->tl to t1: a whole number, each at
 * most fo_dt local gyro-periods (B at the particle at the chunk start). */
static int64_t fo_steps(const struct gcp_hybrid *h, const struct gcp_block *b,
                        const struct gcp_field *f, size_t i, double tl, double t1)
{
    struct gcp_field_sample s = {.need = GCP_NEED_B};
    const double x[3] = {b->x[i], b->y[i], b->z[i]};
    gcp_field_eval(f, tl, x, &s);
    const double Bm = sqrt(dot3(s.B, s.B));
    const double gam = gcp_gamma_of_u(b->ux[i], b->uy[i], b->uz[i]);
    const double Tg = 2.0 * GCP_PI * gam * b->m / (fabs(b->q) * Bm);
    const double ns = ceil((t1 - tl) / (h->o.fo_dt * Tg) * (1.0 - 1e-12));
    /* B = 0: a straight line, one step is exact; a cap keeps a tiny field finite */
    return !(ns >= 1.0) ? 1 : ns > 1e9 ? 1000000000 : (int64_t)ns;
}

/* Group order of FO lanes: by step count, then start time. */
static int later(struct gcp_hybrid *h, const struct gcp_block *b, size_t i, size_t j)
{
    if (h->nsub[i] != h->nsub[j]) return h->nsub[i] > h->nsub[j];
    return lane_of(h, b, i)->tl > lane_of(h, b, j)->tl;
}

/* All FO lanes at grid index k0: one chunk each to t_{k0+1}, grouped by
 * their start time and step count, then the switch decision. */
static void push_fo(struct gcp_hybrid *h, struct gcp_block *b, const struct gcp_field *f,
                    const struct gcp_push_opts *o, int64_t k0, size_t n)
{
    const double t1 = grid_t(o, k0 + 1);
    size_t m = 0;
    for (size_t i = 0; i < n; i++) {
        const struct hlane *L = lane_of(h, b, i);
        if (b->status[i] || L->mode != GCP_MODE_FO || L->kpos != k0) continue;
        h->nsub[i] = fo_steps(h, b, f, i, L->tl, t1);
        h->ord[m++] = i;
    }
    /* groups of equal (nsub, tl): insertion sort, m <= block size */
    for (size_t a = 1; a < m; a++) {
        const size_t v = h->ord[a];
        size_t c = a;
        while (c > 0 && later(h, b, h->ord[c - 1], v)) {
            h->ord[c] = h->ord[c - 1];
            c--;
        }
        h->ord[c] = v;
    }
    size_t g0 = 0;
    while (g0 < m) {
        size_t g1 = g0 + 1;
        const struct hlane *L0 = lane_of(h, b, h->ord[g0]);
        while (g1 < m && h->nsub[h->ord[g1]] == h->nsub[h->ord[g0]] &&
               lane_of(h, b, h->ord[g1])->tl == L0->tl)
            g1++;
        const double tl = L0->tl;
        const int64_t ns = h->nsub[h->ord[g0]];
        int any_avg = 0;
        for (size_t a = g0; a < g1; a++) any_avg |= lane_of(h, b, h->ord[a])->avg;
        struct gcp_block *s = &h->sb;
        gather(s, b, h->ord + g0, g1 - g0);
        struct fo_sampler_ctx fc = {h, b, f};
        const struct gcp_sampler smp = {1, fo_sample, &fc};
        gcp_block_advance_fo(s, f, h->o.fo, tl, (t1 - tl) / (double)ns, ns, any_avg ? &smp : NULL);
        for (size_t j = 0; j < g1 - g0; j++) {
            const size_t i = scatter(b, s, j);
            struct hlane *L = lane_of(h, b, i);
            L->t_fo += (b->status[i] ? b->t[i] : t1) - tl;
            if (b->status[i]) continue;
            L->kpos = k0 + 1;
            L->tl = t1;
            fo_decide(h, b, f, i, L, t1, o->dt, o->tolerance);
        }
        g0 = g1;
    }
}

/* Retires stopped lanes (their t and steps are already set). */
static size_t retire(struct gcp_block *b, size_t n)
{
    size_t i = 0;
    while (i < n) {
        if (b->status[i] != GCP_ALIVE) {
            gcp_block_swap_lanes(b, i, n - 1);
            n--;
        } else {
            i++;
        }
    }
    return n;
}

size_t gcp_hybrid_advance(struct gcp_hybrid *h, struct gcp_block *b, const struct gcp_field *f,
                          const struct gcp_push_opts *o, const struct gcp_sampler *smp)
{
    size_t n = b->n_active;
    if (!h || !(o->dt > 0.0) || !isfinite(o->dt) || o->nsteps < 0 || b->n > h->nlanes) {
        for (size_t i = 0; i < n; i++) b->status[i] = GCP_STEP_FAILED, b->t[i] = o->t0;
        b->n_active = 0;
        return 0;
    }
    const int64_t every = smp && smp->fn ? smp->every : 0;
    int64_t K0 = 0;
    while (K0 < o->nsteps && n > 0) {
        const int64_t K1 = every && K0 + every < o->nsteps ? K0 + every : o->nsteps;
        for (size_t i = 0; i < n; i++) {
            struct hlane *L = lane_of(h, b, i);
            L->kpos = K0;
            L->tl = grid_t(o, K0);
        }
        /* every lane reaches K1 or stops; each pass moves at least one lane on */
        for (;;) {
            int64_t kg = K1, kf = K1;
            for (size_t i = 0; i < n; i++) {
                const struct hlane *L = lane_of(h, b, i);
                if (b->status[i] || L->kpos >= K1) continue;
                if (L->mode == GCP_MODE_GC) kg = L->kpos < kg ? L->kpos : kg;
                else kf = L->kpos < kf ? L->kpos : kf;
            }
            if (kg < K1) push_gc(h, b, f, o, kg, K1, n);
            else if (kf < K1) push_fo(h, b, f, o, kf, n);
            else break;
        }
        n = retire(b, n);
        b->n_active = n;
        K0 = K1;
        if (every && K0 % every == 0) smp->fn(b, grid_t(o, K0), smp->ctx);
    }
    for (size_t i = 0; i < n; i++) b->t[i] = grid_t(o, o->nsteps);
    b->n_active = n;
    return n;
}

/* The registry entry cannot push: there is no state to push with. */
static size_t hybrid_stateless(struct gcp_block *b, const struct gcp_field *f,
                               const struct gcp_pusher_type *p, const struct gcp_push_opts *o,
                               const struct gcp_sampler *s)
{
    (void)p, (void)s;
    return gcp_hybrid_advance(NULL, b, f, o, NULL);
}

const struct gcp_pusher_type gcp_pusher_hybrid = {
    .name = "hybrid",
    .doc = "guiding centre where adiabatic, full orbit where not, switched per particle "
           "with hysteresis (issue 14)",
    .order = 2,
    .kind = GCP_HYBRID,
    .kick = NULL,
    .advance = hybrid_stateless,
};

int gcp_hybrid_final(const struct gcp_hybrid *h, const struct gcp_block *b,
                     const struct gcp_field *f, size_t i, double x[3], double u[3], double X[3],
                     double *ppar, double *mu)
{
    const struct hlane *L = &h->lane[b->index[i]];
    const double t = b->t[i];
    if (L->mode == GCP_MODE_GC) {
        X[0] = b->x[i], X[1] = b->y[i], X[2] = b->z[i];
        *ppar = b->ppar[i];
        *mu = b->mu[i];
        const double phase = gcp_hybrid_phase(h->o.seed, L->id, L->nsw);
        if (gcp_fo_from_gc(f, t, b->q, b->m, X, *ppar, *mu, phase, x, u))
            x[0] = x[1] = x[2] = u[0] = u[1] = u[2] = NAN;
    } else {
        x[0] = b->x[i], x[1] = b->y[i], x[2] = b->z[i];
        u[0] = b->ux[i], u[1] = b->uy[i], u[2] = b->uz[i];
        if (gcp_gc_from_fo(f, t, b->q, b->m, x, u, X, ppar, mu))
            X[0] = X[1] = X[2] = *ppar = *mu = NAN;
    }
    return L->mode;
}
