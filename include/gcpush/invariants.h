/* gcpush/invariants.h -- adiabatic invariants and radiation-belt events.
 *
 * An observer follows every lane of a block, step by step (it is a
 * gcp_sampler with every = 1), and turns the motion into events:
 *
 *   mirror points   p_par changes sign (linear interpolation of the
 *                   guiding-centre stream); latitude, position, B_m.
 *   bounce          two mirror points of the same kind (p_par + -> -, the
 *                   first such pair after the start): bounce period, the
 *                   second invariant J = oint p_par ds = int p_par v_par dt
 *                   and K = J / (2 sqrt(2 m mu)) [T^1/2 m].
 *   equator         the minimum of |B(X)| between two mirror points (the
 *                   magnetic equator of the field line, wherever it is;
 *                   parabolic interpolation): mu, energy, p_phi samples and
 *                   the drift contour.
 *   drift           the guiding centre's azimuth at successive equator
 *                   points has turned by 2 pi (interpolated): drift period,
 *                   the flux Phi = |oint A . dl| around the contour of
 *                   equatorial guiding-centre points, and
 *                   L* = 2 pi B0 R_E^2 / Phi (Roederer 1970).  In a pure
 *                   dipole Phi = 2 pi B0 R_E^2 / L, so L* = L.
 *   loss            the lane stopped (status != ALIVE); for PRECIPITATED
 *                   and LEFT_DOMAIN through r_inner / r_outer the crossing
 *                   of the sphere is interpolated within the last step.
 *   no bounce       (invariants_samples.c) a particle with no equator point
 *                   gets mu / energy / p_phi samples on a time cadence, and
 *                   one whose equator points make no turn gets its drift
 *                   events from the guiding centre on that cadence (drift-
 *                   phase crossings); an undefined event per particle says
 *                   why an asked quantity is missing.
 *
 * Guiding-centre pushers feed their own state (X, p_par, mu) in at every
 * step.  Full-orbit pushers are turned into a guiding-centre stream first:
 * each step goes through the first-order guiding-centre transformation
 * (gcp_gc_from_fo: X = x - b x p/(qB), p_par and mu evaluated at X;
 * Northrop 1963, Cary & Brizard 2009 sec. IV), and X, p_par, mu are then
 * averaged over each gyration (trapezoid in t between gyrophase wraps,
 * interpolated within the step; the phase is the angle swept by the
 * gyroradius vector x - X).  Evaluating at X removes the O(eps) gradient
 * oscillation of the raw p_perp^2/(2 m B(x)); the average over an exact
 * gyro-period removes what is left of the first harmonic, so the reported
 * mu is steady to O(eps^2) (eps = rho/L_B) where the raw value swings by
 * O(eps).  One stream sample per gyration then goes through the same event
 * logic as a guiding-centre step.  (So the full-orbit mu is the zeroth-order
 * moment p_perp^2/(2 m B) at the first-order guiding centre, gyro-averaged,
 * not the first-order invariant: equal to it to O(eps^2) in vacuum fields.)
 * method = hybrid: each lane's steps come with their mode
 * (gcp_observer_sample_mode), GC steps into the stream as they are, FO steps
 * through the gyro-average; events carry the mode in .status.
 *
 * Cost: nothing unless a run asks (the driver attaches no observer);
 * asked, per step one block field evaluation (GC) or two (FO) and
 * vectorised passes over the lanes' state; a GC lane's step that closes
 * nothing (no mirror point, equator or cadence time) stays in the
 * vectorised pass (tests/bench/observer.sh measures it).  A full orbit
 * pushed by a fused step (closed-form B, gcp_block_advance_fo_gyro, as the
 * run engine does) has the per-step part done in the push's tile loop, up
 * to 128 steps a call, and only the completed gyrations come here (the
 * same events bit for bit).
 */
#ifndef GCPUSH_INVARIANTS_H
#define GCPUSH_INVARIANTS_H

#include <stddef.h>
#include <stdint.h>

#include "field.h"
#include "particles.h"
#include "units.h"
#include "pusher.h"
#include "hybrid.h"
#include "api.h"
GCP_API_BEGIN

