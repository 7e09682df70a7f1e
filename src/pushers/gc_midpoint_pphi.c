/* gc-midpoint-pphi (formerly gc-vi): a symmetric midpoint scheme for the
 * guiding-centre phase-space Lagrangian with an exactly conserved p_phi in
 * axisymmetric fields.  It is NOT symplectic and not a variational
 * integrator (issue 11 measured its one-step symplecticity residual against
 * d theta: ~h^3, like any second-order non-symplectic method; the residual
 * equations below impose theta(z1) - theta(z0) = D1 L_d + D2 L_d, which are
 * not the discrete Euler-Lagrange equations of a discrete action).  Its
 * p_phi is exact by construction whatever the accuracy, so a p_phi or L*
 * test run with it cannot fail.  The symplectic methods are gc-gl2 and
 * gc-gl4 (gc_gauss.c).  Kept as a cheap second-order method with exact
 * p_phi in fields where those have no chart (the analytic tokamak until the
 * flux chart exists).
 *
 * Continuous problem.  The guiding-centre phase-space Lagrangian (Littlejohn
 * 1983; Cary & Brizard 2009, Rev. Mod. Phys. 81 693)
 *   L(z, zdot) = theta(z).zdot - H(z),   z = (c, p_par),  c = coordinates of X,
 *   theta = (q A + p_par b) . dX/dc           (a one-form, theta_ppar = 0),
 *   H = gamma m c^2 + q phi,  gamma = sqrt(1 + (p_par/mc)^2 + 2 mu |B|/(m c^2))
 * (relativistic: dH/dp_par = p_par/(gamma m), dH/dX = (mu/gamma) grad|B| - q E)
 * is linear in the velocities, i.e. degenerate: its Euler-Lagrange equations
 *   d/dt theta_i(z) = d_i theta_j(z) zdot^j - d_i H(z)          (EL)
 * are first order, and in the guiding-centre equations of kernels.h.
 *
 * Coordinates.  Where the field is axisymmetric (GCP_CAP_AXISYM: dipole,
 * mirror, tokamak), c = (R, phi, Z) cylindrical; theta and H are then
 * independent of phi (the field, A and their derivatives are evaluated in
 * the phi = 0 half-plane at (R, 0, Z), where Rhat, phihat, Zhat = x, y, z,
 * so the independence holds bit for bit).  Otherwise c = (x, y, z).
 * With V = q A + p_par b and D_ij = dV_i/dx_j at (R, 0, Z):
 *   theta = (V_x, R V_y, V_z),  d theta_i/dR = (D_00, V_y + R D_10, D_20),
 *   d theta_i/dZ = (D_02, R D_12, D_22),  d theta/dphi = 0,
 *   d theta/dp_par = (b_x, R b_y, b_z).
 *
 * Discretisation.  The midpoint discrete Lagrangian
 *   L_d(z0, z1) = theta(zm).(z1 - z0) - h H(zm),   zm = (z0 + z1)/2,
 * gives the two-step discrete Euler-Lagrange equations (Qin & Guan 2008,
 * PRL 100 035006; Li et al. 2011, Phys. Plasmas 18 052902)
 *   D2 L_d(z_{k-1}, z_k) + D1 L_d(z_k, z_{k+1}) = 0,
 * a map on (z_{k-1}, z_k), twice the dimension of the physical phase space
 * for a degenerate L: its extra (parasitic) roots are the known fault,
 * weakly unstable and excited near mirror points.  The cure used here
 * (an equivalent of the projected VI of Kraus 2017, in the spirit of the
 * degenerate VI of Ellison, Finn & Burby 2018): close the discrete
 * Legendre transforms p_k^- = D2 L_d(z_{k-1}, z_k), p_k^+ = -D1 L_d(z_k,
 * z_{k+1}) with the continuous primary constraint p = theta(z) at every
 * node, imposed on their average over the step:
 *   theta(z1) - theta(z0) = D1 L_d(z0, z1) + D2 L_d(z0, z1)
 *                         = Dtheta(zm)^T (z1 - z0) - h grad H(zm),
 * i.e. componentwise, with Delta = z1 - z0,
 *   F_i = theta_i(z1) - theta_i(z0) - Delta^j d_i theta_j(zm) + h d_i H(zm) = 0
 * (i over the three coordinates and p_par; theta_ppar = 0, so the p_par row
 * reads b(zm).Delta X = h v_par(zm)).  This is a one-step map z0 -> z1 on
 * the physical 4-dimensional phase space: there is no second solution
 * branch, so no parasitic mode, by construction.  It is symmetric (swap
 * z0 <-> z1, h -> -h), hence second order and time reversible, and a
 * consistent discretisation of (EL) (Taylor expansion about zm).
 *
 * Discrete Noether theorem.  If theta and H do not depend on a coordinate
 * c_a (phi in an axisymmetric field), then d_a theta = d_a H = 0 and the
 * a-th equation is exactly
 *   theta_a(z1) = theta_a(z0):
 * p_phi = theta_phi = q R A_phi + p_par R b_phi = q psi + p_par R b_phi is
 * conserved to the Newton solver's round-off (tested at 1e-12 relative over
 * 1e5 steps).  In a dipole b_phi = 0: psi, i.e. the drift shell L, is kept.
 * The scheme is not symplectic in general; the energy is not exact but
 * bounded (symmetric method, integrable system: tested, no secular drift).
 *
 * Solver.  Newton-chord on F(z1) = 0: predictor z0 + Delta_prev (h/h_prev)
 * (linear extrapolation, O(h^2)) or, at the first step, an explicit
 * midpoint RK2 step of the GC equations; Jacobian by forward differences
 * (4 residuals, steps 1.5e-8 of the scales |X|, 1 rad, |X|, p = |p|),
 * LU-factorised, kept for the next steps while the iteration contracts by
 * 50x per iteration (otherwise refreshed, at most once per step; measured
 * in the dipole at ~1000 steps per bounce: ~10 field evaluations per step).  Accepted when the
 * scaled Newton update is <= 1e-15 or stalls at round-off (<= 1e-13 and no
 * longer halving); that last update is applied and theta is re-evaluated at
 * the final point (so theta(z0) of the next step is that of the stored
 * state, and F_phi is ~1e-18 relative).  Predictor after two steps:
 * quadratic extrapolation z0 + 2 Delta_1 - Delta_2 (O(h^3)).  At most 20
 * iterations.
 *
 * Newton stalls (near mirror points with large steps, or any step whose
 * predictor is poor): the lane gets GCP_STEP_FAILED with the state and
 * time of the start of the failed step.  (Until issue 11 the step was
 * retried as halved sub-steps, silently: a fixed-step method that became
 * adaptive, with 114 of 428 steps retried at 10 steps per bounce and a
 * 22% energy error on a particle still ALIVE.)  A Jacobian refresh and a
 * restart from the first-step predictor are tried once before failing.
 *
 * Adiabaticity (opts->adiabaticity_max > 0) and B*_par > 0 are checked at
 * the accepted step's midpoint zm: a failing lane gets GCP_NONADIABATIC
 * and keeps the state at the start of that step.
 *
 * Needs the vector potential with its derivatives (gcp_gc_potential):
 * dipole, mirror, tokamak, uniform.  The scene refuses the method in other
 * fields before the run (gcp_pusher_type.applies); a library caller gets
 * every lane GCP_STEP_FAILED.  Static fields
 * (time enters only through E and phi at zm).
 */
