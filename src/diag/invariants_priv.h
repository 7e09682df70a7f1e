/* Private to the invariant observer (src/diag/invariants*.c): per-lane
 * state and the helpers the files share.  Contract: gcpush/invariants.h. */
#ifndef GCPUSH_INVARIANTS_PRIV_H
#define GCPUSH_INVARIANTS_PRIV_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "gcpush/invariants.h"
#include "pushers/fo_gyro_priv.h"

/* One guiding-centre stream sample. */
struct gsample {
    double t;     /* [s] */
    double X[3];  /* [m] guiding centre */
    double ppar;  /* [kg m/s] */
    double mu;    /* [J/T] */
    double B;     /* [T] |B(X)| */
    double p2;    /* [kg^2 m^2/s^2] p^2 */
};

/* The values of a stream sample in the guiding-centre ring (struct
 * gcp_observer.hot.r): a gsample's 8 in the order of its fields, and jd. */
#define GCP_OBS_RING_NV 9

/* A point of a drift contour. */
struct cpoint {
    double t, phi, R, z; /* phi unwrapped along the contour */
    double psi, AR, Az;  /* R A_phi [T m^2], A_R, A_z [T m] */
};

/* A drift contour in progress: points so far, the previous one, where the
 * current turn began, oint A . dl of the turn so far. */
struct contour {
    int n;
    struct cpoint prev;
    double phi0, t0, acc;
    double cprev, sprev; /* the stream contour: cos, sin of prev.phi (set by stream_point) */
    /* gcp_obs_azimuth_from: the position (x, y) whose azimuth the next
     * point's is measured from, and (equator contour) that azimuth */
    double aref_x[2], aref;
};

struct lane {
    int loss_done;
    int32_t mode;         /* method = hybrid: the mode of the last sample (enum gcp_hybrid_mode) */
    /* full orbit: the gyration in progress is in o->g (struct gcp_fo_gyro) */
    /* stream */
    int have_s1;
    struct gsample s1;
    double jd1;      /* the J integrand p_par^2 / (gamma m) of s1, computed once */
    /* half-bounce */
    int half_valid;  /* began at a mirror point */
    double J_acc;    /* int p_par v_par dt of the half so far */
    double eq_Bmin;
    int eq_need_next, eq_has_prev, eq_valid;
    struct gsample e0, e1, e2;
    /* bounce */
    int nm;          /* mirror points of the bounce in progress (0: none yet) */
    double tb0, Jb, mub;
    double lat[2], Bm[2], xm[2][3];
    /* drift: the contour of equator points, and the contour of the stream
     * on the cadence (drift-phase crossings for lanes whose equator points
     * make no turn: invariants_samples.c) */
    struct contour ceq, cst;
    /* the stream contour's points are recorded (t, X: o->sq) and go into
     * cst only where its rows can be kept (gcp_obs_stream_flush): st_n
     * points recorded in all, the last at st_t; nq of them not yet in cst */
    int st_n, nq;
    double st_t;
    /* what the push found (the /invariants/undefined reasons) */
    int n_mirror, n_bounce, n_drift_eq, n_drift_st, psi_nan;
    /* cadence samples (opts.sample_dt): the next grid index k of
     * t0 + k sample_dt; had_eq: an equator point (mu, energy, p_phi rows)
     * was found in this push.  The test is the equator point, not a mirror
     * point: a full orbit at pitch 90 deg on a curved field's equator has
     * p_par ~ 0 and its gyro-averaged sign flips (mirror points) without
     * an equator point between them, and it too must get its samples. */
    int had_eq;
    int64_t s_k, d_k;   /* d_k: the stream contour's next grid index */
};

/* Full orbit: the gyration in progress of each lane (indexed by the lane's
 * original index, as lane[]) is a struct gcp_fo_gyro (pushers/fo_gyro_priv.h):
 * a struct of arrays, so that the step of a gyration that neither starts
 * nor ends in it (all but ~1 step in 20) is one vectorised pass over the
 * block (invariants_fo.c), or is done inside the fused full-orbit step. */

