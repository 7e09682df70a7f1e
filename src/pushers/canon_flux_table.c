/* The construction of the tabulated orthogonal chart's table: the axis,
 * the gradient lines of psi traced with GSL rk8pd, the eta labels and the
 * gauge of A_eta (the equations: canon_flux_num.c's header; the table's
 * layout: canon_flux_num_priv.h).  Split from canon_flux_num.c, which
 * evaluates and caches it, so that each file can be held in mind. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_errno.h>
#include <gsl/gsl_odeiv2.h>

#include "canon_flux_num_priv.h"
#include "flux_priv.h"
#include "gcpush/error.h"
#include "gcpush/particles.h"

/* ---- construction -------------------------------------------------------- */

struct trace_ctx {
    const struct gcp_field *f;
    double dpsi;
    int status;
};

/* y = (R, Z, R_e, Z_e, A), t = rho */
static int trace_rhs(double rho, const double y[], double dy[], void *vctx)
{
    struct trace_ctx *c = vctx;
    double ps[6];
    int st = gcp_field_psi_RZ(c->f, y[0], y[1], ps);
    const double gR = ps[1], gZ = ps[2], g2 = gR * gR + gZ * gZ;
    if (st || !(g2 > 0.0)) {
        c->status = st ? st : GCP_STEP_FAILED;
        return GSL_EBADFUNC;
    }
    const double k = 2.0 * rho * c->dpsi;
    const double VR = k * gR / g2, VZ = k * gZ / g2;
    /* DV_ij = k (H_ij/g2 - 2 g_i (H g)_j / g2^2) */
    const double HgR = ps[3] * gR + ps[4] * gZ, HgZ = ps[4] * gR + ps[5] * gZ;
    const double i2 = 1.0 / g2, i4 = 2.0 * i2 * i2;
    const double D00 = k * (ps[3] * i2 - i4 * gR * HgR), D01 = k * (ps[4] * i2 - i4 * gR * HgZ);
    const double D10 = k * (ps[4] * i2 - i4 * gZ * HgR), D11 = k * (ps[5] * i2 - i4 * gZ * HgZ);
    const double X[3] = {y[0], 0.0, y[1]};
    struct gcp_field_sample s = {.need = GCP_NEED_B};
    if ((st = gcp_field_eval(c->f, 0.0, X, &s))) {
        c->status = st;
        return GSL_EBADFUNC;
    }
    dy[0] = VR;
    dy[1] = VZ;
    dy[2] = D00 * y[2] + D01 * y[3];
    dy[3] = D10 * y[2] + D11 * y[3];
    dy[4] = (VZ * y[2] - VR * y[3]) * s.B[1]; /* B_phi = B_y at phi = 0 */
    return GSL_SUCCESS;
}

/* grad psi = 0 by Newton from the guess. */
static int find_axis(const struct gcp_field *f, double *R, double *Z, double *psi)
{
    for (int it = 0; it < 50; it++) {
        double p[6];
        if (gcp_field_psi_RZ(f, *R, *Z, p)) return GCP_LEFT_DOMAIN;
        const double det = p[3] * p[5] - p[4] * p[4];
        if (!(det > 0.0)) return GCP_STEP_FAILED; /* not an extremum */
        const double dR = -(p[5] * p[1] - p[4] * p[2]) / det;
        const double dZ = -(-p[4] * p[1] + p[3] * p[2]) / det;
        *R += dR, *Z += dZ;
        *psi = p[0];
        if (hypot(dR, dZ) < 1e-13 * fabs(*R)) {
            gcp_field_psi_RZ(f, *R, *Z, p);
            *psi = p[0];
            return 0;
        }
    }
    return GCP_STEP_FAILED;
}

/* Point of the surface psi_N = pn on the ray at angle eta from the axis,
 * and dX/deta there (the surface's own parameterisation by the angle). */
static int ref_point(const struct numchart *n, double pn, double eta, double y[5])
{
    const double c = cos(eta), s = sin(eta);
    double t = 0.0, t1 = 0.05, ps[6];
    /* bracket by stepping out, then bisect + secant to round-off */
    for (;;) {
        if (gcp_field_psi_RZ(n->f, n->Ra + t1 * c, n->Za + t1 * s, ps)) return GCP_LEFT_DOMAIN;
        if ((ps[0] - n->psia) / n->dpsi >= pn) break;
        t = t1, t1 *= 1.5;
        if (t1 > 100.0) return GCP_STEP_FAILED;
    }
    for (int it = 0; it < 200 && t1 - t > 1e-15 * t1; it++) {
        const double m = 0.5 * (t + t1);
        gcp_field_psi_RZ(n->f, n->Ra + m * c, n->Za + m * s, ps);
        if ((ps[0] - n->psia) / n->dpsi >= pn)
            t1 = m;
        else
            t = m;
    }
    const double tm = 0.5 * (t + t1);
    y[0] = n->Ra + tm * c, y[1] = n->Za + tm * s;
    gcp_field_psi_RZ(n->f, y[0], y[1], ps);
    const double ge = ps[1] * c + ps[2] * s, gp = -ps[1] * s + ps[2] * c;
    if (!(ge != 0.0)) return GCP_STEP_FAILED;
    const double tp = -tm * gp / ge;
    y[2] = tp * c - tm * s;
    y[3] = tp * s + tm * c;
    y[4] = 0.0;
    return 0;
}

