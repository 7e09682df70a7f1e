/* The curl-free canonical chart: guiding centres in a curl-free
 * axisymmetric magnetic field (the dipole, the mirror), issue 11.
 *
 * Geometry.  A curl-free axisymmetric field without B_phi is at once
 *   B = grad psi x grad phi = -grad chi,
 * psi = R A_phi the flux function (B_R = -(1/R) dpsi/dZ, B_Z = (1/R) dpsi/dR)
 * and chi the magnetic scalar potential (gcp_field_flux_potential).  The
 * coordinates (psi, chi, phi) are orthogonal (grad psi . grad chi =
 * -R (B x phihat) . B = 0), b = B/|B| has only a chi component,
 *   b . dX = -grad chi . dX / |B| = -dchi / |B|,
 * and A = A_phi phihat gives q A . dX = q A_phi R dphi = q psi dphi.  The
 * guiding-centre one-form (Littlejohn 1983; Cary & Brizard 2009)
 *   theta = (q A + p_par b) . dX = q psi dphi + (-p_par/|B|) dchi
 * is therefore canonical in z = (phi, chi, P_phi, P_chi):
 *   P_phi = q psi,   P_chi = -p_par / |B(psi, chi)|,
 * with the Hamiltonian (relativistic, mu constant)
 *   H(z) = gamma m c^2,  gamma = sqrt(1 + (p_par/mc)^2 + 2 mu |B| / (m c^2)),
 *   p_par = -P_chi |B(psi, chi)|,  psi = P_phi / q.
 *
 * Derivatives.  With v_par = p_par / (gamma m), dH/dp_par = v_par and
 * dH/d|B| (p_par fixed) = mu / gamma, and p_par = -P_chi |B|:
 *   dH/dP_chi = -|B| v_par,
 *   dH/dchi   = (p_par v_par / |B| + mu / gamma) d|B|/dchi,
 *   dH/dP_phi = (p_par v_par / |B| + mu / gamma) d|B|/dpsi / q,
 *   dH/dphi   = 0 (axisymmetry: P_phi is exactly conserved by any
 *               Runge-Kutta method, a discrete Noether invariant).
 * d|B|/d(psi, chi) from grad|B| (d|B|/dx_j = b_i dB_i/dx_j) by the chain rule
 * through the inverse of the Jacobian of (psi, chi) in (R, Z),
 *   d(psi, chi)/d(R, Z) = [[R B_Z, -R B_R], [-B_R, -B_Z]],  det = -R |B|^2,
 *   dR/dpsi = B_Z / (R B^2),  dZ/dpsi = -B_R / (R B^2),
 *   dR/dchi = -B_R / B^2,     dZ/dchi = -B_Z / B^2   (dX/dchi = -B / B^2).
 * Check: dchi/dt = dH/dP_chi = -|B| v_par = grad chi . v_par b.
 *
 * Inverse (psi, chi) -> (R, Z): Newton with that Jacobian from the last
 * point this chart mapped (aux = (R, Z), an in/out guess): quadratic, two or
 * three field evaluations per inversion at small steps, one when the guess
 * is already the solution (the later Newton iterations of a collocation
 * step).  Converged when an update falls below 1e-15 of the scale R + |Z|
 * (round-off: the point in hand is kept with its sample), or after an
 * update below 1e-9 of it (the next one is then at round-off, ~1e-18 by the
 * quadratic rate, and is not taken: the sample in hand is that of the
 * returned point).  30 iterations or a point off the
 * half plane R > 0: GCP_STEP_FAILED.
 *
 * Fields with an electric field are refused (the dipole's corotation field
 * would add q Omega psi = Omega P_phi to H, but the chart would then need
 * the model's Omega; not done, see the report of issue 11).
 */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/field.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "canon_priv.h"

#define CF_MAXIT 30
#define CF_DONE 1e-9
#define CF_ULP 1e-15

