/* The observer's full-orbit side (contract: gcpush/invariants.h): the
 * gyro-average that turns a full orbit into a guiding-centre stream, and the
 * dipole loss-cone classification of a start. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/gc.h"
#include "gcpush/invariants.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "invariants_priv.h"

/* Full orbit: one step of lane li into its gyro-average; emits a stream
 * sample at each completed gyration.  v: X[3], p_par, mu, p^2 of the
 * first-order guiding centre of this step; rho = x - X; B: B(x) (b = B/|B|
 * is needed only where a gyration starts or ends).  The step of a begun
 * gyration is gcp_fo_gyro_lane (pushers/fo_gyro_priv.h: the phase test and
 * the trapezoid sums, shared with the fused full-orbit step). */
static void fo_step_lane(struct gcp_observer *o, struct lane *L, size_t li, int64_t id, double t,
                         const double v[6], const double rho[3], const double B[3])
{
    struct gcp_fo_gyro *G = &o->g;
    if (G->init[li] != GCP_FO_GYRO_STEP) { /* none, or the fused step's (dropped) */
        G->init[li] = GCP_FO_GYRO_STEP;
        G->left[li] = 0;
        for (int k = 0; k < 3; k++) G->rho[k][li] = rho[k];
        for (int k = 0; k < 6; k++) G->prev[k][li] = v[k], G->acc[k][li] = 0.0;
        G->t0[li] = G->tprev[li] = t;
        const double r = sqrt(gcp_obs_dot3(rho, rho));
        double e[3], e2[3];
        for (int k = 0; k < 3; k++) e[k] = G->e1[k][li] = r > 0 ? rho[k] / r : 0.0;
        gcp_fo_gyro_e2(B, e, e2);
        for (int k = 0; k < 3; k++) G->e2[k][li] = e2[k];
        return;
    }
    struct gcp_fo_gyro_rec r = {0};
    if (gcp_fo_gyro_lane(G, li, t, v, rho, B, &r)) gcp_obs_fo_record(o, L, id, &r);
}

/* A record into lane L's stream with |B| at its X given. */
static void fo_record_B(struct gcp_observer *o, struct lane *L, int64_t id,
                        const struct gcp_fo_gyro_rec *r, double B)
{
    struct gsample s = {.t = r->t, .X = {r->X[0], r->X[1], r->X[2]}, .ppar = r->ppar,
                        .mu = r->mu, .p2 = r->p2, .B = B};
    /* the fused step's record carries p_perp^2 (fo_gyro_priv.h) */
    if (r->mid) s.mu = r->mu / (2.0 * o->m * s.B);
    gcp_obs_stream_sample(o, L, id, &s);
}

void gcp_obs_fo_record(struct gcp_observer *o, struct lane *L, int64_t id,
                       const struct gcp_fo_gyro_rec *r)
{
    struct gcp_field_sample fs = {.need = GCP_NEED_B};
    gcp_field_eval(o->f, r->t, r->X, &fs);
    fo_record_B(o, L, id, r, sqrt(gcp_obs_dot3(fs.B, fs.B)));
}

/* Record r's sample, its mu and |B| given, into g. */
static inline void rec_put(struct gsample *g, const struct gcp_fo_gyro_rec *r, double mu, double B)
{
    g->t = r->t;
    g->X[0] = r->X[0], g->X[1] = r->X[1], g->X[2] = r->X[2];
    g->ppar = r->ppar, g->mu = mu, g->B = B, g->p2 = r->p2;
}

/* Whether record s of lane L, in order after its latest sample L->s1,
 * asks gcp_obs_cadence for work (invariants_samples.c): a samples-grid
 * time or a stream-contour grid time at or before s->t, or the azimuth
 * possibly moved by pi/4 (azimuth_moved's first test, the one that says
 * "no" with nothing else done).  Each test is cadence's own expression,
 * so a record found calm here is one cadence would have done nothing for. */
