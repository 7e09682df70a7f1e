/* gcp_par_local_defaults_for (src/par/transport.c): Open MPI's ob1 layer,
 * its shared-memory transports, collective and one-sided components and
 * no hwloc device plugins are asked for only where every rank is on this
 * node, each only where nobody chose it; a rank across nodes or under another launcher keeps the
 * cluster's choice (a wrong guess there would make ranks disagree, or
 * lose the network).  The environment is a table; parameter files are
 * written to a temporary directory. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>

#include <criterion/criterion.h>

#include "par/par.h"

static const char *lookup(void *ctx, const char *name)
{
    for (const char *const *kv = ctx; kv[0]; kv += 2)
        if (strcmp(kv[0], name) == 0) return kv[1];
    return NULL;
}

static const char *const no_files[] = {NULL};

static unsigned decide_file(const char *text);
static unsigned decide(const char *const *env) { return gcp_par_local_defaults_for(lookup, (void *)env, no_files); }

Test(par_defaults, mpirun_one_node_gets_ob1)
{
    const char *env[] = {"OMPI_COMM_WORLD_SIZE", "2", "OMPI_COMM_WORLD_LOCAL_SIZE", "2",
                         "OMPI_COMM_WORLD_RANK", "1", NULL};
    cr_assert_eq(decide(env), GCP_PAR_ONE_NODE);
}

Test(par_defaults, mpirun_across_nodes_left_alone)
{
    const char *env[] = {"OMPI_COMM_WORLD_SIZE", "4", "OMPI_COMM_WORLD_LOCAL_SIZE", "2", NULL};
    cr_assert_eq(decide(env), 0);
    const char *odd[] = {"OMPI_COMM_WORLD_SIZE", "4", NULL}; /* local size unknown */
    cr_assert_eq(decide(odd), 0);
}

Test(par_defaults, user_choice_kept)
{
    const char *env[] = {"OMPI_COMM_WORLD_SIZE", "2", "OMPI_COMM_WORLD_LOCAL_SIZE", "2",
                         "OMPI_MCA_pml", "ucx", NULL};
    cr_assert_eq(decide(env), GCP_PAR_ONE_NODE & ~(unsigned)GCP_PAR_OB1);
    const char *single[] = {"OMPI_MCA_ess_singleton_isolated", "0", NULL};
    /* the daemon the user asked for stays, and inherits no application
     * process's run-time components (its own are a daemon's) */
    cr_assert_eq(decide(single), (GCP_PAR_ONE_NODE | GCP_PAR_SESSION) & ~(unsigned)GCP_PAR_RTE);
    const char *isolated[] = {"OMPI_MCA_ess_singleton_isolated", "true", NULL};
    cr_assert_eq(decide(isolated), GCP_PAR_ONE_NODE | GCP_PAR_SESSION);
    /* each choice of the user's removes only its own default */
    const char *btl[] = {"OMPI_COMM_WORLD_SIZE", "2", "OMPI_COMM_WORLD_LOCAL_SIZE", "2",
                         "OMPI_MCA_btl", "self,tcp", "OMPI_MCA_osc", "rdma", NULL};
    cr_assert_eq(decide(btl), GCP_PAR_OB1 | GCP_PAR_COLL | GCP_PAR_HWLOC | GCP_PAR_YIELD |
                                  (GCP_PAR_RTE & ~(unsigned)GCP_PAR_REACHABLE));
    const char *coll[] = {"OMPI_COMM_WORLD_SIZE", "2", "OMPI_COMM_WORLD_LOCAL_SIZE", "2",
                          "OMPI_MCA_coll", "^han", NULL};
    cr_assert_eq(decide(coll), GCP_PAR_ONE_NODE & ~(unsigned)GCP_PAR_COLL);
    /* hwloc's own variables, any of them: the user's topology setup */
    static const char *const hw[] = {"HWLOC_PLUGINS_BLACKLIST", "HWLOC_COMPONENTS", "HWLOC_XMLFILE",
                                     "HWLOC_FSROOT"};
    for (size_t k = 0; k < sizeof hw / sizeof hw[0]; k++) {
        const char *e[] = {"OMPI_COMM_WORLD_SIZE", "2", "OMPI_COMM_WORLD_LOCAL_SIZE", "2", hw[k], "x", NULL};
        cr_assert_eq(decide(e), GCP_PAR_ONE_NODE & ~(unsigned)GCP_PAR_HWLOC, "%s", hw[k]);
    }
}

/* The run-time layer's components (state, errmgr, schizo, shmem,
 * reachable): each asked for only where nobody chose it; reachable only
 * with gcpush's own btl (a user's list may hold tcp, which asks it);
 * schizo not inside a workload manager's job, where its slurm, jsm or
 * flux component may answer. */