/* (R, Z) with psi(R, Z) = psi_t, chi(R, Z) = chi_t, from the guess aux;
 * s gets the field (B, and grad B when need asks) at the point found. */
static int cf_invert(const struct gcp_field *f, double psi_t, double chi_t, double aux[2],
                     unsigned need, struct gcp_field_sample *s, double *Bm)
{
    double R = aux[0], Z = aux[1];
    int small = 0;
    for (int it = 0; it < CF_MAXIT; it++) {
        if (!(R > 0.0) || !isfinite(Z)) return GCP_STEP_FAILED;
        const double x[3] = {R, 0.0, Z};
        double psi, chi;
        s->need = need | GCP_NEED_B;
        const int st = gcp_field_eval(f, 0.0, x, s);
        if (st) return st;
        gcp_field_flux_potential(f, x, &psi, &chi);
        if (small) {
            aux[0] = R, aux[1] = Z;
            if (Bm) *Bm = sqrt(s->B[0] * s->B[0] + s->B[1] * s->B[1] + s->B[2] * s->B[2]);
            return 0;
        }
        const double BR = s->B[0], BZ = s->B[2], B2 = BR * BR + BZ * BZ;
        const double F0 = psi - psi_t, F1 = chi - chi_t;
        /* d = -J^{-1} F, J^{-1} = [[-B_Z, R B_R], [B_R, R B_Z]] / (-R B^2) */
        const double dR = (-BZ * F0 + R * BR * F1) / (R * B2);
        const double dZ = (BR * F0 + R * BZ * F1) / (R * B2);
        if (!isfinite(dR + dZ)) return GCP_STEP_FAILED;
        const double dn = fabs(dR) + fabs(dZ), scale = R + fabs(Z);
        if (dn <= CF_ULP * scale) {
            /* the point in hand is the solution to a few ulp (an update this
             * small is round-off in psi and chi): keep it and its sample */
            aux[0] = R, aux[1] = Z;
            if (Bm) *Bm = sqrt(B2 + s->B[1] * s->B[1]);
            return 0;
        }
        if (Bm && dn <= CF_DONE * scale) {
            /* |B| alone is asked (from_canon): at the updated point by
             * |B| + grad|B| . d, whose error ~|d|^2 |B|'' ~ 1e-18 |B| is
             * round-off, instead of one more evaluation there */
            const double B = sqrt(B2 + s->B[1] * s->B[1]);
            double gB[3];
            for (int j = 0; j < 3; j += 2)
                gB[j] = (s->B[0] * s->gradB[0][j] + s->B[1] * s->gradB[1][j] +
                         s->B[2] * s->gradB[2][j]) / B;
            *Bm = B + gB[0] * dR + gB[2] * dZ;
            aux[0] = R + dR, aux[1] = Z + dZ;
            return 0;
        }
        R += dR, Z += dZ;
        small = dn <= CF_DONE * scale;
    }
    return GCP_STEP_FAILED;
}

static int cf_to_canon(const struct gcp_canon_chart *c, const struct gcp_gc_consts *k,
                       const double X[3], double ppar, double z[4], double aux[2])
{
    const double R = hypot(X[0], X[1]);
    const double x[3] = {R, 0.0, X[2]};
    struct gcp_field_sample s = {.need = GCP_NEED_B};
    const int st = gcp_field_eval(c->field, 0.0, x, &s);
    double psi, chi;
    gcp_field_flux_potential(c->field, x, &psi, &chi);
    const double Bm = sqrt(s.B[0] * s.B[0] + s.B[1] * s.B[1] + s.B[2] * s.B[2]);
    z[0] = atan2(X[1], X[0]);
    z[1] = chi;
    z[2] = k->q * psi;
    z[3] = -ppar / Bm;
    aux[0] = R, aux[1] = X[2];
    if (st) return st;
    return isfinite(z[1] + z[2] + z[3]) && R > 0.0 ? 0 : GCP_NONFINITE;
}

