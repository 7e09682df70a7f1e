/* gc-gl2 / gc-gl4 in the analytic tokamak: the flux chart's collocation
 * solve (gc_gauss_wlift.c) in closed form, fused (issue 11: cost per step).
 *
 * Why.  The generic path evaluates the flux chart (canon_flux.c) through
 * function pointers: the chart map (fields/tokamak.c tok_chart_map), a
 * field evaluation with grad B, the chart algebra, ~9 such evaluations a
 * step of gc-gl2 (F and its Jacobian by forward differences).  In the
 * analytic tokamak every quantity of the chart is a closed form of
 * (theta, r, p_par), second derivatives included, so one evaluation per
 * stage and iterate gives F, the chart residual and the exact Jacobian:
 * a full Newton, no differences, no inversion.
 *
 * Coordinates: canon_flux.c's, unchanged.  The chart (s, eta) = (r, theta)
 * about the axis (R0, 0) (fields/tokamak.c): R = R0 + r cos theta,
 * Z = r sin theta; z = (phi, theta, P_phi, P_theta),
 *   P_phi = q psi(r) + p k,      k = R b_phi = B0 R0 R/N,
 *   P_theta = q A(r, theta) + p h,   h = b . X_theta = Y r/N,
 *   Y = psi'(r) = B0 r/q(r),  N = sqrt((B0 R0)^2 + Y^2) = R |B|,
 *   A = -B0 R0^2 u^2 g(u cos theta),  u = r/R0  (tok_chart_map's A_eta),
 *   H = m c^2 gamma,  gamma^2 = 1 + (p/mc)^2 + 2 mu |B|/(m c^2),  |B| = N/R.
 * The derivatives (suffixes r, t(heta), p):
 *   Y_r = B0 (q0 - dq r^2)/q^2,  Y_rr = -2 B0 dq r (3 q0 - dq r^2)/q^3,
 *   N_r = Y Y_r/N,  N_rr = (Y_r^2 + Y Y_rr - N_r^2)/N,
 *   A_r = -B0 R0 r/R,  A_t = -B0 R0^2 u^3 sin(theta) h(u cos theta),
 *   A_rr = -B0 R0^2/R^2,  A_rt = -B0 R0 r^2 sin(theta)/R^2,
 *   A_tt = -B0 R0 (cos(theta) I2 + 2 sin^2(theta) I3),
 *   I2 = R0 u^3 h(x), I3 = int_0^r r'^3/(R0 + r' cos theta)^3 dr' = R0 u^4 j(x),
 *   g(x) = sum (-x)^k/(k+2), h(x) = sum (k+1)(-x)^k/(k+3),
 *   j(x) = sum (k+1)(k+2)(-x)^k/(2(k+4))   (x = u cos theta; from the
 *   integrals' binomial series, dI2/dcos = -2 I3),
 * and |B| R = N differentiated: |B|_r = (N_r - |B| cos)/R, |B|_t = |B| r sin/R,
 * |B|_rr = (N_rr - 2 cos |B|_r)/R, |B|_rt = (|B| sin + |B|_r r sin - |B|_t cos)/R,
 * |B|_tt = (2 |B|_t r sin + |B| r cos)/R.
 * psi(r) is taken from the start of the step, r0 (one log1p per step):
 *   psi(r) - psi(r0) = B0 (r^2 - r0^2)/(2 q(r0)) L(e),  L(e) = log1p(e)/e,
 *   e = dq (r^2 - r0^2)/q(r0)   (psi = (B0/(2 dq)) ln(q(r)/q0)).
 * The series are summed as fields/tokamak.c's (Estrin, 32 terms, |x| < 1/4:
 * the same g and h); a stage with |x| or |e| >= 1/4 (near the edge of a
 * fat plasma, or a step across much of the profile) is left to the generic
 * path (below).
 *
 * Rates and their Jacobian.  With G = (P_phi, P_theta) and w = (r, p),
 * lambda solves (dG/dw)^T lambda = dH/dw (canon_flux.c fpoint_dH):
 *   dphi/dt = lambda_1,  dtheta/dt = lambda_2,
 *   dP_theta/dt = -(H_t - lambda_1 P_phi,t - lambda_2 P_theta,t).
 * With L = H - lambda_1 P_phi - lambda_2 P_theta (lambda held), L_w = 0, and
 * along v in (theta, r, p)
 *   (dG/dw)^T dlambda/dv = (L_rv, L_pv),
 *   d(dP_theta/dt)/dv = -(L_tv - dlambda/dv . dG/dtheta),
 * from the Hessians of P_phi, P_theta and H in (theta, r, p), closed forms
 * above.  The collocation equations are gc_gauss_wlift.c's (stage points w_i
 * unknowns with K_i), and so is the update:
 *   (delta_ij I - h a_ij DF_i) d_j = F_i - K_i + M_i r_i,  M = F_w (dG/dw)^-1,
 *   DF = [F_t - M dG/dtheta, M e_2],
 * then w_i moves by (dG/dw)^-1 (r_i + (0, dP) - dG/dtheta deta); with F_w,
 * F_t exact at every iterate this is Newton's method on the whole system
 * (quadratic; the generic path's is a simplified Newton with differences).
 * Same fixed point, same tests: the update relative to gcp_gl_init's scales
 * (theta, P_theta) and the point's (a, |p| + p_perp) <= 1e-15, or the
 * contraction predicting the next below 1e-18, or stalled at the 1e-12
 * floor (gc_gauss_wlift.c's tests, constants and order).  The end point
 * (r, p) at (theta_1, P_theta_1) by Newton from the Hermite guess through
 * the stage points (gcp_gl_end_guess), the last step below 1e-9 taken without
 * a new evaluation (canon_flux.c flux_solve's xlin: R, Z are linear in r).
 * phi and theta are not wrapped differently from gc_gauss.c: phi into
 * [-pi, pi] as gcp_gl_end_state, theta free.
 *
 * Predictor: the polynomial through the last step's start, stage values and
 * this step's start (gc_gauss_dipole.c's weights, gcp_dgl_predictor_weights)
 * for the slopes, and the same nodes' Lagrange polynomial for the stage
 * points; at a lane's first step K = F(z0) at the start point.
 *
 * Generic path.  The lane is set up by gcp_gl_init (the same canonical state
 * and scales as the generic path), and a step this solver does not take (a
 * stage off the series' range or the plasma, r <= 0, non-finite numbers, an
 * update that stops contracting, 40 iterates, an end point not found) is
 * taken by the generic per-lane step (gcp_gl_step_lane) from the same
 * state: the same map, the same failures.  gcp_gl_tokamak_off (tests) sends
 * every push there; gcp_gl_tokamak_extra (tests) iterates that many times
 * past convergence (the map converged further, to round-off).  The
 * start-of-step check and the classification are the generic path's
 * (gcp_evolve_gc_check, the evolve layer). */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "block_priv.h"
