/* test_conformance.h -- the tables and static helpers of the conformance
 * battery (test_conformance.c): the per-method expectations, the per-model
 * table with how each registry model is built, deterministic points, one
 * test particle per model, the independent GSL rk8pd reference and a
 * one-lane push. */
#ifndef GCPUSH_TESTS_CONFORMANCE_H
#define GCPUSH_TESTS_CONFORMANCE_H

#include <criterion/criterion.h>
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <gsl/gsl_errno.h>
#include <gsl/gsl_odeiv2.h>

#include "gcpush/error.h"
#include "gcpush/field.h"
#include "gcpush/field_kernels.h"
#include "gcpush/gc.h"
#include "gcpush/grid.h"
#include "gcpush/grid_file.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "gcpush/pusher.h"

#define RE GCP_EARTH_RADIUS
#define EPS DBL_EPSILON
#define NPT 24 /* points per model (not a multiple of a vector width: loop tails) */

/* ---- per-method expectations ------------------------------------------- */

struct method_row {
    const char *name;
    int order;               /* global order the step halving must show */
    enum gcp_pusher_kind kind;
    int adaptive;            /* takes a tolerance: convergence in tolerance, not dt */
    int energy_roundoff;     /* [bool] energy kept to round-off in a static pure-B field */
    int newtonian;           /* [bool] full orbit, u = v (non-relativistic): the order is
                                measured against the Newtonian reference (a relativistic one
                                would show the model's error, O(v^2/c^2), as a floor) */
};

/* The energy column: every full-orbit kick here is a rotation of u in pure B
 * (|u| kept by construction, kernels.h), so gamma moves only by round-off;
 * the guiding-centre methods integrate (X, p_par) with mu fixed and
 * H = gamma(p_par, mu, |B(X)|) m c^2 is kept only to their truncation error
 * (none of them is energy-exact: the Gauss-Legendre methods are symplectic,
 * bounded error; gc-midpoint-pphi keeps p_phi exactly, not H). */
static const struct method_row methods[] = {
    {"boris", 2, GCP_FULL_ORBIT, 0, 1, 0},
    {"boris-zu", 2, GCP_FULL_ORBIT, 0, 1, 0},
    {"vay", 2, GCP_FULL_ORBIT, 0, 1, 0},
    {"higuera-cary", 2, GCP_FULL_ORBIT, 0, 1, 0},
    {"boris-nr", 2, GCP_FULL_ORBIT, 0, 1, 1},
    {"gc-rk4", 4, GCP_GUIDING_CENTRE, 0, 0, 0},
    {"gc-rk45", 4, GCP_GUIDING_CENTRE, 1, 0, 0},
    {"gc-rk8pd", 8, GCP_GUIDING_CENTRE, 1, 0, 0},
    {"gc-midpoint-pphi", 2, GCP_GUIDING_CENTRE, 0, 0, 0},
    {"gc-gl2", 2, GCP_GUIDING_CENTRE, 0, 0, 0},
    {"gc-gl4", 4, GCP_GUIDING_CENTRE, 0, 0, 0},
    {"gc-gl2-sundman", 2, GCP_GUIDING_CENTRE, 0, 0, 0},
    {"gc-gl4-sundman", 4, GCP_GUIDING_CENTRE, 0, 0, 0},
};

static const struct method_row *method_row_of(const struct gcp_pusher_type *p)
{
    for (size_t i = 0; i < sizeof methods / sizeof methods[0]; i++)
        if (strcmp(methods[i].name, p->name) == 0) return &methods[i];
    return NULL;
}

/* ---- per-model table ------------------------------------------------------
 * How to build each model from its run-file keys (the registry's `build`),
 * a box inside its domain in cylindrical (R, Z) for the field checks, its
 * length scale L (the distance over which B changes by O(1), or a grid
 * cell for the gridded models, whose interpolant varies on that scale), and
 * one test particle (a proton) for the pushes. */
