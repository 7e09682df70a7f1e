/* Sections -> a validated, resolved scene; initial states from (seed, id). */
#include <ctype.h>
#include <errno.h>
#include <stdint.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "gcpush/kernels.h"
#include "gcpush/run.h"
#include "run_priv.h"

/* ---- value parsing ------------------------------------------------------ */

/* "a .. b [lin|log]" or "a".  Quantities carry their unit on each side. */
static int get_range(struct gcp_section *s, const char *key, enum gcp_quantity q, int required,
                     struct gcp_range *r, struct gcp_error *err)
{
    const char *v = gcp_section_get(s, key, NULL);
    if (!v) {
        if (!required) return 0;
        return gcp_error_set(err, GCP_ERR_MISSING, "%s:%d: [%s] %s: required key is missing",
                             s->file, s->line, s->name, key);
    }
    char buf[256], why[256];
    if (strlen(v) >= sizeof buf)
        return gcp_section_error(s, key, err, GCP_ERR_VALUE, "value too long");
    strcpy(buf, v);
    char *dots = strstr(buf, "..");
    if (!dots) {
        r->spread = GCP_FIXED;
        if (gcp_parse_quantity(buf, q, &r->lo, NULL, why, sizeof why))
            return gcp_section_error(s, key, err, GCP_ERR_VALUE, "%s", why);
        r->hi = r->lo;
        return 1;
    }
    *dots = '\0';
    char *rhs = dots + 2;
    r->spread = GCP_LIN;
    size_t n = strlen(rhs);
    while (n && isspace((unsigned char)rhs[n - 1])) rhs[--n] = '\0';
    if (n >= 3 && (strcmp(rhs + n - 3, "lin") == 0 || strcmp(rhs + n - 3, "log") == 0) &&
        (n == 3 || isspace((unsigned char)rhs[n - 4]))) {
        r->spread = rhs[n - 2] == 'o' ? GCP_LOG : GCP_LIN;
        rhs[n - 3] = '\0';
    }
    if (gcp_parse_quantity(buf, q, &r->lo, NULL, why, sizeof why) ||
        gcp_parse_quantity(rhs, q, &r->hi, NULL, why, sizeof why))
        return gcp_section_error(s, key, err, GCP_ERR_VALUE, "%s (a range is 'a .. b [lin|log]')",
                                 why);
    if (!(r->hi > r->lo))
        return gcp_section_error(s, key, err, GCP_ERR_VALUE, "range must have a < b");
    if (r->spread == GCP_LOG && !(r->lo > 0))
        return gcp_section_error(s, key, err, GCP_ERR_VALUE, "a log range needs a > 0");
    return 1;
}

static int get_count(struct gcp_section *s, const char *key, int required, int64_t lo, int64_t hi,
                     int64_t *out, struct gcp_error *err)
{
    const char *v = gcp_section_get(s, key, NULL);
    if (!v && !required) return 0;
    if (!v)
        return gcp_error_set(err, GCP_ERR_MISSING, "%s:%d: [%s] %s: required key is missing",
                             s->file, s->line, s->name, key);
    char *end;
    errno = 0;
    long long n = strtoll(v, &end, 10);
    while (isspace((unsigned char)*end)) end++;
    if (end == v || *end || errno)
        return gcp_section_error(s, key, err, GCP_ERR_VALUE, "expected a whole number, got '%.40s'",
                                 v);
    if (n < lo || n > hi)
        return gcp_section_error(s, key, err, GCP_ERR_VALUE, "must be in %lld .. %lld, got %lld",
                                 (long long)lo, (long long)hi, n);
    *out = n;
    return 1;
}

static int positive(struct gcp_section *s, const char *key, double v, struct gcp_error *err)
{
    if (!(v > 0))
        return gcp_section_error(s, key, err, GCP_ERR_VALUE, "must be > 0");
    return 0;
}

/* ---- sections ----------------------------------------------------------- */

/* A population whose states come from a file: the keys that would draw
 * them are refused (a silent winner between two sources would be a guess);
 * `count` may stay as a check and must then match the file's rows
 * (checked in read_state_files, once the file is read). */
static int file_population(struct gcp_section *s, struct gcp_population *p, struct gcp_error *err)
{
    static const char *const drawn[] = {"energy", "L", "longitude", "position", "pitch",
                                        "phase", "direction", NULL};
    for (const char *const *k = drawn; *k; k++)
        if (gcp_section_get(s, *k, NULL))
            return gcp_section_error(s, *k, err, GCP_ERR_VALUE,
                                     "conflicts with file = %s (the initial states come from "
                                     "the file; leave out energy, L, longitude, position, "
                                     "pitch, phase, direction)", p->file);
    int rc = get_count(s, "count", 0, 1, 1000000000, &p->count, err);
    if (rc < 0) return rc;
    if (rc == 0) p->count = -1; /* from the file */
    return gcp_section_check_unused(s, "species charge mass count file", err);
}

