/* gcp_canon_chart_create: the first chart constructor that applies to a
 * field (canon_priv.h).  Each constructor returns 0, or GCP_ERR_STATE with
 * `why` filled when its chart does not cover the field; the reasons of all
 * that refused are joined into the caller's `why`, so that a refusal says
 * what each chart lacks. */
#include <stdio.h>
#include <string.h>

#include "gcpush/error.h"
#include "canon_priv.h"
#include "canon_flux_priv.h"

int gcp_canon_chart_curlfree_create(const struct gcp_field *f, struct gcp_canon_chart *out,
                                    char *why, size_t whylen);

typedef int (*chart_ctor)(const struct gcp_field *, struct gcp_canon_chart *, char *, size_t);

static const struct {
    const char *name;
    chart_ctor create;
} charts[] = {
    {"curl-free", gcp_canon_chart_curlfree_create},
    {"flux", gcp_canon_chart_flux_create}, /* tokamak, G-EQDSK, R-Z grids with psi */
    {NULL, NULL},
};

int gcp_canon_chart_create(const struct gcp_field *f, struct gcp_canon_chart *out, char *why,
                           size_t whylen)
{
    size_t used = 0;
    if (why && whylen) why[0] = '\0';
    for (size_t i = 0; charts[i].create; i++) {
        char one[256];
        one[0] = '\0';
        if (charts[i].create(f, out, one, sizeof one) == 0) return 0;
        if (why && used + 1 < whylen) {
            const int w = snprintf(why + used, whylen - used, "%s%s chart: %s", used ? "; " : "",
                                   charts[i].name, one);
            if (w > 0) used += (size_t)w < whylen - used ? (size_t)w : whylen - used - 1;
        }
    }
    memset(out, 0, sizeof *out);
    return GCP_ERR_STATE;
}

void gcp_canon_chart_destroy(struct gcp_canon_chart *c)
{
    if (c->destroy && c->data) c->destroy(c->data);
    memset(c, 0, sizeof *c);
}
