/* Canonical flux charts: guiding centres in axisymmetric fields with a
 * toroidal field and currents (analytic tokamak, G-EQDSK, R-Z grids with
 * psi), issue 11.  The interface is canon_priv.h; this file is the chart
 * algebra, shared by every orthogonal poloidal chart (fields/flux_priv.h):
 * the closed-form one a model knows (the analytic tokamak's (r, theta)) and
 * the tabulated one canon_flux_num.c builds from psi (EQDSK, grids).
 *
 * The one-form.  In orthogonal poloidal coordinates (s, eta) of the R-Z
 * plane with eta constant along the gradient lines of psi, dX/ds is along
 * grad psi, so b_s = b . dX/ds = 0 (b_pol is tangent to the flux surfaces).
 * In the gauge A_s = 0, A = psi grad phi + A_eta grad eta with
 * dA_eta/ds = J B^phi (the phi component of curl A is the toroidal field;
 * J the Jacobian of (s, eta, phi)), and
 *   theta = (q A + p_par b) . dX
 *         = (q A_eta + p_par h_eta) deta + (q psi + p_par F/|B|) dphi,
 * h_eta = b . dX/deta, F/|B| = R b_phi = b . dX/dphi (Littlejohn 1983's
 * Lagrangian; the construction follows the canonical flux coordinates of
 * White & Chance 1984 and Albert, Kasilov & Kernbichler 2020, with the
 * orthogonal chart in place of Boozer coordinates).  Hence
 *   z = (phi, eta, P_phi = q psi + p_par R b_phi, P_eta = q A_eta + p_par h_eta)
 * are canonical, and H = gamma m c^2,
 *   gamma = sqrt(1 + (p_par/mc)^2 + 2 mu |B| / (m c^2)),  |B| at X(s, eta).
 *
 * Inversion.  Given (eta, P_phi, P_eta), w = (s, p_par) solves
 *   G(w; eta) = (q psi + p k, q A_eta + p h) = (P_phi, P_eta),  k = R b_phi,
 * by Newton from the guess in aux (the last point).  The Jacobian
 *   dG/dw = [[q psi_s + p k_s, k], [q A_s + p h_s, h]]
 * has determinant q J |B|-ish times B*_par/|B|: regular away from the axis
 * (J = 0) and where B*_par > 0.
 * Derivatives of H by implicit differentiation: with lambda solving
 * (dG/dw)^T lambda = dH/dw,
 *   dH/dP = lambda,  dH/deta = H_eta - lambda . dG/deta,  dH/dphi = 0.
 * The collocation solver does not invert the chart at every evaluation: it
 * takes (s, p_par) of each stage as unknowns and evaluates the chart forward
 * (flux_wlift_eval below, gc_gauss_wlift.c); the inversion remains for
 * from_canon and the fallback solver.
 * Everything is the exact derivative of the chart's own H(z) (the field's
 * grad B is the derivative of its B; the chart's X_s, X_se, ... are the
 * derivatives of its X), so a symplectic integrator on z is symplectic to
 * round-off whatever the chart's accuracy.
 *
 * The field is evaluated at phi = 0, X = (R, 0, Z): Rhat = x, phihat = y,
 * Zhat = z there, and axisymmetry gives every other phi.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "canon_flux_priv.h"
#include "gcpush/error.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"

/* The chart's geometry and field at one point (s, eta), independent of
 * p_par: one map of the chart and one field evaluation. */
struct fgeom {
    double R, Z;              /* [m] */
    double R_s, Z_s;          /* [m/s-unit] dX/ds */
    double psi, psi_s, psi_e; /* P_phi = q psi + p_par k, k = R b_phi = F/|B| */
    double k, k_s, k_e;
    double A, A_s, A_e; /* P_eta = q A_eta + p_par h, h = b . X_e */
    double h, h_s, h_e;
    double Bm, dBs, dBe; /* [T] |B|, d|B|/ds, d|B|/deta */
    double h_res;        /* b . dX/ds: zero for an exact chart (the residual is a measure) */
};

/* Everything at one (s, eta, p_par). */
struct fpoint {
    struct fgeom g;
    double P[2];     /* (P_phi, P_eta) */
    double Gw[2][2]; /* d(P_phi, P_eta)/d(s, p_par) */
    double Ge[2];    /* d(P_phi, P_eta)/deta */
    double H;        /* [J] */
    double Hw[2];    /* dH/d(s, p_par) */
    double He;       /* dH/deta */
    double pscale;   /* [kg m/s] |p| + p_perp: the momentum scale for Newton */
};

