/* gc-rk4: classical fourth-order Runge-Kutta on the relativistic guiding-
 * centre equations (kernels.h gcp_gc_rhs; Cary & Brizard 2009), fixed step,
 * over a struct-of-arrays block of lanes:
 *   k1 = F(t, y), k2 = F(t + h/2, y + h k1/2), k3 = F(t + h/2, y + h k2/2),
 *   k4 = F(t + h, y + h k3),   y += h (k1 + 2 k2 + 2 k3 + k4)/6,
 * y = (X, p_par), mu constant.  Global error O(h^4).  Not symplectic: the
 * energy and p_phi drift secularly (O(t h^4)), which gc-gl2/gc-gl4 (symplectic) avoid.
 *
 * The adiabaticity check (opts->adiabaticity_max) and B*_par > 0 are tested
 * on k1, i.e. at the start of every step: a lane that fails retires with
 * the state and time of the start of that step.  A field status or a
 * non-finite value at any stage stops the lane after the step (classify).
 *
 * How it is fast (issue 12).  Each stage is two dense loops over a chunk of
 * CHUNK lanes whose scratch stays in L1: one block field evaluation with
 * grad B (need bits fixed once per push) and one loop of the right-hand side
 * over the struct-of-arrays values (gcp_gc_rhs inlined, has_E decided once
 * per push by choosing the loop).  No indirect call per lane, no branch on
 * the stage number inside a lane loop; the status of each lane is computed
 * with arithmetic selects into an int16_t array, so that the vectoriser
 * takes 32 lanes per iteration (four independent AVX-512 vectors per double
 * operation: their chains hide the latency of the square roots and the
 * division, as the hand kernels of the limit benchmark interleave).  The
 * right-hand side is rearranged from the scalar path's (see rhs_chunk), so
 * results agree with it to round-off (tests/unit/test_gc_block.c).
 *
 * Where the time goes (1024 protons in the dipole, CPU time, ~15.8 ns a
 * particle-step): each of the 4 stages ~3.8 ns, of which the dipole's block
 * evaluation with grad B ~1.1 ns (1 sqrt, 2 divisions, 12 arrays written)
 * and the right-hand side ~2.7 ns (2 sqrt, 1 division, ~125 other
 * operations without FMA contraction); the evolve layer's begin, classify
 * and retire ~0.4 ns.  Measured and not kept: fusing the field evaluation
 * into the right-hand-side loop (no gain), CHUNK 32 .. 256 (96 and 128
 * best), FMA contraction (~3-6%, moves the last bits), 64 lanes per
 * iteration (int8_t: register spills, 50% slower).
 *
 * Where the field is one closed form (field_kernels.h), `steps` runs the
 * fused step of gc_rk4_fused.c instead (~8.3 ns in the dipole, 8192
 * lanes): the four stages over 128-lane tiles for several steps, the
 * form's field inline, the curl-free right-hand side. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/field_kernels.h"
#include "gcpush/gc.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "block_priv.h"
#include "evolve_priv.h"
#include "gc_priv.h"
#include "gc_rk4_priv.h"

/* Lanes per chunk: ~30 arrays of CHUNK doubles of stage scratch (24 kB). */
#define CHUNK 96

/* One chunk's field values and stage state. */
struct rk4_chunk {
    double X[CHUNK], Y[CHUNK], Z[CHUNK], P[CHUNK]; /* [m], [kg m/s] stage state */
    double B[3][CHUNK], G[3][3][CHUNK], E[3][CHUNK];
    double k[4][CHUNK];   /* stage derivative dX/dt [m/s], dp_par/dt [N] */
    double acc[4][CHUNK]; /* k1 + 2 k2 + 2 k3 + k4 so far */
    int32_t fs[CHUNK];    /* the field's status of this stage */
    /* Stage 1: its verdict (gcp_gc_eval's); stages 2 to 4: the step's
     * verdict so far (the first non-zero one).  Statuses are small enum
     * gcp_status values; int16_t because the narrowest type in a loop sets
     * how many lanes the vectoriser takes per iteration: with it, 32, i.e.
     * four independent AVX-512 vectors per double operation, whose
     * independent chains hide the latency of the square roots and the
     * division (int32_t: 16 lanes, 2 vectors, ~13% slower). */
    int16_t code[CHUNK];
};

