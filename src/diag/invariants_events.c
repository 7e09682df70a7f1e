/* The observer's event storage (struct gcp_events, invariants.h): growth
 * without copies or second page faults, release, and the sort by (id,
 * kind, t) with duplicates dropped that the output and the merge of ranks
 * read.  Split from invariants.c (the observer itself). */
#define _GNU_SOURCE /* mremap, MADV_HUGEPAGE (Linux): gcp_events_push; qsort_r */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#ifdef __linux__
#include <sys/mman.h>
#endif

#include "gcpush/error.h"
#include "gcpush/invariants.h"
#include "invariants_priv.h"

/* Event storage of cap events, the first n kept from old.  A run with
 * invariants asked keeps ~1e5-1e6 events (a mu row per half-bounce, 32
 * bytes in the scalar array since issue 12, a bounce row of 136 bytes per
 * bounce): tens of MB written once, where the
 * first touch of each page is a fault that zeroes it (~16 us per 4 KiB page
 * in a paravirtualised VM: 0.33 s for 83 MB, a third of what the observer
 * cost a gc-rk4 run).  From 2 MiB on the storage is its own mapping,
 * aligned to 2 MiB and offered to the kernel for transparent huge pages
 * (one fault per 2 MiB), and on Linux it grows by mremap onto a new 2 MiB
 * aligned range: the kernel moves the page tables (whole huge pages), so
 * growth neither copies the events nor faults and zeroes the pages a
 * second time.  Doubling with a copy did both: ~2x the final storage
 * zeroed, ~1x copied (measured, 2048 protons of 1 MeV with gc-rk4,
 * tests/bench/observer.sh: perf put 18% of the push there). */
#define EV_HUGE ((size_t)2 << 20)

/* cap events of sz bytes (struct gcp_event or struct gcp_scalar_event). */
static size_t events_bytes(int64_t cap, size_t sz) { return (size_t)cap * sz; }
/* Whether cap events live in a mapping of their own (else malloc). */
static int events_mapped(int64_t cap, size_t sz) { return events_bytes(cap, sz) >= EV_HUGE; }
static size_t events_map_size(int64_t cap, size_t sz)
{
    return (events_bytes(cap, sz) + EV_HUGE - 1) / EV_HUGE * EV_HUGE;
}

#if defined(__linux__) && defined(MREMAP_MAYMOVE) && defined(MREMAP_FIXED)
/* A 2 MiB aligned range of len bytes (a multiple of 2 MiB), reserved
 * (no access, no memory) for mremap to move onto; NULL when none. */
static void *aligned_range(size_t len, int prot)
{
    unsigned char *r = mmap(NULL, len + EV_HUGE, prot, MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE,
                            -1, 0);
    if (r == MAP_FAILED) return NULL;
    const size_t head = (EV_HUGE - (uintptr_t)r % EV_HUGE) % EV_HUGE;
    if (head) munmap(r, head);
    if (EV_HUGE - head) munmap(r + head + len, EV_HUGE - head);
    return r + head;
}

static void *events_grow(void *old, int64_t n, int64_t ocap, int64_t cap, size_t sz)
{
    if (!events_mapped(cap, sz)) return realloc(old, events_bytes(cap, sz));
    const size_t len = events_map_size(cap, sz);
    if (ocap && events_mapped(ocap, sz)) {
        void *to = aligned_range(len, PROT_NONE);
        if (!to) return NULL;
        void *p = mremap(old, events_map_size(ocap, sz), len, MREMAP_MAYMOVE | MREMAP_FIXED, to);
        if (p == MAP_FAILED) {
            munmap(to, len);
            return NULL;
        }
        return p;
    }
    void *p = aligned_range(len, PROT_READ | PROT_WRITE);
    if (!p) return NULL;
#ifdef MADV_HUGEPAGE
    (void)madvise(p, len, MADV_HUGEPAGE); /* a hint: failure is harmless */
#endif
    if (n) memcpy(p, old, events_bytes(n, sz));
    free(old);
    return p;
}

static void events_release(void *e, int64_t cap, size_t sz)
{
    if (e && events_mapped(cap, sz)) munmap(e, events_map_size(cap, sz));
    else free(e);
}
#else
/* Elsewhere: 2 MiB aligned storage, copied on growth as realloc would. */
static void *events_grow(void *old, int64_t n, int64_t ocap, int64_t cap, size_t sz)
{
    (void)ocap;
    if (!events_mapped(cap, sz)) return realloc(old, events_bytes(cap, sz));
    void *p = NULL;
    if (posix_memalign(&p, EV_HUGE, events_map_size(cap, sz))) return NULL;
    if (n) memcpy(p, old, events_bytes(n, sz));
    free(old);
    return p;
}

static void events_release(void *e, int64_t cap, size_t sz)
{
    (void)cap, (void)sz;
    free(e);
}
#endif

