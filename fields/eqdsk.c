/* The `eqdsk` field model: a tokamak equilibrium from a G-EQDSK file.
 *
 * The file is read by eqdsk_read.c (its format and the COCOS signs are
 * described there).
 *
 * Field.  psi(R, Z) is the interpolating biseptic B-spline of psirz (C6,
 * grid_priv.h, spline.c); F = R B_phi is the septic spline of fpol on the
 * uniform psi grid simag .. sibry (q and pres likewise), evaluated at
 * psi_N = (psi - simag)/(sibry - simag); outside the plasma (psi_N > 1, or Z
 * outside the Z range of the boundary polygon: the private-flux region below
 * an X-point also has psi_N < 1) F is the boundary value fpol(nw), the
 * vacuum R B_phi.  B is continuous there; grad B jumps with F' (the edge
 * current), as it physically does.
 * Why C6.  grad B is psi's second derivatives (and F' grad psi), and the
 * guiding-centre flow holds grad B, so the flow is two orders less smooth
 * than psi: C0 from a bicubic psi, C2 from a quintic, C4 from a septic
 * psi and F.  A step of a method of order p across a cell boundary where the
 * flow's k-th derivative jumps errs by O(h^(k+1)) with a coefficient set by
 * where the boundary falls in the step; summed over the ~1e2 cells an orbit
 * crosses in a bounce, an irregular O(h^k) term.  gc-gl4 (p = 4) needs
 * k >= 5 for clean fourth order, i.e. the flow C4, psi and F(psi) C6 (the
 * lowest odd degree that gives it is 7; with quintic psi, k = 3, the
 * irregular h^4 term was as large as the method's own and the error ratios
 * at halved h scattered from 6.7 to 51: tests/unit/test_gc_symplectic_flux.c,
 * eqdsk_order and eqdsk_order_legacy_quintic_fails).  psi's interpolation
 * error is O(h^8) (O(h^6) quintic).  The quintic kind stays loadable
 * (gcp_eqdsk_load_kind, grid_priv.h) for that test.  Cost: 8 x 8
 * coefficients per evaluation against 6 x 6 (tests/bench/bench_eqdsk_eval.c).
 */
#include <math.h>
#include <stdlib.h>

#include "eqdsk_priv.h"
#include "field_priv.h"
#include "gcpush/particles.h"
#include "grid_priv.h"
#include "spl_inline.h"

/* ---- evaluation ----------------------------------------------------------- */

/* gcp_spl1_eval of the septic profile's component 0 (fpol) with its first
 * derivative only, inline: the same cell, weights and sums (the same
 * numbers), without the call, the kind dispatch and the second-derivative
 * weights the generic path forms (F(psi) was ~10% of a gc-gl2 step in
 * DIII-D: every field evaluation takes it). */
static inline double eqdsk_prof7(const struct gcp_spl *s, double u, double *du)
{
    const double x = s->x0[0] + u * s->h[0];
    size_t off;
    double t, w[8], dw[8];
    gcp_spl_cell(s, 0, x, &off, &t);
    gcp_spl_w7(t, s->inv_h[0], 1, w, dw, NULL);
    const double *co = s->coef[0] + off;
    const double c0 = co[0];
    double f = 0, d = 0;
    for (int a = 0; a < 8; a++) {
        const double ca = co[a] - c0;
        f += w[a] * ca;
        d += dw[a] * ca;
    }
    *du = d * s->h[0];
    return c0 + f;
}

/* F and dF/dpsi at psi (file's psi), Z: the profile inside the plasma,
 * the edge value outside. */
static inline void eqdsk_F(const struct eqdsk_params *e, double psi, double Z, double *F,
                           double *dF)
{
    const double psiN = (psi - e->info.simag) / e->dpsi;
    if (psiN > 1.0 || Z < e->info.zbmin || Z > e->info.zbmax) {
        *F = e->F_edge;
        *dF = 0.0;
        return;
    }
    const double scale = (double)(e->info.nw - 1);
    double du;
    *F = e->prof.kind == GCP_SPL_SEPTIC ? eqdsk_prof7(&e->prof, psiN * scale, &du)
                                        : gcp_spl1_eval(&e->prof, 0, psiN * scale, &du, NULL);
    *dF = du * scale / e->dpsi;
}

