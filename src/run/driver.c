/* The scene's push loop: chunks of one population -> one block each.
 *
 * Everything the scene does not ask for is left out here, once, not per
 * step: no trajectory sampler unless output asks for one; the field and the
 * pusher are fixed for the run (the pusher's advance holds the inner loops).
 * A guiding-centre pusher starts each particle from its full-orbit initial
 * state through the first-order guiding-centre transformation
 * (gcp_gc_from_fo), so full-orbit and guiding-centre runs of one run file
 * push the same particles; guiding centres given in a file are pushed as
 * given. */
#include <math.h>
#include <string.h>
#include <time.h>

#include "gcpush/gc.h"
#include "gcpush/hybrid.h"
#include "gcpush/invariants.h"
#include "gcpush/io.h"
#include "gcpush/run.h"
#include "run_priv.h"

int64_t gcp_scene_chunk_count(const struct gcp_scene *s)
{
    int64_t n = 0;
    for (size_t k = 0; k < s->npop; k++) n += (s->pops[k].count + GCP_CHUNK - 1) / GCP_CHUNK;
    return n;
}

void gcp_scene_chunk(const struct gcp_scene *s, int64_t c, int64_t *first, int64_t *count)
{
    *first = 0;
    *count = 0;
    for (size_t k = 0; k < s->npop; k++) {
        const struct gcp_population *p = &s->pops[k];
        const int64_t nc = (p->count + GCP_CHUNK - 1) / GCP_CHUNK;
        if (c < nc) {
            *first = p->first_id + c * GCP_CHUNK;
            const int64_t left = p->count - c * GCP_CHUNK;
            *count = left < GCP_CHUNK ? left : GCP_CHUNK;
            return;
        }
        c -= nc;
    }
}

int64_t gcp_scene_chunk_of(const struct gcp_scene *s, int64_t id)
{
    int64_t base = 0;
    for (size_t k = 0; k < s->npop; k++) {
        const struct gcp_population *p = &s->pops[k];
        if (id < p->first_id + p->count) return base + (id - p->first_id) / GCP_CHUNK;
        base += (p->count + GCP_CHUNK - 1) / GCP_CHUNK;
    }
    return -1;
}

static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

struct traj_ctx {
    struct gcp_results *res;
    int64_t row0;   /* first result row of this chunk */
    int64_t sample; /* next sample index */
    const struct gcp_hybrid *hy; /* method = hybrid: the mode of each lane; else NULL */
};

/* Records one trajectory sample of every live lane. */
static void record(const struct gcp_block *b, double t, void *vctx)
{
    struct traj_ctx *c = vctx;
    struct gcp_results *r = c->res;
    const int64_t S = r->S, k = c->sample++;
    if (k >= S) return;
    for (size_t i = 0; i < b->n_active; i++) {
        const int64_t row = c->row0 + (int64_t)b->index[i];
        const size_t j = (size_t)(row * S + k);
        r->traj_t[j] = t;
        r->traj_x[3 * j] = b->x[i], r->traj_x[3 * j + 1] = b->y[i], r->traj_x[3 * j + 2] = b->z[i];
        if (c->hy) { /* the guiding centre's p_par or the particle's u, and which */
            const int mode = gcp_hybrid_mode(c->hy, b->index[i]);
            r->traj_mode[j] = (int8_t)mode;
            if (mode == GCP_MODE_GC) r->traj_ppar[j] = b->ppar[i];
            else r->traj_u[3 * j] = b->ux[i], r->traj_u[3 * j + 1] = b->uy[i],
                 r->traj_u[3 * j + 2] = b->uz[i];
        } else if (r->gc) {
            r->traj_ppar[j] = b->ppar[i];
        } else {
            r->traj_u[3 * j] = b->ux[i], r->traj_u[3 * j + 1] = b->uy[i];
            r->traj_u[3 * j + 2] = b->uz[i];
        }
        r->traj_count[row] = k + 1;
    }
}

/* Trajectory samples and the invariant observer in one sampler: the
 * observer sees every step, the trajectory every `every` steps. */
struct multi_ctx {
    struct gcp_observer *obs;
    int64_t every, k; /* trajectory every `every` steps (0: none); steps seen */
    struct traj_ctx *tc;
};

static void multi_sample(const struct gcp_block *b, double t, void *vctx)
{
    struct multi_ctx *c = vctx;
    gcp_observer_sample(b, t, c->obs);
    if (c->every && ++c->k % c->every == 0) record(b, t, c->tc);
}

/* Steps per slice of a chunk's push (see gcp_schedule.stop): ~2 ms of a
 * full-orbit chunk, ~1 s of a gc-gl4 one. */
#define GCP_SLICE 8192

