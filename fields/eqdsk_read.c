/* The `eqdsk` field model's reader: a G-EQDSK file to the model's
 * parameters (eqdsk_priv.h); the evaluation is eqdsk.c's.
 *
 * Format (EFIT g-file; gafusion/EFIT docs/files.rst): line 1 is 48
 * characters of text then `idum nw nh`; then Fortran records written with
 * format (5e16.9): 20 header reals
 *   rdim zdim rcentr rleft zmid / rmaxis zmaxis simag sibry bcentr /
 *   current simag xdum rmaxis xdum / zmaxis xdum sibry xdum xdum,
 * then fpol(nw), pres(nw), ffprim(nw), pprime(nw), psirz(nw*nh) (R fastest,
 * Z from zmid - zdim/2 up), qpsi(nw), each array starting on a new line;
 * then `nbbbs limitr` and the boundary and limiter (R, Z) pairs.  Numbers are
 * read as fixed 16-character fields: negative numbers may run together
 * ("-1.0e+00-2.0e+00"), so splitting on white space would be wrong.
 *
 * Signs (COCOS, Sauter & Medvedev, Comput. Phys. Commun. 184 (2013) 293).
 * For psi in Wb/rad (COCOS 1..8), with sigma_Bp, sigma_RphiZ, sigma_rhothetaphi
 * of the file's convention:
 *   B_pol = sigma_Bp grad(phi_f) x grad(psi),  B_phi_f = F / R,
 * where phi_f is the file's toroidal angle: phi_f = phi (gcpush's
 * right-handed (R, phi, Z), phi = atan2(y, x)) when sigma_RphiZ = +1 and
 * phi_f = -phi when -1.  In gcpush's frame, with grad(phi) x Rhat = -Zhat/R
 * and grad(phi) x Zhat = Rhat/R:
 *   B_R = -s_pol (1/R) dpsi/dZ,  B_Z = s_pol (1/R) dpsi/dR,  B_phi = s_tor F/R,
 *   s_pol = -sigma_Bp sigma_RphiZ,  s_tor = sigma_RphiZ.
 * Identification from the file (when no `cocos` key is given): the
 * g-file is taken to be written in a right-handed (R, phi, Z)
 * (sigma_RphiZ = +1, odd COCOS, as EFIT writes it), and
 *   sign(sibry - simag) = sigma_Ip sigma_Bp,
 *   sign(q) = sigma_Ip sigma_B0 sigma_rhothetaphi,
 * with sigma_Ip = sign(current), sigma_B0 = sign(bcentr).  The shipped
 * DIII-D file (current < 0, bcentr < 0, psi increasing, q > 0) gives
 * sigma_Bp = -1, sigma_rhothetaphi = +1: COCOS 7, i.e.
 *   B_R = -(1/R) dpsi/dZ,  B_Z = +(1/R) dpsi/dR,  B_phi = fpol/R.
 * gcp_field_psi returns s_pol psi_file: gcpush's psi = R A_phi, so that
 * p_phi = q psi + m R u_phi is the conserved canonical momentum.
 */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "eqdsk_priv.h"
#include "field_priv.h"
#include "gcpush/particles.h"

/* ---- reading ------------------------------------------------------------- */

struct reader {
    const char *path;
    char *text;     /* whole file */
    char *pos;      /* start of the next line */
    int line;       /* number of the next line (1-based) */
};

/* Next line: returns its start, NUL-terminates it (drops "\r\n"), or NULL. */
static char *next_line(struct reader *r, size_t *len)
{
    if (!r->pos || !*r->pos) return NULL;
    char *s = r->pos, *e = strchr(s, '\n');
    if (e) {
        *e = '\0';
        r->pos = e + 1;
    } else {
        r->pos = s + strlen(s);
    }
    size_t n = strlen(s);
    while (n > 0 && (s[n - 1] == '\r' || s[n - 1] == ' ' || s[n - 1] == '\t')) s[--n] = '\0';
    *len = n;
    r->line++;
    return s;
}

