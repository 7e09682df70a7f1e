/* Grid files (HDF5) for the `grid` model: the reader and the writer (the
 * format is documented in fields/README.md), and what builds on them: the
 * `grid` model from a file (gcp_field_grid_load), the sampler's file
 * (gcp_grid_sample_write), `gcpush grid FILE.run` (gcp_grid_command) and
 * the readers handed to the run layer (gcp_io_readers).  The io layer's:
 * the models (fields/grid.c) interpolate from memory and never see HDF5;
 * they get a file's data through a gcp_grid_reader (field.h), this file's
 * gcp_grid_read for gcpush and for library users who ask for it.  Serial
 * HDF5 calls with default property lists: they work in a process that never
 * called MPI_Init, also with the Open MPI build of HDF5.
 */
#include <hdf5.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "gcpush/grid.h"
#include "gcpush/grid_file.h"
#include "gcpush/io.h"

#define GRID_FORMAT_VERSION 1

static const char *const AXI_B[3] = {"BR", "Bphi", "BZ"};
static const char *const AXI_E[3] = {"ER", "Ephi", "EZ"};
static const char *const CART_B[3] = {"Bx", "By", "Bz"};
static const char *const CART_E[3] = {"Ex", "Ey", "Ez"};
static const char *const AXI_AX[3] = {"R", "Z", NULL};
static const char *const CART_AX[3] = {"x", "y", "z"};

/* HDF5's automatic error printing off while we work (restored after): our
 * messages say what went wrong. */
struct h5quiet {
    H5E_auto2_t fn;
    void *data;
};
static void h5_quiet(struct h5quiet *q)
{
    H5Eget_auto2(H5E_DEFAULT, &q->fn, &q->data);
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
}
static void h5_loud(const struct h5quiet *q) { H5Eset_auto2(H5E_DEFAULT, q->fn, q->data); }

/* ---- reading ------------------------------------------------------------- */

static int attr_string(hid_t f, const char *name, char *out, size_t len)
{
    if (H5Aexists(f, name) <= 0) return -1;
    hid_t a = H5Aopen(f, name, H5P_DEFAULT);
    if (a < 0) return -1;
    hid_t t = H5Aget_type(a);
    int rc = -1;
    if (H5Tget_class(t) == H5T_STRING && !H5Tis_variable_str(t)) {
        size_t sz = H5Tget_size(t);
        char *buf = calloc(sz + 1, 1);
        hid_t mt = H5Tcopy(H5T_C_S1);
        H5Tset_size(mt, sz);
        H5Tset_cset(mt, H5Tget_cset(t)); /* HDF5 converts no ASCII <-> UTF-8 */
        if (buf && H5Aread(a, mt, buf) >= 0) {
            snprintf(out, len, "%s", buf);
            rc = 0;
        }
        H5Tclose(mt);
        free(buf);
    } else if (H5Tget_class(t) == H5T_STRING) {
        char *s = NULL;
        hid_t mt = H5Tcopy(H5T_C_S1);
        H5Tset_size(mt, H5T_VARIABLE);
        /* h5py writes a str as a variable-length UTF-8 string; reading it
         * into an ASCII memory type fails (no conversion path), which was
         * reported as "missing" (issue 13) */
        H5Tset_cset(mt, H5Tget_cset(t));
        if (H5Aread(a, mt, &s) >= 0 && s) {
            snprintf(out, len, "%s", s);
            H5free_memory(s);
            rc = 0;
        }
        H5Tclose(mt);
    }
    H5Tclose(t);
    H5Aclose(a);
    return rc;
}

/* A double attribute of exactly n values: 0, -1 absent, -2 wrong size. */
static int attr_doubles(hid_t f, const char *name, double *v, int n)
{
    if (H5Aexists(f, name) <= 0) return -1;
    hid_t a = H5Aopen(f, name, H5P_DEFAULT);
    if (a < 0) return -1;
    hid_t sp = H5Aget_space(a);
    hssize_t np = H5Sget_simple_extent_npoints(sp);
    int rc = -2;
    if (np == n && H5Aread(a, H5T_NATIVE_DOUBLE, v) >= 0) rc = 0;
    H5Sclose(sp);
    H5Aclose(a);
    return rc;
}

/* Reads dataset `name` of rank nd and dims (slowest first) dims[]; *out is
 * malloc'ed.  Missing: 1 with *out NULL (the caller decides whether that
 * is an error).  Checks rank, shape and finiteness. */
