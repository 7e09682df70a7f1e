/* Error against run time: the rows of a sweep (include/gcpush/sweep.h).
 *
 * For each population, each method and each step (tolerance): the row's
 * scene is the run file's with that method, step and tolerance, and its
 * population is pushed through the push engine of every run (engine.c:
 * the same start from the initial states, the same block push, the same
 * invariant observer), timed with CLOCK_PROCESS_CPUTIME_ID (best of
 * `repeats` batches while a push takes under 0.2 s), and its final states
 * are compared with the analytic answer (uniform fields) or with a
 * reference push (sweep_measure.c).  Each finished row goes to the
 * caller's sink (sweep_output.c: the table, /sweep).  A row pushes without
 * slices (nothing asks it to stop) and without the adiabaticity check (it
 * measures the method's error, which a NONADIABATIC stop would hide).
 *
 * Gyrophase error.  Uniform fields, analytic reference, full-orbit method:
 * the method is pushed once more with a watcher on every step that
 * measures the gyrophase of u in the drift frame (gcp_exact_uniform_phase)
 * and accumulates its per-step change, each taken in (-pi, pi]: the
 * rotation the method actually performed, so the error is not folded
 * modulo 2 pi.  Where the exact rotation per step |omega dt| exceeds pi the
 * samples cannot tell k turns apart and the error is the final difference
 * wrapped to (-pi, pi].
 *
 * Invariants (sweep_measure.c): where the field has bounce or drift
 * motion, each configuration and the reference are pushed once more,
 * untimed, with the invariant observer on every step. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "gcpush/gc.h"
#include "gcpush/results.h"
#include "gcpush/kernels.h"
#include "run_priv.h"
#include "sweep_priv.h"

static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* ---- initial states and steps ------------------------------------------ */

static void states_free(struct gcp_sweep_states *st)
{
    free(st->x0);
    free(st->u0);
    free(st->X0);
    free(st->ppar0);
    free(st->mu0);
    free(st->gc_ok);
    memset(st, 0, sizeof *st);
}

/* The population's initial states as the engine makes them (for the step
 * in periods and the error measures). */
static int states_make(const struct gcp_scene *sc, const struct gcp_population *pop,
                       struct gcp_sweep_states *st)
{
    const size_t n = (size_t)pop->count;
    memset(st, 0, sizeof *st);
    st->n = n;
    st->x0 = malloc(3 * n * sizeof(double));
    st->u0 = malloc(3 * n * sizeof(double));
    st->X0 = malloc(3 * n * sizeof(double));
    st->ppar0 = malloc(n * sizeof(double));
    st->mu0 = malloc(n * sizeof(double));
    st->gc_ok = malloc(n * sizeof(int32_t));
    if (!st->x0 || !st->u0 || !st->X0 || !st->ppar0 || !st->mu0 || !st->gc_ok) {
        states_free(st);
        return GCP_ERR_NOMEM;
    }
    for (size_t j = 0; j < n; j++) {
        int pi;
        gcp_scene_initial_state(sc, pop->first_id + (int64_t)j, &pi, &st->x0[3 * j], &st->u0[3 * j]);
        st->gc_ok[j] = gcp_gc_from_fo(sc->field, 0.0, pop->species.charge, pop->species.mass,
                                      &st->x0[3 * j], &st->u0[3 * j], &st->X0[3 * j],
                                      &st->ppar0[j], &st->mu0[j]) == 0;
    }
    return 0;
}

/* Resolves a step in periods against the population (gyro: the shortest
 * initial gyro period in it; bounce, drift: its first particle). */
static int step_seconds(const struct gcp_scene *sc, const struct gcp_population *pop,
                        const struct gcp_sweep_states *st, double given, enum gcp_period per,
                        double *dt)
{
    if (per == GCP_PERIOD_NONE) {
        *dt = given;
        return 0;
    }
    double Tmin = INFINITY;
    const size_t last = per == GCP_PERIOD_GYRO ? st->n : 1;
    for (size_t j = 0; j < last; j++) {
        double T;
        if (gcp_period_of(sc->field, sc->field_model, &pop->species, &st->x0[3 * j],
                          &st->u0[3 * j], per, &T))
            return GCP_ERR_VALUE;
        Tmin = fmin(Tmin, T);
    }
    *dt = given * Tmin;
    return 0;
}

