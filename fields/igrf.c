/* The `igrf` field model: Earth's main field from the International
 * Geomagnetic Reference Field (IAGA; the table igrf14coeffs.txt).
 *
 * Potential (Schmidt semi-normalised associated Legendre functions P_n^m,
 * no Condon-Shortley phase; reference radius a = 6371.2 km):
 *   V(r, theta, phi) = a sum_{n=1}^{N} (a/r)^{n+1}
 *                      sum_{m=0}^{n} (g_n^m cos m phi + h_n^m sin m phi) P_n^m(cos theta),
 *   B = -grad V,
 * with r, theta (colatitude), phi (east longitude) geocentric spherical
 * coordinates of the geocentric Cartesian x: x towards 0 deg longitude on the
 * equator, z towards the geographic north pole, y completing the right-handed
 * set (90 deg E).  B in tesla.
 *
 * Legendre functions by the standard recurrences (s = sin theta, c = cos theta):
 *   P_0^0 = 1,  P_1^1 = s,  P_n^n = sqrt((2n-1)/(2n)) s P_{n-1}^{n-1}  (n >= 2),
 *   P_n^m = [(2n-1) c P_{n-1}^m - sqrt((n-1)^2 - m^2) P_{n-2}^m] / sqrt(n^2 - m^2),
 * and their first and second theta derivatives by differentiating the
 * recurrences (exact, no division by s).
 *
 * grad B.  In a current-free region grad B = -Hess(V) (symmetric and
 * traceless: curl B = 0, div B = 0).  The Hessian in the orthonormal
 * spherical basis (e_r, e_theta, e_phi), from V_r, V_theta, ..., V_phiphi:
 *   H_rr = V_rr
 *   H_rt = V_rt / r - V_t / r^2
 *   H_rp = (V_rp / r - V_p / r^2) / s
 *   H_tt = V_tt / r^2 + V_r / r
 *   H_tp = (V_tp - c V_p / s) / (r^2 s)
 *   H_pp = V_pp / (r^2 s^2) + V_r / r + c V_t / (r^2 s)
 * (its trace is the spherical Laplacian), rotated to Cartesian as
 * Q H Q^T, Q = [e_r e_theta e_phi].  Near the geographic axis the 1/s terms
 * cancel between large parts: the relative error of grad B grows as
 * eps / sin^2(theta), 2e-8 at 1e-4 rad from the pole; sin(theta) is floored
 * at 1e-7 (0.6 m from the axis at r = a) so the axis itself stays finite.
 *
 * Epochs (the table's rule): linear interpolation between the 5-year
 * epochs 1900.0 .. 2025.0; after the last epoch, the last epoch's
 * coefficients plus the secular variation (nT/yr) times (epoch - 2025.0), up
 * to 2030.0; anything outside 1900.0 .. 2030.0 is refused.
 */
#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "field_priv.h"
#include "gcpush/particles.h"
#include "grid_priv.h"

#define NMAX GCP_IGRF_NMAX
#define IGRF_A 6371.2e3 /* [m] reference radius (= GCP_EARTH_RADIUS) */
#define MAX_EPOCHS 64

struct igrf_params {
    int N;                               /* degree used */
    double g[NMAX + 1][NMAX + 1];        /* [T] */
    double h[NMAX + 1][NMAX + 1];        /* [T] */
    double rec_a[NMAX + 1][NMAX + 1];    /* (2n-1)/sqrt(n^2-m^2) */
    double rec_b[NMAX + 1][NMAX + 1];    /* sqrt((n-1)^2-m^2)/sqrt(n^2-m^2) */
    double diag[NMAX + 1];               /* sqrt((2n-1)/(2n)) (n >= 2) */
};

/* ---- the coefficient table ------------------------------------------------ */

/* *epoch_bad is set when the table is fine but the epoch is outside it, so
 * the caller can blame the epoch key and not the file key */
