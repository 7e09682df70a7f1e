/* test_hybrid_util.h -- static helpers of the hybrid tests (test_hybrid*.c):
 * run a scene from run-file text serially, and push one particle with the
 * hybrid through the library API with a per-step observer. */
#ifndef GCPUSH_TESTS_HYBRID_UTIL_H
#define GCPUSH_TESTS_HYBRID_UTIL_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <criterion/criterion.h>

#include "gcpush/gc.h"
#include "gcpush/hybrid.h"
#include "gcpush/io.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "gcpush/run.h"

struct hy_serial {
    int64_t next, n;
};

static int64_t hy_next_chunk(void *ctx)
{
    struct hy_serial *s = ctx;
    return s->next < s->n ? s->next++ : -1;
}

/* Parses text and pushes every chunk in this process (no output file). */
static inline void hy_run_text(const char *text, struct gcp_scene **sc, struct gcp_results *res)
{
    struct gcp_error err = {0};
    cr_assert_eq(gcp_scene_parse("test.run", text, sc, &err), 0, "%s", err.msg);
    gcp_results_init(res, (*sc)->trajectory_samples, (*sc)->pusher->kind == GCP_GUIDING_CENTRE);
    res->hybrid = (*sc)->hybrid;
    struct hy_serial q = {0, gcp_scene_chunk_count(*sc)};
    const struct gcp_schedule sch = {hy_next_chunk, NULL, &q, NULL};
    cr_assert_eq(gcp_scene_push(*sc, res, &sch, &err), 0, "%s", err.msg);
    cr_assert_eq(gcp_results_sort(res), 0);
}

/* p^2 [kg^2 m^2/s^2] of lane i of a hybrid block in either mode: in a static
 * magnetic field the energy is a function of |p| alone, and p^2 keeps full
 * relative precision where (gamma - 1) m c^2 of a keV proton would lose
 * eleven digits to the rest energy. */
static inline double hy_p2(const struct gcp_hybrid *h, const struct gcp_block *b,
                           const struct gcp_field *f, size_t i, double t)
{
    if (gcp_hybrid_mode(h, b->index[i]) == GCP_MODE_FO)
        return b->m * b->m * (b->ux[i] * b->ux[i] + b->uy[i] * b->uy[i] + b->uz[i] * b->uz[i]);
    const double X[3] = {b->x[i], b->y[i], b->z[i]};
    struct gcp_field_sample s = {.need = GCP_NEED_B};
    gcp_field_eval(f, t, X, &s);
    const double B = sqrt(s.B[0] * s.B[0] + s.B[1] * s.B[1] + s.B[2] * s.B[2]);
    return b->ppar[i] * b->ppar[i] + 2.0 * b->m * b->mu[i] * B;
}

/* One particle through the hybrid API: full-orbit start (x, u) at t = 0,
 * nsteps GC steps of dt, fn(b, t, ctx) after every step. */
static inline void hy_push_one(const struct gcp_field *f, const struct gcp_hybrid_opts *ho,
                               double q, double m, const double x[3], const double u[3],
                               double dt, int64_t nsteps,
                               void (*fn)(const struct gcp_block *, double, void *), void *ctx,
                               struct gcp_hybrid **hout, struct gcp_block *b)
{
    cr_assert_eq(gcp_block_alloc(b, 1), 0);
    b->q = q, b->m = m;
    b->x[0] = x[0], b->y[0] = x[1], b->z[0] = x[2];
    b->ux[0] = u[0], b->uy[0] = u[1], b->uz[0] = u[2];
    cr_assert_eq(gcp_hybrid_create(hout, 1, ho), 0);
    cr_assert_eq(gcp_block_start(b, f, 0.0), 1);
    gcp_hybrid_begin(*hout, b, f, 0.0, 0);
    if (fn) fn(b, 0.0, ctx);
    const struct gcp_push_opts o = {.t0 = 0.0, .dt = dt, .nsteps = nsteps};
    const struct gcp_sampler smp = {1, fn, ctx};
    gcp_hybrid_advance(*hout, b, f, &o, fn ? &smp : NULL);
}

/* u = gamma v [m/s] of kinetic energy W [J] along unit direction d. */
static inline void hy_u_of(double W, double m, const double d[3], double u[3])
{
    const double mc2 = m * GCP_C_LIGHT * GCP_C_LIGHT;
    const double um = sqrt(W * (W + 2.0 * mc2)) / (m * GCP_C_LIGHT);
    for (int k = 0; k < 3; k++) u[k] = um * d[k];
}

#endif
