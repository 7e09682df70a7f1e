/* Analytic axisymmetric tokamak with circular, concentric flux surfaces.
 *
 * Cylindrical (R, phi, Z) about the z axis, R = sqrt(x^2 + y^2), Z = z,
 * right-handed with Rhat x phihat = Zhat.  Minor radius r and poloidal angle
 * theta about the magnetic axis (R0, 0):
 *   R - R0 = r cos theta,  Z = r sin theta,  r^2 = (R - R0)^2 + Z^2.
 *
 * B = B0 R0 / R phihat  +  grad psi x grad phi,
 * with the poloidal flux function psi(r) given by
 *   dpsi/dr = B0 r / q(r),   q(r) = q0 + (qa - q0) (r/a)^2,
 * so that, with F(r) = B0 / q(r):
 *   B_phi = B0 R0 / R,   B_R = -F Z / R,   B_Z = F (R - R0) / R.
 * div B = 0 exactly: the toroidal part depends on R only and points along
 * phi, and div(grad psi x grad phi) = 0 identically (check: (1/R) d(R B_R)/dR
 * + dB_Z/dZ = F'(r)/R [-Z (R-R0)/r + (R-R0) Z/r] = 0).  There is no current
 * density model behind psi(r): it is a prescribed field (e.g. Wesson,
 * Tokamaks, ch. 3; the large-aspect-ratio "cylindrical" q), not a
 * Grad-Shafranov solution, which guiding-centre tests do not need.
 *
 * Safety factor.  |B_pol| = psi'(r)/R, so the cylindrical estimate
 * r B_phi / (R0 B_pol) is q(r) exactly, and the true field-line winding
 * number on the circle r is
 *   q_line = (1/2pi) oint B_phi / (R B_pol) dl = q(r) / sqrt(1 - (r/R0)^2),
 * i.e. q(r) up to O(epsilon^2), epsilon = r/R0.
 *
 * Sign conventions.  For B0 > 0, q0, qa > 0: B_phi points along +phi; at the
 * outboard midplane B_Z > 0, so seen in the (R, Z) plane (R to the right, Z
 * up) the poloidal field circulates counter-clockwise, and by Ampere's law
 * the toroidal plasma current flows along -phi (anti-parallel to B_phi).
 * B0 < 0 reverses both B_phi and B_pol (same field-line helicity).
 *
 * Domain: the plasma r <= a.  eval returns GCP_LEFT_DOMAIN (and eval_block
 * sets status) for r > a; f->r_outer = R0 + a and f->z_max = a are the
 * crude spherical/vertical bounds the scene can check cheaply.
 */
#include <math.h>
#include <stdlib.h>

#include "field_priv.h"
#include "gcpush/particles.h"

struct tokamak_params {
    double B0, R0, a; /* [T], [m], [m] */
    double q0, qa;    /* safety factor on axis and at r = a */
    double a2;        /* [m^2] a^2 */
    double dq;        /* [1/m^2] (qa - q0) / a^2: q = q0 + dq r^2 (0 when qa == q0) */
    double qmin;      /* min(q0, qa) */
    double B0R0;      /* [T m] */
    double R2min;     /* [m^2] floor of R^2 (see tok_B) */
};

/* The one expression of B shared by eval and eval_block (bit-identical
 * results; the build keeps -ffp-contract=off).
 *
 * Cartesian components, with u = 1/R^2 and G = F z:
 *   Bx = B_R x/R - B_phi y/R = -(G x + B0 R0 y) u
 *   By = B_R y/R + B_phi x/R =  (B0 R0 x - G y) u
 *   Bz = F (R - R0)/R.
 * Two floors, both without branches and both acting only outside the plasma
 * (so they never change a field value the pusher uses): R^2 >= R2min = (1e-6
 * R0)^2 keeps the z axis finite (there r = R0 > a); q >= min(q0, qa) keeps q
 * away from 0 when a reversed-shear profile (qa < q0) is extrapolated to
 * r > a.  Returns r^2 for the domain test. */
