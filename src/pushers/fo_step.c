/* The full-orbit step shared by every full-orbit pusher: synchronised
 * drift-kick-drift over a struct-of-arrays block (equations in pusher.h).
 *
 * The pusher and the field model are fixed for the whole call: the inner
 * loops are the field's block evaluation and the pusher's batch kick, both
 * dense over the live lanes with no per-lane decisions.  Lanes that stop
 * (domain, non-finite) are swapped out of the live range once per step. */
#include <math.h>
#include <stdlib.h>
#include <stdio.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/gc.h"
#include "gcpush/kernels.h"
#include "gcpush/particles.h"
#include "gcpush/pusher.h"
#include "block_priv.h"
#include "evolve_priv.h"
#include "fo_fast_priv.h"
#include "fo_fused_priv.h"

static const struct gcp_pusher_type *const all_pushers[] = {
    &gcp_pusher_boris, &gcp_pusher_boris_zu, &gcp_pusher_vay, &gcp_pusher_higuera_cary,
    &gcp_pusher_boris_nr,
    &gcp_pusher_gc_rk4, &gcp_pusher_gc_rk45, &gcp_pusher_gc_rk8pd,
    &gcp_pusher_gc_midpoint_pphi, &gcp_pusher_gc_gl2, &gcp_pusher_gc_gl4,
    &gcp_pusher_gc_gl2_sundman, &gcp_pusher_gc_gl4_sundman, NULL};

const struct gcp_pusher_type *const *gcp_pusher_types(void) { return all_pushers; }

const char *gcp_pusher_names(char *buf, size_t size)
{
    size_t used = 0;
    if (!buf || size == 0) return "";
    buf[0] = '\0';
    for (const struct gcp_pusher_type *const *p = all_pushers; *p && used < size; p++) {
        const int w = snprintf(buf + used, size - used, "%s%s", p == all_pushers ? "" : ", ",
                               (*p)->name);
        if (w < 0) break;
        used += (size_t)w;
    }
    return buf;
}

const struct gcp_pusher_type *gcp_pusher_lookup(const char *name)
{
    for (const struct gcp_pusher_type *const *p = all_pushers; *p; p++)
        if (strcmp((*p)->name, name) == 0) return *p;
    return NULL;
}

/* hg = h / gamma(u): the same expression as gcp_drift_batch, so the split
 * drift is bit-identical to it. */
static void half_drift_factor(size_t n, const double *restrict ux, const double *restrict uy,
                              const double *restrict uz, double *restrict hg, double h)
{
    for (size_t i = 0; i < n; i++) hg[i] = h / gcp_gamma_of_u(ux[i], uy[i], uz[i]);
}

static void drift_by(size_t n, double *restrict x, double *restrict y, double *restrict z,
                     const double *restrict ux, const double *restrict uy,
                     const double *restrict uz, const double *restrict hg)
{
    for (size_t i = 0; i < n; i++) {
        x[i] += ux[i] * hg[i];
        y[i] += uy[i] * hg[i];
        z[i] += uz[i] * hg[i];
    }
}

size_t gcp_block_start(struct gcp_block *b, const struct gcp_field *f, double t0)
{
    size_t n = b->n_active;
    memset(b->fstatus, 0, n * sizeof(int32_t));
    /* The field's own domain verdict (grids) comes from one evaluation. */
    f->type->eval_block(f, t0, n, b->x, b->y, b->z, b->Bx, b->By, b->Bz, NULL, NULL, NULL,
                        b->fstatus);
    if (gcp_block_classify(b, n, f, 0)) n = gcp_block_retire(b, n, t0, 0);
    b->n_active = n;
    return n;
}

/* The full-orbit stepper of the evolve layer: the pusher and the choice
 * of kick (with E, or the pure-magnetic kick_B) fixed for the push. */