/* Whole steps that end at the duration exactly. */
static int fit_steps(double T, double *dt, int64_t *nsteps)
{
    const double steps = ceil(T / *dt * (1.0 - 1e-12));
    if (!(steps <= 1e10)) return GCP_ERR_VALUE;
    *nsteps = steps < 1 ? 1 : (int64_t)steps;
    *dt = T / (double)*nsteps;
    return 0;
}

/* ---- pushes through the engine ------------------------------------------ */

/* The accumulated gyrophase of every particle of a population (uniform
 * fields): the engine's watcher, called at every step. */
struct phase_track {
    const struct gcp_exact_uniform *ex;
    size_t j0;           /* population index of lane index 0 of the pushed chunk */
    double *last, *acc;  /* per particle: the last phase and the accumulated change */
};

static void phase_watch(const struct gcp_block *b, double t, void *ctx)
{
    (void)t;
    struct phase_track *pt = ctx;
    for (size_t i = 0; i < b->n_active; i++) {
        const size_t j = pt->j0 + b->index[i];
        const double u[3] = {b->ux[i], b->uy[i], b->uz[i]};
        const double ph = gcp_exact_uniform_phase(pt->ex, u);
        pt->acc[j] += remainder(ph - pt->last[j], 2.0 * GCP_PI);
        pt->last[j] = ph;
    }
}

/* One push of a population: the method, its step and steps (o.dt,
 * o.nsteps) and tolerance (o.tolerance), the observer on `evts` events (0:
 * none), the gyrophase watcher pt (or NULL), and timing repeats (0:
 * untimed). */
struct pass {
    const struct gcp_pusher_type *p;
    struct gcp_push_opts o;
    unsigned evts;
    struct phase_track *pt;
    int repeats;
};

/* Pushes population k of sc as pass ps asks, through the engine of a run
 * of the scene with that method, step, tolerance and observer.  The finals
 * go to out (out->cpu: the push's CPU seconds, the best of the batches when
 * ps->repeats > 0); with ps->evts, the invariant measures to inv.  0, or a
 * negative code with err set. */
static int push_pass(const struct gcp_scene *sc, size_t k, const struct pass *ps,
                     struct gcp_sweep_finals *out, struct gcp_sweep_inv *inv,
                     struct gcp_error *err)
{
    const struct gcp_population *pop = &sc->pops[k];
    /* the row's scene: sc with this method, step, tolerance and observer */
    struct gcp_scene rs = *sc;
    struct gcp_population *pops = malloc(sc->npop * sizeof *pops);
    if (!pops) return gcp_error_set(err, GCP_ERR_NOMEM, "out of memory");
    memcpy(pops, sc->pops, sc->npop * sizeof *pops);
    for (size_t q = 0; q < sc->npop; q++) pops[q].trajectory_every = 0;
    pops[k].dt = ps->o.dt;
    pops[k].nsteps = ps->o.nsteps;
    rs.pops = pops;
    rs.pusher = ps->p;
    rs.hybrid = 0;
    rs.tolerance = ps->o.tolerance;
    rs.adiabaticity_max = 0.0;
    rs.invariants = 0;
    rs.events = ps->evts;
    rs.trajectory_samples = 0;
    const int gc = ps->p->kind == GCP_GUIDING_CENTRE;
    struct gcp_engine e;
    struct gcp_results res;
    gcp_results_init(&res, 0, gc);
    int rc = gcp_engine_init(&e, &rs, err);
    if (rc) {
        free(pops);
        return rc;
    }
    struct gcp_sampler watch = {1, phase_watch, ps->pt};
    if (ps->pt) e.watch = &watch;
    out->gc = gc;
    out->steps = 0;
    out->cpu = 0.0;
    for (int64_t first = pop->first_id; first < pop->first_id + pop->count && !rc;
         first += GCP_CHUNK) {
        const int64_t left = pop->first_id + pop->count - first;
        const int64_t cnt = left < GCP_CHUNK ? left : GCP_CHUNK;
        if (gcp_results_reserve(&res, cnt)) {
            rc = gcp_error_set(err, GCP_ERR_NOMEM, "out of memory");
            break;
        }
        gcp_engine_load(&e, &res, first, cnt);
        if (ps->pt) ps->pt->j0 = (size_t)(first - pop->first_id);
        /* One push to size the samples; short pushes are timed in batches
         * of k pushes of at least 2 ms together (timer noise), and the best
         * of `repeats` batches is kept; pushes over 0.2 s are timed once. */
        const double c0 = cpu_now();
        rc = gcp_engine_run(&e, &res, 0, NULL, err);
        const double c1 = cpu_now() - c0;
        double best = c1;
        if (!rc && ps->repeats > 0 && c1 <= 0.2) {
            const int nk = c1 >= 2e-3 ? 1 : c1 > 2e-6 ? (int)ceil(2e-3 / c1) : 1000;
            best = INFINITY;
            for (int r = 0; r < ps->repeats && !rc; r++) {
                const double b0 = cpu_now();
                for (int i = 0; i < nk && !rc; i++) rc = gcp_engine_run(&e, &res, 0, NULL, err);
                best = fmin(best, (cpu_now() - b0) / nk);
            }
        }
        out->cpu += best;
        for (int64_t i = 0; i < cnt; i++) {
            const int64_t row = res.n + i;
            const size_t j = (size_t)(res.id[row] - pop->first_id);
            memcpy(&out->x[3 * j], &res.x[3 * row], 3 * sizeof(double));
            if (gc) {
                out->u[3 * j] = res.ppar[row];
                out->u[3 * j + 1] = out->u[3 * j + 2] = 0.0;
            } else {
                memcpy(&out->u[3 * j], &res.u[3 * row], 3 * sizeof(double));
            }
            out->status[j] = res.status[row];
            out->steps += res.steps[row];
        }
        res.n += cnt;
    }
    if (!rc && ps->evts && gcp_sweep_inv_stats(&res.ev, pop->first_id, (size_t)pop->count, inv))
        rc = gcp_error_set(err, GCP_ERR_NOMEM, "out of memory");
    gcp_engine_free(&e);
    gcp_results_free(&res);
    free(pops);
    return rc;
}

