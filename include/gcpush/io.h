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
#include "run.h"
#include "api.h"
GCP_API_BEGIN

#ifdef __cplusplus
extern "C" {
#endif

struct gcp_results {
    int64_t n, cap;        /* rows held, rows allocated */
    int64_t S;             /* trajectory samples per particle (0: none) */
    int gc;                /* [bool] guiding-centre rows: X in x, p_par and mu instead of u */
    int64_t *id;           /* particle id of each row */
    int32_t *pop;          /* population index */
    double *x0, *u0;       /* [m], [m/s] initial state (n x 3) */
    double *t;             /* [s] final time */
    double *x, *u;         /* [m], [m/s] final state (n x 3); guiding centre: x is X, no u */
    double *X0, *ppar0, *mu0; /* [m], [kg m/s], [J/T] initial guiding centre (gc only) */
    double *ppar, *mu;     /* [kg m/s], [J/T] final guiding centre (gc only) */
    int32_t *status;       /* enum gcp_status */
    int32_t *step_failure; /* enum gcp_step_failure: why a STEP_FAILED particle failed, else 0 */
    int64_t *steps;        /* steps taken */
    double *cpu;           /* [s] CPU time per particle */
    double *traj_t;        /* [s] (n x S), NaN after count */
    double *traj_x, *traj_u; /* [m], [m/s] (n x S x 3); traj_u full orbit only */
    double *traj_ppar;     /* [kg m/s] (n x S), guiding centre only */
    int64_t *traj_count;   /* valid samples per particle */
    double *L0;            /* [1] dipole L of the initial guiding centre (NaN off a dipole) */
    double *aeq0;          /* [rad] initial equatorial pitch angle (dipole mapping) */
    double *alc0;          /* [rad] loss cone at L0 for the field's atmosphere */
    int hybrid;            /* [bool] method = hybrid rows: x, u and X0, ppar0, mu0, ppar, mu, plus: */
    double *Xf;            /* [m] final guiding centre (n x 3) (x is the particle) */
    int32_t *hy_mode;      /* final mode: 0 guiding centre, 1 full orbit */
    int32_t *hy_switches;  /* switches (both directions) */
    double *hy_t_gc, *hy_t_fo; /* [s] time pushed as guiding centre, as full orbit */
    int8_t *traj_mode;     /* (n x S) mode of each sample, -1 after count */
    double rank_cpu;       /* [s] CPU time of this rank's pushing */
    struct gcp_events ev;  /* invariant and loss events of these rows (invariants.h) */
};

/* gc: rows of a guiding-centre pusher (the columns differ).  Set r->hybrid
 * before the first reserve for hybrid rows. */
void gcp_results_init(struct gcp_results *r, int64_t samples, int gc);
/* Bytes of one row of results with `samples` trajectory samples; *largest
 * (when not NULL) gets the widest column's bytes per row. */
int64_t gcp_results_row_bytes(int64_t samples, int gc, int64_t *largest);
/* Makes room for `more` rows; returns 0 or GCP_ERR_NOMEM. */
int gcp_results_reserve(struct gcp_results *r, int64_t more);
/* Sorts rows by particle id (the writer needs them in file order). */
int gcp_results_sort(struct gcp_results *r);
/* Appends src's rows to dst (same sample count); 0, GCP_ERR_NOMEM or GCP_ERR_STATE. */
int gcp_results_append(struct gcp_results *dst, const struct gcp_results *src);
void gcp_results_free(struct gcp_results *r);

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

/* Keeps only rows i with keep[i] != 0. */
void gcp_results_drop(struct gcp_results *r, const unsigned char *keep);

#ifdef __cplusplus
}
#endif
GCP_API_END
#endif