struct fo_ctx {
    const struct gcp_pusher_type *p;
    double *Ex, *Ey, *Ez;          /* the block's E, or NULL without an electric field */
    gcp_kick_B_batch_fn kick_B;    /* set when there is no E and the pusher has one */
    /* the fused step (fo_fused_priv.h): set when the field is a closed form
     * and the pusher has a fused kernel for it */
    gcp_fo_tile_fn tile;
    struct gcp_fo_tile_args targs;
    double *save;                  /* [6 b->n] the block's x, u at the start of fo_steps */
    int64_t *done;                 /* [tiles] steps each tile took */
    int64_t left;                  /* steps of the push not yet taken */
    int hg_valid;                  /* [bool] b->hg holds the live lanes' drift factors */
    /* the sampler's gyro-average work (gcp_sampler.gyro, every = 1): gy set
     * when the sampler asks for it; then steps without gyro_tile are one a
     * call (the sampler does each step's work), with it up to
     * GCP_FO_GYRO_STEPS a call (fo_steps_gyro) */
    struct gcp_fo_gyro *gy;
    gcp_fo_gyro_tile_fn gyro_tile;
    double *gsave;                 /* [(6 + FO_GYRO_NSAVE) b->n] x, u and the gyro state at the call's start */
};

/* Steps a call of the fused step with the observer's work (fo_steps_gyro)
 * takes at most: its records (at most one a lane a step) are n of this
 * each, and the sampler's per-call work (the block's last positions, the
 * records into the stream) is spread over this many steps. */
#define GCP_FO_GYRO_STEPS 128

/* u does not change between a step's second half drift and the next
 * step's first, so (dt/2)/gamma is computed once per step (bit-identical to
 * recomputing it); when lanes are renumbered it is recomputed.  The fused
 * step computes its own on a tile's entry (fo_fused_priv.h) and leaves
 * them in b->hg only for the push's next call (fo_steps). */
static void fo_relanes(const struct gcp_evolve *ev, void *vctx, struct gcp_block *b, size_t n)
{
    struct fo_ctx *c = vctx;
    if (c->tile) {
        c->hg_valid = 0;
        return;
    }
    if (c->p->newtonian) return; /* no drift factor: fo_step_newtonian */
    half_drift_factor(n, b->ux, b->uy, b->uz, b->hg, 0.5 * ev->o->dt);
}

/* The step of a Newtonian pusher (u = v, boris-nr): the drift-kick-drift
 * with its two half drifts summed once,
 *   x_1/2 = x + u0 h,  u1 = kick(u0; E, B(x_1/2)),  x1 = x + (u0 + u1) h,
 * (GCP_NR_FMA_: fused where the target has fma, kernels.h), the operations
 * of the fused Newtonian tiles (fo_fused_priv.h), so the same bits.  x_1/2
 * and u0 live in stack tiles of GCP_FO_TILE lanes, the field is evaluated
 * tile by tile (per point, so the same numbers as over the whole block). */
static int32_t fo_step_newtonian(const struct fo_ctx *c, const struct gcp_field *f,
                                 struct gcp_block *b, size_t n, double t, double dt)
{
    const double h = 0.5 * dt;
    double xm[GCP_FO_TILE], ym[GCP_FO_TILE], zm[GCP_FO_TILE];
    double u0[GCP_FO_TILE], v0[GCP_FO_TILE], w0[GCP_FO_TILE];
    for (size_t i0 = 0; i0 < n; i0 += GCP_FO_TILE) {
        const size_t nt = n - i0 < GCP_FO_TILE ? n - i0 : GCP_FO_TILE;
        double *restrict x = b->x + i0, *restrict y = b->y + i0, *restrict z = b->z + i0;
        double *restrict ux = b->ux + i0, *restrict uy = b->uy + i0, *restrict uz = b->uz + i0;
        for (size_t i = 0; i < nt; i++) {
            u0[i] = ux[i], v0[i] = uy[i], w0[i] = uz[i];
            xm[i] = GCP_NR_FMA_(ux[i], h, x[i]);
            ym[i] = GCP_NR_FMA_(uy[i], h, y[i]);
            zm[i] = GCP_NR_FMA_(uz[i], h, z[i]);
        }
        memset(b->fstatus + i0, 0, nt * sizeof(int32_t));
        f->type->eval_block(f, t + h, nt, xm, ym, zm, b->Bx + i0, b->By + i0, b->Bz + i0,
                            c->Ex ? c->Ex + i0 : NULL, c->Ey ? c->Ey + i0 : NULL,
                            c->Ez ? c->Ez + i0 : NULL, b->fstatus + i0);
        if (c->kick_B)
            c->kick_B(nt, ux, uy, uz, b->Bx + i0, b->By + i0, b->Bz + i0, b->q, b->m, dt);
        else
            c->p->kick(nt, ux, uy, uz, b->Ex + i0, b->Ey + i0, b->Ez + i0, b->Bx + i0,
                       b->By + i0, b->Bz + i0, b->q, b->m, dt);
        for (size_t i = 0; i < nt; i++) {
            x[i] = GCP_NR_FMA_(u0[i] + ux[i], h, x[i]);
            y[i] = GCP_NR_FMA_(v0[i] + uy[i], h, y[i]);
            z[i] = GCP_NR_FMA_(w0[i] + uz[i], h, z[i]);
        }
    }
    return 0;
}