/* The gauge of A_eta: A = 0 on the axis (A_eta deta must vanish there for
 * the one-form to be regular at the chart's pole), i.e.
 *   A(rho, eta) = int_0^rho J B^phi drho',  J = Z_rho R_eta - R_rho Z_eta,
 * along the gradient line eta.  The tracing reaches node 1 (rho = drho);
 * the piece from there to the axis is not a polynomial in rho at an
 * elongated axis: there psi - psi_a = (l1 x^2 + l2 y^2)/2 in the Hessian's
 * eigen-axes (x, y), the gradient lines are the power curves y = C x^n,
 * n = l2/l1 (tangent to one axis at the pole, turning at a rho that goes to 0
 * as the line nears the other axis), and a quadratic extrapolation of A
 * through nodes 1, 2, 3 (as before) errs by an amount that varies with
 * eta on the scale of that turn: a ~0.25 rad wiggle in eta of A_eta at every
 * rho in DIII-D, which Gauss-Legendre methods (not invariant under the
 * gauge map P_eta -> P_eta + q f(eta)) turn into an energy drift
 * (tests/unit/test_gc_symplectic_flux.c).  In the quadratic model the piece
 * has a closed form in the line's point (x, y) and tangent (x_e, y_e) at
 * node 1: with alpha = (x dy - y dx)/2 (d alpha = dx ^ dy), the integrand
 * is -(d alpha)_(rho eta), so by Stokes on the strip between the pole and
 * rho, int_0^rho J drho' = -alpha_eta + d/deta int_line alpha, and along
 * y = C x^n, x dy - y dx = (n - 1) y dx integrates to
 * ((n - 1)/(n + 1)) x y: hence
 *   int_0^rho J drho' = (n y x_e - x y_e) / (n + 1),
 * (n = 1, rays: -r^2/2), times B_phi on the axis.  A smooth function of the
 * line's data at node 1, exact for a quadratic psi and constant B_phi; the
 * error is O(drho^3) (cubic terms of psi, B_phi's gradient), smooth in eta. */
struct axis_model {
    double Ra, Za, c, s; /* the axis and the eigen-axis x = (c, s), y = (-s, c) */
    double n;            /* l2 / l1 */
    double Bphi;         /* [T] B_phi on the axis */
};

static void axis_model(const struct gcp_field *f, double Ra, double Za, struct axis_model *m)
{
    double p[6];
    gcp_field_psi_RZ(f, Ra, Za, p);
    const double a = p[3], b = p[4], c = p[5];
    const double th = 0.5 * atan2(2.0 * b, a - c); /* x along the eigenvalue l1 */
    const double mid = 0.5 * (a + c), rad = hypot(0.5 * (a - c), b);
    m->Ra = Ra, m->Za = Za, m->c = cos(th), m->s = sin(th);
    m->n = (mid - rad) / (mid + rad); /* l2 / l1 (same sign at an extremum) */
    const double X[3] = {Ra, 0.0, Za};
    struct gcp_field_sample fs = {.need = GCP_NEED_B};
    gcp_field_eval(f, 0.0, X, &fs);
    m->Bphi = fs.B[1];
}

/* int_0^rho J drho' of the quadratic model at the line's point and tangent
 * y = (R, Z, R_e, Z_e, ...). */
static double inner_A(const struct axis_model *m, const double y[5])
{
    const double dR = y[0] - m->Ra, dZ = y[1] - m->Za;
    const double x = m->c * dR + m->s * dZ, yy = -m->s * dR + m->c * dZ;
    const double xe = m->c * y[2] + m->s * y[3], ye = -m->s * y[2] + m->c * y[3];
    return (m->n * yy * xe - x * ye) / (m->n + 1.0);
}

