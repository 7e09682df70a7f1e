/* gc-gl2 / gc-gl4 in the dipole: Gauss-Legendre collocation in closed-form
 * canonical coordinates of the field line, fused over tiles of lanes
 * (issue 11: cost per step and figure of merit; issue 12: one layered
 * engine).
 *
 * Why.  In the curl-free chart (canon_curlfree.c) the canonical pair is
 * (chi, P_chi), chi the magnetic scalar potential, and every stage
 * evaluation needs the point (R, Z) with the stage's (psi, chi): a Newton
 * inversion, or the lifted solve that carries the points as unknowns
 * (gc_gauss_block.c).  In the dipole the field line psi = const is known in
 * closed form, r = L cos^2(lat), and a coordinate along it gives canonical
 * coordinates with no inversion at all.
 *
 * Coordinates.  The dipole of field_kernels.h, B = k (-3 z x + r^2 zhat)/r^5
 * (k = B0 R_E^3, signed), has flux function and scalar potential
 *   psi = R A_phi = -k R^2/r^3 = -k/L,   chi = -k z/r^3   (B = -grad chi),
 * L = r^3/R^2 the line's equatorial distance.  Along the line take
 * s = z/r = sin(lat), with T = 1 + 3 s^2, W = 1 - s^2 = cos^2(lat), g = sqrt(T):
 *   R = L W^(3/2),  Z = L W s,  |dX/ds| = L g,
 *   |B| = |k| g/(L^3 W^3),   chi = -k s/(L^2 W^2),   dchi/ds = -k T/(L^2 W^3).
 * The guiding-centre one-form in the curl-free chart (canon_curlfree.c),
 *   theta = q psi dphi + P_chi dchi,   P_chi = -p_par/|B|,
 * with chi = chi(s, L) becomes
 *   theta = P_phi dphi + P_s ds - P_s sig dL,
 *   P_phi = q psi = -q k/L,   P_s = P_chi dchi/ds = sgn(k) p_par L g,
 *   sig = (ds/dL) at fixed chi = 2 s W/(L T),
 * and with dL = (L^2/(q k)) dP_phi its two-form is
 *   d theta = dP_phi ^ dphi' + dP_s ^ ds,   phi' = phi + P_s sig L^2/(q k)
 * (the dL term is d(f) ^ dP_phi with f = P_s sig L^2/(q k), absorbed in the
 * angle): (phi', s; P_phi, P_s) are canonical.  They are those of the
 * curl-free chart after a canonical change of variables (chi -> s on each
 * line, with the angle shifted accordingly), so Gauss-Legendre collocation
 * in them is a symplectic map of the guiding centre with its two-form, and
 * P_phi, i.e. L, is exactly constant (discrete Noether; here literally: L is
 * a lane constant).  The map differs from the chi chart's by the
 * coordinates the collocation polynomial lives in (a Runge-Kutta method is
 * not invariant under non-linear changes of variables): both are order 2s,
 * both symplectic (tests/unit/test_gc_symplectic.c measures this one).
 *
 * Hamiltonian.  H = m c^2 gamma, p_par = sgn(k) P_s/(L g), mu |B| as above.
 * In the dimensionless Q = P_s/(m c L) and time tau = t c/L (a linear change
 * of the momentum and of the time unit, under which a Runge-Kutta map is
 * the same map), H/(m c^2) = gamma(s, Q) with
 *   Gamma = gamma^2 = 1 + Q^2/T + beta g/W^3,   beta = 2 mu |k|/(m c^2 L^3),
 *   ds/dtau = dgamma/dQ = Q/(T gamma),
 *   dQ/dtau = -dgamma/ds = -Gamma_s/(2 gamma),
 *   Gamma_s = -6 s Q^2/T^2 + 3 beta N/(g W^4),   N = s (3 + 5 s^2),
 *   dphi'/dtau = (L/c) dH/dP_phi = w (Q^2/T + (3/2) beta g/W^3)/gamma,
 *   w = -m c L^2/(q k)
 * (at the equator with Q = 0: dphi/dt = -3 mu |k|/(q k gamma L^2), the
 * gradient drift of an equatorially mirroring particle), and
 * phi = phi' + w 2 s W Q/T.  The stage Jacobian needs the second
 * derivatives (dip_eval); the trace of dF/d(s, Q) is 0 (Hamiltonian) and is
 * kept 0 exactly.  Per evaluation: 2 square roots (g, gamma), 2 divisions
 * (1/(T W), 1/gamma).
 *
 * Solver.  Unknowns the stage slopes K_i = F(Y_i), Y_i = y0 + h sum_j
 * a_ij K_j; full Newton with the Jacobian delta_ij I - h a_ij DF(Y_i) (2s x
 * 2s, solved by 2 x 2 blocks: 1 division for s = 1, 2 for s = 2) at every
 * iterate (quadratic: a predictor error of 1e-3 is at round-off after 3
 * iterates; a simplified Newton with DF frozen contracts only ~h^2 per
 * iterate).  phi' is a quadrature, its stage rates linearised to the last
 * update (error O(update^2), below round-off).  Converged when the update
 * of the stage values (the sum of |ds| and |dQ|/sqrt(gamma0^2 - 1) over the
 * stages) is below
 * 1e-15, or when its contraction theta predicts the next one below it,
 * theta/(1 - theta) |d| <= 1e-15 (Hairer & Wanner, Solving ODEs II, IV.8),
 * as gc_gauss.c.  Predictor: the polynomial through the last step's start,
 * its stage values and this step's start, extrapolated to the stages (the
 * lane keeps them across calls); none at a lane's first step (K = 0: the
 * first iterate is then the linearly implicit step).  DGL_MAXIT iterates
 * without convergence, or a non-finite one: the step fails (the evolve
 * layer's single step then gives the lane STEP_FAILED, NO_CONVERGENCE, with
 * the state of the start of the step); a converged step whose stage or end
 * point lies past the line's pole (|s| >= 1: a field-aligned particle with
 * a step longer than its fall to the Earth) fails likewise, CHART.
 *
 * Start-of-step check (the evolve layer's `start`, fused): finite state,
 * |s| < 1 and, with opts->adiabaticity_max, the adiabaticity of
 * gcp_gc_adiabaticity_of in closed form on the line (dip_adiabatic: the
 * same quantity to round-off, compared squared, without divisions).
 *
 * Fusion.  As gc_rk4_fused.c: tiles of DGL_TILE lanes held in tile arrays
 * for all the steps of a call (the evolve layer's `steps`), the lanes'
 * canonical state (s, Q, phi', L) kept in the evolve layer's lane storage
 * between calls (so X, p_par are written, never read back: the map applied
 * is exactly the symplectic one, and L never changes), X and p_par written
 * at the end of each call for the samplers and the classification (one
 * vectorised loop, dgl_points).  With a sampler every step (the invariant
 * observer) a call is one step: the tiles then stay as the last call left
 * them (no gather) until the lanes are renumbered, and the scalar point
 * loop and the gather, ~40% of the push, are gone (issue 12, 2048 protons
 * of tests/bench/observer.sh: push with `mu K L` 0.112 -> 0.089 s,
 * medians of 9 alternating; bit-identical).  In one tile (the engine's
 * chunks) the lane states are then written back only where something reads
 * or moves the lane storage, and the stop test on the written X lets the
 * evolve layer skip its classification (dgl_steps): 0.081 -> 0.073 s,
 * over a bare push of 0.051 s (9 alternating pairs on the loaded machine,
 * medians; bit-identical).  The one-step calls now cost about what the
 * bare push does (`events = loss` only, which samples every step but keeps
 * no stream: 0.056 s against 0.055); what is left of the observer's cost
 * is its own work a step (invariants_quiet.c) and per event. */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/field_kernels.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "block_priv.h"
