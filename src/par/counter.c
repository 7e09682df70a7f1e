/* Self-scheduling with an MPI-3 atomic counter (MPI_Fetch_and_op). */
#include "par.h"

int gcp_par_counter_create(struct gcp_par_counter *c, int64_t n, MPI_Comm comm)
{
    int me;
    MPI_Comm_rank(comm, &me);
    c->n = n;
    c->base = NULL;
    const MPI_Aint size = me == 0 ? (MPI_Aint)sizeof(int64_t) : 0;
    if (MPI_Win_allocate(size, sizeof(int64_t), MPI_INFO_NULL, comm, &c->base, &c->win) !=
        MPI_SUCCESS)
        return -1;
    if (me == 0) {
        MPI_Win_lock(MPI_LOCK_EXCLUSIVE, 0, 0, c->win);
        *c->base = 0;
        MPI_Win_unlock(0, c->win);
    }
    MPI_Barrier(comm);
    return 0;
}

int64_t gcp_par_counter_next(void *counter)
{
    struct gcp_par_counter *c = counter;
    const int64_t one = 1;
    int64_t got = 0;
    MPI_Win_lock(MPI_LOCK_SHARED, 0, 0, c->win);
    MPI_Fetch_and_op(&one, &got, MPI_INT64_T, 0, 0, MPI_SUM, c->win);
    MPI_Win_unlock(0, c->win);
    return got < c->n ? got : -1;
}

void gcp_par_counter_free(struct gcp_par_counter *c)
{
    MPI_Win_free(&c->win);
}
