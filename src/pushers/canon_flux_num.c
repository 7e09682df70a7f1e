/* The tabulated orthogonal poloidal chart (s, eta) = (rho, eta) of an
 * axisymmetric field with a flux function (G-EQDSK, R-Z grids with psi, or
 * any model with gcp_field_psi_RZ), for the canonical flux chart
 * (canon_flux.c).  Built once, at construction.
 *
 *   rho = sqrt(psi_N),  psi_N = (psi - psi_axis) / (psi_edge - psi_axis),
 * so R(rho, eta) = R_axis + rho c(eta) + O(rho^2) is smooth at the axis.
 * eta labels the gradient lines of psi by the toroidal flux between them
 * and the outboard line inside the reference surface rho_ref (flux_labels:
 * A_eta is then the same on that whole surface), found from the lines at
 * the geometric angles about the axis (a first, inward pass).  Each line is
 * traced from the reference surface, in and out, with GSL rk8pd at 1e-13:
 *   dX/drho   = V(X) = 2 rho Dpsi grad psi / |grad psi|^2      (psi_N = rho^2),
 *   dX_e/drho = DV(X) X_e,  DV = 2 rho Dpsi (H/|g|^2 - 2 g (H g)^T/|g|^4)
 *               (the tangent equation: X_e = dX/deta, g = grad psi, H its
 *               Hessian; X_e stays tangent to the flux surface),
 *   dA/drho   = (Z_rho R_eta - R_rho Z_eta) B_phi(X)   (= J B^phi, gauge A_rho = 0),
 * starting from X_e on the reference surface (psi(X(eta)) = const:
 * X = X_axis + t(g) e(g), t' = -t (g.e')/(g.e) at the geometric angle g,
 * times dg/deta), with A = 0 on the axis (the remaining gauge freedom
 * A_eta + f(eta) fixed by regularity there; the piece node 1 .. axis in
 * closed form, inner_A).
 * R, Z, A on a uniform (rho, eta) grid, periodic in eta (padded by NPAD
 * nodes each side: the end conditions of the quintic B-spline decay like
 * 0.43^k into the table, 0.43^40 ~ 2e-15; the septic's like 0.54^k, 1.4e-11
 * of end conditions that are themselves O(h^9) right) are interpolated by
 * the spline of fields/grid_priv.h: septic (C6) where the field's psi is C6
 * or smoother (G-EQDSK, analytic), else the C4 biquintic; its derivatives are the chart's,
 * so the chart is exactly canonical in its own coordinates, and
 * approximates the true one-form to the tabulation error (O(h^6) in R, Z,
 * A; O(h^5) in dX/drho, so h_s = b . dX/drho = O(h^5), measured in
 * tests/unit/test_canon_flux.c).  C4 and not C2: the Hamiltonian's
 * gradient holds the table's second derivatives (X_se, X_ee in h_eta's
 * derivatives), so the one-step map's Jacobian holds its third, which a
 * bicubic table makes jump at every cell boundary.  C6 where psi allows:
 * gc-gl4's fourth order needs the flow C4 (fields/eqdsk.c, "Why C6").
 *
 * Domain: rho <= rho_max = sqrt(psiN_max) (default psi_N <= 0.9: the chart
 * degenerates at the separatrix, where grad psi -> 0 at the X-point); a
 * particle beyond gets GCP_LEFT_DOMAIN, and one at the axis (rho -> 0, where
 * the chart is polar) GCP_STEP_FAILED from the inversion.
 */
#include <math.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_errno.h>
#include <gsl/gsl_odeiv2.h>

#include "canon_flux_priv.h"
#include "gcpush/error.h"
#include "gcpush/particles.h"
#include "grid_priv.h"
#include "spl_inline.h"

#define NRHO 128
#define NETA 512
#define NPAD 40       /* periodic padding each side */
#define PSIN_MAX 0.9  /* edge of the chart in psi_N */
#define RHO_REF 0.6

/* The table: immutable once built, shared (reference counted) by every
 * chart of fields with the same fingerprint (see the cache below). */
struct numchart {
    const struct gcp_field *f; /* during construction only (NULL after) */
    int refs;                  /* holders (charts and the cache), under cache_lock */
    struct gcp_spl spl; /* (rho, eta): 0 R, 1 Z, 2 A_eta */
    double Ra, Za;      /* [m] magnetic axis (of the field's psi) */
    double psia, dpsi;  /* [Wb/rad] psi on axis, psi_edge - psi_axis */
    double rho_max;
};

/* What a chart's map and locate see: the field and the shared table. */
struct numview {
    const struct gcp_field *f;
    struct numchart *t;
};

