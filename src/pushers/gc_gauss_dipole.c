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
 * at the end of each call for the samplers and the classification. */
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
#include "gc_gauss_priv.h"
#include "gc_priv.h"

#define DGL_TILE 64
#define DGL_MAXIT 24
#define DGL_TOL 1e-15
#define DGL_PI 3.14159265358979323846

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

/* what every tile needs, fixed for the push */
struct dgl_args {
    int S;                           /* stages */
    double a[GL_SMAX][GL_SMAX], b[GL_SMAX];
    double wk[GL_SMAX][GL_SMAX + 2]; /* predictor: K_i = sum_n wk[i][n] v_n / h */
    double k;                        /* [T m^3] the dipole's constant */
    double sgk;                      /* sgn(k) */
    double mc;                       /* [kg m/s] */
    double q, m;                     /* [C], [kg] */
    double rin2, rout2, zmax;        /* the field's bounds (gcp_block_classify's) */
    double amax2;                    /* adiabaticity_max^2 (0: no check) */
};

struct dgl_ctx {
    struct dgl_args A;
    unsigned char *save_lanes; /* [n lane] the lanes at the start of a call */
    double *save_X;            /* [4 n] x, y, z, p_par at the start of a call */
    int64_t *done;             /* [tiles] steps each tile took */
    size_t nmax;
};

/* The reduced Hamiltonian's derivatives at (s, Q): F = (ds, dQ)/dtau, its
 * Jacobian D (D22 = -D11), and the phi' rate P with its gradient
 * (Ps, PQ).  See the file's header for the formulas; Gamma_ss from
 *   d/ds (s/T^2) = (1 - 9 s^2)/T^3,
 *   d/ds (N/(g W^4)) = (N' - 3 s N/T + 8 s N/W)/(g W^4),  N' = 3 + 15 s^2. */
struct dgl_ev {
    double F1, F2, D11, D12, D21, P, Ps, PQ;
};

static inline __attribute__((always_inline)) struct dgl_ev
dip_eval(double s, double Q, double beta, double w)
{
    struct dgl_ev e;
    const double s2 = s * s;
    const double T = 1.0 + 3.0 * s2, W = 1.0 - s2;
    const double iTW = 1.0 / (T * W);
    const double iT = W * iTW, iW = T * iTW;
    const double g = sqrt(T), ig = g * iT;
    const double iW2 = iW * iW, iW3 = iW2 * iW, iW4 = iW2 * iW2;
    const double Bt = g * iW3;
    const double Q2T = Q * Q * iT;
    const double Gam = 1.0 + Q2T + beta * Bt;
    const double gam = sqrt(Gam), igam = 1.0 / gam, igam2 = igam * igam;
    const double N = s * (3.0 + 5.0 * s2);
    const double Bs = 3.0 * N * ig * iW4; /* d(g/W^3)/ds */
    const double Gs = -6.0 * s * Q2T * iT + beta * Bs;
    const double gs = 0.5 * Gs * igam;   /* dgamma/ds */
    const double F1 = Q * iT * igam;     /* = dgamma/dQ */
    e.F1 = F1;
    e.F2 = -gs;
    e.D11 = -F1 * (6.0 * s * iT + gs * igam);
    e.D12 = iT * igam * (1.0 - Q2T * igam2);
    const double Bss = 3.0 * ig * iW4 * ((3.0 + 15.0 * s2) - 3.0 * s * N * iT + 8.0 * s * N * iW);
    const double Gss = -6.0 * Q2T * (1.0 - 9.0 * s2) * iT * iT + beta * Bss;
    e.D21 = -0.5 * Gss * igam + gs * gs * igam;
    const double Aph = Q2T + 1.5 * beta * Bt;
    e.P = w * Aph * igam;
    e.Ps = w * ((-6.0 * s * Q2T * iT + 1.5 * beta * Bs) * igam - Aph * gs * igam2);
    e.PQ = w * (2.0 * Q * iT * igam - Aph * F1 * igam2);
    return e;
}

