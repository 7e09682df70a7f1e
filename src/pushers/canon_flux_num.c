/* Tabulated orthogonal poloidal chart (placeholder: built next). */
#include <stdio.h>

#include "canon_flux_priv.h"
#include "gcpush/error.h"

int gcp_flux_num_build(const struct gcp_field *f, struct gcp_flux_chart *c, char *why,
                       size_t whylen)
{
    (void)f;
    (void)c;
    snprintf(why, whylen, "no tabulated flux chart yet");
    return GCP_ERR_STATE;
}
