/* Self-scheduling and progress totals with MPI-3 atomics (MPI_Fetch_and_op,
 * MPI_Accumulate) on a window held by rank 0. */
#include "par.h"

int gcp_par_counter_create(struct gcp_par_counter *c, int64_t n, MPI_Comm comm)
{
    int me;
    MPI_Comm_rank(comm, &me);
    c->n = n;
    c->base = NULL;
    const MPI_Aint size = me == 0 ? (MPI_Aint)(3 * sizeof(int64_t)) : 0;
    if (MPI_Win_allocate(size, sizeof(int64_t), MPI_INFO_NULL, comm, &c->base, &c->win) !=
        MPI_SUCCESS)
        return -1;
    if (me == 0) {
        MPI_Win_lock(MPI_LOCK_EXCLUSIVE, 0, 0, c->win);
        c->base[0] = c->base[1] = c->base[2] = 0;
        MPI_Win_unlock(0, c->win);
    }
    MPI_Barrier(comm);
    return 0;
}

int64_t gcp_par_counter_take(struct gcp_par_counter *c)
{
    const int64_t one = 1;
    int64_t got = 0;
    MPI_Win_lock(MPI_LOCK_SHARED, 0, 0, c->win);
    MPI_Fetch_and_op(&one, &got, MPI_INT64_T, 0, 0, MPI_SUM, c->win);
    MPI_Win_unlock(0, c->win);
    return got < c->n ? got : -1;
}

void gcp_par_counter_report(struct gcp_par_counter *c, int64_t particles, int64_t steps)
{
    const int64_t add[2] = {particles, steps};
    MPI_Win_lock(MPI_LOCK_SHARED, 0, 0, c->win);
    MPI_Accumulate(add, 2, MPI_INT64_T, 0, 1, 2, MPI_INT64_T, MPI_SUM, c->win);
    MPI_Win_unlock(0, c->win);
}

void gcp_par_counter_totals(struct gcp_par_counter *c, int64_t *particles, int64_t *steps)
{
    int64_t got[2] = {0, 0};
    MPI_Win_lock(MPI_LOCK_SHARED, 0, 0, c->win);
    MPI_Get_accumulate(NULL, 0, MPI_INT64_T, got, 2, MPI_INT64_T, 0, 1, 2, MPI_INT64_T,
                       MPI_NO_OP, c->win);
    MPI_Win_unlock(0, c->win);
    *particles = got[0];
    *steps = got[1];
}

void gcp_par_counter_free(struct gcp_par_counter *c)
{
    MPI_Win_free(&c->win);
}