static int cf_from_canon(const struct gcp_canon_chart *c, const struct gcp_gc_consts *k,
                         const double z[4], double aux[2], double X[3], double *ppar)
{
    struct gcp_field_sample s;
    double Bm;
    const int st = cf_invert(c->field, z[2] / k->q, z[1], aux, GCP_NEED_GRADB, &s, &Bm);
    if (st) return st;
    X[0] = aux[0] * cos(z[0]);
    X[1] = aux[0] * sin(z[0]);
    X[2] = aux[1];
    *ppar = -z[3] * Bm;
    return 0;
}

/* |B| and its derivatives d|B|/d(psi, chi) (see the header) from the
 * sample s (B and grad B) at (R, 0, Z). */
static void cf_strength_at(const struct gcp_field_sample *s, double R, double *Bm,
                           double *dBdpsi, double *dBdchi)
{
    const double BR = s->B[0], BZ = s->B[2];
    const double B2 = BR * BR + s->B[1] * s->B[1] + BZ * BZ;
    *Bm = sqrt(B2);
    /* grad|B| in the phi = 0 half plane: (R, Z) components */
    double gB[3];
    for (int j = 0; j < 3; j += 2)
        gB[j] = (s->B[0] * s->gradB[0][j] + s->B[1] * s->gradB[1][j] + s->B[2] * s->gradB[2][j]) /
                *Bm;
    *dBdpsi = (gB[0] * BZ - gB[2] * BR) / (R * B2);
    *dBdchi = -(gB[0] * BR + gB[2] * BZ) / B2;
}

/* |B| at z and its derivatives d|B|/d(psi, chi). */
static int cf_strength(const struct gcp_canon_chart *c, const struct gcp_gc_consts *k,
                       const double z[4], double aux[2], double *Bm, double *dBdpsi,
                       double *dBdchi)
{
    struct gcp_field_sample s;
    const int st = cf_invert(c->field, z[2] / k->q, z[1], aux, GCP_NEED_GRADB, &s, NULL);
    if (st) return st;
    cf_strength_at(&s, aux[0], Bm, dBdpsi, dBdchi);
    return 0;
}

/* H and dH/dz (see the header) from |B| and d|B|/d(psi, chi) at P_chi. */
static int cf_ham_at(const struct gcp_gc_consts *k, double Pchi, double Bm, double dBdpsi,
                     double dBdchi, double *H, double dH[4])
{
    const double ppar = -Pchi * Bm;
    const double gamma = gcp_gc_gamma(ppar, k->mu, Bm, k->m);
    const double vpar = ppar / (gamma * k->m);
    const double w = ppar * vpar / Bm + k->mu / gamma;
    *H = gamma * k->m * GCP_C_LIGHT * GCP_C_LIGHT;
    dH[0] = 0.0;
    dH[1] = w * dBdchi;
    dH[2] = w * dBdpsi / k->q;
    dH[3] = -Bm * vpar;
    return isfinite(*H + dH[1] + dH[2] + dH[3]) ? 0 : GCP_NONFINITE;
}

static int cf_hamiltonian(const struct gcp_canon_chart *c, const struct gcp_gc_consts *k,
                          const double z[4], double aux[2], double *H, double dH[4])
{
    double Bm, dBdpsi, dBdchi;
    const int st = cf_strength(c, k, z, aux, &Bm, &dBdpsi, &dBdchi);
    if (st) return st;
    return cf_ham_at(k, z[3], Bm, dBdpsi, dBdchi, H, dH);
}

static int cf_field_strength(const struct gcp_canon_chart *c, const struct gcp_gc_consts *k,
                             const double z[4], double aux[2], double *Bm, double dBm[4])
{
    double dBdpsi, dBdchi;
    const int st = cf_strength(c, k, z, aux, Bm, &dBdpsi, &dBdchi);
    if (st) return st;
    dBm[0] = 0.0;
    dBm[1] = dBdchi;
    dBm[2] = dBdpsi / k->q;
    dBm[3] = 0.0;
    return 0;
}

