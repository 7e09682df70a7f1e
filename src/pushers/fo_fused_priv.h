/* Private to the pushers: the fused full-orbit step (issue 12).
 *
 * The block step of fo_step.c makes six passes over the block's arrays per
 * step (drift, status reset, the field's block evaluation, kick, 1/gamma,
 * drift) and the evolve layer a seventh (classification); with 8192 lanes
 * every pass streams ~0.5 MB through L2.  Where the field is one closed
 * form of field_kernels.h (gcp_field_point_B) and the pusher has a fused
 * kernel set (gcp_pusher_type.fused), one loop does it all per lane in
 * registers:
 *
 *   x += u hg;  B = form(x);  u = kick(u; E, B);  hg = (dt/2)/gamma(u);
 *   x += u hg;  stops = gcp_lane_stops(x, u)  (gcp_lane_status != 0)
 *
 * -- the same operations in the same order as the passes (bit-identical;
 * the build keeps -ffp-contract=off) -- over tiles of GCP_FO_TILE lanes,
 * several steps per tile while the tile's 6 arrays (6 x 8 x 128 B = 6 KiB)
 * stay in L1.  That is the limit kernel's "resident" regime (many steps
 * per block in L1, ../shared/limit); lanes are independent, so stepping a
 * tile ahead of the others changes no lane's arithmetic.  What must stay
 * lock-step is what the evolve layer sees: a tile stops after the first
 * step in which any of its lanes stops (the classification's verdict,
 * computed in the loop), and the block's step count is the smallest over
 * tiles -- tiles that ran further are restored and run again to it
 * (fo_step.c fo_steps).  When a lane stopped, the evolve layer then
 * classifies and retires as after any step; when none did, the loop's test
 * was the classification (the closed forms give no field verdict), so the
 * layer skips its pass over the block.  It samples at its sampling steps,
 * which bound the steps asked for (evolve_priv.h `steps`).
 *
 * Streaming (issue 12: one step per call over a block far larger than the
 * caches, as a PIC code pushes): the tile reads and writes x and u and
 * nothing else -- no drift-factor array (hg is recomputed from u on entry),
 * no status or field-verdict pass unless a lane stopped -- so a step moves
 * the 96 B a lane that the memory floor moves.
 *
 * One tile function per (form, kick): the form's B and the kick are inline
 * in the loop, chosen once per push (fo_ctx), never per lane or per step.
 * Pushers see the form id only, never the model (field_kernels.h). */
#ifndef GCPUSH_FO_FUSED_PRIV_H
#define GCPUSH_FO_FUSED_PRIV_H

#include <float.h>
#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "gcpush/field_kernels.h"
#include "gcpush/kernels.h"
#include "block_priv.h"
#include "fo_gyro_priv.h"

/* Lanes per tile: 6 arrays of GCP_FO_TILE doubles (6 KiB) and the gamma
 * and drift-factor scratch stay in L1 (32 KiB here) with room to spare,
 * and a tile is 16 AVX-512 vectors, so the loop's vector body dominates its remainder.
 * Chosen, not tuned: the fused step is bound by its multiplications
 * (docs/DESIGN.md), not by where the tile lives once it is in L1. */
#define GCP_FO_TILE 128

#include "fo_free_priv.h" /* struct gcp_fo_tile_args, the stop-test proofs */

/* Up to kmax steps of lanes [0, nt) of one tile (arrays at the tile's
 * first lane): returns the steps taken, kmax or the first step after which
 * a lane's status is non-zero, and sets *stopped to 1 in the latter case
 * (it is left as it was otherwise).  x and u are read and written; the
 * drift factor (dt/2)/gamma(u), a function of u, is computed from it on
 * entry (the expression of the block step's half_drift_factor, so the same
 * bits) and kept in the tile between its steps -- a step that streams the
 * block from memory moves x and u and nothing else.  hg: the tile's
 * slots of b->hg, read on entry instead of recomputing the drift factors
 * when hg_mode has GCP_FO_HG_IN, written on return when it has
 * GCP_FO_HG_OUT (the push's next call then reads them: fo_step.c), not
 * touched when hg_mode is 0. */
#define GCP_FO_HG_IN 1
#define GCP_FO_HG_OUT 2
typedef int64_t (*gcp_fo_tile_fn)(double *x, double *y, double *z, double *ux, double *uy,
                                  double *uz, double *hg, int hg_mode, size_t nt, int64_t kmax,
                                  const struct gcp_fo_tile_args *a, int32_t *stopped);

/* The same with the invariant observer's per-step work of every step in
 * the tile loop (fo_gyro_priv.h; no E: the forms' B only): lanes [0, nt)
 * of the tile are the lanes i0 .. i0 + nt - 1 of gy's arrays (a dense
 * block, every lane's gyration begun), step s of the call (0-based) is the
 * push's step k0 + s, sampled at (t0 + (k0 + s) dt) + dt -- the evolve
 * layer's sampling time, bit for bit -- and the records of the gyrations
 * that end are appended to gy->rec (room for nt kmax of them: at most one
 * a lane a step).  The stopping step's observer work is done too (the
 * caller restores the call when a lane stops: fo_step.c). */
typedef int64_t (*gcp_fo_gyro_tile_fn)(double *x, double *y, double *z, double *ux, double *uy,
                                       double *uz, double *hg, int hg_mode, size_t nt,
                                       int64_t kmax, const struct gcp_fo_tile_args *a,
                                       int32_t *stopped, struct gcp_fo_gyro *gy, size_t i0,
                                       double t0, int64_t k0);

/* A pusher's fused kernels, by form and by E (tile[form][has_E]; NULL:
 * none, the block step runs), and with the observer's work (gyro[form],
 * B only). */
struct gcp_fo_fused {
    gcp_fo_tile_fn tile[GCP_POINT_B_NFORMS][2];
    gcp_fo_gyro_tile_fn gyro[GCP_POINT_B_NFORMS];
    int gyro_tele; /* the gyro tiles telescope S_r (gcp_fo_gyro.tele) */
};

/* The forms' B at (X, Y, Z) from a->p (field_kernels.h). */
#define GCP_FO_B_DIPOLE_(X, Y, Z, BX, BY, BZ) gcp_point_B_dipole(a->p[0], X, Y, Z, &BX, &BY, &BZ)
#define GCP_FO_B_UNIFORM_(X, Y, Z, BX, BY, BZ) (BX = a->p[0], BY = a->p[1], BZ = a->p[2])

