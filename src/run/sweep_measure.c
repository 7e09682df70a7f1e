/* The error measures of a sweep row (include/gcpush/sweep.h): the final
 * states of a run against the reference's, per particle, kept as the
 * largest over the population.
 *
 * Gyrophase error.  Uniform fields, analytic reference, full-orbit method:
 * the accumulated rotation (sweep.c measures it during the push).  Against
 * a full-orbit reference run: the angle from the reference's u_perp to the
 * method's about the local b at the reference's end point, in (-pi, pi].
 * Where a guiding-centre method is involved: not defined (NaN).
 *
 * Invariants (fields with a mirror geometry, GCP_CAP_AXISYM: bounce; a
 * centred dipole, GCP_CAP_DIPOLE_L: bounce and drift; elsewhere NaN): per
 * particle, the mean measured bounce and drift periods and the relative
 * drift rates |last - first| / |first| / (t_last - t_first) of the
 * per-bounce mu and K and the per-drift-orbit L* (NaN with fewer than two
 * events).  Phase errors are 2 pi T |1/P - 1/P_ref| with the mean periods
 * P of the run and the reference; everything is the largest over the
 * particles compared. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/gc.h"
#include "gcpush/kernels.h"
#include "gcpush/run.h"
#include "sweep_priv.h"

#define C GCP_C_LIGHT

static double dot(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static double kinetic(const double u[3], double m)
{
    return m * dot(u, u) / (gcp_gamma_of_u(u[0], u[1], u[2]) + 1.0);
}

/* H - m c^2 = W + q phi of a full-orbit state (phi only in fields with E);
 * NaN where the potential is not known. */
static double fo_energy(const struct gcp_field *f, double q, double m, const double x[3],
                        const double u[3])
{
    double W = kinetic(u, m);
    if (!f->has_E) return W;
    if (!gcp_gc_has_potential(f)) return NAN; /* E without phi: unknown, not phi = 0 */
    double A[3], phi;
    if (gcp_gc_potential(f, 0.0, x, A, NULL, &phi)) return NAN;
    return W + q * phi;
}

static double gc_energy(const struct gcp_field *f, double t, double q, double m, const double X[3],
                        double ppar, double mu)
{
    double H;
    if (gcp_gc_energy(f, t, q, m, X, ppar, mu, &H)) return NAN; /* gamma m c^2 + q phi */
    return H - m * C * C;
}

/* Guiding-centre position of a final state. */
static int gc_position(const struct gcp_field *f, double t, const struct gcp_species *sp,
                       const struct gcp_sweep_finals *fi, size_t j, double X[3])
{
    if (fi->gc) {
        memcpy(X, &fi->x[3 * j], 3 * sizeof(double));
        return 0;
    }
    double ppar, mu;
    return gcp_gc_from_fo(f, t, sp->charge, sp->mass, &fi->x[3 * j], &fi->u[3 * j], X, &ppar, &mu);
}

/* ---- invariant measures (src/diag/invariants.c) ------------------------- */

/* Bounce events where a field line can hold a mirrored particle
 * (axisymmetric models: dipole, mirror, tokamak, axisymmetric grids and
 * G-EQDSK equilibria); drift events (L*) where the field has centred-dipole
 * coordinates; none elsewhere (uniform fields, IGRF, Cartesian grids). */
unsigned gcp_sweep_events(const struct gcp_field *f)
{
    const unsigned caps = gcp_field_caps(f);
    if (caps & GCP_CAP_DIPOLE_L) return GCP_EVT_BOUNCE | GCP_EVT_DRIFT;
    if (caps & GCP_CAP_AXISYM) return GCP_EVT_BOUNCE;
    return 0;
}

/* |last - first| / |first| / (t_last - t_first); NaN for fewer than 2 values. */
static double rel_rate(int64_t n, double first, double last, double t0, double t1)
{
    if (n < 2 || !(t1 > t0) || first == 0.0) return NAN;
    return fabs(last - first) / fabs(first) / (t1 - t0);
}

