/* Earth's centred dipole (the radiation-belt reference field).
 *
 * Moment along -z, so that B at the equator points north (+z) as Earth's
 * does:  with m = -zhat, c = B0 R_E^3,
 *   B = c [3 (m.rhat) rhat - m] / r^3
 *     = c [-3 z x_vec + r^2 zhat] / r^5,
 * i.e.  Bx = -3c x z / r^5,  By = -3c y z / r^5,  Bz = c (r^2 - 3 z^2) / r^5
 * (Jackson, Classical Electrodynamics, 3rd ed., eq. 5.56).  |B| = B0/L^3 at
 * the equator at r = L R_E and 2 B0/L^3 at the poles.
 *
 * Vector potential (for the canonical momentum p_phi = q A_phi rho + ...):
 *   A = A_phi phihat,  A_phi = -c rho / r^3 = -B0 R_E^3 rho / r^3,
 * rho = sqrt(x^2 + y^2); curl A gives the B above (Bz = (1/rho) d(rho A_phi)/drho
 * = c (rho^2 - 2 z^2)/r^5).  The flux function psi = rho A_phi is constant on
 * a field line, so a drift shell keeps rho A_phi, i.e. L, fixed.
 *
 * Optional corotation electric field, the field seen by plasma corotating
 * with the Earth (ideal MHD, E + v x B = 0, v = Omega x r, Omega = Omega zhat):
 *   E = -(Omega x r) x B,  Omega x r = Omega (-y, x, 0),
 *   Ex = -Omega x Bz,  Ey = -Omega y Bz,  Ez = Omega (x Bx + y By),
 * radially inward in the equatorial plane, perpendicular to B everywhere.
 */
#include <math.h>
#include <stdlib.h>

#include "field_priv.h"

/* r^2 is floored at 1 m^2 (branch-free max) so that x = 0 gives finite
 * numbers instead of 0 * inf = NaN.  The floor only changes points with
 * r < 1 m, deep inside the Earth (r_inner ~ R_E), where no particle lives. */
#define DIPOLE_R2_MIN 1.0

struct dipole_params {
    double c;     /* [T m^3] B0 R_E^3 */
    double omega; /* [rad/s] corotation rate (0 with corotation off) */
};

/* r^2 floored (branch-free max) and c / r^5: shared by eval and eval_block
 * so that both give bit-identical results (the build keeps
 * -ffp-contract=off). */
static inline double dipole_r2(double x, double y, double z)
{
    const double r2 = x * x + y * y + z * z;
    return r2 > DIPOLE_R2_MIN ? r2 : DIPOLE_R2_MIN;
}

static inline double dipole_c5(double c, double r2) { return c / (r2 * r2 * sqrt(r2)); }

/* B = c (-3 z x_vec + r^2 zhat) / r^5 */
static inline void dipole_B(double c, double x, double y, double z, double *bx, double *by,
                            double *bz)
{
    const double r2 = dipole_r2(x, y, z);
    const double c5 = dipole_c5(c, r2);
    const double m3z = -3.0 * c5 * z;
    *bx = m3z * x;
    *by = m3z * y;
    *bz = c5 * (r2 - 3.0 * z * z);
}

/* E = -(Omega x r) x B, components above. */
static inline void dipole_E(double omega, double x, double y, double bx, double by, double bz,
                            double *ex, double *ey, double *ez)
{
    *ex = -omega * x * bz;
    *ey = -omega * y * bz;
    *ez = omega * (x * bx + y * by);
}

/* grad B from differentiating B_i = c (-3 z x_i + r^2 delta_iz) / r^5:
 *   dB_i/dx_j = -3 c/r^5 [ z delta_ij + x_i delta_jz + x_j delta_iz
 *                          - 5 z x_i x_j / r^2 ],
 * symmetric (curl-free) and of trace -3c/r^5 (3z + 2z - 5z) = 0. */
