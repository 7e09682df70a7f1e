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
 * MPI_Comm_spawn needs, which gcpush never calls: 0.25 s more.
 *
 * What else a rank's MPI_Init spent on one node (strace, perf of a 2-rank
 * MPI_Init + MPI_Win_allocate + MPI_Finalize, Open MPI 4.1.4, hwloc 2.9):
 *   - a rank that mpirun did not bind (--bind-to none, or more ranks than
 *     cores) discovers the node's topology itself (hwloc_base_verbose:
 *     "discovering topology"; a bound one skips it), with hwloc's
 *     plugins: pci reads every device's PCI configuration space (slow in a
 *     VM: 10% of the rank's start-up CPU), gl links X11 and tries to
 *     connect to displays :0..:N, opencl links the OpenCL loader,
 *     xml_libxml links libxml2 and ICU; without them the Linux backend
 *     still reads the PCI devices' configuration and walks the block and
 *     network devices.  Shared memory needs only the cores and NUMA nodes:
 *     HWLOC_PLUGINS_BLACKLIST keeps the plugins from being loaded at all,
 *     HWLOC_COMPONENTS drops the Linux backend's PCI and I/O phases.
 *   - every component of a framework is dlopened, queried and (unless
 *     chosen) dlclosed again: btl tcp (which also opens its sockets) and
 *     sm (an alias of vader) beside self and vader; 10 collective
 *     components where tuned, libnbc, basic and self are the only ones
 *     with a priority above 0 (so the ones used either way: the same
 *     algorithms, the same results); osc rdma and monitoring beside sm,
 *     which is what MPI_Win_allocate on one node picks.
 * On 2 ranks (15 alternating runs, medians) the hwloc plugins cost 0.014 s
 * of each rank's MPI_Init CPU (0.085 -> 0.071 s) and 0.008 s of its
 * MPI_Finalize (0.025 -> 0.017 s), the components 0.009 s more (-> 0.062
 * s) and 0.004 s of MPI_Finalize (-> 0.013 s); the Linux backend's PCI and
 * I/O phases another 0.019 s (10 alternating runs under load: 0.059 ->
 * 0.040 s).  Each is set only where neither the environment nor a
 * parameter file chooses it already.
 *
 * Open MPI 4's run-time layer (ORTE) loads every component of its
 * frameworks to ask each whether it applies, in each rank: state (app,
 * hnp, orted, novm, tool), errmgr (default_app, _hnp, _orted, _tool),
 * schizo (orte, ompi, slurm, jsm, flux), shmem (mmap, posix, sysv) and
 * reachable (netlink, which also links libnl, and weighted).  An
 * application process, under mpirun or alone, selects state app and errmgr
 * default_app (the others answer only in a daemon, mpirun or a tool),
 * schizo orte (the only one that answers under mpirun or as a singleton
 * outside a workload manager's job; inside one, schizo is left alone)
 * and shmem mmap (the highest priority, available on every Linux); these
 * are asked for by name so that only they are loaded (component
 * selection, not behaviour: the same components run).  reachable only
 * serves TCP, which btl = self,vader leaves out, so it is asked for only
 * with that btl (weighted: the one built everywhere).  Not named: pmix
 * (its component's name depends on how Open MPI was built: ext3x, ext2x,
 * pmix3x; isolated for a singleton), io, fcoll and sharedfp (their choice
 * depends on the output's file system and access pattern).  Measured: a
 * bare MPI_Init's CPU 0.043 -> 0.035 s per rank, MPI_Finalize's 0.011 ->
 * 0.010 s (2 ranks, medians of 12 alternating runs under load); the
 * flagship's start-up: see README, "Run it in parallel".
 *
 * A rank waiting in MPI (a collective of the output, the barrier before
 * it) polls; Open MPI yields the core between polls only where mpirun saw
 * more ranks than cores.  On a node shared with other work the ranks are
 * descheduled now and then, each collective waits for the slower one, and
 * the poller takes CPU from the rank it waits for: on the build machine
 * under load (~6 other jobs, 6 alternating 2-rank flagship runs, medians)
 * each rank's CPU outside the push fell from 0.55 to 0.31 s with
 * mpi_yield_when_idle, mpirun's wall from 4.0 to 3.2 s.  gcpush's own
 * traffic is a few collectives and the shared counter (one-sided atomics
 * in shared memory, no polling), so the latency yielding costs on an idle
 * node does not show.  Tried and dropped: pmix_base_async_modex (no fence
 * in MPI_Init; MPI_Init then failed now and then); async_mpi_finalize
 * (no fence in MPI_Finalize, experimental: the fence is 1-4 ms of a rank's
 * exit, whose wait is PMIx_Finalize's: gcp_par_nodelay).
 *
 * A singleton's session directory.  Open MPI 4 keeps every job's files in
 * one directory per user and node, $TMPDIR/ompi.HOST.UID, created by the
 * first job to start and removed by the last to end; an isolated singleton
 * (ess_singleton_isolated) is moreover always job family 0, so concurrent
 * singletons share even their job's and process's directories,
 * ompi.HOST.UID/jf.0/1/0 (strace).  A singleton that ends rmdirs them while
 * another starts (MPI_Init: mkdir ENOENT or EEXIST) or opens its output
 * (MPI-IO's shared file pointer: "mca_sharedfp_sm_file_open: Error, unable
 * to open file for mmap: .../jf.0/1/OUT.tmp-PID_cid-4-PID.sm", then the
 * output cannot be created): 9 of 600 singleton runs failed, 6 at a time
 * beside a loop of 2-rank mpirun jobs; 0 of 600 with the private base.  A
 * singleton whose user chose no session directory (orte_tmpdir_base, ...)
 * is therefore given a private base, mkdtemp in TMPDIR (else TEMP, TMP,
 * /tmp: where Open MPI would have looked), through
 * OMPI_MCA_orte_tmpdir_base; it is removed at exit, after MPI_Finalize
 * (atexit), and before MPI_Abort (gcp_par_abort), which ends the process
 * without atexit.  Under mpirun the session directory is
 * mpirun's, made before any rank starts: README says what to do there. */
#define _XOPEN_SOURCE 700 /* nftw; POSIX 2008 (mkdtemp) */
#include <ctype.h>
#include <dirent.h>
#include <ftw.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>
#include <netinet/in.h>
#include <netinet/tcp.h>

#include "par.h"

#ifndef GCP_OMPI_SYSCONFDIR
#define GCP_OMPI_SYSCONFDIR "/etc/openmpi"
#endif

/* Whether the comma list `list` holds the name q[0..n). */
static int names(const char *list, const char *q, size_t n)
{
    for (const char *p = list; *p;) {
        const size_t m = strcspn(p, ",");
        if (m == n && strncmp(p, q, n) == 0) return 1;
        p += m;
        if (*p == ',') p++;
    }
    return 0;
}

/* Whether a parameter file sets `key`: a line `key = value` (blanks
 * around), other than an exclusion list (value `^a,b`) that leaves every
 * name of the comma list `keep` in.  A missing file sets nothing. */
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
            if (n && names(keep, q, n)) {
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
 * framework `key`'s components (other than an exclusion that keeps all of
 * `keep`). */
static int chosen(gcp_par_getenv get, void *ctx, const char *const *files, const char *key,
                  const char *keep)
{
    char env[64];
    snprintf(env, sizeof env, "OMPI_MCA_%s", key);
    if (get(ctx, env)) return 1;
    for (; *files; files++)
        if (file_sets(*files, key, keep)) return 1;
    return 0;
}

/* The parameters whose value on one node is gcpush's default: bit, the
 * parameter, the value (for a framework, the components asked for: also
 * what an exclusion list must keep). */
static const struct {
    unsigned bit;
    const char *key, *value;
} frameworks[] = {
    {GCP_PAR_OB1, "pml", "ob1"},
    {GCP_PAR_BTL, "btl", "self,vader"},
    {GCP_PAR_COLL, "coll", "basic,libnbc,self,tuned"},
    {GCP_PAR_OSC, "osc", "sm"},
    {GCP_PAR_YIELD, "mpi_yield_when_idle", "1"},
    {GCP_PAR_STATE, "state", "app"},
    {GCP_PAR_ERRMGR, "errmgr", "default_app"},
    {GCP_PAR_SCHIZO, "schizo", "orte"},
    {GCP_PAR_SHMEM, "shmem", "mmap"},
    {GCP_PAR_REACHABLE, "reachable", "weighted"},
};

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
        if (size > 0 && size == local) want = GCP_PAR_ONE_NODE;
    } else {
        /* another launcher (srun, a PMI or PMIx server) says nothing about
         * nodes here: leave it alone; no launcher at all is a singleton */
        static const char *const launched[] = {"PMIX_RANK", "PMIX_NAMESPACE", "PMI_RANK",
                                               "PMI_SIZE", "PMI_FD", "SLURM_PROCID",
                                               "OMPI_COMM_WORLD_RANK", "HYDRA_CONTROL_FD"};
        int any = 0;
        for (size_t k = 0; k < sizeof launched / sizeof launched[0]; k++) any |= get(ctx, launched[k]) != NULL;
        if (!any) {
            const char *iso = get(ctx, "OMPI_MCA_ess_singleton_isolated");
            want = GCP_PAR_ONE_NODE | GCP_PAR_SESSION | (iso ? 0 : GCP_PAR_ISOLATED);
            /* a singleton the user lets fork its helper daemon: the daemon
             * inherits the environment, and the application's run-time
             * components are not a daemon's (orted: "orte_state_base_select
             * failed", MPI_Init failed) */
            if (iso && strcmp(iso, "1") != 0 && strcasecmp(iso, "true") != 0 && strcasecmp(iso, "yes") != 0)
                want &= ~(unsigned)GCP_PAR_RTE;
            /* a session directory of the user's own (Open MPI 4's names;
             * prte_tmpdir_base: Open MPI 5's launcher) */
            static const char *const sdir[] = {"orte_tmpdir_base", "orte_local_tmpdir_base",
                                               "orte_top_session_dir", "orte_jobfam_session_dir",
                                               "prte_tmpdir_base"};
            for (size_t k = 0; k < sizeof sdir / sizeof sdir[0]; k++)
                if (chosen(get, ctx, files, sdir[k], "")) want &= ~(unsigned)GCP_PAR_SESSION;
            if (get(ctx, "PRTE_MCA_prte_tmpdir_base")) want &= ~(unsigned)GCP_PAR_SESSION;
        }
    }
    for (size_t k = 0; k < sizeof frameworks / sizeof frameworks[0]; k++)
        if ((want & frameworks[k].bit) && chosen(get, ctx, files, frameworks[k].key, frameworks[k].value))
            want &= ~frameworks[k].bit;
    /* schizo's other components answer inside a workload manager's job
     * (slurm: a singleton in an allocation; jsm, flux): there, leave the
     * choice to Open MPI */
    static const char *const managed[] = {"SLURM_JOB_ID", "SLURM_JOBID", "LSB_JOBID",
                                          "JSM_NAMESPACE_SIZE", "FLUX_URI", "FLUX_JOB_ID"};
    for (size_t k = 0; k < sizeof managed / sizeof managed[0]; k++)
        if (get(ctx, managed[k])) want &= ~(unsigned)GCP_PAR_SCHIZO;
    /* which interface reaches which is asked only by TCP (btl tcp): with
     * a transport list of the user's, TCP may be in it */
    if (!(want & GCP_PAR_BTL)) want &= ~(unsigned)GCP_PAR_REACHABLE;
    /* hwloc's own variables: a list of plugins, or components, or a
     * topology file of the user's own */
    if ((want & GCP_PAR_HWLOC) && (get(ctx, "HWLOC_PLUGINS_BLACKLIST") || get(ctx, "HWLOC_COMPONENTS") ||
                                   get(ctx, "HWLOC_XMLFILE") || get(ctx, "HWLOC_FSROOT")))
        want &= ~(unsigned)GCP_PAR_HWLOC;
    return want;
}

static const char *real_getenv(void *ctx, const char *name)
{
    (void)ctx;
    return getenv(name);
}

#ifdef OPEN_MPI
/* The singleton's private session base (empty: none) and the process that
 * made it (a forked child that exits must not remove it). */
static char session[4096];
static pid_t session_owner;

static int remove_entry(const char *path, const struct stat *st, int flag, struct FTW *ftw)
{
    (void)st, (void)flag, (void)ftw;
    (void)remove(path);
    return 0; /* go on: remove what can be */
}

/* Removes the private session base and what Open MPI left in it (nothing,
 * after MPI_Finalize or in MPI_Abort: each removes its own directories);
 * depth first, not following links nor crossing into other file systems. */
static void session_remove(void)
{
    if (!session[0] || getpid() != session_owner) return;
    (void)nftw(session, remove_entry, 16, FTW_DEPTH | FTW_PHYS | FTW_MOUNT);
    session[0] = '\0';
}

/* A private session base for a singleton: mkdtemp where Open MPI would put
 * its own (opal_tmp_directory: TMPDIR, TEMP, TMP, /tmp); 0 where none
 * could be made (Open MPI's default then stands). */
static int session_private(void)
{
    const char *base = NULL;
    static const char *const vars[] = {"TMPDIR", "TEMP", "TMP"};
    for (size_t k = 0; k < sizeof vars / sizeof vars[0] && !base; k++)
        if ((base = getenv(vars[k])) && !*base) base = NULL;
    const int n = snprintf(session, sizeof session, "%s/gcpush-mpi.XXXXXX", base ? base : "/tmp");
    if (n < 0 || (size_t)n >= sizeof session || !mkdtemp(session)) {
        session[0] = '\0';
        return 0;
    }
    session_owner = getpid();
    static int registered;
    if (!registered && atexit(session_remove) != 0) {
        (void)rmdir(session);
        session[0] = '\0';
        return 0;
    }
    registered = 1;
    setenv("OMPI_MCA_orte_tmpdir_base", session, 1);
    return 1;
}
#endif

/* Whether the socket fd is a TCP connection to this host (127/8, ::1, or
 * an IPv4-mapped 127/8). */
static int loopback_tcp(int fd)
{
    int type;
    socklen_t len = sizeof type;
    if (getsockopt(fd, SOL_SOCKET, SO_TYPE, &type, &len) != 0 || type != SOCK_STREAM) return 0;
    struct sockaddr_storage peer;
    socklen_t plen = sizeof peer;
    if (getpeername(fd, (struct sockaddr *)&peer, &plen) != 0) return 0;
    if (peer.ss_family == AF_INET) {
        const unsigned char *a = (const unsigned char *)&((const struct sockaddr_in *)&peer)->sin_addr;
        return a[0] == 127;
    }
    if (peer.ss_family == AF_INET6) {
        const struct in6_addr *a = &((const struct sockaddr_in6 *)&peer)->sin6_addr;
        return IN6_IS_ADDR_LOOPBACK(a) || (IN6_IS_ADDR_V4MAPPED(a) && a->s6_addr[12] == 127);
    }
    return 0;
}

/* MPI_Finalize's wait for the launcher.  A rank under mpirun talks to its
 * node's PMIx server (mpirun or orted) over TCP on the loopback (PMIx 4's
 * ptl tcp; no option for TCP_NODELAY).  In MPI_Finalize the rank sends
 * three event-handler deregistrations, which get no answer, then
 * PMIx_Finalize's request, and waits for its acknowledgement: Nagle's
 * algorithm holds each message after the first until the first is
 * acknowledged, and the server, having nothing to send back, delays that
 * acknowledgement by Linux's delayed-ACK timeout (40 ms).  strace of
 * mpirun: the first deregistration read at t, the others and the finalize
 * request together at t + 43 ms; every rank's PMIx_Finalize took 0.045 s
 * of wall for 0.0013 s of CPU.  With TCP_NODELAY on the rank's side each
 * message leaves when written: PMIx_Finalize 0.006-0.019 s.  TCP_NODELAY
 * changes when segments are sent, never what arrives or in which order;
 * only connections to this host are touched (never a network transport's). */
void gcp_par_nodelay(void)
{
    DIR *d = opendir("/proc/self/fd");
    if (!d) return;
    const int self = dirfd(d);
    for (struct dirent *e; (e = readdir(d));) {
        char *end;
        const long fd = strtol(e->d_name, &end, 10);
        if (*end || end == e->d_name || fd == self || fd < 0 || !loopback_tcp((int)fd)) continue;
        const int one = 1;
        (void)setsockopt((int)fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    }
    closedir(d);
}

void gcp_par_abort(MPI_Comm comm, int code)
{
#ifdef OPEN_MPI
    session_remove(); /* MPI_Abort ends the process without atexit */
#endif
    MPI_Abort(comm, code);
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
    unsigned want = gcp_par_local_defaults_for(real_getenv, NULL, files);
    for (size_t k = 0; k < sizeof frameworks / sizeof frameworks[0]; k++)
        if (want & frameworks[k].bit) {
            char env[64];
            snprintf(env, sizeof env, "OMPI_MCA_%s", frameworks[k].key);
            setenv(env, frameworks[k].value, 0);
        }
    if (want & GCP_PAR_HWLOC) {
        setenv("HWLOC_PLUGINS_BLACKLIST", "hwloc_pci,hwloc_gl,hwloc_opencl,hwloc_xml_libxml", 0);
        /* the Linux backend's own PCI and I/O phases (hwloc >= 2.1 reads
         * `component:phase`; older ones find no such component) */
        setenv("HWLOC_COMPONENTS", "-linux:pci,-linux:io", 0);
    }
    if (want & GCP_PAR_ISOLATED) setenv("OMPI_MCA_ess_singleton_isolated", "1", 0);
    if ((want & GCP_PAR_SESSION) && !session_private()) want &= ~(unsigned)GCP_PAR_SESSION;
    return want;
#else
    return 0;
#endif
}
