/* gc-midpoint-pphi (formerly gc-vi; not symplectic, see gc_midpoint_pphi.c
 * and test_gc_symplectic.c): p_phi exact by construction over long runs
 * (a property of the scheme, not a measure of its accuracy), bounded
 * energy (against gc-rk4's secular drift at the same step), and agreement
 * with a full-orbit (boris) electron started from the GC state. */
#include <criterion/criterion.h>

#include "test_gc_util.h"

struct inv_ctx {
    const struct gcp_field *f;
    double q, m, mu, H0, P0;
    int64_t n, nsteps;
    double maxP;           /* max |p_phi/p_phi0 - 1| */
    double eH_first, eH_last; /* max |H/H0 - 1| over the first and last tenth */
};

static int inv_cb(double t, const double X[3], double ppar, void *vctx)
{
    (void)t;
    struct inv_ctx *c = vctx;
    double H, P;
    gcp_gc_energy(c->f, 0, c->q, c->m, X, ppar, c->mu, &H);
    gcp_gc_pphi(c->f, 0, c->q, X, ppar, &P);
    const double eH = fabs(H / c->H0 - 1.0), eP = fabs(P / c->P0 - 1.0);
    c->maxP = fmax(c->maxP, eP);
    if (c->n < c->nsteps / 10) c->eH_first = fmax(c->eH_first, eH);
    if (c->n >= c->nsteps - c->nsteps / 10) c->eH_last = fmax(c->eH_last, eH);
    c->n++;
    return 0;
}

static void run_inv(const struct gcp_field *f, const struct gcp_pusher_type *p, double q, double m,
                    const double X0[3], double ppar0, double mu, double dt, int64_t nsteps,
                    struct inv_ctx *c)
{
    memset(c, 0, sizeof *c);
    c->f = f, c->q = q, c->m = m, c->mu = mu, c->nsteps = nsteps;
    gcp_gc_energy(f, 0, q, m, X0, ppar0, mu, &c->H0);
    gcp_gc_pphi(f, 0, q, X0, ppar0, &c->P0);
    double X[3] = {X0[0], X0[1], X0[2]}, ppar = ppar0, t = 0.0;
    const struct gcp_push_opts o = {0.0, dt, nsteps, 0.0, 0.0};
    const int st = gcp_gc_push(f, p, q, m, &o, &t, X, &ppar, mu, inv_cb, c);
    cr_assert_eq(st, GCP_ALIVE, "%s: status %d", p->name, st);
    cr_assert_eq(c->n, nsteps);
}

/* Dipole: 10 MeV proton, L = 4, a_eq = 30 deg, 50 steps per bounce period,
 * 1e5 steps (2000 bounces).  p_phi = q psi (b_phi = 0): gc-midpoint-pphi solves the
 * phi equation theta_phi(z1) = theta_phi(z0) to round-off each step:
 * ~ a few eps (2e-16) per step, a random walk: sqrt(1e5) * 4e-16 ~ 1e-13;
 * the bound 1e-12 leaves a factor 10 (a systematic 1e-17 per step would
 * still pass; a solver tolerance of 1e-15 would not).
 * Energy (not exact for gc-midpoint-pphi): bounded -- its largest error over the last
 * tenth of the run within 1.5x of that over the first tenth (issue 3);
 * gc-rk4 at the same step drifts secularly: its last-tenth error > 3x the
 * first-tenth one (measured 9.4x), and its p_phi drifts (7.7e-3).
 * Measured for gc-midpoint-pphi: p_phi 2.1e-13 (dipole), 9.3e-14 (tokamak); energy
 * error 2.0e-5 flat (dipole, 50 steps/bounce), 1.4e-11 (tokamak).
 * Tokamak (Qin & Guan-like parameters: R0 = 3 m, a = 1 m, B0 = 2.5 T,
 * q = 1.1 .. 3.5), a trapped 10 keV proton (v_par/v = 0.3 at r = 0.3 m,
 * outboard): p_phi = q psi + p_par R b_phi with b_phi != 0, same bounds. */
