/* Per-rank result rows: grown by chunk, sorted by id before writing,
 * saved to and loaded from checkpoints.  Every operation walks one table of
 * columns, so a new column is one line. */
#define _DEFAULT_SOURCE /* madvise, MADV_HUGEPAGE, posix_memalign */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#ifdef __linux__
#include <sys/mman.h>
#endif

#include "gcpush/results.h"
#include "results_priv.h"

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

/* The trajectory columns are the bulk of a rank's memory (the flagship's
 * 90 particles x 4133 samples: 24 MB), written once by the push and read
 * once by the writer.  In 4 KiB pages each first touch is a fault that
 * zeroes the page, ~16 us in a paravirtualised VM (src/diag/invariants.c,
 * event storage): 0.1 s of the flagship's 0.93 s of CPU on one rank.  From
 * 2 MiB on, columns are aligned to 2 MiB and offered for transparent huge
 * pages (where the system has them on madvise, as Debian does): one fault
 * per 2 MiB.  posix_memalign keeps free() the way to release them. */
#define GCP_HUGE ((size_t)2 << 20)
void *gcp_io_alloc(size_t bytes)
{
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    if (bytes >= GCP_HUGE) {
        const size_t len = (bytes + GCP_HUGE - 1) / GCP_HUGE * GCP_HUGE;
        void *p = NULL;
        if (len < bytes || posix_memalign(&p, GCP_HUGE, len)) return NULL;
        (void)madvise(p, len, MADV_HUGEPAGE); /* a hint: failure is harmless */
        return p;
    }
#endif
    return malloc(bytes ? bytes : 1);
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
        const size_t row = (size_t)c[k].per_row * c[k].elem;
        void *p = gcp_io_alloc((size_t)cap * row);
        if (!p) return GCP_ERR_NOMEM;
        if (r->n) memcpy(p, *c[k].data, (size_t)r->n * row);
        free(*c[k].data);
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

/* Rows are permuted in place, one cycle of the permutation at a time
 * through a one-row buffer: a copy of each column through a temporary
 * moved every byte twice, into freshly mapped pages (0.08 s of the
 * flagship's 1.2 s on one rank: its 15 MB of trajectories); rows already
 * in order (one rank's pushing in id order) are not touched. */
int gcp_results_sort(struct gcp_results *r)
{
    const int64_t n = r->n;
    if (n < 2) return 0;
    int64_t *perm = malloc((size_t)n * sizeof *perm);
    unsigned char *placed = malloc((size_t)n);
    struct gcp_results_column c[GCP_RESULTS_MAX_COLUMNS];
    const size_t nc = gcp_results_columns(r, c);
    size_t widest = 0;
    for (size_t k = 0; k < nc; k++) {
        const size_t row = (size_t)c[k].per_row * c[k].elem;
        widest = row > widest ? row : widest;
    }
    char *held = malloc(widest);
    if (!perm || !placed || !held) {
        free(perm);
        free(placed);
        free(held);
        return GCP_ERR_NOMEM;
    }
    for (int64_t k = 0; k < n; k++) perm[k] = k;
    sort_keys_ = r->id;
    qsort(perm, (size_t)n, sizeof *perm, by_id);
    int64_t moved = 0;
    for (int64_t k = 0; k < n; k++) moved += perm[k] != k;
    for (size_t k = 0; k < nc && moved; k++) {
        /* row j of the sorted column is old row perm[j]: follow each cycle
         * j <- perm[j] <- perm[perm[j]] ..., holding its first row */
        const size_t row = (size_t)c[k].per_row * c[k].elem;
        char *base = *c[k].data;
        memset(placed, 0, (size_t)n);
        for (int64_t i = 0; i < n; i++) {
            if (placed[i] || perm[i] == i) continue;
            memcpy(held, base + (size_t)i * row, row);
            int64_t j = i;
            while (perm[j] != i) {
                memcpy(base + (size_t)j * row, base + (size_t)perm[j] * row, row);
                placed[j] = 1;
                j = perm[j];
            }
            memcpy(base + (size_t)j * row, held, row);
            placed[j] = 1;
        }
    }
    free(perm);
    free(placed);
    free(held);
    return gcp_events_sort(&r->ev);
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
    for (int64_t k = 0; k < src->ev.n + src->ev.ns; k++) {
        const struct gcp_event e = gcp_events_get(&src->ev, k);
        if (gcp_events_push(&dst->ev, &e)) return GCP_ERR_NOMEM;
    }
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

static int cmp_i64(const void *a, const void *b)
{
    const int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return (x > y) - (x < y);
}

void gcp_results_drop(struct gcp_results *r, const unsigned char *keep)
{
    struct gcp_results_column c[GCP_RESULTS_MAX_COLUMNS];
    const size_t nc = gcp_results_columns(r, c);
    int64_t w = 0;
    for (int64_t i = 0; i < r->n; i++) {
        if (!keep[i]) continue;
        if (w != i)
            for (size_t k = 0; k < nc; k++) {
                const size_t row = (size_t)c[k].per_row * c[k].elem;
                memcpy((char *)*c[k].data + (size_t)w * row, (char *)*c[k].data + (size_t)i * row, row);
            }
        w++;
    }
    r->n = w;
    /* events follow their particles: keep those whose id is still held */
    if (!r->ev.n && !r->ev.ns) return;
    int64_t *ids = malloc((size_t)(w ? w : 1) * sizeof *ids);
    if (!ids) return;
    memcpy(ids, r->id, (size_t)w * sizeof *ids);
    qsort(ids, (size_t)w, sizeof *ids, cmp_i64);
    int64_t we = 0;
    for (int64_t k = 0; k < r->ev.n; k++)
        if (w && bsearch(&r->ev.e[k].id, ids, (size_t)w, sizeof *ids, cmp_i64))
            r->ev.e[we++] = r->ev.e[k];
    r->ev.n = we;
    we = 0;
    for (int64_t k = 0; k < r->ev.ns; k++)
        if (w && bsearch(&r->ev.s[k].id, ids, (size_t)w, sizeof *ids, cmp_i64))
            r->ev.s[we++] = r->ev.s[k];
    r->ev.ns = we;
    free(ids);
}
