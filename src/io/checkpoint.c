/* Checkpoints: each rank saves the rows of the chunks it finished to its own
 * file OUT.ckpt.RANK (written to a temporary name, then renamed, so a kill
 * mid-write leaves the previous checkpoint intact).  Ranks write whenever
 * they like, with no collective call, so a checkpoint never waits for the
 * slowest rank.  A restart, with any number of ranks, loads every such file,
 * keeps one copy of each chunk, and pushes only the chunks nobody finished;
 * particles depend only on (seed, id), so the final file equals the one an
 * uninterrupted run writes (timings aside).
 *
 * Format (native byte order; the same machine family writes and reads):
 *   "GCPCKPT3" (3: with the step_failure column), int64 S, int64 rows,
 *   int64 len, run text, int64 len, run path, double rank_cpu, then each
 *   column of struct gcp_results in table order, then int64 events and the
 *   events (struct gcp_event, invariants.h). */
#include <errno.h>
#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/io.h"
#include "io_priv.h"

static const char magic[8] = {'G', 'C', 'P', 'C', 'K', 'P', 'T', '3'};

static int put(FILE *fp, const void *p, size_t n) { return fwrite(p, 1, n, fp) == n ? 0 : -1; }
static int get(FILE *fp, void *p, size_t n) { return fread(p, 1, n, fp) == n ? 0 : -1; }

int gcp_checkpoint_write(const struct gcp_scene *sc, struct gcp_results *r, int rank,
                         struct gcp_error *err)
{
    char path[1200], tmp[1300];
    snprintf(path, sizeof path, "%s.ckpt.%d", sc->output, rank);
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
    FILE *fp = fopen(tmp, "wb");
    if (!fp) return gcp_error_set(err, GCP_ERR_IO, "%s: cannot write checkpoint: %s", tmp, strerror(errno));
    const int64_t tl = (int64_t)strlen(sc->text), pl = (int64_t)strlen(sc->path);
    int bad = put(fp, magic, sizeof magic) | put(fp, &r->S, sizeof r->S) |
              put(fp, &r->n, sizeof r->n) | put(fp, &tl, sizeof tl) | put(fp, sc->text, (size_t)tl) |
              put(fp, &pl, sizeof pl) | put(fp, sc->path, (size_t)pl) |
              put(fp, &r->rank_cpu, sizeof r->rank_cpu);
    struct gcp_results_column c[GCP_RESULTS_MAX_COLUMNS];
    const size_t nc = gcp_results_columns(r, c);
    for (size_t k = 0; k < nc && r->n; k++)
        bad |= put(fp, *c[k].data, (size_t)r->n * (size_t)c[k].per_row * c[k].elem);
    /* every event as a struct gcp_event (the scalar ones widened) */
    const int64_t nev = r->ev.n + r->ev.ns;
    bad |= put(fp, &nev, sizeof nev);
    if (r->ev.n) bad |= put(fp, r->ev.e, (size_t)r->ev.n * sizeof *r->ev.e);
    for (int64_t k = r->ev.n; k < nev && !bad; k++) {
        const struct gcp_event e = gcp_events_get(&r->ev, k);
        bad |= put(fp, &e, sizeof e);
    }
    bad |= fflush(fp) != 0;
    bad |= fclose(fp) != 0;
    if (bad || rename(tmp, path) != 0) {
        remove(tmp);
        return gcp_error_set(err, GCP_ERR_IO, "%s: writing the checkpoint failed", path);
    }
    return 0;
}