struct gcp_observer {
    const struct gcp_field *f;
    const struct gcp_pusher_type *p;
    struct gcp_observer_opts opts;
    int gc;           /* guiding-centre pusher */
    int hybrid;       /* method = hybrid: the mode comes with each sample */
    int stream;       /* any stream work at all */
    int want_bounce, want_drift, want_eq;
    double B0;        /* [T] reference for L* */
    size_t nlanes;
    struct lane *lane;
    double *Bx, *By, *Bz; /* scratch: B at the lanes */
    double *Xx, *Xy, *Xz, *Cx, *Cy, *Cz; /* full orbit: first-order guiding centre, B there */
    double *Vpp, *Vmu, *Vp2;  /* full orbit: p_par, mu, p^2 of that guiding centre */
    int64_t *special;         /* full orbit: the lanes a gyration starts or ends in */
    double *Gb, *Gp2, *Gjd;   /* guiding centre: |B|, p^2 and the J integrand of each lane */
    /* the field is the dipole's closed form (field_kernels.h, constant c):
     * the quiet pass takes B at the lanes inline (gcp_point_B_dipole, the
     * field's own block evaluation bit for bit) instead of from Bx, By, Bz */
    int pdip;
    double pc;
    /* the field is the dipole model: A of a contour point inline
     * (gcp_point_A_dipole, the model's potential bit for bit) */
    int pdipA;
    /* Guiding-centre pushers (not hybrid): the per-step state of each lane's
     * stream (by lane index li), as a struct of arrays, so that a step in
     * which nothing happens to a lane but the trapezoid sums and the
     * tracking of the |B| minimum -- no mirror point, no sample after a
     * minimum, no cadence time, the azimuth within pi/4 -- is one
     * vectorised pass (invariants_quiet.c).  The lane's struct lane holds
     * the same values only around its other steps (hot_to_lane before,
     * lane_to_hot after).  The samples are a ring of three slots, the same
     * slot for every lane at a step: r[cur] is the latest (L->s1), r[cur+2
     * mod 3] the one before it (L->e0 where next is set: the sample before
     * the minimum s1), and a step writes its own into r[cur+1 mod 3] for
     * every lane -- no copy of s1 into a "previous" array at each step. */
    struct {
        double *r[3][GCP_OBS_RING_NV]; /* t, X[3], ppar, mu, B, p2 and the J integrand jd */
        /* A slot's time is the same for every lane (its step's t), so it
         * is rt[slot], not r[slot][0]; and mu is a guiding centre's
         * constant, written into r[0..2][5] once, at gcp_observer_begin
         * (gs_put writes neither: invariants_quiet.c) */
        double rt[3];
        double *J, *mub; /* J_acc, mub */
        double *Bmin;   /* eq_Bmin, or -inf where no equator is wanted */
        double *tnext;  /* the first cadence time that asks for work (inf: none;
                           -inf while the lane has no sample: have_s1 = 0) */
        double *cx, *cy; /* the stream contour's cprev, sprev */
        int64_t *have;  /* have_s1 */
        int64_t *next;  /* eq_need_next: the minimum is s1, e0 the sample before it */
        int64_t *hprev; /* eq_has_prev */
        int64_t *az;    /* the stream contour's azimuth is watched */
        int64_t *slow;  /* scratch: lane position i needs stream_sample */
        int cur;        /* the ring slot of the latest sample */
        /* the last observe_live went through the quiet pass: the ring's
         * latest slot holds every lane's last live position and time
         * (loss interpolation), and xprev, tprev were not written */
        int pos;
        /* tests (test_invariants_quiet.c): per_lane sends every step of
         * every lane through gcp_obs_stream_sample_jd, the reference the
         * quiet pass must equal bit for bit; passes counts the steps that
         * went through the quiet pass */
        int per_lane;
        int64_t passes;
    } hot;
    /* per lane li: the stream contour's recorded points not yet in L->cst,
     * (t, X[3]) each, cap points of room (kept from push to push) */
    struct { double *p; int cap; } *sq;
    /* tests (test_invariants_quiet.c): st_eager takes every stream point
     * into the contour at once (the reference of the deferred contour);
     * st_skipped counts the points of contours found to make no turn */
    int st_eager;
    int64_t st_skipped;
    struct gcp_fo_gyro g;
    /* per lane li, dense, as they are written at every step: begun in this
     * push, the last live position and time (loss interpolation) */
    int64_t *active;
    double *xprev[3], *tprev;
    double *gmem;             /* the storage of these arrays and of the scratch above */
    int64_t *gflags;
    int32_t *fst;
    double q, m;
    int64_t id0;
    double t0;            /* the push's start (the cadence grid's origin) */
    int64_t ev_begin;     /* out->n at gcp_observer_begin */
    struct gcp_events *out;
    int nomem;
    /* scratch of gcp_obs_fo_records: X[3], B[3], p_par, p^2, mu, mid and
     * the field's verdict of rcap records */
    double *rmem;
    int64_t rcap;
};

