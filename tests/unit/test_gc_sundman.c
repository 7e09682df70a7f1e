/* The symplectic adaptive guiding-centre methods gc-gl2-sundman and
 * gc-gl4-sundman (src/pushers/gc_sundman.c, issue 11): the Gauss-Legendre
 * core of gc_gauss.c with a fixed step ds in the fictitious time s of the
 * extended Hamiltonian K = w(z) (H(z) + p_t), dt/ds = w,
 * w = (B_ref/|B|)^(1/4).
 *
 * The lanes are stepped directly (gcp_gl_step_canon with the pusher's own
 * lane set-up, gcp_sundman_lane_init), so that every s-step is the
 * symplectic map: the pusher adds only the landing on output times.
 * These lanes are the chi chart's, which the pushers use outside the
 * dipole; in the dipole the pushers run the same transformation in the
 * field line's coordinates (gc_sundman_dipole.c: its symplecticity, long
 * run and slicing in test_gc_sundman_line.c), which drift_phase_fewer_steps
 * reaches through the pusher.
 * Orbits: 1 MeV electrons at L = 4 in the dipole, equatorial pitch 4 deg
 * (mirror at 62.9 deg latitude, |B| 206x its equatorial value), 0.7 deg
 * (mirror at 75.1 deg, |B| 6700x) and 0.11 deg (mirror at 82.0 deg, |B|
 * 2.7e5x: SD_PITCH_82).  The dipole is self-similar: the step counts
 * depend on the mirror latitude only, not on L (a particle mirroring at 75
 * deg above the surface is on L >= 15, at 82 deg on L >= 52: Jupiter's
 * middle magnetosphere rather than Earth's, where every orbit mirroring
 * above ~60 deg at L = 4 is in the loss cone).
 */
#include <criterion/criterion.h>

#include "pushers/canon_priv.h"
#include "pushers/gc_gauss_priv.h"
#include "pushers/gc_sundman_priv.h"
#include "test_gc_util.h"

struct sd_sys {
    struct gcp_field *f;
    struct gcp_gc_consts k;
    double X[3], ppar;
    double Tb, Td, latm; /* [s], [s], [rad] by the dipole quadratures (test_gc_util.h) */
};

#define SD_PITCH_82 GC_PITCH_OF_MIRROR(82.0)

/* 1 MeV electron on the equator at L = 4 with equatorial pitch a_deg
 * (gc_dip_electron). */
static void sd_dipole(struct sd_sys *s, double a_deg)
{
    struct gc_dip_orbit o;
    cr_assert_eq(gc_dip_electron(&o, a_deg), 0);
    s->f = o.f, s->k = (struct gcp_gc_consts){o.q, o.m, o.mu};
    memcpy(s->X, o.X, sizeof s->X);
    s->ppar = o.ppar, s->Tb = o.Tb, s->Td = o.Td, s->latm = o.latm;
}

/* A lane of the Gauss-Legendre core at (X, p_par): with the Sundman
 * transformation (sundman = 1, w of gc_sundman.c) or plain time steps. */
static void sd_lane(const struct sd_sys *S, struct gl_ctx *C, struct gl_lane *L,
                    const struct gl_tableau *tab, const double X[3], double ppar, int sundman)
{
    memset(C, 0, sizeof *C);
    C->tab = tab;
    C->sundman_a = sundman ? GCP_SUNDMAN_A : 0.0;
    char why[256];
    cr_assert_eq(gcp_canon_chart_create(S->f, &C->chart, why, sizeof why), 0, "%s", why);
    struct gcp_block b;
    cr_assert_eq(gcp_block_alloc(&b, 1), 0);
    b.q = S->k.q, b.m = S->k.m, b.mu[0] = S->k.mu;
    b.x[0] = X[0], b.y[0] = X[1], b.z[0] = X[2], b.ppar[0] = ppar;
    cr_assert_eq(gcp_sundman_lane_init(C, &b, 0, 0.0, L), 0);
    gcp_block_free(&b);
}

/* ---- the extended-phase-space map is symplectic ---- */