Test(gc_midpoint_pphi, long_run_pphi_exact_energy_bounded, .timeout = 120)
{
    struct gcp_field *dip = gcp_field_dipole_create(GC_B0, 0, 0.0, 0.0);
    struct gcp_field *tok = gcp_field_tokamak_create(2.5, 3.0, 1.0, 1.1, 3.5);
    const int64_t N = 100000;
    /* dipole */
    {
        const double q = GCP_E_CHARGE, m = GCP_M_PROTON, T = 10e6 * GCP_E_CHARGE;
        const double a = 30.0 * GCP_PI / 180.0, p = gc_p_of_T(T, m);
        const double X[3] = {4 * GC_RE, 0, 0};
        const double mu = pow(p * sin(a), 2) / (2 * m * gc_Bmag(dip, X));
        double Tb, Td, lm;
        gc_dip_theory(dip, q, m, T, 4.0, a, &Tb, &Td, &lm);
        struct inv_ctx vi, rk;
        run_inv(dip, &gcp_pusher_gc_midpoint_pphi, q, m, X, p * cos(a), mu, Tb / 50, N, &vi);
        run_inv(dip, &gcp_pusher_gc_rk4, q, m, X, p * cos(a), mu, Tb / 50, N, &rk);
        cr_log_info("dipole gc-midpoint-pphi : max |dp_phi| %.2e, |dH| first tenth %.2e last %.2e", vi.maxP,
                    vi.eH_first, vi.eH_last);
        cr_log_info("dipole gc-rk4: max |dp_phi| %.2e, |dH| first tenth %.2e last %.2e", rk.maxP,
                    rk.eH_first, rk.eH_last);
        cr_expect(vi.maxP <= 1e-12, "gc-midpoint-pphi p_phi drift %.3e", vi.maxP);
        cr_expect(vi.eH_last <= 1.5 * vi.eH_first, "gc-midpoint-pphi energy not bounded: %.3e vs %.3e",
                  vi.eH_last, vi.eH_first);
        cr_expect(rk.eH_last > 3.0 * rk.eH_first, "gc-rk4 energy drift not secular? %.3e vs %.3e",
                  rk.eH_last, rk.eH_first);
        cr_expect(rk.maxP > 100 * vi.maxP, "gc-rk4 p_phi %.3e vs gc-midpoint-pphi %.3e", rk.maxP, vi.maxP);
    }
    /* tokamak banana */
    {
        const double q = GCP_E_CHARGE, m = GCP_M_PROTON, p = gc_p_of_T(10e3 * GCP_E_CHARGE, m);
        const double X[3] = {3.3, 0, 0};
        const double ppar = 0.3 * p;
        const double mu = (p * p - ppar * ppar) / (2 * m * gc_Bmag(tok, X));
        struct inv_ctx vi;
        run_inv(tok, &gcp_pusher_gc_midpoint_pphi, q, m, X, ppar, mu, 2e-7, N / 2, &vi);
        cr_log_info("tokamak gc-midpoint-pphi: max |dp_phi| %.2e, |dH| first tenth %.2e last %.2e", vi.maxP,
                    vi.eH_first, vi.eH_last);
        cr_expect(vi.maxP <= 1e-12, "tokamak gc-midpoint-pphi p_phi drift %.3e", vi.maxP);
        cr_expect(vi.eH_last <= 1.5 * vi.eH_first, "tokamak gc-midpoint-pphi energy: %.3e vs %.3e",
                  vi.eH_last, vi.eH_first);
    }
    gcp_field_free(dip);
    gcp_field_free(tok);
}

/* ---- full orbit vs guiding centre ----
 * 1 MeV electron, L = 4, a_eq = 30 deg: GC state at the equator, its
 * full-orbit particle from gcp_fo_from_gc (gyrophase 0), pushed with boris at
 * dt = T_g(mirror)/32 for 3 bounces.  The FO guiding centre, from
 * gcp_gc_from_fo at every step, crosses the equator upward at times t_k
 * (linear interpolation: dt/T_b ~ 5e-6, error ~(dt/T_b)^2); bounce period
 * t_3/3 and drift rate phi_gc(t_3)/t_3 against gc-midpoint-pphi's (1000 steps per
 * bounce).  Differences: the initial mu of the FO particle differs from
 * the GC one at O(eps) = O(rho/L_B) ~ 1e-3 (first-order transformation;
 * T_b depends on mu through y = sin a_eq with d ln T_b/d ln mu ~ -0.15),
 * the FO-GC dynamics at O(eps^2), boris' O((omega_c dt)^2) ~ 4e-2 error on
 * the gyro motion averages out to ~1e-5 on the bounce motion: 1e-3 (issue 3)
 * holds (measured: 4.9e-4 bounce, 2.8e-4 drift rate; gc-midpoint-pphi itself is within
 * 2e-6 of the theory, so the difference is the full orbit's O(eps)). */
