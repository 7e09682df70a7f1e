/* Guiding-centre building blocks: the vector potentials (curl A = B,
 * -grad phi = E), the GC right-hand side against finite differences of b,
 * the full-orbit <-> guiding-centre transformation, and the failure paths
 * shared by every GC pusher (one battery). */
#include <criterion/criterion.h>

#include "gcpush/error.h"
#include "test_gc_util.h"

/* A uniform 1 mT field along z, as a user callback (no vector potential). */
static int cb_uniform(double t, const double x[3], struct gcp_field_sample *out, void *ctx)
{
    (void)t, (void)x, (void)ctx;
    out->B[0] = 0, out->B[1] = 0, out->B[2] = 1e-3;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) out->gradB[i][j] = 0.0;
    out->E[0] = out->E[1] = out->E[2] = 0.0;
    return 0;
}

/* ---- vector potentials ---- */

static void fd_dA(const struct gcp_field *f, const double x[3], double h, double dA[3][3])
{
    for (int j = 0; j < 3; j++) {
        double xp[3] = {x[0], x[1], x[2]}, xm[3] = {x[0], x[1], x[2]}, Ap[3], Am[3];
        xp[j] += h, xm[j] -= h;
        gcp_gc_potential(f, 0.0, xp, Ap, NULL, NULL);
        gcp_gc_potential(f, 0.0, xm, Am, NULL, NULL);
        for (int i = 0; i < 3; i++) dA[i][j] = (Ap[i] - Am[i]) / (2.0 * h);
    }
}

/* At points inside each model: (1) the analytic dA against central
 * differences, step h = 1e-4 L (truncation ~(h/L)^2 = 1e-8, round-off
 * ~1e-16 L/h = 1e-12): 1e-6 of the scale |A|/L; (2) curl A from the analytic
 * dA against the field's B: the same expressions, only round-off: 1e-12 |B|
 * (plus 1e-12 of the largest dA entry); (3) -grad phi against E
 * (corotating dipole), central differences: 1e-6 |E|. */
Test(gc_basic, potential_curl_is_B)
{
    struct {
        struct gcp_field *f;
        double L;
        double x[3][3];
    } F[] = {
        {gcp_field_dipole_create(GC_B0, 1, 0.0, 0.0), GC_RE,
         {{4 * GC_RE, 0.3 * GC_RE, 0.5 * GC_RE}, {-2 * GC_RE, 1.5 * GC_RE, -1 * GC_RE},
          {0.1 * GC_RE, -3 * GC_RE, 2 * GC_RE}}},
        {gcp_field_mirror_create(0.7, 1.3, 10.0, 10.0), 1.0,
         {{0.2, 0.1, 0.5}, {-0.3, 0.4, -0.8}, {0.05, -0.02, 1.1}}},
        {gcp_field_tokamak_create(2.5, 3.0, 1.0, 1.1, 3.5), 1.0,
         {{3.5, 0.2, 0.3}, {-2.4, 1.1, -0.5}, {0.3, -2.6, 0.1}}},
        {gcp_field_uniform_create((const double[3]){0.1, -0.2, 0.9}, (const double[3]){1, 2, 3}),
         1.0, {{1, 2, 3}, {-1, 0, 5}, {0, 0, 0}}},
    };
    for (size_t k = 0; k < sizeof F / sizeof F[0]; k++) {
        const struct gcp_field *f = F[k].f;
        cr_assert_not_null(f);
        for (int n = 0; n < 3; n++) {
            const double *x = F[k].x[n];
            double A[3], dA[3][3], dAn[3][3], phi;
            cr_assert_eq(gcp_gc_potential(f, 0.0, x, A, dA, &phi), 0);
            fd_dA(f, x, 1e-4 * F[k].L, dAn);
            double Am = sqrt(A[0] * A[0] + A[1] * A[1] + A[2] * A[2]), dmax = 0.0;
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++) dmax = fmax(dmax, fabs(dA[i][j]));
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++)
                    cr_expect(fabs(dA[i][j] - dAn[i][j]) <= 1e-6 * (Am / F[k].L + dmax),
                              "%s: dA[%d][%d] %.10e vs FD %.10e", f->type->name, i, j, dA[i][j],
                              dAn[i][j]);
            const double curl[3] = {dA[2][1] - dA[1][2], dA[0][2] - dA[2][0], dA[1][0] - dA[0][1]};
            struct gcp_field_sample s = {.need = GCP_NEED_B | GCP_NEED_E};
            gcp_field_eval(f, 0.0, x, &s);
            const double Bm = sqrt(s.B[0] * s.B[0] + s.B[1] * s.B[1] + s.B[2] * s.B[2]);
            for (int i = 0; i < 3; i++)
                cr_expect(fabs(curl[i] - s.B[i]) <= 1e-12 * (Bm + dmax),
                          "%s: (curl A)_%d %.15e vs B %.15e", f->type->name, i, curl[i], s.B[i]);
            if (f->has_E) {
                const double Em = sqrt(s.E[0] * s.E[0] + s.E[1] * s.E[1] + s.E[2] * s.E[2]);
                for (int j = 0; j < 3; j++) {
                    const double h = 1e-4 * F[k].L;
                    double xp[3] = {x[0], x[1], x[2]}, xm[3] = {x[0], x[1], x[2]}, pp, pm, a[3];
                    xp[j] += h, xm[j] -= h;
                    gcp_gc_potential(f, 0.0, xp, a, NULL, &pp);
                    gcp_gc_potential(f, 0.0, xm, a, NULL, &pm);
                    cr_expect(fabs(-(pp - pm) / (2 * h) - s.E[j]) <= 1e-6 * Em,
                              "%s: -dphi/dx_%d vs E", f->type->name, j);
                }
            }
        }
        gcp_field_free(F[k].f);
    }
    /* fields without a potential say so */
    struct gcp_field *cb = gcp_field_callback_create(cb_uniform, NULL, 0);
    double A[3];
    cr_expect_neq(gcp_gc_potential(cb, 0.0, (const double[3]){1, 0, 0}, A, NULL, NULL), 0);
    gcp_field_free(cb);
}

