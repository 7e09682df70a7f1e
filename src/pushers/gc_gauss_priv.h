/* Private to gc_gauss*.c and gc_sundman*.c: the Gauss-Legendre collocation
 * core of the symplectic guiding-centre methods (issue 11); the solvers in
 * gc_gauss.c, the methods gc-gl2 / gc-gl4 around them in gc_gauss_pusher.c. */
#ifndef GCPUSH_GC_GAUSS_PRIV_H
#define GCPUSH_GC_GAUSS_PRIV_H

#include <float.h>
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "gcpush/pusher.h"
#include "canon_priv.h"

#define GL_SMAX 2

struct gl_tableau {
    int s;                                              /* stages */
    double a[GL_SMAX][GL_SMAX], b[GL_SMAX], c[GL_SMAX]; /* Butcher tableau */
};
extern const struct gl_tableau gcp_gl2_tableau, gcp_gl4_tableau;

struct gl_ctx {
    const struct gl_tableau *tab;
    struct gcp_canon_chart chart;
    double sundman_a; /* [1] exponent of w = (B_ref/|B|)^a; 0: plain time steps */
    /* Lagrange weights of the lifted solver's point predictor (gc_gauss.c
     * gcp_gl_points_extrap) by [have_P][stage][node], filled once by
     * gcp_gl_ctx_weights (have_wext = 0: computed at each use) */
    double wext[3][GL_SMAX][2 * GL_SMAX + 1];
    /* and of the slope predictor (gcp_gl_predict) by [history - 2][stage][node] */
    double wK[2][GL_SMAX][3 * GL_SMAX];
    int have_wext;
    /* the block solver's work space (gcp_gl_block_scratch; freed by the
     * advance that allocated it), NULL: allocated at each block step */
    void *block_scratch;
};
/* Fills C->wext (C->tab set). */
void gcp_gl_ctx_weights(struct gl_ctx *C);

struct gl_lane {
    double z[4];                /* canonical state */
    double aux[GL_SMAX + 1][2]; /* chart guesses: [0] the state, [1 + i] stage i (after a
                                 * step by the lifted solver: [0] a guess of the end point,
                                 * [1 + i] the stage points themselves) */
    double K[GL_SMAX][2];       /* last step's stage slopes (d eta, d P_eta) */
    double K2[GL_SMAX][2];      /* the step's before */
    double K3[GL_SMAX][2];      /* and the one before that */
    double J[16];               /* LU of the stage Jacobian (2s x 2s) */
    int piv[4];
    int have_K, have_J;
    int fail;                   /* enum gcp_step_failure: why the last failed step failed */
    double sc[2];               /* [eta unit, P_eta unit] scales of eta and P_eta */
    double sc_pphi;             /* [kg m^2/s] scale of P_phi (chart residual of a stage point) */
    double DF[GL_SMAX][2][2];   /* the stage Jacobians of F behind J (lifted solver) */
    double DFp[GL_SMAX][2];     /* dF/dP_phi at the stages (lifted solver: the linearisation
                                 * of F at a point off the stage's P_phi) */
    double Jinv[16];            /* J^-1 (lifted solver: a product, not a solve, per iteration) */
    double pst2[GL_SMAX][2];    /* the stage points of the step before the last (lifted solver) */
    int have_P;                 /* steps whose stage points are kept: 0, 1 (aux[1 + i]), 2 (+ pst2) */
    /* the curve P_phi = const at the last stage point of the last lifted
     * step (gc_gauss_block.c gl_points_curve_s): its eta and dp/deta, d^2p/deta^2 */
    double ceta, ct1[2], ct2[2];
    int have_C;                 /* [bool] ceta, ct1, ct2 are the last step's */
    double hJ;                  /* step of the kept Jacobian */
    int have_DF;                /* [bool] DF, DFp, Jinv are the last accepted wlift step's, at step hDF */
    double hDF;
    double wv[GL_SMAX][2];      /* the last wlift step's stage points' dw/dt times h (with have_DF) */
    double t;                   /* [s] physical time (advanced by the step) */
    double pt;                  /* [J] p_t = -H(z0) (Sundman: extended phase space) */
    double Bref;                /* [T] |B| at the start (Sundman: w = 1 there) */
};

/* A lane's accepted step: the end state and time, and the slope history the
 * predictor extrapolates from (K, K2, K3) shifted by one step. */
