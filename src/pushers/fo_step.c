/* The full-orbit step shared by every full-orbit pusher: synchronised
 * drift-kick-drift over a struct-of-arrays block (equations in pusher.h).
 *
 * The pusher and the field model are fixed for the whole call: the inner
 * loops are the field's block evaluation and the pusher's batch kick, both
 * dense over the live lanes with no per-lane decisions.  Lanes that stop
 * (domain, non-finite) are swapped out of the live range once per step. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "gcpush/pusher.h"

static const struct gcp_pusher_type *const all_pushers[] = {
    &gcp_pusher_boris, &gcp_pusher_boris_zu, &gcp_pusher_vay, &gcp_pusher_higuera_cary, NULL};

const struct gcp_pusher_type *const *gcp_pusher_types(void) { return all_pushers; }

const struct gcp_pusher_type *gcp_pusher_lookup(const char *name)
{
    for (const struct gcp_pusher_type *const *p = all_pushers; *p; p++)
        if (strcmp((*p)->name, name) == 0) return *p;
    return NULL;
}

int gcp_block_alloc(struct gcp_block *b, size_t n)
{
    memset(b, 0, sizeof *b);
    size_t m = n ? n : 1;
    double **d[] = {&b->x, &b->y, &b->z, &b->ux, &b->uy, &b->uz, &b->t,
                    &b->Bx, &b->By, &b->Bz, &b->Ex, &b->Ey, &b->Ez};
    int fail = 0;
    for (size_t k = 0; k < sizeof d / sizeof d[0]; k++) fail |= !(*d[k] = calloc(m, sizeof(double)));
    fail |= !(b->status = calloc(m, sizeof(int32_t)));
    fail |= !(b->fstatus = calloc(m, sizeof(int32_t)));
    fail |= !(b->steps = calloc(m, sizeof(int64_t)));
    fail |= !(b->index = calloc(m, sizeof(size_t)));
    if (fail) {
        gcp_block_free(b);
        return GCP_ERR_NOMEM;
    }
    for (size_t i = 0; i < n; i++) b->index[i] = i;
    b->n = b->n_active = n;
    return 0;
}

void gcp_block_free(struct gcp_block *b)
{
    double *d[] = {b->x, b->y, b->z, b->ux, b->uy, b->uz, b->t,
                   b->Bx, b->By, b->Bz, b->Ex, b->Ey, b->Ez};
    for (size_t k = 0; k < sizeof d / sizeof d[0]; k++) free(d[k]);
    free(b->status);
    free(b->fstatus);
    free(b->steps);
    free(b->index);
    memset(b, 0, sizeof *b);
}

#define SWAP_(T, a, i, j) do { T tmp_ = (a)[i]; (a)[i] = (a)[j]; (a)[j] = tmp_; } while (0)

static void swap_lanes(struct gcp_block *b, size_t i, size_t j)
{
    SWAP_(double, b->x, i, j);
    SWAP_(double, b->y, i, j);
    SWAP_(double, b->z, i, j);
    SWAP_(double, b->ux, i, j);
    SWAP_(double, b->uy, i, j);
    SWAP_(double, b->uz, i, j);
    SWAP_(double, b->t, i, j);
    SWAP_(int32_t, b->status, i, j);
    SWAP_(int64_t, b->steps, i, j);
    SWAP_(size_t, b->index, i, j);
}

/* Status of each live lane after a step, without branches:
 * NONFINITE beats the field's own verdict (LEFT_GRID, LEFT_DOMAIN), which
 * beats PRECIPITATED (|x| < r_inner) and LEFT_DOMAIN (|x| > r_outer or
 * |z| > z_max).  Returns non-zero when any lane stopped. */
static int32_t classify(struct gcp_block *b, size_t n, const struct gcp_field *f)
{
    const double rin2 = f->r_inner * f->r_inner;
    const double rout2 = f->r_outer * f->r_outer; /* inf stays inf */
    const double zmax = f->z_max;
    int32_t any = 0;
    for (size_t i = 0; i < n; i++) {
        const double r2 = b->x[i] * b->x[i] + b->y[i] * b->y[i] + b->z[i] * b->z[i];
        const double u2 = b->ux[i] * b->ux[i] + b->uy[i] * b->uy[i] + b->uz[i] * b->uz[i];
        const int32_t nonfinite = !isfinite(r2 + u2);
        const int32_t below = r2 < rin2;
        const int32_t outside = (r2 > rout2) | (fabs(b->z[i]) > zmax);
        const int32_t geo = below ? GCP_PRECIPITATED : outside * GCP_LEFT_DOMAIN;
        const int32_t fs = b->fstatus[i] ? b->fstatus[i] : geo;
        const int32_t s = nonfinite ? GCP_NONFINITE : fs;
        b->status[i] = s;
        any |= s;
    }
    return any;
}