/* The extended state (phi, chi, t, P_phi, P_chi, p_t) of a lane. */
static void sd_get(const struct gl_lane *L, double y[6])
{
    y[0] = L->z[0], y[1] = L->z[1], y[2] = L->t, y[3] = L->z[2], y[4] = L->z[3], y[5] = L->pt;
}
static void sd_set(struct gl_lane *L, const double y[6])
{
    L->z[0] = y[0], L->z[1] = y[1], L->t = y[2], L->z[2] = y[3], L->z[3] = y[4], L->pt = y[5];
}

/* The plain Gauss-Legendre step in t of size h = w(z0) ds, the step chosen
 * from the state that the transformation replaces (t += h, p_t kept):
 * symplectic in (phi, chi, P_phi, P_chi) for a fixed h, but h depends on
 * z0, so the map is not. */
static int sd_naive_step(const struct sd_sys *S, const struct gl_ctx *plain, const struct gl_ctx *C,
                         struct gl_lane *L, double ds)
{
    double w, aux[2] = {L->aux[0][0], L->aux[0][1]};
    if (gcp_sundman_w(C, &S->k, L, aux, &w)) return -1;
    return gcp_gl_step_canon(plain, &S->k, L, ds * w);
}

/* The one-s-step map of gc-gl2/gl4-sundman in the extended phase space:
 * |M^T J M - J| (6 x 6, pairs (phi, P_phi), (chi, P_chi), (t, p_t)),
 * M by central differences over 1e-5 of each scale (truncation ~1e-10,
 * round-off 1e-16/1e-5 = 1e-11: the floor is ~1e-10; 1e-8 asserted, the
 * issue's bound), for ds = T_b/30 .. T_b/240, in the electrons mirroring at
 * 63 deg and at 82 deg (where the steps save 3x and more: the period test
 * below), started a tenth of a bounce from the equator.  Against it, the
 * naive step from the state (sd_naive_step): its residual must be far above
 * the floor (> 1e-6, 100x the bound) at every ds: the test can fail. */
static double sd_residual(const struct sd_sys *S, const struct gl_ctx *C, const struct gl_lane *L0,
                          double ds, const double sc[6], int naive)
{
    struct gl_ctx plain = *C;
    plain.sundman_a = 0.0;
    double M[6][6], y0[6];
    sd_get(L0, y0);
    for (int j = 0; j < 6; j++) {
        double y1p[6], y1m[6];
        for (int sgn = -1; sgn <= 1; sgn += 2) {
            struct gl_lane L = *L0;
            double y[6];
            memcpy(y, y0, sizeof y);
            y[j] += sgn * 1e-5 * sc[j];
            sd_set(&L, y);
            const int st = naive ? sd_naive_step(S, &plain, C, &L, ds)
                                 : gcp_gl_step_canon(C, &S->k, &L, ds);
            if (st) return NAN;
            sd_get(&L, sgn > 0 ? y1p : y1m);
        }
        for (int i = 0; i < 6; i++) M[i][j] = (y1p[i] - y1m[i]) / (2e-5 * sc[j]);
    }
    return gc_ext_symplectic_residual((const double(*)[6])M, sc);
}

