/* Private to the pushers: what a full-orbit tile is given (struct
 * gcp_fo_tile_args) and the proofs that let a tile skip its per-step stop
 * test for a stretch of steps (fo_fused_priv.h's tiles, boris_fast.c).
 * Each proof is about the arithmetic: it covers every state it admits, and
 * a step runs the same operations tested or not, so the verdicts and every
 * bit are the per-step test's (tests/unit/test_fo_fused.c). */
#ifndef GCPUSH_FO_FREE_PRIV_H
#define GCPUSH_FO_FREE_PRIV_H

#include <float.h>
#include <math.h>
#include <stddef.h>
#include <stdint.h>

/* What a tile needs, fixed for the push. */
struct gcp_fo_tile_args {
    double q, m, dt, h;      /* [C], [kg], [s], [s] h = dt/2 */
    double p[6];             /* the form's parameters (gcp_point_B.p) */
    double rin2, rout2, zmax; /* the field's bounds (gcp_block_classify's) */
};

/* The uniform forms (boris-nr, fo_fused_priv.h's Newtonian tiles).
 *
 * The per-step stop test costs as much as a third of this step (it is all
 * additions and multiplications, and the test's 6 squares and 5 sums share
 * their pipes), so a uniform form skips it where it is proved false for
 * every lane at every step of the call (gcp_fo_nr_cannot_stop): with the
 * field's bounds all absent (r_inner = 0, r_outer = z_max = inf) a lane
 * stops only when r2 + p2 is not finite, and from a finite start with
 *   |u|_1 + 2 k |e|_1 <= U_B,  |x|_1 + 2 h k (|u|_1 + 2 k |e|_1) <= X_B,
 *   |t|_1 <= T_B  (e = q dt E / 2m, t = q dt B / 2m, k = kmax)
 * every lane stays finite with |u| <= U_B and |x| <= X_B for all k steps:
 * the rotation keeps |u-| and the two half kicks add at most 2 |e| a step
 * (Boris: |u_{n+1}| <= |u_n| + 2 |e|), each half drift moves x by at most
 * h |u|, and the rotation's intermediate u' is at most |u-| (1 + |t|);
 * |s| <= 1.  U_B = X_B = 1e150 and T_B = 1e149 leave r2 + p2 <= 6e300,
 * a factor 3e7 below DBL_MAX -- room for the round-off of 1e15 steps
 * (|u| grows by at most ~20 eps a step in floating point).  Where the proof
 * does not go through (a bound, a huge state or step, kmax = 1) the test
 * runs every step as in the relativistic tiles.  The proof is about the
 * arithmetic, not the physics: it covers any state it admits, and the
 * verdicts are the block step's (tests/unit/test_fo_fused.c). */
#define GCP_FO_NR_UB_ 1e150
#define GCP_FO_NR_TB_ 1e149
/* The relativistic tiles' bound on |t| (fo_fused_priv.h, GCP_FO_TILE_DEFINE_). */
#define GCP_FO_REL_TB_ 1e70
static inline int gcp_fo_nr_cannot_stop(const double *restrict x, const double *restrict y,
                                        const double *restrict z, const double *restrict ux,
                                        const double *restrict uy, const double *restrict uz,
                                        size_t nt, int64_t kmax,
                                        const struct gcp_fo_tile_args *a, double emag,
                                        double bmag, double tb)
{
    if (kmax < 2 || !(a->rin2 <= 0.0) || a->rout2 != INFINITY || a->zmax != INFINITY) return 0;
    const double qdt2m = fabs(0.5 * a->q * a->dt / a->m), k = (double)kmax;
    const double e2k = 2.0 * k * qdt2m * emag, h2k = 2.0 * k * fabs(a->h);
    if (!(qdt2m * bmag <= tb) || !(e2k <= GCP_FO_NR_UB_) || !(h2k <= 1e300))
        return 0;
    int32_t bad = 0;
    for (size_t i = 0; i < nt; i++) {
        const double um = (fabs(ux[i]) + fabs(uy[i]) + fabs(uz[i])) + e2k;
        const double xm = (fabs(x[i]) + fabs(y[i]) + fabs(z[i])) + h2k * um;
        bad |= !((um <= GCP_FO_NR_UB_) & (xm <= GCP_FO_NR_UB_));
    }
    return !bad;
}

