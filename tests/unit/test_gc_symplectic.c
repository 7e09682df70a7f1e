/* The symplectic guiding-centre integrators gc-gl2 and gc-gl4 (issue 11)
 * and the curl-free canonical chart they run in (src/pushers/canon_*.c).
 *
 * Every measurement is made in the canonical coordinates
 * z = (phi, chi, P_phi, P_chi) of the chart, for every method alike: a
 * method's one-step map z0 -> z1 is
 *   z0 --from_canon--> (X, p_par) --one step of the method--> --to_canon--> z1,
 * and since the chart is a symplectic map between (X, p_par) with the
 * guiding-centre two-form d theta and z with dP ^ dq (theta = P_phi dphi +
 * P_chi dchi), a method is symplectic for the guiding centre exactly when
 * this map satisfies M^T J M = J.  So gc-rk4 and gc-midpoint-pphi, which
 * work in (X, p_par), are measured on the same footing as gc-gl2/gl4.
 */
#include <criterion/criterion.h>

#include "pushers/canon_priv.h"
#include "pushers/gc_gauss_priv.h"
#include "test_gc_util.h"

/* ---- set-ups ---- */

struct sys {
    const char *name;
    struct gcp_field *f;
    struct gcp_gc_consts k;
    double X[3], ppar;
    double Tb; /* [s] bounce period (quadrature for the dipole, estimate for the mirror) */
};

/* Dipole, equatorial start at L = 4 with equatorial pitch a. */
static void sys_dipole(struct sys *s, const char *name, double q, double m, double T, double a)
{
    s->name = name;
    s->f = gcp_field_dipole_create(GC_B0, 0, 0.0, 0.0);
    cr_assert_not_null(s->f);
    s->X[0] = 4.0 * GC_RE, s->X[1] = 0.0, s->X[2] = 0.0;
    const double p = gc_p_of_T(T, m);
    s->ppar = p * cos(a);
    s->k = (struct gcp_gc_consts){q, m, p * sin(a) * p * sin(a) / (2.0 * m * gc_Bmag(s->f, s->X))};
    double Td, latm;
    gc_dip_theory(s->f, q, m, T, 4.0, a, &s->Tb, &Td, &latm);
}

/* Mirror B0 = 1 T, Lm = 1 m; 1 MeV electron at R = 5 cm, pitch 45 deg
 * (gyroradius 3 mm; an electron, not a keV proton, so that the kinetic
 * energy is not at the round-off of the rest energy in H = gamma m c^2).
 * Near the centre |B| ~ B0 (1 + z^2/Lm^2), so the bounce is nearly harmonic
 * with omega_b^2 = 2 mu B0 / (gamma m Lm^2) = v_perp^2 / Lm^2. */
static void sys_mirror(struct sys *s)
{
    s->name = "mirror e- 1 MeV";
    s->f = gcp_field_mirror_create(1.0, 1.0, 0.0, 0.0);
    cr_assert_not_null(s->f);
    const double m = GCP_M_ELECTRON, a = 45.0 * GCP_PI / 180.0;
    const double T = 1e6 * GCP_E_CHARGE, p = gc_p_of_T(T, m);
    const double gamma = 1.0 + T / (m * GC_C * GC_C);
    s->X[0] = 0.05, s->X[1] = 0.0, s->X[2] = 0.0;
    s->ppar = p * cos(a);
    s->k = (struct gcp_gc_consts){-GCP_E_CHARGE, m,
                                  p * sin(a) * p * sin(a) / (2.0 * m * gc_Bmag(s->f, s->X))};
    s->Tb = 2.0 * GCP_PI * 1.0 / (p * sin(a) / (gamma * m));
}

static void sys_free(struct sys *s) { gcp_field_free(s->f); }

/* ---- the chart ---- */

