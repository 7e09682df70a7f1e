/* gcp_gc_lanes_advance: the block loop of the guiding-centre methods that
 * step each lane on its own with a per-lane solver state (gc_priv.h). */
#include <stdlib.h>
#include <string.h>

#include "gcpush/particles.h"
#include "block_priv.h"
#include "gc_priv.h"

/* gcp_block_retire's semantics, carrying the lanes' solver states along. */
static size_t lanes_retire(struct gcp_block *b, unsigned char *L, size_t sz, unsigned char *tmp,
                           size_t n, double t, int64_t steps)
{
    size_t i = 0;
    while (i < n) {
        if (b->status[i] != GCP_ALIVE) {
            b->t[i] = t;
            b->steps[i] += steps;
            gcp_block_swap_lanes(b, i, n - 1);
            memcpy(tmp, L + i * sz, sz);
            memcpy(L + i * sz, L + (n - 1) * sz, sz);
            memcpy(L + (n - 1) * sz, tmp, sz);
            n--;
        } else {
            i++;
        }
    }
    return n;
}

size_t gcp_gc_lanes_advance(struct gcp_block *b, const struct gcp_field *f,
                            const struct gcp_push_opts *o, const struct gcp_sampler *s,
                            const struct gcp_gc_lane_ops *ops, const void *ctx)
{
    size_t n = gcp_gc_block_begin(b, f, o);
    if (n == 0) return 0;
    const size_t sz = ops->lane_size;
    unsigned char *L = malloc((b->n + 1) * sz);
    if (!L) {
        for (size_t i = 0; i < n; i++) b->status[i] = GCP_STEP_FAILED;
        b->n_active = gcp_block_retire(b, n, o->t0, 0);
        return b->n_active;
    }
    unsigned char *tmp = L + b->n * sz;
    int any = 0;
    for (size_t i = 0; i < n; i++) {
        const int r = ops->init(ctx, b, i, o->t0, L + i * sz);
        if (r) b->status[i] = r, any = 1;
    }
    if (any) n = lanes_retire(b, L, sz, tmp, n, o->t0, 0);
    const double h = o->dt, q = b->q, m = b->m, amax = o->adiabaticity_max;
    const int64_t every = s && s->fn ? s->every : 0;
    int64_t k = 0;
    for (; k < o->nsteps && n > 0; k++) {
        const double t = o->t0 + (double)k * h;
        any = 0;
        for (size_t i = 0; i < n; i++) {
            if (k > 0) {
                /* validity at the start of the step (begin checked k = 0) */
                const double X[3] = {b->x[i], b->y[i], b->z[i]};
                double dX[3], dp;
                const int st = gcp_gc_eval(f, t, q, m, X, b->ppar[i], b->mu[i], amax, dX, &dp);
                if (st) {
                    b->status[i] = st;
                    any = 1;
                    continue;
                }
            }
            const int r = ops->step(ctx, b, i, t, h, L + i * sz);
            if (r) b->status[i] = r, any = 1;
        }
        if (any) n = lanes_retire(b, L, sz, tmp, n, t, k);
        if (gcp_block_classify(b, n, f, 1)) n = lanes_retire(b, L, sz, tmp, n, t + h, k + 1);
        b->n_active = n;
        if (every && (k + 1) % every == 0) s->fn(b, t + h, s->ctx);
    }
    gcp_block_finish(b, n, o->t0 + (double)k * h, k);
    free(L);
    return n;
}