/* ---- GC right-hand side against finite differences of b ----
 * Tokamak (curl B != 0, b.curl b != 0: B*_par != B) and dipole.  The RHS is
 * rebuilt here from curl b by central differences of b(x) = B/|B| (step
 * 1e-5 L: truncation ~1e-10, round-off ~1e-11 relative) and grad|B| by
 * central differences of |B|: agreement 1e-7 relative. */
static void fd_rhs(const struct gcp_field *f, const double X[3], double L, double ppar, double mu,
                   double q, double m, double dX[3], double *dp)
{
    const double h = 1e-5 * L;
    double cb[3] = {0, 0, 0}, gB[3], db[3][3];
    for (int j = 0; j < 3; j++) {
        double xp[3] = {X[0], X[1], X[2]}, xm[3] = {X[0], X[1], X[2]};
        xp[j] += h, xm[j] -= h;
        struct gcp_field_sample sp = {.need = GCP_NEED_B}, sm = {.need = GCP_NEED_B};
        gcp_field_eval(f, 0, xp, &sp);
        gcp_field_eval(f, 0, xm, &sm);
        const double Bp = sqrt(sp.B[0] * sp.B[0] + sp.B[1] * sp.B[1] + sp.B[2] * sp.B[2]);
        const double Bn = sqrt(sm.B[0] * sm.B[0] + sm.B[1] * sm.B[1] + sm.B[2] * sm.B[2]);
        gB[j] = (Bp - Bn) / (2 * h);
        for (int i = 0; i < 3; i++) db[i][j] = (sp.B[i] / Bp - sm.B[i] / Bn) / (2 * h);
    }
    cb[0] = db[2][1] - db[1][2], cb[1] = db[0][2] - db[2][0], cb[2] = db[1][0] - db[0][1];
    struct gcp_field_sample s = {.need = GCP_NEED_B};
    gcp_field_eval(f, 0, X, &s);
    const double Bm = sqrt(s.B[0] * s.B[0] + s.B[1] * s.B[1] + s.B[2] * s.B[2]);
    const double b[3] = {s.B[0] / Bm, s.B[1] / Bm, s.B[2] / Bm};
    const double gamma = gcp_gc_gamma(ppar, mu, Bm, m);
    double Bs[3], Es[3];
    for (int i = 0; i < 3; i++) Bs[i] = s.B[i] + ppar / q * cb[i], Es[i] = -mu / (q * gamma) * gB[i];
    const double Bsp = b[0] * Bs[0] + b[1] * Bs[1] + b[2] * Bs[2];
    const double Exb[3] = {Es[1] * b[2] - Es[2] * b[1], Es[2] * b[0] - Es[0] * b[2],
                           Es[0] * b[1] - Es[1] * b[0]};
    for (int i = 0; i < 3; i++) dX[i] = (ppar / (gamma * m) * Bs[i] + Exb[i]) / Bsp;
    *dp = q * (Es[0] * Bs[0] + Es[1] * Bs[1] + Es[2] * Bs[2]) / Bsp;
}

