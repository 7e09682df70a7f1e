/* gcpush/sweep.h -- error against run time (work-precision sweeps) and the
 * exact motion in uniform fields.
 *
 * A run file with a [sweep] section asks gcpush to push the scene's
 * particles (one or a small ensemble, each from the same initial state) with
 * every listed method and step (or tolerance, for adaptive methods), to
 * measure each configuration's CPU time and its errors against an analytic
 * answer or a reference run, and to write the table as /sweep:
 *
 *   [sweep]
 *   methods   = boris boris-zu vay higuera-cary gc-rk4 gc-rk45
 *   dt        = 0.2 0.1 0.05 0.025 gyro     # fixed-step methods: values, one unit at the end
 *   tolerance = 1e-6 1e-8 1e-10             # adaptive methods (gc-rk45, gc-rk8pd)
 *   reference = analytic                    # or: boris-zu 1e-3 gyro | gc-rk8pd 1e-12
 *   repeats   = 3                           # optional: timing repeats of short runs (1..20)
 *
 * The duration is [scene] duration; a step in periods is resolved per
 * population like [integrator] dt (gyro: the shortest initial gyro period in
 * the population) and shortened by less than one step so that the run ends
 * at the duration exactly.  Rows are one per (method, dt or tolerance,
 * population); errors are the largest over the population's particles that
 * ended ALIVE in both the run and the reference (the others are counted in
 * `failed`).  Guiding-centre methods start from gcp_gc_from_fo() of the
 * initial state; where the method or the reference is a guiding-centre
 * method, positions are compared as guiding centres (full-orbit finals
 * converted with gcp_gc_from_fo()).
 */
#ifndef GCPUSH_SWEEP_H
#define GCPUSH_SWEEP_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "error.h"
#include "pusher.h"
#include "run.h"
#include "units.h"
#include "api.h"
GCP_API_BEGIN