static int load_population(struct gcp_scene *sc, struct gcp_section *s, struct gcp_population *p,
                           struct gcp_error *err)
{
    int rc;
    const char *dot = strchr(s->name, '.');
    snprintf(p->name, sizeof p->name, "%s", dot ? dot + 1 : "particles");
    char species[32];
    if ((rc = gcp_section_string(s, "species", 1, species, sizeof species, err)) < 0) return rc;
    if (strcmp(species, "custom") == 0) {
        snprintf(p->species.name, sizeof p->species.name, "%s", p->name);
        if ((rc = gcp_section_quantity(s, "charge", GCP_Q_CHARGE, 1, &p->species.charge, err)) < 0 ||
            (rc = gcp_section_quantity(s, "mass", GCP_Q_MASS, 1, &p->species.mass, err)) < 0)
            return rc;
        if (p->species.charge == 0)
            return gcp_section_error(s, "charge", err, GCP_ERR_VALUE, "must be non-zero");
        if ((rc = positive(s, "mass", p->species.mass, err))) return rc;
    } else if (gcp_species_lookup(species, &p->species)) {
        return gcp_section_error(s, "species", err, GCP_ERR_UNKNOWN,
                                 "unknown species '%s' (proton, electron, alpha, O+, custom)",
                                 species);
    }
    if ((rc = gcp_section_string(s, "file", 0, p->file, sizeof p->file, err)) < 0) return rc;
    if (p->file[0]) return file_population(s, p, err);
    if ((rc = get_count(s, "count", 1, 1, 1000000000, &p->count, err)) < 0) return rc;
    if ((rc = get_range(s, "energy", GCP_Q_ENERGY, 1, &p->energy, err)) < 0) return rc;
    if (!(p->energy.lo > 0))
        return gcp_section_error(s, "energy", err, GCP_ERR_VALUE, "kinetic energy must be > 0");
    /* An energy whose momentum overflows a double starts every particle with
     * a non-finite u; it was found only as "no gyro period" and blamed on
     * duration or dt.  |u| as the sampler forms it, and |u|^2 as the pushers
     * form gamma from it, must be finite at both ends of the range. */
    {
        const double mc2 = p->species.mass * GCP_C_LIGHT * GCP_C_LIGHT;
        const double W[2] = {p->energy.lo, p->energy.hi};
        for (int i = 0; i < 2; i++) {
            const double umag = sqrt(W[i] * (W[i] + 2.0 * mc2)) / (p->species.mass * GCP_C_LIGHT);
            if (!isfinite(umag * umag))
                return gcp_section_error(
                    s, "energy", err, GCP_ERR_VALUE,
                    "%g eV is beyond what double precision can carry for a %s (gamma = %g: "
                    "the momentum squared overflows, so gamma and the gyro period are not "
                    "finite)",
                    W[i] / GCP_E_CHARGE, p->species.name, 1.0 + W[i] / mc2);
        }
    }

    /* Where: an L shell range (dipole) or one position. */
    int hasL = (rc = get_range(s, "L", GCP_Q_NUMBER, 0, &p->L, err));
    if (rc < 0) return rc;
    int hasPos = (rc = gcp_section_vector(s, "position", GCP_Q_LENGTH, 0, p->position, err));
    if (rc < 0) return rc;
    if (hasL == hasPos)
        return gcp_section_error(s, hasL ? "L" : "position", err, hasL ? GCP_ERR_VALUE : GCP_ERR_MISSING,
                                 "give exactly one of L (dipole shells) or position");
    if (hasL) {
        const struct gcp_field_type *ft = gcp_field_type_lookup(sc->field_model);
        if (!ft || !(ft->caps & GCP_CAP_DIPOLE_L))
            return gcp_section_error(s, "L", err, GCP_ERR_VALUE,
                                     "L shells need field = dipole (use position otherwise)");
        if (!(p->L.lo > 1.0))
            return gcp_section_error(s, "L", err, GCP_ERR_VALUE, "L must be > 1");
        p->placement = GCP_PLACE_L_SHELL;
        p->longitude = (struct gcp_range){0.0, 2.0 * GCP_PI, GCP_LIN};
        if ((rc = get_range(s, "longitude", GCP_Q_ANGLE, 0, &p->longitude, err)) < 0) return rc;
    } else {
        p->placement = GCP_PLACE_POSITION;
        /* below the field's loss boundary (dipole, igrf: R_E + atmosphere)
         * every particle PRECIPITATES at step 0; at r = 0 the dipole's
         * gyro period is ~1e-24 s and the fault surfaced as one on dt */
        const double *x = p->position;
        const double r = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
        const double ri = sc->field->r_inner;
        if (ri > 0.0 && r < ri)
            return gcp_section_error(s, "position", err, GCP_ERR_VALUE,
                                     "r = %g m is inside the atmosphere of field '%s' (r < "
                                     "r_inner = %g m = R_E + %g km): the particle would "
                                     "precipitate at once",
                                     r, sc->field_model, ri, (ri - GCP_EARTH_RADIUS) / 1e3);
    }