/* Before a loop over a block's lanes whose arrays do not overlap (and
 * whose lane indices are distinct): GCC would otherwise test the arrays for
 * overlap at run time, and gives up past 10 of them. */
#if defined(__GNUC__) && !defined(__clang__)
#define GCP_OBS_IVDEP _Pragma("GCC ivdep")
#else
#define GCP_OBS_IVDEP
#endif

static inline double gcp_obs_dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* Appends e to the push's events, tagged with the lane's mode (non-loss
 * events carry it in .status). */
void gcp_obs_emit(struct gcp_observer *o, const struct lane *L, struct gcp_event *e);
/* The same for an event of a scalar kind (gcp_event_scalar: mu, energy,
 * p_phi at an equator point, twice a bounce), straight into its row: no
 * 136-byte struct gcp_event formed, zeroed and copied for its 32 bytes. */
void gcp_obs_emit_scalar(struct gcp_observer *o, const struct lane *L, int64_t id, int32_t kind,
                         double t, double v);
/* gcp_events_push of a scalar row (invariants_events.c). */
int gcp_events_push_scalar(struct gcp_events *ev, const struct gcp_scalar_event *e);
/* gamma m [kg] of momentum^2 p2. */
double gcp_obs_gamma_m(const struct gcp_observer *o, double p2);
/* Kinetic energy [J] of momentum^2 p2: p^2 c^2 / (E + m c^2), no cancellation. */
double gcp_obs_energy(const struct gcp_observer *o, double p2);
/* The next stream sample of a lane (invariants.c); _jd: with its J
 * integrand p_par^2 / (gamma m) given. */
void gcp_obs_stream_sample(struct gcp_observer *o, struct lane *L, int64_t id,
                           const struct gsample *s);
void gcp_obs_stream_sample_jd(struct gcp_observer *o, struct lane *L, int64_t id,
                              const struct gsample *s, double jd);
/* Guiding-centre pushers (invariants_quiet.c): the step at t of the n live
 * lanes of b, all begun (dense: lane i is b->index[i] = i), B at them in
 * o->Bx, By, Bz; and the copies between o->hot and a lane's struct lane
 * around any other call of gcp_obs_stream_sample_jd (hot_to_lane: s1 from
 * slot o->hot.cur; lane_to_hot: L->s1 into slot `slot`, which becomes the
 * latest once the step is done). */
void gcp_obs_stream_quiet(struct gcp_observer *o, const struct gcp_block *b, double t, size_t n,
                          int dense);
void gcp_obs_hot_to_lane(const struct gcp_observer *o, struct lane *L, size_t li);
void gcp_obs_lane_to_hot(struct gcp_observer *o, const struct lane *L, size_t li, int slot);
/* Full orbit: the live lanes of b at t into their gyro-averages, B at the
 * particles in o->Bx, By, Bz (invariants_fo.c). */
void gcp_obs_fo_block(struct gcp_observer *o, const struct gcp_block *b, double t);
/* A completed gyration (r) into lane L's stream: |B| at its X, then
 * gcp_obs_stream_sample (invariants_fo.c). */