static int read_dataset(const char *path, hid_t f, const char *name, int nd,
                        const hsize_t dims[], const char *const axes[], double **out,
                        struct gcp_error *err)
{
    *out = NULL;
    if (H5Lexists(f, name, H5P_DEFAULT) <= 0) return 1;
    hid_t ds = H5Dopen2(f, name, H5P_DEFAULT);
    if (ds < 0) return gcp_error_set(err, GCP_ERR_HDF5, "%s: dataset /%s: cannot open", path, name);
    hid_t sp = H5Dget_space(ds);
    int rank = H5Sget_simple_extent_ndims(sp);
    hsize_t d[8] = {0};
    int rc = 0;
    if (rank != nd) {
        rc = gcp_error_set(err, GCP_ERR_VALUE, "%s: dataset /%s: rank %d, expected %d (%s)", path,
                           name, rank, nd,
                           nd == 2 ? "nZ, nR: R varies fastest" : "nz, ny, nx: x varies fastest");
        goto done;
    }
    H5Sget_simple_extent_dims(sp, d, NULL);
    for (int k = 0; k < nd; k++)
        if (d[k] != dims[k]) {
            char got[96], want[96];
            int g = 0, w = 0;
            for (int j = 0; j < nd; j++) {
                g += snprintf(got + g, sizeof got - (size_t)g, "%s%llu", j ? ", " : "",
                              (unsigned long long)d[j]);
                w += snprintf(want + w, sizeof want - (size_t)w, "%s%llu", j ? ", " : "",
                              (unsigned long long)dims[j]);
            }
            rc = gcp_error_set(err, GCP_ERR_VALUE,
                               "%s: dataset /%s: shape (%s), expected (%s) as the other field "
                               "datasets",
                               path, name, got, want);
            goto done;
        }
    size_t total = 1;
    for (int k = 0; k < nd; k++) total *= (size_t)dims[k];
    double *v = malloc(total * sizeof *v);
    if (!v) {
        rc = gcp_error_set(err, GCP_ERR_NOMEM, "%s: dataset /%s: out of memory", path, name);
        goto done;
    }
    if (H5Dread(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v) < 0) {
        free(v);
        rc = gcp_error_set(err, GCP_ERR_HDF5, "%s: dataset /%s: read failed (not numeric?)", path,
                           name);
        goto done;
    }
    for (size_t i = 0; i < total; i++)
        if (!isfinite(v[i])) {
            /* index in HDF5 order (slowest first), named by axis */
            size_t idx[3] = {0, 0, 0}, r = i;
            for (int k = nd - 1; k >= 0; k--) {
                idx[k] = r % (size_t)dims[k];
                r /= (size_t)dims[k];
            }
            /* HDF5 order is slowest first: axis names reversed */
            char where[160];
            int w = 0;
            for (int k = 0; k < nd; k++)
                w += snprintf(where + w, sizeof where - (size_t)w, "%si%s = %zu", k ? ", " : "[",
                              axes[nd - 1 - k], idx[k]);
            snprintf(where + w, sizeof where - (size_t)w, "]");
            const double bad = v[i];
            free(v);
            rc = gcp_error_set(err, GCP_ERR_VALUE,
                               "%s: dataset /%s: non-finite value (%g) at %s; grids with holes "
                               "are refused (fill them, e.g. with the nearest valid value)",
                               path, name, bad, where);
            goto done;
        }
    *out = v;
done:
    H5Sclose(sp);
    H5Dclose(ds);
    return rc;
}

/* Optional 1D axis dataset: must have n values, strictly increasing,
 * uniform and equal to origin + i spacing (to 1e-9 of the spacing). */
static int check_axis(const char *path, hid_t f, const char *name, size_t n, double x0, double h,
                      struct gcp_error *err)
{
    if (H5Lexists(f, name, H5P_DEFAULT) <= 0) return 0;
    const hsize_t dims[1] = {n};
    const char *const ax[1] = {name};
    double *v = NULL;
    int rc = read_dataset(path, f, name, 1, dims, ax, &v, err);
    if (rc) return rc < 0 ? rc : 0;
    for (size_t i = 1; i < n; i++)
        if (!(v[i] > v[i - 1])) {
            rc = gcp_error_set(err, GCP_ERR_VALUE,
                               "%s: axis /%s is not strictly increasing at index %zu (%g after %g)",
                               path, name, i, v[i], v[i - 1]);
            break;
        }
    for (size_t i = 0; rc == 0 && i < n; i++)
        if (fabs(v[i] - (x0 + (double)i * h)) > 1e-9 * h + 1e-12 * fabs(x0)) {
            rc = gcp_error_set(err, GCP_ERR_VALUE,
                               "%s: axis /%s is not uniform or disagrees with the origin/spacing "
                               "attributes at index %zu (%.12g, expected %.12g)",
                               path, name, i, v[i], x0 + (double)i * h);
        }
    free(v);
    return rc;
}