static inline double tok_B(const struct tokamak_params *p, double x, double y, double z,
                           double *bx, double *by, double *bz)
{
    double s = x * x + y * y;
    s = s > p->R2min ? s : p->R2min;
    const double R = sqrt(s);
    const double u = 1.0 / s;
    const double dR = R - p->R0;
    const double r2 = dR * dR + z * z;
    double q = p->q0 + p->dq * r2;
    q = q > p->qmin ? q : p->qmin;
    const double F = p->B0 / q;
    const double G = F * z;
    *bx = -(G * x + p->B0R0 * y) * u;
    *by = (p->B0R0 * x - G * y) * u;
    *bz = F * dR / R;
    return r2;
}

/* grad B, differentiating the Cartesian expressions above.  With
 *   w = (R - R0)/R,  dF/dr^2 = Fp = -F dq / q,  dr^2/dx = 2 w x,
 *   dr^2/dy = 2 w y,  dr^2/dz = 2 z,  du/dx = -2 x u^2,  du/dy = -2 y u^2,
 *   dF_j = dF/dx_j,  dG_j = z dF_j + F delta_jz,
 *   P = G x + B0R0 y (Bx = -P u),  Q = B0R0 x - G y (By = Q u):
 *   dBx/dx = -(x dG_x + G) u + 2 x P u^2     dBx/dy = -(x dG_y + B0R0) u + 2 y P u^2
 *   dBx/dz = -x dG_z u
 *   dBy/dx = (B0R0 - y dG_x) u - 2 x Q u^2    dBy/dy = -(y dG_y + G) u - 2 y Q u^2
 *   dBy/dz = -y dG_z u
 *   dBz/dx = dF_x w + F R0 x / R^3            dBz/dy = dF_y w + F R0 y / R^3
 *   dBz/dz = dF_z w.
 * (Fp uses the unclamped q, exact inside the plasma.) */
static int tokamak_eval(const struct gcp_field *f, double t, const double xv[3],
                        struct gcp_field_sample *s)
{
    (void)t;
    const struct tokamak_params *p = f->params;
    const double x = xv[0], y = xv[1], z = xv[2];
    const double r2 = tok_B(p, x, y, z, &s->B[0], &s->B[1], &s->B[2]);
    if (s->need & GCP_NEED_GRADB) {
        double R2 = x * x + y * y;
        R2 = R2 > p->R2min ? R2 : p->R2min;
        const double R = sqrt(R2), u = 1.0 / R2, w = (R - p->R0) / R;
        double q = p->q0 + p->dq * r2;
        q = q > p->qmin ? q : p->qmin;
        const double F = p->B0 / q, G = F * z, Fp = -F * p->dq / q;
        const double dFx = 2.0 * Fp * w * x, dFy = 2.0 * Fp * w * y, dFz = 2.0 * Fp * z;
        const double dGx = z * dFx, dGy = z * dFy, dGz = z * dFz + F;
        const double P = G * x + p->B0R0 * y, Q = p->B0R0 * x - G * y;
        const double u2 = u * u, FR0R3 = F * p->R0 * u / R;
        s->gradB[0][0] = -(x * dGx + G) * u + 2.0 * x * P * u2;
        s->gradB[0][1] = -(x * dGy + p->B0R0) * u + 2.0 * y * P * u2;
        s->gradB[0][2] = -x * dGz * u;
        s->gradB[1][0] = (p->B0R0 - y * dGx) * u - 2.0 * x * Q * u2;
        s->gradB[1][1] = -(y * dGy + G) * u - 2.0 * y * Q * u2;
        s->gradB[1][2] = -y * dGz * u;
        s->gradB[2][0] = dFx * w + FR0R3 * x;
        s->gradB[2][1] = dFy * w + FR0R3 * y;
        s->gradB[2][2] = dFz * w;
    }
    if (s->need & GCP_NEED_E) s->E[0] = s->E[1] = s->E[2] = 0.0;
    return r2 > p->a2 ? GCP_LEFT_DOMAIN : 0;
}

