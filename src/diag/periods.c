/* Characteristic periods of a particle, used to resolve "duration = 2 drift"
 * or "dt = 0.01 gyro" in run files.
 *
 * Gyro period (relativistic):  T_g = 2 pi gamma m / (|q| B).
 * Dipole bounce period (Schulz & Lanzerotti 1974, eq. 1.28):
 *   T_b = (4 L R_E / v) T(y),  y = sin(a_eq),
 *   T(y) = int_0^lm cos(l) sqrt(1 + 3 sin^2 l) / sqrt(1 - y^2 b(l)) dl,
 *   b(l) = B(l)/B_eq = sqrt(1 + 3 sin^2 l) / cos^6 l,  b(lm) = 1/y^2.
 * Dipole drift period: the bounce average of the guiding-centre drift in a
 * vacuum field, v_d = gamma m (v_par^2 + v_perp^2/2) (B x grad B) / (q B^3),
 * azimuthal rate w = v_d.phi / (r cos l), averaged with weight ds / v_par:
 *   T_d = 2 pi / |<w>|.
 * Integrals by GSL QAG after the substitution l = lm sin(theta), which
 * removes the 1/sqrt endpoint singularity at the mirror point.  Accuracy
 * 1e-10 relative (1e-8 for near-equatorial mirroring): more than a run
 * length or a step needs. */
#include <math.h>
#include <string.h>

#include <gsl/gsl_errno.h>
#include <gsl/gsl_integration.h>

#include "gcpush/kernels.h"
#include "gcpush/error.h"
#include "gcpush/invariants.h"
#include "gcpush/particles.h"

struct bounce_ctx {
    double y2;   /* sin^2 a_eq */
    double LRE;  /* [m] L R_E */
    double Beq;  /* [T] equatorial field */
    const struct gcp_field *f;
    double gm;   /* gamma m [kg] */
    double q;    /* [C] */
    double v2;   /* [m^2/s^2] */
};

static double b_ratio(double l)
{
    const double s = sin(l), c = cos(l);
    return sqrt(1.0 + 3.0 * s * s) / (c * c * c * c * c * c);
}

/* ds/dl / sqrt(1 - y^2 b): the bounce-time weight per unit latitude over L R_E. */
static double bounce_weight(double l, void *p)
{
    const struct bounce_ctx *c = p;
    const double s = sin(l);
    const double w = 1.0 - c->y2 * b_ratio(l);
    return w > 0 ? cos(l) * sqrt(1.0 + 3.0 * s * s) / sqrt(w) : 0.0;
}

/* Azimuthal drift rate w(l) [rad/s] times the bounce weight. */
static double drift_weight(double l, void *p)
{
    const struct bounce_ctx *c = p;
    const double r = c->LRE * cos(l) * cos(l);
    const double x[3] = {r * cos(l), 0.0, r * sin(l)};
    struct gcp_field_sample smp = {.need = GCP_NEED_B | GCP_NEED_GRADB};
    gcp_field_eval(c->f, 0.0, x, &smp);
    const double *B = smp.B;
    const double Bm = sqrt(B[0] * B[0] + B[1] * B[1] + B[2] * B[2]);
    double gB[3];
    for (int j = 0; j < 3; j++)
        gB[j] = (B[0] * smp.gradB[0][j] + B[1] * smp.gradB[1][j] + B[2] * smp.gradB[2][j]) / Bm;
    const double bb = Bm / c->Beq;
    const double vperp2 = c->v2 * c->y2 * bb;
    const double vpar2 = fmax(c->v2 - vperp2, 0.0);
    const double cross_y = B[2] * gB[0] - B[0] * gB[2]; /* (B x grad B).yhat */
    const double vd_phi = c->gm * (vpar2 + 0.5 * vperp2) * cross_y / (c->q * Bm * Bm * Bm);
    return vd_phi / (r * cos(l)) * bounce_weight(l, p);
}

static double mirror_latitude(double y2)
{
    double lo = 0.0, hi = 0.5 * GCP_PI - 1e-12;
    for (int i = 0; i < 200 && hi - lo > 1e-15; i++) {
        const double mid = 0.5 * (lo + hi);
        if (y2 * b_ratio(mid) < 1.0) lo = mid; else hi = mid;
    }
    return 0.5 * (lo + hi);
}

/* int_0^lm fn(l) dl with l = lm sin(theta): the 1/sqrt(lm - l) endpoint
 * singularity of the bounce weight becomes smooth (cos(theta) / sqrt(1 - sin
 * theta) stays finite), so GSL's QAG converges for any mirror latitude,
 * including the near-equatorial ones where the interval is tiny. */
struct subst_ctx {
    double (*fn)(double, void *);
    void *ctx;
    double lm;
};

static double substituted(double th, void *p)
{
    const struct subst_ctx *c = p;
    return c->fn(c->lm * sin(th), c->ctx) * c->lm * cos(th);
}

