/* The guiding-centre stream's quiet steps (contract: gcpush/invariants.h;
 * state: struct gcp_observer.hot in invariants_priv.h).
 *
 * A guiding-centre pusher feeds the observer every step of every lane; on
 * ~9 steps in 10 nothing happens to a lane but the trapezoid sums of J and
 * mu and, on the way down to the equator, a new |B| minimum.  Those steps
 * are one vectorised pass over a struct of arrays here, with the
 * expressions of gcp_obs_stream_sample_jd (so the events are bit-identical
 * to sending every step through it); the rest (mirror points, the sample
 * after a minimum, cadence times) go per lane, the lane's struct lane
 * brought up to date before gcp_obs_stream_sample_jd and read back after.
 *
 * Where the cost is (tests/bench/observer.sh's gc-rk4 row: 2048 protons of
 * 1 MeV, 12.9M lane-steps; bare push ~0.175 s of CPU, the observer ~0.15 s
 * more, 1.8-1.9x), timed with rdtsc around each part (one run on the
 * loaded 2-core machine: wall time, to +-20%): this pass ~0.05 s, bound by
 * each lane's chain of two square roots and a division (|B| and the J
 * integrand p_par^2 / sqrt(m^2 + p^2/c^2), which the events' bits fix)
 * and ~28 loads and stores a lane; the 410k mirror points ~0.12 s
 * (~290 ns each: the equator point's Lagrange weights and rows ~0.05 s,
 * its drift contour about a quarter of that, asin, the bounce rows, the
 * copies between the hot arrays and struct lane ~0.025 s); the samples
 * after a minimum and the cadence times ~0.01 s each; the compaction of
 * the slow lanes ~0.01 s (slow_compact, now ~half that).
 *
 * What paid (push with the observer over the bare push; old and new
 * binaries interleaved on a shared core): this pass (observer ~1.0x ->
 * 0.6-0.8x of the block step's push); against the fused gc-rk4 step
 * (2x faster), the ring, the sample after a minimum in the pass and the
 * events grown in place (2.8x -> 2.25x, best of 9); B from the block
 * where the fused step leaves it (GCP_BLOCK_B_AT_X), the lane state
 * written with selects, the slow lanes prefetched (2.13x -> 1.99x); the
 * chains in a loop of their own; the compaction with AVX-512, the rows'
 * lines prefetched, the scalar rows pushed as such (0.341 -> 0.332 s and
 * 0.396 -> 0.368 s over ~0.177 s, medians of 11 pairs at load 8: a few %,
 * near the machine's noise).
 *
 * Tried and dropped: |B|, p^2 and the J integrand formed by the fused tile
 * at the new state with these expressions (bit-identical) and read here:
 * the push with the observer went 0.342 -> 0.362 s (medians of 9 pairs),
 * three more operations in series on the tile's last stage, already a
 * chain of square roots and divisions, cost more than this loop (the
 * tile's own |B| = |c5| r q and gamma are not these numbers bit for bit).
 * The event storage's page faults cost ~0.1 s only when the kernel hands
 * out pages the host has not backed (this VM reports free pages to its
 * host); with pages warm, a test binary that stored no bounce or mu rows
 * at all was no faster (0.331 vs 0.331 s, medians of 7 pairs). */
#include <math.h>
#include <stdint.h>
#if defined(__AVX512F__)
#include <immintrin.h>
#endif

#include "gcpush/field_kernels.h"
#include "gcpush/invariants.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "invariants_priv.h"

/* Slot k of the ring: a gsample's values and jd, but for its time (the
 * slot's, o->hot.rt[k]) and mu (a guiding centre's constant, in every slot
 * since gcp_observer_begin).  Why: the quiet pass, which writes every
 * lane's sample into a slot at every step, is bound by its loads and
 * stores (~35 a lane); t and mu were 4 of them. */
static void gs_put(double *const a[GCP_OBS_RING_NV], size_t li, const struct gsample *g, double jd)
{
    a[1][li] = g->X[0], a[2][li] = g->X[1], a[3][li] = g->X[2], a[4][li] = g->ppar;
    a[6][li] = g->B, a[7][li] = g->p2, a[8][li] = jd;
}

