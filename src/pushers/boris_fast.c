/* The fast arithmetic tier of boris's fused tiles (issue 12; opt-in,
 * [integrator] arithmetic = fast, the block flag GCP_BLOCK_FAST_ARITH;
 * never the default).
 *
 * The IEEE tiles (fo_fused_priv.h, boris.c) must give the block step's
 * bits: no fused multiply-add, every square root and division IEEE
 * rounded, two of them (c/r^5's sqrt and division) on the divide unit
 * that bounds the step (bench_floor: the 2 sqrt + 4 divisions alone take
 * ~1.2 ns a lane-step, the whole of limit kernel (b)).  This tier gives
 * that up for the same scheme in a different arithmetic:
 *   - 1/r as 1/sqrt(r2) (two roundings) and c/r^5 = c (1/r)^5: one
 *     division fewer than c / (r2 r2 sqrt(r2));
 *   - fused multiply-adds wherever a product meets a sum;
 *   - the explicit AVX-512 vectors below, two lane groups interleaved;
 *   - in the dipole, the stop test only where a lane may reach a bound
 *     (gcp_fo_free_steps proves the others cannot: the verdicts are unchanged).
 * Each reciprocal can instead come from vrsqrt14pd / vrcp14pd (relative
 * error < 2^-14) and two Newton steps on the FMA pipes,
 * e/2 = 1/2 - (x/2) y y,  y <- y + y (e/2)  (one fma for the residual;
 * Markstein, IBM J. Res. Dev. 34 (1990) 111): each step squares the error,
 * 2^-14 -> 2^-28 -> 2^-56, so the result is within ~1 ulp
 * (tests/unit/test_boris_fast.c measures it).  Which reciprocals go to the
 * estimates and which stay on the divide unit was measured (limit_bench's
 * fW / mW: the two units work at once; FAST_IEEE_*): on Zen 5 none --
 * the divide unit's 2 sqrt and 3 divisions a vector then take about as
 * long as the ~43 operations left on the FMA pipes.
 * Not IEEE rounded: a step differs from the IEEE tier's in its last few
 * bits (a few ulp of |u| and |x|: the tests), and runs then drift apart as
 * round-off does; the physics is the same scheme's -- |u| kept by the
 * rotation to round-off, energy bounded as with IEEE Boris (the tests).
 *
 * A dipole step, per lane (ig = 1/gamma(u) kept from the last step, hg =
 * h ig, h = dt/2, qdt2m = q dt/2m):
 *   x_1/2 = x + u hg,  r2 = max(|x_1/2|^2, R2_MIN),  ir = 1/sqrt(r2),
 *   t = (qdt2m c) ig ir^5 (-3 z x, -3 z y, r2 - 3 z^2)  (gcp_point_B_dipole),
 *   s = 2 / (1 + t^2),  u+ = rotate(u; t, s)  (gcp_boris_rotate_ts_),
 *   ig = 1/sqrt(1 + |u+|^2/c^2),  hg = h ig,  x1 = x_1/2 + u+ hg
 * and the stop test of gcp_lane_stops.  In uniform E and B:
 * u- = u + qdt2m E, its 1/gamma, then as above with u+ + qdt2m E
 * (gcp_push_boris); in uniform B, t = qdt2m ig B.
 *
 * Compiled for AVX-512F by function attribute (also in the DEBUG build,
 * whose flags name no -march) and chosen at run time where the CPU has it
 * (gcp_fo_fast_set).  Elsewhere -- another architecture or compiler, a
 * CPU without AVX-512F -- there is no fast tier: arithmetic = fast runs
 * the IEEE tiles (gcp_arithmetic_fast_available says which; the run's log
 * says so).  No observer tile: with the observer's gyro-average on (a
 * sampler of every step) the fast push goes one step a call and the
 * sampler does each step's work itself from the state the fast step left,
 * so it observes exactly the step taken. */
#include <float.h>
#include <stdint.h>
#include <string.h>

#include "gcpush/field_kernels.h"
#include "gcpush/kernels.h"
#include "gcpush/pusher.h"
#include "fo_fast_priv.h"
#include "fo_fused_priv.h"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>

#define FAST_TGT __attribute__((target("avx512f")))
#define FAST_AI static inline __attribute__((always_inline)) FAST_TGT

/* One zmm an operation, W = 8 lanes a group; the step loop takes UNR
 * groups an iteration, so that the chains of one group overlap those of
 * the next (limit_bench's f16: two zmm an operation). */
