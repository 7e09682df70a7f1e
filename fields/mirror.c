/* Vacuum magnetic bottle (axisymmetric mirror about the z axis).
 *
 * B = grad Phi with the scalar potential
 *   Phi = B0 (z + z^3/(3 Lm^2) - r^2 z/(2 Lm^2)),   r^2 = x^2 + y^2,
 * so, with k = B0 / Lm^2,
 *   Bx = -k x z,   By = -k y z,   Bz = B0 + k (z^2 - r^2/2)
 * (Br = -B0 r z / Lm^2).  Phi is harmonic (Laplacian Phi = k (2z - 2z) = 0),
 * hence B is exactly curl- and divergence-free, and it is a quadratic
 * polynomial, so grad B is linear and exact.  On axis the mirror ratio
 * between z and the centre is B(z)/B0 = 1 + z^2/Lm^2.  The expansion is the
 * paraxial bottle of e.g. Chen, Introduction to Plasma Physics, sec. 2.3.3,
 * taken to the order where it is still an exact vacuum field.
 */
#include <math.h>
#include <stdlib.h>

#include "field_priv.h"

struct mirror_params {
    double B0; /* [T] field at the centre */
    double Lm; /* [m] length over which B doubles along the axis */
    double k;  /* [T/m^2] B0 / Lm^2 */
};

/* The one expression of B used by both eval and eval_block, so that both
 * give bit-identical results (the build keeps -ffp-contract=off). */
static inline void mirror_B(const struct mirror_params *p, double x, double y, double z,
                            double *bx, double *by, double *bz)
{
    const double kz = p->k * z;
    *bx = -kz * x;
    *by = -kz * y;
    *bz = p->B0 + p->k * (z * z - 0.5 * (x * x + y * y));
}

/* grad B (dB_i/dx_j) from the expressions above:
 *   [ -kz   0   -kx ]
 *   [  0   -kz  -ky ]
 *   [ -kx  -ky  2kz ]   symmetric (curl-free), trace 0 (divergence-free). */
static int mirror_eval(const struct gcp_field *f, double t, const double x[3],
                       struct gcp_field_sample *s)
{
    (void)t;
    const struct mirror_params *p = f->params;
    mirror_B(p, x[0], x[1], x[2], &s->B[0], &s->B[1], &s->B[2]);
    if (s->need & GCP_NEED_GRADB) {
        const double k = p->k, kx = k * x[0], ky = k * x[1], kz = k * x[2];
        s->gradB[0][0] = -kz;
        s->gradB[0][1] = 0.0;
        s->gradB[0][2] = -kx;
        s->gradB[1][0] = 0.0;
        s->gradB[1][1] = -kz;
        s->gradB[1][2] = -ky;
        s->gradB[2][0] = -kx;
        s->gradB[2][1] = -ky;
        s->gradB[2][2] = 2.0 * kz;
    }
    if (s->need & GCP_NEED_E) s->E[0] = s->E[1] = s->E[2] = 0.0;
    return 0;
}

static void mirror_block_B(const struct mirror_params *p, size_t n, const double *restrict x,
                           const double *restrict y, const double *restrict z,
                           double *restrict Bx, double *restrict By, double *restrict Bz)
{
    const struct mirror_params q = *p; /* a local copy: no reload per lane */
    for (size_t i = 0; i < n; i++) {
        double bx, by, bz; /* locals: stores through the inlined pointers defeat restrict */
        mirror_B(&q, x[i], y[i], z[i], &bx, &by, &bz);
        Bx[i] = bx;
        By[i] = by;
        Bz[i] = bz;
    }
}

static void zero3(size_t n, double *restrict a, double *restrict b, double *restrict c)
{
    for (size_t i = 0; i < n; i++) a[i] = b[i] = c[i] = 0.0;
}

/* The domain (|z| < z_max, |x| < r_outer) is checked by the scene from
 * f->z_max and f->r_outer; the formula itself holds everywhere. */
static void mirror_eval_block(const struct gcp_field *f, double t, size_t n, const double *x,
                              const double *y, const double *z, double *Bx, double *By,
                              double *Bz, double *Ex, double *Ey, double *Ez, int32_t *status)
{
    (void)t;
    (void)status;
    mirror_block_B(f->params, n, x, y, z, Bx, By, Bz);
    if (Ex) zero3(n, Ex, Ey, Ez);
}

