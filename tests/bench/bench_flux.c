/* bench_flux -- cost per step of the symplectic methods in the flux charts
 * (issue 11): gc-gl2, gc-gl4 against gc-rk4 in the analytic tokamak (exact
 * chart) and in DIII-D (G-EQDSK, tabulated chart), one particle each, the
 * orbits of tests/unit/test_gc_symplectic_flux.c's long runs (25.37 steps
 * per bounce), with the energy and P_phi sampled every step as there.
 * CPU time per step; ratios to gc-rk4 at the same step.  Not a test. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "gcpush/grid.h"
#include "test_gc_util.h"

static int NSTEPS = 20000;

struct sys {
    const char *name;
    struct gcp_field *f;
    double q, m, mu, X[3], ppar, Tb;
};

static double cpu_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

struct sample_ctx {
    const struct sys *S;
    double acc;
};

static int sample_cb(double t, const double X[3], double ppar, void *v)
{
    (void)t;
    struct sample_ctx *c = v;
    double H, P;
    gcp_gc_energy(c->S->f, 0, c->S->q, c->S->m, X, ppar, c->S->mu, &H);
    gcp_gc_pphi(c->S->f, 0, c->S->q, X, ppar, &P);
    c->acc += H + P;
    return 0;
}

/* Bounce period by gc-rk8pd: first to third sign change of p_par. */
static void sys_init(struct sys *S, double T, double xi, double R, double Z)
{
    S->q = GCP_E_CHARGE, S->m = GCP_M_PROTON;
    S->X[0] = R, S->X[1] = 0.0, S->X[2] = Z;
    const double p = gc_p_of_T(T, S->m);
    S->ppar = p * xi;
    S->mu = p * p * (1 - xi * xi) / (2 * S->m * gc_Bmag(S->f, S->X));
    S->Tb = gc_bounce_period(S->f, S->q, S->m, S->mu, S->X, S->ppar,
                             gc_tokamak_tb_guess(R, p, S->m));
    if (!isfinite(S->Tb)) {
        fprintf(stderr, "bench_flux: %s: no bounce\n", S->name);
        exit(1);
    }
}

/* h = T_b / (25.37 sub): gc-rk4 at sub = 12 (the long runs' equal-cost
 * comparison; at 25 steps a bounce it leaves DIII-D's chart). */
static double us_per_step(const struct sys *S, const struct gcp_pusher_type *p, double sub)
{
    struct sample_ctx c = {S, 0.0};
    double X[3] = {S->X[0], S->X[1], S->X[2]}, pp = S->ppar, t = 0.0;
    const double h = S->Tb / (25.37 * sub);
    const struct gcp_push_opts o = {0.0, h, NSTEPS, 0.0, 0.0};
    /* one short push first: the chart's table is built (and cached) there */
    const struct gcp_push_opts o1 = {0.0, h, 1, 0.0, 0.0};
    double X1[3] = {S->X[0], S->X[1], S->X[2]}, p1 = S->ppar, t1 = 0.0;
    gcp_gc_push(S->f, p, S->q, S->m, &o1, &t1, X1, &p1, S->mu, NULL, NULL);
    const double c0 = cpu_s();
    const int st = gcp_gc_push(S->f, p, S->q, S->m, &o, &t, X, &pp, S->mu, sample_cb, &c);
    const double dt = cpu_s() - c0;
    if (st) printf("  (%s %s: status %d)\n", S->name, p->name, st);
    return 1e6 * dt / NSTEPS;
}

int main(int argc, char **argv)
{
    /* optional: bench_flux FIELD METHOD [NSTEPS] (0/1, 0..2): that one only (for perf) */
    const int only_k = argc > 2 ? atoi(argv[1]) : -1, only_j = argc > 2 ? atoi(argv[2]) : -1;
    if (argc > 3) NSTEPS = atoi(argv[3]);
    struct sys S[2];
    S[0].name = "tokamak p+ 100 keV";
    S[0].f = gcp_field_tokamak_create(2.5, 3.0, 1.0, 1.1, 3.5);
    sys_init(&S[0], 1e5 * GCP_E_CHARGE, 0.3, 3.5, 0.0);
    struct gcp_error err = {0};
    S[1].name = "DIII-D p+ 50 keV";
    if (gcp_field_eqdsk_load("../../fields/data/diiid_184833.geqdsk", 0, &S[1].f, &err) &&
        gcp_field_eqdsk_load("fields/data/diiid_184833.geqdsk", 0, &S[1].f, &err)) {
        printf("bench_flux: %s\n", err.msg);
        return 1;
    }
    /* psi_N = 0.25 on the outboard side (the chart's rho = 0.5, eta = 0) */
    sys_init(&S[1], 5e4 * GCP_E_CHARGE, 0.3, 2.0127596328434527, -0.025610364973236297);
    printf("flux charts: CPU us per step at 25.37 steps per bounce (gc-rk4: 12x that), energy "
           "and P_phi sampled every step (%d steps)\n",
           NSTEPS);
    const struct gcp_pusher_type *ps[] = {&gcp_pusher_gc_rk4, &gcp_pusher_gc_gl2,
                                          &gcp_pusher_gc_gl4};
    for (int k = 0; k < 2; k++) {
        double us[3];
        for (int j = 0; j < 3; j++)
            us[j] = (only_k < 0 || (k == only_k && j == only_j))
                        ? us_per_step(&S[k], ps[j], j ? 1.0 : 12.0)
                        : 1.0;
        printf("  %-18s gc-rk4 %6.2f   gc-gl2 %6.2f (%4.1fx)   gc-gl4 %6.2f (%4.1fx)\n",
               S[k].name, us[0], us[1], us[1] / us[0], us[2], us[2] / us[0]);
        gcp_field_free(S[k].f);
    }
    return 0;
}
