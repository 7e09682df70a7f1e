/* Error against run time: the [sweep] section, the runs, the error measures
 * (include/gcpush/sweep.h).
 *
 * For each population, each method and each step (tolerance): the
 * population's particles are pushed from their initial states in blocks of
 * GCP_CHUNK lanes, exactly as the scene's driver pushes them (the pusher's
 * .advance), timed with CLOCK_PROCESS_CPUTIME_ID (best of `repeats` runs
 * while a run takes under 0.2 s), and their final states compared with the
 * analytic answer (uniform fields) or with a reference run.
 *
 * Gyrophase error.  Uniform fields, analytic reference, full-orbit method:
 * the method is run once more with a per-step callback that measures the
 * gyrophase of u in the drift frame (gcp_exact_uniform_phase) after every
 * step and accumulates its per-step change, each taken in (-pi, pi]: the
 * rotation the method actually performed, so the error is not folded
 * modulo 2 pi.  Where the exact rotation per step |omega dt| exceeds pi the
 * samples cannot tell k turns apart and the error is the final difference
 * wrapped to (-pi, pi].  Against a full-orbit reference run: the angle from
 * the reference's u_perp to the method's about the local b at the
 * reference's end point, in (-pi, pi].  Where a guiding-centre method is
 * involved: not defined (NaN).
 *
 * Invariants (dipole: bounce and drift; mirror, tokamak: bounce; elsewhere
 * NaN): each configuration and the reference are pushed once more, untimed,
 * with the invariant observer (src/diag/invariants.c) on every step.  Per
 * particle: the mean measured bounce and drift periods, and the relative
 * drift rates |last - first| / |first| / (t_last - t_first) of the
 * per-bounce mu and K and the per-drift-orbit L* (NaN with fewer than two
 * events).  Phase errors are 2 pi T |1/P - 1/P_ref| with the mean periods P
 * of the run and the reference; everything is the largest over the
 * particles compared. */
#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "gcpush/gc.h"
#include "gcpush/invariants.h"
#include "gcpush/kernels.h"
#include "gcpush/sweep.h"
#include "run_priv.h"

#define C GCP_C_LIGHT

static int adaptive(const struct gcp_pusher_type *p)
{
    return p->adaptive;
}