/* d b along v = (vR, 0, vZ): (G v - b (b . G v)) / |B|; returns d|B| = b . G v. */
static double dir_deriv(const double G[3][3], const double b[3], double Bm, double vR, double vZ,
                        double db[3])
{
    double Gv[3];
    for (int i = 0; i < 3; i++) Gv[i] = G[i][0] * vR + G[i][2] * vZ;
    const double dB = b[0] * Gv[0] + b[1] * Gv[1] + b[2] * Gv[2];
    for (int i = 0; i < 3; i++) db[i] = (Gv[i] - b[i] * dB) / Bm;
    return dB;
}

/* The geometry at (s, eta) into o; with j (a chart with map_field3), the
 * second-order jets of the Jacobian too (j->ok = 0 where there are none). */
struct fjets;
static void fjets_of(const struct gcp_polchart_pt *g, const struct flux_d3 *d3, struct fjets *j);

/* With pos (from_canon's inversion: P, dP/dw and X only), the eta
 * derivatives, d|B|/ds and h_res are not formed (left NaN). */
static inline __attribute__((always_inline)) int
fgeom_eval_(const struct gcp_flux_chart *c, double s, double eta, struct fgeom *o,
            struct fjets *j, int pos)
{
    struct gcp_polchart_pt g;
    struct gcp_field_sample fs = {.need = GCP_NEED_B | GCP_NEED_GRADB};
    int st;
    struct flux_d3 d3; /* read only with j */
    d3.ok = 0;
    if (j && c->map_field3) {
        st = c->map_field3(c->pc.ctx, s, eta, &g, &fs, &d3);
    } else if (c->pc.map_field) {
        st = c->pc.map_field(c->pc.ctx, s, eta, &g, &fs);
    } else {
        st = c->pc.map(c->pc.ctx, s, eta, &g);
        const double X[3] = {g.R, 0.0, g.Z};
        const int fst = gcp_field_eval(c->field, 0.0, X, &fs);
        if (!st) st = fst;
    }
    const double Bm = sqrt(fs.B[0] * fs.B[0] + fs.B[1] * fs.B[1] + fs.B[2] * fs.B[2]);
    if (!(Bm > 0.0)) return GCP_STEP_FAILED;
    const double b[3] = {fs.B[0] / Bm, fs.B[1] / Bm, fs.B[2] / Bm};
    double dbs[3], dbe[3];
    o->dBs = dir_deriv(fs.gradB, b, Bm, g.R_s, g.Z_s, dbs);
    o->Bm = Bm;
    o->R = g.R, o->Z = g.Z, o->R_s = g.R_s, o->Z_s = g.Z_s;
    o->psi = g.psi, o->psi_s = g.psi_s, o->psi_e = g.psi_e;
    o->A = g.A, o->A_s = g.A_s, o->A_e = g.A_e;
    /* k = F/|B| = R b_phi;  h = b . X_e */
    o->k = g.R * b[1];
    o->k_s = g.R_s * b[1] + g.R * dbs[1];
    o->h = b[0] * g.R_e + b[2] * g.Z_e;
    o->h_s = dbs[0] * g.R_e + dbs[2] * g.Z_e + b[0] * g.R_se + b[2] * g.Z_se;
    if (pos) {
        o->dBe = o->k_e = o->h_e = o->h_res = o->psi_e = o->A_e = NAN;
        return st;
    }
    o->dBe = dir_deriv(fs.gradB, b, Bm, g.R_e, g.Z_e, dbe);
    o->k_e = g.R_e * b[1] + g.R * dbe[1];
    o->h_e = dbe[0] * g.R_e + dbe[2] * g.Z_e + b[0] * g.R_ee + b[2] * g.Z_ee;
    o->h_res = b[0] * g.R_s + b[2] * g.Z_s;
    if (j) fjets_of(&g, &d3, j);
    return st;
}

static int fgeom_eval(const struct gcp_flux_chart *c, double s, double eta, struct fgeom *o,
                      struct fjets *j)
{
    return fgeom_eval_(c, s, eta, o, j, 0);
}

/* The momenta P, dP/dw and pscale at the geometry g with p_par = p: what
 * from_canon's inversion reads (fpoint_eval_pos). */
static inline void fpoint_pos_at(const struct gcp_gc_consts *k, double p, struct fpoint *o)
{
    const struct fgeom *g = &o->g;
    const double q = k->q;
    o->P[0] = q * g->psi + p * g->k;
    o->P[1] = q * g->A + p * g->h;
    o->Gw[0][0] = q * g->psi_s + p * g->k_s;
    o->Gw[0][1] = g->k;
    o->Gw[1][0] = q * g->A_s + p * g->h_s;
    o->Gw[1][1] = g->h;
    o->pscale = fabs(p) + sqrt(2.0 * k->m * fabs(k->mu) * g->Bm);
}