#include "evolve_priv.h"
#include "gc_dipole_priv.h"
#include "gc_gauss_priv.h"
#include "gc_priv.h"


/* a lane's state between calls (the evolve layer's lane storage) */
struct dgl_lane {
    double s, Q, phip;   /* s = sin(lat) [1], Q = P_s/(m c L) [1], phi' [rad] */
    double L;            /* [m] the field line (P_phi = -q k/L), constant */
    double beta;         /* [1] 2 mu |k|/(m c^2 L^3) */
    double hh;           /* [1] the step in tau = t c/L */
    double w;            /* [1] -m c L^2/(q k): dphi'/dtau factor */
    double iqsc;         /* [1] 1/sqrt(gamma0^2 - 1): Q's scale in the Newton test */
    double hist[GL_SMAX + 1][2]; /* the last step's start and stage values (s, Q) */
    double have;         /* 1: hist is the last step's, 0: none */
};

struct dgl_ctx {
    struct dgl_args A;
    struct dgl_tile *tiles; /* [n / DGL_TILE + 1] each tile's lanes during a call */
    int64_t *done;          /* [tiles] steps each tile took */
    /* 1: every tile holds what dgl_gather would read (the last dgl_steps
     * scattered them all, and the lanes have not been renumbered since):
     * the next call runs them without the gather, which with an observer
     * every step (one step a call) cost a tenth of the push */
    int fresh;
    /* 1: the lane storage is behind the tiles (set only with fresh and one
     * tile): dgl_steps wrote the block but not the lane states back, as no
     * lane stops and nothing reads or moves the storage before the next
     * call (dgl_sync writes them where something may) */
    int dirty;
};

