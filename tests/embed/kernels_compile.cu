// CUDA compile check for include/gcpush/kernels.h (tests/cli/test_kernels_compile.sh):
// nvcc -x cu -c, with host-compiler warnings as errors.  The scalar kernels are
// __host__ __device__ (GCP_HD); a PIC code calls them one particle per thread.
#include <gcpush/kernels.h>

struct fields6 { double Ex, Ey, Ez, Bx, By, Bz; };

// One thread per particle: kick (each pusher, picked by `which`) then drift.
__global__ void push_soa(size_t n, int which, double *x, double *y, double *z, double *ux,
                         double *uy, double *uz, const fields6 *f, double q, double m,
                         double dt)
{
    const size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    double a = ux[i], b = uy[i], c = uz[i];
    const fields6 g = f[i];
    switch (which) {
    case 0: gcp_push_boris(&a, &b, &c, g.Ex, g.Ey, g.Ez, g.Bx, g.By, g.Bz, q, m, dt); break;
    case 1: gcp_push_boris_zu(&a, &b, &c, g.Ex, g.Ey, g.Ez, g.Bx, g.By, g.Bz, q, m, dt); break;
    case 2: gcp_push_vay(&a, &b, &c, g.Ex, g.Ey, g.Ez, g.Bx, g.By, g.Bz, q, m, dt); break;
    default: gcp_push_higuera_cary(&a, &b, &c, g.Ex, g.Ey, g.Ez, g.Bx, g.By, g.Bz, q, m, dt);
    }
    ux[i] = a;
    uy[i] = b;
    uz[i] = c;
    const double hg = dt / gcp_gamma_of_u(a, b, c);
    x[i] += a * hg;
    y[i] += b * hg;
    z[i] += c * hg;
}

// The AoS and strided adapters are device-callable too (one thread, a slice).
__global__ void push_aos(size_t n, gcp_particle_aos *p, const double *E, const double *B,
                         double q, double m, double dt)
{
    const size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    gcp_push_vay_strided(1, &p[i].ux, 6, E + 3 * i, B + 3 * i, 3, q, m, dt);
    gcp_drift_aos(1, p + i, dt);
}
