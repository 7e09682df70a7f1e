/* gc-gl2-sundman / gc-gl4-sundman in the dipole: the Sundman-transformed
 * Gauss-Legendre step in the field line's closed-form canonical
 * coordinates, fused over tiles of lanes (issue 11: the adaptive step that
 * wins in steps should win in CPU time).
 *
 * Coordinates.  Those of gc_gauss_dipole.c (its header has the
 * derivation): on line L (P_phi = -q k/L, exactly constant), s = sin(lat),
 * Q = P_s/(m c L), the shifted angle phi', scaled time tau = t c/L, and
 * H/(m c^2) = gamma(s, Q).  The extended phase space adds (t, p_t); in the
 * same scaling (tau, pi = p_t/(m c^2)) -- a linear change of t, p_t, P_s
 * by the constants c/L, 1/(m c^2), 1/(m c L), under which dP_s ^ ds +
 * dp_t ^ dt = m c L (dQ ^ ds + dpi ^ dtau) and a Runge-Kutta map is the
 * same map.
 *
 * Transformation (Hairer, Lubich & Wanner, Geometric Numerical Integration,
 * sec. VIII.2; Hairer 1997, Appl. Numer. Math. 25 219): in the fictitious
 * time sig (dt = w dsig)
 *   K = w(s) (gamma(s, Q) + pi),   pi = -gamma(z0)  (K = 0 on the orbit),
 *   w = (B_ref/|B|)^(1/4) = (c04 W^3/g)^(1/4),  c04 = g0/W0^3,
 * the w of gc_sundman.c (why 1/4 there: the step follows the local error
 * of the bounce motion; |B| = |k| g/(L^3 W^3) on the line, and L is a
 * constant of every lane, so w is the same function of time along every
 * orbit as in the chi chart: w = 1 at the start, ~|B|^-1/4).  Taking w
 * as a function of s alone (c04 a constant of the lane, not |B|(s, L) with
 * L = L(P_phi)) keeps dK/dP_phi = w dH/dP_phi: phi' stays a quadrature.
 * K is canonical in (phi', s, tau; P_phi, Q, pi), so Gauss-Legendre at a
 * fixed step in sig is symplectic in the extended phase space whatever w
 * (tests/unit/test_gc_sundman.c measures it).  The rates (sdl_eval in
 * gc_dipole_priv.h) and the Jacobian are closed form; per stage
 * evaluation 2 square roots more than the fixed step's (w), no division.
 * pi is a constant of the lane (K does not depend on tau), t a quadrature
 * of w at the stages, as phi' of w P.
 *
 * Output times: landing beside the grid.  A lane's s-steps form one fixed
 * sequence (the grid): the lane steps on it while the next step is
 * predicted to end before the output time t1 (t + 1.5 ds w(s) < t1) and
 * does end before it (a step past t1 is not taken, and is taken again, to
 * the same bits, in the next slice); the state at t1 is then one more
 * Gauss-Legendre step from the last grid point, of size ds' with
 * t(ds') = t1 to 4 ulp by Newton's iteration with dt/ds' = w(s) at the
 * step's end (the exact flow's rate; gc_sundman.c's secant through the
 * origin converges linearly, too slowly over a whole grid step), written
 * to X, p_par -- and not kept: the lane goes on from its grid point.  The
 * landing is never longer than one grid step (ds' <= ds): where w falls
 * along it (toward a mirror point) the predicted t + 1.5 ds w(s) can hide
 * 2-3 grid steps of s, and GL4's energy error at the end of a step of
 * ds' grows as ds'^4 -- 12x the grid's band at the 82-deg mirror point at
 * ds = T_b/40 (tests/unit/test_gc_sundman_line.c landed_outputs_...).  So
 * a Newton iterate past ds, unless the grid step is already known to end
 * past t1, turns the landing back into a grid step (the same bits: the
 * grid step's predictor reads only its grid point and history), and the
 * lane lands from the next grid point; every iterate, the first
 * included, is held to <= ds.  So the
 * map of the lane is exactly the symplectic s-step map however often it
 * is sampled (gc_sundman.c's landing step, kept, is not symplectic), and
 * the numbers do not depend on how the push is sliced (the landing adds
 * one step to b->steps per slice).  The landing step starts its Newton
 * from K = 0; grid steps from the predictor of gc_gauss_dipole.c (the
 * last grid step's stages).
 *
 * Statuses: after every grid step the fused test of gc_gauss_dipole.c
 * (|s| < 1, finite, the adiabaticity: dip_stops; the field's bounds:
 * gcp_lane_stops) picks the lanes that may stop, and for those the
 * verdict is gc_sundman.c's (gcp_gc_eval at the point, then the domain):
 * the lane stops there with that status and its time.  A step whose
 * Newton fails or whose stages leave the line's chart (|s| >= 1): the
 * lane fails (NO_CONVERGENCE, CHART) with the state and time of its last
 * grid point.
 *
 * Fusion.  The lanes run tile by tile (DGL_TILE lanes), every lane of a
 * tile on its own clock: each round takes one Newton solve for every
 * lane that still runs (a grid step, or a secant iterate of its landing),
 * lanes that are done idle (the tile ends when all are done). */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "block_priv.h"