/* Whether the adiabaticity of gcp_gc_adiabaticity_of exceeds amax at (s, Q)
 * on line L: with r = L W, rho_perp = p_perp/(|q| B), rho = p/(|q| B),
 *   |grad B|/B = 3 sqrt(1 + 7 s^2 + 8 s^4)/(r T),
 *   |kappa| = 3 (1 + s^2)/(L sqrt(W) T g)   (the line's curvature),
 * e1 = rho_perp |grad B|/B, e2 = rho |kappa|, e = max(e1, e2) > amax as
 *   9 p_perp^2 (1 + 7 s^2 + 8 s^4) > amax^2 q^2 B^2 r^2 T^2,
 *   9 p^2 (1 + s^2)^2 > amax^2 q^2 B^2 L^2 W T^3,
 * p_perp^2 = 2 m mu B, p^2 = p_par^2 + p_perp^2, p_par^2 = (m c Q)^2/T:
 * one square root (g, for B), no division.  Non-finite or |s| >= 1: 1. */
static inline __attribute__((always_inline)) int32_t
dip_stops(double s, double Q, double L, double beta, const struct dgl_args *A)
{
    const double s2 = s * s, T = 1.0 + 3.0 * s2, W = 1.0 - s2;
    const int ok = (fabs(s) < 1.0) & (fabs(Q) <= DBL_MAX);
    if (!(A->amax2 > 0.0)) return !ok;
    const double g = sqrt(fabs(T));
    const double W3 = W * W * W, L3 = L * L * L;
    const double B = fabs(A->k) * g, Bden = L3 * W3; /* |B| = B / Bden */
    /* p_perp^2 = 2 m mu |B| = beta (m c)^2 g/W^3 (beta = 2 mu |k|/(m c^2 L^3)) */
    const double mc2 = A->mc * A->mc;
    const double pperp2 = beta * mc2 * g; /* times 1/W^3 */
    const double ppar2 = mc2 * Q * Q;     /* times 1/T */
    const double r = L * W;
    const double qB2 = A->q * A->q * B * B; /* times 1/Bden^2 */
    /* e1: 9 pperp2/W^3 (1 + 7 s^2 + 8 s^4) > amax^2 qB2/Bden^2 r^2 T^2
     *     (times W^3 Bden^2, both sides positive) */
    const double c1 = 9.0 * pperp2 * (1.0 + 7.0 * s2 + 8.0 * s2 * s2) * Bden * Bden;
    const double d1 = A->amax2 * qB2 * r * r * T * T * W3;
    /* e2: 9 (ppar2/T + pperp2/W^3) (1 + s^2)^2 > amax^2 qB2/Bden^2 L^2 W T^3
     *     (times T W^3 Bden^2) */
    const double c2 = 9.0 * (ppar2 * W3 + pperp2 * T) * (1.0 + s2) * (1.0 + s2) * Bden * Bden;
    const double d2 = A->amax2 * qB2 * L * L * W * T * T * T * T * W3;
    return (!ok) | (!(c1 <= d1)) | (!(c2 <= d2));
}

/* A tile's lanes as arrays (gathered from the lane storage for a call). */
struct dgl_tile {
    double s[DGL_TILE], Q[DGL_TILE], phip[DGL_TILE], L[DGL_TILE], beta[DGL_TILE];
    double hh[DGL_TILE], w[DGL_TILE], iqsc[DGL_TILE], have[DGL_TILE];
    double hist[GL_SMAX + 1][2][DGL_TILE];
    double K[GL_SMAX][2][DGL_TILE]; /* stage slopes (ds, dQ)/dtau */
    double Kp[GL_SMAX][DGL_TILE];   /* stage rates dphi'/dtau */
    double ndp[DGL_TILE];           /* the last update's size */
    double act[DGL_TILE];           /* 1: iterating */
    double fail[DGL_TILE];          /* 1: the step failed (no convergence, non-finite) */
};