/* to_canon then from_canon gives X, p_par back (Newton inversion to
 * round-off: 1e-13 relative allows ~500 ulp for the Newton's last update and
 * the cancellation in psi near the axis), and dH/dz matches central
 * differences of H (step 1e-5 of each scale: truncation ~1e-10, round-off
 * 1e-16/1e-5 = 1e-11 relative; 1e-7 asserted). */
Test(gc_symplectic, chart_roundtrip_and_gradient)
{
    struct sys S[2];
    sys_dipole(&S[0], "dipole e- 1 MeV", -GCP_E_CHARGE, GCP_M_ELECTRON, 1e6 * GCP_E_CHARGE, 0.5);
    sys_mirror(&S[1]);
    for (int c = 0; c < 2; c++) {
        struct gcp_canon_chart ch;
        char why[256];
        cr_assert_eq(gcp_canon_chart_create(S[c].f, &ch, why, sizeof why), 0, "%s", why);
        cr_expect_str_eq(ch.name, "curl-free");
        /* off the equator, off the x axis */
        const double X0[3] = {0.8 * S[c].X[0], 0.3 * S[c].X[0], 0.2 * S[c].X[0]};
        double z[4], aux[2], X[3], pp;
        cr_assert_eq(ch.to_canon(&ch, &S[c].k, X0, S[c].ppar, z, aux), 0);
        aux[0] *= 1.01, aux[1] *= 0.99; /* a poorer guess, to exercise the Newton */
        cr_assert_eq(ch.from_canon(&ch, &S[c].k, z, aux, X, &pp), 0);
        for (int d = 0; d < 3; d++)
            cr_expect(fabs(X[d] - X0[d]) < 1e-13 * S[c].X[0], "%s: X[%d] %.17g vs %.17g",
                      S[c].name, d, X[d], X0[d]);
        cr_expect(fabs(pp - S[c].ppar) < 1e-13 * fabs(S[c].ppar), "%s: p_par", S[c].name);
        double H, dH[4];
        cr_assert_eq(ch.hamiltonian(&ch, &S[c].k, z, aux, &H, dH), 0);
        /* H is the guiding-centre energy gamma m c^2 */
        double E;
        gcp_gc_energy(S[c].f, 0.0, S[c].k.q, S[c].k.m, X0, S[c].ppar, S[c].k.mu, &E);
        cr_expect(fabs(H / E - 1.0) < 1e-14, "%s: H %.17g vs energy %.17g", S[c].name, H, E);
        const double sc[4] = {1.0, fabs(z[1]) + 1e-3 * fabs(z[2] / S[c].k.q) / S[c].X[0],
                              fabs(z[2]), fabs(z[3])};
        for (int j = 1; j < 4; j++) {
            double zp[4], zm[4], Hp, Hm, g[4];
            memcpy(zp, z, sizeof zp), memcpy(zm, z, sizeof zm);
            const double e = 1e-5 * sc[j];
            zp[j] += e, zm[j] -= e;
            ch.hamiltonian(&ch, &S[c].k, zp, aux, &Hp, g);
            ch.hamiltonian(&ch, &S[c].k, zm, aux, &Hm, g);
            const double fd = (Hp - Hm) / (2.0 * e);
            /* relative to the largest rate |dH/dz_j| sc_j of the kinetic energy */
            const double scale = fabs(dH[j]) * sc[j] + 1e-3 * (H - S[c].k.m * GC_C * GC_C);
            cr_log_info("%s: dH/dz%d %.10e fd %.10e", S[c].name, j, dH[j], fd);
            cr_expect(fabs(fd - dH[j]) * sc[j] < 1e-7 * scale, "%s: dH/dz%d %.10e vs fd %.10e",
                      S[c].name, j, dH[j], fd);
        }
        gcp_canon_chart_destroy(&ch);
        sys_free(&S[c]);
    }
}

/* ---- symplecticity ---- */

