/* gc-gl2 / gc-gl4 in the analytic tokamak: the closed-form solve of
 * src/pushers/gc_gauss_tokamak.c against the generic flux-chart path
 * (gc_gauss_wlift.c through canon_flux.c; gcp_gl_tokamak_off = 1 sends the
 * push there).  Both solve the same Gauss-Legendre equations in the same
 * canonical coordinates; what separates their ends after N steps is how
 * far each stops from the exact solve at every step, summed (a bounded
 * orbit of a symplectic map does not amplify a perturbation exponentially).
 *
 * Tolerances.
 *  - fused against the fused solve iterated 3 times past convergence
 *    (gcp_gl_tokamak_extra: converged to round-off): the fused solve stops
 *    at an update of 1e-15 of the scales, or one predicted below 1e-18, and
 *    linearises phi's rate to its last update, so per step it is ~1e-15 of
 *    the scales off: N 1e-15 (R0 + a) in X, N 1e-15 p in p_par, times 4
 *    (the update's norm is a max over components and stages).
 *  - fused against generic: the generic solve accepts a step whose update
 *    stalls at its round-off floor GLW_FLOOR = 1e-12 of the scales (and its
 *    phi quadrature takes the stage rates of the iterate before that last
 *    update), so per step it may be 1e-12 of the scales off: N 1e-12 (R0 +
 *    a), N 1e-12 p.  (Measured, N = 2000 in the banana: 1.4e-9 m generic
 *    against the converged map for gc-gl2, 2.4e-13 m fused.)
 * That the check can fail: gc-gl2 against gc-gl4 after the same N steps
 * (another map, O(h^2) apart) differ by more than 1e3 times the tolerance. */
#include <criterion/criterion.h>

#include "test_gc_util.h"

extern int gcp_gl_tokamak_off, gcp_gl_tokamak_extra;

#define NSTEP 2000

struct tcase {
    const char *name;
    double B0, R0, a, q0, qa; /* the tokamak */
    double q, T, xi, R;       /* a particle on the outboard midplane */
};

/* the end of N steps of method p from the case's start, fused or generic */
static void run(const struct tcase *c, struct gcp_field *f, const struct gcp_pusher_type *p,
                double h, int generic, int extra, double X[3], double *pp, double mu)
{
    const double p0 = gc_p_of_T(c->T, GCP_M_PROTON);
    X[0] = c->R, X[1] = 0.0, X[2] = 0.0;
    *pp = p0 * c->xi;
    double t = 0.0;
    const struct gcp_push_opts o = {0.0, h, NSTEP, 0.0, 0.0};
    gcp_gl_tokamak_off = generic, gcp_gl_tokamak_extra = extra;
    const int st = gcp_gc_push(f, p, c->q, GCP_M_PROTON, &o, &t, X, pp, mu, NULL, NULL);
    gcp_gl_tokamak_off = 0, gcp_gl_tokamak_extra = 0;
    cr_assert_eq(st, 0, "%s %s: status %d", c->name, p->name, st);
}