static int32_t fo_step(const struct gcp_evolve *ev, void *vctx, struct gcp_block *b, size_t n,
                       double t, double dt)
{
    const struct fo_ctx *c = vctx;
    const struct gcp_field *f = ev->f;
    if (c->p->newtonian) return fo_step_newtonian(c, f, b, n, t, dt);
    const double h = 0.5 * dt;
    drift_by(n, b->x, b->y, b->z, b->ux, b->uy, b->uz, b->hg);
    memset(b->fstatus, 0, n * sizeof(int32_t));
    f->type->eval_block(f, t + h, n, b->x, b->y, b->z, b->Bx, b->By, b->Bz, c->Ex, c->Ey, c->Ez,
                        b->fstatus);
    if (c->kick_B) c->kick_B(n, b->ux, b->uy, b->uz, b->Bx, b->By, b->Bz, b->q, b->m, dt);
    else
        c->p->kick(n, b->ux, b->uy, b->uz, b->Ex, b->Ey, b->Ez, b->Bx, b->By, b->Bz, b->q, b->m, dt);
    half_drift_factor(n, b->ux, b->uy, b->uz, b->hg, h);
    drift_by(n, b->x, b->y, b->z, b->ux, b->uy, b->uz, b->hg);
    return 0;
}

/* The block's per-lane state that a step changes, for fo_steps' restore
 * (the drift factors are recomputed from u: the same bits). */
static void fo_state_arrays(struct gcp_block *b, double *a[6])
{
    a[0] = b->x, a[1] = b->y, a[2] = b->z, a[3] = b->ux, a[4] = b->uy, a[5] = b->uz;
}

/* Up to kmax fused steps, tile by tile (fo_fused_priv.h): each tile runs
 * until kmax or the first step after which one of its lanes stops; the
 * block takes the fewest steps any tile took, kd, and tiles that ran past
 * kd are restored from `save` and run again to kd (the same arithmetic, so
 * the same numbers: every lane then holds exactly its lock-step state after
 * kd steps).  A stop is rare (a lane leaving the domain), so the rerun
 * costs nothing in the usual push; the copy is one pass per call of more
 * than one step (none in a streaming push of one step per call).  *stops:
 * 0 when no lane stopped (the evolve layer then need not classify).
 * When the push goes on after this call (a sampler's cadence), the tiles
 * leave their drift factors in b->hg for the next call to read instead of
 * recomputing (a square root and a division a lane); a push of one call
 * (one step per call, streaming) never touches b->hg. */
/* The gyro state arrays of lanes [0, n) that the fused step changes
 * (fo_steps_gyro's save; GCP_FO_GYRO_MID, fo_gyro_priv.h). */
#define FO_GYRO_NSAVE 16
static void fo_gyro_arrays(struct gcp_fo_gyro *g, void *a[FO_GYRO_NSAVE])
{
    int k = 0;
    a[k++] = g->left, a[k++] = g->kstart, a[k++] = g->w0, a[k++] = g->jc;
    for (int j = 0; j < 3; j++) a[k++] = g->e2[j];
    for (int j = 0; j < 9; j++) a[k++] = g->sum[j];
}

/* Whether fo_steps_gyro can take the block: dense (the gyro state is by
 * lane index, the tile's by position). */