Test(gc_sundman, extended_map_is_symplectic, .timeout = 120)
{
    const double a_deg[2] = {4.0, SD_PITCH_82};
    for (int o = 0; o < 2; o++) {
        struct sd_sys S;
        sd_dipole(&S, a_deg[o]);
        double X[3] = {S.X[0], S.X[1], S.X[2]}, pp = S.ppar, t = 0.0;
        const struct gcp_push_opts op = {0.0, S.Tb / 1000, 100, 0.0, 0.0};
        cr_assert_eq(gcp_gc_push(S.f, &gcp_pusher_gc_rk8pd, S.k.q, S.k.m, &op, &t, X, &pp, S.k.mu,
                                 NULL, NULL), 0);
        const struct gl_tableau *tabs[] = {&gcp_gl2_tableau, &gcp_gl4_tableau};
        for (int k = 0; k < 2; k++) {
            struct gl_ctx C;
            struct gl_lane L;
            sd_lane(&S, &C, &L, tabs[k], X, pp, 1);
            const double r = sqrt(X[0] * X[0] + X[1] * X[1] + X[2] * X[2]), Bm = gc_Bmag(S.f, X);
            const double ptot = sqrt(pp * pp + 2.0 * S.k.m * S.k.mu * Bm);
            const double Ek = -L.pt - S.k.m * GC_C * GC_C;
            const double sc[6] = {1.0, Bm * r, S.Tb, fabs(L.z[2]), ptot / Bm, Ek};
            for (int N = 30; N <= 240; N *= 2) {
                const double res = sd_residual(&S, &C, &L, S.Tb / N, sc, 0);
                const double naive = sd_residual(&S, &C, &L, S.Tb / N, sc, 1);
                cr_log_info("mirror %.1f deg, %s ds = T_b/%d: extended residual sundman %.2e, "
                            "naive step from the state %.2e", S.latm * 180 / GCP_PI,
                            tabs[k]->s == 1 ? "gl2" : "gl4", N, res, naive);
                cr_expect(res < 1e-8, "mirror %.1f s %d N %d: residual %.2e",
                          S.latm * 180 / GCP_PI, tabs[k]->s, N, res);
                cr_expect(naive > 1e-6, "mirror %.1f s %d N %d: naive residual %.2e: test "
                          "cannot fail", S.latm * 180 / GCP_PI, tabs[k]->s, N, naive);
            }
            gcp_canon_chart_destroy(&C.chart);
        }
        gcp_field_free(S.f);
    }
}

/* ---- fewer steps for the same drift period ---- */

/* (chi, t, phi) of a lane and their rates per unit of the step variable
 * (s with the transformation: w times the rates in t; on the orbit
 * H + p_t = 0, so the term (H + p_t) J grad w of the flow is left out:
 * these rates only interpolate between steps).  Updates the chart guess,
 * as the pusher's mapping back to (X, p_par) does after every step. */
static int sd_rates(const struct sd_sys *S, const struct gl_ctx *C, struct gl_lane *L, double y[3],
                    double dy[3])
{
    double H, dH[4], w = 1.0;
    if (C->chart.hamiltonian(&C->chart, &S->k, L->z, L->aux[0], &H, dH)) return -1;
    if (C->sundman_a != 0.0 && gcp_sundman_w(C, &S->k, L, L->aux[0], &w)) return -1;
    y[0] = L->z[1], y[1] = L->t, y[2] = L->z[0];
    dy[0] = w * dH[3], dy[1] = w, dy[2] = w * dH[2];
    return 0;
}

/* Drift and bounce periods of a lane stepped with a fixed step h (in t, or
 * in s with the transformation) from the equator: from the first to the
 * (nb+1)-th equator crossing (chi = 0) in the direction of the start,
 *   T_d = 2 pi (t_nb - t_0) / |phi_nb - phi_0|,  T_b = (t_nb - t_0) / nb,
 * each crossing located by cubic Hermite interpolation of (chi, t, phi) in
 * the step variable (error O(h^4) at a crossing, not accumulated: over 10
 * bounces it is below the periods' own errors -- measured, 40 bounces give
 * the same period errors to 2 digits).  Returns the steps taken, or -1 when a
 * step fails (the Newton solve at a mirror point for too coarse a step). */
