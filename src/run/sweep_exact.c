/* Exact relativistic motion in uniform, static, perpendicular E and B
 * (include/gcpush/sweep.h): a Lorentz boost to the frame where the field is
 * purely magnetic (|E| < c|B|, Jackson 3rd ed. sec. 12.3) or purely
 * electric (|E| > c|B|, Landau & Lifshitz vol. 2 sec. 20), the closed-form
 * motion there, and the boost back.
 *
 * Boost by beta (|beta| < 1, gamma), bhat = beta/|beta|:
 *   event:     t' = gamma (t - beta.x/c),  x' = x + (gamma-1)(bhat.x) bhat - gamma beta c t
 *   momentum:  u' = u + (gamma-1)(bhat.u) bhat - gamma beta g c,  g = sqrt(1 + u^2/c^2)
 *   fields:    E' = gamma (E + c beta x B) - gamma^2/(gamma+1) beta (beta.E)
 *              B' = gamma (B - beta x E / c) - gamma^2/(gamma+1) beta (beta.B)
 * (the inverse boosts take -beta). */
#include <float.h>
#include <math.h>
#include <string.h>

#include "gcpush/kernels.h"
#include "gcpush/sweep.h"

#define C GCP_C_LIGHT

static double dot(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void cross(const double a[3], const double b[3], double c[3])
{
    const double c0 = a[1] * b[2] - a[2] * b[1];
    const double c1 = a[2] * b[0] - a[0] * b[2];
    const double c2 = a[0] * b[1] - a[1] * b[0];
    c[0] = c0, c[1] = c1, c[2] = c2;
}

static double gamma_u(const double u[3]) { return sqrt(1.0 + dot(u, u) / (C * C)); }

/* Unit vectors e1, e2 with (e1, e2, b) right-handed. */
static void basis(const double b[3], double e1[3], double e2[3])
{
    int a = 0;
    for (int i = 1; i < 3; i++)
        if (fabs(b[i]) < fabs(b[a])) a = i;
    double t[3] = {0, 0, 0};
    t[a] = 1.0;
    cross(t, b, e1);
    const double n = sqrt(dot(e1, e1));
    for (int i = 0; i < 3; i++) e1[i] /= n;
    cross(b, e1, e2);
}

/* Momentum boost by s*beta (s = +1 lab -> frame, -1 back). */
static void boost_u(const struct gcp_exact_uniform *ex, double s, const double u[3], double out[3])
{
    const double b2 = dot(ex->beta, ex->beta);
    if (b2 == 0.0) {
        memcpy(out, u, 3 * sizeof(double));
        return;
    }
    const double k = (ex->gamma - 1.0) * dot(ex->beta, u) / b2;
    const double g = gamma_u(u);
    for (int i = 0; i < 3; i++) out[i] = u[i] + k * ex->beta[i] - s * ex->gamma * ex->beta[i] * g * C;
}

int gcp_exact_uniform_init(struct gcp_exact_uniform *ex, const double B[3], const double E[3],
                           double q, double m)
{
    memset(ex, 0, sizeof *ex);
    ex->q = q;
    ex->m = m;
    ex->gamma = 1.0;
    const double Bm = sqrt(dot(B, B)), Em = sqrt(dot(E, E));
    if (!isfinite(Bm) || !isfinite(Em) || !(m > 0) || !isfinite(q)) return GCP_ERR_VALUE;
    if (fabs(dot(E, B)) > 1e-12 * Em * Bm) return GCP_ERR_VALUE;
    double ExB[3];
    cross(E, B, ExB);
    if (Em == 0.0 && Bm == 0.0) {
        ex->regime = 0;
        return 0;
    }
    const double cB = C * Bm;
    if (fabs(Em - cB) <= 1e-12 * (Em + cB)) return GCP_ERR_VALUE;
    if (Em < cB) {
        /* v = E x B / B^2, |beta| = E/(cB) */
        for (int i = 0; i < 3; i++) ex->beta[i] = ExB[i] / (Bm * Bm * C);
        ex->regime = 1;
    } else {
        /* v = c^2 E x B / E^2, |beta| = cB/E */
        for (int i = 0; i < 3; i++) ex->beta[i] = C * ExB[i] / (Em * Em);
        ex->regime = 2;
    }
    const double b2 = dot(ex->beta, ex->beta);
    ex->gamma = 1.0 / sqrt((1.0 - sqrt(b2)) * (1.0 + sqrt(b2)));
    const double g = ex->gamma, k = g * g / (g + 1.0);
    double bxB[3], bxE[3];
    cross(ex->beta, B, bxB);
    cross(ex->beta, E, bxE);
    const double bE = dot(ex->beta, E), bB = dot(ex->beta, B);
    for (int i = 0; i < 3; i++) {
        ex->Ep[i] = g * (E[i] + C * bxB[i]) - k * ex->beta[i] * bE;
        ex->Bp[i] = g * (B[i] - bxE[i] / C) - k * ex->beta[i] * bB;
    }
    /* The boost removes E' (B') exactly in exact arithmetic; drop round-off. */
    const double *main = ex->regime == 1 ? ex->Bp : ex->Ep;
    if (ex->regime == 1)
        memset(ex->Ep, 0, sizeof ex->Ep);
    else
        memset(ex->Bp, 0, sizeof ex->Bp);
    const double n = sqrt(dot(main, main));
    for (int i = 0; i < 3; i++) ex->b[i] = main[i] / n;
    basis(ex->b, ex->e1, ex->e2);
    return 0;
}

/* Motion in the frame from x'(0) = 0, u'(0) = up0 at frame time tp:
 * position xp, momentum up, velocity vp. */
static void frame_motion(const struct gcp_exact_uniform *ex, const double up0[3], double tp,
                         double xp[3], double up[3], double vp[3])
{
    if (ex->regime == 0) {
        const double g = gamma_u(up0);
        for (int i = 0; i < 3; i++) {
            up[i] = up0[i];
            vp[i] = up0[i] / g;
            xp[i] = vp[i] * tp;
        }
        return;
    }
    const double *b = ex->b;
    const double upar = dot(up0, b);
    double uperp[3];
    for (int i = 0; i < 3; i++) uperp[i] = up0[i] - upar * b[i];
    if (ex->regime == 1) {
        /* du/dt = w u x b,  w = q B'/(gamma m): u_perp rotates; gamma constant */
        const double g = gamma_u(up0);
        const double Bm = sqrt(dot(ex->Bp, ex->Bp));
        const double w = ex->q * Bm / (g * ex->m);
        double uxb[3];
        cross(uperp, b, uxb);
        const double s = sin(w * tp), hs = sin(0.5 * w * tp);
        const double c = cos(w * tp), omc = 2.0 * hs * hs; /* 1 - cos without cancellation */
        for (int i = 0; i < 3; i++) {
            up[i] = upar * b[i] + uperp[i] * c + uxb[i] * s;
            vp[i] = up[i] / g;
            xp[i] = (upar * b[i] * tp + (uperp[i] * s + uxb[i] * omc) / w) / g;
        }
        return;
    }
    /* regime 2: du_par/dt = a = q E'/m, u_perp constant */
    const double Em = sqrt(dot(ex->Ep, ex->Ep));
    const double a = ex->q * Em / ex->m;
    const double up2 = dot(uperp, uperp);
    const double gp = sqrt(1.0 + up2 / (C * C)); /* transverse gamma */
    const double u1 = upar + a * tp;
    const double g0 = sqrt(gp * gp + upar * upar / (C * C));
    const double g1 = sqrt(gp * gp + u1 * u1 / (C * C));
    /* x_par = (c^2/a)(g1 - g0) = t (2 upar + a t) / (g1 + g0) */
    const double xpar = tp * (2.0 * upar + a * tp) / (g1 + g0);
    /* x_perp = u_perp (c/a) [asinh(u1/(c gp)) - asinh(upar/(c gp))] */
    const double dash = a != 0.0 ? (C / a) * (asinh(u1 / (C * gp)) - asinh(upar / (C * gp)))
                                 : tp / g0;
    for (int i = 0; i < 3; i++) {
        up[i] = u1 * b[i] + uperp[i];
        vp[i] = up[i] / g1;
        xp[i] = xpar * b[i] + uperp[i] * dash;
    }
}

int gcp_exact_uniform_state(const struct gcp_exact_uniform *ex, const double x0[3],
                            const double u0[3], double t, double x[3], double u[3],
                            double *phase)
{
    double up0[3];
    boost_u(ex, +1.0, u0, up0);
    const double g = ex->gamma;
    const double *beta = ex->beta;
    /* Solve gamma (t' + beta.x'(t')/c) = t; g(t') increasing. */
    double xp[3], up[3], vp[3];
    double lo = t / g, hi = t / g, step = fabs(t / g) * 1e-3 + 1e-300;
    double f;
    for (int k = 0;; k++) {
        frame_motion(ex, up0, lo, xp, up, vp);
        if (g * (lo + dot(beta, xp) / C) - t <= 0.0) break;
        lo -= step, step *= 2.0;
        if (k > 2000) return GCP_ERR_VALUE;
    }
    step = fabs(t / g) * 1e-3 + 1e-300;
    for (int k = 0;; k++) {
        frame_motion(ex, up0, hi, xp, up, vp);
        if (g * (hi + dot(beta, xp) / C) - t >= 0.0) break;
        hi += step, step *= 2.0;
        if (k > 2000) return GCP_ERR_VALUE;
    }
    double tp = 0.5 * (lo + hi);
    for (int it = 0; it < 300; it++) {
        frame_motion(ex, up0, tp, xp, up, vp);
        f = g * (tp + dot(beta, xp) / C) - t;
        if (f == 0.0) break;
        if (f < 0.0)
            lo = tp;
        else
            hi = tp;
        const double df = g * (1.0 + dot(beta, vp) / C);
        double next = tp - f / df;
        if (!(next > lo && next < hi)) next = 0.5 * (lo + hi); /* Newton left the bracket */
        if (fabs(next - tp) <= 4.0 * DBL_EPSILON * fabs(tp) || hi - lo <= 4.0 * DBL_EPSILON * fabs(tp)) {
            tp = next;
            break;
        }
        tp = next;
    }
    frame_motion(ex, up0, tp, xp, up, vp);
    /* back to the lab: x = x' + (gamma-1)(bhat.x') bhat + gamma beta c t' (+ x0) */
    const double b2 = dot(beta, beta);
    const double k = b2 > 0 ? (g - 1.0) * dot(beta, xp) / b2 : 0.0;
    for (int i = 0; i < 3; i++) x[i] = x0[i] + xp[i] + k * beta[i] + g * beta[i] * C * tp;
    boost_u(ex, -1.0, up, u);
    if (phase) {
        if (ex->regime == 1) {
            const double w = gcp_exact_uniform_omega(ex, u0);
            const double p0 = atan2(dot(up0, ex->e2), dot(up0, ex->e1));
            *phase = p0 - w * tp;
        } else {
            *phase = NAN;
        }
    }
    for (int i = 0; i < 3; i++)
        if (!isfinite(x[i]) || !isfinite(u[i])) return GCP_ERR_VALUE;
    return 0;
}

double gcp_exact_uniform_phase(const struct gcp_exact_uniform *ex, const double u[3])
{
    if (ex->regime != 1) return NAN;
    double up[3];
    boost_u(ex, +1.0, u, up);
    return atan2(dot(up, ex->e2), dot(up, ex->e1));
}

double gcp_exact_uniform_omega(const struct gcp_exact_uniform *ex, const double u[3])
{
    if (ex->regime != 1) return NAN;
    double up[3];
    boost_u(ex, +1.0, u, up);
    return ex->q * sqrt(dot(ex->Bp, ex->Bp)) / (gamma_u(up) * ex->m);
}