static struct gsample gs_get(const struct gcp_observer *o, int k, size_t li)
{
    double *const *a = o->hot.r[k];
    return (struct gsample){.t = o->hot.rt[k], .X = {a[1][li], a[2][li], a[3][li]},
                            .ppar = a[4][li], .mu = a[5][li], .B = a[6][li], .p2 = a[7][li]};
}

/* The hot arrays of lane li into its struct lane (before gcp_obs_stream_sample_jd):
 * s1 is the ring's latest slot.  A minimum the quiet pass found (next) is
 * s1, with e0 the sample before it, the slot before (stream_sample's
 * new-minimum branch, with first_of_half = 0). */
void gcp_obs_hot_to_lane(const struct gcp_observer *o, struct lane *L, size_t li)
{
    if (!o->hot.have[li]) return; /* the quiet pass has not run: the lane is its own record */
    const int c = o->hot.cur;
    L->s1 = gs_get(o, c, li);
    L->jd1 = o->hot.r[c][8][li], L->J_acc = o->hot.J[li], L->mub = o->hot.mub[li];
    if (o->hot.next[li]) {
        L->eq_Bmin = o->hot.Bmin[li];
        L->e0 = gs_get(o, (c + 2) % 3, li);
        L->e1 = L->s1;
        L->eq_has_prev = (int)o->hot.hprev[li];
        L->eq_need_next = 1;
        L->eq_valid = 0;
    }
}

/* Lane li's struct lane into its hot arrays (after gcp_obs_stream_sample_jd):
 * L->s1 into ring slot `slot` (the latest once the step is done), e0 where
 * a minimum waits for its next sample into the slot before it, and what
 * decides whether its next step is quiet: the cadence grid times
 * t0 + k T of the samples rows and the stream contour (work when
 * tk <= t; invariants_samples.c). */
static void hot_cadence(struct gcp_observer *o, const struct lane *L, size_t li);

void gcp_obs_lane_to_hot(struct gcp_observer *o, const struct lane *L, size_t li, int slot)
{
    gs_put(o->hot.r[slot], li, &L->s1, L->jd1);
    if (L->eq_need_next) gs_put(o->hot.r[(slot + 2) % 3], li, &L->e0, 0.0);
    o->hot.J[li] = L->J_acc, o->hot.mub[li] = L->mub;
    o->hot.Bmin[li] = o->want_eq ? L->eq_Bmin : -INFINITY;
    o->hot.have[li] = L->have_s1;
    o->hot.next[li] = o->want_eq && L->eq_need_next;
    o->hot.hprev[li] = L->eq_has_prev;
    hot_cadence(o, L, li);
}

/* What of lane li's cadence state its quiet steps read: the first grid
 * time that asks for work (tnext), whether the stream contour's azimuth is
 * watched (az) and the direction of its last point (cx, cy). */
static void hot_cadence(struct gcp_observer *o, const struct lane *L, size_t li)
{
    const double T = o->opts.sample_dt;
    const unsigned inv = o->opts.invariants;
    double tn = INFINITY;
    if (T > 0 && !L->had_eq && (inv & (GCP_INV_MU | GCP_INV_ENERGY | GCP_INV_PPHI)))
        tn = o->t0 + (double)L->s_k * T;
    const int contour = o->want_drift && !L->n_drift_eq && T > 0;
    if (contour) tn = fmin(tn, o->t0 + (double)L->d_k * T);
    /* no sample yet: never quiet (the pass reads no have[] of its own) */
    o->hot.tnext[li] = L->have_s1 ? tn : -INFINITY;
    o->hot.az[li] = contour && L->st_n;
    o->hot.cx[li] = L->cst.cprev, o->hot.cy[li] = L->cst.sprev;
}

/* The step at t of the n live guiding-centre lanes of b (B at them in
 * o->Bx, By, Bz).  A lane is quiet when stream_sample would only add to its
 * trapezoid sums and, at a new |B| minimum, remember it: no mirror point
 * (same sign of p_par), not the sample after a minimum, no cadence time
 * due, the azimuth within pi/4 of the contour's last point (azimuth_moved's
 * first test).  Those steps are one vectorised pass with stream_sample's
 * expressions, and |B|, p^2 and the J integrand with observe_live's
 * (bit-identical).  The sample after a minimum (twice a bounce) takes the
 * same sums here and only its e0, e1, e2 per lane (slow = 2), a cadence
 * time (or an azimuth moved by pi/4) the same sums and only
 * gcp_obs_cadence per lane (slow = 4: one step in sample_every; through
 * the whole of stream_sample and the copies around it, ~15% of the
 * observer); mirror points go through gcp_obs_stream_sample_jd.  The
 * pass writes every lane's sample into the ring's next slot c, quiet or
 * not (a lane that is not gets the same values from lane_to_hot), and
 * leaves the slot before the latest (e0 of a lane whose minimum waits)
 * alone; per lane ~17 loads and ~11 stores (no t, mu or have: gs_put),
 * where the pass with a copy of s1 into a previous-sample array and |B|, p^2, jd through arrays of their
 * own had ~40 and ~30. */