static int64_t sd_periods(const struct sd_sys *S, int sundman, double h, int nb, double *Td,
                          double *Tb)
{
    struct gl_ctx C;
    struct gl_lane L;
    sd_lane(S, &C, &L, &gcp_gl4_tableau, S->X, S->ppar, sundman);
    double y0[3], d0[3], y1[3], d1[3], unwrap = 0.0, tc[2] = {0}, pc[2] = {0};
    int64_t steps = 0;
    int nc = 0, dir = 0;
    cr_assert_eq(sd_rates(S, &C, &L, y0, d0), 0);
    while (nc <= nb) {
        if (gcp_gl_step_canon(&C, &S->k, &L, h) || sd_rates(S, &C, &L, y1, d1)) {
            steps = -1;
            break;
        }
        steps++;
        y1[2] += unwrap;
        if (y1[2] - y0[2] > GCP_PI) unwrap -= 2 * GCP_PI, y1[2] -= 2 * GCP_PI;
        if (y1[2] - y0[2] < -GCP_PI) unwrap += 2 * GCP_PI, y1[2] += 2 * GCP_PI;
        if (!dir) dir = y1[0] > y0[0] ? 1 : -1;
        else if (dir * y0[0] < 0.0 && dir * y1[0] >= 0.0) {
            const double u = gc_herm_root(y0[0], y1[0], d0[0] * h, d1[0] * h);
            const int c = nc ? 1 : 0;
            tc[c] = gc_herm(u, y0[1], y1[1], d0[1] * h, d1[1] * h);
            pc[c] = gc_herm(u, y0[2], y1[2], d0[2] * h, d1[2] * h);
            nc++;
        }
        memcpy(y0, y1, sizeof y0);
        memcpy(d0, d1, sizeof d0);
    }
    gcp_canon_chart_destroy(&C.chart);
    *Td = 2.0 * GCP_PI * (tc[1] - tc[0]) / fabs(pc[1] - pc[0]);
    *Tb = (tc[1] - tc[0]) / nb;
    return steps;
}

/* The fewest steps (over 10 bounces) for the drift period to rel[j]
 * (relative, against the quadrature; rel decreasing), scanning the steps
 * per bounce N up from 10 by 4%:
 *   nfirst[j]  the steps of the first N that runs and meets rel[j];
 *   nall[j]    the steps of the smallest N from which every N of the scan
 *              up to SD_WINDOW N runs and meets it.
 * nall is the step a user can choose without knowing the error: gc-gl4's
 * period error at a coarsely resolved mirror point changes sign as N
 * grows and meets rel at isolated N (a cancellation no user could find
 * without the reference), which nfirst counts.  The sign changes seen
 * recur within ~1.3x in N (80-deg electron: |err| < 1e-6 at 561 and 656
 * steps per bounce, > 1e-6 at 583, 682 and 738, < 1e-6 from 768 to 1500),
 * so a window of 1.5x in N takes them in.  -1: not reached by SD_NMAX. */
#define SD_NMAX 2000.0
#define SD_WINDOW 1.5
static void sd_fewest(const struct sd_sys *S, int sundman, const double *rel, int nrel,
                      int64_t *nfirst, int64_t *nall)
{
    int64_t cand[4];
    double ncand[4];
    for (int j = 0; j < nrel; j++) nfirst[j] = nall[j] = cand[j] = -1, ncand[j] = 0.0;
    for (double N = 10.0; N <= SD_NMAX; N *= 1.04) {
        double Td, Tb;
        const int64_t st = sd_periods(S, sundman, S->Tb / N, 10, &Td, &Tb);
        int done = 1;
        for (int j = 0; j < nrel; j++) {
            const int ok = st > 0 && fabs(Td / S->Td - 1.0) <= rel[j];
            if (ok && nfirst[j] < 0) nfirst[j] = st;
            if (!ok) cand[j] = -1;
            else if (cand[j] < 0) cand[j] = st, ncand[j] = N;
            if (cand[j] >= 0 && N >= SD_WINDOW * ncand[j]) nall[j] = cand[j];
            else nall[j] = -1, done = 0;
        }
        if (done) break;
    }
}

