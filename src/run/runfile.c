/* Run file -> sections.
 *
 * The file is read whole (its text goes into the output), split into
 * sections with libinih, and each consumer fetches its keys through
 * section.h, so that unknown keys and sections are errors naming the line.
 * libinih is fed through a line reader that counts lines (Debian's libinih
 * has no line numbers in the handler) and strips '#' comments, which
 * libinih only knows at the start of a line. */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <ini.h>

#include "gcpush/kernels.h"
#include "gcpush/run.h"
#include "run_priv.h"

/* ---- reading ----------------------------------------------------------- */

struct reader {
    const char *p;  /* next character of the text */
    int line;       /* lines handed to libinih so far */
    int too_long;   /* line number of a line longer than libinih's buffer, 0: none */
};

struct parse_state {
    struct reader rd;
    struct gcp_run_file *rf;
    struct gcp_error *err;
    struct header { char *name; int line; } *hdr; /* section headers seen */
    size_t nhdr;
};

/* A second [name] header: merged, its keys looked like one section's while
 * the reader meant two (or one was pasted twice with different values). */
static int header_seen(struct parse_state *ps, const char *section)
{
    const int line = ps->rd.line;
    for (size_t i = 0; i < ps->nhdr; i++)
        if (strcmp(ps->hdr[i].name, section) == 0)
            return gcp_error_set(ps->err, GCP_ERR_SYNTAX,
                                 "%s:%d: [%s]: section given twice (first on line %d)",
                                 ps->rf->path, line, section, ps->hdr[i].line);
    struct header *h = realloc(ps->hdr, (ps->nhdr + 1) * sizeof *h);
    if (!h) return gcp_error_set(ps->err, GCP_ERR_NOMEM, "out of memory");
    ps->hdr = h;
    if (!(h[ps->nhdr].name = strdup(section)))
        return gcp_error_set(ps->err, GCP_ERR_NOMEM, "out of memory");
    h[ps->nhdr++].line = line;
    return 0;
}

/* Hands libinih one line without its '#' comment.  A line whose text
 * before the comment does not fit libinih's buffer (199 characters) ends
 * the parse, so gcp_run_file_parse rejects it: cut, `seed = 7<spaces>99`
 * gave seed 7.  Line ends: "\n", "\r\n", and a lone "\r" (old Mac files
 * read as a single line otherwise). */
static char *read_line(char *str, int num, void *stream)
{
    struct reader *r = stream; /* the first member of struct parse_state */
    if (!*r->p) return NULL;
    int k = 0, comment = 0;
    for (; *r->p && *r->p != '\n' && *r->p != '\r'; r->p++) {
        if (*r->p == '#') comment = 1;
        if (comment) continue;
        if (k == num - 1) {
            if (*r->p == ' ' || *r->p == '\t') continue; /* blanks before a comment */
            r->too_long = r->line + 1;
            return NULL;
        }
        str[k++] = *r->p;
    }
    if (*r->p == '\r') {
        r->p++;
        if (*r->p == '\n') r->p++; /* "\r\n": one line end */
    } else if (*r->p == '\n') {
        r->p++;
    }
    str[k] = '\0';
    r->line++;
    /* libinih (Debian's) does not report headers: a header is a line
     * starting, blanks aside, with '[' (libinih's own rule) */
    const char *h = str + strspn(str, " \t");
    const char *close = strchr(h, ']');
    if (*h == '[' && close) {
        char name[256];
        snprintf(name, sizeof name, "%.*s", (int)(close - h - 1), h + 1);
        if (header_seen((struct parse_state *)stream, name)) return NULL;
    }
    return str;
}

static struct gcp_section *section_named(struct gcp_run_file *rf, const char *name)
{
    for (size_t i = 0; i < rf->nsec; i++)
        if (strcmp(rf->sec[i].name, name) == 0) return &rf->sec[i];
    return NULL;
}

static struct gcp_section *add_section(struct gcp_run_file *rf, const char *name, int line)
{
    if (rf->nsec == rf->capsec) {
        size_t cap = rf->capsec ? 2 * rf->capsec : 8;
        struct gcp_section *s = realloc(rf->sec, cap * sizeof *s);
        if (!s) return NULL;
        rf->sec = s;
        rf->capsec = cap;
    }
    struct gcp_section *s = &rf->sec[rf->nsec];
    memset(s, 0, sizeof *s);
    s->file = rf->path;
    s->line = line;
    if (!(s->name = strdup(name))) return NULL;
    rf->nsec++;
    return s;
}

