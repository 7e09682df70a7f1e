/* The output's event tables (/invariants, /losses, /hybrid/events): rows of
 * struct gcp_event, sorted by (id, t) whatever the rank count.  Layout:
 * DESIGN.md, "HDF5 output"; the writer that calls these: output.c. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <hdf5.h>

#include "gcpush/io.h"
#include "io_priv.h"
#include "output_events_priv.h"

static void attr_str(struct gcp_ev_writer *w, hid_t loc, const char *name, const char *value)
{
    gcp_h5_attr_str(&w->bad, loc, name, value);
}

static hid_t group(struct gcp_ev_writer *w, hid_t loc, const char *name)
{
    hid_t g = H5Gcreate2(loc, name, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    if (g < 0) w->bad = 1;
    return g;
}

/* ---- event tables (the /invariants tables, /losses) ------------------------------
 * A rank holds a variable number of events per particle.  The file keeps
 * them sorted by (id, t) whatever the rank count: the per-particle counts
 * of one table are summed over ranks (Allreduce of an N-vector), their
 * prefix sum gives each particle's first row, and each rank writes its rows
 * there (runs of consecutive rows, one hyperslab each) in one independent
 * write per column (the datasets are created collectively).  The rank's events are already sorted (id, kind, t). */
struct ev_sel {
    int64_t M;         /* rows in the file */
    int64_t n;         /* rows of this rank */
    int64_t *idx;      /* this rank's events of the table (indices into r->ev.e, or
                          r->ev.s where the kind is scalar) */
    int64_t *row;      /* their file rows (increasing) */
    int scalar;        /* the kind's events are r->ev.s (gcp_event_scalar) */
};

/* A table's row buffers, carved from one block of cap rows (EV_ROW bytes
 * each): the selection (idx, row) and the columns' staging (id, t, v, st). */
#define EV_ROW (5 * sizeof(int64_t) + GCP_EVENT_NV * sizeof(double) + sizeof(int32_t))
struct ev_bufs {
    int64_t *idx, *row, *id;
    double *t, *v;
    int32_t *st;
};
static struct ev_bufs ev_carve(void *block, int64_t cap)
{
    struct ev_bufs b;
    b.idx = block;
    b.row = b.idx + cap;
    b.id = b.row + cap;
    b.t = (double *)(b.id + cap);
    b.v = b.t + cap;
    b.st = (int32_t *)(b.v + cap * GCP_EVENT_NV);
    return b;
}

/* The kind of event k of a table, and its particle id. */
static int32_t ev_kind(const struct gcp_events *ev, int scalar, int64_t k)
{
    return scalar ? ev->s[k].kind : ev->e[k].kind;
}
static int64_t ev_id(const struct gcp_events *ev, int scalar, int64_t k)
{
    return scalar ? ev->s[k].id : ev->e[k].id;
}

int64_t *gcp_output_event_counts(const struct gcp_results *r, int64_t N, void **buf,
                                 int64_t *bufcap, MPI_Comm comm)
{
    *buf = NULL, *bufcap = 0;
    const int64_t K = GCP_EVENT_KINDS;
    if (N > ((int64_t)64 << 20) / (int64_t)sizeof(int64_t) / K) return NULL; /* same on every rank */
    int64_t *cnt = calloc((size_t)(K * N + 1), sizeof *cnt);
    int64_t nk[GCP_EVENT_KINDS] = {0}, cap = 1;
    for (int scalar = 0; scalar < 2 && cnt; scalar++)
        for (int64_t k = 0; k < (scalar ? r->ev.ns : r->ev.n); k++) {
            const int32_t kd = ev_kind(&r->ev, scalar, k);
            const int64_t id = ev_id(&r->ev, scalar, k);
            if (kd < 0 || kd >= K) continue;
            nk[kd]++;
            if (id >= 0 && id < N) cnt[kd * N + id]++;
        }
    for (int k = 0; k < K; k++) cap = nk[k] > cap ? nk[k] : cap;
    *buf = cnt ? malloc((size_t)cap * EV_ROW) : NULL;
    int64_t bad = !*buf;
    if (cnt) cnt[K * N] = bad;
    MPI_Allreduce(MPI_IN_PLACE, cnt ? cnt : &bad, cnt ? (int)(K * N + 1) : 1, MPI_INT64_T, MPI_SUM,
                  comm);
    if (cnt && !cnt[K * N]) {
        *bufcap = cap;
        return cnt;
    }
    free(cnt);
    free(*buf);
    *buf = NULL;
    return NULL;
}