Test(par_defaults, runtime_components)
{
    static const struct { const char *var; unsigned bit; } one[] = {
        {"OMPI_MCA_state", GCP_PAR_STATE},   {"OMPI_MCA_errmgr", GCP_PAR_ERRMGR},
        {"OMPI_MCA_schizo", GCP_PAR_SCHIZO}, {"OMPI_MCA_shmem", GCP_PAR_SHMEM},
        {"OMPI_MCA_reachable", GCP_PAR_REACHABLE}};
    for (size_t k = 0; k < sizeof one / sizeof one[0]; k++) {
        const char *e[] = {"OMPI_COMM_WORLD_SIZE", "2", "OMPI_COMM_WORLD_LOCAL_SIZE", "2",
                           one[k].var, "x", NULL};
        cr_assert_eq(decide(e), GCP_PAR_ONE_NODE & ~one[k].bit, "%s", one[k].var);
    }
    const char *tcp[] = {"OMPI_COMM_WORLD_SIZE", "2", "OMPI_COMM_WORLD_LOCAL_SIZE", "2",
                         "OMPI_MCA_btl", "self,vader,tcp", NULL};
    cr_assert_eq(decide(tcp), GCP_PAR_ONE_NODE & ~(unsigned)(GCP_PAR_BTL | GCP_PAR_REACHABLE));
    static const char *const wlm[] = {"SLURM_JOB_ID", "SLURM_JOBID", "LSB_JOBID",
                                      "JSM_NAMESPACE_SIZE", "FLUX_URI", "FLUX_JOB_ID"};
    for (size_t k = 0; k < sizeof wlm / sizeof wlm[0]; k++) {
        const char *e[] = {"OMPI_COMM_WORLD_SIZE", "2", "OMPI_COMM_WORLD_LOCAL_SIZE", "2",
                           wlm[k], "7", NULL};
        cr_assert_eq(decide(e), GCP_PAR_ONE_NODE & ~(unsigned)GCP_PAR_SCHIZO, "%s", wlm[k]);
        const char *alone[] = {wlm[k], "7", NULL}; /* a singleton in an allocation */
        cr_assert_eq(decide(alone),
                     (GCP_PAR_ONE_NODE | GCP_PAR_ISOLATED | GCP_PAR_SESSION) & ~(unsigned)GCP_PAR_SCHIZO,
                     "%s", wlm[k]);
    }
    /* a parameter file's choice counts as the environment's */
    cr_assert_eq(decide_file("shmem = posix\n"), GCP_PAR_ONE_NODE & ~(unsigned)GCP_PAR_SHMEM);
    cr_assert_eq(decide_file("state = ^hnp\n"), GCP_PAR_ONE_NODE);
}

Test(par_defaults, singleton_and_other_launchers)
{
    const char *none[] = {NULL};
    cr_assert_eq(decide(none), GCP_PAR_ONE_NODE | GCP_PAR_ISOLATED | GCP_PAR_SESSION);
    const char *srun[] = {"PMIX_RANK", "0", "SLURM_PROCID", "0", NULL};
    cr_assert_eq(decide(srun), 0);
    const char *hydra[] = {"PMI_RANK", "3", NULL};
    cr_assert_eq(decide(hydra), 0);
}

/* A singleton's private session directory (concurrent singletons shared
 * Open MPI's and removed it under each other): only where the user chose
 * no session directory, in the environment or a parameter file, and never
 * under mpirun, whose directory it is. */
Test(par_defaults, session_dir)
{
    static const char *const var[] = {"OMPI_MCA_orte_tmpdir_base", "OMPI_MCA_orte_local_tmpdir_base",
                                      "OMPI_MCA_orte_top_session_dir", "OMPI_MCA_orte_jobfam_session_dir",
                                      "OMPI_MCA_prte_tmpdir_base", "PRTE_MCA_prte_tmpdir_base"};
    for (size_t k = 0; k < sizeof var / sizeof var[0]; k++) {
        const char *e[] = {var[k], "/scratch", NULL};
        cr_assert_eq(decide(e), GCP_PAR_ONE_NODE | GCP_PAR_ISOLATED, "%s", var[k]);
    }
    const char *mpirun[] = {"OMPI_COMM_WORLD_SIZE", "1", "OMPI_COMM_WORLD_LOCAL_SIZE", "1",
                            "OMPI_COMM_WORLD_RANK", "0", NULL};
    cr_assert_eq(decide(mpirun) & GCP_PAR_SESSION, 0);
    const char *none[] = {NULL};
    const char *const conf[] = {"/nonexistent/mca-params.conf", NULL};
    cr_assert_eq(gcp_par_local_defaults_for(lookup, (void *)none, conf) & GCP_PAR_SESSION,
                 GCP_PAR_SESSION);
    char path[] = "/tmp/gcp_par_session_XXXXXX";
    const int fd = mkstemp(path);
    cr_assert_geq(fd, 0);
    FILE *fp = fdopen(fd, "w");
    fputs("orte_tmpdir_base_x = 1\n", fp); /* another parameter: not a choice */
    fflush(fp);
    const char *const files[] = {path, NULL};
    const unsigned other = gcp_par_local_defaults_for(lookup, (void *)none, files);
    fputs("orte_tmpdir_base = /scratch/me\n", fp);
    fclose(fp);
    const unsigned mine = gcp_par_local_defaults_for(lookup, (void *)none, files);
    remove(path);
    cr_assert_eq(other & GCP_PAR_SESSION, GCP_PAR_SESSION);
    cr_assert_eq(mine, GCP_PAR_ONE_NODE | GCP_PAR_ISOLATED);
}

