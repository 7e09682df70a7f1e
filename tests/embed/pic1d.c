/* pic1d -- a small electrostatic 1D3V particle-in-cell code that embeds
 * gcpush's header-only kernels (include/gcpush/kernels.h) and nothing else
 * of gcpush: built by tests/cli/test_embed.sh from the *installed* header
 * with `cc $(pkg-config --cflags gcpush) pic1d.c -lm` (and as C++17 with
 * g++), run, and checked against the known discrete dispersion relation.
 *
 * Physics: cold electrons (charge q = -e, mass m_e) on a fixed neutralising
 * ion background, periodic box [0, L), optional uniform B = B_z zhat.  A
 * small displacement dx = eps cos(k x) excites the Langmuir oscillation
 * (B = 0, omega = omega_p) or the upper-hybrid oscillation
 * (omega^2 = omega_p^2 + omega_c^2).
 *
 * Numerics (the textbook momentum-conserving scheme, Birdsall & Langdon):
 *   deposit  cloud-in-cell (linear weighting) of the electrons onto NG nodes
 *   field    Gauss's law as a cumulative sum, no FFT:
 *              E_{j+1/2} = E_{j-1/2} + Delta rho_j / eps0,  mean(E) = 0,
 *              E_j = (E_{j-1/2} + E_{j+1/2}) / 2
 *            (identical to the 3-point Poisson solve with centred gradient)
 *   gather   cloud-in-cell from the nodes
 *   push     leapfrog: gcp_push_boris_batch (u^{n-1/2} -> u^{n+1/2}), then
 *            gcp_drift_batch with h = dt (x^n -> x^{n+1}); or, built with
 *            -DPIC_AOS, the same through gcp_push_boris_aos / gcp_drift_aos
 *            on an array of struct gcp_particle_aos.
 *
 * Exact linear theory of this discrete system (derived here, not fitted).
 * Particles sit at x_{m,s} = m Delta + a_s, a_s = (s + 1/2) Delta / P, with
 * P per cell; displacements stay far below the distance Delta/(2P) to the
 * nearest node, so no particle crosses a node, CIC is linear on the whole
 * orbit, and the system is exactly linear in the displacements (up to the
 * relativistic gamma, |v|/c ~ 1e-5: effects ~ 1e-11).  Let each class s of
 * particles carry displacement eps_s e^{ikx}.  Deposit, solve and gather
 * give the force on class s as
 *   d2 eps_s / dt2 = -omega_p^2 cos(k Delta/2) g(s) (1/P) sum_s' h(s') eps_s'
 *   g(s) = e^{-ik a_s} [(1 - a_s/Delta) + (a_s/Delta) e^{ik Delta}],
 *   h(s) = e^{-ik Delta/2} e^{ik a_s},
 * a rank-one operator: its one non-zero eigenvalue is
 *   omega_s^2 = omega_p^2 cos(k Delta/2) (1/P) sum_s g(s) h(s)
 *             = omega_p^2 cos^2(k Delta/2)
 * (the imaginary part cancels because mean(a_s) = Delta/2); this agrees with
 * the alias sum of B&L, omega_p^2 (kappa k / K^2) sum_p S^2(k_p) k_p / k,
 * whose sum is sin(k Delta)/(k Delta).  The other P-1 combinations make no
 * field (they are invisible in E).  In time, Boris-leapfrog on
 *   x'' = -omega_s^2 x + (q/m) x' x B
 * gives, with u^{n+1/2} = U e^{-i w (n+1/2) dt}, x^n = X e^{-i w n dt}:
 *   (2/dt)^2 sin^2(w dt/2) = omega_s^2 + cos^2(w dt/2) omega_c^2, i.e.
 *   sin^2(w dt/2) = (omega_s^2 + omega_c^2) dt^2 / (4 + omega_c^2 dt^2),
 * which is sin(w dt/2) = omega_s dt/2 for B = 0 (leapfrog) and
 * tan(w dt/2) = omega_c dt/2 for omega_s = 0 (the Boris rotation law).
 *
 * Initial state: u_x^{-1/2} = 0 and u_y^{-1/2} = -omega_c dx (omega_c = qB/m,
 * signed).  This zeroes each particle's discrete invariant
 * u_y^{n+1/2} + (q B dt / 2m)(x^{n+1} + x^n)/dt, so no zero-frequency
 * (displaced E x B drifting) component is excited and the mode amplitude
 * of E is a pure A cos(w n dt + phi).
 *
 * Measurement: s_n = Re(c_n conj(c_0)) / |c_0| with c_n the DFT coefficient
 * of mode k of E_j at step n (a direct sum); zero crossings found by linear
 * interpolation between samples; w = pi (N_c - 1) / (t_last - t_first).
 * Linear interpolation of a sinusoid sampled at phase step W = w dt misplaces
 * a crossing by at most (W^3/6) max_a a(1-a)(1-2a) = 0.016 W^3 rad, so the
 * relative error of w is at most 2 (0.016 W^3) / (pi (N_c - 1)): 2.2e-5 at
 * W = 0.64 with 120 crossings.  Tolerance TOL = 2e-4 (10x that bound; round-off
 * and relativistic terms are < 1e-9).  TOL is far inside the 1% asked for,
 * and both discrete corrections (grid: cos(k Delta/2) - 1 = -1.9%; time
 * step: +1.0% for B = 0) are each 50x TOL: the test fails if either is left
 * out of the theory, or if the kernels mis-rotate.
 *
 * Exit status 0 when every case matches; prints one line per case.  */
