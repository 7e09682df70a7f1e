/* The lifted Gauss-Legendre solve of gc-gl2 / gc-gl4 (gc_gauss.c, "Lifted
 * solver") over the live lanes of a block at once (issue 11, performance).
 *
 * Why.  Lane by lane, each Newton iteration evaluates the field at the s
 * stage points of one lane through the chart's lift_eval: a chain of
 * divisions and square roots that the CPU executes one point at a time.
 * Here the lanes' states are laid out as structs of arrays, and every
 * iteration evaluates the stage points of all lanes of a chunk of up to
 * GB_BLK through the chart's lift_eval_block (the field's block evaluation
 * and one branch-free loop the compiler vectorises); the Newton update is
 * another such loop.  A running mask (ASCOT5 style) records which lanes have
 * converged or failed: their values are computed but not taken, so the loops
 * stay branch free, and the iteration ends when no lane is iterating.  Once
 * at most half the chunk is iterating, the field is evaluated at those lanes'
 * points only (gb_lift_active): the chunk iterates as long as its slowest
 * lane (6.5 iterations a step for gc-gl2 in bench_push's scene, where a lane
 * takes 3.4 on average).  The chunk's work space lives as long as the
 * advance (gl_ctx.block_scratch), not a step.
 *
 * The map is that of gl_step_lift, operation for operation (the same
 * predictor and points, gcp_gl_lift_begin; the same DF and dF/dP_phi; the
 * same J^-1 as gcp_gl_lift_jinv, gb_jinv; the same update, convergence and
 * abandon tests; the same end, gcp_gl_lift_peek and gcp_gl_lift_end; the
 * chart's lift_ham_block, where it has one, gives lift_ham's numbers): each
 * lane's numbers are those of the per-lane solver (bench_push's gc-gl2 and
 * gc-gl4 blocks end on the same positions to the last digit printed, 17).  A lane
 * whose lifted solve fails (predictor, a chart evaluation, a singular J, an
 * update that stops contracting, 40 iterations) takes the per-lane path
 * without the lifted solver (gcp_gl_step_lane, lift = 0: the inverting
 * solver from the start of the step), exactly as gl_step_lift's failure
 * does lane by lane.  The start-of-step check (gcp_gc_check_block) and the
 * end point's mapping back (the chart's from_canon_block) are block
 * evaluations too.  The pieces that both solvers share after their Newton
 * (J^-1, the end of a step: gcp_gl_lift_jinv, gcp_gl_lift_peek,
 * gcp_gl_lift_end) are here as well.
 */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/particles.h"
#include "block_priv.h"
#include "canon_priv.h"
#include "gc_gauss_priv.h"

#define GB_BLK 64
#define GL_MAXIT 40
#define GL_TOL 1e-15
#define GL_FD 1e-7
#define GL_LIFT_FLOOR 1e-13
#define NP (GL_SMAX * GB_BLK) /* points of a chunk: stage i of lane j at i m + j */

/* a lane's state: iterating, converged, failed (the per-lane path), or
 * converged with an end point the chart cannot map (the step fails) */
enum { GB_ITER, GB_DONE, GB_FAIL, GB_UNMAPPED };

/* J^-1 from L->DF (gcp_gl_jinv_blocks): 0, or -1 where it has none. */
int gcp_gl_lift_jinv(const struct gl_ctx *C, struct gl_lane *L, double h)
{
    const int ok = C->tab->s == 2 ? gcp_gl_jinv_blocks(C->tab, 2, h, L->DF, L->Jinv)
                                  : gcp_gl_jinv_blocks(C->tab, 1, h, L->DF, L->Jinv);
    return ok ? 0 : -1;
}

/* The chart point of stage wi from the curve P_phi = P_phi(z0) on which
 * every stage point and the start lie (a fixed curve of the chart: a field
 * line in the curl-free one, smooth through the mirror points, where eta(t)
 * turns), at the stage's eta from the predicted slopes K,
 *   eta_i = eta0 + h sum_j a_ij K_j^eta.
 * The curve as a cubic in d = eta - eta_s about the last stage point of the
 * last step (p_s, eta_s, with its dp/deta t1 and d^2p/deta^2 t2, kept by
 * gcp_gl_lift_end), its cubic coefficient from the start point p0 (the end
 * of the last step, mapped to round-off; D0 = eta0 - eta_s):
 *   p(eta) = p_s + t1 d + t2 d^2/2 + (p0 - p_s - t1 D0 - t2 D0^2/2) (d/D0)^3.
 * Its error is O(d^4) and that of t2 (a difference) times d^2, where the
 * polynomial in time through the last stage points (gcp_gl_points_extrap) has
 * O(h^3) with the bounce's time scale in it: ~1e-6 of the scale against
 * ~1e-3, so that the first Newton update and, with DF computed at these
 * points, the contraction of the rest are smaller.  The cubic term is left
 * out where |d| > 4 |D0| (eta0 ~ eta_s near a mirror point: (d/D0)^3 would
 * amplify the remainder's round-off). */