/* Selects this rank's events of `kind` (into sel->idx, sel->row: set by the
 * caller) and their file rows; `local_bad` (the caller's own allocations)
 * joins the agreement.  With the writer's counts of every table (w->cnt,
 * gcp_output_event_counts) there is no collective here: one Allreduce for
 * all of the tables, where one per table (each a wait for the slower rank)
 * cost 2 ranks a few ms a table under load. */
static int ev_select(struct gcp_ev_writer *w, int kind, MPI_Comm comm, struct ev_sel *sel,
                     int local_bad)
{
    const struct gcp_results *r = w->r;
    const int64_t N = w->total;
    int64_t *cnt = w->cnt ? w->cnt + (int64_t)kind * N : calloc((size_t)(N + 1), sizeof *cnt);
    sel->scalar = gcp_event_scalar(kind);
    sel->n = 0;
    if (!w->cnt) {
        int bad = !cnt || local_bad;
        MPI_Allreduce(MPI_IN_PLACE, &bad, 1, MPI_INT, MPI_MAX, comm);
        if (bad) {
            free(cnt);
            return -1;
        }
    }
    const int64_t nev = sel->scalar ? r->ev.ns : r->ev.n;
    for (int64_t k = 0; k < nev; k++) {
        const int64_t id = ev_id(&r->ev, sel->scalar, k);
        if (ev_kind(&r->ev, sel->scalar, k) != kind || id < 0 || id >= N) continue;
        sel->idx[sel->n++] = k;
        if (!w->cnt) cnt[id]++;
    }
    if (!w->cnt) MPI_Allreduce(MPI_IN_PLACE, cnt, (int)N, MPI_INT64_T, MPI_SUM, comm);
    /* cnt -> first row of each particle (w->cnt: each kind's slice is
     * read by its one table) */
    int64_t acc = 0;
    for (int64_t i = 0; i < N; i++) {
        const int64_t c = cnt[i];
        cnt[i] = acc;
        acc += c;
    }
    sel->M = acc;
    for (int64_t j = 0; j < sel->n; j++) sel->row[j] = cnt[ev_id(&r->ev, sel->scalar, sel->idx[j])]++;
    if (!w->cnt) free(cnt);
    return 0;
}

/* Dataset `name` of shape {M, d1, d2} (rank 1..3): row j of this rank gets
 * per_row values of `data` (rank's rows contiguous, in order). */
