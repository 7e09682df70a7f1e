/* gcpush/kernels.h -- header-only relativistic particle-push kernels.
 *
 * For PIC codes and for gcpush itself: one implementation.  Plain doubles,
 * SI units, u = gamma v [m/s] (the non-relativistic gcp_push_boris_nr: u = v;
 * its position update is x += u h, no gamma).  Each kernel is the momentum update ("kick")
 * over one time step dt [s] with the fields E [V/m], B [T] gathered at the
 * particle's position at mid-step; the position update is the caller's,
 * as in PIC codes (gcpush uses the synchronised drift-kick-drift form:
 * x += v dt/2, kick, x += v' dt/2).
 *
 * No allocation, no globals, no errno (only sqrt, sin, cos, fmax, which set no
 * errno for finite arguments under C99 Annex F).  Compiles as C99, C11, C++17
 * and CUDA (GCP_HD expands to __host__ __device__ there).
 *
 * Embedding: include this header and nothing else (pkg-config --cflags gcpush);
 * no library to link but -lm.  An embedding code need not set any flag:
 * every sqrt argument here is >= 1, a sum of squares, or the positive root
 * of gcp_gamma_root_ (a quotient of positive numbers), and sin/cos get
 * finite arguments, so errno is never written whatever -f[no-]math-errno
 * says.  A non-negative argument does not make a sqrt accurate: each root
 * is written so that it never subtracts nearly equal numbers (issue 13:
 * gamma up to 1e9, omega_c dt up to 1e6, tests/unit/test_kernels_extreme.c).  The one thing -fno-math-errno changes is speed: GCC vectorises a
 * loop calling sqrt only under it (results are identical).  Do not build
 * with -ffast-math or -ffp-contract=fast if you want the batch and AoS forms
 * bit-identical to the scalar kernels across compilers and call sites
 * (ISO -std=c99/c11 keeps GCC at -ffp-contract=off).
 */
#ifndef GCPUSH_KERNELS_H
#define GCPUSH_KERNELS_H

#include <math.h>
#include <float.h>
#include <stddef.h>

#if defined(__CUDACC__)
#define GCP_HD __host__ __device__
#else
#define GCP_HD
#endif

#if defined(__cplusplus)
#define GCP_RESTRICT __restrict__
#else
#define GCP_RESTRICT restrict
#endif

#define GCP_C_LIGHT 299792458.0              /* speed of light [m/s] (exact, SI 2019) */
#define GCP_INV_C2 (1.0 / (GCP_C_LIGHT * GCP_C_LIGHT))

/* Lorentz factor gamma = sqrt(1 + |u|^2/c^2) of u = gamma v [m/s]. */
static inline GCP_HD double gcp_gamma_of_u(double ux, double uy, double uz)
{
    return sqrt(1.0 + (ux * ux + uy * uy + uz * uz) * GCP_INV_C2);
}

/* The magnetic rotation of Boris's scheme, u- -> u+ in place (qdt2m =
 * q dt / 2m): t = qdt2m B / gamma(u-), s = 2 / (1 + t^2),
 * u' = u- + u- x t, u+ = u- + s (u' x t); inv_gamma = 1/gamma(u-) given (a
 * caller that has gamma(u-) already, as the fused step of a pure magnetic
 * field does from the previous step's drift, saves a sqrt).  In two
 * parts: t and s (from B and gamma alone), then the rotation by them; a
 * caller that computes t and s in one loop and rotates in another (the
 * fused tiles, fo_fused_priv.h: two short dependency chains instead of one
 * long one) gets the same bits as gcp_boris_rotate_ig_. */
static inline GCP_HD void gcp_boris_ts_(double Bx, double By, double Bz, double qdt2m,
                                        double inv_gamma, double *tx, double *ty, double *tz,
                                        double *s)
{
    const double a = qdt2m * inv_gamma;
    const double x = a * Bx, y = a * By, z = a * Bz;
    *tx = x, *ty = y, *tz = z;
    *s = 2.0 / (1.0 + x * x + y * y + z * z);
}

static inline GCP_HD void gcp_boris_rotate_ts_(double *ux, double *uy, double *uz, double tx,
                                               double ty, double tz, double s)
{
    const double umx = *ux, umy = *uy, umz = *uz;
    const double upx = umx + (umy * tz - umz * ty);
    const double upy = umy + (umz * tx - umx * tz);
    const double upz = umz + (umx * ty - umy * tx);
    *ux = umx + s * (upy * tz - upz * ty);
    *uy = umy + s * (upz * tx - upx * tz);
    *uz = umz + s * (upx * ty - upy * tx);
}

static inline GCP_HD void gcp_boris_rotate_ig_(double *ux, double *uy, double *uz, double Bx,
                                               double By, double Bz, double qdt2m,
                                               double inv_gamma)
{
    double tx, ty, tz, s;
    gcp_boris_ts_(Bx, By, Bz, qdt2m, inv_gamma, &tx, &ty, &tz, &s);
    gcp_boris_rotate_ts_(ux, uy, uz, tx, ty, tz, s);
}