#include <float.h>
#include <stdio.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/gc.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "block_priv.h"
#include "gc_priv.h"

#define VI_MAXIT 20
#define VI_TOL 1e-15
#define VI_FLOOR 1e-13
#define VI_FD 1.5e-8

struct vi_ctx {
    const struct gcp_field *f;
    int cyl;
    double q, m, mu;
    double amax;
};

struct vi_pt {
    double theta[3];
    double T[3][3];  /* T[i][k] = d theta_i / d c_k */
    double beta[3];  /* d theta_i / d p_par */
    double dHc[3];   /* dH / d c_k */
    double dHp;      /* dH / d p_par */
    int st;          /* field status */
    int ok;          /* B*_par > 0 and adiabatic */
};

struct vi_lane {
    double c[3], p;
    double theta[3];  /* theta(c, p) */
    double dprev[4], hprev, dprev2[4], hprev2;
    int have_prev, have_J;
    double J[16];
    int piv[4];
    double Ls, Ps;
};

static void cart_point(const struct vi_ctx *C, const double c[3], double P[3])
{
    P[0] = c[0];
    P[1] = C->cyl ? 0.0 : c[1];
    P[2] = c[2];
}

/* theta at (c, p); with deriv, also T, beta, grad H and the validity. */
static void vi_point(const struct vi_ctx *C, double t, const double c[3], double p, int deriv,
                     struct vi_pt *o)
{
    double P[3];
    cart_point(C, c, P);
    struct gcp_field_sample s = {.need = deriv ? gc_need(C->f) : GCP_NEED_B};
    o->st = gcp_field_eval(C->f, t, P, &s);
    double A[3], dA[3][3];
    gcp_gc_potential(C->f, t, P, A, deriv ? dA : NULL, NULL);
    const double Bm = sqrt(s.B[0] * s.B[0] + s.B[1] * s.B[1] + s.B[2] * s.B[2]);
    const double b[3] = {s.B[0] / Bm, s.B[1] / Bm, s.B[2] / Bm};
    const double q = C->q;
    double V[3];
    for (int i = 0; i < 3; i++) V[i] = q * A[i] + p * b[i];
    const double R = C->cyl ? c[0] : 1.0;
    o->theta[0] = V[0];
    o->theta[1] = C->cyl ? R * V[1] : V[1];
    o->theta[2] = V[2];
    if (!deriv) return;
    double gB[3], D[3][3];
    for (int j = 0; j < 3; j++) gB[j] = b[0] * s.gradB[0][j] + b[1] * s.gradB[1][j] + b[2] * s.gradB[2][j];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) D[i][j] = q * dA[i][j] + p * (s.gradB[i][j] - b[i] * gB[j]) / Bm;
    const double gamma = gcp_gc_gamma(p, C->mu, Bm, C->m);
    const double mg = C->mu / gamma;
    const double *E = s.E;
    const int hasE = C->f->has_E;
    if (C->cyl) {
        o->T[0][0] = D[0][0], o->T[0][1] = 0.0, o->T[0][2] = D[0][2];
        o->T[1][0] = V[1] + R * D[1][0], o->T[1][1] = 0.0, o->T[1][2] = R * D[1][2];
        o->T[2][0] = D[2][0], o->T[2][1] = 0.0, o->T[2][2] = D[2][2];
        o->beta[0] = b[0], o->beta[1] = R * b[1], o->beta[2] = b[2];
        o->dHc[0] = mg * gB[0] - (hasE ? q * E[0] : 0.0);
        o->dHc[1] = 0.0;
        o->dHc[2] = mg * gB[2] - (hasE ? q * E[2] : 0.0);
    } else {
        for (int i = 0; i < 3; i++) {
            for (int k = 0; k < 3; k++) o->T[i][k] = D[i][k];
            o->beta[i] = b[i];
            o->dHc[i] = mg * gB[i] - (hasE ? q * E[i] : 0.0);
        }
    }
    o->dHp = p / (gamma * C->m);
    double dX[3], dp;
    const double Bs = gcp_gc_rhs(s.B, s.gradB, hasE ? E : NULL, p, C->mu, q, C->m, dX, &dp);
    o->ok = Bs > 0.0 && Bm > 0.0 &&
            (C->amax <= 0.0 || gcp_gc_adiabaticity_sample(&s, p, C->mu, q, C->m) <= C->amax);
}

