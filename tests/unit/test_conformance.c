/* One conformance battery (issue 12, in the style of GSL's test.c): every
 * pusher of gcp_pusher_types() and every field model of gcp_field_types(),
 * taken from the registries, so that a method or a model added later is
 * covered without editing this file -- except for one row in the
 * expectations tables below, whose absence is itself a failure.
 *
 * The checks ask capabilities (gcp_field_caps, pusher->applies, ->kind,
 * ->adaptive), never names; names only key the tables.
 *
 * Fields, for every model, at NPT deterministic points inside its domain:
 *   (F1) block evaluation gcp_field_eval_soa, for every combination of need
 *        bits, and the legacy eval_block, equal to gcp_field_eval point by
 *        point, bit for bit (field.h promises it: the same expressions, the
 *        build has -ffp-contract=off);
 *        A closed form the model exports (gcp_field_point_B) equal to eval
 *        likewise, bit for bit (the fused full-orbit step uses the form);
 *   (F2) div B = trace(grad B) = 0 to round-off and grad B against centred
 *        differences of B (tolerances derived at the check);
 *   (F3) where the model gives A (GCP_CAP_A): curl A = B from the analytic dA;
 *   (F4) where it gives psi (GCP_CAP_PSI): B_R = -(1/R) dpsi/dZ and
 *        B_Z = (1/R) dpsi/dR by centred differences of psi.
 * Pushers, for every (method, model) where method->applies:
 *   (P1) order by step halving against an independent reference: the
 *        full Lorentz equations (full orbit) or the guiding-centre equations
 *        (gcp_gc_rhs_at) integrated here with GSL rk8pd at 1e-13 -- not
 *        through any pusher of the library;
 *   (P2) energy in a static pure-B field: round-off where the table says so,
 *        else bounded by the truncation error, with at least one method of
 *        the registry above the round-off bound (the check can fail);
 *   (P3) bad dt (0, negative, NaN, inf): STEP_FAILED, the state untouched;
 *   (P4) a NaN initial state: NONFINITE, the other lane unharmed;
 *   (P5) unknown method / model names: the lookups say NULL.
 *
 * Cost: 3.1 s of CPU in all, 6.6 s wall on a loaded 2-core machine
 * (`/usr/bin/time build/test_unit --filter 'conformance/' --jobs 1`, the
 * filter ending in a star); each push test builds the seven models once,
 * and most of their time is the eqdsk field and its canonical chart.
 *
 * Overlap with older tests, kept on purpose (they hold more cases):
 * (F1) for the analytic models is test_fields.c check_soa/check_block;
 * (F3) for the four analytic models is test_gc_basic.c potential_curl_is_B;
 * (P3)/(P4) for the guiding-centre methods in the dipole is
 * test_gc_basic.c battery_nonfinite_and_bad_dt.  This file adds the gridded
 * models, IGRF, the full-orbit methods, and the registry coverage.
 *
 * Two findings are disabled tests at their place below: the full-orbit
 * step does not refuse a bad dt, and gc-gl4 in the eqdsk field stalls at a
 * 1.6e-9 m floor with an irregular convergence.
 */
#include <criterion/criterion.h>

#include "test_conformance.h"

/* ---- (P5) and the tables cover the registries --------------------------- */

Test(conformance, every_registry_entry_has_a_row)
{
    int nm = 0, nf = 0;
    FOREACH_METHOD(p)
    {
        const struct method_row *r = method_row_of(p);
        cr_assert_not_null(r, "method %s has no row in the expectations table", p->name);
        cr_expect_eq(r->kind, p->kind, "%s: kind %d, table %d", p->name, p->kind, r->kind);
        cr_expect_eq(r->order, p->order, "%s: order %d, table %d", p->name, p->order, r->order);
        cr_expect_eq(r->adaptive, p->adaptive, "%s: adaptive", p->name);
        cr_expect_eq(r->newtonian, p->newtonian, "%s: newtonian", p->name);
        cr_expect_not_null(p->advance, "%s", p->name);
        cr_expect_eq(gcp_pusher_lookup(p->name), p, "%s: lookup", p->name);
        nm++;
    }
    FOREACH_MODEL(t)
    {
        cr_assert_not_null(model_row_of(t), "model %s has no row in the model table", t->name);
        cr_expect_not_null(t->build, "%s", t->name);
        cr_expect_eq(gcp_field_type_lookup(t->name), t, "%s: lookup", t->name);
        nf++;
    }
    cr_expect_geq(nm, 1);
    cr_expect_geq(nf, 1);
    /* (P5) unknown names are refused */
    const char *bad[] = {"", "Boris", "boris ", "gc-rk", "rk4", "dipol", "uniformx", "callback"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        cr_expect_null(gcp_pusher_lookup(bad[i]), "method '%s' accepted", bad[i]);
        cr_expect_null(gcp_field_type_lookup(bad[i]), "model '%s' accepted", bad[i]);
    }
    cr_expect_null(gcp_field_type_lookup(NULL));
}

