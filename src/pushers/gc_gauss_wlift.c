/* The collocation solve of gc-gl2 / gc-gl4 (gc_gauss.c) with the stage
 * points in the chart's own coordinates (eta, w): for charts with
 * wlift_eval, the flux charts (canon_flux.c, w = (s, p_par)), issue 11.
 *
 * Why.  The inverting solver (gc_gauss.c gl_step_invert) evaluates
 * F(eta, P_eta) = (dH/dP_eta, -dH/deta) at P_phi(z0) through the chart's
 * inversion: a Newton on (s, p_par) per evaluation, ~3 maps of the chart
 * and field evaluations each, ~10 such evaluations a step.  The lifted solver
 * of gc_gauss.c cannot take the flux chart: its point (R, Z) or (s, eta)
 * would have to fix P_phi without p_par, and at a fixed (s, eta) P_eta =
 * q A_eta + p_par h_eta sets p_par with a cancellation of ~1e2 (a point a
 * hair off in s carries a p_par off by p: F is evaluated far from the orbit
 * and the simplified Newton does not converge, measured).  Here w = (s,
 * p_par) of each stage is an unknown: the chart is only ever evaluated
 * forward, at a point where F is what it is on the orbit nearby.
 *
 * Equations (stage i, eta_i = eta0 + h sum_j a_ij K_j^eta, P_i = P_eta0 +
 * h sum_j a_ij K_j^P):
 *   K_i = F(eta_i, w_i),      G(eta_i, w_i) = (P_phi(z0), P_i),
 * G = (P_phi, P_eta) of the point.  Eliminating the points: with r_i the
 * chart residual (P_phi(z0), P_i) - G(eta_i, w_i), Gw = dG/dw, Ge = dG/deta,
 * a change (d eta, d P) of the stage moves the point by
 *   dw = Gw^-1 (r_i + (0, dP) - Ge d eta),
 * and F by F_w dw + F_eta d eta.  With M = F_w Gw^-1, the canonical
 * Jacobians are
 *   dF/dP_phi = M e_1,  dF/dP_eta = M e_2,  dF/deta = F_eta - M Ge,
 * so the Newton update d of the slopes solves (the same J as gc_gauss.c)
 *   (delta_ij I - h a_ij DF_i) d_j = F_i - K_i + M_i r_i,
 * and each point then moves by dw above with (d eta, dP) = h (A d)_i: an
 * exact Newton step for the chart's part (Gw, Ge fresh at every iterate, no
 * field evaluation beyond the point's own), a simplified one for F's (DF,
 * M from the first iterate of the step, or the last accepted step's at the
 * same h: a frozen Jacobian, two chart evaluations a stage saved; the
 * refresh below takes it anew where it contracts badly.  Measured on
 * bench_flux's orbits, chart evaluations a step 10.6 -> 9.3 (gc-gl2) in the
 * tokamak, 17.8 -> 16.5 (gc-gl4) in DIII-D; the fixed point is unchanged).  F_w, F_eta by forward
 * differences, 1e-7 of the scales: s and eta by one evaluation each, p_par
 * from the same geometry (no field evaluation).  The fixed point is the
 * inverting solver's (K_i = F at the stage's z, the point on the chart), so
 * the map is the same to round-off, and symplectic.
 * Predictor: gc_gauss.c's (gcp_gl_lift_begin: the slopes of the last steps,
 * the points of the last two steps and the start extrapolated); with the
 * analytic Jacobian at the same h, one of them with the last step's
 * derivatives as well (glw_predict: Hermite in time).  Converged
 * as gc_gauss.c's lifted solver (the update of the stage values and of the
 * points relative to their scales, <= 1e-15, or the contraction predicting
 * the next below 1e-18, or stalled at the round-off floor, or at the floor
 * with the contraction of the two updates before predicting the next below
 * 1e-18).  DF is taken
 * again once where the first update was large or an update contracted less
 * than 10x; an update that stops contracting after that abandons the step
 * for the inverting solver (gc_gauss.c).
 * Charts with wlift_eval_df (the tabulated flux chart of a G-EQDSK field,
 * canon_flux.c): F_w, F_eta analytic, from the same evaluation as the
 * point (its jets: the table's third derivatives, B's second), at the
 * first iterate and at every iterate after an update above GLW_DFTHR =
 * 1e-3 of the scales or one that contracted less than 10x: a full Newton
 * while far, the Jacobian frozen near the fixed point, no differences.
 * Why: the predictor's first update is ~1e-2 of the scales at 25 steps a
 * bounce, which the frozen Jacobian above took 5.7 (gc-gl2) / 5.2 (gc-gl4)
 * iterates a step to close, the Jacobian differenced at nearly every step
 * (two chart evaluations a stage); with it, 3.8 / 3.7 iterates, 2.2 of
 * them with the Jacobian (bench_flux, DIII-D; a Newton with the Jacobian
 * at every iterate took the same 3.8, and at the first only, 7.2).  An
 * evaluation with the jets costs ~1.6 plain ones.  The fixed point and
 * the tests are unchanged; only the iterates (so the last bits) move.
 * End point (the guess of from_canon): the Hermite polynomial in time
 * through the start point w0 and the stage points w_i with their slopes
 * dw/dt = Gw^-1 ((0, K^P) - Ge K^eta), at t = h: error O(h^(2s+1)), so the
 * chart's Newton in from_canon starts ~1e-6 (gc-gl2) or ~1e-9 (gc-gl4) off.
 */