#include <gcpush/kernels.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#define NG 32          /* grid nodes */
#define PPC 16         /* particles per cell */
#define NP (NG * PPC)  /* particles */
#define MODE 2         /* excited mode: k = 2 pi MODE / L */
#define TOL 2e-4       /* relative frequency tolerance (derivation above) */

static const double PI = 3.14159265358979323846;
static const double QE_C = -1.602176634e-19;   /* electron charge [C] */
static const double ME_KG = 9.1093837015e-31;   /* electron mass [kg] */
static const double EPS0 = 8.8541878128e-12;  /* vacuum permittivity [F/m] */

struct pic {
    double L, dx, n0, w; /* box [m], cell [m], density [m^-3], weight [particles/macro] */
    double rho[NG], eh[NG], E[NG]; /* [C/m^3], E at j+1/2 and j [V/m] */
#ifdef PIC_AOS
    struct gcp_particle_aos *p;
#else
    double *x, *y, *z, *ux, *uy, *uz;
#endif
    double *Ex, *Ey, *Ez, *Bx, *By, *Bz; /* gathered per particle */
};

static double *dalloc(size_t n) { return (double *)calloc(n, sizeof(double)); }

#ifdef PIC_AOS
#define XPOS(pc, i) ((pc)->p[i].x)
#else
#define XPOS(pc, i) ((pc)->x[i])
#endif

static void deposit(struct pic *pc)
{
    for (int j = 0; j < NG; j++) pc->rho[j] = -QE_C * pc->n0; /* ions */
    const double c = QE_C * pc->w / pc->dx;
    for (size_t i = 0; i < NP; i++) {
        const double xi = XPOS(pc, i) / pc->dx;
        const int m = (int)floor(xi);
        const double f = xi - m;
        pc->rho[(m % NG + NG) % NG] += c * (1.0 - f);
        pc->rho[((m + 1) % NG + NG) % NG] += c * f;
    }
}

static void solve(struct pic *pc)
{
    double acc = 0.0, mean = 0.0;
    for (int j = 0; j < NG; j++) {
        acc += pc->dx * pc->rho[j] / EPS0;
        pc->eh[j] = acc; /* E at x_j + dx/2, up to a constant */
        mean += acc;
    }
    mean /= NG;
    for (int j = 0; j < NG; j++) pc->eh[j] -= mean;
    for (int j = 0; j < NG; j++) pc->E[j] = 0.5 * (pc->eh[(j + NG - 1) % NG] + pc->eh[j]);
}

static void gather(struct pic *pc)
{
    for (size_t i = 0; i < NP; i++) {
        const double xi = XPOS(pc, i) / pc->dx;
        const int m = (int)floor(xi);
        const double f = xi - m;
        pc->Ex[i] = (1.0 - f) * pc->E[(m % NG + NG) % NG] + f * pc->E[((m + 1) % NG + NG) % NG];
    }
}

static void push(struct pic *pc, double dt)
{
#ifdef PIC_AOS
    gcp_push_boris_aos(NP, pc->p, pc->Ex, pc->Ey, pc->Ez, pc->Bx, pc->By, pc->Bz, QE_C, ME_KG, dt);
    gcp_drift_aos(NP, pc->p, dt);
#else
    gcp_push_boris_batch(NP, pc->ux, pc->uy, pc->uz, pc->Ex, pc->Ey, pc->Ez, pc->Bx, pc->By,
                         pc->Bz, QE_C, ME_KG, dt);
    gcp_drift_batch(NP, pc->x, pc->y, pc->z, pc->ux, pc->uy, pc->uz, dt);
#endif
    for (size_t i = 0; i < NP; i++) { /* periodic in x */
        double *x = &XPOS(pc, i);
        if (*x < 0.0) *x += pc->L;
        if (*x >= pc->L) *x -= pc->L;
    }
}