/* One step of method p of size h from canonical z0, mapped back to z1. */
static int one_step(const struct sys *S, const struct gcp_canon_chart *ch,
                    const struct gcp_pusher_type *p, double h, const double z0[4], double z1[4])
{
    double aux[2] = {S->X[0], S->X[2]}, X[3], pp, t = 0.0;
    if (ch->from_canon(ch, &S->k, z0, aux, X, &pp)) return -1;
    const struct gcp_push_opts o = {0.0, h, 1, 0.0, 0.0};
    if (gcp_gc_push(S->f, p, S->k.q, S->k.m, &o, &t, X, &pp, S->k.mu, NULL, NULL)) return -1;
    if (ch->to_canon(ch, &S->k, X, pp, z1, aux)) return -1;
    /* phi continuous across the branch cut of atan2 */
    z1[0] = z0[0] + remainder(z1[0] - z0[0], 2.0 * GCP_PI);
    return 0;
}

/* |M^T J M - J| of the one-step map, by central differences, scale free:
 * with s_k a scale of each coordinate and S_pair = s_q s_p the action scale
 * of each canonical pair, entry (i, j) is weighed by s_i s_j /
 * sqrt(S_pair(i) S_pair(j)) -- the residual in coordinates where every pair
 * is scaled to a unit action, in which |J| = 1.  The difference step 1e-5
 * s_k makes the truncation error (1e-5)^2 ~ 1e-10 and the round-off (the
 * map is known to ~1e-15 relative: Newton tolerances, chart round trip)
 * 1e-15/1e-5 = 1e-10: the floor is ~1e-10, and 1e-8 is asserted for the
 * symplectic methods. */
static double sympl_residual(const struct sys *S, const struct gcp_canon_chart *ch,
                             const struct gcp_pusher_type *p, double h, const double z0[4],
                             const double sc[4])
{
    double M[4][4];
    for (int j = 0; j < 4; j++) {
        double zp[4], zm[4], z1p[4], z1m[4];
        memcpy(zp, z0, sizeof zp), memcpy(zm, z0, sizeof zm);
        const double e = 1e-5 * sc[j];
        zp[j] += e, zm[j] -= e;
        if (one_step(S, ch, p, h, zp, z1p) || one_step(S, ch, p, h, zm, z1m)) return NAN;
        for (int i = 0; i < 4; i++) M[i][j] = (z1p[i] - z1m[i]) / (zp[j] - zm[j]);
    }
    return gc_symplectic_residual(M, sc);
}

/* For each system and h = T_b / N, N = 25, 50, 100, 200 (25 to 200 steps per
 * bounce, the range a user would run), the residual of gc-gl2 and gc-gl4
 * stays at the difference floor (< 1e-8, independent of h), while gc-rk4
 * (local error h^5: residual ~ h^5, must fall >= 16x per halving, 32x
 * ideally) and the p_phi-exact midpoint scheme gc-midpoint-pphi (residual
 * h^3, >= 5x per halving, 8x ideally) are measurably not symplectic at the
 * coarsest step (> 1e-6, i.e. 100x the assertion bound): the test can fail. */
