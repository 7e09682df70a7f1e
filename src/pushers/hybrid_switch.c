/* method = hybrid: the switches (contract and physics: include/gcpush/hybrid.h).
 * GC -> FO: the first-order inverse transformation at a drawn gyrophase,
 * corrected by trial gyrations until its gyro-average is the guiding
 * centre's; FO -> GC: the first-order guiding centre averaged over
 * WINDOW_GYRATIONS whole gyrations, taken back to the guiding-centre state
 * with that average, pushed to the chunk end, mu matched to the particle's
 * energy. */
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
    return c->w.K >= WINDOW_GYRATIONS;
}

/* The guiding-centre trajectory's own average over a window, the
 * counterpart of the window's average of the particle's guiding centre.
 * A gyration of a 5 MeV proton at L = 6 carries it ~1 radian along the
 * field line, so the average of X over a gyration is not X at the window's
 * mid-time: it lies inside the arc by ~ (v_par w)^2 kappa / 24, ~300 km
 * there (and p_par's average is off by its own curvature in time).  Both
 * switches therefore compare averages with averages: the GC pushed from
 * (X, p_par) at t0 over [t0, t0 + w] (WINDOW_GC_STEPS steps of the GC
 * method), trapezoid-averaged like the window.  mean: X[3], p_par; the end
 * state in Xe, pe.  Returns 0 or the GC method's status. */
#define WINDOW_GC_STEPS 16
#define WINDOW_ITER 3
struct gc_mean_ctx {
    double t, X[3], p, acc[4];
};
static int gc_mean_step(double t, const double X[3], double ppar, void *vctx)
{
    struct gc_mean_ctx *c = vctx;
    const double h = t - c->t, g[4] = {X[0], X[1], X[2], ppar}, g0[4] = {c->X[0], c->X[1], c->X[2], c->p};
    for (int k = 0; k < 4; k++) c->acc[k] += 0.5 * h * (g0[k] + g[k]);
    c->t = t, c->X[0] = X[0], c->X[1] = X[1], c->X[2] = X[2], c->p = ppar;
    return 0;
}
static int gc_window_mean(const struct gcp_hybrid *h, const struct gcp_field *f, double q, double m,
                          double t0, double w, const double X[3], double ppar, double mu,
                          double mean[4], double Xe[3], double *pe)
{
    struct gc_mean_ctx c = {.t = t0, .X = {X[0], X[1], X[2]}, .p = ppar};
    double tt = t0;
    for (int d = 0; d < 3; d++) Xe[d] = X[d];
    *pe = ppar;
    const struct gcp_push_opts po = {.dt = w / WINDOW_GC_STEPS, .nsteps = WINDOW_GC_STEPS};
    const int st = gcp_gc_push(f, h->o.gc, q, m, &po, &tt, Xe, pe, mu, gc_mean_step, &c);
    if (st || !(c.t > t0)) return st ? st : 1;
    for (int k = 0; k < 4; k++) mean[k] = c.acc[k] / (c.t - t0);
    return 0;
}

/* A trial of the particle (x, u) from time t with the FO method: the
 * lowest-order guiding centre averaged over its first WINDOW_GYRATIONS
 * whole gyrations, as window_close would (avg: X, p_par, mu), and the
 * window's length w.  Returns 0 if they were completed within
 * TRIAL_PERIODS local gyro-periods each (the gyro-period grows as the
 * particle runs into weaker field). */
#define TRIAL_PERIODS 3.0
static int trial_gyration(const struct gcp_hybrid *h, const struct gcp_field *f, double t, double q,
                          double m, double Tg, const double x[3], const double u[3], double avg[5],
                          double *w)
{
    struct trial_ctx c = {.f = f, .q = q, .m = m};
    double X0[3], p0, mu0;
    if (gcp_gc_from_fo(f, t, q, m, x, u, X0, &p0, &mu0)) return 1;
    window_open(&c.w, f, t, x, X0, p0, mu0);
    double tt = t, xx[3] = {x[0], x[1], x[2]}, uu[3] = {u[0], u[1], u[2]};
    gcp_orbit_push(f, h->o.fo, q, m, &tt, xx, uu, h->o.fo_dt * Tg,
                   (int64_t)ceil(TRIAL_PERIODS * WINDOW_GYRATIONS / h->o.fo_dt), trial_step, &c);
    if (c.w.K < WINDOW_GYRATIONS || !(c.w.tK > t)) return 1;
    *w = c.w.tK - t;
    for (int k = 0; k < 5; k++) avg[k] = c.w.IK[k] / *w;
    return 0;
}