int gcp_scene_push(const struct gcp_scene *s, struct gcp_results *res,
                   const struct gcp_schedule *sched, struct gcp_error *err)
{
    struct gcp_block b;
    if (gcp_block_alloc(&b, GCP_CHUNK)) return gcp_error_set(err, GCP_ERR_NOMEM, "out of memory");
    /* The observer exists only when [diagnostics] asks for something. */
    struct gcp_observer *obs = NULL;
    if (s->invariants || s->events) {
        const struct gcp_observer_opts oo = {.invariants = s->invariants, .events = s->events};
        if (gcp_observer_create(&obs, GCP_CHUNK, s->field, s->pusher, &oo)) {
            gcp_block_free(&b);
            return gcp_error_set(err, GCP_ERR_NOMEM, "out of memory");
        }
    }
    struct gcp_hybrid *hy = NULL;
    if (s->hybrid && gcp_hybrid_create(&hy, GCP_CHUNK, &s->hybrid_opts)) {
        gcp_block_free(&b);
        gcp_observer_free(obs);
        return gcp_error_set(err, GCP_ERR_NOMEM, "out of memory (hybrid)");
    }
    const double t0 = 0.0;
    const int64_t S = res->S;
    const int gc = s->pusher->kind == GCP_GUIDING_CENTRE;
    int64_t c;
    while ((c = sched->next(sched->ctx)) >= 0) {
        int64_t first, count;
        gcp_scene_chunk(s, c, &first, &count);
        if (count <= 0) continue;
        if (gcp_results_reserve(res, count)) {
            gcp_block_free(&b);
            gcp_observer_free(obs);
            gcp_hybrid_free(hy);
            return gcp_error_set(err, GCP_ERR_NOMEM, "out of memory for results");
        }
        const int64_t row0 = res->n;
        int pop = 0;
        for (int64_t i = 0; i < count; i++) {
            double x[3], u[3];
            gcp_scene_initial_state(s, first + i, &pop, x, u);
            const int64_t row = row0 + i;
            res->id[row] = first + i;
            res->pop[row] = pop;
            memcpy(&res->x0[3 * row], x, sizeof x);
            memcpy(&res->u0[3 * row], u, sizeof u);
            b.x[i] = x[0], b.y[i] = x[1], b.z[i] = x[2];
            b.ux[i] = u[0], b.uy[i] = u[1], b.uz[i] = u[2];
            const struct gcp_species *sp = &s->pops[pop].species;
            double X[3], ppar, mu;
            /* guiding centres given in a file are used as they are */
            const int given = gc && gcp_scene_initial_gc(s, first + i, X, &ppar, &mu);
            if (gc || hy) {
                /* a start the transformation cannot make (B = 0, outside a grid) is
                 * left non-finite: the block's start-up check gives it its status */
                if (!given &&
                    gcp_gc_from_fo(s->field, t0, sp->charge, sp->mass, x, u, X, &ppar, &mu))
                    X[0] = X[1] = X[2] = ppar = mu = NAN;
                if (gc) { /* hybrid: gcp_hybrid_begin makes the same transformation */
                    b.x[i] = X[0], b.y[i] = X[1], b.z[i] = X[2];
                    b.ppar[i] = ppar;
                    b.mu[i] = mu;
                    /* the start-up check (gcp_block_start) reads u, which a given guiding
                     * centre lacks: (ppar/m, 0, sqrt(mu)) is finite exactly when it is */
                    if (given) b.ux[i] = ppar / sp->mass, b.uy[i] = 0.0, b.uz[i] = sqrt(mu);
                }
                memcpy(&res->X0[3 * row], X, sizeof X);
                res->ppar0[row] = ppar;
                res->mu0[row] = mu;
            }
            b.index[i] = (size_t)i;
            b.status[i] = 0;
            b.steps[i] = 0;
            b.t[i] = t0;
            /* loss-cone classification at the start (dipole; NaN elsewhere) */
            res->L0[row] = res->aeq0[row] = res->alc0[row] = NAN;
            if (obs)
                gcp_dipole_classify(s->field, sp->charge, sp->mass, given ? X : x,
                                    given ? NULL : u, given ? ppar : 0.0, given ? mu : 0.0,
                                    &res->L0[row], &res->aeq0[row], &res->alc0[row]);
        }
        b.n = b.n_active = (size_t)count;
        b.q = s->pops[pop].species.charge;
        b.m = s->pops[pop].species.mass;
        if (S) {
            for (int64_t j = row0 * S; j < (row0 + count) * S; j++) {
                res->traj_t[j] = NAN;
                for (int d = 0; d < 3; d++) res->traj_x[3 * j + d] = NAN;
                if (gc || hy) res->traj_ppar[j] = NAN;
                if (!gc) for (int d = 0; d < 3; d++) res->traj_u[3 * j + d] = NAN;
                if (hy) res->traj_mode[j] = -1;
            }
            for (int64_t i = 0; i < count; i++) res->traj_count[row0 + i] = 0;
        }
        struct traj_ctx tc = {res, row0, 0, hy};
        struct gcp_sampler sampler = {s->pops[pop].trajectory_every, record, &tc};
        /* method = hybrid: the observer sees each mode's steps through the
         * hybrid's own hook (gcp_hybrid_set_observer), the trajectory keeps
         * its sampler */
        const struct gcp_sampler traj_sampler = sampler;
        struct multi_ctx mc = {obs, S ? s->pops[pop].trajectory_every : 0, 0, &tc};
        if (obs) sampler = (struct gcp_sampler){1, multi_sample, &mc};
        const double c0 = cpu_now();
        gcp_block_start(&b, s->field, t0);
        if (hy) gcp_hybrid_begin(hy, &b, s->field, t0, first);
        if (S) record(&b, t0, &tc);
        const int64_t events_before = res->ev.n;
        if (obs) {
            /* cadence samples and the stream contour: every sample_every steps of this population */
            gcp_observer_set_sample_dt(obs, (double)s->sample_every * s->pops[pop].dt);
            gcp_observer_begin(obs, &b, t0, first, &res->ev);
            if (hy) {
                const struct gcp_hybrid_observer ho = {gcp_observer_sample_mode, obs};
                gcp_hybrid_set_observer(hy, &ho);
                gcp_hybrid_observe(hy, &b, t0);
            }
        }
        struct gcp_push_opts opts = {.t0 = t0,
                                     .dt = s->pops[pop].dt,
                                     .nsteps = s->pops[pop].nsteps,
                                     .tolerance = s->tolerance,
                                     .adiabaticity_max = gc ? s->adiabaticity_max : 0.0};
        /* The push in slices, so that a stop request (SIGTERM) is answered
         * within a slice, not a whole chunk; a slice is a whole number of
         * trajectory intervals, so samples fall where they would unsliced. */
        const int64_t every = s->pops[pop].trajectory_every;
        const int64_t slice = every > 0 ? (GCP_SLICE + every - 1) / every * every : GCP_SLICE;
        int stopped = 0;
        for (int64_t done = 0; done < s->pops[pop].nsteps && b.n_active > 0;) {
            if (sched->stop && *sched->stop) {
                stopped = 1;
                break;
            }
            opts.t0 = t0 + (double)done * s->pops[pop].dt;
            opts.nsteps = s->pops[pop].nsteps - done < slice ? s->pops[pop].nsteps - done : slice;
            if (hy) gcp_hybrid_advance(hy, &b, s->field, &opts, S ? &traj_sampler : NULL);
            else s->pusher->advance(&b, s->field, s->pusher, &opts, (S || obs) ? &sampler : NULL);
            done += opts.nsteps;
        }
        if (stopped) { /* drop the chunk: its rows and events were never complete */
            res->ev.n = events_before;
            break;
        }
        if (obs && gcp_observer_end(obs, &b)) {
            gcp_block_free(&b);
            gcp_observer_free(obs);
            gcp_hybrid_free(hy);
            return gcp_error_set(err, GCP_ERR_NOMEM, "out of memory for events");
        }
        if (hy && gcp_hybrid_store(s, hy, &b, res, row0)) {
            gcp_block_free(&b);
            gcp_hybrid_free(hy);
            return gcp_error_set(err, GCP_ERR_NOMEM, "out of memory for switch events");
        }
        const double spent = cpu_now() - c0;
        res->rank_cpu += spent;
        int64_t total_steps = 0;
        for (size_t i = 0; i < b.n; i++) total_steps += b.steps[i];
        for (size_t i = 0; i < b.n; i++) {
            const int64_t row = row0 + (int64_t)b.index[i];
            res->t[row] = b.t[i];
            if (!hy) res->x[3 * row] = b.x[i], res->x[3 * row + 1] = b.y[i], res->x[3 * row + 2] = b.z[i];
            if (hy) {
                /* x, u, X, ppar, mu: gcp_hybrid_store */
            } else if (gc) {
                res->ppar[row] = b.ppar[i];
                res->mu[row] = b.mu[i];
            } else {
                res->u[3 * row] = b.ux[i], res->u[3 * row + 1] = b.uy[i];
                res->u[3 * row + 2] = b.uz[i];
            }
            res->status[row] = b.status[i];
            res->steps[row] = b.steps[i];
            /* The block's CPU time, shared in proportion to steps taken. */
            res->cpu[row] = total_steps ? spent * (double)b.steps[i] / (double)total_steps : 0.0;
        }
        res->n += count;
        if (sched->done) sched->done(sched->ctx, res, count, total_steps);
    }
    gcp_block_free(&b);
    gcp_observer_free(obs);
    gcp_hybrid_free(hy);
    return 0;
}