/* The two halves of a lane's step (GCP_FO_TILE_DEFINE_): the half drift
 * to X_, Y_, Z_, IG0 and the field there; the kick from the point XS, YS,
 * ZS, the second half drift and the stop test. */
#define GCP_FO_LANE1_(FORM_, CARRY_)                                                            \
    const double g0_ = hg[i];                                                                   \
    const double X_ = x[i] + ux[i] * g0_, Y_ = y[i] + uy[i] * g0_, Z_ = z[i] + uz[i] * g0_;     \
    const double IG0 = CARRY_ ? IG[i] : 1.0;                                                    \
    (void)IG0;                                                                                  \
    double bx, by, bz;                                                                          \
    FORM_(X_, Y_, Z_, bx, by, bz);                                                              \
    (void)bx, (void)by, (void)bz;
/* The kick from u- = (U0_, V0_, W0_) at the point (XS, YS, ZS), gamma,
 * the second half drift into x and hg, and the stop test's r2, u2: the
 * lane's step after its field (GCP_FO_LANE2_, and the observer's gyro
 * tile, which keeps u- and u+ in buffers of its own). */
#define GCP_FO_KICK_DRIFT_(KICK_, CARRY_, U0_, V0_, W0_, XS, YS, ZS)                            \
    double U = U0_, V = V0_, W = W0_;                                                           \
    const double X = XS, Y = YS, Z = ZS;                                                        \
    KICK_;                                                                                      \
    const double G1 = gcp_gamma_of_u(U, V, W);                                                  \
    if (CARRY_) G[i] = G1;                                                                      \
    const double g1 = h / G1;                                                                   \
    const double X1 = X + U * g1, Y1 = Y + V * g1, Z1 = Z + W * g1;                             \
    x[i] = X1, y[i] = Y1, z[i] = Z1;                                                            \
    hg[i] = g1;                                                                                 \
    const double r2 = X1 * X1 + Y1 * Y1 + Z1 * Z1;                                              \
    const double u2 = U * U + V * V + W * W;
#define GCP_FO_LANE2_(KICK_, CARRY_, XS, YS, ZS, TEST_)                                         \
    GCP_FO_KICK_DRIFT_(KICK_, 0, ux[i], uy[i], uz[i], XS, YS, ZS)                               \
    if (CARRY_) IG[i] = 1.0 / G1;                                                               \
    ux[i] = U, uy[i] = V, uz[i] = W;                                                            \
    if (TEST_) any |= gcp_lane_stops(r2, u2, Z1, rin2, rout2, zmax);

/* One step of a tile (GCP_FO_TILE_DEFINE_), with the stop test (TEST_ = 1,
 * any set) or without it. */
#define GCP_FO_TILE_STEP_(FORM_, STASH_, KICK_, CARRY_, SPLIT_, TEST_)                          \
    if (SPLIT_) {                                                                               \
        for (size_t i = 0; i < nt; i++) {                                                       \
            GCP_FO_LANE1_(FORM_, CARRY_)                                                        \
            x[i] = X_, y[i] = Y_, z[i] = Z_;                                                    \
            STASH_;                                                                             \
        }                                                                                       \
        for (size_t i = 0; i < nt; i++) {                                                       \
            const double bx = K[0][i], by = K[1][i], bz = K[2][i], IG0 = K[3][i];               \
            (void)bx, (void)by, (void)bz, (void)IG0;                                            \
            GCP_FO_LANE2_(KICK_, CARRY_, x[i], y[i], z[i], TEST_)                               \
        }                                                                                       \
    } else {                                                                                    \
        for (size_t i = 0; i < nt; i++) {                                                       \
            GCP_FO_LANE1_(FORM_, CARRY_)                                                        \
            (void)K;                                                                            \
            GCP_FO_LANE2_(KICK_, CARRY_, X_, Y_, Z_, TEST_)                                     \
        }                                                                                       \
    }

/* One tile function: FORM_ is the B macro above; each step is two loops
 * over the tile's lanes.  The first makes the half drift, the field and
 * what the kick needs of them: STASH_, a statement on bx, by, bz and IG0
 * storing up to 4 numbers a lane in K[0..3][i]; the second the kick, KICK_,
 * a statement on the lane's U, V, W and K[.][i] (and the form's E), the
 * second half drift and the stop test.  One loop did it all before: a
 * step's chain of dependent square roots and divisions (r, c/r^5, s,
 * gamma+, h/gamma+) was longer than the out-of-order window could hide,
 * and the tile ran at ~1.9x the cost of those operations alone
 * (tests/bench/bench_floor.c); two loops each carry half of the chain,
 * and the lanes of a loop overlap.  The same operations on the same
 * values: bit-identical.  With CARRY_ = 1, IG0 = 1 / G0, G0 = gamma(u)
 * of the previous step's drift factor (the same sqrt of the same u:
 * bit-identical, one sqrt a step fewer; only without E, where the kick's
 * u- is u); else IG0 = 1.  The division 1 / G0 is made in the second loop
 * beside h / G0 (IG[i], read back by the next step's first loop), not in
 * the first: the two divisions by G0 then run side by side after its
 * sqrt, and the first loop's chain (r, c/r^5, s) no longer shares the
 * divide unit with a fourth operation -- each loop has 2 of the step's 6
 * roots and divisions' worth of unit time (a sqrt costs about 2
 * divisions here), and the dipole tile ran 3-5% faster (CPU time,
 * alternating; the same operation on the same G0: bit-identical).
 *
 * FREE_ = 1 (boris's uniform tiles): the per-step stop test is skipped
 * where gcp_fo_nr_cannot_stop proves it false for every lane at every step
 * of the call, as in the Newtonian tiles below (the test is a fifth of the
 * step's operations); EMAG_ and BMAG_ are the form's |E|_1 and |B|_1.  The
 * Newtonian proof holds for relativistic Boris: its rotation keeps |u-| as
 * the Newtonian one does, its t = qdt2m B / gamma- is at most qdt2m |B|
 * (gamma >= 1, also in floating point: sqrt(1 + a), a >= 0), its half drifts
 * move x by u h / gamma <= |u| h, and gamma(u) <= 1 + |u| / c stays
 * finite.  One thing differs: its rotation forms s (u' x t), s = 2 / (1 +
 * t^2), where the Newtonian kick forms u' x s with |s| <= 1, so its
 * intermediate u' x t reaches |u|(1 + |t|)|t|; GCP_FO_REL_TB_ = 1e70 bounds
 * |t| so that this stays below 1e291 for |u| <= U_B = 1e150.
 * FREE_ = 2 (boris's dipole tile): the test skipped a stretch of steps at a
 * time where gcp_fo_free_steps proves it false (fo_free_priv.h, which
 * holds GCP_FO_REL_TB_ too), the tile's entry drift factors hg bounding the
 * first step's first drift. */
