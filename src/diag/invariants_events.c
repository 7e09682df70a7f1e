/* The observer's event storage (struct gcp_events, invariants.h): growth
 * without copies or second page faults, release, and the sort by (id,
 * kind, t) with duplicates dropped that the output and the merge of ranks
 * read.  Split from invariants.c (the observer itself). */
#define _GNU_SOURCE /* mremap, MADV_HUGEPAGE (Linux): gcp_events_push */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#ifdef __linux__
#include <sys/mman.h>
#endif

#include "gcpush/error.h"
#include "gcpush/invariants.h"

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

int gcp_events_push(struct gcp_events *ev, const struct gcp_event *e)
{
    if (gcp_event_scalar(e->kind)) {
        if (ev->ns == ev->scap) {
            const int64_t cap = ev->scap ? 2 * ev->scap : 256;
            void *p = events_grow(ev->s, ev->ns, ev->scap, cap, sizeof *ev->s);
            if (!p) return GCP_ERR_NOMEM;
            ev->s = p;
            ev->scap = cap;
        }
        ev->s[ev->ns++] = (struct gcp_scalar_event){e->id, e->kind, e->status, e->t, e->v[0]};
        return 0;
    }
    if (ev->n == ev->cap) {
        const int64_t cap = ev->cap ? 2 * ev->cap : 256;
        void *p = events_grow(ev->e, ev->n, ev->cap, cap, sizeof *ev->e);
        if (!p) return GCP_ERR_NOMEM;
        ev->e = p;
        ev->cap = cap;
    }
    ev->e[ev->n++] = *e;
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

static int by_id_kind_t(const void *va, const void *vb)
{
    const struct gcp_event *a = va, *b = vb;
    if (a->id != b->id) return (a->id > b->id) - (a->id < b->id);
    if (a->kind != b->kind) return (a->kind > b->kind) - (a->kind < b->kind);
    return (a->t > b->t) - (a->t < b->t);
}

static int by_id_kind_t_s(const void *va, const void *vb)
{
    const struct gcp_scalar_event *a = va, *b = vb;
    if (a->id != b->id) return (a->id > b->id) - (a->id < b->id);
    if (a->kind != b->kind) return (a->kind > b->kind) - (a->kind < b->kind);
    return (a->t > b->t) - (a->t < b->t);
}

int gcp_events_sort(struct gcp_events *ev)
{
    if (ev->n >= 2) {
        qsort(ev->e, (size_t)ev->n, sizeof *ev->e, by_id_kind_t);
        int64_t w = 1;
        for (int64_t i = 1; i < ev->n; i++)
            if (by_id_kind_t(&ev->e[i], &ev->e[w - 1]) != 0) ev->e[w++] = ev->e[i];
        ev->n = w;
    }
    if (ev->ns >= 2) {
        qsort(ev->s, (size_t)ev->ns, sizeof *ev->s, by_id_kind_t_s);
        int64_t w = 1;
        for (int64_t i = 1; i < ev->ns; i++)
            if (by_id_kind_t_s(&ev->s[i], &ev->s[w - 1]) != 0) ev->s[w++] = ev->s[i];
        ev->ns = w;
    }
    return 0;
}