static void check_case(const struct tcase *c)
{
    struct gcp_field *f = gcp_field_tokamak_create(c->B0, c->R0, c->a, c->q0, c->qa);
    const double p0 = gc_p_of_T(c->T, GCP_M_PROTON);
    const double X0[3] = {c->R, 0.0, 0.0};
    const double mu = p0 * p0 * (1 - c->xi * c->xi) / (2 * GCP_M_PROTON * gc_Bmag(f, X0));
    const double Tb = gc_bounce_period(f, c->q, GCP_M_PROTON, mu, X0, p0 * c->xi,
                                       gc_tokamak_tb_guess(c->R, p0, GCP_M_PROTON));
    cr_assert(isfinite(Tb), "%s: no bounce or transit", c->name);
    const double h = Tb / 25.37;
    const double tolX = NSTEP * 1e-12 * (c->R0 + c->a), tolp = NSTEP * 1e-12 * p0;
    const double tcX = 4.0 * NSTEP * 1e-15 * (c->R0 + c->a), tcp = 4.0 * NSTEP * 1e-15 * p0;
    const struct gcp_pusher_type *ps[2] = {&gcp_pusher_gc_gl2, &gcp_pusher_gc_gl4};
    double Xe[2][3], pe[2];
    for (int k = 0; k < 2; k++) {
        double Xf[3], pf, Xg[3], pg, Xt[3], pt;
        run(c, f, ps[k], h, 0, 0, Xf, &pf, mu);
        run(c, f, ps[k], h, 1, 0, Xg, &pg, mu);
        run(c, f, ps[k], h, 0, 3, Xt, &pt, mu);
        const double dX = hypot(hypot(Xf[0] - Xg[0], Xf[1] - Xg[1]), Xf[2] - Xg[2]);
        const double dp = fabs(pf - pg);
        const double cX = hypot(hypot(Xf[0] - Xt[0], Xf[1] - Xt[1]), Xf[2] - Xt[2]);
        const double cp = fabs(pf - pt);
        cr_log_info("%s %s: fused - generic |dX| %.2e m (%.3f of tol), |dp| %.2e of tol; "
                    "fused - converged |dX| %.2e m (%.3f of tol), |dp| %.2e of tol",
                    c->name, ps[k]->name, dX, dX / tolX, dp / tolp, cX, cX / tcX, cp / tcp);
        cr_expect(dX <= tolX, "%s %s: fused and generic %.3e m apart (tolerance %.1e)", c->name,
                  ps[k]->name, dX, tolX);
        cr_expect(dp <= tolp, "%s %s: p_par %.3e apart (tolerance %.1e)", c->name, ps[k]->name,
                  dp, tolp);
        cr_expect(cX <= tcX, "%s %s: fused and converged %.3e m apart (tolerance %.1e)", c->name,
                  ps[k]->name, cX, tcX);
        cr_expect(cp <= tcp, "%s %s: p_par %.3e from converged (tolerance %.1e)", c->name,
                  ps[k]->name, cp, tcp);
        /* the fused path ran: its last bits are its own */
        cr_expect(dX > 0.0 || dp > 0.0, "%s %s: bit-identical to the generic path", c->name,
                  ps[k]->name);
        memcpy(Xe[k], Xf, sizeof Xf), pe[k] = pf;
    }
    const double d24 = hypot(hypot(Xe[0][0] - Xe[1][0], Xe[0][1] - Xe[1][1]), Xe[0][2] - Xe[1][2]);
    cr_expect(d24 > 1e3 * tolX || fabs(pe[0] - pe[1]) > 1e3 * tolp,
              "%s: gc-gl2 and gc-gl4 only %.2e m apart: the check would not see another map",
              c->name, d24);
    gcp_field_free(f);
}

/* bench_flux's and test_gc_symplectic_flux.c's banana: 100 keV proton at
 * r = 0.5 m, v_par/v = 0.3 */
Test(gc_gauss_tokamak, banana_matches_generic, .timeout = 120)
{
    const struct tcase c = {"banana", 2.5, 3.0, 1.0, 1.1, 3.5, GCP_E_CHARGE, 1e5 * GCP_E_CHARGE,
                            0.3, 3.5};
    check_case(&c);
}

/* the field and the charge reversed (the sign of every term of the chart)
 * and a flat q (dq = 0: psi's series at e = 0) */
Test(gc_gauss_tokamak, reversed_flat_q_matches_generic, .timeout = 120)
{
    const struct tcase c = {"B0 < 0, q < 0, flat q", -2.0, 3.0, 1.0, 2.0, 2.0, -GCP_E_CHARGE,
                            5e4 * GCP_E_CHARGE, 0.4, 3.4};
    check_case(&c);
}

/* a fat plasma (a/R0 = 2/3): where |r cos(theta)|/R0 >= 1/4 the series of
 * the closed form do not hold and the generic path takes the step, so the
 * orbit alternates between the two (measured: 920 of the 2000 gc-gl2 steps
 * fused, 1080 generic) */
Test(gc_gauss_tokamak, fat_plasma_mixed_paths_match_generic, .timeout = 120)
{
    const struct tcase c = {"fat plasma", 1.5, 1.5, 1.0, 1.1, 3.0, GCP_E_CHARGE,
                            3e4 * GCP_E_CHARGE, 0.4, 2.0};
    check_case(&c);
}
