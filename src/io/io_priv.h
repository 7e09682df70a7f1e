/* Private to io/: HDF5 attributes of the output files; the column table of
 * struct gcp_results (run/results_priv.h, the run layer's). */
#ifndef GCPUSH_IO_PRIV_H
#define GCPUSH_IO_PRIV_H

#include <stddef.h>
#include <stdint.h>

#include "gcpush/io.h"
#include "run/results_priv.h"

/* HDF5 attributes common to the output files (h5attr.c); loc and type are
 * hid_t values (int64_t here, so this header needs no hdf5.h).  A failure
 * sets *bad. */
void gcp_h5_attr_str(int *bad, int64_t loc, const char *name, const char *value);
void gcp_h5_attr_num(int *bad, int64_t loc, const char *name, int64_t type, const void *v);
/* File creation and access properties (hid_t) for sc's output: dense
 * attribute storage when the run file text is too long for a compact one. */
void gcp_h5_plists(const struct gcp_scene *sc, int64_t fcpl, int64_t fapl);
/* The root attributes of every gcpush output file (DESIGN.md, HDF5 output). */
void gcp_h5_root_attrs(int *bad, int64_t file, const struct gcp_scene *sc, int nranks);

#endif
