/* gc-gl2, gc-gl4: symplectic guiding-centre integrators, Gauss-Legendre
 * collocation on the canonical guiding-centre equations (issue 11).
 *
 * In a canonical chart (canon_priv.h: z = (phi, eta, P_phi, P_eta),
 * theta = P_phi dphi + P_eta deta) the guiding-centre motion is Hamilton's
 *   dz/dt = F(z) = (dH/dP_phi, dH/dP_eta, -dH/dphi = 0, -dH/deta).
 * The s-stage Gauss-Legendre Runge-Kutta method (Butcher 1964)
 *   K_i = F(z0 + h sum_j a_ij K_j),   z1 = z0 + h sum_i b_i K_i,
 *   s = 1: a = 1/2, b = 1, c = 1/2            (implicit midpoint, order 2),
 *   s = 2: c = 1/2 -+ sqrt(3)/6, b = 1/2, 1/2,
 *          a = [[1/4, 1/4 - sqrt(3)/6], [1/4 + sqrt(3)/6, 1/4]]   (order 4),
 * satisfies b_i a_ij + b_j a_ji = b_i b_j, hence is symplectic for every
 * canonical Hamiltonian system (Sanz-Serna 1988; Hairer, Lubich & Wanner,
 * Geometric Numerical Integration, 2nd ed., thm. VI.4.3), and it is
 * symmetric.  As the chart is a symplectic map of (X, p_par) with the
 * guiding-centre two-form d theta, the method is symplectic for the guiding
 * centre: the energy error stays bounded (no secular drift) and, H being
 * independent of phi, P_phi is exactly constant (discrete Noether).
 *
 * Unknowns.  F does not depend on phi, and its P_phi row is 0, so P_phi
 * stays P_phi(z0) at every stage, phi is a quadrature
 * (phi1 = phi0 + h sum b_i dH/dP_phi(Y_i)), and the stage equations are
 * solved for the 2s unknowns K_i = (deta/dt, dP_eta/dt) at the stages only.
 *
 * Solver: Newton on G(K) = K_i - F(Y_i(K)) with the Jacobian
 * delta_ij I - h a_ij DF(Y_i) (DF the 2x2 Jacobian of (dH/dP_eta, -dH/deta)
 * in (eta, P_eta) by forward differences, 1e-7 of the lane's scales),
 * kept across steps while the iteration contracts at least 10x per
 * iteration, refreshed once per step otherwise (a simplified Newton).
 * Predictor: the stage slopes of the last steps extrapolated along their
 * interpolating polynomial (gcp_gl_predict: of the last three steps for s = 1,
 * two for s = 2; one at the second step), or F(z0) at the first step.  Converged when the update of the stage values,
 * relative to the lane's scales, is <= 1e-15, or has stalled at round-off
 * (<= 1e-12 and no longer halving): the test is on the increment, never a
 * fixed count.  40 iterations without convergence, a non-finite value, or a
 * chart failure: the lane gets GCP_STEP_FAILED with the state of the start
 * of the step (the step is never shortened).
 *
 * Lifted solver (charts with lift_eval, plain time steps; gl_step_lift).
 * Each F(Y_i) above inverts the chart (psi, chi) -> (R, Z), two or three
 * field evaluations, at every iteration.  Instead the stage points p_i (the
 * chart's own (R, Z)) are unknowns too, with the chart equations
 *   P_phi(p_i) = P_phi(z0),   eta(p_i) = eta0 + h sum_j a_ij K_j^eta,
 * solved together with K_i = F(p_i, P_eta_i) by one Newton: an iteration
 * evaluates the field once at each p_i (lift_eval: the point's P_phi, eta,
 * H's derivatives and d p/d(P_phi, eta)), solves
 *   (delta_ij I - h a_ij DF_i) d_j = F_i - K_i + DF_i (e_i, 0) + dF_i/dP_phi f_i,
 * e_i, f_i = the stage's eta, P_phi minus the point's, and moves each point
 * by d p/d(P_phi, eta) times the (P_phi, eta) it lacks.  The f_i term
 * linearises F to the stage's P_phi (without it the point's P_phi residual,
 * ~1e-5 of the scale at the predicted point, entered K uncorrected and the
 * iteration contracted only ~1e3 per iterate: 5.0 iterates a step for
 * gc-gl2 in bench_push's scene, 4.1 with it); dF/dP_phi comes without a
 * field evaluation from the symmetry of H's Hessian: its rows are the
 * derivatives of the sampled dH/dP_phi along P_eta (lift_ham) and eta (the
 * sample DF's eta column takes).  The fixed point is the
 * same (K_i = F(Y_i) with Y_i on the chart), so the map is the same to
 * round-off.  DF is refreshed at the first iterate of every step (the eta
 * column by one field evaluation, the P_eta column from the sample:
 * lift_ham); the points are predicted along the curve P_phi = const
 * through the last stage point and the start point, at the stage's eta
 * from the predicted slopes (gc_gauss_block.c gl_points_curve_s; where the
 * last step was not a lifted one, the polynomial in time through the last
 * steps' stage points, gcp_gl_points_extrap), and the end point's guess
 * for from_canon along the same curve (gcp_gl_lift_peek).  With the curve, the
 * first update is mostly the slopes' prediction error (median 2.8e-4 of
 * the scale against 1.2e-3 in bench_push's scene, gc-gl2), and the iterates
 * a lane takes fell from 4.1 to 3.4 on average (gc-gl2; gc-gl4: 3.5 to 3.1).
 * Converged as above, or when the contraction theta = nd/nprev
 * predicts the next update below the tolerance (theta/(1 - theta) nd <=
 * 1e-15, Hairer & Wanner, Solving ODEs II, sec. IV.8).  An update that
 * shrinks less than 2x above the round-off floor (after the second
 * iterate) abandons the lifted step for the inverting solver from the
 * start of the step.  Where the chart also has lift_eval_block (the
 * curl-free chart), the same solve runs over the lanes of a block together,
 * vectorised (gc_gauss_block.c); gl_step_lift is then the per-lane form.
 * The flux charts' lifted solve (stage points in (eta, s, p_par)): gc_gauss_wlift.c.
 *
 * State.  The canonical z of each lane is kept between the steps of one
 * advance, so that the map applied is exactly the symplectic map; X, p_par
 * are mapped back from z after every step for the samplers and the domain
 * checks.  phi is kept in [-pi, pi] (an angle grown to 1e3 rad would have
 * an ulp above the Newton tolerance).
 *
 * The methods around these solvers (a lane's set-up, gcp_gl_init; which
 * solver pushes a block; the pusher types): gc_gauss_pusher.c.
 */