/* Everything at the point p = (R, Z) from one field evaluation with grad B
 * (canon_priv.h lift_eval): (psi, chi) there, H, |B| and their derivatives
 * as above, and the inverse chart Jacobian of the header,
 *   d(R, Z)/dpsi = (B_Z, -B_R) / (R B^2),  d(R, Z)/dchi = -(B_R, B_Z) / B^2,
 * d/dP_phi = (1/q) d/dpsi. */
/* H and dH/dz at P_chi from o's |B| and d|B|/dz (cf_ham_at's formulas,
 * with 1/(gamma m) taken once); iBm = 1/|B|. */
static int cf_lift_h(const struct gcp_gc_consts *k, double Peta, double iBm,
                     struct gcp_canon_lift *o)
{
    const double Bm = o->Bm, ppar = -Peta * Bm;
    const double gamma = gcp_gc_gamma(ppar, k->mu, Bm, k->m);
    const double igm = 1.0 / (gamma * k->m);
    const double vpar = ppar * igm;
    const double w = ppar * vpar * iBm + k->mu * (igm * k->m);
    o->H = gamma * k->m * GCP_C_LIGHT * GCP_C_LIGHT;
    o->dH[0] = 0.0;
    o->dH[1] = w * o->dBm[1];
    o->dH[2] = w * o->dBm[2];
    o->dH[3] = -Bm * vpar;
    return isfinite(o->H + o->dH[1] + o->dH[2] + o->dH[3]) ? 0 : GCP_NONFINITE;
}

static int cf_lift_eval(const struct gcp_canon_chart *c, const struct gcp_gc_consts *k,
                        const double p[2], double Peta, struct gcp_canon_lift *o)
{
    const double R = p[0], Z = p[1];
    if (!(R > 0.0) || !isfinite(Z)) return GCP_STEP_FAILED;
    const double x[3] = {R, 0.0, Z};
    struct gcp_field_sample s = {.need = GCP_NEED_B | GCP_NEED_GRADB};
    const int st = gcp_field_eval(c->field, 0.0, x, &s);
    if (st) return st;
    double psi, chi;
    gcp_field_flux_potential(c->field, x, &psi, &chi);
    /* cf_strength_at and cf_ham_at written out with the reciprocals 1/|B|^2,
     * 1/|B|, 1/R, 1/q, 1/(gamma m) taken once (this is the solver's inner
     * evaluation: the chain of divisions and square roots is its cost) */
    const double BR = s.B[0], BZ = s.B[2];
    const double B2 = BR * BR + s.B[1] * s.B[1] + BZ * BZ;
    const double Bm = sqrt(B2), iB2 = 1.0 / B2, iBm = Bm * iB2, iR = 1.0 / R, iq = 1.0 / k->q;
    double gB[3];
    for (int j = 0; j < 3; j += 2)
        gB[j] = (s.B[0] * s.gradB[0][j] + s.B[1] * s.gradB[1][j] + s.B[2] * s.gradB[2][j]) * iBm;
    const double dBdpsi = (gB[0] * BZ - gB[2] * BR) * iR * iB2;
    const double dBdchi = -(gB[0] * BR + gB[2] * BZ) * iB2;
    o->Bm = Bm;
    o->Pphi = k->q * psi;
    o->eta = chi;
    o->dBm[0] = 0.0;
    o->dBm[1] = dBdchi;
    o->dBm[2] = dBdpsi * iq;
    o->dBm[3] = 0.0;
    o->dp[0][0] = BZ * iR * iB2 * iq;
    o->dp[1][0] = -BR * iR * iB2 * iq;
    o->dp[0][1] = -BR * iB2;
    o->dp[1][1] = -BZ * iB2;
    return cf_lift_h(k, Peta, iBm, o);
}