Test(gc_basic, rhs_matches_finite_differences)
{
    struct gcp_field *tok = gcp_field_tokamak_create(2.5, 3.0, 1.0, 1.1, 3.5);
    struct gcp_field *dip = gcp_field_dipole_create(GC_B0, 0, 0.0, 0.0);
    struct { const struct gcp_field *f; double L, X[3], q, m, T, pitch; } c[] = {
        {tok, 1.0, {3.4, 0.5, 0.3}, GCP_E_CHARGE, GCP_M_PROTON, 100e3 * GCP_E_CHARGE, 0.7},
        {tok, 1.0, {-2.6, -0.9, -0.4}, -GCP_E_CHARGE, GCP_M_ELECTRON, 3e6 * GCP_E_CHARGE, 2.0},
        {dip, GC_RE, {3 * GC_RE, 1 * GC_RE, 1 * GC_RE}, GCP_E_CHARGE, GCP_M_PROTON,
         10e6 * GCP_E_CHARGE, 1.0},
    };
    for (size_t k = 0; k < sizeof c / sizeof c[0]; k++) {
        const double p = gc_p_of_T(c[k].T, c[k].m);
        const double B = gc_Bmag(c[k].f, c[k].X);
        const double ppar = p * cos(c[k].pitch);
        const double mu = p * sin(c[k].pitch) * p * sin(c[k].pitch) / (2 * c[k].m * B);
        double dX[3], dp, dXn[3], dpn;
        cr_assert_eq(gcp_gc_rhs_at(c[k].f, 0, c[k].q, c[k].m, c[k].X, ppar, mu, dX, &dp), 0);
        fd_rhs(c[k].f, c[k].X, c[k].L, ppar, mu, c[k].q, c[k].m, dXn, &dpn);
        const double vs = sqrt(dX[0] * dX[0] + dX[1] * dX[1] + dX[2] * dX[2]);
        for (int i = 0; i < 3; i++)
            cr_expect(fabs(dX[i] - dXn[i]) <= 1e-7 * vs, "case %zu dX[%d] %.12e vs %.12e", k, i,
                      dX[i], dXn[i]);
        cr_expect(fabs(dp - dpn) <= 1e-7 * fabs(dpn) + 1e-30, "case %zu dp %.12e vs %.12e", k, dp,
                  dpn);
    }
    gcp_field_free(tok);
    gcp_field_free(dip);
}

/* ---- full orbit <-> guiding centre ----
 * gcp_fo_from_gc solves x - rho(x) = X, so gcp_gc_from_fo of its output
 * returns X, p_par, mu to round-off: |dX| <= 1e-9 rho (the fixed point is
 * iterated to 1e-15 |X|; rho ~ 1e-3 |X|), p_par and mu to 1e-12 relative.
 * The gyroradius |x - X| = p_perp/|qB| to first order: within 5 eps
 * (eps = rho/L_B ~ 1e-3 here), i.e. |x - X| = rho (1 + O(eps)). */
Test(gc_basic, transform_round_trip)
{
    struct gcp_field *f = gcp_field_dipole_create(GC_B0, 0, 0.0, 0.0);
    const struct { double q, m, T; } sp[] = {{-GCP_E_CHARGE, GCP_M_ELECTRON, 1e6 * GCP_E_CHARGE},
                                             {GCP_E_CHARGE, GCP_M_PROTON, 10e6 * GCP_E_CHARGE}};
    for (int s = 0; s < 2; s++)
        for (int k = 0; k < 8; k++) {
            const double X[3] = {3.7 * GC_RE, 0.8 * GC_RE, 0.9 * GC_RE};
            const double p = gc_p_of_T(sp[s].T, sp[s].m), a = 0.3 + 0.3 * k;
            const double B = gc_Bmag(f, X);
            const double ppar = p * cos(a), mu = pow(p * sin(a), 2) / (2 * sp[s].m * B);
            double x[3], u[3], X2[3], ppar2, mu2, eps;
            cr_assert_eq(gcp_fo_from_gc(f, 0, sp[s].q, sp[s].m, X, ppar, mu, 0.7 * k, x, u), 0);
            cr_assert_eq(gcp_gc_from_fo(f, 0, sp[s].q, sp[s].m, x, u, X2, &ppar2, &mu2), 0);
            const double rho = p * sin(a) / (fabs(sp[s].q) * B);
            gcp_gc_adiabaticity(f, 0, sp[s].q, sp[s].m, X, ppar, mu, &eps);
            for (int d = 0; d < 3; d++)
                cr_expect(fabs(X2[d] - X[d]) <= 1e-9 * rho, "X[%d] round trip %.3e of rho %.3e",
                          d, X2[d] - X[d], rho);
            cr_expect(fabs(ppar2 - ppar) <= 1e-12 * p, "ppar round trip");
            cr_expect(fabs(mu2 / mu - 1) <= 1e-12, "mu round trip %.3e", mu2 / mu - 1);
            const double dx = sqrt(pow(x[0] - X[0], 2) + pow(x[1] - X[1], 2) + pow(x[2] - X[2], 2));
            cr_expect(fabs(dx / rho - 1) <= 5 * eps, "|x - X| = %.6e vs rho %.6e (eps %.2e)", dx,
                      rho, eps);
            /* energy kept exactly: gamma(u) = gamma(ppar, mu, B(X)) */
            const double g1 = gcp_gamma_of_u(u[0], u[1], u[2]);
            const double g2 = gcp_gc_gamma(ppar2, mu2, gc_Bmag(f, X2), sp[s].m);
            cr_expect(fabs(g1 / g2 - 1) <= 1e-14, "gamma %.17g vs %.17g", g1, g2);
        }
    gcp_field_free(f);
}