static int igrf_read(const char *path, double epoch, struct gcp_igrf_coeffs *c,
                     struct gcp_error *err, int *epoch_bad)
{
    memset(c, 0, sizeof *c);
    *epoch_bad = 0;
    /* rows seen, [0] g, [1] h: a row left out would otherwise be taken as a
     * zero coefficient and give a quietly wrong field */
    static const char gh[2] = {'g', 'h'};
    unsigned char seen[2][NMAX + 1][NMAX + 1];
    memset(seen, 0, sizeof seen);
    FILE *fp = fopen(path, "r");
    if (!fp) return gcp_error_set(err, GCP_ERR_IO, "%s: cannot open IGRF coefficient file", path);
    char line[4096];
    double ep[MAX_EPOCHS];
    int nep = 0, lineno = 0, rows = 0, rc = 0, nmax = 0;
    int have_hdr = 0;
    /* the row values of each coefficient are folded in as they come */
    int lo = -1;
    double w = 0.0, dyear = 0.0;
    while (fgets(line, sizeof line, fp)) {
        lineno++;
        char *s = line;
        while (isspace((unsigned char)*s)) s++;
        if (*s == '#' || *s == '\0') continue;
        if (!have_hdr && strncmp(s, "g/h", 3) == 0) {
            /* "g/h n m 1900.0 1905.0 ... 2025.0 2025-30" */
            char *tok = strtok(s, " \t\r\n");
            int k = 0;
            while ((tok = strtok(NULL, " \t\r\n"))) {
                if (++k <= 2) continue; /* n m */
                char *end;
                double v = strtod(tok, &end);
                if (*end != '\0') break; /* "2025-30": the SV column */
                if (nep >= MAX_EPOCHS) break;
                ep[nep++] = v;
            }
            if (nep < 1) {
                rc = gcp_error_set(err, GCP_ERR_VALUE, "%s:%d: no epochs in the header line",
                                   path, lineno);
                goto out;
            }
            have_hdr = 1;
            const double first = ep[0], last = ep[nep - 1];
            if (!(epoch >= first && epoch <= last + 5.0)) {
                rc = gcp_error_set(err, GCP_ERR_VALUE,
                                   "%s: epoch %.3f is outside the IGRF's range %.1f .. %.1f "
                                   "(definitive/IGRF epochs %.1f .. %.1f, secular variation "
                                   "up to 5 years after)",
                                   path, epoch, first, last + 5.0, first, last);
                *epoch_bad = 1;
                goto out;
            }
            if (epoch >= last) {
                lo = nep - 1, dyear = epoch - last;
            } else {
                lo = 0;
                while (lo + 1 < nep - 1 && epoch >= ep[lo + 1]) lo++;
                w = (epoch - ep[lo]) / (ep[lo + 1] - ep[lo]);
            }
            continue;
        }
        if (!have_hdr) continue; /* the "c/s deg ord IGRF ..." line */
        if (*s != 'g' && *s != 'h') {
            rc = gcp_error_set(err, GCP_ERR_VALUE, "%s:%d: expected a row 'g|h n m values...'",
                               path, lineno);
            goto out;
        }
        const int is_h = *s == 'h';
        s++;
        char *end;
        long n = strtol(s, &end, 10), m = strtol(end, &end, 10);
        if (!(n >= 1 && n <= NMAX && m >= 0 && m <= n)) {
            rc = gcp_error_set(err, GCP_ERR_VALUE, "%s:%d: degree/order (%ld, %ld) out of range",
                               path, lineno, n, m);
            goto out;
        }
        double v[MAX_EPOCHS + 1];
        int nv = 0;
        s = end;
        while (nv < nep + 1) {
            double x = strtod(s, &end);
            if (end == s) break;
            v[nv++] = x;
            s = end;
        }
        if (nv != nep + 1) {
            rc = gcp_error_set(err, GCP_ERR_VALUE, "%s:%d: %d values, expected %d (%d epochs + SV)",
                               path, lineno, nv, nep + 1, nep);
            goto out;
        }
        double val = lo == nep - 1 ? v[nep - 1] + dyear * v[nep] : (1.0 - w) * v[lo] + w * v[lo + 1];
        val *= 1e-9; /* nT -> T */
        if (is_h)
            c->h[n][m] = val;
        else
            c->g[n][m] = val;
        seen[is_h][n][m] = 1;
        if (n > nmax) nmax = (int)n;
        rows++;
    }
    if (!have_hdr || rows == 0)
        rc = gcp_error_set(err, GCP_ERR_VALUE,
                           "%s: no 'g/h n m <epochs>' header or no coefficient rows (an IGRF "
                           "coefficient table?)",
                           path);
    /* every g n m (m = 0 .. n) and h n m (m = 1 .. n) up to the table's
     * degree; h n 0 does not exist (sin 0 = 0) */
    for (int n = 1; n <= nmax && !rc; n++)
        for (int m = 0; m <= n && !rc; m++)
            for (int k = 0; k < 2 && !rc; k++)
                if (!(k == 1 && m == 0) && !seen[k][n][m])
                    rc = gcp_error_set(err, GCP_ERR_VALUE,
                                       "%s: row %c %d %d (degree n = %d, order m = %d) is missing "
                                       "(the table goes to degree %d)",
                                       path, gh[k], n, m, n, m, nmax);
out:
    fclose(fp);
    if (rc) return rc;
    c->nmax = nmax;
    c->epoch = epoch;
    return 0;
}

