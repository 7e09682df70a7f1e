/* The [sweep] section (include/gcpush/sweep.h), read once with the rest of
 * the run file: build_scene (scene.c) calls gcp_sweep_spec_parse last, when
 * the field, the particles and [output] are known.  Every error names file,
 * line and key. */
#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/sweep.h"
#include "run_priv.h"

int gcp_sweep_wanted(const struct gcp_scene *sc)
{
    return sc && sc->sweep != NULL;
}

static int adaptive(const struct gcp_pusher_type *p)
{
    return p->adaptive;
}

static size_t tokens(const char *v, char *buf, size_t buflen, char **tok, size_t max)
{
    snprintf(buf, buflen, "%s", v);
    size_t n = 0;
    for (char *p = strtok(buf, " \t"); p; p = strtok(NULL, " \t")) {
        if (n == max) return max + 1;
        tok[n++] = p;
    }
    return n;
}

static int method_list(struct gcp_section *s, struct gcp_sweep_spec *sp, struct gcp_error *err)
{
    const char *v = gcp_section_get(s, "methods", NULL);
    if (!v)
        return gcp_error_set(err, GCP_ERR_MISSING, "%s:%d: [sweep] methods: required key is missing",
                             s->file, s->line);
    char buf[1024], *tok[GCP_SWEEP_MAX + 1];
    size_t n = tokens(v, buf, sizeof buf, tok, GCP_SWEEP_MAX);
    if (n == 0 || n > GCP_SWEEP_MAX)
        return gcp_section_error(s, "methods", err, GCP_ERR_VALUE,
                                 "expected 1 to %d method names", GCP_SWEEP_MAX);
    for (size_t i = 0; i < n; i++) {
        const struct gcp_pusher_type *p = gcp_pusher_lookup(tok[i]);
        if (!p) {
            char names[512] = "";
            for (const struct gcp_pusher_type *const *q = gcp_pusher_types(); *q; q++) {
                strncat(names, (*q)->name, sizeof names - strlen(names) - 2);
                if (q[1]) strncat(names, " ", sizeof names - strlen(names) - 1);
            }
            return gcp_section_error(s, "methods", err, GCP_ERR_UNKNOWN,
                                     "unknown method '%.40s' (%s)", tok[i], names);
        }
        for (size_t k = 0; k < i; k++)
            if (sp->methods[k] == p)
                return gcp_section_error(s, "methods", err, GCP_ERR_VALUE,
                                         "method '%s' listed twice", p->name);
        sp->methods[i] = p;
    }
    sp->nmethods = n;
    return 0;
}

static int parse_number(const char *t, double *out)
{
    char *end;
    *out = strtod(t, &end);
    return end != t && !*end && isfinite(*out);
}

/* dt = 0.2 0.1 0.05 gyro: numbers, then one unit. */
static int dt_list(struct gcp_section *s, struct gcp_sweep_spec *sp, struct gcp_error *err)
{
    const char *v = gcp_section_get(s, "dt", NULL);
    char buf[1024], *tok[GCP_SWEEP_MAX + 2];
    size_t n = tokens(v, buf, sizeof buf, tok, GCP_SWEEP_MAX + 1);
    if (n < 2 || n > GCP_SWEEP_MAX + 1)
        return gcp_section_error(s, "dt", err, GCP_ERR_VALUE,
                                 "expected 1 to %d steps and one unit after them "
                                 "(e.g. '0.1 0.05 0.025 gyro')", GCP_SWEEP_MAX);
    const char *unit = tok[n - 1];
    snprintf(sp->dt_unit, sizeof sp->dt_unit, "%s", unit);
    for (size_t i = 0; i + 1 < n; i++) {
        double x;
        if (!parse_number(tok[i], &x))
            return gcp_section_error(s, "dt", err, GCP_ERR_VALUE,
                                     "expected a number, got '%.40s' (numbers first, one unit "
                                     "at the end)", tok[i]);
        char q[128], why[256];
        snprintf(q, sizeof q, "%.17g %s", x, unit);
        enum gcp_period per;
        double si;
        if (gcp_parse_quantity(q, GCP_Q_TIME, &si, &per, why, sizeof why))
            return gcp_section_error(s, "dt", err, GCP_ERR_VALUE, "%s", why);
        if (!(si > 0))
            return gcp_section_error(s, "dt", err, GCP_ERR_VALUE, "steps must be > 0");
        sp->dt_given[i] = x;
        sp->dt_value[i] = si;
        sp->dt_period = per;
    }
    sp->ndt = n - 1;
    return 0;
}