static int on_key(void *user, const char *section, const char *name, const char *value)
{
    struct parse_state *ps = user;
    struct gcp_run_file *rf = ps->rf;
    const int line = ps->rd.line;
    if (!section[0]) {
        gcp_error_set(ps->err, GCP_ERR_SYNTAX, "%s:%d: %s: key outside any [section]", rf->path,
                      line, name);
        return 0;
    }
    if (!name) return 1; /* a new section header: created lazily below */
    struct gcp_section *s = section_named(rf, section);
    if (!s && !(s = add_section(rf, section, line))) {
        gcp_error_set(ps->err, GCP_ERR_NOMEM, "out of memory");
        return 0;
    }
    for (size_t i = 0; i < s->n; i++) {
        if (strcmp(s->kv[i].key, name) == 0) {
            gcp_error_set(ps->err, GCP_ERR_SYNTAX,
                          "%s:%d: [%s] %s: key given twice (first on line %d)", rf->path, line,
                          section, name, s->kv[i].line);
            return 0;
        }
    }
    if (s->n == s->cap) {
        size_t cap = s->cap ? 2 * s->cap : 8;
        struct gcp_keyval *kv = realloc(s->kv, cap * sizeof *kv);
        if (!kv) return 0;
        s->kv = kv;
        s->cap = cap;
    }
    struct gcp_keyval *kv = &s->kv[s->n];
    kv->key = strdup(name);
    kv->value = strdup(value);
    kv->line = line;
    kv->used = 0;
    if (!kv->key || !kv->value) {
        free(kv->key);
        free(kv->value);
        gcp_error_set(ps->err, GCP_ERR_NOMEM, "out of memory");
        return 0;
    }
    s->n++;
    return 1;
}

int gcp_run_file_parse(const char *path, const char *text, struct gcp_run_file *rf,
                       struct gcp_error *err)
{
    memset(rf, 0, sizeof *rf);
    rf->path = path;
    struct parse_state ps = {.rd = {.p = text, .line = 0}, .rf = rf, .err = err};
    int rc = ini_parse_stream(read_line, &ps.rd, on_key, &ps);
    for (size_t i = 0; i < ps.nhdr; i++) free(ps.hdr[i].name);
    free(ps.hdr);
    if (err && err->code) return err->code;
    if (ps.rd.too_long)
        return gcp_error_set(err, GCP_ERR_SYNTAX,
                             "%s:%d: line longer than 199 characters (comments aside)", path,
                             ps.rd.too_long);
    if (rc > 0)
        return gcp_error_set(err, GCP_ERR_SYNTAX,
                             "%s:%d: syntax error: expected [section], key = value, or a comment",
                             path, rc);
    if (rc < 0) return gcp_error_set(err, GCP_ERR_NOMEM, "%s: out of memory", path);
    return 0;
}

struct gcp_section *gcp_run_file_section(struct gcp_run_file *rf, const char *name)
{
    return section_named(rf, name);
}

void gcp_run_file_free(struct gcp_run_file *rf)
{
    for (size_t i = 0; i < rf->nsec; i++) {
        for (size_t k = 0; k < rf->sec[i].n; k++) {
            free(rf->sec[i].kv[k].key);
            free(rf->sec[i].kv[k].value);
        }
        free(rf->sec[i].kv);
        free(rf->sec[i].name);
    }
    free(rf->sec);
    memset(rf, 0, sizeof *rf);
}

int gcp_read_text(const char *path, char **text, struct gcp_error *err)
{
    *text = NULL;
    FILE *fp = fopen(path, "rb");
    if (!fp) return gcp_error_set(err, GCP_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    size_t cap = 4096, n = 0;
    char *buf = malloc(cap);
    for (;;) {
        if (!buf) {
            fclose(fp);
            return gcp_error_set(err, GCP_ERR_NOMEM, "%s: out of memory", path);
        }
        n += fread(buf + n, 1, cap - n - 1, fp);
        if (n < cap - 1) break;
        if (cap > ((size_t)1 << 24)) {
            free(buf);
            fclose(fp);
            return gcp_error_set(err, GCP_ERR_VALUE, "%s: run file larger than 16 MiB", path);
        }
        char *nb = realloc(buf, cap *= 2);
        if (!nb) free(buf);
        buf = nb;
    }
    int bad = ferror(fp);
    fclose(fp);
    if (bad) {
        free(buf);
        return gcp_error_set(err, GCP_ERR_IO, "%s: read error", path);
    }
    buf[n] = '\0';
    if (strlen(buf) != n) {
        free(buf);
        return gcp_error_set(err, GCP_ERR_SYNTAX, "%s: contains a NUL byte (not a text file)",
                             path);
    }
    *text = buf;
    return 0;
}