#include <math.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/gc.h"
#include "gcpush/particles.h"
#include "block_priv.h"
#include "canon_priv.h"
#include "gc_gauss_priv.h"
#include "gc_priv.h"

#define GL_MAXIT 40
#define GL_TOL 1e-15
/* A Newton update that stops contracting (less than halving) below GL_FLOOR
 * is at the round-off floor of the chart's inversion: in a tabulated flux
 * chart (DIII-D) p_par comes from P_phi - q psi with heavy cancellation and
 * the floor sits at ~1.1e-12 relative; 1e-10 keeps the step's error far below
 * the 1e-8 symplecticity check while not failing such steps. */
#define GL_FLOOR 1e-10
#define GL_FD 1e-7
/* The round-off floor of the lifted solver (curl-free chart: no inversion,
 * no cancellation; its updates reach 1e-16 .. 1e-15 of the scales). */
#define GL_LIFT_FLOOR 1e-13

const struct gl_tableau gcp_gl2_tableau = {1, {{0.5}}, {1.0}, {0.5}};
/* sqrt(3)/6 */
#define GL_R36 0.28867513459481288225
const struct gl_tableau gcp_gl4_tableau = {2,
                                           {{0.25, 0.25 - GL_R36}, {0.25 + GL_R36, 0.25}},
                                           {0.5, 0.5},
                                           {0.5 - GL_R36, 0.5 + GL_R36}};

/* LU with partial pivoting of an n x n (n <= 4) row-major matrix. */
static int lu_n(double *a, int *piv, int n)
{
    for (int k = 0; k < n; k++) {
        int pk = k;
        for (int i = k + 1; i < n; i++)
            if (fabs(a[n * i + k]) > fabs(a[n * pk + k])) pk = i;
        piv[k] = pk;
        if (!(a[n * pk + k] != 0.0) || !isfinite(a[n * pk + k])) return -1;
        if (pk != k)
            for (int j = 0; j < n; j++) {
                const double t = a[n * k + j];
                a[n * k + j] = a[n * pk + j];
                a[n * pk + j] = t;
            }
        for (int i = k + 1; i < n; i++) {
            const double l = a[n * i + k] / a[n * k + k];
            a[n * i + k] = l;
            for (int j = k + 1; j < n; j++) a[n * i + j] -= l * a[n * k + j];
        }
    }
    return 0;
}