static inline void gl_lane_accept(struct gl_lane *L, const double z[4], double t,
                                  const double K[GL_SMAX][2])
{
    memcpy(L->z, z, sizeof L->z);
    L->t = t;
    memcpy(L->K3, L->K2, sizeof L->K);
    memcpy(L->K2, L->K, sizeof L->K);
    memcpy(L->K, K, sizeof L->K);
    L->have_K = L->have_K < 3 ? L->have_K + 1 : 3;
}

/* J^-1 of the lifted solver's J = delta_ij I - h a_ij DF_i (n = 2s; row
 * 2i + r, column 2j + c; Jinv row-major n x n) in closed form by 2 x 2
 * blocks, straight-line code (no pivoting: the per-lane and block solvers'
 * lanes vectorise).  s = 1: J = A = I - h a_11 DF_1, J^-1 = adj(A)/det A.
 * s = 2: J = [[A, B], [C, D]], A = I - h a_11 DF_1, B = -h a_12 DF_1,
 * C = -h a_21 DF_2, D = I - h a_22 DF_2; with X = A^-1 B, Y = C A^-1 and the
 * Schur complement S = D - C X,
 *   J^-1 = [[A^-1 + X S^-1 Y, -X S^-1], [-S^-1 Y, S^-1]].
 * A's eigenvalues are 1 - h a_11 lambda for DF's lambda, ~1 +- i h a_11
 * omega for the bounce (lambda = +-i omega): never singular there.
 * Returns 0 where det A or det S is 0 or not finite (the lane's lifted
 * step fails, as a zero pivot did). */
static inline __attribute__((always_inline)) int
gcp_gl_jinv_blocks(const struct gl_tableau *T, int s, double h, const double F[GL_SMAX][2][2],
                   double Jinv[16])
{
    double A[2][2], Ai[2][2];
    for (int r = 0; r < 2; r++)
        for (int c = 0; c < 2; c++) A[r][c] = (r == c ? 1.0 : 0.0) - h * T->a[0][0] * F[0][r][c];
    const double dA = A[0][0] * A[1][1] - A[0][1] * A[1][0];
    const double iA = 1.0 / dA;
    Ai[0][0] = A[1][1] * iA, Ai[0][1] = -A[0][1] * iA;
    Ai[1][0] = -A[1][0] * iA, Ai[1][1] = A[0][0] * iA;
    int ok = (fabs(dA) > 0.0) & (fabs(dA) <= DBL_MAX);
    if (s == 1) {
        for (int r = 0; r < 2; r++)
            for (int c = 0; c < 2; c++) Jinv[2 * r + c] = Ai[r][c];
        return ok;
    }
    double B[2][2], Cm[2][2], D[2][2], X[2][2], Y[2][2], S[2][2], Si[2][2], XS[2][2], SY[2][2];
    for (int r = 0; r < 2; r++)
        for (int c = 0; c < 2; c++) {
            B[r][c] = -h * T->a[0][1] * F[0][r][c];
            Cm[r][c] = -h * T->a[1][0] * F[1][r][c];
            D[r][c] = (r == c ? 1.0 : 0.0) - h * T->a[1][1] * F[1][r][c];
        }
    for (int r = 0; r < 2; r++)
        for (int c = 0; c < 2; c++) {
            X[r][c] = Ai[r][0] * B[0][c] + Ai[r][1] * B[1][c];
            Y[r][c] = Cm[r][0] * Ai[0][c] + Cm[r][1] * Ai[1][c];
        }
    for (int r = 0; r < 2; r++)
        for (int c = 0; c < 2; c++) S[r][c] = D[r][c] - (Cm[r][0] * X[0][c] + Cm[r][1] * X[1][c]);
    const double dS = S[0][0] * S[1][1] - S[0][1] * S[1][0];
    const double iS = 1.0 / dS;
    Si[0][0] = S[1][1] * iS, Si[0][1] = -S[0][1] * iS;
    Si[1][0] = -S[1][0] * iS, Si[1][1] = S[0][0] * iS;
    ok &= (fabs(dS) > 0.0) & (fabs(dS) <= DBL_MAX);
    for (int r = 0; r < 2; r++)
        for (int c = 0; c < 2; c++) {
            XS[r][c] = X[r][0] * Si[0][c] + X[r][1] * Si[1][c];
            SY[r][c] = Si[r][0] * Y[0][c] + Si[r][1] * Y[1][c];
        }
    for (int r = 0; r < 2; r++)
        for (int c = 0; c < 2; c++) {
            Jinv[4 * r + c] = Ai[r][c] + (XS[r][0] * Y[0][c] + XS[r][1] * Y[1][c]);
            Jinv[4 * r + 2 + c] = -XS[r][c];
            Jinv[4 * (2 + r) + c] = -SY[r][c];
            Jinv[4 * (2 + r) + 2 + c] = Si[r][c];
        }
    return ok;
}

