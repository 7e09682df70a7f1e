#!/bin/sh
# A gcpush started without mpirun (a singleton) keeps Open MPI's session
# directory to itself (src/par/transport.c, GCP_PAR_SESSION): Open MPI 4
# shares $TMPDIR/ompi.HOST.UID among all jobs of a user on a node, and
# concurrent singletons even share the job directories below it, so a
# singleton ending removed them under one starting or writing its output.
# The race itself is timing; what is checked here is deterministic:
#   - a run with Open MPI's shared directory made unusable (a file where
#     ompi.HOST.UID would be: MPI_Init failed on it) works, and a run leaves
#     nothing in TMPDIR: after a normal exit (also with the helper daemon),
#     an error exit, and MPI_Abort (which exits without atexit);
#   - a session directory of the user's own (OMPI_MCA_orte_tmpdir_base) is
#     used as it is: there the same obstacle still stops Open MPI.
set -u
. "$(dirname "$0")/lib.sh"
cd "$TMP"

cat > s.run <<'RUN'
[scene]
name     = session
field    = dipole
duration = 0.01 s
seed     = 1
[particles]
species  = proton
count    = 8
energy   = 1 MeV
L        = 3
pitch    = isotropic
[integrator]
method   = boris
dt       = 0.1 gyro
[output]
file       = s.h5
trajectory = none
RUN

# what is in a directory, on one line
left() { ls -A "$1" | tr '\n' ' '; }
# what a file named like Open MPI's shared directory blocks (the node's
# name as gethostname gives it and its short form: Open MPI 4 drops the domain)
block() {
    mkdir "$1"
    for h in $(hostname) $(hostname -s); do : > "$1/ompi.$h.$(id -u)"; done
}

mkdir t1
TMPDIR=$TMP/t1 "$GCPUSH" --quiet s.run > out.txt 2>&1 || die "singleton run failed: $(head -5 out.txt)"
[ -z "$(left t1)" ] || die "a singleton run left in TMPDIR: $(left t1)"

block t2
want=$(left t2)
TMPDIR=$TMP/t2 "$GCPUSH" --quiet --force s.run > out.txt 2>&1 ||
    die "a singleton run failed with Open MPI's shared session directory unusable: $(head -5 out.txt)"
[ "$(left t2)" = "$want" ] || die "a singleton run left in TMPDIR: $(left t2)"

# a singleton that keeps its helper daemon (the user's ess_singleton_isolated=0):
# the daemon shares the private directory and inherits none of an application
# process's run-time choices (with them MPI_Init failed)
OMPI_MCA_ess_singleton_isolated=0 TMPDIR=$TMP/t1 "$GCPUSH" --quiet --force s.run > out.txt 2>&1 ||
    die "a singleton run with its helper daemon failed: $(grep -m3 -i fail out.txt)"
[ -z "$(left t1)" ] || die "a singleton run with its helper daemon left in TMPDIR: $(left t1)"

# an error exit after MPI_Init (the output exists, no --force): exit 2, nothing left
TMPDIR=$TMP/t1 "$GCPUSH" --quiet s.run > out.txt 2>&1
rc=$?
[ $rc = 2 ] || die "a run onto an existing output exited $rc, not 2: $(head -3 out.txt)"
[ -z "$(left t1)" ] || die "an error exit left in TMPDIR: $(left t1)"

# MPI_Abort (gcpush's "MPI window creation failed"): a shim whose
# MPI_Win_allocate fails, preloaded; where no MPI compiler is, skipped
if command -v mpicc > /dev/null 2>&1; then
    cat > shim.c <<'C'
#include <mpi.h>
int MPI_Win_allocate(MPI_Aint size, int disp, MPI_Info info, MPI_Comm comm, void *base, MPI_Win *win)
{
    (void)size, (void)disp, (void)info, (void)comm, (void)base, (void)win;
    return MPI_ERR_OTHER;
}
C
    mpicc -shared -fPIC -o shim.so shim.c || die "cannot build the MPI_Win_allocate shim"
    # (a sanitiser build's runtime must come first in the library list: the shim is preloaded before it)
    TMPDIR=$TMP/t1 LD_PRELOAD=$TMP/shim.so ASAN_OPTIONS="$ASAN_OPTIONS:verify_asan_link_order=0" \
        "$GCPUSH" --quiet --force s.run > out.txt 2>&1
    rc=$?
    grep -q "MPI window creation failed" out.txt || die "the shim did not fail MPI_Win_allocate: $(head -3 out.txt)"
    [ $rc = 1 ] || die "MPI_Abort exited $rc, not 1"
    [ -z "$(left t1)" ] || die "MPI_Abort left in TMPDIR: $(left t1)"
else
    echo "skip MPI_Abort case: no mpicc"
fi

# the user's own session directory: used as given, so the obstacle there stops Open MPI
block u
OMPI_MCA_orte_tmpdir_base=$TMP/u TMPDIR=$TMP/t1 "$GCPUSH" --quiet --force s.run > out.txt 2>&1 &&
    die "a run with OMPI_MCA_orte_tmpdir_base blocked did not fail: the user's choice was not kept"
grep -q "$TMP/u/ompi\." out.txt || die "Open MPI's message does not name the user's directory: $(head -5 out.txt)"
[ -z "$(left t1)" ] || die "a run with the user's session directory left in TMPDIR: $(left t1)"
echo "ok test_session"
