/* Private: a run file split into sections. */
#ifndef GCPUSH_RUN_PRIV_H
#define GCPUSH_RUN_PRIV_H

#include "gcpush/pusher.h"
#include "gcpush/section.h"

struct gcp_run_file {
    const char *path;        /* not owned */
    struct gcp_section *sec;
    size_t nsec, capsec;
};

/* Splits text into sections; returns 0 or a negative code with err set. */
int gcp_run_file_parse(const char *path, const char *text, struct gcp_run_file *rf,
                       struct gcp_error *err);
struct gcp_section *gcp_run_file_section(struct gcp_run_file *rf, const char *name);
void gcp_run_file_free(struct gcp_run_file *rf);

/* Reads a whole file into a NUL-terminated buffer (caller frees). */
int gcp_read_text(const char *path, char **text, struct gcp_error *err);

struct gcp_scene;
/* [integrator] method = hybrid: reads gc, fo, switch_to_fo, switch_to_gc,
 * fo_dt into sc->hybrid_opts (seed from sc->seed) and sets sc->pusher;
 * 0 or a negative code with err set (file, line, key). */
int gcp_scene_hybrid_keys(struct gcp_scene *sc, struct gcp_section *s, struct gcp_error *err);

/* [sweep] (sweep_spec.c): when rf has the section, validates it against
 * the built scene and sets sc->sweep; 0, or a negative code with err set
 * (file, line, key). */
int gcp_sweep_spec_parse(struct gcp_scene *sc, struct gcp_run_file *rf, struct gcp_error *err);

/* A full-orbit state standing for particle id in period estimates
 * (scene_states.c): its own, or for a given guiding centre one at X. */
void gcp_scene_period_state(const struct gcp_scene *s, int64_t id, int *pop, double x[3],
                            double u[3]);

struct gcp_block;
struct gcp_hybrid;
struct gcp_results;
/* The rows [row0, row0 + b->n) of a finished hybrid chunk: final state in
 * both forms (x, u and Xf, ppar, mu), mode, switch count, time in each mode,
 * and the chunk's switches as GCP_EVENT_SWITCH events.  0 or GCP_ERR_NOMEM. */
int gcp_hybrid_store(const struct gcp_scene *s, const struct gcp_hybrid *hy,
                     const struct gcp_block *b, struct gcp_results *res, int64_t row0);

/* ---- the push engine (engine.c) ----------------------------------------
 * What a run does with one chunk (GCP_CHUNK particles of one population):
 * its initial states into a block, the push from them to the end of the
 * population's run (the scene's pusher, dt, steps, tolerance and
 * adiabaticity, its trajectory sampler and invariant observer), and the
 * final rows and events stored.  The driver (gcp_scene_push) and each row
 * of a sweep push through it. */
struct gcp_observer;
struct gcp_engine {
    const struct gcp_scene *s;
    struct gcp_block b;        /* the working block */
    struct gcp_block b0;       /* the loaded start states (each run starts from them) */
    struct gcp_observer *obs;  /* s->invariants or s->events: the observer; else NULL */
    struct gcp_hybrid *hy;     /* method = hybrid; else NULL */
    const struct gcp_sampler *watch; /* (may be NULL) also called at every step */
    int64_t first, count;      /* the loaded particles' ids */
    int pop;                   /* and their population */
};
/* 0, or GCP_ERR_NOMEM with err set. */
int gcp_engine_init(struct gcp_engine *e, const struct gcp_scene *s, struct gcp_error *err);
void gcp_engine_free(struct gcp_engine *e);
/* Loads particles [first, first + count) (one population, count <=
 * GCP_CHUNK) and writes their initial columns to the result rows
 * [res->n, res->n + count), which the caller has reserved. */
void gcp_engine_load(struct gcp_engine *e, struct gcp_results *res, int64_t first, int64_t count);
/* Pushes the loaded particles from their start states to the end of their
 * population's run; their final columns go to rows [res->n, res->n +
 * count) (res->n is left to the caller) and their events are appended to
 * res->ev.  Each call starts again from the loaded states.  slice_steps >
 * 0: the push goes in slices of about that many steps, and a non-zero
 * *stop between two drops the chunk's events and returns 1; slice_steps =
 * 0: one advance over all steps.  0 when done, 1 when stopped, or
 * GCP_ERR_NOMEM with err set. */
int gcp_engine_run(struct gcp_engine *e, struct gcp_results *res, int64_t slice_steps,
                   const volatile int *stop, struct gcp_error *err);

#endif
