/* Guiding centres in Earth's dipole against GC theory by quadrature, over
 * the battery of GC pushers (the accuracy of the symplectic gc-gl2 and
 * gc-gl4 at their orders included: structure is not accuracy); and the
 * order of convergence of the fixed-step methods against a gc-rk8pd
 * reference.
 *
 * Why the textbook bounce and drift periods are *exact* consequences of the
 * first-order GC equations with B* in a vacuum dipole (so the 1e-6
 * comparison is meaningful, with no O(rho/L)^2 theory gap):
 *  - b lies in the meridional plane and the field is axisymmetric, so
 *    curl b = (curl B)/B + b x grad B / B is along phihat (curl B = 0), hence
 *    b.curl b = 0 and B*_par = B exactly;
 *  - grad B is meridional, so E* x b and curl b are along phihat: the
 *    meridional motion is exactly dX/dt = v_par b, and dp_par/dt =
 *    -(mu/gamma) b.grad B; gamma is constant (H = gamma m c^2), so v and y =
 *    sin a_eq (from mu) are constants and the GC runs along its field line
 *    (psi = R A_phi, i.e. L, is an exact invariant: p_phi = q psi as
 *    b_phi = 0) exactly as in the bounce integral T(y);
 *  - the azimuthal velocity is [v_par (p_par/q)(curl b)_phi + (E* x b)_phi]/B
 *    = [gamma m v_par^2 + mu B/gamma] (b x grad B)_phi / (q B^2)
 *    = p v (1 - y^2 b/2) (b x grad B)_phi / (q B^2),
 *    the textbook gradient-curvature drift with the relativistic p v factor,
 *    and the drift per bounce is its bounce average (Schulz & Lanzerotti
 *    1974, eqs. 1.28, 1.35).  In the meridional plane the motion is
 *    periodic, so one bounce gives dphi exactly; the drift period
 *    T_d = 2 pi T_b / dphi follows from a few bounces, without pushing a
 *    whole drift orbit.
 * The references (test_gc_util.h) are GSL QAG quadratures at 1e-13.
 *
 * Measured from the orbit: upward equator crossings of Z and the azimuth
 * there, interpolated with cubic Hermite polynomials from the state and the
 * GC right-hand side at the step ends (error O(h^4), ~(2 pi/N)^4/384 ~ 1e-9
 * relative at N = 200 samples per bounce), over 3 bounces; the mirror
 * latitude as the maximum of the Hermite cubic of the latitude.
 */
#include <criterion/criterion.h>

#include "test_gc_util.h"

struct case_ {
    const char *name;
    double q, m, T, a_deg;
};

static const struct case_ cases[] = {
    {"e- 1 MeV 30", -GCP_E_CHARGE, GCP_M_ELECTRON, 1e6 * GCP_E_CHARGE, 30.0},
    {"e- 1 MeV 60", -GCP_E_CHARGE, GCP_M_ELECTRON, 1e6 * GCP_E_CHARGE, 60.0},
    {"e- 1 MeV 85", -GCP_E_CHARGE, GCP_M_ELECTRON, 1e6 * GCP_E_CHARGE, 85.0},
    {"p+ 10 MeV 30", GCP_E_CHARGE, GCP_M_PROTON, 10e6 * GCP_E_CHARGE, 30.0},
    {"p+ 10 MeV 60", GCP_E_CHARGE, GCP_M_PROTON, 10e6 * GCP_E_CHARGE, 60.0},
    {"p+ 10 MeV 85", GCP_E_CHARGE, GCP_M_PROTON, 10e6 * GCP_E_CHARGE, 85.0},
};

#define L_SHELL 4.0
#define NBOUNCE 3

/* Equatorial GC start at L, pitch a: X = (L R_E, 0, 0), p_par = p cos a,
 * mu = (p sin a)^2 / (2 m B_eq). */
static void start_state(const struct gcp_field *f, const struct case_ *c, double X[3],
                        double *ppar, double *mu)
{
    X[0] = L_SHELL * GC_RE, X[1] = 0.0, X[2] = 0.0;
    const double p = gc_p_of_T(c->T, c->m), a = c->a_deg * GCP_PI / 180.0;
    *ppar = p * cos(a);
    *mu = p * sin(a) * p * sin(a) / (2.0 * c->m * gc_Bmag(f, X));
}

