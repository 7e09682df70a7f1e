/* Private: a run file split into sections. */
#ifndef GCPUSH_RUN_PRIV_H
#define GCPUSH_RUN_PRIV_H

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

struct gcp_block;
struct gcp_hybrid;
struct gcp_results;
/* The rows [row0, row0 + b->n) of a finished hybrid chunk: final state in
 * both forms (x, u and Xf, ppar, mu), mode, switch count, time in each mode,
 * and the chunk's switches as GCP_EVENT_SWITCH events.  0 or GCP_ERR_NOMEM. */
int gcp_hybrid_store(const struct gcp_scene *s, const struct gcp_hybrid *hy,
                     const struct gcp_block *b, struct gcp_results *res, int64_t row0);

#endif