static void table_free(struct numchart *n)
{
    if (!n) return;
    gcp_spl_free(&n->spl);
    free(n);
}

static double wrap_eta(double eta)
{
    return eta - 2.0 * GCP_PI * floor((eta + GCP_PI) / (2.0 * GCP_PI));
}

/* R, Z, A_eta of the table with their first and second derivatives at x:
 * gcp_spl_locate and gcp_spl_eval (order 2, the components 0, 1, 2) from
 * the inlines they are made of (fields/spl_inline.h: the same numbers),
 * with the stencil's size a constant and one locate for the three.  Why:
 * num_map runs at every chart evaluation (~11 a step of gc-gl2, ~17 of
 * gc-gl4 in DIII-D, bench_flux's orbit); with the generic routines (the
 * kind and the stencil's size read at run time, a call a component) a
 * step of gc-gl2 / gc-gl4 took 11% / 19% more CPU there with the quintic
 * table (6.4 / 10.0 us).  A_eta's second derivatives only with d3 (the
 * jets; the map's point has none): order 1 otherwise, the same sums for
 * the value and first derivatives (gcp_spl2_eval8 / _k: the same numbers),
 * a third fewer for that component. */
static void num_spl3(const struct gcp_spl *sp, const double x[2], struct gcp_spl_out o[3],
                     struct flux_d3 *d3)
{
    double w[2][8], dw[2][8], ddw[2][8], dddw[2][8];
    size_t base = 0;
    const int sept = sp->kind == GCP_SPL_SEPTIC;
    for (int a = 0; a < 2; a++) {
        size_t off;
        double t;
        gcp_spl_cell(sp, a, x[a], &off, &t);
        base += off;
        if (sept)
            gcp_spl_w7(t, sp->inv_h[a], 2, w[a], dw[a], ddw[a]);
        else
            gcp_spl_w5(t, sp->inv_h[a], 2, w[a], dw[a], ddw[a]);
        if (d3) gcp_spl_w7_3(t, sp->inv_h[a], dddw[a]);
    }
    const size_t s1 = sp->stride[1];
    for (int c = 0; c < 3; c++) {
        if (d3 && c < 2) /* septic: R and Z with their third derivatives */
            gcp_spl2_eval8_3(sp->coef[c] + base, s1, w[0], dw[0], ddw[0], dddw[0], w[1], dw[1],
                             ddw[1], dddw[1], &o[c], c ? d3->Z3 : d3->R3);
        else if (sept)
            gcp_spl2_eval8(sp->coef[c] + base, s1, w[0], dw[0], ddw[0], w[1], dw[1], ddw[1],
                           c < 2 || d3 ? 2 : 1, &o[c]);
        else
            gcp_spl2_eval_k(6, sp->coef[c] + base, s1, w[0], dw[0], ddw[0], w[1], dw[1], ddw[1],
                            c < 2 || d3 ? 2 : 1, &o[c]);
    }
}

/* The table's part of the map (R, Z, A_eta and their derivatives). */
static void num_map_table(const struct numchart *n, double s, double eta,
                          struct gcp_polchart_pt *pt, struct flux_d3 *d3)
{
    const double x[2] = {s, wrap_eta(eta)};
    struct gcp_spl_out o[3];
    if ((n->spl.kind == GCP_SPL_QUINTIC || n->spl.kind == GCP_SPL_SEPTIC) && n->spl.nd == 2) {
        num_spl3(&n->spl, x, o, d3);
    } else {
        struct gcp_spl_loc loc;
        gcp_spl_locate(&n->spl, x, 2, &loc);
        for (int c = 0; c < 3; c++) gcp_spl_eval(&n->spl, &loc, c, 2, &o[c]);
    }
    pt->R = o[0].f, pt->Z = o[1].f, pt->A = o[2].f;
    pt->R_s = o[0].d[0], pt->R_e = o[0].d[1];
    pt->Z_s = o[1].d[0], pt->Z_e = o[1].d[1];
    pt->A_s = o[2].d[0], pt->A_e = o[2].d[1];
    pt->R_ss = o[0].dd[0][0], pt->R_se = o[0].dd[0][1], pt->R_ee = o[0].dd[1][1];
    pt->Z_ss = o[1].dd[0][0], pt->Z_se = o[1].dd[0][1], pt->Z_ee = o[1].dd[1][1];
    if (d3) d3->A2[0] = o[2].dd[0][0], d3->A2[1] = o[2].dd[0][1], d3->A2[2] = o[2].dd[1][1];
}

/* psi's part, from psi and its R, Z derivatives at the point (ps), and the
 * map's status (st: psi's). */