/* ---- the sweep ----------------------------------------------------------- */

/* Per population: its initial states, the reference's and a row's finals,
 * gyrophases and invariant measures. */
struct pop_work {
    struct gcp_sweep_states st;
    struct gcp_sweep_finals ref, run, aux; /* aux: the finals of untimed passes */
    double *ref_phase, *run_phase, *p0, *last, *acc;
    struct gcp_sweep_inv *ref_inv, *run_inv;
};

static void work_free(struct pop_work *w)
{
    states_free(&w->st);
    struct gcp_sweep_finals *f[] = {&w->ref, &w->run, &w->aux};
    for (int i = 0; i < 3; i++) free(f[i]->x), free(f[i]->u), free(f[i]->status);
    double *d[] = {w->ref_phase, w->run_phase, w->p0, w->last, w->acc};
    for (size_t i = 0; i < sizeof d / sizeof d[0]; i++) free(d[i]);
    free(w->ref_inv);
    free(w->run_inv);
    memset(w, 0, sizeof *w);
}

static int work_make(const struct gcp_scene *sc, const struct gcp_population *pop,
                     struct pop_work *w)
{
    memset(w, 0, sizeof *w);
    if (states_make(sc, pop, &w->st)) return GCP_ERR_NOMEM;
    const size_t n = w->st.n;
    int bad = 0;
    struct gcp_sweep_finals *f[] = {&w->ref, &w->run, &w->aux};
    for (int i = 0; i < 3; i++) {
        f[i]->x = calloc(3 * n, sizeof(double));
        f[i]->u = calloc(3 * n, sizeof(double));
        f[i]->status = calloc(n, sizeof(int32_t));
        bad |= !f[i]->x || !f[i]->u || !f[i]->status;
    }
    double **d[] = {&w->ref_phase, &w->run_phase, &w->p0, &w->last, &w->acc};
    for (size_t i = 0; i < sizeof d / sizeof d[0]; i++) bad |= !(*d[i] = malloc(n * sizeof(double)));
    bad |= !(w->ref_inv = malloc(n * sizeof *w->ref_inv));
    bad |= !(w->run_inv = malloc(n * sizeof *w->run_inv));
    if (bad) {
        work_free(w);
        return GCP_ERR_NOMEM;
    }
    return 0;
}