int gcp_igrf_coeffs_at(const char *path, double epoch, struct gcp_igrf_coeffs *c,
                       struct gcp_error *err)
{
    int epoch_bad;
    return igrf_read(path, epoch, c, err, &epoch_bad);
}

/* ---- evaluation ------------------------------------------------------------- */

/* Legendre functions and theta derivatives up to degree N; order: 0 P only,
 * 1 with dP, 2 with d2P. */
static void legendre(const struct igrf_params *p, double s, double c, int order,
                     double P[NMAX + 1][NMAX + 1], double dP[NMAX + 1][NMAX + 1],
                     double d2P[NMAX + 1][NMAX + 1])
{
    const int N = p->N;
    P[0][0] = 1.0, dP[0][0] = 0.0, d2P[0][0] = 0.0;
    for (int n = 1; n <= N; n++) {
        if (n == 1) {
            P[1][1] = s, dP[1][1] = c, d2P[1][1] = -s;
        } else {
            const double k = p->diag[n];
            const double a = P[n - 1][n - 1], da = dP[n - 1][n - 1], dda = d2P[n - 1][n - 1];
            P[n][n] = k * s * a;
            if (order >= 1) dP[n][n] = k * (c * a + s * da);
            if (order >= 2) d2P[n][n] = k * (-s * a + 2.0 * c * da + s * dda);
        }
        for (int m = 0; m < n; m++) {
            const double A = p->rec_a[n][m], Bc = p->rec_b[n][m];
            const double p1 = P[n - 1][m], p2 = n - 2 >= m ? P[n - 2][m] : 0.0;
            P[n][m] = A * c * p1 - Bc * p2;
            if (order >= 1) {
                const double d1 = dP[n - 1][m], d2 = n - 2 >= m ? dP[n - 2][m] : 0.0;
                dP[n][m] = A * (c * d1 - s * p1) - Bc * d2;
                if (order >= 2) {
                    const double e1 = d2P[n - 1][m], e2 = n - 2 >= m ? d2P[n - 2][m] : 0.0;
                    d2P[n][m] = A * (c * e1 - 2.0 * s * d1 - c * p1) - Bc * e2;
                }
            }
        }
    }
}