/* The step's end for lane i (dgl_finish formed it), and the history
 * (start, stage values) for the next predictor. */
static inline __attribute__((always_inline)) void
dgl_commit(const int S, struct dgl_tile *restrict t, size_t i)
{
    t->hist[0][0][i] = t->s[i], t->hist[0][1][i] = t->Q[i];
    for (int st = 0; st < S; st++)
        t->hist[1 + st][0][i] = t->Y[st][0][i], t->hist[1 + st][1][i] = t->Y[st][1][i];
    t->phip[i] = dgl_wrap(t->phip[i] + t->hh[i] * t->dp[i]);
    t->s[i] = t->s1[i], t->Q[i] = t->Q1[i];
    t->have[i] = 1.0;
}

/* Up to kmax steps of the tile.  mode 0 (the evolve layer's `steps`):
 * stops before a step whose start check stops a lane or whose solve fails
 * for one, and after a step after which one stops (gcp_lane_stops);
 * returns the steps taken.  mode 1 (one step, after the evolve layer's
 * start check): lanes whose solve fails keep their state and get
 * t->fail = 1 (no convergence) or 2 (off the chart); returns 1. */
static inline __attribute__((always_inline)) int64_t
dgl_tile_run(const int S, const struct dgl_args *restrict A, struct dgl_tile *restrict t, size_t nt,
             int64_t kmax, int mode)
{
    for (int64_t k = 0; k < kmax; k++) {
        if (mode == 0) {
            int32_t any = 0;
            for (size_t i = 0; i < nt; i++) any |= dip_stops(t->s[i], t->Q[i], t->L[i], t->beta[i], A);
            if (any) return k;
        }
        dgl_predict(S, A, t, nt);
        int it = 0;
        while (dgl_iterate(S, 0, A, t, nt, it) && ++it < DGL_MAXIT) {
        }
        const int32_t failed = dgl_finish(S, 0, A, t, nt);
        if (mode == 0 && failed) return k;
        int32_t stop = 0;
        for (size_t i = 0; i < nt; i++) {
            if (t->fail[i] != 0.0) continue;
            dgl_commit(S, t, i);
            const double s = t->s[i], r = t->L[i] * (1.0 - s * s);
            stop |= gcp_lane_stops(r * r, t->Q[i] * t->Q[i] + t->beta[i], r * s, A->rin2, A->rout2,
                                   A->zmax);
        }
        if (mode == 1) return 1;
        if (stop) return k + 1;
    }
    return kmax;
}

static int64_t dgl_run_s1(const struct dgl_args *A, struct dgl_tile *t, size_t nt, int64_t kmax,
                          int mode)
{
    return dgl_tile_run(1, A, t, nt, kmax, mode);
}

static int64_t dgl_run_s2(const struct dgl_args *A, struct dgl_tile *t, size_t nt, int64_t kmax,
                          int mode)
{
    return dgl_tile_run(2, A, t, nt, kmax, mode);
}