/* ---- (F1) block evaluation equals scalar evaluation ---------------------- */

static void check_block_equals_scalar(const struct gcp_field *f, double pts[NPT][3])
{
    static const unsigned needs[] = {GCP_NEED_B, GCP_NEED_B | GCP_NEED_GRADB,
                                     GCP_NEED_B | GCP_NEED_E,
                                     GCP_NEED_B | GCP_NEED_GRADB | GCP_NEED_E};
    double x[NPT], y[NPT], z[NPT], B[3][NPT], G[3][3][NPT], E[3][NPT];
    int32_t st[NPT];
    for (int i = 0; i < NPT; i++) x[i] = pts[i][0], y[i] = pts[i][1], z[i] = pts[i][2];
    for (size_t k = 0; k < sizeof needs / sizeof needs[0]; k++) {
        const unsigned need = needs[k];
        struct gcp_field_soa o;
        for (int a = 0; a < 3; a++) {
            o.B[a] = B[a], o.E[a] = E[a];
            for (int c = 0; c < 3; c++) o.G[a][c] = G[a][c];
        }
        memset(st, 0, sizeof st);
        gcp_field_eval_soa(f, 0.0, need, NPT, x, y, z, &o, st);
        for (int i = 0; i < NPT; i++) {
            struct gcp_field_sample s;
            const int rc = sample(f, pts[i], need, &s);
            cr_assert_eq(rc, 0, "%s: point %d outside the domain (status %d)", f->type->name, i, rc);
            cr_expect_eq(st[i], rc, "%s soa need %u: status[%d] %d", f->type->name, need, i, st[i]);
            for (int a = 0; a < 3; a++) {
                cr_expect(memcmp(&B[a][i], &s.B[a], sizeof(double)) == 0,
                          "%s soa need %u: B%d[%d] %.17g, scalar %.17g", f->type->name, need, a, i,
                          B[a][i], s.B[a]);
                if (need & GCP_NEED_E)
                    cr_expect(memcmp(&E[a][i], &s.E[a], sizeof(double)) == 0,
                              "%s soa need %u: E%d[%d] %.17g, scalar %.17g", f->type->name, need,
                              a, i, E[a][i], s.E[a]);
                if (need & GCP_NEED_GRADB)
                    for (int c = 0; c < 3; c++)
                        cr_expect(memcmp(&G[a][c][i], &s.gradB[a][c], sizeof(double)) == 0,
                                  "%s soa need %u: dB%d/dx%d[%d] %.17g, scalar %.17g",
                                  f->type->name, need, a, c, i, G[a][c][i], s.gradB[a][c]);
            }
        }
    }
    /* (F1') a closed form the model exports (field_kernels.h): the same B
     * and E, bit for bit -- the fused full-orbit step relies on it */
    struct gcp_point_B form;
    if (gcp_field_point_B(f, &form)) {
        for (int i = 0; i < NPT; i++) {
            struct gcp_field_sample s;
            double Bf[3], Ef[3];
            sample(f, pts[i], GCP_NEED_B | GCP_NEED_E, &s);
            gcp_point_B_eval(&form, pts[i][0], pts[i][1], pts[i][2], Bf, Ef);
            cr_expect_eq(form.has_E, f->has_E, "%s point_B: has_E", f->type->name);
            for (int a = 0; a < 3; a++) {
                cr_expect(memcmp(&Bf[a], &s.B[a], sizeof(double)) == 0,
                          "%s point_B form %d: B%d[%d] %.17g, scalar %.17g", f->type->name,
                          form.form, a, i, Bf[a], s.B[a]);
                cr_expect(memcmp(&Ef[a], &s.E[a], sizeof(double)) == 0,
                          "%s point_B form %d: E%d[%d]", f->type->name, form.form, a, i);
            }
        }
    } else {
        cr_expect_eq(form.form, GCP_POINT_B_NONE, "%s: no point_B, form %d", f->type->name,
                     form.form);
    }
    /* the legacy B (and E) block form, with and without E */
    for (int withE = 0; withE < 2; withE++) {
        memset(st, 0, sizeof st);
        f->type->eval_block(f, 0.0, NPT, x, y, z, B[0], B[1], B[2], withE ? E[0] : NULL,
                            withE ? E[1] : NULL, withE ? E[2] : NULL, st);
        for (int i = 0; i < NPT; i++) {
            struct gcp_field_sample s;
            sample(f, pts[i], GCP_NEED_B | GCP_NEED_E, &s);
            for (int a = 0; a < 3; a++) {
                cr_expect(memcmp(&B[a][i], &s.B[a], sizeof(double)) == 0,
                          "%s eval_block: B%d[%d] %.17g, scalar %.17g", f->type->name, a, i,
                          B[a][i], s.B[a]);
                if (withE)
                    cr_expect(memcmp(&E[a][i], &s.E[a], sizeof(double)) == 0,
                              "%s eval_block: E%d[%d]", f->type->name, a, i);
            }
        }
    }
}