/* The rotation with inv_gamma = 1/gamma(u-) computed by the caller (the
 * form above: gcp_boris_rotate_ig_ with the caller's 1/gamma). */
static inline GCP_HD void gcp_boris_rotate_(double *ux, double *uy, double *uz, double Bx,
                                            double By, double Bz, double qdt2m)
{
    gcp_boris_rotate_ig_(ux, uy, uz, Bx, By, Bz, qdt2m, 1.0 / gcp_gamma_of_u(*ux, *uy, *uz));
}

/* Relativistic Boris push (Boris 1970; Birdsall & Langdon, Plasma Physics via
 * Computer Simulation, sec. 15-4):
 *   u-  = u + (q dt / 2m) E
 *   t   = (q dt / 2 m gamma-) B,   s = 2 t / (1 + t^2)
 *   u'  = u- + u- x t,   u+ = u- + u' x s
 *   u   = u+ + (q dt / 2m) E
 * The rotation angle per step is 2 atan(omega_c dt / 2), not omega_c dt:
 * the gyrophase lags at large omega_c dt, |u| is kept exactly. */
static inline GCP_HD void gcp_push_boris(double *ux, double *uy, double *uz,
                                         double Ex, double Ey, double Ez,
                                         double Bx, double By, double Bz,
                                         double q, double m, double dt)
{
    const double qdt2m = 0.5 * q * dt / m;
    double vx = *ux + qdt2m * Ex, vy = *uy + qdt2m * Ey, vz = *uz + qdt2m * Ez;
    gcp_boris_rotate_(&vx, &vy, &vz, Bx, By, Bz, qdt2m);
    *ux = vx + qdt2m * Ex;
    *uy = vy + qdt2m * Ey;
    *uz = vz + qdt2m * Ez;
}

/* Non-relativistic Boris push (Boris 1970; Birdsall & Langdon, Plasma
 * Physics via Computer Simulation, secs. 4-3, 4-4), for codes whose
 * particles are slow (|v| << c: electrostatic and non-relativistic ion
 * codes).  Here u = v [m/s]: the Newtonian velocity, which is also p/m
 * with p = m v, so the arrays that hold u = gamma v for the relativistic
 * kernels hold v; there is no gamma anywhere (no sqrt, one division for s,
 * none at all where t and s are the same for every particle, as in a
 * uniform B).  With qdt2m = q dt / 2m:
 *   v-  = v + qdt2m E
 *   t   = qdt2m B,   s = 2 t / (1 + t^2)
 *   v'  = v- + v- x t,   v+ = v- + v' x s
 *   v   = v+ + qdt2m E
 * |v| is kept exactly in pure B (a rotation, by 2 atan(Omega dt / 2) per
 * step, Omega = |q B| / m: the gyrophase lags at large Omega dt); E x B is
 * drifted at exactly E x B / B^2 for any Omega dt.  Differs from the
 * relativistic gcp_push_boris by the gyrofrequency's factor gamma: use it
 * only where gamma - 1 is below the accuracy asked for. */
/* The cross products as explicit fused multiply-adds, a + b c - d e =
 * fma(b, c, fma(-d, e, a)), where the target has a fast fma (C99
 * FP_FAST_FMA: x86 with FMA3, AArch64, CUDA devices), else as separate
 * products and sums.  fma() is one correctly rounded IEEE operation, not a
 * contraction the compiler may or may not make, so the scalar, batch, AoS
 * and gcpush's fused forms stay bit-identical to one another in any one
 * build (-ffp-contract=off or not); builds with and without FMA differ in
 * the last bits.  It halves the kick's operations: 12 fused operations
 * where 12 products and 12 sums were (the push is bound by them).
 * GCP_NR_FMA_(a, b, c) = a b + c, the same choice (gcpush's position
 * update for boris-nr, x + (u0 + u1) dt/2, is GCP_NR_FMA_(u0 + u1, h, x)). */
#if defined(FP_FAST_FMA) || defined(__CUDA_ARCH__)
#define GCP_NR_FMA_(a, b, c) fma(a, b, c)
#define GCP_NR_CROSS_(a, b, c, d, e) fma(b, c, fma(-(d), e, a))
#else
#define GCP_NR_FMA_(a, b, c) ((a) * (b) + (c))
#define GCP_NR_CROSS_(a, b, c, d, e) ((a) + ((b) * (c) - (d) * (e)))
#endif