static int dipole_eval(const struct gcp_field *f, double t, const double x[3],
                       struct gcp_field_sample *s)
{
    (void)t;
    const struct dipole_params *p = f->params;
    dipole_B(p->c, x[0], x[1], x[2], &s->B[0], &s->B[1], &s->B[2]);
    if (s->need & GCP_NEED_GRADB) {
        /* G_ij = a (-zf x_i x_j [+ z if i = j] [+ x_i if j = z] [+ x_j if
         * i = z]), written out (branch-free) in the operations and order of
         * dipole_soa_loop: the two give bit-identical results */
        const double r2 = dipole_r2(x[0], x[1], x[2]), c5 = dipole_c5(p->c, r2);
        const double a = -3.0 * c5, zf = 5.0 * x[2] / r2;
        const double X = x[0], Y = x[1], Z = x[2];
        const double px = -zf * X, py = -zf * Y, pz = -zf * Z;
        s->gradB[0][0] = a * (px * X + Z);
        s->gradB[0][1] = a * (px * Y);
        s->gradB[0][2] = a * (px * Z + X);
        s->gradB[1][0] = a * (py * X);
        s->gradB[1][1] = a * (py * Y + Z);
        s->gradB[1][2] = a * (py * Z + Y);
        s->gradB[2][0] = a * (pz * X + X);
        s->gradB[2][1] = a * (pz * Y + Y);
        s->gradB[2][2] = a * (((pz * Z + Z) + Z) + Z);
    }
    if ((s->need & GCP_NEED_E) && f->has_E)
        dipole_E(p->omega, x[0], x[1], s->B[0], s->B[1], s->B[2], &s->E[0], &s->E[1], &s->E[2]);
    else if (s->need & GCP_NEED_E)
        s->E[0] = s->E[1] = s->E[2] = 0.0; /* exact zeros, as eval_block writes */
    return 0;
}

static void dipole_block_B(double c, size_t n, const double *restrict x,
                           const double *restrict y, const double *restrict z,
                           double *restrict Bx, double *restrict By, double *restrict Bz)
{
    for (size_t i = 0; i < n; i++) {
        double bx, by, bz; /* locals: stores through the inlined pointers defeat restrict */
        dipole_B(c, x[i], y[i], z[i], &bx, &by, &bz);
        Bx[i] = bx;
        By[i] = by;
        Bz[i] = bz;
    }
}

static void dipole_block_BE(double c, double omega, size_t n, const double *restrict x,
                            const double *restrict y, const double *restrict z,
                            double *restrict Bx, double *restrict By, double *restrict Bz,
                            double *restrict Ex, double *restrict Ey, double *restrict Ez)
{
    for (size_t i = 0; i < n; i++) {
        double bx, by, bz;
        dipole_B(c, x[i], y[i], z[i], &bx, &by, &bz);
        dipole_E(omega, x[i], y[i], bx, by, bz, &Ex[i], &Ey[i], &Ez[i]);
        Bx[i] = bx;
        By[i] = by;
        Bz[i] = bz;
    }
}

static void zero3(size_t n, double *restrict a, double *restrict b, double *restrict c)
{
    for (size_t i = 0; i < n; i++) a[i] = b[i] = c[i] = 0.0;
}

/* r_inner (atmosphere) and r_outer are checked by the scene from f. */
static void dipole_eval_block(const struct gcp_field *f, double t, size_t n, const double *x,
                              const double *y, const double *z, double *Bx, double *By,
                              double *Bz, double *Ex, double *Ey, double *Ez, int32_t *status)
{
    (void)t;
    (void)status;
    const struct dipole_params *p = f->params;
    if (Ex && f->has_E) {
        dipole_block_BE(p->c, p->omega, n, x, y, z, Bx, By, Bz, Ex, Ey, Ez);
    } else {
        dipole_block_B(p->c, n, x, y, z, Bx, By, Bz);
        if (Ex) zero3(n, Ex, Ey, Ez);
    }
}