struct model_row {
    const char *name;
    void (*keys)(const struct gcp_field_type *t, struct gcp_field_args *a);
    double Rlo, Rhi, Zlo, Zhi; /* [m] box of the field-check points */
    double L;                  /* [m] length scale of B (T1 below) */
    double x0[3];              /* [m] particle start */
    double T;                  /* [J] kinetic energy */
    double pitch;              /* [rad] angle of u to B at x0 */
    double Lorb;               /* [m] guiding-centre push: the push lasts Lorb/(2v) */
    /* [bool] grad B is smooth (C-infinity) along the orbit.  The guiding-centre
     * equations take grad B; a model that interpolates psi with a cubic
     * spline has grad B only C0 (kinks at the cell faces), which caps the
     * order any fixed-step method can show at ~1 (measured 1.1-1.3 for
     * gc-rk4 in the gridded dipole): there step halving must still
     * converge, but no order is asserted.  B itself (C1) keeps the
     * full-orbit methods at order 2. */
    int smooth;
    /* GCP_CAP_* this instance must declare (gcp_field_caps): the checks take
     * what to test from the capabilities themselves; this column catches a
     * capability that is lost (a model that stops giving A would otherwise
     * just skip its curl A check). */
    unsigned caps;
};

static char tmpdir[64];

static int key_index(const struct gcp_field_type *t, const char *name)
{
    for (int k = 0; k < GCP_FIELD_MAX_KEYS && t->keys[k].name; k++)
        if (strcmp(t->keys[k].name, name) == 0) return k;
    cr_assert_fail("model %s has no key %s", t->name, name);
    return -1;
}
static void set_num(const struct gcp_field_type *t, struct gcp_field_args *a, const char *key,
                    double v0, double v1, double v2)
{
    const int k = key_index(t, key);
    a->v[k][0] = v0, a->v[k][1] = v1, a->v[k][2] = v2;
    a->given[k] = 1;
}
static void set_text(const struct gcp_field_type *t, struct gcp_field_args *a, const char *key,
                     const char *s)
{
    const int k = key_index(t, key);
    snprintf(a->text[k], sizeof a->text[k], "%s", s);
    a->given[k] = 1;
}

static void keys_uniform(const struct gcp_field_type *t, struct gcp_field_args *a)
{
    set_num(t, a, "B", 0.1, -0.2, 0.9); /* off the axes: no component is special */
}
static void keys_mirror(const struct gcp_field_type *t, struct gcp_field_args *a)
{
    set_num(t, a, "B0", 1.0, 0, 0), set_num(t, a, "Lm", 1.0, 0, 0);
    set_num(t, a, "z_max", 2.0, 0, 0), set_num(t, a, "r_max", 1.0, 0, 0);
}
static void keys_dipole(const struct gcp_field_type *t, struct gcp_field_args *a) { (void)t, (void)a; }
static void keys_tokamak(const struct gcp_field_type *t, struct gcp_field_args *a)
{
    set_num(t, a, "B0", 2.5, 0, 0), set_num(t, a, "R0", 3.0, 0, 0), set_num(t, a, "a", 1.0, 0, 0);
    set_num(t, a, "q0", 1.1, 0, 0), set_num(t, a, "qa", 3.5, 0, 0);
}
/* The grid model: the analytic dipole sampled here on an (R, Z) grid of
 * 2-6 RE x -2-2 RE with its psi, read back with use_psi (B_R, B_Z from the
 * spline of psi: divergence-free and consistent with psi by construction). */