/* The lines of the row EV_AHEAD pushes on, asked for now (for writing):
 * the storage is fresh memory that no cache holds (the kernel zeroes a
 * new page with stores that bypass them), and a row's stores otherwise
 * wait for its lines from memory, one row at a time (the pushes are
 * hundreds of ns apart).  A prefetch into a page not yet faulted in is
 * dropped, so the first rows of each new page still wait.  Measured
 * (rdtsc around the observer's pushes, gc-rk4 scene of
 * tests/bench/observer.sh, 610k rows, on the loaded 2-core machine, 6 runs
 * of each binary interleaved): 0.09-0.31 s -> 0.02-0.05 s, mostly; the
 * push's CPU time did not move beyond that machine's noise. */
#define EV_AHEAD 4
static inline void rows_ahead(const void *row, size_t sz)
{
    const char *p = row;
    for (size_t off = 0; off < sz; off += 64) __builtin_prefetch(p + off, 1, 3);
}

int gcp_events_push_scalar(struct gcp_events *ev, const struct gcp_scalar_event *e)
{
    if (ev->ns == ev->scap) {
        const int64_t cap = ev->scap ? 2 * ev->scap : 256;
        void *p = events_grow(ev->s, ev->ns, ev->scap, cap, sizeof *ev->s);
        if (!p) return GCP_ERR_NOMEM;
        ev->s = p;
        ev->scap = cap;
    }
    ev->s[ev->ns++] = *e;
    if (ev->ns + EV_AHEAD < ev->scap) rows_ahead(&ev->s[ev->ns + EV_AHEAD], sizeof *ev->s);
    return 0;
}

int gcp_events_push(struct gcp_events *ev, const struct gcp_event *e)
{
    if (gcp_event_scalar(e->kind))
        return gcp_events_push_scalar(
            ev, &(struct gcp_scalar_event){e->id, e->kind, e->status, e->t, e->v[0]});
    if (ev->n == ev->cap) {
        const int64_t cap = ev->cap ? 2 * ev->cap : 256;
        void *p = events_grow(ev->e, ev->n, ev->cap, cap, sizeof *ev->e);
        if (!p) return GCP_ERR_NOMEM;
        ev->e = p;
        ev->cap = cap;
    }
    ev->e[ev->n++] = *e;
    if (ev->n + EV_AHEAD < ev->cap) rows_ahead(&ev->e[ev->n + EV_AHEAD], sizeof *ev->e + 63);
    return 0;
}

struct gcp_event gcp_events_get(const struct gcp_events *ev, int64_t k)
{
    if (k < ev->n) return ev->e[k];
    const struct gcp_scalar_event *s = &ev->s[k - ev->n];
    return (struct gcp_event){.id = s->id, .kind = s->kind, .status = s->status, .t = s->t,
                              .v = {s->v}};
}

void gcp_events_free(struct gcp_events *ev)
{
    events_release(ev->e, ev->cap, sizeof *ev->e);
    events_release(ev->s, ev->scap, sizeof *ev->s);
    memset(ev, 0, sizeof *ev);
}

/* The sort of gcp_events_sort: rows of either array by (id, kind, t),
 * equal keys in push order, the first of each equal key kept.  That is
 * the order the comparator sort it replaces (glibc qsort by (id, kind, t))
 * gave: glibc's qsort is a merge sort, stable, whenever it can allocate
 * its buffer, so rows of equal key kept push order and the dedup kept the
 * first.  Keys can tie: a particle pushed twice (once per checkpoint file)
 * repeats its rows exactly, so which copy is kept does not show, but the
 * tie-break is kept all the same.  t is assumed not NaN.  The rows the
 * sort sees are push order, per chunk of particles, each particle's rows
 * of one kind in time order: a counting sort of row indices by (id, kind)
 * (ids are the particles' 0 .. N-1, a rank's a dense subrange) leaves
 * each (id, kind) group in time order, checked and sorted by (t, push
 * index) where it is not; then the rows move once, by the permutation's
 * cycles.  The comparator sort moved 136-byte rows (through pointers) in
 * ~17 passes with a call per comparison: 0.037 s of 0.8 s of CPU on one
 * rank of runs/dipole.run. */
/* The key of a row: struct gcp_event and struct gcp_scalar_event begin
 * alike (id, kind, status, t). */
struct ev_key {
    int64_t id;
    int32_t kind, status;
    double t;
};
_Static_assert(offsetof(struct gcp_event, t) == offsetof(struct ev_key, t) &&
                   offsetof(struct gcp_scalar_event, t) == offsetof(struct ev_key, t) &&
                   offsetof(struct gcp_scalar_event, kind) == offsetof(struct ev_key, kind),
               "event rows begin with their key");

static struct ev_key ev_key(const char *rows, size_t sz, int64_t i)
{
    struct ev_key k;
    memcpy(&k, rows + (size_t)i * sz, sizeof k);
    return k;
}

/* -1, 0, 1 as a's key is before, equal to, after b's. */
static int key_cmp(struct ev_key a, struct ev_key b)
{
    if (a.id != b.id) return (a.id > b.id) - (a.id < b.id);
    if (a.kind != b.kind) return (a.kind > b.kind) - (a.kind < b.kind);
    return (a.t > b.t) - (a.t < b.t);
}

/* qsort_r of row indices (a total order: key, then push index, so any
 * sort gives the stable order) where the counting sort does not apply; the
 * rows through the context, not a static (the library may sort in threads). */