/* F(u), u = (c1, p1), for the step (c0, p0, theta0) -> u of size h from t. */
static int vi_residual(const struct vi_ctx *C, double t, double h, const struct vi_lane *L,
                       const double u[4], double F[4], double th1[3], struct vi_pt *mid)
{
    struct vi_pt p1;
    vi_point(C, t + h, u, u[3], 0, &p1);
    const double cm[3] = {0.5 * (L->c[0] + u[0]), 0.5 * (L->c[1] + u[1]), 0.5 * (L->c[2] + u[2])};
    const double pm = 0.5 * (L->p + u[3]);
    vi_point(C, t + 0.5 * h, cm, pm, 1, mid);
    const double d[3] = {u[0] - L->c[0], u[1] - L->c[1], u[2] - L->c[2]};
    for (int i = 0; i < 3; i++) {
        const double td = d[0] * mid->T[0][i] + d[1] * mid->T[1][i] + d[2] * mid->T[2][i];
        F[i] = (p1.theta[i] - L->theta[i]) - td + h * mid->dHc[i];
        th1[i] = p1.theta[i];
    }
    F[3] = -(d[0] * mid->beta[0] + d[1] * mid->beta[1] + d[2] * mid->beta[2]) + h * mid->dHp;
    const int fin = isfinite(F[0] + F[1] + F[2] + F[3]);
    return fin ? p1.st : GCP_NONFINITE;
}