static void keys_grid(const struct gcp_field_type *t, struct gcp_field_args *a)
{
    static char path[128];
    snprintf(path, sizeof path, "%s/dipole_psi.h5", tmpdir);
    if (access(path, R_OK) != 0) {
        struct gcp_field *dip = gcp_field_dipole_create(GCP_EARTH_B0, 0, RE, 0.0);
        const size_t nR = 41, nZ = 41;
        struct gcp_grid_data d;
        memset(&d, 0, sizeof d);
        d.geometry = GCP_GRID_AXISYMMETRIC;
        d.n[0] = nR, d.n[1] = nZ, d.n[2] = 1;
        d.origin[0] = 2 * RE, d.origin[1] = -2 * RE;
        d.spacing[0] = 4 * RE / (double)(nR - 1), d.spacing[1] = 4 * RE / (double)(nZ - 1);
        for (int c = 0; c < 3; c++) d.B[c] = calloc(nR * nZ, sizeof(double));
        d.psi = calloc(nR * nZ, sizeof(double));
        d.r_inner = 0.0, d.r_outer = INFINITY, d.z_max = INFINITY;
        for (size_t j = 0; j < nZ; j++)
            for (size_t i = 0; i < nR; i++) {
                const double x[3] = {d.origin[0] + (double)i * d.spacing[0], 0.0,
                                     d.origin[1] + (double)j * d.spacing[1]};
                struct gcp_field_sample s = {.need = GCP_NEED_B};
                gcp_field_eval(dip, 0.0, x, &s);
                d.B[0][i + nR * j] = s.B[0], d.B[1][i + nR * j] = s.B[1];
                d.B[2][i + nR * j] = s.B[2];
                cr_assert_eq(gcp_field_psi(dip, x, &d.psi[i + nR * j]), 0);
            }
        struct gcp_error err = {0, ""};
        cr_assert_eq(gcp_grid_write(path, &d, "conformance dipole", &err), 0, "%s", err.msg);
        gcp_grid_data_free(&d);
        gcp_field_free(dip);
    }
    set_text(t, a, "file", path);
    set_num(t, a, "use_psi", 1, 0, 0);
    a->grid_read = gcp_grid_read; /* the io layer's HDF5 reader, as gcpush hands it in */
}
static void keys_eqdsk(const struct gcp_field_type *t, struct gcp_field_args *a)
{
    set_text(t, a, "file", "fields/data/diiid_184833.geqdsk");
}
static void keys_igrf(const struct gcp_field_type *t, struct gcp_field_args *a)
{
    set_text(t, a, "file", "fields/data/igrf14coeffs.txt");
    set_num(t, a, "epoch", 2020.0, 0, 0);
}

#define KEV (1e3 * GCP_E_CHARGE)
#define MEV (1e6 * GCP_E_CHARGE)
static const struct model_row models[] = {
    {"uniform", keys_uniform, 0.0, 2.0, -1.0, 1.0, 1.0, {0.3, 0.2, 0.1}, 1 * KEV, 1.0, 1.0, 1,
     GCP_CAP_B | GCP_CAP_GRADB | GCP_CAP_A | GCP_CAP_UNIFORM},
    {"mirror", keys_mirror, 0.0, 0.5, -1.0, 1.0, 1.0, {0.05, 0.02, 0.1}, 1 * KEV, 1.0, 1.0, 1,
     GCP_CAP_B | GCP_CAP_GRADB | GCP_CAP_A | GCP_CAP_AXISYM},
    {"dipole", keys_dipole, 2 * RE, 6 * RE, -2 * RE, 2 * RE, RE, {4 * RE, 0.0, 0.3 * RE},
     1 * MEV, 1.0, RE, 1, GCP_CAP_B | GCP_CAP_GRADB | GCP_CAP_A | GCP_CAP_PSI | GCP_CAP_AXISYM | GCP_CAP_DIPOLE_L},
    {"tokamak", keys_tokamak, 2.5, 3.5, -0.4, 0.4, 1.0, {3.4, 0.0, 0.1}, 10 * KEV, 1.0, 10.0, 1,
     GCP_CAP_B | GCP_CAP_GRADB | GCP_CAP_A | GCP_CAP_AXISYM},
    /* grid cell 0.1 RE: L = one cell */
    {"grid", keys_grid, 2.5 * RE, 5.5 * RE, -1.5 * RE, 1.5 * RE, 0.1 * RE,
     {4 * RE, 0.0, 0.3 * RE}, 1 * MEV, 1.0, RE, 0, GCP_CAP_B | GCP_CAP_GRADB | GCP_CAP_PSI | GCP_CAP_AXISYM},
    /* inside the DIII-D plasma (axis near R = 1.75 m), grid cell ~ 3 cm */
    {"eqdsk", keys_eqdsk, 1.5, 2.1, -0.4, 0.4, 0.03, {1.95, 0.0, 0.1}, 10 * KEV, 1.0, 5.0, 0,
     GCP_CAP_B | GCP_CAP_GRADB | GCP_CAP_PSI | GCP_CAP_AXISYM},
    {"igrf", keys_igrf, 2 * RE, 4 * RE, -1 * RE, 1 * RE, RE, {3.5 * RE, 0.0, 0.3 * RE},
     1 * MEV, 1.0, RE, 1, GCP_CAP_B | GCP_CAP_GRADB},
};

