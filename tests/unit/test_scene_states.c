/* The run layer's side of `[particles] file = ...`: states handed in as
 * plain arrays by a reader (here a fake one, no HDF5), the count taken from
 * them, ids numbered across populations, guiding centres used as given, a
 * step in gyro periods resolved against the given states, and the errors
 * that name run file, line and key. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/kernels.h"
#include "gcpush/run.h"

/* three guiding centres (gc) or full orbits in a uniform 1 T field */
static const double FX[9] = {1, 2, 3, -1, 0, 0.5, 0, 0, 0};
static const double FP[3] = {1e-20, -2e-20, 0};
static const double FMU[3] = {1e-15, 4e-15, 2e-15};
static const double FU[9] = {1e6, 0, 0, 0, 2e6, 0, 0, 0, 3e6};
static int seen_gc = -1;   /* the kind the scene asked the reader for */
static char seen_path[64];

static double *dup(const double *v, size_t n)
{
    double *p = malloc(n * sizeof *p);
    memcpy(p, v, n * sizeof *p);
    return p;
}

static int fake_reader(const char *path, int gc, struct gcp_states *out, char *why, size_t len)
{
    seen_gc = gc;
    snprintf(seen_path, sizeof seen_path, "%s", path);
    memset(out, 0, sizeof *out);
    if (strcmp(path, "bad.h5") == 0) {
        snprintf(why, len, "%s: dataset /particles/initial/X is missing", path);
        return -1;
    }
    out->n = 3;
    out->gc = gc;
    out->x = dup(FX, 9);
    if (gc) {
        out->ppar = dup(FP, 3);
        out->mu = dup(FMU, 3);
    } else {
        out->u = dup(FU, 9);
    }
    return 0;
}

/* A scene: population a from FILE (extra: more lines in it), population b
 * drawn (2 protons), method M. */
static int scene(const char *method, const char *file, const char *extra, gcp_states_reader rd,
                 struct gcp_scene **sc, struct gcp_error *err)
{
    char text[1024];
    snprintf(text, sizeof text,
             "[scene]\nname = t\nfield = uniform\nduration = 1 s\n"   /* lines 1-4 */
             "[field]\nB = 0 0 1 T\n"                                  /* 5-6 */
             "[particles.a]\nspecies = proton\nfile = %s\n%s"          /* 7-9, extra from 10 */
             "[particles.b]\nspecies = proton\ncount = 2\nenergy = 1 keV\n"
             "position = 0 0 0 m\ndirection = 1 0 0\n"
             "[integrator]\nmethod = %s\ndt = 0.25 gyro\n[output]\nfile = t.h5\n",
             file, extra, method);
    const struct gcp_readers readers = {.states = rd, .grid = NULL};
    return gcp_scene_parse_with("t.run", text, &readers, sc, err);
}

/* Guiding centres from the reader: count 3 from it, ids 0..2 then the drawn
 * population at 3..4, states returned untouched, no full orbit (NaN), and
 * dt = 0.25 of the shortest 2 pi gamma m / (q B) over the three, with
 * gamma = sqrt(1 + (ppar/mc)^2 + 2 mu B / (m c^2)) (computed here), shrunk
 * to a whole number of steps in 1 s. */
Test(scene_states, gc_as_given)
{
    struct gcp_scene *sc;
    struct gcp_error err = {0};
    cr_assert_eq(scene("gc-rk4", "init.h5", "", fake_reader, &sc, &err), 0, "%s", err.msg);
    cr_assert_eq(seen_gc, 1);
    cr_assert_str_eq(seen_path, "init.h5");
    cr_assert_eq(sc->npop, 2);
    cr_assert_eq(sc->pops[0].count, 3);
    cr_assert_eq(sc->pops[1].first_id, 3);
    cr_assert_eq(sc->total, 5);
    for (int64_t id = 0; id < 3; id++) {
        double X[3], pp, mu, x[3], u[3];
        int pop;
        cr_assert_eq(gcp_scene_initial_gc(sc, id, X, &pp, &mu), 1);
        cr_assert(memcmp(X, &FX[3 * id], sizeof X) == 0 && pp == FP[id] && mu == FMU[id]);
        gcp_scene_initial_state(sc, id, &pop, x, u);
        cr_assert(pop == 0 && isnan(x[0]) && isnan(u[2]));
    }
    double X[3], pp, mu;
    cr_assert_eq(gcp_scene_initial_gc(sc, 3, X, &pp, &mu), 0, "a drawn particle has no given GC");
    const double m = GCP_M_PROTON, q = GCP_E_CHARGE, c = GCP_C_LIGHT, B = 1.0;
    double T = INFINITY;
    for (int i = 0; i < 3; i++) {
        const double g = sqrt(1 + pow(FP[i] / (m * c), 2) + 2 * FMU[i] * B / (m * c * c));
        T = fmin(T, 2 * GCP_PI * g * m / (q * B));
    }
    const double want = 1.0 / ceil(1.0 / (0.25 * T));
    cr_assert_float_eq(sc->pops[0].dt, want, 1e-12 * want, "dt %.17g, expected %.17g",
                       sc->pops[0].dt, want);
    gcp_scene_free(sc);
}

/* Full orbits from the reader: asked for x, u (gc = 0), returned as they are */
Test(scene_states, fo_as_given)
{
    struct gcp_scene *sc;
    struct gcp_error err = {0};
    cr_assert_eq(scene("boris", "init.h5", "", fake_reader, &sc, &err), 0, "%s", err.msg);
    cr_assert_eq(seen_gc, 0);
    double x[3], u[3];
    int pop;
    gcp_scene_initial_state(sc, 1, &pop, x, u);
    cr_assert(memcmp(x, &FX[3], sizeof x) == 0 && memcmp(u, &FU[3], sizeof u) == 0);
    cr_assert_eq(gcp_scene_initial_gc(sc, 1, x, &u[0], &u[1]), 0);
    gcp_scene_free(sc);
}

static void refused(const char *method, const char *file, const char *extra, gcp_states_reader rd,
                    const char *want)
{
    struct gcp_scene *sc = (struct gcp_scene *)1;
    struct gcp_error err = {0};
    cr_assert_neq(scene(method, file, extra, rd, &sc, &err), 0, "accepted: %s", want);
    cr_assert_null(sc);
    cr_assert(strstr(err.msg, want), "message '%s' lacks '%s'", err.msg, want);
}

Test(scene_states, errors_name_line_and_key)
{
    refused("boris", "init.h5", "count = 4\n", fake_reader,
            "t.run:10: [particles.a] count: is 4, but init.h5 holds 3 initial states");
    refused("boris", "init.h5", "energy = 1 keV\n", fake_reader,
            "t.run:10: [particles.a] energy: conflicts with file = init.h5");
    refused("boris", "init.h5", "L = 4\n", fake_reader, "t.run:10: [particles.a] L: conflicts");
    refused("gc-rk4", "bad.h5", "", fake_reader,
            "t.run:9: [particles.a] file: bad.h5: dataset /particles/initial/X is missing");
    refused("boris", "init.h5", "", NULL,
            "t.run:9: [particles.a] file: this program reads no files of initial states");
    struct gcp_scene *sc;
    struct gcp_error err = {0};
    cr_assert_eq(scene("boris", "init.h5", "count = 3\n", fake_reader, &sc, &err), 0,
                 "a matching count is allowed: %s", err.msg);
    gcp_scene_free(sc);
}