static inline __attribute__((always_inline)) void
gl_points_curve_s(const struct gl_tableau *T, int s, const struct gl_lane *L, double h,
                  const double K[GL_SMAX][2], int wi, double *out)
{
    double ae = 0.0;
    for (int j = 0; j < s; j++) ae += T->a[wi][j] * K[j][0];
    const double d = L->z[1] + h * ae - L->ceta, D0 = L->z[1] - L->ceta;
    const double w = fabs(d) <= 4.0 * fabs(D0) ? d / D0 : 0.0, w3 = w * w * w;
    for (int r = 0; r < 2; r++) {
        const double ps = L->aux[s][r];
        const double rem = L->aux[0][r] - (ps + L->ct1[r] * D0 + 0.5 * L->ct2[r] * D0 * D0);
        out[r] = ps + L->ct1[r] * d + 0.5 * L->ct2[r] * d * d + rem * w3;
    }
}

/* gcp_gl_lift_begin of a lane in the steady state (slopes of nh steps and
 * the curve kept) with s and nh constants: gcp_gl_predict's and
 * gl_points_curve_s's operations in their order (the same numbers), unrolled
 * (this runs for every lane at every step). */
static inline __attribute__((always_inline)) void
gl_begin_steady(const struct gl_ctx *C, const struct gl_lane *L, double h, int s, int nh,
                double K[GL_SMAX][2], double p[GL_SMAX][2])
{
    const double(*kh[3])[2] = {L->K3, L->K2, L->K};
    for (int i = 0; i < s; i++) {
        const double *w = C->wK[nh - 2][i];
        K[i][0] = K[i][1] = 0.0;
        for (int a = 0; a < nh; a++)
            for (int j = 0; j < s; j++) {
                const double *km = kh[3 - nh + a][j], wm = w[a * s + j];
                K[i][0] += wm * km[0], K[i][1] += wm * km[1];
            }
    }
    for (int i = 0; i < s; i++) gl_points_curve_s(C->tab, s, L, h, K, i, p[i]);
}

/* The start of a lifted step: predicted slopes K and stage points p; the
 * stage points are those of the last two steps (nodes c_j - 2, c_j - 1)
 * and the start point (node 0) extrapolated to c_i.  0 or -1. */
int gcp_gl_lift_begin(const struct gl_ctx *C, const struct gcp_gc_consts *k,
                      const struct gl_lane *L, double h, double K[GL_SMAX][2],
                      double p[GL_SMAX][2])
{
    if (!(L->sc_pphi > 0.0)) return -1;
    if (C->have_wext && L->have_C) {
        if (C->tab->s == 2 && L->have_K >= 2) {
            gl_begin_steady(C, L, h, 2, 2, K, p);
            return 0;
        }
        if (C->tab->s == 1 && L->have_K >= 3) {
            gl_begin_steady(C, L, h, 1, 3, K, p);
            return 0;
        }
    }
    if (gcp_gl_predict(C, k, L, K)) return -1;
    for (int i = 0; i < C->tab->s; i++) {
        if (L->have_C) gl_points_curve_s(C->tab, C->tab->s, L, h, K, i, p[i]);
        else gcp_gl_points_extrap(C, L, i, p[i]);
    }
    return 0;
}

/* The end of a converged lifted step without changing L: the end state z
 * (gcp_gl_end_state) and the end point's guess pe for from_canon.  The guess:
 * the end point lies on the curve P_phi = P_phi(z0) through the stage points
 * (a fixed curve of the chart, a field line in the curl-free one: smooth
 * through the mirror points, where eta(t) turns), at eta1.  Taylor's
 * polynomial in eta from the last stage point (eta_s, p_s) with t1 = dp/deta
 * there and t2 = d^2p/deta^2 (its first iterate's, by the difference of DF),
 * D = eta1 - eta_s:
 *   p1 ~ p_s + t1 D + t2 D^2 / 2,
 * and for s = 1 the cubic term from the start point p0 (eta0 - eta_s = -D):
 * minus the remainder p0 - (p_s - t1 D + t2 D^2 / 2).  Its error, ~1e-6 of
 * the scale, leaves from_canon two field evaluations; the polynomial in time
 * through the stage points before (error O(h^3), ~1e-3) left it three. */
