/* Private to the pushers and the invariant observer: the gyro-average of a
 * full orbit (issue 12), shared by the observer's per-step pass
 * (src/diag/invariants_fo.c) and the fused full-orbit step that does the
 * same work inside its tile loop (fo_fused_priv.h), so that the two give
 * the same numbers bit for bit (the same operations in the same order;
 * the build keeps -ffp-contract=off).
 *
 * Physics (gcpush/invariants.h): each step's first-order guiding centre
 * X = x - rho, rho = b x p / (q B(x)) (Northrop 1963), with p_par = p.b(X),
 * mu = p_perp^2 / (2 m |B(X)|) and p^2, is averaged over each gyration by
 * the trapezoid rule in t; a gyration ends where rho crosses the half-plane
 * spanned by b and e1 (e1: rho's direction when the gyration began) after
 * having been on the far side (rho.e1 < 0): rho.e2 changes sign with
 * rho.e1 > 0 at the crossing, e2 = b x e1, the crossing linear in the step.
 *
 * Why the fused step does it (issue 12): the observer is a sampler of every
 * step, so without this the fused step runs one step per call, and the
 * observer makes ~8 passes over the block per step (two block field
 * evaluations among them).  With a gcp_fo_gyro the fused tile loop does a
 * gyration's steps in registers and L1 -- the guiding centre, the phase
 * test and the six running trapezoid sums per lane -- and writes a record
 * (struct gcp_fo_gyro_rec) only where a gyration ends (~1 step in 20 at
 * 0.05 gyro); the observer turns the records into its guiding-centre
 * stream (bounce integrals, equator points, drift contour) after the call. */
#ifndef GCPUSH_FO_GYRO_PRIV_H
#define GCPUSH_FO_GYRO_PRIV_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

/* Before the fused loop over a tile's lanes, whose arrays do not overlap:
 * GCC cannot use restrict on pointers loaded from a struct, tests the
 * arrays for overlap at run time, and gives up past 10 of them. */
#if defined(__GNUC__) && !defined(__clang__)
#define GCP_FO_IVDEP_ _Pragma("GCC ivdep")
#else
#define GCP_FO_IVDEP_
#endif

/* One completed gyration: its mid time and the averages over it. */
struct gcp_fo_gyro_rec {
    int64_t lane;  /* the lane's index (the block is dense: b->index[i] = i) */
    double t;      /* [s] the middle of the gyration */
    double X[3];   /* [m] averaged first-order guiding centre */
    double ppar;   /* [kg m/s] */
    double mu;     /* [J/T] */
    double p2;     /* [kg^2 m^2/s^2] */
};

/* The gyration in progress of each lane, as a struct of arrays indexed by
 * the lane's original index (the observer's; a dense block's position),
 * and the records of the fused step's last call. */
struct gcp_fo_gyro {
    int64_t *init, *left; /* left: the gyroradius has been on the far side of e1 */
    double *rho[3];       /* [m] rho = x - X of the previous step */
    double *e1[3], *e2[3];
    double *acc[6], *prev[6]; /* trapezoid integrals and previous values of X[3], ppar, mu, p2 */
    double *t0, *tprev;   /* [s] the gyration's start, the previous step */
    size_t nlanes;
    /* Filled by the fused step (fo_step.c), read by the observer's sampler
     * call that follows it: the records of the call in the order they were
     * made (per lane, in time), and the steps whose per-step work the call
     * did (0: none, the sampler does that step's work itself). */
    struct gcp_fo_gyro_rec *rec;
    int64_t nrec, cap;
    int64_t steps;
};

/* b x e1 with b = B/|B| (the observer's unit() and cross product). */
static inline void gcp_fo_gyro_e2(const double B[3], const double e1[3], double e2[3])
{
    const double Bm = sqrt(B[0] * B[0] + B[1] * B[1] + B[2] * B[2]);
    const double bx[3] = {B[0] / Bm, B[1] / Bm, B[2] / Bm};
    e2[0] = bx[1] * e1[2] - bx[2] * e1[1];
    e2[1] = bx[2] * e1[0] - bx[0] * e1[2];
    e2[2] = bx[0] * e1[1] - bx[1] * e1[0];
}

static inline double gcp_fo_gyro_dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* One step at t of lane li whose gyration has begun (init[li] != 0): v =
 * X[3], p_par, mu, p^2 of this step's first-order guiding centre, rho =
 * x - X, B = B(x).  Returns 1 with *r filled (but r->lane) where a
 * gyration ended in this step with a positive length. */
static inline int gcp_fo_gyro_lane(struct gcp_fo_gyro *G, size_t li, double t, const double v[6],
                                   const double rho[3], const double B[3],
                                   struct gcp_fo_gyro_rec *r)
{
    const double rp[3] = {G->rho[0][li], G->rho[1][li], G->rho[2][li]};
    const double e1[3] = {G->e1[0][li], G->e1[1][li], G->e1[2][li]};
    const double e2[3] = {G->e2[0][li], G->e2[1][li], G->e2[2][li]};
    double prev[6], acc[6];
    for (int k = 0; k < 6; k++) prev[k] = G->prev[k][li], acc[k] = G->acc[k][li];
    const double tprev = G->tprev[li];
    const double dt = t - tprev;
    const double a = gcp_fo_gyro_dot3(rp, e2), c = gcp_fo_gyro_dot3(rho, e2);
    if (gcp_fo_gyro_dot3(rho, e1) < 0) G->left[li] = 1;
    int wrap = 0, out = 0;
    double th = 0;
    if (G->left[li] && ((a < 0 && c >= 0) || (a > 0 && c <= 0))) {
        th = a / (a - c);
        double rw[3];
        for (int k = 0; k < 3; k++) rw[k] = rp[k] + th * (rho[k] - rp[k]);
        wrap = gcp_fo_gyro_dot3(rw, e1) > 0;
    }
    if (wrap) {
        const double tw = tprev + th * dt;
        double vw[6];
        for (int k = 0; k < 6; k++) {
            vw[k] = prev[k] + th * (v[k] - prev[k]);
            acc[k] += 0.5 * (prev[k] + vw[k]) * (tw - tprev);
        }
        const double T = tw - G->t0[li];
        if (T > 0) {
            r->t = 0.5 * (G->t0[li] + tw);
            for (int k = 0; k < 3; k++) r->X[k] = acc[k] / T;
            r->ppar = acc[3] / T;
            r->mu = acc[4] / T;
            r->p2 = acc[5] / T;
            out = 1;
        }
        for (int k = 0; k < 6; k++) G->acc[k][li] = 0.5 * (vw[k] + v[k]) * (t - tw);
        G->t0[li] = tw;
        G->left[li] = 0;
        /* e1, e2 follow the slowly turning field: e2 = b x e1 from this step */
        double e2n[3];
        gcp_fo_gyro_e2(B, e1, e2n);
        for (int k = 0; k < 3; k++) G->e2[k][li] = e2n[k];
    } else {
        for (int k = 0; k < 6; k++) G->acc[k][li] = acc[k] + 0.5 * (prev[k] + v[k]) * dt;
    }
    for (int k = 0; k < 3; k++) G->rho[k][li] = rho[k];
    for (int k = 0; k < 6; k++) G->prev[k][li] = v[k];
    G->tprev[li] = t;
    return out;
}

#endif
