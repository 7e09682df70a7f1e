/* `gcpush grid FILE.run`: sample a field model onto a grid file.
 * The run file names the source in [scene] field and [field], the grid in
 * [grid] (gcp_grid_spec_from_section); any other section is an error. */
#include <stdlib.h>
#include <string.h>

#include "gcpush/grid.h"
#include "gcpush/run.h"
#include "run_priv.h"

int gcp_grid_command(const char *path, char *out, size_t outlen, struct gcp_error *err)
{
    char *text;
    int rc = gcp_read_text(path, &text, err);
    if (rc) return rc;
    struct gcp_run_file rf;
    struct gcp_field *field = NULL;
    rc = gcp_run_file_parse(path, text, &rf, err);
    if (!rc) {
        for (size_t i = 0; i < rf.nsec && !rc; i++) {
            const char *n = rf.sec[i].name;
            if (strcmp(n, "scene") && strcmp(n, "field") && strcmp(n, "grid"))
                rc = gcp_error_set(err, GCP_ERR_UNKNOWN,
                                   "%s:%d: [%s]: unknown section in a grid file (scene, field, grid)",
                                   path, rf.sec[i].line, n);
        }
        struct gcp_section *sc = gcp_run_file_section(&rf, "scene");
        struct gcp_section *gs = gcp_run_file_section(&rf, "grid");
        struct gcp_section *fs = gcp_run_file_section(&rf, "field");
        struct gcp_section empty = {.file = path, .name = "field"};
        char model[32], name[64];
        if (!rc && (!sc || !gs))
            rc = gcp_error_set(err, GCP_ERR_MISSING, "%s: [%s] section is missing", path,
                               sc ? "grid" : "scene");
        if (!rc && (rc = gcp_section_string(sc, "field", 1, model, sizeof model, err)) > 0) rc = 0;
        if (!rc && (rc = gcp_section_string(sc, "name", 0, name, sizeof name, err)) >= 0) rc = 0;
        if (!rc) rc = gcp_section_check_unused(sc, "name field", err);
        if (!rc && !gcp_field_type_lookup(model))
            rc = gcp_section_error(sc, "field", err, GCP_ERR_UNKNOWN, "unknown field model '%s'",
                                   model);
        if (!rc) rc = gcp_field_from_section(model, fs ? fs : &empty, &field, err);
        struct gcp_grid_spec spec;
        if (!rc) rc = gcp_grid_spec_from_section(gs, &spec, out, outlen, err);
        if (!rc) rc = gcp_grid_sample(field, &spec, out, err);
    }
    gcp_field_free(field);
    gcp_run_file_free(&rf);
    free(text);
    return rc < 0 ? rc : 0;
}
