/* Unit tests of the analytic field models (fields/ directory).
 *
 * Tolerances, derived once here and referred to below.
 *
 * (T1) grad B against a centred difference  D_j B = [B(x + h e_j) - B(x - h e_j)] / (2h).
 *   Truncation: h^2/6 |B'''|.  B varies on a length L (Lm for the mirror,
 *   r for the dipole, the minor radius a for the tokamak); |B'''| <= C |B|/L^3
 *   with C <= 60 (the worst case is the dipole, d^3/dr^3 r^-3 = -60 r^-6).
 *   Round-off: each B is computed with ~15 roundings, relative error
 *   <= 15 eps, so the difference quotient carries <= 15 eps |B| / h.
 *   With h = 1e-5 L:  truncation <= 1e-10/6 * 60 |B|/L = 1e-9 |B|/L,
 *   round-off <= 15 * 2.2e-16 / 1e-5 |B|/L = 3.3e-10 |B|/L.
 *   Both scale with |B|/L, not with |grad B| (which vanishes at the mirror
 *   centre), so the error is measured against S = |grad B|_F + |B|/L and must
 *   be below TOL_FD = 1e-7 S: a 75x margin over the 1.3e-9 estimate, and
 *   still 100x below 1e-5, where a genuinely missing term (the q'(r) term of
 *   the tokamak, O((qa-q0)/q) of grad B; an O(epsilon^2) toroidal correction,
 *   ~1e-2) would still be caught but small sign slips in one sub-term of size
 *   1e-6 S would not.
 *
 * (T2) div B = trace(grad B) and curl B (antisymmetric part of grad B).
 *   Each entry of grad B is a sum of <= 4 products with <= 20 roundings; the
 *   sub-terms are bounded by a few |grad B|_F, so each entry carries an
 *   absolute error <= 20 eps * 4 |grad B|_F ~ 2e-14 |grad B|_F and a sum or
 *   difference of three of them <= 6e-14 |grad B|_F.  TOL_DIV = 1e-12 leaves
 *   a 15x margin; any analytic mistake is O(1).
 *
 * (T3) Closed-form values (|B| of the dipole at the equator and pole, the
 *   mirror ratio): fewer than 20 roundings, relative error <= 20 eps = 4.4e-15;
 *   TOL_EXACT = 1e-14.
 *
 * (T4) eval_block against eval: the same expression (one static inline per
 *   model) compiled with -ffp-contract=off, division and sqrt correctly
 *   rounded in vector and scalar form: bit-identical, compared with memcmp.
 */
#include <criterion/criterion.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/field.h"
#include "gcpush/particles.h"
#include "gcpush/run.h" /* gcp_field_from_section: the run layer reads [field] */
#include "gcpush/section.h"

#define TOL_FD 1e-7
#define TOL_DIV 1e-12
#define TOL_EXACT 1e-14
#define TWO_PI (2.0 * GCP_PI)

/* ---- helpers ------------------------------------------------------------ */

static int eval_all(const struct gcp_field *f, const double x[3], struct gcp_field_sample *s)
{
    memset(s, 0, sizeof *s);
    s->need = GCP_NEED_B | GCP_NEED_GRADB | GCP_NEED_E;
    return gcp_field_eval(f, 0.0, x, s);
}

static double norm3(const double v[3]) { return sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

static double frob(const double g[3][3])
{
    double s = 0.0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) s += g[i][j] * g[i][j];
    return sqrt(s);
}

/* Deterministic points (a 64-bit LCG), uniform in [lo, hi). */
static uint64_t lcg_state = 12345u;
static double urand(double lo, double hi)
{
    lcg_state = lcg_state * 6364136223846793005ull + 1442695040888963407ull;
    return lo + (hi - lo) * (double)(lcg_state >> 11) * (1.0 / 9007199254740992.0);
}

/* Checks (T1) and (T2) at x; curl-free only for vacuum fields. */
static void check_gradient(const struct gcp_field *f, const double x[3], double L, int vacuum)
{
    struct gcp_field_sample s, sp, sm;
    eval_all(f, x, &s);
    const double h = 1e-5 * L;
    double fd[3][3];
    for (int j = 0; j < 3; j++) {
        double xp[3] = {x[0], x[1], x[2]}, xm[3] = {x[0], x[1], x[2]};
        xp[j] += h;
        xm[j] -= h;
        eval_all(f, xp, &sp);
        eval_all(f, xm, &sm);
        /* divide by the actual step, (x + h) - (x - h), not 2h, which x + h rounds */
        for (int i = 0; i < 3; i++) fd[i][j] = (sp.B[i] - sm.B[i]) / (xp[j] - xm[j]);
    }
    const double gn = frob(s.gradB), S = gn + norm3(s.B) / L;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            cr_assert_leq(fabs(fd[i][j] - s.gradB[i][j]), TOL_FD * S,
                          "%s: dB%d/dx%d at (%g, %g, %g): analytic %.15g, difference %.15g",
                          f->type->name, i, j, x[0], x[1], x[2], s.gradB[i][j], fd[i][j]);
    const double div = s.gradB[0][0] + s.gradB[1][1] + s.gradB[2][2];
    cr_assert_leq(fabs(div), TOL_DIV * gn, "%s: div B = %g, |grad B| = %g", f->type->name, div,
                  gn);
    if (vacuum)
        for (int i = 0; i < 3; i++)
            for (int j = i + 1; j < 3; j++)
                cr_assert_leq(fabs(s.gradB[i][j] - s.gradB[j][i]), TOL_DIV * gn,
                              "%s: curl B component (%d,%d) = %g", f->type->name, i, j,
                              s.gradB[i][j] - s.gradB[j][i]);
}