/* Reads n reals as Fortran (5e16.9): starting on a new line, 16-character
 * fields, 5 per line. */
static int read_reals(struct reader *r, size_t n, double *v, const char *what,
                      struct gcp_error *err)
{
    size_t k = 0;
    while (k < n) {
        size_t len;
        char *s = next_line(r, &len);
        if (!s)
            return gcp_error_set(err, GCP_ERR_VALUE,
                                 "%s: end of file while reading %s (%zu of %zu values)", r->path,
                                 what, k, n);
        const size_t want = n - k < 5 ? n - k : 5;
        for (size_t j = 0; j < want; j++) {
            char fld[17];
            const size_t off = 16 * j;
            if (off >= len)
                return gcp_error_set(err, GCP_ERR_VALUE,
                                     "%s:%d: %s: expected %zu numbers of 16 characters on this "
                                     "line, found %zu",
                                     r->path, r->line, what, want, j);
            size_t w = len - off < 16 ? len - off : 16;
            memcpy(fld, s + off, w);
            fld[w] = '\0';
            /* Fortran D exponents */
            for (size_t c = 0; c < w; c++)
                if (fld[c] == 'D' || fld[c] == 'd') fld[c] = 'e';
            char *end;
            errno = 0;
            const double x = strtod(fld, &end);
            while (*end == ' ') end++;
            if (end == fld || *end != '\0' || !isfinite(x))
                return gcp_error_set(err, GCP_ERR_VALUE,
                                     "%s:%d: %s: cannot read a number from columns %zu-%zu "
                                     "('%s')",
                                     r->path, r->line, what, off + 1, off + w, fld);
            v[k++] = x;
        }
    }
    return 0;
}

static int read_file(const char *path, char **out, struct gcp_error *err)
{
    FILE *fp = fopen(path, "rb");
    if (!fp) return gcp_error_set(err, GCP_ERR_IO, "%s: cannot open g-file (no such file?)", path);
    size_t cap = 1 << 16, n = 0;
    char *buf = malloc(cap);
    while (buf) {
        if (n + 4096 + 1 > cap) {
            char *nb = realloc(buf, cap *= 2);
            if (!nb) {
                free(buf);
                buf = NULL;
                break;
            }
            buf = nb;
        }
        size_t got = fread(buf + n, 1, 4096, fp);
        n += got;
        if (got == 0) break;
    }
    fclose(fp);
    if (!buf) return gcp_error_set(err, GCP_ERR_NOMEM, "%s: out of memory", path);
    buf[n] = '\0';
    *out = buf;
    return 0;
}

int gcp_field_eqdsk_load(const char *path, int cocos, struct gcp_field **out,
                         struct gcp_error *err)
{
    return gcp_eqdsk_load_kind(path, cocos, GCP_SPL_SEPTIC, out, err);
}