static int fo_gyro_ready(const struct fo_ctx *c, const struct gcp_block *b, size_t n)
{
    const struct gcp_fo_gyro *g = c->gy;
    int ok = c->gyro_tile && n <= g->nlanes;
    for (size_t i = 0; ok && i < n; i++) ok = b->index[i] == i;
    return ok;
}

/* Lanes whose gyration in progress is not the fused step's (none yet, or
 * one of the observer's per-step pass, after a step without the fused
 * work) begin one at push step k0, time t: the phase reference from B at
 * the particle (fo_gyro_priv.h gcp_fo_gyro_mid_e2, F = B). */
static void fo_gyro_begin(const struct gcp_evolve *ev, struct gcp_fo_gyro *g, struct gcp_block *b,
                          size_t n, int64_t k0, double t)
{
    int64_t need = 0;
    for (size_t i = 0; i < n; i++) need |= g->init[i] != GCP_FO_GYRO_MID;
    if (!need) return;
    memset(b->fstatus, 0, n * sizeof(int32_t));
    ev->f->type->eval_block(ev->f, t, n, b->x, b->y, b->z, b->Bx, b->By, b->Bz, NULL, NULL, NULL,
                            b->fstatus);
    memset(b->fstatus, 0, n * sizeof(int32_t));
    for (size_t i = 0; i < n; i++) {
        if (g->init[i] == GCP_FO_GYRO_MID) continue;
        const double F[3] = {b->Bx[i], b->By[i], b->Bz[i]}, u[3] = {b->ux[i], b->uy[i], b->uz[i]};
        double e2[3];
        gcp_fo_gyro_mid_e2(b->q, 1.0, F, u, e2);
        gcp_fo_gyro_mid_start(g, i, k0, 1.0, e2, u);
    }
}

/* Up to GCP_FO_GYRO_STEPS fused steps with the observer's per-step work
 * (fo_gyro_priv.h), as fo_steps.  Where a lane stops after step kd of a
 * tile, x, u and the gyro state of every lane are restored and the call
 * is run again to kd - 1 steps (no lane stops in them: every tile ran them
 * all), or, for kd = 1, one plain fused step whose observer work the
 * sampler then does itself (gy->steps = 0): the stop itself is seen as
 * without gyro, and the sampler's loss interpolation has the last
 * position before it. */
static int64_t fo_steps_gyro(const struct gcp_evolve *ev, struct fo_ctx *c, struct gcp_block *b,
                             size_t n, int64_t kmax, int32_t *stops)
{
    struct gcp_fo_gyro *g = c->gy;
    if (kmax > GCP_FO_GYRO_STEPS) kmax = GCP_FO_GYRO_STEPS;
    if (g->max_steps > 0 && kmax > g->max_steps) kmax = g->max_steps;
    const int64_t need = (int64_t)n * kmax;
    if (g->cap < need) {
        struct gcp_fo_gyro_rec *r = realloc(g->rec, (size_t)need * sizeof *r);
        if (!r) return -1;
        g->rec = r, g->cap = need;
    }
    double *a[6];
    fo_state_arrays(b, a);
    const int64_t k0 = ev->o->nsteps - c->left;
    const double t0 = ev->o->t0;
    fo_gyro_begin(ev, g, b, n, k0, t0 + (double)k0 * ev->o->dt);
    void *ga[FO_GYRO_NSAVE];
    fo_gyro_arrays(g, ga);
    for (int k = 0; k < 6; k++) memcpy(c->gsave + (size_t)k * b->n, a[k], n * sizeof(double));
    for (int k = 0; k < FO_GYRO_NSAVE; k++)
        memcpy(c->gsave + (size_t)(6 + k) * b->n, ga[k], n * sizeof(double));
    int64_t kd = kmax;
    int32_t stopped = 0;
    int hg_mode = (c->hg_valid ? GCP_FO_HG_IN : 0) | (kmax < c->left ? GCP_FO_HG_OUT : 0);
    g->nrec = 0;
    for (size_t i0 = 0; i0 < n; i0 += GCP_FO_TILE) {
        const size_t nt = n - i0 < GCP_FO_TILE ? n - i0 : GCP_FO_TILE;
        const int64_t k = c->gyro_tile(a[0] + i0, a[1] + i0, a[2] + i0, a[3] + i0, a[4] + i0,
                                       a[5] + i0, b->hg + i0, hg_mode, nt, kd, &c->targs,
                                       &stopped, g, i0, t0, k0);
        if (k < kd) kd = k;
    }
    int64_t taken = kd;
    if (stopped) {
        for (int k = 0; k < 6; k++) memcpy(a[k], c->gsave + (size_t)k * b->n, n * sizeof(double));
        for (int k = 0; k < FO_GYRO_NSAVE; k++)
            memcpy(ga[k], c->gsave + (size_t)(6 + k) * b->n, n * sizeof(double));
        g->nrec = 0;
        /* the restored u's drift factors from u, not b->hg (the first run's) */
        taken = kd > 1 ? kd - 1 : 1;
        hg_mode = taken < c->left ? GCP_FO_HG_OUT : 0;
        stopped = 0;
        for (size_t i0 = 0; i0 < n; i0 += GCP_FO_TILE) {
            const size_t nt = n - i0 < GCP_FO_TILE ? n - i0 : GCP_FO_TILE;
            if (kd > 1)
                c->gyro_tile(a[0] + i0, a[1] + i0, a[2] + i0, a[3] + i0, a[4] + i0, a[5] + i0,
                             b->hg + i0, hg_mode, nt, taken, &c->targs, &stopped, g, i0, t0, k0);
            else
                c->tile(a[0] + i0, a[1] + i0, a[2] + i0, a[3] + i0, a[4] + i0, a[5] + i0,
                        b->hg + i0, hg_mode, nt, 1, &c->targs, &stopped);
        }
    }
    g->steps = stopped ? 0 : taken;
    *stops = stopped;
    if (stopped) memset(b->fstatus, 0, n * sizeof(int32_t));
    c->left -= taken;
    c->hg_valid = (hg_mode & GCP_FO_HG_OUT) != 0;
    return taken;
}