/* Steps for the same drift-period accuracy, gc-gl4-sundman against the best
 * fixed gc-gl4 step, at 1e-4, 1e-5 and 1e-6 of T_d.  The reference is the
 * quadrature (~2e-8, test_gc_util.h; at 82 deg the transformed method's
 * error falls as ds^4 down to 1.5e-11, so the quadrature is at least that
 * good there).  Measured (deterministic; steps fixed / steps sundman, by
 * nall of sd_fewest, nfirst in brackets where it differs; 1 MeV electrons,
 * the same scan run on other mirror latitudes for the notes):
 *   mirror 62.9 deg: 1.10x at 1e-4, 0.94x (0.69x) at 1e-5, 0.94x at 1e-6;
 *   mirror 70.0 deg: 1.55x, 1.33x (1.18x), 1.23x (0.83x);
 *   mirror 75.1 deg: 2.74x, 2.01x, 1.71x (1.16x);
 *   mirror 80.0 deg: 5.83x (5.39x), 4.44x (3.79x), 3.00x (2.77x);
 *   mirror 81.0 deg: 7.49x (6.66x), 4.87x, 3.29x;
 *   mirror 82.0 deg: 8.21x, 7.31x (6.01x), 4.57x
 * (82 deg: gc-gl4 890 / 1481 / 2666 s-steps over the 10 bounces against
 * 7311 / 10822 / 12173 fixed steps).  The gain grows with the mirror
 * latitude because the fixed step is set by the mirror point, where the
 * time scale of the motion is shortest and the orbit spends the least time:
 * gc-gl4's Newton solve fails there below ~400 (80 deg) / ~650 (82 deg)
 * steps per bounce, and above that its period error changes sign from one
 * step to the next (the mirror point falls between steps differently on
 * each bounce) until ~700 / ~1000 steps per bounce, while the transformed
 * step, ~|B|^-1/4, shrinks 23x at an 82-deg mirror point and runs from
 * ~27 nominal steps per bounce, with an error that falls smoothly as ds^4.
 * Below ~75 deg the adaptation gains less than 2x (the ceiling of
 * gc_sundman.c's notes): the 3x holds from ~80 deg up, at every
 * accuracy from 1e-4 to 1e-6 from 81 deg up.
 * Asserted: the 3x at every accuracy at 82 deg, by nall and by
 * nfirst (the gain cannot come from the criterion); and as regression
 * bounds ~10-15% under the measured nall ratios: >= 7.0x, 6.2x, 3.9x at 82
 * deg, >= 0.95x, 0.8x, 0.8x at 63 deg (where the adaptive steps cost no
 * more than ~6% beyond ~1e-5: no gain, no loss).  ~8 s (the fixed scan at
 * 82 deg runs to ~1500 steps per bounce to close the window). */
Test(gc_sundman, drift_period_fewer_steps, .timeout = 120)
{
    const double a_deg[2] = {4.0, SD_PITCH_82}, rel[3] = {1e-4, 1e-5, 1e-6};
    const double need[2][3] = {{0.95, 0.8, 0.8}, {7.0, 6.2, 3.9}};
    for (int o = 0; o < 2; o++) {
        struct sd_sys S;
        sd_dipole(&S, a_deg[o]);
        int64_t nf[3], ns[3], nfa[3], nsa[3];
        sd_fewest(&S, 0, rel, 3, nf, nfa);
        sd_fewest(&S, 1, rel, 3, ns, nsa);
        for (int j = 0; j < 3; j++) {
            const double gain = (double)nfa[j] / (double)nsa[j];
            const double gain1 = (double)nf[j] / (double)ns[j];
            cr_log_info("mirror %.1f deg, T_d to %.0e: gc-gl4 %lld steps (%.0f per bounce; first "
                        "met at %lld), gc-gl4-sundman %lld (%.0f per bounce; first %lld): %.2fx "
                        "(first met: %.2fx)",
                        S.latm * 180 / GCP_PI, rel[j], (long long)nfa[j], nfa[j] / 11.0,
                        (long long)nf[j], (long long)nsa[j], nsa[j] / 11.0, (long long)ns[j],
                        gain, gain1);
            cr_expect(nfa[j] > 0 && nsa[j] > 0, "T_d to %.0e not reached", rel[j]);
            cr_expect(gain >= need[o][j], "mirror %.1f deg, %.0e: %.2fx fewer steps",
                      S.latm * 180 / GCP_PI, rel[j], gain);
            if (o == 1)
                cr_expect(gain >= 3.0 && gain1 >= 3.0, "mirror %.1f deg, %.0e: %.2fx (first "
                          "met %.2fx) fewer steps: the issue's 3x not reached",
                          S.latm * 180 / GCP_PI, rel[j], gain, gain1);
        }
        gcp_field_free(S.f);
    }
}

/* ---- fewer steps for the same drift phase ---- */

/* Azimuth at t = n dt pushed by pusher p from the start (the Sundman
 * pushers land exactly on that time); the status, and the steps taken. */
