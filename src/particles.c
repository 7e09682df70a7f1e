/* Species table, status names, the SoA particle store. */
#include <stdlib.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/particles.h"

static const char *const status_names[GCP_STATUS_COUNT] = {
    "ALIVE", "PRECIPITATED", "LEFT_DOMAIN", "LEFT_GRID", "NONADIABATIC", "NONFINITE",
    "STEP_FAILED"};

const char *gcp_status_name(int status)
{
    return status >= 0 && status < GCP_STATUS_COUNT ? status_names[status] : "UNKNOWN";
}

static const char *const failure_names[GCP_FAIL_COUNT] = {
    "NONE", "UNSPECIFIED", "NO_CONVERGENCE", "NONFINITE_STAGE", "CHART",
    "STEP_UNDERFLOW", "BAD_OPTIONS", "UNSUPPORTED", "NO_MEMORY", "SOLVER_ERROR"};

const char *gcp_step_failure_name(int reason)
{
    return reason >= 0 && reason < GCP_FAIL_COUNT ? failure_names[reason] : "UNKNOWN";
}

static const char *const failure_docs[GCP_FAIL_COUNT] = {
    "not failed",
    "the stepper gave no reason",
    "the Newton / fixed-point iteration did not converge",
    "a stage of the step was not finite, or its Jacobian not finite or singular",
    "the canonical chart could not be inverted, or the step left it",
    "the error control needs a step below round-off",
    "bad push options (dt not finite and positive, nsteps < 0 or t0 not finite)",
    "the method cannot push in this field",
    "out of memory for the stepper's work space",
    "the ODE solver returned an error"};

const char *gcp_step_failure_doc(int reason)
{
    return reason >= 0 && reason < GCP_FAIL_COUNT ? failure_docs[reason] : "unknown reason";
}

/* O+ is the 16O atom (15.99491461957 u, AME2016) less one electron. */
static const struct gcp_species known[] = {
    {"proton", GCP_E_CHARGE, GCP_M_PROTON},
    {"electron", -GCP_E_CHARGE, GCP_M_ELECTRON},
    {"alpha", 2.0 * GCP_E_CHARGE, GCP_M_ALPHA},
    {"O+", GCP_E_CHARGE, 15.99491461957 * GCP_AMU - GCP_M_ELECTRON},
};

int gcp_species_lookup(const char *name, struct gcp_species *s)
{
    for (size_t i = 0; i < sizeof known / sizeof known[0]; i++) {
        if (strcmp(known[i].name, name) == 0) {
            *s = known[i];
            return 0;
        }
    }
    return GCP_ERR_UNKNOWN;
}

int gcp_particles_alloc(struct gcp_particles *p, size_t n)
{
    memset(p, 0, sizeof *p);
    size_t m = n ? n : 1;
    double **d[] = {&p->x, &p->y, &p->z, &p->ux, &p->uy, &p->uz, &p->ppar, &p->mu, &p->t, &p->cpu};
    int fail = 0;
    for (size_t k = 0; k < sizeof d / sizeof d[0]; k++) fail |= !(*d[k] = calloc(m, sizeof(double)));
    fail |= !(p->id = calloc(m, sizeof(int64_t)));
    fail |= !(p->steps = calloc(m, sizeof(int64_t)));
    fail |= !(p->pop = calloc(m, sizeof(int32_t)));
    fail |= !(p->status = calloc(m, sizeof(int32_t)));
    if (fail) {
        gcp_particles_free(p);
        return GCP_ERR_NOMEM;
    }
    p->n = n;
    return 0;
}

void gcp_particles_free(struct gcp_particles *p)
{
    double *d[] = {p->x, p->y, p->z, p->ux, p->uy, p->uz, p->ppar, p->mu, p->t, p->cpu};
    for (size_t k = 0; k < sizeof d / sizeof d[0]; k++) free(d[k]);
    free(p->id);
    free(p->steps);
    free(p->pop);
    free(p->status);
    memset(p, 0, sizeof *p);
}
