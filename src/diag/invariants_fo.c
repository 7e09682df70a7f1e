/* The observer's full-orbit side (contract: gcpush/invariants.h): the
 * gyro-average that turns a full orbit into a guiding-centre stream, and the
 * dipole loss-cone classification of a start. */
#include <math.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/gc.h"
#include "gcpush/invariants.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "invariants_priv.h"

/* Full orbit: one step into the gyro-average; emits a stream sample at each
 * completed gyration.  X, p_par, mu: the first-order guiding centre of this
 * step (computed for the block in observe_live); rho = x - X; bx: b(x).
 * A gyration ends where the gyroradius vector crosses the half-plane
 * spanned by b and e1 (e1: its direction when the gyration began) again,
 * after having been on the far side: rho.e2 changes sign with rho.e1 > 0,
 * e2 = b x e1; the crossing is linear in the step. */
void gcp_obs_fo_step(struct gcp_observer *o, struct lane *L, int64_t id, double t,
                     const double v[6], const double rho[3], const double bx[3])
{
    if (!L->g_init) {
        L->g_init = 1;
        L->g_left = 0;
        memcpy(L->rho_prev, rho, 3 * sizeof(double));
        memcpy(L->g_prev, v, 6 * sizeof(double));
        memset(L->g_acc, 0, sizeof L->g_acc);
        L->g_t0 = L->g_tprev = t;
        const double r = sqrt(gcp_obs_dot3(rho, rho));
        for (int k = 0; k < 3; k++) L->g_e1[k] = r > 0 ? rho[k] / r : 0.0;
        const double *e = L->g_e1;
        L->g_e2[0] = bx[1] * e[2] - bx[2] * e[1];
        L->g_e2[1] = bx[2] * e[0] - bx[0] * e[2];
        L->g_e2[2] = bx[0] * e[1] - bx[1] * e[0];
        return;
    }
    const double dt = t - L->g_tprev;
    const double a = gcp_obs_dot3(L->rho_prev, L->g_e2), c = gcp_obs_dot3(rho, L->g_e2);
    if (gcp_obs_dot3(rho, L->g_e1) < 0) L->g_left = 1;
    int wrap = 0;
    double th = 0;
    if (L->g_left && ((a < 0 && c >= 0) || (a > 0 && c <= 0))) {
        th = a / (a - c);
        double rw[3];
        for (int k = 0; k < 3; k++) rw[k] = L->rho_prev[k] + th * (rho[k] - L->rho_prev[k]);
        wrap = gcp_obs_dot3(rw, L->g_e1) > 0;
    }
    if (wrap) {
        const double tw = L->g_tprev + th * dt;
        double vw[6];
        for (int k = 0; k < 6; k++) {
            vw[k] = L->g_prev[k] + th * (v[k] - L->g_prev[k]);
            L->g_acc[k] += 0.5 * (L->g_prev[k] + vw[k]) * (tw - L->g_tprev);
        }
        const double T = tw - L->g_t0;
        if (T > 0) {
            struct gsample s = {.t = 0.5 * (L->g_t0 + tw)};
            for (int k = 0; k < 3; k++) s.X[k] = L->g_acc[k] / T;
            s.ppar = L->g_acc[3] / T;
            s.mu = L->g_acc[4] / T;
            s.p2 = L->g_acc[5] / T;
            struct gcp_field_sample fs = {.need = GCP_NEED_B};
            gcp_field_eval(o->f, s.t, s.X, &fs);
            s.B = sqrt(gcp_obs_dot3(fs.B, fs.B));
            gcp_obs_stream_sample(o, L, id, &s);
        }
        for (int k = 0; k < 6; k++) L->g_acc[k] = 0.5 * (vw[k] + v[k]) * (t - tw);
        L->g_t0 = tw;
        L->g_left = 0;
        /* e1, e2 follow the slowly turning field: e2 = b x e1 from this step */
        const double *e = L->g_e1;
        double e2[3] = {bx[1] * e[2] - bx[2] * e[1], bx[2] * e[0] - bx[0] * e[2],
                        bx[0] * e[1] - bx[1] * e[0]};
        memcpy(L->g_e2, e2, sizeof e2);
    } else {
        for (int k = 0; k < 6; k++) L->g_acc[k] += 0.5 * (L->g_prev[k] + v[k]) * dt;
    }
    memcpy(L->rho_prev, rho, 3 * sizeof(double));
    memcpy(L->g_prev, v, 6 * sizeof(double));
    L->g_tprev = t;
}


/* ---- loss-cone classification ------------------------------------------ */

double gcp_dipole_loss_cone(double L, double r_atm)
{
    const double RE = GCP_EARTH_RADIUS;
    const double c2 = r_atm / (L * RE); /* cos^2 of the foot latitude */
    if (!(c2 > 0) || c2 >= 1.0) return NAN;
    const double s2 = 1.0 - c2;
    const double a = RE / r_atm;
    const double bfoot = a * a * a * sqrt(1.0 + 3.0 * s2); /* B_foot / B0 */
    const double beq = 1.0 / (L * L * L);                  /* B_eq / B0 */
    return asin(sqrt(beq / bfoot));
}

int gcp_dipole_classify(const struct gcp_field *f, double q, double m, const double x[3],
                        const double u[3], double ppar, double mu, double *L, double *alpha_eq,
                        double *alpha_lc)
{
    *L = *alpha_eq = *alpha_lc = NAN;
    if (!f || !(gcp_field_caps(f) & GCP_CAP_DIPOLE_L)) return GCP_ERR_STATE;
    double X[3], pp = ppar, mm = mu, p2;
    if (u) {
        if (gcp_gc_from_fo(f, 0.0, q, m, x, u, X, &pp, &mm)) return GCP_ERR_STATE;
        p2 = m * m * gcp_obs_dot3(u, u);
    } else {
        memcpy(X, x, sizeof X);
    }
    struct gcp_field_sample s = {.need = GCP_NEED_B};
    if (gcp_field_eval(f, 0.0, X, &s)) return GCP_ERR_STATE;
    const double B = sqrt(gcp_obs_dot3(s.B, s.B));
    if (!u) p2 = pp * pp + 2.0 * m * mm * B;
    const double r = sqrt(gcp_obs_dot3(X, X));
    const double cl2 = 1.0 - X[2] * X[2] / (r * r);
    const double B0 = gcp_observer_reference_B0(f);
    *L = r / (GCP_EARTH_RADIUS * cl2);
    const double Beq = B0 / (*L * *L * *L);
    const double sin2 = p2 > 0 ? 2.0 * m * mm / p2 * Beq : NAN; /* sin^2 a B_eq / B */
    *alpha_eq = asin(sqrt(fmin(fmax(sin2, 0.0), 1.0)));
    *alpha_lc = f->r_inner > 0 ? gcp_dipole_loss_cone(*L, f->r_inner) : 0.0;
    (void)B;
    return 0;
}