int gcp_sweep_inv_stats(const struct gcp_events *ev, int64_t id0, size_t n,
                        struct gcp_sweep_inv *out)
{
    /* per particle: counts, sums, first and last values (a lane's events of
     * one kind come in time order) */
    for (size_t j = 0; j < n; j++) out[j] = (struct gcp_sweep_inv){NAN, NAN, NAN, NAN, NAN};
    int64_t *nb = calloc(n, sizeof *nb), *nd = calloc(n, sizeof *nd);
    double *acc = calloc(n * 12, sizeof *acc);
    if (!nb || !nd || !acc) {
        free(nb), free(nd), free(acc);
        return GCP_ERR_NOMEM;
    }
    for (int64_t k = 0; k < ev->n; k++) {
        const struct gcp_event *e = &ev->e[k];
        if (e->id < id0 || e->id - id0 >= (int64_t)n) continue;
        const size_t j = (size_t)(e->id - id0);
        double *a = &acc[12 * j]; /* sumTb K0 K1 mu0 mu1 tb0 tb1 | sumTd L0 L1 td0 td1 */
        if (e->kind == GCP_EVENT_BOUNCE) {
            if (nb[j]++ == 0) a[1] = e->v[GCP_BOUNCE_K], a[3] = e->v[GCP_BOUNCE_MU], a[5] = e->t;
            a[0] += e->v[GCP_BOUNCE_PERIOD];
            a[2] = e->v[GCP_BOUNCE_K], a[4] = e->v[GCP_BOUNCE_MU], a[6] = e->t;
        } else if (e->kind == GCP_EVENT_DRIFT) {
            if (nd[j]++ == 0) a[8] = e->v[1], a[10] = e->t;
            a[7] += e->v[0];
            a[9] = e->v[1], a[11] = e->t;
        }
    }
    for (size_t j = 0; j < n; j++) {
        const double *a = &acc[12 * j];
        struct gcp_sweep_inv *s = &out[j];
        if (nb[j]) s->Tb = a[0] / (double)nb[j];
        if (nd[j]) s->Td = a[7] / (double)nd[j];
        s->K_rate = rel_rate(nb[j], a[1], a[2], a[5], a[6]);
        s->mu_rate = rel_rate(nb[j], a[3], a[4], a[5], a[6]);
        s->L_rate = rel_rate(nd[j], a[8], a[9], a[10], a[11]);
    }
    free(nb), free(nd), free(acc);
    return 0;
}

/* Bounce and drift phase error at the end, 2 pi T |1/P - 1/P_ref| with the
 * mean measured periods P of the run and the reference; NaN where either
 * is not measured. */
static double phase_error(double T, double P, double Pref)
{
    if (!(P > 0) || !(Pref > 0)) return NAN;
    return 2.0 * GCP_PI * T * fabs(1.0 / P - 1.0 / Pref);
}

/* The per-row maximum over the particles.  An accumulator starts at
 * -INFINITY ("nothing measured yet", turned into NaN by compare at the
 * end) and keeps the value of largest magnitude, with its sign.  A NaN is
 * the worst error, not none (issue 13): a particle whose error cannot be
 * computed (a non-finite state, a measure it lacks) makes the row's
 * maximum unknown, NaN, and no later value replaces it. */
static void keep_max(double *acc, double v)
{
    if (isnan(*acc)) return;
    if (isnan(v) || *acc == -INFINITY || fabs(v) > fabs(*acc)) *acc = v;
}

static void finish_max(double *acc)
{
    if (*acc == -INFINITY) *acc = NAN;
}

