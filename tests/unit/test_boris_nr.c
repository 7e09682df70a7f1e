/* boris-nr, the non-relativistic Boris push (u = v; kernels.h
 * gcp_push_boris_nr, src/pushers/boris_nr.c), against closed forms.
 *
 * In a uniform B the Boris map is an exact rotation of v about b by
 * theta = 2 atan(Omega dt / 2) per step (Omega = |q B| / m; Birdsall &
 * Langdon sec. 4-4); in uniform E perpendicular to B it is that rotation
 * about v_E = E x B / B^2, so v_n = v_E + R(-n theta) (v_0 - v_E) exactly
 * (the affine map's fixed point is v_E for every Omega dt).  Each property
 * is asserted to round-off with a derived bound, and each test shows a
 * method without the property failing it by orders of magnitude: RK4 on the
 * same equation (energy), the relativistic boris and boris-zu (gyrophase,
 * drift).  At a relativistic energy the test shows where boris-nr is not
 * valid: its gyrofrequency is the relativistic one times gamma.
 *
 * The order in the dipole (2, against GSL rk8pd on Newton's equations) is
 * the conformance battery's (test_conformance.c, the method table's
 * newtonian column); the fused step against the block step, bit for bit,
 * is test_fo_fused.c's.
 *
 * Round-off unit u_r = eps/2.  A kick is 2 fused operations a component
 * from v- to v' and 2 more to v+ (|t|, |s| <= 1 here), each rounded once:
 * a step moves |v| by at most ~4 u_r |v|, and the rotation angle (t and s
 * rounded once for the whole push) by ~4 u_r theta.  Over N steps the
 * bounds below take these linearly (worst case, no random-walk luck):
 * 8 u_r (N + Phi), Phi = N theta the total phase.  Cost: ~0.3 s. */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include <criterion/criterion.h>

#include "gcpush/field.h"
#include "gcpush/field_kernels.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "gcpush/pusher.h"

#define UR (DBL_EPSILON / 2.0)
#define QP 1.602176634e-19   /* [C] */
#define MP 1.67262192369e-27 /* [kg] */