#define W 8
#define UNR 2
typedef double fw __attribute__((vector_size(64), aligned(64)));

FAST_AI fw ld(const double *p) { return _mm512_loadu_pd(p); }
FAST_AI void st(double *p, fw v) { _mm512_storeu_pd(p, v); }

/* a b + c, a b - c and c - a b, one rounding each (vfmadd/vfmsub/vfnmadd) */
FAST_AI fw fma_(fw a, fw b, fw c) { return _mm512_fmadd_pd(a, b, c); }
FAST_AI fw fms_(fw a, fw b, fw c) { return _mm512_fmsub_pd(a, b, c); }

/* 1/sqrt(x), two Newton steps from vrsqrt14pd (the header's equations,
 * with e/2 = 1/2 - (x/2) y y formed in one fused operation). */
FAST_AI fw rsqrt_nr(fw x)
{
    const fw hx = 0.5 * x, half = (fw){0} + 0.5;
    fw y = _mm512_rsqrt14_pd(x);
    for (int k = 0; k < 2; k++) y = fma_(y, _mm512_fnmadd_pd(hx * y, y, half), y);
    return y;
}

/* 1/x, two Newton steps from vrcp14pd. */
FAST_AI fw rcp_nr(fw x)
{
    const fw one = (fw){0} + 1.0;
    fw y = _mm512_rcp14_pd(x);
    for (int k = 0; k < 2; k++) y = fma_(y, _mm512_fnmadd_pd(x, y, one), y);
    return y;
}

/* Which of the step's three reciprocals come from the divide/sqrt unit
 * (IEEE vsqrtpd/vdivpd; 1/gamma as 1/sqrt, two roundings) instead of the
 * estimates and Newton steps on the FMA pipes: both units then work at
 * once (limit_bench's mW).  Chosen by measurement on the development
 * machine (AMD EPYC, Zen 4; bench_push limit-fo, CPU time, alternating):
 * dipole 8192 lanes, ns a lane-step with the IEEE tile in the same run
 * ~1.95: S G R = 1 1 0 ~1.6, 0 0 0 (all Newton) ~1.8, 1 0 0 ~1.7, 1 1 1 (no
 * estimates) ~1.6 -- most of the gain is the fused operations, the shorter
 * stop test and the interleaved halves, not the estimates.  Measured again
 * in one process, the tiles called in turn with kernel (b) between them
 * (15 rounds, medians of the per-round ratios to (b), Zen 5, loaded
 * machine): 1 1 1 (this) 1.08x (b), 1 1 0 1.12-1.14x -- the step's ~43
 * multiplications and fused operations and its 2 sqrt and 3 divisions
 * then take about as long on their units (~22 cycles a vector each), where
 * the Newton 1/r put ~7 more on the FMA pipes. */
#ifndef FAST_IEEE_S
#define FAST_IEEE_S 1 /* s = 2 / (1 + t^2) */
#endif
#ifndef FAST_IEEE_G
#define FAST_IEEE_G 1 /* 1/gamma */
#endif
#ifndef FAST_IEEE_R
#define FAST_IEEE_R 1 /* 1/sqrt(r2) */
#endif
FAST_AI fw rsqrt_ieee(fw x) { return 1.0 / _mm512_sqrt_pd(x); }
#define RSQRT_G(x) (FAST_IEEE_G ? rsqrt_ieee(x) : rsqrt_nr(x))
#define RSQRT_R(x) (FAST_IEEE_R ? rsqrt_ieee(x) : rsqrt_nr(x))
#define TWO_OVER(x) (FAST_IEEE_S ? 2.0 / (x) : 2.0 * rcp_nr(x))

/* max(r2, lo) as `r2 > lo ? r2 : lo` (NaN gives lo: vmaxpd returns its
 * second operand where either is NaN). */
FAST_AI fw floor_at(fw r2, double lo) { return _mm512_max_pd(r2, _mm512_set1_pd(lo)); }

/* gcp_lane_stops, lane by lane: a bit set for each lane that stops.  Its
 * six comparisons in four independent ones (no chain of masked compares):
 * r2 and p2 are sums of squares, so r2 + p2 is >= 0 or NaN and only its
 * upper bound can fail; |z| <= zmax is one compare of |z|.  The unordered
 * predicates make NaN a stop, as the negated test of gcp_lane_stops. */