/* (T4): eval_block (with and without E, with status) against eval. */
#define NB 37 /* not a multiple of any vector width: exercises the loop tails */

/* (T4b, issue 12): the block evaluation with need bits, grad B included,
 * against eval point by point, bit for bit (both are the same expressions
 * in the same order; the build keeps -ffp-contract=off), for every need
 * combination, with and without a status array, through the model's own
 * eval_soa where it has one and through the generic one.  Arrays the need
 * bits do not ask for must stay untouched (filled with a marker). */
static void check_soa(const struct gcp_field *f, const double *x, const double *y,
                      const double *z, double pts[NB][3])
{
    static const unsigned needs[] = {GCP_NEED_B, GCP_NEED_B | GCP_NEED_GRADB,
                                     GCP_NEED_B | GCP_NEED_E,
                                     GCP_NEED_B | GCP_NEED_GRADB | GCP_NEED_E};
    static double B[3][NB], G[3][3][NB], E[3][NB];
    int32_t st[NB];
    for (int generic = 0; generic < 2; generic++)
        for (size_t k = 0; k < sizeof needs / sizeof needs[0]; k++) {
            const unsigned need = needs[k];
            struct gcp_field_soa o;
            for (int a = 0; a < 3; a++) {
                o.B[a] = B[a], o.E[a] = E[a];
                for (int c = 0; c < 3; c++) o.G[a][c] = G[a][c];
                for (int i = 0; i < NB; i++) {
                    B[a][i] = E[a][i] = -7.0;
                    for (int c = 0; c < 3; c++) G[a][c][i] = -7.0;
                }
            }
            for (int i = 0; i < NB; i++) st[i] = 0;
            if (generic)
                gcp_field_eval_soa_generic(f, 0.0, need, NB, x, y, z, &o, st);
            else
                gcp_field_eval_soa(f, 0.0, need, NB, x, y, z, &o, st);
            for (int i = 0; i < NB; i++) {
                struct gcp_field_sample s;
                memset(&s, 0, sizeof s);
                s.need = need;
                const int rc = gcp_field_eval(f, 0.0, pts[i], &s);
                cr_assert_eq(st[i], rc, "%s soa(need %u): status[%d] = %d, eval %d",
                             f->type->name, need, i, st[i], rc);
                for (int a = 0; a < 3; a++) {
                    cr_assert(memcmp(&B[a][i], &s.B[a], sizeof(double)) == 0,
                              "%s soa(need %u): B%d[%d] = %.17g, eval %.17g", f->type->name,
                              need, a, i, B[a][i], s.B[a]);
                    const double e = need & GCP_NEED_E ? s.E[a] : -7.0;
                    cr_assert(memcmp(&E[a][i], &e, sizeof(double)) == 0,
                              "%s soa(need %u): E%d[%d] = %.17g, expected %.17g", f->type->name,
                              need, a, i, E[a][i], e);
                    for (int c = 0; c < 3; c++) {
                        const double g = need & GCP_NEED_GRADB ? s.gradB[a][c] : -7.0;
                        cr_assert(memcmp(&G[a][c][i], &g, sizeof(double)) == 0,
                                  "%s soa(need %u): dB%d/dx%d[%d] = %.17g, expected %.17g",
                                  f->type->name, need, a, c, i, G[a][c][i], g);
                    }
                }
            }
        }
}
static void check_block(const struct gcp_field *f, double pts[NB][3])
{
    double x[NB], y[NB], z[NB], B[3][NB], E[3][NB], B2[3][NB];
    int32_t st[NB];
    for (int i = 0; i < NB; i++) {
        x[i] = pts[i][0];
        y[i] = pts[i][1];
        z[i] = pts[i][2];
        st[i] = 0;
    }
    f->type->eval_block(f, 0.0, NB, x, y, z, B[0], B[1], B[2], E[0], E[1], E[2], st);
    f->type->eval_block(f, 0.0, NB, x, y, z, B2[0], B2[1], B2[2], NULL, NULL, NULL, NULL);
    for (int i = 0; i < NB; i++) {
        struct gcp_field_sample s;
        memset(&s, 0, sizeof s);
        s.need = GCP_NEED_B | GCP_NEED_E;
        int rc = gcp_field_eval(f, 0.0, pts[i], &s);
        for (int k = 0; k < 3; k++) {
            cr_assert(memcmp(&B[k][i], &s.B[k], sizeof(double)) == 0,
                      "%s: block B%d[%d] = %.17g, eval %.17g", f->type->name, k, i, B[k][i],
                      s.B[k]);
            cr_assert(memcmp(&B2[k][i], &s.B[k], sizeof(double)) == 0,
                      "%s: block (no E) B%d[%d] = %.17g, eval %.17g", f->type->name, k, i,
                      B2[k][i], s.B[k]);
            cr_assert(memcmp(&E[k][i], &s.E[k], sizeof(double)) == 0,
                      "%s: block E%d[%d] = %.17g, eval %.17g", f->type->name, k, i, E[k][i],
                      s.E[k]);
        }
        cr_assert_eq(st[i], rc, "%s: block status[%d] = %d, eval %d", f->type->name, i, st[i],
                     rc);
    }
    check_soa(f, x, y, z, pts);
}