/* The momenta, their derivatives and H at the geometry g with p_par = p. */
static void fpoint_at(const struct gcp_gc_consts *k, double p, struct fpoint *o)
{
    const struct fgeom *g = &o->g;
    const double q = k->q;
    fpoint_pos_at(k, p, o);
    o->Ge[0] = q * g->psi_e + p * g->k_e;
    o->Ge[1] = q * g->A_e + p * g->h_e;
    const double gam = gcp_gc_gamma(p, k->mu, g->Bm, k->m);
    const double HB = k->mu / gam; /* dH/d|B| */
    o->H = gam * k->m * GCP_C_LIGHT * GCP_C_LIGHT;
    o->Hw[0] = HB * g->dBs;
    o->Hw[1] = p / (gam * k->m);
    o->He = HB * g->dBe;
}

static int fpoint_eval(const struct gcp_flux_chart *c, const struct gcp_gc_consts *k, double s,
                       double eta, double p, struct fpoint *o)
{
    const int st = fgeom_eval(c, s, eta, &o->g, NULL);
    if (st == GCP_STEP_FAILED) return st;
    fpoint_at(k, p, o);
    return st;
}

/* fpoint_eval for from_canon's inversion (flux_solve with xlin): P, dP/dw,
 * X, X_s and pscale, the same numbers; H, its derivatives and dP/deta,
 * which the inversion does not read, not formed (NaN).  ~2% of a gc-gl2
 * step in DIII-D (bench_flux) went to them: two evaluations a step. */
static int fpoint_eval_pos(const struct gcp_flux_chart *c, const struct gcp_gc_consts *k,
                           double s, double eta, double p, struct fpoint *o)
{
    const int st = fgeom_eval_(c, s, eta, &o->g, NULL, 1);
    if (st == GCP_STEP_FAILED) return st;
    fpoint_pos_at(k, p, o);
    o->Ge[0] = o->Ge[1] = o->H = o->Hw[0] = o->Hw[1] = o->He = NAN;
    return st;
}

/* dH/dz at the point of o by implicit differentiation (see the header):
 * (dG/dw)^T lambda = dH/dw. */
static void fpoint_dH(const struct fpoint *o, double dH[4])
{
    const double det = o->Gw[0][0] * o->Gw[1][1] - o->Gw[0][1] * o->Gw[1][0];
    const double l0 = (o->Gw[1][1] * o->Hw[0] - o->Gw[1][0] * o->Hw[1]) / det;
    const double l1 = (-o->Gw[0][1] * o->Hw[0] + o->Gw[0][0] * o->Hw[1]) / det;
    dH[0] = 0.0;
    dH[1] = o->He - l0 * o->Ge[0] - l1 * o->Ge[1];
    dH[2] = l0;
    dH[3] = l1;
}

/* Newton for w = (s, p) with G(w; eta) = P.  aux is the guess in, the
 * solution out.  Quadratic convergence: once the relative step e is below
 * 1e-10 the next is at round-off; the iteration stops at the first step
 * below 1e-15 (nothing left to take) or, below 1e-10, at the first that no
 * longer halves (the round-off floor of p_par, which P_phi - q psi
 * determines with a cancellation of ~|q psi| / (p R): ~1e-12 in DIII-D),
 * without taking it, and returns the evaluation in hand (that point's): no
 * fixed tolerance that the floor could exceed, and no evaluation of a point
 * that differs from the last by round-off (H's derivatives there are off by
 * that round-off).  With xlin (from_canon: only the position and p_par are
 * wanted, and P_phi(X, p_par) must be P_phi(z) to round-off), a step below
 * FLUX_XLIN = 1e-9, the last ones included, is taken and the point
 * moved along the chart's dX/ds instead of evaluated again: the step leaves
 * an error ~e^2 < 1e-18 (Newton's constant measured 0.1 .. 1 on bench_flux's
 * orbits: the iterate after a step e0 is ~e0^2 off), and the linear move one
 * of ~e^2 too.  Not at 1e-8:
 * the ~1e-16 those leave is systematic (the curvature of the line), and
 * gcp_gc_push re-enters the canonical state from (X, p_par) every 256 steps,
 * so P_phi drifted linearly (2.1e-12 over 1e7 steps of gc-gl4 in the
 * tokamak, 10x its 1e6 figure), as it did when the last step below 1e-15
 * was not taken; at 1e-9 that drift scales to ~2e-14.  Why not 1e-11 (as
 * before): gc-gl2's end point guess (gc_gauss_wlift.c) is ~1e-4 .. 1e-6
 * off, the second iterate ~1e-9 .. 1e-11, so 80% of the steps in the
 * tokamak (bench_flux) took a third chart evaluation for a step that the
 * linear move takes at ~1e-18. s is kept above 0 (the axis, where J = 0). */