/* B for n lanes, and the domain test without a branch: a lane outside the
 * plasma gets LEFT_DOMAIN unless the caller already gave it a status (a
 * particle that died earlier keeps its first cause of death). */
static void tok_block(const struct tokamak_params *pp, size_t n, const double *restrict x,
                      const double *restrict y, const double *restrict z, double *restrict Bx,
                      double *restrict By, double *restrict Bz, int32_t *restrict status)
{
    const struct tokamak_params p = *pp;
    for (size_t i = 0; i < n; i++) {
        double bx, by, bz; /* locals: stores through the inlined pointers defeat restrict */
        const double r2 = tok_B(&p, x[i], y[i], z[i], &bx, &by, &bz);
        Bx[i] = bx;
        By[i] = by;
        Bz[i] = bz;
        const int32_t st = status[i];
        status[i] = st + (int32_t)(st == 0) * (int32_t)(r2 > p.a2) * GCP_LEFT_DOMAIN;
    }
}

/* Without a status array (the caller checks the domain itself). */
static void tok_block_nostatus(const struct tokamak_params *pp, size_t n,
                               const double *restrict x, const double *restrict y,
                               const double *restrict z, double *restrict Bx,
                               double *restrict By, double *restrict Bz)
{
    const struct tokamak_params p = *pp;
    for (size_t i = 0; i < n; i++) {
        double bx, by, bz;
        tok_B(&p, x[i], y[i], z[i], &bx, &by, &bz);
        Bx[i] = bx;
        By[i] = by;
        Bz[i] = bz;
    }
}

static void zero3(size_t n, double *restrict a, double *restrict b, double *restrict c)
{
    for (size_t i = 0; i < n; i++) a[i] = b[i] = c[i] = 0.0;
}

static void tokamak_eval_block(const struct gcp_field *f, double t, size_t n, const double *x,
                               const double *y, const double *z, double *Bx, double *By,
                               double *Bz, double *Ex, double *Ey, double *Ez, int32_t *status)
{
    (void)t;
    if (status)
        tok_block(f->params, n, x, y, z, Bx, By, Bz, status);
    else
        tok_block_nostatus(f->params, n, x, y, z, Bx, By, Bz);
    if (Ex) zero3(n, Ex, Ey, Ez);
}

/* The block evaluation; grad B as in tokamak_eval, operation for operation
 * (bit-identical), and the domain test as in tok_block.  Every array a
 * restrict parameter (distinct scratch arrays), so the loop vectorises
 * without alias checks; wantG and wantS are constants at each call. */
static inline __attribute__((always_inline)) void
tok_soa_loop(const struct tokamak_params *p, int wantG, int wantS, size_t n,
             const double *restrict xa, const double *restrict ya, const double *restrict za,
             double *restrict Bx, double *restrict By, double *restrict Bz, double *restrict G00,
             double *restrict G01, double *restrict G02, double *restrict G10,
             double *restrict G11, double *restrict G12, double *restrict G20,
             double *restrict G21, double *restrict G22, int32_t *restrict st)
{
    for (size_t i = 0; i < n; i++) {
        const double x = xa[i], y = ya[i], z = za[i];
        double bx, by, bz;
        const double r2 = tok_B(p, x, y, z, &bx, &by, &bz);
        Bx[i] = bx, By[i] = by, Bz[i] = bz;
        if (wantG) {
            double R2 = x * x + y * y;
            R2 = R2 > p->R2min ? R2 : p->R2min;
            const double R = sqrt(R2), u = 1.0 / R2, w = (R - p->R0) / R;
            double q = p->q0 + p->dq * r2;
            q = q > p->qmin ? q : p->qmin;
            const double F = p->B0 / q, G = F * z, Fp = -F * p->dq / q;
            const double dFx = 2.0 * Fp * w * x, dFy = 2.0 * Fp * w * y, dFz = 2.0 * Fp * z;
            const double dGx = z * dFx, dGy = z * dFy, dGz = z * dFz + F;
            const double P = G * x + p->B0R0 * y, Q = p->B0R0 * x - G * y;
            const double u2 = u * u, FR0R3 = F * p->R0 * u / R;
            G00[i] = -(x * dGx + G) * u + 2.0 * x * P * u2;
            G01[i] = -(x * dGy + p->B0R0) * u + 2.0 * y * P * u2;
            G02[i] = -x * dGz * u;
            G10[i] = (p->B0R0 - y * dGx) * u - 2.0 * x * Q * u2;
            G11[i] = -(y * dGy + G) * u - 2.0 * y * Q * u2;
            G12[i] = -y * dGz * u;
            G20[i] = dFx * w + FR0R3 * x;
            G21[i] = dFy * w + FR0R3 * y;
            G22[i] = dFz * w;
        }
        if (wantS) {
            const int32_t s0 = st[i];
            st[i] = s0 + (int32_t)(s0 == 0) * (int32_t)(r2 > p->a2) * GCP_LEFT_DOMAIN;
        }
    }
}

