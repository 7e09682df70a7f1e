#!/bin/sh
# Parallel efficiency of runs/dipole.run scaled down, 1 against 2 ranks
# (this machine has 2 cores): efficiency = T1 / (2 T2), goal >= 0.9 (1.8x).
set -u
GCPUSH=${GCPUSH:-$(pwd)/bin/gcpush}
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
TMP=$(mktemp -d); trap 'rm -rf "$TMP"' EXIT
sed "s|^file .*|file = $TMP/s.h5|; s|^trajectory .*|trajectory = none|; s|^count .*|count = 256|; s|^duration .*|duration = 60 s|" runs/dipole.run > "$TMP/s.run"
t() { s=$(date +%s%N); mpirun --oversubscribe --bind-to none -np "$1" "$GCPUSH" --quiet --force "$TMP/s.run"; e=$(date +%s%N); echo $(( (e - s) / 1000000 )); }
t 1 > /dev/null   # warm caches
t1=$(t 1); t2=$(t 2)
awk -v a="$t1" -v b="$t2" 'BEGIN { printf "  1 rank %.2f s, 2 ranks %.2f s: speed-up %.2fx, efficiency %.0f%% (goal >= 1.8x)\n", a/1000, b/1000, a/b, 50*a/b }'