void gcp_gl_lift_peek(const struct gl_ctx *C, const struct gl_lane *L, double h,
                      const double K[GL_SMAX][2], const double pd[GL_SMAX][2],
                      const double p[GL_SMAX][2], const double t1[GL_SMAX][2],
                      const double t2[GL_SMAX][2], double z[4], double *t, double pe[2])
{
    const struct gl_tableau *T = C->tab;
    const int s = T->s;
    gcp_gl_end_state(T, L, h, K, pd, z, t);
    double ae = 0.0;
    for (int j = 0; j < s; j++) ae += T->a[s - 1][j] * K[j][0];
    const double D = z[1] - (L->z[1] + h * ae);
    for (int r = 0; r < 2; r++) {
        pe[r] = p[s - 1][r] + t1[s - 1][r] * D + 0.5 * t2[s - 1][r] * D * D;
        if (s == 1) pe[r] -= L->aux[0][r] - (p[0][r] - t1[0][r] * D + 0.5 * t2[0][r] * D * D);
    }
    if (!isfinite(pe[0] + pe[1])) pe[0] = p[s - 1][0], pe[1] = p[s - 1][1];
}

/* The end of a converged lifted step into L: its end state z, t
 * (gcp_gl_lift_peek's), the end point pe (from_canon's), the slopes K and
 * stage points p kept for the next predictor. */
void gcp_gl_lift_end(const struct gl_ctx *C, struct gl_lane *L, double h,
                     const double K[GL_SMAX][2], const double z[4], double t,
                     const double p[GL_SMAX][2], const double t1[GL_SMAX][2],
                     const double t2[GL_SMAX][2], const double pe[2])
{
    const struct gl_tableau *T = C->tab;
    const int s = T->s;
    double ae = 0.0;
    for (int j = 0; j < s; j++) ae += T->a[s - 1][j] * K[j][0];
    L->ceta = L->z[1] + h * ae;
    for (int r = 0; r < 2; r++) L->ct1[r] = t1[s - 1][r], L->ct2[r] = t2[s - 1][r];
    L->have_C = isfinite(L->ceta + L->ct1[0] + L->ct1[1] + L->ct2[0] + L->ct2[1]);
    gl_lane_accept(L, z, t, K);
    memcpy(L->pst2, &L->aux[1], sizeof L->pst2);
    for (int r = 0; r < 2; r++) {
        L->aux[0][r] = pe[r];
        for (int j = 0; j < T->s; j++) L->aux[1 + j][r] = p[j][r];
    }
    L->have_P = L->have_P ? 2 : 1;
}

/* The outputs of one block lift evaluation. */
struct gb_eval {
    double Pphi[NP], eta[NP], H[NP], dH1[NP], dH2[NP], dH3[NP], Bm[NP], dBm1[NP], dBm2[NP];
    double dp00[NP], dp01[NP], dp10[NP], dp11[NP];
    int32_t st[NP];
};

static void gb_lift(const struct gl_ctx *C, const struct gcp_gc_consts *k, size_t np,
                    const double *mu, const double *R, const double *Z, const double *Pe,
                    struct gb_eval *e)
{
    const struct gcp_canon_lift_soa o = {e->Pphi, e->eta,  e->H,    e->dH1,  e->dH2,
                                         e->dH3,  e->Bm,   e->dBm1, e->dBm2, e->dp00,
                                         e->dp01, e->dp10, e->dp11};
    C->chart.lift_eval_block(&C->chart, k, np, mu, R, Z, Pe, &o, e->st);
}

/* The chunk's state (struct of arrays; lane j of the chunk, stage i at
 * i m + j) and its scratch. */
struct gb_chunk {
    double mu[NP], R[NP], Z[NP], Pe[NP], eta[NP], K0[NP], K1[NP], pd[NP];
    double R2[NP], Z2[NP];
    double DFe0[NP], DFe1[NP]; /* the eta column of DF */
    double DFp0[NP], DFp1[NP]; /* dF/dP_phi */
    double hP[NP], h1[NP], h2[NP], h3[NP]; /* P_eta moved, dH/dz there (lift_ham) */
    double t1R[NP], t1Z[NP];   /* dp/deta at the stage points (the last sample) */
    double t2R[NP], t2Z[NP];   /* d^2 p/deta^2 there (the first iterate's) */
    double DF[GL_SMAX][2][2][GB_BLK];
    double Jinv[16][GB_BLK], z1[GB_BLK], z2[GB_BLK], z3[GB_BLK];
    double sc0[GB_BLK], sc1[GB_BLK], scp[GB_BLK], nprev[GB_BLK], nd[GB_BLK];
    double d[4][GB_BLK], e[GL_SMAX][GB_BLK];
    unsigned char state[GB_BLK];
    struct gb_eval ev, ev2;
    /* the points of the lanes still iterating, packed (gb_lift_active) */
    struct gb_eval evc;
    double cmu[NP], cR[NP], cZ[NP], cPe[NP];
    size_t pk[NP];
    /* the end points mapped back (from_canon_block) */
    double ze[4][GB_BLK], te[GB_BLK], a0[GB_BLK], a1[GB_BLK], Xe[3][GB_BLK], pe[GB_BLK];
    int32_t mapped[GB_BLK], code[GB_BLK];
    size_t idx[GB_BLK];
};

