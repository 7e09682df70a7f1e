/* The push engine: one chunk of one population -> one block, pushed from
 * its initial states to the end of the population's run, its rows and
 * events stored (run_priv.h).  The driver (driver.c) hands it the chunks of
 * an ensemble run; a sweep (sweep.c) the chunks of one population under
 * each (method, dt, tolerance) of its rows.
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

#include "gcpush/gc.h"
#include "gcpush/hybrid.h"
#include "gcpush/invariants.h"
#include "gcpush/results.h"
#include "gcpush/run.h"
#include "run_priv.h"

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

/* Trajectory samples, the invariant observer and the engine's watcher in
 * one sampler: the observer and the watcher see every step, the trajectory
 * every `every` steps. */
struct multi_ctx {
    struct gcp_observer *obs;
    const struct gcp_sampler *watch;
    int64_t every, k; /* trajectory every `every` steps (0: none); steps seen */
    struct traj_ctx *tc;
};

static void multi_sample(const struct gcp_block *b, double t, void *vctx)
{
    struct multi_ctx *c = vctx;
    if (c->obs) gcp_observer_sample(b, t, c->obs);
    if (c->watch) c->watch->fn(b, t, c->watch->ctx);
    if (c->every && ++c->k % c->every == 0) record(b, t, c->tc);
}

int gcp_engine_init(struct gcp_engine *e, const struct gcp_scene *s, struct gcp_error *err)
{
    memset(e, 0, sizeof *e);
    e->s = s;
    if (gcp_block_alloc(&e->b, GCP_CHUNK) || gcp_block_alloc(&e->b0, GCP_CHUNK)) {
        gcp_engine_free(e);
        return gcp_error_set(err, GCP_ERR_NOMEM, "out of memory");
    }
    /* The observer exists only when [diagnostics] asks for something. */
    if (s->invariants || s->events) {
        const struct gcp_observer_opts oo = {.invariants = s->invariants, .events = s->events};
        if (gcp_observer_create(&e->obs, GCP_CHUNK, s->field, s->pusher, &oo)) {
            gcp_engine_free(e);
            return gcp_error_set(err, GCP_ERR_NOMEM, "out of memory");
        }
    }
    if (s->hybrid && gcp_hybrid_create(&e->hy, GCP_CHUNK, &s->hybrid_opts)) {
        gcp_engine_free(e);
        return gcp_error_set(err, GCP_ERR_NOMEM, "out of memory (hybrid)");
    }
    return 0;
}

void gcp_engine_free(struct gcp_engine *e)
{
    gcp_block_free(&e->b);
    gcp_block_free(&e->b0);
    gcp_observer_free(e->obs);
    gcp_hybrid_free(e->hy);
    memset(e, 0, sizeof *e);
}