static int fo_rec_cadence(const struct gcp_observer *o, const struct lane *L,
                          const struct gcp_fo_gyro_rec *s)
{
    const double T = o->opts.sample_dt;
    if (!(T > 0)) return 0;
    if (!L->had_eq && (o->opts.invariants & (GCP_INV_MU | GCP_INV_ENERGY | GCP_INV_PPHI)) &&
        o->t0 + (double)L->s_k * T <= s->t)
        return 1;
    if (!o->want_drift || L->n_drift_eq) return 0;
    if (o->t0 + (double)L->d_k * T <= s->t) return 1;
    if (!L->st_n || !(L->st_t < s->t)) return 0;
    const struct contour *c = &L->cst;
    const double dot = s->X[0] * c->cprev + s->X[1] * c->sprev;
    const double crs = s->X[1] * c->cprev - s->X[0] * c->sprev;
    const double margin = 1e-9 * (fabs(s->X[0]) + fabs(s->X[1]));
    return !(dot - fabs(crs) > margin);
}

/* The lines of a struct lane (~750 bytes; 2048 lanes do not fit in L2)
 * that a record's inline step reads (have_s1, s1, jd1, J_acc, eq_*; mub;
 * the stream contour's cprev, sprev; st_*, had_eq, s_k, d_k), fetched
 * FO_REC_AHEAD records before it: the records of a call visit the lanes
 * in the tiles' order, one record a lane a gyration, so each lane's lines
 * come from L3 or memory. */
#define FO_REC_AHEAD 8
static inline void fo_rec_prefetch(const struct lane *L)
{
    __builtin_prefetch(&L->have_s1);
    __builtin_prefetch(&L->J_acc);
    __builtin_prefetch(&L->mub);
    __builtin_prefetch(&L->cst.cprev);
    __builtin_prefetch(&L->s_k);
}

/* The fused step's records of a call (o->g.rec, in order): |B| at their X
 * in one block evaluation per time (a static field: one for all); then,
 * in one vectorised pass over the records, |B|, mu (fo_record_B's) and the
 * J integrand (jdot's, p_par^2 / gamma m: the same expressions, so
 * bit-identical); then each into its lane's stream in order.  A record
 * that is neither a lane's first sample nor a mirror point (~29 in 30 on
 * tests/bench/observer.sh's Boris scene) takes stream_sample's sums, the
 * cadence's work only where fo_rec_cadence finds some, and the minimum
 * tracking inline, in stream_sample's order of operations; the others go
 * through gcp_obs_stream_sample_jd.  A lane may have several records in a call
 * (one per gyration), each reading the sums the one before it wrote: that
 * part stays a loop in record order. */