Test(gc_symplectic, one_step_map_is_symplectic, .timeout = 120)
{
    struct sys S[3];
    sys_dipole(&S[0], "dipole e- 1 MeV", -GCP_E_CHARGE, GCP_M_ELECTRON, 1e6 * GCP_E_CHARGE,
               30.0 * GCP_PI / 180.0);
    sys_dipole(&S[1], "dipole p+ 10 MeV", GCP_E_CHARGE, GCP_M_PROTON, 10e6 * GCP_E_CHARGE,
               30.0 * GCP_PI / 180.0);
    sys_mirror(&S[2]);
    const struct gcp_pusher_type *sym[] = {&gcp_pusher_gc_gl2, &gcp_pusher_gc_gl4};
    const struct gcp_pusher_type *non[] = {&gcp_pusher_gc_rk4, &gcp_pusher_gc_midpoint_pphi};
    const double non_order[] = {5.0, 3.0}, non_min_ratio[] = {16.0, 5.0};
    for (int c = 0; c < 3; c++) {
        struct gcp_canon_chart ch;
        char why[256];
        cr_assert_eq(gcp_canon_chart_create(S[c].f, &ch, why, sizeof why), 0, "%s", why);
        /* start off the equator (a quarter of the way to the mirror point
         * by time), so that every coordinate moves */
        double X[3] = {S[c].X[0], S[c].X[1], S[c].X[2]}, pp = S[c].ppar, t = 0.0;
        const struct gcp_push_opts o = {0.0, S[c].Tb / 400, 40, 0.0, 0.0};
        cr_assert_eq(gcp_gc_push(S[c].f, &gcp_pusher_gc_rk8pd, S[c].k.q, S[c].k.m, &o, &t, X,
                                 &pp, S[c].k.mu, NULL, NULL), 0);
        double z0[4], aux[2];
        cr_assert_eq(ch.to_canon(&ch, &S[c].k, X, pp, z0, aux), 0);
        /* scales: 1 rad; chi over the distance r along B (|B| r); P_phi;
         * P_chi of the full momentum p / |B| */
        const double r = sqrt(X[0] * X[0] + X[1] * X[1] + X[2] * X[2]), Bm = gc_Bmag(S[c].f, X);
        const double ptot = sqrt(pp * pp + 2.0 * S[c].k.m * S[c].k.mu * Bm);
        const double sc[4] = {1.0, Bm * r, fabs(z0[2]), ptot / Bm};
        double prev[2] = {NAN, NAN};
        for (int N = 25; N <= 200; N *= 2) {
            const double h = S[c].Tb / N;
            for (int k = 0; k < 2; k++) {
                const double res = sympl_residual(&S[c], &ch, sym[k], h, z0, sc);
                cr_log_info("%-17s N %3d %-17s residual %.2e", S[c].name, N, sym[k]->name, res);
                cr_expect(res < 1e-8, "%s N %d %s: residual %.2e", S[c].name, N, sym[k]->name,
                          res);
            }
            for (int k = 0; k < 2; k++) {
                const double res = sympl_residual(&S[c], &ch, non[k], h, z0, sc);
                const double ratio = prev[k] / res;
                cr_log_info("%-17s N %3d %-17s residual %.2e ratio %.1f (h^%.0f: %.0f)",
                            S[c].name, N, non[k]->name, res, ratio, non_order[k],
                            pow(2.0, non_order[k]));
                if (N == 25)
                    cr_expect(res > 1e-6, "%s %s: residual %.2e at N 25: test cannot fail",
                              S[c].name, non[k]->name, res);
                else if (res > 1e-9) /* above the floor: the power law */
                    cr_expect(ratio > non_min_ratio[k], "%s N %d %s: ratio %.1f", S[c].name, N,
                              non[k]->name, ratio);
                prev[k] = res;
            }
        }
        gcp_canon_chart_destroy(&ch);
        sys_free(&S[c]);
    }
}

/* ---- long runs: bounded energy, exact P_phi ---- */

struct lr_ctx {
    const struct sys *S;
    int64_t k, every;
    double H0, P0, mc2;
    /* least squares of e(t) = E_kin(t)/E_kin(0) - 1 on t, and its range */
    double n, st, se, stt, ste, emin, emax, maxP;
};

static int lr_cb(double t, const double X[3], double ppar, void *vctx)
{
    struct lr_ctx *c = vctx;
    if (++c->k % c->every) return 0;
    double H, P;
    gcp_gc_energy(c->S->f, 0, c->S->k.q, c->S->k.m, X, ppar, c->S->k.mu, &H);
    gcp_gc_pphi(c->S->f, 0, c->S->k.q, X, ppar, &P);
    const double e = (H - c->mc2) / (c->H0 - c->mc2) - 1.0;
    c->n += 1, c->st += t, c->se += e, c->stt += t * t, c->ste += t * e;
    c->emin = fmin(c->emin, e), c->emax = fmax(c->emax, e);
    c->maxP = fmax(c->maxP, fabs(P / c->P0 - 1.0));
    return 0;
}