/* The predictor (see the header): K_i = sum_n wk[i][n] v_n / h over the
 * nodes v = (last start, last stages, this start); K = 0 without a last
 * step. */
static inline __attribute__((always_inline)) void
dgl_predict(const int S, const struct dgl_args *restrict A, struct dgl_tile *restrict t, size_t nt)
{
    for (size_t i = 0; i < nt; i++) {
        const double ih = t->have[i] / t->hh[i];
        for (int st = 0; st < S; st++)
            for (int c = 0; c < 2; c++) {
                double v = A->wk[st][S + 1] * (c ? t->Q[i] : t->s[i]);
                for (int n = 0; n <= S; n++) v += A->wk[st][n] * t->hist[n][c][i];
                t->K[st][c][i] = v * ih;
            }
        t->act[i] = 1.0, t->fail[i] = 0.0, t->ndp[i] = INFINITY;
    }
}

/* One Newton iterate over the tile's lanes (see the header: full Newton on
 * K_i - F(Y_i) = 0 with the 2s x 2s Jacobian by 2 x 2 blocks).  Returns
 * whether any lane is still iterating. */
static inline __attribute__((always_inline)) int
dgl_iterate(const int S, const struct dgl_args *restrict A, struct dgl_tile *restrict t,
            size_t nt, int it)
{
    const double a11 = A->a[0][0], a12 = A->a[0][1], a21 = A->a[1][0], a22 = A->a[1][1];
    int any = 0;
    for (size_t i = 0; i < nt; i++) {
        const double h = t->hh[i], s0 = t->s[i], Q0 = t->Q[i], bt = t->beta[i], w = t->w[i];
        const double K1s = t->K[0][0][i], K1Q = t->K[0][1][i];
        const double K2s = S == 2 ? t->K[1][0][i] : 0.0, K2Q = S == 2 ? t->K[1][1][i] : 0.0;
        double x1s, x1Q, x2s = 0.0, x2Q = 0.0, P1, P1s, P1Q, P2 = 0.0, P2s = 0.0, P2Q = 0.0;
        if (S == 1) {
            const struct dgl_ev e = dip_eval(s0 + h * a11 * K1s, Q0 + h * a11 * K1Q, bt, w);
            const double r1 = e.F1 - K1s, r2 = e.F2 - K1Q;
            /* (I - h a11 D) x = r */
            const double m11 = 1.0 - h * a11 * e.D11, m12 = -h * a11 * e.D12;
            const double m21 = -h * a11 * e.D21, m22 = 1.0 + h * a11 * e.D11;
            const double id = 1.0 / (m11 * m22 - m12 * m21);
            x1s = (m22 * r1 - m12 * r2) * id;
            x1Q = (m11 * r2 - m21 * r1) * id;
            P1 = e.P, P1s = e.Ps, P1Q = e.PQ;
        } else {
            const struct dgl_ev e1 = dip_eval(s0 + h * (a11 * K1s + a12 * K2s),
                                              Q0 + h * (a11 * K1Q + a12 * K2Q), bt, w);
            const struct dgl_ev e2 = dip_eval(s0 + h * (a21 * K1s + a22 * K2s),
                                              Q0 + h * (a21 * K1Q + a22 * K2Q), bt, w);
            const double r1s = e1.F1 - K1s, r1Q = e1.F2 - K1Q;
            const double r2s = e2.F1 - K2s, r2Q = e2.F2 - K2Q;
            /* J = [[Am, Bm], [Cm, Dm]]: Am = I - h a11 D1, Bm = -h a12 D1,
             * Cm = -h a21 D2, Dm = I - h a22 D2 */
            const double A11 = 1.0 - h * a11 * e1.D11, A12 = -h * a11 * e1.D12;
            const double A21 = -h * a11 * e1.D21, A22 = 1.0 + h * a11 * e1.D11;
            const double B11 = -h * a12 * e1.D11, B12 = -h * a12 * e1.D12;
            const double B21 = -h * a12 * e1.D21, B22 = h * a12 * e1.D11;
            const double C11 = -h * a21 * e2.D11, C12 = -h * a21 * e2.D12;
            const double C21 = -h * a21 * e2.D21, C22 = h * a21 * e2.D11;
            const double D11 = 1.0 - h * a22 * e2.D11, D12 = -h * a22 * e2.D12;
            const double D21 = -h * a22 * e2.D21, D22 = 1.0 + h * a22 * e2.D11;
            const double iA = 1.0 / (A11 * A22 - A12 * A21);
            const double Ai11 = A22 * iA, Ai12 = -A12 * iA, Ai21 = -A21 * iA, Ai22 = A11 * iA;
            /* X = A^-1 B, y = A^-1 r1 */
            const double X11 = Ai11 * B11 + Ai12 * B21, X12 = Ai11 * B12 + Ai12 * B22;
            const double X21 = Ai21 * B11 + Ai22 * B21, X22 = Ai21 * B12 + Ai22 * B22;
            const double y1 = Ai11 * r1s + Ai12 * r1Q, y2 = Ai21 * r1s + Ai22 * r1Q;
            /* S = D - C X, x2 = S^-1 (r2 - C y), x1 = y - X x2 */
            const double S11 = D11 - (C11 * X11 + C12 * X21), S12 = D12 - (C11 * X12 + C12 * X22);
            const double S21 = D21 - (C21 * X11 + C22 * X21), S22 = D22 - (C21 * X12 + C22 * X22);
            const double g1 = r2s - (C11 * y1 + C12 * y2), g2 = r2Q - (C21 * y1 + C22 * y2);
            const double iS = 1.0 / (S11 * S22 - S12 * S21);
            x2s = (S22 * g1 - S12 * g2) * iS;
            x2Q = (S11 * g2 - S21 * g1) * iS;
            x1s = y1 - (X11 * x2s + X12 * x2Q);
            x1Q = y2 - (X21 * x2s + X22 * x2Q);
            P1 = e1.P, P1s = e1.Ps, P1Q = e1.PQ;
            P2 = e2.P, P2s = e2.Ps, P2Q = e2.PQ;
        }
        /* the stage values' update and the phi' rates linearised to it */
        const double d1s = h * (a11 * x1s + (S == 2 ? a12 * x2s : 0.0));
        const double d1Q = h * (a11 * x1Q + (S == 2 ? a12 * x2Q : 0.0));
        const double d2s = S == 2 ? h * (a21 * x1s + a22 * x2s) : 0.0;
        const double d2Q = S == 2 ? h * (a21 * x1Q + a22 * x2Q) : 0.0;
        const double iq = t->iqsc[i];
        /* a sum, not fmax: a NaN must reach the test (fmax drops it) */
        double nd = fabs(d1s) + fabs(d1Q) * iq;
        if (S == 2) nd += fabs(d2s) + fabs(d2Q) * iq;
        const int act = t->act[i] != 0.0;
        const double theta = nd / t->ndp[i];
        const int conv = (nd <= DGL_TOL) | ((it > 0) & (theta < 1.0) &
                                            (theta * nd <= DGL_TOL * (1.0 - theta)));
        /* non-finite, or no longer contracting above round-off */
        const int bad = (!(nd <= DBL_MAX)) | ((it > 2) & (!(theta < 0.9)) & (nd > 1e-12));
        if (act) {
            t->K[0][0][i] = K1s + x1s, t->K[0][1][i] = K1Q + x1Q;
            t->Kp[0][i] = P1 + P1s * d1s + P1Q * d1Q;
            if (S == 2) {
                t->K[1][0][i] = K2s + x2s, t->K[1][1][i] = K2Q + x2Q;
                t->Kp[1][i] = P2 + P2s * d2s + P2Q * d2Q;
            }
            t->ndp[i] = nd;
        }
        const int still = act & !conv & !bad;
        t->fail[i] = (t->fail[i] != 0.0) | (act & bad);
        t->act[i] = still;
        any |= still;
    }
    return any;
}

