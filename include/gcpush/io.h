/* gcpush/io.h -- per-rank results of a scene and the HDF5 output file.
 *
 * Each rank holds the rows of the particles it pushed; gcp_output_write()
 * writes them collectively into one file (parallel HDF5 over MPI-IO), to a
 * temporary name renamed on success, so a failed run leaves no partial file.
 * The layout is the contract of DESIGN.md ("HDF5 output"); analysis/ reads it.
 */
#ifndef GCPUSH_IO_H
#define GCPUSH_IO_H

#include <stdint.h>

#include <mpi.h>

#include "error.h"
#include "invariants.h"
#include "results.h"
#include "run.h"
#include "api.h"
GCP_API_BEGIN

#ifdef __cplusplus
extern "C" {
#endif

/* Writes the scene's output file from every rank's results (collective on
 * comm).  Returns 0 on every rank, or the same negative code on every rank
 * with err set; on failure no output file is left behind. */
int gcp_output_write(const struct gcp_scene *sc, const struct gcp_results *r, MPI_Comm comm,
                     struct gcp_error *err);

/* Progress lines on stderr (rank 0) during writes longer than 5 s; on by
 * default, 0 turns them off (--quiet). */
void gcp_output_progress(int on);
/* Checks early (collectively) that the output path can be created, so a
 * long run does not end in an unwritable directory.  0 or GCP_ERR_IO. */
int gcp_output_probe(const struct gcp_scene *sc, MPI_Comm comm, struct gcp_error *err);

/* Checkpoints (one file per writing rank: OUT.ckpt.RANK; see checkpoint.c). */
int gcp_checkpoint_write(const struct gcp_scene *sc, struct gcp_results *r, int rank,
                         struct gcp_error *err);
/* The checkpoint files of output path `output` (malloc'ed array of strdup'ed names). */
int gcp_checkpoint_list(const char *output, char ***files, size_t *n);
/* The temporaries an interrupted run of `output` left: OUT.tmp-PID (the
 * output write) and OUT.ckpt.N.tmp (a checkpoint write); same conventions. */
int gcp_output_stale_list(const char *output, char ***files, size_t *n);
/* The run file text and path a checkpoint was made from (malloc'ed). */
int gcp_checkpoint_read_text(const char *file, char **text, char **path, struct gcp_error *err);
/* Appends a checkpoint's rows to r (after checking it belongs to sc). */
int gcp_checkpoint_load(const char *file, const struct gcp_scene *sc, struct gcp_results *r,
                        struct gcp_error *err);
/* A gcp_states_reader (run.h) for HDF5 files in the layout gcpush writes
 * under /particles/initial: x, u for full orbits (gc = 0), X, ppar, mu for
 * guiding centres (gc = 1).  See initfile.c for what it refuses. */
int gcp_initfile_read(const char *path, int gc, struct gcp_states *out, char *why,
                      size_t whylen);
/* On restart: the checkpointed initial states of r's rows from file
 * populations must equal the file's now.  0, or GCP_ERR_STATE with err set. */
int gcp_initfile_check_results(const struct gcp_scene *sc, const struct gcp_results *r,
                               struct gcp_error *err);

#ifdef __cplusplus
}
#endif
GCP_API_END
#endif