struct fo_ctx {
    const struct gcp_field *f;
    double q, m, tprev, Zprev, phiprev, unwrap;
    int nc;
    double tc[3], phic[3];
};

static int fo_cb(double t, const double x[3], const double u[3], void *vctx)
{
    struct fo_ctx *c = vctx;
    double X[3], ppar, mu;
    gcp_gc_from_fo(c->f, t, c->q, c->m, x, u, X, &ppar, &mu);
    double phi = atan2(X[1], X[0]) + c->unwrap;
    if (phi - c->phiprev > GCP_PI) c->unwrap -= 2 * GCP_PI, phi -= 2 * GCP_PI;
    if (phi - c->phiprev < -GCP_PI) c->unwrap += 2 * GCP_PI, phi += 2 * GCP_PI;
    if (c->Zprev < 0.0 && X[2] >= 0.0 && c->nc < 3) {
        const double s = c->Zprev / (c->Zprev - X[2]);
        c->tc[c->nc] = c->tprev + s * (t - c->tprev);
        c->phic[c->nc] = c->phiprev + s * (phi - c->phiprev);
        c->nc++;
    }
    c->tprev = t, c->Zprev = X[2], c->phiprev = phi;
    return c->nc >= 3;
}

Test(gc_midpoint_pphi, boris_full_orbit_agrees, .timeout = 120)
{
    struct gcp_field *f = gcp_field_dipole_create(GC_B0, 0, 0.0, 0.0);
    const double q = -GCP_E_CHARGE, m = GCP_M_ELECTRON, T = 1e6 * GCP_E_CHARGE;
    const double a = 30.0 * GCP_PI / 180.0, p = gc_p_of_T(T, m);
    const double X0[3] = {4 * GC_RE, 0, 0};
    const double Beq = gc_Bmag(f, X0);
    const double mu = pow(p * sin(a), 2) / (2 * m * Beq);
    double Tb, Td, lm;
    gc_dip_theory(f, q, m, T, 4.0, a, &Tb, &Td, &lm);
    /* gc-midpoint-pphi */
    double X[3] = {X0[0], X0[1], X0[2]}, ppar = p * cos(a), t = 0.0;
    struct gc_rec r = {.f = f, .q = q, .m = m, .mu = mu};
    gc_rec_add(&r, 0.0, X, ppar);
    const struct gcp_push_opts o = {0.0, Tb / 1000, 3250, 0.0, 0.0};
    cr_assert_eq(gcp_gc_push(f, &gcp_pusher_gc_midpoint_pphi, q, m, &o, &t, X, &ppar, mu, gc_rec_cb, &r), 0);
    double tc[3], phic[3];
    cr_assert_eq(gc_rec_crossings(&r, 3, tc, phic), 3);
    gc_rec_free(&r);
    /* boris */
    double x[3], u[3];
    cr_assert_eq(gcp_fo_from_gc(f, 0, q, m, X0, p * cos(a), mu, 0.0, x, u), 0);
    const double gamma = gcp_gamma_of_u(u[0], u[1], u[2]);
    const double Tg_min = 2 * GCP_PI * gamma * m / (fabs(q) * Beq / (sin(a) * sin(a)));
    const double dt = Tg_min / 32;
    struct fo_ctx c = {f, q, m, 0.0, -1.0, 0.0, 0.0, 0, {0}, {0}};
    {
        double Xg[3], pp, mm;
        gcp_gc_from_fo(f, 0, q, m, x, u, Xg, &pp, &mm);
        c.Zprev = Xg[2], c.phiprev = atan2(Xg[1], Xg[0]);
        /* the GC starts on the equator going up: the first upward crossing
         * is at t = 0; the FO GC may start a hair below or above */
    }
    double tf = 0.0;
    const int64_t nmax = (int64_t)(3.3 * Tb / dt);
    const int st = gcp_orbit_push(f, &gcp_pusher_boris, q, m, &tf, x, u, dt, nmax, fo_cb, &c);
    cr_assert_eq(st, GCP_ALIVE);
    cr_assert_geq(c.nc, 3, "FO crossings %d", c.nc);
    /* if the FO GC started just below the equator, its first crossing is
     * the t = 0 one: use the last two or three intervals accordingly */
    const int k0 = c.tc[0] < 0.5 * Tb ? 0 : -1;
    const double t0 = k0 == 0 ? c.tc[0] : 0.0, phi0 = k0 == 0 ? c.phic[0] : 0.0;
    const int nb = k0 == 0 ? 2 : 3;
    const double Tb_fo = (c.tc[2] - t0) / nb;
    const double w_fo = (c.phic[2] - phi0) / (c.tc[2] - t0);
    const double Tb_vi = tc[2] / 3, w_vi = phic[2] / tc[2];
    cr_log_info("bounce: boris %.9e gc-midpoint-pphi %.9e theory %.9e (rel %.2e)", Tb_fo, Tb_vi, Tb,
                Tb_fo / Tb_vi - 1);
    cr_log_info("drift rate: boris %.9e gc-midpoint-pphi %.9e theory %.9e rad/s (rel %.2e)", w_fo, w_vi,
                2 * GCP_PI / Td, w_fo / w_vi - 1);
    cr_expect(fabs(Tb_fo / Tb_vi - 1) < 1e-3, "bounce period boris %.9e vs gc-midpoint-pphi %.9e", Tb_fo,
              Tb_vi);
    cr_expect(fabs(w_fo / w_vi - 1) < 1e-3, "drift rate boris %.9e vs gc-midpoint-pphi %.9e", w_fo, w_vi);
    gcp_field_free(f);
}

