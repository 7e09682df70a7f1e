/* bench_gc_merit -- `make bench`, issue 11: what the symplectic guiding-
 * centre methods buy, in CPU time, against the non-symplectic ones.
 *
 * Ensemble: 64 protons of 10 MeV in the dipole (no atmosphere), L = 3.9 ..
 * 4.1, equatorial pitch 40 .. 50 deg, pushed as one block (so gc-rk4 keeps
 * its vectorised block form).  Tb_min, Td: the exact dipole quadratures
 * (tests/unit/test_gc_util.h, gc_dip_theory).  CPU time of this process
 * (CLOCK_PROCESS_CPUTIME_ID), best of REPS: the figures are meant as ratios
 * within one run.
 *
 * 1. Time to a drift period accurate to 1e-4.  Each method pushes the block
 *    over 10 Tb_min; the drift rate is the azimuth advance over that time,
 *    against gc-rk8pd at tolerance 1e-13 from the same starts (an
 *    independent, far more accurate reference: its error is below 1e-10 of
 *    the drift).  The step (steps per Tb_min, or the tolerance of the
 *    adaptive methods) is scanned from coarse to fine; the first setting at
 *    which the worst lane's relative error and that of the next finer setting
 *    are both below 1e-4 wins (two, so that an accidental zero of the error
 *    does not count).  Reported: CPU us per particle and per drift period.
 *
 * 2. Long-run figure of merit: CPU time to push 1e4 drift periods (of the
 *    slowest lane) with the energy error kept below 1e-4.  Each setting
 *    pushes NB bounces with the energy sampled once per Tb_min; per lane
 *    the least-squares trend of the relative energy error is extrapolated:
 *    err(T) = max |dH/H| over the run + |trend| (T - t_run), T = 1e4 Td.  A
 *    symplectic method's trend is its fit noise (its error is bounded:
 *    tests/unit/test_gc_symplectic.c measures it over 1e6 steps), a
 *    non-symplectic method's is its secular drift.  The coarsest setting
 *    with err(T) <= 1e-4 for every lane wins; its CPU time (best of REPS
 *    runs) is scaled from the NB-bounce run to T (extrapolated, not run).
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "gcpush/field.h"
#include "gcpush/gc.h"
#include "gcpush/particles.h"
#include "gcpush/pusher.h"
#include "test_gc_util.h"

#define NL 64        /* lanes */
#define REPS 3
#define NB_PHASE 10  /* Tb_min of the drift-rate run */
#define NB_ENERGY 60 /* Tb_min of the energy run */
#define TARGET 1e-4

static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

struct ens {
    struct gcp_field *f;
    double q, m, X[NL][3], ppar[NL], mu[NL], Td[NL];
    double tb_min, td_max;
};

static void ens_init(struct ens *E)
{
    E->f = gcp_field_dipole_create(GC_B0, 0, 0.0, 0.0);
    E->q = GCP_E_CHARGE, E->m = GCP_M_PROTON;
    const double T = 10e6 * GCP_E_CHARGE, p = gc_p_of_T(T, E->m);
    E->tb_min = INFINITY, E->td_max = 0.0;
    for (int i = 0; i < NL; i++) {
        const double L = 3.9 + 0.2 * (i % 8) / 7.0;
        const double a = (40.0 + 10.0 * (i / 8) / 7.0) * GCP_PI / 180.0;
        const double lon = 2.0 * GCP_PI * i / NL;
        E->X[i][0] = L * GC_RE * cos(lon), E->X[i][1] = L * GC_RE * sin(lon), E->X[i][2] = 0.0;
        E->ppar[i] = p * cos(a);
        E->mu[i] = p * sin(a) * p * sin(a) / (2.0 * E->m * gc_Bmag(E->f, E->X[i]));
        double Tb, latm;
        gc_dip_theory(E->f, E->q, E->m, T, L, a, &Tb, &E->Td[i], &latm);
        E->tb_min = fmin(E->tb_min, Tb);
        E->td_max = fmax(E->td_max, E->Td[i]);
    }
}

static void fill(struct gcp_block *b, const struct ens *E)
{
    b->q = E->q, b->m = E->m;
    for (size_t i = 0; i < NL; i++) {
        b->x[i] = E->X[i][0], b->y[i] = E->X[i][1], b->z[i] = E->X[i][2];
        b->ppar[i] = E->ppar[i], b->mu[i] = E->mu[i];
        b->status[i] = 0, b->steps[i] = 0, b->t[i] = 0.0, b->index[i] = i;
        b->step_failure[i] = 0;
    }
    b->n_active = NL;
}

/* One method setting: fixed methods take `per` steps per Tb_min, adaptive
 * ones run at tolerance `tol` with output interval Tb_min. */