#define GCP_FO_TILE_DEFINE_(FNAME, FORM_, STASH_, KICK_, CARRY_, SPLIT_, FREE_, EMAG_, BMAG_)  \
    static int64_t FNAME(double *restrict x, double *restrict y, double *restrict z,            \
                         double *restrict ux, double *restrict uy, double *restrict uz,         \
                         double *restrict hg_io, int hg_mode, size_t nt, int64_t kmax,          \
                         const struct gcp_fo_tile_args *a, int32_t *stopped)                    \
    {                                                                                           \
        const double q = a->q, m = a->m, dt = a->dt, h = a->h;                                  \
        const double rin2 = a->rin2, rout2 = a->rout2, zmax = a->zmax;                          \
        _Alignas(64) double IG[GCP_FO_TILE], hg[GCP_FO_TILE], K[4][SPLIT_ ? GCP_FO_TILE : 8];  \
        double *const G = NULL; /* GCP_FO_KICK_DRIFT_'s gamma slot: unused (CARRY_ 0 there) */ \
        (void)q, (void)m, (void)dt, (void)IG, (void)G;                                          \
        if (hg_mode & GCP_FO_HG_IN) {                                                           \
            for (size_t i = 0; i < nt; i++) hg[i] = hg_io[i];                                   \
            if (CARRY_)                                                                         \
                for (size_t i = 0; i < nt; i++)                                                 \
                    IG[i] = 1.0 / gcp_gamma_of_u(ux[i], uy[i], uz[i]);                          \
        } else {                                                                                \
            for (size_t i = 0; i < nt; i++) {                                                   \
                const double G0 = gcp_gamma_of_u(ux[i], uy[i], uz[i]);                          \
                if (CARRY_) IG[i] = 1.0 / G0;                                                   \
                hg[i] = h / G0;                                                                 \
            }                                                                                   \
        }                                                                                       \
        /* untested steps up to fend (FREE_ = 1: the call's, FREE_ = 2: a                       \
         * stretch's, proved again at next) */                                                  \
        int64_t s = 0, fend, next;                                                              \
        double hm;                                                                              \
        gcp_fo_free_begin(FREE_, x, y, z, ux, uy, uz, hg, nt, kmax, a, EMAG_, BMAG_, h, &fend,  \
                          &next, &hm);                                                          \
        for (; s < kmax; s++) {                                                                 \
            int32_t any = 0;                                                                    \
            if (s == next)                                                                      \
                gcp_fo_free_plan(s, kmax, x, y, z, ux, uy, uz, nt, hm, a, &next, &fend);        \
            if (s < fend) {                                                                     \
                GCP_FO_TILE_STEP_(FORM_, STASH_, KICK_, CARRY_, SPLIT_, 0)                      \
                (void)any;                                                                      \
                continue;                                                                       \
            }                                                                                   \
            GCP_FO_TILE_STEP_(FORM_, STASH_, KICK_, CARRY_, SPLIT_, 1)                          \
            if (any) {                                                                          \
                *stopped = 1;                                                                   \
                s++;                                                                            \
                break;                                                                          \
            }                                                                                   \
        }                                                                                       \
        if (hg_mode & GCP_FO_HG_OUT)                                                            \
            for (size_t i = 0; i < nt; i++) hg_io[i] = hg[i];                                   \
        return s;                                                                               \
    }

/* The plain stash: B and IG0, which the second loop reads back as bx, by,
 * bz and IG0 for its kick. */
#define GCP_FO_STASH_B_ (K[0][i] = bx, K[1][i] = by, K[2][i] = bz, K[3][i] = IG0)

/* An empty statement GCC does not vectorise across: keeps the copy loops
 * of GCP_FO_GYRO_CLOSE8_ scalar (8-lane gathers and scatters measured
 * slower here, AMD EPYC Zen 4, than the 8 scalar moves). */
#define GCP_FO_NOVEC_ __asm__ volatile("")

/* The close of the gyrations that end in push step KK (GCP_FO_GYRO_TILE_DEFINE_)
 * for the 8 tile lanes IX[0..7] (padded: a repeat of a lane before), the
 * first NK of them real; KF: that step's field vectors, UM, UP: its u- and
 * u+ (the tile's buffers of that step).  Their state is copied into 8-lane
 * arrays (in8, ks8 of the tile function: a call's first close fills all 8
 * slots, a later one the NK real lanes only -- the slots past them keep a
 * lane of an earlier close, whose values go through the vector loop
 * unused; a step ends ~6 gyrations in a 128-lane tile at 0.05 gyro, so
 * this copies ~6 lanes' 28 values, not 8 lanes'), the rebuilt step before
 * and gcp_fo_gyro_close_vals in one loop over the 8 (one vector a value:
 * the divisions and square roots of 8 lanes at the price of one's), then
 * the new gyrations' state and the kept records written back in lane
 * order.  Closed one lane at a time, the scalar close and rebuild were
 * ~40% of the tile's time.  The same operations on each lane's values as
 * one lane at a time: bit-identical. */