static int num_map_psi(const struct numchart *n, double s, const double ps[6], int st,
                       struct gcp_polchart_pt *pt)
{
    pt->psi = ps[0];
    pt->psi_s = ps[1] * pt->R_s + ps[2] * pt->Z_s;
    pt->psi_e = ps[1] * pt->R_e + ps[2] * pt->Z_e;
    if (!(s >= 0.0 && s <= n->rho_max)) return GCP_LEFT_DOMAIN;
    return st ? GCP_LEFT_DOMAIN : 0;
}

static int num_map(const void *ctx, double s, double eta, struct gcp_polchart_pt *pt)
{
    const struct numview *v = ctx;
    num_map_table(v->t, s, eta, pt, NULL);
    double ps[6];
    const int st = gcp_field_psi_RZ(v->f, pt->R, pt->Z, ps);
    return num_map_psi(v->t, s, ps, st, pt);
}

/* num_map and the field at the point, psi evaluated once for both
 * (gcp_field_psi_B_RZ: in DIII-D the map's psi and the field's B are one
 * spline locate and evaluation, not two). */
static int num_map_field(const void *ctx, double s, double eta, struct gcp_polchart_pt *pt,
                         struct gcp_field_sample *fs)
{
    const struct numview *v = ctx;
    num_map_table(v->t, s, eta, pt, NULL);
    double ps[6];
    int fst;
    const int st = gcp_field_psi_B_RZ(v->f, pt->R, pt->Z, ps, fs, &fst);
    const int mst = num_map_psi(v->t, s, ps, st, pt);
    return mst ? mst : fst;
}

/* num_map_field (the same numbers) with d3 (canon_flux_priv.h), where the
 * table is septic and the field has B's second derivatives. */
static int num_map_field3(const void *ctx, double s, double eta, struct gcp_polchart_pt *pt,
                          struct gcp_field_sample *fs, struct flux_d3 *d3)
{
    const struct numview *v = ctx;
    d3->ok = v->t->spl.kind == GCP_SPL_SEPTIC && v->t->spl.nd == 2;
    num_map_table(v->t, s, eta, pt, d3->ok ? d3 : NULL);
    int fst, st = d3->ok ? gcp_field_psi_B_RZ3(v->f, pt->R, pt->Z, d3->ps, fs, &fst, d3->Bd) : -1;
    if (st == -1) {
        d3->ok = 0;
        st = gcp_field_psi_B_RZ(v->f, pt->R, pt->Z, d3->ps, fs, &fst);
    }
    const int mst = num_map_psi(v->t, s, d3->ps, st, pt);
    return mst ? mst : fst;
}

/* The distance from (R, Z) to the chart's point (rho, eta node j): R and Z
 * alone, the value of the table's spline (num_map's R and Z to the bit: the
 * same weights and sums, without the derivatives, A_eta and psi).  For
 * the septic table inline (spl_inline.h: the same expressions as
 * gcp_spl_locate / gcp_spl_eval, so the same numbers), rho's cell and
 * weights (axis 0, the same for every node of the scan) taken once
 * (node_scan_rho), and one locate for R and Z.  Why: gcp_gl_init maps five points through to_canon
 * every 256 steps of gcp_gc_push, ~100 node distances each; through the
 * generic routines (the kind and order read at run time, a locate a
 * component) they were 3.6% of gc-gl2's CPU a step in DIII-D
 * (bench_flux). */
struct node_scan {
    int sept;      /* the table is the 2D septic (the inline path) */
    size_t off0;   /* axis 0's cell offset */
    double w0[8];  /* axis 0's weights at rho */
};

static void node_scan_rho(const struct numchart *n, double rho, struct node_scan *ns)
{
    ns->sept = n->spl.kind == GCP_SPL_SEPTIC && n->spl.nd == 2;
    if (!ns->sept) return;
    double t, dw[8], ddw[8];
    gcp_spl_cell(&n->spl, 0, rho, &ns->off0, &t);
    gcp_spl_w7(t, n->spl.inv_h[0], 0, ns->w0, dw, ddw);
}

