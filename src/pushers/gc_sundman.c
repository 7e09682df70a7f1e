/* gc-gl2-sundman, gc-gl4-sundman: symplectic guiding-centre integrators
 * with adaptive time steps (issue 11): the Gauss-Legendre methods of
 * gc_gauss.c applied with a fixed step in a fictitious time s to the
 * Sundman/Poincare-transformed Hamiltonian in extended phase space
 * (Hairer, Lubich & Wanner, Geometric Numerical Integration, sec. VIII.2;
 * Hairer 1997, Appl. Numer. Math. 25 219):
 *   z_ext = (phi, eta, t, P_phi, P_eta, p_t),   K = w(z) (H(z) + p_t),
 *   dt/ds = w(z),   p_t = -H(z0) (K = 0 on the orbit),
 * a canonical system in z_ext, so the map of one s-step is symplectic (in
 * the extended space) whatever w, while the physical step dt = w ds
 * follows w.  Here
 *   w = (B_ref / |B|)^a,  a = 1/4,  B_ref = |B| at the particle's start,
 * so dt = ds at the start and the step shrinks where |B| grows: guiding
 * centres that mirror deep in a dipole (|B| 70x the equatorial value at 60
 * deg latitude, the field changing over r/3 at speeds ~c) get smaller steps
 * there.  `dt` of the run file is ds, i.e. the step at the start point.
 * Why this w.  It must be a smooth function of z alone (a w that depended
 * on the step history would break the symplecticity), with an exact
 * gradient (grad w enters the flow; the extended-space check sees an
 * inexact one): what the chart gives exactly is H, |B| and their first
 * derivatives.  On an orbit H and mu are constant, so v_par^2 is a
 * function of |B| there, and along a dipole field line so is every
 * geometric scale (|grad B|/|B| ~ 1/r ~ |B|^(1/3)): w(|B|) loses nothing
 * against w(|B|, v_par) or a rate of the bounce motion.  The exponent is
 * measured, on 1 MeV electrons at L = 4 (tests/unit/test_gc_sundman.c,
 * and scans not kept as tests):
 *   - the local error of one fixed gc-gl4 step (against gc-rk8pd, in
 *     position and p_par) grows ~400x from the equator to a 63-deg mirror
 *     point; the step that keeps it equal (the error-estimate control of
 *     Burby, Finn & Ellison 2022, made a function of z), ~error^(-1/5),
 *     follows |B|^-1/4 within ~20% along the orbit.  The inverse
 *     phase-space speed in the chart's scales (w ~ 1/(|B| |v_par|) along
 *     the line, i.e. a ~ 1) spends its steps at the mirror points, where
 *     the orbit spends little time: 14x more steps than fixed at 57 deg.
 *   - the gain has a ceiling set by the orbit: with the step following the
 *     local error, fixed steps / adaptive steps <= T_b max(1/tau) /
 *     (integral over the bounce of dt/tau) (tau = the local time scale),
 *     2.3 for a 63-deg mirror, 3.1 at 69 deg, 3.5 at 71 deg.  No w reaches
 *     3x below ~69 deg.
 *   - the orbit's phase (the azimuth at a given time) follows the local
 *     error: at a = 1/4, 1.3-1.8x fewer steps than the best fixed step for
 *     the same drift phase at 63 deg, 2.8-3.8x at 75 deg.  a = 1/8 does as
 *     well at 63 deg and worse (1.5-1.9x) at 71 deg, a = 1/3 worse at
 *     both; a = 1/2 needs more steps than fixed.
 *   - a period (bounce or drift: a bounce average) gains less at moderate
 *     mirror latitudes.  The period error of a symplectic method is the
 *     bounce average of its modified Hamiltonian, spread over the whole
 *     orbit; and the transformed method's energy error, ds^4 (K_4(z0) -
 *     K_4(z)) / w, is largest where w is smallest, at the mirror points the
 *     period depends on.  Scanned over w = |B|^-a e^(-b ln^2|B|): at 63 deg
 *     no smooth w gives a robust gain in T_d (a = 1/8: 1.2-1.3x, a = 1/4:
 *     0.94-1.1x; isolated values of (a, b) that cancel the leading error
 *     term of one orbit do not carry over to another).
 *   - the gain in the drift period grows with the mirror latitude, and
 *     passes the 3x from ~80 deg (steps of the best fixed gc-gl4
 *     step / s-steps, for T_d to 1e-4 / 1e-5 / 1e-6; the fewest steps from
 *     which the accuracy holds on, test_gc_sundman.c sd_fewest):
 *       63 deg  1.10 / 0.94 / 0.94     70 deg  1.55 / 1.33 / 1.23
 *       75 deg  2.74 / 2.01 / 1.71     80 deg  5.83 / 4.44 / 3.00
 *       81 deg  7.49 / 4.87 / 3.29     82 deg  8.21 / 7.31 / 4.57
 *     (at 80 deg a = 1/8, 0.15, 0.2, 1/3, 0.4, 1/2 were scanned too, by
 *     the first step count that meets the accuracy: 0.2 needs 22% more
 *     steps at 1e-4 and 8-11% fewer at 1e-5 and 1e-6, every other a more
 *     at every accuracy: 1/8 and 1/3 1.2-2x, 1/2 7x).  The fixed step is set by the mirror point: it
 *     fails its Newton solve there below ~400 (80 deg) / ~650 (82 deg)
 *     steps per bounce, and above that its period error changes sign from
 *     one step size to the next (the mirror point falls between steps
 *     differently on each bounce) up to ~750 / ~1000 steps per bounce,
 *     while the transformed step, 23x shorter at an 82-deg mirror point
 *     than at the equator, runs from ~30 nominal steps per bounce with an
 *     error that falls smoothly as ds^4.  In CPU time the gain is smaller:
 *     a transformed step costs ~3.7x a fixed one (4.9 against 1.3 us per
 *     lane: the lifted Newton solve of gc_gauss.c is not used with the
 *     transformation), so at 82 deg and 1e-6 the same T_d costs 1.2x less
 *     CPU time per lane, and more than the fixed step on the block solver
 *     (gc_gauss_block.c, ~0.35 us a step).  In the dipole the pushers now
 *     run the transformation in the field line's coordinates, fused over
 *     tiles (gc_sundman_dipole.c: ~0.06 us a step, ~1.6x the fixed fused
 *     gc-gl4 step), and win in CPU time too (tests/bench/bench_sundman.c).
 *     A barely trapped tokamak orbit (100 keV proton, analytic tokamak,
 *     v_par/v = 0.563 at r = a/2, bounce period twice a deep banana's):
 *     w = (|B|/B_ref)^2 or ^4 (larger steps at the turning points, where
 *     it lingers) gives 0.5-2.0x, no robust gain: the time scale of the
 *     motion near the turning points (the hyperbolic rate there,
 *     ~v sqrt(eps/2)/(q R)) is of the order of the transit's
 *     (~v sqrt(2 eps)/(q R)); only the time spent is longer.
 * So a = 1/4: the steps follow the local error, the orbit's phase is 2-4x
 * cheaper in steps on orbits mirroring at 63-75 deg, the drift period 3-8x
 * from 80 deg up, and the steps run where fixed ones fail at the mirror
 * point.
 * When to use it: orbits that mirror where |B| is >= ~100x its minimum
 * (dipole mirror latitudes above ~60 deg: loss-cone and near-loss-cone
 * particles; periods gain from ~75 deg, |B| >= ~7000x), for trajectories,
 * phases and anything that needs the orbit's position at given times; not
 * for tokamak orbits (|B| varies by ~1.5x: plain gc-gl4 is as good).
 *
 * Output times (this file's per-lane path; the dipole's lands beside its
 * grid instead, gc_sundman_dipole.c).  The lanes run on their own clocks (the evolve layer's
 * loop for such methods, gcp_evolve_adaptive with no GSL stepper: begin,
 * lane states, slicing at the sampling times, retirement, the sampler; this
 * file supplies the lane's init and its run to the next sampling time); at
 * each sampling time
 * (and at the end, t0 + nsteps dt) a lane lands exactly: its last s-step
 * before the target is replaced by one of size ds' found by secant iteration
 * so that t(ds') = t_target to 4 ulp (then set to t_target).  That landing
 * step is again a Gauss-Legendre step, but ds' depends on the state, so the
 * map over a sampling interval is symplectic except for that one step: the
 * energy stays bounded (K is conserved by each step), exact symplecticity
 * holds between samples.  Sample sparsely.
 *
 * Statuses as gc-gl4's; the stepped lanes are checked after every s-step
 * (domain, field, adiabaticity at the new point); `steps` counts s-steps.
 */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/gc.h"