/* Retires stopped lanes (status != 0) to the end; returns the live count. */
static size_t retire(struct gcp_block *b, size_t n, double t_stop, int64_t steps_done)
{
    size_t i = 0;
    while (i < n) {
        if (b->status[i] != GCP_ALIVE) {
            b->t[i] = t_stop;
            b->steps[i] += steps_done;
            swap_lanes(b, i, n - 1);
            n--;
        } else {
            i++;
        }
    }
    return n;
}

size_t gcp_block_start(struct gcp_block *b, const struct gcp_field *f, double t0)
{
    size_t n = b->n_active;
    memset(b->fstatus, 0, n * sizeof(int32_t));
    /* The field's own domain verdict (grids) comes from one evaluation. */
    f->type->eval_block(f, t0, n, b->x, b->y, b->z, b->Bx, b->By, b->Bz, NULL, NULL, NULL,
                        b->fstatus);
    if (classify(b, n, f)) n = retire(b, n, t0, 0);
    b->n_active = n;
    return n;
}

size_t gcp_block_advance_fo(struct gcp_block *b, const struct gcp_field *f,
                            const struct gcp_pusher_type *p, double t0, double dt,
                            int64_t nsteps, const struct gcp_sampler *sampler)
{
    size_t n = b->n_active;
    const double h = 0.5 * dt;
    /* Chosen once: with no electric field the gathered E stays zero. */
    double *Ex = f->has_E ? b->Ex : NULL;
    double *Ey = f->has_E ? b->Ey : NULL;
    double *Ez = f->has_E ? b->Ez : NULL;
    if (!f->has_E) {
        memset(b->Ex, 0, b->n * sizeof(double));
        memset(b->Ey, 0, b->n * sizeof(double));
        memset(b->Ez, 0, b->n * sizeof(double));
    }
    const int64_t every = sampler && sampler->fn ? sampler->every : 0;
    const gcp_kick_batch_fn kick = p->kick;
    const struct gcp_field_type *ft = f->type;
    int64_t k = 0;
    for (; k < nsteps && n > 0; k++) {
        const double t = t0 + (double)k * dt;
        gcp_drift_batch(n, b->x, b->y, b->z, b->ux, b->uy, b->uz, h);
        memset(b->fstatus, 0, n * sizeof(int32_t));
        ft->eval_block(f, t + h, n, b->x, b->y, b->z, b->Bx, b->By, b->Bz, Ex, Ey, Ez,
                       b->fstatus);
        kick(n, b->ux, b->uy, b->uz, b->Ex, b->Ey, b->Ez, b->Bx, b->By, b->Bz, b->q, b->m, dt);
        gcp_drift_batch(n, b->x, b->y, b->z, b->ux, b->uy, b->uz, h);
        if (classify(b, n, f)) n = retire(b, n, t + dt, k + 1);
        b->n_active = n;
        if (every && (k + 1) % every == 0) sampler->fn(b, t + dt, sampler->ctx);
    }
    for (size_t i = 0; i < n; i++) {
        b->t[i] = t0 + (double)k * dt;
        b->steps[i] += k;
    }
    b->n_active = n;
    return n;
}

int gcp_orbit_push(const struct gcp_field *f, const struct gcp_pusher_type *p, double q, double m,
                   double *t, double x[3], double u[3], double dt, int64_t nsteps, gcp_step_cb cb,
                   void *ctx)
{
    struct gcp_block b;
    if (gcp_block_alloc(&b, 1)) return GCP_STEP_FAILED;
    b.q = q;
    b.m = m;
    b.x[0] = x[0], b.y[0] = x[1], b.z[0] = x[2];
    b.ux[0] = u[0], b.uy[0] = u[1], b.uz[0] = u[2];
    int status = GCP_ALIVE;
    if (!isfinite(x[0] + x[1] + x[2] + u[0] + u[1] + u[2])) status = GCP_NONFINITE;
    /* With a callback, one step per call; without, the whole run in one. */
    const int64_t chunk = cb ? 1 : nsteps;
    double tt = *t;
    for (int64_t k = 0; status == GCP_ALIVE && k < nsteps; k += chunk) {
        gcp_block_advance_fo(&b, f, p, tt, dt, chunk, NULL);
        tt = b.t[0];
        status = b.status[0];
        const double xs[3] = {b.x[0], b.y[0], b.z[0]}, us[3] = {b.ux[0], b.uy[0], b.uz[0]};
        if (cb && cb(tt, xs, us, ctx)) break;
    }
    *t = tt;
    x[0] = b.x[0], x[1] = b.y[0], x[2] = b.z[0];
    u[0] = b.ux[0], u[1] = b.uy[0], u[2] = b.uz[0];
    gcp_block_free(&b);
    return status;
}