/* The transform against an independent expectation, not its own inverse:
 * the exact relativistic gyration in a uniform oblique B (1 mT along
 * (0.1, -0.2, 0.9)), written from the solution of m d(gamma v)/dt =
 * q v x B with signed omega = q |B| / (gamma m):
 *   x(t) = X0 + v_par t b + R (cos(omega t) e1 - sin(omega t) e2),
 *   v(t) = v_par b - R omega (sin(omega t) e1 + cos(omega t) e2),
 * R = v_perp / |omega|, e2 = b x e1 (check: dv/dt = omega v x b).  Its
 * guiding centre is X0 + v_par t b exactly (eps = 0: no correction
 * beyond the gyroradius), p_par = gamma m v_par, mu = (gamma m v_perp)^2 /
 * (2 m |B|).  Round-off only: |x| ~ 10 m, so 1e-13 (|X0| + R) on X (~200
 * eps of the operands), 1e-13 relative on p_par and mu.  Both signs of
 * charge, gamma from 1 + 1e-6 to 20, eight phases each.  And the inverse:
 * gcp_fo_from_gc at (X0, p_par, mu) puts x on that circle (|x - X0| = R,
 * (x - X0).b = 0) with u = gamma v gyrating the right way round:
 * ((x - X0) x v).b has the sign of -q. */
static double gc_norm(const double a[3]) { return sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]); }

Test(gc_basic, transform_exact_gyration)
{
    const double Bv[3] = {0.1e-3, -0.2e-3, 0.9e-3}, E0[3] = {0, 0, 0};
    struct gcp_field *f = gcp_field_uniform_create(Bv, E0);
    cr_assert_not_null(f);
    const double Bm = gc_norm(Bv);
    const double b[3] = {Bv[0] / Bm, Bv[1] / Bm, Bv[2] / Bm};
    double e1[3] = {b[1], -b[0], 0.0}; /* b x zhat, normalised */
    const double n1 = gc_norm(e1);
    for (int d = 0; d < 3; d++) e1[d] /= n1;
    const double e2[3] = {b[1] * e1[2] - b[2] * e1[1], b[2] * e1[0] - b[0] * e1[2],
                          b[0] * e1[1] - b[1] * e1[0]};
    const double X0[3] = {1.0, 2.0, 3.0};
    const struct { double q, m, T; } sp[] = {
        {GCP_E_CHARGE, GCP_M_PROTON, 1e3 * GCP_E_CHARGE},
        {GCP_E_CHARGE, GCP_M_PROTON, 1e9 * GCP_E_CHARGE},
        {-GCP_E_CHARGE, GCP_M_ELECTRON, 0.5 * GCP_E_CHARGE},
        {-GCP_E_CHARGE, GCP_M_ELECTRON, 1e7 * GCP_E_CHARGE}};
    for (size_t s = 0; s < sizeof sp / sizeof sp[0]; s++) {
        const double q = sp[s].q, m = sp[s].m, p = gc_p_of_T(sp[s].T, m);
        const double mc = m * GCP_C_LIGHT, gamma = sqrt(1 + (p / mc) * (p / mc));
        const double a = 0.7; /* pitch angle [rad] */
        const double v = p / (gamma * m), vpar = v * cos(a), vperp = v * sin(a);
        const double om = q * Bm / (gamma * m), R = vperp / fabs(om);
        const double ppar_ex = gamma * m * vpar, mu_ex = pow(gamma * m * vperp, 2) / (2 * m * Bm);
        for (int k = 0; k < 8; k++) {
            const double t = (0.37 + 0.83 * k) / fabs(om), c = cos(om * t), sn = sin(om * t);
            double x[3], u[3], Xex[3], X[3], ppar, mu;
            for (int d = 0; d < 3; d++) {
                x[d] = X0[d] + vpar * t * b[d] + R * (c * e1[d] - sn * e2[d]);
                u[d] = gamma * (vpar * b[d] - R * om * (sn * e1[d] + c * e2[d]));
                Xex[d] = X0[d] + vpar * t * b[d];
            }
            cr_assert_eq(gcp_gc_from_fo(f, 0, q, m, x, u, X, &ppar, &mu), 0);
            const double scale = gc_norm(Xex) + R;
            for (int d = 0; d < 3; d++)
                cr_assert(fabs(X[d] - Xex[d]) <= 1e-13 * scale,
                          "species %zu phase %d: X[%d] - exact = %.3e (R = %.3e m)", s, k, d,
                          X[d] - Xex[d], R);
            cr_assert(fabs(ppar / ppar_ex - 1) <= 1e-13, "p_par %.3e", ppar / ppar_ex - 1);
            cr_assert(fabs(mu / mu_ex - 1) <= 1e-13, "mu %.3e", mu / mu_ex - 1);
        }
        for (int k = 0; k < 4; k++) {
            double x[3], u[3], r[3], vv[3];
            cr_assert_eq(gcp_fo_from_gc(f, 0, q, m, X0, ppar_ex, mu_ex, 1.3 * k, x, u), 0);
            for (int d = 0; d < 3; d++) r[d] = x[d] - X0[d], vv[d] = u[d] / gamma;
            const double rb = r[0] * b[0] + r[1] * b[1] + r[2] * b[2];
            cr_assert(fabs(gc_norm(r) / R - 1) <= 1e-13 && fabs(rb) <= 1e-13 * (R + gc_norm(X0)),
                      "species %zu: |x - X0| / R - 1 = %.3e, (x - X0).b = %.3e m", s,
                      gc_norm(r) / R - 1, rb);
            const double rxv_b = (r[1] * vv[2] - r[2] * vv[1]) * b[0] +
                                 (r[2] * vv[0] - r[0] * vv[2]) * b[1] +
                                 (r[0] * vv[1] - r[1] * vv[0]) * b[2];
            cr_assert(rxv_b * q < 0, "species %zu gyrates the wrong way round", s);
            cr_assert(fabs((u[0] * b[0] + u[1] * b[1] + u[2] * b[2]) / (gamma * vpar) - 1) <= 1e-13);
        }
    }
    gcp_field_free(f);
}