/* The labels of the gradient lines.  eta labels each line by the toroidal
 * flux between it and the line through the outboard point of the reference
 * surface (geometric angle 0 about the axis), inside that surface:
 *   eta(g) = 2 pi Phi(g) / Phi_tot,  Phi(g) = int_0^g A_ref(g') dg',
 * g the geometric angle at which the line crosses the reference surface and
 * A_ref(g) = A_eta there in the labels g (gauge A = 0 on the axis: the
 * toroidal flux per unit g of the wedge between the axis, the line and the
 * surface).  In these labels A_eta = Phi_tot / 2 pi on the reference surface,
 * the same for every line, and near it A_eta varies with eta only as the
 * flux between neighbouring lines changes along them: the gauge A(0, eta) = 0
 * that the pole needs is kept, and P_eta = q A_eta + p_par h_eta has no
 * eta-dependence of q A_eta to follow that the labels put there.  With the
 * geometric angle as label (as before) q A_eta varied by ~40% along the
 * reference surface in DIII-D, with harmonics up to m ~ 30, which a
 * Gauss-Legendre method at 25 steps per bounce follows with an energy error
 * of 1e-3 that drifts (the method is not invariant under relabellings or
 * gauge changes, only the exact flow is).
 * A_ref at the NETA angles g_j (pass 1 of table_build) gives Phi by its
 * Fourier series (exact for the trigonometric interpolant), and the labels'
 * nodes eta_j = -pi + j deta are mapped back to g_j by Newton.  Out:
 * eg[j] = g_j and eg[NETA + j] = dg/deta there = Phi_tot / (2 pi A_ref(g_j))
 * (the tangent dX/deta = dX/dg dg/deta of the line).  0, or GCP_STEP_FAILED
 * where A_ref changes sign (B_phi must keep one). */
static int flux_labels(const double *Aref, double *eg)
{
    const int M = NETA / 2;
    double *ca = malloc(2 * (size_t)M * sizeof *ca), *sa = ca ? ca + M : NULL;
    if (!ca) return GCP_ERR_NOMEM;
    double c0 = 0.0;
    for (int j = 0; j < NETA; j++) c0 += Aref[j] / NETA;
    for (int m = 1; m < M; m++) {
        double a = 0.0, b = 0.0;
        for (int j = 0; j < NETA; j++) {
            const double g = -GCP_PI + 2.0 * GCP_PI * j / NETA;
            a += Aref[j] * cos(m * g), b += Aref[j] * sin(m * g);
        }
        ca[m] = 2.0 * a / NETA, sa[m] = 2.0 * b / NETA;
    }
    int rc = 0;
    for (int j = 0; j < NETA && !rc; j++) {
        /* eta(g) = g + sum (a_m sin mg - b_m (cos mg - 1)) / (m c0) */
        const double et = -GCP_PI + 2.0 * GCP_PI * j / NETA;
        double g = et, dg = 1.0;
        for (int it = 0; it < 50; it++) {
            double e = g, de = 1.0;
            for (int m = 1; m < M; m++) {
                const double cm = cos(m * g), sm = sin(m * g);
                e += (ca[m] * sm - sa[m] * (cm - 1.0)) / (m * c0);
                de += (ca[m] * cm + sa[m] * sm) / c0;
            }
            if (!(de > 0.0)) {
                rc = GCP_STEP_FAILED;
                break;
            }
            const double step = (e - et) / de;
            g -= step;
            dg = 1.0 / de;
            if (fabs(step) < 1e-15) break;
        }
        eg[j] = g, eg[NETA + j] = dg;
    }
    free(ca);
    return rc;
}

/* Builds the table of f (axis guess Ra, Za; boundary flux pe).  0, or
 * GCP_ERR_STATE / GCP_ERR_NOMEM with why filled. */