#include "gcpush/particles.h"
#include "block_priv.h"
#include "evolve_priv.h"
#include "gc_gauss_priv.h"
#include "gc_priv.h"
#include "gc_sundman_priv.h"

#define SD_LAND_MAXIT 12

/* After a step: X, p_par into block lane i, and the lane's status there. */
static int sd_after(const struct gl_ctx *C, const struct gcp_gc_consts *k, struct gl_lane *L,
                    struct gcp_block *b, size_t i, double amax)
{
    double X[3], ppar, dX[3], dp;
    int st = C->chart.from_canon(&C->chart, k, L->z, L->aux[0], X, &ppar);
    L->fail = GCP_FAIL_CHART;
    if (st) return st == GCP_NONFINITE ? st : GCP_STEP_FAILED;
    b->x[i] = X[0], b->y[i] = X[1], b->z[i] = X[2];
    b->ppar[i] = ppar;
    st = gcp_gc_eval(C->chart.field, L->t, k->q, k->m, X, ppar, k->mu, amax, dX, &dp);
    return st ? st : gcp_point_domain_status(C->chart.field, X);
}

/* The last step before t_target: ds' with t(ds') = t_target, by secant
 * iteration through (0, t0) (t(ds) is smooth and nearly linear). */
static int sd_land(const struct gl_ctx *C, const struct gcp_gc_consts *k, struct gl_lane *L,
                   double t_target, double ds)
{
    const struct gl_lane save = *L;
    const double span = t_target - save.t;
    double dsk = ds * 0.5; /* first guess: below the nominal step */
    {
        double w, aux[2] = {L->aux[0][0], L->aux[0][1]};
        if (gcp_sundman_w(C, k, L, aux, &w) == 0) dsk = span / w;
    }
    for (int it = 0; it < SD_LAND_MAXIT; it++) {
        *L = save;
        if (gcp_gl_step_canon(C, k, L, dsk)) {
            const int why = L->fail;
            *L = save;
            L->fail = why;
            return GCP_STEP_FAILED;
        }
        const double got = L->t - save.t;
        if (fabs(L->t - t_target) <= 4.0 * DBL_EPSILON * fabs(t_target) + DBL_MIN) {
            L->t = t_target;
            return 0;
        }
        if (!(got > 0.0)) break;
        dsk *= span / got;
    }
    *L = save;
    L->fail = GCP_FAIL_NO_CONVERGENCE; /* the secant did not land on t_target */
    return GCP_STEP_FAILED;
}