/* ---- failure paths, one battery over every GC pusher ---- */

static void fill_lane(struct gcp_block *b, size_t i, const double X[3], double ppar, double mu)
{
    b->x[i] = X[0], b->y[i] = X[1], b->z[i] = X[2];
    b->ppar[i] = ppar, b->mu[i] = mu;
    b->status[i] = 0, b->steps[i] = 0, b->t[i] = 0;
    b->index[i] = i;
}

static size_t lane_of(const struct gcp_block *b, size_t idx)
{
    for (size_t i = 0; i < b->n; i++)
        if (b->index[i] == idx) return i;
    return (size_t)-1;
}

/* 10 MeV proton at L = 4, a_eq = 45 deg. */
static void dip_state(const struct gcp_field *f, double X[3], double *ppar, double *mu, double *Tb)
{
    X[0] = 4 * GC_RE, X[1] = 0, X[2] = 0;
    const double p = gc_p_of_T(10e6 * GCP_E_CHARGE, GCP_M_PROTON);
    *ppar = p * cos(GCP_PI / 4);
    *mu = p * p * 0.5 / (2 * GCP_M_PROTON * gc_Bmag(f, X));
    double Td, lm;
    gc_dip_theory(f, GCP_E_CHARGE, GCP_M_PROTON, 10e6 * GCP_E_CHARGE, 4.0, GCP_PI / 4, Tb, &Td, &lm);
}

Test(gc_basic, battery_nonfinite_and_bad_dt)
{
    struct gcp_field *f = gcp_field_dipole_create(GC_B0, 0, GC_RE, 0.0);
    double X[3], ppar, mu, Tb;
    dip_state(f, X, &ppar, &mu, &Tb);
    GC_FOREACH(p)
    {
        struct gcp_block b;
        cr_assert_eq(gcp_block_alloc(&b, 3), 0);
        b.q = GCP_E_CHARGE, b.m = GCP_M_PROTON;
        fill_lane(&b, 0, X, ppar, mu);
        fill_lane(&b, 1, X, NAN, mu);
        fill_lane(&b, 2, X, -ppar, mu);
        const struct gcp_push_opts o = {0.0, Tb / 200, 50, 0.0, 0.0};
        const size_t live = p->advance(&b, f, p, &o, NULL);
        cr_expect_eq(live, 2, "%s: live %zu", p->name, live);
        const size_t i1 = lane_of(&b, 1), i0 = lane_of(&b, 0), i2 = lane_of(&b, 2);
        cr_expect_eq(b.status[i1], GCP_NONFINITE, "%s: NaN lane status %d", p->name, b.status[i1]);
        cr_expect_eq(b.steps[i1], 0);
        cr_expect_eq(b.t[i1], 0.0);
        cr_expect_eq(b.status[i0], GCP_ALIVE, "%s: lane 0 status %d", p->name, b.status[i0]);
        cr_expect_eq(b.status[i2], GCP_ALIVE, "%s: lane 2 status %d", p->name, b.status[i2]);
        cr_expect(fabs(b.t[i0] - 50 * Tb / 200) <= 1e-12 * Tb, "%s: t %.17g", p->name, b.t[i0]);
        cr_expect(b.steps[i0] > 0);
        /* symmetric lanes stay mirror images: Z(lane 0) = -Z(lane 2) */
        cr_expect(fabs(b.z[i0] + b.z[i2]) <= 1e-6 * fabs(b.z[i0]), "%s: mirror symmetry %.3e %.3e",
                  p->name, b.z[i0], b.z[i2]);
        /* dt <= 0 and dt = NaN: every lane STEP_FAILED, nothing moved */
        const double bad[2] = {-1.0, NAN};
        for (int k = 0; k < 2; k++) {
            fill_lane(&b, 0, X, ppar, mu);
            fill_lane(&b, 1, X, ppar, mu);
            b.n_active = 2;
            const struct gcp_push_opts ob = {0.0, bad[k], 10, 0.0, 0.0};
            cr_expect_eq(p->advance(&b, f, p, &ob, NULL), 0);
            for (size_t i = 0; i < 2; i++) {
                cr_expect_eq(b.status[i], GCP_STEP_FAILED, "%s: dt %g status %d", p->name, bad[k],
                             b.status[i]);
                cr_expect(b.x[i] == X[0] && b.ppar[i] == ppar && b.steps[i] == 0);
            }
        }
        gcp_block_free(&b);
    }
    gcp_field_free(f);
}