static double node_dist(const struct numchart *n, const struct node_scan *ns, double rho, int j,
                        double R, double Z)
{
    const double ej = -GCP_PI + 2.0 * GCP_PI * j / NETA;
    const double x[2] = {rho, wrap_eta(ej)};
    struct gcp_spl_out oR, oZ;
    if (ns->sept) {
        size_t off1;
        double t, w1[8], dw[8], ddw[8];
        gcp_spl_cell(&n->spl, 1, x[1], &off1, &t);
        gcp_spl_w7(t, n->spl.inv_h[1], 0, w1, dw, ddw);
        const size_t base = ns->off0 + off1, s1 = n->spl.stride[1];
        gcp_spl2_eval8(n->spl.coef[0] + base, s1, ns->w0, dw, ddw, w1, dw, ddw, 0, &oR);
        gcp_spl2_eval8(n->spl.coef[1] + base, s1, ns->w0, dw, ddw, w1, dw, ddw, 0, &oZ);
    } else {
        struct gcp_spl_loc loc;
        gcp_spl_locate(&n->spl, x, 0, &loc);
        gcp_spl_eval(&n->spl, &loc, 0, 0, &oR);
        gcp_spl_eval(&n->spl, &loc, 1, 0, &oZ);
    }
    return hypot(oR.f - R, oZ.f - Z);
}

/* (R, Z) -> (rho, eta): Newton on X(rho, eta) = (R, Z) from rho = sqrt(psi_N)
 * and the eta node nearest to (R, Z) on that surface, with the eta step kept
 * below one node.  The nearest node by a scan of every NSCAN-th node, then
 * of the nodes within two such strides of the best: (R, Z) lies on the
 * surface (to the chart's tabulation error), where the distance grows with
 * the arc from it, so this is the node the scan of all NETA finds (the same
 * start, the same Newton), at ~1/5 of the nodes and without their
 * derivatives.  to_canon runs it, and gcp_gc_push re-enters the canonical
 * state every 256 steps with a callback, gcp_gl_init mapping five points:
 * the scan of all nodes through num_map took 27% (gc-gl2) and 21%
 * (gc-gl4) of the CPU time a step in DIII-D with the energy sampled
 * (bench_flux's orbit; 9.3 -> 6.8 and 13.1 -> 10.3 us). */
