/* Uniform, static B and E: the textbook field (gyration, E x B drift,
 * uniform acceleration along B) in which every pusher has an exact answer. */
#include <math.h>
#include <stdlib.h>

#include "field_priv.h"

struct uniform_params {
    double B[3]; /* [T] */
    double E[3]; /* [V/m] */
};

/* B(x) = B, grad B = 0, E(x) = E. */
static int uniform_eval(const struct gcp_field *f, double t, const double x[3],
                        struct gcp_field_sample *s)
{
    (void)t;
    (void)x;
    const struct uniform_params *p = f->params;
    for (int i = 0; i < 3; i++) s->B[i] = p->B[i];
    if (s->need & GCP_NEED_GRADB)
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) s->gradB[i][j] = 0.0;
    if (s->need & GCP_NEED_E)
        for (int i = 0; i < 3; i++) s->E[i] = p->E[i];
    return 0;
}

/* Separate loops with restrict pointers: plain stores of a constant, which
 * the compiler turns into vector stores. */
static void fill(size_t n, double v, double *restrict out)
{
    for (size_t i = 0; i < n; i++) out[i] = v;
}

static void uniform_eval_block(const struct gcp_field *f, double t, size_t n, const double *x,
                               const double *y, const double *z, double *Bx, double *By,
                               double *Bz, double *Ex, double *Ey, double *Ez, int32_t *status)
{
    (void)t;
    (void)x;
    (void)y;
    (void)z;
    (void)status; /* defined everywhere */
    const struct uniform_params *p = f->params;
    fill(n, p->B[0], Bx);
    fill(n, p->B[1], By);
    fill(n, p->B[2], Bz);
    if (Ex) {
        fill(n, p->E[0], Ex);
        fill(n, p->E[1], Ey);
        fill(n, p->E[2], Ez);
    }
}

static void uniform_eval_soa(const struct gcp_field *f, double t, unsigned need, size_t n,
                             const double *x, const double *y, const double *z,
                             const struct gcp_field_soa *out, int32_t *status)
{
    (void)t, (void)x, (void)y, (void)z, (void)status;
    const struct uniform_params *p = f->params;
    for (int a = 0; a < 3; a++) {
        if (need & GCP_NEED_B) fill(n, p->B[a], out->B[a]);
        if (need & GCP_NEED_E) fill(n, p->E[a], out->E[a]);
        if (need & GCP_NEED_GRADB)
            for (int c = 0; c < 3; c++) fill(n, 0.0, out->G[a][c]);
    }
}

/* A = (1/2) B x x, dA_i/dx_l = (1/2) eps_ijl B_j;  phi = -E.x. */
static int uniform_potential(const struct gcp_field *f, double t, const double x[3], double A[3],
                             double dA[3][3], double *phi)
{
    (void)t;
    const struct uniform_params *p = f->params;
    const double *B = p->B;
    A[0] = 0.5 * (B[1] * x[2] - B[2] * x[1]);
    A[1] = 0.5 * (B[2] * x[0] - B[0] * x[2]);
    A[2] = 0.5 * (B[0] * x[1] - B[1] * x[0]);
    if (dA) {
        dA[0][0] = 0.0, dA[0][1] = -0.5 * B[2], dA[0][2] = 0.5 * B[1];
        dA[1][0] = 0.5 * B[2], dA[1][1] = 0.0, dA[1][2] = -0.5 * B[0];
        dA[2][0] = -0.5 * B[1], dA[2][1] = 0.5 * B[0], dA[2][2] = 0.0;
    }
    if (phi) *phi = -(p->E[0] * x[0] + p->E[1] * x[1] + p->E[2] * x[2]);
    return 0;
}

/* Keys: B (vector, required), E (vector, optional). */
enum { UK_B, UK_E };
static const struct gcp_field_key uniform_keys[] = {
    {"B", GCP_KEY_VECTOR, GCP_Q_BFIELD, 1, {0, 0, 0}, NULL, "magnetic field vector [T]"},
    {"E", GCP_KEY_VECTOR, GCP_Q_EFIELD, 0, {0, 0, 0}, NULL, "electric field vector [V/m]"},
    {NULL, 0, 0, 0, {0, 0, 0}, NULL, NULL}};

static int uniform_build(struct gcp_field_args *a, struct gcp_field **out, struct gcp_error *err)
{
    for (int i = 0; i < 3; i++) {
        if (!isfinite(a->v[UK_B][i]))
            return gcp_field_key_error(a, UK_B, err, GCP_ERR_VALUE, "components must be finite");
        if (!isfinite(a->v[UK_E][i]))
            return gcp_field_key_error(a, UK_E, err, GCP_ERR_VALUE, "components must be finite");
    }
    *out = gcp_field_uniform_create(a->v[UK_B], a->v[UK_E]);
    if (!*out) return gcp_error_set(err, GCP_ERR_NOMEM, "uniform field: out of memory");
    return 0;
}

/* Always the closed form GCP_POINT_B_UNIFORM: B and E are its parameters. */
static int uniform_point_B(const struct gcp_field *f, struct gcp_point_B *out)
{
    const struct uniform_params *p = f->params;
    *out = (struct gcp_point_B){.form = GCP_POINT_B_UNIFORM, .has_E = f->has_E,
                                .p = {p->B[0], p->B[1], p->B[2], p->E[0], p->E[1], p->E[2]}};
    return 1;
}

const struct gcp_field_type gcp_field_uniform = {
    .name = "uniform",
    .doc = "constant B (and optional E): B = 0 0 1 T, E = 0 0 0 V/m",
    .eval = uniform_eval,
    .eval_block = uniform_eval_block,
    .destroy = NULL,
    /* not GCP_CAP_AXISYM: B may point anywhere (the symmetric gauge above
     * is about B, not z, so p_phi is not a constant of a tilted B) */
    .caps = GCP_CAP_B | GCP_CAP_GRADB | GCP_CAP_E | GCP_CAP_A | GCP_CAP_UNIFORM,
    .eval_soa = uniform_eval_soa,
    .potential = uniform_potential,
    .keys = uniform_keys,
    .build = uniform_build,
    .point_B = uniform_point_B,
};

/* E may be NULL (no electric field). */
struct gcp_field *gcp_field_uniform_create(const double B[3], const double E[3])
{
    struct gcp_field *f = gcp_field_alloc(&gcp_field_uniform, sizeof(struct uniform_params));
    if (!f) return NULL;
    struct uniform_params *p = f->params;
    for (int i = 0; i < 3; i++) {
        p->B[i] = B[i];
        p->E[i] = E ? E[i] : 0.0;
        if (p->E[i] != 0.0) f->has_E = 1;
    }
    return f;
}