/* Mirror field (B0 = 1 T, Lm = 1 m), with its X-type null on the ring
 * R = sqrt(2) Lm, z = 0.  Lane 0: a 1 keV proton on the field line
 * psi = psi_null + 1e-3 B0 Lm^2 (psi = (R^2/2)(B0 + k(z^2 - R^2/4))), started
 * at z = Lm heading down (p_par < 0) towards the null, where B -> 0 and
 * eps = rho |grad B|/B -> inf (eps ~ 1e-3 at the start).  It must stop
 * NONADIABATIC (threshold 0.1) with a finite state and |B| > 0 -- before the
 * null.  Lane 1: a trapped proton near the axis, ALIVE at the end. */
Test(gc_basic, battery_field_null_nonadiabatic)
{
    struct gcp_field *f = gcp_field_mirror_create(1.0, 1.0, 10.0, 10.0);
    const double m = GCP_M_PROTON, q = GCP_E_CHARGE, p = gc_p_of_T(1e3 * GCP_E_CHARGE, m);
    const double s = 4.0 - sqrt(12.0 - 8.0 * 1e-3);
    const double X0[3] = {sqrt(s), 0.0, 1.0}, X1[3] = {0.3, 0.0, 0.0};
    const double a = 20.0 * GCP_PI / 180.0;
    const double mu0 = pow(p * sin(a), 2) / (2 * m * gc_Bmag(f, X0));
    const double mu1 = pow(p * sin(1.0), 2) / (2 * m * gc_Bmag(f, X1));
    GC_FOREACH(P)
    {
        struct gcp_block b;
        cr_assert_eq(gcp_block_alloc(&b, 2), 0);
        b.q = q, b.m = m;
        fill_lane(&b, 0, X0, -p * cos(a), mu0);
        fill_lane(&b, 1, X1, p * cos(1.0), mu1);
        const struct gcp_push_opts o = {0.0, 2e-9, 5000, 0.0, 0.1};
        P->advance(&b, f, P, &o, NULL);
        const size_t i0 = lane_of(&b, 0), i1 = lane_of(&b, 1);
        cr_expect_eq(b.status[i0], GCP_NONADIABATIC, "%s: status %d", P->name, b.status[i0]);
        const double Xe[3] = {b.x[i0], b.y[i0], b.z[i0]};
        const double Be = gc_Bmag(f, Xe);
        cr_expect(isfinite(Be) && Be > 1e-3, "%s: stopped at |B| = %.3e T", P->name, Be);
        cr_expect(b.t[i0] < 5000 * 2e-9, "%s", P->name);
        cr_expect_eq(b.status[i1], GCP_ALIVE, "%s: trapped lane status %d", P->name, b.status[i1]);
        cr_log_info("%s: NONADIABATIC at t = %.3e s, |B| = %.3f T, R = %.4f z = %.4f", P->name,
                    b.t[i0], Be, hypot(Xe[0], Xe[1]), Xe[2]);
        gcp_block_free(&b);
    }
    gcp_field_free(f);
}