static int64_t fo_steps(const struct gcp_evolve *ev, void *vctx, struct gcp_block *b, size_t n,
                        double t, double dt, int64_t kmax, int32_t *stops,
                        unsigned char *lanes)
{
    struct fo_ctx *c = vctx;
    (void)ev, (void)t, (void)dt, (void)lanes;
    if (!c->tile) return 0;
    if (c->gy) {
        c->gy->steps = 0;
        if (fo_gyro_ready(c, b, n)) {
            const int64_t k = fo_steps_gyro(ev, c, b, n, kmax, stops);
            if (k > 0) return k;
        }
        kmax = 1; /* the sampler does this step's observer work itself */
    }
    double *a[6];
    fo_state_arrays(b, a);
    if (kmax > 1)
        for (int k = 0; k < 6; k++) memcpy(c->save + (size_t)k * b->n, a[k], n * sizeof(double));
    int64_t kd = kmax;
    int32_t stopped = 0;
    size_t tile = 0;
    const int more = kmax < c->left; /* another call of this push follows */
    const int hg_mode = (c->hg_valid ? GCP_FO_HG_IN : 0) | (more ? GCP_FO_HG_OUT : 0);
    for (size_t i0 = 0; i0 < n; i0 += GCP_FO_TILE, tile++) {
        const size_t nt = n - i0 < GCP_FO_TILE ? n - i0 : GCP_FO_TILE;
        const int64_t k = c->tile(a[0] + i0, a[1] + i0, a[2] + i0, a[3] + i0, a[4] + i0,
                                  a[5] + i0, b->hg + i0, hg_mode, nt, kd, &c->targs, &stopped);
        if (kmax > 1) c->done[tile] = k;
        if (k < kd) kd = k;
    }
    if (kd < kmax) {
        tile = 0;
        for (size_t i0 = 0; i0 < n; i0 += GCP_FO_TILE, tile++) {
            if (c->done[tile] == kd) continue;
            const size_t nt = n - i0 < GCP_FO_TILE ? n - i0 : GCP_FO_TILE;
            for (int k = 0; k < 6; k++)
                memcpy(a[k] + i0, c->save + (size_t)k * b->n + i0, nt * sizeof(double));
            /* the restored u's drift factors from u, not b->hg (the first run's) */
            c->tile(a[0] + i0, a[1] + i0, a[2] + i0, a[3] + i0, a[4] + i0, a[5] + i0,
                    b->hg + i0, hg_mode & GCP_FO_HG_OUT, nt, kd, &c->targs, &stopped);
        }
    }
    /* A tile that stopped set `stopped` (with kd < kmax some tile stopped
     * at kd).  Then the layer classifies, and the closed forms, defined
     * everywhere, give no field verdict; otherwise fstatus is not read. */
    *stops = stopped;
    if (stopped) memset(b->fstatus, 0, n * sizeof(int32_t));
    c->left -= kd;
    c->hg_valid = more;
    return kd;
}