int gcp_eqdsk_load_kind(const char *path, int cocos, int kind, struct gcp_field **out,
                        struct gcp_error *err)
{
    *out = NULL;
    if (kind != GCP_SPL_SEPTIC && kind != GCP_SPL_QUINTIC)
        return gcp_error_set(err, GCP_ERR_STATE, "eqdsk: spline kind %d", kind);
    if (cocos < 0 || cocos > 8)
        return gcp_error_set(err, GCP_ERR_VALUE, "eqdsk: cocos must be 1..8 (or 0: identify), "
                             "got %d", cocos);
    struct reader r = {path, NULL, NULL, 0};
    int rc = read_file(path, &r.text, err);
    if (rc) return rc;
    r.pos = r.text;
    double *buf = NULL, *psirz = NULL;
    struct eqdsk_params *e = NULL;
    size_t len;
    char *l1 = next_line(&r, &len);
    int nw = 0, nh = 0;
    {
        /* after the 48-character description: idum nw nh (the last three integers) */
        long vals[8];
        int nv = 0;
        const char *s = len > 48 ? l1 + 48 : "";
        while (*s && nv < 8) {
            char *end;
            long x = strtol(s, &end, 10);
            if (end == s) break;
            vals[nv++] = x;
            s = end;
        }
        if (nv >= 2) nw = (int)vals[nv - 2], nh = (int)vals[nv - 1];
    }
    if (!l1 || nw < 5 || nh < 5 || nw > 100000 || nh > 100000) {
        rc = gcp_error_set(err, GCP_ERR_VALUE,
                           "%s:1: expected 48 characters of text then 'idum nw nh' with nw, nh "
                           ">= 5 (a G-EQDSK file?)",
                           path);
        goto fail;
    }
    double h[20];
    if ((rc = read_reals(&r, 20, h, "header (rdim zdim rcentr rleft zmid ...)", err))) goto fail;
    const size_t NW = (size_t)nw, NH = (size_t)nh;
    /* the sizes from the header must fit the file before they are
     * allocated: a 99999^2 header in an 80 KB file asked for 80 GB and
     * ended in a bare "out of memory"; a number takes 2 characters at least */
    const double values = 5.0 * (double)NW + (double)NW * (double)NH;
    const size_t left = strlen(r.pos);
    if (2.0 * values > (double)left) {
        rc = gcp_error_set(err, GCP_ERR_VALUE,
                           "%s:1: nw x nh = %d x %d asks for %.0f numbers, but only %zu bytes "
                           "follow (truncated, or not a G-EQDSK file?)",
                           path, nw, nh, values, left);
        goto fail;
    }
    buf = malloc((5 * NW) * sizeof *buf);
    psirz = malloc(NW * NH * sizeof *psirz);
    e = calloc(1, sizeof *e);
    if (!buf || !psirz || !e) {
        rc = gcp_error_set(err, GCP_ERR_NOMEM, "%s: out of memory", path);
        goto fail;
    }
    double *fpol = buf, *pres = buf + NW, *ffp = buf + 2 * NW, *ppr = buf + 3 * NW,
           *qpsi = buf + 4 * NW;
    if ((rc = read_reals(&r, NW, fpol, "fpol", err)) || (rc = read_reals(&r, NW, pres, "pres", err)) ||
        (rc = read_reals(&r, NW, ffp, "ffprim", err)) ||
        (rc = read_reals(&r, NW, ppr, "pprime", err)) ||
        (rc = read_reals(&r, NW * NH, psirz, "psirz", err)) ||
        (rc = read_reals(&r, NW, qpsi, "qpsi", err)))
        goto fail;
    struct gcp_eqdsk_info *in = &e->info;
    in->nw = nw, in->nh = nh;
    in->rdim = h[0], in->zdim = h[1], in->rcentr = h[2], in->rleft = h[3], in->zmid = h[4];
    in->rmaxis = h[5], in->zmaxis = h[6], in->simag = h[7], in->sibry = h[8], in->bcentr = h[9];
    in->current = h[10];
    if (!(in->rdim > 0.0 && in->zdim > 0.0 && in->rleft >= 0.0)) {
        rc = gcp_error_set(err, GCP_ERR_VALUE, "%s: header: rdim = %g, zdim = %g, rleft = %g: "
                           "need rdim, zdim > 0 and rleft >= 0", path, in->rdim, in->zdim,
                           in->rleft);
        goto fail;
    }
    if (!(in->sibry != in->simag)) {
        rc = gcp_error_set(err, GCP_ERR_VALUE, "%s: header: simag = sibry = %g", path, in->simag);
        goto fail;
    }
    /* boundary: Z extent of the last closed flux surface (optional record) */
    in->zbmin = -INFINITY, in->zbmax = INFINITY;
    {
        char *s = next_line(&r, &len);
        int nb = 0, nl = 0;
        if (s && sscanf(s, "%d %d", &nb, &nl) >= 1 && nb > 2 && nb < 1000000) {
            double *bb = malloc(2 * (size_t)nb * sizeof *bb);
            if (!bb) {
                rc = gcp_error_set(err, GCP_ERR_NOMEM, "%s: out of memory", path);
                goto fail;
            }
            if ((rc = read_reals(&r, 2 * (size_t)nb, bb, "boundary (rbbbs, zbbbs)", err))) {
                free(bb);
                goto fail;
            }
            in->zbmin = INFINITY, in->zbmax = -INFINITY;
            for (int k = 0; k < nb; k++) {
                in->zbmin = fmin(in->zbmin, bb[2 * k + 1]);
                in->zbmax = fmax(in->zbmax, bb[2 * k + 1]);
            }
            free(bb);
        }
    }
    /* COCOS */
    const double dpsi = in->sibry - in->simag;
    int sBp, sRphiZ, srtp;
    if (cocos == 0) {
        if (in->current == 0.0 || in->bcentr == 0.0) {
            rc = gcp_error_set(err, GCP_ERR_VALUE,
                               "%s: cannot identify the COCOS convention (current = %g A, bcentr "
                               "= %g T); give cocos = 1..8",
                               path, in->current, in->bcentr);
            goto fail;
        }
        const int sIp = in->current > 0 ? 1 : -1, sB0 = in->bcentr > 0 ? 1 : -1;
        const int sq = qpsi[0] > 0 ? 1 : -1;
        sRphiZ = 1;
        sBp = (dpsi > 0 ? 1 : -1) * sIp;
        srtp = sq * sIp * sB0;
        /* odd COCOS: (sBp, srtp) = (+,+) 1, (-,-) 3, (+,-) 5, (-,+) 7 */
        cocos = sBp > 0 ? (srtp > 0 ? 1 : 5) : (srtp > 0 ? 7 : 3);
    } else {
        sBp = (cocos == 1 || cocos == 2 || cocos == 5 || cocos == 6) ? 1 : -1;
        sRphiZ = (cocos % 2) ? 1 : -1;
        srtp = (cocos <= 2 || cocos >= 7) ? 1 : -1;
    }
    (void)srtp;
    in->cocos = cocos;
    e->s_pol = -(double)sBp * sRphiZ;
    e->s_tor = sRphiZ;
    e->dpsi = dpsi;
    e->F_edge = fpol[NW - 1];
    /* splines */
    {
        const size_t n2[2] = {NW, NH};
        const double x0[2] = {in->rleft, in->zmid - 0.5 * in->zdim};
        const double hh[2] = {in->rdim / (double)(nw - 1), in->zdim / (double)(nh - 1)};
        const double *d1[1] = {psirz};
        if ((rc = gcp_spl_build(&e->psi, 2, kind, n2, x0, hh, 1, d1, err))) goto fail;
        e->Rmin = 1e-9 * hh[0];
        e->kind = kind;
        const size_t n1[1] = {NW};
        const double p0[1] = {0.0}, ph[1] = {1.0};
        const double *dp[3] = {fpol, qpsi, pres};
        if ((rc = gcp_spl_build(&e->prof, 1, kind, n1, p0, ph, 3, dp, err))) goto fail;
    }
    struct gcp_field *f = gcp_field_alloc(&gcp_field_eqdsk, 0);
    if (!f) {
        rc = gcp_error_set(err, GCP_ERR_NOMEM, "%s: out of memory", path);
        goto fail;
    }
    f->params = e;
    f->axisymmetric = 1;
    free(buf);
    free(psirz);
    free(r.text);
    *out = f;
    return 0;
fail:
    if (rc == 0) rc = GCP_ERR_VALUE;
    free(buf);
    free(psirz);
    free(r.text);
    gcp_eqdsk_destroy(e);
    return rc;
}