FAST_AI unsigned lane_stops(fw r2, fw p2, fw z, double rin2, double rout2, double zmax)
{
    const __mmask8 b = _mm512_cmp_pd_mask(r2 + p2, _mm512_set1_pd(DBL_MAX), _CMP_NLE_UQ) |
                       _mm512_cmp_pd_mask(r2, _mm512_set1_pd(rin2), _CMP_NGE_UQ) |
                       _mm512_cmp_pd_mask(r2, _mm512_set1_pd(rout2), _CMP_NLE_UQ) |
                       _mm512_cmp_pd_mask(_mm512_abs_pd(z), _mm512_set1_pd(zmax), _CMP_NLE_UQ);
    return (unsigned)b;
}

enum { F_DIPOLE_B, F_UNIFORM_B, F_UNIFORM_EB };

/* What a group's step needs, fixed for the call. */
struct fast_k {
    double h, qdt2m, qc, rin2, rout2, zmax, B0, B1, B2, qE0, qE1, qE2;
};

/* One step of the W UNR lanes at i0 in two halves (the header's
 * equations), each statement for the UNR groups in turn (J_), so that
 * their instructions interleave: a group's whole step is one dependency
 * chain of ~150 cycles (two 1/sqrt, a division, the field and rotation
 * between them), longer than the out-of-order window can overlap with the
 * next group's, so the tile runs, as the IEEE one (fo_fused_priv.h), as
 * two loops over its lanes: the first to the field's t and s (kept in
 * K[4][tile]), the second the rotation, 1/gamma, the drift and the stop
 * test.  Returns the stop bits of its lanes (0 unless check). */
#define J_ for (int j = 0; j < UNR; j++)
FAST_AI void fast_half1(const int form, size_t i0, double *restrict x, double *restrict y,
                        double *restrict z, const double *restrict ux,
                        const double *restrict uy, const double *restrict uz,
                        const double *restrict ig_, const double *restrict hg_,
                        double (*restrict K)[GCP_FO_TILE], const struct fast_k *k)
{
    const fw one = (fw){0} + 1.0, ic2 = (fw){0} + GCP_INV_C2, m3 = (fw){0} - 3.0;
    fw U[UNR], V[UNR], Wz[UNR], g[UNR], X[UNR], Y[UNR], Z[UNR], tx[UNR], ty[UNR], tz[UNR];
    fw ig[UNR];
    J_ U[j] = ld(ux + i0 + W * j), V[j] = ld(uy + i0 + W * j), Wz[j] = ld(uz + i0 + W * j);
    J_ g[j] = ld(hg_ + i0 + W * j);
    J_ X[j] = fma_(U[j], g[j], ld(x + i0 + W * j));
    J_ Y[j] = fma_(V[j], g[j], ld(y + i0 + W * j));
    J_ Z[j] = fma_(Wz[j], g[j], ld(z + i0 + W * j));
    J_ st(x + i0 + W * j, X[j]), st(y + i0 + W * j, Y[j]), st(z + i0 + W * j, Z[j]);
    if (form == F_UNIFORM_EB) { /* u- = u + qdt2m E and its 1/gamma */
        J_ U[j] = U[j] + k->qE0, V[j] = V[j] + k->qE1, Wz[j] = Wz[j] + k->qE2;
        J_ ig[j] = RSQRT_G(fma_(fma_(U[j], U[j], fma_(V[j], V[j], Wz[j] * Wz[j])), ic2, one));
    } else {
        J_ ig[j] = ld(ig_ + i0 + W * j);
    }
    if (form == F_DIPOLE_B) {
        /* t = (qdt/2m) ig B, B = c/r^5 (-3 z x, -3 z y, r2 - 3 z^2)
         * (gcp_point_B_dipole), c folded into qdt2m, 1/r^5 from rsqrt(r2) */
        fw r2[UNR], ir[UNR], ir2[UNR], f[UNR], fz[UNR];
        J_ r2[j] = fma_(X[j], X[j], fma_(Y[j], Y[j], Z[j] * Z[j]));
        J_ r2[j] = floor_at(r2[j], GCP_POINT_DIPOLE_R2_MIN);
        J_ ir[j] = RSQRT_R(r2[j]);
        J_ ir2[j] = ir[j] * ir[j];
        J_ f[j] = (k->qc * ig[j]) * ((ir2[j] * ir2[j]) * ir[j]);
        J_ fz[j] = (m3 * f[j]) * Z[j];
        J_ tx[j] = fz[j] * X[j], ty[j] = fz[j] * Y[j];
        J_ tz[j] = f[j] * fma_(m3 * Z[j], Z[j], r2[j]);
    } else {
        J_ tx[j] = (k->qdt2m * ig[j]) * k->B0, ty[j] = (k->qdt2m * ig[j]) * k->B1;
        J_ tz[j] = (k->qdt2m * ig[j]) * k->B2;
    }
    /* gcp_boris_ts_ */
    J_ {
        const size_t i = i0 + W * j;
        st(K[0] + i, tx[j]), st(K[1] + i, ty[j]), st(K[2] + i, tz[j]);
        st(K[3] + i, TWO_OVER(fma_(tx[j], tx[j], fma_(ty[j], ty[j], fma_(tz[j], tz[j], one)))));
    }
}