static inline __attribute__((always_inline)) void
stream_quiet_pass(struct gcp_observer *o, const struct gcp_block *b, double t, size_t n,
                  const size_t *restrict idx, int dip, const double *restrict Bx,
                  const double *restrict By, const double *restrict Bz)
{
    const double *restrict x = b->x, *restrict y = b->y, *restrict z = b->z;
    const double *restrict pp = b->ppar, *restrict mu = b->mu;
    const double m = o->m, pc = o->pc;
    const int p = o->hot.cur, c = (p + 1) % 3;
    /* every lane's previous sample is at the slot's time; a lane that has
     * none has tnext = -inf (lane_to_hot), so it is not calm */
    const double h = t - o->hot.rt[p];
    const double *restrict pp1 = o->hot.r[p][4], *restrict jd1 = o->hot.r[p][8];
    double *restrict X0 = o->hot.r[c][1], *restrict X1 = o->hot.r[c][2];
    double *restrict X2 = o->hot.r[c][3], *restrict ppc = o->hot.r[c][4];
    double *restrict Bc = o->hot.r[c][6], *restrict p2c = o->hot.r[c][7], *restrict jdc = o->hot.r[c][8];
    double *restrict J = o->hot.J, *restrict mub = o->hot.mub, *restrict Bmin = o->hot.Bmin;
    const double *restrict tnext = o->hot.tnext, *restrict cx = o->hot.cx, *restrict cy = o->hot.cy;
    const int64_t *restrict az = o->hot.az;
    int64_t *restrict next = o->hot.next, *restrict hprev = o->hot.hprev, *restrict slow = o->hot.slow;
    /* |B|, p^2 and jd first, straight into the new slot, in a loop of their
     * own: each lane's is a chain of two square roots and two divisions in
     * series (~110 cycles), and a chunk is 64 lanes (8 vectors); inside the
     * loop below, whose ~150 instructions a vector fill the out-of-order
     * window, ~2 vectors' chains overlapped, here all of them (the same
     * expressions: the same numbers) */
    GCP_OBS_IVDEP
    for (size_t i = 0; i < n; i++) {
        const size_t li = idx ? idx[i] : i;
        /* B at the lane: the field's block evaluation's (dip: the same
         * numbers inline, no B arrays written and read back) */
        double bx, by, bz;
        if (dip) gcp_point_B_dipole(pc, x[i], y[i], z[i], &bx, &by, &bz);
        else bx = Bx[i], by = By[i], bz = Bz[i];
        /* observe_live's |B|, p^2, jd.  jd = p_par^2 / sqrt(m^2 + p^2/c^2)
         * multiplies by 1/c^2 (kernels.h GCP_INV_C2, folded at compile
         * time) where jdot divides by c^2: the division was one of two in
         * each lane's chain (~8% of this pass), and the product differs
         * from the quotient by at most an ulp of p^2/c^2, ~1e-3 of m^2 for
         * a 1 MeV proton, so m^2 + p^2/c^2 almost always rounds the same
         * (tests/bench/observer.sh's gc-rk4 scene: 20 of 202251 bounce J,
         * and 18 K, moved by an ulp, 2e-16 relative; nothing else).
         * observe_live's own pass (the reference of tests/unit/
         * test_invariants_quiet.c) takes the same product; jdot and
         * gcp_obs_gamma_m (full orbit, energies) keep the division. */
        const double Gb = sqrt(bx * bx + by * by + bz * bz);
        const double Gp2 = pp[i] * pp[i] + 2.0 * m * mu[i] * Gb;
        Bc[li] = Gb, p2c[li] = Gp2;
        jdc[li] = pp[i] * pp[i] / sqrt(m * m + Gp2 * GCP_INV_C2);
    }
    GCP_OBS_IVDEP
    for (size_t i = 0; i < n; i++) {
        const size_t li = idx ? idx[i] : i;
        const double Gb = Bc[li], Gjd = jdc[li];
        const double dot = x[i] * cx[li] + y[i] * cy[li];
        const double crs = y[i] * cx[li] - x[i] * cy[li];
        const double margin = 1e-9 * (fabs(x[i]) + fabs(y[i]));
        const int64_t still = !az[li] | (dot - fabs(crs) > margin);
        /* the lane's state read once and written once, unconditionally
         * (selects, not masked stores: a masked store that a later load of
         * the same line reads cannot forward to it, ~15% of the pass) */
        const double bmin = Bmin[li], Jl = J[li], mbl = mub[li];
        const int64_t nx = next[li], hp = hprev[li];
        const int64_t newmin = Gb < bmin;
        /* calm: the trapezoid sums and the minimum are all that happens,
         * but for the sample after a minimum (after), which stream_sample
         * would only take as e2, and the cadence's work (cad: a grid time
         * due, or the azimuth moved), which touches neither; a lane with
         * no sample yet (tnext = -inf) is never calm */
        const int64_t calm = (int64_t)((pp1[li] > 0) == (pp[i] > 0)) & (int64_t)(tnext[li] > -INFINITY);
        const int64_t cad = calm & ((int64_t)(tnext[li] <= t) | (still ^ 1));
        const int64_t after = calm & nx & (newmin ^ 1);
        const int64_t quiet = calm & (after ^ 1);
        slow[i] = (calm ^ 1) | (after << 1) | (cad << 2);
        const double Jn = Jl + 0.5 * (jd1[li] + Gjd) * h;
        /* stream_sample's 0.5 (mu_1 + mu) h with mu_1 = mu (a guiding
         * centre's mu is constant): the same number */
        const double mn = mbl + mu[i] * h;
        const int64_t nm = quiet & newmin;
        Bmin[li] = nm ? Gb : bmin;
        next[li] = (nm | nx) & (after ^ 1);
        hprev[li] = nm | hp;
        J[li] = calm ? Jn : Jl;
        mub[li] = calm ? mn : mbl;
        X0[li] = x[i], X1[li] = y[i], X2[li] = z[i];
        ppc[li] = pp[i];
    }
}