static const struct gcp_stepper fo_stepper = {
    .gc = 0,
    .relanes = fo_relanes,
    .steps = fo_steps,
    .step = fo_step,
};

/* The same where a sampler of every step has its gyro-average work done
 * by the fused step (fo_steps_gyro), which then bounds its own steps. */
static const struct gcp_stepper fo_stepper_gyro = {
    .gc = 0,
    .gyro = 1,
    .relanes = fo_relanes,
    .steps = fo_steps,
    .step = fo_step,
};

static size_t advance_fo(struct gcp_block *b, const struct gcp_field *f,
                         const struct gcp_pusher_type *p, double t0, double dt, int64_t nsteps,
                         const struct gcp_sampler *sampler, struct gcp_fo_gyro *gyro)
{
    /* Chosen once: with no electric field the gathered E stays zero, or the
     * pusher's pure-magnetic kick skips the E terms altogether. */
    struct fo_ctx c = {.p = p,
                       .left = nsteps,
                       .Ex = f->has_E ? b->Ex : NULL,
                       .Ey = f->has_E ? b->Ey : NULL,
                       .Ez = f->has_E ? b->Ez : NULL,
                       .kick_B = f->has_E ? NULL : p->kick_B};
    if (!f->has_E && !c.kick_B) {
        memset(b->Ex, 0, b->n * sizeof(double));
        memset(b->Ey, 0, b->n * sizeof(double));
        memset(b->Ez, 0, b->n * sizeof(double));
    }
    /* The fused step where the field is a closed form the pusher has a
     * kernel for (never asked which model it is: field_kernels.h). */
    struct gcp_point_B form;
    /* GCP_BLOCK_FAST_ARITH: the fast tier's tiles where it has them (no
     * observer tile: the sampler then observes each fast step itself) */
    const struct gcp_fo_fused *fz = p->fused;
    const struct gcp_fo_fused *ff = b->flags & GCP_BLOCK_FAST_ARITH ? gcp_fo_fast_set(p) : NULL;
    if (p->fused && gcp_field_point_B(f, &form) && form.form > 0 &&
        form.form < GCP_POINT_B_NFORMS) {
        if (ff && ff->tile[form.form][form.has_E != 0]) fz = ff;
        c.tile = fz->tile[form.form][form.has_E != 0];
    }
    if (c.tile) {
        c.targs = (struct gcp_fo_tile_args){
            .q = b->q, .m = b->m, .dt = dt, .h = 0.5 * dt, .rin2 = f->r_inner * f->r_inner,
            .rout2 = f->r_outer * f->r_outer, .zmax = f->z_max};
        memcpy(c.targs.p, form.p, sizeof form.p);
        /* the observer's per-step work in the tile loop (fo_gyro_priv.h):
         * B-only forms with a gyro kernel, a sampler of every step */
        if (gyro && sampler && sampler->fn && sampler->every == 1) {
            c.gy = gyro;
            if (!form.has_E) c.gyro_tile = fz->gyro[form.form];
            gyro->tele = fz->gyro_tele; /* how its tile keeps S_r (fo_gyro_priv.h) */
            if (c.gyro_tile &&
                (nsteps <= 1 ||
                 !(c.gsave = malloc((6 + FO_GYRO_NSAVE) * (b->n + 1) * sizeof(double)))))
                c.gyro_tile = NULL;
        }
        if (nsteps > 1) {
            /* without memory, the block step (the same numbers) */
            c.save = malloc(6 * (b->n + 1) * sizeof(double));
            c.done = malloc((b->n / GCP_FO_TILE + 1) * sizeof(int64_t));
            if (!c.save || !c.done)
                free(c.save), free(c.done), c.save = NULL, c.done = NULL, c.tile = NULL;
        }
    }
    const struct gcp_push_opts o = {.t0 = t0, .dt = dt, .nsteps = nsteps};
    const size_t live = c.gy ? gcp_evolve_inline(b, f, &o, sampler, &fo_stepper_gyro, &c)
                             : gcp_evolve_inline(b, f, &o, sampler, &fo_stepper, &c);
    free(c.save);
    free(c.done);
    free(c.gsave);
    if (c.gy) c.gy->steps = 0;
    return live;
}