/* H at another P_chi from the |B| and d|B|/dz that cf_lift_eval stored. */
static int cf_lift_ham(const struct gcp_canon_chart *c, const struct gcp_gc_consts *k,
                       const struct gcp_canon_lift *o, double Peta, double *H, double dH[4])
{
    (void)c;
    struct gcp_canon_lift o2 = *o;
    const int st = cf_lift_h(k, Peta, 1.0 / o->Bm, &o2);
    *H = o2.H;
    memcpy(dH, o2.dH, sizeof o2.dH);
    return st;
}

/* cf_lift_ham at n samples (canon_priv.h lift_ham_block): cf_lift_h's
 * operations in one branch-free loop (restrict: it vectorises). */
static void cf_lift_ham_block(const struct gcp_canon_chart *c, const struct gcp_gc_consts *k,
                              size_t n, const double *restrict mu, const double *restrict Bm,
                              const double *restrict dBm1, const double *restrict dBm2,
                              const double *restrict Peta, double *restrict dH1,
                              double *restrict dH2, double *restrict dH3,
                              int32_t *restrict status)
{
    (void)c;
    const double m = k->m;
    for (size_t j = 0; j < n; j++) {
        const double B = Bm[j], iBm = 1.0 / B, ppar = -Peta[j] * B;
        const double gamma = gcp_gc_gamma(ppar, mu[j], B, m);
        const double igm = 1.0 / (gamma * m);
        const double vpar = ppar * igm;
        const double w = ppar * vpar * iBm + mu[j] * (igm * m);
        const double H = gamma * m * GCP_C_LIGHT * GCP_C_LIGHT;
        const double d1 = w * dBm1[j], d2 = w * dBm2[j], d3 = -B * vpar;
        dH1[j] = d1, dH2[j] = d2, dH3[j] = d3;
        status[j] = fabs(H + d1 + d2 + d3) <= DBL_MAX ? 0 : GCP_NONFINITE;
    }
}

#define CF_BLK 64

/* cf_lift_eval's and cf_lift_h's arithmetic at nb points from the field
 * values B, G and psi, chi (cf_lift_eval_block), into out[CF_*] (local
 * arrays and restrict parameters: the compiler can prove that nothing
 * aliases, and vectorises the loop). */
enum { CF_PPHI, CF_ETA, CF_H, CF_DH1, CF_DH2, CF_DH3, CF_BM, CF_DBM1, CF_DBM2, CF_DP00, CF_DP01,
       CF_DP10, CF_DP11, CF_NOUT };