#include <math.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/particles.h"
#include "canon_priv.h"
#include "gc_gauss_priv.h"

#define GLW_MAXIT 40

#define GLW_TOL 1e-15
#define GLW_FD 1e-7
#define GLW_DFTHR 1e-3 /* see the header: above, the analytic Jacobian again */
/* The round-off floor of the updates: the chart residual r carries the
 * rounding of q A_eta + p_par h_eta (~1e2 times p_par's ulp, ~1e-14 of the
 * scale); measured below 1e-13 in the tokamak and DIII-D. */
#define GLW_FLOOR 1e-12

/* The rates of a stage sample o: g = (d eta, d P_eta) = (dH/dP_eta,
 * -dH/deta), qd = (d phi, d t) = (dH/dP_phi, 1). */
static inline void glw_rates(const struct gcp_canon_wpoint *o, double g[2], double qd[2])
{
    g[0] = o->dH[3];
    g[1] = -o->dH[1];
    qd[0] = o->dH[2];
    qd[1] = 1.0;
}

/* Stage at (eta, w): sample o, rates g = (d eta, d P_eta) and qd = (d phi, d t). */
static int glw_stage(const struct gl_ctx *C, const struct gcp_gc_consts *k, double eta,
                     const double w[2], const struct gcp_canon_wpoint *same,
                     struct gcp_canon_wpoint *o, double g[2], double qd[2])
{
    const int st = C->chart.wlift_eval(&C->chart, k, eta, w, same, o);
    if (st) return st;
    glw_rates(o, g, qd);
    return 0;
}

/* glw_stage with F's derivatives (wlift_eval_df; have = 0: none). */
static int glw_stage_df(const struct gl_ctx *C, const struct gcp_gc_consts *k, double eta,
                        const double w[2], struct gcp_canon_wpoint *o, double g[2], double qd[2],
                        double Fw[2][2], double Fe[2], int *have)
{
    const int st = C->chart.wlift_eval_df(&C->chart, k, eta, w, o, Fw, Fe, have);
    if (st) return st;
    glw_rates(o, g, qd);
    return 0;
}

/* fmax(a, b) (a NaN argument gives the other), inline: GCC 12 calls libm's
 * fmax here, four times an iterate. */
static inline double glw_max(double a, double b) { return (b > a || a != a) ? b : a; }