    /* Which way: a direction, or a pitch angle (value, range, isotropic). */
    int hasDir = (rc = gcp_section_vector(s, "direction", GCP_Q_NUMBER, 0, p->direction, err));
    if (rc < 0) return rc;
    int hasPitch = gcp_section_get(s, "pitch", NULL) != NULL;
    if (hasDir == hasPitch)
        return gcp_section_error(s, hasDir ? "direction" : "pitch", err,
                                 hasDir ? GCP_ERR_VALUE : GCP_ERR_MISSING,
                                 "give exactly one of direction (unit vector) or pitch "
                                 "(angle, range, or isotropic)");
    if (hasDir) {
        p->aim = GCP_AIM_DIRECTION;
        double n = sqrt(p->direction[0] * p->direction[0] + p->direction[1] * p->direction[1] +
                        p->direction[2] * p->direction[2]);
        if (!(n > 0))
            return gcp_section_error(s, "direction", err, GCP_ERR_VALUE, "must be non-zero");
        for (int i = 0; i < 3; i++) p->direction[i] /= n;
    } else {
        const char *v = gcp_section_get(s, "pitch", NULL);
        if (strcmp(v, "isotropic") == 0) {
            p->aim = GCP_AIM_ISOTROPIC;
        } else {
            p->aim = GCP_AIM_PITCH;
            if ((rc = get_range(s, "pitch", GCP_Q_ANGLE, 1, &p->pitch, err)) < 0) return rc;
            if (p->pitch.spread == GCP_LOG)
                return gcp_section_error(s, "pitch", err, GCP_ERR_VALUE, "a pitch range is lin");
            if (p->pitch.lo < 0 || p->pitch.hi > GCP_PI)
                return gcp_section_error(s, "pitch", err, GCP_ERR_VALUE,
                                         "pitch angles lie in 0 .. 180 deg");
        }
        if ((rc = gcp_section_quantity(s, "phase", GCP_Q_ANGLE, 0, &p->phase, err)) < 0) return rc;
        p->has_phase = rc;
    }
    return gcp_section_check_unused(
        s, "species charge mass count energy L longitude position direction pitch phase file", err);
}

/* trajectory = none | every N steps | N samples (evenly over the run). */
static int parse_trajectory(struct gcp_section *s, int64_t *every, int64_t *samples,
                            struct gcp_error *err)
{
    const char *v = gcp_section_get(s, "trajectory", NULL);
    *every = *samples = 0;
    if (!v || strcmp(v, "none") == 0) return 0;
    long long n;
    char unit[16];
    int used = 0;
    if (sscanf(v, "every %lld %15s %n", &n, unit, &used) == 2 && !v[used] && n >= 1 &&
        (strcmp(unit, "steps") == 0 || strcmp(unit, "step") == 0)) {
        *every = n;
        return 0;
    }
    used = 0;
    if (sscanf(v, "%lld %15s %n", &n, unit, &used) == 2 && !v[used] && n >= 2 &&
        strcmp(unit, "samples") == 0) {
        *samples = n;
        return 0;
    }
    return gcp_section_error(s, "trajectory", err, GCP_ERR_VALUE,
                             "expected 'none', 'every N steps' (N >= 1) or 'N samples' (N >= 2), "
                             "got '%.40s'", v);
}

/* A list of words, each one of names[] (bit k for names[k]); empty or
 * "none": no bits.  A word twice is allowed (and means the same). */
