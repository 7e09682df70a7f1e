/* gcpush/run.h -- run files to scenes.
 *
 * A run file (INI, read with libinih) describes a scene: field, particle
 * populations, integrator, output.  gcp_scene_load() validates all of it
 * before anything runs; every error names file, line and key.  Initial
 * states are a pure function of (seed, particle id), so any split of the
 * ensemble over ranks produces the same particles.
 */
#ifndef GCPUSH_RUN_H
#define GCPUSH_RUN_H

#include <stdint.h>

#include "error.h"
#include "field.h"
#include "hybrid.h"
#include "invariants.h"
#include "particles.h"
#include "pusher.h"
#include "section.h"
#include "units.h"
#include "api.h"
GCP_API_BEGIN

#ifdef __cplusplus
extern "C" {
#endif

struct gcp_sweep_spec;

enum gcp_spread { GCP_FIXED = 0, GCP_LIN = 1, GCP_LOG = 2 };

/* A range "a .. b [lin|log]" or a single value (lo == hi, GCP_FIXED). */
struct gcp_range {
    double lo, hi;        /* [SI unit of the quantity] */
    enum gcp_spread spread;
};

enum gcp_placement { GCP_PLACE_POSITION = 0, GCP_PLACE_L_SHELL = 1 };
enum gcp_aim { GCP_AIM_DIRECTION = 0, GCP_AIM_PITCH = 1, GCP_AIM_ISOTROPIC = 2 };

/* Initial states given as plain arrays (from `[particles] file = ...`): full
 * orbit x, u; or guiding centre X (in x), ppar, mu, used as given.  The run
 * layer reads no files of states itself (no HDF5 here): a gcp_states_reader
 * passed in by the caller does (gcp_initfile_read, io.h, for gcpush's own
 * layout).  Owned by the population (freed by gcp_scene_free). */
struct gcp_states {
    int64_t n;          /* rows */
    int gc;             /* [bool] guiding-centre rows: X, ppar, mu; else x, u */
    double *x;          /* [m] (n x 3) x, or X for guiding-centre rows */
    double *u;          /* [m/s] (n x 3) u = gamma v (full orbit; NULL for gc) */
    double *ppar, *mu;  /* [kg m/s], [J/T] (n) (gc; NULL for full orbit) */
    int64_t nonfinite;  /* rows holding a NaN or Inf (those particles end NONFINITE) */
};

/* Reads the states of file `path` (as written in the run file) for a method
 * of kind gc (1: guiding centre, 0: full orbit) into *out (malloc'ed
 * arrays).  Returns 0, or non-zero with a one-line reason in why. */
typedef int (*gcp_states_reader)(const char *path, int gc, struct gcp_states *out, char *why,
                                 size_t whylen);

/* The file readers the caller hands the run layer, which reads no binary
 * files itself: a NULL member refuses the key that needs it, naming file,
 * line and key.  gcp_io_readers (grid_file.h) holds gcpush's HDF5 readers. */
struct gcp_readers {
    gcp_states_reader states; /* `[particles] file = ...` (gcp_initfile_read, io.h) */
    gcp_grid_reader grid;     /* `[field] file = ...` of the grid model (gcp_grid_read) */
};

/* One [particles] or [particles.NAME] section. */
struct gcp_population {
    char name[32];
    struct gcp_species species;
    int64_t count;          /* particles in this population */
    int64_t first_id;       /* ids first_id .. first_id + count - 1 */
    struct gcp_range energy;/* [J] kinetic energy */
    enum gcp_placement placement;
    double position[3];     /* [m] (GCP_PLACE_POSITION) */
    struct gcp_range L;     /* [1] equatorial L shell (GCP_PLACE_L_SHELL) */
    struct gcp_range longitude; /* [rad] of the L-shell start */
    enum gcp_aim aim;
    double direction[3];    /* [1] unit velocity direction (GCP_AIM_DIRECTION) */
    struct gcp_range pitch; /* [rad] pitch angle to the local B (equatorial for L shells) */
    int has_phase;          /* [bool] gyrophase given; else uniform random */
    double phase;           /* [rad] gyrophase about the local B */
    double dt;              /* [s] resolved step of this population */
    int64_t nsteps;         /* steps per particle (duration / dt) */
    int64_t trajectory_every; /* steps between trajectory samples; 0: none */
    char file[1024];        /* `file` key: states from this file ("" : drawn from the keys) */
    struct gcp_states init; /* the file's states (n == count), when file[0] */
};

struct gcp_scene {
    char *path;             /* run file path */
    char *text;             /* full run file text (stored in the output) */
    char name[64];
    char field_model[32];
    struct gcp_field *field;
    uint64_t seed;
    struct gcp_population *pops;
    size_t npop;
    int64_t total;          /* particles in all populations */
    const struct gcp_pusher_type *pusher;
    int hybrid;             /* [bool] method = hybrid: pusher is gcp_pusher_hybrid, options below */
    struct gcp_hybrid_opts hybrid_opts; /* [integrator] gc, fo, switch_to_fo, switch_to_gc, fo_dt */
    double duration;        /* [s] resolved run time */
    double duration_given;  /* as written: seconds or periods */
    enum gcp_period duration_period;
    double tolerance;       /* [1] adaptive methods: relative error per step (0: the method's default) */
    double adiabaticity_max;/* [1] guiding centre: eps = rho |grad B|/B (or rho/R_c) above which a
                               particle is NONADIABATIC */
    int fast_arith;         /* [bool] [integrator] arithmetic = fast (full orbit, opt-in): the
                               pushes run with GCP_BLOCK_FAST_ARITH (pusher.h) */
    double dt_given;
    enum gcp_period dt_period;
    char output[1024];      /* output file path */
    int compression;        /* trajectory deflate level 1..9; 0: none (chunked, unfiltered) */
    double checkpoint_every;/* [s] wall time between checkpoints; 0: only on SIGINT/SIGTERM */
    int64_t trajectory_samples; /* samples per particle, incl. the initial one (0: none) */
    unsigned invariants;    /* [diagnostics] invariants: GCP_INV_* bits (invariants.h); 0: none */
    unsigned events;        /* [diagnostics] events: GCP_EVT_* bits; 0: none */
    struct gcp_sweep_spec *sweep; /* the [sweep] section (sweep.h), read with the rest; NULL: none */
    int64_t sample_every;   /* [diagnostics] sample_every: steps of the population's dt between
                               cadence samples (GCP_OBSERVER_SAMPLE_STEPS by default) */
};

/* Reads, validates and resolves a run file (field built, periods turned
 * into seconds: the duration with the first particle's period; a step in
 * periods with the shortest initial period in each population (gyro: over
 * all its particles; bounce, drift: over its first 1000), so every particle
 * gets at least the asked resolution).  Returns 0 or a negative code
 * with err set; *out is NULL on error. */
int gcp_scene_load(const char *path, struct gcp_scene **out, struct gcp_error *err);
/* The same from text in memory (path is used in messages only). */
int gcp_scene_parse(const char *path, const char *text, struct gcp_scene **out,
                    struct gcp_error *err);
/* The same, with readers for `[particles] file = ...` and for a grid
 * field's `[field] file = ...` (the two above have none, and refuse those
 * keys; so does a NULL rd or member): &gcp_io_readers (grid_file.h) reads
 * gcpush's HDF5 files.  A file's path is used as written: relative paths are
 * relative to the working directory, like [output] file. */
int gcp_scene_load_with(const char *path, const struct gcp_readers *rd, struct gcp_scene **out,
                        struct gcp_error *err);
int gcp_scene_parse_with(const char *path, const char *text, const struct gcp_readers *rd,
                         struct gcp_scene **out, struct gcp_error *err);
void gcp_scene_free(struct gcp_scene *s);

/* Initial full-orbit state of particle id (0 <= id < total): position x [m],
 * u = gamma v [m/s], and its population index.  A pure function of
 * (scene seed, id), or the file's row.  A population of guiding-centre
 * states from a file has no full-orbit state: x and u are NaN.  Returns 0,
 * or GCP_ERR_VALUE for an id out of range. */
int gcp_scene_initial_state(const struct gcp_scene *s, int64_t id, int *pop, double x[3],
                            double u[3]);
/* Initial guiding centre of particle id when its population has one given
 * (a file of guiding-centre states): X [m], ppar [kg m/s], mu [J/T] and 1;
 * 0 when the state is to be made from the full orbit (gcp_gc_from_fo). */
int gcp_scene_initial_gc(const struct gcp_scene *s, int64_t id, double X[3], double *ppar,
                         double *mu);

/* `gcpush grid FILE.run` up to the sampling (gcp_grid_command, grid_file.h,
 * samples and writes): builds the file's [scene] field from its [field]
 * keys (rd's readers, as gcp_field_from_section_with) into *field (free
 * with gcp_field_free) and reads its [grid] section into spec and out (the
 * grid file's path).  0, or a negative code with err set and *field NULL. */
struct gcp_grid_spec;
int gcp_grid_command_parse(const char *path, const struct gcp_readers *rd,
                           struct gcp_field **field, struct gcp_grid_spec *spec, char *out,
                           size_t outlen, struct gcp_error *err);

/* The [grid] section of a `gcpush grid FILE.run` run file:
 *   geometry = axisymmetric | cartesian
 *   file     = fields/data/dipole.h5           (output)
 *   R_min, R_max, Z_min, Z_max = lengths; nR, nZ = node counts   (axisymmetric)
 *   x_min .. z_max, nx, ny, nz                                     (cartesian)
 *   time     = 0 s                              (optional)
 * Fills spec and path (pathlen bytes).  0 or a negative code (err set). */
int gcp_grid_spec_from_section(struct gcp_section *sec, struct gcp_grid_spec *spec, char *path,
                               size_t pathlen, struct gcp_error *err);

/* Builds a field from its run-file section ([field]): reads the keys the
 * model declares (gcp_field_type.keys, with their units), rejects others,
 * and calls the model's build (src/run/field_keys.c).  Returns 0, or a
 * negative code with err filled ("file:line: [field] key: ..."). */
int gcp_field_from_section(const char *model, struct gcp_section *sec, struct gcp_field **out,
                           struct gcp_error *err);
/* The same with rd's grid reader for a grid model's file (NULL rd or
 * rd->grid: refused, as gcp_field_from_section does). */
int gcp_field_from_section_with(const char *model, struct gcp_section *sec,
                                const struct gcp_readers *rd, struct gcp_field **out,
                                struct gcp_error *err);

/* gcp_period_of (the gyro, bounce and drift periods) is a diagnostic:
 * invariants.h, included here. */

struct gcp_results;

/* Work distribution for gcp_scene_push(): next() returns the next chunk
 * index to push (chunks are gcp_scene_chunk_count() slices of the ensemble),
 * or -1 when there is none left (a serial run counts up; MPI ranks share an
 * atomic counter); done() (may be NULL) is told after each chunk, for
 * progress and checkpoints. */
struct gcp_schedule {
    int64_t (*next)(void *ctx);
    void (*done)(void *ctx, struct gcp_results *res, int64_t particles, int64_t steps);
    void *ctx;
    /* (may be NULL) a flag polled between slices of a chunk's push: when it
     * turns non-zero the chunk in progress is dropped (its particles stay
     * to be pushed, e.g. after a restart) and gcp_scene_push returns. */
    const volatile int *stop;
};

/* Particles per chunk at most: one block of the stepper, one population. */
#define GCP_CHUNK 64
/* ... and at least (unless a population is smaller). */
#define GCP_CHUNK_MIN 32

/* Particles per chunk of the scene: GCP_CHUNK for large ensembles, down to
 * GCP_CHUNK_MIN so that a small one still makes several chunks (about 8) to share
 * among the ranks (the flagship's 90 particles were 3 chunks, one a
 * population, which 2 ranks cannot share evenly: 1.24x; in chunks of 32,
 * 5 chunks: 1.45-1.5x).  Smaller chunks cost more per particle (8: +21%,
 * 16: +10%, 32: +3% on one rank, gc-gl4 block solve and per-chunk work).
 * A population larger than this is cut into ceil(count / size) chunks of
 * its even share rounded up to whole 8-lane vectors (the last chunk the
 * rest: the flagship's 40 electrons 24 + 16, not 32 + 8; driver.c).
 * A function of the scene alone, never of the rank count: a checkpoint's
 * chunks are the same chunks on restart with any number of ranks. */
int64_t gcp_scene_chunk_size(const struct gcp_scene *s);
int64_t gcp_scene_chunk_count(const struct gcp_scene *s);
/* Ids [first, first + count) of chunk c. */
void gcp_scene_chunk(const struct gcp_scene *s, int64_t c, int64_t *first, int64_t *count);
/* The chunk holding particle id. */
int64_t gcp_scene_chunk_of(const struct gcp_scene *s, int64_t id);

/* Pushes the chunks handed out by sched->next() and appends their rows to
 * res.  Per-particle failures are statuses; returns 0, or GCP_ERR_NOMEM. */
int gcp_scene_push(const struct gcp_scene *s, struct gcp_results *res,
                   const struct gcp_schedule *sched, struct gcp_error *err);

#ifdef __cplusplus
}
#endif
GCP_API_END
#endif