int gcp_sundman_lane_init(const struct gl_ctx *C, const struct gcp_block *b, size_t i, double t0,
                          struct gl_lane *L)
{
    const struct gcp_gc_consts k = {b->q, b->m, b->mu[i]};
    int st = gcp_gl_init(C, b, i, t0, L);
    double H = NAN, dH[4], Bm = NAN, dB[4];
    if (!st) st = C->chart.hamiltonian(&C->chart, &k, L->z, L->aux[0], &H, dH);
    if (!st) st = C->chart.field_strength(&C->chart, &k, L->z, L->aux[0], &Bm, dB);
    L->t = t0, L->pt = -H, L->Bref = Bm;
    return st;
}

/* The evolve layer's init (gcp_evolve_adaptive): the lane in extended
 * phase space at t0. */
static int sd_init(const struct gcp_evolve *ev, void *ctx, const struct gcp_block *b, size_t i,
                   void *lane)
{
    const int st = gcp_sundman_lane_init(ctx, b, i, ev->o->t0, lane);
    return st == 0 || st == GCP_NONFINITE ? st : GCP_STEP_FAILED;
}

/* The evolve layer's run: lane i by s-steps of ds = dt until it lands on t1
 * (the last step by sd_land), each step followed by the lane's status at
 * its new point (sd_after); b->t[i], b->steps[i] written. */
