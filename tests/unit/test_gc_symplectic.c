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