/* LU with partial pivoting of a 4x4 row-major matrix; 0 if non-singular. */
static int lu4(double *a, int *piv)
{
    for (int k = 0; k < 4; k++) {
        int pk = k;
        for (int i = k + 1; i < 4; i++)
            if (fabs(a[4 * i + k]) > fabs(a[4 * pk + k])) pk = i;
        piv[k] = pk;
        if (!(a[4 * pk + k] != 0.0) || !isfinite(a[4 * pk + k])) return -1;
        if (pk != k)
            for (int j = 0; j < 4; j++) {
                const double tmp = a[4 * k + j];
                a[4 * k + j] = a[4 * pk + j];
                a[4 * pk + j] = tmp;
            }
        for (int i = k + 1; i < 4; i++) {
            const double l = a[4 * i + k] / a[4 * k + k];
            a[4 * i + k] = l;
            for (int j = k + 1; j < 4; j++) a[4 * i + j] -= l * a[4 * k + j];
        }
    }
    return 0;
}

static void lus4(const double *a, const int *piv, double *x)
{
    /* rows were swapped whole (multipliers included): permute, then solve */
    for (int k = 0; k < 4; k++) {
        const double tmp = x[k];
        x[k] = x[piv[k]];
        x[piv[k]] = tmp;
    }
    for (int k = 0; k < 4; k++)
        for (int i = k + 1; i < 4; i++) x[i] -= a[4 * i + k] * x[k];
    for (int k = 3; k >= 0; k--) {
        for (int j = k + 1; j < 4; j++) x[k] -= a[4 * k + j] * x[j];
        x[k] /= a[4 * k + k];
    }
}

static void vi_scales(const struct vi_ctx *C, const struct vi_lane *L, double sc[4])
{
    sc[0] = L->Ls;
    sc[1] = C->cyl ? 1.0 : L->Ls;
    sc[2] = L->Ls;
    sc[3] = L->Ps;
}

static int vi_jacobian(const struct vi_ctx *C, double t, double h, struct vi_lane *L,
                       const double u[4], const double F[4])
{
    double sc[4], th[3], Fk[4];
    struct vi_pt mid;
    vi_scales(C, L, sc);
    for (int k = 0; k < 4; k++) {
        double uk[4] = {u[0], u[1], u[2], u[3]};
        const double e = VI_FD * sc[k];
        uk[k] += e;
        const double ek = uk[k] - u[k];
        vi_residual(C, t, h, L, uk, Fk, th, &mid);
        for (int i = 0; i < 4; i++) L->J[4 * i + k] = (Fk[i] - F[i]) / ek;
    }
    L->have_J = lu4(L->J, L->piv) == 0;
    return L->have_J ? 0 : -1;
}