#include "evolve_priv.h"
#include "gc_dipole_priv.h"
#include "gc_gauss_priv.h"
#include "gc_priv.h"
#include "gc_sundman_priv.h"

#define SDL_LAND_MAXIT 12

/* a lane's state between slices (the adaptive layer's lane storage) */
struct sdl_lane {
    double s, Q, phip, L, beta; /* as struct dgl_lane (gc_gauss_dipole.c) */
    double hg;                  /* [1] the grid step in c sig/L */
    double w, iqsc;             /* dphi'/dtau factor, Q's Newton scale */
    double c04, pi;             /* w^4 = c04 W^3/g; pi = -gamma0 */
    double t;                   /* [s] time of the grid point */
    double cL;                  /* [1/s] c/L */
    double hist[GL_SMAX + 1][2];
    double have;
};

struct sdl_tile {
    struct dgl_tile g;
    double t[DGL_TILE], cL[DGL_TILE], hg[DGL_TILE], hv[DGL_TILE]; /* hv: the lane's `have` */
    double mode[DGL_TILE];      /* 0 grid steps, 1 landing, 2 done */
    double gs[DGL_TILE];        /* 1: a grid step is known to end before t1 (take it) */
    double past[DGL_TILE];      /* 1: the next grid step is known to end past t1 */
    double dsp[DGL_TILE];       /* [s] this round's step in sig */
    double dsk[DGL_TILE], span[DGL_TILE], nl[DGL_TILE]; /* landing: step, t1 - t, iterates */
    double os[DGL_TILE], oQ[DGL_TILE], op[DGL_TILE], ot[DGL_TILE]; /* the state written out */
    int32_t status[DGL_TILE];
    int64_t steps[DGL_TILE];
};

struct sdl_ctx {
    struct dgl_args A;
    double ds;                 /* [s] the step in sig (the run's dt) */
    struct sdl_tile *tile;
};

/* w = (c04 W^3/g)^(1/4) at s (sdl_eval's, by the same operations) */
static inline double sdl_w(double s, double c04)
{
    const double s2 = s * s;
    const double T = 1.0 + 3.0 * s2, W = 1.0 - s2;
    const double iTW = 1.0 / (T * W);
    const double g = sqrt(T), ig = g * (W * iTW);
    return sqrt(sqrt(c04 * (W * W * W) * ig));
}

