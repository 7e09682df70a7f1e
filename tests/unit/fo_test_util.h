/* fo_test_util.h -- shared static helpers of the full-orbit physics tests
 * (test_fo_uniform.c, test_fo_exb.c, test_fo_drifts.c, test_fo_dipole.c).
 * Test-only: small vector helpers, the battery of full-orbit pushers, the
 * weighted Birkhoff average used to measure mean frequencies, dipole
 * geometry.  Everything is static; no state is shared between tests. */
#ifndef GCPUSH_TESTS_FO_TEST_UTIL_H
#define GCPUSH_TESTS_FO_TEST_UTIL_H

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "gcpush/field.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "gcpush/pusher.h"

#define FO_EPS DBL_EPSILON /* 2.2e-16 */
#define FO_C GCP_C_LIGHT

/* The battery: every registered relativistic full-orbit pusher, in
 * registry order.  FO_FOREACH(p) { ... } runs the body once per such
 * pusher p.  The Newtonian ones (u = v: boris-nr) are left out: these tests
 * compare with relativistic theory (gyro-frequencies with gamma, 1 MeV
 * electrons); boris-nr has its own, test_boris_nr.c, and the registry-wide
 * batteries (test_conformance.c, test_fo_fused.c) take it. */
#define FO_FOREACH(p)                                                              \
    for (const struct gcp_pusher_type *const *p##_it_ = gcp_pusher_types(), *p;   \
         (p = *p##_it_) != NULL; p##_it_++)                                        \
        if (p->kind == GCP_FULL_ORBIT && !p->newtonian)

static inline int fo_is(const struct gcp_pusher_type *p, const char *name)
{
    return strcmp(p->name, name) == 0;
}

static inline int fo_count_pushers(void)
{
    int n = 0;
    FO_FOREACH(p) n++;
    return n;
}

static inline double fo_dot(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static inline double fo_norm(const double a[3]) { return sqrt(fo_dot(a, a)); }
static inline void fo_cross(const double a[3], const double b[3], double out[3])
{
    const double c0 = a[1] * b[2] - a[2] * b[1];
    const double c1 = a[2] * b[0] - a[0] * b[2];
    const double c2 = a[0] * b[1] - a[1] * b[0];
    out[0] = c0, out[1] = c1, out[2] = c2;
}

static inline double fo_gamma(const double u[3]) { return gcp_gamma_of_u(u[0], u[1], u[2]); }

/* Kinetic energy (gamma - 1) m c^2 = m u^2 / (gamma + 1) [J], written without
 * the cancellation of gamma - 1 so it is accurate to round-off at any gamma. */
static inline double fo_ekin(const double u[3], double m)
{
    return m * fo_dot(u, u) / (fo_gamma(u) + 1.0);
}

/* |u| = gamma v [m/s] of a particle of mass m [kg] and kinetic energy T [J]. */
static inline double fo_u_of_ekin(double T, double m)
{
    const double mc2 = m * FO_C * FO_C;
    return sqrt(T * (T + 2.0 * mc2)) / (m * FO_C);
}

#define FO_MEV (1e6 * GCP_E_CHARGE) /* [J] */
#define FO_KEV (1e3 * GCP_E_CHARGE) /* [J] */

/* Weighted Birkhoff average (Das, Sander, Saiki, Yorke, Nonlinearity 30
 * (2017) 4111; Das & Yorke, J. Nonlinear Sci. 28 (2018) 1): the mean of
 * f_n over n = 0..N-1 with the C-infinity bump weight
 *   w(s) = exp(-1 / (s (1 - s))),  s = (n + 1/2) / N.
 * For f_n = g(theta_n) sampled along a quasi-periodic orbit (the state of a
 * near-integrable map on an invariant torus, g smooth) the weighted mean
 * converges to the torus average faster than any power of N, where the
 * plain mean converges only as 1/N (the end-point leakage of the
 * oscillating part).  This is what lets a test read a mean drift rate that
 * is 10^-6 of the gyration's oscillation from a few hundred periods. */
struct fo_birkhoff {
    int64_t N, n;   /* samples planned, taken */
    double sw, swf; /* sum of weights, of weighted samples */
};

static inline void fo_birkhoff_init(struct fo_birkhoff *b, int64_t N)
{
    b->N = N, b->n = 0, b->sw = 0.0, b->swf = 0.0;
}

static inline void fo_birkhoff_add(struct fo_birkhoff *b, double f)
{
    if (b->n >= b->N) return;
    const double s = ((double)b->n + 0.5) / (double)b->N;
    const double w = exp(-1.0 / (s * (1.0 - s)));
    b->sw += w;
    b->swf += w * f;
    b->n++;
}

static inline double fo_birkhoff_mean(const struct fo_birkhoff *b) { return b->swf / b->sw; }

/* Signed angle [rad] from the plane vector (ax, ay) to (bx, by), in (-pi, pi]:
 * an increment that needs no unwrapping and keeps full relative precision
 * for small angles (atan2 of cross and dot, not a difference of atan2s). */
static inline double fo_angle_between(double ax, double ay, double bx, double by)
{
    return atan2(ax * by - ay * bx, ax * bx + ay * by);
}

/* Dipole geometry (moment along -z, as fields/dipole.c):
 *   B_z(equator, r) = +B0 (R_E / r)^3,  A_phi(r, theta) = -B0 R_E^3 sin(theta) / r^2. */
#define FO_RE GCP_EARTH_RADIUS
#define FO_B0 GCP_EARTH_B0

/* Magnetic latitude [rad] of x. */
static inline double fo_latitude(const double x[3])
{
    return atan2(x[2], hypot(x[0], x[1]));
}

/* Places a full-orbit particle of charge q, mass m and momentum u = gamma v
 * so that its first-order guiding centre is X:  x = X - rho, with the
 * gyro-radius vector rho = (m / (q B^2)) B x u  evaluated at X (the guiding
 * centre is X = x + (m / (q B^2)) u x B).  The neglected terms are
 * O(rho^2 / L_B) in position. */
static inline int fo_place_at_gc(const struct gcp_field *f, double q, double m, const double X[3],
                                 const double u[3], double x[3])
{
    struct gcp_field_sample s;
    memset(&s, 0, sizeof s);
    s.need = GCP_NEED_B;
    int st = gcp_field_eval(f, 0.0, X, &s);
    if (st) return st;
    double Bxu[3];
    fo_cross(s.B, u, Bxu);
    const double k = m / (q * fo_dot(s.B, s.B));
    for (int i = 0; i < 3; i++) x[i] = X[i] - k * Bxu[i];
    return 0;
}

#endif /* GCPUSH_TESTS_FO_TEST_UTIL_H */