/* The block evaluation: B, and grad B and E as asked (the flags are
 * constants in each call below, so each loop is specialised and
 * branch-free).  Every array a restrict parameter: the outputs are distinct
 * scratch arrays, which lets the loops vectorise without alias checks.
 * grad B written out component by component from the loop in dipole_eval,
 * operation for operation (bit-identical results):
 *   G_ij = a (-zf x_i x_j [+ z if i = j] [+ x_i if j = z] [+ x_j if i = z]). */
static inline __attribute__((always_inline)) void
dipole_soa_loop(double c, double omega, int wantG, int wantE, size_t n,
                const double *restrict xa, const double *restrict ya, const double *restrict za,
                double *restrict Bx, double *restrict By, double *restrict Bz,
                double *restrict G00, double *restrict G01, double *restrict G02,
                double *restrict G10, double *restrict G11, double *restrict G12,
                double *restrict G20, double *restrict G21, double *restrict G22,
                double *restrict Ex, double *restrict Ey, double *restrict Ez)
{
    for (size_t i = 0; i < n; i++) {
        const double x = xa[i], y = ya[i], z = za[i];
        double bx, by, bz;
        dipole_B(c, x, y, z, &bx, &by, &bz);
        Bx[i] = bx, By[i] = by, Bz[i] = bz;
        if (wantG) {
            const double r2 = dipole_r2(x, y, z), c5 = dipole_c5(c, r2);
            const double a = -3.0 * c5, zf = 5.0 * z / r2;
            const double px = -zf * x, py = -zf * y, pz = -zf * z;
            G00[i] = a * (px * x + z);
            G01[i] = a * (px * y);
            G02[i] = a * (px * z + x);
            G10[i] = a * (py * x);
            G11[i] = a * (py * y + z);
            G12[i] = a * (py * z + y);
            G20[i] = a * (pz * x + x);
            G21[i] = a * (pz * y + y);
            G22[i] = a * (((pz * z + z) + z) + z);
        }
        if (wantE) {
            double ex, ey, ez;
            dipole_E(omega, x, y, bx, by, bz, &ex, &ey, &ez);
            Ex[i] = ex, Ey[i] = ey, Ez[i] = ez;
        }
    }
}

#define DIPOLE_SOA_LOOP(WG, WE)                                                                 \
    dipole_soa_loop(c, omega, WG, WE, n, x, y, z, o->B[0], o->B[1], o->B[2], o->G[0][0],         \
                    o->G[0][1], o->G[0][2], o->G[1][0], o->G[1][1], o->G[1][2], o->G[2][0],     \
                    o->G[2][1], o->G[2][2], o->E[0], o->E[1], o->E[2])

static void dipole_eval_soa(const struct gcp_field *f, double t, unsigned need, size_t n,
                            const double *x, const double *y, const double *z,
                            const struct gcp_field_soa *o, int32_t *status)
{
    (void)t;
    (void)status; /* defined everywhere; r_inner and r_outer are the scene's */
    const struct dipole_params *p = f->params;
    const double c = p->c, omega = p->omega;
    const int G = (need & GCP_NEED_GRADB) != 0, E = (need & GCP_NEED_E) && f->has_E;
    if (G && E) DIPOLE_SOA_LOOP(1, 1);
    else if (G) DIPOLE_SOA_LOOP(1, 0);
    else if (E) DIPOLE_SOA_LOOP(0, 1);
    else DIPOLE_SOA_LOOP(0, 0);
    if ((need & GCP_NEED_E) && !f->has_E) zero3(n, o->E[0], o->E[1], o->E[2]);
}
#undef DIPOLE_SOA_LOOP

/* A = A_phi phihat, A_phi = -c R / r^3 (header comment), written
 * A = a (-y, x, 0) with a = -c / r^3, da/dx_j = 3 c x_j / r^5.
 * Corotation E = -(Omega x r) x B = -grad(Omega R A_phi): phi = Omega R A_phi. */