/* Pushes nsteps of h with p (tol: the adaptive methods' tolerance, else 0);
 * returns the fitted trend |slope| * duration and the range max e - min e of
 * the kinetic-energy error, and P_phi's. */
static void long_run(const struct sys *S, const struct gcp_pusher_type *p, double h,
                     int64_t nsteps, double tol, double *trend, double *range, double *maxP)
{
    /* every step: a sampling interval near the bounce period would alias
     * the oscillation into a slow beat, i.e. a spurious trend */
    struct lr_ctx c = {.S = S, .every = 1,
                       .mc2 = S->k.m * GC_C * GC_C, .emin = INFINITY, .emax = -INFINITY};
    gcp_gc_energy(S->f, 0, S->k.q, S->k.m, S->X, S->ppar, S->k.mu, &c.H0);
    gcp_gc_pphi(S->f, 0, S->k.q, S->X, S->ppar, &c.P0);
    double X[3] = {S->X[0], S->X[1], S->X[2]}, pp = S->ppar, t = 0.0;
    const struct gcp_push_opts o = {0.0, h, nsteps, tol, 0.0};
    const int st = gcp_gc_push(S->f, p, S->k.q, S->k.m, &o, &t, X, &pp, S->k.mu, lr_cb, &c);
    cr_assert_eq(st, GCP_ALIVE, "%s %s: status %d", S->name, p->name, st);
    const double slope = (c.n * c.ste - c.st * c.se) / (c.n * c.stt - c.st * c.st);
    *trend = fabs(slope) * t;
    *range = c.emax - c.emin;
    *maxP = c.maxP;
}

/* 25 steps per bounce (the coarse end of the 20-50 the issue asks for),
 * LR_STEPS = 1e7 steps = 4e5 bounces of gc-gl2 and of gc-gl4 per particle
 * (the figure).  Cost (CPU, energy and P_phi sampled every step):
 * ~2.3 us a step for either method in the dipole, so ~46 s per particle
 * (~55 s with the non-symplectic segment below);
 * one test per particle, so that make check's two jobs share them.
 * Energy: the kinetic-energy error of a symplectic method oscillates with
 * the bounce and has no secular part; a least-squares line fitted over the
 * run picks up, from a bounded signal of range A over 4e5 periods, a
 * spurious trend ~A/4e5 = 2.5e-6 A, plus the round-off random walk
 * (~1e-16 sqrt(1e7) = 3e-13): the trend must be below 1e-3 A (the issue's
 * bound).  P_phi = q psi: exact in exact arithmetic (Noether, as dH/dphi =
 * 0); each step adds the round-off of the Newton and of the chart's round
 * trip, and each re-start of gcp_gc_push's 256-step chunks that of
 * (X, p_par) -> z: a random walk.  Measured, its largest excursion over
 * 1e7 steps is 9.7e-13 (gc-gl2) and 1.2e-13 (gc-gl4): sigma ~ 3e-16 = 1.4
 * ulp a step for gc-gl2 (9.7e-13 / sqrt(1e7)).  The 1e-12 is the
 * walk's own size at 1e7 steps: since the lifted solver's predictor along
 * the field line (another rounding of the same steps) gc-gl2 reads 1.2e-12
 * in both cases, gc-gl4 2.7e-13 / 1.7e-13; asserted: 3e-12, three times
 * sigma sqrt(N).
 * The same test fails the non-symplectic methods at no less than gc-gl4's
 * cost per unit time: gc-rk4 at a 12x smaller step (48 field evaluations
 * against gc-gl4's ~15 a step) and gc-rk45 at tolerance 1e-8 (84 and 96
 * accepted steps per bounce for the electron and the proton, ~0.5 us each
 * in make bench's dipole block against gc-gl4's 25 at ~1.7 us), over the
 * first LR_STEPS / 10 steps' time only (4e4 bounces; at the full length
 * gc-rk4 alone would be 1.2e8 steps): their energy error grows linearly
 * (trend / range ~ 1 measured), so over the whole run it would be 10x
 * what this segment shows, and a segment in which the trend already
 * exceeds 1e-3 of the range shows the drift that the full run would. */