#define TOK_SOA_LOOP(WG, WS)                                                                    \
    tok_soa_loop(&p, WG, WS, n, x, y, z, o->B[0], o->B[1], o->B[2], o->G[0][0], o->G[0][1],      \
                 o->G[0][2], o->G[1][0], o->G[1][1], o->G[1][2], o->G[2][0], o->G[2][1],         \
                 o->G[2][2], status)

static void tokamak_eval_soa(const struct gcp_field *f, double t, unsigned need, size_t n,
                             const double *x, const double *y, const double *z,
                             const struct gcp_field_soa *o, int32_t *status)
{
    (void)t;
    const struct tokamak_params p = *(const struct tokamak_params *)f->params;
    const int G = (need & GCP_NEED_GRADB) != 0, S = status != NULL;
    if (G && S) TOK_SOA_LOOP(1, 1);
    else if (G) TOK_SOA_LOOP(1, 0);
    else if (S) TOK_SOA_LOOP(0, 1);
    else TOK_SOA_LOOP(0, 0);
    if (need & GCP_NEED_E) zero3(n, o->E[0], o->E[1], o->E[2]);
}
#undef TOK_SOA_LOOP

/* B_phi = B0 R0 / R from A_R = B0 R0 Z / R (curl_phi = dA_R/dZ = B0 R0/R;
 * curl_R = curl_Z = 0), and B_pol = grad psi x grad phi = curl(psi grad phi)
 * from A_phi = psi / R, with
 *   psi(r) = int_0^r B0 r'/q(r') dr' = (B0/(2 dq)) ln(1 + dq r^2/q0)
 * (= B0 r^2/(2 q0) for dq = 0), r^2 = (R - R0)^2 + Z^2.  Cartesian:
 * A_x = (g x - psi y)/R^2, A_y = (g y + psi x)/R^2, A_z = 0, g = B0 R0 z;
 * dpsi/dx = F w x, dpsi/dy = F w y, dpsi/dz = F z, F = B0/q(r), w = (R - R0)/R. */