static int igrf_eval(const struct gcp_field *f, double t, const double x[3],
                     struct gcp_field_sample *out)
{
    (void)t;
    const struct igrf_params *p = f->params;
    const int grad = (out->need & GCP_NEED_GRADB) != 0;
    const int N = p->N;
    double r = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
    if (!(r > 1.0)) r = 1.0; /* the origin: finite numbers (deep inside the Earth) */
    double rho = hypot(x[0], x[1]);
    double cp = 1.0, sp = 0.0;
    if (rho > 0.0) cp = x[0] / rho, sp = x[1] / rho;
    double s = rho / r, c = x[2] / r;
    if (s < 1e-7) { /* on the axis: nudge off it (see the top of the file) */
        s = 1e-7;
        c = c >= 0.0 ? sqrt(1.0 - s * s) : -sqrt(1.0 - s * s);
    }
    double P[NMAX + 1][NMAX + 1], dP[NMAX + 1][NMAX + 1], d2P[NMAX + 1][NMAX + 1];
    legendre(p, s, c, grad ? 2 : 1, P, dP, d2P);
    double cm[NMAX + 1], sm[NMAX + 1];
    cm[0] = 1.0, sm[0] = 0.0;
    for (int m = 1; m <= N; m++) { /* cos, sin of m phi by the angle-addition recurrence */
        cm[m] = cm[m - 1] * cp - sm[m - 1] * sp;
        sm[m] = sm[m - 1] * cp + cm[m - 1] * sp;
    }
    const double ar = IGRF_A / r;
    double An = IGRF_A * ar; /* a (a/r)^{n+1} at n = 1 below */
    double Vr = 0, Vt = 0, Vp = 0, Vrr = 0, Vrt = 0, Vrp = 0, Vtt = 0, Vtp = 0, Vpp = 0;
    for (int n = 1; n <= N; n++) {
        An *= ar;
        double sT = 0, sTd = 0, sTp = 0, sTdd = 0, sTpd = 0, sTpp = 0;
        for (int m = 0; m <= n; m++) {
            const double g = p->g[n][m], h = p->h[n][m];
            const double T = g * cm[m] + h * sm[m];
            const double Tp = m * (h * cm[m] - g * sm[m]);
            sT += T * P[n][m];
            sTd += T * dP[n][m];
            sTp += Tp * P[n][m];
            if (grad) {
                sTdd += T * d2P[n][m];
                sTpd += Tp * dP[n][m];
                sTpp -= (double)(m * m) * T * P[n][m];
            }
        }
        const double k1 = -(double)(n + 1) / r;
        Vr += k1 * An * sT;
        Vt += An * sTd;
        Vp += An * sTp;
        if (grad) {
            Vrr += (double)((n + 1) * (n + 2)) / (r * r) * An * sT;
            Vrt += k1 * An * sTd;
            Vrp += k1 * An * sTp;
            Vtt += An * sTdd;
            Vtp += An * sTpd;
            Vpp += An * sTpp;
        }
    }
    /* basis: e_r, e_theta, e_phi in Cartesian components */
    const double Q[3][3] = {{s * cp, c * cp, -sp}, {s * sp, c * sp, cp}, {c, -s, 0.0}};
    const double Bs[3] = {-Vr, -Vt / r, -Vp / (r * s)};
    for (int i = 0; i < 3; i++) out->B[i] = Q[i][0] * Bs[0] + Q[i][1] * Bs[1] + Q[i][2] * Bs[2];
    if (grad) {
        const double r2 = r * r;
        double H[3][3];
        H[0][0] = Vrr;
        H[0][1] = H[1][0] = Vrt / r - Vt / r2;
        H[0][2] = H[2][0] = (Vrp / r - Vp / r2) / s;
        H[1][1] = Vtt / r2 + Vr / r;
        H[1][2] = H[2][1] = (Vtp - c * Vp / s) / (r2 * s);
        H[2][2] = Vpp / (r2 * s * s) + Vr / r + c * Vt / (r2 * s);
        double QH[3][3];
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                QH[i][j] = Q[i][0] * H[0][j] + Q[i][1] * H[1][j] + Q[i][2] * H[2][j];
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                out->gradB[i][j] = -(QH[i][0] * Q[j][0] + QH[i][1] * Q[j][1] + QH[i][2] * Q[j][2]);
    }
    if (out->need & GCP_NEED_E) out->E[0] = out->E[1] = out->E[2] = 0.0;
    return 0;
}

static void igrf_eval_block(const struct gcp_field *f, double t, size_t n, const double *x,
                            const double *y, const double *z, double *Bx, double *By, double *Bz,
                            double *Ex, double *Ey, double *Ez, int32_t *status)
{
    (void)status;
    struct gcp_field_sample s;
    s.need = GCP_NEED_B;
    for (size_t i = 0; i < n; i++) {
        const double p[3] = {x[i], y[i], z[i]};
        igrf_eval(f, t, p, &s);
        Bx[i] = s.B[0];
        By[i] = s.B[1];
        Bz[i] = s.B[2];
        if (Ex) Ex[i] = Ey[i] = Ez[i] = 0.0;
    }
}

/* Keys: file (required: the IGRF coefficient table), epoch (required,
 * decimal year), nmax (degree, default: the table's), atmosphere (altitude
 * of the loss boundary, default 100 km), r_outer (default 15 RE). */
enum { IK_FILE, IK_EPOCH, IK_NMAX, IK_ATM, IK_ROUT };
static const struct gcp_field_key igrf_keys[] = {
    {"file", GCP_KEY_STRING, 0, 1, {0, 0, 0}, NULL, "IGRF coefficient table"},
    {"epoch", GCP_KEY_QUANTITY, GCP_Q_NUMBER, 1, {0, 0, 0}, NULL, "decimal year"},
    {"nmax", GCP_KEY_QUANTITY, GCP_Q_NUMBER, 0, {0, 0, 0}, NULL, "degree (default: all)"},
    {"atmosphere", GCP_KEY_QUANTITY, GCP_Q_LENGTH, 0, {100e3, 0, 0}, NULL,
     "altitude of the loss boundary [m]"},
    {"r_outer", GCP_KEY_QUANTITY, GCP_Q_LENGTH, 0, {15.0 * GCP_EARTH_RADIUS, 0, 0}, NULL,
     "outer boundary [m]"},
    {NULL, 0, 0, 0, {0, 0, 0}, NULL, NULL}};