/* B (and grad B with grad) at R, Z from psi's spline output o there (order
 * 2 with grad, else 1), with the cylindrical frame (c, sn) of the point. */
/* always_inline: compiled as a function of its own (as GCC 12 did once
 * eqdsk_prof7 was inlined into it) the rotation gcp_axi_to_cart became an
 * SLP complex multiply with vfmaddsub, a contraction despite
 * -ffp-contract=off, and changed B's last bits. */
static inline __attribute__((always_inline)) void
eqdsk_B_ofF(const struct eqdsk_params *e, const struct gcp_spl_out *o, double R, double F,
            double dF, double c, double sn, int grad, struct gcp_field_sample *s)
{
    const double iR = 1.0 / R, sp = e->s_pol, st = e->s_tor;
    double b[3], dR[3] = {0}, dZ[3] = {0};
    b[0] = -sp * o->d[1] * iR;
    b[1] = st * F * iR;
    b[2] = sp * o->d[0] * iR;
    if (grad) {
        dR[0] = -sp * (o->dd[0][1] - o->d[1] * iR) * iR;
        dZ[0] = -sp * o->dd[1][1] * iR;
        dR[1] = st * (dF * o->d[0] - F * iR) * iR;
        dZ[1] = st * dF * o->d[1] * iR;
        dR[2] = sp * (o->dd[0][0] - o->d[0] * iR) * iR;
        dZ[2] = sp * o->dd[0][1] * iR;
    }
    gcp_axi_to_cart(c, sn, R, b, dR, dZ, s->B, s->gradB, grad);
    if (s->need & GCP_NEED_E) s->E[0] = s->E[1] = s->E[2] = 0.0;
}

/* eqdsk_B_ofF with F, dF/dpsi from the profile at psi = o->f. */
static inline __attribute__((always_inline)) void
eqdsk_B_of(const struct eqdsk_params *e, const struct gcp_spl_out *o, double R, double Z, double c,
           double sn, int grad, struct gcp_field_sample *s)
{
    double F, dF;
    eqdsk_F(e, o->f, Z, &F, &dF);
    eqdsk_B_ofF(e, o, R, F, dF, c, sn, grad, s);
}

static int eqdsk_eval(const struct gcp_field *f, double t, const double x[3],
                      struct gcp_field_sample *s)
{
    (void)t;
    const struct eqdsk_params *e = f->params;
    const int grad = (s->need & GCP_NEED_GRADB) != 0;
    double c, sn;
    const double R = gcp_axi_R(x[0], x[1], e->Rmin, &c, &sn);
    const double p[2] = {R, x[2]};
    struct gcp_spl_loc loc;
    struct gcp_spl_out o;
    const int out = gcp_spl_locate(&e->psi, p, grad ? 2 : 1, &loc);
    gcp_spl_eval(&e->psi, &loc, 0, grad ? 2 : 1, &o);
    eqdsk_B_of(e, &o, R, x[2], c, sn, grad, s);
    return out ? GCP_LEFT_GRID : 0;
}

static void eqdsk_eval_block(const struct gcp_field *f, double t, size_t n, const double *x,
                             const double *y, const double *z, double *Bx, double *By,
                             double *Bz, double *Ex, double *Ey, double *Ez, int32_t *status)
{
    struct gcp_field_sample s;
    s.need = GCP_NEED_B;
    for (size_t i = 0; i < n; i++) {
        const double p[3] = {x[i], y[i], z[i]};
        const int rc = eqdsk_eval(f, t, p, &s);
        Bx[i] = s.B[0];
        By[i] = s.B[1];
        Bz[i] = s.B[2];
        if (Ex) Ex[i] = Ey[i] = Ez[i] = 0.0;
        if (status && rc && status[i] == 0) status[i] = rc;
    }
}

/* Keys: file (required), cocos = 1..8 (optional; default: identified from
 * the signs, see the top of this file). */
enum { EK_FILE, EK_COCOS };
static const struct gcp_field_key eqdsk_keys[] = {
    {"file", GCP_KEY_STRING, 0, 1, {0, 0, 0}, NULL, "G-EQDSK file"},
    {"cocos", GCP_KEY_QUANTITY, GCP_Q_NUMBER, 0, {0, 0, 0}, NULL,
     "COCOS of the file, 1..8 (default: from the signs)"},
    {NULL, 0, 0, 0, {0, 0, 0}, NULL, NULL}};

