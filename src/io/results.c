/* Per-rank result rows: grown by chunk, sorted by id before writing,
 * saved to and loaded from checkpoints.  Every operation walks one table of
 * columns, so a new column is one line. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/io.h"
#include "io_priv.h"

size_t gcp_results_columns(struct gcp_results *r, struct gcp_results_column *c)
{
    const int64_t S = r->S;
    size_t n = 0;
#define COL_(field, per_row)                                                       \
    c[n++] = (struct gcp_results_column){#field, (void **)&r->field, sizeof *r->field, (per_row)}
    COL_(id, 1);
    COL_(pop, 1);
    COL_(x0, 3);
    COL_(u0, 3);
    COL_(t, 1);
    COL_(x, 3);
    if (r->gc || r->hybrid) {
        COL_(X0, 3);
        COL_(ppar0, 1);
        COL_(mu0, 1);
        COL_(ppar, 1);
        COL_(mu, 1);
    }
    if (!r->gc) COL_(u, 3);
    if (r->hybrid) {
        COL_(Xf, 3);
        COL_(hy_mode, 1);
        COL_(hy_switches, 1);
        COL_(hy_t_gc, 1);
        COL_(hy_t_fo, 1);
    }
    COL_(status, 1);
    COL_(step_failure, 1);
    COL_(steps, 1);
    COL_(cpu, 1);
    COL_(L0, 1);
    COL_(aeq0, 1);
    COL_(alc0, 1);
    if (S) {
        COL_(traj_t, S);
        COL_(traj_x, 3 * S);
        if (r->gc || r->hybrid) COL_(traj_ppar, S);
        if (!r->gc) COL_(traj_u, 3 * S);
        if (r->hybrid) COL_(traj_mode, S);
        COL_(traj_count, 1);
    }
#undef COL_
    return n;
}

int64_t gcp_results_row_bytes(int64_t samples, int gc, int64_t *largest)
{
    struct gcp_results r;
    gcp_results_init(&r, samples, gc);
    struct gcp_results_column c[GCP_RESULTS_MAX_COLUMNS];
    const size_t nc = gcp_results_columns(&r, c);
    int64_t sum = 0, big = 0;
    for (size_t k = 0; k < nc; k++) {
        const int64_t b = c[k].per_row * (int64_t)c[k].elem;
        sum += b;
        big = b > big ? b : big;
    }
    if (largest) *largest = big;
    return sum;
}

void gcp_results_init(struct gcp_results *r, int64_t samples, int gc)
{
    memset(r, 0, sizeof *r);
    r->S = samples;
    r->gc = gc;
}

int gcp_results_reserve(struct gcp_results *r, int64_t more)
{
    /* `more` may come from a file (a checkpoint): no doubling or byte count
     * may overflow, whatever its value */
    if (more < 0 || more > INT64_MAX / 4 - r->n) return GCP_ERR_NOMEM;
    if (r->n + more <= r->cap) return 0;
    int64_t cap = r->cap ? r->cap : 256;
    while (cap < r->n + more) cap *= 2;
    struct gcp_results_column c[GCP_RESULTS_MAX_COLUMNS];
    const size_t nc = gcp_results_columns(r, c);
    for (size_t k = 0; k < nc; k++)
        if ((uint64_t)cap > SIZE_MAX / ((size_t)c[k].per_row * c[k].elem)) return GCP_ERR_NOMEM;
    for (size_t k = 0; k < nc; k++) {
        void *p = realloc(*c[k].data, (size_t)cap * (size_t)c[k].per_row * c[k].elem);
        if (!p) return GCP_ERR_NOMEM;
        *c[k].data = p;
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

int gcp_results_sort(struct gcp_results *r)
{
    if (r->n < 2) return 0;
    int64_t *perm = malloc((size_t)r->n * sizeof *perm);
    if (!perm) return GCP_ERR_NOMEM;
    for (int64_t k = 0; k < r->n; k++) perm[k] = k;
    sort_keys_ = r->id;
    qsort(perm, (size_t)r->n, sizeof *perm, by_id);
    struct gcp_results_column c[GCP_RESULTS_MAX_COLUMNS];
    const size_t nc = gcp_results_columns(r, c);
    int rc = 0;
    for (size_t k = 0; k < nc && !rc; k++) {
        /* row j of the sorted column is old row perm[j] */
        const size_t row = (size_t)c[k].per_row * c[k].elem;
        char *tmp = malloc((size_t)r->n * row), *base = *c[k].data;
        if (!tmp) {
            rc = GCP_ERR_NOMEM;
            break;
        }
        for (int64_t j = 0; j < r->n; j++) memcpy(tmp + (size_t)j * row, base + (size_t)perm[j] * row, row);
        memcpy(base, tmp, (size_t)r->n * row);
        free(tmp);
    }
    free(perm);
    if (!rc) rc = gcp_events_sort(&r->ev);
    return rc;
}

int gcp_results_append(struct gcp_results *dst, const struct gcp_results *src)
{
    if (dst->S != src->S || dst->gc != src->gc || dst->hybrid != src->hybrid) return GCP_ERR_STATE;
    if (gcp_results_reserve(dst, src->n)) return GCP_ERR_NOMEM;
    struct gcp_results_column cd[GCP_RESULTS_MAX_COLUMNS], cs[GCP_RESULTS_MAX_COLUMNS];
    const size_t nc = gcp_results_columns(dst, cd);
    gcp_results_columns((struct gcp_results *)src, cs);
    for (size_t k = 0; k < nc && src->n; k++) { /* no rows: the arrays may be NULL */
        const size_t row = (size_t)cd[k].per_row * cd[k].elem;
        memcpy((char *)*cd[k].data + (size_t)dst->n * row, *cs[k].data, (size_t)src->n * row);
    }
    dst->n += src->n;
    dst->rank_cpu += src->rank_cpu;
    for (int64_t k = 0; k < src->ev.n; k++)
        if (gcp_events_push(&dst->ev, &src->ev.e[k])) return GCP_ERR_NOMEM;
    return 0;
}

void gcp_results_free(struct gcp_results *r)
{
    struct gcp_results_column c[GCP_RESULTS_MAX_COLUMNS];
    const size_t nc = gcp_results_columns(r, c);
    for (size_t k = 0; k < nc; k++) free(*c[k].data);
    gcp_events_free(&r->ev);
    memset(r, 0, sizeof *r);
}