/* ---- uniform -------------------------------------------------------------- */

Test(field_uniform, values_gradient_block)
{
    const double B[3] = {1e-3, -2e-3, 5e-2}, E[3] = {0.0, 1e3, 0.0};
    struct gcp_field *f = gcp_field_uniform_create(B, E);
    cr_assert_not_null(f);
    cr_assert_eq(f->has_E, 1);
    struct gcp_field_sample s;
    const double x[3] = {3.0, -1.0, 7.0};
    cr_assert_eq(eval_all(f, x, &s), 0);
    for (int i = 0; i < 3; i++) {
        cr_assert_eq(s.B[i], B[i]);
        cr_assert_eq(s.E[i], E[i]);
        for (int j = 0; j < 3; j++) cr_assert_eq(s.gradB[i][j], 0.0);
    }
    double pts[NB][3];
    for (int i = 0; i < NB; i++) {
        pts[i][0] = urand(-10, 10);
        pts[i][1] = urand(-10, 10);
        pts[i][2] = urand(-10, 10);
        check_gradient(f, pts[i], 1.0, 1);
    }
    check_block(f, pts);
    gcp_field_free(f);

    f = gcp_field_uniform_create(B, NULL);
    cr_assert_eq(f->has_E, 0);
    check_block(f, pts);
    gcp_field_free(f);
}

/* ---- mirror --------------------------------------------------------------- */

Test(field_mirror, gradient_div_curl_block)
{
    const double B0 = 0.5, Lm = 2.0;
    struct gcp_field *f = gcp_field_mirror_create(B0, Lm, 3.0, 1.0);
    cr_assert_not_null(f);
    cr_assert_eq(f->axisymmetric, 1);
    cr_assert_eq(f->z_max, 3.0);
    cr_assert_eq(f->r_outer, 1.0);
    double pts[NB][3];
    for (int i = 0; i < NB; i++) {
        pts[i][0] = urand(-1, 1);
        pts[i][1] = urand(-1, 1);
        pts[i][2] = urand(-3, 3);
        check_gradient(f, pts[i], Lm, 1);
    }
    const double centre[3] = {0.0, 0.0, 0.0};
    check_gradient(f, centre, Lm, 1); /* grad B = 0 here: the |B|/L term of S matters */
    check_block(f, pts);
    gcp_field_free(f);
}

/* On-axis mirror ratio B(z)/B(0) = 1 + z^2/Lm^2, B(0) = B0 (T3); B along z. */
Test(field_mirror, mirror_ratio)
{
    const double B0 = 0.5, Lm = 2.0;
    struct gcp_field *f = gcp_field_mirror_create(B0, Lm, 10.0, 0.0);
    cr_assert_eq(f->r_outer, INFINITY);
    struct gcp_field_sample s;
    const double o[3] = {0, 0, 0};
    eval_all(f, o, &s);
    cr_assert_eq(s.B[2], B0);
    for (double z = -4.0; z <= 4.0; z += 0.5) {
        const double x[3] = {0.0, 0.0, z};
        eval_all(f, x, &s);
        const double want = 1.0 + z * z / (Lm * Lm);
        cr_assert_leq(fabs(norm3(s.B) / B0 - want), TOL_EXACT * want, "z = %g: ratio %.17g",
                      z, norm3(s.B) / B0);
        cr_assert_eq(s.B[0], 0.0);
        cr_assert_eq(s.B[1], 0.0);
    }
    const double at_Lm[3] = {0.0, 0.0, Lm};
    eval_all(f, at_Lm, &s);
    cr_assert_float_eq(s.B[2], 2.0 * B0, TOL_EXACT * B0);
    gcp_field_free(f);
}

/* ---- dipole --------------------------------------------------------------- */

static void dipole_points(double pts[NB][3])
{
    for (int i = 0; i < NB; i++) {
        /* 1.1 .. 10 R_E in all directions, poles and equator included */
        const double r = urand(1.1, 10.0) * GCP_EARTH_RADIUS, ct = urand(-1, 1),
                     ph = urand(0, TWO_PI), st = sqrt(1.0 - ct * ct);
        pts[i][0] = r * st * cos(ph);
        pts[i][1] = r * st * sin(ph);
        pts[i][2] = r * ct;
    }
    pts[0][0] = 3 * GCP_EARTH_RADIUS, pts[0][1] = 0, pts[0][2] = 0; /* equator */
    pts[1][0] = 0, pts[1][1] = 0, pts[1][2] = -2 * GCP_EARTH_RADIUS; /* pole */
    pts[2][0] = 0, pts[2][1] = 0, pts[2][2] = 0;                     /* the floored centre */
}