static int32_t sd_run(const struct gcp_evolve *ev, void *ctx, struct gcp_block *b, size_t i,
                      double t1, void *lane)
{
    const struct gl_ctx *C = ctx;
    struct gl_lane *L = lane;
    const struct gcp_gc_consts k = {b->q, b->m, b->mu[i]};
    const double ds = ev->o->dt;
    int64_t steps = 0;
    int st = 0;
    while (!st && L->t < t1) {
        /* the next step's dt ~ w ds: land when it would reach the target */
        double w, aux[2] = {L->aux[0][0], L->aux[0][1]};
        st = gcp_sundman_w(C, &k, L, aux, &w);
        if (st) break;
        if (L->t + 1.5 * ds * w >= t1)
            st = sd_land(C, &k, L, t1, ds);
        else
            st = gcp_gl_step_canon(C, &k, L, ds);
        if (st) break;
        steps++;
        st = sd_after(C, &k, L, b, i, ev->o->adiabaticity_max);
    }
    if (st == GCP_STEP_FAILED) st = gcp_lane_fail(b, i, L->fail);
    b->t[i] = L->t;
    b->steps[i] += steps;
    return st;
}

static size_t sd_advance(struct gcp_block *b, const struct gcp_field *f,
                         const struct gcp_push_opts *o, const struct gcp_sampler *s,
                         const struct gl_tableau *tab)
{
    /* the dipole: its line coordinates, fused (gc_sundman_dipole.c) */
    size_t live;
    if (gcp_sundman_dipole_advance(b, f, o, s, tab, &live) == 0) return live;
    struct gl_ctx C = {.tab = tab, .sundman_a = GCP_SUNDMAN_A};
    if (gcp_canon_chart_create(f, &C.chart, NULL, 0) || !C.chart.field_strength) {
        gcp_canon_chart_destroy(&C.chart);
        return gcp_evolve_fail_all(b, gcp_gc_block_begin(b, f, o), o->t0, GCP_FAIL_UNSUPPORTED);
    }
    const struct gcp_adaptive_stepper st = {
        .gc = 1,
        .lane_size = sizeof(struct gl_lane),
        .type = NULL, /* the steps are the method's: fixed in s */
        .init = sd_init,
        .run = sd_run,
    };
    const size_t n = gcp_evolve_adaptive(b, f, o, s, &st, &C);
    gcp_canon_chart_destroy(&C.chart);
    return n;
}

/* A chart, and one that gives |B| (the time transformation's w). */
static int sd_applies(const struct gcp_field *f, char *why, size_t whylen)
{
    struct gcp_canon_chart c;
    if (gcp_canon_chart_create(f, &c, why, whylen)) return GCP_ERR_STATE;
    const int ok = c.field_strength != NULL;
    if (!ok && why && whylen)
        snprintf(why, whylen, "the %s chart gives no |B| for the time transformation", c.name);
    gcp_canon_chart_destroy(&c);
    return ok ? 0 : GCP_ERR_STATE;
}

static size_t sd2_advance(struct gcp_block *b, const struct gcp_field *f,
                          const struct gcp_pusher_type *p, const struct gcp_push_opts *o,
                          const struct gcp_sampler *s)
{
    (void)p;
    return sd_advance(b, f, o, s, &gcp_gl2_tableau);
}

static size_t sd4_advance(struct gcp_block *b, const struct gcp_field *f,
                          const struct gcp_pusher_type *p, const struct gcp_push_opts *o,
                          const struct gcp_sampler *s)
{
    (void)p;
    return sd_advance(b, f, o, s, &gcp_gl4_tableau);
}

const struct gcp_pusher_type gcp_pusher_gc_gl2_sundman = {
    .name = "gc-gl2-sundman",
    .doc = "guiding centre, gc-gl2 with symplectic adaptive steps (Sundman transformation, "
           "dt ~ |B|^-1/4; dt = the step at the start)",
    .order = 2,
    .kind = GCP_GUIDING_CENTRE,
    .advance = sd2_advance,
    .applies = sd_applies,
};

const struct gcp_pusher_type gcp_pusher_gc_gl4_sundman = {
    .name = "gc-gl4-sundman",
    .doc = "guiding centre, gc-gl4 with symplectic adaptive steps (Sundman transformation, "
           "dt ~ |B|^-1/4; dt = the step at the start)",
    .order = 4,
    .kind = GCP_GUIDING_CENTRE,
    .advance = sd4_advance,
    .applies = sd_applies,
};
