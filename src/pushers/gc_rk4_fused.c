/* The fused gc-rk4 step (issue 12): where the field is one closed form of
 * field_kernels.h (gcp_field_point_B), the four stages of a step -- field,
 * right-hand side, stage state, accumulation -- run as four loops over a
 * tile of GCP_RK4_TILE lanes whose stage state lives in tile-local arrays
 * (in L1), with the form's field inline (no field call, no B or grad B
 * arrays), for several steps per tile, as the full-orbit fused step does
 * (fo_fused_priv.h):
 *
 *   stage 1  k1 and the start-of-step verdict (gc_rk4.c's stage1: finite,
 *            |B| > 0, and with opts->adiabaticity_max > 0 the adiabaticity
 *            test on the form's B and grad B, gcp_point_BG_dipole: the
 *            model's numbers, so the block step's verdicts)
 *   stage 2  k2 at y + h/2 k1,  stage 3  k3 at y + h/2 k2,
 *   stage 4  k4 at y + h k3, y += h/6 (k1 + 2 k2 + 2 k3 + k4), and the
 *            classification (whether gcp_block_classify stops the lane).
 *
 * A tile stops before a step whose start check stops a lane, or after a
 * step that a lane does not survive; the block takes the fewest steps any
 * tile took, tiles that ran further are restored and run again to it
 * (gc_rk4.c rk4_steps), so the evolve layer sees the lanes, statuses and
 * steps lock-step would have given.
 *
 * The right-hand side is that of a curl-free field (rhs_vacuum: B*_par =
 * |B|) from B, |B|, B x H and B.H, H = B.grad B, in closed form
 * (gcp_point_gc_dipole): per stage 3 square roots and 2 divisions (block
 * step: 3 and 3) and ~53 multiplications (~105); what bounds it now is
 * the latency of a stage's chain (sqrt, division, sqrt, division in
 * series, ~110 cycles) against the out-of-order window: removing a square
 * root or a tenth of the multiplications gains < 3%.  The numbers differ from the block step's by round-off
 * (tests/unit/test_gc_fused.c: within 7e-14 of the travel over 400 steps).
 * Each stage loop keeps the verdicts in int16_t so that the vectoriser
 * takes 32 lanes per iteration (four AVX-512 vectors per operation, whose
 * independent chains hide the latency of the divisions and square roots;
 * int32_t: 16 lanes, ~35% slower; int8_t: 64 lanes, spills, ~30% slower).
 * 1 MeV protons in the dipole, one core, 8192 lanes: 8.3 ns a
 * particle-step (the block step: 16.9; limit kernel (c): 6.6). */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "gcpush/field_kernels.h"
#include "gcpush/particles.h"
#include "block_priv.h"
#include "gc_priv.h"
#include "gc_rk4_priv.h"

/* The form's B, |B|, C = B x H and P = B.H (H = B.grad B;
 * field_kernels.h gcp_point_gc_dipole; C = P = 0 for the uniform form) and
 * E at (x, y, z) from its parameters p (form and withE constants at each
 * call: one instance per tile function). */
static inline __attribute__((always_inline)) void
form_gc(int form, int withE, const double *p, double x, double y, double z, double B[3],
        double *Bm, double C[3], double *P, double E[3])
{
    if (form == GCP_POINT_B_DIPOLE) {
        gcp_point_gc_dipole(p[0], x, y, z, B, Bm, C, P);
    } else {
        B[0] = p[0], B[1] = p[1], B[2] = p[2];
        *Bm = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
        C[0] = C[1] = C[2] = *P = 0.0;
    }
    E[0] = withE ? p[3] : 0.0, E[1] = withE ? p[4] : 0.0, E[2] = withE ? p[5] : 0.0;
}

/* The same with the full gradient G (the adiabaticity test's input). */
static inline __attribute__((always_inline)) void
form_BG(int form, const double *p, double x, double y, double z, double B[3], double G[3][3])
{
    if (form == GCP_POINT_B_DIPOLE) {
        gcp_point_BG_dipole(p[0], x, y, z, B, G);
    } else {
        B[0] = p[0], B[1] = p[1], B[2] = p[2];
        for (int i = 0; i < 3; i++) G[i][0] = G[i][1] = G[i][2] = 0.0;
    }
}