/* Lane j's slopes K, quadrature rates pd and stage points p from the chunk. */
static void gb_lane_end(const struct gb_chunk *c, size_t j, size_t m, int s,
                        double K[GL_SMAX][2], double pd[GL_SMAX][2], double p[GL_SMAX][2])
{
    for (int st = 0; st < s; st++) {
        const size_t q = (size_t)st * m + j;
        K[st][0] = c->K0[q], K[st][1] = c->K1[q];
        pd[st][0] = c->pd[q], pd[st][1] = 1.0;
        p[st][0] = c->R[q], p[st][1] = c->Z[q];
    }
}

/* J^-1 of every lane of the chunk (gcp_gl_jinv_blocks, the numbers of
 * gcp_gl_lift_jinv) in one loop over the lanes that the compiler
 * vectorises; a lane without one fails.  They stay in the chunk: a lane's
 * own Jinv is not written (every lifted step builds it anew). */
static inline __attribute__((always_inline)) void
gb_jinv_s(const struct gl_tableau *T, struct gb_chunk *c, size_t m, double h, int s)
{
    const int n = 2 * s;
    for (size_t j = 0; j < m; j++) {
        double F[GL_SMAX][2][2] = {{{0.0}}}, Ji[16];
        for (int i = 0; i < s; i++)
            for (int r = 0; r < 2; r++)
                for (int col = 0; col < 2; col++) F[i][r][col] = c->DF[i][r][col][j];
        const int ok = gcp_gl_jinv_blocks(T, s, h, F, Ji);
        for (int k = 0; k < n * n; k++) c->Jinv[k][j] = Ji[k];
        c->state[j] = !ok && c->state[j] == GB_ITER ? GB_FAIL : c->state[j];
    }
}

/* s constant in each branch: the loops over the matrix entries unroll and
 * the one over the lanes vectorises */
static void gb_jinv(const struct gl_tableau *T, struct gb_chunk *c, size_t m, double h)
{
    if (T->s == 2) gb_jinv_s(T, c, m, h, 2);
    else gb_jinv_s(T, c, m, h, 1);
}

/* One Newton iteration's update over the chunk (gl_step_lift's, lane by
 * lane the same operations): the updates d = J^-1 G, their norm nd, and the
 * points and slopes moved, for the lanes still iterating (act). */
static void gb_update(const struct gl_tableau *T, struct gb_chunk *c, size_t m, double h)
{
    const int s = T->s, n = 2 * s;
    const struct gb_eval *o = &c->ev;
    for (int i = 0; i < s; i++) {
        const size_t q0 = (size_t)i * m;
        for (size_t j = 0; j < m; j++) c->e[i][j] = c->eta[q0 + j] - o->eta[q0 + j];
    }
    double G[4][GB_BLK];
    for (int i = 0; i < s; i++) {
        const size_t q0 = (size_t)i * m;
        for (size_t j = 0; j < m; j++) {
            const size_t q = q0 + j;
            const double ep = c->z2[j] - o->Pphi[q];
            G[2 * i][j] = o->dH3[q] - c->K0[q] + c->DFe0[q] * c->e[i][j] + c->DFp0[q] * ep;
            G[2 * i + 1][j] = -o->dH1[q] - c->K1[q] + c->DFe1[q] * c->e[i][j] + c->DFp1[q] * ep;
        }
    }
    for (int r = 0; r < n; r++)
        for (size_t j = 0; j < m; j++) {
            double acc = 0.0;
            for (int col = 0; col < n; col++) acc += c->Jinv[n * r + col][j] * G[col][j];
            c->d[r][j] = acc;
        }
    for (size_t j = 0; j < m; j++) c->nd[j] = 0.0;
    for (int i = 0; i < s; i++) {
        const size_t q0 = (size_t)i * m;
        for (size_t j = 0; j < m; j++) {
            double ae = 0.0, aP = 0.0;
            for (int jj = 0; jj < s; jj++)
                ae += T->a[i][jj] * c->d[2 * jj][j], aP += T->a[i][jj] * c->d[2 * jj + 1][j];
            /* fmax(nd, x) as a select (x > nd ? x : nd: the same for every
             * x, NaN included, as nd is never NaN), which vectorises */
            const double x0 = fabs(c->e[i][j] + h * ae) / c->sc0[j];
            const double x1 = fabs(h * aP) / c->sc1[j];
            const double x2 = fabs(c->z2[j] - o->Pphi[q0 + j]) / c->scp[j];
            double nd = c->nd[j];
            nd = x0 > nd ? x0 : nd;
            nd = x1 > nd ? x1 : nd;
            nd = x2 > nd ? x2 : nd;
            c->nd[j] = nd;
        }
    }
    for (int i = 0; i < s; i++) {
        const size_t q0 = (size_t)i * m;
        for (size_t j = 0; j < m; j++) {
            const size_t q = q0 + j;
            const int act = c->state[j] == GB_ITER;
            double ae = 0.0;
            for (int jj = 0; jj < s; jj++) ae += T->a[i][jj] * c->d[2 * jj][j];
            const double dPphi = c->z2[j] - o->Pphi[q], deta = c->e[i][j] + h * ae;
            const double R = c->R[q] + (o->dp00[q] * dPphi + o->dp01[q] * deta);
            const double Z = c->Z[q] + (o->dp10[q] * dPphi + o->dp11[q] * deta);
            c->R[q] = act ? R : c->R[q];
            c->Z[q] = act ? Z : c->Z[q];
            c->pd[q] = act ? o->dH2[q] : c->pd[q];
        }
    }
    for (int i = 0; i < s; i++) {
        const size_t q0 = (size_t)i * m;
        for (size_t j = 0; j < m; j++) {
            const int act = c->state[j] == GB_ITER;
            const size_t q = q0 + j;
            c->K0[q] = act ? c->K0[q] + c->d[2 * i][j] : c->K0[q];
            c->K1[q] = act ? c->K1[q] + c->d[2 * i + 1][j] : c->K1[q];
        }
    }
}