void gcp_engine_load(struct gcp_engine *e, struct gcp_results *res, int64_t first, int64_t count)
{
    const struct gcp_scene *s = e->s;
    struct gcp_block *b = &e->b0;
    const double t0 = 0.0;
    const int gc = s->pusher->kind == GCP_GUIDING_CENTRE;
    const int hy = e->hy != NULL;
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
        b->x[i] = x[0], b->y[i] = x[1], b->z[i] = x[2];
        b->ux[i] = u[0], b->uy[i] = u[1], b->uz[i] = u[2];
        const struct gcp_species *sp = &s->pops[pop].species;
        double X[3], ppar, mu;
        /* guiding centres given in a file are used as they are */
        const int given = gc && gcp_scene_initial_gc(s, first + i, X, &ppar, &mu);
        if (gc || hy) {
            /* a start the transformation cannot make (B = 0, outside a grid) is
             * left non-finite: the block's start-up check gives it its status */
            if (!given && gcp_gc_from_fo(s->field, t0, sp->charge, sp->mass, x, u, X, &ppar, &mu))
                X[0] = X[1] = X[2] = ppar = mu = NAN;
            if (gc) { /* hybrid: gcp_hybrid_begin makes the same transformation */
                b->x[i] = X[0], b->y[i] = X[1], b->z[i] = X[2];
                b->ppar[i] = ppar;
                b->mu[i] = mu;
                /* the start-up check (gcp_block_start) reads u, which a given guiding
                 * centre lacks: (ppar/m, 0, sqrt(mu)) is finite exactly when it is */
                if (given) b->ux[i] = ppar / sp->mass, b->uy[i] = 0.0, b->uz[i] = sqrt(mu);
            }
            memcpy(&res->X0[3 * row], X, sizeof X);
            res->ppar0[row] = ppar;
            res->mu0[row] = mu;
        }
        b->index[i] = (size_t)i;
        b->status[i] = 0;
        b->step_failure[i] = 0;
        b->steps[i] = 0;
        b->t[i] = t0;
        /* loss-cone classification at the start (dipole; NaN elsewhere) */
        res->L0[row] = res->aeq0[row] = res->alc0[row] = NAN;
        if (e->obs)
            gcp_dipole_classify(s->field, sp->charge, sp->mass, given ? X : x, given ? NULL : u,
                                given ? ppar : 0.0, given ? mu : 0.0, &res->L0[row],
                                &res->aeq0[row], &res->alc0[row]);
    }
    b->n = b->n_active = (size_t)count;
    b->q = s->pops[pop].species.charge;
    b->m = s->pops[pop].species.mass;
    e->first = first;
    e->count = count;
    e->pop = pop;
}

/* The loaded start states into the working block. */
static void restore(struct gcp_engine *e)
{
    const struct gcp_block *a = &e->b0;
    struct gcp_block *b = &e->b;
    const size_t n = a->n;
    double *const from[] = {a->x, a->y, a->z, a->ux, a->uy, a->uz, a->ppar, a->mu, a->t};
    double *const to[] = {b->x, b->y, b->z, b->ux, b->uy, b->uz, b->ppar, b->mu, b->t};
    for (size_t k = 0; k < sizeof from / sizeof from[0]; k++)
        memcpy(to[k], from[k], n * sizeof(double));
    memcpy(b->status, a->status, n * sizeof *b->status);
    memcpy(b->steps, a->steps, n * sizeof *b->steps);
    memcpy(b->index, a->index, n * sizeof *b->index);
    b->n = a->n;
    b->n_active = a->n_active;
    b->q = a->q;
    b->m = a->m;
}

