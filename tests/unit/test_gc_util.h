/* test_gc_util.h -- static helpers of the guiding-centre tests
 * (test_gc_*.c): the GC battery, dipole GC theory by quadrature, and an
 * orbit recorder with cubic-Hermite crossing interpolation. */
#ifndef GCPUSH_TESTS_GC_TEST_UTIL_H
#define GCPUSH_TESTS_GC_TEST_UTIL_H

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_errno.h>
#include <gsl/gsl_integration.h>

#include "gcpush/field.h"
#include "gcpush/gc.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "gcpush/pusher.h"

#define GC_RE GCP_EARTH_RADIUS
#define GC_B0 GCP_EARTH_B0
#define GC_C GCP_C_LIGHT

/* GC_FOREACH(p) { ... }: every registered guiding-centre pusher. */
#define GC_FOREACH(p)                                                              \
    for (const struct gcp_pusher_type *const *p##_it_ = gcp_pusher_types(), *p;   \
         (p = *p##_it_) != NULL; p##_it_++)                                        \
        if (p->kind == GCP_GUIDING_CENTRE)

static inline int gc_is(const struct gcp_pusher_type *p, const char *name)
{
    return strcmp(p->name, name) == 0;
}

/* Momentum [kg m/s] of kinetic energy T [J], mass m. */
static inline double gc_p_of_T(double T, double m)
{
    const double mc2 = m * GC_C * GC_C;
    return sqrt(T * T + 2.0 * T * mc2) / GC_C;
}

static inline double gc_Bmag(const struct gcp_field *f, const double x[3])
{
    struct gcp_field_sample s = {.need = GCP_NEED_B};
    gcp_field_eval(f, 0.0, x, &s);
    return sqrt(s.B[0] * s.B[0] + s.B[1] * s.B[1] + s.B[2] * s.B[2]);
}

/* ---- dipole GC theory (Schulz & Lanzerotti 1974, ch. 1) ----
 * Along the field line r = L R_E cos^2(lat): ds/dlat = L R_E cos(lat)
 * sqrt(1 + 3 sin^2 lat), B/B_eq = b(lat) = sqrt(1 + 3 sin^2 lat)/cos^6 lat,
 * v_par = v sqrt(1 - y^2 b), y = sin(a_eq), mirror at y^2 b(lat_m) = 1.
 *   T_b = 4 int_0^lat_m (ds/dlat) / v_par dlat = (4 L R_E / v) T(y),
 *   dphi per bounce = 4 int_0^lat_m (v_phi / R)(ds/dlat)/v_par dlat,
 * v_phi = p v (1 - y^2 b/2) (b x grad B)_phi / (q B^2) (gradient-curvature
 * drift of the exact GC equations: see test_gc_dipole.c), T_d = 2 pi T_b /
 * |dphi|.  Substituting lat = lat_m sin(th) removes the 1/sqrt end-point
 * singularity (dlat = lat_m cos th dth, 1 - y^2 b ~ cos^2 th), so GSL QAG
 * converges fast; the accuracy, ~2e-8 relative at worst (a_eq = 60 deg,
 * where every method agrees on the same 1.8e-8 offset), is limited by the
 * cancellation in 1 - y^2 b(lat) next to the mirror point: 50x below the
 * 1e-6 asserted. */
struct gc_dip {
    const struct gcp_field *f;
    double L, y2, latm, p, v, q;
};

static inline double gc_dip_b(double l)
{
    const double s = sin(l), c = cos(l), c3 = c * c * c;
    return sqrt(1.0 + 3.0 * s * s) / (c3 * c3);
}

static inline double gc_dip_latm(double y2)
{
    double lo = 0.0, hi = 0.5 * GCP_PI - 1e-9;
    for (int i = 0; i < 200 && hi - lo > 0.0; i++) {
        const double mid = 0.5 * (lo + hi);
        if (mid == lo || mid == hi) break;
        if (y2 * gc_dip_b(mid) < 1.0) lo = mid; else hi = mid;
    }
    return 0.5 * (lo + hi);
}

/* (ds/dlat)/v_par, and the azimuthal rate, at lat = latm sin(th), times
 * dlat/dth. */
static inline double gc_dip_tb_integrand(double th, void *vp)
{
    const struct gc_dip *d = vp;
    const double l = d->latm * sin(th), s = sin(l);
    const double w = 1.0 - d->y2 * gc_dip_b(l);
    const double ds = d->L * GC_RE * cos(l) * sqrt(1.0 + 3.0 * s * s);
    return w > 0.0 ? ds / (d->v * sqrt(w)) * d->latm * cos(th) : 0.0;
}

static inline double gc_dip_phi_integrand(double th, void *vp)
{
    const struct gc_dip *d = vp;
    const double l = d->latm * sin(th);
    const double r = d->L * GC_RE * cos(l) * cos(l);
    const double x[3] = {r * cos(l), 0.0, r * sin(l)};
    struct gcp_field_sample s = {.need = GCP_NEED_B | GCP_NEED_GRADB};
    gcp_field_eval(d->f, 0.0, x, &s);
    const double Bm = sqrt(s.B[0] * s.B[0] + s.B[1] * s.B[1] + s.B[2] * s.B[2]);
    double gB[3];
    for (int j = 0; j < 3; j++)
        gB[j] = (s.B[0] * s.gradB[0][j] + s.B[1] * s.gradB[1][j] + s.B[2] * s.gradB[2][j]) / Bm;
    const double bxg_y = (s.B[2] * gB[0] - s.B[0] * gB[2]) / Bm; /* (b x grad B).yhat = phi */
    const double bb = Bm / gc_Bmag(d->f, (const double[3]){d->L * GC_RE, 0, 0});
    const double vphi = d->p * d->v * (1.0 - 0.5 * d->y2 * bb) * bxg_y / (d->q * Bm * Bm);
    return vphi / x[0] * gc_dip_tb_integrand(th, vp);
}

static inline double gc_quad(double (*fn)(double, void *), void *ctx)
{
    gsl_integration_workspace *w = gsl_integration_workspace_alloc(1000);
    gsl_function F = {fn, ctx};
    double res = NAN, err;
    gsl_error_handler_t *old = gsl_set_error_handler_off();
    gsl_integration_qag(&F, 0.0, 0.5 * GCP_PI, 0.0, 1e-13, 1000, GSL_INTEG_GAUSS61, w, &res, &err);
    gsl_set_error_handler(old);
    gsl_integration_workspace_free(w);
    return res;
}

/* Bounce period, drift period, mirror latitude of a GC at L with
 * equatorial pitch angle a [rad], kinetic energy T [J]. */
static inline void gc_dip_theory(const struct gcp_field *f, double q, double m, double T,
                                 double L, double a, double *Tb, double *Td, double *latm)
{
    const double p = gc_p_of_T(T, m);
    const double gamma = sqrt(1.0 + (p / (m * GC_C)) * (p / (m * GC_C)));
    struct gc_dip d = {f, L, sin(a) * sin(a), 0.0, p, p / (gamma * m), q};
    d.latm = gc_dip_latm(d.y2);
    *latm = d.latm;
    *Tb = 4.0 * gc_quad(gc_dip_tb_integrand, &d);
    const double dphi = 4.0 * gc_quad(gc_dip_phi_integrand, &d);
    *Td = 2.0 * GCP_PI * *Tb / fabs(dphi);
}

/* The equatorial pitch [deg] of a dipole orbit mirroring at lat_deg
 * latitude: sin^2 a = 1/b(lat). */
#define GC_PITCH_OF_MIRROR(lat_deg) \
    (asin(1.0 / sqrt(gc_dip_b((lat_deg) * GCP_PI / 180.0))) * 180.0 / GCP_PI)

/* The Sundman tests' and bench's orbit (test_gc_sundman.c,
 * test_gc_sundman_line.c, bench_sundman.c): a 1 MeV electron on the
 * equator at L = 4 in Earth's dipole (no surface) with equatorial pitch
 * a_deg, its mu from |B| there, and T_b, T_d, the mirror latitude by the
 * quadratures above.  The caller frees o->f.  0, or -1 without a field. */
struct gc_dip_orbit {
    struct gcp_field *f;
    double q, m, mu, X[3], ppar;
    double Tb, Td, latm; /* [s], [s], [rad] */
};
static inline int gc_dip_electron(struct gc_dip_orbit *o, double a_deg)
{
    o->f = gcp_field_dipole_create(GC_B0, 0, 0.0, 0.0);
    if (!o->f) return -1;
    o->m = GCP_M_ELECTRON, o->q = -GCP_E_CHARGE;
    const double T = 1e6 * GCP_E_CHARGE, a = a_deg * GCP_PI / 180.0, p = gc_p_of_T(T, o->m);
    o->X[0] = 4.0 * GC_RE, o->X[1] = 0.0, o->X[2] = 0.0;
    o->ppar = p * cos(a);
    o->mu = p * sin(a) * p * sin(a) / (2.0 * o->m * gc_Bmag(o->f, o->X));
    gc_dip_theory(o->f, o->q, o->m, T, 4.0, a, &o->Tb, &o->Td, &o->latm);
    return 0;
}

/* ---- orbit recorder ---- */
struct gc_rec {
    const struct gcp_field *f;
    double q, m, mu;
    int64_t n, cap;
    double *t, *X, *p, *dX, *dp; /* X, dX: 3 per sample */
};

static inline void gc_rec_add(struct gc_rec *r, double t, const double X[3], double p)
{
    if (r->n == r->cap) {
        r->cap = r->cap ? 2 * r->cap : 4096;
        r->t = realloc(r->t, (size_t)r->cap * sizeof(double));
        r->p = realloc(r->p, (size_t)r->cap * sizeof(double));
        r->dp = realloc(r->dp, (size_t)r->cap * sizeof(double));
        r->X = realloc(r->X, 3 * (size_t)r->cap * sizeof(double));
        r->dX = realloc(r->dX, 3 * (size_t)r->cap * sizeof(double));
    }
    const int64_t k = r->n++;
    r->t[k] = t;
    r->p[k] = p;
    memcpy(&r->X[3 * k], X, 3 * sizeof(double));
    gcp_gc_rhs_at(r->f, t, r->q, r->m, X, p, r->mu, &r->dX[3 * k], &r->dp[k]);
}

static inline int gc_rec_cb(double t, const double X[3], double p, void *ctx)
{
    gc_rec_add(ctx, t, X, p);
    return 0;
}

static inline void gc_rec_free(struct gc_rec *r)
{
    free(r->t), free(r->p), free(r->dp), free(r->X), free(r->dX);
    memset(r, 0, sizeof *r);
}

/* Cubic Hermite on [0, 1] with values y0, y1 and slopes d0, d1 (per unit s). */
static inline double gc_herm(double s, double y0, double y1, double d0, double d1)
{
    const double s2 = s * s, s3 = s2 * s;
    return (2 * s3 - 3 * s2 + 1) * y0 + (s3 - 2 * s2 + s) * d0 + (-2 * s3 + 3 * s2) * y1 +
           (s3 - s2) * d1;
}

static inline double gc_herm_d(double s, double y0, double y1, double d0, double d1)
{
    const double s2 = s * s;
    return (6 * s2 - 6 * s) * y0 + (3 * s2 - 4 * s + 1) * d0 + (-6 * s2 + 6 * s) * y1 +
           (3 * s2 - 2 * s) * d1;
}

/* Root in [0,1] of the Hermite cubic (sign change assumed), by bisection+secant. */
static inline double gc_herm_root(double y0, double y1, double d0, double d1)
{
    double lo = 0.0, hi = 1.0, flo = y0;
    for (int i = 0; i < 200; i++) {
        const double mid = 0.5 * (lo + hi);
        if (mid == lo || mid == hi) break;
        const double fm = gc_herm(mid, y0, y1, d0, d1);
        if ((fm < 0) == (flo < 0)) lo = mid, flo = fm; else hi = mid;
    }
    return 0.5 * (lo + hi);
}

/* Azimuth phi(t) unwrapped, and its rate, at sample k. */
static inline double gc_rec_phi(const struct gc_rec *r, int64_t k)
{
    return atan2(r->X[3 * k + 1], r->X[3 * k]);
}
static inline double gc_rec_dphi(const struct gc_rec *r, int64_t k)
{
    const double *X = &r->X[3 * k], *d = &r->dX[3 * k];
    return (X[0] * d[1] - X[1] * d[0]) / (X[0] * X[0] + X[1] * X[1]);
}

/* Upward equator crossings (Z from < 0 to >= 0) after sample 0: times and
 * unwrapped azimuths, at most nmax. Returns the count. */
static inline int gc_rec_crossings(const struct gc_rec *r, int nmax, double *tc, double *phic)
{
    int nc = 0;
    double unwrap = 0.0;
    for (int64_t k = 1; k < r->n && nc < nmax; k++) {
        double p0 = gc_rec_phi(r, k - 1) + unwrap, p1 = gc_rec_phi(r, k) + unwrap;
        if (p1 - p0 > GCP_PI) unwrap -= 2 * GCP_PI, p1 -= 2 * GCP_PI;
        if (p1 - p0 < -GCP_PI) unwrap += 2 * GCP_PI, p1 += 2 * GCP_PI;
        const double z0 = r->X[3 * (k - 1) + 2], z1 = r->X[3 * k + 2];
        if (!(z0 < 0.0 && z1 >= 0.0)) continue;
        const double h = r->t[k] - r->t[k - 1];
        const double dz0 = r->dX[3 * (k - 1) + 2] * h, dz1 = r->dX[3 * k + 2] * h;
        const double s = gc_herm_root(z0, z1, dz0, dz1);
        tc[nc] = r->t[k - 1] + s * h;
        phic[nc] = gc_herm(s, p0, p1, gc_rec_dphi(r, k - 1) * h, gc_rec_dphi(r, k) * h);
        nc++;
    }
    return nc;
}

/* Largest latitude on the first step where dlat/dt turns negative
 * (the first mirror point), from the Hermite cubic of lat(t). */
static inline double gc_rec_mirror_lat(const struct gc_rec *r)
{
    for (int64_t k = 1; k < r->n; k++) {
        double l[2], dl[2];
        for (int j = 0; j < 2; j++) {
            const double *X = &r->X[3 * (k - 1 + j)], *d = &r->dX[3 * (k - 1 + j)];
            const double R = hypot(X[0], X[1]);
            const double dR = (X[0] * d[0] + X[1] * d[1]) / R;
            l[j] = atan2(X[2], R);
            dl[j] = (R * d[2] - X[2] * dR) / (R * R + X[2] * X[2]);
        }
        if (!(dl[0] > 0.0 && dl[1] <= 0.0)) continue;
        const double h = r->t[k] - r->t[k - 1];
        /* derivative of the cubic is a quadratic: find its root by bisection */
        double lo = 0.0, hi = 1.0;
        for (int i = 0; i < 200; i++) {
            const double mid = 0.5 * (lo + hi);
            if (mid == lo || mid == hi) break;
            if (gc_herm_d(mid, l[0], l[1], dl[0] * h, dl[1] * h) > 0.0) lo = mid; else hi = mid;
        }
        return gc_herm(0.5 * (lo + hi), l[0], l[1], dl[0] * h, dl[1] * h);
    }
    return NAN;
}


/* ---- canonical-map checks (test_gc_symplectic*.c) ---- */

/* max |(M^T J M - J)_ij| of a one-step Jacobian M in canonical z = (phi,
 * eta, P_phi, P_eta), each entry scaled by sc_i sc_j / sqrt(action_i
 * action_j) with the actions sc[0] sc[2] and sc[1] sc[3], so that the
 * residual is relative for every pair (J: dz/dt = J grad H). */
static inline double gc_symplectic_residual(const double M[4][4], const double sc[4])
{
    static const double J[4][4] = {{0, 0, 1, 0}, {0, 0, 0, 1}, {-1, 0, 0, 0}, {0, -1, 0, 0}};
    const double act[2] = {sc[0] * sc[2], sc[1] * sc[3]};
    double res = 0.0;
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            double r = -J[i][j];
            for (int a = 0; a < 4; a++)
                for (int b = 0; b < 4; b++) r += M[a][i] * J[a][b] * M[b][j];
            res = fmax(res, fabs(r) * sc[i] * sc[j] / sqrt(act[i % 2] * act[j % 2]));
        }
    return res;
}

/* The same in the extended phase space of the Sundman forms, z = (q1, q2,
 * t, p1, p2, p_t) with pairs (0, 3), (1, 4), (2, 5): max |(M^T J M - J)_ij|
 * scaled by sc_i sc_j / sqrt(action_i action_j), the actions sc[k] sc[k+3]
 * (test_gc_sundman.c, test_gc_sundman_line.c). */
static inline double gc_ext_symplectic_residual(const double M[6][6], const double sc[6])
{
    double res = 0.0;
    for (int i = 0; i < 6; i++)
        for (int j = 0; j < 6; j++) {
            double r = (j == i + 3) ? -1.0 : (i == j + 3) ? 1.0 : 0.0;
            for (int a = 0; a < 3; a++) r += M[a][i] * M[a + 3][j] - M[a + 3][i] * M[a][j];
            const double ai = sc[i % 3] * sc[i % 3 + 3], aj = sc[j % 3] * sc[j % 3 + 3];
            res = fmax(res, fabs(r) * sc[i] * sc[j] / sqrt(ai * aj));
        }
    return res;
}

/* The first three sign changes of p_par along an orbit (a gcp_gc_push
 * callback; stops the push at the third), each by linear interpolation
 * between the samples around it: two of them bracket one bounce. */
struct gc_bounce_ctx {
    double tprev, pprev, tc[3];
    int nc;
};

static inline int gc_bounce_cb(double t, const double X[3], double ppar, void *v)
{
    (void)X;
    struct gc_bounce_ctx *c = v;
    if (c->pprev * ppar < 0 && c->nc < 3)
        c->tc[c->nc++] = c->tprev + (t - c->tprev) * c->pprev / (c->pprev - ppar);
    c->tprev = t, c->pprev = ppar;
    return c->nc == 3;
}

/* Bounce period: the time between the first and the third sign change of
 * p_par under gc-rk8pd (tolerance 1e-12), located by linear interpolation
 * between samples 1e-4 T_guess apart (error ~1e-8 T_b, far below what the
 * tests need: the step h = T_b/N only sets the resolution).  NAN when the
 * orbit does not bounce within 10 T_guess. */
static inline double gc_bounce_period(const struct gcp_field *f, double q, double m, double mu,
                                      const double X0[3], double ppar, double Tguess)
{
    struct gc_bounce_ctx c = {0, ppar, {0}, 0};
    double X[3] = {X0[0], X0[1], X0[2]}, pp = ppar, t = 0;
    const struct gcp_push_opts o = {0.0, 1e-4 * Tguess, 100000, 0.0, 0.0};
    gcp_gc_push(f, &gcp_pusher_gc_rk8pd, q, m, &o, &t, X, &pp, mu, gc_bounce_cb, &c);
    return c.nc == 3 ? c.tc[2] - c.tc[0] : NAN;
}

/* A transit of the connection length 2 pi q R (q ~ 2) at v_par = 0.3 v:
 * the bounce-period guess of the tokamak-like tests [s]. */
static inline double gc_tokamak_tb_guess(double R, double p, double m)
{
    return 2 * GCP_PI * 2.0 * R / (p / m * 0.3);
}

#endif