struct srt_ctx {
    const char *rows;
    size_t sz;
};
static int by_key_index(const void *va, const void *vb, void *vc)
{
    const struct srt_ctx *c = vc;
    const int64_t a = *(const int64_t *)va, b = *(const int64_t *)vb;
    const int k = key_cmp(ev_key(c->rows, c->sz, a), ev_key(c->rows, c->sz, b));
    return k ? k : (a > b) - (a < b);
}

/* Sorts n rows of sz bytes in place and drops repeated keys; the number
 * kept, or -1 out of memory. */
static int64_t sort_rows(char *rows, int64_t n, size_t sz)
{
    if (n < 2) return n;
    struct ev_key k0 = ev_key(rows, sz, 0), prev = k0;
    int64_t idlo = k0.id, idhi = k0.id, sorted = 1;
    for (int64_t i = 1; i < n; i++) {
        const struct ev_key k = ev_key(rows, sz, i);
        sorted &= key_cmp(prev, k) < 0; /* strictly: no repeat to drop either */
        idlo = k.id < idlo ? k.id : idlo;
        idhi = k.id > idhi ? k.id : idhi;
        prev = k;
    }
    if (sorted) return n;
    int64_t *perm = malloc((size_t)n * sizeof *perm);
    if (!perm) return -1;
    struct srt_ctx sc = {rows, sz};
    /* buckets (id, kind), kind < GCP_EVENT_KINDS; dense when at most ~2n */
    const uint64_t span = (uint64_t)idhi - (uint64_t)idlo;
    int64_t *at = NULL;
    if (span < (uint64_t)n * 2 / GCP_EVENT_KINDS + 64) {
        const int64_t nb = ((int64_t)span + 1) * GCP_EVENT_KINDS;
        at = calloc((size_t)nb + 1, sizeof *at);
        if (!at) {
            free(perm);
            return -1;
        }
        int bad = 0;
        for (int64_t i = 0; i < n; i++) {
            const struct ev_key k = ev_key(rows, sz, i);
            bad |= k.kind < 0 || k.kind >= GCP_EVENT_KINDS;
            if (!bad) at[(k.id - idlo) * GCP_EVENT_KINDS + k.kind + 1]++;
        }
        if (bad) { /* a kind out of range: the general sort below */
            free(at);
            at = NULL;
        } else {
            for (int64_t b = 0; b < nb; b++) at[b + 1] += at[b];
            for (int64_t i = 0; i < n; i++) {
                const struct ev_key k = ev_key(rows, sz, i);
                perm[at[(k.id - idlo) * GCP_EVENT_KINDS + k.kind]++] = i;
            }
            /* at[b] is now the end of bucket b: each group in time order? */
            for (int64_t b = 0, lo = 0; b < nb; lo = at[b++]) {
                int64_t j = lo + 1;
                while (j < at[b] && ev_key(rows, sz, perm[j - 1]).t <= ev_key(rows, sz, perm[j]).t) j++;
                if (j < at[b])
                    qsort_r(perm + lo, (size_t)(at[b] - lo), sizeof *perm, by_key_index, &sc);
            }
            free(at);
        }
    }
    if (!at) { /* ids too sparse for buckets */
        for (int64_t i = 0; i < n; i++) perm[i] = i;
        qsort_r(perm, (size_t)n, sizeof *perm, by_key_index, &sc);
    }
    /* row j of the sorted rows is old row perm[j]: follow each cycle
     * j <- perm[j] <- perm[perm[j]] ..., holding its first row; a placed
     * row's perm becomes -1 */
    _Alignas(16) char held[sizeof(struct gcp_event)];
    for (int64_t i = 0; i < n; i++) {
        if (perm[i] < 0) continue;
        if (perm[i] == i) {
            perm[i] = -1;
            continue;
        }
        memcpy(held, rows + (size_t)i * sz, sz);
        int64_t j = i;
        while (perm[j] != i) {
            memcpy(rows + (size_t)j * sz, rows + (size_t)perm[j] * sz, sz);
            const int64_t nx = perm[j];
            perm[j] = -1;
            j = nx;
        }
        memcpy(rows + (size_t)j * sz, held, sz);
        perm[j] = -1;
    }
    free(perm);
    int64_t w = 1;
    for (int64_t i = 1; i < n; i++)
        if (key_cmp(ev_key(rows, sz, i), ev_key(rows, sz, w - 1)) != 0) {
            if (w != i) memcpy(rows + (size_t)w * sz, rows + (size_t)i * sz, sz);
            w++;
        }
    return w;
}

int gcp_events_sort(struct gcp_events *ev)
{
    _Static_assert(sizeof(struct gcp_scalar_event) <= sizeof(struct gcp_event), "held row");
    const int64_t n = sort_rows((char *)ev->e, ev->n, sizeof *ev->e);
    const int64_t ns = sort_rows((char *)ev->s, ev->ns, sizeof *ev->s);
    if (n >= 0) ev->n = n;
    if (ns >= 0) ev->ns = ns;
    return n < 0 || ns < 0 ? GCP_ERR_NOMEM : 0;
}