static int parse_words(struct gcp_section *s, const char *key, const char *const *names,
                       unsigned *bits, struct gcp_error *err)
{
    *bits = 0;
    const char *v = gcp_section_get(s, key, NULL);
    if (!v) return 0;
    char buf[256];
    if (strlen(v) >= sizeof buf)
        return gcp_section_error(s, key, err, GCP_ERR_VALUE, "value too long");
    strcpy(buf, v);
    char list[128] = "";
    for (size_t k = 0; names[k]; k++) {
        strcat(list, k ? " " : "");
        strcat(list, names[k]);
    }
    int nwords = 0, none = 0;
    for (char *w = strtok(buf, " \t,"); w; w = strtok(NULL, " \t,")) {
        nwords++;
        if (strcmp(w, "none") == 0) {
            none = 1;
            continue;
        }
        size_t k = 0;
        while (names[k] && strcmp(names[k], w) != 0) k++;
        if (!names[k])
            return gcp_section_error(s, key, err, GCP_ERR_VALUE,
                                     "unknown word '%.32s' (any of: %s; or none)", w, list);
        *bits |= 1u << k;
    }
    if (none && nwords > 1)
        return gcp_section_error(s, key, err, GCP_ERR_VALUE, "'none' goes alone");
    return 1;
}

static const char *const known_sections[] = {"scene", "field", "integrator", "diagnostics",
                                             "output", "sweep", NULL};

static int check_sections(struct gcp_run_file *rf, struct gcp_error *err)
{
    for (size_t i = 0; i < rf->nsec; i++) {
        const char *n = rf->sec[i].name;
        int ok = strcmp(n, "particles") == 0 || strncmp(n, "particles.", 10) == 0;
        for (const char *const *k = known_sections; !ok && *k; k++) ok = strcmp(n, *k) == 0;
        if (!ok)
            return gcp_error_set(err, GCP_ERR_UNKNOWN,
                                 "%s:%d: [%s]: unknown section (scene, field, particles, "
                                 "particles.NAME, integrator, diagnostics, output, sweep)",
                                 rf->path, rf->sec[i].line, n);
    }
    static const char *const required[] = {"scene", "integrator", "output", NULL};
    for (const char *const *k = required; *k; k++)
        if (!gcp_run_file_section(rf, *k))
            return gcp_error_set(err, GCP_ERR_MISSING, "%s: [%s] section is missing", rf->path,
                                 *k);
    return 0;
}

/* Reads the states of every population with a `file` key (its count is
 * the file's), then numbers the particles: ids are consecutive across the
 * populations in file order. */
static int read_state_files(struct gcp_scene *sc, struct gcp_run_file *rf,
                            const struct gcp_readers *rd, struct gcp_error *err)
{
    const int gc = sc->pusher->kind == GCP_GUIDING_CENTRE;
    size_t k = 0;
    for (size_t i = 0; i < rf->nsec; i++) {
        if (strncmp(rf->sec[i].name, "particles", 9) != 0) continue;
        struct gcp_section *s = &rf->sec[i];
        struct gcp_population *p = &sc->pops[k++];
        if (p->file[0]) {
            char why[1200] = "";
            if (!rd || !rd->states)
                return gcp_section_error(s, "file", err, GCP_ERR_VALUE,
                                         "this program reads no files of initial states "
                                         "(gcp_scene_load_with)");
            if (gcp_run_file_section(rf, "sweep"))
                return gcp_section_error(s, "file", err, GCP_ERR_VALUE,
                                         "a [sweep] draws its particles from the keys; "
                                         "initial states from a file are for runs");
            if (rd->states(p->file, gc, &p->init, why, sizeof why))
                return gcp_section_error(s, "file", err, GCP_ERR_IO, "%s", why);
            if (p->init.gc != gc || p->init.n < 1)
                return gcp_section_error(s, "file", err, GCP_ERR_STATE,
                                         "%s: the reader returned no usable states", p->file);
            if (p->count >= 0 && p->count != p->init.n)
                return gcp_section_error(s, "count", err, GCP_ERR_VALUE,
                                         "is %lld, but %s holds %lld initial states (leave "
                                         "count out: the file sets it)",
                                         (long long)p->count, p->file, (long long)p->init.n);
            p->count = p->init.n;
        }
        p->first_id = sc->total;
        sc->total += p->count;
    }
    return 0;
}

static const char *period_name(enum gcp_period p)
{
    return p == GCP_PERIOD_GYRO ? "gyro" : p == GCP_PERIOD_BOUNCE ? "bounce" : "drift";
}