/* lane storage <-> tile */
static void sdl_gather(struct sdl_tile *t, const unsigned char *lanes, size_t nt)
{
    struct dgl_tile *g = &t->g;
    for (size_t i = 0; i < nt; i++) {
        const struct sdl_lane *l = (const struct sdl_lane *)(lanes + i * sizeof *l);
        g->s[i] = l->s, g->Q[i] = l->Q, g->phip[i] = l->phip, g->L[i] = l->L;
        g->beta[i] = l->beta, g->w[i] = l->w, g->iqsc[i] = l->iqsc;
        g->c04[i] = l->c04, g->pi[i] = l->pi;
        for (int n = 0; n <= GL_SMAX; n++) g->hist[n][0][i] = l->hist[n][0], g->hist[n][1][i] = l->hist[n][1];
        t->t[i] = l->t, t->cL[i] = l->cL, t->hg[i] = l->hg, t->hv[i] = l->have;
        t->mode[i] = 0.0, t->status[i] = 0, t->steps[i] = 0;
        t->gs[i] = 0.0, t->past[i] = 0.0;
    }
}

static void sdl_scatter(const struct sdl_ctx *c, const struct sdl_tile *t, unsigned char *lanes,
                        struct gcp_block *b, size_t i0, size_t nt)
{
    const struct dgl_tile *g = &t->g;
    for (size_t i = 0; i < nt; i++) {
        struct sdl_lane *l = (struct sdl_lane *)(lanes + i * sizeof *l);
        l->s = g->s[i], l->Q = g->Q[i], l->phip = g->phip[i], l->t = t->t[i], l->have = t->hv[i];
        for (int n = 0; n <= GL_SMAX; n++) l->hist[n][0] = g->hist[n][0][i], l->hist[n][1] = g->hist[n][1][i];
        const size_t j = i0 + i;
        double X[3], pp;
        dgl_point(&c->A, t->os[i], t->oQ[i], t->op[i], g->L[i], g->w[i], X, &pp);
        b->x[j] = X[0], b->y[j] = X[1], b->z[j] = X[2], b->ppar[j] = pp;
        b->t[j] = t->ot[i];
        b->steps[j] += t->steps[i];
        b->status[j] = t->status[i];
    }
}

/* Lane i is done: state (s, Q, phi') at time tt written out, status st. */
static inline void sdl_done(struct sdl_tile *t, size_t i, double s, double Q, double pp, double tt,
                            int32_t st)
{
    t->mode[i] = 2.0, t->status[i] = st;
    t->os[i] = s, t->oQ[i] = Q, t->op[i] = pp, t->ot[i] = tt;
}

/* The verdict at a grid point the fused test picked (gc_sundman.c
 * sd_after's): gcp_gc_eval with the adiabaticity, then the domain. */
static int32_t sdl_verdict(const struct gcp_evolve *ev, const struct sdl_ctx *c,
                           const struct gcp_block *b, size_t j, const struct sdl_tile *t, size_t i)
{
    double X[3], pp, dX[3], dp;
    const struct dgl_tile *g = &t->g;
    dgl_point(&c->A, g->s[i], g->Q[i], g->phip[i], g->L[i], g->w[i], X, &pp);
    const int st = gcp_gc_eval(ev->f, t->t[i], b->q, b->m, X, pp, b->mu[j], ev->o->adiabaticity_max,
                               dX, &dp);
    return st ? st : gcp_point_domain_status(ev->f, X);
}