/* The guiding-centre right-hand side of kernels.h gcp_gc_rhs (Cary &
 * Brizard 2009; equations in docs/DESIGN.md), rearranged so that a lane
 * needs two square roots and one division instead of two and eight (the
 * divider, not the multipliers, bounds a vectorised loop of gcp_gc_rhs):
 *   Bm = |B|,  gamma = sqrt(1 + (p_par/mc)^2 + 2 mu Bm/(m c^2)),
 *   B*_par = b.B* = Bm + (p_par/q) B.curl B / Bm^2,  so with
 *   S = B*_par Bm^2 = Bm^3 + (p_par/q) B.curl B  and  D = 1/(Bm gamma S):
 *   1/Bm = gamma S D,  1/gamma = Bm S D,  1/B*_par = Bm^2 Bm gamma D.
 * Constants (1/q, 1/(mc), 1/m) are reciprocals taken once.  The results
 * differ from gcp_gc_rhs by round-off (a few ulp per evaluation); the
 * edge cases keep their verdicts: B = 0 or B*_par = 0 give an infinite D,
 * hence NaN (NONFINITE, as gcp_gc_rhs's inf/NaN), B*_par < 0 gives S < 0
 * (NONADIABATIC).  Writes k (dX/dt, dp_par/dt) and the verdict of
 * gcp_gc_eval without the adiabaticity test: the field's status, else
 * NONFINITE for a non-finite derivative, else NONADIABATIC where B*_par <= 0
 * or |B| = 0.  withE is a constant at each call.  The constants:
 * struct gcp_rk4_consts (gc_rk4_priv.h). */

/* What to do with the derivative of a stage (constant at each call):
 * STORE it in c->k with the verdict in c->code (stage 1), or, in stages 2
 * to 4, ACCumulate w k into c->acc, merge the verdict into c->code (the
 * step's, written to the lanes' fstatus after stage 4) and, but for the
 * last stage, write the NEXT stage's state y0 + cn k into c->X .. c->P
 * (one pass instead of four). */
enum { RHS_STORE, RHS_ACC, RHS_ACC_NEXT };
struct rhs_fuse {
    double w, cn;                       /* weight of this k in acc; next stage's offset [s] */
    const double *x0, *y0, *z0, *p0;    /* the step's start state */
};

