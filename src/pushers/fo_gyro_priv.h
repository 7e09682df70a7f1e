/* Private to the pushers and the invariant observer: the gyro-average of a
 * full orbit (issue 12), shared by the observer's per-step pass
 * (src/diag/invariants_fo.c) and the fused full-orbit step that does the
 * same work inside its tile loop (fo_fused_priv.h), so that the two give
 * the same numbers bit for bit (the same operations in the same order;
 * the build keeps -ffp-contract=off).
 *
 * Physics (gcpush/invariants.h): each step's first-order guiding centre
 * X = x - rho, rho = b x p / (q B(x)) (Northrop 1963), with p_par = p.b(X),
 * mu = p_perp^2 / (2 m |B(X)|) and p^2, is averaged over each gyration by
 * the trapezoid rule in t; a gyration ends where rho crosses the half-plane
 * spanned by b and e1 (e1: rho's direction when the gyration began) after
 * having been on the far side (rho.e1 < 0): rho.e2 changes sign with
 * rho.e1 > 0 at the crossing, e2 = b x e1, the crossing linear in the step.
 *
 * Why the fused step does it (issue 12): the observer is a sampler of every
 * step, so without this the fused step runs one step per call, and the
 * observer makes ~8 passes over the block per step (two block field
 * evaluations among them).  With a gcp_fo_gyro the fused tile loop does a
 * gyration's steps in registers and L1 -- the guiding centre, the phase
 * test and the six running trapezoid sums per lane -- and writes a record
 * (struct gcp_fo_gyro_rec) only where a gyration ends (~1 step in 20 at
 * 0.05 gyro); the observer turns the records into its guiding-centre
 * stream (bounce integrals, equator points, drift contour) after the call. */
#ifndef GCPUSH_FO_GYRO_PRIV_H
#define GCPUSH_FO_GYRO_PRIV_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

/* Before the fused loop over a tile's lanes, whose arrays do not overlap:
 * GCC cannot use restrict on pointers loaded from a struct, tests the
 * arrays for overlap at run time, and gives up past 10 of them. */
#if defined(__GNUC__) && !defined(__clang__)
#define GCP_FO_IVDEP_ _Pragma("GCC ivdep")
#else
#define GCP_FO_IVDEP_
#endif

/* One completed gyration: its mid time and the averages over it. */
struct gcp_fo_gyro_rec {
    int64_t lane;  /* the lane's index (the block is dense: b->index[i] = i) */
    double t;      /* [s] the middle of the gyration */
    double X[3];   /* [m] averaged first-order guiding centre */
    double ppar;   /* [kg m/s] */
    double mu;     /* [J/T]; with mid set, p_perp^2 [kg^2 m^2/s^2] (the observer
                    * divides by 2 m |B(X)|) */
    double p2;     /* [kg^2 m^2/s^2] */
    int mid;       /* from the fused step's raw sums (gcp_fo_gyro_close_vals) */
};

/* gcp_fo_gyro.init: no gyration in progress, one of the observer's
 * per-step pass (invariants_fo.c), one of the fused step's raw sums. */
#define GCP_FO_GYRO_NONE 0
#define GCP_FO_GYRO_STEP 1
#define GCP_FO_GYRO_MID 2

/* The gyration in progress of each lane, as a struct of arrays indexed by
 * the lane's original index (the observer's; a dense block's position),
 * and the records of the fused step's last call. */
struct gcp_fo_gyro {
    int64_t *init, *left; /* left: the gyroradius has been on the far side of e1
                           * (GCP_FO_GYRO_MID: u.e2 has been negative) */
    /* GCP_FO_GYRO_MID: the raw sums over the gyration's steps so far
     * (gcp_fo_gyro_close_vals), the push step it began at */
    double *sum[9];
    double *w0;           /* the weight of its first step's sample */
    double *jc;           /* the slope's part of its time sum (gcp_fo_gyro_close_vals) */
    int64_t *kstart;
    double *rho[3];       /* [m] rho = x - X of the previous step */
    double *e1[3], *e2[3];
    double *acc[6], *prev[6]; /* trapezoid integrals and previous values of X[3], ppar, mu, p2 */
    double *t0, *tprev;   /* [s] the gyration's start, the previous step */
    size_t nlanes;
    /* Filled by the fused step (fo_step.c), read by the observer's sampler
     * call that follows it: the records of the call in the order they were
     * made (per lane, in time), and the steps whose per-step work the call
     * did (0: none, the sampler does that step's work itself). */
    struct gcp_fo_gyro_rec *rec;
    int64_t nrec, cap;
    int64_t steps;
    int64_t max_steps; /* tests: the most steps a fused call takes (0: its own bound) */
    /* GCP_FO_GYRO_MID with Boris's kick (gcp_fo_fused.gyro_tele, set by the
     * fused step): S_r is telescoped (gcp_fo_gyro_mid_start), sum[3..5]
     * hold the part of the start step past the crossing plus u there */
    int tele;
};