/* The duration in periods is that of the scene's first particle. */
static int resolve_duration(struct gcp_scene *sc, struct gcp_section *s, struct gcp_error *err)
{
    if (sc->duration_period == GCP_PERIOD_NONE) {
        sc->duration = sc->duration_given;
        return 0;
    }
    int pop;
    double x[3], u[3], T;
    gcp_scene_period_state(sc, 0, &pop, x, u);
    if (gcp_period_of(sc->field, sc->field_model, &sc->pops[pop].species, x, u,
                      sc->duration_period, &T))
        return gcp_section_error(s, "duration", err, GCP_ERR_VALUE,
                                 "the first particle has no %s period in field '%s' "
                                 "(give the time in s, ms, us)",
                                 period_name(sc->duration_period), sc->field_model);
    sc->duration = sc->duration_given * T;
    return 0;
}

/* A step in periods resolves against the shortest initial period in the
 * population (every particle then has at least that resolution): gyro
 * periods over all its particles, bounce and drift periods over its first
 * 1000. */
/* [output] file must name a file that is not the run file: found only at
 * the rename, after the whole run, an empty name or a directory lost the
 * run; the run file itself was replaced by the output. */
static int check_output_path(struct gcp_section *s, const struct gcp_scene *sc,
                             struct gcp_error *err)
{
    const char *o = sc->output;
    const char *base = strrchr(o, '/') ? strrchr(o, '/') + 1 : o;
    struct stat so, sr;
    if (!*o) return gcp_section_error(s, "file", err, GCP_ERR_VALUE, "empty: name the output file");
    if (!*base || strcmp(base, ".") == 0 || strcmp(base, "..") == 0 ||
        (stat(o, &so) == 0 && S_ISDIR(so.st_mode)))
        return gcp_section_error(s, "file", err, GCP_ERR_VALUE,
                                 "'%s' is a directory: name the output file", o);
    if (strcmp(o, sc->path) == 0 ||
        (stat(o, &so) == 0 && stat(sc->path, &sr) == 0 && so.st_dev == sr.st_dev &&
         so.st_ino == sr.st_ino))
        return gcp_section_error(s, "file", err, GCP_ERR_VALUE,
                                 "'%s' is the run file itself: name another output file", o);
    return 0;
}

static int resolve_dt(struct gcp_scene *sc, struct gcp_population *p, struct gcp_section *s,
                      struct gcp_error *err)
{
    if (sc->dt_period == GCP_PERIOD_NONE) {
        p->dt = sc->dt_given;
        return 0;
    }
    /* bounce and drift periods cost two quadratures each: the first 1000
     * particles (random draws) stand for the population */
    const int64_t scan = sc->dt_period == GCP_PERIOD_GYRO ? p->count
                         : p->count < 1000            ? p->count
                                                      : 1000;
    const int64_t last = p->first_id + scan;
    double Tmin = INFINITY;
    for (int64_t id = p->first_id; id < last; id++) {
        int pop;
        double x[3], u[3], T;
        gcp_scene_period_state(sc, id, &pop, x, u);
        /* a non-finite row of a file ends NONFINITE at the start: it has no say */
        if (p->file[0] && !(isfinite(x[0] + x[1] + x[2]) && isfinite(u[0] + u[1] + u[2])))
            continue;
        if (gcp_period_of(sc->field, sc->field_model, &p->species, x, u, sc->dt_period, &T))
            return gcp_section_error(s, "dt", err, GCP_ERR_VALUE,
                                     "particle %lld of [particles%s%s] has no %s period in "
                                     "field '%s' (give dt in s, ms, us)",
                                     (long long)id, strcmp(p->name, "particles") ? "." : "",
                                     strcmp(p->name, "particles") ? p->name : "",
                                     period_name(sc->dt_period), sc->field_model);
        Tmin = fmin(Tmin, T);
    }
    p->dt = sc->dt_given * Tmin;
    return 0;
}