int gcp_engine_run(struct gcp_engine *e, struct gcp_results *res, int64_t slice_steps,
                   const volatile int *stop, struct gcp_error *err)
{
    const struct gcp_scene *s = e->s;
    const struct gcp_population *P = &s->pops[e->pop];
    struct gcp_block *b = &e->b;
    struct gcp_observer *obs = e->obs;
    struct gcp_hybrid *hy = e->hy;
    const double t0 = 0.0;
    const int64_t S = res->S, row0 = res->n, count = e->count;
    const int gc = s->pusher->kind == GCP_GUIDING_CENTRE;
    restore(e);
    if (s->fast_arith) b->flags |= GCP_BLOCK_FAST_ARITH; /* [integrator] arithmetic = fast */
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
    struct gcp_sampler sampler = {P->trajectory_every, record, &tc};
    /* method = hybrid: the observer sees each mode's steps through the
     * hybrid's own hook (gcp_hybrid_set_observer), the trajectory keeps
     * its sampler */
    const struct gcp_sampler traj_sampler = sampler;
    struct multi_ctx mc = {obs, e->watch, S ? P->trajectory_every : 0, 0, &tc};
    if (obs || e->watch) sampler = (struct gcp_sampler){1, multi_sample, &mc};
    /* the observer alone (no trajectory or watcher, which count calls):
     * a fused full-orbit step may do its per-step work (issue 12) */
    struct gcp_fo_gyro *gyro = obs && !S && !e->watch && !hy ? gcp_observer_fo_gyro(obs) : NULL;
    gcp_block_start(b, s->field, t0);
    if (hy) gcp_hybrid_begin(hy, b, s->field, t0, e->first);
    if (S) record(b, t0, &tc);
    const int64_t events_before = res->ev.n, scalars_before = res->ev.ns;
    if (obs) {
        /* cadence samples and the stream contour: every sample_every steps of this population */
        gcp_observer_set_sample_dt(obs, (double)s->sample_every * P->dt);
        gcp_observer_begin(obs, b, t0, e->first, &res->ev);
        if (hy) {
            const struct gcp_hybrid_observer ho = {gcp_observer_sample_mode, obs};
            gcp_hybrid_set_observer(hy, &ho);
            gcp_hybrid_observe(hy, b, t0);
        }
    }
    struct gcp_push_opts opts = {.t0 = t0,
                                 .dt = P->dt,
                                 .nsteps = P->nsteps,
                                 .tolerance = s->tolerance,
                                 .adiabaticity_max = gc ? s->adiabaticity_max : 0.0};
    /* The push in slices, so that a stop request (SIGTERM) is answered
     * within a slice, not a whole chunk; a slice is a whole number of
     * trajectory intervals, so samples fall where they would unsliced. */
    const int64_t every = P->trajectory_every;
    const int64_t slice = slice_steps <= 0 ? P->nsteps
                          : every > 0     ? (slice_steps + every - 1) / every * every
                                          : slice_steps;
    const struct gcp_sampler *smp = (S || obs || e->watch) ? &sampler : NULL;
    for (int64_t done = 0; done < P->nsteps && b->n_active > 0;) {
        if (stop && *stop) { /* drop the chunk: its rows and events were never complete */
            res->ev.n = events_before, res->ev.ns = scalars_before;
            return 1;
        }
        opts.t0 = t0 + (double)done * P->dt;
        opts.nsteps = P->nsteps - done < slice ? P->nsteps - done : slice;
        if (hy) gcp_hybrid_advance(hy, b, s->field, &opts, S ? &traj_sampler : NULL);
        else if (gyro) gcp_block_advance_fo_gyro(b, s->field, s->pusher, &opts, smp, gyro);
        else s->pusher->advance(b, s->field, s->pusher, &opts, smp);
        done += opts.nsteps;
    }
    if (obs && gcp_observer_end(obs, b))
        return gcp_error_set(err, GCP_ERR_NOMEM, "out of memory for events");
    if (hy && gcp_hybrid_store(s, hy, b, res, row0))
        return gcp_error_set(err, GCP_ERR_NOMEM, "out of memory for switch events");
    for (size_t i = 0; i < b->n; i++) {
        const int64_t row = row0 + (int64_t)b->index[i];
        res->t[row] = b->t[i];
        res->status[row] = b->status[i];
        /* a STEP_FAILED particle always has a reason (issue 11):
         * UNSPECIFIED where its stepper gave none */
        res->step_failure[row] = b->status[i] != GCP_STEP_FAILED ? GCP_FAIL_NONE
                                 : b->step_failure[i]          ? b->step_failure[i]
                                                               : GCP_FAIL_UNSPECIFIED;
        res->steps[row] = b->steps[i];
        if (hy) continue; /* x, u, X, ppar, mu: gcp_hybrid_store */
        res->x[3 * row] = b->x[i], res->x[3 * row + 1] = b->y[i], res->x[3 * row + 2] = b->z[i];
        if (gc) {
            res->ppar[row] = b->ppar[i];
            res->mu[row] = b->mu[i];
        } else {
            res->u[3 * row] = b->ux[i], res->u[3 * row + 1] = b->uy[i];
            res->u[3 * row + 2] = b->uz[i];
        }
    }
    return 0;
}
