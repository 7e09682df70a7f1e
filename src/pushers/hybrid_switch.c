/* method = hybrid: the switches (contract and physics: include/gcpush/hybrid.h).
 * GC -> FO: the first-order inverse transformation at a drawn gyrophase,
 * corrected by one trial gyration; FO -> GC: the first-order guiding centre
 * averaged over whole gyrations, pushed to the chunk end, mu matched to the
 * particle's energy. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/gc.h"
#include "gcpush/hybrid.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "hybrid_priv.h"

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
    const double B = sqrt(hy_dot3(s.B, s.B));
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
    const double muc = 0.5 * ((gam * gam - 1.0) * mc * mc - pc * pc) / (m * sqrt(hy_dot3(sc.B, sc.B)));
    double xc[3], uc[3];
    if (!(muc > 0.0) || gcp_fo_from_gc(f, t, q, m, Xc, pc, muc, phase, xc, uc)) return 0;
    for (int d = 0; d < 3; d++) x[d] = xc[d], u[d] = uc[d];
    return 0;
}

/* GC -> FO at time t from the lane's GC state. */
void gcp_hybrid_to_fo(struct gcp_hybrid *h, struct gcp_block *b, const struct gcp_field *f, size_t i,
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
    const double Bm = sqrt(hy_dot3(s.B, s.B));
    const double bh[3] = {s.B[0] / Bm, s.B[1] / Bm, s.B[2] / Bm};
    const double rho[3] = {x[0] - X[0], x[1] - X[1], x[2] - X[2]};
    /* e1 along the gyroradius now, e2 = b x e1: the phase starts at 0 */
    const double rr = hy_dot3(rho, bh);
    double e1[3] = {rho[0] - rr * bh[0], rho[1] - rr * bh[1], rho[2] - rr * bh[2]};
    const double ne = sqrt(hy_dot3(e1, e1));
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
    const double th = atan2(hy_dot3(rho, L->e2), hy_dot3(rho, L->e1));
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

void gcp_hybrid_fo_sample(const struct gcp_block *s, double t, void *vctx)
{
    struct gcp_hybrid_fo_ctx *c = vctx;
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
        const double pc2 = ppar * ppar + 2.0 * b->m * mu * sqrt(hy_dot3(s.B, s.B));
        if (!(pt2 > 0.0 && pc2 > 0.0)) return 0;
        dp2 = pt2 / pc2 - 1.0;
        /* p^2 = <p_par0^2> + <p_perp0^2> at every sample, so the average falls
         * short of p^2 by var(p_par0): the gyrophase oscillation of p_par0,
         * which is gyration seen in a tilted frame.  That share belongs to the
         * perpendicular energy: mu takes it all (scaling p_par too would bleed
         * cos^2(pitch) dp2 of mu per return, a secular pitch-angle drift). */
        mu = 0.5 * (pt2 - ppar * ppar) / (b->m * sqrt(hy_dot3(s.B, s.B)));
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
void gcp_hybrid_fo_decide(struct gcp_hybrid *h, struct gcp_block *b, const struct gcp_field *f,
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