#ifdef __cplusplus
extern "C" {
#endif

/* [diagnostics] invariants = mu J K L energy pphi */
enum gcp_invariant_bits {
    GCP_INV_MU = 1u,
    GCP_INV_J = 2u,
    GCP_INV_K = 4u,
    GCP_INV_L = 8u,
    GCP_INV_ENERGY = 16u,
    GCP_INV_PPHI = 32u
};
/* [diagnostics] events = bounce drift loss */
enum gcp_event_bits { GCP_EVT_BOUNCE = 1u, GCP_EVT_DRIFT = 2u, GCP_EVT_LOSS = 4u };

/* Event tables (one HDF5 table each).  .status of an event: for a loss its
 * enum gcp_status; for the others the mode (enum gcp_hybrid_mode) of the
 * stream sample that closed it -- GCP_MODE_FO on a full-orbit stretch of
 * method = hybrid, 0 (GCP_MODE_GC) for every other method. */
enum gcp_event_kind {
    GCP_EVENT_BOUNCE = 0, /* v: period, J, K, lat1, lat2, Bm1, Bm2, x1[3], x2[3], mu */
    GCP_EVENT_DRIFT = 1,  /* v: enum gcp_drift_slot */
    GCP_EVENT_MU = 2,     /* v: mu (at each equator point) */
    GCP_EVENT_ENERGY = 3, /* v: kinetic energy [J] (at each equator point) */
    GCP_EVENT_PPHI = 4,   /* v: p_phi [kg m^2/s] (at each equator point) */
    GCP_EVENT_LOSS = 5,   /* status; v: x[3] */
    GCP_EVENT_SWITCH = 6, /* method = hybrid (hybrid.h): v: X[3], eps, direction (+1 to full
                             orbit, -1 to guiding centre), dp2 (energy rescaling) */
    GCP_EVENT_SAMPLE = 7, /* a particle with no equator point, every sample_dt: v: mu [J/T],
                             energy [J], p_phi [kg m^2/s] (NaN where not asked) */
    GCP_EVENT_UNDEFINED = 8, /* one per particle with an asked quantity missing, at the end of
                                its push: v[enum gcp_undefined_slot] = enum gcp_undefined */
    GCP_EVENT_KINDS = 9
};

/* Value slots of a drift event. */
enum gcp_drift_slot {
    GCP_DRIFT_PERIOD = 0,  /* [s] time for the azimuth to turn by 2 pi */
    GCP_DRIFT_LSTAR = 1,   /* [1] 2 pi B0 R_E^2 / Phi */
    GCP_DRIFT_PHI = 2,     /* [T m^2] |oint A . dl| */
    GCP_DRIFT_CONTOUR = 3  /* enum gcp_contour: the points the turn was made of */
};
/* The drift contour a drift event came from. */
enum gcp_contour {
    GCP_CONTOUR_EQUATOR = 0, /* the equator points (one per half-bounce) */
    GCP_CONTOUR_STREAM = 1   /* the guiding centre on the sample_dt cadence: kept only for a
                                particle whose equator points made no turn (equatorially
                                mirroring, passing, or too few bounces per drift) */
};

/* Why an asked quantity has no row (or a NaN one) for a particle. */
enum gcp_undefined {
    GCP_UNDEF_NONE = 0,          /* defined: it has rows */
    GCP_UNDEF_NOT_ASKED = 1,     /* [diagnostics] did not ask for it */
    GCP_UNDEF_NO_MIRROR = 2,     /* p_par never changed sign (passing orbit, uniform field) */
    GCP_UNDEF_NO_BOUNCE = 3,     /* mirror points, but not three in a row (push too short or
                                    stopped early) */
    GCP_UNDEF_NO_EQUATOR = 4,    /* no minimum of |B| between two mirror points (equatorially
                                    mirroring or no bounce): mu, energy, pphi are in
                                    /invariants/samples */
    GCP_UNDEF_NO_TURN = 5,       /* the guiding centre's azimuth did not turn by 2 pi */
    GCP_UNDEF_NO_POTENTIAL = 6,  /* the field gives no vector potential (igrf): Phi, L* NaN */
    GCP_UNDEF_COUNT = 7
};
/* Value slots of an undefined event: one reason per quantity. */
enum gcp_undefined_slot {
    GCP_UNDEF_BOUNCE = 0,  /* bounce period, J, K */
    GCP_UNDEF_EQUATOR = 1, /* mu, energy, pphi at equator points */
    GCP_UNDEF_DRIFT = 2,   /* drift period */
    GCP_UNDEF_LSTAR = 3    /* L*, Phi */
};
/* The name of a reason ("NO_MIRROR", ...). */
const char *gcp_undefined_name(int why);

/* Value slots of a bounce event. */
enum gcp_bounce_slot {
    GCP_BOUNCE_PERIOD = 0, /* [s] time between the two mirror points of the same kind */
    GCP_BOUNCE_J = 1,      /* [kg m^2/s] oint p_par ds */
    GCP_BOUNCE_K = 2,      /* [T^1/2 m] J / (2 sqrt(2 m mu)) */
    GCP_BOUNCE_LAT = 3,    /* [rad] latitudes of the two mirror points met during the bounce */
    GCP_BOUNCE_BM = 5,     /* [T] |B| at those mirror points */
    GCP_BOUNCE_X = 7,      /* [m] their positions (2 x 3) */
    GCP_BOUNCE_MU = 13     /* [J/T] mu averaged over the bounce */
};
#define GCP_EVENT_NV 14

struct gcp_event {
    int64_t id;     /* particle id */
    int32_t kind;   /* enum gcp_event_kind */
    int32_t status; /* loss: enum gcp_status; else 0 */
    double t;       /* [s] time of the event (end of a bounce / drift orbit) */
    double v[GCP_EVENT_NV];
};

/* An event of one value (kinds GCP_EVENT_MU, ENERGY, PPHI: gcp_event_scalar):
 * its v[0]; the rest of a struct gcp_event of these kinds is zero. */
struct gcp_scalar_event {
    int64_t id;
    int32_t kind, status;
    double t, v;
};

/* Whether events of this kind are kept as struct gcp_scalar_event. */
static inline int gcp_event_scalar(int32_t kind)
{
    return kind == GCP_EVENT_MU || kind == GCP_EVENT_ENERGY || kind == GCP_EVENT_PPHI;
}

/* A growable event list: e[0 .. n) the events of every kind but the
 * scalar ones, s[0 .. ns) those (32 bytes each instead of 136: two of three
 * rows of a run that asks for mu, whose storage -- the kernel's zeroing
 * of fresh pages -- was a third of what the observer cost; issue 12).
 * Either array on its own is in push order, or sorted (gcp_events_sort). */
struct gcp_events {
    int64_t n, cap;
    struct gcp_event *e;
    int64_t ns, scap;
    struct gcp_scalar_event *s;
};

/* Appends e (to s where its kind is scalar); 0 or GCP_ERR_NOMEM. */
int gcp_events_push(struct gcp_events *ev, const struct gcp_event *e);
/* The k-th event of the list as a struct gcp_event: e[k] for k < n, then
 * s[k - n] (k < n + ns). */
struct gcp_event gcp_events_get(const struct gcp_events *ev, int64_t k);
void gcp_events_free(struct gcp_events *ev);
/* Sorts each array by (id, kind, t) and drops exact repeats of (id, kind,
 * t) (a particle pushed twice, e.g. once per checkpoint file, gives
 * identical events). */
int gcp_events_sort(struct gcp_events *ev);

struct gcp_observer_opts {
    unsigned invariants; /* GCP_INV_* */
    unsigned events;     /* GCP_EVT_* */
    double B0;           /* [T] reference dipole field at R_E for L* (0: GCP_EARTH_B0) */
    /* [s] cadence of GCP_EVENT_SAMPLE rows (0: none).  mu, energy and p_phi
     * are otherwise recorded only at equator points, between two mirror
     * points, so a particle that never mirrors (a passing orbit, a uniform
     * field, a full orbit at pitch 90 deg on the equator) would have none:
     * a particle with no equator point in its whole push gets them at
     * t0 + k sample_dt (k = 1, 2, ...; linear interpolation of the
     * guiding-centre stream), and one with an equator point gets no sample
     * row at all (its equator rows are unchanged): each particle has the
     * one kind of row or the other.
     * The same cadence feeds the stream's drift contour (the guiding
     * centre at t0 + k sample_dt; none if 0): its turns
     * are drift events (contour GCP_CONTOUR_STREAM) for a particle whose
     * equator points made none.  The driver sets [diagnostics]
     * sample_every (default GCP_OBSERVER_SAMPLE_STEPS) times the
     * population's dt. */
    double sample_dt;
};
#define GCP_OBSERVER_SAMPLE_STEPS 64

struct gcp_observer;

/* An observer for blocks of up to nlanes lanes pushed with p in f.
 * Returns 0, or GCP_ERR_NOMEM. */
int gcp_observer_create(struct gcp_observer **out, size_t nlanes, const struct gcp_field *f,
                        const struct gcp_pusher_type *p, const struct gcp_observer_opts *opts);
void gcp_observer_free(struct gcp_observer *o);

/* Starts observing block b (its lanes filled, gcp_block_start done) at t0;
 * lane i is particle id0 + b->index[i] with charge b->q, mass b->m; events
 * go to out (b->index[i] < nlanes).  Per-lane state
 * is kept by b->index (stable under the stepper's lane swaps). */
void gcp_observer_begin(struct gcp_observer *o, const struct gcp_block *b, double t0,
                        int64_t id0, struct gcp_events *out);
/* The sampler function (ctx = the observer): call after every step.  For
 * method = hybrid it only notes the lanes that stopped: the samples come
 * through gcp_observer_sample_mode. */
void gcp_observer_sample(const struct gcp_block *b, double t, void *ctx);
/* Full orbit (not hybrid): the observer's gyro-average state for a
 * gcp_sampler's .gyro (every = 1, ctx = the observer, fn =
 * gcp_observer_sample, or a sampler that calls it): a fused full-orbit
 * step then does the per-step work of several steps in its tile loop and
 * the sampler is called after them (the same events, bit for bit).  NULL
 * where the observer has no use for it. */
struct gcp_fo_gyro *gcp_observer_fo_gyro(struct gcp_observer *o);
/* method = hybrid (an observer created with gcp_pusher_hybrid): the live
 * lanes of b after a step of the given mode (enum gcp_hybrid_mode): GC
 * lanes hold X, p_par, mu and go into the stream as they are, FO lanes hold
 * x, u and go through the gyro-average as for a full-orbit method; a lane
 * whose mode changed drops its unfinished gyration.  b->index[i] is the
 * lane's stable index as in gcp_observer_begin. */
void gcp_observer_sample_mode(const struct gcp_block *b, double t, int mode, void *ctx);
/* Sets opts.sample_dt for the next gcp_observer_begin (populations differ
 * in dt; 0: no cadence). */
void gcp_observer_set_sample_dt(struct gcp_observer *o, double sample_dt);
/* After the push: loss events for lanes that stopped and were not seen
 * (e.g. at the start); drops the sample rows of lanes that had an equator
 * point and the stream-contour drift rows of lanes with an equator-contour
 * one; one GCP_EVENT_UNDEFINED row per lane with an asked quantity
 * missing.  Returns 0, or GCP_ERR_NOMEM if an event was lost. */
int gcp_observer_end(struct gcp_observer *o, const struct gcp_block *b);

/* Equatorial pitch-angle classification at the start, dipole fields:
 * from the first-order guiding centre of (x, u) (or X, p_par, mu for GC
 * with u = NULL, x = X), L = r / (R_E cos^2 lat), the equatorial pitch
 * angle sin^2 a_eq = sin^2 a B_eq / B(X) (mu conserved along the line), and
 * the loss cone a_lc at L for an atmosphere at r_atm = R_E + h:
 *   sin^2 a_lc = B_eq / B_foot,  B_eq = B0 / L^3,
 *   B_foot = B0 (R_E / r_atm)^3 sqrt(1 + 3 sin^2 l_f),  cos^2 l_f = r_atm / (L R_E)
 * (the foot of the field line r = L R_E cos^2 l at r_atm).  L = 4, h = 100 km:
 * a_lc = 5.47 deg.  Returns 0, or GCP_ERR_STATE (results NaN) off a dipole. */
int gcp_dipole_classify(const struct gcp_field *f, double q, double m, const double x[3],
                        const double u[3], double ppar, double mu, double *L, double *alpha_eq,
                        double *alpha_lc);
/* The dipole loss cone alone [rad]: L [1], r_atm [m]. */
double gcp_dipole_loss_cone(double L, double r_atm);
/* The reference B0 [T] for L* in field f: |B(R_E, 0, 0)| for a dipole
 * model, GCP_EARTH_B0 otherwise. */
double gcp_observer_reference_B0(const struct gcp_field *f);

/* The period of `which` for a particle of species sp with state (x, u) in
 * field f: gyro 2 pi gamma m / (|q| B) anywhere; bounce and drift from
 * guiding-centre theory in fields with centred-dipole coordinates
 * (GCP_CAP_DIPOLE_L; `model` is not used).  Returns 0 or GCP_ERR_STATE when
 * the field has no such period.  (src/diag/periods.c) */
int gcp_period_of(const struct gcp_field *f, const char *model, const struct gcp_species *sp,
                  const double x[3], const double u[3], enum gcp_period which, double *period);

#ifdef __cplusplus
}
#endif
GCP_API_END
#endif /* GCPUSH_INVARIANTS_H */