static int tokamak_potential(const struct gcp_field *f, double t, const double xv[3],
                             double A[3], double dA[3][3], double *phi)
{
    (void)t;
    const struct tokamak_params *p = f->params;
    const double x = xv[0], y = xv[1], z = xv[2];
    double s = x * x + y * y;
    s = s > p->R2min ? s : p->R2min;
    const double R = sqrt(s), is = 1.0 / s;
    const double dR = R - p->R0;
    const double r2 = dR * dR + z * z;
    /* psi = B0 r^2/(2 q0) * log1p(v)/v, v = dq r^2 / q0 (-> 1 as v -> 0) */
    const double v = p->dq * r2 / p->q0;
    const double lv = v != 0.0 ? log1p(v) / v : 1.0;
    const double psi = p->B0 * r2 / (2.0 * p->q0) * lv;
    const double g = p->B0R0 * z;
    A[0] = (g * x - psi * y) * is;
    A[1] = (g * y + psi * x) * is;
    A[2] = 0.0;
    if (dA) {
        const double q = p->q0 + p->dq * r2; /* unclamped: exact inside the plasma */
        const double F = p->B0 / q, w = dR / R;
        const double px = F * w * x, py = F * w * y, pz = F * z;
        const double P = g * x - psi * y, Q = g * y + psi * x, is2 = is * is;
        dA[0][0] = (g - y * px) * is - 2.0 * x * P * is2;
        dA[0][1] = (-psi - y * py) * is - 2.0 * y * P * is2;
        dA[0][2] = (p->B0R0 * x - y * pz) * is;
        dA[1][0] = (psi + x * px) * is - 2.0 * x * Q * is2;
        dA[1][1] = (g + x * py) * is - 2.0 * y * Q * is2;
        dA[1][2] = (p->B0R0 * y + x * pz) * is;
        dA[2][0] = dA[2][1] = dA[2][2] = 0.0;
    }
    if (phi) *phi = 0.0;
    return 0;
}

/* Keys, all required: B0 (field on axis, non-zero; its sign sets the field
 * direction), R0 (major radius), a (minor radius, 0 < a < R0), q0, qa
 * (numbers > 0). */
enum { TK_B0, TK_R0, TK_A, TK_Q0, TK_QA };
static const struct gcp_field_key tokamak_keys[] = {
    {"B0", GCP_KEY_QUANTITY, GCP_Q_BFIELD, 1, {0, 0, 0}, NULL, "toroidal field on axis [T]"},
    {"R0", GCP_KEY_QUANTITY, GCP_Q_LENGTH, 1, {0, 0, 0}, NULL, "major radius [m]"},
    {"a", GCP_KEY_QUANTITY, GCP_Q_LENGTH, 1, {0, 0, 0}, NULL, "minor radius [m]"},
    {"q0", GCP_KEY_QUANTITY, GCP_Q_NUMBER, 1, {0, 0, 0}, NULL, "safety factor on axis"},
    {"qa", GCP_KEY_QUANTITY, GCP_Q_NUMBER, 1, {0, 0, 0}, NULL, "safety factor at r = a"},
    {NULL, 0, 0, 0, {0, 0, 0}, NULL, NULL}};

static int tokamak_build(struct gcp_field_args *k, struct gcp_field **out, struct gcp_error *err)
{
    const double B0 = k->v[TK_B0][0], R0 = k->v[TK_R0][0], a = k->v[TK_A][0];
    const double q0 = k->v[TK_Q0][0], qa = k->v[TK_QA][0];
    if (!(B0 != 0.0 && isfinite(B0)))
        return gcp_field_key_error(k, TK_B0, err, GCP_ERR_VALUE,
                                   "must be non-zero and finite, got %g T", B0);
    if (!(R0 > 0.0 && isfinite(R0)))
        return gcp_field_key_error(k, TK_R0, err, GCP_ERR_VALUE,
                                   "must be positive and finite, got %g m", R0);
    if (!(a > 0.0 && a < R0))
        return gcp_field_key_error(k, TK_A, err, GCP_ERR_VALUE,
                                   "minor radius must be in (0, R0 = %g m), got %g m", R0, a);
    if (!(q0 > 0.0 && isfinite(q0)))
        return gcp_field_key_error(k, TK_Q0, err, GCP_ERR_VALUE,
                                   "must be positive and finite, got %g", q0);
    if (!(qa > 0.0 && isfinite(qa)))
        return gcp_field_key_error(k, TK_QA, err, GCP_ERR_VALUE,
                                   "must be positive and finite, got %g", qa);
    *out = gcp_field_tokamak_create(B0, R0, a, q0, qa);
    if (!*out) return gcp_error_set(err, GCP_ERR_NOMEM, "tokamak field: out of memory");
    return 0;
}