/* Gw^-1 b. */
static void glw_solve2(const double A[2][2], const double b[2], double x[2])
{
    const double det = A[0][0] * A[1][1] - A[0][1] * A[1][0];
    x[0] = (A[1][1] * b[0] - A[0][1] * b[1]) / det;
    x[1] = (-A[1][0] * b[0] + A[0][0] * b[1]) / det;
}

/* DF and dF/dP_phi of stage i (see the header) into L->DF[i], L->DFp[i]
 * from F's derivatives in w (Fw) and eta (Fe) at the stage point o. */
static int glw_df_set(struct gl_lane *L, int i, const struct gcp_canon_wpoint *o,
                      const double Fw[2][2], const double Fe[2])
{
    const double det = o->Pw[0][0] * o->Pw[1][1] - o->Pw[0][1] * o->Pw[1][0];
    const double Gi[2][2] = {{o->Pw[1][1] / det, -o->Pw[0][1] / det},
                             {-o->Pw[1][0] / det, o->Pw[0][0] / det}};
    for (int r = 0; r < 2; r++) {
        const double M0 = Fw[r][0] * Gi[0][0] + Fw[r][1] * Gi[1][0];
        const double M1 = Fw[r][0] * Gi[0][1] + Fw[r][1] * Gi[1][1];
        L->DFp[i][r] = M0;
        L->DF[i][r][1] = M1;
        L->DF[i][r][0] = Fe[r] - (M0 * o->Pe[0] + M1 * o->Pe[1]);
    }
    return isfinite(L->DF[i][0][0] + L->DF[i][1][0] + L->DF[i][0][1] + L->DF[i][1][1] +
                    L->DFp[i][0] + L->DFp[i][1])
               ? 0
               : -1;
}

/* DF and dF/dP_phi of stage i with F's derivatives by forward differences
 * (charts without wlift_eval_df, or where it has none). */
static int glw_df(const struct gl_ctx *C, const struct gcp_gc_consts *k, struct gl_lane *L,
                  int i, double eta, const double w[2], const struct gcp_canon_wpoint *o,
                  const double g[2])
{
    struct gcp_canon_wpoint o2;
    double g2[2], q2[2], Fw[2][2], Fe[2];
    for (int c = 0; c < 2; c++) {
        double w2[2] = {w[0], w[1]};
        w2[c] += GLW_FD * o->wscale[c];
        if (glw_stage(C, k, eta, w2, c ? o : NULL, &o2, g2, q2)) return -1;
        const double dw = w2[c] - w[c];
        for (int r = 0; r < 2; r++) Fw[r][c] = (g2[r] - g[r]) / dw;
    }
    const double e2 = eta + GLW_FD * L->sc[0], de = e2 - eta;
    if (glw_stage(C, k, e2, w, NULL, &o2, g2, q2)) return -1;
    for (int r = 0; r < 2; r++) Fe[r] = (g2[r] - g[r]) / de;
    return glw_df_set(L, i, o, Fw, Fe);
}

/* The polynomial through m nodes x (ascending; a repeated node carries the
 * derivative dv there, Hermite) with values v, at t, each component: its
 * Newton form by divided differences on the confluent nodes. */
static void glw_hermite(int m, const double *x, const double (*v)[2], const double (*dv)[2],
                        double t, double out[2])
{
    for (int r = 0; r < 2; r++) {
        double dd[4 * GL_SMAX + 1], coef[4 * GL_SMAX + 1];
        for (int b = 0; b < m; b++) dd[b] = v[b][r];
        coef[0] = dd[0];
        for (int l = 1; l < m; l++) {
            for (int b = m - 1; b >= l; b--) {
                if (x[b] == x[b - l]) /* confluent pair: the derivative */
                    dd[b] = dv[b][r];
                else
                    dd[b] = (dd[b] - dd[b - 1]) / (x[b] - x[b - l]);
            }
            coef[l] = dd[l];
        }
        double acc = coef[m - 1];
        for (int l = m - 2; l >= 0; l--) acc = coef[l] + (t - x[l]) * acc;
        out[r] = acc;
    }
}