static inline __attribute__((always_inline)) void lu_solve(const double *a, const int *piv,
                                                            int n, double *x)
{
    for (int k = 0; k < n; k++) {
        const double t = x[k];
        x[k] = x[piv[k]];
        x[piv[k]] = t;
    }
    for (int k = 0; k < n; k++)
        for (int i = k + 1; i < n; i++) x[i] -= a[n * i + k] * x[k];
    for (int k = n - 1; k >= 0; k--) {
        for (int j = k + 1; j < n; j++) x[k] -= a[n * k + j] * x[j];
        x[k] /= a[n * k + k];
    }
}

/* The rates at a point from H, dH and (Sundman) |B|, d|B|/dz: g = (d eta,
 * d P_eta) and the quadrature rates qd = (d phi, d t), per unit of the
 * independent variable: time (g = (dH/dP_eta, -dH/deta), qd = (dH/dP_phi,
 * 1)), or, with the Sundman transformation (C->sundman_a != 0), the
 * fictitious time s of the extended Hamiltonian K = w(z) (H(z) + p_t),
 * w = (B_ref/|B|)^a:
 *   dz/ds = w J grad H + (H + p_t) J grad w,  dt/ds = w,  dp_t/ds = 0
 * (grad w = -a w grad|B| / |B|; H + p_t = 0 on the orbit, but the term is
 * kept: without it the map is not symplectic in the extended space). */
static int gl_rates(const struct gl_ctx *C, const struct gl_lane *L, double H,
                    const double dH[4], double Bm, const double dB[4], double g[2], double qd[2])
{
    if (C->sundman_a != 0.0) {
        const double w = pow(L->Bref / Bm, C->sundman_a), E = H + L->pt;
        const double dw = -C->sundman_a * w / Bm; /* times dB_j */
        g[0] = w * dH[3] + E * dw * dB[3];
        g[1] = -(w * dH[1] + E * dw * dB[1]);
        qd[0] = w * dH[2] + E * dw * dB[2];
        qd[1] = w;
        return isfinite(g[0] + g[1] + qd[0] + qd[1]) ? 0 : GCP_NONFINITE;
    }
    g[0] = dH[3];
    g[1] = -dH[1];
    qd[0] = dH[2];
    qd[1] = 1.0;
    return 0;
}

/* F at (eta, P_eta) with P_phi fixed (gl_rates), through the chart's
 * inversion (hamiltonian, field_strength). */
static int gl_rhs(const struct gl_ctx *C, const struct gcp_gc_consts *k, const struct gl_lane *L,
                  double eta, double Peta, double aux[2], double g[2], double qd[2])
{
    const double z[4] = {0.0, eta, L->z[2], Peta};
    double H, dH[4], Bm = 0.0, dB[4] = {0.0, 0.0, 0.0, 0.0};
    int st = C->chart.hamiltonian(&C->chart, k, z, aux, &H, dH);
    if (C->sundman_a != 0.0 && !st) st = C->chart.field_strength(&C->chart, k, z, aux, &Bm, dB);
    return st ? st : gl_rates(C, L, H, dH, Bm, dB, g, qd);
}

/* J = LU of delta_ij I - h a_ij DF_i from the stage Jacobians L->DF. */
static int gl_assemble(const struct gl_ctx *C, struct gl_lane *L, double h)
{
    const int s = C->tab->s, n = 2 * s;
    memset(L->J, 0, sizeof L->J);
    for (int i = 0; i < s; i++)
        for (int j = 0; j < s; j++)
            for (int r = 0; r < 2; r++)
                for (int c = 0; c < 2; c++)
                    L->J[n * (2 * i + r) + 2 * j + c] =
                        (i == j && r == c ? 1.0 : 0.0) - h * C->tab->a[i][j] * L->DF[i][r][c];
    L->hJ = h;
    L->have_J = lu_n(L->J, L->piv, n) == 0;
    return L->have_J ? 0 : -1;
}