static inline GCP_HD void gcp_boris_nr_rotate_(double *ux, double *uy, double *uz, double Bx,
                                               double By, double Bz, double qdt2m)
{
    const double umx = *ux, umy = *uy, umz = *uz;
    const double tx = qdt2m * Bx, ty = qdt2m * By, tz = qdt2m * Bz;
    const double f = 2.0 / (1.0 + tx * tx + ty * ty + tz * tz);
    const double sx = f * tx, sy = f * ty, sz = f * tz;
    const double upx = GCP_NR_CROSS_(umx, umy, tz, umz, ty);
    const double upy = GCP_NR_CROSS_(umy, umz, tx, umx, tz);
    const double upz = GCP_NR_CROSS_(umz, umx, ty, umy, tx);
    *ux = GCP_NR_CROSS_(umx, upy, sz, upz, sy);
    *uy = GCP_NR_CROSS_(umy, upz, sx, upx, sz);
    *uz = GCP_NR_CROSS_(umz, upx, sy, upy, sx);
}

static inline GCP_HD void gcp_push_boris_nr(double *ux, double *uy, double *uz,
                                            double Ex, double Ey, double Ez,
                                            double Bx, double By, double Bz,
                                            double q, double m, double dt)
{
    const double qdt2m = 0.5 * q * dt / m;
    double vx = *ux + qdt2m * Ex, vy = *uy + qdt2m * Ey, vz = *uz + qdt2m * Ez;
    gcp_boris_nr_rotate_(&vx, &vy, &vz, Bx, By, Bz, qdt2m);
    *ux = vx + qdt2m * Ex;
    *uy = vy + qdt2m * Ey;
    *uz = vz + qdt2m * Ez;
}

/* Boris with the exact gyro-angle (Zenitani & Umeda 2018, Phys. Plasmas 25
 * 112110, eqs. 20-22): the magnetic rotation of u- is by
 *   theta = q |B| dt / (m gamma-)
 * exactly, written with cos/sin so it stays regular at theta = pi:
 *   u+ = (u-.b) b + [u- - (u-.b) b] cos(theta) + (u- x b) sin(theta).
 * In uniform B with E = 0 the gyrophase is exact for any omega_c dt.
 * Limitation: the electric half-kicks are Boris's, so the E x B (and grad-B,
 * curvature) drift is V (theta/2) cot(theta/2) = V (1 - theta^2/12 + ...):
 * 2% slow at omega_c dt = 0.5, and the force-free case is not kept.  Use
 * vay or higuera-cary where E matters at large omega_c dt. */
static inline GCP_HD void gcp_push_boris_zu(double *ux, double *uy, double *uz,
                                            double Ex, double Ey, double Ez,
                                            double Bx, double By, double Bz,
                                            double q, double m, double dt)
{
    const double qdt2m = 0.5 * q * dt / m;
    const double umx = *ux + qdt2m * Ex;
    const double umy = *uy + qdt2m * Ey;
    const double umz = *uz + qdt2m * Ez;
    const double inv_gamma = 1.0 / gcp_gamma_of_u(umx, umy, umz);
    const double Bmag = sqrt(Bx * Bx + By * By + Bz * Bz);
    /* B = 0 gives b = 0 and theta = 0: u+ = u-, without a branch. */
    const double inv_B = 1.0 / fmax(Bmag, DBL_MIN);
    const double bx = Bx * inv_B, by = By * inv_B, bz = Bz * inv_B;
    const double theta = 2.0 * qdt2m * inv_gamma * Bmag;
    const double c = cos(theta), s = sin(theta);
    const double upar = umx * bx + umy * by + umz * bz;
    *ux = upar * bx + (umx - upar * bx) * c + (umy * bz - umz * by) * s + qdt2m * Ex;
    *uy = upar * by + (umy - upar * by) * c + (umz * bx - umx * bz) * s + qdt2m * Ey;
    *uz = upar * bz + (umz - upar * bz) * c + (umx * by - umy * bx) * s + qdt2m * Ez;
}

/* The gamma root shared by Vay and Higuera-Cary: gamma^2 is the positive
 * root of g^2 - sigma g - (tau^2 + u*^2) = 0 (g = gamma^2),
 *   g = (sigma + sqrt(sigma^2 + 4 (tau^2 + u*^2))) / 2            sigma >= 0,
 *   g = 2 (tau^2 + u*^2) / (sqrt(sigma^2 + 4 (tau^2 + u*^2)) - sigma)   sigma < 0.
 * The two are equal in exact arithmetic (multiply the first by the
 * conjugate).  Where sigma << 0 (tau >> gamma: omega_c dt >> 1) the first
 * subtracts two nearly equal numbers -- relative error eps sigma^2 / g, and
 * with u* = 0 it rounds to g = 0, then t = tau / 0 -- the second adds two
 * positive ones.  Neither form divides by zero: for sigma < 0, tau^2 > 0
 * (sigma = gamma'^2 - tau^2 and gamma' >= 1), so the denominator is > 0.
 * Returns gamma = sqrt(g). */