#define FLUX_XLIN 1e-9
/* A Newton step e above FLUX_XLIN after one of e1 (the evaluation before,
 * at (s1, p1) on the same eta): the step taken to second order (Newton-
 * Chebyshev), G's second derivatives along the line from the two
 * evaluations, G_ss = (G_s(2) - G_s(1) - G_sp dp1) / ds1 (G_sp = (k_s, h_s),
 * G_pp = 0), and X moved with X_ss likewise.  Those are off by O(e1)
 * (relative), the step's second-order term by O(e^2 e1), the third-order
 * one is O(e^3): taken where e^2 e1 <= FLUX_X2 = 1e-18 (the linear move's
 * e^2 < 1e-18 above; e.g. e1 = 1e-4, e = 1e-7) and the first step moved s
 * by at least e1 / 10 (G_ss's difference quotient).  Why: gc-gl2's end
 * point guess is ~1e-4 off in DIII-D (bench_flux), the second iterate 1e-7
 * .. 1e-10, so half the steps took a third chart evaluation for it. */
#define FLUX_X2 1e-18
static int flux_step2(struct fpoint *o, const double z[4], const struct fpoint *q, double s,
                      double p, double s1, double p1, double ds, double dp, double aux[2])
{
    const double d1s = s - s1, d1p = p - p1, ids = 1.0 / d1s;
    const double Gss0 = (o->Gw[0][0] - q->Gw[0][0] - q->g.k_s * d1p) * ids;
    const double Gss1 = (o->Gw[1][0] - q->Gw[1][0] - q->g.h_s * d1p) * ids;
    /* r + G''[d, d] / 2 with d the Newton step, G''[d, d] = G_ss ds^2 + 2 G_sp ds dp */
    const double r0 = o->P[0] - z[2] + 0.5 * Gss0 * ds * ds + o->g.k_s * ds * dp;
    const double r1 = o->P[1] - z[3] + 0.5 * Gss1 * ds * ds + o->g.h_s * ds * dp;
    const double det = o->Gw[0][0] * o->Gw[1][1] - o->Gw[0][1] * o->Gw[1][0];
    const double ds2 = -(o->Gw[1][1] * r0 - o->Gw[0][1] * r1) / det;
    const double dp2 = -(-o->Gw[1][0] * r0 + o->Gw[0][0] * r1) / det;
    const double Rss = (o->g.R_s - q->g.R_s) * ids, Zss = (o->g.Z_s - q->g.Z_s) * ids;
    aux[0] = s + ds2, aux[1] = p + dp2;
    o->g.R += (o->g.R_s + 0.5 * Rss * ds2) * ds2;
    o->g.Z += (o->g.Z_s + 0.5 * Zss * ds2) * ds2;
    return aux[0] > 0.0 && isfinite(aux[0] + aux[1] + o->g.R + o->g.Z) ? 0 : GCP_STEP_FAILED;
}

static int flux_solve(const struct gcp_flux_chart *c, const struct gcp_gc_consts *k,
                      const double z[4], double aux[2], struct fpoint *o, int xlin)
{
    double s = aux[0], p = aux[1];
    if (!(isfinite(s) && isfinite(p) && isfinite(z[1] + z[2] + z[3]))) return GCP_STEP_FAILED;
    const double sscale = c->pc.s_max;
    double eprev = INFINITY, s1 = s, p1 = p;
    struct fpoint prev = {0};
    for (int it = 0; it < 60; it++) {
        const int st = xlin ? fpoint_eval_pos(c, k, s, z[1], p, o) : fpoint_eval(c, k, s, z[1], p, o);
        const double r0 = o->P[0] - z[2], r1 = o->P[1] - z[3];
        const double det = o->Gw[0][0] * o->Gw[1][1] - o->Gw[0][1] * o->Gw[1][0];
        if (!(det != 0.0) || !isfinite(det)) return GCP_STEP_FAILED;
        const double ds = -(o->Gw[1][1] * r0 - o->Gw[0][1] * r1) / det;
        const double dp = -(-o->Gw[1][0] * r0 + o->Gw[0][0] * r1) / det;
        const double e = fmax(fabs(ds) / sscale, fabs(dp) / o->pscale);
        if (xlin && e < FLUX_XLIN && !st) {
            aux[0] = s + ds, aux[1] = p + dp;
            o->g.R += o->g.R_s * ds, o->g.Z += o->g.Z_s * ds;
            return aux[0] > 0.0 ? 0 : GCP_STEP_FAILED;
        }
        if (xlin && it > 0 && !st && e * e * eprev <= FLUX_X2 &&
            fabs(s - s1) >= 0.1 * eprev * sscale)
            return flux_step2(o, z, &prev, s, p, s1, p1, ds, dp, aux);
        if (e < 1e-15 || (eprev < 1e-10 && e > 0.5 * eprev)) {
            aux[0] = s, aux[1] = p;
            return st;
        }
        prev = *o, s1 = s, p1 = p;
        double sn = s + ds;
        if (!(sn > 0.0)) sn = 0.5 * s; /* never through the axis */
        if (sn > 2.0 * sscale) sn = 0.5 * (s + 2.0 * sscale);
        s = sn;
        p += dp;
        eprev = e;
    }
    return GCP_STEP_FAILED;
}