const struct gcp_field_type gcp_field_tokamak = {
    .name = "tokamak",
    .doc = "analytic circular tokamak, q(r) = q0 + (qa - q0)(r/a)^2: B0, R0, a, q0, qa",
    .eval = tokamak_eval,
    .eval_block = tokamak_eval_block,
    .destroy = NULL,
    .caps = GCP_CAP_B | GCP_CAP_GRADB | GCP_CAP_A | GCP_CAP_AXISYM,
    .eval_soa = tokamak_eval_soa,
    .potential = tokamak_potential,
    .keys = tokamak_keys,
    .build = tokamak_build,
};

struct gcp_field *gcp_field_tokamak_create(double B0, double R0, double a, double q0, double qa)
{
    struct gcp_field *f = gcp_field_alloc(&gcp_field_tokamak, sizeof(struct tokamak_params));
    if (!f) return NULL;
    struct tokamak_params *p = f->params;
    p->B0 = B0;
    p->R0 = R0;
    p->a = a;
    p->q0 = q0;
    p->qa = qa;
    p->a2 = a * a;
    p->dq = (qa - q0) / p->a2; /* exactly 0 when qa == q0: flat q, no special case */
    p->qmin = q0 < qa ? q0 : qa;
    p->B0R0 = B0 * R0;
    p->R2min = 1e-12 * R0 * R0;
    f->axisymmetric = 1;
    f->r_outer = R0 + a;
    f->z_max = a;
    return f;
}

/* ---- flux function and the exact orthogonal chart (fields/flux_priv.h) ---- */

#include "flux_priv.h"

/* psi(r^2) = int_0^r B0 r'/q(r') dr' = B0 r^2/(2 q0) log1p(v)/v, v = dq r^2/q0
 * (the same expression as gcp_gc_potential's, so p_phi agrees to round-off). */
static double tok_psi(const struct tokamak_params *p, double r2)
{
    const double v = p->dq * r2 / p->q0;
    const double lv = v != 0.0 ? log1p(v) / v : 1.0;
    return p->B0 * r2 / (2.0 * p->q0) * lv;
}

/* psi_R = (B0/q) (R - R0), psi_Z = (B0/q) Z (grad psi = psi'(r) grad r with
 * psi' = B0 r/q); d(B0/q)/dR = -2 B0 dq (R - R0)/q^2, likewise in Z. */
int gcp_tokamak_psi_RZ(const struct gcp_field *f, double R, double Z, double out[6])
{
    const struct tokamak_params *p = f->params;
    const double dR = R - p->R0, r2 = dR * dR + Z * Z;
    const double q = p->q0 + p->dq * r2, F = p->B0 / q, F2 = 2.0 * F * p->dq / q;
    out[0] = tok_psi(p, r2);
    out[1] = F * dR;
    out[2] = F * Z;
    out[3] = F - F2 * dR * dR;
    out[4] = -F2 * dR * Z;
    out[5] = F - F2 * Z * Z;
    return r2 > p->a2 ? GCP_LEFT_DOMAIN : 0;
}

int gcp_tokamak_flux_surfaces(const struct gcp_field *f, double *Ra, double *Za, double *pe)
{
    const struct tokamak_params *p = f->params;
    *Ra = p->R0;
    *Za = 0.0;
    *pe = tok_psi(p, p->a2);
    return 0;
}

/* g(x) = (x - log1p(x))/x^2 = sum_k (-x)^k/(k+2) and
 * h(x) = -g'(x) = (x - 2 log1p(x) + x/(1+x))/x^3 = sum_k (k+1)/(k+3) (-x)^k.
 * The closed forms cancel like eps/x^2 and eps/x^3 at small x, so below
 * |x| = 1/4 the series is summed (32 terms: 4^-32 < 1e-19); above it the
 * cancellation costs at most about eps |x| / (|x|^3/3) = 50 eps < 1.2e-14
 * relative in h, less in g. */