static inline GCP_HD double gcp_gamma_root_(double sigma, double tau2, double ustar)
{
    const double d = tau2 + ustar * ustar;
    const double r = sqrt(sigma * sigma + 4.0 * d);
    return sqrt(sigma >= 0.0 ? 0.5 * (sigma + r) : 2.0 * d / (r - sigma));
}

/* Vay pusher (Vay 2008, Phys. Plasmas 15 056701, eqs. 11-13): correct
 * E x B drift at any gamma, including the force-free E + v x B = 0 case.
 *   u'    = u + (q dt/m) E + (q dt/2m) (u/gamma) x B
 *   tau   = (q dt / 2m) B,  u* = u'.tau / c,  sigma = gamma'^2 - tau^2
 *   gamma = sqrt( (sigma + sqrt(sigma^2 + 4 (tau^2 + u*^2))) / 2 )
 *   t = tau / gamma,  s = 1 / (1 + t^2)
 *   u_new = s [u' + (u'.t) t + u' x t]
 * Written without cancellation at omega_c dt >> 1 (issue 13), where the
 * half-rotated u' = w + v x tau (w = u + (q dt/m) E, v = u/gamma) is
 * dominated by v x tau, |u'| ~ |u| omega_c dt / 2:
 *  - sigma from w and v, not from |u'|^2: with |v x tau|^2 =
 *    v^2 tau^2 - (v.tau)^2 (c = 1), 1 - v^2 = 1/gamma^2 and
 *    u.(v x tau) = 0,
 *      sigma = 1 + |w|^2 + 2 e.(v x tau) - tau^2/gamma^2 - (v.tau)^2,
 *    e = (q dt/m) E; 1 + |u'|^2 - tau^2 instead rounds to eps tau^2 and
 *    loses eps (omega_c dt)^2 of |u| per step;
 *  - u'.tau = w.tau and u'.t = w.t ((v x tau) is normal to tau), so the
 *    huge normal component does not round into u* and (u'.t) t;
 *  - the gamma root in its cancellation-free form (gcp_gamma_root_).
 * All three are identities: the scheme is Vay's, only its rounding changes. */
static inline GCP_HD void gcp_push_vay(double *ux, double *uy, double *uz,
                                       double Ex, double Ey, double Ez,
                                       double Bx, double By, double Bz,
                                       double q, double m, double dt)
{
    const double qdt2m = 0.5 * q * dt / m;
    const double inv_gamma = 1.0 / gcp_gamma_of_u(*ux, *uy, *uz);
    const double vx = *ux * inv_gamma, vy = *uy * inv_gamma, vz = *uz * inv_gamma;
    const double ex = 2.0 * qdt2m * Ex, ey = 2.0 * qdt2m * Ey, ez = 2.0 * qdt2m * Ez;
    const double wx = *ux + ex, wy = *uy + ey, wz = *uz + ez;
    const double taux = qdt2m * Bx, tauy = qdt2m * By, tauz = qdt2m * Bz;
    const double vtx = vy * tauz - vz * tauy; /* v x tau */
    const double vty = vz * taux - vx * tauz;
    const double vtz = vx * tauy - vy * taux;
    const double upx = wx + vtx, upy = wy + vty, upz = wz + vtz;
    const double tau2 = taux * taux + tauy * tauy + tauz * tauz;
    const double wtau = wx * taux + wy * tauy + wz * tauz;
    const double vtau = (vx * taux + vy * tauy + vz * tauz) * (1.0 / GCP_C_LIGHT);
    const double sigma = 1.0 + (wx * wx + wy * wy + wz * wz) * GCP_INV_C2 +
                         2.0 * (ex * vtx + ey * vty + ez * vtz) * GCP_INV_C2 -
                         tau2 * (inv_gamma * inv_gamma) - vtau * vtau;
    const double gamma_new = gcp_gamma_root_(sigma, tau2, wtau * (1.0 / GCP_C_LIGHT));
    const double tx = taux / gamma_new, ty = tauy / gamma_new, tz = tauz / gamma_new;
    const double s = 1.0 / (1.0 + tx * tx + ty * ty + tz * tz);
    const double ut = wtau / gamma_new; /* u'.t = w.tau / gamma_new */
    *ux = s * (upx + ut * tx + (upy * tz - upz * ty));
    *uy = s * (upy + ut * ty + (upz * tx - upx * tz));
    *uz = s * (upz + ut * tz + (upx * ty - upy * tx));
}