/* Coordinate rates at (c, p) from the GC equations (for the predictor). */
static int vi_rates(const struct vi_ctx *C, double t, const double c[3], double p, double r[4])
{
    double P[3], dX[3], dp;
    cart_point(C, c, P);
    const int st = gcp_gc_rhs_at(C->f, t, C->q, C->m, P, p, C->mu, dX, &dp);
    if (C->cyl) {
        r[0] = dX[0];
        r[1] = dX[1] / c[0];
        r[2] = dX[2];
    } else {
        r[0] = dX[0], r[1] = dX[1], r[2] = dX[2];
    }
    r[3] = dp;
    return isfinite(r[0] + r[1] + r[2] + r[3]) ? st : GCP_NONFINITE;
}

/* One step of size h by Newton; on success updates the lane.  Returns 0,
 * -1 (Newton failure), or GCP_NONADIABATIC; *fst gets the field status at
 * the new point. */
/* Records why Newton failed (enum gcp_step_failure) and returns -1. */
static int vi_fail(int *why, int reason)
{
    *why = reason;
    return -1;
}

static int vi_newton(const struct vi_ctx *C, double t, double h, struct vi_lane *L, int *fst,
                     int *why)
{
    double u[4];
    if (L->have_prev >= 2 && L->hprev == h && L->hprev2 == h) {
        /* quadratic extrapolation z0 + 2 Delta_1 - Delta_2: error O(h^3) */
        for (int d = 0; d < 3; d++) u[d] = L->c[d] + 2.0 * L->dprev[d] - L->dprev2[d];
        u[3] = L->p + 2.0 * L->dprev[3] - L->dprev2[3];
    } else if (L->have_prev) {
        const double r = h / L->hprev;
        for (int d = 0; d < 3; d++) u[d] = L->c[d] + r * L->dprev[d];
        u[3] = L->p + r * L->dprev[3];
    } else {
        double k1[4], k2[4], cm[3];
        if (vi_rates(C, t, L->c, L->p, k1) == GCP_NONFINITE)
            return vi_fail(why, GCP_FAIL_NONFINITE_STAGE);
        for (int d = 0; d < 3; d++) cm[d] = L->c[d] + 0.5 * h * k1[d];
        if (vi_rates(C, t + 0.5 * h, cm, L->p + 0.5 * h * k1[3], k2) == GCP_NONFINITE)
            return vi_fail(why, GCP_FAIL_NONFINITE_STAGE);
        for (int d = 0; d < 3; d++) u[d] = L->c[d] + h * k2[d];
        u[3] = L->p + h * k2[3];
    }
    double sc[4], F[4], th1[3], nprev = INFINITY;
    (void)th1;
    struct vi_pt mid;
    vi_scales(C, L, sc);
    int refreshed = 0;
    for (int it = 0; it < VI_MAXIT; it++) {
        const int st = vi_residual(C, t, h, L, u, F, th1, &mid);
        if (st == GCP_NONFINITE) return vi_fail(why, GCP_FAIL_NONFINITE_STAGE);
        if (!L->have_J) {
            if (vi_jacobian(C, t, h, L, u, F)) return vi_fail(why, GCP_FAIL_NONFINITE_STAGE);
            refreshed = 1;
        }
        double d[4] = {-F[0], -F[1], -F[2], -F[3]};
        lus4(L->J, L->piv, d);
        double nd = 0.0;
        for (int k = 0; k < 4; k++) nd = fmax(nd, fabs(d[k]) / sc[k]);
        if (!isfinite(nd)) return vi_fail(why, GCP_FAIL_NONFINITE_STAGE);
        if (it > 0 && nd > 0.02 * nprev && nd > VI_TOL && !refreshed) {
            /* slow contraction with an old Jacobian: refresh it here */
            if (vi_jacobian(C, t, h, L, u, F)) return vi_fail(why, GCP_FAIL_NONFINITE_STAGE);
            refreshed = 1;
            for (int k = 0; k < 4; k++) d[k] = -F[k];
            lus4(L->J, L->piv, d);
            nd = 0.0;
            for (int k = 0; k < 4; k++) nd = fmax(nd, fabs(d[k]) / sc[k]);
            if (!isfinite(nd)) return vi_fail(why, GCP_FAIL_NONFINITE_STAGE);
        }
        const int stalled = it > 0 && nd <= VI_FLOOR && nd > 0.5 * nprev;
        if (nd <= VI_TOL || stalled) {
            if (!mid.ok) return GCP_NONADIABATIC;
            /* apply the last (round-off sized) update too, and take theta
             * at the final point: the next step's theta(z0) is then the
             * theta of the stored state exactly */
            for (int k = 0; k < 4; k++) u[k] += d[k];
            struct vi_pt p1;
            vi_point(C, t + h, u, u[3], 0, &p1);
            if (!isfinite(p1.theta[0] + p1.theta[1] + p1.theta[2]))
                return vi_fail(why, GCP_FAIL_NONFINITE_STAGE);
            memcpy(L->dprev2, L->dprev, sizeof L->dprev);
            L->hprev2 = L->hprev;
            for (int k = 0; k < 3; k++) L->dprev[k] = u[k] - L->c[k];
            L->dprev[3] = u[3] - L->p;
            L->hprev = h;
            L->have_prev = L->have_prev ? 2 : 1;
            for (int k = 0; k < 3; k++) {
                L->c[k] = u[k];
                L->theta[k] = p1.theta[k];
            }
            L->p = u[3];
            /* keep the azimuth in [-pi, pi]: the scheme sees phi only through
             * its increments, and an azimuth grown to ~1e3 rad over long runs
             * would have an ulp (1e-13) above the Newton tolerance on phi, so
             * Newton could no longer converge (seen after ~3e5 steps) */
            if (C->cyl) L->c[1] = remainder(L->c[1], 2.0 * GCP_PI);
            *fst = p1.st ? p1.st : st;
            return 0;
        }
        for (int k = 0; k < 4; k++) u[k] += d[k];
        nprev = nd;
    }
    return vi_fail(why, GCP_FAIL_NO_CONVERGENCE);
}