/* The tile's lanes to t1 (see the header). */
static inline __attribute__((always_inline)) void
sdl_tile_run(const int S, const struct gcp_evolve *ev, const struct sdl_ctx *c, struct gcp_block *b,
             size_t i0, struct sdl_tile *restrict t, size_t nt, double t1)
{
    const struct dgl_args *A = &c->A;
    struct dgl_tile *g = &t->g;
    const double ds = c->ds;
    for (;;) {
        int any = 0;
        for (size_t i = 0; i < nt; i++) {
            if (t->mode[i] == 0.0 && t->gs[i] == 0.0) {
                const double w0 = sdl_w(g->s[i], g->c04[i]);
                if (t->t[i] + 1.5 * ds * w0 >= t1)
                    t->mode[i] = 1.0, t->span[i] = t1 - t->t[i], t->dsk[i] = fmin(t->span[i] / w0, ds),
                    t->nl[i] = 0.0, t->past[i] = 0.0;
            }
            if (t->mode[i] == 1.0 && t->span[i] == 0.0) /* on t1 already */
                sdl_done(t, i, g->s[i], g->Q[i], g->phip[i], t1, 0);
            const int land = t->mode[i] == 1.0;
            t->dsp[i] = land ? t->dsk[i] : ds;
            g->hh[i] = land ? t->dsk[i] * t->cL[i] : t->hg[i];
            g->have[i] = t->mode[i] == 0.0 ? t->hv[i] : 0.0;
            any |= t->mode[i] != 2.0;
        }
        if (!any) return;
        dgl_predict(S, A, g, nt);
        for (size_t i = 0; i < nt; i++) g->act[i] = t->mode[i] != 2.0; /* done lanes idle */
        int it = 0;
        while (dgl_iterate(S, 1, A, g, nt, it) && ++it < DGL_MAXIT) {
        }
        dgl_finish(S, 1, A, g, nt);
        for (size_t i = 0; i < nt; i++) {
            if (t->mode[i] == 2.0) continue;
            const double tn = t->t[i] + t->dsp[i] * g->dt[i];
            if (g->fail[i] != 0.0) {
                const int why = g->fail[i] == 2.0 ? GCP_FAIL_CHART : GCP_FAIL_NO_CONVERGENCE;
                sdl_done(t, i, g->s[i], g->Q[i], g->phip[i], t->t[i], gcp_lane_fail(b, i0 + i, why));
            } else if (t->mode[i] == 0.0) {
                if (tn > t1) {
                    /* past t1: not taken (the next slice takes it again) */
                    t->mode[i] = 1.0, t->span[i] = t1 - t->t[i], t->nl[i] = 0.0;
                    t->gs[i] = 0.0, t->past[i] = 1.0;
                    t->dsk[i] = ds * (t->span[i] / (tn - t->t[i]));
                    continue;
                }
                g->hist[0][0][i] = g->s[i], g->hist[0][1][i] = g->Q[i];
                for (int st = 0; st < S; st++)
                    g->hist[1 + st][0][i] = g->Y[st][0][i], g->hist[1 + st][1][i] = g->Y[st][1][i];
                g->phip[i] = dgl_wrap(g->phip[i] + g->hh[i] * g->dp[i]);
                g->s[i] = g->s1[i], g->Q[i] = g->Q1[i], t->t[i] = tn, t->hv[i] = 1.0;
                t->gs[i] = 0.0;
                t->steps[i]++;
                const double s = g->s[i], r = g->L[i] * (1.0 - s * s);
                const int32_t cand =
                    dip_stops(s, g->Q[i], g->L[i], g->beta[i], A) |
                    gcp_lane_stops(r * r, g->Q[i] * g->Q[i] + g->beta[i], r * s, A->rin2, A->rout2,
                                   A->zmax);
                if (cand) {
                    const int32_t st = sdl_verdict(ev, c, b, i0 + i, t, i);
                    if (st) sdl_done(t, i, g->s[i], g->Q[i], g->phip[i], t->t[i], st);
                }
            } else {
                /* landing: Newton on t(ds') = t1 with dt/ds' = w at the end */
                const double got = tn - t->t[i];
                if (fabs(tn - t1) <= 4.0 * DBL_EPSILON * fmax(fabs(t1), fabs(t->t[i])) + DBL_MIN) {
                    t->steps[i]++;
                    sdl_done(t, i, g->s1[i], g->Q1[i], dgl_wrap(g->phip[i] + g->hh[i] * g->dp[i]),
                             t1, 0);
                } else if (!(got * t->span[i] > 0.0) || ++t->nl[i] >= SDL_LAND_MAXIT) {
                    sdl_done(t, i, g->s[i], g->Q[i], g->phip[i], t->t[i],
                             gcp_lane_fail(b, i0 + i, GCP_FAIL_NO_CONVERGENCE));
                } else {
                    const double nd = t->dsk[i] + (t1 - tn) / sdl_w(g->s1[i], g->c04[i]);
                    if (nd > ds && t->past[i] == 0.0)
                        /* t1 lies more than a grid step ahead: take the grid step */
                        t->mode[i] = 0.0, t->gs[i] = 1.0;
                    else
                        t->dsk[i] = fmin(nd, ds);
                }
            }
        }
    }
}