Test(field_dipole, gradient_div_curl_block)
{
    struct gcp_field *f = gcp_field_dipole_create(GCP_EARTH_B0, 0, GCP_EARTH_RADIUS, 0.0);
    cr_assert_not_null(f);
    cr_assert_eq(f->axisymmetric, 1);
    cr_assert_eq(f->has_E, 0);
    cr_assert_eq(f->r_outer, INFINITY);
    double pts[NB][3];
    dipole_points(pts);
    for (int i = 0; i < NB; i++) {
        if (i == 2) continue; /* r = 0: only required to be finite (below) */
        check_gradient(f, pts[i], norm3(pts[i]), 1);
    }
    struct gcp_field_sample s;
    eval_all(f, pts[2], &s);
    for (int i = 0; i < 3; i++) {
        cr_assert(isfinite(s.B[i]), "B at r = 0 not finite");
        for (int j = 0; j < 3; j++) cr_assert(isfinite(s.gradB[i][j]), "grad B at r = 0");
    }
    check_block(f, pts);
    gcp_field_free(f);
}

/* |B| = B0/L^3 at the equator (pointing +z), 2 B0/L^3 at the poles (pointing
 * -z at both: into the north pole, out of the south pole) (T3). */
Test(field_dipole, equator_and_pole)
{
    const double B0 = 3.0e-5;
    struct gcp_field *f = gcp_field_dipole_create(B0, 0, 0.0, 0.0);
    const double Ls[] = {1.0, 2.0, 4.0, 6.6};
    for (size_t k = 0; k < sizeof Ls / sizeof Ls[0]; k++) {
        const double L = Ls[k], r = L * GCP_EARTH_RADIUS, want = B0 / (L * L * L);
        struct gcp_field_sample s;
        const double eq[3] = {r * cos(0.7), r * sin(0.7), 0.0};
        eval_all(f, eq, &s);
        cr_assert_leq(fabs(norm3(s.B) - want), TOL_EXACT * want, "L = %g equator |B| = %.17g",
                      L, norm3(s.B));
        cr_assert_gt(s.B[2], 0.0, "equatorial B must point north (+z)");
        for (int sgn = -1; sgn <= 1; sgn += 2) {
            const double pole[3] = {0.0, 0.0, sgn * r};
            eval_all(f, pole, &s);
            cr_assert_leq(fabs(norm3(s.B) - 2.0 * want), TOL_EXACT * 2.0 * want,
                          "L = %g pole |B| = %.17g", L, norm3(s.B));
            cr_assert_lt(s.B[2], 0.0);
        }
    }
    gcp_field_free(f);
}

/* The vector potential documented in dipole.c, A = A_phi phihat with
 * A_phi = -B0 R_E^3 rho / r^3, i.e. A = -B0 R_E^3 (-y, x, 0) / r^3, has
 * curl A = B: centred differences of A, same budget as (T1) (A varies on r). */
static void dipole_A(double c, const double x[3], double A[3])
{
    const double r = norm3(x), k = -c / (r * r * r);
    A[0] = -k * x[1];
    A[1] = k * x[0];
    A[2] = 0.0;
}

Test(field_dipole, vector_potential)
{
    struct gcp_field *f = gcp_field_dipole_create(GCP_EARTH_B0, 0, 0.0, 0.0);
    const double c = GCP_EARTH_B0 * GCP_EARTH_RADIUS * GCP_EARTH_RADIUS * GCP_EARTH_RADIUS;
    double pts[NB][3];
    dipole_points(pts);
    for (int i = 3; i < NB; i++) {
        const double r = norm3(pts[i]), h = 1e-5 * r;
        double dA[3][3]; /* dA[i][j] = dA_i/dx_j */
        for (int j = 0; j < 3; j++) {
            double xp[3] = {pts[i][0], pts[i][1], pts[i][2]}, xm[3] = {xp[0], xp[1], xp[2]};
            xp[j] += h;
            xm[j] -= h;
            double Ap[3], Am[3];
            dipole_A(c, xp, Ap);
            dipole_A(c, xm, Am);
            for (int k = 0; k < 3; k++) dA[k][j] = (Ap[k] - Am[k]) / (xp[j] - xm[j]);
        }
        const double curl[3] = {dA[2][1] - dA[1][2], dA[0][2] - dA[2][0], dA[1][0] - dA[0][1]};
        struct gcp_field_sample s;
        eval_all(f, pts[i], &s);
        for (int k = 0; k < 3; k++)
            cr_assert_leq(fabs(curl[k] - s.B[k]), TOL_FD * norm3(s.B), "curl A - B [%d] = %g",
                          k, curl[k] - s.B[k]);
    }
    gcp_field_free(f);
}

/* Corotation: E = -(Omega x r) x B.  E.B = 0 to round-off (each product
 * ~3 roundings: <= 1e-14 |E||B|); at the equator E = -Omega r Bz rhat (T3). */
Test(field_dipole, corotation)
{
    struct gcp_field *f = gcp_field_dipole_create(GCP_EARTH_B0, 1, GCP_EARTH_RADIUS, 0.0);
    cr_assert_eq(f->has_E, 1);
    double pts[NB][3];
    dipole_points(pts);
    for (int i = 3; i < NB; i++) {
        struct gcp_field_sample s;
        eval_all(f, pts[i], &s);
        const double EB = s.E[0] * s.B[0] + s.E[1] * s.B[1] + s.E[2] * s.B[2];
        cr_assert_leq(fabs(EB), TOL_EXACT * norm3(s.E) * norm3(s.B), "E.B = %g", EB);
    }
    const double L = 4.0, r = L * GCP_EARTH_RADIUS;
    const double x[3] = {0.0, r, 0.0};
    struct gcp_field_sample s;
    eval_all(f, x, &s);
    const double want = -GCP_EARTH_OMEGA * r * GCP_EARTH_B0 / (L * L * L);
    cr_assert_leq(fabs(s.E[1] - want), TOL_EXACT * fabs(want), "E_r = %.17g, want %.17g",
                  s.E[1], want);
    cr_assert_eq(s.E[0], 0.0);
    cr_assert_eq(s.E[2], 0.0);
    check_block(f, pts);
    gcp_field_free(f);
}