#define SLOW_AHEAD 4

/* The lanes i < n with slow[i] != 0, as 8 i + slow[i], in order into
 * slow[0 .. ns) (in place: ns <= i); returns ns.  With AVX-512 eight lanes
 * a step, compressed in a register and written with a masked store (a
 * compressing store to memory is microcoded on AMD Zen 4); the scalar loop
 * carries ns from each lane to the next (~0.011 s of the observer's ~0.15 s
 * in tests/bench/observer.sh's gc-rk4 scene, ~0.006 s this way: rdtsc, the
 * least of 7 runs each). */
static size_t slow_compact(int64_t *slow, size_t n)
{
    size_t ns = 0, i = 0;
#if defined(__AVX512F__)
    const __m512i iota = _mm512_set_epi64(7, 6, 5, 4, 3, 2, 1, 0);
    for (; i < n; i += 8) {
        const unsigned m = n - i < 8 ? (unsigned)(n - i) : 8u;
        const __mmask8 valid = (__mmask8)((1u << m) - 1u);
        const __m512i v = _mm512_maskz_loadu_epi64(valid, slow + i);
        const __mmask8 k = _mm512_test_epi64_mask(v, v);
        const __m512i at = _mm512_slli_epi64(_mm512_add_epi64(_mm512_set1_epi64((int64_t)i), iota), 3);
        const __m512i c = _mm512_maskz_compress_epi64(k, _mm512_add_epi64(at, v));
        const unsigned nk = (unsigned)__builtin_popcount((unsigned)k);
        _mm512_mask_storeu_epi64(slow + ns, (__mmask8)((1u << nk) - 1u), c);
        ns += nk;
    }
#endif
    for (; i < n; i++) {
        const int64_t v = slow[i];
        slow[ns] = 8 * (int64_t)i + v; /* v: 1, or 2 and 4 */
        ns += v != 0;
    }
    return ns;
}

static inline void lane_prefetch(const struct lane *L)
{
    const char *p = (const char *)L;
    for (size_t off = 0; off < sizeof *L; off += 64) __builtin_prefetch(p + off, 1, 3);
    __builtin_prefetch(p + sizeof *L - 1, 1, 3);
}