/* ---- (F2) div B and grad B against centred differences --------------------
 * (T1) grad B against D_j B = [B(x + h e_j) - B(x - h e_j)] / (2h), h = 1e-5 L.
 *   Truncation h^2/6 |B'''|; B varies on L (the model's length scale: a grid
 *   cell for the interpolants, whose third derivative is bounded by the
 *   data's over a cell), |B'''| <= 60 |B|/L^3 (the dipole's d^3/dr^3 r^-3
 *   coefficient, the largest here): <= 1e-9 |B|/L.  Round-off: B carries
 *   <= ~100 roundings in the spline and spherical-harmonic models, i.e.
 *   100 eps |B| / h = 2.2e-9 |B|/L.  Measured against S = |grad B|_F + |B|/L,
 *   the sum is 3.2e-9 S: TOL_FD = 1e-7 S is a 30x margin, and 1e-7 is far
 *   below any analytic slip (a missing or wrong-signed term is O(1e-2) S or
 *   more).
 * (T2) div B = trace(grad B): each entry a sum of products with <= ~100
 *   roundings, sub-terms bounded by a few |grad B|_F: |div B| <= 3 * 100 eps
 *   * 4 |grad B|_F ~ 3e-13 |grad B|_F, but the interpolants' entries come
 *   from second derivatives of psi rotated to Cartesian, whose sub-terms
 *   are |B|/R-sized: TOL_DIV = 1e-11 (|grad B|_F + |B|/L). */
#define TOL_FD 1e-7
#define TOL_DIV 1e-11

static void check_div_grad(const struct gcp_field *f, const struct model_row *r,
                           const double x[3])
{
    struct gcp_field_sample s, sp, sm;
    sample(f, x, GCP_NEED_B | GCP_NEED_GRADB, &s);
    const double h = 1e-5 * r->L;
    double fd[3][3];
    for (int j = 0; j < 3; j++) {
        double xp[3] = {x[0], x[1], x[2]}, xm[3] = {x[0], x[1], x[2]};
        xp[j] += h, xm[j] -= h;
        sample(f, xp, GCP_NEED_B, &sp);
        sample(f, xm, GCP_NEED_B, &sm);
        for (int i = 0; i < 3; i++) fd[i][j] = (sp.B[i] - sm.B[i]) / (xp[j] - xm[j]);
    }
    const double S = frob(s.gradB) + norm3(s.B) / r->L;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            cr_expect_leq(fabs(fd[i][j] - s.gradB[i][j]), TOL_FD * S,
                          "%s: dB%d/dx%d at (%g, %g, %g): %.12g, difference %.12g", f->type->name,
                          i, j, x[0], x[1], x[2], s.gradB[i][j], fd[i][j]);
    const double div = s.gradB[0][0] + s.gradB[1][1] + s.gradB[2][2];
    cr_expect_leq(fabs(div), TOL_DIV * S, "%s: div B = %g at (%g, %g, %g), scale %g",
                  f->type->name, div, x[0], x[1], x[2], S);
}

