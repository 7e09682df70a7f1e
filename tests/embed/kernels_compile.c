/* Compile check for include/gcpush/kernels.h (tests/cli/test_kernels_compile.sh):
 * built as C99, C11 and C++17 with -Wall -Wextra -Werror -pedantic.  Calls
 * every kernel and every batch / AoS / strided form so that each is
 * instantiated, not just declared. */
#include <gcpush/kernels.h>

#define CALL_ALL_(NAME)                                                            \
    NAME(&ux, &uy, &uz, 1.0, 2.0, 3.0, 0.0, 0.0, 1.0, q, m, dt);                   \
    NAME##_batch(n, vx, vy, vz, e, e + n, e + 2 * n, b, b + n, b + 2 * n, q, m, dt); \
    NAME##_aos(n, p, e, e + n, e + 2 * n, b, b + n, b + 2 * n, q, m, dt);          \
    NAME##_strided(n, &p[0].ux, 6, e, b, 1, q, m, dt)

#ifdef __cplusplus
extern "C" double gcp_kernels_compile_check(size_t n, double *vx, double *vy, double *vz,
                                            const double *e, const double *b,
                                            struct gcp_particle_aos *p);
#else
double gcp_kernels_compile_check(size_t n, double *vx, double *vy, double *vz, const double *e,
                                 const double *b, struct gcp_particle_aos *p);
#endif

double gcp_kernels_compile_check(size_t n, double *vx, double *vy, double *vz, const double *e,
                                 const double *b, struct gcp_particle_aos *p)
{
    const double q = -1.602176634e-19, m = 9.1093837015e-31, dt = 1e-12;
    double ux = 1e6, uy = 0.0, uz = 0.0;
    CALL_ALL_(gcp_push_boris);
    CALL_ALL_(gcp_push_boris_zu);
    CALL_ALL_(gcp_push_vay);
    CALL_ALL_(gcp_push_higuera_cary);
    double x[4] = {0, 0, 0, 0}, y[4] = {0, 0, 0, 0}, z[4] = {0, 0, 0, 0};
    gcp_drift_batch(n < 4 ? n : 4, x, y, z, vx, vy, vz, 0.5 * dt);
    gcp_drift_aos(n, p, 0.5 * dt);
    return ux + uy + uz + gcp_gamma_of_u(ux, uy, uz) + x[0] + y[0] + z[0];
}