/* Higuera-Cary pusher (Higuera & Cary 2017, Phys. Plasmas 24 052104, eqs.
 * 20-23): volume preserving; the force-free motion (E + v x B = 0) is exact
 * at any gamma, while the relativistic E x B drift of a gyrating particle
 * carries an O((omega_c dt)^2) error (Vay's is exact there).  The gyro-angle
 * per step is 2 atan(tau / gamma_bar), gamma_bar of the step-averaged u.
 *   u-  = u + (q dt/2m) E,  tau = (q dt/2m) B
 *   gamma_new from the same quartic root as Vay with u- in place of u'
 *   (gcp_gamma_root_: cancellation-free where sigma = gamma-^2 - tau^2 < 0)
 *   t = tau/gamma_new,  s = 1/(1 + t^2)
 *   u_bar = s [u- + (u-.t) t + u- x t]
 *   u   = u_bar + (q dt/2m) E + u_bar x t
 * computed as u = u- + 2 s (u- + u- x t) x t + (q dt/2m) E, the identical
 * Cayley rotation (u_bar x t = s [u- x t + (u-.t) t - t^2 u-]) without the
 * eps |u| omega_c dt rounding of u_bar x t at omega_c dt >> 1 (issue 13). */
static inline GCP_HD void gcp_push_higuera_cary(double *ux, double *uy, double *uz,
                                                double Ex, double Ey, double Ez,
                                                double Bx, double By, double Bz,
                                                double q, double m, double dt)
{
    const double qdt2m = 0.5 * q * dt / m;
    const double umx = *ux + qdt2m * Ex;
    const double umy = *uy + qdt2m * Ey;
    const double umz = *uz + qdt2m * Ez;
    const double taux = qdt2m * Bx, tauy = qdt2m * By, tauz = qdt2m * Bz;
    const double tau2 = taux * taux + tauy * tauy + tauz * tauz;
    const double ustar = (umx * taux + umy * tauy + umz * tauz) * (1.0 / GCP_C_LIGHT);
    const double sigma = 1.0 + (umx * umx + umy * umy + umz * umz) * GCP_INV_C2 - tau2;
    const double gamma_new = gcp_gamma_root_(sigma, tau2, ustar);
    const double tx = taux / gamma_new, ty = tauy / gamma_new, tz = tauz / gamma_new;
    const double s = 1.0 / (1.0 + tx * tx + ty * ty + tz * tz);
    /* u_bar + u_bar x t = u- + 2 s (u- + u- x t) x t: the same Cayley
     * rotation in Boris's form, where the parallel part of u- never meets
     * t in a cross product (u_bar x t rounds it to eps |u| t). */
    const double s2 = 2.0 * s;
    const double upx = umx + (umy * tz - umz * ty);
    const double upy = umy + (umz * tx - umx * tz);
    const double upz = umz + (umx * ty - umy * tx);
    *ux = umx + s2 * (upy * tz - upz * ty) + qdt2m * Ex;
    *uy = umy + s2 * (upz * tx - upx * tz) + qdt2m * Ey;
    *uz = umz + s2 * (upx * ty - upy * tx) + qdt2m * Ez;
}

/* Batch forms over struct-of-arrays: the same scalar kernel in a restrict-ed
 * loop the compiler vectorises; bit-identical to calling the scalar kernel
 * per particle.  u arrays are updated in place; E and B are gathered.
 * The loop body copies u through locals on purpose: every array access is
 * then made directly through a restrict parameter, which is what lets GCC
 * keep the no-alias facts when it inlines the batch function into a caller
 * (passing &ux[i] to the scalar kernel loses them there, and the loop falls
 * back to scalar code, 6x slower: measured by tests/bench). */
#define GCP_DEFINE_BATCH_(NAME)                                                        \
    static inline GCP_HD void NAME##_batch(                                           \
        size_t n, double *GCP_RESTRICT ux, double *GCP_RESTRICT uy,                   \
        double *GCP_RESTRICT uz, const double *GCP_RESTRICT Ex,                       \
        const double *GCP_RESTRICT Ey, const double *GCP_RESTRICT Ez,                 \
        const double *GCP_RESTRICT Bx, const double *GCP_RESTRICT By,                 \
        const double *GCP_RESTRICT Bz, double q, double m, double dt)                 \
    {                                                                                  \
        for (size_t i = 0; i < n; i++) {                                               \
            double a = ux[i], b = uy[i], c = uz[i];                                    \
            NAME(&a, &b, &c, Ex[i], Ey[i], Ez[i], Bx[i], By[i], Bz[i], q, m, dt);      \
            ux[i] = a;                                                                 \
            uy[i] = b;                                                                 \
            uz[i] = c;                                                                 \
        }                                                                              \
    }

GCP_DEFINE_BATCH_(gcp_push_boris)
GCP_DEFINE_BATCH_(gcp_push_boris_nr)
GCP_DEFINE_BATCH_(gcp_push_boris_zu)
GCP_DEFINE_BATCH_(gcp_push_vay)
GCP_DEFINE_BATCH_(gcp_push_higuera_cary)

/* Boris in a pure magnetic field (E = 0): the rotation of gcp_push_boris
 * without its electric half-kicks, for scenes that have no E.  The same
 * operations on the same values, so it equals gcp_push_boris with E = 0
 * except possibly for the sign of a zero component (x + 0.0 turns -0 into
 * +0 there). */