struct setting {
    const struct gcp_pusher_type *p;
    int adaptive;
    double per, tol;
};

static struct gcp_push_opts opts_for(const struct ens *E, const struct setting *s, int nb)
{
    struct gcp_push_opts o = {0.0, 0.0, 0, 0.0, 0.0};
    if (s->adaptive) {
        /* output interval Tb_min / 8 (also the first trial step: one of 10
         * Tb_min puts GSL's trial stages where B*_par < 0, and gc-rk45/rk8pd
         * then stop the lane NONADIABATIC instead of shrinking the step) */
        o.dt = E->tb_min / 8.0;
        o.nsteps = 8 * (int64_t)nb;
        o.tolerance = s->tol;
    } else {
        o.nsteps = (int64_t)ceil(nb * s->per);
        o.dt = nb * E->tb_min / (double)o.nsteps;
    }
    return o;
}

/* Azimuth advance of every lane over nb Tb_min; CPU seconds (best of reps);
 * 0 if every lane stayed alive. */
static int push_phase(const struct ens *E, const struct setting *s, int nb, int reps,
                      double dphi[NL], double *cpu)
{
    struct gcp_block b;
    if (gcp_block_alloc(&b, NL)) return -1;
    const struct gcp_push_opts o = opts_for(E, s, nb);
    *cpu = INFINITY;
    size_t alive = 0;
    for (int r = 0; r < reps; r++) {
        fill(&b, E);
        const double c0 = cpu_now();
        alive = s->p->advance(&b, E->f, s->p, &o, NULL);
        *cpu = fmin(*cpu, cpu_now() - c0);
    }
    for (size_t i = 0; i < NL; i++) {
        const size_t k = b.index[i];
        dphi[k] = remainder(atan2(b.y[i], b.x[i]) - atan2(E->X[k][1], E->X[k][0]), 2.0 * GCP_PI);
    }
    if (alive != NL && getenv("MERIT_DEBUG"))
        for (size_t i = alive; i < NL; i++)
            fprintf(stderr, "%s: lane %zu status %s (%s)\n", s->p->name, b.index[i],
                    gcp_status_name(b.status[i]), gcp_step_failure_name(b.step_failure[i]));
    gcp_block_free(&b);
    return alive == NL ? 0 : -1;
}

/* Energy samples: per lane sums for the least-squares trend. */
struct esum {
    const struct ens *E;
    double H0[NL], n[NL], st[NL], se[NL], stt[NL], ste[NL], emax[NL];
};

static void energy_sample(const struct gcp_block *b, double t, void *ctx)
{
    struct esum *S = ctx;
    for (size_t i = 0; i < b->n_active; i++) {
        const size_t k = b->index[i];
        const double X[3] = {b->x[i], b->y[i], b->z[i]};
        double H;
        if (gcp_gc_energy(S->E->f, t, b->q, b->m, X, b->ppar[i], b->mu[i], &H)) continue;
        const double e = H / S->H0[k] - 1.0;
        S->n[k] += 1, S->st[k] += t, S->se[k] += e, S->stt[k] += t * t, S->ste[k] += t * e;
        S->emax[k] = fmax(S->emax[k], fabs(e));
    }
}

/* err(T) of the worst lane (see the file comment) and the CPU seconds of
 * the NB_ENERGY-bounce run; -1 when a lane stopped. */
static int push_energy(const struct ens *E, const struct setting *s, double T, double *err,
                       double *cpu)
{
    struct gcp_block b;
    if (gcp_block_alloc(&b, NL)) return -1;
    struct esum S;
    memset(&S, 0, sizeof S);
    S.E = E;
    fill(&b, E);
    for (size_t i = 0; i < NL; i++)
        gcp_gc_energy(E->f, 0.0, E->q, E->m, E->X[i], E->ppar[i], E->mu[i], &S.H0[i]);
    const struct gcp_push_opts o = opts_for(E, s, NB_ENERGY);
    const int64_t every = (int64_t)llround((double)o.nsteps / NB_ENERGY);
    const struct gcp_sampler smp = {every > 0 ? every : 1, energy_sample, &S};
    const double c0 = cpu_now();
    const size_t alive = s->p->advance(&b, E->f, s->p, &o, &smp);
    *cpu = cpu_now() - c0;
    gcp_block_free(&b);
    if (alive != NL) return -1;
    const double t_run = NB_ENERGY * E->tb_min;
    *err = 0.0;
    for (int k = 0; k < NL; k++) {
        const double den = S.n[k] * S.stt[k] - S.st[k] * S.st[k];
        const double slope = den > 0.0 ? (S.n[k] * S.ste[k] - S.st[k] * S.se[k]) / den : INFINITY;
        *err = fmax(*err, S.emax[k] + fabs(slope) * (T - t_run));
    }
    return 0;
}

