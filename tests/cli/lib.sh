# Shared helpers for the CLI tests (sourced).
GCPUSH=${GCPUSH:-$(pwd)/bin/gcpush}
PY=${PY:-/usr/bin/python3}
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_btl_vader_single_copy_mechanism=none
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
# Open MPI keeps every job's session directory in $TMPDIR/ompi.HOST.UID and
# removes that shared directory when its last job ends: a gcpush starting
# elsewhere on the machine at that moment fails in MPI_Init (mkdir: no such
# file or directory; seen twice with other jobs running beside the tests).
# A private TMPDIR per script keeps the rest of the machine out of the tests.
export TMPDIR="$TMP"
die() { echo "FAIL: $*" >&2; exit 1; }
# DEBUG=1 builds: keep Open MPI's plugins loaded at exit so their frames have
# names (full unwinding: Open MPI has no frame pointers), and suppress Open MPI's own at-exit allocations (tests/lsan.supp).
export OMPI_MCA_mca_base_component_disable_dlclose=1
export ASAN_OPTIONS="fast_unwind_on_malloc=0${ASAN_OPTIONS:+:$ASAN_OPTIONS}"
export LSAN_OPTIONS="suppressions=$(cd "$(dirname "$0")/../.." && pwd)/tests/lsan.supp:print_suppressions=0"