/* The stage Jacobian delta_ij I - h a_ij DF(Y_i), DF by forward differences. */
static int gl_jacobian(const struct gl_ctx *C, const struct gcp_gc_consts *k, struct gl_lane *L,
                       double h, const double Y[GL_SMAX][2], const double g[GL_SMAX][2])
{
    for (int i = 0; i < C->tab->s; i++)
        for (int c = 0; c < 2; c++) {
            double y[2] = {Y[i][0], Y[i][1]};
            const double e = GL_FD * L->sc[c];
            y[c] += e;
            double gk[2], pd[2], aux[2] = {L->aux[1 + i][0], L->aux[1 + i][1]};
            if (gl_rhs(C, k, L, y[0], y[1], aux, gk, pd)) return -1;
            const double ec = y[c] - Y[i][c];
            L->DF[i][0][c] = (gk[0] - g[i][0]) / ec;
            L->DF[i][1][c] = (gk[1] - g[i][1]) / ec;
        }
    return gl_assemble(C, L, h);
}

/* The update h A d of the stage values, relative to the lane's scales. */
static double gl_update_norm(const struct gl_tableau *T, const struct gl_lane *L, double h,
                             const double d[4])
{
    double nd = 0.0;
    for (int i = 0; i < T->s; i++)
        for (int r = 0; r < 2; r++) {
            double acc = 0.0;
            for (int j = 0; j < T->s; j++) acc += T->a[i][j] * d[2 * j + r];
            nd = fmax(nd, fabs(h * acc) / L->sc[r]);
        }
    return nd;
}

/* The weights of gcp_gl_predict's extrapolation of the slopes of the last nh
 * steps (nodes c_j - nh .. c_j - 1 in units of h) to the node c_i: their
 * interpolating polynomial of degree nh s - 1. */
static void gl_kweights(const struct gl_tableau *T, int nh, int i, double *w)
{
    const int s = T->s, nn = nh * s;
    double x[3 * GL_SMAX];
    for (int a = 0; a < nh; a++)
        for (int j = 0; j < s; j++) x[a * s + j] = T->c[j] - (double)(nh - a);
    for (int m = 0; m < nn; m++) {
        w[m] = 1.0;
        for (int l = 0; l < nn; l++)
            if (l != m) w[m] *= (T->c[i] - x[l]) / (x[m] - x[l]);
    }
}

/* The predictor of the stage slopes K (see the header of this file). */
int gcp_gl_predict(const struct gl_ctx *C, const struct gcp_gc_consts *k,
                   const struct gl_lane *L, double K[GL_SMAX][2])
{
    const struct gl_tableau *T = C->tab;
    const int s = T->s;
    if (L->have_K >= 2) {
        /* the slopes of the last nh steps extrapolated to the nodes c_i of
         * this step (gl_kweights): error O(h^(nh s)); nh = 3 for s = 1 (3%
         * fewer iterations than 2), 2 for s = 2 (the degree-5 extrapolation
         * over three steps is worse than the cubic) */
        const int nh = L->have_K >= 3 && s == 1 ? 3 : 2;
        const double(*kh[3])[2] = {L->K3, L->K2, L->K};
        for (int i = 0; i < s; i++) {
            double wl[3 * GL_SMAX];
            const double *w = wl;
            if (C->have_wext) w = C->wK[nh - 2][i];
            else gl_kweights(T, nh, i, wl);
            K[i][0] = K[i][1] = 0.0;
            for (int a = 0; a < nh; a++)
                for (int j = 0; j < s; j++) {
                    const double *km = kh[3 - nh + a][j], wm = w[a * s + j];
                    K[i][0] += wm * km[0], K[i][1] += wm * km[1];
                }
        }
    } else if (L->have_K) {
        /* the last step's slopes, extrapolated along their interpolating
         * polynomial (nodes c_j - 1) to c_i: constant for s = 1, linear for 2 */
        for (int i = 0; i < s; i++)
            for (int r = 0; r < 2; r++) {
                if (s == 1) {
                    K[i][r] = L->K[0][r];
                } else {
                    const double x = 1.0 + T->c[i];
                    const double w0 = (x - T->c[1]) / (T->c[0] - T->c[1]);
                    K[i][r] = w0 * L->K[0][r] + (1.0 - w0) * L->K[1][r];
                }
            }
    } else {
        double g0[2], p0[2], aux[2] = {L->aux[0][0], L->aux[0][1]};
        if (gl_rhs(C, k, L, L->z[1], L->z[3], aux, g0, p0)) return -1;
        for (int i = 0; i < s; i++) K[i][0] = g0[0], K[i][1] = g0[1];
    }
    return 0;
}