static inline GCP_HD void gcp_push_boris_B(double *ux, double *uy, double *uz, double Bx,
                                           double By, double Bz, double q, double m, double dt)
{
    gcp_boris_rotate_(ux, uy, uz, Bx, By, Bz, 0.5 * q * dt / m);
}

/* The same with inv_gamma = 1/gcp_gamma_of_u(u) given: bit-identical to
 * gcp_push_boris_B when the caller computed it from the same u. */
static inline GCP_HD void gcp_push_boris_B_ig(double *ux, double *uy, double *uz, double Bx,
                                              double By, double Bz, double q, double m,
                                              double dt, double inv_gamma)
{
    gcp_boris_rotate_ig_(ux, uy, uz, Bx, By, Bz, 0.5 * q * dt / m, inv_gamma);
}

static inline GCP_HD void gcp_push_boris_B_batch(size_t n, double *GCP_RESTRICT ux,
                                                 double *GCP_RESTRICT uy,
                                                 double *GCP_RESTRICT uz,
                                                 const double *GCP_RESTRICT Bx,
                                                 const double *GCP_RESTRICT By,
                                                 const double *GCP_RESTRICT Bz, double q,
                                                 double m, double dt)
{
    for (size_t i = 0; i < n; i++) {
        double a = ux[i], b = uy[i], c = uz[i];
        gcp_push_boris_B(&a, &b, &c, Bx[i], By[i], Bz[i], q, m, dt);
        ux[i] = a;
        uy[i] = b;
        uz[i] = c;
    }
}

/* Non-relativistic Boris in a pure magnetic field (E = 0): the rotation of
 * gcp_push_boris_nr without its electric half-kicks (equal to it with E = 0
 * but for the sign of a zero component, as gcp_push_boris_B). */
static inline GCP_HD void gcp_push_boris_nr_B(double *ux, double *uy, double *uz, double Bx,
                                              double By, double Bz, double q, double m,
                                              double dt)
{
    gcp_boris_nr_rotate_(ux, uy, uz, Bx, By, Bz, 0.5 * q * dt / m);
}

static inline GCP_HD void gcp_push_boris_nr_B_batch(size_t n, double *GCP_RESTRICT ux,
                                                    double *GCP_RESTRICT uy,
                                                    double *GCP_RESTRICT uz,
                                                    const double *GCP_RESTRICT Bx,
                                                    const double *GCP_RESTRICT By,
                                                    const double *GCP_RESTRICT Bz, double q,
                                                    double m, double dt)
{
    for (size_t i = 0; i < n; i++) {
        double a = ux[i], b = uy[i], c = uz[i];
        gcp_push_boris_nr_B(&a, &b, &c, Bx[i], By[i], Bz[i], q, m, dt);
        ux[i] = a;
        uy[i] = b;
        uz[i] = c;
    }
}

/* Synchronised half drift x += (u / gamma) h over a batch, h = dt/2 [s]. */
static inline GCP_HD void gcp_drift_batch(size_t n, double *GCP_RESTRICT x,
                                          double *GCP_RESTRICT y, double *GCP_RESTRICT z,
                                          const double *GCP_RESTRICT ux,
                                          const double *GCP_RESTRICT uy,
                                          const double *GCP_RESTRICT uz, double h)
{
    for (size_t i = 0; i < n; i++) {
        const double hg = h / gcp_gamma_of_u(ux[i], uy[i], uz[i]);
        x[i] += ux[i] * hg;
        y[i] += uy[i] * hg;
        z[i] += uz[i] * hg;
    }
}

/* Array-of-structs adapters, for codes that keep a particle as a struct.
 *
 * gcp_particle_aos is the plain 6-double layout; NAME_aos pushes n of them
 * with E and B gathered into struct-of-arrays (as a PIC gather writes them),
 * gcp_drift_aos moves them.  For any other layout (extra members such as
 * weight or id, interleaved arrays, fields gathered per particle as 6
 * doubles) the NAME_strided form takes base pointers and strides counted in
 * doubles:
 *   ux of particle i is u[i*us], uy u[i*us + 1], uz u[i*us + 2];
 *   E of particle i is E[i*fs + 0..2], B is B[i*fs + 0..2].
 * E.g. for struct { double x[3], u[3], w; } p[n] with gathered
 * double eb[n][6] (Ex Ey Ez Bx By Bz):
 *   gcp_push_boris_strided(n, p[0].u, 7, &eb[0][0], &eb[0][3], 6, q, m, dt)
 * (a struct of doubles has no padding on the ABIs gcpush targets; check
 * sizeof(p[0]) == 7 * sizeof(double) once, as tests/unit/test_kernels_aos.c
 * does).
 *
 * On the host each goes through tiles of GCP_AOS_TILE particles copied into
 * struct-of-arrays locals and pushed by the batch kernel: compilers do not
 * vectorise a loop over 6- or 7-double records (GCC 12: group size not a
 * power of 2), the batch loop they do, and the copies cost little next to
 * the kick.  In CUDA device code the tile is one particle (one per thread).
 * Same scalar arithmetic either way: bit-identical to the scalar kernels. */