static inline __attribute__((always_inline)) void
rhs_chunk(struct rk4_chunk *restrict c, size_t m, const double *restrict mu,
          const struct gcp_rk4_consts *kc, int withE, int mode, const struct rhs_fuse *fu)
{
    const double w = fu ? fu->w : 0.0, cn = fu ? fu->cn : 0.0;
    const double *restrict x0 = fu ? fu->x0 : NULL, *restrict y0 = fu ? fu->y0 : NULL;
    const double *restrict z0 = fu ? fu->z0 : NULL, *restrict p0 = fu ? fu->p0 : NULL;
    const double iq = kc->iq, q = kc->q, imc = kc->imc, k2 = kc->k2, im = kc->im;
    for (size_t i = 0; i < m; i++) {
        const double Bx = c->B[0][i], By = c->B[1][i], Bz = c->B[2][i];
        const double G00 = c->G[0][0][i], G01 = c->G[0][1][i], G02 = c->G[0][2][i];
        const double G10 = c->G[1][0][i], G11 = c->G[1][1][i], G12 = c->G[1][2][i];
        const double G20 = c->G[2][0][i], G21 = c->G[2][1][i], G22 = c->G[2][2][i];
        const double pp = c->P[i], mui = mu[i];
        const double B2 = Bx * Bx + By * By + Bz * Bz;
        const double Bm = sqrt(B2);
        const double a = pp * imc;
        const double gamma = sqrt(1.0 + a * a + mui * Bm * k2);
        const double rq = pp * iq;
        /* curl B and B.curl B */
        const double cx = G21 - G12, cy = G02 - G20, cz = G10 - G01;
        const double S = B2 * Bm + rq * (Bx * cx + By * cy + Bz * cz);
        const double D = 1.0 / (Bm * gamma * S);
        const double iB = gamma * S * D, ig = Bm * S * D, iBs = B2 * Bm * gamma * D;
        const double bx = Bx * iB, by = By * iB, bz = Bz * iB;
        /* grad |B|_j = b_i dB_i/dx_j */
        const double gx = bx * G00 + by * G10 + bz * G20;
        const double gy = bx * G01 + by * G11 + bz * G21;
        const double gz = bx * G02 + by * G12 + bz * G22;
        const double rqiB = rq * iB;
        const double Bsx = Bx + rqiB * (cx + (by * gz - bz * gy));
        const double Bsy = By + rqiB * (cy + (bz * gx - bx * gz));
        const double Bsz = Bz + rqiB * (cz + (bx * gy - by * gx));
        const double f = mui * iq * ig;
        const double Esx = (withE ? c->E[0][i] : 0.0) - f * gx;
        const double Esy = (withE ? c->E[1][i] : 0.0) - f * gy;
        const double Esz = (withE ? c->E[2][i] : 0.0) - f * gz;
        const double vpar = pp * im * ig;
        const double dX = (vpar * Bsx + (Esy * bz - Esz * by)) * iBs;
        const double dY = (vpar * Bsy + (Esz * bx - Esx * bz)) * iBs;
        const double dZ = (vpar * Bsz + (Esx * by - Esy * bx)) * iBs;
        const double dp = q * (Esx * Bsx + Esy * Bsy + Esz * Bsz) * iBs;
        const int32_t nonfinite = !(fabs(dX + dY + dZ + dp) <= DBL_MAX);
        const int32_t bad = !(S > 0.0) | !(B2 > 0.0);
        const int32_t own = nonfinite * GCP_NONFINITE + (1 - nonfinite) * bad * GCP_NONADIABATIC;
        const int32_t fs = c->fs[i];
        const int32_t code = fs + (fs == 0) * own;
        if (mode == RHS_STORE) {
            c->k[0][i] = dX, c->k[1][i] = dY, c->k[2][i] = dZ, c->k[3][i] = dp;
            c->code[i] = (int16_t)code;
        } else {
            c->acc[0][i] = c->acc[0][i] + w * dX;
            c->acc[1][i] = c->acc[1][i] + w * dY;
            c->acc[2][i] = c->acc[2][i] + w * dZ;
            c->acc[3][i] = c->acc[3][i] + w * dp;
            const int32_t s0 = c->code[i];
            c->code[i] = (int16_t)(s0 + (s0 == 0) * code);
            if (mode == RHS_ACC_NEXT) {
                c->X[i] = x0[i] + cn * dX;
                c->Y[i] = y0[i] + cn * dY;
                c->Z[i] = z0[i] + cn * dZ;
                c->P[i] = p0[i] + cn * dp;
            }
        }
    }
}

/* Field and right-hand side at the chunk's stage state (time t); mode and
 * fu as in rhs_chunk, each combination with E or without its own loop. */
static void stage_eval(struct rk4_chunk *c, size_t m, const struct gcp_field *f, double t,
                       unsigned need, const double *mu, const struct gcp_rk4_consts *kc, int mode,
                       const struct rhs_fuse *fu)
{
    const struct gcp_field_soa o = {{c->B[0], c->B[1], c->B[2]},
                                    {{c->G[0][0], c->G[0][1], c->G[0][2]},
                                     {c->G[1][0], c->G[1][1], c->G[1][2]},
                                     {c->G[2][0], c->G[2][1], c->G[2][2]}},
                                    {c->E[0], c->E[1], c->E[2]}};
    memset(c->fs, 0, m * sizeof(int32_t));
    gcp_field_eval_soa(f, t, need, m, c->X, c->Y, c->Z, &o, c->fs);
    const int E = (need & GCP_NEED_E) != 0;
    if (mode == RHS_STORE) {
        if (E) rhs_chunk(c, m, mu, kc, 1, RHS_STORE, NULL);
        else rhs_chunk(c, m, mu, kc, 0, RHS_STORE, NULL);
    } else if (mode == RHS_ACC) {
        if (E) rhs_chunk(c, m, mu, kc, 1, RHS_ACC, fu);
        else rhs_chunk(c, m, mu, kc, 0, RHS_ACC, fu);
    } else {
        if (E) rhs_chunk(c, m, mu, kc, 1, RHS_ACC_NEXT, fu);
        else rhs_chunk(c, m, mu, kc, 0, RHS_ACC_NEXT, fu);
    }
}

/* The adiabaticity test of stage 1 (only when amax > 0): lanes that pass
 * everything else but exceed amax become NONADIABATIC. */