/* The guiding-centre right-hand side of kernels.h gcp_gc_rhs (Cary &
 * Brizard 2009) in a curl-free field (the forms of field_kernels.h are
 * vacuum fields), from B, |B|, C = B x H and H.B, H = B.grad B = |B| grad|B|,
 * and E:
 *   curl b = (b x grad|B|)/|B|,  so  b.curl b = 0  and  B*_par = |B|,
 *   B* = B + (p_par/q) (B x H)/|B|^3,
 *   E* = E - (mu/(q gamma |B|)) H = E - phi H,
 *   E* x b / B*_par = (E x B)/|B|^2 + phi (B x H)/|B|^2,
 *   dX/dt = (v_par/|B|) B* + E* x b/|B|,   v_par = p_par/(gamma m),
 *   dp_par/dt = (q/|B|) E*.B* = (q/|B|) (E.B* - phi H.B)
 * (H.(B x H) = 0).  One division, D = 1/(|B| gamma), gives 1/|B| = gamma D
 * and phi = mu D/q, v_par/|B| = p_par D/m; one square root (gamma; |B|
 * comes with the form); 23 multiplications without E (the block step's
 * rhs_chunk, gc_rk4.c, which takes the full gradient and keeps curl B:
 * 68).  The numbers differ from
 * the block step's by round-off (tests/unit/test_gc_fused.c).  Returns the
 * block step's verdict: NONFINITE for a non-finite derivative, else
 * NONADIABATIC where |B| = 0 (B*_par = |B| here), else 0. */
static inline __attribute__((always_inline)) int32_t
rhs_vacuum(const double B[3], double Bm, const double C[3], double HB, const double E[3],
           int withE, double pp, double mui, const struct gcp_rk4_consts *kc, double *dXo,
           double *dYo, double *dZo, double *dpo)
{
    const double Bx = B[0], By = B[1], Bz = B[2], Cx = C[0], Cy = C[1], Cz = C[2];
    const double a = pp * kc->imc;
    const double gamma = sqrt(1.0 + a * a + mui * Bm * kc->k2);
    const double D = 1.0 / (Bm * gamma); /* 1/(|B| gamma) */
    const double iB = gamma * D, iB2 = iB * iB;
    /* dX/dt = al B + ce (B x H) [+ (E x B)/|B|^2] with al = v_par/|B| and
     * ce = al kap + phi/|B|^2, kap = (p_par/q)/|B|^3 (B* = B + kap B x H):
     *   ce = (D/(q |B|^2)) (p_par^2/(m |B|) + mu) */
    const double ppm = pp * kc->im, al = ppm * D;
    const double ce = D * iB2 * kc->iq * (ppm * pp * iB + mui);
    double dX = al * Bx + ce * Cx, dY = al * By + ce * Cy, dZ = al * Bz + ce * Cz;
    double dp;
    if (withE) {
        const double Ex = E[0], Ey = E[1], Ez = E[2];
        const double kap = pp * kc->iq * iB * iB2, phi = mui * kc->iq * D;
        dX = dX + iB2 * (Ey * Bz - Ez * By);
        dY = dY + iB2 * (Ez * Bx - Ex * Bz);
        dZ = dZ + iB2 * (Ex * By - Ey * Bx);
        const double EBs = (Ex * Bx + Ey * By + Ez * Bz) + kap * (Ex * Cx + Ey * Cy + Ez * Cz);
        dp = kc->q * iB * (EBs - phi * HB);
    } else {
        /* (q/|B|) (-phi H.B), phi = mu/(q gamma |B|) = mu D/q */
        dp = -(mui * D * iB * HB);
    }
    *dXo = dX, *dYo = dY, *dZo = dZ, *dpo = dp;
    const int32_t nonfinite = !(fabs(dX + dY + dZ + dp) <= DBL_MAX);
    const int32_t bad = !(Bm > 0.0);
    return nonfinite * GCP_NONFINITE + (1 - nonfinite) * bad * GCP_NONADIABATIC;
}

/* The stages.  FIRST: at the step's start state (x .. p), k1 into acc,
 * the next stage's state y + (h/2) k1 into
 * the tile arrays S, its verdict into code; returns non-zero when a lane's
 * verdict is.  MID: at S, acc += w k, S = y + cn k, verdicts merged.
 * LAST: at S, acc += k, y += (h/6) acc, the verdicts merged and written to
 * fst, and returns non-zero when a lane stops (its verdict or the
 * classification's bounds). */
enum { ST_FIRST, ST_MID, ST_LAST };

/* The dipole form's values at a lane's state (B, |B|, C_x, C_y, P: C_z
 * is 0), formed by the last step of a call at the new state (ST_LAST with
 * `carried`) into the caller's arrays cv (B in the block's b->Bx, By, Bz,
 * where the invariant observer reads it: gc_rk4_priv.h), and read by the
 * next call's first stage 1 instead of forming them again: the same
 * numbers (the same function of the same state), so the push is the same
 * bit for bit.  With the observer a call is one step: the step's form is
 * then formed once for the pusher and the observer.  Without a sampler a
 * call takes every step of the push, and nothing is carried (carry 0). */

struct tile_state {
    double S[4][GCP_RK4_TILE];   /* the stage state X, Y, Z, p_par */
    double acc[4][GCP_RK4_TILE]; /* k1 + 2 k2 + 2 k3 + k4 so far */
    int16_t code[GCP_RK4_TILE];  /* the step's verdict so far (gc_rk4.c: why int16_t) */
};