/* Step failures: the adaptive methods with an impossible tolerance
 * (1e-30, below round-off: the step size collapses to round-off), the
 * implicit fixed-step methods (gc-midpoint-pphi, gc-gl2, gc-gl4) with a step
 * of 50 bounce periods (Newton fails; the step is never shortened; gc-gl2
 * and gc-gl4 on a lane nearly along B, see below).
 * The lane gets STEP_FAILED with the state of its last accepted step: a
 * valid GC state whose energy equals the initial one to 1e-9 (the energy
 * error of a few accepted steps, if any), at a time before the end; the
 * implicit methods fail on its first step, so its state and time are exactly the initial
 * ones.  (Tolerance and dt are per block, so here every lane fails; the
 * per-lane isolation is shown by the NaN and null batteries above.)  And
 * gc-midpoint-pphi on a field without a vector potential (a user callback) gives
 * STEP_FAILED, while the uniform field has one. */

Test(gc_basic, battery_step_failed_state_restored)
{
    struct gcp_field *f = gcp_field_dipole_create(GC_B0, 0, GC_RE, 0.0);
    double X[3], ppar, mu, Tb;
    dip_state(f, X, &ppar, &mu, &Tb);
    GC_FOREACH(p)
    {
        if (gc_is(p, "gc-rk4")) continue; /* explicit fixed step: no failure mode */
        struct gcp_block b;
        cr_assert_eq(gcp_block_alloc(&b, 1), 0);
        b.q = GCP_E_CHARGE, b.m = GCP_M_PROTON;
        /* gc-gl2 / gc-gl4 in the dipole collocate in the field line's own
         * closed-form coordinates (gc_gauss_dipole.c), where the stage
         * equations of this trapped lane have a solution at any step (the
         * 1-D bounce Hamiltonian: at 50 Tb the converged step lands near the
         * equator, energy kept to 1e-6); what they cannot step is a lane
         * nearly along B (pitch 0.1 deg, mirror point far inside the Earth)
         * over 50 Tb: its stage points pass the line's pole, where Newton
         * has no solution */
        const int line = gc_is(p, "gc-gl2") || gc_is(p, "gc-gl4");
        const double pa = 0.1 * GCP_PI / 180, ptot = hypot(ppar, ppar);
        const double ppar_l = line ? ptot * cos(pa) : ppar;
        const double mu_l = line ? mu * 2.0 * sin(pa) * sin(pa) : mu;
        double Hl0;
        gcp_gc_energy(f, 0, GCP_E_CHARGE, GCP_M_PROTON, X, ppar_l, mu_l, &Hl0);
        fill_lane(&b, 0, X, ppar_l, mu_l);
        const int vi = gc_is(p, "gc-midpoint-pphi") || gc_is(p, "gc-gl2") || gc_is(p, "gc-gl4") ||
                       gc_is(p, "gc-gl2-sundman") || gc_is(p, "gc-gl4-sundman");
        const struct gcp_push_opts o = {0.0, vi ? 50 * Tb : Tb / 100, vi ? 1 : 100,
                                        vi ? 0.0 : 1e-30, 0.0};
        p->advance(&b, f, p, &o, NULL);
        if (strstr(p->name, "-sundman")) {
            /* in the dipole the Sundman forms run in the line's coordinates
             * (gc_sundman_dipole.c), where this s-step converges: w -> 0
             * toward the line's pole slows the transformed flow, and the
             * 1-D bounce's stage equations have a solution; the lane lands
             * alive on t = dt (its failure path is gc_sundman.c's outside
             * the dipole) */
            cr_expect_eq(b.status[0], GCP_ALIVE, "%s: status %d", p->name, b.status[0]);
            cr_expect(b.t[0] == o.dt, "%s: t %g", p->name, b.t[0]);
            gcp_block_free(&b);
            continue;
        }
        cr_expect_eq(b.status[0], GCP_STEP_FAILED, "%s: status %d", p->name, b.status[0]);
        /* the reason rides with the lane (issue 11): Newton for the midpoint
         * scheme, the error control below round-off for the GSL methods, and
         * for the Gauss-Legendre methods (fixed and Sundman) the chart: a step
         * of 50 bounce periods puts the Newton's stage points where the chart
         * inversion (psi, chi) -> (R, Z) has no solution near its guess */
        const int why = b.step_failure[0];
        cr_log_info("%s: step failure %s", p->name, gcp_step_failure_name(why));
        cr_expect(why != GCP_FAIL_NONE, "%s: no failure reason", p->name);
        if (gc_is(p, "gc-midpoint-pphi"))
            cr_expect_eq(why, GCP_FAIL_NO_CONVERGENCE, "%s: %s", p->name, gcp_step_failure_name(why));
        if (strstr(p->name, "-sundman"))
            cr_expect_eq(why, GCP_FAIL_CHART, "%s: %s", p->name, gcp_step_failure_name(why));
        if (line)
            cr_expect_eq(why, GCP_FAIL_NO_CONVERGENCE, "%s: %s", p->name,
                         gcp_step_failure_name(why));
        if (gc_is(p, "gc-rk45") || gc_is(p, "gc-rk8pd"))
            cr_expect_eq(why, GCP_FAIL_STEP_UNDERFLOW, "%s: %s", p->name, gcp_step_failure_name(why));
        const double Xe[3] = {b.x[0], b.y[0], b.z[0]};
        double H;
        gcp_gc_energy(f, 0, b.q, b.m, Xe, b.ppar[0], b.mu[0], &H);
        cr_expect(isfinite(H) && fabs(H / Hl0 - 1) < 1e-9, "%s: restored state energy %.3e",
                  p->name, H / Hl0 - 1);
        cr_expect(b.t[0] >= 0.0 && b.t[0] < o.dt * (double)o.nsteps, "%s: t %g", p->name, b.t[0]);
        if (vi)
            cr_expect(b.x[0] == X[0] && b.ppar[0] == ppar_l && b.t[0] == 0.0 && b.steps[0] == 0);
        gcp_block_free(&b);
    }
    struct gcp_field *u = gcp_field_uniform_create((const double[3]){0, 0, 1e-3}, NULL);
    struct gcp_field *cb = gcp_field_callback_create(cb_uniform, NULL, 0);
    const struct gcp_push_opts o = {0.0, 1e-6, 10, 0.0, 0.0};
    for (int k = 0; k < 2; k++) {
        struct gcp_block b;
        cr_assert_eq(gcp_block_alloc(&b, 1), 0);
        b.q = GCP_E_CHARGE, b.m = GCP_M_PROTON;
        fill_lane(&b, 0, (const double[3]){1, 2, 3}, 1e-22, 1e-20);
        const size_t live = gcp_pusher_gc_midpoint_pphi.advance(&b, k ? cb : u, &gcp_pusher_gc_midpoint_pphi, &o, NULL);
        cr_expect_eq(live, k ? 0u : 1u, "gc-midpoint-pphi live lanes %zu (field %d)", live, k);
        cr_expect_eq(b.status[0], k ? GCP_STEP_FAILED : GCP_ALIVE);
        cr_expect_eq(b.step_failure[0], k ? GCP_FAIL_UNSUPPORTED : GCP_FAIL_NONE);
        cr_expect(!k || (b.x[0] == 1 && b.ppar[0] == 1e-22));
        gcp_block_free(&b);
    }
    gcp_field_free(cb);
    gcp_field_free(u);
    gcp_field_free(f);
}

