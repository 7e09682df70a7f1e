#!/bin/sh
# Issue 12: gcpush's header-only kernels (include/gcpush/kernels.h) under
# CUDA -- particle-steps/s of Boris and gc-rk4 in the dipole on the GPU
# against the same source on one core of the same machine
# (tests/bench/cuda/bench_cuda.cu).  Where nvcc and a GPU are present the
# bench is built and run here; otherwise the figures recorded on the last
# machine that had one (tests/bench/cuda/last_gpu.txt) are printed, marked
# as such.  Usage (from the repository root): sh tests/bench/cuda.sh [BUILD_DIR]
BUILD=${1:-build}
NVCC=${NVCC:-$(command -v nvcc || echo /usr/local/cuda/bin/nvcc)}
REC=tests/bench/cuda/last_gpu.txt
echo "Issue 12: kernels.h under CUDA (Boris and gc-rk4, dipole, 1 MeV protons)"
if [ -x "$NVCC" ] && nvidia-smi -L >/dev/null 2>&1; then
    mkdir -p "$BUILD/bench"
    # --fmad=false and -ffp-contract=off: no fused multiply-adds on either
    # side, as the library builds, so the device and host trajectories can
    # be compared bit for bit.
    "$NVCC" -O3 -std=c++17 --fmad=false -arch=native -Iinclude \
        -Xcompiler -O3,-march=native,-ffp-contract=off,-fno-math-errno,-Wall,-Wextra \
        -o "$BUILD/bench/bench_cuda" tests/bench/cuda/bench_cuda.cu || exit 1
    shift 2>/dev/null
    "$BUILD/bench/bench_cuda" "$@" >"$BUILD/bench/cuda_rows.txt" || exit 1
    ROWS="$BUILD/bench/cuda_rows.txt"
    sed 's/^/  /' "$ROWS"
elif [ -f "$REC" ]; then
    echo "  no CUDA device on this machine; the figures recorded on the last one that had one:"
    sed 's/^/  | /' "$REC"
    ROWS="$REC"
else
    echo "  no CUDA device on this machine and no recorded figures"
fi
# Against gcpush's own CPU engine on this machine, one core, this run
# (tests/bench/vs_limit.sh leaves its ns/particle-step rows behind).
LIM="$BUILD/bench/limit_rows.txt"
if [ -n "$ROWS" ] && [ -f "$LIM" ]; then
    awk 'FNR == NR && /^limit-row/ { ns[$2] = $4; next }
         /cuda-row/ { for (i = 1; i <= NF; i++) if ($i == "cuda-row") break;
                      p = $(i + 1); g = $(i + 3);
                      if (p in ns) printf "  %-14s GPU %.3g steps/s = %.0fx gcpush CPU engine here (%.3f ns/step, one core)\n", p, g, g * ns[p] * 1e-9, ns[p] }' "$LIM" "$ROWS"
fi