/* Steps per bounce period of each method for the 1e-6 comparison ("converged
 * dt"): the periods' error is ~C (2 pi/N)^p; gc-rk4 (p = 4) at N = 400 is
 * ~1e-8, gc-midpoint-pphi (p = 2) at N = 8000 ~1.6e-7 (measured at 4000:
 * 6.3e-7); gc-gl2 at 8000 measured <= 1.3e-7, gc-gl4 at 400 <= 1.8e-8 (their
 * Sundman forms the same: sampled every step, they land on every step); the
 * adaptive methods run at their tolerance (1e-11, 1e-12) and are sampled
 * N = 200 times per bounce (Hermite interpolation error ~1e-9). */
static int steps_per_bounce(const struct gcp_pusher_type *p)
{
    if (gc_is(p, "gc-rk4") || gc_is(p, "gc-gl4") || gc_is(p, "gc-gl4-sundman")) return 400;
    if (gc_is(p, "gc-midpoint-pphi") || gc_is(p, "gc-gl2") || gc_is(p, "gc-gl2-sundman"))
        return 8000;
    return 200;
}

Test(gc_dipole, periods_match_gc_theory, .timeout = 120)
{
    struct gcp_field *f = gcp_field_dipole_create(GC_B0, 0, 0.0, 0.0);
    cr_assert_not_null(f);
    int npush = 0;
    for (size_t ci = 0; ci < sizeof cases / sizeof cases[0]; ci++) {
        const struct case_ *c = &cases[ci];
        double Tb, Td, latm;
        gc_dip_theory(f, c->q, c->m, c->T, L_SHELL, c->a_deg * GCP_PI / 180.0, &Tb, &Td, &latm);
        cr_assert(isfinite(Tb) && isfinite(Td) && isfinite(latm), "%s: theory", c->name);
        GC_FOREACH(p)
        {
            double X[3], ppar, mu, t = 0.0;
            start_state(f, c, X, &ppar, &mu);
            const int N = steps_per_bounce(p);
            struct gcp_push_opts o = {.t0 = 0.0, .dt = Tb / N,
                                      .nsteps = (int64_t)((NBOUNCE + 0.25) * N),
                                      .tolerance = gc_is(p, "gc-rk45") ? 1e-11 : 0.0,
                                      .adiabaticity_max = 0.0};
            struct gc_rec r = {.f = f, .q = c->q, .m = c->m, .mu = mu};
            gc_rec_add(&r, 0.0, X, ppar);
            const int st = gcp_gc_push(f, p, c->q, c->m, &o, &t, X, &ppar, mu, gc_rec_cb, &r);
            cr_assert_eq(st, GCP_ALIVE, "%s %s: status %d", p->name, c->name, st);
            double tc[NBOUNCE], phic[NBOUNCE];
            const int nc = gc_rec_crossings(&r, NBOUNCE, tc, phic);
            cr_assert_eq(nc, NBOUNCE, "%s %s: %d crossings", p->name, c->name, nc);
            const double Tb_num = tc[NBOUNCE - 1] / NBOUNCE;
            const double Td_num = 2.0 * GCP_PI * tc[NBOUNCE - 1] / fabs(phic[NBOUNCE - 1]);
            const double lat_num = gc_rec_mirror_lat(&r);
            const double eb = Tb_num / Tb - 1.0, ed = Td_num / Td - 1.0, el = lat_num / latm - 1.0;
            cr_log_info("%-8s %-13s Tb %.6e rel %+.2e  Td %.6e rel %+.2e  lat_m %.4f deg rel %+.2e",
                        p->name, c->name, Tb, eb, Td, ed, latm * 180.0 / GCP_PI, el);
            /* 1e-6 relative (issue 3); the measured errors are ~1e-8..1e-7 */
            cr_expect(fabs(eb) < 1e-6, "%s %s: bounce period %.10e vs %.10e (%.2e)", p->name,
                      c->name, Tb_num, Tb, eb);
            cr_expect(fabs(ed) < 1e-6, "%s %s: drift period %.10e vs %.10e (%.2e)", p->name,
                      c->name, Td_num, Td, ed);
            cr_expect(fabs(el) < 1e-6, "%s %s: mirror latitude %.10e vs %.10e (%.2e)", p->name,
                      c->name, lat_num, latm, el);
            /* electrons drift east (+phi), protons west, in this dipole */
            cr_expect((phic[0] > 0) == (c->q < 0), "%s %s: drift direction", p->name, c->name);
            gc_rec_free(&r);
            npush++;
        }
    }
    cr_assert_geq(npush, 4 * 6, "battery has %d pushes", npush);
    gcp_field_free(f);
}

