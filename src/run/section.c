/* Typed access to one run-file section; every key fetched is marked used so
 * that leftovers (typos) are reported as unknown keys. */
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <strings.h>

#include "gcpush/section.h"

static struct gcp_keyval *find(struct gcp_section *s, const char *key)
{
    for (size_t i = 0; i < s->n; i++)
        if (strcmp(s->kv[i].key, key) == 0) return &s->kv[i];
    return NULL;
}

static int key_line(const struct gcp_section *s, const char *key)
{
    for (size_t i = 0; i < s->n; i++)
        if (strcmp(s->kv[i].key, key) == 0) return s->kv[i].line;
    return s->line;
}

int gcp_section_error(const struct gcp_section *s, const char *key, struct gcp_error *err,
                      int code, const char *fmt, ...)
{
    char what[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    return gcp_error_set(err, code, "%s:%d: [%s] %s: %s", s->file ? s->file : "(run)",
                         key_line(s, key), s->name ? s->name : "", key, what);
}

const char *gcp_section_get(struct gcp_section *s, const char *key, int *line)
{
    struct gcp_keyval *kv = s ? find(s, key) : NULL;
    if (!kv) return NULL;
    kv->used = 1;
    if (line) *line = kv->line;
    return kv->value;
}

static const char *fetch(struct gcp_section *s, const char *key, int required,
                         struct gcp_error *err, int *rc)
{
    const char *v = gcp_section_get(s, key, NULL);
    *rc = 1;
    if (!v) {
        if (required) {
            *rc = gcp_error_set(err, GCP_ERR_MISSING, "%s:%d: [%s] %s: required key is missing",
                                s && s->file ? s->file : "(run)", s ? s->line : 0,
                                s && s->name ? s->name : "", key);
        } else {
            *rc = 0;
        }
    }
    return v;
}

int gcp_section_quantity(struct gcp_section *s, const char *key, enum gcp_quantity q,
                         int required, double *out, struct gcp_error *err)
{
    int rc;
    const char *v = fetch(s, key, required, err, &rc);
    if (!v) return rc;
    char why[256];
    enum gcp_period period = GCP_PERIOD_NONE;
    if (gcp_parse_quantity(v, q, out, &period, why, sizeof why))
        return gcp_section_error(s, key, err, GCP_ERR_VALUE, "%s", why);
    if (period != GCP_PERIOD_NONE)
        return gcp_section_error(s, key, err, GCP_ERR_VALUE,
                                 "periods (gyro, bounce, drift) are not accepted here");
    return 1;
}

int gcp_section_time(struct gcp_section *s, const char *key, int required, double *out,
                     enum gcp_period *period, struct gcp_error *err)
{
    int rc;
    const char *v = fetch(s, key, required, err, &rc);
    if (!v) return rc;
    char why[256];
    if (gcp_parse_quantity(v, GCP_Q_TIME, out, period, why, sizeof why))
        return gcp_section_error(s, key, err, GCP_ERR_VALUE, "%s", why);
    return 1;
}

int gcp_section_vector(struct gcp_section *s, const char *key, enum gcp_quantity q,
                       int required, double v[3], struct gcp_error *err)
{
    int rc;
    const char *t = fetch(s, key, required, err, &rc);
    if (!t) return rc;
    char why[256];
    if (gcp_parse_vector(t, q, v, why, sizeof why))
        return gcp_section_error(s, key, err, GCP_ERR_VALUE, "%s", why);
    return 1;
}

int gcp_section_flag(struct gcp_section *s, const char *key, int required, int *out,
                     struct gcp_error *err)
{
    int rc;
    const char *v = fetch(s, key, required, err, &rc);
    if (!v) return rc;
    static const char *yes[] = {"yes", "true", "on", "1"}, *no[] = {"no", "false", "off", "0"};
    for (int i = 0; i < 4; i++) {
        if (strcasecmp(v, yes[i]) == 0) { *out = 1; return 1; }
        if (strcasecmp(v, no[i]) == 0) { *out = 0; return 1; }
    }
    return gcp_section_error(s, key, err, GCP_ERR_VALUE, "expected yes or no, got '%.40s'", v);
}

int gcp_section_string(struct gcp_section *s, const char *key, int required, char *out,
                       size_t outlen, struct gcp_error *err)
{
    int rc;
    const char *v = fetch(s, key, required, err, &rc);
    if (!v) return rc;
    if (strlen(v) >= outlen)
        return gcp_section_error(s, key, err, GCP_ERR_VALUE, "value longer than %zu characters",
                                 outlen - 1);
    memcpy(out, v, strlen(v) + 1);
    return 1;
}

int gcp_section_check_unused(const struct gcp_section *s, const char *accepted,
                             struct gcp_error *err)
{
    for (size_t i = 0; i < s->n; i++)
        if (!s->kv[i].used)
            return gcp_error_set(err, GCP_ERR_UNKNOWN, "%s:%d: [%s] %s: unknown key (accepted: %s)",
                                 s->file ? s->file : "(run)", s->kv[i].line, s->name,
                                 s->kv[i].key, accepted);
    return 0;
}