/* The series' coefficients 1/(k+2) and (k+1)/(k+3) as constants: the same
 * correctly rounded quotients the loop divided out at every call (64
 * divisions, most of the chart map's time in the tokamak). */
#define TOK_G1(k) (1.0 / ((k) + 2))
#define TOK_H1(k) ((double)((k) + 1) / ((k) + 3))
static const double tok_gc[32] = {GCP_SERIES_32(TOK_G1)}, tok_hc[32] = {GCP_SERIES_32(TOK_H1)};

static void tok_gh(double x, double *g, double *h)
{
    if (fabs(x) < 0.25) {
        *g = gcp_estrin32(tok_gc, -x);
        *h = gcp_estrin32(tok_hc, -x);
        return;
    }
    const double l = log1p(x);
    *g = (x - l) / (x * x);
    *h = (x - 2.0 * l + x / (1.0 + x)) / (x * x * x);
}

/* The chart (s, eta) = (r, theta): R = R0 + r cos theta, Z = r sin theta,
 * exactly orthogonal, psi = psi(r).  J = -r R, B^phi = B0 R0/R^2, so in the
 * gauge A_r = 0
 *   A_theta(r, theta) = -B0 R0 int_0^r r'/(R0 + r' cos theta) dr'
 *                     = -B0 R0^2 u^2 g(u cos theta),              u = r/R0,
 *   dA_theta/dr = -B0 R0 r / R,
 *   dA_theta/dtheta = -B0 R0^2 u^3 sin theta h(u cos theta).
 * With g and h as above there is no cancellation at cos theta -> 0.  The
 * chart is smooth through r = 0 (r -> -r, theta -> theta + pi gives the same
 * point and the same A_theta), so map accepts r < 0. */
static int tok_chart_map(const void *ctx, double s, double eta, struct gcp_polchart_pt *pt)
{
    const struct tokamak_params *p = ctx;
    const double c = cos(eta), sn = sin(eta), r = s;
    const double R = p->R0 + r * c;
    pt->R = R;
    pt->Z = r * sn;
    pt->R_s = c, pt->Z_s = sn;
    pt->R_e = -r * sn, pt->Z_e = r * c;
    pt->R_ss = 0.0, pt->Z_ss = 0.0;
    pt->R_se = -sn, pt->Z_se = c;
    pt->R_ee = -r * c, pt->Z_ee = -r * sn;
    const double u = r / p->R0;
    double g, h;
    tok_gh(u * c, &g, &h);
    pt->A = -p->B0R0 * p->R0 * u * u * g;
    pt->A_s = -p->B0R0 * r / R;
    pt->A_e = -p->B0R0 * p->R0 * u * u * u * sn * h;
    const double r2 = r * r;
    pt->psi = tok_psi(p, r2);
    pt->psi_s = p->B0 * r / (p->q0 + p->dq * r2);
    pt->psi_e = 0.0;
    return r2 > p->a2 ? GCP_LEFT_DOMAIN : 0;
}

static int tok_chart_locate(const void *ctx, double R, double Z, double *s, double *eta)
{
    const struct tokamak_params *p = ctx;
    const double dR = R - p->R0;
    *s = hypot(dR, Z);
    *eta = atan2(Z, dR);
    return *s * *s > p->a2 ? GCP_LEFT_DOMAIN : 0;
}

int gcp_tokamak_polchart(const struct gcp_field *f, struct gcp_polchart *out)
{
    const struct tokamak_params *p = f->params;
    out->ctx = p;
    out->map = tok_chart_map;
    out->locate = tok_chart_locate;
    out->s_max = p->a;
    out->what = "(r, theta) about the magnetic axis";
    return 0;
}

int gcp_field_flux_tokamak(const struct gcp_field *f, struct gcp_flux_tokamak *out)
{
    if (!f || f->type != &gcp_field_tokamak) return 0;
    const struct tokamak_params *p = f->params;
    *out = (struct gcp_flux_tokamak){p->B0, p->R0, p->a, p->q0, p->dq};
    return 1;
}