/* ---- order of convergence ----
 * 10 MeV proton, L = 4, a_eq = 30 deg, pushed for 1/2 bounce period T_b
 * (through the mirror point, where the dynamics is least smooth) with
 * N and 2N steps; error = max(|X - X_ref|/(L R_E), |p_par - p_ref|/p) against
 * gc-rk8pd at 1e-12 (its own error ~1e-12, far below the errors measured,
 * >= 1e-9).  The ratio e(N)/e(2N) -> 2^p; within 10% needs the next term of
 * the error expansion (relative size ~ C' h) below ~5%: N = 64 (rk4,
 * midpoint-pphi, gl2) and 32 (gl4) steps per half bounce were measured to be
 * in the asymptotic range (ratios 15.94, 4.00, 4.05, 16.07). */
static double run_err(const struct gcp_field *f, const struct gcp_pusher_type *p, int nsteps,
                      double Thalf, const double Xr[3], double pr, double *Xout)
{
    const struct case_ *c = &cases[3];
    double X[3], ppar, mu, t = 0.0;
    start_state(f, c, X, &ppar, &mu);
    struct gcp_push_opts o = {0.0, Thalf / nsteps, nsteps, 0.0, 0.0};
    const int st = gcp_gc_push(f, p, c->q, c->m, &o, &t, X, &ppar, mu, NULL, NULL);
    cr_assert_eq(st, GCP_ALIVE);
    if (Xout) memcpy(Xout, X, sizeof X), Xout[3] = ppar;
    if (!Xr) return 0.0;
    const double pt = gc_p_of_T(c->T, c->m);
    double e = fabs(ppar - pr) / pt;
    for (int d = 0; d < 3; d++) e = fmax(e, fabs(X[d] - Xr[d]) / (L_SHELL * GC_RE));
    return e;
}

Test(gc_dipole, order_of_convergence)
{
    struct gcp_field *f = gcp_field_dipole_create(GC_B0, 0, 0.0, 0.0);
    const struct case_ *c = &cases[3];
    double Tb, Td, latm;
    gc_dip_theory(f, c->q, c->m, c->T, L_SHELL, c->a_deg * GCP_PI / 180.0, &Tb, &Td, &latm);
    const double Th = 0.5 * Tb;
    double ref[4];
    run_err(f, &gcp_pusher_gc_rk8pd, 1, Th, NULL, 0.0, ref);
    struct { const struct gcp_pusher_type *p; int N; double order; } m[] = {
        {&gcp_pusher_gc_rk4, 64, 4.0}, {&gcp_pusher_gc_midpoint_pphi, 64, 2.0},
        {&gcp_pusher_gc_gl2, 64, 2.0}, {&gcp_pusher_gc_gl4, 32, 4.0}};
    for (int k = 0; k < 4; k++) {
        const double e1 = run_err(f, m[k].p, m[k].N, Th, ref, ref[3], NULL);
        const double e2 = run_err(f, m[k].p, 2 * m[k].N, Th, ref, ref[3], NULL);
        const double ratio = e1 / e2, want = pow(2.0, m[k].order);
        cr_log_info("%s: e(N=%d) %.3e e(2N) %.3e ratio %.3f (want %.0f)", m[k].p->name, m[k].N,
                    e1, e2, ratio, want);
        cr_expect(e2 > 1e3 * 1e-12, "%s: error %.2e too close to the reference's", m[k].p->name, e2);
        cr_expect(fabs(ratio / want - 1.0) < 0.1, "%s: ratio %.3f, want %.0f +- 10%%",
                  m[k].p->name, ratio, want);
    }
    gcp_field_free(f);
}

/* ---- adaptive steps follow the tolerance, not the output cadence -------- */

struct cad_rec {
    int64_t n;
    double t[4096], X[4096][3], p[4096];
};

static void cad_sample(const struct gcp_block *b, double t, void *ctx)
{
    struct cad_rec *r = ctx;
    if (b->n_active < 1 || r->n >= 4096) return;
    r->t[r->n] = t;
    r->X[r->n][0] = b->x[0], r->X[r->n][1] = b->y[0], r->X[r->n][2] = b->z[0];
    r->p[r->n] = b->ppar[0];
    r->n++;
}

/* One lane through p->advance in one call: nsteps sampling intervals of dt,
 * with a sampler every interval (r) or none (r = NULL).  Returns the
 * accepted steps; X, ppar the final state. */
