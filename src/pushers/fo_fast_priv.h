/* Private to the pushers: the fast arithmetic tier (issue 12; boris_fast.c). */
#ifndef GCPUSH_FO_FAST_PRIV_H
#define GCPUSH_FO_FAST_PRIV_H

#include <stddef.h>

#include "gcpush/pusher.h"

struct gcp_fo_fused;

/* The fused tiles of p's fast tier (1/sqrt and 1/x from the AVX-512
 * estimates and two Newton steps), or NULL where it has none or this CPU
 * or build cannot run them: arithmetic = fast then runs the IEEE tiles. */
const struct gcp_fo_fused *gcp_fo_fast_set(const struct gcp_pusher_type *p);

/* For the tests: the tier's 1/sqrt(in[i]) into rs[i] and 1/in[i] into
 * rc[i], n a multiple of 16; -1 (nothing written) where there is no tier. */
int gcp_fo_fast_prims(size_t n, const double *in, double *rs, double *rc);

#endif
