/* HDF5 attributes shared by every output file gcpush writes (the ensemble
 * output and the sweep file): scalar string and number attributes, and the
 * root attributes of DESIGN.md's layout.  A failure sets *bad. */
#include <string.h>

#include <hdf5.h>

#include "gcpush/pusher.h"
#include "io_priv.h"

#ifndef GCP_VERSION
#define GCP_VERSION "unknown"
#endif
#ifndef GCP_GIT_HASH
#define GCP_GIT_HASH "unknown"
#endif
#ifndef GCP_BUILD_FLAGS
#define GCP_BUILD_FLAGS "unknown"
#endif

void gcp_h5_attr_str(int *bad, int64_t loc, const char *name, const char *value)
{
    hid_t t = H5Tcopy(H5T_C_S1);
    H5Tset_size(t, strlen(value) + 1);
    H5Tset_strpad(t, H5T_STR_NULLTERM);
    hid_t sp = H5Screate(H5S_SCALAR);
    hid_t a = H5Acreate2((hid_t)loc, name, t, sp, H5P_DEFAULT, H5P_DEFAULT);
    if (a < 0 || H5Awrite(a, t, value) < 0) *bad = 1;
    if (a >= 0) H5Aclose(a);
    H5Sclose(sp);
    H5Tclose(t);
}

void gcp_h5_attr_num(int *bad, int64_t loc, const char *name, int64_t type, const void *v)
{
    hid_t sp = H5Screate(H5S_SCALAR);
    hid_t a = H5Acreate2((hid_t)loc, name, (hid_t)type, sp, H5P_DEFAULT, H5P_DEFAULT);
    if (a < 0 || H5Awrite(a, (hid_t)type, v) < 0) *bad = 1;
    if (a >= 0) H5Aclose(a);
    H5Sclose(sp);
}

void gcp_h5_plists(const struct gcp_scene *sc, int64_t fcpl, int64_t fapl)
{
    /* An attribute in the object header holds 64 KiB at most: a longer run
     * file failed the write after the whole run.  Dense attribute storage
     * (HDF5 1.8 file format) lifts that limit; smaller run files keep the
     * default layout. */
    if (strlen(sc->text) + strlen(sc->path) < 32768) return;
    H5Pset_attr_phase_change((hid_t)fcpl, 0, 0);
    H5Pset_libver_bounds((hid_t)fapl, H5F_LIBVER_V18, H5F_LIBVER_V18);
}

void gcp_h5_root_attrs(int *bad, int64_t file, const struct gcp_scene *sc, int nranks)
{
    gcp_h5_attr_str(bad, file, "gcpush_version", GCP_VERSION);
    gcp_h5_attr_str(bad, file, "git_hash", GCP_GIT_HASH);
    gcp_h5_attr_str(bad, file, "build_flags", GCP_BUILD_FLAGS);
    gcp_h5_attr_str(bad, file, "run_file", sc->text);
    gcp_h5_attr_str(bad, file, "run_file_name", sc->path);
    gcp_h5_attr_str(bad, file, "units", "SI");
    gcp_h5_attr_str(bad, file, "scene", sc->name);
    gcp_h5_attr_str(bad, file, "field", sc->field_model);
    gcp_h5_attr_str(bad, file, "method", sc->pusher->name);
    /* the arithmetic the method's steps ran in: `fast` only where it was
     * asked and this CPU, build, method and field have the fast step */
    gcp_h5_attr_str(bad, file, "arithmetic",
                    sc->fast_arith && sc->field && gcp_arithmetic_fast_runs(sc->pusher, sc->field)
                        ? "fast"
                        : "ieee");
    gcp_h5_attr_num(bad, file, "ranks", H5T_NATIVE_INT, &nranks);
    gcp_h5_attr_num(bad, file, "duration", H5T_NATIVE_DOUBLE, &sc->duration);
    gcp_h5_attr_num(bad, file, "seed", H5T_NATIVE_UINT64, &sc->seed);
    gcp_h5_attr_num(bad, file, "particles", H5T_NATIVE_INT64, &sc->total);
}