/* The dipole's stop test skipped where it is proved false, a stretch of
 * steps at a time (relativistic Boris: the IEEE tile, FREE_ = 2 above,
 * and the fast tier, boris_fast.c; gcp_fo_nr_cannot_stop does not cover
 * an inner bound).  A lane at distance m = min(r - r_in, r_out - r,
 * z_max - |z|) from the bounds, with speed U = |u|, stays inside for K
 * steps when every step moves it by at most d and K d <= m / 2:
 *  - the rotation keeps |u| to a few roundings a step (s (u' x t) is at
 *    most ~2 |u| whatever |t|, its errors eps |u| sized), so over K <=
 *    GCP_FO_FREE_CAP = 2^24 steps |u| < 2 U; the two half drifts move x
 *    by u hg each, hg = h / gamma <= h (IEEE h / sqrt of a number >= 1,
 *    or 1 + a few eps from the fast tier's Newton steps; the caller passes
 *    as h a bound on the drift factors it enters with): at most
 *    4 h U (1 + 1e-15) a step;
 *  - the drifts' roundings (1/2 ulp of each coordinate, twice a step, |x|
 *    < r + m/2 <= 1.5 r) move x by at most 1.5 eps r a step, and the
 *    proof's own roundings (r, m, the sums of squares, a fused or unfused
 *    multiply-add: a few eps r) are covered by d = 4.2 h U + 8 eps r,
 *    whose surplus over the two is >= 5 eps r;
 *  - within m/2 of the start, r2 >= r_in2 and r2 <= r_out2 hold for the
 *    test's rounded r2 too (m >= 2 d >= 16 eps r: more than its 2 eps
 *    r2), and |z| <= z_max; r2 + u2 stays finite while r2 + u2 <= 1e300
 *    at the start (|x| <= 1.5 r, |u| < 2 U).
 * t stays finite (|t| <= 2 |qdt2m c| / r_in^3 <= GCP_FO_REL_TB_, as the
 * uniform tiles' bound: gcp_fo_free_ok), so u' x t cannot overflow.  The
 * tile takes K = gcp_fo_free_steps = min over its lanes of floor(m / 2 d)
 * steps untested, then proves again from where it is; K < GCP_FO_FREE_MIN
 * (a lane near a bound, a non-finite one): GCP_FO_FREE_KCHK steps with
 * the test.  The steps are the same tested or not, so the verdicts (and
 * every bit) are the per-step test's.  Plain C, so that the same code
 * serves the IEEE tiles and, inlined, the AVX-512 one (whose target adds
 * to this one's); its loop vectorises (an integer min reduction). */
#define GCP_FO_FREE_CAP 16777216
#define GCP_FO_FREE_MIN 4
#define GCP_FO_FREE_KCHK 16
/* Whether the proof applies to the call at all: a dipole with an inner
 * bound (t bounded) and enough steps asked. */