static void adiabaticity_chunk(struct rk4_chunk *c, size_t m, const double *mu, double q,
                               double mass, double amax)
{
    for (size_t i = 0; i < m; i++) {
        if (c->code[i]) continue;
        struct gcp_field_sample s;
        for (int a = 0; a < 3; a++) {
            s.B[a] = c->B[a][i];
            for (int b = 0; b < 3; b++) s.gradB[a][b] = c->G[a][b][i];
        }
        if (!(gcp_gc_adiabaticity_sample(&s, c->P[i], mu[i], q, mass) <= amax))
            c->code[i] = GCP_NONADIABATIC;
    }
}

/* Stage 1 over all n live lanes: k1 into k1[4][N] (k1 NULL: not kept), the verdict into
 * b->fstatus.  Returns non-zero when any lane failed. */
static int32_t stage1(struct gcp_block *b, size_t n, struct rk4_chunk *c, double *k1,
                      const struct gcp_field *f, double t, unsigned need, double amax,
                      const struct gcp_rk4_consts *kc)
{
    const size_t N = b->n;
    int32_t any = 0;
    for (size_t i0 = 0; i0 < n; i0 += CHUNK) {
        const size_t m = n - i0 < CHUNK ? n - i0 : CHUNK;
        memcpy(c->X, b->x + i0, m * sizeof(double));
        memcpy(c->Y, b->y + i0, m * sizeof(double));
        memcpy(c->Z, b->z + i0, m * sizeof(double));
        memcpy(c->P, b->ppar + i0, m * sizeof(double));
        stage_eval(c, m, f, t, need, b->mu + i0, kc, RHS_STORE, NULL);
        if (amax > 0.0) adiabaticity_chunk(c, m, b->mu + i0, b->q, b->m, amax);
        if (k1)
            for (int d = 0; d < 4; d++) memcpy(k1 + d * N + i0, c->k[d], m * sizeof(double));
        for (size_t i = 0; i < m; i++) {
            b->fstatus[i0 + i] = c->code[i];
            any |= c->code[i];
        }
    }
    return any;
}

/* Stages 2 to 4 and the update of the chunk of lanes [i0, i0 + m). */
static void stages234(struct gcp_block *b, size_t i0, size_t m, struct rk4_chunk *restrict c,
                      const double *k1, const struct gcp_field *f, double t, double h,
                      unsigned need, const struct gcp_rk4_consts *kc)
{
    const size_t N = b->n;
    /* One restrict pointer per state array, for the reads and the update:
     * two restrict pointers to one array, one of them written, is undefined. */
    double *restrict x = b->x + i0, *restrict y = b->y + i0, *restrict z = b->z + i0;
    double *restrict p = b->ppar + i0;
    const double *restrict mu = b->mu + i0;
    const double *restrict k1x = k1 + i0, *restrict k1y = k1 + N + i0;
    const double *restrict k1z = k1 + 2 * N + i0, *restrict k1p = k1 + 3 * N + i0;
    int32_t *restrict fst = b->fstatus + i0;
    const double c2 = 0.5 * h; /* k2's offset */
    for (size_t i = 0; i < m; i++) {
        c->acc[0][i] = 0.0 + 1.0 * k1x[i];
        c->acc[1][i] = 0.0 + 1.0 * k1y[i];
        c->acc[2][i] = 0.0 + 1.0 * k1z[i];
        c->acc[3][i] = 0.0 + 1.0 * k1p[i];
        c->X[i] = x[i] + c2 * k1x[i];
        c->Y[i] = y[i] + c2 * k1y[i];
        c->Z[i] = z[i] + c2 * k1z[i];
        c->P[i] = p[i] + c2 * k1p[i];
    }
    for (size_t i = 0; i < m; i++) c->code[i] = (int16_t)fst[i];
    /* k2 at t + h/2 (weight 2, next offset h/2), k3 at t + h/2 (2, h), k4 at t + h (1) */
    struct rhs_fuse fu = {2.0, 0.5 * h, x, y, z, p};
    stage_eval(c, m, f, t + 0.5 * h, need, mu, kc, RHS_ACC_NEXT, &fu);
    fu.cn = 1.0 * h;
    stage_eval(c, m, f, t + 0.5 * h, need, mu, kc, RHS_ACC_NEXT, &fu);
    fu.w = 1.0;
    stage_eval(c, m, f, t + 1.0 * h, need, mu, kc, RHS_ACC, &fu);
    const double h6 = h / 6.0;
    for (size_t i = 0; i < m; i++) {
        x[i] = x[i] + h6 * c->acc[0][i];
        y[i] = y[i] + h6 * c->acc[1][i];
        z[i] = z[i] + h6 * c->acc[2][i];
        p[i] = p[i] + h6 * c->acc[3][i];
    }
    for (size_t i = 0; i < m; i++) fst[i] = c->code[i];
}