/* The block evaluation of an iteration at the stage points of the lanes
 * still iterating only: a lane that has converged (or failed) is masked in
 * gb_update and the tests, so its points need no evaluation, and the later
 * iterations, where a few lanes are left, cost those lanes' points rather
 * than the chunk's (each lane's numbers are unchanged: the same evaluation
 * at the same point).  left: the lanes iterating; packed only where at most
 * half of the chunk is (the gather and scatter cost instructions too; in
 * bench_push's scene, instructions a step: 13% (gc-gl2) and 12% (gc-gl4)
 * fewer than without packing, and fewer than packing at 1/4). */
static void gb_lift_active(const struct gl_ctx *C, struct gb_chunk *c,
                           const struct gcp_gc_consts *k, size_t m, int s, size_t left,
                           size_t np)
{
    if (2 * left > m) {
        gb_lift(C, k, np, c->mu, c->R, c->Z, c->Pe, &c->ev);
        return;
    }
    size_t n = 0;
    for (int i = 0; i < s; i++)
        for (size_t j = 0; j < m; j++) {
            const size_t q = (size_t)i * m + j;
            c->pk[n] = q;
            n += c->state[j] == GB_ITER;
        }
    for (size_t a = 0; a < n; a++) {
        const size_t q = c->pk[a];
        c->cmu[a] = c->mu[q], c->cR[a] = c->R[q], c->cZ[a] = c->Z[q], c->cPe[a] = c->Pe[q];
    }
    gb_lift(C, k, n, c->cmu, c->cR, c->cZ, c->cPe, &c->evc);
    struct gb_eval *e = &c->ev;
    const struct gb_eval *o = &c->evc;
    for (size_t a = 0; a < n; a++) {
        const size_t q = c->pk[a];
        e->Pphi[q] = o->Pphi[a], e->eta[q] = o->eta[a], e->H[q] = o->H[a];
        e->dH1[q] = o->dH1[a], e->dH2[q] = o->dH2[a], e->dH3[q] = o->dH3[a];
        e->Bm[q] = o->Bm[a], e->dBm1[q] = o->dBm1[a], e->dBm2[q] = o->dBm2[a];
        e->dp00[q] = o->dp00[a], e->dp01[q] = o->dp01[a], e->dp10[q] = o->dp10[a];
        e->dp11[q] = o->dp11[a], e->st[q] = o->st[a];
    }
}

/* The lifted solve of the m lanes L[0 .. m) (block lanes i0 ..); the
 * lanes it cannot step take the per-lane path.  Non-zero when a lane failed. */
