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

#endif