static inline __attribute__((always_inline)) int32_t
stage(int form, int withE, int mode, int carried, struct tile_state *restrict ts,
      double *restrict x, double *restrict y, double *restrict z, double *restrict p,
      const double *restrict mu, int32_t *restrict fst, double *const *restrict cv, size_t nt,
      double w, double cn, const struct gcp_rk4_tile_args *pa)
{
    /* a copy: the loop reads no memory that a store of it could change */
    const struct gcp_rk4_tile_args A = *pa, *a = &A;
    double *restrict X = ts->S[0], *restrict Y = ts->S[1], *restrict Z = ts->S[2];
    double *restrict P = ts->S[3];
    double *restrict a0 = ts->acc[0], *restrict a1 = ts->acc[1], *restrict a2 = ts->acc[2];
    double *restrict a3 = ts->acc[3];
    int16_t *restrict code = ts->code;
    const double h6 = a->h / 6.0;
    const double rin2 = a->rin2, rout2 = a->rout2, zmax = a->zmax;
    double *restrict v0 = cv[0], *restrict v1 = cv[1], *restrict v2 = cv[2], *restrict v3 = cv[3];
    double *restrict v4 = cv[4], *restrict v5 = cv[5], *restrict v6 = cv[6];
    int32_t any = 0;
    /* the arrays are distinct (GCC would test 12+ pairs of them for overlap
     * at run time, and gives up past 10: the loop ran scalar) */
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC ivdep
#endif
    for (size_t i = 0; i < nt; i++) {
        const double Xi = mode == ST_FIRST ? x[i] : X[i], Yi = mode == ST_FIRST ? y[i] : Y[i];
        const double Zi = mode == ST_FIRST ? z[i] : Z[i], Pi = mode == ST_FIRST ? p[i] : P[i];
        double B[3], Bm, C[3], HB, E[3], dX, dY, dZ, dp;
        if (mode == ST_FIRST && carried && form == GCP_POINT_B_DIPOLE) {
            B[0] = v0[i], B[1] = v1[i], B[2] = v2[i], Bm = v3[i];
            C[0] = v4[i], C[1] = v5[i], C[2] = 0.0, HB = v6[i];
            E[0] = withE ? a->p[3] : 0.0, E[1] = withE ? a->p[4] : 0.0;
            E[2] = withE ? a->p[5] : 0.0;
        } else {
            form_gc(form, withE, a->p, Xi, Yi, Zi, B, &Bm, C, &HB, E);
        }
        const int32_t own = rhs_vacuum(B, Bm, C, HB, E, withE, Pi, mu[i], &a->kc, &dX, &dY, &dZ, &dp);
        if (mode == ST_FIRST) {
            a0[i] = dX, a1[i] = dY, a2[i] = dZ, a3[i] = dp;
            X[i] = x[i] + cn * dX, Y[i] = y[i] + cn * dY;
            Z[i] = z[i] + cn * dZ, P[i] = p[i] + cn * dp;
            code[i] = (int16_t)own;
            any |= own;
        } else {
            const double s0 = a0[i] + w * dX, s1 = a1[i] + w * dY;
            const double s2 = a2[i] + w * dZ, s3 = a3[i] + w * dp;
            const int32_t c0 = code[i];
            const int32_t code1 = c0 + (c0 == 0) * own;
            if (mode == ST_MID) {
                a0[i] = s0, a1[i] = s1, a2[i] = s2, a3[i] = s3;
                code[i] = (int16_t)code1;
                X[i] = x[i] + cn * dX, Y[i] = y[i] + cn * dY;
                Z[i] = z[i] + cn * dZ, P[i] = p[i] + cn * dp;
            } else {
                const double x1 = x[i] + h6 * s0, y1 = y[i] + h6 * s1;
                const double z1 = z[i] + h6 * s2, p1 = p[i] + h6 * s3;
                x[i] = x1, y[i] = y1, z[i] = z1, p[i] = p1;
                fst[i] = code1;
                /* the form at the new state, for the next call's stage 1 */
                if (carried && form == GCP_POINT_B_DIPOLE) {
                    double B1[3], Bm1, C1[3], HB1;
                    gcp_point_gc_dipole(a->p[0], x1, y1, z1, B1, &Bm1, C1, &HB1);
                    v0[i] = B1[0], v1[i] = B1[1], v2[i] = B1[2], v3[i] = Bm1;
                    v4[i] = C1[0], v5[i] = C1[1], v6[i] = HB1;
                }
                const double r2 = x1 * x1 + y1 * y1 + z1 * z1;
                any |= (code1 != 0) | gcp_lane_stops(r2, p1 * p1 + mu[i], z1, rin2, rout2, zmax);
            }
        }
    }
    return any;
}