/* ---- (F3) curl A = B ------------------------------------------------------
 * curl A from the analytic dA (the same expressions as B, only round-off):
 * 1e-12 (|B| + max |dA_ij|), as in test_gc_basic.c; and dA against centred
 * differences of A with h = 1e-4 L (truncation (h/L)^2 ~ 1e-8, round-off
 * eps |A| / h ~ 1e-12 |A|/L): 1e-6 (|A|/L + max |dA|). */
static void check_curl_A(const struct gcp_field *f, const struct model_row *r, const double x[3])
{
    double A[3], dA[3][3], phi;
    cr_assert_eq(gcp_field_potential(f, 0.0, x, A, dA, &phi), 0, "%s: potential", f->type->name);
    double dmax = 0.0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) dmax = fmax(dmax, fabs(dA[i][j]));
    const double h = 1e-4 * r->L;
    for (int j = 0; j < 3; j++) {
        double xp[3] = {x[0], x[1], x[2]}, xm[3] = {x[0], x[1], x[2]}, Ap[3], Am[3];
        xp[j] += h, xm[j] -= h;
        gcp_field_potential(f, 0.0, xp, Ap, NULL, NULL);
        gcp_field_potential(f, 0.0, xm, Am, NULL, NULL);
        for (int i = 0; i < 3; i++)
            cr_expect_leq(fabs((Ap[i] - Am[i]) / (xp[j] - xm[j]) - dA[i][j]),
                          1e-6 * (norm3(A) / r->L + dmax), "%s: dA%d/dx%d", f->type->name, i, j);
    }
    const double curl[3] = {dA[2][1] - dA[1][2], dA[0][2] - dA[2][0], dA[1][0] - dA[0][1]};
    struct gcp_field_sample s;
    sample(f, x, GCP_NEED_B, &s);
    for (int i = 0; i < 3; i++)
        cr_expect_leq(fabs(curl[i] - s.B[i]), 1e-12 * (norm3(s.B) + dmax),
                      "%s: (curl A)_%d = %.15g, B = %.15g", f->type->name, i, curl[i], s.B[i]);
}

/* ---- (F4) psi consistent with B -------------------------------------------
 * psi = R A_phi: B_R = -(1/R) dpsi/dZ, B_Z = (1/R) dpsi/dR.  Centred
 * differences with h = 1e-5 L, the same budget as (T1) one derivative lower
 * (truncation h^2/6 |psi'''| <= 1e-9 |B| R, round-off 100 eps |psi|/h with
 * |psi| <~ |B| R L): TOL_FD (|B| + |psi|/(R L)). */
static void check_psi(const struct gcp_field *f, const struct model_row *r, const double x[3])
{
    const double R = hypot(x[0], x[1]), c = x[0] / R, sn = x[1] / R, h = 1e-5 * r->L;
    double psi, pRp, pRm, pZp, pZm;
    cr_assert_eq(gcp_field_psi(f, x, &psi), 0, "%s: psi", f->type->name);
    const double xRp[3] = {(R + h) * c, (R + h) * sn, x[2]}, xRm[3] = {(R - h) * c, (R - h) * sn, x[2]};
    const double xZp[3] = {x[0], x[1], x[2] + h}, xZm[3] = {x[0], x[1], x[2] - h};
    gcp_field_psi(f, xRp, &pRp), gcp_field_psi(f, xRm, &pRm);
    gcp_field_psi(f, xZp, &pZp), gcp_field_psi(f, xZm, &pZm);
    struct gcp_field_sample s;
    sample(f, x, GCP_NEED_B, &s);
    const double BR = s.B[0] * c + s.B[1] * sn;
    const double tol = TOL_FD * (norm3(s.B) + fabs(psi) / (R * r->L));
    cr_expect_leq(fabs(-(pZp - pZm) / (2 * h) / R - BR), tol, "%s: B_R %.12g vs -(1/R) dpsi/dZ %.12g",
                  f->type->name, BR, -(pZp - pZm) / (2 * h) / R);
    cr_expect_leq(fabs((pRp - pRm) / (2 * h) / R - s.B[2]), tol,
                  "%s: B_Z %.12g vs (1/R) dpsi/dR %.12g", f->type->name, s.B[2],
                  (pRp - pRm) / (2 * h) / R);
}

