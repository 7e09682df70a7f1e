/* test_gc_slicing.h -- the slicing check of the fused dipole pushers
 * (test_gc_dipole_line.c: gc-gl2 / gc-gl4; test_gc_sundman_line.c: their
 * Sundman forms): a push sampled at every step, every 7 steps and never
 * must give the same bits.  Criterion tests only (asserts inside). */
#ifndef GCPUSH_TESTS_GC_SLICING_H
#define GCPUSH_TESTS_GC_SLICING_H

#include <criterion/criterion.h>

#include "test_gc_util.h"

#define GC_SL_NL 150

static uint64_t gc_sl_rs;
static inline double gc_sl_urand(void)
{
    gc_sl_rs = gc_sl_rs * 6364136223846793005ull + 1442695040888963407ull;
    return (double)(gc_sl_rs >> 11) * 0x1.0p-53;
}

struct gc_sl_rec {
    int calls;
};
static inline void gc_sl_count(const struct gcp_block *b, double t, void *ctx)
{
    (void)b, (void)t;
    ((struct gc_sl_rec *)ctx)->calls++;
}

/* nl <= GC_SL_NL protons or electrons (the first nl of GC_SL_NL's scene):
 * trapped (L = 2 .. 6.2), every 7th inside
 * the loss cone (precipitates at 100 km within the push), every 9th proton
 * of 50-200 MeV (non-adiabatic at amax = 0.1, at once or after some steps,
 * where its gyroradius over the field's scale grows along its bounce). */
static inline void gc_sl_fill(struct gcp_block *b, const struct gcp_field *f, int el, size_t nl)
{
    gc_sl_rs = 0x243F6A8885A308D3ull + (uint64_t)el;
    b->q = el ? -GCP_E_CHARGE : GCP_E_CHARGE, b->m = el ? GCP_M_ELECTRON : GCP_M_PROTON;
    for (size_t i = 0; i < nl; i++) {
        const double L = 2.0 + 4.2 * gc_sl_urand(), lon = 2.0 * GCP_PI * gc_sl_urand();
        const int hot = !el && (i % 9 == 0);
        const double T = (hot ? 5e7 : 1e5) * GCP_E_CHARGE * pow(hot ? 4.0 : 100.0, gc_sl_urand());
        const double a = (i % 7 == 0 ? 3.0 + 5.0 * gc_sl_urand() : 20.0 + 70.0 * gc_sl_urand()) *
                         GCP_PI / 180.0;
        const double lat = 0.3 * (gc_sl_urand() - 0.5);
        const double s = sin(lat), W = 1.0 - s * s, R = L * GC_RE * W * sqrt(W);
        b->x[i] = R * cos(lon), b->y[i] = R * sin(lon), b->z[i] = L * GC_RE * W * s;
        const double X[3] = {b->x[i], b->y[i], b->z[i]};
        const double p = gc_p_of_T(T, b->m);
        b->ppar[i] = p * cos(a) * (i % 2 ? 1.0 : -1.0);
        b->mu[i] = p * sin(a) * p * sin(a) / (2.0 * b->m * gc_Bmag(f, X));
        b->status[i] = 0, b->steps[i] = 0, b->t[i] = 0.0, b->index[i] = i;
    }
    b->n_active = nl;
}

/* Pushes gc_sl_fill's scene (protons and electrons; dt ~ 1/30 of a 1 MeV
 * proton's bounce at L = 4, electrons: 1/30 of 3 ms) nst steps with P,
 * sampled every step, every 7 steps and never, in the dipole with the
 * surface at 100 km and r_outer = 6.2 R_E, amax = 0.1; every lane must end
 * with the same status, time and state bits.  landing = 0 (fixed steps):
 * the same steps and lane order too; landing = 1 (the Sundman forms, which
 * land beside their grid on each output time): lanes compared by index (a
 * lane retires at the end of the slice it stops in), and a lane alive at
 * the end has taken one landing step per sampling interval but the last
 * more than unsampled.  The scene must do what it is for: lanes stop, of
 * each kind, in different tiles (GC_SL_NL lanes; or in the one tile of a
 * block of <= 64, an engine's chunk: nl).  With nl < GC_SL_NL, the nl lanes
 * must also end as they do among all GC_SL_NL, sampled every step (a lane's
 * numbers do not depend on the lanes beside it; the larger block runs
 * several tiles, where a one-tile form of the pusher is not used: the
 * three pushes of the nl lanes alone share such a form, and a fault of it
 * that they all have, this comparison catches). */