static int build_scene(struct gcp_scene *sc, struct gcp_run_file *rf,
                       const struct gcp_readers *rd, struct gcp_error *err)
{
    int rc;
    if ((rc = check_sections(rf, err))) return rc;

    struct gcp_section *s = gcp_run_file_section(rf, "scene");
    if ((rc = gcp_section_string(s, "name", 1, sc->name, sizeof sc->name, err)) < 0 ||
        (rc = gcp_section_string(s, "field", 1, sc->field_model, sizeof sc->field_model, err)) < 0 ||
        (rc = gcp_section_time(s, "duration", 1, &sc->duration_given, &sc->duration_period, err)) < 0)
        return rc;
    if ((rc = positive(s, "duration", sc->duration_given, err))) return rc;
    int64_t seed = 0;
    if ((rc = get_count(s, "seed", 0, 0, INT64_MAX, &seed, err)) < 0) return rc;
    sc->seed = (uint64_t)seed;
    if ((rc = gcp_section_check_unused(s, "name field duration seed", err))) return rc;

    /* The field: a missing [field] section is an empty one (models with all
     * keys optional, like the dipole, need none). */
    struct gcp_section empty = {.file = rf->path, .name = "field"};
    struct gcp_section *fs = gcp_run_file_section(rf, "field");
    char names[256];
    if (!gcp_field_type_lookup(sc->field_model))
        return gcp_section_error(s, "field", err, GCP_ERR_UNKNOWN,
                                 "unknown field model '%s' (%s)", sc->field_model,
                                 gcp_field_model_names(names, sizeof names));
    if ((rc = gcp_field_from_section_with(sc->field_model, fs ? fs : &empty, rd, &sc->field,
                                          err)) < 0)
        return rc;

    /* Populations in file order; ids are consecutive across them. */
    for (size_t i = 0; i < rf->nsec; i++)
        if (strncmp(rf->sec[i].name, "particles", 9) == 0) sc->npop++;
    if (sc->npop == 0)
        return gcp_error_set(err, GCP_ERR_MISSING, "%s: no [particles] section", rf->path);
    if (!(sc->pops = calloc(sc->npop, sizeof *sc->pops)))
        return gcp_error_set(err, GCP_ERR_NOMEM, "out of memory");
    size_t k = 0;
    for (size_t i = 0; i < rf->nsec; i++) {
        if (strncmp(rf->sec[i].name, "particles", 9) != 0) continue;
        if ((rc = load_population(sc, &rf->sec[i], &sc->pops[k++], err)) < 0) return rc;
    }

    s = gcp_run_file_section(rf, "integrator");
    char method[32];
    if ((rc = gcp_section_string(s, "method", 1, method, sizeof method, err)) < 0) return rc;
    /* gc-vi was renamed (issue 11): it is a midpoint scheme with exact p_phi,
     * neither variational nor symplectic.  No silent alias: a run file that
     * asked for a variational integrator learns what it gets instead. */
    if (strcmp(method, "gc-vi") == 0)
        return gcp_section_error(s, "method", err, GCP_ERR_UNKNOWN,
                                 "gc-vi is gone: it was not a variational integrator; use "
                                 "gc-gl2 or gc-gl4 (symplectic, exact p_phi) or "
                                 "gc-midpoint-pphi (the same scheme under its honest name)");
    if (strcmp(method, "hybrid") == 0) {
        if ((rc = gcp_scene_hybrid_keys(sc, s, err)) < 0) return rc;
    } else if (!(sc->pusher = gcp_pusher_lookup(method))) {
        char names[512];
        gcp_pusher_names(names, sizeof names);
        return gcp_section_error(s, "method", err, GCP_ERR_UNKNOWN,
                                 "unknown method '%s' (%s, hybrid)",
                                 method, names);
    }
    /* A method that cannot push in this field is refused here, before any
     * particle runs (never a run in which every particle fails). */
    char why[512];
    if (sc->pusher->applies && sc->pusher->applies(sc->field, why, sizeof why))
        return gcp_section_error(s, "method", err, GCP_ERR_VALUE,
                                 "method '%s' cannot run in the %s field: %s", method,
                                 sc->field->type->name, why);
    if ((rc = gcp_section_time(s, "dt", 1, &sc->dt_given, &sc->dt_period, err)) < 0) return rc;
    if ((rc = positive(s, "dt", sc->dt_given, err))) return rc;
    /* adaptive methods: dt is the first trial step, tolerance the error per step */
    if ((rc = gcp_section_quantity(s, "tolerance", GCP_Q_NUMBER, 0, &sc->tolerance, err)) < 0)
        return rc;
    /* hybrid: the tolerance is its guiding-centre method's */
    const struct gcp_pusher_type *stepper = sc->hybrid ? sc->hybrid_opts.gc : sc->pusher;
    if (rc == 1 && !stepper->adaptive)
        return gcp_section_error(s, "tolerance", err, GCP_ERR_VALUE,
                                 "method '%s' has a fixed step: tolerance applies only to "
                                 "adaptive methods (gc-rk45, gc-rk8pd)", stepper->name);
    if (rc == 1 && !(sc->tolerance > 0 && sc->tolerance < 1))
        return gcp_section_error(s, "tolerance", err, GCP_ERR_VALUE, "must lie in (0, 1)");
    /* Guiding-centre validity: first-order guiding-centre theory has O(eps)
     * relative errors, eps = rho |grad B| / B; at eps = 0.1 a drift is off by
     * ~10% and a 10 MeV proton at L = 4 is at the edge, so 0.1 is the default
     * threshold (a particle past it ends NONADIABATIC; push it with a
     * full-orbit method instead). */
    sc->adiabaticity_max = sc->pusher->kind == GCP_GUIDING_CENTRE ? 0.1 : 0.0;
    if ((rc = gcp_section_quantity(s, "adiabaticity", GCP_Q_NUMBER, 0, &sc->adiabaticity_max,
                                   err)) < 0)
        return rc;
    if (rc == 1 && sc->pusher->kind != GCP_GUIDING_CENTRE)
        return gcp_section_error(s, "adiabaticity", err, GCP_ERR_VALUE,
                                 sc->hybrid ? "method = hybrid switches at switch_to_fo and "
                                              "switch_to_gc instead"
                                            : "applies only to guiding-centre methods (gc-*)");
    if (rc == 1 && !(sc->adiabaticity_max >= 0))
        return gcp_section_error(s, "adiabaticity", err, GCP_ERR_VALUE,
                                 "must be >= 0 (0: no check)");
    /* arithmetic = ieee (the default: every root and division IEEE rounded)
     * or fast (opt-in, full orbit: pusher.h GCP_BLOCK_FAST_ARITH) */
    char arith[16];
    if ((rc = gcp_section_string(s, "arithmetic", 0, arith, sizeof arith, err)) < 0) return rc;
    if (rc == 1) {
        if (strcmp(arith, "fast") != 0 && strcmp(arith, "ieee") != 0)
            return gcp_section_error(s, "arithmetic", err, GCP_ERR_VALUE,
                                     "expected ieee or fast, got '%s'", arith);
        sc->fast_arith = strcmp(arith, "fast") == 0;
        if (sc->fast_arith && (sc->hybrid || sc->pusher->kind != GCP_FULL_ORBIT))
            return gcp_section_error(s, "arithmetic", err, GCP_ERR_VALUE,
                                     "fast applies only to full-orbit methods (boris)");
    }
    if ((rc = gcp_section_check_unused(s, sc->hybrid ? "method dt tolerance gc fo switch_to_fo "
                                                       "switch_to_gc fo_dt arithmetic"
                                                     : "method dt tolerance adiabaticity arithmetic",
                                       err)))
        return rc;
    /* the method's kind says which states a file must hold: read them now */
    if ((rc = read_state_files(sc, rf, rd, err))) return rc;

    s = gcp_run_file_section(rf, "diagnostics");
    sc->sample_every = GCP_OBSERVER_SAMPLE_STEPS;
    if (s) {
        static const char *const inv_names[] = {"mu", "J", "K", "L", "energy", "pphi", NULL};
        static const char *const evt_names[] = {"bounce", "drift", "loss", NULL};
        if ((rc = parse_words(s, "invariants", inv_names, &sc->invariants, err)) < 0 ||
            (rc = parse_words(s, "events", evt_names, &sc->events, err)) < 0)
            return rc;
        /* the cadence of /invariants/samples and of the stream's drift contour
         * (invariants.h, sample_dt), in steps of each population's dt */
        if ((rc = get_count(s, "sample_every", 0, 1, 1000000000, &sc->sample_every, err)) < 0)
            return rc;
        if ((rc = gcp_section_check_unused(s, "invariants events sample_every", err))) return rc;
    }

    s = gcp_run_file_section(rf, "output");
    if ((rc = gcp_section_string(s, "file", 1, sc->output, sizeof sc->output, err)) < 0) return rc;
    if ((rc = check_output_path(s, sc, err))) return rc;
    int64_t traj_every, traj_samples;
    if ((rc = parse_trajectory(s, &traj_every, &traj_samples, err))) return rc;
    if ((rc = gcp_section_quantity(s, "checkpoint", GCP_Q_TIME, 0, &sc->checkpoint_every, err)) < 0)
        return rc;
    if (rc == 1 && !(sc->checkpoint_every > 0))
        return gcp_section_error(s, "checkpoint", err, GCP_ERR_VALUE, "must be > 0");
    /* trajectories: shuffle + deflate at this level (default 1: ~1.7x smaller
     * orbits for ~10x the write time of plain bytes -- still far below the
     * push time of any run worth its trajectories); none for raw speed */
    sc->compression = 1;
    const char *cv = gcp_section_get(s, "compression", NULL);
    if (cv) {
        char *end;
        const long lvl = strtol(cv, &end, 10);
        if (strcmp(cv, "none") == 0) sc->compression = 0;
        else if (end != cv && !*end && lvl >= 1 && lvl <= 9) sc->compression = (int)lvl;
        else
            return gcp_section_error(s, "compression", err, GCP_ERR_VALUE,
                                     "expected none or a deflate level 1..9, got '%.40s'", cv);
    }
    if ((rc = gcp_section_check_unused(s, "file trajectory checkpoint compression", err))) return rc;

    struct gcp_section *ss = gcp_run_file_section(rf, "scene");
    struct gcp_section *is = gcp_run_file_section(rf, "integrator");
    if ((rc = resolve_duration(sc, ss, err))) return rc;
    for (size_t k = 0; k < sc->npop; k++) {
        struct gcp_population *p = &sc->pops[k];
        if ((rc = resolve_dt(sc, p, is, err))) return rc;
        /* The run ends at `duration` exactly: dt shrinks by less than one step. */
        const double steps = ceil(sc->duration / p->dt * (1.0 - 1e-12));
        if (!(steps <= 1e13))
            return gcp_section_error(is, "dt", err, GCP_ERR_VALUE,
                                     "[%s]: %.3g steps per particle: dt is far too small for "
                                     "the duration", p->name, steps);
        /* a step longer than the run (dt = 1e308 s) silently became one
         * step of the whole duration */
        if (p->dt > sc->duration * (1.0 + 1e-12))
            return gcp_section_error(is, "dt", err, GCP_ERR_VALUE,
                                     "[%s]: a step of %.3g s is longer than the run (%.3g s)",
                                     p->name, p->dt, sc->duration);
        p->nsteps = steps < 1 ? 1 : (int64_t)steps;
        p->dt = sc->duration / (double)p->nsteps;
        if (traj_every) p->trajectory_every = traj_every;
        if (traj_samples) {
            p->trajectory_every = p->nsteps / (traj_samples - 1);
            if (p->trajectory_every < 1) p->trajectory_every = 1;
        }
        if (p->trajectory_every) {
            const int64_t S = p->nsteps / p->trajectory_every + 1;
            if (S > sc->trajectory_samples) sc->trajectory_samples = S;
        }
    }
    if (sc->trajectory_samples) {
        const double bytes = (double)sc->total * (double)sc->trajectory_samples * 7.0 * 8.0;
        if (bytes > 16.0 * (1 << 30))
            return gcp_section_error(gcp_run_file_section(rf, "output"), "trajectory", err,
                                     GCP_ERR_VALUE,
                                     "%.1f GiB of trajectory samples: sample less often",
                                     bytes / (1 << 30));
    }
    return gcp_sweep_spec_parse(sc, rf, err);
}