/* The predictor with the last step's derivatives (charts with
 * wlift_eval_df, the same h, see the header), in units of h from this
 * step's start, at the nodes c_i:
 *  s = 1: the slopes K through the last three steps' (at c - 3, c - 2,
 *    c - 1) and the last one's time derivative dK/dt = DF K (F's Jacobian
 *    at the stage: the flow's), a cubic, error O(h^4) (gcp_gl_predict's
 *    quadratic: O(h^3));
 *  s = 2: the stage points w through the last two steps' (c_j - 2, c_j - 1)
 *    and the start w0, with the last step's slopes dw/dt (gcp_gl_end_guess's
 *    v_j), degree 6 (gcp_gl_points_extrap's, values only: 4).
 * Measured on bench_flux's DIII-D orbit: iterations a step 3.80 -> 3.69
 * (gc-gl2) and 3.74 -> 3.53 (gc-gl4); the other way round each was worse
 * (gc-gl2 3.84 with the points', gc-gl4 4.14 with the slopes'). */
static void glw_predict(const struct gl_tableau *T, const struct gl_lane *L, double h,
                        double K[GL_SMAX][2], double w[GL_SMAX][2])
{
    const int s = T->s;
    double x[4 * GL_SMAX + 1], v[4 * GL_SMAX + 1][2], dv[4 * GL_SMAX + 1][2];
    int m = 0;
    if (s == 1) {
        if (L->have_K < 3) return;
        const double(*kh[2])[2] = {L->K3, L->K2};
        for (int a = 0; a < 2; a++, m++) {
            x[m] = T->c[0] - (double)(3 - a);
            v[m][0] = kh[a][0][0], v[m][1] = kh[a][0][1];
        }
        for (int c = 0; c < 2; c++, m++) {
            x[m] = T->c[0] - 1.0;
            v[m][0] = L->K[0][0], v[m][1] = L->K[0][1];
            for (int r = 0; r < 2; r++)
                dv[m][r] = h * (L->DF[0][r][0] * L->K[0][0] + L->DF[0][r][1] * L->K[0][1]);
        }
        if (T->c[0] != 0.5) {
            glw_hermite(m, x, (const double(*)[2])v, (const double(*)[2])dv, T->c[0], K[0]);
            return;
        }
        /* glw_hermite's numbers on these nodes (-5/2, -3/2, -1/2, -1/2, at
         * 1/2): its divisions are by 1 and 2 (exact: x and x/2 = x * 0.5),
         * its factors (t - x) 1, 2 and 3; without the loop's branches and
         * division chain (glw_hermite: 1.8% of a gc-gl2 step in DIII-D, perf) */
        for (int r = 0; r < 2; r++) {
            const double a1 = v[1][r] - v[0][r], b1 = v[2][r] - v[1][r];
            const double a2 = (b1 - a1) * 0.5, b2 = dv[3][r] - b1;
            const double a3 = (b2 - a2) * 0.5;
            K[0][r] = v[0][r] + 3.0 * (a1 + 2.0 * (a2 + 1.0 * a3));
        }
        return;
    }
    if (L->have_P < 2) return;
    for (int j = 0; j < s; j++, m++) {
        x[m] = T->c[j] - 2.0;
        v[m][0] = L->pst2[j][0], v[m][1] = L->pst2[j][1];
    }
    for (int j = 0; j < s; j++)
        for (int c = 0; c < 2; c++, m++) {
            x[m] = T->c[j] - 1.0;
            v[m][0] = L->aux[1 + j][0], v[m][1] = L->aux[1 + j][1];
            dv[m][0] = L->wv[j][0], dv[m][1] = L->wv[j][1];
        }
    x[m] = 0.0, v[m][0] = L->aux[0][0], v[m][1] = L->aux[0][1], m++;
    for (int i = 0; i < s; i++)
        glw_hermite(m, x, (const double(*)[2])v, (const double(*)[2])dv, T->c[i], w[i]);
}

