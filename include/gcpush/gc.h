/* gcpush/gc.h -- guiding-centre (GC) pushers and helpers (issue 3).
 *
 * GC state: X [m] (guiding-centre position), p_par [kg m/s] (momentum along
 * b = B/|B|), mu = p_perp^2 / (2 m |B(X)|) [J/T] (relativistic magnetic
 * moment, constant).  Equations: kernels.h, gcp_gc_rhs (Cary & Brizard 2009).
 *
 * Pushers (kind GCP_GUIDING_CENTRE, registered in gcp_pusher_types()):
 *   gc-rk4    classical RK4, fixed step dt
 *   gc-rk45   GSL odeiv2 rkf45, adaptive, tolerance opts->tolerance (default 1e-9)
 *   gc-rk8pd  GSL odeiv2 rk8pd, adaptive (default tolerance 1e-12: the reference)
 *   gc-gl2    symplectic implicit midpoint (Gauss-Legendre, order 2) in the
 *             canonical chart of an axisymmetric field, exact p_phi (gc_gauss.c)
 *   gc-gl4    symplectic 2-stage Gauss-Legendre (order 4), the same (gc_gauss.c)
 *   gc-gl2-sundman, gc-gl4-sundman  the same with symplectic adaptive steps:
 *             fixed step in s of the Sundman-transformed extended Hamiltonian,
 *             dt = (B_start/|B|) ds, dt of the options = ds (gc_sundman.c);
 *             lanes land exactly on sampling times and t0 + nsteps dt
 *   gc-midpoint-pphi  symmetric midpoint scheme with exact p_phi, order 2, not
 *             symplectic (formerly gc-vi; src/pushers/gc_midpoint_pphi.c)
 * gc-gl2/gl4 run in fields with a canonical chart (canon_priv.h: today the
 * curl-free dipole and mirror), gc-midpoint-pphi in fields with an analytic
 * vector potential; gcp_pusher_type.applies says which, and why not.
 * All take struct gcp_push_opts; the block's x, y, z hold X, ppar and mu the
 * GC state; ux, uy, uz are untouched.  A lane stops with
 *   NONFINITE      non-finite X or p_par (also at the start),
 *   NONADIABATIC   opts->adiabaticity_max > 0 and gcp_gc_adiabaticity() above
 *                  it (checked at the start of every step), or B*_par <= 0,
 *   STEP_FAILED    dt <= 0 or non-finite; adaptive step size under round-off;
 *                  a Newton failure of gc-gl2, gc-gl4, gc-midpoint-pphi (the
 *                  step is never shortened); a field the method does not
 *                  apply to (library callers; the scene refuses such runs):
 *                  the state is the last good one,
 *   the field's own statuses (LEFT_DOMAIN, PRECIPITATED, LEFT_GRID).
 * Fixed-step methods take nsteps steps of dt; adaptive methods integrate each
 * lane to t0 + nsteps dt with their own steps (steps = accepted steps); with
 * a sampler they land on every t0 + k every dt, where the sampler is called.
 */
#ifndef GCPUSH_GC_H
#define GCPUSH_GC_H

#include <stdint.h>

#include "field.h"
#include "pusher.h"
#include "api.h"
GCP_API_BEGIN