/* Reads the header: run text and path (malloc'ed), S and rows. */
static int read_header(FILE *fp, char **text, char **path, int64_t *S, int64_t *rows,
                       double *cpu)
{
    char m[8];
    int64_t tl, pl;
    *text = *path = NULL;
    if (get(fp, m, 8) || memcmp(m, magic, 8) || get(fp, S, sizeof *S) || get(fp, rows, sizeof *rows) ||
        get(fp, &tl, sizeof tl) || tl < 0 || tl > (1 << 24))
        return -1;
    if (!(*text = malloc((size_t)tl + 1)) || get(fp, *text, (size_t)tl)) return -1;
    (*text)[tl] = '\0';
    if (get(fp, &pl, sizeof pl) || pl < 0 || pl > 4096) return -1;
    if (!(*path = malloc((size_t)pl + 1)) || get(fp, *path, (size_t)pl)) return -1;
    (*path)[pl] = '\0';
    if (get(fp, cpu, sizeof *cpu) || *S < 0 || *rows < 0) return -1;
    return 0;
}

/* Whether s is one or more decimal digits and nothing else. */
static int all_digits(const char *s)
{
    if (!*s) return 0;
    for (; *s; s++)
        if (*s < '0' || *s > '9') return 0;
    return 1;
}

/* Whether directory entry `name` is, for output base name `base`, a
 * checkpoint (OUT.ckpt.N) or, with stale set, a temporary an interrupted
 * run left (OUT.tmp-PID of the output write, OUT.ckpt.N.tmp of a checkpoint
 * write).  Exact names, no glob: the output name may hold '*' or '[', and
 * OUT.ckpt.0.bak is somebody else's file. */
static int ours(const char *name, const char *base, int stale)
{
    const size_t bl = strlen(base);
    if (strncmp(name, base, bl) != 0) return 0;
    const char *rest = name + bl;
    if (!stale) return strncmp(rest, ".ckpt.", 6) == 0 && all_digits(rest + 6);
    if (strncmp(rest, ".tmp-", 5) == 0) return all_digits(rest + 5);
    if (strncmp(rest, ".ckpt.", 6) != 0) return 0;
    const size_t rl = strlen(rest + 6);
    char digits[64];
    if (rl <= 4 || rl - 4 >= sizeof digits || strcmp(rest + 6 + rl - 4, ".tmp") != 0) return 0;
    memcpy(digits, rest + 6, rl - 4);
    digits[rl - 4] = '\0';
    return all_digits(digits);
}

static int cmp_str(const void *a, const void *b)
{
    return strcmp(*(char *const *)a, *(char *const *)b);
}

/* The files next to `output` that ours() accepts, sorted by name. */
static int list_ours(const char *output, int stale, char ***files, size_t *n)
{
    *files = NULL;
    *n = 0;
    const char *slash = strrchr(output, '/');
    const char *base = slash ? slash + 1 : output;
    const size_t dl = slash ? (size_t)(slash - output) + 1 : 0; /* "dir/" kept as given */
    char dir[1100];
    if (dl + 2 > sizeof dir) return GCP_ERR_IO;
    if (dl) {
        memcpy(dir, output, dl);
        dir[dl] = '\0';
    } else {
        strcpy(dir, ".");
    }
    DIR *d = opendir(dir);
    if (!d) return errno == ENOENT ? 0 : GCP_ERR_IO;
    size_t cap = 8, k = 0;
    char **out = malloc(cap * sizeof *out);
    int rc = out ? 0 : GCP_ERR_NOMEM;
    for (struct dirent *e; !rc && (e = readdir(d));) {
        if (!ours(e->d_name, base, stale)) continue;
        if (k + 1 == cap) {
            char **more = realloc(out, (cap *= 2) * sizeof *out);
            if (!more) {
                rc = GCP_ERR_NOMEM;
                break;
            }
            out = more;
        }
        const size_t len = dl + strlen(e->d_name) + 1;
        if (!(out[k] = malloc(len))) {
            rc = GCP_ERR_NOMEM;
            break;
        }
        memcpy(out[k], output, dl);
        strcpy(out[k] + dl, e->d_name);
        k++;
    }
    closedir(d);
    if (rc) {
        for (size_t i = 0; i < k; i++) free(out[i]);
        free(out);
        return rc;
    }
    qsort(out, k, sizeof *out, cmp_str);
    out[k] = NULL;
    *files = out;
    *n = k;
    return 0;
}

