/* Initial states from (seed, id): the counter-based draws, the state of a
 * particle drawn from its population's keys or read from its file, and
 * the state standing for it in period estimates. */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "gcpush/kernels.h"
#include "gcpush/run.h"
#include "run_priv.h"

/* ---- counter-based random numbers --------------------------------------
 * Draw k of particle id is a pure function of (seed, id, k): the SplitMix64
 * finaliser (Steele, Lea & Flood 2014) of a Weyl-sequence counter.  No
 * state, so any split of the ensemble gives the same particles. */
static uint64_t mix64(uint64_t z)
{
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

/* Uniform in (0, 1): 53 random bits, never 0 or 1. */
static double draw(uint64_t seed, int64_t id, unsigned k)
{
    uint64_t z = mix64(seed * 0x9e3779b97f4a7c15ULL + (uint64_t)id * 16u + k + 1u);
    return ((double)(z >> 11) + 0.5) * 0x1.0p-53;
}

static double spread(const struct gcp_range *r, double u)
{
    switch (r->spread) {
    case GCP_LIN: return r->lo + (r->hi - r->lo) * u;
    case GCP_LOG: return r->lo * exp(log(r->hi / r->lo) * u);
    case GCP_FIXED: break;
    }
    return r->lo;
}

/* Unit vectors e1, e2 completing b to a right-handed basis; e1 lies along
 * the coordinate axis least aligned with b, projected. */
static void perp_basis(const double b[3], double e1[3], double e2[3])
{
    int a = 0;
    for (int i = 1; i < 3; i++)
        if (fabs(b[i]) < fabs(b[a])) a = i;
    double t[3] = {0, 0, 0};
    t[a] = 1.0;
    /* e1 = (t x b) normalised, e2 = b x e1 */
    e1[0] = t[1] * b[2] - t[2] * b[1];
    e1[1] = t[2] * b[0] - t[0] * b[2];
    e1[2] = t[0] * b[1] - t[1] * b[0];
    const double n = sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]);
    for (int i = 0; i < 3; i++) e1[i] /= n;
    e2[0] = b[1] * e1[2] - b[2] * e1[1];
    e2[1] = b[2] * e1[0] - b[0] * e1[2];
    e2[2] = b[0] * e1[1] - b[1] * e1[0];
}

/* Draws: 0 population member energy, 1 L, 2 longitude, 3 pitch, 4 phase.
 * Momentum from kinetic energy W: p c = sqrt(W (W + 2 m c^2)), u = p / m. */
int gcp_scene_initial_state(const struct gcp_scene *s, int64_t id, int *pop, double x[3],
                            double u[3])
{
    if (id < 0 || id >= s->total) return GCP_ERR_VALUE;
    size_t k = 0;
    while (id >= s->pops[k].first_id + s->pops[k].count) k++;
    const struct gcp_population *p = &s->pops[k];
    *pop = (int)k;
    if (p->file[0]) { /* the file's row; a guiding-centre row has no full orbit */
        const int64_t r = id - p->first_id;
        for (int i = 0; i < 3; i++) {
            x[i] = p->init.gc ? NAN : p->init.x[3 * r + i];
            u[i] = p->init.gc ? NAN : p->init.u[3 * r + i];
        }
        return 0;
    }
    const double W = spread(&p->energy, draw(s->seed, id, 0));
    const double mc2 = p->species.mass * GCP_C_LIGHT * GCP_C_LIGHT;
    const double umag = sqrt(W * (W + 2.0 * mc2)) / (p->species.mass * GCP_C_LIGHT);
    if (p->placement == GCP_PLACE_L_SHELL) {
        const double r = spread(&p->L, draw(s->seed, id, 1)) * GCP_EARTH_RADIUS;
        const double phi = spread(&p->longitude, draw(s->seed, id, 2));
        x[0] = r * cos(phi), x[1] = r * sin(phi), x[2] = 0.0;
    } else {
        memcpy(x, p->position, 3 * sizeof(double));
    }
    double d[3];
    if (p->aim == GCP_AIM_DIRECTION) {
        memcpy(d, p->direction, sizeof d);
    } else {
        struct gcp_field_sample smp = {.need = GCP_NEED_B};
        int st = gcp_field_eval(s->field, 0.0, x, &smp);
        const double Bm = sqrt(smp.B[0] * smp.B[0] + smp.B[1] * smp.B[1] + smp.B[2] * smp.B[2]);
        if (st || !(Bm > 0) || !isfinite(Bm)) {
            /* no local B to take a pitch angle from: the particle cannot start */
            u[0] = u[1] = u[2] = NAN;
            return 0;
        }
        const double b[3] = {smp.B[0] / Bm, smp.B[1] / Bm, smp.B[2] / Bm};
        const double alpha = p->aim == GCP_AIM_ISOTROPIC
                                 ? acos(1.0 - 2.0 * draw(s->seed, id, 3))
                                 : spread(&p->pitch, draw(s->seed, id, 3));
        const double phase = p->has_phase ? p->phase : 2.0 * GCP_PI * draw(s->seed, id, 4);
        double e1[3], e2[3];
        perp_basis(b, e1, e2);
        const double ca = cos(alpha), sa = sin(alpha), cp = cos(phase), sp = sin(phase);
        for (int i = 0; i < 3; i++) d[i] = ca * b[i] + sa * (cp * e1[i] + sp * e2[i]);
    }
    for (int i = 0; i < 3; i++) u[i] = umag * d[i];
    return 0;
}

int gcp_scene_initial_gc(const struct gcp_scene *s, int64_t id, double X[3], double *ppar,
                         double *mu)
{
    if (id < 0 || id >= s->total) return 0;
    size_t k = 0;
    while (id >= s->pops[k].first_id + s->pops[k].count) k++;
    const struct gcp_population *p = &s->pops[k];
    if (!p->file[0] || !p->init.gc) return 0;
    const int64_t r = id - p->first_id;
    memcpy(X, &p->init.x[3 * r], 3 * sizeof(double));
    *ppar = p->init.ppar[r];
    *mu = p->init.mu[r];
    return 1;
}

/* A full-orbit state standing for particle id in period estimates (a step or
 * duration given in periods): its own, or for a given guiding centre one at
 * X itself with p = ppar b + p_perp e1 (gcp_period_of reads the field at x:
 * the gyro period 2 pi gamma m / (|q| B(X)), and the bounce and drift periods
 * of X's field line with the guiding centre's pitch angle). */
void gcp_scene_period_state(const struct gcp_scene *s, int64_t id, int *pop, double x[3],
                            double u[3])
{
    double X[3], ppar, mu;
    gcp_scene_initial_state(s, id, pop, x, u);
    if (!gcp_scene_initial_gc(s, id, X, &ppar, &mu)) return;
    const struct gcp_species *sp = &s->pops[*pop].species;
    struct gcp_field_sample smp = {.need = GCP_NEED_B};
    const int st = gcp_field_eval(s->field, 0.0, X, &smp);
    const double Bm = sqrt(smp.B[0] * smp.B[0] + smp.B[1] * smp.B[1] + smp.B[2] * smp.B[2]);
    if (st || !(Bm > 0) || !isfinite(Bm) || !(mu >= 0)) return; /* stays NaN */
    const double b[3] = {smp.B[0] / Bm, smp.B[1] / Bm, smp.B[2] / Bm};
    double e1[3], e2[3];
    perp_basis(b, e1, e2);
    const double pperp = sqrt(2.0 * sp->mass * mu * Bm);
    for (int i = 0; i < 3; i++) {
        x[i] = X[i];
        u[i] = (ppar * b[i] + pperp * e1[i]) / sp->mass;
    }
}