struct gcp_particle_aos {
    double x, y, z;    /* [m] position */
    double ux, uy, uz; /* [m/s] u = gamma v */
};

#if defined(__CUDA_ARCH__)
#define GCP_AOS_TILE_ 1
#elif defined(GCP_AOS_TILE)
#define GCP_AOS_TILE_ GCP_AOS_TILE
#else
#define GCP_AOS_TILE_ 32
#endif

#define GCP_DEFINE_AOS_(NAME)                                                          \
    static inline GCP_HD void NAME##_aos(                                             \
        size_t n, struct gcp_particle_aos *GCP_RESTRICT p,                            \
        const double *GCP_RESTRICT Ex, const double *GCP_RESTRICT Ey,                 \
        const double *GCP_RESTRICT Ez, const double *GCP_RESTRICT Bx,                 \
        const double *GCP_RESTRICT By, const double *GCP_RESTRICT Bz, double q,       \
        double m, double dt)                                                           \
    {                                                                                  \
        double a[GCP_AOS_TILE_], b[GCP_AOS_TILE_], c[GCP_AOS_TILE_];                   \
        for (size_t i0 = 0; i0 < n; i0 += GCP_AOS_TILE_) {                             \
            const size_t nt = n - i0 < GCP_AOS_TILE_ ? n - i0 : GCP_AOS_TILE_;         \
            const struct gcp_particle_aos *pt = p + i0;                                \
            for (size_t t = 0; t < nt; t++) {                                          \
                a[t] = pt[t].ux;                                                       \
                b[t] = pt[t].uy;                                                       \
                c[t] = pt[t].uz;                                                       \
            }                                                                          \
            NAME##_batch(nt, a, b, c, Ex + i0, Ey + i0, Ez + i0, Bx + i0, By + i0,     \
                         Bz + i0, q, m, dt);                                           \
            for (size_t t = 0; t < nt; t++) {                                          \
                p[i0 + t].ux = a[t];                                                   \
                p[i0 + t].uy = b[t];                                                   \
                p[i0 + t].uz = c[t];                                                   \
            }                                                                          \
        }                                                                              \
    }                                                                                  \
    static inline GCP_HD void NAME##_strided(                                         \
        size_t n, double *GCP_RESTRICT u, size_t us, const double *GCP_RESTRICT E,    \
        const double *GCP_RESTRICT B, size_t fs, double q, double m, double dt)       \
    {                                                                                  \
        double a[GCP_AOS_TILE_], b[GCP_AOS_TILE_], c[GCP_AOS_TILE_];                   \
        double f[6][GCP_AOS_TILE_];                                                    \
        for (size_t i0 = 0; i0 < n; i0 += GCP_AOS_TILE_) {                             \
            const size_t nt = n - i0 < GCP_AOS_TILE_ ? n - i0 : GCP_AOS_TILE_;         \
            for (size_t t = 0; t < nt; t++) {                                          \
                const size_t j = (i0 + t) * us, k = (i0 + t) * fs;                     \
                a[t] = u[j];                                                           \
                b[t] = u[j + 1];                                                       \
                c[t] = u[j + 2];                                                       \
                for (int d = 0; d < 3; d++) {                                          \
                    f[d][t] = E[k + d];                                                \
                    f[3 + d][t] = B[k + d];                                            \
                }                                                                      \
            }                                                                          \
            NAME##_batch(nt, a, b, c, f[0], f[1], f[2], f[3], f[4], f[5], q, m, dt);   \
            for (size_t t = 0; t < nt; t++) {                                          \
                const size_t j = (i0 + t) * us;                                        \
                u[j] = a[t];                                                           \
                u[j + 1] = b[t];                                                       \
                u[j + 2] = c[t];                                                       \
            }                                                                          \
        }                                                                              \
    }

GCP_DEFINE_AOS_(gcp_push_boris)
GCP_DEFINE_AOS_(gcp_push_boris_nr)
GCP_DEFINE_AOS_(gcp_push_boris_zu)
GCP_DEFINE_AOS_(gcp_push_vay)
GCP_DEFINE_AOS_(gcp_push_higuera_cary)

/* Position update x += (u / gamma) h over n AoS particles (h = dt for a
 * leapfrog PIC step, dt/2 for gcpush's drift-kick-drift halves), through
 * gcp_drift_batch: bit-identical to it. */