int gcp_scene_parse_with(const char *path, const char *text, const struct gcp_readers *rd,
                         struct gcp_scene **out, struct gcp_error *err)
{
    *out = NULL;
    struct gcp_scene *sc = calloc(1, sizeof *sc);
    if (!sc) return gcp_error_set(err, GCP_ERR_NOMEM, "out of memory");
    sc->path = strdup(path);
    sc->text = strdup(text);
    if (!sc->path || !sc->text) {
        gcp_scene_free(sc);
        return gcp_error_set(err, GCP_ERR_NOMEM, "out of memory");
    }
    struct gcp_run_file rf;
    int rc = gcp_run_file_parse(sc->path, text, &rf, err);
    if (!rc) rc = build_scene(sc, &rf, rd, err);
    gcp_run_file_free(&rf);
    if (rc) {
        gcp_scene_free(sc);
        return rc;
    }
    *out = sc;
    return 0;
}

int gcp_scene_parse(const char *path, const char *text, struct gcp_scene **out,
                    struct gcp_error *err)
{
    return gcp_scene_parse_with(path, text, NULL, out, err);
}

int gcp_scene_load_with(const char *path, const struct gcp_readers *rd, struct gcp_scene **out,
                        struct gcp_error *err)
{
    char *text;
    *out = NULL;
    int rc = gcp_read_text(path, &text, err);
    if (rc) return rc;
    rc = gcp_scene_parse_with(path, text, rd, out, err);
    free(text);
    return rc;
}

int gcp_scene_load(const char *path, struct gcp_scene **out, struct gcp_error *err)
{
    return gcp_scene_load_with(path, NULL, out, err);
}

void gcp_scene_free(struct gcp_scene *s)
{
    if (!s) return;
    gcp_field_free(s->field);
    for (size_t k = 0; s->pops && k < s->npop; k++) {
        free(s->pops[k].init.x);
        free(s->pops[k].init.u);
        free(s->pops[k].init.ppar);
        free(s->pops[k].init.mu);
    }
    free(s->pops);
    free(s->sweep);
    free(s->path);
    free(s->text);
    free(s);
}