#include "canon_priv.h"
#include "evolve_priv.h"
#include "flux_priv.h"
#include "gc_dipole_priv.h"
#include "gc_gauss_priv.h"
#include "gc_priv.h"

#define TGL_MAXIT 40
#define TGL_TOL 1e-15
#define TGL_FLOOR 1e-12
#define TGL_XLIN 1e-9

int gcp_gl_tokamak_off = 0;
int gcp_gl_tokamak_extra = 0;

/* the series' coefficients (fields/tokamak.c's g and h, and j, L) */
#define TGL_G(k) (1.0 / ((k) + 2))
#define TGL_H(k) ((double)((k) + 1) / ((k) + 3))
#define TGL_J(k) ((double)(((k) + 1) * ((k) + 2)) / (2 * ((k) + 4)))
#define TGL_L(k) (1.0 / ((k) + 1))
static const double tgl_gc[32] = {GCP_SERIES_32(TGL_G)}, tgl_hc[32] = {GCP_SERIES_32(TGL_H)};
static const double tgl_jc[32] = {GCP_SERIES_32(TGL_J)}, tgl_lc[32] = {GCP_SERIES_32(TGL_L)};

/* fixed for the push */
struct tgl_args {
    const struct gl_tableau *tab;
    int S;
    double wk[GL_SMAX][GL_SMAX + 2]; /* slopes: K_i = sum_n wk[i][n] v_n / h */
    double wl[GL_SMAX][GL_SMAX + 2]; /* stage points: w_i = sum_n wl[i][n] w_n */
    double B0, R0, a, q0, dq, B0R0, B0R0sq, a2;
    double q, m, mc, mcc;            /* [C], [kg], m c, m c^2 */
    struct gl_ctx C;                 /* the generic path (set-up and the steps it takes) */
};