#define NSCAN 8
static int num_locate(const void *ctx, double R, double Z, double *s, double *eta)
{
    const struct numview *v = ctx;
    const struct numchart *n = v->t;
    double ps[6];
    if (gcp_field_psi_RZ(v->f, R, Z, ps)) return GCP_LEFT_DOMAIN;
    const double psiN = (ps[0] - n->psia) / n->dpsi;
    if (!(psiN <= PSIN_MAX)) return GCP_LEFT_DOMAIN;
    double rho = sqrt(fmax(psiN, 0.0)), best = INFINITY;
    int jc = 0, jb = 0;
    struct node_scan ns;
    node_scan_rho(n, rho, &ns);
    for (int j = 0; j < NETA; j += NSCAN) {
        const double dd = node_dist(n, &ns, rho, j, R, Z);
        if (dd < best) best = dd, jc = j;
    }
    /* the window in ascending node order (the first of equal distances, as
     * the full scan takes) */
    best = INFINITY;
    for (int a = 0; a <= 4 * NSCAN; a++) {
        const int j = (jc - 2 * NSCAN + a + NETA) % NETA;
        const double dd = node_dist(n, &ns, rho, j, R, Z);
        if (dd < best || (dd == best && j < jb)) best = dd, jb = j;
    }
    /* (no finite distance: eta = 0, as the full scan left it) */
    double e = best < INFINITY ? -GCP_PI + 2.0 * GCP_PI * jb / NETA : 0.0;
    for (int it = 0; it < 60; it++) {
        struct gcp_polchart_pt p;
        num_map(v, rho, e, &p);
        const double fR = p.R - R, fZ = p.Z - Z;
        const double det = p.R_s * p.Z_e - p.R_e * p.Z_s;
        if (!(det != 0.0)) return GCP_STEP_FAILED;
        const double dr = -(p.Z_e * fR - p.R_e * fZ) / det;
        double de = -(-p.Z_s * fR + p.R_s * fZ) / det;
        const double demax = 2.0 * GCP_PI / NETA;
        if (fabs(de) > demax) de = copysign(demax, de);
        rho += dr, e += de;
        if (!(rho > 0.0)) rho = 1e-6 * n->rho_max;
        /* converged when the step moves X by less than 1e-14 R (round-off) */
        if (hypot(dr * p.R_s + de * p.R_e, dr * p.Z_s + de * p.Z_e) < 1e-14 * R) {
            *s = rho, *eta = wrap_eta(e);
            return rho <= n->rho_max ? 0 : GCP_LEFT_DOMAIN;
        }
    }
    return GCP_STEP_FAILED;
}

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
static int table_build(const struct gcp_field *f, double Ra, double Za, double pe,
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

/* ---- one table per equilibrium ----------------------------------------------
 * Building a table takes ~1 s CPU (an inward pass for the labels, then
 * NETA x NRHO rk8pd steps of 13 evaluations of psi and B); a chart is
 * created wherever a method needs one (every advance of a block, the
 * scene's check).  So the tables are cached, one
 * entry, keyed by a fingerprint of the field: its type, the flux-surface
 * data, and psi with its derivatives and B at 8 points about the axis,
 * compared bit for bit.  Two fields with the same fingerprint are the same
 * equilibrium (one file loaded twice, or one field freed and another at its
 * address with the same data): the table depends only on psi and B.  The
 * table never holds the field (each chart's view does).  The entry and the
 * reference counts are guarded by a spin lock (C11 atomic_flag), so charts
 * may be created and destroyed from several threads. */
#define NFP (3 + 8 * 9)

static atomic_flag cache_lock = ATOMIC_FLAG_INIT;
static struct numchart *cache_t;
static const void *cache_type;
static double cache_fp[NFP];

static void lock(void)
{
    while (atomic_flag_test_and_set_explicit(&cache_lock, memory_order_acquire)) {
    }
}

static void unlock(void) { atomic_flag_clear_explicit(&cache_lock, memory_order_release); }

static void fingerprint(const struct gcp_field *f, double Ra, double Za, double pe,
                        double fp[NFP])
{
    fp[0] = Ra, fp[1] = Za, fp[2] = pe;
    const double d = 0.05 * fabs(Ra);
    for (int j = 0; j < 8; j++) {
        const double R = Ra + d * cos(j * GCP_PI / 4), Z = Za + d * sin(j * GCP_PI / 4);
        double *o = fp + 3 + 9 * j;
        gcp_field_psi_RZ(f, R, Z, o);
        const double X[3] = {R, 0.0, Z};
        struct gcp_field_sample s = {.need = GCP_NEED_B};
        gcp_field_eval(f, 0.0, X, &s);
        o[6] = s.B[0], o[7] = s.B[1], o[8] = s.B[2];
    }
}

static void table_release(struct numchart *t)
{
    lock();
    const int last = --t->refs == 0;
    unlock();
    if (last) table_free(t);
}

static void view_free(void *p)
{
    struct numview *v = p;
    if (!v) return;
    table_release(v->t);
    free(v);
}

int gcp_flux_num_build(const struct gcp_field *f, struct gcp_flux_chart *c, char *why,
                       size_t whylen)
{
    double Ra, Za, pe, ps[6];
    if (gcp_field_psi_RZ(f, 0.0, 0.0, ps) == GCP_ERR_STATE) {
        snprintf(why, whylen, "the field has no flux function psi (a grid needs psi and cubic "
                              "interpolation)");
        return GCP_ERR_STATE;
    }
    if (gcp_field_flux_surfaces(f, &Ra, &Za, &pe)) {
        snprintf(why, whylen, "the field does not say where its closed flux surfaces are "
                              "(magnetic axis and boundary flux)");
        return GCP_ERR_STATE;
    }
    struct numview *v = malloc(sizeof *v);
    if (!v) {
        snprintf(why, whylen, "out of memory");
        return GCP_ERR_NOMEM;
    }
    double fp[NFP];
    fingerprint(f, Ra, Za, pe, fp);
    struct numchart *t = NULL;
    lock();
    if (cache_t && cache_type == (const void *)f->type && memcmp(fp, cache_fp, sizeof fp) == 0) {
        t = cache_t;
        t->refs++;
    }
    unlock();
    if (!t) {
        const int rc = table_build(f, Ra, Za, pe, &t, why, whylen);
        if (rc) {
            free(v);
            return rc;
        }
        struct numchart *old = NULL;
        lock();
        old = cache_t;
        cache_t = t;
        t->refs++; /* the cache's reference */
        cache_type = (const void *)f->type;
        memcpy(cache_fp, fp, sizeof fp);
        unlock();
        if (old) table_release(old);
    }
    v->f = f;
    v->t = t;
    c->pc.ctx = v;
    c->pc.map = num_map;
    c->pc.map_field = num_map_field;
    c->pc.locate = num_locate;
    c->pc.s_max = t->rho_max;
    c->pc.what = "tabulated orthogonal (rho, eta), rho = sqrt(psi_N)";
    c->owned = v;
    c->free_ctx = view_free;
    /* the jets where the table is septic and the field has B's second
     * derivatives (a probe on the axis): elsewhere the solver's Jacobian by
     * differences, as before */
    struct gcp_field_sample fs;
    double pr[6], Bd[3][6];
    int fst;
    if (t->spl.kind == GCP_SPL_SEPTIC && gcp_field_psi_B_RZ3(f, t->Ra, t->Za, pr, &fs, &fst, Bd) != -1)
        c->map_field3 = num_map_field3;
    return 0;
}