/* ---- tokamak -------------------------------------------------------------- */

#define TK_B0 2.0
#define TK_R0 3.0
#define TK_A 1.0
#define TK_Q0 1.1
#define TK_QA 3.5

/* Points in the plasma (minor radius < a), at any toroidal angle. */
static void tokamak_points(double pts[NB][3], double rmax)
{
    for (int i = 0; i < NB; i++) {
        const double r = rmax * sqrt(urand(0, 1)), th = urand(0, TWO_PI), ph = urand(0, TWO_PI);
        const double R = TK_R0 + r * cos(th);
        pts[i][0] = R * cos(ph);
        pts[i][1] = R * sin(ph);
        pts[i][2] = r * sin(th);
    }
    pts[0][0] = TK_R0, pts[0][1] = 0, pts[0][2] = 0; /* the magnetic axis */
}

Test(field_tokamak, gradient_div_block)
{
    struct gcp_field *f = gcp_field_tokamak_create(TK_B0, TK_R0, TK_A, TK_Q0, TK_QA);
    cr_assert_not_null(f);
    cr_assert_eq(f->axisymmetric, 1);
    double pts[NB][3];
    tokamak_points(pts, 0.999 * TK_A);
    for (int i = 0; i < NB; i++) check_gradient(f, pts[i], TK_A, 0);
    /* the magnetic axis: B = B0 phihat exactly */
    struct gcp_field_sample s;
    cr_assert_eq(eval_all(f, pts[0], &s), 0);
    cr_assert_eq(s.B[0], 0.0);
    cr_assert_eq(s.B[1], TK_B0);
    cr_assert_eq(s.B[2], 0.0);
    /* block: half the points outside the plasma, statuses included */
    tokamak_points(pts, 2.0 * TK_A);
    check_block(f, pts);
    gcp_field_free(f);

    /* flat q (qa == q0) and reversed field: still exact and divergence-free */
    f = gcp_field_tokamak_create(-TK_B0, TK_R0, TK_A, 2.0, 2.0);
    tokamak_points(pts, 0.999 * TK_A);
    for (int i = 0; i < NB; i++) check_gradient(f, pts[i], TK_A, 0);
    check_block(f, pts);
    gcp_field_free(f);
}

Test(field_tokamak, domain)
{
    struct gcp_field *f = gcp_field_tokamak_create(TK_B0, TK_R0, TK_A, TK_Q0, TK_QA);
    cr_assert_eq(f->r_outer, TK_R0 + TK_A);
    struct gcp_field_sample s;
    const double in[3] = {0.0, TK_R0 + 0.99 * TK_A, 0.0};
    const double out[3] = {0.0, TK_R0 + 1.01 * TK_A, 0.0};
    const double above[3] = {TK_R0, 0.0, 1.01 * TK_A};
    const double axis[3] = {0.0, 0.0, 0.0}; /* z axis: far outside, and finite */
    cr_assert_eq(eval_all(f, in, &s), 0);
    cr_assert_eq(eval_all(f, out, &s), GCP_LEFT_DOMAIN);
    cr_assert_eq(eval_all(f, above, &s), GCP_LEFT_DOMAIN);
    cr_assert_eq(eval_all(f, axis, &s), GCP_LEFT_DOMAIN);
    for (int i = 0; i < 3; i++) cr_assert(isfinite(s.B[i]));

    /* block: a status already set by the caller is kept, never cleared */
    double x[4] = {in[0], out[0], out[0], in[0]}, y[4] = {in[1], out[1], out[1], in[1]},
           z[4] = {0, 0, 0, 0}, B[3][4];
    int32_t st[4] = {0, 0, GCP_PRECIPITATED, GCP_NONFINITE};
    f->type->eval_block(f, 0.0, 4, x, y, z, B[0], B[1], B[2], NULL, NULL, NULL, st);
    cr_assert_eq(st[0], 0);
    cr_assert_eq(st[1], GCP_LEFT_DOMAIN);
    cr_assert_eq(st[2], GCP_PRECIPITATED);
    cr_assert_eq(st[3], GCP_NONFINITE);
    gcp_field_free(f);
}

/* Field-line tracing in (R, phi, Z) with the poloidal angle theta about the
 * axis (R0, 0) as the independent variable:
 *   d(R, phi, Z)/dtheta = (B_R, B_phi/R, B_Z) / (dtheta/ds),
 *   dtheta/ds = ((R - R0) B_Z - Z B_R) / r^2   (s: the field-line parameter
 * with dX/ds = B).  One poloidal turn is theta: 0 -> 2 pi exactly, so the
 * winding number is q = Delta phi / (2 pi). */