/* stream_quiet_pass, densely where the lanes' indices are still 0 .. n-1
 * (a block before its first retirement), and then the lanes that were not
 * quiet through stream_sample; the new slot becomes the latest. */
void gcp_obs_stream_quiet(struct gcp_observer *o, const struct gcp_block *b, double t, size_t n,
                          int dense)
{
    const size_t *idx = b->index;
    o->hot.rt[(o->hot.cur + 1) % 3] = t;
    /* B at the lanes: where the step left it in the block (gc-rk4's fused
     * step: the form it formed at the new state for its next step, the
     * field's numbers bit for bit), else the dipole's closed form inline,
     * else the field's block evaluation (observe_live) */
    const int at_x = (b->flags & GCP_BLOCK_B_AT_X) != 0;
    const double *Bx = at_x ? b->Bx : o->Bx, *By = at_x ? b->By : o->By;
    const double *Bz = at_x ? b->Bz : o->Bz;
    if (o->pdip && !at_x) {
        if (dense) stream_quiet_pass(o, b, t, n, NULL, 1, Bx, By, Bz);
        else stream_quiet_pass(o, b, t, n, idx, 1, Bx, By, Bz);
    } else {
        if (dense) stream_quiet_pass(o, b, t, n, NULL, 0, Bx, By, Bz);
        else stream_quiet_pass(o, b, t, n, idx, 0, Bx, By, Bz);
    }
    o->hot.passes++;
    const int p = o->hot.cur, c = (p + 1) % 3;
    /* the positions of the lanes that were not quiet (~1 in 10 a step:
     * mirror points, samples after a minimum, cadence times), found
     * without a branch per lane (one that mispredicts 1 time in 10 cost
     * as much as a fifth of the pass), in place over slow[] (k <= i), as 8 i + slow[i] */
    int64_t *restrict slow = o->hot.slow;
    const size_t ns = slow_compact(slow, n);
    /* the struct lane of each (744 bytes, 12 cache lines; the 2048 lanes
     * of the bench, 1.5 MB, are not in L2): fetched SLOW_AHEAD lanes ahead,
     * so that their misses overlap instead of stalling each lane's work */
    for (size_t k = 0; k < ns && k < SLOW_AHEAD; k++) lane_prefetch(&o->lane[idx[(size_t)(slow[k] >> 3)]]);
    for (size_t k = 0; k < ns; k++) {
        const size_t i = (size_t)(slow[k] >> 3);
        const int64_t kind = slow[k] & 7;
        const size_t li = idx[i];
        struct lane *L = &o->lane[li];
        if (k + SLOW_AHEAD < ns) lane_prefetch(&o->lane[idx[(size_t)(slow[k + SLOW_AHEAD] >> 3)]]);
        if (kind & 4) {
            /* the cadence's work of this step (stream_sample's
             * gcp_obs_cadence, between the sums and the minimum, which it
             * neither reads nor writes): a, the sample before, as L->s1
             * (L->s1 is not read while the hot arrays hold the lane) */
            const struct gsample s = gs_get(o, c, li);
            L->s1 = gs_get(o, p, li);
            gcp_obs_cadence(o, L, o->id0 + (int64_t)li, &s);
            hot_cadence(o, L, li);
        }
        if (kind & 2) {
            /* the sample after the minimum s1 (the pass took its sums and
             * cleared next): stream_sample's e0, e1, e2 and flags from the
             * ring, the sample before s1, s1 and this one */
            L->e0 = gs_get(o, (p + 2) % 3, li);
            L->e1 = gs_get(o, p, li);
            L->e2 = gs_get(o, c, li);
            L->eq_Bmin = o->hot.Bmin[li];
            L->eq_has_prev = L->eq_valid = (int)o->hot.hprev[li];
            L->eq_need_next = 0;
        }
        if (kind != 1) continue;
        /* the pass's values of this step, in slot c */
        const struct gsample s = gs_get(o, c, li);
        gcp_obs_hot_to_lane(o, L, li);
        gcp_obs_stream_sample_jd(o, L, o->id0 + (int64_t)li, &s, o->hot.r[c][8][li]);
        gcp_obs_lane_to_hot(o, L, li, c);
    }
    o->hot.cur = c;
}