void gcp_obs_fo_records(struct gcp_observer *o)
{
    const struct gcp_fo_gyro *G = &o->g;
    const int64_t n = G->nrec;
    int vec = n > 0 && o->f->type->eval_block && !(gcp_field_caps(o->f) & GCP_CAP_TIME);
    if (vec && o->rcap < n) {
        double *m = realloc(o->rmem, (size_t)n * 11 * sizeof(double));
        if (m) o->rmem = m, o->rcap = n;
        vec = m != NULL;
    }
    if (!vec) {
        for (int64_t k = 0; k < n; k++)
            gcp_obs_fo_record(o, &o->lane[G->rec[k].lane], o->id0 + G->rec[k].lane, &G->rec[k]);
        return;
    }
    const size_t c = (size_t)o->rcap;
    double *restrict X = o->rmem, *restrict Y = X + c, *restrict Z = Y + c;
    double *restrict Bx = Z + c, *restrict By = Bx + c, *restrict Bz = By + c;
    double *restrict P = Bz + c, *restrict Q = P + c, *restrict M = Q + c;
    int64_t *restrict mid = (int64_t *)(M + c);
    int32_t *restrict st = (int32_t *)(mid + c);
    const struct gcp_fo_gyro_rec *restrict rec = G->rec;
    for (int64_t k = 0; k < n; k++) {
        X[k] = rec[k].X[0], Y[k] = rec[k].X[1], Z[k] = rec[k].X[2], st[k] = 0;
        P[k] = rec[k].ppar, Q[k] = rec[k].p2, M[k] = rec[k].mu, mid[k] = rec[k].mid;
    }
    o->f->type->eval_block(o->f, rec[0].t, (size_t)n, X, Y, Z, Bx, By, Bz, NULL, NULL, NULL, st);
    /* in place: Bx <- |B|, By <- mu, Bz <- jd */
    const double m = o->m;
    GCP_OBS_IVDEP
    for (int64_t k = 0; k < n; k++) {
        const double B = sqrt(Bx[k] * Bx[k] + By[k] * By[k] + Bz[k] * Bz[k]);
        const double mu = mid[k] ? M[k] / (2.0 * m * B) : M[k];
        const double jd = P[k] * P[k] / sqrt(m * m + Q[k] / (GCP_C_LIGHT * GCP_C_LIGHT));
        Bx[k] = B, By[k] = mu, Bz[k] = jd;
    }
    const int want_eq = o->want_eq;
    for (int64_t k = 0; k < n; k++) {
        const struct gcp_fo_gyro_rec *r = &rec[k];
        struct lane *L = &o->lane[r->lane];
        if (k + FO_REC_AHEAD < n) fo_rec_prefetch(&o->lane[rec[k + FO_REC_AHEAD].lane]);
        const double B = Bx[k], mu = By[k], jd = Bz[k];
        /* a first sample or a mirror point: the whole of stream_sample */
        if (!L->have_s1 || (L->s1.ppar > 0) != (r->ppar > 0)) {
            const struct gsample s = {.t = r->t, .X = {r->X[0], r->X[1], r->X[2]},
                                      .ppar = r->ppar, .mu = mu, .p2 = r->p2, .B = B};
            gcp_obs_stream_sample_jd(o, L, o->id0 + r->lane, &s, jd);
            continue;
        }
        /* else gcp_obs_stream_sample_jd's steps inline, in its order (the
         * sums, the cadence's work where there is any -- ~1 record in 3
         * here, the stream contour's grid at ~3 gyrations -- the minimum,
         * s1), with first_of_half = 0; the sample written field by field
         * (rec_put): a gsample built on the stack and copied whole into
         * L->s1, e1 or e2 was read back before its stores had retired (a
         * store-forwarding stall per record) */
        const double h = r->t - L->s1.t;
        L->J_acc += 0.5 * (L->jd1 + jd) * h;
        L->mub += 0.5 * (L->s1.mu + mu) * h;
        if (fo_rec_cadence(o, L, r)) {
            const struct gsample s = {.t = r->t, .X = {r->X[0], r->X[1], r->X[2]},
                                      .ppar = r->ppar, .mu = mu, .p2 = r->p2, .B = B};
            gcp_obs_cadence(o, L, o->id0 + r->lane, &s);
        }
        if (want_eq) {
            if (B < L->eq_Bmin) {
                L->eq_Bmin = B;
                L->e0 = L->s1;
                rec_put(&L->e1, r, mu, B);
                L->eq_has_prev = 1;
                L->eq_need_next = 1;
                L->eq_valid = 0;
            } else if (L->eq_need_next) {
                rec_put(&L->e2, r, mu, B);
                L->eq_need_next = 0;
                L->eq_valid = L->eq_has_prev;
            }
        }
        rec_put(&L->s1, r, mu, B);
        L->jd1 = jd;
    }
}

/* The step of every live lane whose gyration neither starts nor ends in it
 * (19 steps in 20 at 0.05 gyro): the same arithmetic as fo_step_lane's (so
 * bit-identical to it), as one pass with no branches that the compiler
 * vectorises; the other lanes are marked in o->special and left as they
 * were.  idx: the lanes'
 * original indices, or NULL where they are 0 .. n-1 (a block before its
 * first retirement: then the state arrays are read and written densely). */
