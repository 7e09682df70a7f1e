/* gcpush/section.h -- one section of a run file, as read by libinih.
 *
 * Consumers (the scene, each field model) fetch their keys with the typed
 * getters below, which mark a key used and format errors as
 * "FILE:LINE: [section] key: reason".  gcp_section_check_unused() then
 * rejects any key nobody asked for (a typo is an error, not ignored).
 */
#ifndef GCPUSH_SECTION_H
#define GCPUSH_SECTION_H

#include <stddef.h>

#include "error.h"
#include "units.h"
#include "api.h"
GCP_API_BEGIN

#ifdef __cplusplus
extern "C" {
#endif

struct gcp_keyval {
    char *key;
    char *value;
    int line;  /* 1-based line in the run file */
    int used;  /* [bool] fetched by a consumer */
};

struct gcp_section {
    const char *file; /* run file path, for messages (not owned) */
    char *name;       /* "scene", "field", "particles.electrons", ... */
    int line;         /* line of the [header] (0 for an implicit section) */
    size_t n, cap;
    struct gcp_keyval *kv;
};

/* Raw value of key (marks it used), or NULL when absent; *line (may be NULL)
 * receives its line. */
const char *gcp_section_get(struct gcp_section *s, const char *key, int *line);

/* Typed getters.  Each returns 1 when the key was present and parsed, 0 when
 * absent and not required, or a negative error (GCP_ERR_MISSING when absent
 * and required, GCP_ERR_VALUE when the value does not fit), with err set. */
int gcp_section_quantity(struct gcp_section *s, const char *key, enum gcp_quantity q,
                         int required, double *out, struct gcp_error *err);
/* Time quantities that may be given in periods (gyro, bounce, drift). */
int gcp_section_time(struct gcp_section *s, const char *key, int required, double *out,
                     enum gcp_period *period, struct gcp_error *err);
int gcp_section_vector(struct gcp_section *s, const char *key, enum gcp_quantity q,
                       int required, double v[3], struct gcp_error *err);
/* yes/no, true/false, on/off, 1/0. */
int gcp_section_flag(struct gcp_section *s, const char *key, int required, int *out,
                     struct gcp_error *err);
/* A plain string (copied into out, truncated values are an error). */
int gcp_section_string(struct gcp_section *s, const char *key, int required, char *out,
                       size_t outlen, struct gcp_error *err);

/* Formats an error about key of s: "FILE:LINE: [name] key: <fmt...>". */
int gcp_section_error(const struct gcp_section *s, const char *key, struct gcp_error *err,
                      int code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 5, 6)))
#endif
    ;

/* GCP_ERR_UNKNOWN for the first key not fetched, naming it and listing what
 * the section accepts (accepted: "B0 corotation r_outer", for the message). */
int gcp_section_check_unused(const struct gcp_section *s, const char *accepted,
                             struct gcp_error *err);

#ifdef __cplusplus
}
#endif
GCP_API_END
#endif