/* a parameter file's pml line: a choice, or an exclusion that keeps ob1 */
static unsigned decide_file(const char *text)
{
    char path[] = "/tmp/gcp_par_defaults_XXXXXX";
    const int fd = mkstemp(path);
    cr_assert_geq(fd, 0);
    FILE *fp = fdopen(fd, "w");
    fputs(text, fp);
    fclose(fp);
    const char *env[] = {"OMPI_COMM_WORLD_SIZE", "2", "OMPI_COMM_WORLD_LOCAL_SIZE", "2", NULL};
    const char *const files[] = {"/nonexistent/mca-params.conf", path, NULL};
    const unsigned got = gcp_par_local_defaults_for(lookup, (void *)env, files);
    remove(path);
    return got;
}

Test(par_defaults, parameter_files)
{
    /* Debian's own file excludes ucx and network transports only: ob1,
     * self and vader, and osc sm are still free to be asked for */
    cr_assert_eq(decide_file("# comment\nbtl = ^uct,openib,ofi\npml = ^ucx\nosc = ^ucx,pt2pt\n"),
                 GCP_PAR_ONE_NODE);
    cr_assert_eq(decide_file("pml_ucx_verbose = 0\n"), GCP_PAR_ONE_NODE);
    const unsigned no_pml = GCP_PAR_ONE_NODE & ~(unsigned)GCP_PAR_OB1;
    cr_assert_eq(decide_file("  pml=ucx\n"), no_pml);
    cr_assert_eq(decide_file("pml = ^ucx, ob1\n"), no_pml);
    cr_assert_eq(decide_file("pml = cm\n"), no_pml);
    /* an exclusion list that names one of the components asked for */
    const unsigned no_btl = GCP_PAR_ONE_NODE & ~(unsigned)(GCP_PAR_BTL | GCP_PAR_REACHABLE);
    cr_assert_eq(decide_file("btl = ^vader\n"), no_btl);
    cr_assert_eq(decide_file("btl = ^tcp,self\n"), no_btl);
    cr_assert_eq(decide_file("btl = ^tcp\n"), GCP_PAR_ONE_NODE);
    cr_assert_eq(decide_file("coll = ^tuned\n"), GCP_PAR_ONE_NODE & ~(unsigned)GCP_PAR_COLL);
    cr_assert_eq(decide_file("coll = ^han,adapt\n"), GCP_PAR_ONE_NODE);
    cr_assert_eq(decide_file("osc = rdma\n"), GCP_PAR_ONE_NODE & ~(unsigned)GCP_PAR_OSC);
    cr_assert_eq(decide_file("mpi_yield_when_idle = 0\n"), GCP_PAR_ONE_NODE & ~(unsigned)GCP_PAR_YIELD);
}

/* gcp_par_nodelay: a TCP connection to this host (the PMIx server's, in a
 * rank) gets TCP_NODELAY, so that MPI_Finalize's one-way messages do not
 * wait out the server's delayed acknowledgement; a socket that is not
 * connected is left as it is. */
Test(par_defaults, nodelay_loopback)
{
    const int lis = socket(AF_INET, SOCK_STREAM, 0);
    cr_assert_geq(lis, 0);
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = 0};
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t alen = sizeof a;
    cr_assert_eq(bind(lis, (struct sockaddr *)&a, sizeof a), 0);
    cr_assert_eq(listen(lis, 1), 0);
    cr_assert_eq(getsockname(lis, (struct sockaddr *)&a, &alen), 0);
    const int cli = socket(AF_INET, SOCK_STREAM, 0);
    cr_assert_eq(connect(cli, (struct sockaddr *)&a, sizeof a), 0);
    const int srv = accept(lis, NULL, NULL);
    cr_assert_geq(srv, 0);
    int v = -1;
    socklen_t len = sizeof v;
    cr_assert_eq(getsockopt(cli, IPPROTO_TCP, TCP_NODELAY, &v, &len), 0);
    cr_assert_eq(v, 0, "a new connection has Nagle's algorithm on");
    gcp_par_nodelay();
    cr_assert_eq(getsockopt(cli, IPPROTO_TCP, TCP_NODELAY, &v, &len), 0);
    cr_assert_neq(v, 0, "the loopback connection did not get TCP_NODELAY");
    cr_assert_eq(getsockopt(srv, IPPROTO_TCP, TCP_NODELAY, &v, &len), 0);
    cr_assert_neq(v, 0, "the accepted loopback connection did not get TCP_NODELAY");
    cr_assert_eq(getsockopt(lis, IPPROTO_TCP, TCP_NODELAY, &v, &len), 0);
    cr_assert_eq(v, 0, "the listening socket (no peer) was changed");
    close(srv);
    close(cli);
    close(lis);
}
