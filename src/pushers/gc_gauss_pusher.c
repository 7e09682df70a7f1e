/* gc-gl2, gc-gl4: the methods around the collocation solvers of
 * gc_gauss.c (issue 11) -- a lane's set-up in a canonical chart (its
 * state and the scales of the Newton test: gcp_gl_init, shared with the
 * Sundman forms, gc_sundman.c), and which solver pushes a block: the
 * dipole's closed form (gc_gauss_dipole.c), the analytic tokamak's
 * (gc_gauss_tokamak.c), else the chart's, over the block where the chart
 * has a block lift evaluation (gc_gauss_block.c) or lane by lane
 * (gcp_gl_step_lane) through the evolve layer (gcp_gc_lanes_advance).
 * The equations, the solvers and their tests: gc_gauss.c's header. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/gc.h"
#include "gcpush/particles.h"
#include "block_priv.h"
#include "canon_priv.h"
#include "gc_gauss_priv.h"
#include "gc_priv.h"

int gcp_gl_init(const void *vctx, const struct gcp_block *b, size_t i, double t, void *vlane)
{
    const struct gl_ctx *C = vctx;
    struct gl_lane *L = vlane;
    memset(L, 0, sizeof *L);
    const struct gcp_gc_consts k = {b->q, b->m, b->mu[i]};
    const double X[3] = {b->x[i], b->y[i], b->z[i]};
    const int st = C->chart.to_canon(&C->chart, &k, X, b->ppar[i], L->z, L->aux[0]);
    if (st) return st == GCP_NONFINITE ? st : GCP_STEP_FAILED;
    for (int j = 1; j <= GL_SMAX; j++) L->aux[j][0] = L->aux[0][0], L->aux[j][1] = L->aux[0][1];
    /* Scales of the Newton test (any chart): eta's change over a displacement
     * of |X| (largest of the three axes, by differences over 1e-4 |X|), and
     * P_eta's change for a change |p| of p_par. */
    const double r = sqrt(X[0] * X[0] + X[1] * X[1] + X[2] * X[2]);
    double zp[4], auxp[2];
    L->sc[0] = L->sc_pphi = 0.0;
    for (int j = 0; j < 3; j++) {
        double Xp[3] = {X[0], X[1], X[2]};
        Xp[j] += 1e-4 * r;
        if (C->chart.to_canon(&C->chart, &k, Xp, b->ppar[i], zp, auxp)) continue;
        L->sc[0] = fmax(L->sc[0], fabs(zp[1] - L->z[1]) * 1e4);
        L->sc_pphi = fmax(L->sc_pphi, fabs(zp[2] - L->z[2]) * 1e4);
    }
    struct gcp_field_sample fs = {.need = GCP_NEED_B};
    gcp_field_eval(C->chart.field, t, X, &fs);
    const double Bm = sqrt(fs.B[0] * fs.B[0] + fs.B[1] * fs.B[1] + fs.B[2] * fs.B[2]);
    const double p = fabs(b->ppar[i]) + sqrt(2.0 * b->m * fmax(b->mu[i], 0.0) * Bm);
    if (C->chart.to_canon(&C->chart, &k, X, b->ppar[i] + p, zp, auxp)) return GCP_STEP_FAILED;
    L->sc[1] = fabs(zp[3] - L->z[3]);
    if (!(L->sc[0] > 0.0 && isfinite(L->sc[0]) && L->sc[1] > 0.0 && isfinite(L->sc[1])))
        return GCP_STEP_FAILED;
    return 0;
}

static int gl_step(const void *vctx, struct gcp_block *b, size_t i, double t, double h,
                   void *vlane)
{
    (void)t;
    return gcp_gl_step_lane(vctx, b, i, h, vlane, 1);
}

static const struct gcp_gc_lane_ops gl_ops = {sizeof(struct gl_lane), gcp_gl_init, gl_step,
                                              NULL};
/* charts with a block lift evaluation: the lifted solve over the block */
static const struct gcp_gc_lane_ops gl_block_ops = {sizeof(struct gl_lane), gcp_gl_init, gl_step,
                                                    gcp_gl_step_block};

static size_t gl_advance(struct gcp_block *b, const struct gcp_field *f,
                         const struct gcp_pusher_type *p, const struct gcp_push_opts *o,
                         const struct gcp_sampler *s, const struct gl_tableau *tab)
{
    (void)p;
    /* the dipole: its closed-form canonical coordinates, fused (gc_gauss_dipole.c) */
    size_t live;
    if (gcp_gl_dipole_advance(b, f, o, s, tab, &live) == 0) return live;
    /* the analytic tokamak: its chart in closed form, fused (gc_gauss_tokamak.c) */
    if (gcp_gl_tokamak_advance(b, f, o, s, tab, &live) == 0) return live;
    struct gl_ctx C = {.tab = tab};
    char why[256];
    gcp_gl_ctx_weights(&C);
    if (gcp_canon_chart_create(f, &C.chart, why, sizeof why)) {
        /* the scene refuses such runs before they start (gcp_pusher_type.applies);
         * a library caller gets STEP_FAILED on every lane */
        size_t n = b->n_active;
        for (size_t i = 0; i < n; i++) b->status[i] = gcp_lane_fail(b, i, GCP_FAIL_UNSUPPORTED);
        b->n_active = gcp_block_retire(b, n, o->t0, 0);
        return b->n_active;
    }
    /* one work space for the block solver's steps of this advance (NULL:
     * each step allocates its own) */
    if (C.chart.lift_eval_block) C.block_scratch = gcp_gl_block_scratch();
    const size_t n =
        gcp_gc_lanes_advance(b, f, o, s, C.chart.lift_eval_block ? &gl_block_ops : &gl_ops, &C);
    free(C.block_scratch);
    gcp_canon_chart_destroy(&C.chart);
    return n;
}

static size_t gl2_advance(struct gcp_block *b, const struct gcp_field *f,
                          const struct gcp_pusher_type *p, const struct gcp_push_opts *o,
                          const struct gcp_sampler *s)
{
    return gl_advance(b, f, p, o, s, &gcp_gl2_tableau);
}

static size_t gl4_advance(struct gcp_block *b, const struct gcp_field *f,
                          const struct gcp_pusher_type *p, const struct gcp_push_opts *o,
                          const struct gcp_sampler *s)
{
    return gl_advance(b, f, p, o, s, &gcp_gl4_tableau);
}

/* A method needing a canonical chart applies where one exists. */
int gcp_gc_canon_applies(const struct gcp_field *f, char *why, size_t whylen)
{
    struct gcp_canon_chart c;
    if (gcp_canon_chart_create(f, &c, why, whylen)) return GCP_ERR_STATE;
    gcp_canon_chart_destroy(&c);
    return 0;
}

const struct gcp_pusher_type gcp_pusher_gc_gl2 = {
    .name = "gc-gl2",
    .doc = "guiding centre, symplectic implicit midpoint (Gauss-Legendre, order 2) in canonical "
           "coordinates, exact p_phi (axisymmetric fields with a canonical chart)",
    .order = 2,
    .kind = GCP_GUIDING_CENTRE,
    .advance = gl2_advance,
    .applies = gcp_gc_canon_applies,
};

const struct gcp_pusher_type gcp_pusher_gc_gl4 = {
    .name = "gc-gl4",
    .doc = "guiding centre, symplectic 2-stage Gauss-Legendre (order 4) in canonical "
           "coordinates, exact p_phi (axisymmetric fields with a canonical chart)",
    .order = 4,
    .kind = GCP_GUIDING_CENTRE,
    .advance = gl4_advance,
    .applies = gcp_gc_canon_applies,
};
