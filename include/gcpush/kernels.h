/* gcpush/kernels.h -- header-only relativistic particle-push kernels.
 *
 * For PIC codes and for gcpush itself: one implementation.  Plain doubles,
 * SI units, u = gamma v [m/s].  Each kernel is the momentum update ("kick")
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
 * every sqrt argument here is >= 1 (or a sum of squares) and sin/cos get
 * finite arguments, so errno is never written whatever -f[no-]math-errno
 * says.  The one thing -fno-math-errno changes is speed: GCC vectorises a
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
    const double umx = *ux + qdt2m * Ex;
    const double umy = *uy + qdt2m * Ey;
    const double umz = *uz + qdt2m * Ez;
    const double inv_gamma = 1.0 / gcp_gamma_of_u(umx, umy, umz);
    const double tx = qdt2m * inv_gamma * Bx;
    const double ty = qdt2m * inv_gamma * By;
    const double tz = qdt2m * inv_gamma * Bz;
    const double s = 2.0 / (1.0 + tx * tx + ty * ty + tz * tz);
    const double upx = umx + (umy * tz - umz * ty);
    const double upy = umy + (umz * tx - umx * tz);
    const double upz = umz + (umx * ty - umy * tx);
    *ux = umx + s * (upy * tz - upz * ty) + qdt2m * Ex;
    *uy = umy + s * (upz * tx - upx * tz) + qdt2m * Ey;
    *uz = umz + s * (upx * ty - upy * tx) + qdt2m * Ez;
}

/* Boris with the exact gyro-angle (Zenitani & Umeda 2018, Phys. Plasmas 25
 * 112110, eqs. 20-22): the magnetic rotation of u- is by
 *   theta = q |B| dt / (m gamma-)
 * exactly, written with cos/sin so it stays regular at theta = pi:
 *   u+ = (u-.b) b + [u- - (u-.b) b] cos(theta) + (u- x b) sin(theta).
 * In uniform B with E = 0 the gyrophase is exact for any omega_c dt. */
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

/* Vay pusher (Vay 2008, Phys. Plasmas 15 056701, eqs. 11-13): correct
 * E x B drift at any gamma, including the force-free E + v x B = 0 case.
 *   u'    = u + (q dt/m) E + (q dt/2m) (u/gamma) x B
 *   tau   = (q dt / 2m) B,  u* = u'.tau / c,  sigma = gamma'^2 - tau^2
 *   gamma = sqrt( (sigma + sqrt(sigma^2 + 4 (tau^2 + u*^2))) / 2 )
 *   t = tau / gamma,  s = 1 / (1 + t^2)
 *   u_new = s [u' + (u'.t) t + u' x t]                                     */
static inline GCP_HD void gcp_push_vay(double *ux, double *uy, double *uz,
                                       double Ex, double Ey, double Ez,
                                       double Bx, double By, double Bz,
                                       double q, double m, double dt)
{
    const double qdt2m = 0.5 * q * dt / m;
    const double inv_gamma = 1.0 / gcp_gamma_of_u(*ux, *uy, *uz);
    const double vx = *ux * inv_gamma, vy = *uy * inv_gamma, vz = *uz * inv_gamma;
    const double upx = *ux + 2.0 * qdt2m * Ex + qdt2m * (vy * Bz - vz * By);
    const double upy = *uy + 2.0 * qdt2m * Ey + qdt2m * (vz * Bx - vx * Bz);
    const double upz = *uz + 2.0 * qdt2m * Ez + qdt2m * (vx * By - vy * Bx);
    const double taux = qdt2m * Bx, tauy = qdt2m * By, tauz = qdt2m * Bz;
    const double tau2 = taux * taux + tauy * tauy + tauz * tauz;
    const double ustar = (upx * taux + upy * tauy + upz * tauz) * (1.0 / GCP_C_LIGHT);
    const double sigma = 1.0 + (upx * upx + upy * upy + upz * upz) * GCP_INV_C2 - tau2;
    const double gamma_new =
        sqrt(0.5 * (sigma + sqrt(sigma * sigma + 4.0 * (tau2 + ustar * ustar))));
    const double tx = taux / gamma_new, ty = tauy / gamma_new, tz = tauz / gamma_new;
    const double s = 1.0 / (1.0 + tx * tx + ty * ty + tz * tz);
    const double ut = upx * tx + upy * ty + upz * tz;
    *ux = s * (upx + ut * tx + (upy * tz - upz * ty));
    *uy = s * (upy + ut * ty + (upz * tx - upx * tz));
    *uz = s * (upz + ut * tz + (upx * ty - upy * tx));
}

/* Higuera-Cary pusher (Higuera & Cary 2017, Phys. Plasmas 24 052104, eqs.
 * 20-23): volume preserving and correct E x B at any gamma.
 *   u-  = u + (q dt/2m) E,  tau = (q dt/2m) B
 *   gamma_new from the same quartic root as Vay with u- in place of u'
 *   t = tau/gamma_new,  s = 1/(1 + t^2)
 *   u+  = s [u- + (u-.t) t + u- x t]
 *   u   = u+ + (q dt/2m) E + u+ x t                                          */
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
    const double gamma_new =
        sqrt(0.5 * (sigma + sqrt(sigma * sigma + 4.0 * (tau2 + ustar * ustar))));
    const double tx = taux / gamma_new, ty = tauy / gamma_new, tz = tauz / gamma_new;
    const double s = 1.0 / (1.0 + tx * tx + ty * ty + tz * tz);
    const double ut = umx * tx + umy * ty + umz * tz;
    const double upx = s * (umx + ut * tx + (umy * tz - umz * ty));
    const double upy = s * (umy + ut * ty + (umz * tx - umx * tz));
    const double upz = s * (umz + ut * tz + (umx * ty - umy * tx));
    *ux = upx + qdt2m * Ex + (upy * tz - upz * ty);
    *uy = upy + qdt2m * Ey + (upz * tx - upx * tz);
    *uz = upz + qdt2m * Ez + (upx * ty - upy * tx);
}

