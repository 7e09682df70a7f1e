/* Initial states from an HDF5 file (`[particles] file = ...`): the layout
 * gcpush writes under /particles/initial, read back as plain arrays for the
 * run layer (which includes no hdf5.h; it gets this reader as a function
 * pointer, gcp_scene_load_with).
 *
 * Full-orbit methods read x (N,3) [m] and u (N,3) [m/s]; guiding-centre
 * methods X (N,3) [m], ppar (N) [kg m/s], mu (N) [J/T], used as given (no
 * transformation).  Anything else in the file is not read.  A file that
 * cannot serve the method as a whole (missing, not HDF5, a dataset missing
 * or of the wrong shape or type, no rows, mu < 0, no finite row at all) is
 * refused before anything runs; a row with a NaN or Inf is one bad particle
 * (it ends NONFINITE at the start and the run goes on), because the final
 * state of an earlier run, fed back, holds such rows legitimately. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <hdf5.h>

#include "gcpush/io.h"

#define GROUP "/particles/initial"

static int why_set(char *why, size_t len, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
static int why_set(char *why, size_t len, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(why, len, fmt, ap);
    va_end(ap);
    return -1;
}

/* Reads dataset GROUP/name, which must be a floating-point (n) or (n, 3)
 * array (width 1 or 3); *n is set by the first dataset read (-1: not yet)
 * and every later one must agree.  0, or -1 with why set. */
static int read_column(hid_t f, const char *path, const char *name, int width, int64_t *n,
                       double **out, const char *needs, char *why, size_t len)
{
    char full[64];
    snprintf(full, sizeof full, GROUP "/%s", name);
    if (H5Lexists(f, full, H5P_DEFAULT) <= 0)
        return why_set(why, len, "%s: dataset %s is missing (%s)", path, full, needs);
    hid_t ds = H5Dopen2(f, full, H5P_DEFAULT);
    if (ds < 0) return why_set(why, len, "%s: %s is not a dataset (%s)", path, full, needs);
    hid_t sp = H5Dget_space(ds), ty = H5Dget_type(ds);
    int rc = 0;
    hsize_t dims[2] = {0, 0};
    const int rank = H5Sget_simple_extent_ndims(sp);
    if (H5Tget_class(ty) != H5T_FLOAT) {
        rc = why_set(why, len, "%s: %s is not floating-point (expected doubles, SI units)", path,
                     full);
    } else if (rank != (width == 1 ? 1 : 2) || H5Sget_simple_extent_dims(sp, dims, NULL) < 0 ||
               (width == 3 && dims[1] != 3)) {
        rc = why_set(why, len, "%s: %s has the wrong shape (expected %s)", path, full,
                     width == 1 ? "(N)" : "(N, 3)");
    } else if (dims[0] < 1 || dims[0] > 1000000000) {
        rc = why_set(why, len, "%s: %s has %llu rows (expected 1 .. 1e9)", path, full,
                     (unsigned long long)dims[0]);
    } else if (*n >= 0 && (int64_t)dims[0] != *n) {
        rc = why_set(why, len, "%s: %s has %llu rows, the datasets before it %lld", path, full,
                     (unsigned long long)dims[0], (long long)*n);
    } else if (!(*out = malloc((size_t)dims[0] * (size_t)width * sizeof **out))) {
        rc = why_set(why, len, "%s: out of memory for %s", path, full);
    } else if (H5Dread(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, *out) < 0) {
        rc = why_set(why, len, "%s: reading %s failed", path, full);
    } else {
        *n = (int64_t)dims[0];
    }
    H5Tclose(ty);
    H5Sclose(sp);
    H5Dclose(ds);
    return rc;
}