static void cross(const double a[3], const double b[3], double o[3])
{
    const double c0 = a[1] * b[2] - a[2] * b[1], c1 = a[2] * b[0] - a[0] * b[2],
                 c2 = a[0] * b[1] - a[1] * b[0];
    o[0] = c0, o[1] = c1, o[2] = c2;
}
static double dot(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static double norm(const double a[3]) { return sqrt(dot(a, a)); }

/* b: a unit vector off the axes (no component is special) */
static void unit_b(double b[3])
{
    const double v[3] = {0.1, -0.2, 0.9}, n = norm(v);
    for (int k = 0; k < 3; k++) b[k] = v[k] / n;
}

/* The exact motion of v about v0c (the drift velocity, 0 in pure B) in B
 * along b for a positive charge: dv/dt = Omega (v - vc) x b, so v - vc
 * turns by -phi about b:  w(phi) = w_par + w_perp cos phi - (b x w) sin phi. */
static void rotate(const double v0[3], const double vc[3], const double b[3], double phi,
                   double out[3])
{
    double w[3], bxw[3];
    for (int k = 0; k < 3; k++) w[k] = v0[k] - vc[k];
    const double wp = dot(w, b);
    cross(b, w, bxw);
    for (int k = 0; k < 3; k++)
        out[k] = vc[k] + wp * b[k] + (w[k] - wp * b[k]) * cos(phi) - bxw[k] * sin(phi);
}

/* n lanes pushed nsteps by p in field f (the library's block push: the
 * fused tiles in these uniform fields) */
static void push(const struct gcp_field *f, const struct gcp_pusher_type *p, size_t n,
                 double x[][3], double u[][3], double dt, int64_t nsteps)
{
    struct gcp_block b;
    cr_assert_eq(gcp_block_alloc(&b, n), 0);
    b.q = QP, b.m = MP;
    for (size_t i = 0; i < n; i++) {
        b.x[i] = x[i][0], b.y[i] = x[i][1], b.z[i] = x[i][2];
        b.ux[i] = u[i][0], b.uy[i] = u[i][1], b.uz[i] = u[i][2];
    }
    cr_assert_eq(gcp_block_start(&b, f, 0.0), n);
    cr_assert_eq(gcp_block_advance_fo(&b, f, p, 0.0, dt, nsteps, NULL), n);
    for (size_t l = 0; l < n; l++) {
        const size_t i = b.index[l];
        x[i][0] = b.x[l], x[i][1] = b.y[l], x[i][2] = b.z[l];
        u[i][0] = b.ux[l], u[i][1] = b.uy[l], u[i][2] = b.uz[l];
    }
    gcp_block_free(&b);
}

static double urand(unsigned long long *s)
{
    *s = *s * 6364136223846793005ULL + 1442695040888963407ULL;
    return (double)(*s >> 11) * 0x1.0p-53;
}

/* RK4 on dv/dt = Omega v x b (the contrast: not a rotation; per step
 * |v|^2 shrinks by (Omega dt)^6 / 72, Hairer, Lubich & Wanner sec. IV.1) */
static void rk4_rotation(double v[3], const double b[3], double w, int64_t n)
{
    for (int64_t s = 0; s < n; s++) {
        double k[4][3], y[3];
        for (int j = 0; j < 4; j++) {
            const double c = j == 0 ? 0.0 : (j == 3 ? 1.0 : 0.5);
            for (int d = 0; d < 3; d++) y[d] = v[d] + (j ? c * k[j - 1][d] : 0.0);
            cross(y, b, k[j]);
            for (int d = 0; d < 3; d++) k[j][d] *= w;
        }
        for (int d = 0; d < 3; d++)
            v[d] += (k[0][d] + 2.0 * k[1][d] + 2.0 * k[2][d] + k[3][d]) / 6.0;
    }
}

/* Energy in pure B: |v|^2 kept to round-off over 1e5 steps at Omega dt =
 * 0.1, 64 lanes with random velocities (1e5 m/s).  Bound: 2 x 4 u_r a step
 * on |v|^2, linearly: 8 u_r N = 8.9e-11 (measured ~1e-14: the errors do
 * walk).  RK4 with the same step loses 1e5 (0.1)^6 / 72 = 1.4e-3. */
Test(boris_nr, kinetic_energy_roundoff_uniform_B)
{
    enum { NL = 64 };
    const int64_t N = 100000;
    double b[3], B[3];
    unit_b(b);
    for (int k = 0; k < 3; k++) B[k] = 1.0 * b[k];
    struct gcp_field *f = gcp_field_uniform_create(B, (const double[3]){0, 0, 0});
    cr_assert_not_null(f);
    const double Om = QP * 1.0 / MP, dt = 0.1 / Om;
    static double x[NL][3], u[NL][3], u0[NL][3];
    unsigned long long s = 7;
    for (int i = 0; i < NL; i++)
        for (int k = 0; k < 3; k++) x[i][k] = urand(&s), u0[i][k] = u[i][k] = 1e5 * (2.0 * urand(&s) - 1.0);
    push(f, &gcp_pusher_boris_nr, NL, x, u, dt, N);
    double worst = 0.0;
    for (int i = 0; i < NL; i++) worst = fmax(worst, fabs(dot(u[i], u[i]) / dot(u0[i], u0[i]) - 1.0));
    const double bound = 8.0 * UR * (double)N;
    cr_log_info("boris-nr: max |d|v|^2/|v|^2| over 1e5 steps %.2e (bound %.2e)", worst, bound);
    cr_expect_leq(worst, bound, "boris-nr: |v|^2 moved by %.3e > %.3e", worst, bound);
    /* the contrast: RK4 on the same rotation, the same step */
    double v[3] = {u0[0][0], u0[0][1], u0[0][2]};
    rk4_rotation(v, b, Om * dt, N);
    const double rk = fabs(dot(v, v) / dot(u0[0], u0[0]) - 1.0);
    cr_log_info("RK4: |d|v|^2/|v|^2| %.2e (theory: (0.1)^6/72 x 1e5 = 1.4e-3 of v_perp^2)", rk);
    cr_expect_gt(rk, 1e3 * bound, "RK4 kept |v|^2 to %.3e: the test cannot tell", rk);
    gcp_field_free(f);
}

/* The gyrophase: after N steps v is the exact rotation of v0 by N theta,
 * theta = 2 atan(Omega dt / 2), at Omega dt = 0.1, N = 1e5 (Phi ~ 1e4 rad).
 * Bound on |v - v_exact| / |v|: 8 u_r (N + Phi) (the step's radial and
 * angular round-off, linearly) + 2 u_r Phi (the reference's own phase
 * rounding) = 1.2e-10.  The relativistic boris turns by 2 atan(Omega dt /
 * (2 gamma)): at 1e5 m/s (gamma - 1 = 5.6e-8) it is off by ~Phi (gamma - 1)
 * = 6e-4; boris-zu turns by Omega dt / gamma: off by N (Omega dt)^3 / 12 ~ 8. */
Test(boris_nr, gyrophase_advances_by_2_atan_half_omega_dt)
{
    const int64_t N = 100000;
    double b[3], B[3];
    unit_b(b);
    for (int k = 0; k < 3; k++) B[k] = b[k];
    struct gcp_field *f = gcp_field_uniform_create(B, (const double[3]){0, 0, 0});
    const double Om = QP / MP, dt = 0.1 / Om, theta = 2.0 * atan(0.5 * Om * dt);
    const double Phi = (double)N * theta;
    const double v0[3] = {1e5, 0.3e5, -0.2e5}, zero[3] = {0, 0, 0};
    double vex[3];
    rotate(v0, zero, b, Phi, vex);
    const double bound = 8.0 * UR * ((double)N + Phi) + 2.0 * UR * Phi;
    const struct gcp_pusher_type *ps[3] = {&gcp_pusher_boris_nr, &gcp_pusher_boris,
                                           &gcp_pusher_boris_zu};
    for (int k = 0; k < 3; k++) {
        double x[1][3] = {{0, 0, 0}}, u[1][3] = {{v0[0], v0[1], v0[2]}};
        push(f, ps[k], 1, x, u, dt, N);
        double d[3];
        for (int j = 0; j < 3; j++) d[j] = u[0][j] - vex[j];
        const double err = norm(d) / norm(v0);
        cr_log_info("%-9s |v - R(N 2atan(Omega dt/2)) v0| / |v0| = %.2e (bound %.2e)", ps[k]->name,
                    err, bound);
        if (k == 0)
            cr_expect_leq(err, bound, "boris-nr: gyrophase error %.3e > %.3e", err, bound);
        else
            cr_expect_gt(err, 1e3 * bound, "%s matches boris-nr's phase law (%.3e)",
                         ps[k]->name, err);
    }
    gcp_field_free(f);
}

/* E x B: uniform E perpendicular to B, Omega dt = 0.5 (large), v0 = v_E +
 * w (a gyration of 1e5 m/s about the drift, |v_E| = 1e4 m/s): after N =
 * 1e4 steps v = v_E + R(-N theta) w exactly.  Bound 8 u_r (N + Phi) |v0|
 * + 2 u_r Phi |w| as above, on |v|.  Started at v_E the particle stays
 * there: |v - v_E| within the same bound, x moves by v_E t (bound: each
 * step's position round-off, 2 u_r |x| + dt |dv|, linearly).  boris-zu
 * drifts at v_E (theta/2) cot(theta/2), 2% slow at Omega dt = 0.5. */
Test(boris_nr, exb_drift_exact)
{
    const int64_t N = 10000;
    double b[3], B[3], e1[3], E[3], vE[3];
    unit_b(b);
    for (int k = 0; k < 3; k++) B[k] = b[k];
    const double zhat[3] = {0, 0, 1};
    cross(b, zhat, e1);
    const double n1 = norm(e1);
    for (int k = 0; k < 3; k++) E[k] = 1e4 * e1[k] / n1; /* [V/m], |B| = 1 T */
    cross(E, B, vE);                                     /* E x B / B^2 */
    struct gcp_field *f = gcp_field_uniform_create(B, E);
    const double Om = QP / MP, dt = 0.5 / Om, theta = 2.0 * atan(0.5 * Om * dt);
    const double Phi = (double)N * theta;
    double w[3], vex[3];
    cross(b, vE, w); /* perpendicular to b and v_E */
    for (int k = 0; k < 3; k++) w[k] *= 1e5 / norm(vE);
    double v0[3];
    for (int k = 0; k < 3; k++) v0[k] = vE[k] + w[k];
    rotate(v0, vE, b, Phi, vex);
    const double bv = 8.0 * UR * ((double)N + Phi) * norm(v0) + 2.0 * UR * Phi * norm(w);
    {
        double x[1][3] = {{0, 0, 0}}, u[1][3] = {{v0[0], v0[1], v0[2]}}, d[3];
        push(f, &gcp_pusher_boris_nr, 1, x, u, dt, N);
        for (int k = 0; k < 3; k++) d[k] = u[0][k] - vex[k];
        cr_log_info("boris-nr E x B with gyration: |v - v_exact| = %.2e m/s (bound %.2e)",
                    norm(d), bv);
        cr_expect_leq(norm(d), bv, "boris-nr: |v - v_exact| = %.3e > %.3e", norm(d), bv);
    }
    const double T = (double)N * dt, X = norm(vE) * T;
    const double bx = (double)N * (2.0 * UR * X + dt * bv);
    const struct gcp_pusher_type *ps[2] = {&gcp_pusher_boris_nr, &gcp_pusher_boris_zu};
    for (int k = 0; k < 2; k++) {
        double x[1][3] = {{0, 0, 0}}, u[1][3] = {{vE[0], vE[1], vE[2]}}, d[3], dx[3];
        push(f, ps[k], 1, x, u, dt, N);
        for (int j = 0; j < 3; j++) d[j] = u[0][j] - vE[j], dx[j] = x[0][j] - vE[j] * T;
        cr_log_info("%-9s started at v_E: |v - v_E| = %.2e m/s (bound %.2e), |x - v_E t| = %.2e m "
                    "(bound %.2e)", ps[k]->name, norm(d), bv, norm(dx), bx);
        if (k == 0) {
            cr_expect_leq(norm(d), bv, "boris-nr: |v - v_E| = %.3e", norm(d));
            cr_expect_leq(norm(dx), bx, "boris-nr: |x - v_E t| = %.3e > %.3e", norm(dx), bx);
        } else {
            cr_expect_gt(norm(d), 1e3 * bv, "boris-zu keeps v_E too (%.3e)", norm(d));
        }
    }
    gcp_field_free(f);
}

/* Where boris-nr is not valid: a 1 GeV proton (gamma = 2.066), the same
 * initial u = p/m for both methods (the run's convention).  Each turns by
 * its own closed form a step, boris-nr by 2 atan(Omega dt / 2), boris by
 * 2 atan(Omega dt / (2 gamma)): boris-nr's gyrofrequency is gamma times the
 * true one (and its speed |u| > c).  N = 2000 steps at Omega dt = 0.01
 * (Phi = 20 rad): each matches its own law to 8 u_r (N + Phi) + 2 u_r Phi
 * = 1.8e-12 and misses the other's by ~|1 - gamma| Phi: swapping the two
 * methods fails the test. */
Test(boris_nr, gyrofrequency_off_by_gamma_at_relativistic_energy)
{
    const int64_t N = 2000;
    const double zero[3] = {0, 0, 0}, B[3] = {0, 0, 1.0};
    struct gcp_field *f = gcp_field_uniform_create(B, zero);
    const double mc2 = MP * GCP_C_LIGHT * GCP_C_LIGHT, T = 1e9 * QP;
    const double gamma = 1.0 + T / mc2, u = GCP_C_LIGHT * sqrt(gamma * gamma - 1.0);
    const double Om = QP / MP, dt = 0.01 / Om;
    const double phi_nr = (double)N * 2.0 * atan(0.5 * Om * dt);
    const double phi_rel = (double)N * 2.0 * atan(0.5 * Om * dt / gamma);
    const double u0[3] = {u, 0, 0}, bz[3] = {0, 0, 1};
    const double bound = 8.0 * UR * ((double)N + phi_nr) + 2.0 * UR * phi_nr;
    const struct gcp_pusher_type *ps[2] = {&gcp_pusher_boris_nr, &gcp_pusher_boris};
    double e[2][2]; /* e[method][law] */
    for (int k = 0; k < 2; k++) {
        double x[1][3] = {{0, 0, 0}}, uu[1][3] = {{u0[0], u0[1], u0[2]}};
        push(f, ps[k], 1, x, uu, dt, N);
        for (int l = 0; l < 2; l++) {
            double vex[3], d[3];
            rotate(u0, zero, bz, l == 0 ? phi_nr : phi_rel, vex);
            for (int j = 0; j < 3; j++) d[j] = uu[0][j] - vex[j];
            e[k][l] = norm(d) / u;
        }
        cr_log_info("%-9s 1 GeV: off the non-relativistic law by %.2e, the relativistic by %.2e",
                    ps[k]->name, e[k][0], e[k][1]);
    }
    cr_log_info("the laws' gyrofrequency ratio boris-nr / boris = %.6f (gamma = %.6f)",
                phi_nr / phi_rel, gamma);
    cr_expect_leq(e[0][0], bound, "boris-nr off its law by %.3e", e[0][0]);
    cr_expect_leq(e[1][1], bound, "boris off its law by %.3e", e[1][1]);
    cr_expect_gt(e[0][1], 0.1, "boris-nr follows the relativistic law (%.3e)", e[0][1]);
    cr_expect_gt(e[1][0], 0.1, "boris follows the non-relativistic law (%.3e)", e[1][0]);
    gcp_field_free(f);
}

/* The fused uniform tiles skip the per-step stop test where it is proved
 * false (fo_fused_priv.h gcp_fo_nr_cannot_stop: no field bounds, a bounded
 * finite start).  test_fo_fused.c gives its fields bounds, so here without:
 * 300 lanes (two full tiles and a partial one) in uniform B and in uniform E
 * and B (B = 1e-9 T: Omega dt = 0.1 at dt = 1 s), pushed 400 steps by the
 * fused step and by the block step (a callback twin of the field, no closed
 * form), with and without a sampler, compared bit for bit.  Lane 150
 * (tile 1) moves along b at 1e153 m/s: r2 + p2 overflows after ~14 steps,
 * a NONFINITE stop of the block step that the fused step must give at the
 * same step (its tile cannot use the proof, the others do and are run
 * again to the stop); lane 17 starts non-finite.  The same for boris,
 * whose uniform tiles use the proof too (fo_fused_priv.h FREE_): there
 * lane 150 (u = 1e153 m/s, |x| growing by ~c dt a step) stays finite and
 * alive, and its tile runs with the test while the others skip it. */
static int twin_eval(double t, const double x[3], struct gcp_field_sample *out, void *ctx)
{
    return gcp_field_eval(ctx, t, x, out);
}

static void run_lanes(const struct gcp_field *f, const struct gcp_pusher_type *p, int64_t every,
                      struct gcp_block *b, const double bhat[3], uint64_t *hash)
{
    enum { NL = 300 };
    cr_assert_eq(gcp_block_alloc(b, NL), 0);
    b->q = QP, b->m = MP;
    unsigned long long s = 99;
    for (size_t i = 0; i < NL; i++) {
        b->x[i] = 1e5 * urand(&s), b->y[i] = 1e5 * urand(&s), b->z[i] = 1e5 * urand(&s);
        b->ux[i] = 1e5 * (2.0 * urand(&s) - 1.0), b->uy[i] = 1e5 * (2.0 * urand(&s) - 1.0);
        b->uz[i] = 1e5 * (2.0 * urand(&s) - 1.0);
    }
    b->x[150] = b->y[150] = b->z[150] = 0.0;
    b->ux[150] = 1e153 * bhat[0], b->uy[150] = 1e153 * bhat[1], b->uz[150] = 1e153 * bhat[2];
    b->uy[17] = NAN;
    gcp_block_start(b, f, 0.0);
    *hash = 0xCBF29CE484222325ull;
    for (int64_t k = 0; k < 400; k += every) {
        gcp_block_advance_fo(b, f, p, (double)k, 1.0, every, NULL);
        const double *a[6] = {b->x, b->y, b->z, b->ux, b->uy, b->uz};
        for (int c = 0; c < 6; c++) {
            const unsigned char *p = (const unsigned char *)a[c];
            for (size_t j = 0; j < b->n_active * sizeof(double); j++)
                *hash = (*hash ^ p[j]) * 0x100000001B3ull;
        }
    }
}

Test(boris_nr, unbounded_uniform_fused_equals_block_step)
{
    double bhat[3], B[3], E[3];
    unit_b(bhat);
    for (int k = 0; k < 3; k++) B[k] = 1e-9 * bhat[k];
    const double e1[3] = {bhat[1], -bhat[0], 0.0}; /* perpendicular to b */
    for (int k = 0; k < 3; k++) E[k] = 1e-6 * e1[k]; /* v_E ~ 1e3 m/s */
    for (int rel = 0; rel < 2; rel++)
    for (int withE = 0; withE < 2; withE++)
        for (int r = 0; r < 3; r++) {
            const struct gcp_pusher_type *p = rel ? &gcp_pusher_boris : &gcp_pusher_boris_nr;
            const int64_t every = r == 0 ? 1 : r == 1 ? 7 : 400;
            struct gcp_field *f = gcp_field_uniform_create(B, withE ? E : NULL);
            struct gcp_field *twin = gcp_field_callback_create(twin_eval, f, f->has_E);
            struct gcp_point_B form;
            cr_assert(gcp_field_point_B(f, &form) && !(f->r_inner > 0.0) &&
                      f->r_outer == INFINITY && f->z_max == INFINITY);
            struct gcp_block a, b;
            uint64_t ha, hb;
            run_lanes(f, p, every, &a, bhat, &ha);
            run_lanes(twin, p, every, &b, bhat, &hb);
            cr_expect_eq(a.n_active, b.n_active);
            cr_expect_eq(a.n_active, rel ? 299u : 298u, "%s E %d every %d: %zu live", p->name,
                         withE, (int)every, a.n_active);
            cr_expect_eq(ha, hb, "%s E %d every %d: the live lanes differ along the push",
                         p->name, withE, (int)every);
            for (size_t i = 0; i < a.n; i++) {
                const double *da[7] = {a.x, a.y, a.z, a.ux, a.uy, a.uz, a.t};
                const double *db[7] = {b.x, b.y, b.z, b.ux, b.uy, b.uz, b.t};
                for (int k = 0; k < 7; k++)
                    cr_expect(memcmp(&da[k][i], &db[k][i], sizeof(double)) == 0,
                              "%s E %d every %d lane %zu array %d: %.17g vs %.17g", p->name,
                              withE, (int)every, i, k, da[k][i], db[k][i]);
                cr_expect_eq(a.status[i], b.status[i]);
                cr_expect_eq(a.steps[i], b.steps[i]);
                cr_expect_eq(a.index[i], b.index[i]);
                if (a.index[i] == 150 && rel)
                    cr_expect(a.status[i] == GCP_ALIVE &&
                                  a.steps[i] == (400 + every - 1) / every * every,
                              "boris lane 150: status %d after %lld steps", a.status[i],
                              (long long)a.steps[i]);
                else if (a.index[i] == 150)
                    cr_expect(a.status[i] == GCP_NONFINITE && a.steps[i] > 5 && a.steps[i] < 50,
                              "lane 150: status %d after %lld steps", a.status[i],
                              (long long)a.steps[i]);
            }
            gcp_block_free(&a);
            gcp_block_free(&b);
            gcp_field_free(twin);
            gcp_field_free(f);
        }
}