/* The step's end for lane i: y1 = y0 + h sum b_i K_i, phi' likewise, and
 * the history (start, stage values) for the next predictor. */
static inline __attribute__((always_inline)) void
dgl_commit(const int S, const struct dgl_args *restrict A, struct dgl_tile *restrict t, size_t i)
{
    const double h = t->hh[i], s0 = t->s[i], Q0 = t->Q[i];
    t->hist[0][0][i] = s0, t->hist[0][1][i] = Q0;
    double ds = 0.0, dQ = 0.0, dp = 0.0;
    for (int st = 0; st < S; st++) {
        double ys = 0.0, yQ = 0.0;
        for (int j = 0; j < S; j++) ys += A->a[st][j] * t->K[j][0][i], yQ += A->a[st][j] * t->K[j][1][i];
        t->hist[1 + st][0][i] = s0 + h * ys, t->hist[1 + st][1][i] = Q0 + h * yQ;
        ds += A->b[st] * t->K[st][0][i], dQ += A->b[st] * t->K[st][1][i];
        dp += A->b[st] * t->Kp[st][i];
    }
    /* phi' kept in [-pi, pi] at every step (an angle grown to 1e3 rad would
     * have an ulp above the Newton tolerance; per step, so that the numbers
     * do not depend on how the push is sliced into calls) */
    double pp = t->phip[i] + h * dp;
    pp = fabs(pp) > DGL_PI ? pp - 2.0 * DGL_PI * rint(pp * (0.5 / DGL_PI)) : pp;
    t->s[i] = s0 + h * ds, t->Q[i] = Q0 + h * dQ, t->phip[i] = pp;
    t->have[i] = 1.0;
}