FAST_AI unsigned fast_half2(const int form, size_t i0, double *restrict x, double *restrict y,
                            double *restrict z, double *restrict ux, double *restrict uy,
                            double *restrict uz, double *restrict ig_, double *restrict hg_,
                            double (*restrict K)[GCP_FO_TILE], const struct fast_k *k,
                            int check)
{
    const fw one = (fw){0} + 1.0, ic2 = (fw){0} + GCP_INV_C2;
    fw U[UNR], V[UNR], Wz[UNR], g[UNR], X[UNR], Y[UNR], Z[UNR], tx[UNR], ty[UNR], tz[UNR];
    fw ig[UNR], sv[UNR], up[3][UNR], u2[UNR];
    unsigned bad = 0;
    J_ U[j] = ld(ux + i0 + W * j), V[j] = ld(uy + i0 + W * j), Wz[j] = ld(uz + i0 + W * j);
    J_ tx[j] = ld(K[0] + i0 + W * j), ty[j] = ld(K[1] + i0 + W * j);
    J_ tz[j] = ld(K[2] + i0 + W * j), sv[j] = ld(K[3] + i0 + W * j);
    if (form == F_UNIFORM_EB) J_ U[j] = U[j] + k->qE0, V[j] = V[j] + k->qE1, Wz[j] = Wz[j] + k->qE2;
    /* gcp_boris_rotate_ts_ */
    J_ up[0][j] = U[j] + fms_(V[j], tz[j], Wz[j] * ty[j]);
    J_ up[1][j] = V[j] + fms_(Wz[j], tx[j], U[j] * tz[j]);
    J_ up[2][j] = Wz[j] + fms_(U[j], ty[j], V[j] * tx[j]);
    J_ U[j] = fma_(sv[j], fms_(up[1][j], tz[j], up[2][j] * ty[j]), U[j]);
    J_ V[j] = fma_(sv[j], fms_(up[2][j], tx[j], up[0][j] * tz[j]), V[j]);
    J_ Wz[j] = fma_(sv[j], fms_(up[0][j], ty[j], up[1][j] * tx[j]), Wz[j]);
    if (form == F_UNIFORM_EB) J_ U[j] = U[j] + k->qE0, V[j] = V[j] + k->qE1, Wz[j] = Wz[j] + k->qE2;
    J_ u2[j] = fma_(U[j], U[j], fma_(V[j], V[j], Wz[j] * Wz[j]));
    J_ ig[j] = RSQRT_G(fma_(u2[j], ic2, one));
    J_ g[j] = k->h * ig[j];
    J_ X[j] = fma_(U[j], g[j], ld(x + i0 + W * j));
    J_ Y[j] = fma_(V[j], g[j], ld(y + i0 + W * j));
    J_ Z[j] = fma_(Wz[j], g[j], ld(z + i0 + W * j));
    J_ {
        const size_t i = i0 + W * j;
        st(x + i, X[j]), st(y + i, Y[j]), st(z + i, Z[j]);
        st(ux + i, U[j]), st(uy + i, V[j]), st(uz + i, Wz[j]);
        st(ig_ + i, ig[j]), st(hg_ + i, g[j]);
    }
    if (check)
        J_ bad |= lane_stops(fma_(X[j], X[j], fma_(Y[j], Y[j], Z[j] * Z[j])), u2[j], Z[j],
                             k->rin2, k->rout2, k->zmax);
    return bad;
}

/* kmax steps of the lanes [0, n) (n a multiple of W UNR) of one tile; the
 * arrays ig and hg the lanes' 1/gamma and h/gamma on entry.  Returns the
 * steps taken, as gcp_fo_tile_fn (with check = 0: no stop test, kmax). */