#define GCP_FO_GYRO_CLOSE8_(FORM_, FT_, IX, NK, KK, KF, UM, UP)                                 \
    {                                                                                           \
        const int64_t *restrict ix8 = (IX);                                                     \
        _Alignas(64) double out8[16][8], rv8[7][8], ok8[8];                                     \
        const int64_t kk = (KK);                                                                \
        const int nfill = in8_set ? (int)(NK) : 8;                                              \
        in8_set = 1;                                                                            \
        for (int l = 0; l < nfill; l++) {                                                       \
            const int64_t i = ix8[l];                                                           \
            in8[0][l] = KF[0][i], in8[1][l] = KF[1][i], in8[2][l] = KF[2][i];                   \
            in8[3][l] = UM[0][i], in8[4][l] = UM[1][i], in8[5][l] = UM[2][i];                   \
            in8[6][l] = UP[0][i], in8[7][l] = UP[1][i], in8[8][l] = UP[2][i];                   \
            in8[9][l] = x[i], in8[10][l] = y[i], in8[11][l] = z[i], in8[12][l] = hg[i];         \
            in8[13][l] = E2[0][i], in8[14][l] = E2[1][i], in8[15][l] = E2[2][i];                \
            in8[16][l] = S[0][i], in8[17][l] = S[1][i], in8[18][l] = S[2][i];                   \
            in8[19][l] = S[3][i], in8[20][l] = S[4][i], in8[21][l] = S[5][i];                   \
            in8[22][l] = S[6][i], in8[23][l] = S[7][i], in8[24][l] = S[8][i];                   \
            in8[25][l] = w0s[i], in8[26][l] = jcs[i];                                           \
            ks8[l] = kst[i];                                                                    \
            GCP_FO_NOVEC_;                                                                      \
        }                                                                                       \
        for (int l = 0; l < 8; l++) {                                                           \
            const double F[3] = {in8[0][l], in8[1][l], in8[2][l]};                              \
            const double u0[3] = {in8[3][l], in8[4][l], in8[5][l]};                             \
            const double u1[3] = {in8[6][l], in8[7][l], in8[8][l]};                             \
            const double g1 = in8[12][l]; /* h / gamma, gamma the same for u- and u+ */         \
            const double xh[3] = {in8[9][l] - u1[0] * g1, in8[10][l] - u1[1] * g1,              \
                                  in8[11][l] - u1[2] * g1};                                     \
            /* Boris's t = a B, a = q dt / (2 m gamma) */                                       \
            const double ab = 0.5 * q * dt / m * (g1 / h), scale = FT_ ? ab : 1.0;              \
            double f[9], fp[9];                                                                 \
            gcp_fo_gyro_mid_sample(xh, F, u0, u1, f);                                           \
            { /* the step before's sample (fo_gyro_priv.h) */                                   \
                const double xp[3] = {xh[0] - 2.0 * u0[0] * g1, xh[1] - 2.0 * u0[1] * g1,       \
                                      xh[2] - 2.0 * u0[2] * g1};                                \
                double Bx_, By_, Bz_;                                                           \
                FORM_(xp[0], xp[1], xp[2], Bx_, By_, Bz_);                                      \
                const double tx_ = ab * Bx_, ty_ = ab * By_, tz_ = ab * Bz_;                    \
                const double s_ = 2.0 / (1.0 + tx_ * tx_ + ty_ * ty_ + tz_ * tz_);              \
                double up[3] = {u0[0], u0[1], u0[2]};                                           \
                gcp_boris_rotate_ts_(&up[0], &up[1], &up[2], -tx_, -ty_, -tz_, s_);             \
                const double Fp[3] = {scale * Bx_, scale * By_, scale * Bz_};                   \
                gcp_fo_gyro_mid_sample(xp, Fp, up, u0, fp);                                     \
            }                                                                                   \
            const double e2[3] = {in8[13][l], in8[14][l], in8[15][l]};                          \
            double Sl[9], fn[9], e2n[3], rv[7], w0n, jcn;                                       \
            for (int j = 0; j < 9; j++) Sl[j] = in8[16 + j][l];                                 \
            if (FT_) /* telescoped S_r: u+ at the start (and its fn) less u+ now */            \
                for (int j = 0; j < 3; j++) Sl[3 + j] -= u1[j];                                 \
            ok8[l] = gcp_fo_gyro_close_vals(kk, ks8[l], in8[25][l], in8[26][l], e2, Sl, t0, dt, \
                                            q, m, F, scale, f, fp, u0, u1, rv, fn, e2n, &w0n,   \
                                            &jcn);                                              \
            for (int j = 0; j < 7; j++) rv8[j][l] = rv[j];                                      \
            for (int j = 0; j < 9; j++) out8[j][l] = fn[j];                                     \
            if (FT_)                                                                            \
                for (int j = 0; j < 3; j++) out8[3 + j][l] = fn[3 + j] + u1[j];                 \
            for (int j = 0; j < 3; j++) out8[9 + j][l] = e2n[j];                                \
            out8[12][l] = w0n, out8[13][l] = jcn;                                               \
        }                                                                                       \
        for (int l = 0; l < (NK); l++) {                                                        \
            /* the next gyration begins (gcp_fo_gyro_mid_start) with step k's rest */           \
            const int64_t i = ix8[l];                                                           \
            LF[i] = 0, kst[i] = kk, w0s[i] = out8[12][l], jcs[i] = out8[13][l];                 \
            S[0][i] = out8[0][l], S[1][i] = out8[1][l], S[2][i] = out8[2][l];                   \
            S[3][i] = out8[3][l], S[4][i] = out8[4][l], S[5][i] = out8[5][l];                   \
            S[6][i] = out8[6][l], S[7][i] = out8[7][l], S[8][i] = out8[8][l];                   \
            E2[0][i] = out8[9][l], E2[1][i] = out8[10][l], E2[2][i] = out8[11][l];              \
            GCP_FO_NOVEC_;                                                                      \
            if (ok8[l] == 0.0) continue;                                                        \
            struct gcp_fo_gyro_rec *rec = gy->rec + gy->nrec++;                                 \
            rec->lane = (int64_t)i0 + i;                                                        \
            rec->t = rv8[0][l];                                                                 \
            for (int j = 0; j < 3; j++) rec->X[j] = rv8[1 + j][l];                              \
            rec->ppar = rv8[4][l];                                                              \
            rec->mu = rv8[5][l];                                                                \
            rec->p2 = rv8[6][l];                                                                \
            rec->mid = 1;                                                                       \
        }                                                                                       \
    }

/* The first half of a lane's step in the gyro tile (GCP_FO_LANE1_'s
 * operations with u from the tile's buffer UC): the half drift to x_1/2,
 * into XH, the field there and the stash. */
#define GCP_FO_GYRO_LANE1_(FORM_, STASH_, CARRY_)                                               \
    {                                                                                           \
        const double g0_ = hg[i];                                                               \
        const double X_ = x[i] + UC[0][i] * g0_, Y_ = y[i] + UC[1][i] * g0_,                    \
                     Z_ = z[i] + UC[2][i] * g0_;                                                \
        const double IG0 = CARRY_ ? 1.0 / G[i] : 1.0;                                           \
        (void)IG0;                                                                              \
        double bx, by, bz;                                                                      \
        FORM_(X_, Y_, Z_, bx, by, bz);                                                          \
        XH[0][i] = X_, XH[1][i] = Y_, XH[2][i] = Z_;                                            \
        STASH_;                                                                                 \
    }

/* Of lane i, the part of a step's sample (fo_gyro_priv.h) that needs its
 * field vector KF and its u- and u+ (UM, UP) -- S_r, S_p, S_p2, S_F; S_x
 * is added beside it -- and the phase test: u.e2 turns negative first, and the gyration ends where
 * it goes from > 0 to <= 0 (sp[i], counted in nsp; LF: 'left', set from
 * the steps before, since at a gyration's start u.e2 = 0 up to rounding). */