void gcp_obs_fo_record(struct gcp_observer *o, struct lane *L, int64_t id,
                       const struct gcp_fo_gyro_rec *r);
/* The fused step's records of its last call, o->g.rec, in order. */
void gcp_obs_fo_records(struct gcp_observer *o);
/* Contour quantities of a position (R, psi = R A_phi, A_R, A_z). */
void gcp_obs_contour_of(const struct gcp_observer *o, double t, const double X[3], double *R,
                        double *psi, double *AR, double *Az);

/* The azimuth of b from that of a, wrapped to (-pi, pi]: atan2(a x b, a . b)
 * (z components), which equals wrap(atan2(b) - atan2(a)) up to rounding.
 * Between the samples around an equator point (a step apart, a few 1e-4
 * rad of drift azimuth) and between successive points of a drift contour
 * (half a bounce or sample_dt apart: ~0.025 and ~0.065 rad for the 1 MeV
 * protons at L = 4 of tests/bench/observer.sh) it is almost always the
 * series atan u = sum_k (-1)^k u^(2k+1)/(2k+1), k = 0 .. 9 (u = cross/dot):
 * for |u| < 1/8 the first term left out, u^21/21, is
 * < 4.2e-20 |u|, below the rounding of u; atan2 elsewhere (~30 ns, 6e5
 * calls a run there; issue 12). */
static inline double gcp_obs_azimuth_step(const double a[2], const double b[2])
{
    const double c = a[0] * b[1] - a[1] * b[0], d = a[0] * b[0] + a[1] * b[1];
    if (d > 0 && fabs(c) < 0.125 * d) {
        /* Estrin's scheme in t = u^2 (a chain of ~8 operations, where
         * Horner's has 18: it bounds the cost of a call) */
        const double u = c / d, t = u * u, t2 = t * t, t4 = t2 * t2;
        const double p0 = 1.0 - t * (1.0 / 3.0), p1 = 1.0 / 5.0 - t * (1.0 / 7.0);
        const double p2 = 1.0 / 9.0 - t * (1.0 / 11.0), p3 = 1.0 / 13.0 - t * (1.0 / 15.0);
        const double p4 = 1.0 / 17.0 - t * (1.0 / 19.0);
        const double q0 = p0 + t2 * p1, q1 = p2 + t2 * p3;
        return u * (q0 + t4 * (q1 + t4 * p4));
    }
    return atan2(c, d);
}

/* The azimuth of a contour c's next point at X from ref, the azimuth of the
 * position c->aref_x (the last point's, which X then becomes):
 * wrap(ref + gcp_obs_azimuth_step), no atan2 -- but atan2 at c's first
 * point and at every GCP_OBS_AZ_ANCHOR-th (c->n), so that the rounding of
 * the chained sums (~2e-16 rad a point) stays below ~1.5e-14 rad. */
#define GCP_OBS_AZ_ANCHOR 64
double gcp_obs_azimuth_from(struct contour *c, double ref, const double X[3]);
/* Adds point P to contour c; emits a drift event (v[3] = contour) per turn. */
void gcp_obs_drift_point(struct gcp_observer *o, struct lane *L, struct contour *c, int64_t id,
                         struct cpoint P, int which);
double gcp_obs_wrap_pi(double a);
/* The cadence work of stream sample s (samples rows, the stream contour),
 * before s becomes L->s1 (invariants_samples.c). */
void gcp_obs_cadence(struct gcp_observer *o, struct lane *L, int64_t id, const struct gsample *s);
/* The stream contour's recorded points of lane li into L->cst (potentials,
 * azimuths, drift_point): its drift rows up to the last point. */
void gcp_obs_stream_flush(struct gcp_observer *o, struct lane *L, size_t li);
/* After the push: drops the rows that the lane's other rows replace, adds
 * the /invariants/undefined rows. */
void gcp_obs_finish(struct gcp_observer *o, const struct gcp_block *b);

#endif
