/* Per-rank result rows: grown by chunk, sorted by id before writing. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/io.h"

void gcp_results_init(struct gcp_results *r, int64_t samples)
{
    memset(r, 0, sizeof *r);
    r->S = samples;
}

#define GROW_(ptr, count)                                                        \
    do {                                                                         \
        void *p_ = realloc((ptr), (size_t)(count) * sizeof *(ptr));              \
        if (!p_) return GCP_ERR_NOMEM;                                           \
        (ptr) = p_;                                                              \
    } while (0)

int gcp_results_reserve(struct gcp_results *r, int64_t more)
{
    if (r->n + more <= r->cap) return 0;
    int64_t cap = r->cap ? r->cap : 256;
    while (cap < r->n + more) cap *= 2;
    GROW_(r->id, cap);
    GROW_(r->pop, cap);
    GROW_(r->x0, 3 * cap);
    GROW_(r->u0, 3 * cap);
    GROW_(r->t, cap);
    GROW_(r->x, 3 * cap);
    GROW_(r->u, 3 * cap);
    GROW_(r->status, cap);
    GROW_(r->steps, cap);
    GROW_(r->cpu, cap);
    if (r->S) {
        GROW_(r->traj_t, cap * r->S);
        GROW_(r->traj_x, 3 * cap * r->S);
        GROW_(r->traj_u, 3 * cap * r->S);
        GROW_(r->traj_count, cap);
    }
    r->cap = cap;
    return 0;
}

static const int64_t *sort_keys_;
static int by_id(const void *a, const void *b)
{
    const int64_t x = sort_keys_[*(const int64_t *)a], y = sort_keys_[*(const int64_t *)b];
    return (x > y) - (x < y);
}

/* Applies the permutation perm (row k of the result = old row perm[k]) to an
 * array of rows of `w` elements of `size` bytes. */
static int permute(void *base, const int64_t *perm, int64_t n, size_t rowbytes)
{
    if (!base || n == 0) return 0;
    char *tmp = malloc((size_t)n * rowbytes);
    if (!tmp) return GCP_ERR_NOMEM;
    for (int64_t k = 0; k < n; k++)
        memcpy(tmp + (size_t)k * rowbytes, (char *)base + (size_t)perm[k] * rowbytes, rowbytes);
    memcpy(base, tmp, (size_t)n * rowbytes);
    free(tmp);
    return 0;
}

int gcp_results_sort(struct gcp_results *r)
{
    if (r->n < 2) return 0;
    int64_t *perm = malloc((size_t)r->n * sizeof *perm);
    if (!perm) return GCP_ERR_NOMEM;
    for (int64_t k = 0; k < r->n; k++) perm[k] = k;
    sort_keys_ = r->id;
    qsort(perm, (size_t)r->n, sizeof *perm, by_id);
    const size_t S = (size_t)r->S;
    int rc = permute(r->id, perm, r->n, sizeof(int64_t)) | permute(r->pop, perm, r->n, sizeof(int32_t)) |
             permute(r->x0, perm, r->n, 3 * sizeof(double)) |
             permute(r->u0, perm, r->n, 3 * sizeof(double)) |
             permute(r->t, perm, r->n, sizeof(double)) |
             permute(r->x, perm, r->n, 3 * sizeof(double)) |
             permute(r->u, perm, r->n, 3 * sizeof(double)) |
             permute(r->status, perm, r->n, sizeof(int32_t)) |
             permute(r->steps, perm, r->n, sizeof(int64_t)) |
             permute(r->cpu, perm, r->n, sizeof(double));
    if (S)
        rc |= permute(r->traj_t, perm, r->n, S * sizeof(double)) |
              permute(r->traj_x, perm, r->n, 3 * S * sizeof(double)) |
              permute(r->traj_u, perm, r->n, 3 * S * sizeof(double)) |
              permute(r->traj_count, perm, r->n, sizeof(int64_t));
    free(perm);
    return rc ? GCP_ERR_NOMEM : 0;
}

void gcp_results_free(struct gcp_results *r)
{
    free(r->id);
    free(r->pop);
    free(r->x0);
    free(r->u0);
    free(r->t);
    free(r->x);
    free(r->u);
    free(r->status);
    free(r->steps);
    free(r->cpu);
    free(r->traj_t);
    free(r->traj_x);
    free(r->traj_u);
    free(r->traj_count);
    memset(r, 0, sizeof *r);
}
