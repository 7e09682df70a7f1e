/* The scene's run: the chunks a schedule hands out (chunks of one
 * population, gcp_scene_chunk_size particles each) through the push engine
 * (engine.c), in slices that answer a stop request, each chunk's CPU time
 * shared among its rows. */
#include <time.h>

#include "gcpush/results.h"
#include "gcpush/run.h"
#include "run_priv.h"

/* Chunks per scene aimed at by gcp_scene_chunk_size (run.h): enough for
 * two to four ranks to share (handed out costliest first), few enough that
 * chunks stay at GCP_CHUNK lanes from 512 particles up (32-lane chunks cost
 * 14% more per particle than 64 in the 768-particle scaling run). */
#define GCP_CHUNKS_AIMED 8

int64_t gcp_scene_chunk_size(const struct gcp_scene *s)
{
    int64_t total = 0;
    for (size_t k = 0; k < s->npop; k++) total += s->pops[k].count;
    const int64_t c = (total + GCP_CHUNKS_AIMED - 1) / GCP_CHUNKS_AIMED;
    return c < GCP_CHUNK_MIN ? GCP_CHUNK_MIN : c > GCP_CHUNK ? GCP_CHUNK : c;
}

/* A population of n particles larger than a chunk in nc = ceil(n / cs)
 * chunks of `piece` particles (the last one the rest): the even share
 * ceil(n / nc) rounded up to whole 8-lane vectors, at most cs.  In chunks of
 * cs the flagship's 40 electrons were 32 + 8, the 32 alone ~53% of the
 * whole run's push: 2 ranks could not share it (the rank that drew it
 * finished last, 0.01-0.05 s of CPU behind the other); 24 + 16 leave no
 * chunk above ~40%, and LPT order (gcpush.c) then shares the flagship to
 * ~50.3/49.7% by the scene's estimate.  Whole vectors: 20 + 20 cost each
 * lane that falls outside the kernels' 8-wide loops more (the flagship's
 * push +30% on one rank); 24 + 16 against 32 + 8 measured within the
 * machine's noise (10 pairs run side by side, one rank: ratios 0.77-1.11,
 * median 0.93; by the per-lane costs of run.h ~+1%).  Large ensembles
 * (cs = 64) keep chunks of 64 and a rest (1000 -> 15 x 64 + 40). */
static void pop_chunks(const struct gcp_population *p, int64_t cs, int64_t *nc, int64_t *piece)
{
    const int64_t n0 = (p->count + cs - 1) / cs;
    int64_t even = n0 ? (p->count + n0 - 1) / n0 : 1;
    even = (even + 7) / 8 * 8;
    *piece = even < cs ? even : cs;
    *nc = (p->count + *piece - 1) / *piece;
}

int64_t gcp_scene_chunk_count(const struct gcp_scene *s)
{
    const int64_t cs = gcp_scene_chunk_size(s);
    int64_t n = 0;
    for (size_t k = 0; k < s->npop; k++) {
        int64_t nc, piece;
        pop_chunks(&s->pops[k], cs, &nc, &piece);
        n += nc;
    }
    return n;
}

void gcp_scene_chunk(const struct gcp_scene *s, int64_t c, int64_t *first, int64_t *count)
{
    const int64_t cs = gcp_scene_chunk_size(s);
    *first = 0;
    *count = 0;
    for (size_t k = 0; k < s->npop; k++) {
        const struct gcp_population *p = &s->pops[k];
        int64_t nc, piece;
        pop_chunks(p, cs, &nc, &piece);
        if (c < nc) {
            *first = p->first_id + c * piece;
            *count = c + 1 < nc ? piece : p->count - c * piece;
            return;
        }
        c -= nc;
    }
}

int64_t gcp_scene_chunk_of(const struct gcp_scene *s, int64_t id)
{
    const int64_t cs = gcp_scene_chunk_size(s);
    int64_t first = 0;
    for (size_t k = 0; k < s->npop; k++) {
        const struct gcp_population *p = &s->pops[k];
        int64_t nc, piece;
        pop_chunks(p, cs, &nc, &piece);
        if (id < p->first_id + p->count) return first + (id - p->first_id) / piece;
        first += nc;
    }
    return -1;
}

static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Steps per slice of a chunk's push (see gcp_schedule.stop): ~2 ms of a
 * full-orbit chunk, ~1 s of a gc-gl4 one. */
#define GCP_SLICE 8192

int gcp_scene_push(const struct gcp_scene *s, struct gcp_results *res,
                   const struct gcp_schedule *sched, struct gcp_error *err)
{
    struct gcp_engine e;
    int rc = gcp_engine_init(&e, s, err);
    if (rc) return rc;
    int64_t c;
    while ((c = sched->next(sched->ctx)) >= 0) {
        int64_t first, count;
        gcp_scene_chunk(s, c, &first, &count);
        if (count <= 0) continue;
        if (gcp_results_reserve(res, count)) {
            gcp_engine_free(&e);
            return gcp_error_set(err, GCP_ERR_NOMEM, "out of memory for results");
        }
        gcp_engine_load(&e, res, first, count);
        const double c0 = cpu_now();
        rc = gcp_engine_run(&e, res, GCP_SLICE, sched->stop, err);
        if (rc < 0) {
            gcp_engine_free(&e);
            return rc;
        }
        if (rc == 1) break; /* stopped: the chunk is dropped */
        const double spent = cpu_now() - c0;
        res->rank_cpu += spent;
        const int64_t row0 = res->n;
        int64_t total_steps = 0;
        for (int64_t i = 0; i < count; i++) total_steps += res->steps[row0 + i];
        /* The block's CPU time, shared in proportion to steps taken. */
        for (int64_t i = 0; i < count; i++)
            res->cpu[row0 + i] = total_steps ? spent * (double)res->steps[row0 + i] /
                                                   (double)total_steps
                                             : 0.0;
        res->n += count;
        if (sched->done) sched->done(sched->ctx, res, count, total_steps);
    }
    gcp_engine_free(&e);
    return 0;
}
