/* gcpush/particles.h -- species, particle status codes, the SoA store. */
#ifndef GCPUSH_PARTICLES_H
#define GCPUSH_PARTICLES_H

#include <stddef.h>
#include <stdint.h>
#include "api.h"
GCP_API_BEGIN

#ifdef __cplusplus
extern "C" {
#endif

#ifndef GCP_PI
#define GCP_PI 3.14159265358979323846 /* pi (M_PI is not ISO C) */
#endif

/* CODATA 2018 constants [SI]. */
#define GCP_E_CHARGE 1.602176634e-19       /* elementary charge [C] (exact) */
#define GCP_M_PROTON 1.67262192369e-27     /* proton mass [kg] */
#define GCP_M_ELECTRON 9.1093837015e-31    /* electron mass [kg] */
#define GCP_M_ALPHA 6.6446573357e-27       /* alpha particle mass [kg] */
#define GCP_AMU 1.66053906660e-27          /* atomic mass constant [kg] */

/* Every particle ends with one of these (stored as int32 in the output). */
enum gcp_status {
    GCP_ALIVE = 0,        /* pushed to the end of the run */
    GCP_PRECIPITATED = 1, /* went below the atmosphere (|x| < field r_inner) */
    GCP_LEFT_DOMAIN = 2,  /* left the scene's bounds */
    GCP_LEFT_GRID = 3,    /* left a gridded field's grid */
    GCP_NONADIABATIC = 4, /* guiding-centre validity broken */
    GCP_NONFINITE = 5,    /* state became NaN or Inf (or started so) */
    GCP_STEP_FAILED = 6,  /* an implicit or adaptive step failed */
    GCP_STATUS_COUNT = 7
};

/* "ALIVE", "PRECIPITATED", ... or "UNKNOWN". */
const char *gcp_status_name(int status);

/* Why a particle ended GCP_STEP_FAILED (issue 11): set by the stepper that
 * failed, carried with the particle, written to the output
 * (/particles/final/step_failure) and logged.  NONE for every other status. */
enum gcp_step_failure {
    GCP_FAIL_NONE = 0,          /* not failed (or a status other than STEP_FAILED) */
    GCP_FAIL_UNSPECIFIED = 1,   /* STEP_FAILED by a stepper that gave no reason */
    GCP_FAIL_NO_CONVERGENCE = 2,/* Newton / fixed-point iteration did not converge */
    GCP_FAIL_NONFINITE_STAGE = 3,/* a stage was NaN or Inf, or its Jacobian singular */
    GCP_FAIL_CHART = 4,         /* canonical chart inversion failed or left the chart */
    GCP_FAIL_STEP_UNDERFLOW = 5,/* adaptive: the error control needs a step below round-off */
    GCP_FAIL_BAD_OPTIONS = 6,   /* dt not finite and positive, nsteps < 0, t0 not finite */
    GCP_FAIL_UNSUPPORTED = 7,   /* the method cannot push in this field */
    GCP_FAIL_NO_MEMORY = 8,     /* the stepper's work space could not be allocated */
    GCP_FAIL_SOLVER_ERROR = 9,  /* the ODE library returned an error */
    GCP_FAIL_COUNT = 10
};

/* "NONE", "NO_CONVERGENCE", ... or "UNKNOWN". */
const char *gcp_step_failure_name(int reason);
/* The reason in words, for logs ("the Newton iteration did not converge"). */
const char *gcp_step_failure_doc(int reason);

struct gcp_species {
    char name[32];  /* "proton", "electron", "alpha", "O+", or the user's name */
    double charge;  /* [C] */
    double mass;    /* [kg] */
};

/* Fills s for "proton", "electron", "alpha", "O+"; returns 0 or GCP_ERR_UNKNOWN. */
int gcp_species_lookup(const char *name, struct gcp_species *s);

/* Struct-of-arrays particle store.  Full-orbit state: x, u = gamma v.
 * Guiding-centre state: X in x/y/z, p_par, mu. */
struct gcp_particles {
    size_t n;          /* number of particles */
    int64_t *id;       /* global particle id (the seed stream index) */
    int32_t *pop;      /* index of the population (run-file [particles.*] section) */
    double *x, *y, *z; /* [m] position (GC: guiding-centre position) */
    double *ux, *uy, *uz; /* [m/s] u = gamma v (full orbit) */
    double *ppar;      /* [kg m/s] parallel momentum (guiding centre) */
    double *mu;        /* [J/T] magnetic moment p_perp^2 / (2 m B) */
    double *t;         /* [s] time reached */
    int32_t *status;   /* enum gcp_status */
    int64_t *steps;    /* steps taken */
    double *cpu;       /* [s] CPU time spent on this particle */
};

/* Allocates all arrays for n particles (zeroed); returns 0 or GCP_ERR_NOMEM. */
int gcp_particles_alloc(struct gcp_particles *p, size_t n);
void gcp_particles_free(struct gcp_particles *p);

#ifdef __cplusplus
}
#endif
GCP_API_END
#endif