#ifdef __cplusplus
extern "C" {
#endif

extern const struct gcp_pusher_type gcp_pusher_gc_rk4;
extern const struct gcp_pusher_type gcp_pusher_gc_rk45;
extern const struct gcp_pusher_type gcp_pusher_gc_rk8pd;
extern const struct gcp_pusher_type gcp_pusher_gc_midpoint_pphi;
extern const struct gcp_pusher_type gcp_pusher_gc_gl2;
extern const struct gcp_pusher_type gcp_pusher_gc_gl4;
extern const struct gcp_pusher_type gcp_pusher_gc_gl2_sundman;
extern const struct gcp_pusher_type gcp_pusher_gc_gl4_sundman;

/* Default tolerances of the adaptive methods when opts->tolerance == 0. */
#define GCP_GC_RK45_TOL 1e-9
#define GCP_GC_RK8PD_TOL 1e-12

/* Full orbit -> guiding centre, first-order guiding-centre transformation
 * (Northrop 1963; Cary & Brizard 2009 sec. IV):
 *   p = m u (u = gamma v),  rho = b(x) x p / (q |B(x)|)   (signed q),
 *   X = x - rho,
 *   p_par = p.b(X),  mu = (p^2 - p_par^2) / (2 m |B(X)|).
 * X is first order: error O(eps rho), eps = rho/L_B.  p_par and mu are the
 * zeroth-order (lowest-order) values at X: relative error O(eps), oscillating
 * with the gyrophase (the first-order mu correction is not applied).  The
 * energy is kept exactly: gamma(p_par, mu, |B(X)|) equals the full-orbit gamma.
 * Returns 0 or the field's status at x or X (enum gcp_status). */
int gcp_gc_from_fo(const struct gcp_field *f, double t, double q, double m, const double x[3],
                   const double u[3], double X[3], double *ppar, double *mu);

/* Guiding centre -> full orbit, the exact inverse of gcp_gc_from_fo:
 * p = p_par b(X) + p_perp (cos(phase) e1 + sin(phase) e2), p_perp =
 * sqrt(2 m mu |B(X)|), e1 = unit(b x zhat) (b x xhat when |b_z| > 0.9),
 * e2 = b x e1; then x solves x - b(x) x p / (q |B(x)|) = X (fixed-point
 * iteration, converging like eps), u = p/m.  gcp_gc_from_fo(x, u) then gives
 * back X, p_par, mu to round-off.  Returns 0, the field's status, or
 * GCP_STEP_FAILED if the iteration does not converge. */
int gcp_fo_from_gc(const struct gcp_field *f, double t, double q, double m, const double X[3],
                   double ppar, double mu, double phase, double x[3], double u[3]);

/* GC validity measure at a GC state: eps = max(rho_perp |grad B| / B,
 * rho |kappa|), rho_perp = p_perp/|qB|, rho = p/|qB| (largest gyroradius at
 * that energy), kappa = (b.grad) b (field-line curvature; rho |kappa| =
 * rho/R_c = 1/kappa_BZ^2 of Buechner & Zelenyi 1989).  Returns 0 or the
 * field's status; *eps = +inf where B*_par <= 0 or |B| = 0. */
int gcp_gc_adiabaticity(const struct gcp_field *f, double t, double q, double m,
                        const double X[3], double ppar, double mu, double *eps);

/* Right-hand side at one GC state (field evaluation + gcp_gc_rhs). */
int gcp_gc_rhs_at(const struct gcp_field *f, double t, double q, double m, const double X[3],
                  double ppar, double mu, double dXdt[3], double *dppar);

/* 1 when the field's electric potential is known wherever it has an E
 * (the analytic models; any field without E), 0 otherwise (a grid, an
 * EQDSK or a callback field with E): then gcp_gc_energy cannot give
 * H = gamma m c^2 + q phi. */
int gcp_gc_has_potential(const struct gcp_field *f);

/* Energy H = gamma m c^2 + q phi [J] (phi from gcp_gc_potential; none
 * needed where the field has no E).  Returns 0 or the field's status;
 * GCP_ERR_UNKNOWN with *H = NaN where the field has E but no potential
 * (gcp_gc_has_potential): never a silent phi = 0. */
int gcp_gc_energy(const struct gcp_field *f, double t, double q, double m, const double X[3],
                  double ppar, double mu, double *H);

/* Canonical toroidal momentum p_phi = q R A_phi + p_par R b_phi [kg m^2/s]
 * (= q psi + p_par R b_phi), conserved in axisymmetric fields. */
int gcp_gc_pphi(const struct gcp_field *f, double t, double q, const double X[3], double ppar,
                double *pphi);

/* Vector potential of the built-in analytic fields (dipole, mirror,
 * tokamak, uniform), until gcp_field_type grows a `potential` member:
 * A [T m], dA[i][j] = dA_i/dx_j [T], electrostatic potential phi [V]
 * (E = -grad phi; any of dA, phi may be NULL).  Returns 0, or
 * GCP_ERR_UNKNOWN for a field without one (grid, callback). */
int gcp_gc_potential(const struct gcp_field *f, double t, const double x[3], double A[3],
                     double dA[3][3], double *phi);

/* Single-particle convenience, like gcp_orbit_push: pushes one GC particle
 * from *t with pusher p (kind GCP_GUIDING_CENTRE) under opts (o->t0 is
 * ignored: the push starts at *t), updating t, X, p_par in place.  cb (may
 * be NULL) is called after every step (adaptive methods: every dt) and stops
 * the push by returning non-zero.  Returns the final status. */
typedef int (*gcp_gc_step_cb)(double t, const double X[3], double ppar, void *ctx);
int gcp_gc_push(const struct gcp_field *f, const struct gcp_pusher_type *p, double q, double m,
                const struct gcp_push_opts *o, double *t, double X[3], double *ppar, double mu,
                gcp_gc_step_cb cb, void *ctx);

#ifdef __cplusplus
}
#endif
GCP_API_END
#endif /* GCPUSH_GC_H */