/* The reference of population k: the exact motion (analytic) or a push of
 * the reference method, and its invariant measures (evts). */
static int reference(const struct gcp_scene *sc, const struct gcp_sweep_spec *spec, size_t k,
                     struct gcp_exact_uniform *ex, unsigned evts, struct pop_work *w,
                     double *wmax, FILE *progress, struct gcp_error *err)
{
    const struct gcp_population *pop = &sc->pops[k];
    const struct gcp_sweep_states *st = &w->st;
    const double T = sc->duration;
    if (spec->analytic) {
        /* the uniform field's B and E */
        struct gcp_field_sample lab = {.need = GCP_NEED_B | GCP_NEED_E};
        gcp_field_eval(sc->field, 0.0, (double[3]){0, 0, 0}, &lab);
        if (gcp_exact_uniform_init(ex, lab.B, lab.E, pop->species.charge, pop->species.mass))
            return gcp_error_set(err, GCP_ERR_VALUE, "%s: [sweep] reference: no analytic answer",
                                 sc->path);
        for (size_t j = 0; j < st->n; j++) {
            w->ref.status[j] = gcp_exact_uniform_state(ex, &st->x0[3 * j], &st->u0[3 * j], T,
                                                       &w->ref.x[3 * j], &w->ref.u[3 * j],
                                                       &w->ref_phase[j])
                                   ? GCP_NONFINITE
                                   : GCP_ALIVE;
            if (ex->regime == 1)
                *wmax = fmax(*wmax, fabs(gcp_exact_uniform_omega(ex, &st->u0[3 * j])));
        }
        return 0;
    }
    struct pass ps = {spec->ref_method, {.t0 = 0.0, .tolerance = spec->ref_tolerance}, 0, NULL, 0};
    if (spec->ref_method->adaptive) {
        ps.o.dt = pop->dt, ps.o.nsteps = pop->nsteps;
    } else if (step_seconds(sc, pop, st, spec->ref_dt_given, spec->ref_period, &ps.o.dt) ||
               fit_steps(T, &ps.o.dt, &ps.o.nsteps)) {
        return gcp_error_set(err, GCP_ERR_VALUE,
                             "%s: [sweep] reference: cannot resolve the step for [%s] "
                             "(no such period, or more than 1e10 steps)", sc->path, pop->name);
    }
    if (progress)
        fprintf(progress, "sweep: [%s] reference %s ...\n", pop->name,
                spec->analytic ? "analytic" : spec->ref_text);
    int rc = push_pass(sc, k, &ps, &w->ref, NULL, err);
    ps.evts = evts;
    if (!rc && evts) /* the invariants: a separate pass with the observer */
        rc = push_pass(sc, k, &ps, &w->aux, w->ref_inv, err);
    return rc;
}