void gcp_gl_end_state(const struct gl_tableau *T, const struct gl_lane *L, double h,
                      const double K[GL_SMAX][2], const double pd[GL_SMAX][2], double z[4],
                      double *t)
{
    double de = 0.0, dP = 0.0, dphi = 0.0, dt = 0.0;
    for (int i = 0; i < T->s; i++) {
        de += T->b[i] * K[i][0];
        dP += T->b[i] * K[i][1];
        dphi += T->b[i] * pd[i][0];
        dt += T->b[i] * pd[i][1];
    }
    /* phi + h dphi into [-pi, pi]: remainder's value, by one subtraction or
     * addition of 2 pi where |phi| < 3 pi (exact by Sterbenz's lemma, as
     * remainder is), the library call (slow) beyond */
    const double phi = L->z[0] + h * dphi, tp = 2.0 * GCP_PI;
    if (fabs(phi) <= GCP_PI) z[0] = phi;
    else if (phi > GCP_PI && phi < 3.0 * GCP_PI) z[0] = phi - tp;
    else if (phi < -GCP_PI && phi > -3.0 * GCP_PI) z[0] = phi + tp;
    else z[0] = remainder(phi, tp);
    *t = L->t + h * dt;
    z[1] = L->z[1] + h * de;
    z[2] = L->z[2];
    z[3] = L->z[3] + h * dP;
}

/* The end of a converged step (gcp_gl_end_state) into L, and the slopes kept
 * for the next predictor. */
static void gl_finish(const struct gl_tableau *T, struct gl_lane *L, double h,
                      const double K[GL_SMAX][2], const double pd[GL_SMAX][2])
{
    double z[4], t;
    gcp_gl_end_state(T, L, h, K, pd, z, &t);
    gl_lane_accept(L, z, t, K);
}

/* Why a step failed (enum gcp_step_failure, issue 11): kept in the lane for
 * the caller, which restores the rest of the lane and reports it with
 * gcp_lane_fail. */
static int gl_fail(struct gl_lane *L, int why)
{
    L->fail = why;
    return GCP_STEP_FAILED;
}

/* One step through the chart's inversion (charts without lift_eval). */
static int gl_step_invert(const struct gl_ctx *C, const struct gcp_gc_consts *k,
                          struct gl_lane *L, double h)
{
    const struct gl_tableau *T = C->tab;
    const int s = T->s, n = 2 * s;
    double K[GL_SMAX][2], Y[GL_SMAX][2], g[GL_SMAX][2], pd[GL_SMAX][2];
    if (gcp_gl_predict(C, k, L, K)) return gl_fail(L, GCP_FAIL_CHART);
    if (L->have_J && L->hJ != h) L->have_J = 0;
    int refreshed = 0;
    double nprev = INFINITY;
    for (int it = 0; it < GL_MAXIT; it++) {
        double G[4];
        for (int i = 0; i < s; i++) {
            for (int r = 0; r < 2; r++) {
                double acc = 0.0;
                for (int j = 0; j < s; j++) acc += T->a[i][j] * K[j][r];
                Y[i][r] = L->z[1 + 2 * r] + h * acc;
            }
            if (gl_rhs(C, k, L, Y[i][0], Y[i][1], L->aux[1 + i], g[i], pd[i]))
                return gl_fail(L, GCP_FAIL_CHART);
            G[2 * i] = -(K[i][0] - g[i][0]);
            G[2 * i + 1] = -(K[i][1] - g[i][1]);
        }
        if (!L->have_J) {
            if (gl_jacobian(C, k, L, h, Y, g)) return gl_fail(L, GCP_FAIL_NONFINITE_STAGE);
            refreshed = 1;
        }
        double d[4];
        memcpy(d, G, sizeof d);
        lu_solve(L->J, L->piv, n, d);
        double nd = gl_update_norm(T, L, h, d);
        if (!isfinite(nd)) return gl_fail(L, GCP_FAIL_NONFINITE_STAGE);
        if (it > 0 && nd > 0.1 * nprev && nd > GL_TOL && !refreshed) {
            /* slow contraction with a kept Jacobian: refresh it once, redo the update */
            if (gl_jacobian(C, k, L, h, Y, g)) return gl_fail(L, GCP_FAIL_NONFINITE_STAGE);
            refreshed = 1;
            memcpy(d, G, sizeof d);
            lu_solve(L->J, L->piv, n, d);
            nd = gl_update_norm(T, L, h, d);
            if (!isfinite(nd)) return gl_fail(L, GCP_FAIL_NONFINITE_STAGE);
        }
        for (int i = 0; i < s; i++) K[i][0] += d[2 * i], K[i][1] += d[2 * i + 1];
        const int stalled = it > 0 && nd <= GL_FLOOR && nd > 0.5 * nprev;
        if (nd <= GL_TOL || stalled) {
            gl_finish(T, L, h, K, pd);
            return 0;
        }
        nprev = nd;
    }
    return gl_fail(L, GCP_FAIL_NO_CONVERGENCE);
}