static inline __attribute__((always_inline)) void
fo_pass(struct gcp_observer *o, const struct gcp_block *b, size_t n, double t,
        const size_t *restrict idx)
{
    struct gcp_fo_gyro *G = &o->g;
    int64_t *restrict init = G->init, *restrict left = G->left, *restrict sp = o->special;
    double *restrict r0 = G->rho[0], *restrict r1 = G->rho[1], *restrict r2 = G->rho[2];
    const double *restrict e10 = G->e1[0], *restrict e11 = G->e1[1], *restrict e12 = G->e1[2];
    const double *restrict e20 = G->e2[0], *restrict e21 = G->e2[1], *restrict e22 = G->e2[2];
    double *restrict tprev = G->tprev;
    double *restrict a0 = G->acc[0], *restrict a1 = G->acc[1], *restrict a2 = G->acc[2];
    double *restrict a3 = G->acc[3], *restrict a4 = G->acc[4], *restrict a5 = G->acc[5];
    double *restrict p0 = G->prev[0], *restrict p1 = G->prev[1], *restrict p2 = G->prev[2];
    double *restrict p3 = G->prev[3], *restrict p4 = G->prev[4], *restrict p5 = G->prev[5];
    const double *restrict v0 = o->Xx, *restrict v1 = o->Xy, *restrict v2 = o->Xz;
    const double *restrict v3 = o->Vpp, *restrict v4 = o->Vmu, *restrict v5 = o->Vp2;
    const double *restrict x = b->x, *restrict y = b->y, *restrict z = b->z;
    GCP_OBS_IVDEP
    for (size_t i = 0; i < n; i++) {
        const size_t li = idx ? idx[i] : i;
        const double rx = x[i] - v0[i], ry = y[i] - v1[i], rz = z[i] - v2[i];
        const double a = r0[li] * e20[li] + r1[li] * e21[li] + r2[li] * e22[li];
        const double c = rx * e20[li] + ry * e21[li] + rz * e22[li];
        const int64_t lf = left[li] | (rx * e10[li] + ry * e11[li] + rz * e12[li] < 0);
        const int64_t cross = ((a < 0) & (c >= 0)) | ((a > 0) & (c <= 0));
        /* where it crossed, whether on e1's side (fo_step_lane's test) */
        const double th = a / (a - c);
        const double wx = r0[li] + th * (rx - r0[li]), wy = r1[li] + th * (ry - r1[li]),
                     wz = r2[li] + th * (rz - r2[li]);
        const int64_t wrap = wx * e10[li] + wy * e11[li] + wz * e12[li] > 0;
        const int64_t s = (init[li] != GCP_FO_GYRO_STEP) | (lf & cross & wrap);
        sp[i] = s;
        const double dt = t - tprev[li];
#define GYRO_ACC(A, P, V)                                                                    \
    do {                                                                                     \
        const double acc_k = A[li] + 0.5 * (P[li] + V[i]) * dt;                              \
        A[li] = s ? A[li] : acc_k;                                                           \
        P[li] = s ? P[li] : V[i];                                                            \
    } while (0)
        GYRO_ACC(a0, p0, v0);
        GYRO_ACC(a1, p1, v1);
        GYRO_ACC(a2, p2, v2);
        GYRO_ACC(a3, p3, v3);
        GYRO_ACC(a4, p4, v4);
        GYRO_ACC(a5, p5, v5);
#undef GYRO_ACC
        r0[li] = s ? r0[li] : rx;
        r1[li] = s ? r1[li] : ry;
        r2[li] = s ? r2[li] : rz;
        left[li] = s ? left[li] : lf;
        tprev[li] = s ? tprev[li] : t;
    }
}