/* a lane's state between steps (the evolve layer's lane storage) */
struct tgl_lane {
    double phi, th, Pphi, Pth;       /* z */
    double r, p;                     /* the chart point of z */
    double sc0, sc1, scp;            /* gcp_gl_init's scales (theta, P_theta, P_phi) */
    double have;                     /* 1: hist holds the last step's */
    double hist[GL_SMAX + 1][4];     /* its start and stage values (theta, P_theta, r, p) */
};

/* one evaluation at (theta, r, p) */
struct tgl_ev {
    double res0, res1;       /* the chart residual (P_phi - P_phi(w), P_t - P_theta(w)) */
    double Gw[2][2], Ge[2];  /* d(P_phi, P_theta)/d(r, p), and /dtheta */
    double psc;              /* [kg m/s] |p| + p_perp: p's scale */
    double f[2], fp;         /* (dtheta, dP_theta)/dt, dphi/dt */
    double DF[2][2], DFp[2]; /* the Jacobian of f in (theta, P_theta) at fixed P_phi, df/dP_phi */
    double dfp[3];           /* d(dphi/dt)/d(theta, r, p) */
    int bad;
};

/* mode 0: residual, dG/dw, dG/dtheta; 1: and the rates; 2: and their
 * Jacobian.  r0, iq0 = 1/q(r0), P0r = P_phi - q psi(r0): the step's start
 * (psi's reference); Pt the stage's P_theta. */
