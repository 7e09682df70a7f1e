/* gcpush/grid_file.h -- HDF5 grid files (the io layer, src/io/grid_file.c).
 *
 * The `grid` model (grid.h) interpolates from data in memory; fields/ reads
 * no files of its own.  The data of a grid file comes through a
 * gcp_grid_reader (field.h): gcp_grid_read below for the HDF5 format of
 * fields/README.md.  The one-call ways to the HDF5 reader:
 *   - a field:  gcp_field_grid_load(path, interp, use_psi, &f, &err);
 *   - a scene:  gcp_scene_load_with(path, &gcp_io_readers, &sc, &err) (run.h),
 *     which also reads `[particles] file = ...` (gcp_initfile_read, io.h);
 *   - [field] keys: gcp_field_from_section_with(model, sec, &gcp_io_readers, ...),
 *     or gcp_field_args.grid_read = gcp_grid_read before a type's build.
 * Without a reader, a `grid` field is refused with a message naming the file
 * (and, from a run file, its line and key).
 *
 * Needs no hdf5.h or mpi.h to include; link with libgcpush (HDF5 inside).
 */
#ifndef GCPUSH_GRID_FILE_H
#define GCPUSH_GRID_FILE_H

#include <stddef.h>

#include "error.h"
#include "field.h"
#include "grid.h"
#include "run.h"
#include "api.h"
GCP_API_BEGIN

#ifdef __cplusplus
extern "C" {
#endif

/* Reads a grid file (fields/README.md), checking everything before it
 * returns: rank and shape of every dataset, finite values (the first NaN or
 * Inf is named with its dataset and node index), uniform increasing axes.
 * Errors name the file and the dataset or attribute.  0 or a negative code.
 * A gcp_grid_reader. */
int gcp_grid_read(const char *path, struct gcp_grid_data *d, struct gcp_error *err);
/* Writes d to path (via a temporary name, renamed on success). */
int gcp_grid_write(const char *path, const struct gcp_grid_data *d, const char *source,
                   struct gcp_error *err);

/* The `grid` model from an HDF5 grid file: gcp_field_grid_load_with (grid.h)
 * with gcp_grid_read. */
int gcp_field_grid_load(const char *path, enum gcp_grid_interp interp, int use_psi,
                        struct gcp_field **out, struct gcp_error *err);

/* gcp_grid_sample (grid.h) written to path (gcp_grid_write; the file's
 * `source` attribute names the field and the time).  No file on failure. */
int gcp_grid_sample_write(const struct gcp_field *src, const struct gcp_grid_spec *spec,
                          const char *path, struct gcp_error *err);

/* The HDF5 readers of gcpush's files for the run layer: initial states
 * (gcp_initfile_read, io.h) and grid files (gcp_grid_read). */
extern const struct gcp_readers gcp_io_readers;

/* `gcpush grid FILE.run`: samples the file's [scene] field with its [field]
 * keys onto the grid of its [grid] section (gcp_grid_command_parse, run.h)
 * and writes the grid file, whose path is copied to out.  0, or a negative
 * code with err set (no file left on failure). */
int gcp_grid_command(const char *path, char *out, size_t outlen, struct gcp_error *err);

#ifdef __cplusplus
}
#endif
GCP_API_END
#endif /* GCPUSH_GRID_FILE_H */