FAST_AI int64_t fast_steps(const int form, double *restrict x, double *restrict y,
                           double *restrict z, double *restrict ux, double *restrict uy,
                           double *restrict uz, double *restrict ig_, double *restrict hg_,
                           size_t n, int64_t kmax, const struct fast_k *k, int32_t *stopped,
                           int check)
{
    _Alignas(64) double K[4][GCP_FO_TILE];
    for (int64_t s = 0; s < kmax; s++) {
        unsigned bad = 0;
        for (size_t i = 0; i < n; i += W * UNR)
            fast_half1(form, i, x, y, z, ux, uy, uz, ig_, hg_, K, k);
        for (size_t i = 0; i < n; i += W * UNR)
            bad |= fast_half2(form, i, x, y, z, ux, uy, uz, ig_, hg_, K, k, check);
        if (bad) {
            *stopped = 1;
            return s + 1;
        }
    }
    return kmax;
}

/* The dipole's stop test skipped where gcp_fo_free_steps proves it false
 * (fo_fused_priv.h, the proof shared with the IEEE dipole tile; the test
 * is ~10% of this tier's dipole step: 1.51 -> 1.36 ns a lane-step, 1024
 * lanes, the tiles timed in one process in turn with kernel (b), Zen 5):
 * its bound on a step's drift, 4.2 h |u|, covers this tier's 1/gamma
 * (1/sqrt, IEEE or Newton: <= 1 + a few eps) and its fused operations. */
#ifndef FAST_PROOF
#define FAST_PROOF 1 /* 0: the test every step (to measure what the proof saves) */
#endif
/* One tile (gcp_fo_tile_fn): lanes [0, nt) in place when nt is a multiple
 * of W, else through a padded copy whose extra lanes repeat lane 0 (so
 * they stop exactly when lane 0 does: the tile's verdict is unchanged).
 * ig and hg are formed from u on entry -- the same bits as the previous
 * call's last step left (the same expression of the same u), so b->hg is
 * neither read nor written (hg_mode ignored) and a push split into calls
 * takes the same steps as one call.  Uniform fields skip the per-step stop
 * test where gcp_fo_nr_cannot_stop proves it false (fo_fused_priv.h: its
 * bounds hold with |s| and 1/gamma within a few ulp of the IEEE ones --
 * the proof leaves a factor 3e7 of room), the dipole where gcp_fo_free_steps
 * does, a stretch of steps at a time. */