static void cf_lift_math(const struct gcp_gc_consts *k, size_t nb, const double *restrict r,
                         const double *restrict zz, const double *restrict pe,
                         const double *restrict mu_, const double *restrict Bv,
                         const double *restrict Gv, const double *restrict psi,
                         const double *restrict chi, double *restrict out, int32_t *restrict st)
{
    const double q = k->q, m = k->m, iq = 1.0 / q, mc = m * GCP_C_LIGHT;
#define B_(c) Bv[(c) * CF_BLK + j]
#define G_(a, b) Gv[((a) * 3 + (b)) * CF_BLK + j]
#define O_(w) out[(w) * CF_BLK + j]
    for (size_t j = 0; j < nb; j++) {
        const double BR = B_(0), BZ = B_(2), Bp = B_(1);
        const double B2 = BR * BR + Bp * Bp + BZ * BZ;
        const double Bm = sqrt(B2), iB2 = 1.0 / B2, iBm = Bm * iB2, iR = 1.0 / r[j];
        const double gB0 = (BR * G_(0, 0) + Bp * G_(1, 0) + BZ * G_(2, 0)) * iBm;
        const double gB2 = (BR * G_(0, 2) + Bp * G_(1, 2) + BZ * G_(2, 2)) * iBm;
        const double dBdpsi = (gB0 * BZ - gB2 * BR) * iR * iB2;
        const double dBdchi = -(gB0 * BR + gB2 * BZ) * iB2;
        const double dBm2 = dBdpsi * iq;
        O_(CF_BM) = Bm;
        O_(CF_PPHI) = q * psi[j];
        O_(CF_ETA) = chi[j];
        O_(CF_DBM1) = dBdchi;
        O_(CF_DBM2) = dBm2;
        O_(CF_DP00) = BZ * iR * iB2 * iq;
        O_(CF_DP10) = -BR * iR * iB2 * iq;
        O_(CF_DP01) = -BR * iB2;
        O_(CF_DP11) = -BZ * iB2;
        /* cf_lift_h */
        const double ppar = -pe[j] * Bm, a = ppar / mc;
        const double gamma = sqrt(1.0 + a * a + 2.0 * mu_[j] * Bm / (mc * GCP_C_LIGHT));
        const double igm = 1.0 / (gamma * m);
        const double vpar = ppar * igm;
        const double w = ppar * vpar * iBm + mu_[j] * (igm * m);
        const double H = gamma * m * GCP_C_LIGHT * GCP_C_LIGHT;
        const double dH1 = w * dBdchi, dH2 = w * dBm2, dH3 = -Bm * vpar;
        O_(CF_H) = H;
        O_(CF_DH1) = dH1;
        O_(CF_DH2) = dH2;
        O_(CF_DH3) = dH3;
        /* the statuses by selects (no branch: the loop vectorises) */
        const int okp = (r[j] > 0.0) & (fabs(zz[j]) <= DBL_MAX);
        const int okv = fabs(H + dH1 + dH2 + dH3) <= DBL_MAX;
        const int32_t code = okp ? (okv ? 0 : GCP_NONFINITE) : GCP_STEP_FAILED;
        st[j] = st[j] != 0 ? st[j] : code;
    }
#undef B_
#undef G_
#undef O_
}

/* The block evaluation's outputs: B and grad B into a chunk's arrays, no E. */
static struct gcp_field_soa cf_soa_BG(double B[3][CF_BLK], double G[3][3][CF_BLK])
{
    const struct gcp_field_soa fo = {{B[0], B[1], B[2]},
                                     {{G[0][0], G[0][1], G[0][2]},
                                      {G[1][0], G[1][1], G[1][2]},
                                      {G[2][0], G[2][1], G[2][2]}},
                                     {NULL, NULL, NULL}};
    return fo;
}

/* cf_lift_eval at n points (canon_priv.h lift_eval_block): the field's
 * block evaluation (gcp_field_eval_soa), then cf_lift_eval's and
 * cf_lift_h's arithmetic, in the same order, in one branch-free loop that
 * the compiler vectorises (the divisions and square roots of the scalar
 * form were the solver's cost). */
static void cf_lift_eval_block(const struct gcp_canon_chart *c, const struct gcp_gc_consts *k,
                               size_t n, const double *mu, const double *R, const double *Z,
                               const double *Peta, const struct gcp_canon_lift_soa *o,
                               int32_t *status)
{
    double Y[CF_BLK], B[3][CF_BLK], G[3][3][CF_BLK], psi[CF_BLK], chi[CF_BLK];
    double out[CF_NOUT][CF_BLK];
    const struct gcp_field_soa fo = cf_soa_BG(B, G);
    for (size_t j0 = 0; j0 < n; j0 += CF_BLK) {
        const size_t nb = n - j0 < CF_BLK ? n - j0 : CF_BLK;
        const double *r = R + j0, *zz = Z + j0, *pe = Peta + j0, *mu_ = mu + j0;
        int32_t *st = status + j0;
        for (size_t j = 0; j < nb; j++) Y[j] = 0.0, st[j] = 0;
        gcp_field_eval_soa(c->field, 0.0, GCP_NEED_B | GCP_NEED_GRADB, nb, r, Y, zz, &fo, st);
        gcp_field_flux_potential_rz(c->field, nb, r, zz, psi, chi);
        cf_lift_math(k, nb, r, zz, pe, mu_, &B[0][0], &G[0][0][0], psi, chi, &out[0][0], st);
        double *const dst[CF_NOUT] = {o->Pphi, o->eta,  o->H,    o->dH1,  o->dH2,  o->dH3, o->Bm,
                                      o->dBm1, o->dBm2, o->dp00, o->dp01, o->dp10, o->dp11};
        for (int w = 0; w < CF_NOUT; w++) memcpy(dst[w] + j0, out[w], nb * sizeof(double));
    }
}