static int flux_to_canon(const struct gcp_canon_chart *cc, const struct gcp_gc_consts *k,
                         const double X[3], double ppar, double z[4], double aux[2])
{
    const struct gcp_flux_chart *c = cc->data;
    const double R = hypot(X[0], X[1]);
    double s, eta;
    int st = c->pc.locate(c->pc.ctx, R, X[2], &s, &eta);
    if (st) return st;
    struct fpoint o;
    st = fpoint_eval(c, k, s, eta, ppar, &o);
    z[0] = atan2(X[1], X[0]);
    z[1] = eta;
    z[2] = o.P[0];
    z[3] = o.P[1];
    aux[0] = s;
    aux[1] = ppar;
    return st;
}

static int flux_from_canon(const struct gcp_canon_chart *cc, const struct gcp_gc_consts *k,
                           const double z[4], double aux[2], double X[3], double *ppar)
{
    const struct gcp_flux_chart *c = cc->data;
    struct fpoint o;
    const int st = flux_solve(c, k, z, aux, &o, 1);
    X[0] = o.g.R * cos(z[0]);
    X[1] = o.g.R * sin(z[0]);
    X[2] = o.g.Z;
    *ppar = aux[1];
    return st;
}

static int flux_hamiltonian(const struct gcp_canon_chart *cc, const struct gcp_gc_consts *k,
                            const double z[4], double aux[2], double *H, double dH[4])
{
    const struct gcp_flux_chart *c = cc->data;
    struct fpoint o;
    const int st = flux_solve(c, k, z, aux, &o, 0);
    if (st) return st;
    *H = o.H;
    fpoint_dH(&o, dH);
    return 0;
}

/* |B| at z and d|B|/dz (canon_priv.h, for the Sundman time transformation),
 * by the same implicit differentiation as H with (d|B|/ds, d|B|/dp_par = 0). */
static int flux_field_strength(const struct gcp_canon_chart *cc, const struct gcp_gc_consts *k,
                               const double z[4], double aux[2], double *Bm, double dBm[4])
{
    const struct gcp_flux_chart *c = cc->data;
    struct fpoint o;
    const int st = flux_solve(c, k, z, aux, &o, 0);
    if (st) return st;
    const double det = o.Gw[0][0] * o.Gw[1][1] - o.Gw[0][1] * o.Gw[1][0];
    const double l0 = o.Gw[1][1] * o.g.dBs / det, l1 = -o.Gw[0][1] * o.g.dBs / det;
    *Bm = o.g.Bm;
    dBm[0] = 0.0;
    dBm[1] = o.g.dBe - l0 * o.Ge[0] - l1 * o.Ge[1];
    dBm[2] = l0;
    dBm[3] = l1;
    return 0;
}

int gcp_flux_chart_hs(const struct gcp_canon_chart *cc, const struct gcp_gc_consts *k,
                      double s, double eta, double ppar, double *h_s)
{
    struct fpoint o;
    const int st = fpoint_eval(cc->data, k, s, eta, ppar, &o);
    *h_s = o.g.h_res;
    return st;
}

/* The forward evaluation at (eta, w = (s, p_par)) for the solver of
 * gc_gauss_wlift.c (canon_priv.h wlift_eval): P = G(w; eta), dG/dw,
 * dG/deta, H and dH/dz as in flux_hamiltonian, from one map and one field
 * evaluation, or none when `same` holds the geometry at (eta, s). */