static int eqdsk_build(struct gcp_field_args *a, struct gcp_field **out, struct gcp_error *err)
{
    const double cocos = a->v[EK_COCOS][0];
    if (!(cocos == floor(cocos) && cocos >= 0 && cocos <= 8))
        return gcp_field_key_error(a, EK_COCOS, err, GCP_ERR_VALUE,
                                   "expected an integer 1..8 (COCOS of psi in Wb/rad), got %g",
                                   cocos);
    struct gcp_error e2 = {0, ""};
    const int rc = gcp_field_eqdsk_load(a->text[EK_FILE], (int)cocos, out, &e2);
    if (rc) return gcp_field_key_error(a, EK_FILE, err, rc, "%s", e2.msg);
    return 0;
}

static int eqdsk_psi(const struct gcp_field *f, const double x[3], double *psi)
{
    return gcp_eqdsk_psi_RZ(f, hypot(x[0], x[1]), x[2], psi);
}

const struct gcp_field_type gcp_field_eqdsk = {
    .name = "eqdsk",
    .doc = "tokamak equilibrium from a G-EQDSK file (psi biseptic, F(psi) spline): file, [cocos]",
    .eval = eqdsk_eval,
    .eval_block = eqdsk_eval_block,
    .destroy = gcp_eqdsk_destroy,
    .caps = GCP_CAP_B | GCP_CAP_GRADB | GCP_CAP_PSI | GCP_CAP_AXISYM,
    .psi = eqdsk_psi,
    .keys = eqdsk_keys,
    .build = eqdsk_build,
};

int gcp_eqdsk_psi_RZ(const struct gcp_field *f, double R, double Z, double *psi)
{
    const struct eqdsk_params *e = f->params;
    const double p[2] = {R, Z};
    struct gcp_spl_loc loc;
    struct gcp_spl_out o;
    const int out = gcp_spl_locate(&e->psi, p, 0, &loc);
    gcp_spl_eval(&e->psi, &loc, 0, 0, &o);
    *psi = e->s_pol * o.f;
    return out ? GCP_LEFT_GRID : 0;
}

int gcp_field_eqdsk_info(const struct gcp_field *f, struct gcp_eqdsk_info *info)
{
    if (!f || f->type != &gcp_field_eqdsk) return GCP_ERR_STATE;
    *info = ((const struct eqdsk_params *)f->params)->info;
    return 0;
}

static double eqdsk_profile(const struct gcp_field *f, int c, double psiN)
{
    if (!f || f->type != &gcp_field_eqdsk) return NAN;
    const struct eqdsk_params *e = f->params;
    return gcp_spl1_eval(&e->prof, c, psiN * (double)(e->info.nw - 1), NULL, NULL);
}

double gcp_field_eqdsk_q(const struct gcp_field *f, double psiN) { return eqdsk_profile(f, 1, psiN); }
double gcp_field_eqdsk_F(const struct gcp_field *f, double psiN) { return eqdsk_profile(f, 0, psiN); }

/* psi and its first and second derivatives in (R, Z) [Wb/rad, /m, /m^2]
 * from the spline's output of the file's psi, times sp = s_pol (gcpush's sign). */
static void psi_out(double sp, const struct gcp_spl_out *o, double out[6])
{
    out[0] = sp * o->f;
    out[1] = sp * o->d[0];
    out[2] = sp * o->d[1];
    out[3] = sp * o->dd[0][0];
    out[4] = sp * o->dd[0][1];
    out[5] = sp * o->dd[1][1];
}

/* psi (gcpush's sign: s_pol psi_file) with its R, Z derivatives
 * (fields/flux_priv.h), from the same spline as eval. */
#include "flux_priv.h"

int gcp_eqdsk_psi_RZ2(const struct gcp_field *f, double R, double Z, double out[6])
{
    const struct eqdsk_params *e = f->params;
    const double p[2] = {R, Z};
    struct gcp_spl_loc loc;
    struct gcp_spl_out o;
    const int outside = gcp_spl_locate(&e->psi, p, 2, &loc);
    gcp_spl_eval(&e->psi, &loc, 0, 2, &o);
    psi_out(e->s_pol, &o, out);
    return outside ? GCP_LEFT_GRID : 0;
}