/* b x e1 with b = B/|B| (the observer's unit() and cross product). */
static inline void gcp_fo_gyro_e2(const double B[3], const double e1[3], double e2[3])
{
    const double Bm = sqrt(B[0] * B[0] + B[1] * B[1] + B[2] * B[2]);
    const double bx[3] = {B[0] / Bm, B[1] / Bm, B[2] / Bm};
    e2[0] = bx[1] * e1[2] - bx[2] * e1[1];
    e2[1] = bx[2] * e1[0] - bx[0] * e1[2];
    e2[2] = bx[0] * e1[1] - bx[1] * e1[0];
}

static inline double gcp_fo_gyro_dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* One step at t of lane li whose gyration has begun (init[li] != 0): v =
 * X[3], p_par, mu, p^2 of this step's first-order guiding centre, rho =
 * x - X, B = B(x).  Returns 1 with *r filled (but r->lane) where a
 * gyration ended in this step with a positive length. */
static inline int gcp_fo_gyro_lane(struct gcp_fo_gyro *G, size_t li, double t, const double v[6],
                                   const double rho[3], const double B[3],
                                   struct gcp_fo_gyro_rec *r)
{
    const double rp[3] = {G->rho[0][li], G->rho[1][li], G->rho[2][li]};
    const double e1[3] = {G->e1[0][li], G->e1[1][li], G->e1[2][li]};
    const double e2[3] = {G->e2[0][li], G->e2[1][li], G->e2[2][li]};
    double prev[6], acc[6];
    for (int k = 0; k < 6; k++) prev[k] = G->prev[k][li], acc[k] = G->acc[k][li];
    const double tprev = G->tprev[li];
    const double dt = t - tprev;
    const double a = gcp_fo_gyro_dot3(rp, e2), c = gcp_fo_gyro_dot3(rho, e2);
    if (gcp_fo_gyro_dot3(rho, e1) < 0) G->left[li] = 1;
    int wrap = 0, out = 0;
    double th = 0;
    if (G->left[li] && ((a < 0 && c >= 0) || (a > 0 && c <= 0))) {
        th = a / (a - c);
        double rw[3];
        for (int k = 0; k < 3; k++) rw[k] = rp[k] + th * (rho[k] - rp[k]);
        wrap = gcp_fo_gyro_dot3(rw, e1) > 0;
    }
    if (wrap) {
        const double tw = tprev + th * dt;
        double vw[6];
        for (int k = 0; k < 6; k++) {
            vw[k] = prev[k] + th * (v[k] - prev[k]);
            acc[k] += 0.5 * (prev[k] + vw[k]) * (tw - tprev);
        }
        const double T = tw - G->t0[li];
        if (T > 0) {
            r->t = 0.5 * (G->t0[li] + tw);
            for (int k = 0; k < 3; k++) r->X[k] = acc[k] / T;
            r->ppar = acc[3] / T;
            r->mu = acc[4] / T;
            r->p2 = acc[5] / T;
            out = 1;
        }
        for (int k = 0; k < 6; k++) G->acc[k][li] = 0.5 * (vw[k] + v[k]) * (t - tw);
        G->t0[li] = tw;
        G->left[li] = 0;
        /* e1, e2 follow the slowly turning field: e2 = b x e1 from this step */
        double e2n[3];
        gcp_fo_gyro_e2(B, e1, e2n);
        for (int k = 0; k < 3; k++) G->e2[k][li] = e2n[k];
    } else {
        for (int k = 0; k < 6; k++) G->acc[k][li] = acc[k] + 0.5 * (prev[k] + v[k]) * dt;
    }
    for (int k = 0; k < 3; k++) G->rho[k][li] = rho[k];
    for (int k = 0; k < 6; k++) G->prev[k][li] = v[k];
    G->tprev[li] = t;
    return out;
}