_Static_assert(sizeof(struct fgeom) <= sizeof(((struct gcp_canon_wpoint *)0)->own),
               "gcp_canon_wpoint.own holds a struct fgeom");

static int flux_wlift_eval(const struct gcp_canon_chart *cc, const struct gcp_gc_consts *k,
                           double eta, const double w[2], const struct gcp_canon_wpoint *same,
                           struct gcp_canon_wpoint *out)
{
    const struct gcp_flux_chart *c = cc->data;
    if (!(w[0] > 0.0) || !isfinite(w[1]) || !isfinite(eta)) return GCP_STEP_FAILED;
    struct fpoint o;
    if (same) {
        memcpy(&o.g, same->own, sizeof o.g);
    } else {
        const int st = fgeom_eval(c, w[0], eta, &o.g, NULL);
        if (st) return st;
        memcpy(out->own, &o.g, sizeof o.g);
    }
    fpoint_at(k, w[1], &o);
    if (same) memcpy(out->own, same->own, sizeof o.g);
    memcpy(out->P, o.P, sizeof o.P);
    memcpy(out->Pw, o.Gw, sizeof o.Gw);
    memcpy(out->Pe, o.Ge, sizeof o.Ge);
    out->H = o.H;
    fpoint_dH(&o, out->dH);
    out->wscale[0] = c->pc.s_max;
    out->wscale[1] = o.pscale;
    return isfinite(out->H + out->dH[1] + out->dH[2] + out->dH[3]) ? 0 : GCP_NONFINITE;
}

/* ---- the analytic Jacobian of the collocation solve ----------------------
 * gc_gauss_wlift.c's Newton needs dF/dw (fixed eta) and dF/deta (fixed w) of
 * F = (dH/dP_eta, -dH/deta) = (l1, -(H_eta - l . G_eta)), l = Gw^-T H_w
 * (fpoint_dH): second derivatives of H, so the second derivatives in
 * (s, eta) of psi, k, A_eta, h and |B| at X(s, eta).  They are carried as
 * second-order jets (value and derivatives to order 2 in (s, eta), "j2"),
 * composed from the chart's X to third order (h = b . X_eta), A_eta to
 * second, psi and B in (R, Z) to second (struct flux_d3); then F's formula
 * is run on first-order jets in (s, eta, p_par) ("j1").  The derivatives
 * are exact (of the chart's own H), so the Newton is a full one; before,
 * forward differences (two more maps of the chart and field evaluations
 * a stage).  F itself is fgeom's, unchanged. */
struct j2 {
    double v, s, e, ss, se, ee;
};
/* The j2 helpers always inline: GCC 12 kept j2_field a call, and the
 * jets' evaluation (flux_wlift_eval_df) took ~5% more CPU (0.44 -> 0.42 us,
 * 5 alternating pairs); the same expressions, the same numbers. */
#define J2_INLINE static inline __attribute__((always_inline))
struct j1 {
    double v, s, e, p;
};

J2_INLINE struct j2 j2_add(struct j2 a, struct j2 b)
{
    return (struct j2){a.v + b.v, a.s + b.s, a.e + b.e, a.ss + b.ss, a.se + b.se, a.ee + b.ee};
}

J2_INLINE struct j2 j2_mul(struct j2 a, struct j2 b)
{
    return (struct j2){a.v * b.v,
                       a.s * b.v + a.v * b.s,
                       a.e * b.v + a.v * b.e,
                       a.ss * b.v + 2.0 * a.s * b.s + a.v * b.ss,
                       a.se * b.v + a.s * b.e + a.e * b.s + a.v * b.se,
                       a.ee * b.v + 2.0 * a.e * b.e + a.v * b.ee};
}

/* phi(a) from phi's value and first two derivatives at a.v */
J2_INLINE struct j2 j2_fn(struct j2 a, double f0, double f1, double f2)
{
    return (struct j2){f0,
                       f1 * a.s,
                       f1 * a.e,
                       f2 * a.s * a.s + f1 * a.ss,
                       f2 * a.s * a.e + f1 * a.se,
                       f2 * a.e * a.e + f1 * a.ee};
}

/* g(R, Z) along the chart, g = (g, g_R, g_Z, g_RR, g_RZ, g_ZZ) at X */
J2_INLINE struct j2 j2_field(const double g[6], const struct j2 *R, const struct j2 *Z)
{
    return (struct j2){
        g[0],
        g[1] * R->s + g[2] * Z->s,
        g[1] * R->e + g[2] * Z->e,
        g[3] * R->s * R->s + 2.0 * g[4] * R->s * Z->s + g[5] * Z->s * Z->s + g[1] * R->ss +
            g[2] * Z->ss,
        g[3] * R->s * R->e + g[4] * (R->s * Z->e + R->e * Z->s) + g[5] * Z->s * Z->e +
            g[1] * R->se + g[2] * Z->se,
        g[3] * R->e * R->e + 2.0 * g[4] * R->e * Z->e + g[5] * Z->e * Z->e + g[1] * R->ee +
            g[2] * Z->ee};
}