int gcp_checkpoint_list(const char *output, char ***files, size_t *n)
{
    return list_ours(output, 0, files, n);
}

int gcp_output_stale_list(const char *output, char ***files, size_t *n)
{
    return list_ours(output, 1, files, n);
}

int gcp_checkpoint_read_text(const char *file, char **text, char **path, struct gcp_error *err)
{
    FILE *fp = fopen(file, "rb");
    if (!fp) return gcp_error_set(err, GCP_ERR_IO, "%s: cannot open: %s", file, strerror(errno));
    int64_t S, rows;
    double cpu;
    int bad = read_header(fp, text, path, &S, &rows, &cpu);
    fclose(fp);
    if (bad) {
        free(*text);
        free(*path);
        *text = *path = NULL;
        return gcp_error_set(err, GCP_ERR_IO, "%s: not a gcpush checkpoint or truncated", file);
    }
    return 0;
}

/* Bytes from the current position to the end of the file; -1 on error. */
static int64_t bytes_left(FILE *fp)
{
    const long here = ftell(fp);
    if (here < 0 || fseek(fp, 0, SEEK_END) != 0) return -1;
    const long end = ftell(fp);
    if (end < 0 || fseek(fp, here, SEEK_SET) != 0) return -1;
    return (int64_t)end - (int64_t)here;
}

int gcp_checkpoint_load(const char *file, const struct gcp_scene *sc, struct gcp_results *r,
                        struct gcp_error *err)
{
    FILE *fp = fopen(file, "rb");
    if (!fp) return gcp_error_set(err, GCP_ERR_IO, "%s: cannot open: %s", file, strerror(errno));
    char *text = NULL, *path = NULL;
    int64_t S, rows;
    double cpu;
    struct gcp_results part;
    gcp_results_init(&part, r->S, r->gc);
    part.hybrid = r->hybrid;
    int bad = read_header(fp, &text, &path, &S, &rows, &cpu);
    bad = bad || strcmp(text, sc->text) != 0 || S != r->S;
    /* every size read from the file is checked against what the file holds
     * and what the run has, before anything is allocated for it */
    int64_t left = bad ? 0 : bytes_left(fp);
    if (!bad) {
        struct gcp_results_column c[GCP_RESULTS_MAX_COLUMNS];
        const size_t nc = gcp_results_columns(&part, c);
        int64_t row_bytes = 0;
        for (size_t k = 0; k < nc; k++) row_bytes += c[k].per_row * (int64_t)c[k].elem;
        bad = rows > sc->total || left < 0 || rows > left / row_bytes ||
              gcp_results_reserve(&part, rows);
        for (size_t k = 0; k < nc && !bad; k++)
            bad = get(fp, *c[k].data, (size_t)rows * (size_t)c[k].per_row * c[k].elem);
        if (!bad) { /* rows is known to fit the file now */
            left -= rows * row_bytes;
            part.n = rows;
        }
        part.rank_cpu = cpu;
        int64_t nev = -1;
        bad = bad || get(fp, &nev, sizeof nev) || nev < 0 ||
              nev > (left - (int64_t)sizeof nev) / (int64_t)sizeof(struct gcp_event);
        for (int64_t k = 0; k < nev && !bad; k++) {
            struct gcp_event e;
            bad = get(fp, &e, sizeof e) || gcp_events_push(&part.ev, &e);
        }
        for (int64_t i = 0; i < rows && !bad; i++)
            bad = part.id[i] < 0 || part.id[i] >= sc->total || part.pop[i] < 0 ||
                  (size_t)part.pop[i] >= sc->npop;
    }
    fclose(fp);
    free(text);
    free(path);
    if (!bad) bad = gcp_results_append(r, &part) != 0;
    gcp_results_free(&part);
    if (bad)
        return gcp_error_set(err, GCP_ERR_IO,
                             "%s: truncated, corrupt, or from a different run file", file);
    return 0;
}