Test(conformance, every_model_block_div_curl_psi)
{
    FOREACH_MODEL(t)
    {
        const struct model_row *r = model_row_of(t);
        cr_assert_not_null(r, "model %s has no row", t->name);
        struct gcp_field *f = build_model(t, r);
        const unsigned caps = gcp_field_caps(f);
        cr_expect_eq(caps, r->caps, "%s: capabilities 0x%x, table 0x%x", t->name, caps, r->caps);
        double pts[NPT][3];
        model_points(r, pts);
        check_block_equals_scalar(f, pts);
        int nA = 0, npsi = 0;
        for (int i = 0; i < NPT; i++) {
            if (caps & GCP_CAP_GRADB) check_div_grad(f, r, pts[i]);
            if (caps & GCP_CAP_A) check_curl_A(f, r, pts[i]), nA++;
            if (caps & GCP_CAP_PSI) check_psi(f, r, pts[i]), npsi++;
        }
        /* a model without the capability must say so, not give a wrong value */
        double A[3], psi;
        if (!(caps & GCP_CAP_A))
            cr_expect_neq(gcp_field_potential(f, 0.0, pts[0], A, NULL, NULL), 0, "%s: A", t->name);
        if (!(caps & GCP_CAP_PSI))
            cr_expect_neq(gcp_field_psi(f, pts[0], &psi), 0, "%s: psi", t->name);
        cr_log_info("%s: caps 0x%x, %d points, curl A at %d, psi at %d", t->name, caps, NPT, nA,
                    npsi);
        gcp_field_free(f);
    }
    remove_tmpdir();
}

/* (P1) Order by step halving.  Fixed-step methods: N, 2N, 4N steps over the
 * same time; e_k = |x_k - x_ref|.  The floor below which an error is
 * round-off or the reference's own error: 2e-13 (|x0| + scale) (the
 * reference's 1e-13 relative control per step on the scaled state, whose
 * errors largely cancel over a smooth orbit: gc-rk4 shows a clean order
 * 3.99 down to 5e-13 |x0| in the dipole; positions are known to eps |x0|).  A method exact in the field (the
 * guiding centre in a uniform field moves on a straight line at constant
 * speed) shows e_0 below the floor: then all three must be.  Else the
 * measured order log2(e_k/e_k+1) of the finest pair whose finer error is
 * above 10x the floor must be within 0.35 of the table's: with
 * e(h) = C h^p (1 + D h^a + ...), the measured value is
 * p + log2((1 + D h^a)/(1 + D (h/2)^a)), within 0.35 while the next term is
 * below a third of the leading one at the finer step pair.  In a model
 * whose grad B is not smooth (model_row.smooth) the errors must fall at
 * each halving (over the two halvings together: see the disabled test),
 * no order asserted.  Adaptive methods: the error at
 * tolerance 1e-9 must not exceed that at 1e-6, and both stay below 1e3 tol (|x0| + scale) (per-step relative control
 * accumulated over <~100 steps, 10x margin). */
#define ORDER_MARGIN 0.35

static int strict_convergence;