int gcp_flux_num_table_build(const struct gcp_field *f, double Ra, double Za, double pe,
                             struct numchart **out, char *why, size_t whylen)
{
    struct numchart *n = calloc(1, sizeof *n);
    double *tab = malloc((3 * NRHO + 1) * (NETA + 2 * NPAD) * sizeof *tab);
    if (!n || !tab) {
        free(n), free(tab);
        snprintf(why, whylen, "out of memory");
        return GCP_ERR_NOMEM;
    }
    n->f = f;
    double psia = 0.0;
    if (find_axis(f, &Ra, &Za, &psia)) {
        snprintf(why, whylen, "no magnetic axis (an extremum of psi) near (R, Z) = (%g, %g) m",
                 Ra, Za);
        free(n), free(tab);
        return GCP_ERR_STATE;
    }
    n->Ra = Ra, n->Za = Za, n->psia = psia, n->dpsi = pe - psia;
    n->rho_max = sqrt(PSIN_MAX);
    const double drho = n->rho_max / (NRHO - 1), deta = 2.0 * GCP_PI / NETA;
    const size_t ne = NETA + 2 * NPAD, nn = (size_t)NRHO * ne;
    double *TR = tab, *TZ = tab + nn, *TA = tab + 2 * nn, *TI = tab + 3 * nn;
    struct axis_model ax;
    axis_model(f, Ra, Za, &ax);
    struct trace_ctx tc = {.f = f, .dpsi = n->dpsi, .status = 0};
    gsl_odeiv2_system sys = {trace_rhs, NULL, 5, &tc};
    gsl_odeiv2_driver *d =
        gsl_odeiv2_driver_alloc_y_new(&sys, gsl_odeiv2_step_rk8pd, 1e-3 * drho, 1e-13, 1e-13);
    const double rho_ref = RHO_REF * n->rho_max;
    int rc = d ? 0 : GCP_ERR_NOMEM;
    gsl_error_handler_t *old_handler = gsl_set_error_handler_off();
    /* pass 1: the lines at the geometric angles, inward only: A on the
     * reference surface (flux_labels); pass 2: the lines at the labels of
     * equal toroidal flux, the table */
    double *Aref = malloc(NETA * sizeof *Aref), *eg = malloc(2 * NETA * sizeof *eg);
    if (!Aref || !eg) rc = GCP_ERR_NOMEM;
    for (int pass = 0; pass < 2 && !rc; pass++) {
        for (int j = 0; j < NETA && !rc; j++) {
            double y0[5];
            if ((rc = ref_point(n, rho_ref * rho_ref, pass ? eg[j] : -GCP_PI + j * deta, y0)))
                break;
            if (pass) y0[2] *= eg[NETA + j], y0[3] *= eg[NETA + j];
            for (int dir = -1; dir <= pass && !rc; dir += 2) {
                double y[5], rho = rho_ref;
                memcpy(y, y0, sizeof y);
                gsl_odeiv2_driver_reset_hstart(d, dir * 1e-3 * drho);
                /* inward: nodes floor(ref) .. 1 (node 0 is the axis); outward: the rest */
                const int i0 =
                    dir < 0 ? (int)floor(rho_ref / drho) : (int)floor(rho_ref / drho) + 1;
                for (int i = i0; dir < 0 ? i >= 1 : i < NRHO; i += dir) {
                    if (gsl_odeiv2_driver_apply(d, &rho, i * drho, y) != GSL_SUCCESS) {
                        rc = tc.status ? tc.status : GCP_STEP_FAILED;
                        break;
                    }
                    /* A(rho_ref) - A(0) = -(A(node 1) - inner) */
                    if (!pass && i == 1) Aref[j] = ax.Bphi * inner_A(&ax, y) - y[4];
                    for (int pk = -1; pk <= 1 && pass; pk++) { /* the node, periodic copies */
                        const int jj = j + NPAD + pk * NETA;
                        if (jj < 0 || jj >= (int)ne) continue;
                        const size_t at = (size_t)i + (size_t)NRHO * (size_t)jj;
                        TR[at] = y[0], TZ[at] = y[1], TA[at] = y[4];
                        if (i == 1) TI[jj] = ax.Bphi * inner_A(&ax, y); /* node 1 .. axis */
                    }
                }
            }
        }
        if (!pass && !rc) rc = flux_labels(Aref, eg);
    }
    free(Aref), free(eg);
    if (d) gsl_odeiv2_driver_free(d);
    gsl_set_error_handler(old_handler);
    if (rc) {
        snprintf(why, whylen, "tracing the gradient lines of psi failed (status %d): are the "
                              "flux surfaces closed up to psi_N = %g inside the field's domain?",
                 rc, PSIN_MAX);
        free(n), free(tab);
        return GCP_ERR_STATE;
    }
    /* The axis row, and A = 0 there: A was integrated from the reference
     * surface down to node 1; the rest, node 1 .. the axis, is the axis
     * model's inner_A (a smooth function of the line's point and tangent at
     * node 1), so A(0, eta) = A(node 1) - inner. */
    for (size_t jj = 0; jj < ne; jj++) {
        double *r = TR + NRHO * jj, *z = TZ + NRHO * jj, *a = TA + NRHO * jj;
        r[0] = Ra, z[0] = Za;
        const double a0 = a[1] - TI[jj];
        for (int i = 1; i < NRHO; i++) a[i] -= a0;
        a[0] = 0.0;
    }
    const size_t nsz[2] = {NRHO, ne};
    const double x0[2] = {0.0, -GCP_PI - NPAD * deta}, hh[2] = {drho, deta};
    const double *data[3] = {TR, TZ, TA};
    struct gcp_error err = {0};
    /* as smooth as psi: septic (C6) where psi is C6 or smoother */
    const int kind = gcp_field_psi_continuity(f) >= 6 ? GCP_SPL_SEPTIC : GCP_SPL_QUINTIC;
    rc = gcp_spl_build(&n->spl, 2, kind, nsz, x0, hh, 3, data, &err);
    free(tab);
    if (rc) {
        snprintf(why, whylen, "flux chart table: %s", err.msg);
        free(n);
        return rc;
    }
    n->f = NULL;
    n->refs = 1;
    *out = n;
    return 0;
}