/* gc-rk4 on the evolve layer: stage 1 is the start-of-step check (k1 and
 * the validity verdict of every lane; the layer retires stopped lanes and
 * calls it again on the rest), stages 2 to 4 and the update are the step.
 * Block scratch: k1 of every lane (4 N doubles) and one chunk. */
static size_t rk4_chunk_offset(size_t N) { return (4 * N * sizeof(double) + 63) / 64 * 64; }

static size_t rk4_work_size(size_t N) { return rk4_chunk_offset(N) + sizeof(struct rk4_chunk); }

/* The chunk after k1, on a cache line of its own (work is 64-byte aligned). */
static struct rk4_chunk *rk4_chunk_of(const struct gcp_evolve *ev, const struct gcp_block *b)
{
    return (struct rk4_chunk *)((unsigned char *)ev->work + rk4_chunk_offset(b->n));
}

/* The push's constants and, where the field is a closed form, the fused
 * step (gc_rk4_fused.c). */
struct rk4_ctx {
    struct gcp_rk4_consts kc;
    gcp_rk4_tile_fn tile;          /* NULL: the block step */
    struct gcp_rk4_tile_args targs;
    /* [4][b->n] the block's X, p_par at the start of rk4_steps: the
     * block's own E and hg scratch (pusher.h: owned by the block, which
     * no guiding-centre push reads), else save_own */
    double *save[4];
    double *save_own;
    int64_t *done;                 /* [tiles] steps each tile took */
    /* the form at each lane's state, kept from a call of the fused step to
     * the next (gcp_rk4_tile_fn cv): B in the block's b->Bx, By, Bz (the
     * statement GCP_BLOCK_B_AT_X), |B|, C_x, C_y, P in vals (B too where
     * the block has no b->Bx); have: they hold the form at the live lanes'
     * state -- cleared by anything else that moves a lane (the block step,
     * a retirement's renumbering), which also clears the block's flag */
    double *vals;
    double *cv[7];
    /* the tile carries the form (the dipole's; the uniform form's is its
     * constants) where a sampler follows the steps: without one, `steps`
     * takes every step left in one call (evolve_priv.h), so nothing would
     * read it */
    int carry;
    int have;
};

/* The carried form no longer holds (the block step moved the lanes, or
 * lanes were renumbered). */
static void rk4_drop(struct rk4_ctx *c, struct gcp_block *b)
{
    c->have = 0;
    b->flags &= ~GCP_BLOCK_B_AT_X;
}

static void rk4_relanes(const struct gcp_evolve *ev, void *vctx, struct gcp_block *b, size_t n)
{
    (void)ev, (void)n;
    rk4_drop(vctx, b);
}

static int32_t rk4_start(const struct gcp_evolve *ev, void *vctx, struct gcp_block *b, size_t n,
                         double t, int first)
{
    struct rk4_ctx *c = vctx;
    (void)first; /* k1 is needed at every step */
    rk4_drop(c, b);
    return stage1(b, n, rk4_chunk_of(ev, b), ev->work, ev->f, t, ev->need,
                  ev->o->adiabaticity_max, &c->kc);
}

static int32_t rk4_step(const struct gcp_evolve *ev, void *vctx, struct gcp_block *b, size_t n,
                        double t, double h)
{
    struct rk4_ctx *rc = vctx;
    struct rk4_chunk *c = rk4_chunk_of(ev, b);
    rk4_drop(rc, b);
    for (size_t i0 = 0; i0 < n; i0 += CHUNK)
        stages234(b, i0, n - i0 < CHUNK ? n - i0 : CHUNK, c, ev->work, ev->f, t, h, ev->need,
                  &rc->kc);
    return 0;
}

