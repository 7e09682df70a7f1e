/* Private to gc_gauss_dipole.c (gc-gl2 / gc-gl4 in the dipole) and
 * gc_sundman_dipole.c (gc-gl2 / gc-gl4-sundman in the dipole): the field
 * line's closed-form canonical coordinates (s, Q, phi'; L), their
 * Hamiltonian's derivatives, and the Gauss-Legendre Newton over 64-lane
 * tiles.  The derivation is in the header comment of gc_gauss_dipole.c;
 * the time transformation in gc_sundman_dipole.c's. */
#ifndef GCPUSH_GC_DIPOLE_PRIV_H
#define GCPUSH_GC_DIPOLE_PRIV_H

#include <float.h>
#include <math.h>
#include <stdint.h>

#include "gcpush/field.h"
#include "gcpush/particles.h"
#include "gcpush/pusher.h"
#include "gc_gauss_priv.h"

#define DGL_TILE 64
#define DGL_MAXIT 24
#define DGL_TOL 1e-15
#define DGL_PI 3.14159265358979323846

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

/* A's fields for a push of block b in field f with tableau tab: 0, or -1
 * when f is not the dipole form without E (or q, m, k do not allow it). */
__attribute__((visibility("hidden"))) int gcp_dgl_args(struct dgl_args *A,
                                                       const struct gl_tableau *tab,
                                                       const struct gcp_block *b,
                                                       const struct gcp_field *f,
                                                       const struct gcp_push_opts *o);

/* The predictor's weights wk of tableau tab (gcp_dgl_args sets A->wk so). */
__attribute__((visibility("hidden"))) void gcp_dgl_predictor_weights(const struct gl_tableau *tab,
                                                                     double wk[GL_SMAX][GL_SMAX + 2]);

/* A guiding centre at (x, y, z), p_par [kg m/s], mu [J/T] lifted to the
 * line coordinates (gc_gauss_dipole.c's header):
 *   s = z/r, L = r^3/R^2, Q = sgn(k) p_par g/(m c), beta = 2 mu |k|/(m c^2 L^3),
 *   w = -m c L^2/(q k), phi' = atan2(y, x) - w 2 s W Q/T,
 *   p2 = gamma^2 - 1 = Q^2/T + beta g/W^3,  gW3 = g/W^3,
 * T = 1 + 3 s^2, g = sqrt(T), W = 1 - s^2 (as dgl_point forms it, so that
 * phi' maps back to the same phi).  The fixed step (dgl_init) and the
 * Sundman form (sdl_init) start from it.  0, or -1 off the chart (on the
 * axis, not finite). */
struct dgl_lift {
    double s, L, Q, beta, w, phip, p2, gW3;
};
static inline int dgl_lift_of(const struct dgl_args *A, double x, double y, double z,
                              double ppar, double mu, struct dgl_lift *o)
{
    const double R2 = x * x + y * y, r2 = R2 + z * z, r = sqrt(r2);
    if (!(R2 > 0.0) || !(r2 <= DBL_MAX) || !isfinite(ppar) || !isfinite(mu)) return -1;
    const double s = z / r, W = 1.0 - s * s, L = r * r2 / R2;
    const double T = 1.0 + 3.0 * s * s, g = sqrt(T);
    o->s = s, o->L = L;
    o->Q = A->sgk * ppar * g / A->mc;
    o->beta = 2.0 * mu * fabs(A->k) / (A->m * GCP_C_LIGHT * GCP_C_LIGHT * L * L * L);
    o->w = -A->mc * L * L / (A->q * A->k);
    o->phip = atan2(y, x) - o->w * 2.0 * s * W * o->Q / T;
    o->p2 = o->Q * o->Q / T + o->beta * g / (W * W * W);
    o->gW3 = g / (W * W * W);
    return 0;
}

/* The reduced Hamiltonian's derivatives at (s, Q): F = (ds, dQ)/dtau, its
 * Jacobian D (D22 = -D11), the phi' rate P with its gradient (Ps, PQ), and
 * gamma.  See gc_gauss_dipole.c's header for the formulas; Gamma_ss from
 *   d/ds (s/T^2) = (1 - 9 s^2)/T^3,
 *   d/ds (N/(g W^4)) = (N' - 3 s N/T + 8 s N/W)/(g W^4),  N' = 3 + 15 s^2.
 * W, Ws: the time transformation's w and dw/ds (sdl_eval; 1, 0 here). */