/* The adaptive layer's run_lanes: the n lanes to t1, tile by tile. */
static void sdl_run_lanes(const struct gcp_evolve *ev, void *vctx, struct gcp_block *b, size_t n,
                          double t1, unsigned char *lanes)
{
    struct sdl_ctx *c = vctx;
    for (size_t i0 = 0; i0 < n; i0 += DGL_TILE) {
        const size_t nt = n - i0 < DGL_TILE ? n - i0 : DGL_TILE;
        unsigned char *l0 = lanes + i0 * sizeof(struct sdl_lane);
        sdl_gather(c->tile, l0, nt);
        if (c->A.S == 1)
            sdl_tile_run(1, ev, c, b, i0, c->tile, nt, t1);
        else
            sdl_tile_run(2, ev, c, b, i0, c->tile, nt, t1);
        sdl_scatter(c, c->tile, l0, b, i0, nt);
    }
}

/* Lane i at t0 in the extended phase space (the lift of gc_gauss_dipole.c
 * dgl_init, with W = 1 - s^2 as dgl_point forms it): t = t0, pi =
 * -gamma(z0), c04 = g0/W0^3 (w = 1 at the start). */
static int sdl_init(const struct gcp_evolve *ev, void *vctx, const struct gcp_block *b, size_t i,
                    void *vlane)
{
    const struct sdl_ctx *c = vctx;
    const struct dgl_args *A = &c->A;
    struct sdl_lane *l = vlane;
    memset(l, 0, sizeof *l);
    struct dgl_lift z;
    if (dgl_lift_of(A, b->x[i], b->y[i], b->z[i], b->ppar[i], b->mu[i], &z))
        return gcp_lane_fail((struct gcp_block *)b, i, GCP_FAIL_CHART);
    l->s = z.s, l->L = z.L, l->Q = z.Q, l->beta = z.beta, l->w = z.w, l->phip = z.phip;
    l->cL = GCP_C_LIGHT / z.L;
    l->hg = c->ds * l->cL;
    l->iqsc = z.p2 > 0.0 ? 1.0 / sqrt(z.p2) : 1.0;
    l->pi = -sqrt(1.0 + z.p2);
    l->c04 = z.gW3;
    const double s = z.s;
    l->t = ev->o->t0;
    for (int n = 0; n <= GL_SMAX; n++) l->hist[n][0] = s, l->hist[n][1] = l->Q;
    l->have = 0.0;
    return 0;
}

int gcp_sundman_dipole_advance(struct gcp_block *b, const struct gcp_field *f,
                               const struct gcp_push_opts *o, const struct gcp_sampler *smp,
                               const struct gl_tableau *tab, size_t *live)
{
    struct sdl_ctx c = {.ds = o->dt};
    if (gcp_dgl_args(&c.A, tab, b, f, o)) return -1;
    c.tile = aligned_alloc(64, sizeof(struct sdl_tile));
    if (!c.tile) return -1;
    const struct gcp_adaptive_stepper st = {
        .gc = 1,
        .lane_size = sizeof(struct sdl_lane),
        .type = NULL,
        .init = sdl_init,
        .run_lanes = sdl_run_lanes,
    };
    *live = gcp_evolve_adaptive(b, f, o, smp, &st, &c);
    free(c.tile);
    return 0;
}

/* n s-steps of the extended map on y = (phi', s, t, P_phi, P_s, p_t)
 * (tests/unit/test_gc_sundman_line.c): the tile's solve for one lane, the
 * first from K = 0, the next from the predictor of the last step's stages
 * (the pusher's grid steps), phi' not wrapped; fn(y, H, ctx) after each
 * step, H = m c^2 gamma at its end.  plain: steps in t of size w(s0) ds
 * with w = 1 in the flow (p_t kept).  0, or -1 when a solve fails (y is
 * then the last step's end). */