int gcp_grid_read(const char *path, struct gcp_grid_data *d, struct gcp_error *err)
{
    memset(d, 0, sizeof *d);
    d->r_outer = INFINITY;
    d->z_max = INFINITY;
    struct h5quiet q;
    h5_quiet(&q);
    int rc = 0;
    hid_t f = -1;
    FILE *probe = fopen(path, "rb");
    if (!probe) {
        rc = gcp_error_set(err, GCP_ERR_IO, "%s: cannot open grid file (no such file?)", path);
        goto out;
    }
    fclose(probe);
    if (H5Fis_hdf5(path) <= 0) {
        rc = gcp_error_set(err, GCP_ERR_IO, "%s: not an HDF5 file", path);
        goto out;
    }
    f = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
    if (f < 0) {
        rc = gcp_error_set(err, GCP_ERR_IO, "%s: cannot open HDF5 file", path);
        goto out;
    }
    char geom[64] = "";
    if (attr_string(f, "geometry", geom, sizeof geom) < 0) {
        rc = gcp_error_set(err, GCP_ERR_VALUE,
                           "%s: attribute /geometry %s (expected the string 'axisymmetric' or "
                           "'cartesian')",
                           path, H5Aexists(f, "geometry") > 0 ? "is not a readable string" : "missing");
        goto out;
    }
    int nd;
    const char *const *bn, *const *en, *const *ax;
    if (strcmp(geom, "axisymmetric") == 0) {
        d->geometry = GCP_GRID_AXISYMMETRIC;
        nd = 2, bn = AXI_B, en = AXI_E, ax = AXI_AX;
    } else if (strcmp(geom, "cartesian") == 0) {
        d->geometry = GCP_GRID_CARTESIAN;
        nd = 3, bn = CART_B, en = CART_E, ax = CART_AX;
    } else {
        rc = gcp_error_set(err, GCP_ERR_VALUE,
                           "%s: attribute /geometry = '%s', expected 'axisymmetric' or 'cartesian'",
                           path, geom);
        goto out;
    }
    char units[32] = "SI";
    if (attr_string(f, "units", units, sizeof units) == 0 && strcmp(units, "SI") != 0) {
        rc = gcp_error_set(err, GCP_ERR_VALUE, "%s: attribute /units = '%s', expected 'SI'", path,
                           units);
        goto out;
    }
    const char *an[2] = {"origin", "spacing"};
    double *av[2] = {d->origin, d->spacing};
    for (int k = 0; k < 2; k++) {
        int a = attr_doubles(f, an[k], av[k], nd);
        if (a < 0) {
            rc = gcp_error_set(err, GCP_ERR_VALUE, "%s: attribute /%s %s (expected %d doubles [m])",
                               path, an[k], a == -1 ? "missing" : "has the wrong size", nd);
            goto out;
        }
    }
    /* origin and spacing are checked apart: a NaN origin reported as a
     * spacing error sends the user to the wrong attribute */
    for (int k = 0; k < nd; k++)
        if (!isfinite(d->origin[k])) {
            rc = gcp_error_set(err, GCP_ERR_VALUE,
                               "%s: attribute /origin[%d] = %g (axis %s): not finite", path, k,
                               d->origin[k], ax[k]);
            goto out;
        }
    for (int k = 0; k < nd; k++)
        if (!(d->spacing[k] > 0.0 && isfinite(d->spacing[k]))) {
            rc = gcp_error_set(err, GCP_ERR_VALUE,
                               "%s: attribute /spacing[%d] = %g (axis %s): must be positive and "
                               "finite",
                               path, k, d->spacing[k], ax[k]);
            goto out;
        }
    double v1;
    if (attr_doubles(f, "r_inner", &v1, 1) == 0) d->r_inner = v1;
    if (attr_doubles(f, "r_outer", &v1, 1) == 0) d->r_outer = v1;
    if (attr_doubles(f, "z_max", &v1, 1) == 0) d->z_max = v1;
    /* shape from the first B dataset present (Bphi / By always required) */
    const char *first = bn[1];
    if (H5Lexists(f, first, H5P_DEFAULT) <= 0) {
        rc = gcp_error_set(err, GCP_ERR_VALUE, "%s: dataset /%s missing (the B components %s %s %s "
                           "are required%s)",
                           path, first, bn[0], bn[1], bn[2],
                           nd == 2 ? "; BR and BZ may be replaced by psi" : "");
        goto out;
    }
    hsize_t dims[3] = {0, 0, 0};
    {
        hid_t ds = H5Dopen2(f, first, H5P_DEFAULT);
        hid_t sp = H5Dget_space(ds);
        int rank = H5Sget_simple_extent_ndims(sp);
        if (rank == nd) H5Sget_simple_extent_dims(sp, dims, NULL);
        H5Sclose(sp);
        H5Dclose(ds);
        if (rank != nd) {
            rc = gcp_error_set(err, GCP_ERR_VALUE, "%s: dataset /%s: rank %d, expected %d (%s)",
                               path, first, rank, nd,
                               nd == 2 ? "nZ, nR" : "nz, ny, nx");
            goto out;
        }
    }
    for (int k = 0; k < nd; k++) d->n[k] = (size_t)dims[nd - 1 - k];
    for (int k = 0; k < 3; k++) {
        rc = read_dataset(path, f, bn[k], nd, dims, ax, &d->B[k], err);
        if (rc < 0) goto out;
    }
    rc = 0;
    if (nd == 2) {
        rc = read_dataset(path, f, "psi", nd, dims, ax, &d->psi, err);
        if (rc < 0) goto out;
        rc = 0;
    }
    if ((!d->B[0] || !d->B[2]) && !d->psi) {
        rc = gcp_error_set(err, GCP_ERR_VALUE, "%s: dataset /%s missing (and no /psi to replace it)",
                           path, d->B[0] ? bn[2] : bn[0]);
        goto out;
    }
    int ne = 0;
    for (int k = 0; k < 3; k++) {
        rc = read_dataset(path, f, en[k], nd, dims, ax, &d->E[k], err);
        if (rc < 0) goto out;
        ne += d->E[k] != NULL;
    }
    rc = 0;
    if (ne != 0 && ne != 3) {
        rc = gcp_error_set(err, GCP_ERR_VALUE, "%s: E needs all three datasets %s %s %s (%d found)",
                           path, en[0], en[1], en[2], ne);
        goto out;
    }
    for (int k = 0; k < nd; k++)
        if ((rc = check_axis(path, f, ax[k], d->n[k], d->origin[k], d->spacing[k], err)) < 0)
            goto out;
    rc = 0;
out:
    if (f >= 0) H5Fclose(f);
    h5_loud(&q);
    if (rc) gcp_grid_data_free(d);
    return rc;
}