struct fjets {
    int ok;
    struct j2 psi, k, A, h, Bm;
};

static void fjets_of(const struct gcp_polchart_pt *g, const struct flux_d3 *d3, struct fjets *j)
{
    j->ok = d3->ok;
    if (!d3->ok) return;
    const struct j2 R = {g->R, g->R_s, g->R_e, g->R_ss, g->R_se, g->R_ee};
    const struct j2 Z = {g->Z, g->Z_s, g->Z_e, g->Z_ss, g->Z_se, g->Z_ee};
    const struct j2 Re = {g->R_e, g->R_se, g->R_ee, d3->R3[1], d3->R3[2], d3->R3[3]};
    const struct j2 Ze = {g->Z_e, g->Z_se, g->Z_ee, d3->Z3[1], d3->Z3[2], d3->Z3[3]};
    j->psi = j2_field(d3->ps, &R, &Z);
    j->A = (struct j2){g->A, g->A_s, g->A_e, d3->A2[0], d3->A2[1], d3->A2[2]};
    struct j2 B[3], B2 = {0, 0, 0, 0, 0, 0};
    for (int i = 0; i < 3; i++) {
        B[i] = j2_field(d3->Bd[i], &R, &Z);
        B2 = j2_add(B2, j2_mul(B[i], B[i]));
    }
    const double Bm = sqrt(B2.v);
    j->Bm = j2_fn(B2, Bm, 0.5 / Bm, -0.25 / (Bm * B2.v));
    const struct j2 iB = j2_fn(j->Bm, 1.0 / Bm, -1.0 / (Bm * Bm), 2.0 / (Bm * Bm * Bm));
    j->k = j2_mul(R, j2_mul(B[1], iB));
    j->h = j2_mul(j2_add(j2_mul(B[0], Re), j2_mul(B[2], Ze)), iB);
}

static struct j1 j1_add(struct j1 a, struct j1 b)
{
    return (struct j1){a.v + b.v, a.s + b.s, a.e + b.e, a.p + b.p};
}

static struct j1 j1_sub(struct j1 a, struct j1 b)
{
    return (struct j1){a.v - b.v, a.s - b.s, a.e - b.e, a.p - b.p};
}

static struct j1 j1_mul(struct j1 a, struct j1 b)
{
    return (struct j1){a.v * b.v, a.s * b.v + a.v * b.s, a.e * b.v + a.v * b.e,
                       a.p * b.v + a.v * b.p};
}

static struct j1 j1_div(struct j1 a, struct j1 b)
{
    const double q = a.v / b.v, ib = 1.0 / b.v;
    return (struct j1){q, (a.s - q * b.s) * ib, (a.e - q * b.e) * ib, (a.p - q * b.p) * ib};
}

static struct j1 j1_scale(double c, struct j1 a) { return (struct j1){c * a.v, c * a.s, c * a.e, c * a.p}; }

/* a jet's value, its s- and eta-derivative, as first-order jets in (s, eta, p) */
static struct j1 j1_v(struct j2 a) { return (struct j1){a.v, a.s, a.e, 0.0}; }
static struct j1 j1_s(struct j2 a) { return (struct j1){a.s, a.ss, a.se, 0.0}; }
static struct j1 j1_e(struct j2 a) { return (struct j1){a.e, a.se, a.ee, 0.0}; }