static int64_t dgl_run(const struct dgl_args *A, struct dgl_tile *t, size_t nt, int64_t kmax,
                       int mode)
{
    return A->S == 1 ? dgl_run_s1(A, t, nt, kmax, mode) : dgl_run_s2(A, t, nt, kmax, mode);
}

/* lane storage <-> tile */
static void dgl_gather(struct dgl_tile *t, const unsigned char *lanes, size_t i0, size_t nt)
{
    for (size_t i = 0; i < nt; i++) {
        const struct dgl_lane *l = (const struct dgl_lane *)(lanes + (i0 + i) * sizeof *l);
        t->s[i] = l->s, t->Q[i] = l->Q, t->phip[i] = l->phip, t->L[i] = l->L;
        t->beta[i] = l->beta, t->hh[i] = l->hh, t->w[i] = l->w, t->iqsc[i] = l->iqsc;
        t->have[i] = l->have;
        for (int n = 0; n <= GL_SMAX; n++) t->hist[n][0][i] = l->hist[n][0], t->hist[n][1][i] = l->hist[n][1];
    }
}

/* X, p_par of the tile's lanes into the block (dgl_point), one SoA loop
 * that vectorises (dgl_sincos's polynomial and quadrant select included):
 * with an observer every step (issue 12: a sample per step, so one step a
 * call) the scalar form of this loop was a third of the push.  Returns
 * whether any lane stops by gcp_block_classify's test on the written X,
 * p_par (mu: the lanes'), the field's verdicts fs being 0: where none
 * does, the evolve layer need not classify (the `steps` contract's
 * *stops = 0; the tile's own test is on (s, L), not on the written X). */
static int32_t dgl_points(const struct dgl_args *restrict A, const struct dgl_tile *restrict t,
                          double *restrict x, double *restrict y, double *restrict z,
                          double *restrict pp, const double *restrict mu, int32_t *restrict fs,
                          size_t nt)
{
    const struct dgl_args a = *A;
    const double *restrict ts = t->s, *restrict tq = t->Q, *restrict tp = t->phip;
    const double *restrict tl = t->L, *restrict tw = t->w;
    int32_t any = 0;
    for (size_t i = 0; i < nt; i++) {
        double X[3], p;
        dgl_point(&a, ts[i], tq[i], tp[i], tl[i], tw[i], X, &p);
        x[i] = X[0], y[i] = X[1], z[i] = X[2], pp[i] = p;
        fs[i] = 0;
        const double r2 = X[0] * X[0] + X[1] * X[1] + X[2] * X[2];
        any |= gcp_lane_stops(r2, p * p + mu[i], X[2], a.rin2, a.rout2, a.zmax);
    }
    return any;
}

/* The lane states of the tile back to the lane storage (all of them: the
 * `steps` form, whose tile holds the state of the steps it took). */
static void dgl_store(const struct dgl_tile *t, unsigned char *lanes, size_t i0, size_t nt)
{
    for (size_t i = 0; i < nt; i++) {
        struct dgl_lane *l = (struct dgl_lane *)(lanes + (i0 + i) * sizeof *l);
        l->s = t->s[i], l->Q = t->Q[i], l->phip = t->phip[i], l->have = t->have[i];
        for (int n = 0; n <= GL_SMAX; n++) l->hist[n][0] = t->hist[n][0][i], l->hist[n][1] = t->hist[n][1][i];
    }
}

/* The lane storage brought up to the tiles where dgl_steps left it behind
 * (c->dirty: one tile, holding the lanes): before anything reads or moves
 * it. */
static void dgl_sync(struct dgl_ctx *c, unsigned char *lanes, size_t n)
{
    if (!c->dirty) return;
    dgl_store(&c->tiles[0], lanes, 0, n);
    c->dirty = 0;
}

/* The one-step form's end (dgl_step_lanes): back to the lane storage, and
 * X, p_par of the lanes into the block (dgl_point), but for lanes whose
 * step failed, which are left as they were (nothing of a failed step is
 * kept: they keep the state of the start of the step). */
