/* Private to gc-rk4: its constants and the fused step of the closed-form
 * fields (gc_rk4_fused.c), which gc_rk4.c's stepper calls. */
#ifndef GCPUSH_GC_RK4_PRIV_H
#define GCPUSH_GC_RK4_PRIV_H

#include <stddef.h>
#include <stdint.h>

/* Constants of the right-hand side, reciprocals taken once per push. */
struct gcp_rk4_consts {
    double iq;  /* [1/C] 1/q */
    double q;   /* [C] */
    double imc; /* [s/(kg m)] 1/(m c) */
    double k2;  /* [1/J] 2/(m c^2), times mu B [J] */
    double im;  /* [1/kg] 1/m */
};

/* The fused step (gc_rk4_fused.c): up to kmax steps of the lanes [0, nt)
 * of one tile (arrays at the tile's first lane, nt <= GCP_RK4_TILE) in a
 * closed-form field.  Returns the steps taken: kmax, or s where the
 * start-of-step check of step s + 1 stops a lane (the tile then holds the
 * state after s steps; s = 0: nothing moved), or s where the
 * classification after step s stops one (gcp_block_classify's verdict;
 * *stopped = 1 then, else 0: no lane of the tile stops after its last
 * step, by the classification's own test, and fst is all 0).
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
/* cv: 7 arrays at the tile's first lane, the dipole form's B (3), |B|,
 * C_x, C_y and P at each lane's state: written by the call's step kmax
 * where carry has GCP_RK4_CARRY_OUT (after a call that took kmax steps
 * they hold the form at the lanes' state), read by the first step's stage
 * 1 where carry has GCP_RK4_CARRY_IN (they then must hold the form at the
 * state given) instead of forming it again.  Other forms neither read nor
 * write them; with carry 0 cv is not used (may be NULL). */
#define GCP_RK4_CARRY_IN 1
#define GCP_RK4_CARRY_OUT 2
typedef int64_t (*gcp_rk4_tile_fn)(double *x, double *y, double *z, double *p, const double *mu,
                                   int32_t *fst, double *const *cv, int carry, int32_t *stopped,
                                   size_t nt, int64_t kmax, const struct gcp_rk4_tile_args *a);

/* GCP_BLOCK_B_AT_X (pusher.h): the fused step in the dipole sets it. */

/* The tile function for a form (enum gcp_point_B_form) with or without E;
 * NULL where there is none. */
gcp_rk4_tile_fn gcp_rk4_fused_tile(int form, int has_E);

#endif