/* Fw, Fe at p_par = p from the jets (fpoint_at and fpoint_dH on j1). */
static void fjets_dF(const struct fjets *j, const struct gcp_gc_consts *k, double p,
                     double Fw[2][2], double Fe[2])
{
    const struct j1 P = {p, 0.0, 0.0, 1.0};
    const double q = k->q, mc = k->m * GCP_C_LIGHT;
    const struct j1 Gw00 = j1_add(j1_scale(q, j1_s(j->psi)), j1_mul(P, j1_s(j->k)));
    const struct j1 Gw01 = j1_v(j->k);
    const struct j1 Gw10 = j1_add(j1_scale(q, j1_s(j->A)), j1_mul(P, j1_s(j->h)));
    const struct j1 Gw11 = j1_v(j->h);
    const struct j1 Ge0 = j1_add(j1_scale(q, j1_e(j->psi)), j1_mul(P, j1_e(j->k)));
    const struct j1 Ge1 = j1_add(j1_scale(q, j1_e(j->A)), j1_mul(P, j1_e(j->h)));
    /* gamma^2 = 1 + (p/mc)^2 + 2 mu |B| / (m c^2) */
    const struct j1 g2 =
        j1_add(j1_scale(1.0 / (mc * mc), j1_mul(P, P)),
               j1_scale(2.0 * k->mu / (mc * GCP_C_LIGHT), j1_v(j->Bm)));
    const double gam = sqrt(1.0 + g2.v);
    const struct j1 iG = {1.0 / gam, -0.5 * g2.s / (gam * gam * gam),
                          -0.5 * g2.e / (gam * gam * gam), -0.5 * g2.p / (gam * gam * gam)};
    const struct j1 HB = j1_scale(k->mu, iG);
    const struct j1 Hw0 = j1_mul(HB, j1_s(j->Bm));
    const struct j1 Hw1 = j1_scale(1.0 / k->m, j1_mul(P, iG));
    const struct j1 He = j1_mul(HB, j1_e(j->Bm));
    const struct j1 det = j1_sub(j1_mul(Gw00, Gw11), j1_mul(Gw01, Gw10));
    const struct j1 l0 = j1_div(j1_sub(j1_mul(Gw11, Hw0), j1_mul(Gw10, Hw1)), det);
    const struct j1 l1 = j1_div(j1_sub(j1_mul(Gw00, Hw1), j1_mul(Gw01, Hw0)), det);
    const struct j1 F1 = j1_sub(j1_add(j1_mul(l0, Ge0), j1_mul(l1, Ge1)), He);
    Fw[0][0] = l1.s, Fw[0][1] = l1.p, Fe[0] = l1.e;
    Fw[1][0] = F1.s, Fw[1][1] = F1.p, Fe[1] = F1.e;
}

static int flux_wlift_eval_df(const struct gcp_canon_chart *cc, const struct gcp_gc_consts *k,
                              double eta, const double w[2], struct gcp_canon_wpoint *out,
                              double Fw[2][2], double Fe[2], int *have)
{
    const struct gcp_flux_chart *c = cc->data;
    *have = 0;
    if (!(w[0] > 0.0) || !isfinite(w[1]) || !isfinite(eta)) return GCP_STEP_FAILED;
    struct fgeom g;
    struct fjets j;
    const int st = fgeom_eval(c, w[0], eta, &g, &j);
    if (st) return st;
    struct gcp_canon_wpoint same;
    memcpy(same.own, &g, sizeof g);
    const int r = flux_wlift_eval(cc, k, eta, w, &same, out);
    if (r || !j.ok) return r;
    fjets_dF(&j, k, w[1], Fw, Fe);
    *have = isfinite(Fw[0][0] + Fw[0][1] + Fw[1][0] + Fw[1][1] + Fe[0] + Fe[1]);
    return 0;
}

static void flux_destroy(void *data)
{
    struct gcp_flux_chart *c = data;
    if (!c) return;
    if (c->free_ctx) c->free_ctx(c->owned);
    free(c);
}

int gcp_canon_chart_flux_create(const struct gcp_field *f, struct gcp_canon_chart *out, char *why,
                                size_t whylen)
{
    memset(out, 0, sizeof *out);
    if (!f->axisymmetric) {
        snprintf(why, whylen, "the field is not axisymmetric");
        return GCP_ERR_STATE;
    }
    if (f->has_E || f->time_dependent) {
        snprintf(why, whylen, "the flux chart takes static fields without an electric field");
        return GCP_ERR_STATE;
    }
    struct gcp_flux_chart *c = calloc(1, sizeof *c);
    if (!c) {
        snprintf(why, whylen, "out of memory");
        return GCP_ERR_NOMEM;
    }
    c->field = f;
    if (gcp_field_polchart(f, &c->pc) != 0) {
        const int rc = gcp_flux_num_build(f, c, why, whylen);
        if (rc) {
            free(c);
            return rc;
        }
    }
    out->name = "flux-orthogonal";
    out->field = f;
    out->data = c;
    out->to_canon = flux_to_canon;
    out->from_canon = flux_from_canon;
    out->hamiltonian = flux_hamiltonian;
    out->destroy = flux_destroy;
    out->field_strength = flux_field_strength;
    out->wlift_eval = flux_wlift_eval;
    if (c->map_field3) out->wlift_eval_df = flux_wlift_eval_df;
    return 0;
}