static inline __attribute__((always_inline)) void
tgl_eval(const struct tgl_args *A, const int mode, double th, double r, double p, double mu,
         double r0, double iq0, double P0r, double Pt, struct tgl_ev *e)
{
    double sn, c;
    dgl_sincos(th, &sn, &c);
    const double B0 = A->B0, B0R0 = A->B0R0, qc = A->q;
    const double R = A->R0 + r * c, iR = 1.0 / R;
    const double r2 = r * r, iq = 1.0 / (A->q0 + A->dq * r2);
    const double Y = B0 * r * iq, Yr = B0 * (A->q0 - A->dq * r2) * iq * iq;
    const double N = sqrt(A->B0R0sq + Y * Y), iN = 1.0 / N;
    const double Nr = Y * Yr * iN, m1r = -Nr * iN * iN; /* m1 = 1/N */
    const double k = B0R0 * R * iN, kr = B0R0 * (c * iN + R * m1r), kt = -B0R0 * r * sn * iN;
    const double hh = Y * r * iN, hr = (Yr * r + Y) * iN + Y * r * m1r;
    const double u = r / A->R0, x = u * c;
    const double gs = gcp_estrin32(tgl_gc, -x), hs = gcp_estrin32(tgl_hc, -x);
    const double Ath = -B0R0 * A->R0 * u * u * gs;
    const double Ar = -B0R0 * r * iR, At = -B0R0 * A->R0 * u * u * u * sn * hs;
    const double dr2 = (r - r0) * (r + r0), ep = A->dq * dr2 * iq0;
    const double dpsi = 0.5 * B0 * dr2 * iq0 * gcp_estrin32(tgl_lc, -ep);
    e->res0 = P0r - (qc * dpsi + p * k);
    e->res1 = Pt - (qc * Ath + p * hh);
    const double G00 = qc * Y + p * kr, G01 = k, G10 = qc * Ar + p * hr, G11 = hh;
    const double Ge0 = p * kt, Ge1 = qc * At;
    e->Gw[0][0] = G00, e->Gw[0][1] = G01, e->Gw[1][0] = G10, e->Gw[1][1] = G11;
    e->Ge[0] = Ge0, e->Ge[1] = Ge1;
    const double Bm = N * iR;
    e->psc = fabs(p) + sqrt(2.0 * A->m * fabs(mu) * Bm);
    e->bad = !(r > 0.0) | !(r2 <= A->a2) | !(fabs(x) < 0.25) | !(fabs(ep) < 0.25);
    if (mode == 0) return;
    const double Bmr = (Nr - Bm * c) * iR, Bmt = Bm * r * sn * iR;
    const double ap = p / A->mc;
    const double gam = sqrt(1.0 + ap * ap + 2.0 * mu * Bm / A->mcc), ig = 1.0 / gam;
    const double HB = mu * ig, Hp = p / (gam * A->m), Hr = HB * Bmr, Ht = HB * Bmt;
    const double idet = 1.0 / (G00 * G11 - G01 * G10);
    const double l0 = (G11 * Hr - G10 * Hp) * idet, l1 = (G00 * Hp - G01 * Hr) * idet;
    e->f[0] = l1, e->f[1] = -(Ht - l0 * Ge0 - l1 * Ge1), e->fp = l0;
    e->bad |= !(fabs(e->f[0]) + fabs(e->f[1]) + fabs(l0) <= DBL_MAX);
    if (mode == 1) return;
    /* second derivatives (header) */
    const double iq3 = iq * iq * iq;
    const double Yrr = -2.0 * B0 * A->dq * r * (3.0 * A->q0 - A->dq * r2) * iq3;
    const double Nrr = (Yr * Yr + Y * Yrr - Nr * Nr) * iN;
    const double m1rr = (2.0 * Nr * Nr * iN - Nrr) * iN * iN;
    const double krr = B0R0 * (2.0 * c * m1r + R * m1rr), krt = -B0R0 * sn * (iN + r * m1r);
    const double ktt = -B0R0 * r * c * iN;
    const double hrr = (Yrr * r + 2.0 * Yr) * iN + 2.0 * (Yr * r + Y) * m1r + Y * r * m1rr;
    const double iR2 = iR * iR, u3 = u * u * u;
    const double Arr = -B0R0 * A->R0 * iR2, Art = -B0R0 * r2 * sn * iR2;
    const double I2 = A->R0 * u3 * hs, I3 = A->R0 * u3 * u * gcp_estrin32(tgl_jc, -x);
    const double Att = -B0R0 * (c * I2 + 2.0 * sn * sn * I3);
    const double Bmrr = (Nrr - 2.0 * c * Bmr) * iR;
    const double Bmrt = (Bm * sn + Bmr * r * sn - Bmt * c) * iR;
    const double Bmtt = (2.0 * Bmt * r * sn + Bm * r * c) * iR;
    const double ig3 = ig * ig * ig;
    const double HBB = -mu * mu * ig3 / A->mcc, HpB = -p * mu * ig3 / (A->m * A->mcc);
    const double Hpp = ig / A->m * (1.0 - ap * ap * ig * ig);
    /* the Hessian of L = H - l0 P_phi - l1 P_theta */
    const double Ltt = HBB * Bmt * Bmt + HB * Bmtt - l0 * p * ktt - l1 * qc * Att;
    const double Lrt = HBB * Bmr * Bmt + HB * Bmrt - l0 * p * krt - l1 * qc * Art;
    const double Ltp = HpB * Bmt - l0 * kt;
    const double Lrr = HBB * Bmr * Bmr + HB * Bmrr - l0 * (qc * Yr + p * krr) - l1 * (qc * Arr + p * hrr);
    const double Lrp = HpB * Bmr - l0 * kr - l1 * hr;
    const double Lpp = Hpp;
    /* dlambda along theta, r, p; the rates' derivatives */
    const double La[3] = {Lrt, Lrr, Lrp}, Lb[3] = {Ltp, Lrp, Lpp}, Lc[3] = {Ltt, Lrt, Ltp};
    double F1[3], F2[3];
    for (int v = 0; v < 3; v++) {
        const double d0 = (G11 * La[v] - G10 * Lb[v]) * idet, d1 = (G00 * Lb[v] - G01 * La[v]) * idet;
        F1[v] = d1;
        F2[v] = -(Lc[v] - d0 * Ge0 - d1 * Ge1);
        e->dfp[v] = d0;
    }
    /* M = F_w (dG/dw)^-1, DF = [F_t - M Ge, M e2], DFp = M e1 */
    const double Gi00 = G11 * idet, Gi01 = -G01 * idet, Gi10 = -G10 * idet, Gi11 = G00 * idet;
    const double *Fq[2] = {F1, F2};
    for (int q = 0; q < 2; q++) {
        const double M0 = Fq[q][1] * Gi00 + Fq[q][2] * Gi10, M1 = Fq[q][1] * Gi01 + Fq[q][2] * Gi11;
        e->DF[q][0] = Fq[q][0] - (M0 * Ge0 + M1 * Ge1);
        e->DF[q][1] = M1;
        e->DFp[q] = M0;
    }
}

