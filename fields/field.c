/* Field models: the registry of built-in models, run-file dispatch, the
 * generic block evaluation and the user-callback model.
 *
 * The models themselves live one per file (uniform.c, mirror.c, dipole.c,
 * tokamak.c); this file only knows their names and their run-file readers, so
 * adding a model is one line in `models` below.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "field_priv.h"
#include "gcpush/particles.h"
#include "grid_priv.h"

/* The one list of models a run file may name: the lookup, the type list
 * (--help) and the names in messages all come from it, so adding a model is
 * one entry here.  The callback model is absent on purpose: a function
 * pointer cannot come from a run file. */
#define GCP_FIELD_MODELS(X) X(uniform) X(mirror) X(dipole) X(tokamak) X(grid) X(eqdsk) X(igrf)

#define GCP_MODEL_TYPE_(n) &gcp_field_##n,
static const struct gcp_field_type *const type_list[] = {GCP_FIELD_MODELS(GCP_MODEL_TYPE_) NULL};
#define N_MODELS (sizeof type_list / sizeof type_list[0] - 1)

const char *gcp_field_model_names(char *buf, size_t size)
{
    size_t used = 0;
    if (!buf || size == 0) return "";
    buf[0] = '\0';
    for (size_t i = 0; i < N_MODELS && used < size; i++) {
        const int w = snprintf(buf + used, size - used, "%s%s", i ? " " : "", type_list[i]->name);
        if (w < 0) break;
        used += (size_t)w;
    }
    return buf;
}

const struct gcp_field_type *const *gcp_field_types(void) { return type_list; }

const struct gcp_field_type *gcp_field_type_lookup(const char *name)
{
    if (!name) return NULL;
    for (size_t i = 0; i < N_MODELS; i++)
        if (strcmp(type_list[i]->name, name) == 0) return type_list[i];
    return NULL;
}

struct gcp_field *gcp_field_alloc(const struct gcp_field_type *type, size_t params_size)
{
    struct gcp_field *f = calloc(1, sizeof *f);
    if (!f) return NULL;
    if (params_size) {
        f->params = calloc(1, params_size);
        if (!f->params) {
            free(f);
            return NULL;
        }
    }
    f->type = type;
    f->r_inner = 0.0;
    f->r_outer = INFINITY;
    f->z_max = INFINITY;
    return f;
}

void gcp_field_free(struct gcp_field *f)
{
    if (!f) return;
    if (f->type && f->type->destroy)
        f->type->destroy(f->params);
    else
        free(f->params);
    free(f);
}

int gcp_field_eval(const struct gcp_field *f, double t, const double x[3],
                   struct gcp_field_sample *s)
{
    return f->type->eval(f, t, x, s);
}

void gcp_field_axial_potential(const double x[3], double a, const double da[3], double A[3],
                               double dA[3][3])
{
    A[0] = -a * x[1];
    A[1] = a * x[0];
    A[2] = 0.0;
    if (!dA) return;
    for (int j = 0; j < 3; j++) {
        dA[0][j] = -x[1] * da[j];
        dA[1][j] = x[0] * da[j];
        dA[2][j] = 0.0;
    }
    dA[0][1] -= a;
    dA[1][0] += a;
}