static int dipole_potential(const struct gcp_field *f, double t, const double x[3], double A[3],
                            double dA[3][3], double *phi)
{
    (void)t;
    const struct dipole_params *p = f->params;
    double r2 = x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
    r2 = r2 > DIPOLE_R2_MIN ? r2 : DIPOLE_R2_MIN; /* the floor of dipole_r2 */
    const double r = sqrt(r2), ir3 = 1.0 / (r2 * r);
    const double a = -p->c * ir3;
    const double f5 = 3.0 * p->c * ir3 / r2;
    const double da[3] = {f5 * x[0], f5 * x[1], f5 * x[2]};
    gcp_field_axial_potential(x, a, da, A, dA);
    if (phi) *phi = p->omega * (x[0] * A[1] - x[1] * A[0]); /* Omega R A_phi */
    return 0;
}

/* psi = R A_phi = -c R^2 / r^3: constant on a field line (R^2/r^3 = 1/(L R_E)). */
static int dipole_psi(const struct gcp_field *f, const double x[3], double *psi)
{
    double A[3];
    dipole_potential(f, 0.0, x, A, NULL, NULL);
    *psi = x[0] * A[1] - x[1] * A[0];
    return 0;
}

/* |B| at (R_E, 0, 0) evaluated, not c / R_E^3 read back: the number the
 * invariant observer has always used for L (bit-identical results). */
static double dipole_B0(const struct gcp_field *f)
{
    const struct dipole_params *p = f->params;
    double bx, by, bz;
    dipole_B(p->c, GCP_EARTH_RADIUS, 0.0, 0.0, &bx, &by, &bz);
    return sqrt(bx * bx + by * by + bz * bz);
}

/* Keys, all optional:
 *   B0         equatorial surface field, default GCP_EARTH_B0 = 3.12e-5 T
 *   corotation yes/no, default no (adds E = -(Omega x r) x B)
 *   atmosphere altitude of the loss boundary, default 100 km:
 *              r_inner = R_E + atmosphere, below it a particle PRECIPITATES
 *   r_outer    default 15 RE, beyond it a particle has LEFT_DOMAIN */
enum { DK_B0, DK_COROT, DK_ATM, DK_ROUT };
static const struct gcp_field_key dipole_keys[] = {
    {"B0", GCP_KEY_QUANTITY, GCP_Q_BFIELD, 0, {GCP_EARTH_B0, 0, 0}, NULL,
     "equatorial surface field [T]"},
    {"corotation", GCP_KEY_FLAG, 0, 0, {0, 0, 0}, NULL, "add the corotation E field"},
    {"atmosphere", GCP_KEY_QUANTITY, GCP_Q_LENGTH, 0, {100e3, 0, 0}, NULL,
     "altitude of the loss boundary [m]"},
    {"r_outer", GCP_KEY_QUANTITY, GCP_Q_LENGTH, 0, {15.0 * GCP_EARTH_RADIUS, 0, 0}, NULL,
     "outer boundary [m]"},
    {NULL, 0, 0, 0, {0, 0, 0}, NULL, NULL}};

static int dipole_build(struct gcp_field_args *a, struct gcp_field **out, struct gcp_error *err)
{
    const double B0 = a->v[DK_B0][0], alt = a->v[DK_ATM][0], r_outer = a->v[DK_ROUT][0];
    if (!(B0 > 0.0 && isfinite(B0)))
        return gcp_field_key_error(a, DK_B0, err, GCP_ERR_VALUE,
                                   "must be positive and finite, got %g T", B0);
    if (!(alt >= 0.0 && isfinite(alt)))
        return gcp_field_key_error(a, DK_ATM, err, GCP_ERR_VALUE,
                                   "altitude must be >= 0 and finite, got %g m", alt);
    const double r_inner = GCP_EARTH_RADIUS + alt;
    if (!(r_outer > r_inner && isfinite(r_outer)))
        return gcp_field_key_error(a, DK_ROUT, err, GCP_ERR_VALUE,
                                   "must be finite and above the atmosphere (%g m), got %g m",
                                   r_inner, r_outer);
    *out = gcp_field_dipole_create(B0, a->v[DK_COROT][0] != 0.0, r_inner, r_outer);
    if (!*out) return gcp_error_set(err, GCP_ERR_NOMEM, "dipole field: out of memory");
    return 0;
}