/* gc_rk4.c's adiabaticity_chunk on the tile (opts->adiabaticity_max > 0),
 * vectorised: lanes whose stage-1 verdict is 0 but exceed amax at the
 * step's start become NONADIABATIC (gcp_gc_adiabaticity_of on the form's B
 * and grad B, the model's numbers: the block step's verdicts). */
static inline __attribute__((always_inline)) int32_t
adiabaticity_tile(int form, struct tile_state *restrict ts, const double *restrict x,
                  const double *restrict y, const double *restrict z, const double *restrict p,
                  const double *restrict mu, size_t nt, const struct gcp_rk4_tile_args *pa)
{
    const struct gcp_rk4_tile_args A = *pa;
    int16_t *restrict code = ts->code;
    int32_t any = 0;
    for (size_t i = 0; i < nt; i++) {
        double B[3], G[3][3];
        form_BG(form, A.p, x[i], y[i], z[i], B, G);
        const int32_t over = !(gcp_gc_adiabaticity_of(B, G, p[i], mu[i], A.q, A.m) <= A.amax);
        const int32_t c0 = code[i];
        const int32_t cv = c0 + (c0 == 0) * over * GCP_NONADIABATIC;
        code[i] = (int16_t)cv;
        any |= cv;
    }
    return any;
}

static inline __attribute__((always_inline)) int64_t
tile_steps(int form, int withE, double *restrict x, double *restrict y, double *restrict z,
           double *restrict p, const double *restrict mu, int32_t *restrict fst,
           double *const *restrict cv, int carry, int32_t *stopped, size_t nt, int64_t kmax,
           const struct gcp_rk4_tile_args *a)
{
    *stopped = 0;
    struct tile_state ts;
    const double h = a->h;
    for (int64_t s = 0; s < kmax; s++) {
        /* the call's first stage 1 reads the form where it is carried in;
         * the others form it (in registers: carrying it from step to step
         * through the tile's memory cost ~6% of the step) */
        int32_t any = s == 0 && (carry & GCP_RK4_CARRY_IN)
                          ? stage(form, withE, ST_FIRST, 1, &ts, x, y, z, p, mu, fst, cv, nt, 1.0,
                                  0.5 * h, a)
                          : stage(form, withE, ST_FIRST, 0, &ts, x, y, z, p, mu, fst, cv, nt, 1.0,
                                  0.5 * h, a);
        if (a->amax > 0.0) any |= adiabaticity_tile(form, &ts, x, y, z, p, mu, nt, a);
        if (any) return s;
        /* k2 at t + h/2 (weight 2, next offset h/2), k3 at t + h/2 (2, h), k4 at t + h (1) */
        stage(form, withE, ST_MID, 0, &ts, x, y, z, p, mu, fst, cv, nt, 2.0, 0.5 * h, a);
        stage(form, withE, ST_MID, 0, &ts, x, y, z, p, mu, fst, cv, nt, 2.0, 1.0 * h, a);
        /* the call's last step writes the form at the new state (where
         * the caller asks: a next call or a sampler reads it) */
        const int32_t stop =
            s == kmax - 1 && (carry & GCP_RK4_CARRY_OUT)
                ? stage(form, withE, ST_LAST, 1, &ts, x, y, z, p, mu, fst, cv, nt, 1.0, 0.0, a)
                : stage(form, withE, ST_LAST, 0, &ts, x, y, z, p, mu, fst, cv, nt, 1.0, 0.0, a);
        if (stop) {
            *stopped = 1;
            return s + 1;
        }
    }
    return kmax;
}

#define TILE_FN_(NAME, FORM, WITHE)                                                             \
    static int64_t NAME(double *restrict x, double *restrict y, double *restrict z,             \
                        double *restrict p, const double *restrict mu, int32_t *restrict fst,    \
                        double *const *cv, int carry, int32_t *stopped, size_t nt,               \
                        int64_t kmax, const struct gcp_rk4_tile_args *a)                         \
    {                                                                                           \
        return tile_steps(FORM, WITHE, x, y, z, p, mu, fst, cv, carry, stopped, nt, kmax, a);   \
    }
TILE_FN_(tile_dipole_B, GCP_POINT_B_DIPOLE, 0)
TILE_FN_(tile_uniform_B, GCP_POINT_B_UNIFORM, 0)
TILE_FN_(tile_uniform_EB, GCP_POINT_B_UNIFORM, 1)

gcp_rk4_tile_fn gcp_rk4_fused_tile(int form, int has_E)
{
    if (form == GCP_POINT_B_DIPOLE && !has_E) return tile_dipole_B;
    if (form == GCP_POINT_B_UNIFORM) return has_E ? tile_uniform_EB : tile_uniform_B;
    return NULL;
}