/* psi(r) as fields/tokamak.c tok_psi */
static double tgl_psi(const struct tgl_args *A, double r)
{
    const double r2 = r * r, v = A->dq * r2 / A->q0;
    const double lv = v != 0.0 ? log1p(v) / v : 1.0;
    return A->B0 * r2 / (2.0 * A->q0) * lv;
}

/* One step of lane l (magnetic moment mu): 0 with l advanced and the end
 * point X, p_par, or -1 with l untouched (the generic path takes it). */
static inline __attribute__((always_inline)) int
tgl_step(const int S, const struct tgl_args *A, struct tgl_lane *l, double mu, double h,
         double X[3], double *ppar)
{
    const struct gl_tableau *T = A->tab;
    const double r0 = l->r, p0 = l->p, th0 = l->th, P0 = l->Pth;
    const double iq0 = 1.0 / (A->q0 + A->dq * r0 * r0);
    const double P0r = l->Pphi - A->q * tgl_psi(A, r0);
    double K[GL_SMAX][2], w[GL_SMAX][2], fp[GL_SMAX];
    struct tgl_ev e[GL_SMAX];
    if (l->have != 0.0) {
        const double cur[4] = {th0, P0, r0, p0};
        for (int i = 0; i < S; i++) {
            for (int c = 0; c < 2; c++) {
                double v = A->wk[i][S + 1] * cur[c], y = A->wl[i][S + 1] * cur[2 + c];
                for (int n = 0; n <= S; n++)
                    v += A->wk[i][n] * l->hist[n][c], y += A->wl[i][n] * l->hist[n][2 + c];
                K[i][c] = v / h, w[i][c] = y;
            }
        }
    } else {
        tgl_eval(A, 1, th0, r0, p0, mu, r0, iq0, P0r, P0, &e[0]);
        if (e[0].bad) return -1;
        for (int i = 0; i < S; i++) K[i][0] = e[0].f[0], K[i][1] = e[0].f[1], w[i][0] = r0, w[i][1] = p0;
    }
    double nprev = INFINITY, thprev = 0.0;
    int it = 0, past = 0;
    for (;; it++) {
        if (it == TGL_MAXIT) return -1;
        double DF[GL_SMAX][2][2], G[4], Jinv[16], d[4];
        for (int i = 0; i < S; i++) {
            double ae = 0.0, aP = 0.0;
            for (int j = 0; j < S; j++) ae += T->a[i][j] * K[j][0], aP += T->a[i][j] * K[j][1];
            tgl_eval(A, 2, th0 + h * ae, w[i][0], w[i][1], mu, r0, iq0, P0r, P0 + h * aP, &e[i]);
            if (e[i].bad) return -1;
            for (int q = 0; q < 2; q++) {
                G[2 * i + q] = e[i].f[q] - K[i][q] + e[i].DFp[q] * e[i].res0 + e[i].DF[q][1] * e[i].res1;
                DF[i][q][0] = e[i].DF[q][0], DF[i][q][1] = e[i].DF[q][1];
            }
        }
        if (!gcp_gl_jinv_blocks(T, S, h, DF, Jinv)) return -1;
        for (int a = 0; a < 2 * S; a++) {
            d[a] = 0.0;
            for (int c = 0; c < 2 * S; c++) d[a] += Jinv[2 * S * a + c] * G[c];
        }
        double nd = 0.0;
        for (int i = 0; i < S; i++) {
            double ae = 0.0, aP = 0.0;
            for (int j = 0; j < S; j++) ae += T->a[i][j] * d[2 * j], aP += T->a[i][j] * d[2 * j + 1];
            ae *= h, aP *= h;
            nd = fmax(nd, fmax(fabs(ae) / l->sc0, fabs(aP) / l->sc1));
            const double b0 = e[i].res0 - e[i].Ge[0] * ae, b1 = e[i].res1 + aP - e[i].Ge[1] * ae;
            const double (*Gw)[2] = e[i].Gw;
            const double det = Gw[0][0] * Gw[1][1] - Gw[0][1] * Gw[1][0];
            const double dw0 = (Gw[1][1] * b0 - Gw[0][1] * b1) / det;
            const double dw1 = (-Gw[1][0] * b0 + Gw[0][0] * b1) / det;
            nd = fmax(nd, fmax(fabs(dw0) / A->a, fabs(dw1) / e[i].psc));
            w[i][0] += dw0, w[i][1] += dw1;
            /* phi's rate linearised to the update (its error then O(update^2):
             * quadratic convergence ends on updates of up to ~1e-9, whose
             * first order in a quadrature would drift) */
            fp[i] = e[i].fp + e[i].dfp[0] * ae + e[i].dfp[1] * dw0 + e[i].dfp[2] * dw1;
        }
        if (!isfinite(nd) || !isfinite(d[0] + d[1] + d[2 * S - 2] + d[2 * S - 1])) return -1;
        for (int i = 0; i < S; i++) K[i][0] += d[2 * i], K[i][1] += d[2 * i + 1];
        /* gc_gauss_wlift.c's tests */
        const double th = nd / nprev;
        const int next_below = it > 0 && th < 1.0 && th / (1.0 - th) * nd <= 1e-3 * TGL_TOL;
        const int stalled = it > 0 && nd <= TGL_FLOOR && th > 0.5;
        const int floor_next = it > 1 && nd <= TGL_FLOOR && nprev > TGL_FLOOR && thprev < 0.5 &&
                               thprev / (1.0 - thprev) * nd <= 1e-3 * TGL_TOL;
        if (it > 1 && th > 0.5 && !stalled) return -1;
        const int conv = nd <= TGL_TOL || next_below || stalled || floor_next;
        if ((conv || past) && past++ >= gcp_gl_tokamak_extra) break;
        nprev = nd;
        thprev = th;
    }
    /* the end state (gcp_gl_end_state) */
    double de = 0.0, dP = 0.0, dphi = 0.0;
    for (int i = 0; i < S; i++) de += T->b[i] * K[i][0], dP += T->b[i] * K[i][1], dphi += T->b[i] * fp[i];
    const double phi = l->phi + h * dphi, tp = 2.0 * GCP_PI;
    double phi1;
    if (fabs(phi) <= GCP_PI) phi1 = phi;
    else if (phi > GCP_PI && phi < 3.0 * GCP_PI) phi1 = phi - tp;
    else if (phi < -GCP_PI && phi > -3.0 * GCP_PI) phi1 = phi + tp;
    else phi1 = remainder(phi, tp);
    const double th1 = th0 + h * de, P1 = P0 + h * dP;
    /* the end point: the Hermite guess, then Newton on the chart */
    double v[GL_SMAX][2] = {{0.0}}, pe[2]; /* rows past S unread (T->s == S) */
    for (int i = 0; i < S; i++) {
        const double (*Gw)[2] = e[i].Gw;
        const double b0 = -e[i].Ge[0] * K[i][0], b1 = K[i][1] - e[i].Ge[1] * K[i][0];
        const double det = Gw[0][0] * Gw[1][1] - Gw[0][1] * Gw[1][0];
        v[i][0] = h * ((Gw[1][1] * b0 - Gw[0][1] * b1) / det);
        v[i][1] = h * ((-Gw[1][0] * b0 + Gw[0][0] * b1) / det);
    }
    const double w0[2] = {r0, p0};
    gcp_gl_end_guess(T, w0, w, v, pe);
    if (!(pe[0] > 0.0 && isfinite(pe[1]))) pe[0] = w[S - 1][0], pe[1] = w[S - 1][1];
    double r1 = pe[0], p1 = pe[1];
    for (int k = 0;; k++) {
        if (k == 20) return -1;
        struct tgl_ev o;
        tgl_eval(A, 0, th1, r1, p1, mu, r0, iq0, P0r, P1, &o);
        if (o.bad) return -1;
        const double det = o.Gw[0][0] * o.Gw[1][1] - o.Gw[0][1] * o.Gw[1][0];
        const double ds = (o.Gw[1][1] * o.res0 - o.Gw[0][1] * o.res1) / det;
        const double dp = (-o.Gw[1][0] * o.res0 + o.Gw[0][0] * o.res1) / det;
        const double ee = fmax(fabs(ds) / A->a, fabs(dp) / o.psc);
        if (!isfinite(ee)) return -1;
        r1 += ds, p1 += dp;
        if (ee < TGL_XLIN) break;
    }
    if (!(r1 > 0.0)) return -1;
    /* commit */
    l->hist[0][0] = th0, l->hist[0][1] = P0, l->hist[0][2] = r0, l->hist[0][3] = p0;
    for (int i = 0; i < S; i++) {
        double ae = 0.0, aP = 0.0;
        for (int j = 0; j < S; j++) ae += T->a[i][j] * K[j][0], aP += T->a[i][j] * K[j][1];
        l->hist[1 + i][0] = th0 + h * ae, l->hist[1 + i][1] = P0 + h * aP;
        l->hist[1 + i][2] = w[i][0], l->hist[1 + i][3] = w[i][1];
    }
    l->have = 1.0;
    l->phi = phi1, l->th = th1, l->Pth = P1, l->r = r1, l->p = p1;
    double st, ct, sp, cp;
    dgl_sincos(th1, &st, &ct);
    dgl_sincos(phi1, &sp, &cp);
    const double R = A->R0 + r1 * ct;
    X[0] = R * cp, X[1] = R * sp, X[2] = r1 * st;
    *ppar = p1;
    return 0;
}

