/* libFuzzer target for the restart path: any byte string given as a
 * checkpoint file must load or be refused with a message -- no crash, no
 * leak, no undefined behaviour, no huge allocation, no hang (sizes in the
 * file once overflowed a doubling loop and a buffer).
 *
 * The first byte picks how the input becomes a file: odd, the input's rest
 * is the whole file; even, a valid header of this target's run file (magic,
 * S, its text and path, which a mutation seldom hits) is followed by the
 * input's rest (row count, cpu time, columns, events), so the fuzzer spends
 * its time in the row and event checks. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "gcpush/io.h"
#include "gcpush/run.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static const char run_text[] =
    "[scene]\nname = ck\nfield = mirror\nduration = 1 us\nseed = 7\n"
    "[field]\nB0 = 1 T\nLm = 0.5 m\nz_max = 1 m\n"
    "[particles]\nspecies = proton\ncount = 128\nenergy = 10 keV\nposition = 0 0 0 m\n"
    "pitch = 5 deg .. 90 deg\n"
    "[integrator]\nmethod = boris\ndt = 1 ns\n"
    "[diagnostics]\nevents = loss\n"
    "[output]\nfile = ck.h5\ntrajectory = 3 samples\n";

static struct gcp_scene *scene(void)
{
    static struct gcp_scene *sc;
    struct gcp_error err = {0};
    if (!sc && gcp_scene_parse("ck.run", run_text, &sc, &err)) {
        fprintf(stderr, "fuzz_checkpoint: %s\n", err.msg);
        abort();
    }
    return sc;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const struct gcp_scene *sc = scene();
    char path[64];
    snprintf(path, sizeof path, "/tmp/gcp-fuzz-ckpt-%ld", (long)getpid());
    FILE *fp = fopen(path, "wb");
    if (!fp) return 0;
    if (size && !(data[0] & 1)) {
        const int64_t S = sc->trajectory_samples, tl = (int64_t)strlen(sc->text),
                      pl = (int64_t)strlen(sc->path);
        fwrite("GCPCKPT3", 1, 8, fp);
        fwrite(&S, sizeof S, 1, fp);
        /* the row count comes from the input (next 8 bytes), then the header's rest */
        int64_t rows = 0;
        memcpy(&rows, data + 1, size - 1 < 8 ? size - 1 : 8);
        fwrite(&rows, sizeof rows, 1, fp);
        fwrite(&tl, sizeof tl, 1, fp);
        fwrite(sc->text, 1, (size_t)tl, fp);
        fwrite(&pl, sizeof pl, 1, fp);
        fwrite(sc->path, 1, (size_t)pl, fp);
        if (size > 9) fwrite(data + 9, 1, size - 9, fp);
    } else if (size) {
        fwrite(data + 1, 1, size - 1, fp);
    }
    fclose(fp);

    struct gcp_error err = {0};
    char *text = NULL, *rpath = NULL;
    if (gcp_checkpoint_read_text(path, &text, &rpath, &err) == 0) {
        free(text);
        free(rpath);
    } else if (!err.msg[0]) {
        __builtin_trap();
    }
    struct gcp_results r;
    gcp_results_init(&r, sc->trajectory_samples, 0);
    struct gcp_error lerr = {0};
    if (gcp_checkpoint_load(path, sc, &r, &lerr) == 0) {
        /* what loads is usable: sorted and dropped as a restart does */
        if (gcp_results_sort(&r)) __builtin_trap();
        for (int64_t i = 0; i < r.n; i++)
            if (r.id[i] < 0 || r.id[i] >= sc->total) __builtin_trap();
    } else if (!lerr.msg[0]) {
        __builtin_trap();
    }
    gcp_results_free(&r);
    remove(path);
    return 0;
}