static void check_order(const struct gcp_field *f, const struct model_row *r,
                        const struct gcp_pusher_type *p, const struct method_row *mr)
{
    const int gc = p->kind == GCP_GUIDING_CENTRE;
    const struct start s = make_start(f, r, gc);
    double xref[3], xe[3], ue[3], pp, e[3];
    reference(f, &s, gc, mr->newtonian, xref);
    const double floor_ = 2e-13 * (norm3(s.x) + s.scale);
    if (mr->adaptive) {
        const double tols[2] = {1e-6, 1e-9};
        for (int k = 0; k < 2; k++) {
            const struct gcp_push_opts o = {0.0, s.T_push, 1, tols[k], 0.0};
            const int st = push_one(f, p, &s, &o, xe, ue, &pp);
            cr_expect_eq(st, GCP_ALIVE, "%s in %s: status %d", p->name, f->type->name, st);
            e[k] = dist3(xe, xref);
            cr_expect_leq(e[k], fmax(1e3 * tols[k] * (norm3(s.x) + s.scale), floor_),
                          "%s in %s: error %.3e at tolerance %g", p->name, f->type->name, e[k],
                          tols[k]);
        }
        cr_expect(e[1] <= e[0] * (1.0 + 1e-6) + floor_, "%s in %s: no convergence %.3e -> %.3e",
                  p->name, f->type->name, e[0], e[1]);
        cr_log_info("%-18s %-8s error %.3e (tol 1e-6) %.3e (tol 1e-9) [m]", p->name,
                    f->type->name, e[0], e[1]);
        return;
    }
    const int64_t N0 = gc ? 4 : 64;
    for (int k = 0; k < 3; k++) {
        const int64_t N = N0 << k;
        const struct gcp_push_opts o = {0.0, s.T_push / (double)N, N, 0.0, 0.0};
        const int st = push_one(f, p, &s, &o, xe, ue, &pp);
        cr_expect_eq(st, GCP_ALIVE, "%s in %s: status %d with %lld steps", p->name,
                     f->type->name, st, (long long)N);
        e[k] = dist3(xe, xref);
    }
    if (e[0] <= floor_) {
        cr_expect(e[1] <= floor_ && e[2] <= floor_, "%s in %s: errors %.3e %.3e %.3e", p->name,
                  f->type->name, e[0], e[1], e[2]);
        cr_log_info("%-18s %-8s exact here: errors %.2e %.2e %.2e [m]", p->name, f->type->name,
                    e[0], e[1], e[2]);
        return;
    }
    const double p01 = log2(e[0] / e[1]), p12 = log2(e[1] / e[2]);
    if (!(gc && !r->smooth)) {
        const int fine = e[2] > 10.0 * floor_;
        cr_expect(fine || e[1] > 10.0 * floor_, "%s in %s: errors %.3e %.3e too close to the floor %.3e",
                  p->name, f->type->name, e[1], e[2], floor_);
        const double pm = fine ? p12 : p01;
        cr_expect_leq(fabs(pm - mr->order), ORDER_MARGIN,
                      "%s in %s: measured order %.2f, table %d; errors %.3e %.3e %.3e", p->name,
                      f->type->name, pm, mr->order, e[0], e[1], e[2]);
    } else if (strict_convergence) {
        cr_expect(e[1] < e[0] && e[2] < e[1], "%s in %s: no convergence %.3e %.3e %.3e", p->name,
                  f->type->name, e[0], e[1], e[2]);
    } else {
        /* over two halvings; see the disabled test below for each one */
        cr_expect(e[2] < e[0], "%s in %s: no convergence %.3e %.3e %.3e", p->name,
                  f->type->name, e[0], e[1], e[2]);
    }
    cr_log_info("%-18s %-8s order %.2f %.2f (table %d), errors %.2e %.2e %.2e [m]", p->name,
                f->type->name, p01, p12, mr->order, e[0], e[1], e[2]);
}

Test(conformance, every_method_order_by_step_halving, .timeout = 60)
{
    FOREACH_MODEL(t)
    {
        struct gcp_field *f = build_model(t, model_row_of(t));
        FOREACH_METHOD(p)
        {
            const struct method_row *mr = method_row_of(p);
            cr_assert_not_null(mr, "%s", p->name);
            if (!applies(p, f)) continue;
            check_order(f, model_row_of(t), p, mr);
        }
        gcp_field_free(f);
    }
    remove_tmpdir();
}

/* DISABLED (a finding, not a pass): in the DIII-D equilibrium (eqdsk, the
 * one non-smooth model in which the symplectic methods apply) gc-gl4 and
 * gc-gl4-sundman do not converge at each halving.  Position errors of the
 * same push (tau/2 of a 10 keV proton, 2.5 m) after 4, 8, 16, ..., 256
 * steps, gc-gl4: 3.0e-5 3.4e-7 2.5e-6 1.0e-7 1.8e-8 1.5e-9 1.6e-9 m;
 * gc-rk4 in the same field: 1.3e-5 8.2e-7 5.4e-8 2.9e-9 2.7e-10 7.2e-12
 * 2.5e-12; gc-gl2: a clean order 2 down to 1.2e-7.  Two things: the
 * irregular sequence (possibly the C0 grad B of the spline, which an
 * implicit 4th-order stage samples differently at each dt), and a floor
 * near 1.6e-9 m (8e-10 of |X|) that no step removes while gc-rk4 reaches
 * 2.5e-12 m: the size of an approximation in the numerical canonical chart
 * of the eqdsk field (src/pushers/canon_flux_num.c), not of the
 * Gauss-Legendre stages (order 4.00 in the dipole, mirror and tokamak).
 * The enabled order test asks these models only e_4N < e_N. */
Test(conformance, every_method_converges_at_each_halving_in_nonsmooth_models, .disabled = true)
{
    strict_convergence = 1;
    FOREACH_MODEL(t)
    {
        if (model_row_of(t)->smooth) continue;
        struct gcp_field *f = build_model(t, model_row_of(t));
        FOREACH_METHOD(p)
        if (applies(p, f) && !p->adaptive) check_order(f, model_row_of(t), p, method_row_of(p));
        gcp_field_free(f);
    }
    remove_tmpdir();
}