/* gcp_eqdsk_psi_RZ2 and eqdsk_eval at (R, 0, Z) with B and grad B from one
 * locate and evaluation of psi (the flux chart's, fields/flux_priv.h): the
 * same spline output feeds both, so the same numbers as the two calls.
 * Below Rmin eqdsk_eval floors R and psi_RZ2 does not: the two calls. */
int gcp_eqdsk_psi_B_RZ(const struct gcp_field *f, double R, double Z, double out[6],
                       struct gcp_field_sample *s, int *fst)
{
    const struct eqdsk_params *e = f->params;
    double c, sn;
    const double Rf = gcp_axi_R(R, 0.0, e->Rmin, &c, &sn);
    if (Rf != R) {
        const double X[3] = {R, 0.0, Z};
        s->need = GCP_NEED_B | GCP_NEED_GRADB;
        *fst = eqdsk_eval(f, 0.0, X, s);
        return gcp_eqdsk_psi_RZ2(f, R, Z, out);
    }
    const double p[2] = {R, Z};
    struct gcp_spl_out o;
    int outside;
    if (e->psi.kind == GCP_SPL_SEPTIC) {
        /* gcp_spl_locate and gcp_spl_eval's septic path inline (the same numbers) */
        double w[2][8], dw[2][8], ddw[2][8];
        size_t base = 0, off;
        double t;
        outside = 0;
        for (int a = 0; a < 2; a++) {
            outside |= gcp_spl_cell(&e->psi, a, p[a], &off, &t);
            base += off;
            gcp_spl_w7(t, e->psi.inv_h[a], 2, w[a], dw[a], ddw[a]);
        }
        gcp_spl2_eval8(e->psi.coef[0] + base, e->psi.stride[1], w[0], dw[0], ddw[0], w[1], dw[1],
                       ddw[1], 2, &o);
    } else {
        struct gcp_spl_loc loc;
        outside = gcp_spl_locate(&e->psi, p, 2, &loc);
        gcp_spl_eval(&e->psi, &loc, 0, 2, &o);
    }
    psi_out(e->s_pol, &o, out);
    s->need = GCP_NEED_B | GCP_NEED_GRADB;
    eqdsk_B_of(e, &o, R, Z, c, sn, 1, s);
    *fst = outside ? GCP_LEFT_GRID : 0;
    return *fst;
}

/* c w / R with w = (w, w_R, w_Z, w_RR, w_RZ, w_ZZ) and its R, Z derivatives
 * to second order (iR = 1/R), in the same layout. */
static void axi_over_R(double c, const double w[6], double iR, double o[6])
{
    o[0] = c * w[0] * iR;
    o[1] = c * (w[1] - w[0] * iR) * iR;
    o[2] = c * w[2] * iR;
    o[3] = c * (w[3] - 2.0 * (w[1] - w[0] * iR) * iR) * iR;
    o[4] = c * (w[4] - w[2] * iR) * iR;
    o[5] = c * w[5] * iR;
}

/* gcp_eqdsk_psi_B_RZ (the same numbers in out and *s) and the second-order
 * Taylor data of B in the R-Z plane at phi = 0: Bd[i] = (B_i, dB_i/dR,
 * dB_i/dZ, d2B_i/dR2, d2B_i/dRdZ, d2B_i/dZ2) for (B_R, B_phi, B_Z), from
 * psi's third derivatives and F''(psi): B_R = -s_pol psi_Z / R, B_phi =
 * s_tor F(psi) / R, B_Z = s_pol psi_R / R (file's psi).  For the analytic
 * Jacobian of the flux chart's collocation solve (src/pushers/canon_flux.c);
 * fields/flux_priv.h's dispatch, here as only this model has it.  Returns
 * -1 without evaluating where it does not apply (another model, a quintic
 * psi, R below Rmin): the caller takes gcp_field_psi_B_RZ. */