#ifdef __cplusplus
extern "C" {
#endif

#define GCP_SWEEP_MAX 32          /* methods, steps, tolerances per sweep */
#define GCP_SWEEP_MAX_PARTICLES 1000

struct gcp_sweep_spec {
    size_t nmethods;
    const struct gcp_pusher_type *methods[GCP_SWEEP_MAX];
    size_t ndt;
    double dt_given[GCP_SWEEP_MAX]; /* the numbers as written, in dt_unit */
    double dt_value[GCP_SWEEP_MAX]; /* [s], or [periods] when dt_period is set */
    enum gcp_period dt_period;
    char dt_unit[16];               /* the unit as written ("gyro", "s", "us", ...) */
    size_t ntol;
    double tolerance[GCP_SWEEP_MAX];/* [1] */
    int analytic;                   /* [bool] reference = analytic */
    const struct gcp_pusher_type *ref_method;
    double ref_dt_given;            /* fixed-step reference: step [s] or [periods] */
    char ref_text[64];              /* the reference as written */
    enum gcp_period ref_period;
    double ref_tolerance;           /* adaptive reference: tolerance */
    int repeats;                    /* timing repeats of runs shorter than 0.2 s CPU */
};

/* One configuration on one population.  Errors [SI or 1] are the maximum
 * over the population's comparable particles; NaN where not defined. */
struct gcp_sweep_row {
    char method[32];
    char population[32];
    double dt;                /* [s] resolved step (adaptive: the first trial step) */
    double dt_given;          /* as written, in dt_unit */
    char dt_unit[16];
    double tolerance;         /* [1] adaptive methods; NaN for fixed-step ones */
    double cpu_seconds;       /* [s] best of the timing repeats, all particles of the population */
    int64_t steps;            /* steps taken, all particles */
    int64_t particles;
    int64_t failed;           /* particles not ALIVE at the end (run or reference) */
    double position_error;    /* [m] |x - x_ref| at the end (guiding centres if a GC is involved) */
    double position_error_gyroradius; /* [1] / initial gyroradius p_perp/(|q| B) */
    double position_error_path;       /* [1] / distance travelled, estimated as
                                         max(|v0|, |v_ref,end|) T */
    double gc_position_error; /* [m] |X - X_ref| of the guiding centres (gcp_gc_from_fo of
                                 full-orbit states): the error of the drift and bounce
                                 motion, whatever the gyrophase */
    double gyrophase_error;   /* [rad] signed; uniform fields: accumulated (see sweep.c) */
    double bounce_phase_error;/* [rad] 2 pi T |1/T_b - 1/T_b,ref|: the bounce phase at the end
                                 (T the duration) from the mean measured bounce periods of the
                                 run and the reference (invariant observer, untimed pass;
                                 axisymmetric fields: dipole, mirror, tokamak, R-Z grids,
                                 G-EQDSK); NaN where either has no bounce */
    double drift_phase_error; /* [rad] the same with the mean drift periods (centred-dipole
                                 fields, GCP_CAP_DIPOLE_L) */
    double energy_error;      /* [1] static fields: |H_end - H_0| / W, H = W + q phi, W the
                                 largest kinetic energy of the start and the two ends;
                                 time-dependent fields: |W_end - W_ref| / W_ref */
    double mu_drift;          /* [1/s] relative drift rate |last - first| / first / (t_last -
                                 t_first) of the per-bounce mean mu; NaN with < 2 bounces */
    double K_drift;           /* [1/s] the same for K (per bounce) */
    double Lstar_drift;       /* [1/s] the same for L* (per drift orbit; GCP_CAP_DIPOLE_L) */
};

struct gcp_sweep_table {
    size_t n, cap;
    struct gcp_sweep_row *rows;
    char reference[96];       /* "analytic", "boris-zu dt = 0.001 gyro", "gc-rk8pd tol = 1e-12" */
    double duration;          /* [s] */
};

/* Whether the scene's run file has a [sweep] section (read and validated
 * with the rest of the run file by gcp_scene_load: sc->sweep, errors naming
 * file, line and key). */
int gcp_sweep_wanted(const struct gcp_scene *sc);

/* Where a sweep's rows go: row() is called once per finished row, in
 * order; it returns 0, or a negative code that ends the sweep. */
struct gcp_sweep_sink {
    int (*row)(void *ctx, const struct gcp_sweep_row *row);
    void *ctx;
};

/* Runs the sweep of sc->sweep: each row pushes its population through the
 * same engine as a run of the scene (its start, block push and invariant
 * observer) with the row's method, step and tolerance, and goes to sink.
 * progress (may be NULL) gets one line per finished row.  Returns 0 or a
 * negative code with err set (no analytic answer for this scene, out of
 * memory, the sink's code). */
int gcp_sweep_run(const struct gcp_scene *sc, const struct gcp_sweep_sink *sink, FILE *progress,
                  struct gcp_error *err);

/* A table of rows in memory (sweep_output.c): init sets its reference and
 * duration from sc; gcp_sweep_table_add is a sink's row() (ctx = the
 * table). */
void gcp_sweep_table_init(struct gcp_sweep_table *t, const struct gcp_scene *sc);
int gcp_sweep_table_add(void *table, const struct gcp_sweep_row *row);
void gcp_sweep_table_free(struct gcp_sweep_table *t);

/* The table on `to`, one line per row. */
void gcp_sweep_print(FILE *to, const struct gcp_scene *sc, const struct gcp_sweep_table *t);

/* Writes /sweep (+ the root attributes of every output file) to
 * sc->output through a temporary name, serially (call on one rank). */
int gcp_sweep_write(const struct gcp_scene *sc, const struct gcp_sweep_table *t,
                    struct gcp_error *err);

/* The command line's sweep (gcpush FILE.run when FILE has [sweep]):
 * unless check, runs the sweep on rank 0 of
 * MPI_COMM_WORLD (the other ranks wait: timings are of one process),
 * prints the table (unless quiet) and writes the output.  Collective;
 * returns the process exit status: 0 or 1 (run or output failed), with the
 * message on stderr from rank 0. */
int gcp_sweep_main(const struct gcp_scene *sc, int check, int quiet);

/* ---- exact motion in uniform, static fields ---------------------------
 *
 * E perpendicular to B (E.B = 0 within 1e-12 |E||B|):
 *   |E| < c|B|: in the frame moving with v_d = E x B / B^2 the field is
 *     purely magnetic, B' = B / gamma_d, and the particle follows a helix
 *     (Jackson, Classical Electrodynamics 3rd ed., sec. 12.3 and 11.10);
 *   |E| > c|B|: in the frame moving with c^2 E x B / E^2 it is purely
 *     electric, E' = E / gamma_d, and the motion is hyperbolic (Landau &
 *     Lifshitz vol. 2, sec. 20): u_par' = u_par0' + q E' t'/m, u_perp' const;
 *   |E| = c|B|: no such frame, no answer here.
 * The lab time t maps to the frame time t' through t = gamma_d (t' +
 * beta.x'(t')/c), monotone in t', solved by safeguarded Newton. */
struct gcp_exact_uniform {
    double q, m;
    int regime;          /* 0 free, 1 magnetic (helix), 2 electric (hyperbolic) */
    double beta[3];      /* [1] frame velocity / c */
    double gamma;        /* [1] of the frame */
    double Bp[3], Ep[3]; /* [T], [V/m] fields in the frame */
    double b[3], e1[3], e2[3]; /* frame unit vectors: b along B' (or E'), e2 = b x e1 */
};

/* 0, or GCP_ERR_VALUE (E not perpendicular to B, |E| = c|B|, non-finite). */
int gcp_exact_uniform_init(struct gcp_exact_uniform *ex, const double B[3], const double E[3],
                           double q, double m);
/* State at lab time t from (x0, u0) at t = 0: x [m], u = gamma v [m/s];
 * phase (may be NULL): the unwrapped gyrophase in the drift frame [rad]
 * (NaN outside the magnetic regime).  0, or GCP_ERR_VALUE if the time map fails. */
int gcp_exact_uniform_state(const struct gcp_exact_uniform *ex, const double x0[3],
                            const double u0[3], double t, double x[3], double u[3],
                            double *phase);
/* Gyrophase in (-pi, pi] of momentum u [m/s] (lab) about b in the drift
 * frame's (e1, e2) basis (NaN outside the magnetic regime). */
double gcp_exact_uniform_phase(const struct gcp_exact_uniform *ex, const double u[3]);
/* Gyro frequency in the drift frame [rad/s] (signed with q; NaN outside the
 * magnetic regime) of a particle with lab momentum u. */
double gcp_exact_uniform_omega(const struct gcp_exact_uniform *ex, const double u[3]);

#ifdef __cplusplus
}
#endif
GCP_API_END
#endif /* GCPUSH_SWEEP_H */
