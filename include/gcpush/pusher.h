/* gcpush/pusher.h -- pusher types and the block stepper.
 *
 * Each pusher is one file in src/pushers/ exporting one
 * `const struct gcp_pusher_type`; a scene picks it by name once.  Full-orbit
 * pushers contribute only their momentum update (the batch kernel from
 * kernels.h); the step around it is shared:
 *
 *   drift-kick-drift (synchronised leapfrog, second order, time reversible):
 *     x_{1/2} = x_n + (u_n / gamma_n) dt/2
 *     u_{n+1} = kick(u_n; E(x_{1/2}, t_n + dt/2), B(x_{1/2}, t_n + dt/2); dt)
 *     x_{n+1} = x_{1/2} + (u_{n+1} / gamma_{n+1}) dt/2
 *
 * so x and u are known at the same time after every step (output,
 * checkpoints and invariants need no half-step bookkeeping).
 */
#ifndef GCPUSH_PUSHER_H
#define GCPUSH_PUSHER_H

#include <stddef.h>
#include <stdint.h>

#include "field.h"
#include "api.h"
GCP_API_BEGIN

#ifdef __cplusplus
extern "C" {
#endif

enum gcp_pusher_kind {
    GCP_FULL_ORBIT = 0,
    GCP_GUIDING_CENTRE = 1,
    GCP_HYBRID = 2           /* switches between the two per particle (hybrid.h) */
};

struct gcp_block;
struct gcp_sampler;
struct gcp_pusher_type;

/* How far and how finely to push (one set per block push). */
struct gcp_push_opts {
    double t0;               /* [s] start time */
    double dt;               /* [s] step; the first trial step of adaptive methods */
    int64_t nsteps;          /* fixed-step methods: steps to take; adaptive: end at t0 + nsteps dt */
    double tolerance;        /* [1] adaptive methods: relative error per step (0: method default) */
    double adiabaticity_max; /* [1] guiding centre: rho/L_B (or rho/R_c) above which a particle is
                                NONADIABATIC; 0: no check */
};

/* Advances the live lanes of a block (see gcp_block_advance_fo for the
 * contract: statuses set, stopped lanes retired, returns live lanes). */
typedef size_t (*gcp_advance_fn)(struct gcp_block *b, const struct gcp_field *f,
                                 const struct gcp_pusher_type *p, const struct gcp_push_opts *o,
                                 const struct gcp_sampler *s);

/* Momentum update of n particles of one species (kernels.h batch form). */
typedef void (*gcp_kick_batch_fn)(size_t n, double *ux, double *uy, double *uz,
                                  const double *Ex, const double *Ey, const double *Ez,
                                  const double *Bx, const double *By, const double *Bz,
                                  double q, double m, double dt);

/* Momentum update in a pure magnetic field (optional, for scenes without E). */
typedef void (*gcp_kick_B_batch_fn)(size_t n, double *ux, double *uy, double *uz,
                                    const double *Bx, const double *By, const double *Bz,
                                    double q, double m, double dt);

struct gcp_fo_fused; /* private to the library (src/pushers/fo_fused_priv.h) */

struct gcp_pusher_type {
    const char *name;          /* run-file name: "boris", "vay", ... */
    const char *doc;           /* one line for --help, with the reference */
    int order;                 /* global order of accuracy in dt */
    int adaptive;              /* [bool] chooses its own steps (takes a tolerance) */
    enum gcp_pusher_kind kind;
    gcp_kick_batch_fn kick;    /* full orbit: the momentum update (NULL for guiding centre) */
    gcp_kick_B_batch_fn kick_B;/* full orbit, optional: the same with E = 0 (fewer operations) */
    gcp_advance_fn advance;    /* the block push: every pusher has one */
    /* Optional (NULL: every field): 0 when the method can push in field f,
     * else non-zero with `why` saying why not (e.g. the symplectic
     * guiding-centre methods need an axisymmetric field with a canonical
     * chart).  The scene asks before a run, so that no run starts in which
     * every particle would fail. */
    int (*applies)(const struct gcp_field *f, char *why, size_t whylen);
    /* Optional, the library's own full-orbit pushers: drift, field and kick
     * fused into one loop for the closed-form fields of field_kernels.h
     * (src/pushers/fo_fused_priv.h; NULL: the block step, the same numbers). */
    const struct gcp_fo_fused *fused;
    /* [bool] full orbit: Newtonian mechanics, u = v [m/s] (boris-nr): the
     * drifts are x += u dt/2 with no gamma.  0: u = gamma v (relativistic). */
    int newtonian;
};

extern const struct gcp_pusher_type gcp_pusher_boris;
extern const struct gcp_pusher_type gcp_pusher_boris_nr;
extern const struct gcp_pusher_type gcp_pusher_boris_zu;
extern const struct gcp_pusher_type gcp_pusher_vay;
extern const struct gcp_pusher_type gcp_pusher_higuera_cary;
/* The full Lorentz equations under GSL rk8pd (src/pushers/fo_rk8pd.c): a
 * reference for sweeps ([sweep] reference = fo-rk8pd 1e-13), independent of
 * every method it judges; not in gcp_pusher_types() (no run uses it). */
extern const struct gcp_pusher_type gcp_pusher_fo_rk8pd;
#define GCP_FO_RK8PD_TOL 1e-13

/* The pusher called `name`, or NULL. */
const struct gcp_pusher_type *gcp_pusher_lookup(const char *name);
/* NULL-terminated list of all pushers. */
const struct gcp_pusher_type *const *gcp_pusher_types(void);
/* The registered names, comma-separated, into buf (for messages and --help); returns buf. */
const char *gcp_pusher_names(char *buf, size_t size);

/* A block: n lanes of one species, struct-of-arrays, pushed together.
 * The stepper keeps the active lanes in [0, n_active): a lane whose status
 * turns non-zero is swapped to the end (with its lane index in `index`), so
 * the inner loops run dense, branch-free, over live particles only. */
struct gcp_block {
    size_t n;            /* lanes */
    size_t n_active;     /* live lanes, always the first n_active */
    double q;            /* [C] charge */
    double m;            /* [kg] mass */
    double *x, *y, *z;   /* [m] */
    double *ux, *uy, *uz;/* [m/s] u = gamma v (full orbit) */
    double *ppar;        /* [kg m/s] parallel momentum (guiding centre; x, y, z hold X) */
    double *mu;          /* [J/T] magnetic moment (guiding centre) */
    double *t;           /* [s] time of each lane (set when it stops or at the end) */
    int32_t *status;     /* enum gcp_status */
    int32_t *step_failure; /* enum gcp_step_failure: why a STEP_FAILED lane failed, else 0 */
    int64_t *steps;      /* steps taken */
    size_t *index;       /* caller's index of the particle in each lane */
    /* scratch for gathered fields, n entries each (owned by the block) */
    double *Bx, *By, *Bz, *Ex, *Ey, *Ez;
    int32_t *fstatus;
    double *hg;          /* [s] (dt/2) / gamma of each live lane, kept between half drifts */
    unsigned flags;      /* GCP_BLOCK_* below; 0 from gcp_block_alloc */
};

/* The caller keeps the clock of the live lanes (a PIC code, which knows
 * that every live particle is at t0 + nsteps dt after a push): a
 * fixed-step push (gcp_block_advance_fo, gc-rk4, gc-gl2/gl4, ...) leaves
 * their t and steps as they were, so that a push of a block far larger
 * than the caches reads and writes x and u only.  A lane that stops gets
 * its t (the time of the stop) and its steps increased by the steps of the
 * push in which it stopped, as always. */
#define GCP_BLOCK_CALLER_CLOCK 1u

/* The fast arithmetic tier of the full-orbit fused step (opt-in, never
 * the default; the run file's [integrator] arithmetic = fast).  Without
 * it (IEEE): every square root and division IEEE rounded, the same numbers
 * as the block step.  With it (boris in the closed-form fields, dipole and
 * uniform): 1/sqrt and 1/x from the AVX-512 estimates vrsqrt14pd/vrcp14pd
 * and two Newton steps, each within ~1 ulp, not IEEE rounded -- a step
 * differs from the IEEE one in its last few bits (src/pushers/
 * boris_fast.c).  Where the CPU or the build has no AVX-512F, and for any
 * other pusher or field, the flag changes nothing (the IEEE step runs:
 * gcp_arithmetic_fast_available says which). */
#define GCP_BLOCK_FAST_ARITH 2u

/* A statement a stepper makes in b->flags, not a request: b->Bx, By, Bz
 * hold B at the live lanes' positions, the field's own block evaluation
 * bit for bit (gc-rk4's fused step in the dipole writes them at the end of
 * its steps, and clears the flag before anything moves a lane or its state
 * otherwise).  The invariant observer's quiet pass then reads B there
 * instead of forming it again (src/diag/invariants_quiet.c).  Callers
 * leave it clear; the push clears it on entry and on return. */
#define GCP_BLOCK_B_AT_X (1u << 16)

/* Non-zero when GCP_BLOCK_FAST_ARITH has a fast step for pusher p on this
 * CPU and build (in the closed-form fields, dipole and uniform). */
int gcp_arithmetic_fast_available(const struct gcp_pusher_type *p);

/* Non-zero when GCP_BLOCK_FAST_ARITH runs the fast step for pusher p in
 * field f on this CPU and build: the pusher has a fast tier here and the
 * field is a closed form the tier has a tile for (without E: dipole,
 * uniform B).  What the output's root attribute `arithmetic` records. */
int gcp_arithmetic_fast_runs(const struct gcp_pusher_type *p, const struct gcp_field *f);

/* Allocates a block of n lanes (all arrays; index[i] = i). */
int gcp_block_alloc(struct gcp_block *b, size_t n);
void gcp_block_free(struct gcp_block *b);

/* Called by the stepper every `every` steps (and at the start) with the
 * active lanes, for trajectory samples and invariants. */
struct gcp_sampler {
    int64_t every;  /* steps between calls; 0: never */
    void (*fn)(const struct gcp_block *b, double t, void *ctx);
    void *ctx;
};

/* Classifies freshly filled lanes before the first step (non-finite state,
 * outside the field's domain): such lanes get their status, t = t0 and
 * 0 steps, and are retired.  Returns the number of live lanes. */
size_t gcp_block_start(struct gcp_block *b, const struct gcp_field *f, double t0);

/* Advances the live lanes of b by up to nsteps steps of dt [s] from time t0
 * with the full-orbit pusher p in field f.  Checks every step for
 * non-finite states and the field's domain (r_inner, r_outer, z_max, grid),
 * setting the lane's status and t and retiring it.  Returns the number of
 * live lanes. */
size_t gcp_block_advance_fo(struct gcp_block *b, const struct gcp_field *f,
                            const struct gcp_pusher_type *p, double t0, double dt,
                            int64_t nsteps, const struct gcp_sampler *sampler);
/* p->advance(b, f, p, o, s), where s (every = 1) is the invariant
 * observer's sampler or calls it, and gyro its gcp_observer_fo_gyro:
 * a fused full-orbit step then does the observer's per-step gyro-average
 * work of several steps in its tile loop and calls s after them (the
 * same events, bit for bit; issue 12).  gyro NULL: p->advance. */
struct gcp_fo_gyro; /* private to the library (src/pushers/fo_gyro_priv.h) */
size_t gcp_block_advance_fo_gyro(struct gcp_block *b, const struct gcp_field *f,
                                 const struct gcp_pusher_type *p, const struct gcp_push_opts *o,
                                 const struct gcp_sampler *s, struct gcp_fo_gyro *gyro);
/* The same as a gcp_advance_fn (the .advance of every full-orbit pusher). */
size_t gcp_block_advance_fo_opts(struct gcp_block *b, const struct gcp_field *f,
                                 const struct gcp_pusher_type *p, const struct gcp_push_opts *o,
                                 const struct gcp_sampler *s);

/* Single-particle convenience: pushes one full-orbit particle nsteps steps
 * of dt from *t, updating t, x [m], u [m/s] in place; cb (may be NULL) is
 * called after every step and stops the push by returning non-zero.
 * Returns the particle's final status (enum gcp_status). */
typedef int (*gcp_step_cb)(double t, const double x[3], const double u[3], void *ctx);
int gcp_orbit_push(const struct gcp_field *f, const struct gcp_pusher_type *p, double q, double m,
                   double *t, double x[3], double u[3], double dt, int64_t nsteps, gcp_step_cb cb,
                   void *ctx);

#ifdef __cplusplus
}
#endif
GCP_API_END
#endif
