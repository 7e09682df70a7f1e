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
#include "hybrid_priv.h"

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
    h->vidx = calloc(m, sizeof *h->vidx);
    if (!h->lane || !h->ord || !h->nsub || !h->vidx || gcp_block_alloc(&h->sb, m)) {
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
    free(h->vidx);
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

int gcp_hybrid_status(const struct gcp_hybrid *h) { return h->nomem ? GCP_ERR_NOMEM : 0; }

void gcp_hybrid_begin(struct gcp_hybrid *h, struct gcp_block *b, const struct gcp_field *f,
                      double t0, int64_t id0)
{
    h->nsw = 0;
    h->nomem = 0;
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

/* ---- the observer ---------------------------------------------------------- */

void gcp_hybrid_set_observer(struct gcp_hybrid *h, const struct gcp_hybrid_observer *obs)
{
    h->obs = obs ? *obs : (struct gcp_hybrid_observer){NULL, NULL};
}

/* Sampler of a sub-block push: the observer sees the sub-block with the
 * outer lanes' stable indices (s->index[j] is the outer lane). */
struct fwd_ctx {
    struct gcp_hybrid *h;
    const struct gcp_block *b; /* the outer block */
    int mode;
    int any_avg;               /* FO: some lane has an averaging window open */
    struct gcp_hybrid_fo_ctx fc;
};

static void forward(const struct gcp_block *s, double t, void *vctx)
{
    struct fwd_ctx *c = vctx;
    if (c->any_avg) gcp_hybrid_fo_sample(s, t, &c->fc);
    if (!c->h->obs.fn) return;
    struct gcp_block v = *s;
    for (size_t j = 0; j < s->n_active; j++) c->h->vidx[j] = c->b->index[s->index[j]];
    v.index = c->h->vidx;
    c->h->obs.fn(&v, t, c->mode, c->h->obs.ctx);
}

void gcp_hybrid_observe(struct gcp_hybrid *h, const struct gcp_block *b, double t)
{
    if (!h->obs.fn) return;
    for (int mode = GCP_MODE_GC; mode <= GCP_MODE_FO; mode++) {
        size_t m = 0;
        for (size_t i = 0; i < b->n_active; i++)
            if (!b->status[i] && lane_of(h, b, i)->mode == mode) h->ord[m++] = i;
        if (!m) continue;
        gather(&h->sb, b, h->ord, m);
        struct fwd_ctx c = {.h = h, .b = b, .mode = mode};
        forward(&h->sb, t, &c);
    }
}

/* ---- switches ------------------------------------------------------------ */

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
    struct fwd_ctx fw = {.h = h, .b = b, .mode = GCP_MODE_GC};
    const struct gcp_sampler smp = {1, forward, &fw};
    h->o.gc->advance(s, f, h->o.gc, &go, h->obs.fn ? &smp : NULL);
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
        gcp_hybrid_to_fo(h, b, f, i, L, tf);
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
    const double Bm = sqrt(hy_dot3(s.B, s.B));
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
        struct fwd_ctx fw = {.h = h, .b = b, .mode = GCP_MODE_FO, .any_avg = any_avg,
                             .fc = {h, b, f}};
        const struct gcp_sampler smp = {1, forward, &fw};
        /* a lane that switched exactly at t1 has nothing left to push (the
         * full-orbit step refuses dt = 0: it used to count a step of zero) */
        if (t1 > tl)
            gcp_block_advance_fo(s, f, h->o.fo, tl, (t1 - tl) / (double)ns, ns,
                                 any_avg || h->obs.fn ? &smp : NULL);
        for (size_t j = 0; j < g1 - g0; j++) {
            const size_t i = scatter(b, s, j);
            struct hlane *L = lane_of(h, b, i);
            L->t_fo += (b->status[i] ? b->t[i] : t1) - tl;
            if (b->status[i]) continue;
            L->kpos = k0 + 1;
            L->tl = t1;
            gcp_hybrid_fo_decide(h, b, f, i, L, t1, o->dt, o->tolerance);
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