/* Batch forms over struct-of-arrays: the same scalar kernel in a restrict-ed
 * loop the compiler vectorises; bit-identical to calling the scalar kernel
 * per particle.  u arrays are updated in place; E and B are gathered. */
#define GCP_DEFINE_BATCH_(NAME)                                                        \
    static inline GCP_HD void NAME##_batch(                                           \
        size_t n, double *GCP_RESTRICT ux, double *GCP_RESTRICT uy,                   \
        double *GCP_RESTRICT uz, const double *GCP_RESTRICT Ex,                       \
        const double *GCP_RESTRICT Ey, const double *GCP_RESTRICT Ez,                 \
        const double *GCP_RESTRICT Bx, const double *GCP_RESTRICT By,                 \
        const double *GCP_RESTRICT Bz, double q, double m, double dt)                 \
    {                                                                                  \
        for (size_t i = 0; i < n; i++)                                                 \
            NAME(&ux[i], &uy[i], &uz[i], Ex[i], Ey[i], Ez[i], Bx[i], By[i], Bz[i], q, \
                 m, dt);                                                               \
    }

GCP_DEFINE_BATCH_(gcp_push_boris)
GCP_DEFINE_BATCH_(gcp_push_boris_zu)
GCP_DEFINE_BATCH_(gcp_push_vay)
GCP_DEFINE_BATCH_(gcp_push_higuera_cary)

/* Array-of-structs adapters, for codes that keep a particle as a struct.
 *
 * gcp_particle_aos is the plain 6-double layout; NAME_aos pushes n of them
 * with E and B gathered into struct-of-arrays (as a PIC gather writes them).
 * For any other layout (extra members such as weight or id, interleaved
 * arrays, fields gathered per particle as 6 doubles) the NAME_strided form
 * takes base pointers and strides counted in doubles:
 *   ux of particle i is u[i*us], uy u[i*us + 1], uz u[i*us + 2];
 *   E of particle i is E[i*fs + 0..2], B is B[i*fs + 0..2].
 * E.g. for struct { double x[3], u[3], w; } p[n] with gathered
 * double eb[n][6] (Ex Ey Ez Bx By Bz):
 *   gcp_push_boris_strided(n, p[0].u, 7, &eb[0][0], &eb[0][3], 6, q, m, dt)
 * (a struct of doubles has no padding on any ABI gcpush targets; check
 * sizeof(p[0]) == 7 * sizeof(double) once, as the test does).
 * Both call the scalar kernel per particle: bit-identical to it.           */
struct gcp_particle_aos {
    double x, y, z;    /* [m] position */
    double ux, uy, uz; /* [m/s] u = gamma v */
};

#define GCP_DEFINE_AOS_(NAME)                                                          \
    static inline GCP_HD void NAME##_aos(                                             \
        size_t n, struct gcp_particle_aos *GCP_RESTRICT p,                            \
        const double *GCP_RESTRICT Ex, const double *GCP_RESTRICT Ey,                 \
        const double *GCP_RESTRICT Ez, const double *GCP_RESTRICT Bx,                 \
        const double *GCP_RESTRICT By, const double *GCP_RESTRICT Bz, double q,       \
        double m, double dt)                                                           \
    {                                                                                  \
        for (size_t i = 0; i < n; i++)                                                 \
            NAME(&p[i].ux, &p[i].uy, &p[i].uz, Ex[i], Ey[i], Ez[i], Bx[i], By[i],      \
                 Bz[i], q, m, dt);                                                     \
    }                                                                                  \
    static inline GCP_HD void NAME##_strided(                                         \
        size_t n, double *GCP_RESTRICT u, size_t us, const double *GCP_RESTRICT E,    \
        const double *GCP_RESTRICT B, size_t fs, double q, double m, double dt)       \
    {                                                                                  \
        for (size_t i = 0; i < n; i++) {                                               \
            double *ui = u + i * us;                                                   \
            const double *e = E + i * fs, *b = B + i * fs;                             \
            NAME(&ui[0], &ui[1], &ui[2], e[0], e[1], e[2], b[0], b[1], b[2], q, m, dt); \
        }                                                                              \
    }

GCP_DEFINE_AOS_(gcp_push_boris)
GCP_DEFINE_AOS_(gcp_push_boris_zu)
GCP_DEFINE_AOS_(gcp_push_vay)
GCP_DEFINE_AOS_(gcp_push_higuera_cary)

/* Position update x += (u / gamma) h over n AoS particles (h = dt for a
 * leapfrog PIC step, dt/2 for gcpush's drift-kick-drift halves); the same
 * arithmetic as gcp_drift_batch, so bit-identical to it. */
static inline GCP_HD void gcp_drift_aos(size_t n, struct gcp_particle_aos *GCP_RESTRICT p,
                                        double h)
{
    for (size_t i = 0; i < n; i++) {
        const double hg = h / gcp_gamma_of_u(p[i].ux, p[i].uy, p[i].uz);
        p[i].x += p[i].ux * hg;
        p[i].y += p[i].uy * hg;
        p[i].z += p[i].uz * hg;
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

#endif /* GCPUSH_KERNELS_H */