int gcp_gl_step_wlift(const struct gl_ctx *C, const struct gcp_gc_consts *k, struct gl_lane *L,
                      double h)
{
    const struct gl_tableau *T = C->tab;
    const int s = T->s, n = 2 * s;
    double K[GL_SMAX][2], w[GL_SMAX][2], g[GL_SMAX][2], pd[GL_SMAX][2];
    struct gcp_canon_wpoint o[GL_SMAX];
    /* the last step's DF (a frozen Jacobian) where it has one at this h */
    const int stale = L->have_DF && L->hDF == h;
    L->have_DF = 0;
    if (gcp_gl_lift_begin(C, k, L, h, K, w)) return GCP_STEP_FAILED;
    if (stale && C->chart.wlift_eval_df) glw_predict(T, L, h, K, w);
    double nprev = INFINITY, thprev = 0.0;
    int refreshed = 0;
    for (int it = 0; it < GLW_MAXIT; it++) {
        double eta[GL_SMAX], r[GL_SMAX][2];
        /* the analytic Jacobian, where the chart has it: at the first
         * iterate, after an update above GLW_DFTHR (a full Newton there) or
         * one that contracted less than 10x (see the header) */
        const int adf = C->chart.wlift_eval_df &&
                        (it == 0 || nprev > GLW_DFTHR || (it > 1 && thprev > 0.1));
        for (int i = 0; i < s; i++) {
            double ae = 0.0, aP = 0.0;
            for (int j = 0; j < s; j++) ae += T->a[i][j] * K[j][0], aP += T->a[i][j] * K[j][1];
            eta[i] = L->z[1] + h * ae;
            if (adf) {
                double Fw[2][2], Fe[2];
                int have;
                if (glw_stage_df(C, k, eta[i], w[i], &o[i], g[i], pd[i], Fw, Fe, &have))
                    return GCP_STEP_FAILED;
                if (have) {
                    if (glw_df_set(L, i, &o[i], Fw, Fe)) return GCP_STEP_FAILED;
                } else if (glw_df(C, k, L, i, eta[i], w[i], &o[i], g[i])) {
                    return GCP_STEP_FAILED;
                }
            } else if (glw_stage(C, k, eta[i], w[i], NULL, &o[i], g[i], pd[i])) {
                return GCP_STEP_FAILED;
            }
            r[i][0] = L->z[2] - o[i].P[0];
            r[i][1] = L->z[3] + h * aP - o[i].P[1];
        }
        if (adf) {
            if (it > 0) refreshed = 1;
            if (gcp_gl_lift_jinv(C, L, h)) return GCP_STEP_FAILED;
        }
        /* DF at the first iterate, and once more where the first update was
         * large (a predictor far off: DF taken there is off too) or an update
         * contracted less than 10x */
        else if (C->chart.wlift_eval_df) {
            /* frozen: the last analytic one */
        } else if ((it == 0 && !stale) ||
                 (!refreshed && it > 0 && (it == 1 ? nprev > 1e-2 : thprev > 0.1))) {
            refreshed = it > 0;
            for (int i = 0; i < s; i++)
                if (glw_df(C, k, L, i, eta[i], w[i], &o[i], g[i])) return GCP_STEP_FAILED;
            if (gcp_gl_lift_jinv(C, L, h)) return GCP_STEP_FAILED;
        }
        double G[4], d[4], nd = 0.0;
        for (int i = 0; i < s; i++)
            for (int q = 0; q < 2; q++)
                G[2 * i + q] = g[i][q] - K[i][q] + L->DFp[i][q] * r[i][0] +
                               L->DF[i][q][1] * r[i][1];
        for (int a = 0; a < n; a++) {
            d[a] = 0.0;
            for (int c = 0; c < n; c++) d[a] += L->Jinv[n * a + c] * G[c];
        }
        for (int i = 0; i < s; i++) {
            double ae = 0.0, aP = 0.0;
            for (int j = 0; j < s; j++)
                ae += T->a[i][j] * d[2 * j], aP += T->a[i][j] * d[2 * j + 1];
            ae *= h, aP *= h;
            nd = glw_max(nd, glw_max(fabs(ae) / L->sc[0], fabs(aP) / L->sc[1]));
            const double b[2] = {r[i][0] - o[i].Pe[0] * ae, r[i][1] + aP - o[i].Pe[1] * ae};
            double dw[2];
            glw_solve2(o[i].Pw, b, dw);
            nd = glw_max(nd, glw_max(fabs(dw[0]) / o[i].wscale[0], fabs(dw[1]) / o[i].wscale[1]));
            w[i][0] += dw[0], w[i][1] += dw[1];
        }
        if (!isfinite(nd)) return GCP_STEP_FAILED;
        for (int i = 0; i < s; i++) K[i][0] += d[2 * i], K[i][1] += d[2 * i + 1];
        /* the tests of gc_gauss.c's lifted solver (gl_step_lift), with the
         * contraction's prediction taken 1e3 below the tolerance: at the
         * tolerance itself the last update left a bias of ~1e-16 a step in
         * the energy, a linear drift over 1e7 steps of 9e-4 of gc-gl4's
         * range in the tokamak (1e6 steps: trend 8.6e-5 of the range, 6.5e-6
         * with this) */
        const double th = nd / nprev;
        const int next_below = it > 0 && th < 1.0 && th / (1.0 - th) * nd <= 1e-3 * GLW_TOL;
        const int stalled = it > 0 && nd <= GLW_FLOOR && th > 0.5;
        /* at the floor, the contraction of the last two updates above it
         * (thprev: both above the floor, so not the round-off's ratio)
         * bounds the next update the same way: converged without the
         * iteration that "stalled" takes to see the floor (a whole chart
         * evaluation a stage; 28% (gc-gl2) and 37% (gc-gl4) of the steps in
         * DIII-D ended that way, 11% and 6% with this; iterations a step 4.54
         * -> 4.18 and 4.56 -> 3.95).  The update not taken is below 1e-18 of
         * the scales, as next_below's. */
        const int floor_next = it > 1 && nd <= GLW_FLOOR && nprev > GLW_FLOOR &&
                               thprev < 0.5 && thprev / (1.0 - thprev) * nd <= 1e-3 * GLW_TOL;
        if (it > 1 && th > 0.5 && !stalled && refreshed) return GCP_STEP_FAILED;
        if (nd <= GLW_TOL || next_below || stalled || floor_next) {
            double z1[4], t1, v[GL_SMAX][2], pe[2];
            gcp_gl_end_state(T, L, h, K, pd, z1, &t1);
            for (int i = 0; i < s; i++) {
                const double b[2] = {-o[i].Pe[0] * K[i][0], K[i][1] - o[i].Pe[1] * K[i][0]};
                glw_solve2(o[i].Pw, b, v[i]);
                v[i][0] *= h, v[i][1] *= h;
            }
            gcp_gl_end_guess(T, L->aux[0], w, v, pe);
            if (!(pe[0] > 0.0 && isfinite(pe[1]))) pe[0] = w[s - 1][0], pe[1] = w[s - 1][1];
            /* no curve slopes (NaN: have_C = 0): the next start guess is
             * the time extrapolation of the stage points (gcp_gl_lift_begin),
             * the curve P_phi = const being the dipole lift's (r, theta) */
            double nc[GL_SMAX][2];
            for (int i = 0; i < GL_SMAX; i++) nc[i][0] = nc[i][1] = NAN;
            gcp_gl_lift_end(C, L, h, K, z1, t1, w, nc, nc, pe);
            L->have_DF = 1, L->hDF = h;
            memcpy(L->wv, v, sizeof L->wv); /* glw_predict's */
            return 0;
        }
        nprev = nd;
        thprev = th;
    }
    return GCP_STEP_FAILED;
}