static const struct model_row *model_row_of(const struct gcp_field_type *t)
{
    for (size_t i = 0; i < sizeof models / sizeof models[0]; i++)
        if (strcmp(models[i].name, t->name) == 0) return &models[i];
    return NULL;
}

static void make_tmpdir(void)
{
    if (tmpdir[0]) return;
    snprintf(tmpdir, sizeof tmpdir, "/tmp/gcp_conf_XXXXXX");
    cr_assert_not_null(mkdtemp(tmpdir));
}
static void remove_tmpdir(void)
{
    char p[128];
    snprintf(p, sizeof p, "%s/dipole_psi.h5", tmpdir);
    unlink(p);
    rmdir(tmpdir);
}

/* The model built through its registry entry: defaults, then the row's keys. */
static struct gcp_field *build_model(const struct gcp_field_type *t, const struct model_row *r)
{
    struct gcp_field_args a;
    memset(&a, 0, sizeof a);
    a.bad_key = -1;
    for (int k = 0; k < GCP_FIELD_MAX_KEYS && t->keys[k].name; k++) {
        memcpy(a.v[k], t->keys[k].def, sizeof a.v[k]);
        snprintf(a.text[k], sizeof a.text[k], "%s", t->keys[k].def_text ? t->keys[k].def_text : "");
    }
    make_tmpdir();
    r->keys(t, &a);
    struct gcp_field *f = NULL;
    struct gcp_error err = {0, ""};
    cr_assert_eq(t->build(&a, &f, &err), 0, "%s: build: %s", t->name, err.msg);
    cr_assert_not_null(f);
    return f;
}