/* The end of a step from its slopes K and quadrature rates pd (gc_gauss.c):
 * z1 = z0 + h sum b_i K_i, and the quadratures phi and t. */
void gcp_gl_end_state(const struct gl_tableau *T, const struct gl_lane *L, double h,
                      const double K[GL_SMAX][2], const double pd[GL_SMAX][2], double z[4],
                      double *t);
/* Lane set-up from block lane i (canonical state, Newton scales); t, pt,
 * Bref are the caller's.  0 or a status (gcp_gc_lane_ops.init). */
int gcp_gl_init(const void *ctx, const struct gcp_block *b, size_t i, double t, void *lane);
/* One step of size h (time, or s with the Sundman transformation) of lane
 * L: 0, or GCP_STEP_FAILED with L unchanged. */
int gcp_gl_step_canon(const struct gl_ctx *C, const struct gcp_gc_consts *k, struct gl_lane *L,
                      double h);
/* gcp_gl_step_canon's step of block lane i with the lane's end state
 * written back (X, p_par; the gcp_gc_lane_ops.step contract); lift = 0
 * skips the lifted solver (the block solver's fallback). */
int gcp_gl_step_lane(const struct gl_ctx *C, struct gcp_block *b, size_t i, double h,
                     struct gl_lane *L, int lift);
/* gc_gauss.c's predictors of a step: the slopes K from the last steps'
 * (see its header; 0 or -1) and the chart point of stage wi by the
 * polynomial in time through the kept stage points. */
int gcp_gl_predict(const struct gl_ctx *C, const struct gcp_gc_consts *k,
                   const struct gl_lane *L, double K[GL_SMAX][2]);
void gcp_gl_points_extrap(const struct gl_ctx *C, const struct gl_lane *L, int wi, double *out);
/* Pieces of the lifted solver shared with gc_gauss_block.c: its start
 * (predicted slopes K, stage points p; 0 or -1), J^-1 from
 * L->DF (0 or -1), and its end (all in gc_gauss_block.c):
 * gcp_gl_lift_peek, without changing L, the end state z, t and the end
 * point's guess pe from a converged step's slopes K, quadrature rates pd,
 * stage points p with their dp/deta t1 and d^2p/deta^2 t2;
 * gcp_gl_lift_end, the step into L with the end point pe. */
int gcp_gl_lift_begin(const struct gl_ctx *C, const struct gcp_gc_consts *k,
                      const struct gl_lane *L, double h, double K[GL_SMAX][2],
                      double p[GL_SMAX][2]);
int gcp_gl_lift_jinv(const struct gl_ctx *C, struct gl_lane *L, double h);
void gcp_gl_lift_peek(const struct gl_ctx *C, const struct gl_lane *L, double h,
                      const double K[GL_SMAX][2], const double pd[GL_SMAX][2],
                      const double p[GL_SMAX][2], const double t1[GL_SMAX][2],
                      const double t2[GL_SMAX][2], double z[4], double *t, double pe[2]);
void gcp_gl_lift_end(const struct gl_ctx *C, struct gl_lane *L, double h,
                     const double K[GL_SMAX][2], const double z[4], double t,
                     const double p[GL_SMAX][2], const double t1[GL_SMAX][2],
                     const double t2[GL_SMAX][2], const double pe[2]);
/* One step of lane L by the solver of gc_gauss_wlift.c (charts with
 * wlift_eval, plain time steps): 0, or GCP_STEP_FAILED with only the
 * Jacobian fields of L changed (the caller falls back on the inverting
 * solver). */
int gcp_gl_step_wlift(const struct gl_ctx *C, const struct gcp_gc_consts *k, struct gl_lane *L,
                      double h);
/* The lifted solve over the n live lanes of b at once (gc_gauss_block.c;
 * gcp_gc_lane_ops.step_block), the per-lane path for lanes it fails. */