/* One case: B = wc_over_wp * omega_p m_e / e along z.  Returns 0 on a match. */
static int run_case(const char *name, double wc_over_wp)
{
    struct pic pc;
    pc.L = 0.01;
    pc.dx = pc.L / NG;
    pc.n0 = 1e16;
    pc.w = pc.n0 * pc.L / NP;
    const double wp = sqrt(pc.n0 * QE_C * QE_C / (EPS0 * ME_KG));
    const double wc = wc_over_wp * wp;        /* |omega_c| */
    const double Bz = wc * ME_KG / fabs(QE_C);   /* [T] */
    const double wc_signed = QE_C * Bz / ME_KG;  /* q B / m */
    const double dt = 0.5 / wp;
    const double k = 2.0 * PI * MODE / pc.L;
    const double eps = 1e-3 * pc.dx;          /* << dx / (2 PPC) = 0.031 dx */

    /* theory: the discrete dispersion relation above, and the continuum one */
    const double ws = wp * cos(0.5 * k * pc.dx);
    const double s2 = (ws * ws + wc * wc) * dt * dt / (4.0 + wc * wc * dt * dt);
    const double w_th = 2.0 / dt * asin(sqrt(s2));
    const double w_cont = sqrt(wp * wp + wc * wc);
    const int nsteps = (int)ceil(60.0 * 2.0 * PI / (w_th * dt)); /* 60 periods */

#ifdef PIC_AOS
    pc.p = (struct gcp_particle_aos *)calloc(NP, sizeof *pc.p);
    int fail = !pc.p;
#else
    pc.x = dalloc(NP), pc.y = dalloc(NP), pc.z = dalloc(NP);
    pc.ux = dalloc(NP), pc.uy = dalloc(NP), pc.uz = dalloc(NP);
    int fail = !pc.x || !pc.y || !pc.z || !pc.ux || !pc.uy || !pc.uz;
#endif
    pc.Ex = dalloc(NP), pc.Ey = dalloc(NP), pc.Ez = dalloc(NP);
    pc.Bx = dalloc(NP), pc.By = dalloc(NP), pc.Bz = dalloc(NP);
    double *sig = dalloc((size_t)nsteps);
    fail |= !pc.Ex || !pc.Ey || !pc.Ez || !pc.Bx || !pc.By || !pc.Bz || !sig;
    if (fail) {
        fprintf(stderr, "pic1d: out of memory\n");
        exit(2);
    }
    for (size_t i = 0; i < NP; i++) {
        const double x0 = (double)(i / PPC) * pc.dx + ((double)(i % PPC) + 0.5) * pc.dx / PPC;
        const double d = eps * cos(k * x0);
        pc.Bz[i] = Bz;
#ifdef PIC_AOS
        pc.p[i].x = x0 + d;
        pc.p[i].uy = -wc_signed * d;
#else
        pc.x[i] = x0 + d;
        pc.uy[i] = -wc_signed * d;
#endif
    }

    double c0r = 0.0, c0i = 0.0;
    for (int n = 0; n < nsteps; n++) {
        deposit(&pc);
        solve(&pc);
        double cr = 0.0, ci = 0.0; /* DFT coefficient of mode k of E */
        for (int j = 0; j < NG; j++) {
            cr += pc.E[j] * cos(k * j * pc.dx);
            ci -= pc.E[j] * sin(k * j * pc.dx);
        }
        if (n == 0) c0r = cr, c0i = ci;
        sig[n] = (cr * c0r + ci * c0i) / sqrt(c0r * c0r + c0i * c0i);
        gather(&pc);
        push(&pc, dt);
    }

    /* zero crossings, linearly interpolated */
    int nc = 0;
    double t_first = 0.0, t_last = 0.0;
    for (int n = 0; n + 1 < nsteps; n++) {
        const double a = sig[n], b = sig[n + 1];
        if ((a > 0.0 && b <= 0.0) || (a < 0.0 && b >= 0.0)) {
            const double t = (n + a / (a - b)) * dt;
            if (nc == 0) t_first = t;
            t_last = t;
            nc++;
        }
    }
    const double w_meas = nc > 1 ? PI * (nc - 1) / (t_last - t_first) : 0.0;
    const double err = w_meas / w_th - 1.0;
    const int ok = nc > 100 && fabs(err) < TOL;
    printf("%-12s %s  omega_c/omega_p %.2f  omega_p dt %.2f  k dx %.4f  crossings %d\n"
           "        measured/theory - 1 = %+.2e (tol %.0e)   continuum theory off by %+.2e   %s\n",
           name,
#ifdef PIC_AOS
           "(AoS)",
#else
           "(SoA)",
#endif
           wc_over_wp, wp * dt, k * pc.dx, nc, err, TOL, w_meas / w_cont - 1.0,
           ok ? "ok" : "FAIL");

#ifdef PIC_AOS
    free(pc.p);
#else
    free(pc.x), free(pc.y), free(pc.z), free(pc.ux), free(pc.uy), free(pc.uz);
#endif
    free(pc.Ex), free(pc.Ey), free(pc.Ez), free(pc.Bx), free(pc.By), free(pc.Bz), free(sig);
    return !ok;
}

int main(void)
{
    int bad = 0;
    bad |= run_case("langmuir", 0.0);
    bad |= run_case("upper-hybrid", 0.8);
    return bad;
}