static int sd_push_phi(const struct sd_sys *S, const struct gcp_pusher_type *p, double dt,
                       int64_t n, double tol, double *phi, int64_t *steps)
{
    struct gcp_block b;
    cr_assert_eq(gcp_block_alloc(&b, 1), 0);
    b.q = S->k.q, b.m = S->k.m, b.mu[0] = S->k.mu;
    b.x[0] = S->X[0], b.y[0] = S->X[1], b.z[0] = S->X[2], b.ppar[0] = S->ppar;
    const struct gcp_push_opts o = {0.0, dt, n, tol, 0.0};
    p->advance(&b, S->f, p, &o, NULL);
    const int st = b.status[0];
    *phi = atan2(b.y[0], b.x[0]);
    *steps = b.steps[0];
    gcp_block_free(&b);
    return st;
}

/* The fewest steps at which pusher p gives the azimuth at t = 3 T_b to
 * err[j] rad, at that setting and at each of the next NEXT_OK finer ones,
 * scanning the steps per bounce (of the start point, for the Sundman forms)
 * up from 10 by 4%.  Why the finer settings: the fixed step's phase error
 * changes sign from one setting to the next while the mirror point falls
 * between steps differently (75 deg, gc-gl4: 2.8e-4 at 182 steps per
 * bounce, 7.3e-6 at 227, 8.2e-6 at 284 of the drift), so the first setting
 * below a bound can be an accidental zero of the error (this test's first
 * form took 230 steps per bounce for 1e-6 that way, where the error stays
 * below 1e-6 only from ~550). */
#define NEXT_OK 3
static void sd_fewest_phase(const struct sd_sys *S, const struct gcp_pusher_type *p, double phi_ref,
                            const double *err, int nerr, int64_t *n)
{
    enum { NS = 200 };
    double e[NS];
    int64_t st[NS];
    int m = 0;
    for (double N = 10.0; N <= 2000.0 && m < NS; N *= 1.04, m++) {
        const int64_t nsteps = (int64_t)(3.0 * N);
        double phi;
        e[m] = INFINITY, st[m] = -1;
        if (sd_push_phi(S, p, 3.0 * S->Tb / (double)nsteps, nsteps, 0.0, &phi, &st[m])) continue;
        e[m] = fabs(remainder(phi - phi_ref, 2.0 * GCP_PI));
    }
    for (int j = 0; j < nerr; j++) {
        n[j] = -1;
        for (int i = 0; i + NEXT_OK < m && n[j] < 0; i++) {
            int ok = 1;
            for (int d = 0; d <= NEXT_OK; d++) ok &= e[i + d] <= err[j];
            if (ok) n[j] = st[i];
        }
    }
}