int gcp_field_psi_B_RZ3(const struct gcp_field *f, double R, double Z, double out[6],
                        struct gcp_field_sample *s, int *fst, double Bd[3][6])
{
    if (f->type != &gcp_field_eqdsk) return -1;
    const struct eqdsk_params *e = f->params;
    double c, sn;
    const double Rf = gcp_axi_R(R, 0.0, e->Rmin, &c, &sn);
    if (Rf != R || e->psi.kind != GCP_SPL_SEPTIC || e->prof.kind != GCP_SPL_SEPTIC) return -1;
    const double p[2] = {R, Z};
    struct gcp_spl_out o;
    double w[2][8], dw[2][8], ddw[2][8], dddw[2][8], d3[4];
    size_t base = 0, off;
    double t;
    int outside = 0;
    for (int a = 0; a < 2; a++) {
        outside |= gcp_spl_cell(&e->psi, a, p[a], &off, &t);
        base += off;
        gcp_spl_w7(t, e->psi.inv_h[a], 2, w[a], dw[a], ddw[a]);
        gcp_spl_w7_3(t, e->psi.inv_h[a], dddw[a]);
    }
    gcp_spl2_eval8_3(e->psi.coef[0] + base, e->psi.stride[1], w[0], dw[0], ddw[0], dddw[0], w[1],
                     dw[1], ddw[1], dddw[1], &o, d3);
    psi_out(e->s_pol, &o, out);
    *fst = outside ? GCP_LEFT_GRID : 0;
    /* F(psi) with dF/dpsi, d2F/dpsi2 (file's psi), the edge value outside:
     * one evaluation of the profile for B, grad B and Bd (eqdsk_B_of would
     * evaluate it again); dFB is dF/dpsi rounded as eqdsk_F rounds it, so
     * B and grad B are the same numbers as gcp_eqdsk_psi_B_RZ's */
    double F = e->F_edge, F1 = 0.0, F2 = 0.0, dFB = 0.0;
    const double psiN = (o.f - e->info.simag) / e->dpsi;
    if (!(psiN > 1.0 || Z < e->info.zbmin || Z > e->info.zbmax)) {
        /* eqdsk_prof7 with the second derivative (the same cell and weights) */
        const struct gcp_spl *sp = &e->prof;
        const double sc = (double)(e->info.nw - 1), x = sp->x0[0] + psiN * sc * sp->h[0];
        size_t off;
        double tt, w[8], dw[8], ddw[8], f0 = 0, f1 = 0, f2 = 0;
        gcp_spl_cell(sp, 0, x, &off, &tt);
        gcp_spl_w7(tt, sp->inv_h[0], 2, w, dw, ddw);
        const double *co = sp->coef[0] + off, c0 = co[0];
        for (int a = 0; a < 8; a++) {
            const double ca = co[a] - c0;
            f0 += w[a] * ca, f1 += dw[a] * ca, f2 += ddw[a] * ca;
        }
        const double du = sc * sp->h[0] / e->dpsi; /* d(x)/d(psi) */
        F = c0 + f0;
        F1 = f1 * du;
        F2 = f2 * du * du;
        dFB = f1 * sp->h[0] * sc / e->dpsi;
    }
    s->need = GCP_NEED_B | GCP_NEED_GRADB;
    eqdsk_B_ofF(e, &o, R, F, dFB, c, sn, 1, s);
    const double pR = o.d[0], pZ = o.d[1];
    const double wR[6] = {o.d[1], o.dd[0][1], o.dd[1][1], d3[1], d3[2], d3[3]}; /* psi_Z */
    const double wZ[6] = {o.d[0], o.dd[0][0], o.dd[0][1], d3[0], d3[1], d3[2]}; /* psi_R */
    const double wF[6] = {F, F1 * pR, F1 * pZ, F2 * pR * pR + F1 * o.dd[0][0],
                          F2 * pR * pZ + F1 * o.dd[0][1], F2 * pZ * pZ + F1 * o.dd[1][1]};
    const double iR = 1.0 / R;
    axi_over_R(-e->s_pol, wR, iR, Bd[0]);
    axi_over_R(e->s_tor, wF, iR, Bd[1]);
    axi_over_R(e->s_pol, wZ, iR, Bd[2]);
    return *fst;
}

/* The file's magnetic axis and boundary flux (rmaxis, zmaxis, sibry). */
int gcp_eqdsk_flux_surfaces(const struct gcp_field *f, double *Ra, double *Za, double *pe)
{
    const struct eqdsk_params *e = f->params;
    *Ra = e->info.rmaxis;
    *Za = e->info.zmaxis;
    *pe = e->s_pol * e->info.sibry;
    return 0;
}

/* psi's continuity (flux_priv.h): C6 septic, C4 quintic (the test's legacy). */
int gcp_eqdsk_psi_continuity(const struct gcp_field *f)
{
    const struct eqdsk_params *e = f->params;
    return e->kind == GCP_SPL_SEPTIC ? 6 : 4;
}
