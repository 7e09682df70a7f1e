/* gcp_events_sort against an independent reference: a stable insertion sort
 * by (id, kind, t) on a copy of the rows in push order, then the first row
 * of each equal key kept.  That is the order the file's rows had when the
 * sort was glibc's qsort (a stable merge sort), so the output of a run is
 * bit-identical across the change.  The rows carry their push index in v,
 * so a tie broken otherwise (a row of equal key kept from later in the push,
 * or rows of equal t reordered) shows; each case checks that such ties
 * occur, else it could not fail on the tie-break. */
#include <stdint.h>
#include <string.h>

#include <criterion/criterion.h>

#include "gcpush/invariants.h"

/* A small deterministic generator (xorshift64*): the same rows every run. */
static uint64_t rnd(uint64_t *s)
{
    *s ^= *s >> 12, *s ^= *s << 25, *s ^= *s >> 27;
    return *s * 2685821657736338717ull;
}

static int key_less(const struct gcp_event *a, const struct gcp_event *b)
{
    if (a->id != b->id) return a->id < b->id;
    if (a->kind != b->kind) return a->kind < b->kind;
    return a->t < b->t;
}

static int key_equal(const struct gcp_event *a, const struct gcp_event *b)
{
    return !key_less(a, b) && !key_less(b, a);
}

/* Pushes n rows; ids id_scale * (0 .. nid-1); kinds over all of them
 * (scalar or not); t: per particle increasing in push order when ordered,
 * else drawn from a few values (ties, groups out of order). Then sorts and
 * compares each array with the reference. */
static void check(int n, int nid, int64_t id_scale, int ordered, uint64_t seed)
{
    struct gcp_events ev = {0};
    struct gcp_event *ref = calloc((size_t)n, sizeof *ref);
    double *tnext = calloc((size_t)nid, sizeof *tnext);
    cr_assert(ref && tnext);
    for (int i = 0; i < n; i++) {
        const int p = (int)(rnd(&seed) % (uint64_t)nid);
        struct gcp_event e = {.id = p * id_scale, .kind = (int32_t)(rnd(&seed) % GCP_EVENT_KINDS)};
        /* ordered: a tie with the particle's previous row one time in 4 */
        if (ordered) tnext[p] += rnd(&seed) % 4 ? 1.0 : 0.0;
        e.t = ordered ? tnext[p] : (double)(rnd(&seed) % 5);
        e.v[0] = i; /* the push index: shows which row of a tie is kept */
        ref[i] = e;
        cr_assert(gcp_events_push(&ev, &e) == 0);
    }
    /* reference: stable insertion sort, then the first of each key */
    for (int i = 1; i < n; i++) {
        const struct gcp_event x = ref[i];
        int j = i;
        while (j > 0 && key_less(&x, &ref[j - 1])) ref[j] = ref[j - 1], j--;
        ref[j] = x;
    }
    int m = 0, ties = 0;
    for (int i = 0; i < n; i++) {
        if (m && key_equal(&ref[i], &ref[m - 1])) {
            ties++;
            continue;
        }
        ref[m++] = ref[i];
    }
    cr_assert_gt(ties, 10, "the case has ties (%d)", ties);
    cr_assert(gcp_events_sort(&ev) == 0);
    cr_assert_eq(ev.n + ev.ns, m);
    int64_t ie = 0, is = 0;
    for (int k = 0; k < m; k++) {
        const struct gcp_event *r = &ref[k];
        const struct gcp_event got =
            gcp_events_get(&ev, gcp_event_scalar(r->kind) ? ev.n + is++ : ie++);
        cr_assert(got.id == r->id && got.kind == r->kind && got.t == r->t && got.v[0] == r->v[0],
                  "row %d: id %lld kind %d t %g push %g, expected id %lld kind %d t %g push %g", k,
                  (long long)got.id, got.kind, got.t, got.v[0], (long long)r->id, r->kind, r->t,
                  r->v[0]);
    }
    gcp_events_free(&ev);
    free(ref);
    free(tnext);
}

/* Dense ids (the particles 0 .. N-1): the counting sort by (id, kind). */
Test(invariants_events, dense_push_order) { check(6000, 50, 1, 1, 1); }
Test(invariants_events, dense_groups_out_of_order) { check(6000, 50, 1, 0, 2); }
/* Ids far apart: the general sort of row indices. */
Test(invariants_events, sparse_ids) { check(5000, 40, 1000000007, 0, 3); }
Test(invariants_events, sparse_push_order) { check(5000, 40, 1000000007, 1, 4); }

/* Rows already sorted with no repeat are left as they are; a second sort
 * of sorted rows changes nothing. */
Test(invariants_events, sorted_twice)
{
    struct gcp_events ev = {0};
    uint64_t seed = 5;
    for (int i = 0; i < 3000; i++) {
        struct gcp_event e = {.id = (int64_t)(rnd(&seed) % 30), .kind = (int32_t)(rnd(&seed) % 3),
                              .t = (double)(rnd(&seed) % 7)};
        e.v[0] = i;
        cr_assert(gcp_events_push(&ev, &e) == 0);
    }
    cr_assert(gcp_events_sort(&ev) == 0);
    const int64_t n = ev.n, ns = ev.ns;
    struct gcp_event *e = malloc((size_t)n * sizeof *e);
    struct gcp_scalar_event *s = malloc((size_t)ns * sizeof *s);
    cr_assert(e && s);
    memcpy(e, ev.e, (size_t)n * sizeof *e);
    memcpy(s, ev.s, (size_t)ns * sizeof *s);
    cr_assert(gcp_events_sort(&ev) == 0);
    cr_assert(ev.n == n && ev.ns == ns);
    cr_assert(!memcmp(e, ev.e, (size_t)n * sizeof *e) && !memcmp(s, ev.s, (size_t)ns * sizeof *s));
    free(e);
    free(s);
    gcp_events_free(&ev);
}
