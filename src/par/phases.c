/* Where a run's time goes, per rank (GCPUSH_TIMING=1 in the environment;
 * nothing is measured or printed otherwise).  Each mark closes the phase
 * begun at the previous one and records its wall time (CLOCK_BOOTTIME, the
 * clock /proc/self/stat's start time counts in, so the first phase runs
 * from the exec) and this process's CPU time (CLOCK_PROCESS_CPUTIME_ID).
 * On an idle machine a phase whose CPU time is well below its wall time
 * waited (on I/O or on another rank in a blocking call); Open MPI's busy
 * polling makes most waits in MPI calls count as CPU, so the waits that
 * matter for parallel efficiency are marked as their own phases (the
 * barrier after the push) or counted apart (gcp_phase_wait: the shared
 * counter).  Each rank prints one line on stderr at the end, with each
 * phase's page faults beside its times (getrusage): a fault costs ~13 us
 * of CPU in the paravirtualised build VM, so a phase's faults say how
 * much of its CPU went to first touches of memory and mapped files. */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#include <sys/resource.h>

#include "par.h"

#define GCP_PHASES_MAX 32

static struct {
    int on;
    int n;
    double wall0, cpu0; /* the open phase's start */
    long faults0;
    const char *name[GCP_PHASES_MAX];
    double wall[GCP_PHASES_MAX], cpu[GCP_PHASES_MAX];
    long faults[GCP_PHASES_MAX];
    double wait;        /* gcp_phase_wait: seconds in the shared counter */
    int64_t waits;
    double busy;        /* gcp_phase_busy: CPU seconds pushing chunks */
} ph;

/* Page faults (minor and major) of this process since its start. */
static long faults_now(void)
{
    struct rusage ru;
    return getrusage(RUSAGE_SELF, &ru) == 0 ? ru.ru_minflt + ru.ru_majflt : 0;
}

static double clock_s(clockid_t id)
{
    struct timespec ts;
    clock_gettime(id, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* The process's start on CLOCK_BOOTTIME (field 22 of /proc/self/stat, in
 * clock ticks), or now where it cannot be read. */
static double process_start(void)
{
    const double now = clock_s(CLOCK_BOOTTIME);
    FILE *fp = fopen("/proc/self/stat", "r");
    if (!fp) return now;
    char buf[1024];
    const size_t len = fread(buf, 1, sizeof buf - 1, fp);
    fclose(fp);
    buf[len] = '\0';
    /* the command name (field 2) may hold spaces: count fields after its ')' */
    const char *p = strrchr(buf, ')');
    if (!p) return now;
    unsigned long long ticks = 0;
    int field = 2;
    for (; *p && field < 22; p++)
        if (*p == ' ') field++;
    if (field != 22 || sscanf(p, "%llu", &ticks) != 1) return now;
    const long hz = sysconf(_SC_CLK_TCK);
    return hz > 0 ? (double)ticks / (double)hz : now;
}

void gcp_phase_start(void)
{
    const char *e = getenv("GCPUSH_TIMING");
    ph.on = e && *e && strcmp(e, "0") != 0;
    if (!ph.on) return;
    ph.wall0 = process_start();
    ph.cpu0 = 0.0; /* the process's CPU time and faults count from its start too */
    ph.faults0 = 0;
}

int gcp_phase_on(void) { return ph.on; }

void gcp_phase_mark(const char *name)
{
    if (!ph.on || ph.n >= GCP_PHASES_MAX) return;
    const double w = clock_s(CLOCK_BOOTTIME), c = clock_s(CLOCK_PROCESS_CPUTIME_ID);
    const long f = faults_now();
    ph.name[ph.n] = name;
    ph.faults[ph.n] = f - ph.faults0;
    ph.faults0 = f;
    ph.wall[ph.n] = w - ph.wall0;
    ph.cpu[ph.n] = c - ph.cpu0;
    ph.n++;
    ph.wall0 = w;
    ph.cpu0 = c;
}

double gcp_phase_clock(void) { return ph.on ? clock_s(CLOCK_BOOTTIME) : 0.0; }

void gcp_phase_wait(double since)
{
    if (!ph.on) return;
    ph.wait += clock_s(CLOCK_BOOTTIME) - since;
    ph.waits++;
}

void gcp_phase_busy(double cpu_seconds)
{
    if (ph.on) ph.busy += cpu_seconds;
}

void gcp_phase_report(int me, int nranks)
{
    if (!ph.on) return;
    char line[2048];
    double wall = 0.0, cpu = 0.0;
    for (int k = 0; k < ph.n; k++) wall += ph.wall[k], cpu += ph.cpu[k];
    int len = snprintf(line, sizeof line,
                       "gcpush timing: rank %d/%d wall %.3f s cpu %.3f s; busy %.3f s, "
                       "counter %.4f s in %lld takes; phase wall/cpu/faults s:",
                       me, nranks, wall, cpu, ph.busy, ph.wait, (long long)ph.waits);
    for (int k = 0; k < ph.n && len > 0 && (size_t)len < sizeof line; k++)
        len += snprintf(line + len, sizeof line - (size_t)len, " %s %.3f/%.3f/%ld", ph.name[k],
                        ph.wall[k], ph.cpu[k], ph.faults[k]);
    fprintf(stderr, "%s\n", line);
    fflush(stderr);
}