static int32_t gb_chunk(const struct gl_ctx *C, struct gb_chunk *c, struct gcp_block *b,
                        size_t i0, size_t m, double h, struct gl_lane *L)
{
    const struct gl_tableau *T = C->tab;
    const int s = T->s;
    struct gcp_gc_consts k = {b->q, b->m, 0.0};
    const size_t np = (size_t)s * m;
    for (size_t j = 0; j < m; j++) {
        double K[GL_SMAX][2], p[GL_SMAX][2];
        k.mu = b->mu[i0 + j];
        c->state[j] = gcp_gl_lift_begin(C, &k, &L[j], h, K, p) ? GB_FAIL : GB_ITER;
        c->z1[j] = L[j].z[1], c->z2[j] = L[j].z[2], c->z3[j] = L[j].z[3];
        c->sc0[j] = L[j].sc[0], c->sc1[j] = L[j].sc[1], c->scp[j] = L[j].sc_pphi;
        c->nprev[j] = INFINITY;
        for (int i = 0; i < s; i++) {
            const size_t q = (size_t)i * m + j;
            const int ok = c->state[j] == GB_ITER;
            c->mu[q] = k.mu;
            c->K0[q] = ok ? K[i][0] : 0.0, c->K1[q] = ok ? K[i][1] : 0.0;
            c->R[q] = ok ? p[i][0] : L[j].aux[0][0], c->Z[q] = ok ? p[i][1] : L[j].aux[0][1];
            c->pd[q] = 0.0;
        }
    }
    size_t left = m;
    for (int it = 0; it < GL_MAXIT && left > 0; it++) {
        for (int i = 0; i < s; i++) {
            const size_t q0 = (size_t)i * m;
            for (size_t j = 0; j < m; j++) {
                double eta = 0.0, P = 0.0;
                for (int jj = 0; jj < s; jj++) {
                    eta += T->a[i][jj] * c->K0[(size_t)jj * m + j];
                    P += T->a[i][jj] * c->K1[(size_t)jj * m + j];
                }
                c->eta[q0 + j] = c->z1[j] + h * eta;
                c->Pe[q0 + j] = c->z3[j] + h * P;
            }
        }
        gb_lift_active(C, c, &k, m, s, left, np);
        for (int i = 0; i < s; i++)
            for (size_t j = 0; j < m; j++)
                c->state[j] = c->state[j] == GB_ITER && c->ev.st[(size_t)i * m + j] ? GB_FAIL
                                                                                    : c->state[j];
        if (it == 0) {
            /* DF at the first iterate (gl_lift_df): the eta column from the
             * points moved by GL_FD sc0 along dp/deta */
            for (int i = 0; i < s; i++) {
                const size_t q0 = (size_t)i * m;
                for (size_t j = 0; j < m; j++) {
                    const size_t q = q0 + j;
                    const double e = GL_FD * c->sc0[j];
                    c->R2[q] = c->R[q] + c->ev.dp01[q] * e;
                    c->Z2[q] = c->Z[q] + c->ev.dp11[q] * e;
                }
            }
            gb_lift(C, &k, np, c->mu, c->R2, c->Z2, c->Pe, &c->ev2);
            /* d^2 p/deta^2 at the stages, by the same difference (the end
             * point's guess, gcp_gl_lift_end) */
            for (size_t q = 0; q < np; q++) {
                const double de = c->ev2.eta[q] - c->ev.eta[q];
                c->t2R[q] = (c->ev2.dp01[q] - c->ev.dp01[q]) / de;
                c->t2Z[q] = (c->ev2.dp11[q] - c->ev.dp11[q]) / de;
            }
            /* the P_eta column from each sample (lift_ham), then DF (gl_lift_df's
             * numbers, with dF/dP_phi: the Hessian of H is symmetric, so
             * d(dH/dP_eta)/dP_phi and d(dH/deta)/dP_phi are the derivatives of
             * the sampled dH/dP_phi along P_eta and eta) in loops over the lanes */
            if (C->chart.lift_ham_block) {
                /* the same numbers as lift_ham's, in one loop over the chunk */
                int32_t hst[NP];
                for (int i = 0; i < s; i++)
                    for (size_t j = 0; j < m; j++)
                        c->hP[(size_t)i * m + j] = c->Pe[(size_t)i * m + j] + GL_FD * c->sc1[j];
                C->chart.lift_ham_block(&C->chart, &k, np, c->mu, c->ev.Bm, c->ev.dBm1,
                                        c->ev.dBm2, c->hP, c->h1, c->h2, c->h3, hst);
                for (int i = 0; i < s; i++)
                    for (size_t j = 0; j < m; j++) {
                        const size_t q = (size_t)i * m + j;
                        const int bad = c->state[j] != GB_ITER || hst[q] || c->ev2.st[q];
                        c->state[j] = bad ? GB_FAIL : c->state[j];
                    }
            } else {
                for (int i = 0; i < s; i++)
                    for (size_t j = 0; j < m; j++) {
                        const size_t q = (size_t)i * m + j;
                        struct gcp_canon_lift o = {0};
                        o.Pphi = c->ev.Pphi[q], o.eta = c->ev.eta[q], o.Bm = c->ev.Bm[q];
                        o.dBm[1] = c->ev.dBm1[q], o.dBm[2] = c->ev.dBm2[q];
                        double H2, dH2[4] = {0.0, 0.0, 0.0, 0.0};
                        c->hP[q] = c->Pe[q] + GL_FD * c->sc1[j];
                        k.mu = b->mu[i0 + j];
                        const int bad = c->state[j] != GB_ITER ||
                                        C->chart.lift_ham(&C->chart, &k, &o, c->hP[q], &H2, dH2) ||
                                        c->ev2.st[q];
                        c->state[j] = bad ? GB_FAIL : c->state[j];
                        c->h1[q] = dH2[1], c->h2[q] = dH2[2], c->h3[q] = dH2[3];
                    }
            }
            for (int i = 0; i < s; i++)
                for (size_t j = 0; j < m; j++) {
                    const size_t q = (size_t)i * m + j;
                    const struct gb_eval *e = &c->ev, *e2 = &c->ev2;
                    const double g0 = e->dH3[q], g1 = -e->dH1[q];
                    const double dP = c->hP[q] - c->Pe[q], de = e2->eta[q] - e->eta[q];
                    const double a = (c->h3[q] - g0) / dP, bb = (-c->h1[q] - g1) / dP;
                    const double cc = (e2->dH3[q] - g0) / de, d = (-e2->dH1[q] - g1) / de;
                    const double p0 = (c->h2[q] - e->dH2[q]) / dP;
                    const double p1 = -(e2->dH2[q] - e->dH2[q]) / de;
                    const int ok = c->state[j] == GB_ITER &&
                                   fabs(a + bb + cc + d + p0 + p1) <= DBL_MAX;
                    c->state[j] = ok || c->state[j] != GB_ITER ? c->state[j] : GB_FAIL;
                    /* the failed lanes' J: I (not used) */
                    c->DF[i][0][1][j] = ok ? a : 0.0, c->DF[i][1][1][j] = ok ? bb : 0.0;
                    c->DF[i][0][0][j] = ok ? cc : 0.0, c->DF[i][1][0][j] = ok ? d : 0.0;
                    c->DFp0[q] = p0, c->DFp1[q] = p1;
                }
            gb_jinv(T, c, m, h);
            for (int i = 0; i < s; i++)
                for (size_t j = 0; j < m; j++) {
                    c->DFe0[(size_t)i * m + j] = c->DF[i][0][0][j];
                    c->DFe1[(size_t)i * m + j] = c->DF[i][1][0][j];
                }
        }
        gb_update(T, c, m, h);
        /* the converged sample's dp/deta (gcp_gl_lift_end) */
        for (int i = 0; i < s; i++)
            for (size_t j = 0; j < m; j++) {
                const size_t q = (size_t)i * m + j;
                const int act = c->state[j] == GB_ITER;
                c->t1R[q] = act ? c->ev.dp01[q] : c->t1R[q];
                c->t1Z[q] = act ? c->ev.dp11[q] : c->t1Z[q];
            }
        /* the mask: gl_step_lift's convergence and abandon tests, by selects */
        left = 0;
        for (size_t j = 0; j < m; j++) {
            const int act = c->state[j] == GB_ITER;
            const double nd = c->nd[j], th = nd / c->nprev[j];
            const int next_below = (it > 0) & (th < 1.0) & (th / (1.0 - th) * nd <= GL_TOL);
            const int stalled = (it > 0) & (nd <= GL_LIFT_FLOOR) & (th > 0.5);
            const int fail = (fabs(nd) > DBL_MAX) | !(nd == nd) | ((it > 1) & (th > 0.5) & (stalled == 0));
            const int done = (fail == 0) & ((nd <= GL_TOL) | next_below | stalled);
            c->state[j] = act ? (fail ? GB_FAIL : done ? GB_DONE : GB_ITER) : c->state[j];
            c->nprev[j] = act ? nd : c->nprev[j];
            left += (size_t)(act & (fail == 0) & (done == 0));
        }
    }
    /* the converged lanes' end states and end point guesses
     * (gcp_gl_lift_peek), packed at the front, their end points mapped back
     * together where the chart can (from_canon_block, else from_canon), and
     * the lanes mapped stepped (gcp_gl_lift_end): a lane whose end point
     * cannot be mapped keeps the start of the step (gl_step) */
    size_t nd = 0;
    for (size_t j = 0; j < m; j++) {
        if (c->state[j] != GB_DONE) continue;
        double K[GL_SMAX][2], pd[GL_SMAX][2], p[GL_SMAX][2], t1[GL_SMAX][2], t2[GL_SMAX][2];
        double z[4], pe[2];
        gb_lane_end(c, j, m, s, K, pd, p);
        for (int st = 0; st < s; st++) {
            const size_t q = (size_t)st * m + j;
            t1[st][0] = c->t1R[q], t1[st][1] = c->t1Z[q];
            t2[st][0] = c->t2R[q], t2[st][1] = c->t2Z[q];
        }
        gcp_gl_lift_peek(C, &L[j], h, K, pd, p, t1, t2, z, &c->te[nd], pe);
        for (int r = 0; r < 4; r++) c->ze[r][nd] = z[r];
        c->a0[nd] = pe[0], c->a1[nd] = pe[1];
        c->mapped[nd] = 0;
        c->idx[nd++] = j;
    }
    if (C->chart.from_canon_block) {
        const double *const zp[4] = {c->ze[0], c->ze[1], c->ze[2], c->ze[3]};
        double *const Xp[3] = {c->Xe[0], c->Xe[1], c->Xe[2]};
        C->chart.from_canon_block(&C->chart, &k, nd, zp, c->a0, c->a1, Xp, c->pe, c->mapped);
    }
    for (size_t a = 0; a < nd; a++) {
        const size_t j = c->idx[a], i = i0 + j;
        if (!c->mapped[a]) {
            double z[4] = {c->ze[0][a], c->ze[1][a], c->ze[2][a], c->ze[3][a]};
            double aux[2] = {c->a0[a], c->a1[a]}, X[3], ppar;
            const struct gcp_gc_consts kj = {b->q, b->m, b->mu[i]};
            const int r = C->chart.from_canon(&C->chart, &kj, z, aux, X, &ppar);
            if (r) {
                c->state[j] = GB_UNMAPPED;
                c->code[j] = r;
                continue;
            }
            c->a0[a] = aux[0], c->a1[a] = aux[1];
            c->Xe[0][a] = X[0], c->Xe[1][a] = X[1], c->Xe[2][a] = X[2], c->pe[a] = ppar;
        }
        double K[GL_SMAX][2], pd[GL_SMAX][2], p[GL_SMAX][2];
        gb_lane_end(c, j, m, s, K, pd, p);
        const double pe[2] = {c->a0[a], c->a1[a]};
        const double z[4] = {c->ze[0][a], c->ze[1][a], c->ze[2][a], c->ze[3][a]};
        double t1[GL_SMAX][2], t2[GL_SMAX][2];
        for (int st = 0; st < s; st++) {
            const size_t q = (size_t)st * m + j;
            t1[st][0] = c->t1R[q], t1[st][1] = c->t1Z[q];
            t2[st][0] = c->t2R[q], t2[st][1] = c->t2Z[q];
        }
        gcp_gl_lift_end(C, &L[j], h, K, z, c->te[a], p, t1, t2, pe);
        b->x[i] = c->Xe[0][a], b->y[i] = c->Xe[1][a], b->z[i] = c->Xe[2][a];
        b->ppar[i] = c->pe[a];
        b->fstatus[i] = 0;
    }
    int32_t failed = 0;
    for (size_t j = 0; j < m; j++) {
        const size_t i = i0 + j;
        int r = 0;
        if (c->state[j] == GB_DONE) continue;
        if (c->state[j] == GB_UNMAPPED) {
            /* nothing of the failed step is kept (gl_step) */
            r = c->code[j] == GCP_NONFINITE ? GCP_NONFINITE : gcp_lane_fail(b, i, GCP_FAIL_CHART);
        } else {
            /* the lifted solve failed (or did not converge): the per-lane
             * inverting solver from the start of the step */
            L[j].have_J = 0;
            r = gcp_gl_step_lane(C, b, i, h, &L[j], 0);
        }
        if (r) b->status[i] = r, failed = 1;
    }
    return failed;
}

int32_t gcp_gl_step_block(const void *ctx, struct gcp_block *b, size_t n, double t, double h,
                          unsigned char *lanes)
{
    (void)t;
    const struct gl_ctx *C = ctx;
    struct gl_lane *L = (struct gl_lane *)(void *)lanes;
    struct gb_chunk *c = C->block_scratch;
    if (!c) c = gcp_gl_block_scratch();
    int32_t failed = 0;
    if (!c) {
        for (size_t i = 0; i < n; i++) {
            const int r = gcp_gl_step_lane(C, b, i, h, &L[i], 1);
            if (r) b->status[i] = r, failed = 1;
        }
        return failed;
    }
    for (size_t i0 = 0; i0 < n; i0 += GB_BLK)
        failed |= gb_chunk(C, c, b, i0, n - i0 < GB_BLK ? n - i0 : GB_BLK, h, L + i0);
    if (c != C->block_scratch) free(c);
    return failed;
}

void *gcp_gl_block_scratch(void)
{
    return aligned_alloc(64, (sizeof(struct gb_chunk) + 63) / 64 * 64);
}