/* Up to kmax fused steps, tile by tile (gc_rk4_fused.c), in place of the
 * start-of-step check and the step (the evolve layer's `steps`): each tile
 * runs until kmax, or until a step whose start check stops one of its lanes
 * (it stops before that step), or the first step after which one stops; the
 * block takes the fewest steps any tile took, kd, and tiles that ran past
 * kd are restored from `save` and run again to kd (the same arithmetic, so
 * every lane holds exactly its lock-step state after kd steps).  kd = 0
 * (a lane stops at the start of the first step): every tile is restored
 * and the start check and block step run instead, which retire the lane. */
static int64_t rk4_steps(const struct gcp_evolve *ev, void *vctx, struct gcp_block *b, size_t n,
                         double t, double h, int64_t kmax, int32_t *stops,
                         unsigned char *lanes)
{
    struct rk4_ctx *c = vctx;
    (void)ev, (void)t, (void)h, (void)lanes;
    *stops = 1; /* the evolve layer classifies after the steps, as after one */
    if (!c->tile) return 0;
    const int carry = (c->have ? GCP_RK4_CARRY_IN : 0) | (c->carry ? GCP_RK4_CARRY_OUT : 0);
    rk4_drop(c, b);
    double *a[4] = {b->x, b->y, b->z, b->ppar};
    for (int k = 0; k < 4; k++) memcpy(c->save[k], a[k], n * sizeof(double));
    int64_t kd = kmax;
    size_t tile = 0;
    int32_t stopped = 0;
    for (size_t i0 = 0; i0 < n; i0 += GCP_RK4_TILE, tile++) {
        const size_t nt = n - i0 < GCP_RK4_TILE ? n - i0 : GCP_RK4_TILE;
        double *cv[7];
        for (int v = 0; v < 7; v++) cv[v] = c->cv[v] ? c->cv[v] + i0 : NULL;
        int32_t st;
        const int64_t k = c->tile(a[0] + i0, a[1] + i0, a[2] + i0, a[3] + i0, b->mu + i0,
                                  b->fstatus + i0, cv, carry, &st, nt, kd, &c->targs);
        c->done[tile] = k;
        stopped |= st;
        if (k < kd) kd = k;
    }
    /* every tile took kmax steps and tested every lane after the last
     * with the classification's own test (gcp_lane_stops, the verdicts
     * all 0): none stops, and the evolve layer need not classify */
    if (kd == kmax && !stopped) *stops = 0;
    if (kd < kmax) {
        tile = 0;
        for (size_t i0 = 0; i0 < n; i0 += GCP_RK4_TILE, tile++) {
            if (c->done[tile] == kd) continue;
            const size_t nt = n - i0 < GCP_RK4_TILE ? n - i0 : GCP_RK4_TILE;
            for (int k = 0; k < 4; k++) memcpy(a[k] + i0, c->save[k] + i0, nt * sizeof(double));
            /* the carried form was overwritten by the steps past kd: formed
             * again (the same numbers); kd < kmax, so none is carried out */
            double *cv[7] = {NULL};
            int32_t st;
            if (kd > 0)
                c->tile(a[0] + i0, a[1] + i0, a[2] + i0, a[3] + i0, b->mu + i0, b->fstatus + i0,
                        cv, 0, &st, nt, kd, &c->targs);
        }
    }
    /* every tile took kmax steps, the last of which wrote the form at its
     * lanes' new state (where a tile stopped short, or was run again to
     * kd, the carried form does not hold: formed again next call) */
    if (kd == kmax && c->carry) {
        c->have = 1;
        if (c->cv[0] == b->Bx) b->flags |= GCP_BLOCK_B_AT_X;
    }
    return kd;
}

/* gcp_evolve_gc_check over the block (the start-of-step check of the
 * per-lane guiding-centre methods whose step is a block solve, gc_lanes.c):
 * stage 1's evaluation, whose verdicts are gcp_gc_eval's (see rhs_chunk),
 * without keeping k1. */
int32_t gcp_gc_check_block(const struct gcp_evolve *ev, void *ctx, struct gcp_block *b, size_t n,
                           double t, int first)
{
    (void)ctx;
    if (first) return 0;
    const double mc = b->m * GCP_C_LIGHT, amax = ev->o->adiabaticity_max;
    const struct gcp_rk4_consts kc = {1.0 / b->q, b->q, 1.0 / mc, 2.0 / (mc * GCP_C_LIGHT),
                                  1.0 / b->m};
    struct rk4_chunk *c = aligned_alloc(64, (sizeof *c + 63) / 64 * 64);
    if (!c) return gcp_evolve_gc_check(ev, ctx, b, n, t, first);
    const int32_t any = stage1(b, n, c, NULL, ev->f, t, ev->need, amax, &kc);
    free(c);
    return any;
}