/* One row: method p at step (or tolerance) ci of the spec on population k. */
static int one_row(const struct gcp_scene *sc, const struct gcp_sweep_spec *spec, size_t k,
                   const struct gcp_pusher_type *p, size_t ci, struct gcp_exact_uniform *ex,
                   unsigned evts, double wmax, struct pop_work *w, struct gcp_sweep_row *row,
                   struct gcp_error *err)
{
    const struct gcp_population *pop = &sc->pops[k];
    const struct gcp_sweep_states *st = &w->st;
    memset(row, 0, sizeof *row);
    snprintf(row->method, sizeof row->method, "%s", p->name);
    snprintf(row->population, sizeof row->population, "%s", pop->name);
    struct pass ps = {p, {.t0 = 0.0}, 0, NULL, spec->repeats};
    if (p->adaptive) {
        ps.o.dt = pop->dt, ps.o.nsteps = pop->nsteps, ps.o.tolerance = spec->tolerance[ci];
        row->tolerance = ps.o.tolerance;
        row->dt_given = NAN;
        snprintf(row->dt_unit, sizeof row->dt_unit, "-");
    } else {
        row->tolerance = NAN;
        row->dt_given = spec->dt_given[ci];
        snprintf(row->dt_unit, sizeof row->dt_unit, "%s", spec->dt_unit);
        if (step_seconds(sc, pop, st, spec->dt_value[ci], spec->dt_period, &ps.o.dt) ||
            fit_steps(sc->duration, &ps.o.dt, &ps.o.nsteps))
            return gcp_error_set(err, GCP_ERR_VALUE,
                                 "%s: [sweep] dt: cannot resolve %g %s for [%s] (no such "
                                 "period, or more than 1e10 steps)", sc->path,
                                 spec->dt_given[ci], spec->dt_unit, pop->name);
    }
    row->dt = ps.o.dt;
    row->particles = (int64_t)st->n;
    int rc = push_pass(sc, k, &ps, &w->run, NULL, err);
    if (rc) return rc;
    row->cpu_seconds = w->run.cpu;
    row->steps = w->run.steps;
    /* untimed passes (finals in aux: the row compares the timed push's) */
    struct pass un = ps;
    un.repeats = 0;
    /* the accumulated gyrophase (uniform fields, full orbit) */
    int use_phase = 0, wrapped = 0;
    if (spec->analytic && ex->regime == 1 && p->kind == GCP_FULL_ORBIT) {
        use_phase = 1;
        wrapped = wmax * ps.o.dt > GCP_PI;
        for (size_t j = 0; j < st->n; j++) {
            w->p0[j] = w->last[j] = gcp_exact_uniform_phase(ex, &st->u0[3 * j]);
            w->acc[j] = 0.0;
        }
        struct phase_track pt = {ex, 0, w->last, w->acc};
        un.pt = &pt;
        if ((rc = push_pass(sc, k, &un, &w->aux, NULL, err))) return rc;
        un.pt = NULL;
        for (size_t j = 0; j < st->n; j++)
            w->run_phase[j] = wrapped ? w->last[j] : w->p0[j] + w->acc[j];
    }
    /* the invariants: a separate, untimed pass with the observer */
    if (evts) {
        un.evts = evts;
        if ((rc = push_pass(sc, k, &un, &w->aux, w->run_inv, err))) return rc;
    }
    gcp_sweep_compare(sc, pop, st, &w->run, &w->ref, use_phase ? w->ref_phase : NULL,
                      use_phase ? w->run_phase : NULL, wrapped, evts ? w->run_inv : NULL,
                      evts && !spec->analytic ? w->ref_inv : NULL, row);
    return 0;
}

int gcp_sweep_run(const struct gcp_scene *sc, const struct gcp_sweep_sink *sink, FILE *progress,
                  struct gcp_error *err)
{
    const struct gcp_sweep_spec *spec = sc->sweep;
    if (!spec) return gcp_error_set(err, GCP_ERR_STATE, "%s: no [sweep] section", sc->path);
    /* the invariant observer's events in this field (0: none) */
    const unsigned evts = gcp_sweep_events(sc->field);
    int rc = 0;
    for (size_t k = 0; k < sc->npop && !rc; k++) {
        const struct gcp_population *pop = &sc->pops[k];
        struct pop_work w;
        if (work_make(sc, pop, &w)) return gcp_error_set(err, GCP_ERR_NOMEM, "out of memory");
        struct gcp_exact_uniform ex;
        memset(&ex, 0, sizeof ex);
        double wmax = 0.0; /* largest |omega| in the drift frame */
        rc = reference(sc, spec, k, &ex, evts, &w, &wmax, progress, err);
        for (size_t mi = 0; mi < spec->nmethods && !rc; mi++) {
            const struct gcp_pusher_type *p = spec->methods[mi];
            const size_t ncfg = p->adaptive ? spec->ntol : spec->ndt;
            for (size_t ci = 0; ci < ncfg && !rc; ci++) {
                struct gcp_sweep_row row;
                rc = one_row(sc, spec, k, p, ci, &ex, evts, wmax, &w, &row, err);
                if (!rc && (rc = sink->row(sink->ctx, &row)) < 0 && !err->code)
                    gcp_error_set(err, rc, "%s: [sweep]: the row sink failed", sc->path);
                if (!rc && progress)
                    fprintf(progress, "sweep: [%s] %-12s %s %-10.4g %.3g s CPU, error %.3g m\n",
                            pop->name, p->name, p->adaptive ? "tol" : "dt ",
                            p->adaptive ? row.tolerance : row.dt, row.cpu_seconds,
                            row.position_error);
            }
        }
        work_free(&w);
    }
    return rc;
}