static double integrate(double (*fn)(double, void *), void *ctx, double b)
{
    gsl_integration_workspace *w = gsl_integration_workspace_alloc(200);
    struct subst_ctx sc = {fn, ctx, b};
    gsl_function F = {substituted, &sc};
    double res = NAN, abserr;
    gsl_error_handler_t *old = gsl_set_error_handler_off();
    /* near-equatorial mirroring: 1 - y^2 b(l) loses digits to cancellation,
     * and QAG may stop short of 1e-10 (GSL_EROUND, GSL_EMAXITER) with an error
     * estimate ~1e-8 relative; that is still far more than a run length or a
     * step needs, so such a result is kept */
    const int rc = w ? gsl_integration_qag(&F, 0.0, 0.5 * GCP_PI, 0.0, 1e-10, 200,
                                           GSL_INTEG_GAUSS31, w, &res, &abserr)
                     : GSL_ENOMEM;
    if (rc && !(rc != GSL_ENOMEM && isfinite(res) && abserr <= 1e-6 * fabs(res))) res = NAN;
    gsl_set_error_handler(old);
    gsl_integration_workspace_free(w);
    return res;
}

int gcp_period_of(const struct gcp_field *f, const char *model, const struct gcp_species *sp,
                  const double x[3], const double u[3], enum gcp_period which, double *period)
{
    const double gamma = gcp_gamma_of_u(u[0], u[1], u[2]);
    const double u2 = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
    struct gcp_field_sample smp = {.need = GCP_NEED_B};
    if (gcp_field_eval(f, 0.0, x, &smp)) return GCP_ERR_STATE;
    const double B = sqrt(smp.B[0] * smp.B[0] + smp.B[1] * smp.B[1] + smp.B[2] * smp.B[2]);
    if (which == GCP_PERIOD_GYRO) {
        *period = 2.0 * GCP_PI * gamma * sp->mass / (fabs(sp->charge) * B);
        return isfinite(*period) && *period > 0 ? 0 : GCP_ERR_STATE;
    }
    (void)model; /* the field's capabilities say it, not its name */
    if (!(gcp_field_caps(f) & GCP_CAP_DIPOLE_L) || u2 == 0.0) return GCP_ERR_STATE;
    /* Equatorial pitch angle from the local one via mu conservation,
     * sin^2 a_eq = sin^2 a B_eq / B, with the particle mapped along its
     * dipole field line r = L R_E cos^2(lat). */
    const double r = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
    const double lat = asin(x[2] / r);
    const double LRE = r / (cos(lat) * cos(lat));
    const double upar = (u[0] * smp.B[0] + u[1] * smp.B[1] + u[2] * smp.B[2]) / B;
    const double sin2 = fmax(0.0, 1.0 - upar * upar / u2);
    struct bounce_ctx c = {
        .y2 = fmin(1.0, sin2 / b_ratio(lat)),
        .LRE = LRE,
        .f = f,
        .gm = gamma * sp->mass,
        .q = sp->charge,
        .v2 = u2 / (gamma * gamma),
    };
    {
        const double xe[3] = {LRE, 0, 0};
        struct gcp_field_sample se = {.need = GCP_NEED_B};
        gcp_field_eval(f, 0.0, xe, &se);
        c.Beq = sqrt(se.B[0] * se.B[0] + se.B[1] * se.B[1] + se.B[2] * se.B[2]);
    }
    const double v = sqrt(c.v2);
    if (c.y2 > 1.0 - 1e-6) {
        /* Equatorially mirroring: small-oscillation limit T(1) = pi sqrt(2) / 6,
         * drift at the equator itself.  Within 1 - y^2 < 1e-6 the mirror
         * latitude is l_m ~ sqrt((1 - y^2) / 4.5) < 5e-4 rad and both periods
         * differ from the limit by O(l_m^2) < 2.2e-7 relative, while QAG over
         * so short an interval loses the integrand to cancellation in
         * 1 - y^2 b(l) (pitch 89.99 deg, 1 - y^2 = 3e-8, gave NaN). */
        if (which == GCP_PERIOD_BOUNCE) *period = 4.0 * LRE / v * GCP_PI * sqrt(2.0) / 6.0;
        else *period = 2.0 * GCP_PI / fabs(drift_weight(0.0, &(struct bounce_ctx){
                           .y2 = 1.0 - 1e-12, .LRE = LRE, .f = f, .gm = c.gm, .q = c.q,
                           .v2 = c.v2, .Beq = c.Beq}) / bounce_weight(0.0, &(struct bounce_ctx){
                           .y2 = 1.0 - 1e-12}));
        return isfinite(*period) ? 0 : GCP_ERR_STATE;
    }
    const double lm = c.y2 > 0 ? mirror_latitude(c.y2) : 0.5 * GCP_PI;
    const double Ty = integrate(bounce_weight, &c, lm);
    if (which == GCP_PERIOD_BOUNCE) {
        *period = 4.0 * LRE / v * Ty;
    } else {
        const double Wy = integrate(drift_weight, &c, lm);
        *period = 2.0 * GCP_PI * Ty / fabs(Wy);
    }
    return isfinite(*period) && *period > 0 ? 0 : GCP_ERR_STATE;
}