static inline int gcp_fo_free_ok(const struct gcp_fo_tile_args *a, int64_t kmax)
{
    if (kmax < GCP_FO_FREE_MIN || !(a->rin2 > 0.0)) return 0;
    const double qc = 0.5 * a->q * a->dt / a->m * a->p[0], rin = sqrt(a->rin2);
    return 2.0 * fabs(qc) / (a->rin2 * rin) <= GCP_FO_REL_TB_;
}
static inline int64_t gcp_fo_free_steps(const double *restrict x, const double *restrict y,
                                        const double *restrict z, const double *restrict ux,
                                        const double *restrict uy, const double *restrict uz,
                                        size_t n, double h, double rin, double rout,
                                        double zmax)
{
    int32_t kmin = GCP_FO_FREE_CAP;
    const double h42 = 4.2 * h, cap = GCP_FO_FREE_CAP;
    for (size_t i = 0; i < n; i++) {
        const double r2 = x[i] * x[i] + y[i] * y[i] + z[i] * z[i];
        const double u2 = ux[i] * ux[i] + uy[i] * uy[i] + uz[i] * uz[i];
        const double r = sqrt(r2), m1 = r - rin, m2 = rout - r, m3 = zmax - fabs(z[i]);
        const double m = m1 < m2 ? (m1 < m3 ? m1 : m3) : (m2 < m3 ? m2 : m3);
        const double kl = m / (2.0 * (h42 * sqrt(u2) + (8.0 * DBL_EPSILON) * r));
        /* ordered compares: a NaN anywhere (or h < 0) gives no free step */
        const int ok = (r2 + u2 <= 1e300) & (kl >= 1.0);
        const int32_t ki = (int32_t)(ok ? (kl < cap ? kl : cap) : 0.0);
        kmin = ki < kmin ? ki : kmin;
    }
    return kmin;
}

/* A relativistic tile's call start (FREE_ of GCP_FO_TILE_DEFINE_ and the
 * gyro tile): free = 1, the whole call untested where the uniform field's
 * proof holds (*fend = kmax); free = 2, the dipole's stretches, the first
 * proved at step 0 (*next = 0) with *hm the largest |h/gamma| of the tile;
 * otherwise every step tested (*next = kmax, no proof step). */
static inline void gcp_fo_free_begin(int free, const double *restrict x, const double *restrict y,
                                     const double *restrict z, const double *restrict ux,
                                     const double *restrict uy, const double *restrict uz,
                                     const double *restrict hg, size_t nt, int64_t kmax,
                                     const struct gcp_fo_tile_args *a, double emag, double bmag,
                                     double h, int64_t *fend, int64_t *next, double *hm)
{
    *fend = 0, *next = kmax, *hm = fabs(h);
    if (free == 1 && gcp_fo_nr_cannot_stop(x, y, z, ux, uy, uz, nt, kmax, a, emag, bmag,
                                           GCP_FO_REL_TB_))
        *fend = kmax;
    if (free == 2 && gcp_fo_free_ok(a, kmax)) {
        double m = *hm;
        for (size_t i = 0; i < nt; i++) m = fabs(hg[i]) > m ? fabs(hg[i]) : m;
        *next = 0, *hm = m;
    }
}
/* At a stretch's proof step s (s == *next): the stretch's end, *fend =
 * *next = s + K with K = gcp_fo_free_steps capped at the call's kmax, or,
 * where K < GCP_FO_FREE_MIN, the next proof GCP_FO_FREE_KCHK steps on
 * (those steps tested).  Shared by the plain tiles and the observer's gyro
 * tile (fo_fused_priv.h), which pass their u- arrays. */
static inline void gcp_fo_free_plan(int64_t s, int64_t kmax, const double *restrict x,
                                    const double *restrict y, const double *restrict z,
                                    const double *restrict ux, const double *restrict uy,
                                    const double *restrict uz, size_t n, double h,
                                    const struct gcp_fo_tile_args *a, int64_t *next,
                                    int64_t *fend)
{
    int64_t kf = 0;
    if (kmax - s >= GCP_FO_FREE_MIN)
        kf = gcp_fo_free_steps(x, y, z, ux, uy, uz, n, h, sqrt(a->rin2), sqrt(a->rout2),
                               a->zmax);
    if (kf > kmax - s) kf = kmax - s;
    if (kf >= GCP_FO_FREE_MIN)
        *fend = *next = s + kf;
    else
        *next = s + GCP_FO_FREE_KCHK;
}

#endif