/* ---- the fused step's gyro-average (GCP_FO_GYRO_MID, issue 12) -----------
 *
 * The fused step samples each step at its middle, where the push already
 * has all it needs: the point x_1/2, the field vector F there (B, or
 * Boris's t = a B, a = q dt / (2 m gamma)), u- and u+ (the tile loop's
 * registers), with u_1/2 = (u- + u+)/2 -- in pure B the kick is a rotation
 * about F, so u_1/2 . b = u_par exactly, and u_1/2 x B is the Lorentz force
 * of the step (Boris: u+ - u- = (q dt / m gamma) u_1/2 x B).  Per step it
 * adds to nine raw sums, with us = u- + u+ = 2 u_1/2:
 *   S_x += x_1/2 (3),  S_r += F x us (3),  S_p += F . us,
 *   S_p2 += (F . us)^2,  S_F += F . F
 * -- no field evaluation, square root or division a step.  Over the
 * steps of a gyration (weights w: 1, the partial steps at its ends below)
 * the averages are formed once, where it ends:
 *   X     = <x> - (m a / q) <F x u_1/2> / <F^2>   (<rho> = <b x p / (q B)>)
 *   p_par = m <F . u_1/2> / sqrt(<F^2>) sgn(a)
 *   p_perp^2 = m^2 (|u+|^2 - <(F . u_1/2)^2> / <F^2>),  p^2 = m^2 |u+|^2
 * and mu = p_perp^2 / (2 m |B(X)|) (the observer, with |B| at X).
 * <f g> / <g> for <f> is the average weighted by g = F^2, which varies over
 * a gyration by O(eps) (eps = rho / L_B) in step with f's O(eps) swing:
 * the two differ at O(eps^2).  p_par and b are taken at the particle, not
 * at the first-order guiding centre of the per-step pass: they differ by
 * p_perp . (rho . grad) b, whose gyro-average is (p_perp rho / 2) b . curl b
 * (Northrop 1963) -- zero in the vacuum fields the fused step has (the
 * dipole, uniform B: curl B = 0, so b . curl b = 0); p^2 is a constant of
 * the kick in pure B.
 *
 * The gyration is a whole turn of u's phase: e2 = sgn F x u_c at its start
 * (u_c the velocity there; sgn such that u . e2 turns negative first); it
 * ends in the step where u . e2 goes from d0 > 0 to d1 <= 0 after having
 * been negative, at the fraction th = d0 / (d0 - d1) of the step (linear
 * in u).  That step's sample f_k (at its middle) is split between the two
 * gyrations with the slope from the step before, f' ~ (f_k - f_{k-1}) / dt:
 *   int_{t_k}^{t_c} f ~ th dt (f_k - (1 - th)(f_k - f_{k-1}) / 2)
 * to this one, the rest of the step to the next -- O(dt^3 f'') at each
 * end.  The midpoint value alone would leave th (1 - th) dt^2 f'/2,
 * O(eps (dt / T_g)(omega dt) / 8) relative to these nearly constant
 * averages (f' = O(eps omega f)), which the electron mu checks of
 * tests/cli/test_analysis.sh see (1.4e-6 per bounce against 6e-8 with
 * the slope).  f_{k-1} is rebuilt where the gyration ends
 * (fo_fused_priv.h: x_{k-1/2} = x_{k+1/2} - 2 u- h / gamma, the field
 * there, u of step k-1 from u- by the inverse Boris rotation -- the
 * pushers' kicks agree with Boris's to O((omega dt)^3), below what the
 * slope needs).  The phase is u's, not rho's: u . e2 also sees u_par b . e2
 * as b turns along the orbit, which moves the ends by O(eps) in phase --
 * harmless to averages that are constant up to O(eps) swings (O(eps^2)).
 * With Boris's kick (F = t) S_r needs no per-step work: the rotation
 * gives u+ - u- = us x t exactly (in real arithmetic; s = 2 / (1 + t^2)),
 * so F x us = u- - u+ and the sum over the gyration's whole steps
 * telescopes to u+ of its start step less u+ of its end step.  sum[3..5]
 * then hold the start step's part past the crossing (fn, below) plus u+
 * there (gcp_fo_gyro.tele): the close forms S_r = sum[3..5] - u+.  The
 * two differ from the summed S_r by roundings of |u| eps (the summed one
 * ~20 of |t| |us| eps), which move X by ~eps rho / N: the last bit of X
 * at most (issue 12: ~12 of the per-step loop's ~45 operations a lane).
 * t is the weighted mean of the samples' times.  The per-step pass
 * (gcp_fo_gyro_lane, above) remains where there is no fused step (other
 * fields, lanes renumbered by a loss); a lane that changes from one to
 * the other begins a new gyration (the one in progress is dropped). */
static inline void gcp_fo_gyro_mid_start(struct gcp_fo_gyro *G, size_t li, int64_t k, double w0,
                                         const double e2[3], const double u[3])
{
    G->init[li] = GCP_FO_GYRO_MID;
    G->left[li] = 0;
    G->kstart[li] = k;
    G->w0[li] = w0;
    G->jc[li] = 0.0;
    for (int j = 0; j < 9; j++) G->sum[j][li] = 0.0;
    for (int j = 0; j < 3; j++) G->e2[j][li] = e2[j];
    /* telescoped S_r (G->tele): the sum of F x us from step k on is u - u+ */
    for (int j = 0; j < 3; j++) G->sum[3 + j][li] = G->tele ? u[j] : 0.0;
}

