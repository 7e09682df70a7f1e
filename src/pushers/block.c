/* Block lane management shared by every pusher: allocation, lane swaps,
 * the per-step status classification and the retirement of stopped lanes. */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/particles.h"
#include "gcpush/pusher.h"
#include "block_priv.h"

/* n zeroed doubles on a cache line (64 B): calloc gives 16 B, and a block's
 * vector loops (the fused steps' tiles start at multiples of 128 lanes)
 * would split every 64-byte load and store across two lines -- measured
 * ~15-25% of boris-nr's fused step (make bench, issue 12). */
static double *alloc_doubles(size_t m)
{
    if (m > SIZE_MAX / sizeof(double) - 64) return NULL;
    const size_t bytes = (m * sizeof(double) + 63) / 64 * 64;
    double *p = aligned_alloc(64, bytes);
    if (p) memset(p, 0, bytes);
    return p;
}

int gcp_block_alloc(struct gcp_block *b, size_t n)
{
    memset(b, 0, sizeof *b);
    size_t m = n ? n : 1;
    double **d[] = {&b->x, &b->y, &b->z, &b->ux, &b->uy, &b->uz, &b->ppar, &b->mu, &b->t,
                    &b->Bx, &b->By, &b->Bz, &b->Ex, &b->Ey, &b->Ez, &b->hg};
    int fail = 0;
    for (size_t k = 0; k < sizeof d / sizeof d[0]; k++) fail |= !(*d[k] = alloc_doubles(m));
    fail |= !(b->status = calloc(m, sizeof(int32_t)));
    fail |= !(b->fstatus = calloc(m, sizeof(int32_t)));
    fail |= !(b->step_failure = calloc(m, sizeof(int32_t)));
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
    double *d[] = {b->x, b->y, b->z, b->ux, b->uy, b->uz, b->ppar, b->mu, b->t,
                   b->Bx, b->By, b->Bz, b->Ex, b->Ey, b->Ez, b->hg};
    for (size_t k = 0; k < sizeof d / sizeof d[0]; k++) free(d[k]);
    free(b->status);
    free(b->fstatus);
    free(b->step_failure);
    free(b->steps);
    free(b->index);
    memset(b, 0, sizeof *b);
}

#define SWAP_(T, a, i, j) do { T tmp_ = (a)[i]; (a)[i] = (a)[j]; (a)[j] = tmp_; } while (0)

void gcp_block_swap_lanes(struct gcp_block *b, size_t i, size_t j)
{
    SWAP_(double, b->x, i, j);
    SWAP_(double, b->y, i, j);
    SWAP_(double, b->z, i, j);
    SWAP_(double, b->ux, i, j);
    SWAP_(double, b->uy, i, j);
    SWAP_(double, b->uz, i, j);
    SWAP_(double, b->ppar, i, j);
    SWAP_(double, b->mu, i, j);
    SWAP_(double, b->t, i, j);
    SWAP_(int32_t, b->status, i, j);
    SWAP_(int32_t, b->step_failure, i, j);
    SWAP_(int64_t, b->steps, i, j);
    SWAP_(size_t, b->index, i, j);
}

/* Status of each live lane after a step: gcp_lane_status (block_priv.h). */
int32_t gcp_block_classify(struct gcp_block *b, size_t n, const struct gcp_field *f, int gc)
{
    const double rin2 = f->r_inner * f->r_inner;
    const double rout2 = f->r_outer * f->r_outer; /* inf stays inf */
    const double zmax = f->z_max;
    const double *restrict x = b->x, *restrict y = b->y, *restrict z = b->z;
    const int32_t *restrict fs = b->fstatus;
    int32_t *restrict st = b->status;
    int32_t any = 0;
    /* full orbit: u; guiding centre: p_par and mu -- chosen once, not per lane */
    if (gc) {
        const double *restrict pp = b->ppar, *restrict mu = b->mu;
        for (size_t i = 0; i < n; i++) {
            const double r2 = x[i] * x[i] + y[i] * y[i] + z[i] * z[i];
            st[i] = gcp_lane_status(r2, pp[i] * pp[i] + mu[i], z[i], fs[i], rin2, rout2, zmax);
            any |= st[i];
        }
    } else {
        const double *restrict ux = b->ux, *restrict uy = b->uy, *restrict uz = b->uz;
        for (size_t i = 0; i < n; i++) {
            const double r2 = x[i] * x[i] + y[i] * y[i] + z[i] * z[i];
            const double u2 = ux[i] * ux[i] + uy[i] * uy[i] + uz[i] * uz[i];
            st[i] = gcp_lane_status(r2, u2, z[i], fs[i], rin2, rout2, zmax);
            any |= st[i];
        }
    }
    return any;
}

/* Retires stopped lanes (status != 0) to the end; returns the live count. */
size_t gcp_block_retire(struct gcp_block *b, size_t n, double t_stop, int64_t steps_done)
{
    size_t i = 0;
    while (i < n) {
        if (b->status[i] != GCP_ALIVE) {
            b->t[i] = t_stop;
            gcp_lane_failure_default(b, i);
            b->steps[i] += steps_done;
            gcp_block_swap_lanes(b, i, n - 1);
            n--;
        } else {
            i++;
        }
    }
    return n;
}


void gcp_block_finish(struct gcp_block *b, size_t n, double t_end, int64_t k)
{
    /* 24 B a lane (t written, steps read and written): a quarter again of
     * what a streaming full-orbit step must move, x and u (96 B) */
    if (!(b->flags & GCP_BLOCK_CALLER_CLOCK))
        for (size_t i = 0; i < n; i++) {
            b->t[i] = t_end;
            b->steps[i] += k;
        }
    b->n_active = n;
}