void gcp_obs_fo_block(struct gcp_observer *o, const struct gcp_block *b, double t)
{
    const size_t n = b->n_active;
    const double m = o->m, qi = 1.0 / o->q;
    const double *restrict Bx = o->Bx, *restrict By = o->By, *restrict Bz = o->Bz;
    const double *restrict ux = b->ux, *restrict uy = b->uy, *restrict uz = b->uz;
    const double *restrict x = b->x, *restrict y = b->y, *restrict z = b->z;
    double *restrict Xx = o->Xx, *restrict Xy = o->Xy, *restrict Xz = o->Xz;
    /* first-order guiding centre of every lane (gcp_gc_from_fo, as a block):
     * rho = b x p / (q B) at x, X = x - rho; B at X next */
    GCP_OBS_IVDEP
    for (size_t i = 0; i < n; i++) {
        const double B2 = Bx[i] * Bx[i] + By[i] * By[i] + Bz[i] * Bz[i];
        const double s = m * qi / B2; /* b x p /(q B) = B x u m /(q B^2) */
        const double rx = s * (By[i] * uz[i] - Bz[i] * uy[i]);
        const double ry = s * (Bz[i] * ux[i] - Bx[i] * uz[i]);
        const double rz = s * (Bx[i] * uy[i] - By[i] * ux[i]);
        Xx[i] = x[i] - rx, Xy[i] = y[i] - ry, Xz[i] = z[i] - rz;
    }
    o->f->type->eval_block(o->f, t, n, o->Xx, o->Xy, o->Xz, o->Cx, o->Cy, o->Cz, NULL, NULL, NULL,
                           o->fst);
    /* its p_par = p . b(X), mu = p_perp^2 / (2 m |B(X)|), p^2 */
    const double *restrict Cx = o->Cx, *restrict Cy = o->Cy, *restrict Cz = o->Cz;
    double *restrict Vpp = o->Vpp, *restrict Vmu = o->Vmu, *restrict Vp2 = o->Vp2;
    GCP_OBS_IVDEP
    for (size_t i = 0; i < n; i++) {
        const double px = m * ux[i], py = m * uy[i], pz = m * uz[i];
        const double BX = sqrt(Cx[i] * Cx[i] + Cy[i] * Cy[i] + Cz[i] * Cz[i]);
        const double pp = (px * Cx[i] + py * Cy[i] + pz * Cz[i]) / BX;
        const double p2 = px * px + py * py + pz * pz;
        const double d = p2 - pp * pp; /* fmax(d, 0), which does not vectorise */
        Vpp[i] = pp;
        Vmu[i] = (d > 0.0 ? d : 0.0) / (2.0 * m * BX);
        Vp2[i] = p2;
    }
    /* The pass needs every live lane begun (always, after
     * gcp_observer_begin); dense: their indices are still 0 .. n-1. */
    int ok = n <= o->nlanes, dense = ok;
    for (size_t i = 0; ok && i < n; i++) {
        const size_t li = b->index[i];
        ok = li < o->nlanes && o->active[li];
        dense &= li == i;
    }
    if (dense) {
        fo_pass(o, b, n, t, NULL);
    } else if (ok) {
        fo_pass(o, b, n, t, b->index);
    } else {
        for (size_t i = 0; i < n; i++)
            o->special[i] = b->index[i] < o->nlanes && o->active[b->index[i]];
    }
    for (size_t i = 0; i < n; i++) {
        if (!o->special[i]) continue;
        const size_t li = b->index[i];
        struct lane *L = &o->lane[li];
        const double v[6] = {o->Xx[i], o->Xy[i], o->Xz[i], Vpp[i], Vmu[i], Vp2[i]};
        const double rho[3] = {b->x[i] - o->Xx[i], b->y[i] - o->Xy[i], b->z[i] - o->Xz[i]};
        const double B[3] = {Bx[i], By[i], Bz[i]};
        fo_step_lane(o, L, li, o->id0 + (int64_t)li, t, v, rho, B);
    }
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