/* Lagrange weights w_m of the nodes x[0 .. m-1] at xi. */
static void gl_lagrange(const double *x, int m, double xi, double *w)
{
    for (int a = 0; a < m; a++) {
        w[a] = 1.0;
        for (int l = 0; l < m; l++)
            if (l != a) w[a] *= (xi - x[l]) / (x[a] - x[l]);
    }
}

/* The nodes (in units of h from the start of the step) of the points that
 * gcp_gl_points_extrap interpolates: the stage points of the last two steps
 * (nodes c_j - 2, c_j - 1, as far as kept: have_P) and the start (node 0).
 * Returns their count. */
static int gl_extrap_nodes(const struct gl_tableau *T, int have_P, double *x)
{
    const int s = T->s;
    int m = 0;
    for (int j = 0; j < s && have_P >= 2; j++) x[m++] = T->c[j] - 2.0;
    for (int j = 0; j < s && have_P >= 1; j++) x[m++] = T->c[j] - 1.0;
    x[m++] = 0.0;
    return m;
}

void gcp_gl_ctx_weights(struct gl_ctx *C)
{
    const struct gl_tableau *T = C->tab;
    double x[2 * GL_SMAX + 1];
    for (int hp = 0; hp < 3; hp++)
        for (int i = 0; i < T->s; i++) {
            const int m = gl_extrap_nodes(T, hp, x);
            gl_lagrange(x, m, T->c[i], C->wext[hp][i]);
        }
    for (int nh = 2; nh <= 3; nh++)
        for (int i = 0; i < T->s; i++) gl_kweights(T, nh, i, C->wK[nh - 2][i]);
    C->have_wext = 1;
}

/* The chart point at node c_wi by the polynomial through the kept points
 * (gl_extrap_nodes), with the weights of gcp_gl_ctx_weights where C has
 * them. */
void gcp_gl_points_extrap(const struct gl_ctx *C, const struct gl_lane *L, int wi, double *out)
{
    const struct gl_tableau *T = C->tab;
    const int s = T->s, hp = L->have_P < 2 ? L->have_P : 2;
    double x[2 * GL_SMAX + 1], v[2 * GL_SMAX + 1][2], wl[2 * GL_SMAX + 1];
    const int m = gl_extrap_nodes(T, hp, x);
    const double *w = wl;
    if (C->have_wext) w = C->wext[hp][wi];
    else gl_lagrange(x, m, T->c[wi], wl);
    int a = 0;
    for (int j = 0; j < s && hp >= 2; j++, a++)
        v[a][0] = L->pst2[j][0], v[a][1] = L->pst2[j][1];
    for (int j = 0; j < s && hp >= 1; j++, a++)
        v[a][0] = L->aux[1 + j][0], v[a][1] = L->aux[1 + j][1];
    v[a][0] = L->aux[0][0], v[a][1] = L->aux[0][1], a++;
    out[0] = out[1] = 0.0;
    for (int k = 0; k < m; k++) out[0] += w[k] * v[k][0], out[1] += w[k] * v[k][1];
}

/* Stage i evaluated at the chart point p with P_eta: sample o, rates g, qd. */
static int gl_lift_stage(const struct gl_ctx *C, const struct gcp_gc_consts *k,
                         const struct gl_lane *L, const double p[2], double Peta,
                         struct gcp_canon_lift *o, double g[2], double qd[2])
{
    const int st = C->chart.lift_eval(&C->chart, k, p, Peta, o);
    return st ? st : gl_rates(C, L, o->H, o->dH, o->Bm, o->dBm, g, qd);
}

/* DF of stage i (sample o, rates g at its point p) by forward differences:
 * the eta column by a move of p along dp/deta (the eta reached, from the
 * sample, is the divisor; P_phi moves by O(e^2)), the P_eta column from the
 * sample o itself (lift_ham: no field evaluation). */