#define GCP_FO_GYRO_SAMPLE_(KF, UM, UP, FT_)                                                    \
    {                                                                                           \
        const double F0 = KF[0][i], F1 = KF[1][i], F2 = KF[2][i];                               \
        const double U0 = UM[0][i], V0 = UM[1][i], W0 = UM[2][i];                               \
        const double U1 = UP[0][i], V1 = UP[1][i], W1 = UP[2][i];                               \
        /* us = u- + u+ = 2 u_1/2 */                                                            \
        const double usx = U0 + U1, usy = V0 + V1, usz = W0 + W1;                               \
        const double fu = F0 * usx + F1 * usy + F2 * usz;                                       \
        if (!(FT_)) { /* else telescoped (fo_gyro_priv.h) */                                  \
            S[3][i] += F1 * usz - F2 * usy;                                                     \
            S[4][i] += F2 * usx - F0 * usz;                                                     \
            S[5][i] += F0 * usy - F1 * usx;                                                     \
        }                                                                                       \
        S[6][i] += fu;                                                                          \
        S[7][i] += fu * fu;                                                                     \
        S[8][i] += F0 * F0 + F1 * F1 + F2 * F2;                                                 \
        const double d0 = U0 * E2[0][i] + V0 * E2[1][i] + W0 * E2[2][i];                        \
        const double d1 = U1 * E2[0][i] + V1 * E2[1][i] + W1 * E2[2][i];                        \
        const int64_t sf = LF[i] & (d0 > 0) & (d1 <= 0);                                        \
        LF[i] |= d1 < 0;                                                                        \
        sp[i] = sf;                                                                             \
        nsp += sf;                                                                              \
    }

/* The lanes whose gyration ended in push step KK (flagged in sp by
 * GCP_FO_GYRO_SAMPLE_), found 8 at a time -- a bit a lane, 64 lanes a word
 * (a vector or-reduction), then the set bits in order: no branch a lane --
 * and closed 8 at a time (GCP_FO_GYRO_CLOSE8_). */
#define GCP_FO_GYRO_CLOSES_(FORM_, FT_, KK, KF, UM, UP)                                         \
    if (nsp > 0) {                                                                              \
        int64_t n = 0;                                                                          \
        for (size_t j = 0; j < nt; j += 64) {                                                   \
            uint64_t bits = 0;                                                                  \
            const size_t je = nt - j < 64 ? nt - j : 64;                                        \
            for (size_t i = 0; i < je; i++) bits |= (uint64_t)sp[j + i] << i;                   \
            for (; bits; bits &= bits - 1) ix[n++] = (int64_t)j + __builtin_ctzll(bits);        \
        }                                                                                       \
        /* padded to 8 with the last lane: the same values, the record kept once */             \
        for (int64_t c = n; c < ((n + 7) & ~(int64_t)7); c++) ix[c] = ix[n - 1];                \
        for (int64_t c0 = 0; c0 < n; c0 += 8)                                                   \
            GCP_FO_GYRO_CLOSE8_(FORM_, FT_, ix + c0, n - c0 < 8 ? n - c0 : 8, KK, KF, UM, UP)   \
    }

/* The second half of a lane's step in the gyro tile: the kick from u- in
 * UC at x_1/2 in XH, u+ into UN, the second half drift; the caller adds
 * the stop test where it is not proved false (FREE_). */
#define GCP_FO_GYRO_LANE2_(KICK_, CARRY_)                                                       \
    const double bx = K[0][i], by = K[1][i], bz = K[2][i], IG0 = K[3][i];                       \
    (void)bx, (void)by, (void)bz, (void)IG0;                                                    \
    GCP_FO_KICK_DRIFT_(KICK_, CARRY_, UC[0][i], UC[1][i], UC[2][i], XH[0][i], XH[1][i],         \
                       XH[2][i])                                                                \
    UN[0][i] = U, UN[1][i] = V, UN[2][i] = W;                                                   \
    (void)r2, (void)u2, (void)Z1;

/* A row of a gyro tile's buffer, read only. */
typedef const double gcp_fo_ct_[GCP_FO_TILE]; /* a row of a tile's read-only buffer */
#define GCP_FO_CT_(P) ((gcp_fo_ct_ *)(P))

/* One gyro tile function (gcp_fo_gyro_tile_fn): the split tile loop of
 * GCP_FO_TILE_DEFINE_ (STASH_, KICK_ as there: K[0..2] is the field vector
 * F of the step, B or, with FT_ = 1, Boris's t = (q dt / 2 m gamma) B;
 * STASH_ must not read u, which here lives in the tile's buffers) with the
 * observer's per-step work: a sample of each step at its middle, where the
 * push has everything it needs (fo_gyro_priv.h: the point x_1/2, F there,
 * u- and u+), added to the lane's nine raw sums, and the phase test -- no
 * field evaluation, no square root, no division.  The lanes whose
 * gyration ends in the step (~1 in 20) then close it, 8 at a time
 * (GCP_FO_GYRO_CLOSES_: the record, from the sums).
 *
 * Where the work goes (issue 12): with the sample and the phase test in
 * the kick's loop, that loop stored 22 vectors a group of 8 lanes against
 * the plain tile's 8, and its body grew past what the out-of-order window
 * holds while it overlaps the sqrt/division chains of successive lanes (it took
 * ~3x the plain loop's time; in the field's loop instead, ~2x that one's).
 * So each step is three loops: the field (x_1/2 into XH, not x, so that
 * x_k+1 is there for the close), the kick (as in the plain tile), and the
 * sample and phase test alone, a loop of additions and multiplications
 * with no long chain, then the closes.  u ping-pongs between two buffers
 * by the step's parity: the kick reads u- from one and writes u+ to the
 * other, so that u- needs no store of its own.  The sums, e2 and 'left'
 * are the tile's own arrays during the call (copied in and out once: a
 * pointer a quantity spilled registers in the loops).  The same operations
 * on the same values in the same order per lane as one loop did:
 * bit-identical.  FREE_, BMAG_: the plain tile's (GCP_FO_TILE_DEFINE_): the
 * kick loop skips the stop test where it is proved false (a fifth of that
 * loop's operations; the proof reads u at the step's start, in UC), with
 * the same verdicts and bits as the test every step. */
