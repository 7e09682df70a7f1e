/* gcp_gc_lanes_advance: the per-lane guiding-centre methods (gc-gl2,
 * gc-gl4, gc-midpoint-pphi; gc_priv.h) on the evolve layer: their lane
 * operations become a stepper whose start-of-step check is
 * gcp_evolve_gc_check and whose step is the per-lane form. */
#include "gcpush/particles.h"
#include "block_priv.h"
#include "evolve_priv.h"
#include "gc_priv.h"

struct lanes_ctx {
    const struct gcp_gc_lane_ops *ops;
    const void *ctx;
};

static int lanes_init(const struct gcp_evolve *ev, void *vctx, const struct gcp_block *b, size_t i,
                      double t, void *lane)
{
    (void)ev;
    const struct lanes_ctx *c = vctx;
    return c->ops->init(c->ctx, b, i, t, lane);
}

static int lanes_step(const struct gcp_evolve *ev, void *vctx, struct gcp_block *b, size_t i,
                      double t, double h, void *lane)
{
    (void)ev;
    const struct lanes_ctx *c = vctx;
    return c->ops->step(c->ctx, b, i, t, h, lane);
}

static int32_t lanes_block(const struct gcp_evolve *ev, void *vctx, struct gcp_block *b, size_t n,
                           double t, double h, unsigned char *lanes)
{
    (void)ev;
    const struct lanes_ctx *c = vctx;
    return c->ops->step_block(c->ctx, b, n, t, h, lanes);
}

size_t gcp_gc_lanes_advance(struct gcp_block *b, const struct gcp_field *f,
                            const struct gcp_push_opts *o, const struct gcp_sampler *s,
                            const struct gcp_gc_lane_ops *ops, const void *ctx)
{
    const struct gcp_stepper st = {
        .gc = 1,
        .lane_size = ops->lane_size,
        .init = lanes_init,
        .start = ops->step_block ? gcp_gc_check_block : gcp_evolve_gc_check,
        .step_lane = lanes_step,
        .step_lanes = ops->step_block ? lanes_block : NULL,
    };
    struct lanes_ctx c = {ops, ctx};
    return gcp_evolve(b, f, o, s, &st, &c);
}
