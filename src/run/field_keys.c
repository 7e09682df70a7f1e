/* The [field] section of a run file -> a field model (issue 12).
 *
 * Each model declares its run-file keys in a table on its type (name, kind,
 * unit, required or default, doc: struct gcp_field_key in field.h).  This
 * file, in the run layer, reads those keys with their units, rejects keys
 * the model does not declare, and hands the plain SI values to the model's
 * `build`, which validates them and constructs the field; a build error
 * about one key (args->bad_key) is given that key's file and line here.
 * So fields/ never calls up into the run-file reader, nor into the io
 * layer: a file the model needs (a grid's) comes through the reader the
 * caller handed in (struct gcp_readers, run.h). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/field.h"
#include "gcpush/run.h"
#include "gcpush/section.h"

/* Reads the model's keys into args (defaults where absent). */
static int read_keys(const struct gcp_field_type *t, struct gcp_section *sec,
                     struct gcp_field_args *a, struct gcp_error *err)
{
    for (int k = 0; k < GCP_FIELD_MAX_KEYS && t->keys[k].name; k++) {
        const struct gcp_field_key *key = &t->keys[k];
        int rc = 0, flag = 0;
        memcpy(a->v[k], key->def, sizeof a->v[k]);
        snprintf(a->text[k], sizeof a->text[k], "%s", key->def_text ? key->def_text : "");
        switch (key->kind) {
        case GCP_KEY_QUANTITY:
            rc = gcp_section_quantity(sec, key->name, (enum gcp_quantity)key->quantity,
                                      key->required, &a->v[k][0], err);
            break;
        case GCP_KEY_VECTOR:
            rc = gcp_section_vector(sec, key->name, (enum gcp_quantity)key->quantity,
                                    key->required, a->v[k], err);
            break;
        case GCP_KEY_FLAG:
            rc = gcp_section_flag(sec, key->name, key->required, &flag, err);
            if (rc > 0) a->v[k][0] = flag != 0;
            break;
        case GCP_KEY_STRING:
            rc = gcp_section_string(sec, key->name, key->required, a->text[k], sizeof a->text[k],
                                    err);
            break;
        default:
            return gcp_error_set(err, GCP_ERR_STATE, "field %s: key %s of unknown kind %d",
                                 t->name, key->name, key->kind);
        }
        if (rc < 0) return rc;
        a->given[k] = rc > 0;
    }
    return 0;
}

static int build_from(const struct gcp_field_type *t, struct gcp_section *sec,
                      struct gcp_field_args *a, struct gcp_field **out, struct gcp_error *err);

int gcp_field_from_section(const char *model, struct gcp_section *sec, struct gcp_field **out,
                           struct gcp_error *err)
{
    return gcp_field_from_section_with(model, sec, NULL, out, err);
}

int gcp_field_from_section_with(const char *model, struct gcp_section *sec,
                                const struct gcp_readers *rd, struct gcp_field **out,
                                struct gcp_error *err)
{
    if (!out) return gcp_error_set(err, GCP_ERR_STATE, "gcp_field_from_section: out is NULL");
    *out = NULL;
    if (!sec) return gcp_error_set(err, GCP_ERR_STATE, "gcp_field_from_section: no [field] section");
    const struct gcp_field_type *t = gcp_field_type_lookup(model);
    if (!t || !t->keys || !t->build) {
        /* The model name comes from [scene] field = ..., whose line the
         * caller knows; name the [field] section so the user finds the run. */
        char names[256];
        return gcp_error_set(err, GCP_ERR_UNKNOWN,
                             "%s:%d: [%s] unknown field model '%.60s' (expected one of: %s)",
                             sec->file ? sec->file : "(run)", sec->line,
                             sec->name ? sec->name : "field", model ? model : "(none)",
                             gcp_field_model_names(names, sizeof names));
    }
    struct gcp_field_args *a = calloc(1, sizeof *a); /* 8 kB of text: not on the stack */
    if (!a) return gcp_error_set(err, GCP_ERR_NOMEM, "field %s: out of memory", t->name);
    a->bad_key = -1;
    a->grid_read = rd ? rd->grid : NULL;
    int rc = build_from(t, sec, a, out, err);
    free(a);
    return rc;
}

static int build_from(const struct gcp_field_type *t, struct gcp_section *sec,
                      struct gcp_field_args *a, struct gcp_field **out, struct gcp_error *err)
{
    int rc = read_keys(t, sec, a, err);
    if (rc < 0) return rc;
    char accepted[256] = "";
    for (int k = 0; k < GCP_FIELD_MAX_KEYS && t->keys[k].name; k++) {
        const size_t used = strlen(accepted);
        snprintf(accepted + used, sizeof accepted - used, "%s%s", k ? " " : "", t->keys[k].name);
    }
    if ((rc = gcp_section_check_unused(sec, accepted, err)) < 0) return rc;
    struct gcp_error e2 = {0, ""};
    rc = t->build(a, out, &e2);
    if (rc < 0) {
        /* builds construct the field last; this only guards one that forgets */
        gcp_field_free(*out);
        *out = NULL;
        if (a->bad_key >= 0 && a->bad_key < GCP_FIELD_MAX_KEYS)
            return gcp_section_error(sec, t->keys[a->bad_key].name, err, rc, "%s", e2.msg);
        return gcp_error_set(err, rc, "%s", e2.msg);
    }
    return 0;
}