FAST_AI int64_t fast_tile(const int form, double *restrict x0, double *restrict y0,
                          double *restrict z0, double *restrict ux0, double *restrict uy0,
                          double *restrict uz0, size_t nt, int64_t kmax,
                          const struct gcp_fo_tile_args *a, int32_t *stopped)
{
    const double qdt2m = 0.5 * a->q * a->dt / a->m;
    struct fast_k k = {.h = a->h, .qdt2m = qdt2m, .qc = qdt2m * a->p[0],
                       .rin2 = a->rin2, .rout2 = a->rout2, .zmax = a->zmax,
                       .B0 = a->p[0], .B1 = a->p[1], .B2 = a->p[2],
                       .qE0 = qdt2m * a->p[3], .qE1 = qdt2m * a->p[4],
                       .qE2 = qdt2m * a->p[5]};
    _Alignas(64) double ig[GCP_FO_TILE], hg[GCP_FO_TILE], pad[6][GCP_FO_TILE];
    double *v0[6] = {x0, y0, z0, ux0, uy0, uz0}, *v[6];
    const size_t n = (nt + W * UNR - 1) / (W * UNR) * (W * UNR);
    for (int k = 0; k < 6; k++) {
        v[k] = v0[k];
        if (n == nt) continue;
        memcpy(pad[k], v0[k], nt * sizeof(double));
        for (size_t i = nt; i < n; i++) pad[k][i] = v0[k][0];
        v[k] = pad[k];
    }
    for (size_t i = 0; i < n; i += W) {
        const fw U = ld(v[3] + i), V = ld(v[4] + i), Wz = ld(v[5] + i);
        const fw g = RSQRT_G(fma_(fma_(U, U, fma_(V, V, Wz * Wz)), (fw){0} + GCP_INV_C2,
                                  (fw){0} + 1.0));
        st(ig + i, g), st(hg + i, a->h * g);
    }
    int64_t s = 0;
    int32_t stp = 0; /* *stopped may be set by an earlier tile */
    if (form != F_DIPOLE_B) {
        const double emag = form == F_UNIFORM_EB ? GCP_FO_ABS3_(a->p + 3) : 0.0;
        if (gcp_fo_nr_cannot_stop(v[0], v[1], v[2], v[3], v[4], v[5], nt, kmax, a, emag,
                                  GCP_FO_ABS3_(a->p), GCP_FO_REL_TB_))
            s = fast_steps(form, v[0], v[1], v[2], v[3], v[4], v[5], ig, hg, n, kmax, &k,
                           &stp, 0);
    } else if (FAST_PROOF && gcp_fo_free_ok(a, kmax)) {
        const double rin = sqrt(a->rin2), rout = sqrt(a->rout2);
        while (kmax - s >= GCP_FO_FREE_MIN) {
            int64_t kf = gcp_fo_free_steps(v[0], v[1], v[2], v[3], v[4], v[5], n, a->h, rin,
                                           rout, a->zmax);
            if (kf > kmax - s) kf = kmax - s;
            if (kf >= GCP_FO_FREE_MIN) {
                s += fast_steps(form, v[0], v[1], v[2], v[3], v[4], v[5], ig, hg, n, kf, &k,
                                &stp, 0);
                continue;
            }
            const int64_t kc = kmax - s < GCP_FO_FREE_KCHK ? kmax - s : GCP_FO_FREE_KCHK;
            const int64_t sc = fast_steps(form, v[0], v[1], v[2], v[3], v[4], v[5], ig, hg, n,
                                          kc, &k, &stp, 1);
            s += sc;
            if (sc < kc || stp) break;
        }
    }
    if (s < kmax && !stp)
        s = fast_steps(form, v[0], v[1], v[2], v[3], v[4], v[5], ig, hg, n, kmax - s, &k,
                       &stp, 1) + s;
    if (stp) *stopped = 1;
    if (n != nt)
        for (int k = 0; k < 6; k++) memcpy(v0[k], pad[k], nt * sizeof(double));
    return s;
}

#define FAST_TILE_FN_(NAME, FORM)                                                               \
    static FAST_TGT int64_t NAME(double *x, double *y, double *z, double *ux, double *uy,       \
                                 double *uz, double *hg, int hg_mode, size_t nt, int64_t kmax,  \
                                 const struct gcp_fo_tile_args *a, int32_t *stopped)            \
    {                                                                                           \
        (void)hg, (void)hg_mode;                                                                \
        return fast_tile(FORM, x, y, z, ux, uy, uz, nt, kmax, a, stopped);                      \
    }
FAST_TILE_FN_(boris_fast_dipole_B, F_DIPOLE_B)
FAST_TILE_FN_(boris_fast_uniform_B, F_UNIFORM_B)
FAST_TILE_FN_(boris_fast_uniform_EB, F_UNIFORM_EB)

static const struct gcp_fo_fused boris_fast = {
    .tile = {[GCP_POINT_B_UNIFORM] = {boris_fast_uniform_B, boris_fast_uniform_EB},
             [GCP_POINT_B_DIPOLE] = {boris_fast_dipole_B, NULL}}};

/* For the tests: the refined 1/sqrt and 1/x of n values (n a multiple of W). */
static FAST_TGT void fast_prims(size_t n, const double *in, double *rs, double *rc)
{
    for (size_t i = 0; i < n; i += W) st(rs + i, rsqrt_nr(ld(in + i))), st(rc + i, rcp_nr(ld(in + i)));
}

const struct gcp_fo_fused *gcp_fo_fast_set(const struct gcp_pusher_type *p)
{
    if (p != &gcp_pusher_boris) return NULL;
    return __builtin_cpu_supports("avx512f") ? &boris_fast : NULL;
}

int gcp_fo_fast_prims(size_t n, const double *in, double *rs, double *rc)
{
    if (!__builtin_cpu_supports("avx512f") || n % W) return -1;
    fast_prims(n, in, rs, rc);
    return 0;
}

#else /* no AVX-512 tier on this architecture or compiler: arithmetic = fast runs IEEE */

const struct gcp_fo_fused *gcp_fo_fast_set(const struct gcp_pusher_type *p)
{
    (void)p;
    return NULL;
}

int gcp_fo_fast_prims(size_t n, const double *in, double *rs, double *rc)
{
    (void)n, (void)in, (void)rs, (void)rc;
    return -1;
}

#endif