static int read_all(hid_t f, const char *path, int gc, struct gcp_states *o, char *why, size_t len)
{
    if (H5Lexists(f, "/particles", H5P_DEFAULT) <= 0 ||
        H5Lexists(f, GROUP, H5P_DEFAULT) <= 0)
        return why_set(why, len,
                       "%s: no group " GROUP " (the layout gcpush writes: x, u for full-orbit "
                       "methods; X, ppar, mu for guiding-centre methods)", path);
    o->n = -1;
    if (gc) {
        const char *needs = "guiding-centre methods start from X (N,3) [m], ppar (N) [kg m/s], "
                            "mu (N) [J/T]";
        if (read_column(f, path, "X", 3, &o->n, &o->x, needs, why, len) ||
            read_column(f, path, "ppar", 1, &o->n, &o->ppar, needs, why, len) ||
            read_column(f, path, "mu", 1, &o->n, &o->mu, needs, why, len))
            return -1;
    } else {
        const char *needs = "full-orbit methods start from x (N,3) [m], u = gamma v (N,3) [m/s]";
        if (read_column(f, path, "x", 3, &o->n, &o->x, needs, why, len) ||
            read_column(f, path, "u", 3, &o->n, &o->u, needs, why, len))
            return -1;
    }
    o->nonfinite = 0;
    for (int64_t i = 0; i < o->n; i++) {
        double s = o->x[3 * i] + o->x[3 * i + 1] + o->x[3 * i + 2];
        if (gc) {
            /* a negative mu is no state at all, not a particle gone bad */
            if (o->mu[i] < 0)
                return why_set(why, len, "%s: " GROUP "/mu[%lld] = %g: mu must be >= 0", path,
                               (long long)i, o->mu[i]);
            s += o->ppar[i] + o->mu[i];
        } else {
            s += o->u[3 * i] + o->u[3 * i + 1] + o->u[3 * i + 2];
        }
        o->nonfinite += !isfinite(s);
    }
    if (o->nonfinite == o->n)
        return why_set(why, len, "%s: none of its %lld initial states is finite", path,
                       (long long)o->n);
    return 0;
}

int gcp_initfile_read(const char *path, int gc, struct gcp_states *out, char *why, size_t whylen)
{
    memset(out, 0, sizeof *out);
    out->gc = gc != 0;
    FILE *probe = fopen(path, "rb");
    if (!probe) return why_set(why, whylen, "%s: cannot open (no such file?)", path);
    fclose(probe);
    H5E_auto2_t efn;
    void *edata;
    H5Eget_auto2(H5E_DEFAULT, &efn, &edata);
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL); /* our messages, not HDF5's stack dumps */
    int rc;
    hid_t f = -1;
    if (H5Fis_hdf5(path) <= 0) rc = why_set(why, whylen, "%s: not an HDF5 file", path);
    else if ((f = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT)) < 0)
        rc = why_set(why, whylen, "%s: cannot open the HDF5 file", path);
    else rc = read_all(f, path, out->gc, out, why, whylen);
    if (f >= 0) H5Fclose(f);
    H5Eset_auto2(H5E_DEFAULT, efn, edata);
    if (rc) {
        free(out->x);
        free(out->u);
        free(out->ppar);
        free(out->mu);
        memset(out, 0, sizeof *out);
        out->gc = gc != 0;
    }
    return rc;
}

/* Bitwise equality that also holds for NaN rows (their bits are copied). */
static int same(const double *a, const double *b, size_t n)
{
    return memcmp(a, b, n * sizeof *a) == 0;
}

int gcp_initfile_check_results(const struct gcp_scene *sc, const struct gcp_results *r,
                               struct gcp_error *err)
{
    for (int64_t i = 0; i < r->n; i++) {
        const struct gcp_population *p = &sc->pops[r->pop[i]];
        if (!p->file[0]) continue;
        double x[3], u[3], X[3], pm[2];
        int pop;
        gcp_scene_initial_state(sc, r->id[i], &pop, x, u);
        int ok = pop == r->pop[i];
        if (ok && gcp_scene_initial_gc(sc, r->id[i], X, &pm[0], &pm[1]))
            ok = r->gc && same(X, &r->X0[3 * i], 3) && same(&pm[0], &r->ppar0[i], 1) &&
                 same(&pm[1], &r->mu0[i], 1);
        else if (ok)
            ok = same(x, &r->x0[3 * i], 3) && same(u, &r->u0[3 * i], 3);
        if (!ok)
            return gcp_error_set(err, GCP_ERR_STATE,
                                 "%s: the initial state of particle %lld differs from the one "
                                 "checkpointed: the file changed since the interrupted run "
                                 "(restore it, or start the run afresh)",
                                 p->file, (long long)r->id[i]);
    }
    return 0;
}