/* ---- (P2) energy in static pure-B fields ----------------------------------
 * Every model without E and without time dependence (capabilities), every
 * method that applies, 200 steps (full orbit, 2 gyro-periods) or 20 steps
 * (guiding centre, tau/2; adaptive: tolerance 1e-9).  The kinetic measure
 * p^2 (full orbit m^2 |u|^2; guiding centre p_par^2 + 2 m mu |B(X)|) is
 * exact for the true motion.  Round-off methods: each step changes |u|^2 by
 * <= ~10 roundings of relative eps (a rotation), summed over N steps at
 * worst: |dp^2/p^2| <= 10 eps N.  The others: bounded by their truncation
 * error, < 1e-3 at these steps (a broken update gives O(1)); and the check
 * has to discriminate: some method of the registry must exceed 10 eps N
 * somewhere, or the round-off bound would prove nothing. */
static double p2_end(const struct gcp_field *f, const struct start *s, int gc, const double xe[3],
                     const double ue[3], double ppar)
{
    if (!gc) return s->m * s->m * dot3(ue, ue);
    struct gcp_field_sample fs;
    sample(f, xe, GCP_NEED_B, &fs);
    return ppar * ppar + 2.0 * s->m * s->mu * norm3(fs.B);
}

Test(conformance, energy_in_static_pure_B)
{
    int above_roundoff = 0, checked = 0;
    FOREACH_MODEL(t)
    {
        const struct model_row *r = model_row_of(t);
        struct gcp_field *f = build_model(t, r);
        if (gcp_field_caps(f) & (GCP_CAP_E | GCP_CAP_TIME)) {
            gcp_field_free(f);
            continue;
        }
        FOREACH_METHOD(p)
        {
            const struct method_row *mr = method_row_of(p);
            if (!applies(p, f)) continue;
            const int gc = p->kind == GCP_GUIDING_CENTRE;
            const struct start s = make_start(f, r, gc);
            const int64_t N = gc ? 20 : 200;
            /* adaptive: one interval T_push (its first trial step), tolerance 1e-9 */
            const struct gcp_push_opts o = {0.0, p->adaptive ? s.T_push : s.T_push / (double)N,
                                            p->adaptive ? 1 : N, p->adaptive ? 1e-9 : 0.0, 0.0};
            double xe[3], ue[3], pp;
            const int st = push_one(f, p, &s, &o, xe, ue, &pp);
            cr_expect_eq(st, GCP_ALIVE, "%s in %s: status %d", p->name, t->name, st);
            const double p20 = p2_end(f, &s, gc, s.x, s.u, s.ppar);
            const double rel = fabs(p2_end(f, &s, gc, xe, ue, pp) / p20 - 1.0);
            const double bound = 10.0 * EPS * (double)N;
            if (mr->energy_roundoff)
                cr_expect_leq(rel, bound, "%s in %s: |dp^2/p^2| = %.3e > round-off %.3e", p->name,
                              t->name, rel, bound);
            else
                cr_expect_lt(rel, 1e-3, "%s in %s: |dp^2/p^2| = %.3e", p->name, t->name, rel);
            above_roundoff += rel > bound;
            checked++;
            cr_log_info("%-18s %-8s |dp^2/p^2| = %.2e (round-off bound %.1e)", p->name, t->name,
                        rel, bound);
        }
        gcp_field_free(f);
    }
    cr_expect_gt(checked, 0);
    cr_expect_gt(above_roundoff, 0, "no method exceeds the round-off bound anywhere");
    remove_tmpdir();
}

/* ---- (P3) bad dt, (P4) NaN state -------------------------------------------
 * Two lanes of the row's particle.  dt in {0, -dt, NaN, inf}: both lanes
 * STEP_FAILED with no step taken and the state bit for bit the initial one
 * (gc.h's contract; the same is asked of every kind).  A NaN position in
 * lane 1: NONFINITE, no crash, lane 0 ALIVE. */
