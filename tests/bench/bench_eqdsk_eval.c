/* bench_eqdsk_eval -- CPU time per evaluation of the G-EQDSK field (DIII-D
 * 184833, fields/data): B with grad B point by point (gcp_field_eval, what
 * the guiding-centre methods call), the same over struct-of-arrays blocks
 * (gcp_field_eval_soa), and B alone over blocks (the model's eval_block,
 * the full-orbit step's).  4096 points spread over the plasma (R within
 * 0.45 m of the axis, |Z - Z_axis| < 0.7 m, any phi), each pass over all of
 * them; min and median of 9 passes, ns per point.  Not a test.
 * Usage: bench_eqdsk_eval [G-EQDSK file] (default: the DIII-D file, from
 * tests/bench or the repository root). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "gcpush/grid.h"

#define NPT 4096
#define NREP 9
#define BLK 256

static double cpu_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int cmp(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double x[NPT], y[NPT], z[NPT], B[3][NPT], G[9][NPT], E[3][NPT];
static volatile double sink;

/* ns per point of one pass of mode m (0 scalar B + grad B, 1 soa B + grad B, 2 block B) */
static double pass(const struct gcp_field *f, int m, int reps)
{
    const double t0 = cpu_s();
    double acc = 0.0;
    for (int r = 0; r < reps; r++) {
        if (m == 0) {
            for (size_t i = 0; i < NPT; i++) {
                struct gcp_field_sample s = {.need = GCP_NEED_B | GCP_NEED_GRADB};
                const double p[3] = {x[i], y[i], z[i]};
                gcp_field_eval(f, 0.0, p, &s);
                acc += s.B[0] + s.gradB[2][1];
            }
        } else {
            for (size_t i = 0; i < NPT; i += BLK) {
                int32_t st[BLK] = {0};
                if (m == 1) {
                    struct gcp_field_soa o;
                    for (int a = 0; a < 3; a++) {
                        o.B[a] = B[a] + i, o.E[a] = E[a] + i;
                        for (int b = 0; b < 3; b++) o.G[a][b] = G[3 * a + b] + i;
                    }
                    gcp_field_eval_soa(f, 0.0, GCP_NEED_B | GCP_NEED_GRADB, BLK, x + i, y + i,
                                       z + i, &o, st);
                } else {
                    f->type->eval_block(f, 0.0, BLK, x + i, y + i, z + i, B[0] + i, B[1] + i,
                                        B[2] + i, NULL, NULL, NULL, st);
                }
            }
            acc += B[0][7] + G[5][9];
        }
    }
    sink = acc;
    return 1e9 * (cpu_s() - t0) / ((double)reps * NPT);
}

int main(int argc, char **argv)
{
    struct gcp_field *f;
    struct gcp_error err = {0};
    if (argc > 1 ? gcp_field_eqdsk_load(argv[1], 0, &f, &err)
                 : gcp_field_eqdsk_load("../../fields/data/diiid_184833.geqdsk", 0, &f, &err) &&
                       gcp_field_eqdsk_load("fields/data/diiid_184833.geqdsk", 0, &f, &err)) {
        fprintf(stderr, "bench_eqdsk_eval: %s\n", err.msg);
        return 1;
    }
    struct gcp_eqdsk_info in;
    gcp_field_eqdsk_info(f, &in);
    srand(12345);
    for (size_t i = 0; i < NPT; i++) {
        const double R = in.rmaxis + 0.45 * (2.0 * rand() / RAND_MAX - 1.0);
        const double ph = 2.0 * GCP_PI * rand() / RAND_MAX;
        x[i] = R * cos(ph), y[i] = R * sin(ph);
        z[i] = in.zmaxis + 0.7 * (2.0 * rand() / RAND_MAX - 1.0);
    }
    static const char *const what[] = {"eval B + grad B (scalar)", "eval_soa B + grad B",
                                       "eval_block B"};
    for (int m = 0; m < 3; m++) {
        double ns[NREP];
        pass(f, m, 5); /* warm */
        for (int k = 0; k < NREP; k++) ns[k] = pass(f, m, 20);
        qsort(ns, NREP, sizeof *ns, cmp);
        printf("eqdsk %-26s  %6.1f ns/point (min)  %6.1f (median)\n", what[m], ns[0],
               ns[NREP / 2]);
    }
    gcp_field_free(f);
    return 0;
}