int gcp_field_key_error(struct gcp_field_args *args, int k, struct gcp_error *err, int code,
                        const char *fmt, ...)
{
    char what[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    args->bad_key = k;
    return gcp_error_set(err, code, "%s", what);
}

unsigned gcp_field_caps(const struct gcp_field *f)
{
    const unsigned dyn = GCP_CAP_E | GCP_CAP_TIME | GCP_CAP_AXISYM;
    return (f->type->caps & ~f->caps_off & ~dyn) | (f->has_E ? GCP_CAP_E : 0u) |
           (f->time_dependent ? GCP_CAP_TIME : 0u) | (f->axisymmetric ? GCP_CAP_AXISYM : 0u);
}

int gcp_field_potential(const struct gcp_field *f, double t, const double x[3], double A[3],
                        double dA[3][3], double *phi)
{
    if (!f->type->potential) return GCP_ERR_UNKNOWN;
    return f->type->potential(f, t, x, A, dA, phi);
}

int gcp_field_psi(const struct gcp_field *f, const double x[3], double *psi)
{
    if (!f->type->psi || !(gcp_field_caps(f) & GCP_CAP_PSI)) return GCP_ERR_STATE;
    return f->type->psi(f, x, psi);
}

int gcp_field_point_B(const struct gcp_field *f, struct gcp_point_B *out)
{
    *out = (struct gcp_point_B){.form = GCP_POINT_B_NONE};
    return f && f->type->point_B ? f->type->point_B(f, out) : 0;
}

double gcp_field_dipole_B0(const struct gcp_field *f)
{
    if (!f || !f->type->dipole_B0 || !(gcp_field_caps(f) & GCP_CAP_DIPOLE_L)) return 0.0;
    return f->type->dipole_B0(f);
}

void gcp_field_eval_soa(const struct gcp_field *f, double t, unsigned need, size_t n,
                        const double *x, const double *y, const double *z,
                        const struct gcp_field_soa *out, int32_t *status)
{
    if (f->type->eval_soa)
        f->type->eval_soa(f, t, need, n, x, y, z, out, status);
    else
        gcp_field_eval_soa_generic(f, t, need, n, x, y, z, out, status);
}

/* One scalar eval per point, scattered into the SoA arrays the need bits
 * ask for; statuses as in gcp_field_eval_block_generic. */
void gcp_field_eval_soa_generic(const struct gcp_field *f, double t, unsigned need, size_t n,
                                const double *x, const double *y, const double *z,
                                const struct gcp_field_soa *out, int32_t *status)
{
    for (size_t i = 0; i < n; i++) {
        struct gcp_field_sample s;
        memset(&s, 0, sizeof s);
        s.need = need | GCP_NEED_B;
        const double xi[3] = {x[i], y[i], z[i]};
        const int rc = f->type->eval(f, t, xi, &s);
        for (int a = 0; a < 3; a++) {
            if (need & GCP_NEED_B) out->B[a][i] = s.B[a];
            if (need & GCP_NEED_E) out->E[a][i] = s.E[a];
            if (need & GCP_NEED_GRADB)
                for (int c = 0; c < 3; c++) out->G[a][c][i] = s.gradB[a][c];
        }
        if (rc && status && status[i] == 0) status[i] = rc;
    }
}

/* One scalar eval per point.  A status already set by the caller (a particle
 * that died earlier in the block) is kept: the field only ever turns ALIVE
 * into an out-of-domain status, never the other way. */
void gcp_field_eval_block_generic(const struct gcp_field *f, double t, size_t n,
                                  const double *x, const double *y, const double *z, double *Bx,
                                  double *By, double *Bz, double *Ex, double *Ey, double *Ez,
                                  int32_t *status)
{
    const unsigned need = GCP_NEED_B | (Ex ? GCP_NEED_E : 0u);
    for (size_t i = 0; i < n; i++) {
        struct gcp_field_sample s;
        memset(&s, 0, sizeof s);
        s.need = need;
        const double xi[3] = {x[i], y[i], z[i]};
        int rc = f->type->eval(f, t, xi, &s);
        Bx[i] = s.B[0];
        By[i] = s.B[1];
        Bz[i] = s.B[2];
        if (Ex) {
            Ex[i] = s.E[0];
            Ey[i] = s.E[1];
            Ez[i] = s.E[2];
        }
        if (rc && status && status[i] == 0) status[i] = rc;
    }
}

/* ---- user callback ----------------------------------------------------- */

struct callback_params {
    gcp_field_eval_fn fn;
    void *ctx; /* the user's, not owned */
};

static int callback_eval(const struct gcp_field *f, double t, const double x[3],
                         struct gcp_field_sample *s)
{
    const struct callback_params *p = f->params;
    return p->fn(t, x, s, p->ctx);
}

const struct gcp_field_type gcp_field_callback = {
    .name = "callback",
    .doc = "user function int fn(t, x, sample, ctx) (library use only)",
    .eval = callback_eval,
    .eval_block = gcp_field_eval_block_generic,
    .destroy = NULL,
    .caps = GCP_CAP_B | GCP_CAP_GRADB | GCP_CAP_E | GCP_CAP_TIME,
};

/* The callback may depend on t and on anything in ctx, so the field is
 * marked time dependent: a scene must not skip the time argument for it. */
struct gcp_field *gcp_field_callback_create(gcp_field_eval_fn fn, void *ctx, int has_E)
{
    if (!fn) return NULL;
    struct gcp_field *f = gcp_field_alloc(&gcp_field_callback, sizeof(struct callback_params));
    if (!f) return NULL;
    struct callback_params *p = f->params;
    p->fn = fn;
    p->ctx = ctx;
    f->has_E = has_E != 0;
    f->time_dependent = 1;
    return f;
}