static int64_t cad_run(const struct gcp_field *f, const struct gcp_pusher_type *p, double tol,
                       double dt, int64_t nsteps, const struct case_ *c, struct cad_rec *r,
                       double X[3], double *ppar)
{
    double mu;
    start_state(f, c, X, ppar, &mu);
    struct gcp_block b;
    cr_assert_eq(gcp_block_alloc(&b, 1), 0);
    b.q = c->q, b.m = c->m;
    b.x[0] = X[0], b.y[0] = X[1], b.z[0] = X[2], b.ppar[0] = *ppar, b.mu[0] = mu;
    b.t[0] = 0, b.status[0] = 0, b.steps[0] = 0, b.n_active = 1;
    const struct gcp_push_opts o = {.t0 = 0, .dt = dt, .nsteps = nsteps, .tolerance = tol};
    const struct gcp_sampler s = {1, cad_sample, r};
    p->advance(&b, f, p, &o, r ? &s : NULL);
    cr_assert_eq(b.status[0], GCP_ALIVE);
    X[0] = b.x[0], X[1] = b.y[0], X[2] = b.z[0], *ppar = b.ppar[0];
    const int64_t k = b.steps[0];
    gcp_block_free(&b);
    return k;
}

/* gc-rk45 (tolerance 1e-8) over two bounces of a 10 MeV proton, sampled
 * every 1/400 bounce -- finer than the steps the tolerance asks for:
 * (1) the accepted steps are those of the run without samples, exactly
 * (the same step sequence: issue 13; before, every sample ended a step and
 * the run took one step per sample at least), and so is the final state;
 * (2) the samples, each one extra step of the stepper out of the accepted
 * step that contains its time, agree with gc-rk8pd at 1e-12 sampled the
 * same way to the tolerance's scale: 1e-6 of the orbit size and of the
 * momentum (the global error of rk45 at 1e-8 over ~100 steps, measured
 * 1e-7). */
Test(gc_dipole, adaptive_steps_ignore_the_cadence)
{
    struct gcp_field *f = gcp_field_dipole_create(GC_B0, 0, 0.0, 0.0);
    const struct case_ *c = &cases[4]; /* p+ 10 MeV 60 deg */
    double Tb, Td, lm;
    gc_dip_theory(f, c->q, c->m, c->T, L_SHELL, c->a_deg * GCP_PI / 180.0, &Tb, &Td, &lm);
    const int64_t ns = 800;
    const double dt = 2 * Tb / ns;
    static struct cad_rec r1, r2;
    double X0[3], p0, X1[3], p1, X2[3], p2;
    const int64_t k0 = cad_run(f, &gcp_pusher_gc_rk45, 1e-8, dt, ns, c, NULL, X0, &p0);
    r1.n = r2.n = 0;
    const int64_t k1 = cad_run(f, &gcp_pusher_gc_rk45, 1e-8, dt, ns, c, &r1, X1, &p1);
    cad_run(f, &gcp_pusher_gc_rk8pd, 1e-12, dt, ns, c, &r2, X2, &p2);
    cr_log_info("gc-rk45 1e-8: %lld steps without samples, %lld with %lld samples",
                (long long)k0, (long long)k1, (long long)r1.n);
    cr_assert_eq(k1, k0, "steps with samples %lld, without %lld", (long long)k1, (long long)k0);
    cr_assert_lt(k0, ns / 2, "the tolerance should need fewer steps than samples (%lld)",
                 (long long)k0);
    cr_assert(X1[0] == X0[0] && X1[1] == X0[1] && X1[2] == X0[2] && p1 == p0,
              "the final state depends on the sampling");
    cr_assert_eq(r1.n, ns);
    cr_assert_eq(r2.n, ns);
    const double Ls = L_SHELL * GC_RE, P = gc_p_of_T(c->T, c->m);
    double ex = 0, ep = 0;
    for (int64_t j = 0; j < ns; j++) {
        cr_assert_eq(r1.t[j], r2.t[j]);
        for (int d = 0; d < 3; d++) ex = fmax(ex, fabs(r1.X[j][d] - r2.X[j][d]) / Ls);
        ep = fmax(ep, fabs(r1.p[j] - r2.p[j]) / P);
    }
    cr_log_info("samples vs gc-rk8pd: %.2e of the orbit, %.2e of p", ex, ep);
    cr_assert(ex < 1e-6 && ep < 1e-6, "samples off by %.3g (X) %.3g (p_par)", ex, ep);
    gcp_field_free(f);
}
