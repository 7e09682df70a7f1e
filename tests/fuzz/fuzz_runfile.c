/* libFuzzer target for the run-file reader: any byte string must give
 * either a scene or an error message -- no crash, no leak (ASan/LSan), no
 * undefined behaviour (UBSan), no hang.
 *
 * Inputs asking for more than 100000 particles are skipped, before the
 * parse: resolving "dt = 0.1 gyro" inside it scans every particle's gyro
 * period (linear in count, intended), which is slow, not stuck, and not the
 * parser under test (a mutated "count = 000000000000270598120" ran past
 * libFuzzer's 20 s timeout there). */
#include <ctype.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "gcpush/run.h"
#include "gcpush/sweep.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* The sum of every "count = N" line's N (any case, any spacing; what strtod
 * reads of N, so 1e9 and 0x... count too): larger than any count the reader
 * could take from the same line. */
static double counts_asked(const char *text)
{
    double sum = 0.0;
    for (const char *l = text; l && *l; l = strchr(l, '\n'), l = l ? l + 1 : NULL) {
        while (*l == ' ' || *l == '\t') l++;
        if (strncasecmp(l, "count", 5) != 0) continue;
        const char *v = l + 5;
        while (*v == ' ' || *v == '\t') v++;
        if (*v != '=' && *v != ':') continue;
        v++;
        while (isspace((unsigned char)*v) && *v != '\n') v++;
        const double n = strtod(v, NULL);
        sum += n > 0.0 ? n : 0.0;
    }
    return sum;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char *text = malloc(size + 1);
    if (!text) return 0;
    memcpy(text, data, size);
    text[size] = '\0';
    if (!(counts_asked(text) <= 100000.0)) {
        free(text);
        return 0;
    }
    struct gcp_error err = {0};
    struct gcp_scene *sc = NULL;
    if (gcp_scene_parse("fuzz.run", text, &sc, &err) == 0) {
        if (sc->total > 100000) {
            gcp_scene_free(sc);
            free(text);
            return 0;
        }
        /* a [sweep] section is read with the rest: a scene that has one holds it */
        if (gcp_sweep_wanted(sc) && sc->sweep->nmethods == 0) __builtin_trap();
        /* a valid scene: its initial states must be computable */
        for (int64_t id = 0; id < sc->total && id < 64; id++) {
            int pop;
            double x[3], u[3];
            gcp_scene_initial_state(sc, id, &pop, x, u);
        }
        gcp_scene_free(sc);
    } else if (err.msg[0] == '\0') {
        __builtin_trap(); /* an error must always say what went wrong */
    }
    free(text);
    return 0;
}