static void dgl_scatter_kept(const struct dgl_args *A, const struct dgl_tile *t,
                             unsigned char *lanes, struct gcp_block *b, size_t i0, size_t nt)
{
    for (size_t i = 0; i < nt; i++) {
        if (t->fail[i] != 0.0) continue;
        struct dgl_lane *l = (struct dgl_lane *)(lanes + (i0 + i) * sizeof *l);
        l->s = t->s[i], l->Q = t->Q[i], l->phip = t->phip[i], l->have = t->have[i];
        for (int n = 0; n <= GL_SMAX; n++) l->hist[n][0] = t->hist[n][0][i], l->hist[n][1] = t->hist[n][1][i];
        const size_t j = i0 + i;
        double X[3], pp;
        dgl_point(A, t->s[i], t->Q[i], t->phip[i], t->L[i], t->w[i], X, &pp);
        b->x[j] = X[0], b->y[j] = X[1], b->z[j] = X[2], b->ppar[j] = pp;
        b->fstatus[j] = 0;
    }
}

/* The lift of block lane i (the evolve layer's init): dgl_lift_of, with
 * the step in tau = t c/L and Q's Newton scale 1/sqrt(gamma0^2 - 1). */
static int dgl_init(const struct gcp_evolve *ev, void *vctx, const struct gcp_block *b, size_t i,
                    double t, void *vlane)
{
    (void)t;
    const struct dgl_ctx *c = vctx;
    const struct dgl_args *A = &c->A;
    struct dgl_lane *l = vlane;
    memset(l, 0, sizeof *l);
    struct dgl_lift z;
    if (dgl_lift_of(A, b->x[i], b->y[i], b->z[i], b->ppar[i], b->mu[i], &z))
        return gcp_lane_fail((struct gcp_block *)b, i, GCP_FAIL_CHART);
    l->s = z.s, l->L = z.L, l->Q = z.Q, l->beta = z.beta, l->w = z.w, l->phip = z.phip;
    l->hh = ev->o->dt * GCP_C_LIGHT / z.L;
    l->iqsc = z.p2 > 0.0 ? 1.0 / sqrt(z.p2) : 1.0;
    const double s = z.s;
    for (int n = 0; n <= GL_SMAX; n++) l->hist[n][0] = s, l->hist[n][1] = l->Q;
    l->have = 0.0;
    return 0;
}

/* Up to kmax steps, tile by tile (the evolve layer's `steps`): as
 * gc_rk4.c rk4_steps, the block takes the fewest steps kd any tile took.
 * Each tile keeps its lanes in its own tile struct and nothing is written
 * back before every tile has run, so the lane storage still holds the
 * start of the call: a tile that ran further than kd is gathered again
 * from it and run to kd (no copy of the block for the restore, which
 * multi-tile blocks only need), and kd = 0 leaves the block untouched.
 *
 * One tile (the engine's chunks of <= 64 lanes) needs no restore: when it
 * takes no step its lane states are still those of the start of the call.
 * Its states then go back to the lane storage only where something may
 * read or move the storage before the next call: kd = 0 (the start check
 * and dgl_step_lanes run), or a lane that stops by the classification's
 * test on the written X (the evolve layer classifies and retires, moving
 * the storage).  Else *stops = 0 and the storage is left behind (dirty).
 * Why: with an observer every step (one step a call) the write-back of
 * each lane's 10 doubles into the lane storage at every step was ~7% of
 * the push, the classification pass ~1.5% (perf, tests/bench/observer.sh's
 * gc-gl4 scene). */