static inline GCP_HD void gcp_drift_aos(size_t n, struct gcp_particle_aos *GCP_RESTRICT p,
                                        double h)
{
    double x[GCP_AOS_TILE_], y[GCP_AOS_TILE_], z[GCP_AOS_TILE_];
    double ux[GCP_AOS_TILE_], uy[GCP_AOS_TILE_], uz[GCP_AOS_TILE_];
    for (size_t i0 = 0; i0 < n; i0 += GCP_AOS_TILE_) {
        const size_t nt = n - i0 < GCP_AOS_TILE_ ? n - i0 : GCP_AOS_TILE_;
        for (size_t t = 0; t < nt; t++) {
            const struct gcp_particle_aos *pt = p + i0 + t;
            x[t] = pt->x, y[t] = pt->y, z[t] = pt->z;
            ux[t] = pt->ux, uy[t] = pt->uy, uz[t] = pt->uz;
        }
        gcp_drift_batch(nt, x, y, z, ux, uy, uz, h);
        for (size_t t = 0; t < nt; t++) {
            p[i0 + t].x = x[t];
            p[i0 + t].y = y[t];
            p[i0 + t].z = z[t];
        }
    }
}

/* ---- Guiding-centre right-hand side (issue 3 / issue 8) --------------------
 *
 * Relativistic guiding-centre equations (Cary & Brizard 2009, Rev. Mod. Phys.
 * 81 693, eqs. 5.x; Littlejohn 1983) from the phase-space Lagrangian
 *   L = (q A + p_par b).Xdot - H,   H = gamma m c^2 + q phi,
 *   gamma = sqrt(1 + (p_par/mc)^2 + 2 mu |B| / (m c^2)):
 *   B*      = B + (p_par/q) curl b,      B*_par = b.B*,
 *   E*      = E - (mu/(q gamma)) grad|B|,
 *   dX/dt   = [ (p_par/(gamma m)) B* + E* x b ] / B*_par,
 *   dp_par/dt = q E*.B* / B*_par.
 * Everything comes from B and the tensor G_ij = dB_i/dx_j:
 *   grad|B|_j = b_i G_ij,
 *   (curl B)_i = eps_ijk G_kj,
 *   curl b = curl(B/|B|) = (curl B)/|B| + grad(1/|B|) x B
 *          = (curl B)/|B| + (b x grad|B|)/|B|.
 * (Static B assumed: a time-dependent b adds -p_par db/dt to E*, not done.)
 * Inputs: B [T], G [T/m], E [V/m] (NULL: none), p_par [kg m/s], mu [J/T],
 * q [C], m [kg].  Outputs dXdt [m/s], dppar [N].  Returns B*_par [T]: the
 * equations are singular where it vanishes (GC breakdown); the caller
 * checks its sign against |B|. */
static inline GCP_HD double gcp_gc_gamma(double ppar, double mu, double Bmag, double m)
{
    const double mc = m * GCP_C_LIGHT;
    const double a = ppar / mc;
    return sqrt(1.0 + a * a + 2.0 * mu * Bmag / (mc * GCP_C_LIGHT));
}

static inline GCP_HD double gcp_gc_rhs(const double B[3], const double G[3][3],
                                       const double *E, double ppar, double mu, double q,
                                       double m, double dXdt[3], double *dppar)
{
    const double Bm = sqrt(B[0] * B[0] + B[1] * B[1] + B[2] * B[2]);
    const double iB = 1.0 / Bm;
    const double b[3] = {B[0] * iB, B[1] * iB, B[2] * iB};
    double gB[3];
    for (int j = 0; j < 3; j++) gB[j] = b[0] * G[0][j] + b[1] * G[1][j] + b[2] * G[2][j];
    const double curlB[3] = {G[2][1] - G[1][2], G[0][2] - G[2][0], G[1][0] - G[0][1]};
    const double bxg[3] = {b[1] * gB[2] - b[2] * gB[1], b[2] * gB[0] - b[0] * gB[2],
                           b[0] * gB[1] - b[1] * gB[0]};
    const double gamma = gcp_gc_gamma(ppar, mu, Bm, m);
    const double rq = ppar / q;
    double Bs[3], Es[3];
    for (int i = 0; i < 3; i++) {
        Bs[i] = B[i] + rq * (curlB[i] + bxg[i]) * iB;
        Es[i] = (E ? E[i] : 0.0) - mu / (q * gamma) * gB[i];
    }
    const double Bspar = b[0] * Bs[0] + b[1] * Bs[1] + b[2] * Bs[2];
    const double iBs = 1.0 / Bspar;
    const double vpar = ppar / (gamma * m);
    const double Exb[3] = {Es[1] * b[2] - Es[2] * b[1], Es[2] * b[0] - Es[0] * b[2],
                           Es[0] * b[1] - Es[1] * b[0]};
    for (int i = 0; i < 3; i++) dXdt[i] = (vpar * Bs[i] + Exb[i]) * iBs;
    *dppar = q * (Es[0] * Bs[0] + Es[1] * Bs[1] + Es[2] * Bs[2]) * iBs;
    return Bspar;
}

#endif /* GCPUSH_KERNELS_H */