/* The block evaluation; grad B as in mirror_eval (bit-identical).  Every
 * array a restrict parameter (distinct scratch arrays), so the loop
 * vectorises without alias checks; wantG is a constant at each call. */
static inline __attribute__((always_inline)) void
mirror_soa_loop(const struct mirror_params *p, int wantG, size_t n, const double *restrict xa,
                const double *restrict ya, const double *restrict za, double *restrict Bx,
                double *restrict By, double *restrict Bz, double *restrict G00,
                double *restrict G01, double *restrict G02, double *restrict G10,
                double *restrict G11, double *restrict G12, double *restrict G20,
                double *restrict G21, double *restrict G22)
{
    for (size_t i = 0; i < n; i++) {
        const double x = xa[i], y = ya[i], z = za[i];
        double bx, by, bz;
        mirror_B(p, x, y, z, &bx, &by, &bz);
        Bx[i] = bx, By[i] = by, Bz[i] = bz;
        if (wantG) {
            const double k = p->k, kx = k * x, ky = k * y, kz = k * z;
            G00[i] = -kz, G01[i] = 0.0, G02[i] = -kx;
            G10[i] = 0.0, G11[i] = -kz, G12[i] = -ky;
            G20[i] = -kx, G21[i] = -ky, G22[i] = 2.0 * kz;
        }
    }
}

static void mirror_eval_soa(const struct gcp_field *f, double t, unsigned need, size_t n,
                            const double *x, const double *y, const double *z,
                            const struct gcp_field_soa *o, int32_t *status)
{
    (void)t;
    (void)status; /* z_max and r_outer are the scene's */
    const struct mirror_params q = *(const struct mirror_params *)f->params;
    if (need & GCP_NEED_GRADB)
        mirror_soa_loop(&q, 1, n, x, y, z, o->B[0], o->B[1], o->B[2], o->G[0][0], o->G[0][1],
                        o->G[0][2], o->G[1][0], o->G[1][1], o->G[1][2], o->G[2][0], o->G[2][1],
                        o->G[2][2]);
    else
        mirror_soa_loop(&q, 0, n, x, y, z, o->B[0], o->B[1], o->B[2], NULL, NULL, NULL, NULL,
                        NULL, NULL, NULL, NULL, NULL);
    if (need & GCP_NEED_E) zero3(n, o->E[0], o->E[1], o->E[2]);
}

/* Bz = B0 + k (z^2 - R^2/2), B_R = -k R z, k = B0/Lm^2, from
 *   A_phi = (R/2) [B0 + k (z^2 - R^2/4)]:  (1/R) d(R A_phi)/dR = Bz,
 *   -dA_phi/dz = -k R z = B_R;  A = a (-y, x, 0), a = [B0 + k (z^2 - R^2/4)]/2. */
static int mirror_potential(const struct gcp_field *f, double t, const double x[3], double A[3],
                            double dA[3][3], double *phi)
{
    (void)t;
    const struct mirror_params *p = f->params;
    const double k = p->k;
    const double a = 0.5 * (p->B0 + k * (x[2] * x[2] - 0.25 * (x[0] * x[0] + x[1] * x[1])));
    const double da[3] = {-0.25 * k * x[0], -0.25 * k * x[1], k * x[2]};
    gcp_field_axial_potential(x, a, da, A, dA);
    if (phi) *phi = 0.0;
    return 0;
}

/* Keys: B0 (field, > 0), Lm (length, > 0), z_max (length, > 0: particles
 * beyond |z| = z_max have left the bottle), r_max (length, optional). */
enum { MK_B0, MK_LM, MK_ZMAX, MK_RMAX };
static const struct gcp_field_key mirror_keys[] = {
    {"B0", GCP_KEY_QUANTITY, GCP_Q_BFIELD, 1, {0, 0, 0}, NULL, "field at the centre [T]"},
    {"Lm", GCP_KEY_QUANTITY, GCP_Q_LENGTH, 1, {0, 0, 0}, NULL, "length over which B doubles [m]"},
    {"z_max", GCP_KEY_QUANTITY, GCP_Q_LENGTH, 1, {0, 0, 0}, NULL, "|z| beyond which particles leave [m]"},
    {"r_max", GCP_KEY_QUANTITY, GCP_Q_LENGTH, 0, {INFINITY, 0, 0}, NULL, "radial bound [m] (none)"},
    {NULL, 0, 0, 0, {0, 0, 0}, NULL, NULL}};