static void scan(const struct ens *E, const struct gcp_pusher_type *p, int adaptive,
                 const double dphi_ref[NL])
{
    /* 1. drift period to 1e-4 */
    double best_us = NAN, best_set = NAN, prev_cpu = NAN, prev_set = NAN;
    int prev_ok = 0;
    for (int j = 0; j < 40; j++) {
        struct setting s = {p, adaptive, 6.0 * pow(1.25, j), 1e-3 * pow(10.0, -0.5 * j)};
        if (adaptive && s.tol < 1e-13) break;
        double dphi[NL], cpu;
        if (push_phase(E, &s, NB_PHASE, REPS, dphi, &cpu)) {
            prev_ok = 0;
            continue;
        }
        double err = 0.0;
        for (int k = 0; k < NL; k++) err = fmax(err, fabs(dphi[k] / dphi_ref[k] - 1.0));
        const int ok = err <= TARGET;
        if (ok && prev_ok) {
            /* per particle, per drift period (mean Td of the lanes ~ Td of each) */
            best_us = 1e6 * prev_cpu / NL * (E->td_max / (NB_PHASE * E->tb_min));
            best_set = prev_set;
            break;
        }
        prev_ok = ok, prev_cpu = cpu, prev_set = adaptive ? s.tol : s.per;
    }
    /* 2. 1e4 drift periods with the energy error <= 1e-4 */
    const double T = 1e4 * E->td_max;
    double long_s = NAN, long_set = NAN, long_err = NAN;
    for (int j = 0; j < 40; j++) {
        struct setting s = {p, adaptive, 6.0 * pow(1.25, j), 1e-3 * pow(10.0, -0.5 * j)};
        if (adaptive && s.tol < 1e-13) break;
        if (!adaptive && s.per > 4000.0) break;
        double err, cpu;
        if (push_energy(E, &s, T, &err, &cpu)) continue;
        if (err <= TARGET) {
            /* the winning setting's CPU time: best of REPS, as in part 1 (a
             * single run's varies with the machine's load) */
            for (int r = 1; r < REPS; r++) {
                double e2, c2;
                if (!push_energy(E, &s, T, &e2, &c2)) cpu = fmin(cpu, c2);
            }
            long_s = cpu / NL * T / (NB_ENERGY * E->tb_min);
            long_set = adaptive ? s.tol : s.per;
            long_err = err;
            break;
        }
    }
    char a[32], c[32];
    if (adaptive) {
        snprintf(a, sizeof a, "tol %.0e", best_set);
        snprintf(c, sizeof c, "tol %.0e", long_set);
    } else {
        snprintf(a, sizeof a, "%.0f/Tb", best_set);
        snprintf(c, sizeof c, "%.0f/Tb", long_set);
    }
    printf("  %-16s %14.1f %-10s %16.3g %-10s %9.1e\n", p->name, best_us, a, long_s, c, long_err);
}

int main(void)
{
    struct ens E;
    ens_init(&E);
    printf("Issue 11: figure of merit, 64 protons of 10 MeV at L = 3.9-4.1, pitch 40-50 deg "
           "(Tb_min %.3f s, Td_max %.1f s), CPU time\n", E.tb_min, E.td_max);
    /* the reference drift: gc-rk8pd at 1e-13 */
    double dphi_ref[NL], cpu;
    const struct setting ref = {&gcp_pusher_gc_rk8pd, 1, 0.0, 1e-13};
    if (push_phase(&E, &ref, NB_PHASE, 1, dphi_ref, &cpu)) {
        printf("  reference failed\n");
        return 1;
    }
    printf("  %-16s %14s %-10s %16s %-10s %9s\n", "method", "Td to 1e-4", "at", "1e4 Td, dH<1e-4",
           "at", "dH(1e4Td)");
    printf("  %-16s %14s %-10s %16s %-10s %9s\n", "", "[us/particle]", "", "[CPU s/particle]",
           "", "(extrap.)");
    const struct gcp_pusher_type *fixed[] = {&gcp_pusher_gc_rk4, &gcp_pusher_gc_midpoint_pphi,
                                             &gcp_pusher_gc_gl2, &gcp_pusher_gc_gl4};
    for (size_t k = 0; k < sizeof fixed / sizeof fixed[0]; k++) scan(&E, fixed[k], 0, dphi_ref);
    scan(&E, &gcp_pusher_gc_rk45, 1, dphi_ref);
    scan(&E, &gcp_pusher_gc_rk8pd, 1, dphi_ref);
    printf("  (symplectic: gc-gl2, gc-gl4; the long-run CPU time is the %d-bounce run's scaled "
           "to 1e4 Td; NaN: not reached in the scan)\n", NB_ENERGY);
    gcp_field_free(E.f);
    return 0;
}