static int gl_lift_df(const struct gl_ctx *C, const struct gcp_gc_consts *k, struct gl_lane *L,
                      int i, const double p[2], double Peta, const struct gcp_canon_lift *o,
                      const double g[2], double t2[2])
{
    struct gcp_canon_lift o2 = *o;
    double g2[2], q2[2];
    const double P2 = Peta + GL_FD * L->sc[1], dP = P2 - Peta;
    if (C->chart.lift_ham(&C->chart, k, o, P2, &o2.H, o2.dH) ||
        gl_rates(C, L, o2.H, o2.dH, o2.Bm, o2.dBm, g2, q2))
        return -1;
    L->DF[i][0][1] = (g2[0] - g[0]) / dP;
    L->DF[i][1][1] = (g2[1] - g[1]) / dP;
    L->DFp[i][0] = (o2.dH[2] - o->dH[2]) / dP;
    const double e = GL_FD * L->sc[0];
    const double p2[2] = {p[0] + o->dp[0][1] * e, p[1] + o->dp[1][1] * e};
    if (gl_lift_stage(C, k, L, p2, Peta, &o2, g2, q2)) return -1;
    const double de = o2.eta - o->eta;
    L->DF[i][0][0] = (g2[0] - g[0]) / de;
    L->DF[i][1][0] = (g2[1] - g[1]) / de;
    L->DFp[i][1] = -(o2.dH[2] - o->dH[2]) / de;
    t2[0] = (o2.dp[0][1] - o->dp[0][1]) / de; /* d^2 p/deta^2 (gcp_gl_lift_end) */
    t2[1] = (o2.dp[1][1] - o->dp[1][1]) / de;
    return isfinite(L->DF[i][0][0] + L->DF[i][1][0] + L->DF[i][0][1] + L->DF[i][1][1] +
                    L->DFp[i][0] + L->DFp[i][1])
               ? 0
               : -1;
}

/* One step by the lifted solver (charts with lift_eval; see the header). */
static int gl_step_lift(const struct gl_ctx *C, const struct gcp_gc_consts *k, struct gl_lane *L,
                        double h)
{
    const struct gl_tableau *T = C->tab;
    const int s = T->s, n = 2 * s;
    double K[GL_SMAX][2], g[GL_SMAX][2], pd[GL_SMAX][2], p[GL_SMAX][2], Pe[GL_SMAX];
    double t1[GL_SMAX][2], t2[GL_SMAX][2];
    struct gcp_canon_lift o[GL_SMAX];
    if (gcp_gl_lift_begin(C, k, L, h, K, p)) return GCP_STEP_FAILED;
    /* DF at the first iterate of every step (one field evaluation a stage),
     * kept through the step (a simplified Newton) */
    double nprev = INFINITY;
    for (int it = 0; it < GL_MAXIT; it++) {
        double e[GL_SMAX];
        for (int i = 0; i < s; i++) {
            double eta = 0.0, P = 0.0;
            for (int j = 0; j < s; j++) eta += T->a[i][j] * K[j][0], P += T->a[i][j] * K[j][1];
            eta = L->z[1] + h * eta;
            Pe[i] = L->z[3] + h * P;
            if (gl_lift_stage(C, k, L, p[i], Pe[i], &o[i], g[i], pd[i])) return GCP_STEP_FAILED;
            e[i] = eta - o[i].eta; /* the point's eta short of the stage's */
        }
        if (it == 0) {
            for (int i = 0; i < s; i++)
                if (gl_lift_df(C, k, L, i, p[i], Pe[i], &o[i], g[i], t2[i]))
                    return GCP_STEP_FAILED;
            if (gcp_gl_lift_jinv(C, L, h)) return GCP_STEP_FAILED;
        }
        /* K_i + d_i = F(point_i) + DF_i (e_i + h (A d)_i, h (A d)_i^P)
         *                        + dF/dP_phi (P_phi(z0) - P_phi(point_i)) */
        double G[4], d[4], nd = 0.0;
        for (int i = 0; i < s; i++) {
            const double ep = L->z[2] - o[i].Pphi;
            G[2 * i] = g[i][0] - K[i][0] + L->DF[i][0][0] * e[i] + L->DFp[i][0] * ep;
            G[2 * i + 1] = g[i][1] - K[i][1] + L->DF[i][1][0] * e[i] + L->DFp[i][1] * ep;
        }
        for (int r = 0; r < n; r++) {
            d[r] = 0.0;
            for (int c = 0; c < n; c++) d[r] += L->Jinv[n * r + c] * G[c];
        }
        for (int i = 0; i < s; i++) {
            double ae = 0.0, aP = 0.0;
            for (int j = 0; j < s; j++) ae += T->a[i][j] * d[2 * j], aP += T->a[i][j] * d[2 * j + 1];
            nd = fmax(nd, fabs(e[i] + h * ae) / L->sc[0]);
            nd = fmax(nd, fabs(h * aP) / L->sc[1]);
            nd = fmax(nd, fabs(L->z[2] - o[i].Pphi) / L->sc_pphi);
        }
        if (!isfinite(nd)) return GCP_STEP_FAILED;
        /* the slopes, and the points moved to the stage values they give */
        for (int i = 0; i < s; i++) {
            double ae = 0.0;
            for (int j = 0; j < s; j++) ae += T->a[i][j] * d[2 * j];
            const double dPphi = L->z[2] - o[i].Pphi, deta = e[i] + h * ae;
            p[i][0] += o[i].dp[0][0] * dPphi + o[i].dp[0][1] * deta;
            p[i][1] += o[i].dp[1][0] * dPphi + o[i].dp[1][1] * deta;
        }
        for (int i = 0; i < s; i++) K[i][0] += d[2 * i], K[i][1] += d[2 * i + 1];
        /* converged: this update at the tolerance, or the next one (a
         * contraction theta = nd/nprev leaves theta/(1 - theta) nd) below it
         * (Hairer & Wanner, Solving ODEs II, sec. IV.8), or stalled at the
         * round-off floor */
        const double th = nd / nprev;
        const int next_below = it > 0 && th < 1.0 && th / (1.0 - th) * nd <= GL_TOL;
        /* from the third iterate on (the first update carries the predicted
         * points' chart residual), an update that shrinks less than 2x above
         * the round-off floor with a DF fresh from this step: the iteration
         * diverges or crawls (a healthy step contracts 20x or more), i.e. a
         * guess too far off or a step far beyond what the method resolves --
         * the lifted step is abandoned rather than crawl to a floor that the
         * stall test would accept */
        const int stalled = it > 0 && nd <= GL_LIFT_FLOOR && th > 0.5;
        if (it > 1 && th > 0.5 && !stalled) return GCP_STEP_FAILED;
        if (nd <= GL_TOL || next_below || stalled) {
            double z1[4], t1e, pe[2];
            for (int i = 0; i < s; i++) t1[i][0] = o[i].dp[0][1], t1[i][1] = o[i].dp[1][1];
            gcp_gl_lift_peek(C, L, h, K, pd, p, t1, t2, z1, &t1e, pe);
            gcp_gl_lift_end(C, L, h, K, z1, t1e, p, t1, t2, pe);
            return 0;
        }
        nprev = nd;
    }
    return GCP_STEP_FAILED;
}