#define GCP_FO_GYRO_TILE_DEFINE_(FNAME, FORM_, STASH_, KICK_, CARRY_, FT_, FREE_, BMAG_)      \
    static int64_t FNAME(double *restrict x, double *restrict y, double *restrict z,            \
                         double *restrict ux, double *restrict uy, double *restrict uz,         \
                         double *restrict hg_io, int hg_mode, size_t nt, int64_t kmax,          \
                         const struct gcp_fo_tile_args *a, int32_t *stopped,                    \
                         struct gcp_fo_gyro *gy, size_t i0, double t0, int64_t k0)              \
    {                                                                                           \
        const double q = a->q, m = a->m, dt = a->dt, h = a->h;                                  \
        const double rin2 = a->rin2, rout2 = a->rout2, zmax = a->zmax;                          \
        _Alignas(64) double G[GCP_FO_TILE], hg[GCP_FO_TILE];                                    \
        _Alignas(64) double K[4][GCP_FO_TILE];                                                  \
        _Alignas(64) double UB[2][3][GCP_FO_TILE]; /* u- and u+, by the step's parity */        \
        _Alignas(64) double XH[3][GCP_FO_TILE];    /* x_1/2 of the step */                      \
        _Alignas(64) double S[9][GCP_FO_TILE], E2[3][GCP_FO_TILE];                              \
        _Alignas(64) int64_t LF[GCP_FO_TILE], sp[GCP_FO_TILE];                                  \
        int64_t ix[GCP_FO_TILE + 8]; /* the rare lanes of the step */                           \
        /* the closes' 8-lane inputs (GCP_FO_GYRO_CLOSE8_), set by the call's first */          \
        _Alignas(64) double in8[29][8];                                                         \
        _Alignas(64) int64_t ks8[8];                                                            \
        int in8_set = 0;                                                                        \
        (void)G;                                                                                \
        int64_t *restrict kst = gy->kstart + i0;                                                \
        double *restrict w0s = gy->w0 + i0, *restrict jcs = gy->jc + i0;                        \
        for (size_t i = 0; i < nt; i++) {                                                       \
            UB[0][0][i] = ux[i], UB[0][1][i] = uy[i], UB[0][2][i] = uz[i];                      \
            LF[i] = gy->left[i0 + i];                                                           \
        }                                                                                       \
        for (int j = 0; j < 9; j++)                                                             \
            for (size_t i = 0; i < nt; i++) S[j][i] = gy->sum[j][i0 + i];                       \
        for (int j = 0; j < 3; j++)                                                             \
            for (size_t i = 0; i < nt; i++) E2[j][i] = gy->e2[j][i0 + i];                       \
        if (hg_mode & GCP_FO_HG_IN) {                                                           \
            for (size_t i = 0; i < nt; i++) hg[i] = hg_io[i];                                   \
            if (CARRY_)                                                                         \
                for (size_t i = 0; i < nt; i++) G[i] = gcp_gamma_of_u(ux[i], uy[i], uz[i]);     \
        } else {                                                                                \
            for (size_t i = 0; i < nt; i++) {                                                   \
                const double G0 = gcp_gamma_of_u(ux[i], uy[i], uz[i]);                          \
                if (CARRY_) G[i] = G0;                                                          \
                hg[i] = h / G0;                                                                 \
            }                                                                                   \
        }                                                                                       \
        /* untested steps up to fend (FREE_ as in GCP_FO_TILE_DEFINE_: 1, the               \
         * call's; 2, a stretch's, proved again at next, from u in UC) */                       \
        int64_t s = 0, fend, next;                                                              \
        double hm;                                                                              \
        gcp_fo_free_begin(FREE_, x, y, z, ux, uy, uz, hg, nt, kmax, a, 0.0, BMAG_, h, &fend,    \
                          &next, &hm);                                                          \
        for (; s < kmax; s++) {                                                                 \
            int32_t any = 0;                                                                    \
            int64_t nsp = 0;                                                                    \
            /* step s: u- in UC, u+ into UN */                                                  \
            gcp_fo_ct_ *restrict UC = GCP_FO_CT_(UB[s & 1]);                                    \
            double (*restrict UN)[GCP_FO_TILE] = UB[(s & 1) ^ 1];                               \
            GCP_FO_IVDEP_                                                                       \
            for (size_t i = 0; i < nt; i++) {                                                   \
                GCP_FO_GYRO_LANE1_(FORM_, STASH_, CARRY_)                                       \
            }                                                                                   \
            if (s == next)                                                                      \
                gcp_fo_free_plan(s, kmax, x, y, z, UC[0], UC[1], UC[2], nt, hm, a, &next, &fend);\
            if (s < fend) {                                                                     \
                GCP_FO_IVDEP_                                                                   \
                for (size_t i = 0; i < nt; i++) {                                               \
                    GCP_FO_GYRO_LANE2_(KICK_, CARRY_)                                           \
                }                                                                               \
            } else {                                                                            \
                GCP_FO_IVDEP_                                                                   \
                for (size_t i = 0; i < nt; i++) {                                               \
                    GCP_FO_GYRO_LANE2_(KICK_, CARRY_)                                           \
                    any |= gcp_lane_stops(r2, u2, Z1, rin2, rout2, zmax);                       \
                }                                                                               \
            }                                                                                   \
            GCP_FO_IVDEP_                                                                       \
            for (size_t i = 0; i < nt; i++) {                                                   \
                S[0][i] += XH[0][i];                                                            \
                S[1][i] += XH[1][i];                                                            \
                S[2][i] += XH[2][i];                                                            \
                GCP_FO_GYRO_SAMPLE_(K, UC, UN, FT_)                                                  \
            }                                                                                   \
            GCP_FO_GYRO_CLOSES_(FORM_, FT_, k0 + s, K, UC, UN)                                  \
            if (any) {                                                                          \
                *stopped = 1;                                                                   \
                s++;                                                                            \
                break;                                                                          \
            }                                                                                   \
        }                                                                                       \
        for (size_t i = 0; i < nt; i++) {                                                       \
            ux[i] = UB[s & 1][0][i], uy[i] = UB[s & 1][1][i], uz[i] = UB[s & 1][2][i];          \
            gy->left[i0 + i] = LF[i];                                                           \
        }                                                                                       \
        for (int j = 0; j < 9; j++)                                                             \
            for (size_t i = 0; i < nt; i++) gy->sum[j][i0 + i] = S[j][i];                       \
        for (int j = 0; j < 3; j++)                                                             \
            for (size_t i = 0; i < nt; i++) gy->e2[j][i0 + i] = E2[j][i];                       \
        if (hg_mode & GCP_FO_HG_OUT)                                                            \
            for (size_t i = 0; i < nt; i++) hg_io[i] = hg[i];                                   \
        return s;                                                                               \
    }