static int tol_list(struct gcp_section *s, struct gcp_sweep_spec *sp, struct gcp_error *err)
{
    const char *v = gcp_section_get(s, "tolerance", NULL);
    char buf[1024], *tok[GCP_SWEEP_MAX + 1];
    size_t n = tokens(v, buf, sizeof buf, tok, GCP_SWEEP_MAX);
    if (n == 0 || n > GCP_SWEEP_MAX)
        return gcp_section_error(s, "tolerance", err, GCP_ERR_VALUE,
                                 "expected 1 to %d tolerances", GCP_SWEEP_MAX);
    for (size_t i = 0; i < n; i++) {
        double x;
        if (!parse_number(tok[i], &x) || !(x > 1e-16 && x < 1))
            return gcp_section_error(s, "tolerance", err, GCP_ERR_VALUE,
                                     "expected numbers in 1e-16 .. 1 (no unit), got '%.40s'",
                                     tok[i]);
        sp->tolerance[i] = x;
    }
    sp->ntol = n;
    return 0;
}

/* reference = analytic | METHOD STEP UNIT | METHOD TOLERANCE, METHOD also
 * fo-rk8pd (the full Lorentz equations under GSL rk8pd, not a run method) */
static int reference(const struct gcp_scene *sc, struct gcp_section *s, struct gcp_sweep_spec *sp,
                     struct gcp_error *err)
{
    const char *v = gcp_section_get(s, "reference", NULL);
    if (!v)
        return gcp_error_set(err, GCP_ERR_MISSING,
                             "%s:%d: [sweep] reference: required key is missing (analytic, "
                             "or a method and its step or tolerance, e.g. 'boris-zu 1e-3 gyro')",
                             s->file, s->line);
    char buf[256], *tok[4];
    snprintf(sp->ref_text, sizeof sp->ref_text, "%s", v);
    size_t n = tokens(v, buf, sizeof buf, tok, 3);
    if (n == 1 && strcmp(tok[0], "analytic") == 0) {
        sp->analytic = 1;
        if (!(gcp_field_caps(sc->field) & GCP_CAP_UNIFORM))
            return gcp_section_error(s, "reference", err, GCP_ERR_VALUE,
                                     "no analytic answer in field '%s' (only uniform fields); "
                                     "give a reference method, e.g. 'boris-zu 1e-3 gyro'",
                                     sc->field_model);
        struct gcp_field_sample smp = {.need = GCP_NEED_B | GCP_NEED_E};
        gcp_field_eval(sc->field, 0.0, (double[3]){0, 0, 0}, &smp);
        struct gcp_exact_uniform ex;
        if (gcp_exact_uniform_init(&ex, smp.B, smp.E, 1.0, 1.0))
            return gcp_section_error(s, "reference", err, GCP_ERR_VALUE,
                                     "no analytic answer here: it needs E perpendicular to B "
                                     "and |E| != c|B|");
        return 0;
    }
    if (n < 2 || n > 3)
        return gcp_section_error(s, "reference", err, GCP_ERR_VALUE,
                                 "expected 'analytic', 'METHOD STEP UNIT' or 'METHOD TOLERANCE', "
                                 "got '%.60s'", v);
    sp->ref_method = strcmp(tok[0], gcp_pusher_fo_rk8pd.name) == 0 ? &gcp_pusher_fo_rk8pd
                                                                    : gcp_pusher_lookup(tok[0]);
    if (!sp->ref_method)
        return gcp_section_error(s, "reference", err, GCP_ERR_UNKNOWN,
                                 "unknown method '%.40s' (a method, or fo-rk8pd: the full "
                                 "Lorentz equations under GSL rk8pd)", tok[0]);
    if (adaptive(sp->ref_method)) {
        double x;
        if (n != 2 || !parse_number(tok[1], &x) || !(x > 1e-16 && x < 1))
            return gcp_section_error(s, "reference", err, GCP_ERR_VALUE,
                                     "adaptive method '%s' takes a tolerance in 1e-16 .. 1 "
                                     "(e.g. '%s 1e-12')", tok[0], tok[0]);
        sp->ref_tolerance = x;
        return 0;
    }
    char q[128], why[256];
    snprintf(q, sizeof q, "%s %s", tok[1], n == 3 ? tok[2] : "");
    if (n != 3 || gcp_parse_quantity(q, GCP_Q_TIME, &sp->ref_dt_given, &sp->ref_period, why,
                                     sizeof why) ||
        !(sp->ref_dt_given > 0))
        return gcp_section_error(s, "reference", err, GCP_ERR_VALUE,
                                 "fixed-step method '%s' takes a step with its unit "
                                 "(e.g. '%s 1e-3 gyro')", tok[0], tok[0]);
    return 0;
}