static int64_t dgl_steps(const struct gcp_evolve *ev, void *vctx, struct gcp_block *b, size_t n,
                         double t, double h, int64_t kmax, int32_t *stops, unsigned char *lanes)
{
    (void)ev, (void)t, (void)h;
    struct dgl_ctx *c = vctx;
    *stops = 1; /* the evolve layer classifies after the steps */
    const int one = n <= DGL_TILE;
    if (!one) dgl_sync(c, lanes, n); /* (never dirty: set for one tile only) */
    int64_t kd = kmax;
    size_t tile = 0;
    for (size_t i0 = 0; i0 < n; i0 += DGL_TILE, tile++) {
        const size_t nt = n - i0 < DGL_TILE ? n - i0 : DGL_TILE;
        if (!c->fresh) dgl_gather(&c->tiles[tile], lanes, i0, nt);
        const int64_t k = dgl_run(&c->A, &c->tiles[tile], nt, kd, 0);
        c->done[tile] = k;
        if (k < kd) kd = k;
    }
    if (kd == 0) {
        /* one tile: its lane states are the call's start, which the
         * storage gets before the start check and dgl_step_lanes */
        if (one) dgl_sync(c, lanes, n);
        c->fresh = 0;
        return 0;
    }
    int32_t stop = 0;
    tile = 0;
    for (size_t i0 = 0; i0 < n; i0 += DGL_TILE, tile++) {
        const size_t nt = n - i0 < DGL_TILE ? n - i0 : DGL_TILE;
        if (c->done[tile] != kd) {
            dgl_gather(&c->tiles[tile], lanes, i0, nt);
            dgl_run(&c->A, &c->tiles[tile], nt, kd, 0);
        }
        stop |= dgl_points(&c->A, &c->tiles[tile], b->x + i0, b->y + i0, b->z + i0,
                           b->ppar + i0, b->mu + i0, b->fstatus + i0, nt);
        if (!one) dgl_store(&c->tiles[tile], lanes, i0, nt);
    }
    c->fresh = 1;
    if (one) {
        c->dirty = 1;
        if (stop) dgl_sync(c, lanes, n); /* the evolve layer classifies and retires */
        else *stops = 0;
    }
    return kd;
}

/* One step (after the evolve layer's start check, when `steps` could not
 * take one): a lane whose solve fails keeps the state of the start of the
 * step and gets STEP_FAILED (NO_CONVERGENCE, or CHART off the line). */
static int32_t dgl_step_lanes(const struct gcp_evolve *ev, void *vctx, struct gcp_block *b,
                              size_t n, double t, double h, unsigned char *lanes)
{
    (void)ev, (void)t, (void)h;
    struct dgl_ctx *c = vctx;
    struct dgl_tile *tl = &c->tiles[0];
    dgl_sync(c, lanes, n); /* (dgl_steps returned 0 and synced: a guard) */
    c->fresh = 0; /* tile 0 is its scratch */
    int32_t failed = 0;
    for (size_t i0 = 0; i0 < n; i0 += DGL_TILE) {
        const size_t nt = n - i0 < DGL_TILE ? n - i0 : DGL_TILE;
        dgl_gather(tl, lanes, i0, nt);
        dgl_run(&c->A, tl, nt, 1, 1);
        dgl_scatter_kept(&c->A, tl, lanes, b, i0, nt);
        for (size_t i = 0; i < nt; i++)
            if (tl->fail[i] != 0.0) {
                b->status[i0 + i] = gcp_lane_fail(
                    b, i0 + i, tl->fail[i] == 2.0 ? GCP_FAIL_CHART : GCP_FAIL_NO_CONVERGENCE);
                failed = 1;
            }
    }
    return failed;
}

/* The lanes were renumbered (the evolve layer moved their storage): the
 * tiles no longer hold them. */
static void dgl_relanes(const struct gcp_evolve *ev, void *vctx, struct gcp_block *b, size_t n)
{
    (void)ev, (void)b, (void)n;
    ((struct dgl_ctx *)vctx)->fresh = 0;
}

static const struct gcp_stepper dgl_stepper = {
    .gc = 1,
    .lane_size = sizeof(struct dgl_lane),
    .init = dgl_init,
    .relanes = dgl_relanes,
    .start = gcp_gc_check_block,
    .steps = dgl_steps,
    .step_lanes = dgl_step_lanes,
};

/* Lagrange basis polynomial n of the nodes x[0 .. m-1] at xi. */
static double dgl_lagrange(const double *x, int m, int n, double xi)
{
    double v = 1.0;
    for (int j = 0; j < m; j++)
        if (j != n) v *= (xi - x[j]) / (x[n] - x[j]);
    return v;
}