/* GC -> FO, gyro-consistent: the inverse of the way back (window_close).
 * The particle gcp_fo_from_gc makes at phase phi has the guiding centre's
 * X, p_par, mu as its instantaneous lowest-order guiding centre, but
 * averaged over its gyrations -- what the way back and the observer see --
 * its X and p_par are off by O(eps), with the sign of the gyrophase (the
 * first-order corrections that transformation leaves out).  A trial with
 * the FO method measures the offset against the guiding centre's own
 * average over the same window (gc_window_mean), and the particle is made
 * again from the state corrected by it, mu set so that its energy is the
 * guiding centre's; repeated (fixed-point iteration: the offset depends on
 * the start state only at O(eps)) until the averaged p_par matches to
 * TRIAL_TOL of p.  A single correction, as before issue 14's measurement,
 * left O(eps^2) of p in p_par, which at small pitch angles is not small in
 * mu (d mu / mu = -2 p_par d p_par / p_perp^2: -12% +- 16% per cycle for
 * a 5 MeV proton at L = 6, 25 deg, eps = 0.1).  Returns 0 or a status; when
 * a trial fails (no whole gyrations, or no positive mu for the corrected
 * p_par) the last particle made stands. */
#define TRIAL_ITER 8
#define TRIAL_TOL 1e-4
static int fo_start(const struct gcp_hybrid *h, const struct gcp_field *f, double t, double q,
                    double m, const double X[3], double ppar, double mu, double phase, double x[3],
                    double u[3])
{
    int st = gcp_fo_from_gc(f, t, q, m, X, ppar, mu, phase, x, u);
    if (st) return st;
    struct gcp_field_sample s = {.need = GCP_NEED_B};
    if (gcp_field_eval(f, t, X, &s)) return 0;
    const double B = sqrt(hy_dot3(s.B, s.B));
    const double gam0 = gcp_gc_gamma(ppar, mu, B, m);
    const double Tg = 2.0 * GCP_PI * gam0 * m / (fabs(q) * B);
    const double mc = m * GCP_C_LIGHT;
    const double pmag = sqrt(gam0 * gam0 - 1.0) * mc;
    double A[3], phX = 0.0;
    if (f->has_E && gcp_gc_potential(f, t, X, A, NULL, &phX)) phX = 0.0;
    double Xc[3] = {X[0], X[1], X[2]}, pc = ppar;
    for (int it = 0; it < TRIAL_ITER; it++) {
        double avg[5], w;
        if (trial_gyration(h, f, t, q, m, Tg, x, u, avg, &w)) return 0;
        double Xr[4], Xe[3], pe;
        if (gc_window_mean(h, f, q, m, t, w, X, ppar, mu, Xr, Xe, &pe)) return 0;
        const double dp = Xr[3] - avg[3];
        if (fabs(dp) <= TRIAL_TOL * pmag) break;
        for (int d = 0; d < 3; d++) Xc[d] += Xr[d] - avg[d];
        pc += dp;
        /* the energy of the guiding centre, gamma m c^2 + q phi(X), at the
         * corrected centre Xc: all of the difference goes into mu, the
         * perpendicular energy (why: window_close) */
        double phc = phX;
        if (f->has_E && gcp_gc_potential(f, t, Xc, A, NULL, &phc)) phc = phX;
        struct gcp_field_sample sc = {.need = GCP_NEED_B};
        if (gcp_field_eval(f, t, Xc, &sc)) return 0;
        const double gam = gam0 + q * (phX - phc) / (mc * GCP_C_LIGHT);
        const double muc =
            0.5 * ((gam * gam - 1.0) * mc * mc - pc * pc) / (m * sqrt(hy_dot3(sc.B, sc.B)));
        double xc[3], uc[3];
        if (!(muc > 0.0) || gcp_fo_from_gc(f, t, q, m, Xc, pc, muc, phase, xc, uc)) return 0;
        for (int d = 0; d < 3; d++) x[d] = xc[d], u[d] = uc[d];
    }
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

/* FO -> GC of lane i at time t, from the completed window: the GC state at
 * the window's start whose own average over the window (gc_window_mean) is
 * the particle's, pushed to t with the GC method, then the energy matched
 * to the particle's.  Returns 1 if the lane switched. */
static int window_close(struct gcp_hybrid *h, struct gcp_block *b, const struct gcp_field *f,
                        size_t i, struct hlane *L, double t, double dt_gc, double tol)
{
    L->avg = 0;
    const double w = L->tK - L->ts;
    if (!(w > 0.0)) return 0;
    /* the GC state at the window's start whose own window average is the
     * particle's (fixed point, as fo_start's), then pushed to t */
    const double A[4] = {L->IK[0] / w, L->IK[1] / w, L->IK[2] / w, L->IK[3] / w};
    double mu = L->IK[4] / w, X[3] = {A[0], A[1], A[2]}, ppar = A[3];
    for (int it = 0; it < WINDOW_ITER; it++) {
        double M[4], Xe[3], pe;
        if (gc_window_mean(h, f, b->q, b->m, L->ts, w, X, ppar, mu, M, Xe, &pe)) return 0;
        for (int d = 0; d < 3; d++) X[d] += A[d] - M[d];
        ppar += A[3] - M[3];
    }
    double tt = L->ts;
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
    double Ap[3], phx = 0.0, phX = 0.0;
    const int pot = gcp_gc_potential(f, t, x, Ap, NULL, &phx) == 0 &&
                    gcp_gc_potential(f, t, X, Ap, NULL, &phX) == 0;
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
        if (L->K >= WINDOW_GYRATIONS) window_close(h, b, f, i, L, t, dt_gc, tol);
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