#define LR_STEPS 10000000
static void long_run_case(struct sys *S)
{
    const struct gcp_pusher_type *sym[] = {&gcp_pusher_gc_gl2, &gcp_pusher_gc_gl4};
    const double h = S->Tb / 25;
    double trend, range, maxP;
    for (int k = 0; k < 2; k++) {
        long_run(S, sym[k], h, LR_STEPS, 0.0, &trend, &range, &maxP);
        cr_log_info("%-17s %-7s 25/bounce %d steps: energy range %.2e trend %.2e (%.1e of "
                    "range), P_phi %.1e",
                    S->name, sym[k]->name, LR_STEPS, range, trend, trend / range, maxP);
        cr_expect(trend < 1e-3 * range, "%s %s: energy trend %.2e vs range %.2e", S->name,
                  sym[k]->name, trend, range);
        cr_expect(maxP < 3e-12, "%s %s: P_phi %.2e", S->name, sym[k]->name, maxP);
    }
    const int64_t nseg = LR_STEPS / 10;
    const struct {
        const struct gcp_pusher_type *p;
        double h, tol;
        int64_t n;
    } ns[] = {{&gcp_pusher_gc_rk4, h / 12, 0.0, 12 * nseg}, {&gcp_pusher_gc_rk45, h, 1e-8, nseg}};
    for (int k = 0; k < 2; k++) {
        long_run(S, ns[k].p, ns[k].h, ns[k].n, ns[k].tol, &trend, &range, &maxP);
        cr_log_info("%-17s %-7s %s, 1/10 of the time: energy range %.2e trend %.2e (%.1e of "
                    "range), P_phi %.1e",
                    S->name, ns[k].p->name, k ? "tol 1e-8" : "300/bounce", range, trend,
                    trend / range, maxP);
        cr_expect(trend > 1e-3 * range, "%s %s: no drift seen (trend %.2e, range %.2e): "
                  "the test cannot tell", S->name, ns[k].p->name, trend, range);
        cr_expect(maxP > 1e-12, "%s %s: P_phi %.2e", S->name, ns[k].p->name, maxP);
    }
    sys_free(S);
}

/* Measured (1e7 steps; ~45 s CPU): gc-gl2 energy range 1.45e-2, trend
 * 5.6e-7 of it, P_phi 1.2e-12; gc-gl4 9.73e-5, 7.3e-5, 2.7e-13.  Over 1e6
 * steps' time: gc-rk4 trend 1.0 of its range (4.8e-5), P_phi 1.8e-5;
 * gc-rk45 1.0 (3.7e-3), 4.4e-4. */
Test(gc_symplectic, long_run_electron_energy_bounded_pphi_exact, .timeout = 600)
{
    struct sys S;
    sys_dipole(&S, "dipole e- 1 MeV", -GCP_E_CHARGE, GCP_M_ELECTRON, 1e6 * GCP_E_CHARGE,
               30.0 * GCP_PI / 180.0);
    long_run_case(&S);
}

/* Measured (1e7 steps; ~45 s CPU): gc-gl2 energy range 2.11e-2, trend
 * 3.0e-7 of it, P_phi 1.2e-12; gc-gl4 1.45e-4, 2.6e-5, 1.7e-13.  Over 1e6
 * steps' time: gc-rk4 trend 1.0 of its range (8.2e-5), P_phi 2.1e-5;
 * gc-rk45 1.0 (1.6e-3), 3.5e-4. */
Test(gc_symplectic, long_run_proton_energy_bounded_pphi_exact, .timeout = 600)
{
    struct sys S;
    sys_dipole(&S, "dipole p+ 10 MeV", GCP_E_CHARGE, GCP_M_PROTON, 10e6 * GCP_E_CHARGE,
               30.0 * GCP_PI / 180.0);
    long_run_case(&S);
}
