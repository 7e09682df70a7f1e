/* Field models: the registry of built-in models, run-file dispatch, the
 * generic block evaluation and the user-callback model.
 *
 * The models themselves live one per file (uniform.c, mirror.c, dipole.c,
 * tokamak.c); this file only knows their names and their run-file readers, so
 * adding a model is one line in `models` below.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "field_priv.h"
#include "gcpush/particles.h"
#include "grid_priv.h"

/* Models a run file may name, with their readers.  The callback model is
 * absent on purpose: a function pointer cannot come from a run file. */
static const struct {
    const struct gcp_field_type *type;
    int (*from_section)(struct gcp_section *, struct gcp_field **, struct gcp_error *);
} models[] = {
    {&gcp_field_uniform, gcp_field_uniform_from_section},
    {&gcp_field_mirror, gcp_field_mirror_from_section},
    {&gcp_field_dipole, gcp_field_dipole_from_section},
    {&gcp_field_tokamak, gcp_field_tokamak_from_section},
    {&gcp_field_grid, gcp_field_grid_from_section}, {&gcp_field_eqdsk, gcp_field_eqdsk_from_section},
    {&gcp_field_igrf, gcp_field_igrf_from_section},
};
#define N_MODELS (sizeof models / sizeof models[0])

/* Kept in step with `models` (a static initialiser cannot read models[i].type). */
static const struct gcp_field_type *const type_list[N_MODELS + 1] = {
    &gcp_field_uniform, &gcp_field_mirror, &gcp_field_dipole, &gcp_field_tokamak,
    &gcp_field_grid, &gcp_field_eqdsk, &gcp_field_igrf, NULL};

/* For messages: the names in `models`, space separated. */
#define MODEL_NAMES "uniform mirror dipole tokamak grid eqdsk igrf"

const struct gcp_field_type *const *gcp_field_types(void) { return type_list; }

const struct gcp_field_type *gcp_field_type_lookup(const char *name)
{
    if (!name) return NULL;
    for (size_t i = 0; i < N_MODELS; i++)
        if (strcmp(models[i].type->name, name) == 0) return models[i].type;
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

int gcp_field_from_section(const char *model, struct gcp_section *sec, struct gcp_field **out,
                           struct gcp_error *err)
{
    if (!out) return gcp_error_set(err, GCP_ERR_STATE, "gcp_field_from_section: out is NULL");
    *out = NULL;
    if (!sec) return gcp_error_set(err, GCP_ERR_STATE, "gcp_field_from_section: no [field] section");
    for (size_t i = 0; model && i < N_MODELS; i++)
        if (strcmp(models[i].type->name, model) == 0) {
            int rc = models[i].from_section(sec, out, err);
            if (rc < 0) {
                /* The readers build the field last, so there is nothing to
                 * free; this only guards a reader that forgets *out = NULL. */
                gcp_field_free(*out);
                *out = NULL;
            }
            return rc < 0 ? rc : 0;
        }
    /* The model name comes from [scene] field = ..., whose line the caller
     * knows; name the [field] section here so the user can find the run. */
    return gcp_error_set(err, GCP_ERR_UNKNOWN,
                         "%s:%d: [%s] unknown field model '%.60s' (expected one of: " MODEL_NAMES
                         ")",
                         sec->file ? sec->file : "(run)", sec->line, sec->name ? sec->name : "field",
                         model ? model : "(none)");
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