static const struct gcp_stepper rk4_stepper = {
    .gc = 1,
    .work_size = rk4_work_size,
    .start = rk4_start,
    .step = rk4_step,
    .steps = rk4_steps,
    .relanes = rk4_relanes,
};

static size_t gc_rk4_advance(struct gcp_block *b, const struct gcp_field *f,
                             const struct gcp_pusher_type *p, const struct gcp_push_opts *o,
                             const struct gcp_sampler *s)
{
    (void)p;
    const double mc = b->m * GCP_C_LIGHT;
    struct rk4_ctx c = {.kc = {1.0 / b->q, b->q, 1.0 / mc, 2.0 / (mc * GCP_C_LIGHT), 1.0 / b->m}};
    /* The fused step where the field is a closed form (never asked which
     * model it is: field_kernels.h); without memory for the restore, the
     * block step. */
    struct gcp_point_B form;
    if (gcp_field_point_B(f, &form) && form.has_E == (f->has_E != 0))
        c.tile = gcp_rk4_fused_tile(form.form, form.has_E);
    if (c.tile) {
        c.targs = (struct gcp_rk4_tile_args){.kc = c.kc, .h = o->dt,
                                             .rin2 = f->r_inner * f->r_inner,
                                             .rout2 = f->r_outer * f->r_outer, .zmax = f->z_max,
                                             .amax = o->adiabaticity_max, .q = b->q, .m = b->m};
        memcpy(c.targs.p, form.p, sizeof form.p);
        /* Scratch of n lanes: the save in the block's own E and hg scratch,
         * which lives as long as the block, and the carried form only
         * with a sampler.  Allocated afresh per push (4 + 7 arrays, ~0.7 MB
         * at 8192 lanes), they went back to the system at free (glibc
         * trims the heap's top) and faulted in again at the next push:
         * ~98 page faults of ~16 us on this VM, ~20% of a 122-step push. */
        const size_t N = b->n + 1;
        const int own = b->Bx && b->By && b->Bz;
        const int sampled = s && s->fn && s->every > 0;
        c.carry = form.form == GCP_POINT_B_DIPOLE && sampled;
        double *bs[4] = {b->Ex, b->Ey, b->Ez, b->hg};
        const int bsave = bs[0] && bs[1] && bs[2] && bs[3];
        c.save_own = bsave ? NULL : malloc(4 * N * sizeof(double));
        c.done = malloc((b->n / GCP_RK4_TILE + 1) * sizeof(int64_t));
        c.vals = c.carry ? malloc((own ? 4 : 7) * N * sizeof(double)) : NULL;
        if ((!bsave && !c.save_own) || !c.done || (c.carry && !c.vals)) {
            free(c.save_own), free(c.done), free(c.vals);
            c.save_own = NULL, c.done = NULL, c.vals = NULL, c.tile = NULL, c.carry = 0;
        } else {
            for (int k = 0; k < 4; k++)
                c.save[k] = bsave ? bs[k] : c.save_own + (size_t)k * N;
            if (c.carry) {
                const int v0 = own ? 3 : 0;
                for (int v = v0; v < 7; v++) c.cv[v] = c.vals + (size_t)(v - v0) * N;
                if (own) c.cv[0] = b->Bx, c.cv[1] = b->By, c.cv[2] = b->Bz;
            }
        }
    }
    b->flags &= ~GCP_BLOCK_B_AT_X;
    const size_t live = gcp_evolve_inline(b, f, o, s, &rk4_stepper, &c);
    b->flags &= ~GCP_BLOCK_B_AT_X;
    free(c.save_own);
    free(c.done);
    free(c.vals);
    return live;
}

const struct gcp_pusher_type gcp_pusher_gc_rk4 = {
    .name = "gc-rk4",
    .doc = "guiding centre, classical RK4, fixed step (Cary & Brizard 2009 equations)",
    .order = 4,
    .kind = GCP_GUIDING_CENTRE,
    .kick = NULL,
    .advance = gc_rk4_advance,
};