#define FOREACH_MODEL(t) \
    for (const struct gcp_field_type *const *t##_it_ = gcp_field_types(), *t; (t = *t##_it_); t##_it_++)
#define FOREACH_METHOD(p) \
    for (const struct gcp_pusher_type *const *p##_it_ = gcp_pusher_types(), *p; (p = *p##_it_); p##_it_++)

/* ---- small vector helpers ------------------------------------------------ */

static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static double norm3(const double a[3]) { return sqrt(dot3(a, a)); }
static double frob(const double g[3][3])
{
    double s = 0.0;
    for (int i = 0; i < 3; i++) s += dot3(g[i], g[i]);
    return sqrt(s);
}

/* Deterministic points in the row's box (R, phi, Z), phi all round. */
static void model_points(const struct model_row *r, double pts[NPT][3])
{
    uint64_t s = 88172645463325252ull;
    for (int i = 0; i < NPT; i++) {
        double u[3];
        for (int c = 0; c < 3; c++) {
            s = s * 6364136223846793005ull + 1442695040888963407ull;
            u[c] = (double)(s >> 11) * (1.0 / 9007199254740992.0);
        }
        const double R = r->Rlo + (r->Rhi - r->Rlo) * u[0], ph = 2.0 * GCP_PI * u[1];
        pts[i][0] = R * cos(ph), pts[i][1] = R * sin(ph);
        pts[i][2] = r->Zlo + (r->Zhi - r->Zlo) * u[2];
    }
}

static int sample(const struct gcp_field *f, const double x[3], unsigned need,
                  struct gcp_field_sample *s)
{
    memset(s, 0, sizeof *s);
    s->need = need;
    return gcp_field_eval(f, 0.0, x, s);
}

/* ---- pushes ----------------------------------------------------------------
 * One proton per model (the row's x0, T, pitch).  Full orbit: u = gamma v
 * at the row's pitch to B(x0), pushed 2 gyro-periods of x0 (omega t = 4 pi).
 * Guiding centre: X = x0, p_par = p cos(pitch), mu = p_perp^2/(2 m |B|),
 * pushed tau/2 with tau = Lorb / v (a fraction of a transit). */
struct start {
    double q, m, x[3], u[3], ppar, mu, v;
    double T_push; /* [s] */
    double scale;  /* [m] length the position error is measured against */
};

static double p_of_T(double T, double m)
{
    const double mc2 = m * GCP_C_LIGHT * GCP_C_LIGHT;
    return sqrt(T * T + 2.0 * T * mc2) / GCP_C_LIGHT;
}

static struct start make_start(const struct gcp_field *f, const struct model_row *r, int gc)
{
    struct start s;
    memset(&s, 0, sizeof s);
    s.q = GCP_E_CHARGE, s.m = GCP_M_PROTON;
    memcpy(s.x, r->x0, sizeof s.x);
    struct gcp_field_sample fs;
    cr_assert_eq(sample(f, s.x, GCP_NEED_B, &fs), 0, "%s: x0 outside", f->type->name);
    const double Bm = norm3(fs.B), b[3] = {fs.B[0] / Bm, fs.B[1] / Bm, fs.B[2] / Bm};
    double e[3];
    if (fabs(b[2]) < 0.9) e[0] = b[1], e[1] = -b[0], e[2] = 0.0; /* b x zhat */
    else e[0] = 0.0, e[1] = b[2], e[2] = -b[1];                   /* b x xhat */
    const double en = norm3(e);
    const double p = p_of_T(r->T, s.m), gamma = sqrt(1.0 + pow(p / (s.m * GCP_C_LIGHT), 2));
    s.v = p / (gamma * s.m);
    for (int i = 0; i < 3; i++)
        s.u[i] = p / s.m * (cos(r->pitch) * b[i] + sin(r->pitch) * e[i] / en);
    s.ppar = p * cos(r->pitch);
    s.mu = pow(p * sin(r->pitch), 2) / (2.0 * s.m * Bm);
    if (gc) {
        s.T_push = 0.5 * r->Lorb / s.v;
        s.scale = r->Lorb;
    } else {
        s.T_push = 2.0 * 2.0 * GCP_PI * gamma * s.m / (s.q * Bm);
        s.scale = p / (s.q * Bm); /* the gyro-radius */
    }
    return s;
}

/* Independent reference: GSL rk8pd at 1e-13 on the scaled equations
 * (lengths in s.scale, momenta in p0, time in tau), through no pusher.
 * Full orbit: dx/dt = u/gamma, du/dt = (q/m)(E + u x B / gamma), gamma = 1
 * (Newton's equations, u = v) for a method whose table row says newtonian.
 * Guiding centre: (dX/dt, dp_par/dt) = gcp_gc_rhs_at (kernels.h gcp_gc_rhs,
 * Cary & Brizard 2009). */
struct ref_ctx {
    const struct gcp_field *f;
    const struct start *s;
    double L, P, tau;
    int newtonian;
};

static int ref_fo(double t, const double y[], double dy[], void *vp)
{
    const struct ref_ctx *c = vp;
    const double x[3] = {y[0] * c->L, y[1] * c->L, y[2] * c->L};
    const double u[3] = {y[3] * c->P, y[4] * c->P, y[5] * c->P};
    struct gcp_field_sample fs;
    memset(&fs, 0, sizeof fs);
    fs.need = GCP_NEED_B | GCP_NEED_E;
    if (gcp_field_eval(c->f, t * c->tau, x, &fs)) return GSL_EBADFUNC;
    const double g = c->newtonian ? 1.0 : gcp_gamma_of_u(u[0], u[1], u[2]);
    const double qm = c->s->q / c->s->m;
    const double uxB[3] = {u[1] * fs.B[2] - u[2] * fs.B[1], u[2] * fs.B[0] - u[0] * fs.B[2],
                           u[0] * fs.B[1] - u[1] * fs.B[0]};
    for (int i = 0; i < 3; i++) {
        dy[i] = u[i] / g * c->tau / c->L;
        dy[3 + i] = qm * (fs.E[i] + uxB[i] / g) * c->tau / c->P;
    }
    return GSL_SUCCESS;
}

static int ref_gc(double t, const double y[], double dy[], void *vp)
{
    const struct ref_ctx *c = vp;
    const double X[3] = {y[0] * c->L, y[1] * c->L, y[2] * c->L};
    double dX[3], dp;
    if (gcp_gc_rhs_at(c->f, t * c->tau, c->s->q, c->s->m, X, y[3] * c->P, c->s->mu, dX, &dp))
        return GSL_EBADFUNC;
    for (int i = 0; i < 3; i++) dy[i] = dX[i] * c->tau / c->L;
    dy[3] = dp * c->tau / c->P;
    return GSL_SUCCESS;
}

/* The reference end position [m]. */
static void reference(const struct gcp_field *f, const struct start *s, int gc, int newtonian,
                      double xe[3])
{
    /* momenta in the total momentum p = m |u| (GC p_par) or |u| (FO u); time
     * in scale / v: tau/(Lorb/v) (GC), rho/v = 1/omega_c (FO) */
    const double P = gc ? s->m * norm3(s->u) : norm3(s->u);
    struct ref_ctx c = {f, s, s->scale, P, s->scale / s->v, newtonian};
    gsl_odeiv2_system sys = {gc ? ref_gc : ref_fo, NULL, gc ? 4u : 6u, &c};
    gsl_odeiv2_driver *d = gsl_odeiv2_driver_alloc_y_new(&sys, gsl_odeiv2_step_rk8pd, 1e-3,
                                                         1e-14, 1e-13);
    double y[6], t = 0.0;
    for (int i = 0; i < 3; i++) y[i] = s->x[i] / c.L;
    if (gc) y[3] = s->ppar / c.P;
    else
        for (int i = 0; i < 3; i++) y[3 + i] = s->u[i] / c.P;
    const int rc = gsl_odeiv2_driver_apply(d, &t, s->T_push / c.tau, y);
    cr_assert_eq(rc, GSL_SUCCESS, "%s: reference rk8pd failed (%d)", f->type->name, rc);
    gsl_odeiv2_driver_free(d);
    for (int i = 0; i < 3; i++) xe[i] = y[i] * c.L;
}

/* One lane pushed by p with opts o; returns the lane's status, the end
 * position in xe and (GC) p_par, (FO) u. */
static int push_one(const struct gcp_field *f, const struct gcp_pusher_type *p,
                    const struct start *s, const struct gcp_push_opts *o, double xe[3],
                    double ue[3], double *ppar)
{
    struct gcp_block b;
    cr_assert_eq(gcp_block_alloc(&b, 1), 0);
    b.q = s->q, b.m = s->m;
    b.x[0] = s->x[0], b.y[0] = s->x[1], b.z[0] = s->x[2];
    b.ux[0] = s->u[0], b.uy[0] = s->u[1], b.uz[0] = s->u[2];
    b.ppar[0] = s->ppar, b.mu[0] = s->mu;
    b.status[0] = 0, b.steps[0] = 0, b.t[0] = 0.0;
    b.n_active = 1;
    p->advance(&b, f, p, o, NULL);
    xe[0] = b.x[0], xe[1] = b.y[0], xe[2] = b.z[0];
    ue[0] = b.ux[0], ue[1] = b.uy[0], ue[2] = b.uz[0];
    *ppar = b.ppar[0];
    const int st = b.status[0];
    gcp_block_free(&b);
    return st;
}

static int applies(const struct gcp_pusher_type *p, const struct gcp_field *f)
{
    char why[256];
    return !p->applies || p->applies(f, why, sizeof why) == 0;
}

static double dist3(const double a[3], const double b[3])
{
    const double d[3] = {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
    return norm3(d);
}

#endif /* GCPUSH_TESTS_CONFORMANCE_H */