static int parse_section(const struct gcp_scene *sc, struct gcp_run_file *rf,
                         struct gcp_section *s, struct gcp_sweep_spec *sp, struct gcp_error *err)
{
    int rc;
    if ((rc = method_list(s, sp, err))) return rc;
    for (size_t i = 0; i < sp->nmethods; i++) {
        char why[512];
        const struct gcp_pusher_type *p = sp->methods[i];
        if (p->applies && p->applies(sc->field, why, sizeof why))
            return gcp_section_error(s, "methods", err, GCP_ERR_VALUE,
                                     "method '%s' cannot run in the %s field: %s", p->name,
                                     sc->field->type->name, why);
    }
    int nfixed = 0, nadapt = 0;
    for (size_t i = 0; i < sp->nmethods; i++) *(adaptive(sp->methods[i]) ? &nadapt : &nfixed) += 1;
    const int hasdt = gcp_section_get(s, "dt", NULL) != NULL;
    const int hastol = gcp_section_get(s, "tolerance", NULL) != NULL;
    if (nfixed && !hasdt)
        return gcp_error_set(err, GCP_ERR_MISSING,
                             "%s:%d: [sweep] dt: required for the fixed-step methods "
                             "(e.g. dt = 0.1 0.05 0.025 gyro)", s->file, s->line);
    if (!nfixed && hasdt)
        return gcp_section_error(s, "dt", err, GCP_ERR_VALUE,
                                 "no fixed-step method in methods: give tolerance only");
    if (nadapt && !hastol)
        return gcp_error_set(err, GCP_ERR_MISSING,
                             "%s:%d: [sweep] tolerance: required for the adaptive methods "
                             "(e.g. tolerance = 1e-6 1e-8 1e-10)", s->file, s->line);
    if (!nadapt && hastol)
        return gcp_section_error(s, "tolerance", err, GCP_ERR_VALUE,
                                 "tolerance applies only to adaptive methods (gc-rk45, gc-rk8pd)");
    if (hasdt && (rc = dt_list(s, sp, err))) return rc;
    if (hastol && (rc = tol_list(s, sp, err))) return rc;
    if ((rc = reference(sc, s, sp, err))) return rc;
    int64_t rep = 3;
    const char *v = gcp_section_get(s, "repeats", NULL);
    if (v) {
        char *end;
        rep = strtoll(v, &end, 10);
        while (isspace((unsigned char)*end)) end++;
        if (end == v || *end || rep < 1 || rep > 20)
            return gcp_section_error(s, "repeats", err, GCP_ERR_VALUE,
                                     "expected a whole number in 1 .. 20");
    }
    sp->repeats = (int)rep;
    if ((rc = gcp_section_check_unused(s, "methods dt tolerance reference repeats", err)))
        return rc;
    if (sc->total > GCP_SWEEP_MAX_PARTICLES)
        return gcp_error_set(err, GCP_ERR_VALUE,
                             "%s: [sweep]: %lld particles: a sweep takes at most %d (one particle "
                             "or a small ensemble)", sc->path, (long long)sc->total,
                             GCP_SWEEP_MAX_PARTICLES);
    if (sc->trajectory_samples) {
        struct gcp_section *o = gcp_run_file_section(rf, "output");
        return gcp_section_error(o, "trajectory", err, GCP_ERR_VALUE,
                                 "a sweep writes no trajectories: set 'none' or remove the key");
    }
    return 0;
}

int gcp_sweep_spec_parse(struct gcp_scene *sc, struct gcp_run_file *rf, struct gcp_error *err)
{
    struct gcp_section *s = gcp_run_file_section(rf, "sweep");
    if (!s) return 0;
    if (!(sc->sweep = calloc(1, sizeof *sc->sweep)))
        return gcp_error_set(err, GCP_ERR_NOMEM, "out of memory");
    return parse_section(sc, rf, s, sc->sweep, err);
}
