/* The driver's side of method = hybrid: a finished chunk's rows and switch
 * events (layout: README "Output (HDF5)", /hybrid). */
#include <string.h>

#include "gcpush/hybrid.h"
#include "gcpush/invariants.h"
#include "gcpush/results.h"
#include "gcpush/run.h"
#include "run_priv.h"

int gcp_hybrid_store(const struct gcp_scene *s, const struct gcp_hybrid *hy,
                     const struct gcp_block *b, struct gcp_results *res, int64_t row0)
{
    for (size_t i = 0; i < b->n; i++) {
        const int64_t row = row0 + (int64_t)b->index[i];
        double x[3], u[3], X[3], ppar, mu;
        gcp_hybrid_final(hy, b, s->field, i, x, u, X, &ppar, &mu);
        memcpy(&res->x[3 * row], x, sizeof x);
        memcpy(&res->u[3 * row], u, sizeof u);
        memcpy(&res->Xf[3 * row], X, sizeof X);
        res->ppar[row] = ppar;
        res->mu[row] = mu;
        struct gcp_hybrid_lane_info info;
        gcp_hybrid_info(hy, b->index[i], &info);
        res->hy_mode[row] = info.mode;
        res->hy_switches[row] = info.switches;
        res->hy_t_gc[row] = info.t_gc;
        res->hy_t_fo[row] = info.t_fo;
    }
    if (gcp_hybrid_status(hy)) return GCP_ERR_NOMEM;
    const struct gcp_hybrid_switch *sw;
    const size_t n = gcp_hybrid_switches(hy, &sw);
    for (size_t k = 0; k < n; k++) {
        struct gcp_event e = {.id = sw[k].id, .kind = GCP_EVENT_SWITCH, .t = sw[k].t};
        memcpy(e.v, sw[k].X, 3 * sizeof(double));
        e.v[3] = sw[k].eps;
        e.v[4] = sw[k].dir;
        e.v[5] = sw[k].dp2;
        if (gcp_events_push(&res->ev, &e)) return GCP_ERR_NOMEM;
    }
    return 0;
}