struct dgl_ev {
    double F1, F2, D11, D12, D21, P, Ps, PQ, gam, W, Ws;
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
    e.gam = gam;
    e.W = 1.0, e.Ws = 0.0;
    return e;
}

/* The Sundman-transformed rates (gc_sundman_dipole.c): with
 *   K = w(s) (gamma(s, Q) + pi),  w = (c04 W^3/g)^(1/4),  w'/w = l = -(3/4) N/(T W),
 * (dl/ds = -(3/4) (N' - N s (4 - 12 s^2)/(T W))/(T W)), E = gamma + pi:
 *   ds/dsig = w F1,  dQ/dsig = w F2 - w l E,  dtau/dsig = w,  dphi'/dsig = w P,
 *   Jacobian  w (l F1 + D11),  w D12,  w (2 l F2 + D21 - (l^2 + dl/ds) E),  -w (l F1 + D11)
 * (trace 0: the flow stays Hamiltonian).  plain: w = 1, the rates of
 * dip_eval (the step in time that tests set against the transformation). */
static inline __attribute__((always_inline)) struct dgl_ev
sdl_eval(double s, double Q, double beta, double wphi, double c04, double pi, int plain)
{
    struct dgl_ev e = dip_eval(s, Q, beta, wphi);
    if (plain) return e;
    const double s2 = s * s;
    const double T = 1.0 + 3.0 * s2, W = 1.0 - s2;
    const double iTW = 1.0 / (T * W);
    const double g = sqrt(T), ig = g * (W * iTW);
    const double w = sqrt(sqrt(c04 * (W * W * W) * ig));
    const double N = s * (3.0 + 5.0 * s2);
    const double l = -0.75 * N * iTW;
    const double lp = -0.75 * iTW * ((3.0 + 15.0 * s2) - N * s * (4.0 - 12.0 * s2) * iTW);
    const double E = e.gam + pi;
    const struct dgl_ev d = e;
    e.F1 = w * d.F1;
    e.F2 = w * (d.F2 - l * E);
    e.D11 = w * (l * d.F1 + d.D11);
    e.D12 = w * d.D12;
    e.D21 = w * (2.0 * l * d.F2 + d.D21 - (l * l + lp) * E);
    e.P = w * d.P;
    e.Ps = w * (l * d.P + d.Ps);
    e.PQ = w * d.PQ;
    e.W = w, e.Ws = w * l;
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

/* A tile's lanes as arrays (gathered from the lane storage for a call).
 * c04, pi, Kt and dt: the Sundman form's only. */
struct dgl_tile {
    double s[DGL_TILE], Q[DGL_TILE], phip[DGL_TILE], L[DGL_TILE], beta[DGL_TILE];
    double hh[DGL_TILE], w[DGL_TILE], iqsc[DGL_TILE], have[DGL_TILE];
    double c04[DGL_TILE], pi[DGL_TILE]; /* w^4 = c04 W^3/g; pi = p_t/(m c^2) */
    double hist[GL_SMAX + 1][2][DGL_TILE];
    double K[GL_SMAX][2][DGL_TILE]; /* stage slopes (ds, dQ)/dtau */
    double Kp[GL_SMAX][DGL_TILE];   /* stage rates dphi'/dtau */
    double Kt[GL_SMAX][DGL_TILE];   /* stage rates dtau/dsig = w */
    double ndp[DGL_TILE];           /* the last update's size */
    double act[DGL_TILE];           /* 1: iterating */
    double fail[DGL_TILE];          /* 1: no convergence (non-finite), 2: off the chart */
    /* after the Newton (dgl_finish): stage values, the end, the increments of phi' and t */
    double Y[GL_SMAX][2][DGL_TILE];
    double s1[DGL_TILE], Q1[DGL_TILE], dp[DGL_TILE], dt[DGL_TILE];
};

/* The predictor (see gc_gauss_dipole.c's header): K_i = sum_n wk[i][n] v_n
 * / h over the nodes v = (last start, last stages, this start); K = 0
 * without a last step (have = 0). */
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

/* One Newton iterate over the tile's lanes (full Newton on K_i - F(Y_i) =
 * 0 with the 2s x 2s Jacobian by 2 x 2 blocks; gc_gauss_dipole.c's
 * header).  SUND: 0 the rates of dip_eval, 1 the transformed ones of
 * sdl_eval, 2 sdl_eval's plain form (w = 1, with the t rates).  Returns
 * whether any lane is still iterating. */
static inline __attribute__((always_inline)) int
dgl_iterate(const int S, const int SUND, const struct dgl_args *restrict A,
            struct dgl_tile *restrict t, size_t nt, int it)
{
    const double a11 = A->a[0][0], a12 = A->a[0][1], a21 = A->a[1][0], a22 = A->a[1][1];
    int any = 0;
    for (size_t i = 0; i < nt; i++) {
        const double h = t->hh[i], s0 = t->s[i], Q0 = t->Q[i], bt = t->beta[i], w = t->w[i];
        const double c04 = SUND ? t->c04[i] : 0.0, pi = SUND ? t->pi[i] : 0.0;
        const double K1s = t->K[0][0][i], K1Q = t->K[0][1][i];
        const double K2s = S == 2 ? t->K[1][0][i] : 0.0, K2Q = S == 2 ? t->K[1][1][i] : 0.0;
        double x1s, x1Q, x2s = 0.0, x2Q = 0.0, P1, P1s, P1Q, P2 = 0.0, P2s = 0.0, P2Q = 0.0;
        double W1 = 1.0, W1s = 0.0, W2 = 1.0, W2s = 0.0;
        if (S == 1) {
            const double ys = s0 + h * a11 * K1s, yQ = Q0 + h * a11 * K1Q;
            const struct dgl_ev e = SUND ? sdl_eval(ys, yQ, bt, w, c04, pi, SUND == 2)
                                         : dip_eval(ys, yQ, bt, w);
            const double r1 = e.F1 - K1s, r2 = e.F2 - K1Q;
            /* (I - h a11 D) x = r */
            const double m11 = 1.0 - h * a11 * e.D11, m12 = -h * a11 * e.D12;
            const double m21 = -h * a11 * e.D21, m22 = 1.0 + h * a11 * e.D11;
            const double id = 1.0 / (m11 * m22 - m12 * m21);
            x1s = (m22 * r1 - m12 * r2) * id;
            x1Q = (m11 * r2 - m21 * r1) * id;
            P1 = e.P, P1s = e.Ps, P1Q = e.PQ;
            W1 = e.W, W1s = e.Ws;
        } else {
            const double y1s = s0 + h * (a11 * K1s + a12 * K2s), y1Q = Q0 + h * (a11 * K1Q + a12 * K2Q);
            const double y2s = s0 + h * (a21 * K1s + a22 * K2s), y2Q = Q0 + h * (a21 * K1Q + a22 * K2Q);
            const struct dgl_ev e1 = SUND ? sdl_eval(y1s, y1Q, bt, w, c04, pi, SUND == 2)
                                          : dip_eval(y1s, y1Q, bt, w);
            const struct dgl_ev e2 = SUND ? sdl_eval(y2s, y2Q, bt, w, c04, pi, SUND == 2)
                                          : dip_eval(y2s, y2Q, bt, w);
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
            const double yy1 = Ai11 * r1s + Ai12 * r1Q, yy2 = Ai21 * r1s + Ai22 * r1Q;
            /* S = D - C X, x2 = S^-1 (r2 - C y), x1 = y - X x2 */
            const double S11 = D11 - (C11 * X11 + C12 * X21), S12 = D12 - (C11 * X12 + C12 * X22);
            const double S21 = D21 - (C21 * X11 + C22 * X21), S22 = D22 - (C21 * X12 + C22 * X22);
            const double g1 = r2s - (C11 * yy1 + C12 * yy2), g2 = r2Q - (C21 * yy1 + C22 * yy2);
            const double iS = 1.0 / (S11 * S22 - S12 * S21);
            x2s = (S22 * g1 - S12 * g2) * iS;
            x2Q = (S11 * g2 - S21 * g1) * iS;
            x1s = yy1 - (X11 * x2s + X12 * x2Q);
            x1Q = yy2 - (X21 * x2s + X22 * x2Q);
            P1 = e1.P, P1s = e1.Ps, P1Q = e1.PQ;
            P2 = e2.P, P2s = e2.Ps, P2Q = e2.PQ;
            W1 = e1.W, W1s = e1.Ws, W2 = e2.W, W2s = e2.Ws;
        }
        /* the stage values' update and the phi' (and t) rates linearised to it */
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
            if (SUND) t->Kt[0][i] = W1 + W1s * d1s;
            if (S == 2) {
                t->K[1][0][i] = K2s + x2s, t->K[1][1][i] = K2Q + x2Q;
                t->Kp[1][i] = P2 + P2s * d2s + P2Q * d2Q;
                if (SUND) t->Kt[1][i] = W2 + W2s * d2s;
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

/* After the Newton: the stage values Y_i = y0 + h sum_j a_ij K_j (formed
 * once, for the chart test and the next predictor), the end y0 + h sum
 * b_i K_i, the increments of phi' (and of tau: sum b_i w_i, SUND), and the
 * verdict in t->fail: 1 no convergence (or a non-finite iterate), 2 a
 * converged step whose stage or end point is off the chart, |s| >= 1 (past
 * the line's pole, where W = cos^2(lat) <= 0).  Returns whether any lane
 * failed.  The chart test is a conjunction of comparisons, not fmax: fmax
 * is a libm call on x86 (its NaN rule is not maxsd's), and a call in the
 * loop spilled every live register around it (gc-gl2 per step 4-7% slower
 * than with the test inline). */
static inline __attribute__((always_inline)) int32_t
dgl_finish(const int S, const int SUND, const struct dgl_args *restrict A,
           struct dgl_tile *restrict t, size_t nt)
{
    int32_t failed = 0;
    for (size_t i = 0; i < nt; i++) {
        const double h = t->hh[i], s0 = t->s[i], Q0 = t->Q[i];
        double ds = 0.0, dQ = 0.0, dp = 0.0, dt = 0.0;
        int in = 1;
        for (int st = 0; st < S; st++) {
            double ys = 0.0, yQ = 0.0;
            for (int j = 0; j < S; j++) ys += A->a[st][j] * t->K[j][0][i], yQ += A->a[st][j] * t->K[j][1][i];
            t->Y[st][0][i] = s0 + h * ys, t->Y[st][1][i] = Q0 + h * yQ;
            in &= fabs(t->Y[st][0][i]) < 1.0;
            ds += A->b[st] * t->K[st][0][i], dQ += A->b[st] * t->K[st][1][i];
            dp += A->b[st] * t->Kp[st][i];
            if (SUND) dt += A->b[st] * t->Kt[st][i];
        }
        const double s1 = s0 + h * ds;
        t->s1[i] = s1, t->Q1[i] = Q0 + h * dQ, t->dp[i] = dp;
        if (SUND) t->dt[i] = dt;
        const int chart = !in | !(fabs(s1) < 1.0);
        const int nc = (t->fail[i] != 0.0) | (t->act[i] != 0.0);
        t->fail[i] = nc ? 1.0 : chart ? 2.0 : 0.0;
        failed |= t->fail[i] != 0.0;
    }
    return failed;
}

/* phi' + h dp kept in [-pi, pi] (an angle grown to 1e3 rad would have an
 * ulp above the Newton tolerance; at every step, so that the numbers do
 * not depend on how the push is sliced into calls). */
static inline __attribute__((always_inline)) double dgl_wrap(double pp)
{
    return fabs(pp) > DGL_PI ? pp - 2.0 * DGL_PI * rint(pp * (0.5 / DGL_PI)) : pp;
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

/* The point and p_par of (s, Q, phi') on line L (w: the lane's phi' factor):
 *   R = L W^(3/2), Z = L W s, p_par = sgn(k) m c Q g/T, phi = phi' + w 2 s W Q/T. */
static inline __attribute__((always_inline)) void
dgl_point(const struct dgl_args *A, double s, double Q, double pp, double L, double w, double X[3],
          double *ppar)
{
    const double W = 1.0 - s * s, T = 1.0 + 3.0 * s * s, iT = 1.0 / T;
    const double R = L * W * sqrt(W), phi = pp + w * 2.0 * s * W * Q * iT;
    double sn, cs;
    dgl_sincos(phi, &sn, &cs);
    X[0] = R * cs, X[1] = R * sn, X[2] = L * W * s;
    *ppar = A->sgk * A->mc * Q * sqrt(T) * iT;
}

#endif
