/* Private to fields/: the eqdsk model's parameters, shared by its reader
 * (eqdsk_read.c, which builds them from the file) and its evaluation
 * (eqdsk.c).  Not installed. */
#ifndef GCP_EQDSK_PRIV_H
#define GCP_EQDSK_PRIV_H

#include <stdlib.h>

#include "grid_priv.h"

struct eqdsk_params {
    struct gcp_spl psi;   /* psirz, 2D (R, Z) */
    struct gcp_spl prof;  /* 1D on u = psi_N (nw - 1): 0 fpol, 1 qpsi, 2 pres */
    struct gcp_eqdsk_info info;
    double s_pol, s_tor;  /* sign factors above */
    double dpsi;          /* [Wb/rad] sibry - simag */
    double F_edge;        /* [T m] fpol(nw) */
    double Rmin;          /* [m] floor of R */
    int kind;             /* enum gcp_spl_kind of psi and the profiles */
};

static inline void gcp_eqdsk_destroy(void *p)
{
    struct eqdsk_params *e = p;
    if (!e) return;
    gcp_spl_free(&e->psi);
    gcp_spl_free(&e->prof);
    free(e);
}

#endif