static int igrf_build(struct gcp_field_args *a, struct gcp_field **out, struct gcp_error *err)
{
    const double epoch = a->v[IK_EPOCH][0], nmax = a->v[IK_NMAX][0];
    const double alt = a->v[IK_ATM][0], r_outer = a->v[IK_ROUT][0];
    if (!(nmax == floor(nmax) && nmax >= 0 && nmax <= NMAX))
        return gcp_field_key_error(a, IK_NMAX, err, GCP_ERR_VALUE,
                                   "expected a degree 1 .. %d, got %g", NMAX, nmax);
    if (!(alt >= 0.0 && isfinite(alt)))
        return gcp_field_key_error(a, IK_ATM, err, GCP_ERR_VALUE,
                                   "altitude must be >= 0 and finite, got %g m", alt);
    const double r_inner = IGRF_A + alt;
    if (!(r_outer > r_inner && isfinite(r_outer)))
        return gcp_field_key_error(a, IK_ROUT, err, GCP_ERR_VALUE,
                                   "must be finite and above the atmosphere (%g m), got %g m",
                                   r_inner, r_outer);
    struct gcp_igrf_coeffs c;
    struct gcp_error e2 = {0, ""};
    int rc, epoch_bad;
    /* a fault in the table is the file key's; only an epoch outside the
     * table's range is the epoch key's */
    if ((rc = igrf_read(a->text[IK_FILE], epoch, &c, &e2, &epoch_bad)) < 0)
        return gcp_field_key_error(a, epoch_bad ? IK_EPOCH : IK_FILE, err, rc, "%s", e2.msg);
    *out = gcp_field_igrf_create(&c, (int)nmax, r_inner, r_outer);
    if (!*out) return gcp_error_set(err, GCP_ERR_NOMEM, "igrf field: out of memory");
    return 0;
}

const struct gcp_field_type gcp_field_igrf = {
    .name = "igrf",
    .doc = "IGRF geomagnetic main field (geocentric x y z): file, epoch, [nmax] [atmosphere] "
           "[r_outer]",
    .eval = igrf_eval,
    .eval_block = igrf_eval_block,
    .destroy = NULL,
    .caps = GCP_CAP_B | GCP_CAP_GRADB,
    .keys = igrf_keys,
    .build = igrf_build,
};

struct gcp_field *gcp_field_igrf_create(const struct gcp_igrf_coeffs *c, int nmax, double r_inner,
                                        double r_outer)
{
    struct gcp_field *f = gcp_field_alloc(&gcp_field_igrf, sizeof(struct igrf_params));
    if (!f) return NULL;
    struct igrf_params *p = f->params;
    int N = c->nmax;
    if (nmax > 0 && nmax < N) N = nmax;
    if (N < 1) N = 1;
    if (N > NMAX) N = NMAX;
    p->N = N;
    for (int n = 0; n <= N; n++)
        for (int m = 0; m <= n; m++) {
            p->g[n][m] = c->g[n][m];
            p->h[n][m] = c->h[n][m];
            if (m < n) {
                const double d = sqrt((double)(n * n - m * m));
                p->rec_a[n][m] = (2.0 * n - 1.0) / d;
                p->rec_b[n][m] = n >= 2 ? sqrt((double)((n - 1) * (n - 1) - m * m)) / d : 0.0;
                if ((n - 1) * (n - 1) < m * m) p->rec_b[n][m] = 0.0;
            }
        }
    for (int n = 2; n <= N; n++) p->diag[n] = sqrt((2.0 * n - 1.0) / (2.0 * n));
    f->r_inner = r_inner > 0.0 ? r_inner : 0.0;
    f->r_outer = r_outer > 0.0 ? r_outer : INFINITY;
    return f;
}

/* Keys:
 *   file       the coefficient table (required), e.g. fields/data/igrf14coeffs.txt
 *   epoch      decimal year (required), 1900.0 .. 2030.0
 *   nmax       truncation degree (optional; 1 = the dipole terms; default all)
 *   atmosphere altitude above the reference radius of the loss boundary, default 100 km
 *   r_outer    default 15 RE */