static int tgl_step_s1(const struct tgl_args *A, struct tgl_lane *l, double mu, double h,
                       double X[3], double *ppar)
{
    return tgl_step(1, A, l, mu, h, X, ppar);
}

static int tgl_step_s2(const struct tgl_args *A, struct tgl_lane *l, double mu, double h,
                       double X[3], double *ppar)
{
    return tgl_step(2, A, l, mu, h, X, ppar);
}

static int tgl_init(const struct gcp_evolve *ev, void *vctx, const struct gcp_block *b, size_t i,
                    double t, void *vlane)
{
    (void)ev;
    const struct tgl_args *A = vctx;
    struct tgl_lane *l = vlane;
    struct gl_lane g;
    const int r = gcp_gl_init(&A->C, b, i, t, &g);
    if (r) return r;
    memset(l, 0, sizeof *l);
    l->phi = g.z[0], l->th = g.z[1], l->Pphi = g.z[2], l->Pth = g.z[3];
    l->r = g.aux[0][0], l->p = g.aux[0][1];
    l->sc0 = g.sc[0], l->sc1 = g.sc[1], l->scp = g.sc_pphi;
    return 0;
}

/* One step of the n live lanes: the closed form, or for a lane it does not
 * take, the generic per-lane step from the same state. */
static int32_t tgl_step_lanes(const struct gcp_evolve *ev, void *vctx, struct gcp_block *b,
                              size_t n, double t, double h, unsigned char *lanes)
{
    (void)ev, (void)t;
    const struct tgl_args *A = vctx;
    int32_t failed = 0;
    for (size_t i = 0; i < n; i++) {
        struct tgl_lane *l = (struct tgl_lane *)(lanes + i * sizeof *l);
        double X[3], pp;
        const int r = A->S == 1 ? tgl_step_s1(A, l, b->mu[i], h, X, &pp)
                                : tgl_step_s2(A, l, b->mu[i], h, X, &pp);
        if (r == 0) {
            b->x[i] = X[0], b->y[i] = X[1], b->z[i] = X[2], b->ppar[i] = pp;
            b->fstatus[i] = 0;
            continue;
        }
        struct gl_lane g;
        memset(&g, 0, sizeof g);
        g.z[0] = l->phi, g.z[1] = l->th, g.z[2] = l->Pphi, g.z[3] = l->Pth;
        for (int j = 0; j <= GL_SMAX; j++) g.aux[j][0] = l->r, g.aux[j][1] = l->p;
        g.sc[0] = l->sc0, g.sc[1] = l->sc1, g.sc_pphi = l->scp;
        const int rg = gcp_gl_step_lane(&A->C, b, i, h, &g, 1);
        if (rg) {
            b->status[i] = rg, failed = 1;
            continue;
        }
        l->phi = g.z[0], l->th = g.z[1], l->Pphi = g.z[2], l->Pth = g.z[3];
        l->r = g.aux[0][0], l->p = g.aux[0][1];
        l->have = 0.0;
    }
    return failed;
}