static double dot(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* ---- parsing ------------------------------------------------------------ */

int gcp_sweep_wanted(const struct gcp_scene *sc)
{
    struct gcp_run_file rf;
    if (!sc || !sc->text || gcp_run_file_parse(sc->path, sc->text, &rf, NULL)) return 0;
    const int yes = gcp_run_file_section(&rf, "sweep") != NULL;
    gcp_run_file_free(&rf);
    return yes;
}

/* Splits v into at most max whitespace-separated tokens of buf. */
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
        if (strcmp(sc->field_model, "uniform") != 0)
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

int gcp_sweep_parse(const struct gcp_scene *sc, struct gcp_sweep_spec *sp, struct gcp_error *err)
{
    memset(sp, 0, sizeof *sp);
    struct gcp_run_file rf;
    int rc = gcp_run_file_parse(sc->path, sc->text, &rf, err);
    if (rc) return rc;
    struct gcp_section *s = gcp_run_file_section(&rf, "sweep");
    if (s && !(rc = parse_section(sc, &rf, s, sp, err))) rc = 1;
    gcp_run_file_free(&rf);
    return rc;
}

/* ---- pushing ------------------------------------------------------------ */

/* The states of one population: initial (full orbit and its guiding
 * centre) and final. */
struct states {
    size_t n;
    double *x0, *u0;       /* n x 3 */
    double *X0, *ppar0, *mu0; /* guiding centre of the initial state */
    int32_t *gc_ok;        /* [bool] gcp_gc_from_fo succeeded */
};

struct finals {
    double *x, *u;         /* full orbit: x, u; guiding centre: x = X, u[0] = p_par */
    int32_t *status;
    int64_t steps;
    double cpu;
    int gc;                /* [bool] a guiding-centre method */
};

static int finals_alloc(struct finals *f, size_t n)
{
    memset(f, 0, sizeof *f);
    f->x = calloc(3 * n, sizeof(double));
    f->u = calloc(3 * n, sizeof(double));
    f->status = calloc(n, sizeof(int32_t));
    return f->x && f->u && f->status ? 0 : GCP_ERR_NOMEM;
}

static void finals_free(struct finals *f)
{
    free(f->x);
    free(f->u);
    free(f->status);
    memset(f, 0, sizeof *f);
}

/* One push of all particles with method p under opts; returns CPU seconds. */

/* Loads particles [first, first + cnt) of st into block b: the full-orbit
 * start, or its guiding centre for a guiding-centre method (one that could
 * not be made starts non-finite and gets its status at the first step). */
static void fill_block(struct gcp_block *b, const struct states *st, size_t first, size_t cnt,
                       int gc, const struct gcp_species *sp, double t0)
{
    for (size_t i = 0; i < cnt; i++) {
        const size_t j = first + i;
        const double *x = gc ? &st->X0[3 * j] : &st->x0[3 * j];
        b->x[i] = x[0], b->y[i] = x[1], b->z[i] = x[2];
        b->ux[i] = st->u0[3 * j], b->uy[i] = st->u0[3 * j + 1], b->uz[i] = st->u0[3 * j + 2];
        b->ppar[i] = gc ? st->ppar0[j] : 0.0;
        b->mu[i] = gc ? st->mu0[j] : 0.0;
        if (gc && !st->gc_ok[j]) b->x[i] = NAN;
        b->index[i] = i;
        b->status[i] = 0;
        b->steps[i] = 0;
        b->t[i] = t0;
    }
    b->n = b->n_active = cnt;
    b->q = sp->charge;
    b->m = sp->mass;
}

static double push_all(const struct gcp_field *field, const struct gcp_species *sp,
                       const struct gcp_pusher_type *p, const struct gcp_push_opts *o,
                       const struct states *st, struct gcp_block *b, struct finals *out)
{
    const int gc = p->kind == GCP_GUIDING_CENTRE;
    out->gc = gc;
    out->steps = 0;
    const double c0 = cpu_now();
    for (size_t first = 0; first < st->n; first += GCP_CHUNK) {
        const size_t cnt = st->n - first < GCP_CHUNK ? st->n - first : GCP_CHUNK;
        fill_block(b, st, first, cnt, gc, sp, o->t0);
        if (!gc) gcp_block_start(b, field, o->t0);
        p->advance(b, field, p, o, NULL);
        for (size_t i = 0; i < cnt; i++) {
            const size_t j = first + b->index[i];
            out->x[3 * j] = b->x[i], out->x[3 * j + 1] = b->y[i], out->x[3 * j + 2] = b->z[i];
            if (gc) {
                out->u[3 * j] = b->ppar[i];
                out->u[3 * j + 1] = out->u[3 * j + 2] = 0.0;
            } else {
                out->u[3 * j] = b->ux[i], out->u[3 * j + 1] = b->uy[i], out->u[3 * j + 2] = b->uz[i];
            }
            out->status[j] = b->status[i];
            out->steps += b->steps[i];
        }
    }
    return cpu_now() - c0;
}

/* Resolves a step in periods against the population (gyro: the shortest
 * initial gyro period in it; bounce, drift: its first particle). */
static int step_seconds(const struct gcp_scene *sc, const struct gcp_population *pop,
                        const struct states *st, double given, enum gcp_period per, double *dt)
{
    if (per == GCP_PERIOD_NONE) {
        *dt = given;
        return 0;
    }
    double Tmin = INFINITY;
    const size_t last = per == GCP_PERIOD_GYRO ? st->n : 1;
    for (size_t j = 0; j < last; j++) {
        double T;
        if (gcp_period_of(sc->field, sc->field_model, &pop->species, &st->x0[3 * j],
                          &st->u0[3 * j], per, &T))
            return GCP_ERR_VALUE;
        Tmin = fmin(Tmin, T);
    }
    *dt = given * Tmin;
    return 0;
}

/* Whole steps that end at the duration exactly. */
static int fit_steps(double T, double *dt, int64_t *nsteps)
{
    const double steps = ceil(T / *dt * (1.0 - 1e-12));
    if (!(steps <= 1e10)) return GCP_ERR_VALUE;
    *nsteps = steps < 1 ? 1 : (int64_t)steps;
    *dt = T / (double)*nsteps;
    return 0;
}

/* ---- error measures ----------------------------------------------------- */

struct phase_track {
    const struct gcp_exact_uniform *ex;
    double last, acc;
};

static int phase_cb(double t, const double x[3], const double u[3], void *ctx)
{
    (void)t;
    (void)x;
    struct phase_track *pt = ctx;
    const double ph = gcp_exact_uniform_phase(pt->ex, u);
    pt->acc += remainder(ph - pt->last, 2.0 * GCP_PI);
    pt->last = ph;
    return 0;
}

static double kinetic(const double u[3], double m)
{
    return m * dot(u, u) / (gcp_gamma_of_u(u[0], u[1], u[2]) + 1.0);
}

/* H - m c^2 = W + q phi of a full-orbit state (phi only in fields with E);
 * NaN where the potential is not known. */
static double fo_energy(const struct gcp_field *f, double q, double m, const double x[3],
                        const double u[3])
{
    double W = kinetic(u, m);
    if (!f->has_E) return W;
    if (!gcp_gc_has_potential(f)) return NAN; /* E without phi: unknown, not phi = 0 */
    double A[3], phi;
    if (gcp_gc_potential(f, 0.0, x, A, NULL, &phi)) return NAN;
    return W + q * phi;
}

static double gc_energy(const struct gcp_field *f, double t, double q, double m, const double X[3],
                        double ppar, double mu)
{
    double H;
    if (gcp_gc_energy(f, t, q, m, X, ppar, mu, &H)) return NAN; /* gamma m c^2 + q phi */
    return H - m * C * C;
}

/* Guiding-centre position of a final state. */
static int gc_position(const struct gcp_field *f, double t, const struct gcp_species *sp,
                       const struct finals *fi, size_t j, double X[3])
{
    if (fi->gc) {
        memcpy(X, &fi->x[3 * j], 3 * sizeof(double));
        return 0;
    }
    double ppar, mu;
    return gcp_gc_from_fo(f, t, sp->charge, sp->mass, &fi->x[3 * j], &fi->u[3 * j], X, &ppar, &mu);
}

/* ---- invariant measures (src/diag/invariants.c) ------------------------- */

/* Per particle, from the observer's events of one run: mean bounce and
 * drift periods [s] and the relative drift rates [1/s] of mu, K (bounce
 * events) and L* (drift events); NaN where not measured. */
struct inv_stats {
    double Tb, Td;
    double mu_rate, K_rate, L_rate;
};

/* The events worth observing in the scene's field: dipole bounce + drift,
 * mirror and tokamak bounce only, elsewhere none (0). */
static unsigned inv_events(const struct gcp_field *f)
{
    if (f->type == &gcp_field_dipole) return GCP_EVT_BOUNCE | GCP_EVT_DRIFT;
    if (f->type == &gcp_field_mirror || f->type == &gcp_field_tokamak) return GCP_EVT_BOUNCE;
    return 0;
}

/* |last - first| / |first| / (t_last - t_first); NaN for fewer than 2 values. */
static double rel_rate(int64_t n, double first, double last, double t0, double t1)
{
    if (n < 2 || !(t1 > t0) || first == 0.0) return NAN;
    return fabs(last - first) / fabs(first) / (t1 - t0);
}

/* The push of push_all once more, untimed, with the invariant observer on
 * every step (every = 1, as the driver attaches it); fills out[0..n).
 * Returns 0 or GCP_ERR_NOMEM. */
static int observe_all(const struct gcp_field *field, const struct gcp_species *sp,
                       const struct gcp_pusher_type *p, const struct gcp_push_opts *o,
                       const struct states *st, struct gcp_block *b, unsigned evts,
                       struct inv_stats *out)
{
    const int gc = p->kind == GCP_GUIDING_CENTRE;
    struct gcp_observer *obs = NULL;
    const struct gcp_observer_opts oo = {.events = evts};
    if (gcp_observer_create(&obs, GCP_CHUNK, field, p, &oo)) return GCP_ERR_NOMEM;
    struct gcp_events ev = {0};
    int rc = 0;
    for (size_t first = 0; first < st->n && !rc; first += GCP_CHUNK) {
        const size_t cnt = st->n - first < GCP_CHUNK ? st->n - first : GCP_CHUNK;
        fill_block(b, st, first, cnt, gc, sp, o->t0);
        gcp_block_start(b, field, o->t0);
        gcp_observer_begin(obs, b, o->t0, (int64_t)first, &ev);
        const struct gcp_sampler smp = {1, gcp_observer_sample, obs};
        p->advance(b, field, p, o, &smp);
        rc = gcp_observer_end(obs, b);
    }
    gcp_observer_free(obs);
    if (rc) {
        gcp_events_free(&ev);
        return rc;
    }
    /* per particle: counts, sums, first and last values (a lane's events of
     * one kind come in time order) */
    for (size_t j = 0; j < st->n; j++) out[j] = (struct inv_stats){NAN, NAN, NAN, NAN, NAN};
    int64_t *nb = calloc(st->n, sizeof *nb), *nd = calloc(st->n, sizeof *nd);
    double *acc = calloc(st->n * 12, sizeof *acc);
    if (!nb || !nd || !acc) {
        free(nb), free(nd), free(acc), gcp_events_free(&ev);
        return GCP_ERR_NOMEM;
    }
    for (int64_t k = 0; k < ev.n; k++) {
        const struct gcp_event *e = &ev.e[k];
        if (e->id < 0 || (size_t)e->id >= st->n) continue;
        const size_t j = (size_t)e->id;
        double *a = &acc[12 * j]; /* sumTb K0 K1 mu0 mu1 tb0 tb1 | sumTd L0 L1 td0 td1 */
        if (e->kind == GCP_EVENT_BOUNCE) {
            if (nb[j]++ == 0) a[1] = e->v[GCP_BOUNCE_K], a[3] = e->v[GCP_BOUNCE_MU], a[5] = e->t;
            a[0] += e->v[GCP_BOUNCE_PERIOD];
            a[2] = e->v[GCP_BOUNCE_K], a[4] = e->v[GCP_BOUNCE_MU], a[6] = e->t;
        } else if (e->kind == GCP_EVENT_DRIFT) {
            if (nd[j]++ == 0) a[8] = e->v[1], a[10] = e->t;
            a[7] += e->v[0];
            a[9] = e->v[1], a[11] = e->t;
        }
    }
    for (size_t j = 0; j < st->n; j++) {
        const double *a = &acc[12 * j];
        struct inv_stats *s = &out[j];
        if (nb[j]) s->Tb = a[0] / (double)nb[j];
        if (nd[j]) s->Td = a[7] / (double)nd[j];
        s->K_rate = rel_rate(nb[j], a[1], a[2], a[5], a[6]);
        s->mu_rate = rel_rate(nb[j], a[3], a[4], a[5], a[6]);
        s->L_rate = rel_rate(nd[j], a[8], a[9], a[10], a[11]);
    }
    free(nb), free(nd), free(acc);
    gcp_events_free(&ev);
    return 0;
}

/* Bounce and drift phase error at the end, 2 pi T |1/P - 1/P_ref| with the
 * mean measured periods P of the run and the reference; NaN where either
 * is not measured. */
static double phase_error(double T, double P, double Pref)
{
    if (!(P > 0) || !(Pref > 0)) return NAN;
    return 2.0 * GCP_PI * T * fabs(1.0 / P - 1.0 / Pref);
}

/* The per-row maximum over the particles.  An accumulator starts at
 * -INFINITY ("nothing measured yet", turned into NaN by compare at the
 * end) and keeps the value of largest magnitude, with its sign.  A NaN is
 * the worst error, not none (issue 13): a particle whose error cannot be
 * computed (a non-finite state, a measure it lacks) makes the row's
 * maximum unknown, NaN, and no later value replaces it. */
static void keep_max(double *acc, double v)
{
    if (isnan(*acc)) return;
    if (isnan(v) || *acc == -INFINITY || fabs(v) > fabs(*acc)) *acc = v;
}

static void finish_max(double *acc)
{
    if (*acc == -INFINITY) *acc = NAN;
}

static void compare(const struct gcp_scene *sc, const struct gcp_population *pop,
                    const struct states *st, const struct finals *run, const struct finals *ref,
                    const double *ref_phase, const double *run_phase, int phase_wrapped,
                    const struct inv_stats *run_inv, const struct inv_stats *ref_inv,
                    struct gcp_sweep_row *row)
{
    const struct gcp_species *sp = &pop->species;
    const struct gcp_field *f = sc->field;
    const double T = sc->duration;
    const int gcmode = run->gc || ref->gc;
    double *const acc[] = {&row->position_error, &row->position_error_gyroradius,
                           &row->position_error_path, &row->gc_position_error,
                           &row->gyrophase_error, &row->energy_error,
                           &row->bounce_phase_error, &row->drift_phase_error,
                           &row->mu_drift, &row->K_drift, &row->Lstar_drift};
    const size_t nacc = sizeof acc / sizeof acc[0];
    for (size_t k = 0; k < nacc; k++) *acc[k] = -INFINITY;
    row->failed = 0;
    for (size_t j = 0; j < st->n; j++) {
        if (run->status[j] != GCP_ALIVE || ref->status[j] != GCP_ALIVE) {
            row->failed++;
            /* Both ended the same way (e.g. both precipitated), or one is
             * a guiding centre outside its model's validity (NONADIABATIC:
             * not a numerical error): nothing to compare.  Otherwise the
             * method lost (or kept) a particle the reference did not, or
             * went non-finite: its error is unbounded, the row's is NaN. */
            const int32_t a = run->status[j], r = ref->status[j];
            if (a != r && a != GCP_NONADIABATIC && r != GCP_NONADIABATIC)
                for (size_t k = 0; k < 4; k++) keep_max(acc[k], NAN);
            continue;
        }
        const double *x0 = &st->x0[3 * j], *u0 = &st->u0[3 * j];
        double a[3], b[3];
        if (gcmode) {
            if (gc_position(f, T, sp, run, j, a) || gc_position(f, T, sp, ref, j, b)) {
                row->failed++;
                continue;
            }
        } else {
            memcpy(a, &run->x[3 * j], sizeof a);
            memcpy(b, &ref->x[3 * j], sizeof b);
        }
        const double d[3] = {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
        const double err = sqrt(dot(d, d));
        double Xa[3], Xb[3];
        if (gcmode) {
            keep_max(&row->gc_position_error, err);
        } else if (!gc_position(f, T, sp, run, j, Xa) && !gc_position(f, T, sp, ref, j, Xb)) {
            const double D[3] = {Xa[0] - Xb[0], Xa[1] - Xb[1], Xa[2] - Xb[2]};
            keep_max(&row->gc_position_error, sqrt(dot(D, D)));
        }
        /* initial gyroradius p_perp / (|q| B) and path |v0| T */
        struct gcp_field_sample smp = {.need = GCP_NEED_B};
        gcp_field_eval(f, 0.0, x0, &smp);
        const double Bm = sqrt(dot(smp.B, smp.B));
        const double upar = Bm > 0 ? dot(u0, smp.B) / Bm : 0.0;
        const double uperp = sqrt(fmax(dot(u0, u0) - upar * upar, 0.0));
        const double rho = sp->mass * uperp / (fabs(sp->charge) * Bm);
        const double v0 = sqrt(dot(u0, u0)) / gcp_gamma_of_u(u0[0], u0[1], u0[2]);
        const double *ure = &ref->u[3 * j];
        const double vre = ref->gc ? 0.0 : sqrt(dot(ure, ure)) / gcp_gamma_of_u(ure[0], ure[1], ure[2]);
        const double path = fmax(v0, vre) * T;
        keep_max(&row->position_error, err);
        keep_max(&row->position_error_gyroradius, rho > 0 ? err / rho : NAN);
        keep_max(&row->position_error_path, path > 0 ? err / path : NAN);
        /* energy */
        double e = NAN;
        const double W0 = kinetic(u0, sp->mass);
        if (!f->time_dependent) {
            double H0, H1;
            if (run->gc) {
                H0 = gc_energy(f, 0.0, sp->charge, sp->mass, &st->X0[3 * j], st->ppar0[j],
                               st->mu0[j]);
                H1 = gc_energy(f, T, sp->charge, sp->mass, &run->x[3 * j], run->u[3 * j],
                               st->mu0[j]);
            } else {
                H0 = fo_energy(f, sp->charge, sp->mass, x0, u0);
                H1 = fo_energy(f, sp->charge, sp->mass, &run->x[3 * j], &run->u[3 * j]);
            }
            double Wmax = W0;
            if (!run->gc) Wmax = fmax(Wmax, kinetic(&run->u[3 * j], sp->mass));
            if (!ref->gc) Wmax = fmax(Wmax, kinetic(&ref->u[3 * j], sp->mass));
            e = fabs(H1 - H0) / Wmax;
        } else if (!run->gc && !ref->gc) {
            const double Wr = kinetic(&ref->u[3 * j], sp->mass);
            e = fabs(kinetic(&run->u[3 * j], sp->mass) - Wr) / Wr;
        }
        keep_max(&row->energy_error, e);
        /* gyrophase */
        double ph = NAN;
        if (ref_phase && run_phase) {
            ph = run_phase[j] - ref_phase[j];
            if (phase_wrapped) ph = remainder(ph, 2.0 * GCP_PI);
        } else if (!gcmode) {
            smp.need = GCP_NEED_B;
            if (gcp_field_eval(f, T, &ref->x[3 * j], &smp) == 0) {
                const double Bn = sqrt(dot(smp.B, smp.B));
                if (Bn > 0) {
                    const double bb[3] = {smp.B[0] / Bn, smp.B[1] / Bn, smp.B[2] / Bn};
                    double pr[3], pm[3];
                    const double *ur = &ref->u[3 * j], *um = &run->u[3 * j];
                    const double kr = dot(ur, bb), km = dot(um, bb);
                    for (int i = 0; i < 3; i++) pr[i] = ur[i] - kr * bb[i], pm[i] = um[i] - km * bb[i];
                    const double cr[3] = {pr[1] * pm[2] - pr[2] * pm[1], pr[2] * pm[0] - pr[0] * pm[2],
                                          pr[0] * pm[1] - pr[1] * pm[0]};
                    ph = atan2(dot(cr, bb), dot(pr, pm));
                }
            }
        }
        keep_max(&row->gyrophase_error, ph);
        /* invariants: drift rates of the run, periods against the reference's */
        if (run_inv) {
            const struct inv_stats *ri = &run_inv[j];
            keep_max(&row->mu_drift, ri->mu_rate);
            keep_max(&row->K_drift, ri->K_rate);
            keep_max(&row->Lstar_drift, ri->L_rate);
            if (ref_inv) {
                keep_max(&row->bounce_phase_error, phase_error(T, ri->Tb, ref_inv[j].Tb));
                keep_max(&row->drift_phase_error, phase_error(T, ri->Td, ref_inv[j].Td));
            }
        }
    }
    for (size_t k = 0; k < nacc; k++) finish_max(acc[k]);
}

/* ---- the sweep ---------------------------------------------------------- */

static int table_add(struct gcp_sweep_table *t, const struct gcp_sweep_row *r)
{
    if (t->n == t->cap) {
        size_t cap = t->cap ? 2 * t->cap : 32;
        struct gcp_sweep_row *nr = realloc(t->rows, cap * sizeof *nr);
        if (!nr) return GCP_ERR_NOMEM;
        t->rows = nr;
        t->cap = cap;
    }
    t->rows[t->n++] = *r;
    return 0;
}

void gcp_sweep_table_free(struct gcp_sweep_table *t)
{
    free(t->rows);
    memset(t, 0, sizeof *t);
}

static void states_free(struct states *st)
{
    free(st->x0);
    free(st->u0);
    free(st->X0);
    free(st->ppar0);
    free(st->mu0);
    free(st->gc_ok);
    memset(st, 0, sizeof *st);
}

static int states_make(const struct gcp_scene *sc, const struct gcp_population *pop,
                       struct states *st)
{
    const size_t n = (size_t)pop->count;
    memset(st, 0, sizeof *st);
    st->n = n;
    st->x0 = malloc(3 * n * sizeof(double));
    st->u0 = malloc(3 * n * sizeof(double));
    st->X0 = malloc(3 * n * sizeof(double));
    st->ppar0 = malloc(n * sizeof(double));
    st->mu0 = malloc(n * sizeof(double));
    st->gc_ok = malloc(n * sizeof(int32_t));
    if (!st->x0 || !st->u0 || !st->X0 || !st->ppar0 || !st->mu0 || !st->gc_ok) {
        states_free(st);
        return GCP_ERR_NOMEM;
    }
    for (size_t j = 0; j < n; j++) {
        int pi;
        gcp_scene_initial_state(sc, pop->first_id + (int64_t)j, &pi, &st->x0[3 * j], &st->u0[3 * j]);
        st->gc_ok[j] = gcp_gc_from_fo(sc->field, 0.0, pop->species.charge, pop->species.mass,
                                      &st->x0[3 * j], &st->u0[3 * j], &st->X0[3 * j],
                                      &st->ppar0[j], &st->mu0[j]) == 0;
    }
    return 0;
}

/* Push with timing repeats; finals of the last run. */
static void timed(const struct gcp_scene *sc, const struct gcp_population *pop,
                  const struct gcp_pusher_type *p, const struct gcp_push_opts *o,
                  const struct states *st, struct gcp_block *b, int repeats, struct finals *out)
{
    /* One run to size the samples; short runs are timed in batches of k
     * runs of at least 2 ms together (timer noise), and the best of
     * `repeats` samples is kept; runs over 0.2 s are timed once. */
    const double c1 = push_all(sc->field, &pop->species, p, o, st, b, out);
    double best = c1;
    if (c1 <= 0.2) {
        const int k = c1 >= 2e-3 ? 1 : c1 > 2e-6 ? (int)ceil(2e-3 / c1) : 1000;
        best = INFINITY;
        for (int r = 0; r < repeats; r++) {
            double c = 0.0;
            for (int i = 0; i < k; i++) c += push_all(sc->field, &pop->species, p, o, st, b, out);
            best = fmin(best, c / k);
        }
    }
    out->cpu = best;
}

int gcp_sweep_run(const struct gcp_scene *sc, const struct gcp_sweep_spec *spec,
                  struct gcp_sweep_table *t, FILE *progress, struct gcp_error *err)
{
    memset(t, 0, sizeof *t);
    t->duration = sc->duration;
    const double T = sc->duration;
    snprintf(t->reference, sizeof t->reference, "%s", spec->analytic ? "analytic" : spec->ref_text);
    struct gcp_block b;
    if (gcp_block_alloc(&b, GCP_CHUNK)) return gcp_error_set(err, GCP_ERR_NOMEM, "out of memory");
    int rc = 0;
    struct gcp_exact_uniform ex;
    memset(&ex, 0, sizeof ex);
    /* the uniform field's B and E (analytic reference only) */
    struct gcp_field_sample lab = {.need = GCP_NEED_B | GCP_NEED_E};
    if (spec->analytic) gcp_field_eval(sc->field, 0.0, (double[3]){0, 0, 0}, &lab);
    const double *B_lab = lab.B, *E_lab = lab.E;
    for (size_t k = 0; k < sc->npop && !rc; k++) {
        const struct gcp_population *pop = &sc->pops[k];
        struct states st = {0};
        struct finals ref = {0}, run = {0};
        double *ref_phase = NULL, *run_phase = NULL;
        struct inv_stats *ref_inv = NULL, *run_inv = NULL;
        if (states_make(sc, pop, &st) || finals_alloc(&ref, st.n) || finals_alloc(&run, st.n) ||
            !(ref_phase = malloc(st.n * sizeof(double))) ||
            !(run_phase = malloc(st.n * sizeof(double))) ||
            !(ref_inv = malloc(st.n * sizeof *ref_inv)) ||
            !(run_inv = malloc(st.n * sizeof *run_inv))) {
            rc = gcp_error_set(err, GCP_ERR_NOMEM, "out of memory");
            states_free(&st);
            finals_free(&ref);
            finals_free(&run);
            free(ref_phase);
            free(run_phase);
            free(ref_inv);
            free(run_inv);
            break;
        }
        int have_phase = 0;
        /* the invariant observer's events in this field (0: none) */
        const unsigned evts = inv_events(sc->field);
        double wmax = 0.0; /* largest |omega| in the drift frame */
        /* the reference */
        if (spec->analytic) {
            if (gcp_exact_uniform_init(&ex, B_lab, E_lab, pop->species.charge, pop->species.mass))
                rc = gcp_error_set(err, GCP_ERR_VALUE, "%s: [sweep] reference: no analytic answer",
                                   sc->path);
            have_phase = ex.regime == 1;
            for (size_t j = 0; j < st.n && !rc; j++) {
                ref.status[j] = gcp_exact_uniform_state(&ex, &st.x0[3 * j], &st.u0[3 * j], T,
                                                        &ref.x[3 * j], &ref.u[3 * j], &ref_phase[j])
                                    ? GCP_NONFINITE
                                    : GCP_ALIVE;
                if (have_phase) wmax = fmax(wmax, fabs(gcp_exact_uniform_omega(&ex, &st.u0[3 * j])));
            }
        } else {
            struct gcp_push_opts o = {.t0 = 0.0, .tolerance = spec->ref_tolerance};
            if (adaptive(spec->ref_method)) {
                o.dt = pop->dt, o.nsteps = pop->nsteps;
            } else if (step_seconds(sc, pop, &st, spec->ref_dt_given, spec->ref_period, &o.dt) ||
                       fit_steps(T, &o.dt, &o.nsteps)) {
                rc = gcp_error_set(err, GCP_ERR_VALUE,
                                   "%s: [sweep] reference: cannot resolve the step for [%s] "
                                   "(no such period, or more than 1e10 steps)", sc->path, pop->name);
            }
            if (!rc) {
                if (progress) fprintf(progress, "sweep: [%s] reference %s ...\n", pop->name, t->reference);
                push_all(sc->field, &pop->species, spec->ref_method, &o, &st, &b, &ref);
                if (evts && observe_all(sc->field, &pop->species, spec->ref_method, &o, &st, &b,
                                        evts, ref_inv))
                    rc = gcp_error_set(err, GCP_ERR_NOMEM, "out of memory");
            }
        }
        for (size_t mi = 0; mi < spec->nmethods && !rc; mi++) {
            const struct gcp_pusher_type *p = spec->methods[mi];
            const int ad = adaptive(p);
            const size_t ncfg = ad ? spec->ntol : spec->ndt;
            for (size_t ci = 0; ci < ncfg && !rc; ci++) {
                struct gcp_sweep_row row;
                memset(&row, 0, sizeof row);
                snprintf(row.method, sizeof row.method, "%s", p->name);
                snprintf(row.population, sizeof row.population, "%s", pop->name);
                struct gcp_push_opts o = {.t0 = 0.0};
                if (ad) {
                    o.dt = pop->dt, o.nsteps = pop->nsteps, o.tolerance = spec->tolerance[ci];
                    row.tolerance = o.tolerance;
                    row.dt_given = NAN;
                    snprintf(row.dt_unit, sizeof row.dt_unit, "-");
                } else {
                    row.tolerance = NAN;
                    row.dt_given = spec->dt_given[ci];
                    snprintf(row.dt_unit, sizeof row.dt_unit, "%s", spec->dt_unit);
                    if (step_seconds(sc, pop, &st, spec->dt_value[ci], spec->dt_period, &o.dt) ||
                        fit_steps(T, &o.dt, &o.nsteps)) {
                        rc = gcp_error_set(err, GCP_ERR_VALUE,
                                           "%s: [sweep] dt: cannot resolve %g %s for [%s] (no such "
                                           "period, or more than 1e10 steps)", sc->path,
                                           spec->dt_given[ci], spec->dt_unit, pop->name);
                        break;
                    }
                }
                row.dt = o.dt;
                row.particles = (int64_t)st.n;
                timed(sc, pop, p, &o, &st, &b, spec->repeats, &run);
                row.cpu_seconds = run.cpu;
                row.steps = run.steps;
                /* the accumulated gyrophase (uniform fields, full orbit) */
                int use_phase = 0, wrapped = 0;
                if (have_phase && p->kind == GCP_FULL_ORBIT) {
                    use_phase = 1;
                    wrapped = wmax * o.dt > GCP_PI;
                    for (size_t j = 0; j < st.n; j++) {
                        struct phase_track pt = {&ex, gcp_exact_uniform_phase(&ex, &st.u0[3 * j]), 0.0};
                        const double p0 = pt.last;
                        double tt = 0.0, x[3], u[3];
                        memcpy(x, &st.x0[3 * j], sizeof x);
                        memcpy(u, &st.u0[3 * j], sizeof u);
                        gcp_orbit_push(sc->field, p, pop->species.charge, pop->species.mass, &tt,
                                       x, u, o.dt, o.nsteps, phase_cb, &pt);
                        run_phase[j] = wrapped ? pt.last : p0 + pt.acc;
                    }
                }
                /* the invariants: a separate, untimed pass with the observer */
                int use_inv = 0;
                if (evts) {
                    if (observe_all(sc->field, &pop->species, p, &o, &st, &b, evts, run_inv)) {
                        rc = gcp_error_set(err, GCP_ERR_NOMEM, "out of memory");
                        break;
                    }
                    use_inv = 1;
                }
                compare(sc, pop, &st, &run, &ref, use_phase ? ref_phase : NULL,
                        use_phase ? run_phase : NULL, wrapped, use_inv ? run_inv : NULL,
                        use_inv && !spec->analytic ? ref_inv : NULL, &row);
                if (table_add(t, &row)) rc = gcp_error_set(err, GCP_ERR_NOMEM, "out of memory");
                if (progress)
                    fprintf(progress, "sweep: [%s] %-12s %s %-10.4g %.3g s CPU, error %.3g m\n",
                            pop->name, p->name, ad ? "tol" : "dt ", ad ? row.tolerance : row.dt,
                            row.cpu_seconds, row.position_error);
            }
        }
        states_free(&st);
        finals_free(&ref);
        finals_free(&run);
        free(ref_phase);
        free(run_phase);
        free(ref_inv);
        free(run_inv);
    }
    gcp_block_free(&b);
    if (rc) gcp_sweep_table_free(t);
    return rc;
}

void gcp_sweep_print(FILE *to, const struct gcp_scene *sc, const struct gcp_sweep_table *t)
{
    fprintf(to, "sweep %s: %lld particle%s, %.6g s in %s, reference %s\n", sc->name,
            (long long)sc->total, sc->total == 1 ? "" : "s", t->duration, sc->field_model,
            t->reference);
    fprintf(to, "%-13s %-10s %-10s %-12s %-7s %11s %10s %8s %10s %10s %10s %10s %10s %6s\n",
            "method", "population", "dt[s]", "given", "tol", "steps", "cpu[s]", "ns/step",
            "pos_err[m]", "err/rho", "gc_err[m]", "phase[rad]", "energy", "failed");
    for (size_t i = 0; i < t->n; i++) {
        const struct gcp_sweep_row *r = &t->rows[i];
        char given[32], tol[16];
        if (isfinite(r->dt_given))
            snprintf(given, sizeof given, "%g %s", r->dt_given, r->dt_unit);
        else
            snprintf(given, sizeof given, "-");
        if (isfinite(r->tolerance))
            snprintf(tol, sizeof tol, "%.0e", r->tolerance);
        else
            snprintf(tol, sizeof tol, "-");
        fprintf(to, "%-13s %-10s %-10.4g %-12s %-7s %11lld %10.4g %8.3g %10.3e %10.3e %10.3e "
                    "%10.3e %10.3e %6lld\n",
                r->method, r->population, r->dt, given, tol, (long long)r->steps, r->cpu_seconds,
                r->steps ? 1e9 * r->cpu_seconds / (double)r->steps : 0.0, r->position_error,
                r->position_error_gyroradius, r->gc_position_error, r->gyrophase_error,
                r->energy_error, (long long)r->failed);
    }
}