/* Up to kmax steps of the tile.  mode 0 (the evolve layer's `steps`):
 * stops before a step whose start check stops a lane or whose solve fails
 * for one, and after a step after which one stops (gcp_lane_stops);
 * returns the steps taken.  mode 1 (one step, after the evolve layer's
 * start check): lanes whose solve fails keep their state and get
 * t->fail = 1; returns 1. */
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
        while (dgl_iterate(S, A, t, nt, it) && ++it < DGL_MAXIT) {
        }
        /* fail: 1 no convergence (or a non-finite iterate), 2 a converged
         * step whose stage or end point is off the chart, |s| >= 1 (past the
         * line's pole, where W = cos^2(lat) <= 0) */
        int32_t failed = 0;
        for (size_t i = 0; i < nt; i++) {
            double off = 0.0, ds = 0.0;
            for (int st = 0; st < S; st++) {
                double ys = 0.0;
                for (int j = 0; j < S; j++) ys += A->a[st][j] * t->K[j][0][i];
                off = fmax(off, fabs(t->s[i] + t->hh[i] * ys));
                ds += A->b[st] * t->K[st][0][i];
            }
            const double s1 = t->s[i] + t->hh[i] * ds;
            const int chart = !(off < 1.0) | !(fabs(s1) < 1.0);
            const int nc = (t->fail[i] != 0.0) | (t->act[i] != 0.0);
            t->fail[i] = nc ? 1.0 : chart ? 2.0 : 0.0;
            failed |= t->fail[i] != 0.0;
        }
        if (mode == 0 && failed) return k;
        int32_t stop = 0;
        for (size_t i = 0; i < nt; i++) {
            if (t->fail[i] != 0.0) continue;
            dgl_commit(S, A, t, i);
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

/* cos and sin of |x| <= ~4 (phi' in [-pi, pi] plus the shift), branch free
 * so the scatter loop vectorises (libm's sincos is a call per lane: at one
 * step per call, a sampler at every step, it cost half the step).  Cody &
 * Waite's reduction r = x - k pi/2, k = rint(2x/pi), with pi/2 split in
 * two parts (fdlibm's pio2_1 of 33 bits, k pio2_1 exact, and its tail),
 * then Taylor's series on
 * |r| <= pi/4 to r^17 / r^18 (truncation < 1e-19); error ~1 ulp of the
 * result, for the written X only (the state is phi'). */
static inline __attribute__((always_inline)) void dgl_sincos(double x, double *sn, double *cs)
{
    const double k = rint(x * 0.63661977236758134308);
    const double r = (x - k * 1.57079632673412561417e+00) - k * 6.07710050650619224932e-11;
    const double r2 = r * r;
    double ps = 1.0 / 355687428096000.0;
    ps = ps * r2 - 1.0 / 1307674368000.0;
    ps = ps * r2 + 1.0 / 6227020800.0;
    ps = ps * r2 - 1.0 / 39916800.0;
    ps = ps * r2 + 1.0 / 362880.0;
    ps = ps * r2 - 1.0 / 5040.0;
    ps = ps * r2 + 1.0 / 120.0;
    ps = ps * r2 - 1.0 / 6.0;
    const double s0 = r + r * r2 * ps;
    double pc = -1.0 / 6402373705728000.0;
    pc = pc * r2 + 1.0 / 20922789888000.0;
    pc = pc * r2 - 1.0 / 87178291200.0;
    pc = pc * r2 + 1.0 / 479001600.0;
    pc = pc * r2 - 1.0 / 3628800.0;
    pc = pc * r2 + 1.0 / 40320.0;
    pc = pc * r2 - 1.0 / 720.0;
    pc = pc * r2 + 1.0 / 24.0;
    const double c0 = 1.0 - 0.5 * r2 + r2 * r2 * pc;
    /* quadrant q = k mod 4: (sin, cos) = (s0, c0), (c0, -s0), (-s0, -c0), (-c0, s0) */
    /* k of a non-finite x would make the conversion undefined: 0 (the
     * result is then NaN through r) */
    const long q = (long)(fabs(k) < 1e9 ? k : 0.0) & 3;
    const double sa = (q & 1) ? c0 : s0, ca = (q & 1) ? s0 : c0;
    *sn = (q & 2) ? -sa : sa;
    *cs = ((q + 1) & 2) ? -ca : ca;
}

/* Back to the lane storage, and X, p_par of the
 * lanes into the block (not of lanes whose step failed: they keep theirs):
 *   R = L W^(3/2), Z = L W s, p_par = sgn(k) m c Q g/T, phi = phi' + w 2 s W Q/T. */
static void dgl_scatter(const struct dgl_args *A, const struct dgl_tile *t, unsigned char *lanes,
                        struct gcp_block *b, size_t i0, size_t nt)
{
    for (size_t i = 0; i < nt; i++) {
        if (t->fail[i] != 0.0) continue; /* nothing of a failed step is kept */
        struct dgl_lane *l = (struct dgl_lane *)(lanes + (i0 + i) * sizeof *l);
        const double pp = t->phip[i];
        l->s = t->s[i], l->Q = t->Q[i], l->phip = pp, l->have = t->have[i];
        for (int n = 0; n <= GL_SMAX; n++) l->hist[n][0] = t->hist[n][0][i], l->hist[n][1] = t->hist[n][1][i];
        const double s = t->s[i], Q = t->Q[i], L = t->L[i];
        const double W = 1.0 - s * s, T = 1.0 + 3.0 * s * s, iT = 1.0 / T;
        const double R = L * W * sqrt(W), phi = pp + t->w[i] * 2.0 * s * W * Q * iT;
        const size_t j = i0 + i;
        double sn, cs;
        dgl_sincos(phi, &sn, &cs);
        b->x[j] = R * cs, b->y[j] = R * sn, b->z[j] = L * W * s;
        b->ppar[j] = A->sgk * A->mc * Q * sqrt(T) * iT;
        b->fstatus[j] = 0;
    }
}

/* The lift of block lane i (the evolve layer's init):
 *   R^2 = x^2 + y^2, r^2 = R^2 + z^2, s = z/r, W = R^2/r^2, L = r^3/R^2,
 *   Q = sgn(k) p_par g/(m c), phi' = atan2(y, x) - w 2 s W Q/T. */
static int dgl_init(const struct gcp_evolve *ev, void *vctx, const struct gcp_block *b, size_t i,
                    double t, void *vlane)
{
    (void)t;
    const struct dgl_ctx *c = vctx;
    const struct dgl_args *A = &c->A;
    struct dgl_lane *l = vlane;
    memset(l, 0, sizeof *l);
    const double x = b->x[i], y = b->y[i], z = b->z[i];
    const double R2 = x * x + y * y, r2 = R2 + z * z, r = sqrt(r2);
    if (!(R2 > 0.0) || !(r2 <= DBL_MAX) || !isfinite(b->ppar[i]) || !isfinite(b->mu[i]))
        return gcp_lane_fail((struct gcp_block *)b, i, GCP_FAIL_CHART);
    const double s = z / r, W = R2 / r2, L = r * r2 / R2;
    const double T = 1.0 + 3.0 * s * s, g = sqrt(T);
    l->s = s, l->L = L;
    l->Q = A->sgk * b->ppar[i] * g / A->mc;
    l->beta = 2.0 * b->mu[i] * fabs(A->k) / (A->m * GCP_C_LIGHT * GCP_C_LIGHT * L * L * L);
    l->w = -A->mc * L * L / (A->q * A->k);
    l->hh = ev->o->dt * GCP_C_LIGHT / L;
    l->phip = atan2(y, x) - l->w * 2.0 * s * W * l->Q / T;
    const double W1 = 1.0 - s * s;
    const double p2 = l->Q * l->Q / T + l->beta * g / (W1 * W1 * W1);
    l->iqsc = p2 > 0.0 ? 1.0 / sqrt(p2) : 1.0;
    for (int n = 0; n <= GL_SMAX; n++) l->hist[n][0] = s, l->hist[n][1] = l->Q;
    l->have = 0.0;
    return 0;
}

/* Up to kmax steps, tile by tile (the evolve layer's `steps`): as
 * gc_rk4.c rk4_steps, the block takes the fewest steps any tile took, and
 * tiles that ran further are restored (lanes and X) and run again to it. */
static int64_t dgl_steps(const struct gcp_evolve *ev, void *vctx, struct gcp_block *b, size_t n,
                         double t, double h, int64_t kmax, int32_t *stops, unsigned char *lanes)
{
    (void)ev, (void)t, (void)h;
    struct dgl_ctx *c = vctx;
    *stops = 1; /* the evolve layer classifies after the steps */
    const size_t sz = sizeof(struct dgl_lane);
    memcpy(c->save_lanes, lanes, n * sz);
    double *X[4] = {b->x, b->y, b->z, b->ppar};
    for (int k = 0; k < 4; k++) memcpy(c->save_X + (size_t)k * c->nmax, X[k], n * sizeof(double));
    struct dgl_tile tl;
    int64_t kd = kmax;
    size_t tile = 0;
    for (size_t i0 = 0; i0 < n; i0 += DGL_TILE, tile++) {
        const size_t nt = n - i0 < DGL_TILE ? n - i0 : DGL_TILE;
        dgl_gather(&tl, lanes, i0, nt);
        const int64_t k = dgl_run(&c->A, &tl, nt, kd, 0);
        if (k > 0) dgl_scatter(&c->A, &tl, lanes, b, i0, nt);
        c->done[tile] = k;
        if (k < kd) kd = k;
    }
    if (kd < kmax) {
        tile = 0;
        for (size_t i0 = 0; i0 < n; i0 += DGL_TILE, tile++) {
            if (c->done[tile] == kd) continue;
            const size_t nt = n - i0 < DGL_TILE ? n - i0 : DGL_TILE;
            memcpy(lanes + i0 * sz, c->save_lanes + i0 * sz, nt * sz);
            for (int k = 0; k < 4; k++)
                memcpy(X[k] + i0, c->save_X + (size_t)k * c->nmax + i0, nt * sizeof(double));
            if (kd > 0) {
                dgl_gather(&tl, lanes, i0, nt);
                dgl_run(&c->A, &tl, nt, kd, 0);
                dgl_scatter(&c->A, &tl, lanes, b, i0, nt);
            }
        }
    }
    return kd;
}

/* One step (after the evolve layer's start check, when `steps` could not
 * take one): a lane whose solve fails keeps the state of the start of the
 * step and gets STEP_FAILED (NO_CONVERGENCE). */
static int32_t dgl_step_lanes(const struct gcp_evolve *ev, void *vctx, struct gcp_block *b,
                              size_t n, double t, double h, unsigned char *lanes)
{
    (void)ev, (void)t, (void)h;
    struct dgl_ctx *c = vctx;
    struct dgl_tile tl;
    int32_t failed = 0;
    for (size_t i0 = 0; i0 < n; i0 += DGL_TILE) {
        const size_t nt = n - i0 < DGL_TILE ? n - i0 : DGL_TILE;
        dgl_gather(&tl, lanes, i0, nt);
        dgl_run(&c->A, &tl, nt, 1, 1);
        dgl_scatter(&c->A, &tl, lanes, b, i0, nt);
        for (size_t i = 0; i < nt; i++)
            if (tl.fail[i] != 0.0) {
                b->status[i0 + i] = gcp_lane_fail(
                    b, i0 + i, tl.fail[i] == 2.0 ? GCP_FAIL_CHART : GCP_FAIL_NO_CONVERGENCE);
                failed = 1;
            }
    }
    return failed;
}

static const struct gcp_stepper dgl_stepper = {
    .gc = 1,
    .lane_size = sizeof(struct dgl_lane),
    .init = dgl_init,
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

int gcp_gl_dipole_advance(struct gcp_block *b, const struct gcp_field *f,
                          const struct gcp_push_opts *o, const struct gcp_sampler *smp,
                          const struct gl_tableau *tab, size_t *live)
{
    struct gcp_point_B form;
    if (!gcp_field_point_B(f, &form) || form.form != GCP_POINT_B_DIPOLE || form.has_E || f->has_E)
        return -1;
    if (!(form.p[0] != 0.0) || !(b->q != 0.0) || !(b->m > 0.0)) return -1;
    struct dgl_ctx c = {.A = {.S = tab->s}};
    struct dgl_args *A = &c.A;
    const int S = tab->s;
    for (int i = 0; i < S; i++) {
        A->b[i] = tab->b[i];
        for (int j = 0; j < S; j++) A->a[i][j] = tab->a[i][j];
    }
    /* predictor weights: nodes -1, -1 + c_i, 0 (in steps); Y_j = sum_n
     * l_n(c_j) v_n, K = A^-1 (Y - y0)/h */
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
            A->wk[i][nn] = v;
        }
    A->k = form.p[0];
    A->sgk = form.p[0] > 0.0 ? 1.0 : -1.0;
    A->mc = b->m * GCP_C_LIGHT;
    A->q = b->q, A->m = b->m;
    A->rin2 = f->r_inner * f->r_inner, A->rout2 = f->r_outer * f->r_outer, A->zmax = f->z_max;
    A->amax2 = o->adiabaticity_max > 0.0 ? o->adiabaticity_max * o->adiabaticity_max : 0.0;
    c.nmax = b->n;
    c.save_lanes = malloc((b->n + 1) * sizeof(struct dgl_lane));
    c.save_X = malloc(4 * (b->n + 1) * sizeof(double));
    c.done = malloc((b->n / DGL_TILE + 1) * sizeof(int64_t));
    if (!c.save_lanes || !c.save_X || !c.done) {
        free(c.save_lanes), free(c.save_X), free(c.done);
        return -1;
    }
    *live = gcp_evolve(b, f, o, smp, &dgl_stepper, &c);
    free(c.save_lanes), free(c.save_X), free(c.done);
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
