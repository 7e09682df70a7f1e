/* gcp_par_local_defaults_for (src/par/transport.c): Open MPI's ob1 layer
 * is asked for only where every rank is on this node and nobody chose a
 * layer; a rank across nodes or under another launcher keeps the
 * cluster's choice (a wrong guess there would make ranks disagree, or
 * lose the network).  The environment is a table; parameter files are
 * written to a temporary directory. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <criterion/criterion.h>

#include "par/par.h"

static const char *lookup(void *ctx, const char *name)
{
    for (const char *const *kv = ctx; kv[0]; kv += 2)
        if (strcmp(kv[0], name) == 0) return kv[1];
    return NULL;
}

static const char *const no_files[] = {NULL};

static unsigned decide(const char *const *env) { return gcp_par_local_defaults_for(lookup, (void *)env, no_files); }

Test(par_defaults, mpirun_one_node_gets_ob1)
{
    const char *env[] = {"OMPI_COMM_WORLD_SIZE", "2", "OMPI_COMM_WORLD_LOCAL_SIZE", "2",
                         "OMPI_COMM_WORLD_RANK", "1", NULL};
    cr_assert_eq(decide(env), GCP_PAR_OB1);
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
    cr_assert_eq(decide(env), 0);
    const char *single[] = {"OMPI_MCA_ess_singleton_isolated", "0", NULL};
    cr_assert_eq(decide(single), GCP_PAR_OB1); /* the daemon the user asked for stays */
}

Test(par_defaults, singleton_and_other_launchers)
{
    const char *none[] = {NULL};
    cr_assert_eq(decide(none), GCP_PAR_OB1 | GCP_PAR_ISOLATED);
    const char *srun[] = {"PMIX_RANK", "0", "SLURM_PROCID", "0", NULL};
    cr_assert_eq(decide(srun), 0);
    const char *hydra[] = {"PMI_RANK", "3", NULL};
    cr_assert_eq(decide(hydra), 0);
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
    /* Debian's own file excludes ucx only: ob1 is still free to be asked for */
    cr_assert_eq(decide_file("# comment\nbtl = ^uct,openib,ofi\npml = ^ucx\nosc = ^ucx,pt2pt\n"),
                 GCP_PAR_OB1);
    cr_assert_eq(decide_file("pml_ucx_verbose = 0\n"), GCP_PAR_OB1);
    cr_assert_eq(decide_file("  pml=ucx\n"), 0);
    cr_assert_eq(decide_file("pml = ^ucx, ob1\n"), 0);
    cr_assert_eq(decide_file("pml = cm\n"), 0);
}