/* A step of size h: Newton, retried once from the first-step predictor
 * with a fresh Jacobian (the extrapolated predictor or the kept Jacobian
 * may be poor after a sharp turn); the step size never changes. */
static int vi_step(const struct vi_ctx *C, double t, double h, struct vi_lane *L, int *fst,
                   int *why)
{
    const int r = vi_newton(C, t, h, L, fst, why);
    if (r >= 0) return r;
    L->have_J = 0;
    L->have_prev = 0;
    const int r2 = vi_newton(C, t, h, L, fst, why); /* the retry's reason is the lane's */
    return r2 >= 0 ? r2 : GCP_STEP_FAILED;
}

static void lane_to_block(const struct vi_ctx *C, const struct vi_lane *L, struct gcp_block *b,
                          size_t i)
{
    if (C->cyl) {
        b->x[i] = L->c[0] * cos(L->c[1]);
        b->y[i] = L->c[0] * sin(L->c[1]);
    } else {
        b->x[i] = L->c[0];
        b->y[i] = L->c[1];
    }
    b->z[i] = L->c[2];
    b->ppar[i] = L->p;
}

static void lane_from_block(const struct vi_ctx *C, struct vi_lane *L, const struct gcp_block *b,
                            size_t i, double t)
{
    memset(L, 0, sizeof *L);
    if (C->cyl) {
        L->c[0] = hypot(b->x[i], b->y[i]);
        L->c[1] = atan2(b->y[i], b->x[i]);
    } else {
        L->c[0] = b->x[i];
        L->c[1] = b->y[i];
    }
    L->c[2] = b->z[i];
    L->p = b->ppar[i];
    const double X[3] = {b->x[i], b->y[i], b->z[i]};
    struct gcp_field_sample s = {.need = GCP_NEED_B};
    gcp_field_eval(C->f, t, X, &s);
    const double Bm = sqrt(s.B[0] * s.B[0] + s.B[1] * s.B[1] + s.B[2] * s.B[2]);
    const double Ls = sqrt(X[0] * X[0] + X[1] * X[1] + X[2] * X[2]);
    const double Ps = sqrt(L->p * L->p + 2.0 * b->m * b->mu[i] * Bm);
    L->Ls = Ls > 0.0 && isfinite(Ls) ? Ls : 1.0;
    L->Ps = Ps > 0.0 && isfinite(Ps) ? Ps : b->m;
    struct vi_pt pt;
    vi_point(C, t, L->c, L->p, 0, &pt);
    memcpy(L->theta, pt.theta, sizeof pt.theta);
}

