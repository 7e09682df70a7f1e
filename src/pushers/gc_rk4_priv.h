/* Private to gc-rk4 (gc_rk4.c, the block step; gc_rk4_fused.c, the fused
 * step of the closed-form fields): the right-hand side of one lane, written
 * once so that both paths do the same operations in the same order (the
 * build keeps -ffp-contract=off): the fused step gives the block step's
 * numbers bit for bit. */
#ifndef GCPUSH_GC_RK4_PRIV_H
#define GCPUSH_GC_RK4_PRIV_H

#include <float.h>
#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "gcpush/particles.h"
#include "evolve_priv.h"

/* The guiding-centre right-hand side of kernels.h gcp_gc_rhs (Cary &
 * Brizard 2009; equations in docs/DESIGN.md), rearranged so that a lane
 * needs two square roots and one division instead of two and eight (the
 * divider, not the multipliers, bounds a vectorised loop of gcp_gc_rhs):
 *   Bm = |B|,  gamma = sqrt(1 + (p_par/mc)^2 + 2 mu Bm/(m c^2)),
 *   B*_par = b.B* = Bm + (p_par/q) B.curl B / Bm^2,  so with
 *   S = B*_par Bm^2 = Bm^3 + (p_par/q) B.curl B  and  D = 1/(Bm gamma S):
 *   1/Bm = gamma S D,  1/gamma = Bm S D,  1/B*_par = Bm^2 Bm gamma D.
 * Constants (1/q, 1/(mc), 1/m) are reciprocals taken once.  The results
 * differ from gcp_gc_rhs by round-off (a few ulp per evaluation); the
 * edge cases keep their verdicts: B = 0 or B*_par = 0 give an infinite D,
 * hence NaN (NONFINITE, as gcp_gc_rhs's inf/NaN), B*_par < 0 gives S < 0
 * (NONADIABATIC). */
struct gcp_rk4_consts {
    double iq;  /* [1/C] 1/q */
    double q;   /* [C] */
    double imc; /* [s/(kg m)] 1/(m c) */
    double k2;  /* [1/J] 2/(m c^2), times mu B [J] */
    double im;  /* [1/kg] 1/m */
};

/* One lane: B [T], G_ij = dB_i/dx_j [T/m], E [V/m] (read only when withE,
 * a constant at each call), p_par, mu.  Writes the derivative (dX/dt
 * [m/s], dp_par/dt [N]) and returns the verdict of gcp_gc_eval without the
 * adiabaticity test and the field's status: NONFINITE for a non-finite
 * derivative, else NONADIABATIC where B*_par <= 0 or |B| = 0, else 0. */
static inline __attribute__((always_inline)) int32_t
gcp_rk4_rhs(double Bx, double By, double Bz, const double G[3][3], double Ex, double Ey,
            double Ez, int withE, double pp, double mui, const struct gcp_rk4_consts *kc,
            double *dXo, double *dYo, double *dZo, double *dpo)
{
    const double iq = kc->iq, q = kc->q, imc = kc->imc, k2 = kc->k2, im = kc->im;
    const double G00 = G[0][0], G01 = G[0][1], G02 = G[0][2];
    const double G10 = G[1][0], G11 = G[1][1], G12 = G[1][2];
    const double G20 = G[2][0], G21 = G[2][1], G22 = G[2][2];
    const double B2 = Bx * Bx + By * By + Bz * Bz;
    const double Bm = sqrt(B2);
    const double a = pp * imc;
    const double gamma = sqrt(1.0 + a * a + mui * Bm * k2);
    const double rq = pp * iq;
    /* curl B and B.curl B */
    const double cx = G21 - G12, cy = G02 - G20, cz = G10 - G01;
    const double S = B2 * Bm + rq * (Bx * cx + By * cy + Bz * cz);
    const double D = 1.0 / (Bm * gamma * S);
    const double iB = gamma * S * D, ig = Bm * S * D, iBs = B2 * Bm * gamma * D;
    const double bx = Bx * iB, by = By * iB, bz = Bz * iB;
    /* grad |B|_j = b_i dB_i/dx_j */
    const double gx = bx * G00 + by * G10 + bz * G20;
    const double gy = bx * G01 + by * G11 + bz * G21;
    const double gz = bx * G02 + by * G12 + bz * G22;
    const double rqiB = rq * iB;
    const double Bsx = Bx + rqiB * (cx + (by * gz - bz * gy));
    const double Bsy = By + rqiB * (cy + (bz * gx - bx * gz));
    const double Bsz = Bz + rqiB * (cz + (bx * gy - by * gx));
    const double f = mui * iq * ig;
    const double Esx = (withE ? Ex : 0.0) - f * gx;
    const double Esy = (withE ? Ey : 0.0) - f * gy;
    const double Esz = (withE ? Ez : 0.0) - f * gz;
    const double vpar = pp * im * ig;
    const double dX = (vpar * Bsx + (Esy * bz - Esz * by)) * iBs;
    const double dY = (vpar * Bsy + (Esz * bx - Esx * bz)) * iBs;
    const double dZ = (vpar * Bsz + (Esx * by - Esy * bx)) * iBs;
    const double dp = q * (Esx * Bsx + Esy * Bsy + Esz * Bsz) * iBs;
    *dXo = dX, *dYo = dY, *dZo = dZ, *dpo = dp;
    const int32_t nonfinite = !(fabs(dX + dY + dZ + dp) <= DBL_MAX);
    const int32_t bad = !(S > 0.0) | !(B2 > 0.0);
    return nonfinite * GCP_NONFINITE + (1 - nonfinite) * bad * GCP_NONADIABATIC;
}

/* The fused step (gc_rk4_fused.c): up to kmax steps of the lanes [0, nt)
 * of one tile (arrays at the tile's first lane, nt <= GCP_RK4_TILE) in a
 * closed-form field.  Returns the steps taken: kmax, or s where the
 * start-of-step check of step s + 1 stops a lane (the tile then holds the
 * state after s steps; s = 0: nothing moved), or s where the
 * classification after step s stops one (gcp_block_classify's verdict).
 * fst holds the verdict of the last step taken (s >= 1). */
#define GCP_RK4_TILE 128
struct gcp_rk4_tile_args {
    struct gcp_rk4_consts kc;
    double h;                 /* [s] the step */
    double p[6];              /* the form's parameters (gcp_point_B.p) */
    double rin2, rout2, zmax; /* the field's bounds (gcp_block_classify's) */
    double amax;              /* opts->adiabaticity_max (> 0: tested at each step's start) */
    double q, m;              /* [C], [kg] for the adiabaticity test */
};
typedef int64_t (*gcp_rk4_tile_fn)(double *x, double *y, double *z, double *p, const double *mu,
                                   int32_t *fst, size_t nt, int64_t kmax,
                                   const struct gcp_rk4_tile_args *a);

/* The tile function for a form (enum gcp_point_B_form) with or without E;
 * NULL where there is none. */
gcp_rk4_tile_fn gcp_rk4_fused_tile(int form, int has_E);

#endif
