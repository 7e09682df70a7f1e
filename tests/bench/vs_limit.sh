#!/bin/sh
# Issue 12: gcpush's Boris and gc-rk4 in the dipole as ratios to the hand
# kernels (b) and (c) of ../shared/limit, both measured in this run, one core,
# resident regime (the limit's "resident" summary rows; ours: one block).
# Usage (from tests/bench): sh vs_limit.sh BIN_DIR LIMIT_SRC [scale]
set -e
BIN=$1
SRC=$2
SCALE=${3:-1}
LIM=$BIN/limit
mkdir -p "$LIM"
cp "$SRC/limit_bench.c" "$SRC/Makefile" "$LIM/"
make -s -C "$LIM" limit_bench >/dev/null
ours=$("$BIN/bench_push" limit "$SCALE")
echo "$ours" >"$BIN/limit_rows.txt"
lim=$(cd "$LIM" && OMP_PROC_BIND=close ./limit_bench bench -q -r 3 -t 1 -k bc | grep '| resident | 1 |')
kb=$(echo "$lim" | awk -F'|' '/\(b\)/ {gsub(/ /,"",$6); print $6}')
kc=$(echo "$lim" | awk -F'|' '/\(c\)/ {gsub(/ /,"",$6); print $6}')
echo "Issue 12: pushers in the dipole against ../shared/limit (same run, one core, resident)"
echo "  limit kernel (b) Boris rel. dipole: $kb ns/particle-step; (c) GC RK4 dipole: $kc ns"
printf '  %-16s %6s %12s %12s %8s %8s\n' push lanes "gcpush [ns]" "limit [ns]" ratio goal
echo "$ours" | awk -v kb="$kb" -v kc="$kc" '/^limit-row/ {
    k = ($2 == "boris-dipole") ? kb : kc; g = ($2 == "boris-dipole") ? "<=1.25" : "<=1.5";
    printf "  %-16s %6d %12.3f %12.3f %8.2f %8s\n", $2, $3, $4, k, $4 / k, g }'