static void fl_rhs(const struct gcp_field *f, const double u[3], double du[3])
{
    const double R = u[0], ph = u[1], Z = u[2], c = cos(ph), sn = sin(ph);
    const double x[3] = {R * c, R * sn, Z};
    struct gcp_field_sample s;
    memset(&s, 0, sizeof s);
    s.need = GCP_NEED_B;
    gcp_field_eval(f, 0.0, x, &s);
    const double BR = s.B[0] * c + s.B[1] * sn, Bph = -s.B[0] * sn + s.B[1] * c, BZ = s.B[2];
    const double dR = R - TK_R0, r2 = dR * dR + Z * Z;
    const double dth = (dR * BZ - Z * BR) / r2;
    du[0] = BR / dth;
    du[1] = Bph / R / dth;
    du[2] = BZ / dth;
}

static double trace_q(const struct gcp_field *f, double r, int nsteps, double *r_end)
{
    double u[3] = {TK_R0 + r, 0.0, 0.0};
    const double h = TWO_PI / nsteps;
    for (int n = 0; n < nsteps; n++) {
        double k1[3], k2[3], k3[3], k4[3], v[3];
        fl_rhs(f, u, k1);
        for (int i = 0; i < 3; i++) v[i] = u[i] + 0.5 * h * k1[i];
        fl_rhs(f, v, k2);
        for (int i = 0; i < 3; i++) v[i] = u[i] + 0.5 * h * k2[i];
        fl_rhs(f, v, k3);
        for (int i = 0; i < 3; i++) v[i] = u[i] + h * k3[i];
        fl_rhs(f, v, k4);
        for (int i = 0; i < 3; i++) u[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    }
    *r_end = hypot(u[0] - TK_R0, u[2]);
    return u[1] / TWO_PI;
}

/* q = (1/2pi) oint B_phi / (R B_pol) dl on the circle r, by the trapezoidal
 * rule in theta (dl = r dtheta), with B from the field's eval. */
static double quad_q(const struct gcp_field *f, double r, int m)
{
    double sum = 0.0;
    for (int k = 0; k < m; k++) {
        const double th = TWO_PI * k / m, R = TK_R0 + r * cos(th);
        const double x[3] = {R, 0.0, r * sin(th)};
        struct gcp_field_sample s;
        memset(&s, 0, sizeof s);
        s.need = GCP_NEED_B;
        gcp_field_eval(f, 0.0, x, &s);
        const double Bpol = hypot(s.B[0], s.B[2]);
        sum += s.B[1] / (R * Bpol) * r;
    }
    return sum * (TWO_PI / m) / TWO_PI;
}

/* Field-line q at r = a/2 (epsilon = r/R0 = 1/6), three ways:
 *  - closed form q(r)/sqrt(1 - epsilon^2) (tokamak.c header);
 *  - quadrature: trapezoidal rule on a periodic analytic integrand converges
 *    geometrically, like epsilon^m; m = 256 is exact to round-off; the sum of
 *    256 terms carries <= 256 * 2 eps ~ 1e-13 relative: tolerance 1e-12;
 *  - RK4 trace, N = 2000 steps of h = pi/1000: the global error is
 *    C h^4 = 1e-11 C, and C is O(epsilon q) because dphi/dtheta =
 *    q R0/(R0 + r cos theta) varies by O(epsilon) along the turn (and RK4 on
 *    a whole period of a smooth periodic integrand does better still), so
 *    the error is ~1e-11; tolerance 1e-9 relative (100x margin), the same
 *    for r staying on its flux surface (|r_end - r| <= 1e-9 a).
 * The finite-aspect-ratio correction q_line/q(r) - 1 = 0.0142 is 1e7 times
 * the tolerance, so comparing with q(r) itself would fail: asserted too. */
Test(field_tokamak, field_line_q)
{
    const double qas[2] = {TK_QA, TK_Q0}; /* sheared, then flat (qa == q0) */
    for (int k = 0; k < 2; k++) {
        struct gcp_field *f = gcp_field_tokamak_create(TK_B0, TK_R0, TK_A, TK_Q0, qas[k]);
        const double r = 0.5 * TK_A, eps = r / TK_R0;
        const double qr = TK_Q0 + (qas[k] - TK_Q0) * (r / TK_A) * (r / TK_A);
        const double q_exact = qr / sqrt(1.0 - eps * eps);
        const double q_quad = quad_q(f, r, 256);
        cr_assert_leq(fabs(q_quad - q_exact), 1e-12 * q_exact, "quadrature q = %.17g, exact %.17g",
                      q_quad, q_exact);
        double r_end;
        const double q_trace = trace_q(f, r, 2000, &r_end);
        cr_assert_leq(fabs(q_trace - q_exact), 1e-9 * q_exact, "traced q = %.17g, exact %.17g",
                      q_trace, q_exact);
        cr_assert_leq(fabs(r_end - r), 1e-9 * TK_A, "field line left its flux surface: %.17g",
                      r_end);
        cr_assert_gt(fabs(q_trace - qr), 1e-3 * qr, "the test would not see O(eps^2)");
        gcp_field_free(f);
    }
}

/* ---- callback, registry ----------------------------------------------------- */

struct cb_ctx {
    double B0;
    int calls;
};

static int cb_eval(double t, const double x[3], struct gcp_field_sample *out, void *ctx)
{
    struct cb_ctx *c = ctx;
    c->calls++;
    out->B[0] = 0.0;
    out->B[1] = 0.0;
    out->B[2] = c->B0 * (1.0 + t);
    if (out->need & GCP_NEED_E) out->E[0] = out->E[1] = out->E[2] = 1.0;
    return x[0] > 1.0 ? GCP_LEFT_DOMAIN : 0;
}

Test(field_callback, eval_and_generic_block)
{
    struct cb_ctx c = {0.25, 0};
    struct gcp_field *f = gcp_field_callback_create(cb_eval, &c, 1);
    cr_assert_not_null(f);
    cr_assert_eq(f->has_E, 1);
    cr_assert_eq(f->type, &gcp_field_callback);
    struct gcp_field_sample s;
    memset(&s, 0, sizeof s);
    s.need = GCP_NEED_B;
    const double x[3] = {0.5, 0, 0};
    cr_assert_eq(gcp_field_eval(f, 1.0, x, &s), 0);
    cr_assert_eq(s.B[2], 0.5);
    double px[3] = {0.0, 2.0, 0.5}, py[3] = {0}, pz[3] = {0}, B[3][3], E[3][3];
    int32_t st[3] = {0, 0, GCP_NONFINITE};
    f->type->eval_block(f, 0.0, 3, px, py, pz, B[0], B[1], B[2], E[0], E[1], E[2], st);
    cr_assert_eq(B[2][0], 0.25);
    cr_assert_eq(E[0][1], 1.0);
    cr_assert_eq(st[0], 0);
    cr_assert_eq(st[1], GCP_LEFT_DOMAIN);
    cr_assert_eq(st[2], GCP_NONFINITE);
    cr_assert_eq(c.calls, 4);
    gcp_field_free(f);
}

Test(field_registry, lookup_and_list)
{
    const struct gcp_field_type *const *t = gcp_field_types();
    const char *names[] = {"uniform", "mirror", "dipole", "tokamak", "grid", "eqdsk", "igrf"};
    const int expected = (int)(sizeof names / sizeof names[0]);
    int n = 0;
    for (; t[n]; n++) {
        cr_assert_lt(n, expected, "more models than this test knows");
        cr_assert_str_eq(t[n]->name, names[n]);
        cr_assert_not_null(t[n]->doc);
        cr_assert_not_null(t[n]->eval);
        cr_assert_not_null(t[n]->eval_block);
        cr_assert_eq(gcp_field_type_lookup(names[n]), t[n]);
    }
    cr_assert_eq(n, expected);
    cr_assert_eq(gcp_field_type_lookup("dipole"), &gcp_field_dipole);
    cr_assert_null(gcp_field_type_lookup("callback"), "callback is not a run-file model");
    cr_assert_null(gcp_field_type_lookup("dipol"));
    cr_assert_null(gcp_field_type_lookup(NULL));
    gcp_field_free(NULL);
}

/* ---- gcp_field_from_section ------------------------------------------------ */

/* A [field] section at line 3 of "test.run" holding the given key = value
 * pairs on lines 4, 5, ... */
struct test_section {
    struct gcp_section sec;
    struct gcp_keyval kv[8];
};

static void make_section(struct test_section *t, const char *const *kv, size_t n)
{
    memset(t, 0, sizeof *t);
    t->sec.file = "test.run";
    t->sec.name = "field";
    t->sec.line = 3;
    t->sec.n = t->sec.cap = n;
    t->sec.kv = t->kv;
    for (size_t i = 0; i < n; i++) {
        t->kv[i].key = (char *)kv[2 * i];
        t->kv[i].value = (char *)kv[2 * i + 1];
        t->kv[i].line = 4 + (int)i;
    }
}

Test(field_section, builds_each_model)
{
    struct test_section t;
    struct gcp_error err = {0, ""};
    struct gcp_field *f = NULL;

    const char *uni[] = {"B", "0 0 2 T", "E", "1 0 0 mV/m"};
    make_section(&t, uni, 2);
    cr_assert_eq(gcp_field_from_section("uniform", &t.sec, &f, &err), 0, "%s", err.msg);
    cr_assert_eq(f->type, &gcp_field_uniform);
    cr_assert_eq(f->has_E, 1);
    gcp_field_free(f);

    const char *mir[] = {"B0", "1 T", "Lm", "50 cm", "z_max", "1 m", "r_max", "20 cm"};
    make_section(&t, mir, 4);
    cr_assert_eq(gcp_field_from_section("mirror", &t.sec, &f, &err), 0, "%s", err.msg);
    cr_assert_float_eq(f->r_outer, 0.2, 1e-15);
    cr_assert_float_eq(f->z_max, 1.0, 1e-15);
    gcp_field_free(f);

    /* dipole with nothing set: B0 = GCP_EARTH_B0, r_inner = R_E + 100 km, 15 RE */
    make_section(&t, NULL, 0);
    cr_assert_eq(gcp_field_from_section("dipole", &t.sec, &f, &err), 0, "%s", err.msg);
    cr_assert_eq(f->has_E, 0);
    cr_assert_float_eq(f->r_inner, GCP_EARTH_RADIUS + 100e3, 1e-6);
    cr_assert_float_eq(f->r_outer, 15.0 * GCP_EARTH_RADIUS, 1e-6);
    struct gcp_field_sample s;
    const double eq[3] = {GCP_EARTH_RADIUS, 0, 0};
    eval_all(f, eq, &s);
    cr_assert_float_eq(s.B[2], GCP_EARTH_B0, TOL_EXACT * GCP_EARTH_B0);
    gcp_field_free(f);

    const char *dip[] = {"B0", "30000 nT", "corotation", "yes", "atmosphere", "200 km",
                         "r_outer", "10 RE"};
    make_section(&t, dip, 4);
    cr_assert_eq(gcp_field_from_section("dipole", &t.sec, &f, &err), 0, "%s", err.msg);
    cr_assert_eq(f->has_E, 1);
    cr_assert_float_eq(f->r_inner, GCP_EARTH_RADIUS + 200e3, 1e-6);
    gcp_field_free(f);

    const char *tok[] = {"B0", "2 T", "R0", "3 m", "a", "1 m", "q0", "1.1", "qa", "3.5"};
    make_section(&t, tok, 5);
    cr_assert_eq(gcp_field_from_section("tokamak", &t.sec, &f, &err), 0, "%s", err.msg);
    const double axis[3] = {3.0, 0.0, 0.0};
    eval_all(f, axis, &s);
    cr_assert_eq(s.B[1], 2.0);
    gcp_field_free(f);
    cr_assert_eq(err.code, 0);
}

Test(field_section, rejects_unknown_key)
{
    struct test_section t;
    struct gcp_error err = {0, ""};
    struct gcp_field *f = (struct gcp_field *)&t; /* must come back NULL */
    const char *kv[] = {"B0", "3.12e-5 T", "corrotation", "yes"};
    make_section(&t, kv, 2);
    int rc = gcp_field_from_section("dipole", &t.sec, &f, &err);
    cr_assert_eq(rc, GCP_ERR_UNKNOWN);
    cr_assert_null(f);
    cr_assert(strstr(err.msg, "test.run:5") != NULL, "no file:line in '%s'", err.msg);
    cr_assert(strstr(err.msg, "corrotation") != NULL, "no key in '%s'", err.msg);
    cr_assert(strstr(err.msg, "corotation") != NULL, "accepted keys not listed: '%s'", err.msg);
}

Test(field_section, rejects_missing_key)
{
    struct test_section t;
    struct gcp_error err = {0, ""};
    struct gcp_field *f = NULL;
    const char *kv[] = {"B0", "1 T", "z_max", "1 m"};
    make_section(&t, kv, 2);
    int rc = gcp_field_from_section("mirror", &t.sec, &f, &err);
    cr_assert_eq(rc, GCP_ERR_MISSING);
    cr_assert_null(f);
    /* a missing key has no line of its own: the [field] header's (3) */
    cr_assert(strstr(err.msg, "test.run:3") != NULL, "no file:line in '%s'", err.msg);
    cr_assert(strstr(err.msg, "Lm") != NULL, "no key in '%s'", err.msg);
}

Test(field_section, rejects_bad_values)
{
    struct test_section t;
    struct gcp_field *f = NULL;
    struct {
        const char *model;
        const char *kv[10];
        size_t n;
        const char *key_line; /* expected in the message */
    } cases[] = {
        {"tokamak", {"B0", "2 T", "R0", "3 m", "a", "4 m", "q0", "1", "qa", "3"}, 5, "test.run:6"},
        {"tokamak", {"B0", "0 T", "R0", "3 m", "a", "1 m", "q0", "1", "qa", "3"}, 5, "test.run:4"},
        {"tokamak", {"B0", "1 T", "R0", "3 m", "a", "1 m", "q0", "1", "qa", "-3"}, 5, "test.run:8"},
        {"mirror", {"B0", "-1 T", "Lm", "1 m", "z_max", "1 m"}, 3, "test.run:4"},
        {"mirror", {"B0", "1 T", "Lm", "0 m", "z_max", "1 m"}, 3, "test.run:5"},
        {"dipole", {"r_outer", "1 RE"}, 1, "test.run:4"},
        {"dipole", {"atmosphere", "-5 km"}, 1, "test.run:4"},
        {"uniform", {"B", "0 0 nan T"}, 1, "test.run:4"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        struct gcp_error err = {0, ""};
        make_section(&t, cases[i].kv, cases[i].n);
        int rc = gcp_field_from_section(cases[i].model, &t.sec, &f, &err);
        cr_assert_eq(rc, GCP_ERR_VALUE, "case %zu: rc %d (%s)", i, rc, err.msg);
        cr_assert_null(f);
        cr_assert(strstr(err.msg, cases[i].key_line) != NULL, "case %zu: '%s'", i, err.msg);
    }
}

Test(field_section, rejects_unknown_model)
{
    struct test_section t;
    struct gcp_error err = {0, ""};
    struct gcp_field *f = NULL;
    make_section(&t, NULL, 0);
    int rc = gcp_field_from_section("callback", &t.sec, &f, &err);
    cr_assert_eq(rc, GCP_ERR_UNKNOWN);
    cr_assert_null(f);
    cr_assert(strstr(err.msg, "test.run:3") != NULL, "'%s'", err.msg);
    cr_assert(strstr(err.msg, "uniform mirror dipole tokamak") != NULL, "'%s'", err.msg);
}