/* E without a potential (issue 13): the energy H = gamma m c^2 + q phi is
 * unknown there, and gcp_gc_energy says so (GCP_ERR_UNKNOWN, NaN) instead of
 * taking phi = 0, which made a sweep's energy error that of the kinetic
 * energy alone.  With a potential (uniform E: phi = -E.x) H is exact; without
 * E no potential is needed. */
static int cb_uniform_E(double t, const double x[3], struct gcp_field_sample *out, void *ctx)
{
    cb_uniform(t, x, out, ctx);
    out->E[0] = 1e3;
    return 0;
}

Test(gc_basic, energy_needs_the_potential)
{
    const double X[3] = {1.0, 2.0, 3.0}, q = GCP_E_CHARGE, m = GCP_M_PROTON;
    const double ppar = 1e-21, mu = 1e-16;
    double H;
    struct gcp_field *fe = gcp_field_callback_create(cb_uniform_E, NULL, 1);
    cr_assert_not_null(fe);
    cr_assert_eq(gcp_gc_has_potential(fe), 0);
    cr_assert_eq(gcp_gc_energy(fe, 0, q, m, X, ppar, mu, &H), GCP_ERR_UNKNOWN);
    cr_assert(isnan(H), "H = %g with an unknown potential", H);
    gcp_field_free(fe);

    struct gcp_field *f0 = gcp_field_callback_create(cb_uniform, NULL, 0);
    cr_assert_eq(gcp_gc_has_potential(f0), 1);
    cr_assert_eq(gcp_gc_energy(f0, 0, q, m, X, ppar, mu, &H), 0);
    const double g = gcp_gc_gamma(ppar, mu, 1e-3, m);
    cr_assert(fabs(H / (g * m * GCP_C_LIGHT * GCP_C_LIGHT) - 1) < 1e-15);
    gcp_field_free(f0);

    const double B[3] = {0, 0, 1e-3}, E[3] = {1e3, 0, 0};
    struct gcp_field *fu = gcp_field_uniform_create(B, E);
    cr_assert_eq(gcp_gc_has_potential(fu), 1);
    cr_assert_eq(gcp_gc_energy(fu, 0, q, m, X, ppar, mu, &H), 0);
    const double Hex = g * m * GCP_C_LIGHT * GCP_C_LIGHT - q * E[0] * X[0]; /* phi = -E.x */
    cr_assert(fabs(H - Hex) <= 1e-15 * fabs(Hex), "H %.17g vs %.17g", H, Hex);
    gcp_field_free(fu);
}