/* The fused kernel set of a full-orbit pusher NAME from its scalar kicks
 * (kernels.h): KICK(ux, uy, uz, Ex, Ey, Ez, Bx, By, Bz, q, m, dt) and
 * KICK_B, the kick with E = 0: KICK_B(ux, uy, uz, Bx, By, Bz, q, m, dt)
 * (the pusher's kick_B, or KICK with literal zeros: the same numbers as the
 * zeroed E arrays of the block step), or with CARRY = 1
 * KICK_B(..., dt, inv_gamma) (gcp_push_boris_B_ig).  Defines
 * gcp_fo_fused_NAME_.  GCP_FO_FUSED_DEFINE_SPLIT_ takes the B tiles' stash
 * and kick (GCP_FO_TILE_DEFINE_) as given: a kick that computes part of
 * its work from B and gamma alone can do it in the first loop
 * (gcp_fo_fused_boris_, src/pushers/boris.c); with USPLIT_ = 1 the uniform
 * tiles are split too, the B tile with the same stash and kick, the E and B
 * tile with STASH_EB_ and KICK2_EB_, and skip the stop test where it is
 * proved false (FREE_ above: Boris's bounds; USPLIT_ = 0: one loop a step
 * with the test, the plain kicks; STASH_EB_ and KICK2_EB_ unused).  FT = 1:
 * the B tiles' field vector is Boris's t, not B (the gyro tile's sums).
 * DFREE_ = 2: the dipole tile skips the stop test where gcp_fo_free_steps
 * proves it false (its bound on a step's drift needs a rotation that keeps
 * |u|: Boris's), 0: the test every step. */