/* ---- writing ------------------------------------------------------------- */

static int put_attr_str(hid_t f, const char *name, const char *v)
{
    hid_t t = H5Tcopy(H5T_C_S1);
    H5Tset_size(t, strlen(v) + 1);
    hid_t sp = H5Screate(H5S_SCALAR);
    hid_t a = H5Acreate2(f, name, t, sp, H5P_DEFAULT, H5P_DEFAULT);
    herr_t e = a >= 0 ? H5Awrite(a, t, v) : -1;
    if (a >= 0) H5Aclose(a);
    H5Sclose(sp);
    H5Tclose(t);
    return e < 0 ? -1 : 0;
}

static int put_attr_dbl(hid_t o, const char *name, const double *v, int n)
{
    const hsize_t dim[1] = {(hsize_t)n};
    hid_t sp = H5Screate_simple(1, dim, NULL);
    hid_t a = H5Acreate2(o, name, H5T_IEEE_F64LE, sp, H5P_DEFAULT, H5P_DEFAULT);
    herr_t e = a >= 0 ? H5Awrite(a, H5T_NATIVE_DOUBLE, v) : -1;
    if (a >= 0) H5Aclose(a);
    H5Sclose(sp);
    return e < 0 ? -1 : 0;
}

static int put_dataset(hid_t f, const char *name, int nd, const hsize_t *dims, const double *v,
                       const char *units)
{
    hid_t sp = H5Screate_simple(nd, dims, NULL);
    hid_t ds = H5Dcreate2(f, name, H5T_IEEE_F64LE, sp, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    herr_t e = ds >= 0 ? H5Dwrite(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v) : -1;
    if (ds >= 0) {
        if (units) put_attr_str(ds, "units", units);
        H5Dclose(ds);
    }
    H5Sclose(sp);
    return e < 0 ? -1 : 0;
}

int gcp_grid_write(const char *path, const struct gcp_grid_data *d, const char *source,
                   struct gcp_error *err)
{
    const int axi = d->geometry == GCP_GRID_AXISYMMETRIC;
    const int nd = axi ? 2 : 3;
    const char *const *bn = axi ? AXI_B : CART_B, *const *en = axi ? AXI_E : CART_E;
    const char *const *ax = axi ? AXI_AX : CART_AX;
    char tmp[4096];
    if (snprintf(tmp, sizeof tmp, "%s.tmp-%ld", path, (long)getpid()) >= (int)sizeof tmp)
        return gcp_error_set(err, GCP_ERR_IO, "%s: path too long", path);
    struct h5quiet q;
    h5_quiet(&q);
    int bad = 0;
    hid_t f = H5Fcreate(tmp, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    if (f < 0) {
        h5_loud(&q);
        return gcp_error_set(err, GCP_ERR_IO, "%s: cannot create file", tmp);
    }
    const int ver = GRID_FORMAT_VERSION;
    {
        hid_t sp = H5Screate(H5S_SCALAR);
        hid_t a = H5Acreate2(f, "gcpush_grid_version", H5T_STD_I32LE, sp, H5P_DEFAULT, H5P_DEFAULT);
        bad |= a < 0 || H5Awrite(a, H5T_NATIVE_INT, &ver) < 0;
        if (a >= 0) H5Aclose(a);
        H5Sclose(sp);
    }
    bad |= put_attr_str(f, "geometry", axi ? "axisymmetric" : "cartesian");
    bad |= put_attr_str(f, "units", "SI");
    bad |= put_attr_str(f, "coordinates", axi ? "R Z" : "x y z");
    if (source) bad |= put_attr_str(f, "source", source);
    bad |= put_attr_dbl(f, "origin", d->origin, nd);
    bad |= put_attr_dbl(f, "spacing", d->spacing, nd);
    if (d->r_inner > 0.0) bad |= put_attr_dbl(f, "r_inner", &d->r_inner, 1);
    if (isfinite(d->r_outer) && d->r_outer > 0.0) bad |= put_attr_dbl(f, "r_outer", &d->r_outer, 1);
    if (isfinite(d->z_max) && d->z_max > 0.0) bad |= put_attr_dbl(f, "z_max", &d->z_max, 1);
    hsize_t dims[3];
    for (int k = 0; k < nd; k++) dims[k] = d->n[nd - 1 - k];
    for (int k = 0; k < 3; k++) {
        if (d->B[k]) bad |= put_dataset(f, bn[k], nd, dims, d->B[k], "T");
        if (d->E[k]) bad |= put_dataset(f, en[k], nd, dims, d->E[k], "V/m");
    }
    if (axi && d->psi) bad |= put_dataset(f, "psi", nd, dims, d->psi, "Wb/rad");
    for (int k = 0; k < nd && !bad; k++) {
        double *v = malloc(d->n[k] * sizeof *v);
        if (!v) {
            bad = 1;
            break;
        }
        for (size_t i = 0; i < d->n[k]; i++) v[i] = d->origin[k] + (double)i * d->spacing[k];
        const hsize_t n1[1] = {d->n[k]};
        bad |= put_dataset(f, ax[k], 1, n1, v, "m");
        free(v);
    }
    bad |= H5Fclose(f) < 0;
    h5_loud(&q);
    if (bad) {
        remove(tmp);
        return gcp_error_set(err, GCP_ERR_HDF5, "%s: writing the grid failed", path);
    }
    if (rename(tmp, path) != 0) {
        remove(tmp);
        return gcp_error_set(err, GCP_ERR_IO, "%s: cannot rename %s to it", path, tmp);
    }
    return 0;
}

/* ---- what builds on them --------------------------------------------------- */

int gcp_field_grid_load(const char *path, enum gcp_grid_interp interp, int use_psi,
                        struct gcp_field **out, struct gcp_error *err)
{
    return gcp_field_grid_load_with(path, gcp_grid_read, interp, use_psi, out, err);
}

int gcp_grid_sample_write(const struct gcp_field *src, const struct gcp_grid_spec *spec,
                          const char *path, struct gcp_error *err)
{
    struct gcp_grid_data d;
    int rc = gcp_grid_sample(src, spec, &d, err);
    if (rc) return rc;
    char source[128];
    snprintf(source, sizeof source, "gcp_grid_sample of field '%s' at t = %g s", src->type->name,
             spec->t);
    rc = gcp_grid_write(path, &d, source, err);
    gcp_grid_data_free(&d);
    return rc;
}

const struct gcp_readers gcp_io_readers = {.states = gcp_initfile_read, .grid = gcp_grid_read};

int gcp_grid_command(const char *path, char *out, size_t outlen, struct gcp_error *err)
{
    struct gcp_field *field = NULL;
    struct gcp_grid_spec spec;
    int rc = gcp_grid_command_parse(path, &gcp_io_readers, &field, &spec, out, outlen, err);
    if (!rc) rc = gcp_grid_sample_write(field, &spec, out, err);
    gcp_field_free(field);
    return rc < 0 ? rc : 0;
}