size_t gcp_block_advance_fo(struct gcp_block *b, const struct gcp_field *f,
                            const struct gcp_pusher_type *p, double t0, double dt,
                            int64_t nsteps, const struct gcp_sampler *sampler)
{
    return advance_fo(b, f, p, t0, dt, nsteps, sampler, NULL);
}

size_t gcp_block_advance_fo_gyro(struct gcp_block *b, const struct gcp_field *f,
                                 const struct gcp_pusher_type *p, const struct gcp_push_opts *o,
                                 const struct gcp_sampler *s, struct gcp_fo_gyro *gyro)
{
    if (p->advance != gcp_block_advance_fo_opts) return p->advance(b, f, p, o, s);
    return advance_fo(b, f, p, o->t0, o->dt, o->nsteps, s, gyro);
}

size_t gcp_block_advance_fo_opts(struct gcp_block *b, const struct gcp_field *f,
                                 const struct gcp_pusher_type *p, const struct gcp_push_opts *o,
                                 const struct gcp_sampler *s)
{
    return gcp_block_advance_fo(b, f, p, o->t0, o->dt, o->nsteps, s);
}

int gcp_arithmetic_fast_available(const struct gcp_pusher_type *p)
{
    return gcp_fo_fast_set(p) != NULL;
}

/* The same choice gcp_block_advance_fo makes (the fused tile of the
 * field's point form, the fast set's where it has one), made once. */
int gcp_arithmetic_fast_runs(const struct gcp_pusher_type *p, const struct gcp_field *f)
{
    const struct gcp_fo_fused *ff = gcp_fo_fast_set(p);
    struct gcp_point_B form;
    if (!ff || !p->fused || !gcp_field_point_B(f, &form) || form.form <= 0 ||
        form.form >= GCP_POINT_B_NFORMS)
        return 0;
    return ff->tile[form.form][form.has_E != 0] != NULL;
}

int gcp_orbit_push(const struct gcp_field *f, const struct gcp_pusher_type *p, double q, double m,
                   double *t, double x[3], double u[3], double dt, int64_t nsteps, gcp_step_cb cb,
                   void *ctx)
{
    struct gcp_block b;
    if (gcp_block_alloc(&b, 1)) return GCP_STEP_FAILED;
    b.q = q;
    b.m = m;
    b.x[0] = x[0], b.y[0] = x[1], b.z[0] = x[2];
    b.ux[0] = u[0], b.uy[0] = u[1], b.uz[0] = u[2];
    int status = GCP_ALIVE;
    if (!isfinite(x[0] + x[1] + x[2] + u[0] + u[1] + u[2])) status = GCP_NONFINITE;
    /* With a callback, one step per call; without, the whole run in one. */
    const int64_t chunk = cb ? 1 : nsteps;
    double tt = *t;
    for (int64_t k = 0; status == GCP_ALIVE && k < nsteps; k += chunk) {
        gcp_block_advance_fo(&b, f, p, tt, dt, chunk, NULL);
        tt = b.t[0];
        status = b.status[0];
        const double xs[3] = {b.x[0], b.y[0], b.z[0]}, us[3] = {b.ux[0], b.uy[0], b.uz[0]};
        if (cb && cb(tt, xs, us, ctx)) break;
    }
    *t = tt;
    x[0] = b.x[0], x[1] = b.y[0], x[2] = b.z[0];
    u[0] = b.ux[0], u[1] = b.uy[0], u[2] = b.uz[0];
    gcp_block_free(&b);
    return status;
}