/* One of cf_invert's Newton iterates (its operations and tests; from_canon
 * asks for |B|) at the nb points (Rw, Zw) of cf_from_canon_block from the
 * field there (Bv, Gv, psi, chi), for the lanes still active: a lane done
 * gets |B| (Bm) and its point, the others move by the update.  Returns the
 * count still active.  Restrict parameters: the loop vectorises. */
static size_t cf_invert_iterate(size_t nb, const double *restrict Bv, const double *restrict Gv,
                                const double *restrict psi, const double *restrict chi,
                                const double *restrict psit, const double *restrict chit,
                                const int32_t *restrict st, double *restrict Rw,
                                double *restrict Zw, double *restrict Bm, int32_t *restrict act,
                                int32_t *restrict done)
{
    size_t left = 0;
#define B_(c) Bv[(c) * CF_BLK + j]
#define G_(a, b) Gv[((a) * 3 + (b)) * CF_BLK + j]
    for (size_t j = 0; j < nb; j++) {
        const double R = Rw[j], Z = Zw[j];
        const double BR = B_(0), BZ = B_(2), B2 = BR * BR + BZ * BZ;
        const double F0 = psi[j] - psit[j], F1 = chi[j] - chit[j];
        const double dR = (-BZ * F0 + R * BR * F1) / (R * B2);
        const double dZ = (BR * F0 + R * BZ * F1) / (R * B2);
        const double dn = fabs(dR) + fabs(dZ), scale = R + fabs(Z);
        const double Bt = sqrt(B2 + B_(1) * B_(1));
        const double gB0 = (B_(0) * G_(0, 0) + B_(1) * G_(1, 0) + B_(2) * G_(2, 0)) / Bt;
        const double gB2 = (B_(0) * G_(0, 2) + B_(1) * G_(1, 2) + B_(2) * G_(2, 2)) / Bt;
        const int ok = (R > 0.0) & (fabs(Z) <= DBL_MAX) & (st[j] == 0) &
                       (fabs(dR + dZ) <= DBL_MAX);
        const int ulp = dn <= CF_ULP * scale, fin = ok & (dn <= CF_DONE * scale);
        const int a = act[j];
        /* finished here: the point in hand (ulp) or the updated one */
        const double Bfin = ulp ? Bt : Bt + gB0 * dR + gB2 * dZ;
        const int take = a & fin, move = a & ok & !(fin & ulp);
        Bm[j] = take ? Bfin : Bm[j];
        done[j] = take ? 1 : done[j];
        Rw[j] = move ? R + dR : R;
        Zw[j] = move ? Z + dZ : Z;
        act[j] = a & ok & !fin;
        left += (size_t)act[j];
    }
#undef B_
#undef G_
    return left;
}

/* cf_from_canon at n states (canon_priv.h from_canon_block): cf_invert's
 * Newton iterates for all of them at once (one block field evaluation per
 * iterate, the converged lanes masked), with its operations and tests, so
 * the same numbers (from_canon asks for |B|: an update below CF_DONE ends
 * it, with |B| linearised unless below CF_ULP).  A lane that cannot be
 * mapped (off the half plane, a field status, a non-finite update,
 * CF_MAXIT iterates) is left to cf_from_canon, which fails it the same way. */