/* sgn (F x u): the phase reference of a gyration starting at u with the
 * field vector F = a B (sgn = sign(q) sign(a)). */
static inline void gcp_fo_gyro_mid_e2(double q, double a, const double F[3], const double u[3],
                                      double e2[3])
{
    /* (q > 0) == (a > 0) as selects (a comparison of two masks stops GCC
     * vectorising the fused step's close: fo_fused_priv.h) */
    const double sg = q > 0 ? (a > 0 ? 1.0 : -1.0) : (a > 0 ? -1.0 : 1.0);
    e2[0] = sg * (F[1] * u[2] - F[2] * u[1]);
    e2[1] = sg * (F[2] * u[0] - F[0] * u[2]);
    e2[2] = sg * (F[0] * u[1] - F[1] * u[0]);
}

/* The sample of a step (the nine terms above) from x_1/2, F, u-, u+. */
static inline void gcp_fo_gyro_mid_sample(const double xh[3], const double F[3],
                                          const double u0[3], const double u1[3], double f[9])
{
    const double us[3] = {u0[0] + u1[0], u0[1] + u1[1], u0[2] + u1[2]};
    const double fu = F[0] * us[0] + F[1] * us[1] + F[2] * us[2];
    f[0] = xh[0], f[1] = xh[1], f[2] = xh[2];
    f[3] = F[1] * us[2] - F[2] * us[1];
    f[4] = F[2] * us[0] - F[0] * us[2];
    f[5] = F[0] * us[1] - F[1] * us[0];
    f[6] = fu, f[7] = fu * fu;
    f[8] = F[0] * F[0] + F[1] * F[1] + F[2] * F[2];
}

/* The close of a gyration that ended in push step k, on one lane's values
 * (the fused tile closes the lanes of a step together, as a struct of
 * arrays: fo_fused_priv.h): ks, w0, jc, e2 and S = the raw sums of the
 * gyration (holding step k's sample f whole; fp: the step before's).  The
 * record's t, X[3], p_par, mu (p_perp^2) and p^2 go to rv[0..6] from the
 * sums (above) less the part of step k past the crossing, which begins the
 * next gyration there: its sums fn[9], e2n, first weight *w0n and slope
 * share *jcn.  F = a B, u0 = u- and u1 = u+ of step k.  Branch-free (the
 * record's values are formed whether or not it is kept); returns 1.0 where
 * the record is kept (N > 1 and S_F > 0), else 0.0. */
static inline __attribute__((always_inline)) double
gcp_fo_gyro_close_vals(int64_t k, int64_t ks, double w0, double jc, const double e2[3],
                       const double S0[9], double t0, double dt, double q, double m,
                       const double F[3], double a, const double f[9], const double fp[9],
                       const double u0[3], const double u1[3], double rv[7], double fn[9],
                       double e2n[3], double *w0n, double *jcn)
{
    const double d0 = gcp_fo_gyro_dot3(u0, e2), d1 = gcp_fo_gyro_dot3(u1, e2);
    const double th = d0 / (d0 - d1), rest = 1.0 - th; /* d0 > 0 >= d1 */
    const double cs = 0.5 * th * rest; /* the slope's weight */
    double S[9];
    for (int j = 0; j < 9; j++) {
        fn[j] = rest * f[j] + cs * (f[j] - fp[j]); /* the part past the crossing */
        S[j] = S0[j] - fn[j];
    }
    const double N = (double)(k - ks + 1) - (1.0 - w0) - rest;
    const double u2 = gcp_fo_gyro_dot3(u1, u1);
    /* the samples' times t0 + (j + 1/2) dt, weighted */
    const double jbar = (0.5 * (double)(ks + k) * (double)(k - ks + 1) - (1.0 - w0) * (double)ks -
                         rest * (double)k - cs + jc) / N;
    rv[0] = t0 + (jbar + 0.5) * dt;
    /* S_r, S_p, S_p2 are of us = 2 u_1/2 */
    const double rf = 0.5 * m * a / (q * S[8]);
    for (int j = 0; j < 3; j++) rv[1 + j] = S[j] / N - rf * S[3 + j];
    rv[4] = (a > 0 ? 0.5 : -0.5) * m * S[6] / sqrt(S[8] * N);
    const double pp = m * m * (u2 - 0.25 * S[7] / S[8]);
    rv[5] = pp > 0.0 ? pp : 0.0;
    rv[6] = m * m * u2;
    double uc[3];
    for (int j = 0; j < 3; j++) uc[j] = u0[j] + th * (u1[j] - u0[j]);
    gcp_fo_gyro_mid_e2(q, a, F, uc, e2n);
    *w0n = rest;
    *jcn = cs; /* the slope's share of the first step's time */
    return N > 1 ? (S[8] > 0 ? 1.0 : 0.0) : 0.0;
}

#endif