struct vi_run {
    struct vi_ctx C; /* mu and m set per lane */
};

static int vi_init(const void *vctx, const struct gcp_block *b, size_t i, double t, void *vlane)
{
    struct vi_ctx Ci = ((const struct vi_run *)vctx)->C;
    Ci.m = b->m, Ci.mu = b->mu[i];
    lane_from_block(&Ci, vlane, b, i, t);
    return 0;
}

static int vi_lane_step(const void *vctx, struct gcp_block *b, size_t i, double t, double h,
                        void *vlane)
{
    struct vi_ctx Ci = ((const struct vi_run *)vctx)->C;
    Ci.m = b->m, Ci.mu = b->mu[i];
    struct vi_lane *L = vlane;
    const struct vi_lane save = *L;
    int fst = 0, why = GCP_FAIL_UNSPECIFIED;
    const int r = vi_step(&Ci, t, h, L, &fst, &why);
    if (r) {
        *L = save; /* state of the start of the step */
        return r == GCP_STEP_FAILED ? gcp_lane_fail(b, i, why) : r;
    }
    lane_to_block(&Ci, L, b, i);
    b->fstatus[i] = fst;
    return 0;
}

static const struct gcp_gc_lane_ops vi_ops = {sizeof(struct vi_lane), vi_init, vi_lane_step,
                                              NULL};

/* The whole vector potential with its derivatives: a property of the model
 * (gcp_gc_potential answers by model for dA), so any point will do. */
static int vi_applies(const struct gcp_field *f, char *why, size_t whylen)
{
    const double x[3] = {1.0, 0.0, 1.0};
    double A[3], dA[3][3];
    if (gcp_gc_potential(f, 0.0, x, A, dA, NULL) == 0) return 0;
    if (why && whylen)
        snprintf(why, whylen, "the field model has no analytic vector potential with "
                              "derivatives (dipole, mirror, tokamak, uniform have one)");
    return GCP_ERR_STATE;
}

static size_t gc_vi_advance(struct gcp_block *b, const struct gcp_field *f,
                            const struct gcp_pusher_type *p, const struct gcp_push_opts *o,
                            const struct gcp_sampler *s)
{
    (void)p;
    if (vi_applies(f, NULL, 0)) {
        const size_t n = b->n_active;
        for (size_t i = 0; i < n; i++) b->status[i] = gcp_lane_fail(b, i, GCP_FAIL_UNSUPPORTED);
        b->n_active = gcp_block_retire(b, n, o->t0, 0);
        return b->n_active;
    }
    const struct vi_run R = {{f, (gcp_field_caps(f) & GCP_CAP_AXISYM) != 0, b->q, 0.0, 0.0,
                              o->adiabaticity_max}};
    return gcp_gc_lanes_advance(b, f, o, s, &vi_ops, &R);
}

const struct gcp_pusher_type gcp_pusher_gc_midpoint_pphi = {
    .name = "gc-midpoint-pphi",
    .doc = "guiding centre, symmetric midpoint scheme with exact p_phi, order 2, NOT symplectic "
           "(formerly gc-vi; fields with an analytic vector potential)",
    .order = 2,
    .kind = GCP_GUIDING_CENTRE,
    .kick = NULL,
    .advance = gc_vi_advance,
    .applies = vi_applies,
};