static void cf_from_canon_block(const struct gcp_canon_chart *c, const struct gcp_gc_consts *k,
                                size_t n, const double *const z[4], double *aux0, double *aux1,
                                double *const X[3], double *ppar, int32_t *done)
{
    double Y[CF_BLK], B[3][CF_BLK], G[3][3][CF_BLK], psi[CF_BLK], chi[CF_BLK], Bm[CF_BLK];
    double Rw[CF_BLK], Zw[CF_BLK], psit[CF_BLK], chit[CF_BLK];
    int32_t st[CF_BLK], act[CF_BLK];
    const struct gcp_field_soa fo = cf_soa_BG(B, G);
    for (size_t j0 = 0; j0 < n; j0 += CF_BLK) {
        const size_t nb = n - j0 < CF_BLK ? n - j0 : CF_BLK;
        int32_t *dn_ = done + j0;
        for (size_t j = 0; j < nb; j++) {
            Rw[j] = aux0[j0 + j], Zw[j] = aux1[j0 + j], Y[j] = 0.0;
            dn_[j] = 0, act[j] = 1, Bm[j] = 0.0;
            psit[j] = z[2][j0 + j] / k->q, chit[j] = z[1][j0 + j];
        }
        size_t left = nb;
        for (int it = 0; it < CF_MAXIT && left > 0; it++) {
            for (size_t j = 0; j < nb; j++) st[j] = 0;
            gcp_field_eval_soa(c->field, 0.0, GCP_NEED_B | GCP_NEED_GRADB, nb, Rw, Y, Zw, &fo, st);
            gcp_field_flux_potential_rz(c->field, nb, Rw, Zw, psi, chi);
            left = cf_invert_iterate(nb, &B[0][0], &G[0][0][0], psi, chi, psit, chit, st, Rw, Zw,
                                     Bm, act, dn_);
        }
        for (size_t j = 0; j < nb; j++) {
            if (!dn_[j]) continue;
            const double phi = z[0][j0 + j];
            aux0[j0 + j] = Rw[j], aux1[j0 + j] = Zw[j];
            X[0][j0 + j] = Rw[j] * cos(phi);
            X[1][j0 + j] = Rw[j] * sin(phi);
            X[2][j0 + j] = Zw[j];
            ppar[j0 + j] = -z[3][j0 + j] * Bm[j];
        }
    }
}

int gcp_canon_chart_curlfree_create(const struct gcp_field *f, struct gcp_canon_chart *out,
                                    char *why, size_t whylen)
{
    const double probe[3] = {1.0, 0.0, 1.0};
    double psi, chi;
    const char *no = NULL;
    if (!f->axisymmetric)
        no = "the field is not axisymmetric (no ignorable angle to make canonical)";
    else if (gcp_field_flux_potential(f, probe, &psi, &chi) != 0)
        no = "the field has no flux function and magnetic scalar potential pair "
             "(not a curl-free axisymmetric model)";
    else if (f->has_E)
        no = "the curl-free chart has no electric potential (switch corotation off)";
    else if (f->time_dependent)
        no = "the field is time dependent";
    if (no) {
        if (why && whylen) snprintf(why, whylen, "%s", no);
        return GCP_ERR_STATE;
    }
    memset(out, 0, sizeof *out);
    out->name = "curl-free";
    out->field = f;
    out->to_canon = cf_to_canon;
    out->from_canon = cf_from_canon;
    out->hamiltonian = cf_hamiltonian;
    out->field_strength = cf_field_strength;
    out->lift_eval = cf_lift_eval;
    out->lift_ham = cf_lift_ham;
    out->lift_eval_block = cf_lift_eval_block;
    out->lift_ham_block = cf_lift_ham_block;
    out->from_canon_block = cf_from_canon_block;
    return 0;
}
