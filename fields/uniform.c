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

const struct gcp_field_type gcp_field_uniform = {
    .name = "uniform",
    .doc = "constant B (and optional E): B = 0 0 1 T, E = 0 0 0 V/m",
    .eval = uniform_eval,
    .eval_block = uniform_eval_block,
    .destroy = NULL,
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

/* Keys: B (vector, required), E (vector, optional). */
int gcp_field_uniform_from_section(struct gcp_section *sec, struct gcp_field **out,
                                   struct gcp_error *err)
{
    double B[3], E[3] = {0.0, 0.0, 0.0};
    *out = NULL;
    int rc = gcp_section_vector(sec, "B", GCP_Q_BFIELD, 1, B, err);
    if (rc < 0) return rc;
    rc = gcp_section_vector(sec, "E", GCP_Q_EFIELD, 0, E, err);
    if (rc < 0) return rc;
    for (int i = 0; i < 3; i++) {
        if (!isfinite(B[i]))
            return gcp_section_error(sec, "B", err, GCP_ERR_VALUE, "components must be finite");
        if (!isfinite(E[i]))
            return gcp_section_error(sec, "E", err, GCP_ERR_VALUE, "components must be finite");
    }
    rc = gcp_section_check_unused(sec, "B E", err);
    if (rc < 0) return rc;
    *out = gcp_field_uniform_create(B, E);
    if (!*out) return gcp_error_set(err, GCP_ERR_NOMEM, "uniform field: out of memory");
    return 0;
}