/* 1e7 steps (issue 3's title): the same 10 MeV proton at L = 4, a_eq = 30
 * deg, 50 steps per bounce, 2e5 bounces (~2e3 drift orbits) in one push.
 * p_phi: the Newton solve leaves each step's phi equation satisfied to
 * ~1e-18 relative, and these residuals do not cancel: the 1e5-step run
 * above measures 2.1e-13, i.e. ~2e-18 per step growing linearly, which
 * predicts 2e-11 at 1e7 steps (measured 2.6e-11).  The bound 1e-10 allows
 * 4x that; a truncation-level drift (gc-rk4: ~8e-8 per step here) fails it
 * by twelve orders of magnitude.  Energy: gc-midpoint-pphi's error oscillates
 * in a band of ~2e-5 at this step (the 1e5-step test above), with no
 * secular part, so after 1e7 steps it must still be inside 5e-5 (a drift of
 * even 1e-11 per step would reach 1e-4).  mu is a constant of the scheme. */
Test(gc_midpoint_pphi, ten_million_steps_invariants_held)
{
    struct gcp_field *dip = gcp_field_dipole_create(GC_B0, 0, 0.0, 0.0);
    const double q = GCP_E_CHARGE, m = GCP_M_PROTON, T = 10e6 * GCP_E_CHARGE;
    const double a = 30.0 * GCP_PI / 180.0, p = gc_p_of_T(T, m);
    double X[3] = {4 * GC_RE, 0, 0};
    const double mu = pow(p * sin(a), 2) / (2 * m * gc_Bmag(dip, X));
    double Tb, Td, lm;
    gc_dip_theory(dip, q, m, T, 4.0, a, &Tb, &Td, &lm);
    double ppar = p * cos(a), t = 0.0, H0, H1, P0, P1;
    gcp_gc_energy(dip, 0, q, m, X, ppar, mu, &H0);
    gcp_gc_pphi(dip, 0, q, X, ppar, &P0);
    const int64_t N = 10000000;
    const struct gcp_push_opts o = {0.0, Tb / 50, N, 0.0, 0.0};
    const int st = gcp_gc_push(dip, &gcp_pusher_gc_midpoint_pphi, q, m, &o, &t, X, &ppar, mu, NULL, NULL);
    cr_assert_eq(st, GCP_ALIVE, "status %d", st);
    cr_assert_float_eq(t, N * (Tb / 50), 1e-9 * t);
    gcp_gc_energy(dip, 0, q, m, X, ppar, mu, &H1);
    gcp_gc_pphi(dip, 0, q, X, ppar, &P1);
    cr_log_info("gc-midpoint-pphi 1e7 steps: |dp_phi| %.2e, |dH| %.2e, drift orbits %.0f", fabs(P1 / P0 - 1),
                fabs(H1 / H0 - 1), t / Td);
    cr_expect(fabs(P1 / P0 - 1) <= 1e-10, "p_phi drift %.3e after 1e7 steps", fabs(P1 / P0 - 1));
    cr_expect(fabs(H1 / H0 - 1) <= 5e-5, "energy error %.3e after 1e7 steps", fabs(H1 / H0 - 1));
    gcp_field_free(dip);
}
