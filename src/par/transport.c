/* Open MPI's start-up on one node (gcp_par_local_defaults, par.h).
 *
 * Debian's Open MPI (etc/openmpi-mca-params.conf: pml = ^ucx) opens the
 * cm point-to-point layer, whose PSM and PSM2 transports (Omni-Path,
 * InfiniPath) probe for their hardware in MPI_Init: 0.2 s of each rank's
 * start on the 2-core build machine, 7% of runs/dipole.run on one rank,
 * before ob1 is chosen anyway, since no such device is there.  On one node
 * ob1 (shared memory) is what any choice ends with, so asking for it is
 * correct and skips the probes; across nodes the choice is the cluster's
 * and is left alone.  A process started without mpirun (a singleton, as
 * `make run` starts gcpush) forks a helper daemon in MPI_Init that only
 * MPI_Comm_spawn needs, which gcpush never calls: 0.25 s more. */
#define _POSIX_C_SOURCE 200809L
#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "par.h"

#ifndef GCP_OMPI_SYSCONFDIR
#define GCP_OMPI_SYSCONFDIR "/etc/openmpi"
#endif

/* Whether a parameter file sets `key`: a line `key = value` (blanks
 * around), other than an exclusion list (value `^a,b`) that leaves `keep`
 * in.  A missing file sets nothing. */
static int file_sets(const char *path, const char *key, const char *keep)
{
    FILE *fp = fopen(path, "r");
    if (!fp) return 0;
    char line[1024];
    int set = 0;
    const size_t klen = strlen(key);
    while (!set && fgets(line, sizeof line, fp)) {
        const char *p = line;
        while (isspace((unsigned char)*p)) p++;
        if (strncmp(p, key, klen) != 0) continue;
        p += klen;
        while (*p == ' ' || *p == '\t') p++;
        if (*p++ != '=') continue;
        while (*p == ' ' || *p == '\t') p++;
        if (*p != '^') {
            set = 1;
            break;
        }
        /* an exclusion list (`^a,b`): does it name `keep`? */
        for (const char *q = p + 1;;) {
            q += strspn(q, " \t");
            const size_t n = strcspn(q, ", \t\r\n#");
            if (n == strlen(keep) && strncmp(q, keep, n) == 0) {
                set = 1;
                break;
            }
            q += n;
            q += strspn(q, " \t");
            if (*q != ',') break;
            q++;
        }
    }
    fclose(fp);
    return set;
}

/* Whether the environment or Open MPI's parameter files choose the
 * point-to-point layer. */
static int pml_chosen(gcp_par_getenv get, void *ctx, const char *const *files)
{
    if (get(ctx, "OMPI_MCA_pml")) return 1;
    for (; *files; files++)
        if (file_sets(*files, "pml", "ob1")) return 1;
    return 0;
}

static long env_long(gcp_par_getenv get, void *ctx, const char *name)
{
    const char *v = get(ctx, name);
    char *end;
    const long n = v && *v ? strtol(v, &end, 10) : -1;
    return v && *v && *end == '\0' ? n : -1;
}

unsigned gcp_par_local_defaults_for(gcp_par_getenv get, void *ctx, const char *const *files)
{
    /* mpirun (ORTE) tells each rank the job's size and its node's share */
    const long size = env_long(get, ctx, "OMPI_COMM_WORLD_SIZE");
    const long local = env_long(get, ctx, "OMPI_COMM_WORLD_LOCAL_SIZE");
    unsigned want = 0;
    if (size > 0 || local > 0) {
        if (size > 0 && size == local) want = GCP_PAR_OB1;
    } else {
        /* another launcher (srun, a PMI or PMIx server) says nothing about
         * nodes here: leave it alone; no launcher at all is a singleton */
        static const char *const launched[] = {"PMIX_RANK", "PMIX_NAMESPACE", "PMI_RANK",
                                               "PMI_SIZE", "PMI_FD", "SLURM_PROCID",
                                               "OMPI_COMM_WORLD_RANK", "HYDRA_CONTROL_FD"};
        int any = 0;
        for (size_t k = 0; k < sizeof launched / sizeof launched[0]; k++) any |= get(ctx, launched[k]) != NULL;
        if (!any) want = GCP_PAR_OB1 | (get(ctx, "OMPI_MCA_ess_singleton_isolated") ? 0 : GCP_PAR_ISOLATED);
    }
    if ((want & GCP_PAR_OB1) && pml_chosen(get, ctx, files)) want &= ~(unsigned)GCP_PAR_OB1;
    return want;
}

static const char *real_getenv(void *ctx, const char *name)
{
    (void)ctx;
    return getenv(name);
}

unsigned gcp_par_local_defaults(void)
{
#ifdef OPEN_MPI
    /* the files Open MPI reads, unless a list of its own is given (then
     * it is the user's: leave the choice to it) */
    if (getenv("OMPI_MCA_mca_base_param_files")) return 0;
    char home[1024] = "", sys[1024], pre[1024] = "";
    const char *h = getenv("HOME"), *prefix = getenv("OPAL_PREFIX");
    if (h && *h) snprintf(home, sizeof home, "%s/.openmpi/mca-params.conf", h);
    snprintf(sys, sizeof sys, "%s/openmpi-mca-params.conf", GCP_OMPI_SYSCONFDIR);
    if (prefix && *prefix) snprintf(pre, sizeof pre, "%s/etc/openmpi-mca-params.conf", prefix);
    const char *const files[] = {home, sys, pre, NULL};
    const unsigned want = gcp_par_local_defaults_for(real_getenv, NULL, files);
    if (want & GCP_PAR_OB1) setenv("OMPI_MCA_pml", "ob1", 0);
    if (want & GCP_PAR_ISOLATED) setenv("OMPI_MCA_ess_singleton_isolated", "1", 0);
    return want;
#else
    return 0;
#endif
}