/* One Gauss-Legendre step of lane L; 0 or GCP_STEP_FAILED (L unchanged): a
 * lifted solver where the chart has one, else or where it fails the inverting one. */
static int gl_step_canon(const struct gl_ctx *C, const struct gcp_gc_consts *k,
                         struct gl_lane *L, double h, int lift)
{
    if (lift && (C->chart.lift_eval || C->chart.wlift_eval) && C->sundman_a == 0.0) {
        /* either changes only the Jacobian fields of L until it succeeds */
        const int r = C->chart.lift_eval ? gl_step_lift(C, k, L, h) : gcp_gl_step_wlift(C, k, L, h);
        if (r == 0) return 0;
        L->have_J = 0;
    }
    const int r = gl_step_invert(C, k, L, h);
    /* its aux[1 + i] are this step's stage points, aux[0] the start's */
    if (!r) L->have_P = 1, L->have_C = 0;
    return r;
}

int gcp_gl_step_canon(const struct gl_ctx *C, const struct gcp_gc_consts *k, struct gl_lane *L,
                      double h)
{
    return gl_step_canon(C, k, L, h, 1);
}

int gcp_gl_step_lane(const struct gl_ctx *C, struct gcp_block *b, size_t i, double h,
                     struct gl_lane *L, int lift)
{
    const struct gcp_gc_consts k = {b->q, b->m, b->mu[i]};
    const struct gl_lane save = *L;
    int r = gl_step_canon(C, &k, L, h, lift), why = r ? L->fail : GCP_FAIL_NONE;
    double X[3], ppar;
    if (!r) {
        r = C->chart.from_canon(&C->chart, &k, L->z, L->aux[0], X, &ppar);
        why = GCP_FAIL_CHART; /* the end point's inversion */
    }
    if (r) {
        /* nothing of the failed step is kept */
        *L = save;
        return r == GCP_NONFINITE ? r : gcp_lane_fail(b, i, why);
    }
    b->x[i] = X[0], b->y[i] = X[1], b->z[i] = X[2];
    b->ppar[i] = ppar;
    b->fstatus[i] = 0;
    return 0;
}