static const struct gcp_stepper tgl_stepper = {
    .gc = 1,
    .lane_size = sizeof(struct tgl_lane),
    .init = tgl_init,
    .start = gcp_evolve_gc_check,
    .step_lanes = tgl_step_lanes,
};

int gcp_gl_tokamak_advance(struct gcp_block *b, const struct gcp_field *f,
                           const struct gcp_push_opts *o, const struct gcp_sampler *smp,
                           const struct gl_tableau *tab, size_t *live)
{
    struct gcp_flux_tokamak tk;
    if (gcp_gl_tokamak_off || !gcp_field_flux_tokamak(f, &tk) || f->has_E || f->time_dependent)
        return -1;
    if (!(b->q != 0.0) || !(b->m > 0.0)) return -1;
    struct tgl_args *A = calloc(1, sizeof *A);
    if (!A) return -1;
    char why[256];
    A->C.tab = tab;
    gcp_gl_ctx_weights(&A->C);
    if (gcp_canon_chart_create(f, &A->C.chart, why, sizeof why)) {
        free(A);
        return -1;
    }
    A->tab = tab, A->S = tab->s;
    gcp_dgl_predictor_weights(tab, A->wk);
    /* Lagrange weights of the nodes -1, -1 + c_j, 0 at c_i */
    double x[GL_SMAX + 2];
    x[0] = -1.0, x[A->S + 1] = 0.0;
    for (int j = 0; j < A->S; j++) x[1 + j] = -1.0 + tab->c[j];
    for (int i = 0; i < A->S; i++)
        for (int nn = 0; nn < A->S + 2; nn++) {
            double v = 1.0;
            for (int j = 0; j < A->S + 2; j++)
                if (j != nn) v *= (tab->c[i] - x[j]) / (x[nn] - x[j]);
            A->wl[i][nn] = v;
        }
    A->B0 = tk.B0, A->R0 = tk.R0, A->a = tk.a, A->q0 = tk.q0, A->dq = tk.dq;
    A->B0R0 = tk.B0 * tk.R0, A->B0R0sq = A->B0R0 * A->B0R0, A->a2 = tk.a * tk.a;
    A->q = b->q, A->m = b->m, A->mc = b->m * GCP_C_LIGHT, A->mcc = A->mc * GCP_C_LIGHT;
    *live = gcp_evolve(b, f, o, smp, &tgl_stepper, A);
    gcp_canon_chart_destroy(&A->C.chart);
    free(A);
    return 0;
}
