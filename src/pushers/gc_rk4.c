/* gc-rk4: classical fourth-order Runge-Kutta on the relativistic guiding-
 * centre equations (kernels.h gcp_gc_rhs; Cary & Brizard 2009), fixed step,
 * over a struct-of-arrays block of lanes:
 *   k1 = F(t, y), k2 = F(t + h/2, y + h k1/2), k3 = F(t + h/2, y + h k2/2),
 *   k4 = F(t + h, y + h k3),   y += h (k1 + 2 k2 + 2 k3 + k4)/6,
 * y = (X, p_par), mu constant.  Global error O(h^4).  Not symplectic: the
 * energy and p_phi drift secularly (O(t h^4)), which gc-gl2/gc-gl4 (symplectic) avoid.
 *
 * The adiabaticity check (opts->adiabaticity_max) and B*_par > 0 are tested
 * on k1, i.e. at the start of every step: a lane that fails retires with
 * the state and time of the start of that step.  A field status or a
 * non-finite value at any stage stops the lane after the step (classify). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/gc.h"
#include "gcpush/particles.h"
#include "block_priv.h"
#include "gc_priv.h"

static size_t gc_rk4_advance(struct gcp_block *b, const struct gcp_field *f,
                             const struct gcp_pusher_type *p, const struct gcp_push_opts *o,
                             const struct gcp_sampler *s)
{
    (void)p;
    size_t n = gcp_gc_block_begin(b, f, o);
    if (n == 0) return 0;
    const size_t N = b->n;
    /* y0 (4), accumulated increment (4), stage derivative (4) */
    double *w = malloc(12 * N * sizeof(double));
    if (!w) {
        for (size_t i = 0; i < n; i++) b->status[i] = GCP_STEP_FAILED;
        b->n_active = gcp_block_retire(b, n, o->t0, 0);
        return b->n_active;
    }
    double *y0 = w, *acc = w + 4 * N, *kk = w + 8 * N;
    const double h = o->dt, q = b->q, m = b->m, amax = o->adiabaticity_max;
    const int64_t every = s && s->fn ? s->every : 0;
    int64_t k = 0;
    for (; k < o->nsteps && n > 0; k++) {
        const double t = o->t0 + (double)k * h;
        /* stage 1, with the validity check; stopped lanes leave first */
        for (;;) {
            int any = 0;
            for (size_t i = 0; i < n; i++) {
                const double X[3] = {b->x[i], b->y[i], b->z[i]};
                double dX[3], dp;
                const int st = gcp_gc_eval(f, t, q, m, X, b->ppar[i], b->mu[i], amax, dX, &dp);
                b->fstatus[i] = st;
                any |= st;
                y0[4 * i] = X[0], y0[4 * i + 1] = X[1], y0[4 * i + 2] = X[2];
                y0[4 * i + 3] = b->ppar[i];
                for (int d = 0; d < 3; d++) kk[4 * i + d] = dX[d];
                kk[4 * i + 3] = dp;
            }
            if (!any) break;
            if (gcp_block_classify(b, n, f, 1)) n = gcp_block_retire(b, n, t, k);
            b->n_active = n;
        }
        if (n == 0) break;
        static const double cs[4] = {0.5, 0.5, 1.0, 0.0}; /* next stage offset */
        static const double ws[4] = {1.0, 2.0, 2.0, 1.0};
        for (int st = 0; st < 4; st++) {
            for (size_t i = 0; i < n; i++) {
                double *a = &acc[4 * i];
                const double *kd = &kk[4 * i], *y = &y0[4 * i];
                for (int d = 0; d < 4; d++) a[d] = (st == 0 ? 0.0 : a[d]) + ws[st] * kd[d];
                if (st == 3) continue;
                /* state of the next stage */
                const double c = cs[st] * h;
                const double X[3] = {y[0] + c * kd[0], y[1] + c * kd[1], y[2] + c * kd[2]};
                double dX[3], dp;
                const int fs = gcp_gc_eval(f, t + c, q, m, X, y[3] + c * kd[3], b->mu[i], 0.0, dX, &dp);
                if (!b->fstatus[i]) b->fstatus[i] = fs;
                double *kn = &kk[4 * i];
                kn[0] = dX[0], kn[1] = dX[1], kn[2] = dX[2], kn[3] = dp;
            }
        }
        const double h6 = h / 6.0;
        for (size_t i = 0; i < n; i++) {
            const double *y = &y0[4 * i], *a = &acc[4 * i];
            b->x[i] = y[0] + h6 * a[0];
            b->y[i] = y[1] + h6 * a[1];
            b->z[i] = y[2] + h6 * a[2];
            b->ppar[i] = y[3] + h6 * a[3];
        }
        if (gcp_block_classify(b, n, f, 1)) n = gcp_block_retire(b, n, t + h, k + 1);
        b->n_active = n;
        if (every && (k + 1) % every == 0) s->fn(b, t + h, s->ctx);
    }
    gcp_block_finish(b, n, o->t0 + (double)k * h, k);
    free(w);
    return n;
}

const struct gcp_pusher_type gcp_pusher_gc_rk4 = {
    .name = "gc-rk4",
    .doc = "guiding centre, classical RK4, fixed step (Cary & Brizard 2009 equations)",
    .order = 4,
    .kind = GCP_GUIDING_CENTRE,
    .kick = NULL,
    .advance = gc_rk4_advance,
};