static inline void gc_sl_check_n(const struct gcp_pusher_type *P, int64_t nst, int landing,
                                 size_t nl)
{
    struct gcp_field *f = gcp_field_dipole_create(GC_B0, 0, GC_RE + 100e3, 0.0);
    cr_assert_not_null(f);
    f->r_outer = 6.2 * GC_RE;
    for (int el = 0; el < 2; el++) {
        struct gcp_block b[4];
        const int64_t every[4] = {0, 1, 7, 1};
        const size_t nv[4] = {nl, nl, nl, GC_SL_NL};
        const int nvar = nl < GC_SL_NL ? 4 : 3;
        struct gc_sl_rec r[4] = {{0}, {0}, {0}, {0}};
        for (int v = 0; v < nvar; v++) {
            cr_assert_eq(gcp_block_alloc(&b[v], nv[v]), 0);
            gc_sl_fill(&b[v], f, el, nv[v]);
            const struct gcp_push_opts o = {0.0, el ? 1e-4 : 0.05, nst, 0.0, 0.1};
            const struct gcp_sampler smp = {every[v], gc_sl_count, &r[v]};
            P->advance(&b[v], f, P, &o, every[v] ? &smp : NULL);
        }
        size_t stopped = 0, at[4][GC_SL_NL];
        int kinds[16] = {0};
        for (int v = 0; v < nvar; v++)
            for (size_t i = 0; i < nv[v]; i++) at[v][b[v].index[i]] = i;
        for (size_t id = 0; id < nl; id++) {
            const size_t i = at[0][id];
            stopped += b[0].status[i] != GCP_ALIVE;
            if (b[0].status[i] >= 0 && b[0].status[i] < 16) kinds[b[0].status[i]]++;
            for (int v = 1; v < nvar; v++) {
                const size_t j = at[v][id];
                if (!landing && v < 3) cr_expect_eq(j, i, "%s: lane order", P->name);
                cr_expect_eq(b[v].status[j], b[0].status[i], "%s lane %zu: status %d vs %d",
                             P->name, id, b[v].status[j], b[0].status[i]);
                if (!landing || b[0].status[i] == GCP_ALIVE) {
                    const int64_t land = landing ? (nst + every[v] - 1) / every[v] - 1 : 0;
                    cr_expect_eq(b[v].steps[j], b[0].steps[i] + land, "%s lane %zu: steps",
                                 P->name, id);
                }
                cr_expect(b[v].t[j] == b[0].t[i], "%s lane %zu: t", P->name, id);
                cr_expect(b[v].x[j] == b[0].x[i] && b[v].y[j] == b[0].y[i] &&
                              b[v].z[j] == b[0].z[i] && b[v].ppar[j] == b[0].ppar[i],
                          "%s lane %zu (every %lld, %zu lanes): state differs", P->name, id,
                          (long long)every[v], nv[v]);
            }
        }
        cr_log_info("%s %s: %zu of %d stopped (precipitated %d, left %d, non-adiabatic %d, "
                    "failed %d), samples %d / %d", P->name, el ? "e-" : "p+", stopped, (int)nl,
                    kinds[GCP_PRECIPITATED], kinds[GCP_LEFT_DOMAIN], kinds[GCP_NONADIABATIC],
                    kinds[GCP_STEP_FAILED], r[1].calls, r[2].calls);
        /* 10 of GC_SL_NL lanes, in proportion for fewer */
        cr_expect(stopped >= 10 * nl / GC_SL_NL && stopped < nl, "%s: %zu stopped", P->name,
                  stopped);
        cr_expect(kinds[GCP_PRECIPITATED] > 0, "%s: none precipitated", P->name);
        if (!el) cr_expect(kinds[GCP_NONADIABATIC] > 0, "%s: none non-adiabatic", P->name);
        cr_expect_eq(r[1].calls, nst);
        for (int v = 0; v < nvar; v++) gcp_block_free(&b[v]);
    }
    gcp_field_free(f);
}

/* gc_sl_check_n with GC_SL_NL lanes. */
static inline void gc_sl_check(const struct gcp_pusher_type *P, int64_t nst, int landing)
{
    gc_sl_check_n(P, nst, landing, GC_SL_NL);
}

#endif