/* The drift phase (the azimuth at t = 3 T_b, against gc-rk8pd at tolerance
 * 1e-13: error ~1e-11 rad, 400x below the finest 6e-9 rad compared) to
 * 1e-4 and 1e-6 of the drift over the 3 bounces, through the pushers
 * (gc-gl4-sundman lands exactly on 3 T_b): the orbit's phase, where the
 * local error counts and w = |B|^-1/4 evens it out along the orbit.  In the
 * dipole both collocate in the field line's coordinate s = sin(lat), fused
 * (gc_gauss_dipole.c, gc_sundman_dipole.c): the best fixed step against
 * the adaptive one, in the same coordinates.
 * Measured (deterministic; steps fixed / steps sundman, NEXT_OK = 3):
 *   mirror 63 deg: 1.93x at 1e-4 (205 / 106), 2.42x at 1e-6 (591 / 244);
 *   mirror 75 deg: 4.22x at 1e-4 (591 / 140), 5.58x at 1e-6 (1456 / 261);
 *   mirror 82 deg: 11.8x at 1e-4 (2073 / 176), 9.67x at 1e-6 (3734 / 386)
 * (the chi-chart form before: 1.69x / 1.76x, 4.10x / 2.75x, 8.26x / 4.58x:
 * collocating s, not chi, gains most at the finer accuracy).  In CPU time
 * (tests/bench/bench_sundman.c) the gain is ~0.6x the gain in steps: a
 * transformed step costs ~1.6x a fixed one there.
 * Other exponents of w = (B_ref/|B|)^a (the same scan, a the only change;
 * fixed gc-gl4 at a 60.0-deg mirror: 155 / 505 steps), gains at 1e-4 / 1e-6:
 *   a = 1/6:  60 deg 2.0x / 2.2x, 63 deg 2.3x / 2.3x, 75 deg 3.4x / 3.2x, 82 deg 5.8x / 5.4x;
 *   a = 1/5:  60 deg 2.0x / 3.6x, 63 deg 2.6x / 3.4x, 75 deg 3.6x / 4.2x, 82 deg 8.7x / 7.7x;
 *   a = 1/4:  60 deg 1.9x / 2.1x, 63 deg 1.9x / 2.4x, 75 deg 4.2x / 5.6x, 82 deg 11.8x / 9.7x;
 *   a = 1/3:  60 deg 1.5x / 1.6x, 63 deg 1.6x / 1.8x, 75 deg 2.9x / 3.3x, 82 deg 6.4x / 4.8x;
 *   a = 1/2:  60 deg 0.8x / 1.0x, 63 deg 0.9x / 1.1x, 75 deg 0.9x / 1.0x, 82 deg 1.3x / 0.9x.
 * No a reaches 3x at 1e-4 below ~70 deg (the fewest transformed steps at
 * 60 deg are 77-81 for every a from 1/6 to 1/4: ~26 a bounce, where the
 * equatorial part's error, not the mirror point's, sets the bound); 1/5
 * gains at 1e-6 below 65 deg what it loses above 70: 1/4 kept.
 * Asserted: the 3x at 82 deg at both accuracies, and ~15% under
 * the measured ratios elsewhere: >= 1.6x, 2.0x at 63 deg, >= 3.6x, 4.7x at
 * 75 deg, >= 10x, 8.2x at 82 deg.  ~1 s. */
Test(gc_sundman, drift_phase_fewer_steps, .timeout = 120)
{
    const double a_deg[3] = {4.0, 0.7, SD_PITCH_82}, rel[2] = {1e-4, 1e-6};
    const double need[3][2] = {{1.6, 2.0}, {3.6, 4.7}, {10.0, 8.2}};
    for (int o = 0; o < 3; o++) {
        struct sd_sys S;
        sd_dipole(&S, a_deg[o]);
        double phi_ref;
        int64_t steps;
        cr_assert_eq(sd_push_phi(&S, &gcp_pusher_gc_rk8pd, 3.0 * S.Tb, 1, 1e-13, &phi_ref, &steps),
                     0);
        /* the drift over the 3 bounces sets the scale of the phase errors */
        const double dphi = 2.0 * GCP_PI * 3.0 * S.Tb / S.Td;
        const double err[2] = {rel[0] * dphi, rel[1] * dphi};
        int64_t nf[2], ns[2];
        sd_fewest_phase(&S, &gcp_pusher_gc_gl4, phi_ref, err, 2, nf);
        sd_fewest_phase(&S, &gcp_pusher_gc_gl4_sundman, phi_ref, err, 2, ns);
        for (int j = 0; j < 2; j++) {
            const double gain = (double)nf[j] / (double)ns[j];
            cr_log_info("mirror %.1f deg, phase at 3 T_b to %.0e of the drift: gc-gl4 %lld steps, "
                        "gc-gl4-sundman %lld: %.2fx",
                        S.latm * 180 / GCP_PI, rel[j], (long long)nf[j], (long long)ns[j], gain);
            cr_expect(nf[j] > 0 && ns[j] > 0, "phase to %.0e not reached", rel[j]);
            cr_expect(gain >= need[o][j], "mirror %.1f deg, phase to %.0e: %.2fx fewer steps",
                      S.latm * 180 / GCP_PI, rel[j], gain);
            if (o == 2)
                cr_expect(gain >= 3.0, "mirror %.1f deg, phase to %.0e: %.2fx fewer steps: the "
                          "issue's 3x not reached", S.latm * 180 / GCP_PI, rel[j], gain);
        }
        gcp_field_free(S.f);
    }
}

/* ---- bounded energy over a long run ---- */

/* Least-squares trend and range of the kinetic-energy error e(t) of a lane
 * stepped nsteps times by ds (symplectic: the Sundman s-step; naive: the
 * step from the state, sd_naive_step). */