int gcp_sundman_dipole_run(double k, double q, double m, double mu, double c04, int S, double ds,
                           int plain, double y[6], int64_t n,
                           void (*fn)(const double y[6], double H, void *ctx), void *ctx)
{
    const struct gl_tableau *tab = S == 1 ? &gcp_gl2_tableau : &gcp_gl4_tableau;
    struct dgl_args A = {.S = S, .k = k, .sgk = k > 0.0 ? 1.0 : -1.0, .mc = m * GCP_C_LIGHT,
                         .q = q, .m = m};
    gcp_dgl_predictor_weights(tab, A.wk);
    for (int i = 0; i < S; i++) {
        A.b[i] = tab->b[i];
        for (int j = 0; j < S; j++) A.a[i][j] = tab->a[i][j];
    }
    struct dgl_tile *g = aligned_alloc(64, sizeof *g);
    if (!g) return -1;
    const double c2 = GCP_C_LIGHT * GCP_C_LIGHT, L = -q * k / y[3], s = y[1];
    const double T = 1.0 + 3.0 * s * s, W = 1.0 - s * s, gg = sqrt(T);
    g->s[0] = s, g->Q[0] = y[4] / (A.mc * L), g->phip[0] = y[0], g->L[0] = L;
    g->beta[0] = 2.0 * mu * fabs(k) / (m * c2 * L * L * L);
    g->w[0] = -A.mc * L * L / (q * k);
    g->c04[0] = c04, g->pi[0] = y[5] / (m * c2);
    const double p2 = g->Q[0] * g->Q[0] / T + g->beta[0] * gg / (W * W * W);
    g->iqsc[0] = p2 > 0.0 ? 1.0 / sqrt(p2) : 1.0;
    g->have[0] = 0.0;
    int failed = 0;
    for (int64_t step = 0; step < n && !failed; step++) {
        const double dsp = plain ? sdl_w(g->s[0], c04) * ds : ds;
        g->hh[0] = dsp * GCP_C_LIGHT / L;
        dgl_predict(S, &A, g, 1);
        int it = 0;
        if (plain)
            while (dgl_iterate(S, 2, &A, g, 1, it) && ++it < DGL_MAXIT) {
            }
        else
            while (dgl_iterate(S, 1, &A, g, 1, it) && ++it < DGL_MAXIT) {
            }
        failed = dgl_finish(S, 1, &A, g, 1);
        if (failed) break;
        /* the history for the next predictor (sdl_tile_run's), then the end */
        g->hist[0][0][0] = g->s[0], g->hist[0][1][0] = g->Q[0];
        for (int st = 0; st < S; st++)
            g->hist[1 + st][0][0] = g->Y[st][0][0], g->hist[1 + st][1][0] = g->Y[st][1][0];
        g->have[0] = 1.0;
        g->phip[0] += g->hh[0] * g->dp[0];
        g->s[0] = g->s1[0], g->Q[0] = g->Q1[0];
        y[0] = g->phip[0];
        y[1] = g->s1[0];
        y[2] += dsp * g->dt[0];
        y[4] = g->Q1[0] * A.mc * L;
        if (fn) {
            const struct dgl_ev e = dip_eval(g->s1[0], g->Q1[0], g->beta[0], g->w[0]);
            fn(y, m * c2 * e.gam, ctx);
        }
    }
    free(g);
    return failed ? -1 : 0;
}

static void sdl_keep_H(const double y[6], double H, void *ctx)
{
    (void)y;
    *(double *)ctx = H;
}

/* One s-step of gcp_sundman_dipole_run, from K = 0; *H = m c^2 gamma at
 * the end. */
int gcp_sundman_dipole_step(double k, double q, double m, double mu, double c04, int S, double ds,
                            int plain, double y[6], double *H)
{
    return gcp_sundman_dipole_run(k, q, m, mu, c04, S, ds, plain, y, 1, sdl_keep_H, H);
}