void gcp_sweep_compare(const struct gcp_scene *sc, const struct gcp_population *pop,
                       const struct gcp_sweep_states *st, const struct gcp_sweep_finals *run,
                       const struct gcp_sweep_finals *ref, const double *ref_phase,
                       const double *run_phase, int phase_wrapped,
                       const struct gcp_sweep_inv *run_inv, const struct gcp_sweep_inv *ref_inv,
                       struct gcp_sweep_row *row)
{
    const struct gcp_species *sp = &pop->species;
    const struct gcp_field *f = sc->field;
    const double T = sc->duration;
    const int gcmode = run->gc || ref->gc;
    double *const acc[] = {&row->position_error, &row->position_error_gyroradius,
                           &row->position_error_path, &row->gc_position_error,
                           &row->gyrophase_error, &row->energy_error,
                           &row->bounce_phase_error, &row->drift_phase_error,
                           &row->mu_drift, &row->K_drift, &row->Lstar_drift};
    const size_t nacc = sizeof acc / sizeof acc[0];
    for (size_t k = 0; k < nacc; k++) *acc[k] = -INFINITY;
    row->failed = 0;
    for (size_t j = 0; j < st->n; j++) {
        if (run->status[j] != GCP_ALIVE || ref->status[j] != GCP_ALIVE) {
            row->failed++;
            /* Both ended the same way (e.g. both precipitated), or one is
             * a guiding centre outside its model's validity (NONADIABATIC:
             * not a numerical error): nothing to compare.  Otherwise the
             * method lost (or kept) a particle the reference did not, or
             * went non-finite: its error is unbounded, the row's is NaN. */
            const int32_t a = run->status[j], r = ref->status[j];
            if (a != r && a != GCP_NONADIABATIC && r != GCP_NONADIABATIC)
                for (size_t k = 0; k < 4; k++) keep_max(acc[k], NAN);
            continue;
        }
        const double *x0 = &st->x0[3 * j], *u0 = &st->u0[3 * j];
        double a[3], b[3];
        if (gcmode) {
            if (gc_position(f, T, sp, run, j, a) || gc_position(f, T, sp, ref, j, b)) {
                row->failed++;
                continue;
            }
        } else {
            memcpy(a, &run->x[3 * j], sizeof a);
            memcpy(b, &ref->x[3 * j], sizeof b);
        }
        const double d[3] = {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
        const double err = sqrt(dot(d, d));
        double Xa[3], Xb[3];
        if (gcmode) {
            keep_max(&row->gc_position_error, err);
        } else if (!gc_position(f, T, sp, run, j, Xa) && !gc_position(f, T, sp, ref, j, Xb)) {
            const double D[3] = {Xa[0] - Xb[0], Xa[1] - Xb[1], Xa[2] - Xb[2]};
            keep_max(&row->gc_position_error, sqrt(dot(D, D)));
        }
        /* initial gyroradius p_perp / (|q| B) and path |v0| T */
        struct gcp_field_sample smp = {.need = GCP_NEED_B};
        gcp_field_eval(f, 0.0, x0, &smp);
        const double Bm = sqrt(dot(smp.B, smp.B));
        const double upar = Bm > 0 ? dot(u0, smp.B) / Bm : 0.0;
        const double uperp = sqrt(fmax(dot(u0, u0) - upar * upar, 0.0));
        const double rho = sp->mass * uperp / (fabs(sp->charge) * Bm);
        const double v0 = sqrt(dot(u0, u0)) / gcp_gamma_of_u(u0[0], u0[1], u0[2]);
        const double *ure = &ref->u[3 * j];
        const double vre = ref->gc ? 0.0 : sqrt(dot(ure, ure)) / gcp_gamma_of_u(ure[0], ure[1], ure[2]);
        const double path = fmax(v0, vre) * T;
        keep_max(&row->position_error, err);
        keep_max(&row->position_error_gyroradius, rho > 0 ? err / rho : NAN);
        keep_max(&row->position_error_path, path > 0 ? err / path : NAN);
        /* energy */
        double e = NAN;
        const double W0 = kinetic(u0, sp->mass);
        if (!f->time_dependent) {
            double H0, H1;
            if (run->gc) {
                H0 = gc_energy(f, 0.0, sp->charge, sp->mass, &st->X0[3 * j], st->ppar0[j],
                               st->mu0[j]);
                H1 = gc_energy(f, T, sp->charge, sp->mass, &run->x[3 * j], run->u[3 * j],
                               st->mu0[j]);
            } else {
                H0 = fo_energy(f, sp->charge, sp->mass, x0, u0);
                H1 = fo_energy(f, sp->charge, sp->mass, &run->x[3 * j], &run->u[3 * j]);
            }
            double Wmax = W0;
            if (!run->gc) Wmax = fmax(Wmax, kinetic(&run->u[3 * j], sp->mass));
            if (!ref->gc) Wmax = fmax(Wmax, kinetic(&ref->u[3 * j], sp->mass));
            e = fabs(H1 - H0) / Wmax;
        } else if (!run->gc && !ref->gc) {
            const double Wr = kinetic(&ref->u[3 * j], sp->mass);
            e = fabs(kinetic(&run->u[3 * j], sp->mass) - Wr) / Wr;
        }
        keep_max(&row->energy_error, e);
        /* gyrophase */
        double ph = NAN;
        if (ref_phase && run_phase) {
            ph = run_phase[j] - ref_phase[j];
            if (phase_wrapped) ph = remainder(ph, 2.0 * GCP_PI);
        } else if (!gcmode) {
            smp.need = GCP_NEED_B;
            if (gcp_field_eval(f, T, &ref->x[3 * j], &smp) == 0) {
                const double Bn = sqrt(dot(smp.B, smp.B));
                if (Bn > 0) {
                    const double bb[3] = {smp.B[0] / Bn, smp.B[1] / Bn, smp.B[2] / Bn};
                    double pr[3], pm[3];
                    const double *ur = &ref->u[3 * j], *um = &run->u[3 * j];
                    const double kr = dot(ur, bb), km = dot(um, bb);
                    for (int i = 0; i < 3; i++) pr[i] = ur[i] - kr * bb[i], pm[i] = um[i] - km * bb[i];
                    const double cr[3] = {pr[1] * pm[2] - pr[2] * pm[1], pr[2] * pm[0] - pr[0] * pm[2],
                                          pr[0] * pm[1] - pr[1] * pm[0]};
                    ph = atan2(dot(cr, bb), dot(pr, pm));
                }
            }
        }
        keep_max(&row->gyrophase_error, ph);
        /* invariants: drift rates of the run, periods against the reference's */
        if (run_inv) {
            const struct gcp_sweep_inv *ri = &run_inv[j];
            keep_max(&row->mu_drift, ri->mu_rate);
            keep_max(&row->K_drift, ri->K_rate);
            keep_max(&row->Lstar_drift, ri->L_rate);
            if (ref_inv) {
                keep_max(&row->bounce_phase_error, phase_error(T, ri->Tb, ref_inv[j].Tb));
                keep_max(&row->drift_phase_error, phase_error(T, ri->Td, ref_inv[j].Td));
            }
        }
    }
    for (size_t k = 0; k < nacc; k++) finish_max(acc[k]);
}