static int mirror_build(struct gcp_field_args *a, struct gcp_field **out, struct gcp_error *err)
{
    const double B0 = a->v[MK_B0][0], Lm = a->v[MK_LM][0], z_max = a->v[MK_ZMAX][0];
    const double r_max = a->v[MK_RMAX][0];
    if (!(B0 > 0.0 && isfinite(B0)))
        return gcp_field_key_error(a, MK_B0, err, GCP_ERR_VALUE,
                                   "must be positive and finite, got %g T", B0);
    if (!(Lm > 0.0 && isfinite(Lm)))
        return gcp_field_key_error(a, MK_LM, err, GCP_ERR_VALUE,
                                   "must be positive and finite, got %g m", Lm);
    if (!(z_max > 0.0 && isfinite(z_max)))
        return gcp_field_key_error(a, MK_ZMAX, err, GCP_ERR_VALUE,
                                   "must be positive and finite, got %g m", z_max);
    if (a->given[MK_RMAX] && !(r_max > 0.0 && isfinite(r_max)))
        return gcp_field_key_error(a, MK_RMAX, err, GCP_ERR_VALUE,
                                   "must be positive and finite, got %g m", r_max);
    *out = gcp_field_mirror_create(B0, Lm, z_max, r_max);
    if (!*out) return gcp_error_set(err, GCP_ERR_NOMEM, "mirror field: out of memory");
    return 0;
}

const struct gcp_field_type gcp_field_mirror = {
    .name = "mirror",
    .doc = "vacuum magnetic bottle Bz = B0 (1 + (z^2 - r^2/2)/Lm^2): B0, Lm, z_max [, r_max]",
    .eval = mirror_eval,
    .eval_block = mirror_eval_block,
    .destroy = NULL,
    .caps = GCP_CAP_B | GCP_CAP_GRADB | GCP_CAP_A | GCP_CAP_AXISYM,
    .eval_soa = mirror_eval_soa,
    .potential = mirror_potential,
    .keys = mirror_keys,
    .build = mirror_build,
};

/* r_max <= 0 or infinite: no radial bound.  r_max becomes f->r_outer, which
 * the scene compares with the spherical |x| (field.h), so it bounds the
 * bottle by a sphere, not a cylinder. */
struct gcp_field *gcp_field_mirror_create(double B0, double Lm, double z_max, double r_max)
{
    struct gcp_field *f = gcp_field_alloc(&gcp_field_mirror, sizeof(struct mirror_params));
    if (!f) return NULL;
    struct mirror_params *p = f->params;
    p->B0 = B0;
    p->Lm = Lm;
    p->k = B0 / (Lm * Lm);
    f->axisymmetric = 1;
    f->z_max = z_max > 0.0 ? z_max : INFINITY;
    f->r_outer = r_max > 0.0 ? r_max : INFINITY;
    return f;
}

/* Flux function and magnetic scalar potential (fields/potential.c), with
 * k = B0 / Lm^2 and R^2 = x^2 + y^2:
 *   chi = -Phi = -B0 (z + z^3/(3 Lm^2) - R^2 z/(2 Lm^2))   (B = -grad chi),
 *   psi = R A_phi = B0 R^2/2 + k (z^2 R^2/2 - R^4/8)
 *   (B_R = -(1/R) dpsi/dz = -k R z, B_z = (1/R) dpsi/dR = B0 + k (z^2 - R^2/2)). */
int gcp_mirror_flux_potential(const struct gcp_field *f, const double x[3], double *psi,
                              double *chi)
{
    const struct mirror_params *p = f->params;
    const double R2 = x[0] * x[0] + x[1] * x[1], z = x[2], k = p->k;
    *psi = 0.5 * p->B0 * R2 + k * (0.5 * z * z * R2 - 0.125 * R2 * R2);
    *chi = -(p->B0 * z + k * (z * z * z / 3.0 - 0.5 * R2 * z));
    return 0;
}
