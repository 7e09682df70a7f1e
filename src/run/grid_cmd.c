/* `gcpush grid FILE.run`: sample a field model onto a grid file.
 * The run file names the source in [scene] field and [field], the grid in
 * [grid] (gcp_grid_spec_from_section); any other section is an error.
 * This reads the run file into a field and a grid; the io layer samples
 * and writes the file (gcp_grid_command, src/io/grid_file.c). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/grid.h"
#include "gcpush/run.h"
#include "gcpush/section.h"
#include "run_priv.h"

/* ---- [grid] section (moved from fields/grid_io.c: the run layer reads run files) ---- */

static int count_key(struct gcp_section *sec, const char *key, size_t *n, struct gcp_error *err)
{
    double v;
    int rc = gcp_section_quantity(sec, key, GCP_Q_NUMBER, 1, &v, err);
    if (rc < 0) return rc;
    if (!(v >= 5 && v <= 1e8 && v == floor(v)))
        return gcp_section_error(sec, key, err, GCP_ERR_VALUE,
                                 "expected a whole number of nodes >= 5, got %g", v);
    *n = (size_t)v;
    return 0;
}

int gcp_grid_spec_from_section(struct gcp_section *sec, struct gcp_grid_spec *spec, char *path,
                               size_t pathlen, struct gcp_error *err)
{
    char geom[32];
    int rc;
    memset(spec, 0, sizeof *spec);
    if ((rc = gcp_section_string(sec, "geometry", 1, geom, sizeof geom, err)) < 0) return rc;
    if ((rc = gcp_section_string(sec, "file", 1, path, pathlen, err)) < 0) return rc;
    static const char *const axi_keys[2][3] = {{"R_min", "Z_min", NULL}, {"R_max", "Z_max", NULL}};
    static const char *const axi_n[3] = {"nR", "nZ", NULL};
    static const char *const car_keys[2][3] = {{"x_min", "y_min", "z_min"},
                                               {"x_max", "y_max", "z_max"}};
    static const char *const car_n[3] = {"nx", "ny", "nz"};
    const char *const(*keys)[3];
    const char *const *nk;
    int nd;
    if (strcmp(geom, "axisymmetric") == 0) {
        spec->geometry = GCP_GRID_AXISYMMETRIC;
        keys = axi_keys, nk = axi_n, nd = 2;
    } else if (strcmp(geom, "cartesian") == 0) {
        spec->geometry = GCP_GRID_CARTESIAN;
        keys = car_keys, nk = car_n, nd = 3;
    } else {
        return gcp_section_error(sec, "geometry", err, GCP_ERR_VALUE,
                                 "expected axisymmetric or cartesian, got '%s'", geom);
    }
    for (int k = 0; k < nd; k++) {
        if ((rc = gcp_section_quantity(sec, keys[0][k], GCP_Q_LENGTH, 1, &spec->lo[k], err)) < 0)
            return rc;
        if ((rc = gcp_section_quantity(sec, keys[1][k], GCP_Q_LENGTH, 1, &spec->hi[k], err)) < 0)
            return rc;
        if ((rc = count_key(sec, nk[k], &spec->n[k], err)) < 0) return rc;
        if (!(spec->hi[k] > spec->lo[k]))
            return gcp_section_error(sec, keys[1][k], err, GCP_ERR_VALUE,
                                     "must exceed %s = %g m, got %g m", keys[0][k], spec->lo[k],
                                     spec->hi[k]);
    }
    if (nd == 2 && spec->lo[0] < 0.0)
        return gcp_section_error(sec, "R_min", err, GCP_ERR_VALUE, "must be >= 0, got %g m",
                                 spec->lo[0]);
    double t = 0.0;
    if ((rc = gcp_section_quantity(sec, "time", GCP_Q_TIME, 0, &t, err)) < 0) return rc;
    spec->t = t;
    rc = gcp_section_check_unused(
        sec,
        nd == 2 ? "geometry file R_min R_max nR Z_min Z_max nZ time"
                : "geometry file x_min x_max nx y_min y_max ny z_min z_max nz time",
        err);
    return rc < 0 ? rc : 0;
}

int gcp_grid_command_parse(const char *path, const struct gcp_readers *rd,
                           struct gcp_field **field, struct gcp_grid_spec *spec, char *out,
                           size_t outlen, struct gcp_error *err)
{
    *field = NULL;
    char *text;
    int rc = gcp_read_text(path, &text, err);
    if (rc) return rc;
    struct gcp_run_file rf;
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
        if (!rc) rc = gcp_field_from_section_with(model, fs ? fs : &empty, rd, field, err);
        if (!rc) rc = gcp_grid_spec_from_section(gs, spec, out, outlen, err);
    }
    if (rc) {
        gcp_field_free(*field);
        *field = NULL;
    }
    gcp_run_file_free(&rf);
    free(text);
    return rc < 0 ? rc : 0;
}
