/* fields/field_priv.h -- shared by the field models in fields/ (not installed).
 *
 * Each model file exports its `const struct gcp_field_type gcp_field_<name>`,
 * its public create function (field.h) and the run-file reader declared here,
 * which field.c dispatches to by model name.
 */
#ifndef GCPUSH_FIELD_PRIV_H
#define GCPUSH_FIELD_PRIV_H

#include <stddef.h>

#include "gcpush/error.h"
#include "gcpush/field.h"
#include "gcpush/field_kernels.h"
#include "gcpush/units.h"

/* A field of the given type with zeroed params of params_size bytes (none
 * when 0) and the defaults "no domain limits": r_inner = 0, r_outer = z_max =
 * INFINITY, no E, static, not axisymmetric.  NULL when out of memory. */
struct gcp_field *gcp_field_alloc(const struct gcp_field_type *type, size_t params_size);

/* A = a(x) (-y, x, 0) (an axisymmetric A_phi = a R) with the gradient da
 * of a: fills A and, when dA != NULL, dA[i][j] = dA_i/dx_j (field.c). */
void gcp_field_axial_potential(const double x[3], double a, const double da[3], double A[3],
                               double dA[3][3]);

/* A build error about key k of the model's table: sets args->bad_key and
 * the message (the run layer prefixes the key's file and line).  Returns code. */
int gcp_field_key_error(struct gcp_field_args *args, int k, struct gcp_error *err, int code,
                        const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 5, 6)))
#endif
    ;

/* Flux function psi = R A_phi [T m^2] and magnetic scalar potential chi
 * (B = -grad chi) [T m] of the curl-free axisymmetric models, dispatched to
 * by gcp_field_flux_potential (potential.c).  0 always. */
int gcp_dipole_flux_potential(const struct gcp_field *f, const double x[3], double *psi,
                              double *chi);
int gcp_mirror_flux_potential(const struct gcp_field *f, const double x[3], double *psi,
                              double *chi);
/* gcp_dipole_flux_potential at n points (R[k], 0, Z[k]). */
void gcp_dipole_flux_potential_rz(const struct gcp_field *f, size_t n, const double *R,
                                  const double *Z, double *psi, double *chi);

#endif
