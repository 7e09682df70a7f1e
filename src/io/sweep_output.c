/* The sweep's results sink: the rows as a table in memory, printed and
 * written as /sweep in the output file (include/gcpush/sweep.h), and the
 * command line's sweep.  The table is small: rank 0 writes it alone with the
 * default (serial) file access, under a temporary name renamed on success.
 *
 * Layout: /sweep holds one 1-D dataset per column, one row per (method,
 * dt or tolerance, population); each dataset has a `units` attribute.
 * /sweep attributes: reference, duration [s], repeats.  The root carries
 * the attributes of every gcpush output file (gcpush_version, git_hash,
 * build_flags, run_file, run_file_name, units = "SI", scene, field, method,
 * ranks, duration, seed, particles). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <hdf5.h>
#include <mpi.h>

#include "gcpush/sweep.h"
#include "io_priv.h"

/* ---- the table: a sink's rows ------------------------------------------- */

void gcp_sweep_table_init(struct gcp_sweep_table *t, const struct gcp_scene *sc)
{
    memset(t, 0, sizeof *t);
    t->duration = sc->duration;
    if (sc->sweep)
        snprintf(t->reference, sizeof t->reference, "%s",
                 sc->sweep->analytic ? "analytic" : sc->sweep->ref_text);
}

int gcp_sweep_table_add(void *table, const struct gcp_sweep_row *r)
{
    struct gcp_sweep_table *t = table;
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
    t->rows = NULL;
    t->n = t->cap = 0;
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

/* ---- /sweep ------------------------------------------------------------- */

static void column(int *bad, hid_t g, const char *name, hid_t type, size_t n, const void *data,
                   const char *units)
{
    hsize_t dims = n;
    hid_t sp = H5Screate_simple(1, &dims, NULL);
    hid_t d = H5Dcreate2(g, name, type, sp, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    if (d < 0 || (n && H5Dwrite(d, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0)) *bad = 1;
    if (d >= 0) {
        gcp_h5_attr_str(bad, d, "units", units);
        H5Dclose(d);
    }
    H5Sclose(sp);
}

/* A double column from member `off` of every row. */
static void dcol(int *bad, hid_t g, const struct gcp_sweep_table *t, const char *name, size_t off,
                 const char *units, double *buf)
{
    for (size_t i = 0; i < t->n; i++) memcpy(&buf[i], (const char *)&t->rows[i] + off, sizeof(double));
    column(bad, g, name, H5T_NATIVE_DOUBLE, t->n, buf, units);
}

static void icol(int *bad, hid_t g, const struct gcp_sweep_table *t, const char *name, size_t off,
                 int64_t *buf)
{
    for (size_t i = 0; i < t->n; i++) memcpy(&buf[i], (const char *)&t->rows[i] + off, sizeof(int64_t));
    column(bad, g, name, H5T_NATIVE_INT64, t->n, buf, "1");
}

static void scol(int *bad, hid_t g, const struct gcp_sweep_table *t, const char *name, size_t off,
                 size_t len, char *buf)
{
    for (size_t i = 0; i < t->n; i++) snprintf(buf + i * len, len, "%s", (const char *)&t->rows[i] + off);
    hid_t st = H5Tcopy(H5T_C_S1);
    H5Tset_size(st, len);
    H5Tset_strpad(st, H5T_STR_NULLTERM);
    column(bad, g, name, st, t->n, buf, "");
    H5Tclose(st);
}

int gcp_sweep_write(const struct gcp_scene *sc, const struct gcp_sweep_table *t,
                    struct gcp_error *err)
{
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
    char tmp[1100];
    snprintf(tmp, sizeof tmp, "%s.tmp-%ld", sc->output, (long)getpid());
    hid_t fcpl = H5Pcreate(H5P_FILE_CREATE), fapl = H5Pcreate(H5P_FILE_ACCESS);
    gcp_h5_plists(sc, fcpl, fapl);
    hid_t f = H5Fcreate(tmp, H5F_ACC_TRUNC, fcpl, fapl);
    H5Pclose(fcpl);
    H5Pclose(fapl);
    if (f < 0) return gcp_error_set(err, GCP_ERR_IO, "%s: cannot create '%s'", sc->output, tmp);
    int bad = 0;
    gcp_h5_root_attrs(&bad, f, sc, 1);

    hid_t g = H5Gcreate2(f, "sweep", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    if (g < 0) bad = 1;
    gcp_h5_attr_str(&bad, g, "reference", t->reference);
    gcp_h5_attr_num(&bad, g, "duration", H5T_NATIVE_DOUBLE, &t->duration);
    const size_t n = t->n ? t->n : 1;
    double *d = malloc(n * sizeof *d);
    int64_t *iv = malloc(n * sizeof *iv);
    char *s = malloc(n * 32);
    if (!d || !iv || !s) {
        bad = 1;
    } else {
#define D(name, member, units) dcol(&bad, g, t, name, offsetof(struct gcp_sweep_row, member), units, d)
#define I(name, member) icol(&bad, g, t, name, offsetof(struct gcp_sweep_row, member), iv)
#define S(name, member, len) scol(&bad, g, t, name, offsetof(struct gcp_sweep_row, member), len, s)
        S("method", method, 32);
        S("population", population, 32);
        D("dt", dt, "s");
        D("dt_given", dt_given, "dt_unit");
        S("dt_unit", dt_unit, 16);
        D("tolerance", tolerance, "1");
        D("cpu_seconds", cpu_seconds, "s");
        I("steps", steps);
        I("particles", particles);
        I("failed", failed);
        D("position_error", position_error, "m");
        D("position_error_gyroradius", position_error_gyroradius, "1");
        D("position_error_path", position_error_path, "1");
        D("gc_position_error", gc_position_error, "m");
        D("gyrophase_error", gyrophase_error, "rad");
        D("bounce_phase_error", bounce_phase_error, "rad");
        D("drift_phase_error", drift_phase_error, "rad");
        D("energy_error", energy_error, "1");
        D("mu_drift", mu_drift, "1/s");
        D("K_drift", K_drift, "1/s");
        D("Lstar_drift", Lstar_drift, "1/s");
#undef D
#undef I
#undef S
    }
    free(d);
    free(iv);
    free(s);
    if (g >= 0) H5Gclose(g);
    if (H5Fclose(f) < 0) bad = 1;
    if (bad) {
        remove(tmp);
        return gcp_error_set(err, GCP_ERR_HDF5, "%s: writing the sweep failed", sc->output);
    }
    if (rename(tmp, sc->output) != 0) {
        const int code = errno;
        remove(tmp);
        return gcp_error_set(err, GCP_ERR_IO, "%s: cannot rename the finished output: %s",
                             sc->output, strerror(code));
    }
    return 0;
}

int gcp_sweep_main(const struct gcp_scene *sc, int check, int quiet)
{
    int me;
    MPI_Comm_rank(MPI_COMM_WORLD, &me);
    struct gcp_error err = {0};
    int status = 0;
    if (check) {
        const struct gcp_sweep_spec *spec = sc->sweep;
        if (me == 0 && !quiet)
            printf("%s: ok: sweep of %zu method(s) x %zu step(s) / %zu tolerance(s) on %lld "
                   "particle(s) for %.6g s\n", sc->path, spec->nmethods, spec->ndt, spec->ntol,
                   (long long)sc->total, sc->duration);
    } else if (me == 0) {
        struct gcp_sweep_table t;
        gcp_sweep_table_init(&t, sc);
        const struct gcp_sweep_sink sink = {gcp_sweep_table_add, &t};
        if (gcp_sweep_run(sc, &sink, quiet ? NULL : stderr, &err)) {
            status = 1;
        } else {
            if (!quiet) gcp_sweep_print(stdout, sc, &t);
            if (gcp_sweep_write(sc, &t, &err)) status = 1;
            else if (!quiet) printf("output: %s\n", sc->output);
        }
        gcp_sweep_table_free(&t);
    }
    if (me == 0 && status) fprintf(stderr, "gcpush: %s\n", err.msg);
    MPI_Bcast(&status, 1, MPI_INT, 0, MPI_COMM_WORLD);
    return status;
}