/* The predictor's weights (see the header): nodes -1, -1 + c_i, 0 (in
 * steps); Y_j = sum_n l_n(c_j) v_n, K = A^-1 (Y - y0)/h. */
void gcp_dgl_predictor_weights(const struct gl_tableau *tab, double wk[GL_SMAX][GL_SMAX + 2])
{
    const int S = tab->s;
    double x[GL_SMAX + 2];
    x[0] = -1.0;
    for (int i = 0; i < S; i++) x[1 + i] = -1.0 + tab->c[i];
    x[S + 1] = 0.0;
    double Ai[GL_SMAX][GL_SMAX];
    if (S == 1) {
        Ai[0][0] = 1.0 / tab->a[0][0];
    } else {
        const double d = tab->a[0][0] * tab->a[1][1] - tab->a[0][1] * tab->a[1][0];
        Ai[0][0] = tab->a[1][1] / d, Ai[0][1] = -tab->a[0][1] / d;
        Ai[1][0] = -tab->a[1][0] / d, Ai[1][1] = tab->a[0][0] / d;
    }
    for (int i = 0; i < S; i++)
        for (int nn = 0; nn < S + 2; nn++) {
            double v = 0.0;
            for (int j = 0; j < S; j++)
                v += Ai[i][j] * (dgl_lagrange(x, S + 2, nn, tab->c[j]) - (nn == S + 1 ? 1.0 : 0.0));
            wk[i][nn] = v;
        }
}

int gcp_dgl_args(struct dgl_args *A, const struct gl_tableau *tab, const struct gcp_block *b,
                 const struct gcp_field *f, const struct gcp_push_opts *o)
{
    struct gcp_point_B form;
    if (!gcp_field_point_B(f, &form) || form.form != GCP_POINT_B_DIPOLE || form.has_E || f->has_E)
        return -1;
    if (!(form.p[0] != 0.0) || !(b->q != 0.0) || !(b->m > 0.0)) return -1;
    memset(A, 0, sizeof *A);
    const int S = tab->s;
    A->S = S;
    for (int i = 0; i < S; i++) {
        A->b[i] = tab->b[i];
        for (int j = 0; j < S; j++) A->a[i][j] = tab->a[i][j];
    }
    gcp_dgl_predictor_weights(tab, A->wk);
    A->k = form.p[0];
    A->sgk = form.p[0] > 0.0 ? 1.0 : -1.0;
    A->mc = b->m * GCP_C_LIGHT;
    A->q = b->q, A->m = b->m;
    A->rin2 = f->r_inner * f->r_inner, A->rout2 = f->r_outer * f->r_outer, A->zmax = f->z_max;
    A->amax2 = o->adiabaticity_max > 0.0 ? o->adiabaticity_max * o->adiabaticity_max : 0.0;
    return 0;
}

int gcp_gl_dipole_advance(struct gcp_block *b, const struct gcp_field *f,
                          const struct gcp_push_opts *o, const struct gcp_sampler *smp,
                          const struct gl_tableau *tab, size_t *live)
{
    struct dgl_ctx c = {.fresh = 0};
    if (gcp_dgl_args(&c.A, tab, b, f, o)) return -1;
    const size_t ntiles = b->n / DGL_TILE + 1;
    c.tiles = aligned_alloc(64, ntiles * sizeof(struct dgl_tile));
    c.done = malloc(ntiles * sizeof(int64_t));
    if (!c.tiles || !c.done) {
        free(c.tiles), free(c.done);
        return -1;
    }
    *live = gcp_evolve(b, f, o, smp, &dgl_stepper, &c);
    free(c.tiles), free(c.done);
    return 0;
}

/* dip_stops for tests/unit/test_gc_dipole_line.c: the fused start check at
 * (s, Q) on line L of the dipole k (mu from beta), against
 * gcp_gc_adiabaticity_of. */
int gcp_gl_dipole_stops(double k, double q, double m, double L, double s, double Q, double beta,
                        double amax)
{
    const struct dgl_args A = {.k = k, .q = q, .m = m, .mc = m * GCP_C_LIGHT,
                               .amax2 = amax > 0.0 ? amax * amax : 0.0};
    return dip_stops(s, Q, L, beta, &A);
}