int32_t gcp_gl_step_block(const void *ctx, struct gcp_block *b, size_t n, double t, double h,
                          unsigned char *lanes);
/* The block solver's work space (free() it), or NULL. */
void *gcp_gl_block_scratch(void);
/* gc-gl2 / gc-gl4 in the dipole's closed form (gc_gauss_dipole.c): 0 with
 * the live lane count in *live when it pushed, -1 when the field is not
 * the dipole form without E (the chart's solvers then push). */
int gcp_gl_dipole_advance(struct gcp_block *b, const struct gcp_field *f,
                          const struct gcp_push_opts *o, const struct gcp_sampler *smp,
                          const struct gl_tableau *tab, size_t *live);
/* Its start-of-step check at a point of line L (tests): non-zero where the
 * lane stops (|s| >= 1, non-finite, or the adiabaticity above amax > 0). */
int gcp_gl_dipole_stops(double k, double q, double m, double L, double s, double Q, double beta,
                        double amax);
/* gc-gl2 / gc-gl4 in the analytic tokamak's closed form (gc_gauss_tokamak.c):
 * 0 with the live lane count in *live when it pushed, -1 when the field is
 * not that model (gcp_field_flux_tokamak) or gcp_gl_tokamak_off is set
 * (tests: the generic path then pushes); gcp_gl_tokamak_extra (tests): Newton
 * iterates past convergence. */
int gcp_gl_tokamak_advance(struct gcp_block *b, const struct gcp_field *f,
                           const struct gcp_push_opts *o, const struct gcp_sampler *smp,
                           const struct gl_tableau *tab, size_t *live);
extern int gcp_gl_tokamak_off, gcp_gl_tokamak_extra;
/* gcp_pusher_type.applies of the methods that need a canonical chart. */
int gcp_gc_canon_applies(const struct gcp_field *f, char *why, size_t whylen);

/* The end point's guess pe at t = h (units of h: nodes 0 and c_i): the
 * polynomial of degree 2s through w0 at 0 and w_i, v_i (slopes times h) at
 * c_i (Hermite), by its Newton form on the confluent nodes 0, c_1, c_1, ...
 * (divided differences).  The lifted solve's (gc_gauss_wlift.c) and the
 * closed-form tokamak's (gc_gauss_tokamak.c), which must agree. */
static inline void gcp_gl_end_guess(const struct gl_tableau *T, const double w0[2],
                                    const double w[GL_SMAX][2], const double v[GL_SMAX][2],
                                    double pe[2])
{
    const int s = T->s, m = 2 * s + 1;
    if (s == 1 && T->c[0] == 0.5) {
        /* the loop below on the nodes 0, 1/2, 1/2: its divisions are by
         * 1/2 (doublings) and its factors (1 - x) are 1/2 and 1, so these
         * are its numbers, without the loop's branches and division
         * chain (the loop: 1.2% of a gc-gl2 step in DIII-D, perf) */
        for (int r = 0; r < 2; r++) {
            const double d1 = (w[0][r] - w0[r]) * 2.0, d2 = (v[0][r] - d1) * 2.0;
            pe[r] = w0[r] + (d1 + 0.5 * d2);
        }
        return;
    }
    double x[2 * GL_SMAX + 1];
    x[0] = 0.0;
    for (int i = 0; i < s; i++) x[1 + 2 * i] = x[2 + 2 * i] = T->c[i];
    for (int r = 0; r < 2; r++) {
        double dd[2 * GL_SMAX + 1]; /* the divided-difference table, column by column */
        dd[0] = w0[r];
        for (int i = 0; i < s; i++) dd[1 + 2 * i] = dd[2 + 2 * i] = w[i][r];
        double coef[2 * GL_SMAX + 1];
        coef[0] = dd[0];
        for (int l = 1; l < m; l++) {
            for (int a = m - 1; a >= l; a--) /* a confluent pair takes the slope */
                dd[a] = x[a] == x[a - l] ? v[(a - 1) / 2][r]
                                         : (dd[a] - dd[a - 1]) / (x[a] - x[a - l]);
            coef[l] = dd[l];
        }
        double acc = coef[m - 1];
        for (int l = m - 2; l >= 0; l--) acc = coef[l] + (1.0 - x[l]) * acc;
        pe[r] = acc;
    }
}

#endif