#define GCP_FO_IG_0_
#define GCP_FO_IG_1_ , IG0
#define GCP_FO_FUSED_DEFINE_SPLIT_(NAME, KICK, KICK_B, CARRY, STASH_B_, KICK2_B_, USPLIT_,      \
                                   STASH_EB_, KICK2_EB_, FT, DFREE_)                            \
    GCP_FO_TILE_DEFINE_(NAME##_tile_dipole_B, GCP_FO_B_DIPOLE_, STASH_B_, KICK2_B_, CARRY, 1, \
                        DFREE_, 0.0, 0.0)                                                       \
    GCP_FO_TILE_DEFINE_(NAME##_tile_uniform_B, GCP_FO_B_UNIFORM_, STASH_B_, KICK2_B_, CARRY,    \
                        USPLIT_, USPLIT_, 0.0, GCP_FO_ABS3_(a->p))                              \
    GCP_FO_TILE_DEFINE_(NAME##_tile_uniform_EB, GCP_FO_B_UNIFORM_, STASH_EB_, KICK2_EB_, 0,     \
                        USPLIT_, USPLIT_, GCP_FO_ABS3_(a->p + 3), GCP_FO_ABS3_(a->p))           \
    GCP_FO_GYRO_TILE_DEFINE_(NAME##_gyro_dipole_B, GCP_FO_B_DIPOLE_, STASH_B_, KICK2_B_, CARRY, \
                             FT, DFREE_, 0.0)                                                   \
    GCP_FO_GYRO_TILE_DEFINE_(NAME##_gyro_uniform_B, GCP_FO_B_UNIFORM_, STASH_B_, KICK2_B_, CARRY, \
                             FT, USPLIT_, GCP_FO_ABS3_(a->p))                                   \
    static const struct gcp_fo_fused gcp_fo_fused_##NAME##_ = {                                 \
        .tile = {[GCP_POINT_B_UNIFORM] = {NAME##_tile_uniform_B, NAME##_tile_uniform_EB},       \
                 [GCP_POINT_B_DIPOLE] = {NAME##_tile_dipole_B, NULL}},                          \
        .gyro = {[GCP_POINT_B_UNIFORM] = NAME##_gyro_uniform_B,                                 \
                 [GCP_POINT_B_DIPOLE] = NAME##_gyro_dipole_B},                        \
        .gyro_tele = FT};
#define GCP_FO_FUSED_DEFINE(NAME, KICK, KICK_B, CARRY)                                          \
    GCP_FO_FUSED_DEFINE_SPLIT_(NAME, KICK, KICK_B, CARRY, GCP_FO_STASH_B_,                      \
                               KICK_B(&U, &V, &W, bx, by, bz, q, m, dt GCP_FO_IG_##CARRY##_),   \
                               0, GCP_FO_STASH_B_,                                              \
                               KICK(&U, &V, &W, a->p[3], a->p[4], a->p[5], bx, by, bz, q, m,    \
                                    dt), 0, 0)

/* ---- Newtonian pushers (u = v: boris-nr) --------------------------------
 *
 * The Newtonian step of fo_step.c (fo_step_newtonian), the same operations:
 *   x_1/2 = x + u0 h  (the field's point),  u1 = kick(u0; E, B(x_1/2)),
 *   x1 = x + (u0 + u1) h
 * (h = dt/2; GCP_NR_FMA_, kernels.h) -- drift-kick-drift with its two half
 * drifts summed once: no gamma, nothing kept per lane between steps, hg_io
 * never touched; in a uniform form x_1/2 is not computed at all.
 * Its stop-test proof for the uniform forms: fo_free_priv.h. */

/* One Newtonian tile function (FORM_, KICK_ as above); EMAG_ and BMAG_ the
 * 1-norms of the form's E and B for gcp_fo_nr_cannot_stop, or FREE_ = 0:
 * the per-step test always (the dipole: its inner bound is a stop). */
#define GCP_FO_NR_LANE_(FORM_, KICK_)                                                           \
    const double U0 = ux[i], V0 = uy[i], W0 = uz[i];                                            \
    const double X = GCP_NR_FMA_(U0, h, x[i]), Y = GCP_NR_FMA_(V0, h, y[i]),                   \
                 Z = GCP_NR_FMA_(W0, h, z[i]);                                                  \
    double bx, by, bz, U = U0, V = V0, W = W0;                                                  \
    (void)X, (void)Y, (void)Z;                                                                  \
    FORM_(X, Y, Z, bx, by, bz);                                                                 \
    KICK_;                                                                                      \
    const double X1 = GCP_NR_FMA_(U0 + U, h, x[i]), Y1 = GCP_NR_FMA_(V0 + V, h, y[i]),         \
                 Z1 = GCP_NR_FMA_(W0 + W, h, z[i]);                                             \
    x[i] = X1, y[i] = Y1, z[i] = Z1;                                                            \
    ux[i] = U, uy[i] = V, uz[i] = W;
/* SPLIT_ = 1 (the dipole): each checked step is two loops over the tile's
 * lanes, the field at x_1/2 into K first, then the lane's step with the
 * field read back (FORM2_ = GCP_FO_B_STASHED_): the field's sqrt and
 * division and the kick's division are then in separate dependency chains
 * whose lanes overlap, as in the relativistic tiles above; the same
 * operations on the same values, bit-identical. */
#define GCP_FO_B_STASHED_(X, Y, Z, BX, BY, BZ) (BX = K[0][i], BY = K[1][i], BZ = K[2][i])
#define GCP_FO_NR_TILE_DEFINE_(FNAME, FORM_, KICK_, FREE_, EMAG_, BMAG_, SPLIT_, FORM2_)        \
    /* one unchecked step of the tile: a function of its own, so that the    \
     * compiler keeps the lanes innermost (it interchanges a bare loop nest   \
     * and then vectorises neither loop) */                                   \
    static __attribute__((noinline)) void FNAME##_free_(                                        \
        double *restrict x, double *restrict y, double *restrict z, double *restrict ux,        \
        double *restrict uy, double *restrict uz, size_t nt, int64_t kmax,                      \
        const struct gcp_fo_tile_args *a)                                                       \
    {                                                                                           \
        const double q = a->q, m = a->m, dt = a->dt, h = a->h;                                  \
        (void)q, (void)m, (void)dt;                                                             \
        for (int64_t s = 0; s < kmax; s++)                                                      \
            for (size_t i = 0; i < nt; i++) {                                                   \
                GCP_FO_NR_LANE_(FORM_, KICK_)                                                   \
            }                                                                                   \
    }                                                                                           \
    static int64_t FNAME(double *restrict x, double *restrict y, double *restrict z,            \
                         double *restrict ux, double *restrict uy, double *restrict uz,         \
                         double *restrict hg_io, int hg_mode, size_t nt, int64_t kmax,          \
                         const struct gcp_fo_tile_args *a, int32_t *stopped)                    \
    {                                                                                           \
        const double q = a->q, m = a->m, dt = a->dt, h = a->h;                                  \
        const double rin2 = a->rin2, rout2 = a->rout2, zmax = a->zmax;                          \
        (void)q, (void)m, (void)dt, (void)hg_io, (void)hg_mode;                                 \
        if (FREE_ && gcp_fo_nr_cannot_stop(x, y, z, ux, uy, uz, nt, kmax, a, EMAG_, BMAG_,     \
                                      GCP_FO_NR_TB_)) {                                         \
            FNAME##_free_(x, y, z, ux, uy, uz, nt, kmax, a);                                    \
            return kmax;                                                                        \
        }                                                                                       \
        _Alignas(64) double K[3][SPLIT_ ? GCP_FO_TILE : 8];                                     \
        (void)K;                                                                                \
        int64_t s = 0;                                                                          \
        for (; s < kmax; s++) {                                                                 \
            int32_t any = 0;                                                                    \
            if (SPLIT_)                                                                         \
                for (size_t i = 0; i < nt; i++) {                                               \
                    const double X = GCP_NR_FMA_(ux[i], h, x[i]);                               \
                    const double Y = GCP_NR_FMA_(uy[i], h, y[i]);                               \
                    const double Z = GCP_NR_FMA_(uz[i], h, z[i]);                               \
                    double bx, by, bz;                                                          \
                    (void)X, (void)Y, (void)Z;                                                  \
                    FORM_(X, Y, Z, bx, by, bz);                                                 \
                    K[0][i] = bx, K[1][i] = by, K[2][i] = bz;                                   \
                }                                                                               \
            for (size_t i = 0; i < nt; i++) {                                                   \
                GCP_FO_NR_LANE_(FORM2_, KICK_)                                                  \
                const double r2 = X1 * X1 + Y1 * Y1 + Z1 * Z1;                                  \
                const double u2 = U * U + V * V + W * W;                                        \
                any |= gcp_lane_stops(r2, u2, Z1, rin2, rout2, zmax);                          \
            }                                                                                   \
            if (any) {                                                                          \
                *stopped = 1;                                                                   \
                s++;                                                                            \
                break;                                                                          \
            }                                                                                   \
        }                                                                                       \
        return s;                                                                               \
    }

/* The fused kernel set of a Newtonian pusher NAME: KICK(ux, uy, uz, Ex, Ey,
 * Ez, Bx, By, Bz, q, m, dt) and KICK_B(ux, uy, uz, Bx, By, Bz, q, m, dt)
 * (E = 0).  Defines gcp_fo_fused_NAME_. */
#define GCP_FO_ABS3_(P) (fabs((P)[0]) + fabs((P)[1]) + fabs((P)[2]))
#define GCP_FO_FUSED_DEFINE_NEWTONIAN(NAME, KICK, KICK_B)                                       \
    GCP_FO_NR_TILE_DEFINE_(NAME##_tile_dipole_B, GCP_FO_B_DIPOLE_,                              \
                           KICK_B(&U, &V, &W, bx, by, bz, q, m, dt), 0, 0.0, 0.0, 1,            \
                           GCP_FO_B_STASHED_)                                                   \
    GCP_FO_NR_TILE_DEFINE_(NAME##_tile_uniform_B, GCP_FO_B_UNIFORM_,                            \
                           KICK_B(&U, &V, &W, bx, by, bz, q, m, dt), 1, 0.0,                    \
                           GCP_FO_ABS3_(a->p), 0, GCP_FO_B_UNIFORM_)                            \
    GCP_FO_NR_TILE_DEFINE_(NAME##_tile_uniform_EB, GCP_FO_B_UNIFORM_,                           \
                           KICK(&U, &V, &W, a->p[3], a->p[4], a->p[5], bx, by, bz, q, m, dt),   \
                           1, GCP_FO_ABS3_(a->p + 3), GCP_FO_ABS3_(a->p), 0,                    \
                           GCP_FO_B_UNIFORM_)                                                   \
    static const struct gcp_fo_fused gcp_fo_fused_##NAME##_ = {                                 \
        .tile = {[GCP_POINT_B_UNIFORM] = {NAME##_tile_uniform_B, NAME##_tile_uniform_EB},       \
                 [GCP_POINT_B_DIPOLE] = {NAME##_tile_dipole_B, NULL}}};

#endif