static void fill2(struct gcp_block *b, const struct start *s)
{
    b->q = s->q, b->m = s->m, b->n_active = 2;
    for (size_t i = 0; i < 2; i++) {
        b->x[i] = s->x[0], b->y[i] = s->x[1], b->z[i] = s->x[2];
        b->ux[i] = s->u[0], b->uy[i] = s->u[1], b->uz[i] = s->u[2];
        b->ppar[i] = s->ppar, b->mu[i] = s->mu;
        b->status[i] = 0, b->steps[i] = 0, b->t[i] = 0.0, b->index[i] = i;
    }
}

static void check_bad_dt(const struct gcp_field *f, const struct model_row *r,
                         const struct gcp_pusher_type *p)
{
    const int gc = p->kind == GCP_GUIDING_CENTRE;
    const struct start s = make_start(f, r, gc);
    const double dt0 = s.T_push / 16.0, bad[4] = {0.0, -dt0, NAN, INFINITY};
    struct gcp_block b;
    cr_assert_eq(gcp_block_alloc(&b, 2), 0);
    for (int k = 0; k < 4; k++) {
        fill2(&b, &s);
        const struct gcp_push_opts o = {0.0, bad[k], 4, 0.0, 0.0};
        const size_t live = p->advance(&b, f, p, &o, NULL);
        cr_expect_eq(live, 0u, "%s in %s: dt %g, %zu lanes live", p->name, f->type->name, bad[k], live);
        for (size_t i = 0; i < 2; i++) {
            cr_expect_eq(b.status[i], GCP_STEP_FAILED, "%s in %s: dt %g, status %d", p->name,
                         f->type->name, bad[k], b.status[i]);
            cr_expect_eq(b.steps[i], 0, "%s in %s: dt %g", p->name, f->type->name, bad[k]);
            cr_expect(b.x[i] == s.x[0] && b.y[i] == s.x[1] && b.z[i] == s.x[2] &&
                          (gc ? b.ppar[i] == s.ppar
                              : (b.ux[i] == s.u[0] && b.uy[i] == s.u[1] && b.uz[i] == s.u[2])),
                      "%s in %s: dt %g moved the state", p->name, f->type->name, bad[k]);
        }
    }
    gcp_block_free(&b);
}

static void check_nan_state(const struct gcp_field *f, const struct model_row *r,
                            const struct gcp_pusher_type *p)
{
    const int gc = p->kind == GCP_GUIDING_CENTRE;
    const struct start s = make_start(f, r, gc);
    struct gcp_block b;
    cr_assert_eq(gcp_block_alloc(&b, 2), 0);
    fill2(&b, &s);
    b.x[1] = NAN;
    const struct gcp_push_opts o = {0.0, s.T_push / 16.0, 4, 0.0, 0.0};
    const size_t live = p->advance(&b, f, p, &o, NULL);
    cr_expect_eq(live, 1u, "%s in %s: %zu lanes live", p->name, f->type->name, live);
    for (size_t i = 0; i < 2; i++) {
        const int want = b.index[i] == 1 ? GCP_NONFINITE : GCP_ALIVE;
        cr_expect_eq(b.status[i], want, "%s in %s: lane %zu status %d, expected %d", p->name,
                     f->type->name, b.index[i], b.status[i], want);
    }
    gcp_block_free(&b);
}

Test(conformance, nan_state_every_method_every_model)
{
    FOREACH_MODEL(t)
    {
        struct gcp_field *f = build_model(t, model_row_of(t));
        FOREACH_METHOD(p)
        if (applies(p, f)) check_nan_state(f, model_row_of(t), p);
        gcp_field_free(f);
    }
    remove_tmpdir();
}

static void bad_dt_of_kind(int full_orbit)
{
    FOREACH_MODEL(t)
    {
        struct gcp_field *f = build_model(t, model_row_of(t));
        FOREACH_METHOD(p)
        if (applies(p, f) && (p->kind == GCP_FULL_ORBIT) == full_orbit)
            check_bad_dt(f, model_row_of(t), p);
        gcp_field_free(f);
    }
    remove_tmpdir();
}

Test(conformance, bad_dt_guiding_centre_methods) { bad_dt_of_kind(0); }

/* The full-orbit step (gcp_block_advance_fo) did not check dt (found by
 * this battery): dt = 0 left every lane ALIVE with steps counted, a
 * negative dt pushed backwards, inf and NaN overwrote the state.  The evolve
 * layer now refuses all four as for the guiding centre (STEP_FAILED,
 * BAD_OPTIONS, the state untouched). */
Test(conformance, bad_dt_full_orbit_methods) { bad_dt_of_kind(1); }