/* Without corotation the dipole is the closed form GCP_POINT_B_DIPOLE
 * (field_kernels.h: dipole_B's operations, bit-identical; the conformance
 * battery checks it point by point); with corotation E it exports none. */
static int dipole_point_B(const struct gcp_field *f, struct gcp_point_B *out)
{
    const struct dipole_params *p = f->params;
    if (f->has_E || f->time_dependent || DIPOLE_R2_MIN != GCP_POINT_DIPOLE_R2_MIN) return 0;
    *out = (struct gcp_point_B){.form = GCP_POINT_B_DIPOLE, .has_E = 0, .has_A = 1, .p = {p->c}};
    return 1;
}

const struct gcp_field_type gcp_field_dipole = {
    .name = "dipole",
    .doc = "Earth's centred dipole, moment along -z: [B0] [corotation] [atmosphere] [r_outer]",
    .eval = dipole_eval,
    .eval_block = dipole_eval_block,
    .destroy = NULL,
    .caps = GCP_CAP_B | GCP_CAP_GRADB | GCP_CAP_E | GCP_CAP_A | GCP_CAP_PSI | GCP_CAP_AXISYM |
            GCP_CAP_DIPOLE_L,
    .eval_soa = dipole_eval_soa,
    .potential = dipole_potential,
    .psi = dipole_psi,
    .dipole_B0 = dipole_B0,
    .keys = dipole_keys,
    .build = dipole_build,
    .point_B = dipole_point_B,
};

/* r_inner <= 0: no precipitation boundary; r_outer <= 0 or inf: no outer one. */
struct gcp_field *gcp_field_dipole_create(double B0, int corotation, double r_inner,
                                          double r_outer)
{
    struct gcp_field *f = gcp_field_alloc(&gcp_field_dipole, sizeof(struct dipole_params));
    if (!f) return NULL;
    struct dipole_params *p = f->params;
    p->c = B0 * GCP_EARTH_RADIUS * GCP_EARTH_RADIUS * GCP_EARTH_RADIUS;
    p->omega = corotation ? GCP_EARTH_OMEGA : 0.0;
    f->has_E = corotation != 0;
    f->axisymmetric = 1;
    f->r_inner = r_inner > 0.0 ? r_inner : 0.0;
    f->r_outer = r_outer > 0.0 ? r_outer : INFINITY;
    return f;
}

/* Flux function and magnetic scalar potential (fields/potential.c):
 *   psi = R A_phi = -c R^2 / r^3          (B_R = -(1/R) dpsi/dZ = -3 c R Z / r^5,
 *                                          B_Z = (1/R) dpsi/dR = c (R^2 - 2 Z^2) / r^5),
 *   chi = -c z / r^3                       (B = -grad chi: c grad(z / r^3) is the B above).
 * Both with the field's own r^2 floor. */
int gcp_dipole_flux_potential(const struct gcp_field *f, const double x[3], double *psi,
                              double *chi)
{
    const struct dipole_params *p = f->params;
    const double r2 = dipole_r2(x[0], x[1], x[2]);
    const double ir3 = 1.0 / (r2 * sqrt(r2));
    *psi = -p->c * (x[0] * x[0] + x[1] * x[1]) * ir3;
    *chi = -p->c * x[2] * ir3;
    return 0;
}

/* The same at n points (R[k], 0, Z[k]), the same operations point by point
 * (the loop vectorises). */
void gcp_dipole_flux_potential_rz(const struct gcp_field *f, size_t n, const double *restrict R,
                                  const double *restrict Z, double *restrict psi,
                                  double *restrict chi)
{
    const struct dipole_params *p = f->params;
    const double c = p->c;
    for (size_t k = 0; k < n; k++) {
        const double x[3] = {R[k], 0.0, Z[k]};
        const double r2 = dipole_r2(x[0], x[1], x[2]);
        const double ir3 = 1.0 / (r2 * sqrt(r2));
        psi[k] = -c * (x[0] * x[0] + x[1] * x[1]) * ir3;
        chi[k] = -c * x[2] * ir3;
    }
}