static void sd_energy_run(const struct sd_sys *S, int64_t nsteps, double ds, int naive,
                          double *trend, double *range, double *bounces)
{
    struct gl_ctx C;
    struct gl_lane L;
    sd_lane(S, &C, &L, &gcp_gl4_tableau, S->X, S->ppar, 1);
    struct gl_ctx plain = C;
    plain.sundman_a = 0.0;
    const double mc2 = S->k.m * GC_C * GC_C, E0 = -L.pt - mc2;
    double n = 0, st = 0, se = 0, stt = 0, ste = 0, emin = INFINITY, emax = -INFINITY;
    for (int64_t k = 0; k < nsteps; k++) {
        const int r = naive ? sd_naive_step(S, &plain, &C, &L, ds)
                            : gcp_gl_step_canon(&C, &S->k, &L, ds);
        cr_assert_eq(r, 0, "step %lld", (long long)k);
        double H, dH[4];
        cr_assert_eq(C.chart.hamiltonian(&C.chart, &S->k, L.z, L.aux[0], &H, dH), 0);
        const double e = (H - mc2) / E0 - 1.0, t = L.t;
        n += 1, st += t, se += e, stt += t * t, ste += t * e;
        emin = fmin(emin, e), emax = fmax(emax, e);
    }
    *trend = fabs((n * ste - st * se) / (n * stt - st * st)) * L.t;
    *range = emax - emin;
    *bounces = L.t / S->Tb;
    gcp_canon_chart_destroy(&C.chart);
}

/* SD_LONG = 2e6 s-steps of gc-gl4-sundman at ds = T_b/40 on the electron
 * mirroring at 82 deg, the orbit where the steps save 4.6-8x for the drift
 * period (40 nominal steps per bounce, ~104 s-steps per bounce in all, T_d
 * to ~3e-5): 19300 bounces, ~10 s of one core here (~30 s under load).  As
 * for the fixed steps (test_gc_symplectic.c): the energy error of a
 * symplectic map oscillates with no secular part; a line fitted to a
 * bounded signal of range A over N periods picks up ~A/N, plus the
 * round-off random walk (~1e-16 sqrt(2e6) = 1.4e-13): the trend must stay
 * below 1e-3 A.  Measured: A = 1.51e-3, trend 8.7e-6 A; over the issue's
 * 1e7 s-steps (96500 bounces, run once: ~4 min under load, too long for
 * make check) the same A = 1.51e-3 and trend 1.1e-6 A.  The same run with
 * the naive step from the state (the same steps, not symplectic) over
 * SD_NAIVE = 5e4 steps must drift: trend > 1e-3 A (measured: 0.96 A, the
 * energy off by 100% at the end; at 8.4e4 steps it fails a Newton solve).
 * (On the 63-deg electron at T_b/30, before: A = 6.7e-4, trend 2.6e-6 A
 * over 4e6 steps.) */
#define SD_LONG 2000000
#define SD_NAIVE 50000
Test(gc_sundman, energy_bounded_long_run, .timeout = 300)
{
    struct sd_sys S;
    sd_dipole(&S, SD_PITCH_82);
    double trend, range, bounces;
    sd_energy_run(&S, SD_LONG, S.Tb / 40, 0, &trend, &range, &bounces);
    cr_log_info("gc-gl4-sundman %d s-steps (%.0f bounces): energy range %.2e, trend %.2e (%.1e "
                "of range)", SD_LONG, bounces, range, trend, trend / range);
    cr_expect(trend < 1e-3 * range, "trend %.2e range %.2e", trend, range);
    sd_energy_run(&S, SD_NAIVE, S.Tb / 40, 1, &trend, &range, &bounces);
    cr_log_info("naive step from the state %d steps (%.0f bounces): energy range %.2e, trend "
                "%.2e (%.1e of range)", SD_NAIVE, bounces, range, trend, trend / range);
    cr_expect(trend > 1e-3 * range, "naive steps: no drift seen (trend %.2e, range %.2e): the "
              "test cannot tell", trend, range);
    gcp_field_free(S.f);
}
