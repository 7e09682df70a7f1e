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

#include "canon_flux_num_priv.h"
#include "canon_flux_priv.h"
#include "gcpush/error.h"
#include "gcpush/particles.h"
#include "grid_priv.h"
#include "spl_inline.h"

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

/* The squared distance from (R, Z) to the chart's point (rho, eta node j)
 * (the scan only compares them; with hypot's correctly rounded root a
 * to_canon in DIII-D took 6.6 us CPU, 5.9 without, medians of 3
 * alternating runs; bench_flux's states unchanged): R and Z
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
    const double dR = oR.f - R, dZ = oZ.f - Z;
    return dR * dR + dZ * dZ;
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
        const int rc = gcp_flux_num_table_build(f, Ra, Za, pe, &t, why, whylen);
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