static void write_ev_col(struct gcp_ev_writer *w, hid_t loc, const char *name, hid_t type, int rank,
                         hsize_t d1, hsize_t d2, const struct ev_sel *sel, const void *data,
                         const char *units)
{
    hsize_t dims[3] = {(hsize_t)sel->M, d1, d2};
    hid_t fspace = H5Screate_simple(rank, dims, NULL);
    hid_t dset = H5Dcreate2(loc, name, type, fspace, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    H5Sselect_none(fspace);
    int64_t k = 0;
    while (k < sel->n) {
        int64_t e = k + 1;
        while (e < sel->n && sel->row[e] == sel->row[e - 1] + 1) e++;
        hsize_t start[3] = {(hsize_t)sel->row[k], 0, 0};
        hsize_t count[3] = {(hsize_t)(e - k), rank > 1 ? d1 : 1, rank > 2 ? d2 : 1};
        H5Sselect_hyperslab(fspace, H5S_SELECT_OR, start, NULL, count, NULL);
        k = e;
    }
    const hsize_t per_row = (rank > 1 ? d1 : 1) * (rank > 2 ? d2 : 1);
    hsize_t mdims = (hsize_t)sel->n * per_row, one = 1;
    hid_t mspace = H5Screate_simple(1, mdims ? &mdims : &one, NULL);
    if (!mdims) H5Sselect_none(mspace);
    /* an empty table: nothing to write (every rank knows M) */
    if (dset < 0 || (sel->M && H5Dwrite(dset, type, mspace, fspace, w->dxpl, data) < 0)) w->bad = 1;
    if (dset >= 0 && units) attr_str(w, dset, "units", units);
    H5Sclose(mspace);
    H5Sclose(fspace);
    if (dset >= 0) H5Dclose(dset);
}


/* The reasons of /invariants/undefined as an HDF5 enum over int32. */
static hid_t undefined_type(struct gcp_ev_writer *w)
{
    hid_t et = H5Tenum_create(H5T_NATIVE_INT32);
    for (int32_t v = 0; v < GCP_UNDEF_COUNT; v++)
        if (et < 0 || H5Tenum_insert(et, gcp_undefined_name(v), &v) < 0) w->bad = 1;
    return et;
}

/* with_status: 0 no int column; 1 "status" (losses: enum gcp_status); 2
 * "mode" (method = hybrid: the mode of the sample that closed the event). */
void gcp_output_event_table(struct gcp_ev_writer *w, hid_t parent, const char *name, int kind,
                           const struct gcp_ev_col *cols, size_t ncols, int with_status,
                           MPI_Comm comm)
{
    const struct gcp_results *r = w->r;
    /* the rows' buffers: the writer's (w->buf, sized for the largest
     * table), else this table's own, whose failure joins the agreement in
     * ev_select */
    void *own = NULL;
    struct ev_bufs b;
    if (w->buf) {
        b = ev_carve(w->buf, w->bufcap);
    } else {
        int64_t nk = 0;
        if (gcp_event_scalar(kind))
            for (int64_t k = 0; k < r->ev.ns; k++) nk += r->ev.s[k].kind == kind;
        else
            for (int64_t k = 0; k < r->ev.n; k++) nk += r->ev.e[k].kind == kind;
        own = malloc((size_t)(nk ? nk : 1) * EV_ROW);
        b = own ? ev_carve(own, nk ? nk : 1) : (struct ev_bufs){0};
    }
    int64_t *id = b.id;
    int32_t *st = b.st;
    double *t = b.t, *v = b.v;
    struct ev_sel sel = {.idx = b.idx, .row = b.row};
    if (ev_select(w, kind, comm, &sel, !w->buf && !own)) {
        free(own);
        w->bad = 1;
        return;
    }
    hid_t g = group(w, parent, name);
    {
        for (int64_t j = 0; j < sel.n; j++) {
            if (sel.scalar) {
                const struct gcp_scalar_event *e = &r->ev.s[sel.idx[j]];
                id[j] = e->id, st[j] = e->status, t[j] = e->t;
            } else {
                const struct gcp_event *e = &r->ev.e[sel.idx[j]];
                id[j] = e->id, st[j] = e->status, t[j] = e->t;
            }
        }
        write_ev_col(w, g, "id", H5T_NATIVE_INT64, 1, 0, 0, &sel, id, NULL);
        write_ev_col(w, g, "t", H5T_NATIVE_DOUBLE, 1, 0, 0, &sel, t, "s");
        if (with_status == 1) write_ev_col(w, g, "status", H5T_NATIVE_INT32, 1, 0, 0, &sel, st, NULL);
        if (with_status == 2)
            write_ev_col(w, g, "mode", H5T_NATIVE_INT32, 1, 0, 0, &sel, st,
                         "0: guiding centre, 1: full orbit (gyro-averaged)");
        for (size_t c = 0; c < ncols; c++) {
            const size_t per = (cols[c].rank > 1 ? cols[c].d1 : 1) * (cols[c].rank > 2 ? cols[c].d2 : 1);
            if (cols[c].undef_enum) { /* rank 1: the reason codes as int32 */
                for (int64_t j = 0; j < sel.n; j++) st[j] = (int32_t)r->ev.e[sel.idx[j]].v[cols[c].slot];
                hid_t et = undefined_type(w);
                if (et >= 0) {
                    write_ev_col(w, g, cols[c].name, et, 1, 0, 0, &sel, st, NULL);
                    H5Tclose(et);
                }
                continue;
            }
            if (sel.scalar) /* one column, slot 0 */
                for (int64_t j = 0; j < sel.n; j++) v[j] = r->ev.s[sel.idx[j]].v;
            else
                for (int64_t j = 0; j < sel.n; j++)
                    memcpy(&v[(size_t)j * per], &r->ev.e[sel.idx[j]].v[cols[c].slot], per * sizeof *v);
            write_ev_col(w, g, cols[c].name, H5T_NATIVE_DOUBLE, cols[c].rank, cols[c].d1,
                         cols[c].d2, &sel, v, cols[c].units);
        }
    }
    free(own);
    H5Gclose(g);
}

/* The /invariants group (sc asked for something): every table, and the
 * attributes that say when rows come and when not. */
void gcp_output_invariants(struct gcp_ev_writer *w, const struct gcp_scene *sc, MPI_Comm comm)
{
    const unsigned inv = sc->invariants, evt = sc->events;
    const int bounce = (inv & (GCP_INV_J | GCP_INV_K)) || (evt & GCP_EVT_BOUNCE);
    const int drift = (inv & GCP_INV_L) || (evt & GCP_EVT_DRIFT);
    /* method = hybrid: every /invariants table says which mode made each row */
    const int mode = sc->hybrid ? 2 : 0;
    if (bounce || drift || (inv & (GCP_INV_MU | GCP_INV_ENERGY | GCP_INV_PPHI))) {
        hid_t g = group(w, w->file, "invariants");
        /* when the events come, and when they do not (issue 13) */
        char sampling[1536];
        snprintf(sampling, sizeof sampling,
                 "mu, energy, pphi: at each equator point (the minimum of |B| between two "
                 "mirror points); bounce (J, K): between two mirror points of the same kind; "
                 "drift (L*, Phi): per turn of the azimuth of the equator points (contour 0), "
                 "or, for a particle whose equator points made no turn (equatorially "
                 "mirroring, passing), of the guiding centre sampled every %lld steps and "
                 "every pi/4 of azimuth (contour 1). A particle with no equator point gets, "
                 "if mu, energy or pphi is asked, rows in /invariants/samples at t0 + k * "
                 "%lld dt (k = 1, 2, ...; dt its population's step; [diagnostics] "
                 "sample_every), interpolated linearly between guiding-centre samples, and "
                 "no equator rows; /invariants/undefined says per particle why an asked "
                 "quantity has no row. Full orbits: guiding-centre samples are the "
                 "first-order guiding centre averaged over each gyration (mu: the "
                 "zeroth-order p_perp^2/(2 m B) at that guiding centre, gyro-averaged)%s",
                 (long long)sc->sample_every, (long long)sc->sample_every,
                 sc->hybrid ? "; method = hybrid: column mode says whether the sample that "
                              "closed a row was a guiding-centre step (0) or a gyration of a "
                              "full-orbit stretch (1)" : "");
        attr_str(w, g, "sampling", sampling);
        if (bounce) {
            static const struct gcp_ev_col c[] = {
                {"period", GCP_BOUNCE_PERIOD, 1, 0, 0, "s", 0},
                {"J", GCP_BOUNCE_J, 1, 0, 0, "kg m^2/s", 0},
                {"K", GCP_BOUNCE_K, 1, 0, 0, "T^0.5 m", 0},
                {"mirror_lat", GCP_BOUNCE_LAT, 2, 2, 0, "rad", 0},
                {"mirror_B", GCP_BOUNCE_BM, 2, 2, 0, "T", 0},
                {"mirror_x", GCP_BOUNCE_X, 3, 2, 3, "m", 0},
                {"mu", GCP_BOUNCE_MU, 1, 0, 0, "J/T", 0}};
            gcp_output_event_table(w, g, "bounce", GCP_EVENT_BOUNCE, c, sizeof c / sizeof c[0], mode, comm);
        }
        if (drift) {
            static const struct gcp_ev_col c[] = {
                {"period", GCP_DRIFT_PERIOD, 1, 0, 0, "s", 0},
                {"Lstar", GCP_DRIFT_LSTAR, 1, 0, 0, "1", 0},
                {"Phi", GCP_DRIFT_PHI, 1, 0, 0, "T m^2", 0},
                {"contour", GCP_DRIFT_CONTOUR, 1, 0, 0,
                 "0: equator points, 1: guiding centre on the cadence (no equator turn)", 0}};
            gcp_output_event_table(w, g, "drift", GCP_EVENT_DRIFT, c, 4, mode, comm);
            /* say why a column is NaN throughout (issue 13) */
            if (!(gcp_field_caps(sc->field) & GCP_CAP_A)) {
                char why[256];
                snprintf(why, sizeof why,
                         "Lstar and Phi are NaN: Phi = |oint A.dl| needs the field's vector "
                         "potential, which the %s model does not give", sc->field_model);
                hid_t gd = H5Gopen2(g, "drift", H5P_DEFAULT);
                if (gd >= 0) {
                    attr_str(w, gd, "Lstar_undefined", why);
                    H5Gclose(gd);
                }
            }
        }
        if (inv & GCP_INV_MU) {
            static const struct gcp_ev_col c[] = {{"mu", 0, 1, 0, 0, "J/T", 0}};
            gcp_output_event_table(w, g, "mu", GCP_EVENT_MU, c, 1, mode, comm);
        }
        if (inv & GCP_INV_ENERGY) {
            static const struct gcp_ev_col c[] = {{"energy", 0, 1, 0, 0, "J", 0}};
            gcp_output_event_table(w, g, "energy", GCP_EVENT_ENERGY, c, 1, mode, comm);
        }
        if (inv & GCP_INV_PPHI) {
            static const struct gcp_ev_col c[] = {{"pphi", 0, 1, 0, 0, "kg m^2/s", 0}};
            gcp_output_event_table(w, g, "pphi", GCP_EVENT_PPHI, c, 1, mode, comm);
        }
        if (inv & (GCP_INV_MU | GCP_INV_ENERGY | GCP_INV_PPHI)) {
            /* particles with no equator point, on a time cadence: the asked columns */
            static const struct gcp_ev_col all[] = {{"mu", 0, 1, 0, 0, "J/T", 0},
                                                {"energy", 1, 1, 0, 0, "J", 0},
                                                {"pphi", 2, 1, 0, 0, "kg m^2/s", 0}};
            static const unsigned bit[] = {GCP_INV_MU, GCP_INV_ENERGY, GCP_INV_PPHI};
            struct gcp_ev_col c[3];
            size_t nc = 0;
            for (size_t k = 0; k < 3; k++)
                if (inv & bit[k]) c[nc++] = all[k];
            gcp_output_event_table(w, g, "samples", GCP_EVENT_SAMPLE, c, nc, mode, comm);
        }
        {
            /* per particle with an asked quantity missing: why (enum columns) */
            static const struct gcp_ev_col c[] = {{"bounce", GCP_UNDEF_BOUNCE, 1, 0, 0, NULL, 1},
                                              {"equator", GCP_UNDEF_EQUATOR, 1, 0, 0, NULL, 1},
                                              {"drift", GCP_UNDEF_DRIFT, 1, 0, 0, NULL, 1},
                                              {"Lstar", GCP_UNDEF_LSTAR, 1, 0, 0, NULL, 1}};
            gcp_output_event_table(w, g, "undefined", GCP_EVENT_UNDEFINED, c, 4, 0, comm);
            hid_t gu = H5Gopen2(g, "undefined", H5P_DEFAULT);
            if (gu >= 0) {
                attr_str(w, gu, "reasons",
                         "per particle (id) with an asked quantity missing, at the end of its "
                         "push (t): bounce (period, J, K), equator (mu, energy, pphi rows), "
                         "drift (period), Lstar (L*, Phi): DEFINED; NOT_ASKED; NO_MIRROR (p_par "
                         "never changed sign: passing orbit, uniform field); NO_BOUNCE (mirror "
                         "points but no full bounce: push too short or stopped); NO_EQUATOR (no "
                         "|B| minimum between mirror points: equatorially mirroring or no "
                         "bounce; see /invariants/samples); NO_TURN (the azimuth did not turn "
                         "by 2 pi); NO_POTENTIAL (the field gives no vector potential, e.g. "
                         "igrf: Phi and L* NaN)");
                H5Gclose(gu);
            }
        }
        H5Gclose(g);
    }
}
