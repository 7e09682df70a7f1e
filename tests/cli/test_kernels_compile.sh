#!/bin/sh
# kernels.h compiles, warning-free, as C99, C11, C++17 and CUDA (issue 8):
# tests/embed/kernels_compile.c instantiates every scalar, batch, AoS and
# strided kernel; tests/embed/kernels_compile.cu calls them from __global__
# functions.  -Werror everywhere.  CUDA is compile-only (nvcc -x cu -c needs
# no GPU); where nvcc is absent the CUDA part prints "skip" and passes.
set -u
root=$(cd "$(dirname "$0")/../.." && pwd)
. "$root/tests/cli/lib.sh"
src="$root/tests/embed/kernels_compile.c"
W="-Wall -Wextra -Werror -pedantic"
CC_=${CC_HOST:-cc}

for std in c99 c11; do
    $CC_ -std=$std -O2 $W -I"$root/include" -c "$src" -o "$TMP/k_$std.o" \
        || die "kernels.h does not compile as $std"
done
if command -v clang >/dev/null 2>&1; then
    clang -std=c99 -O2 $W -I"$root/include" -c "$src" -o "$TMP/k_clang.o" \
        || die "kernels.h does not compile with clang -std=c99"
fi
${CXX:-g++} -std=c++17 -O2 $W -I"$root/include" -x c++ -c "$src" -o "$TMP/k_cxx.o" \
    || die "kernels.h does not compile as C++17"

NVCC=$(command -v nvcc 2>/dev/null || true)
[ -z "$NVCC" ] && [ -x /usr/local/cuda/bin/nvcc ] && NVCC=/usr/local/cuda/bin/nvcc
if [ -n "$NVCC" ]; then
    "$NVCC" -std=c++17 -Werror all-warnings -Xcompiler -Wall,-Wextra,-Werror \
        -I"$root/include" -x cu -c "$root/tests/embed/kernels_compile.cu" -o "$TMP/k_cu.o" \
        || die "kernels.h does not compile under CUDA ($NVCC)"
    cuda="cuda"
else
    echo "skip cuda: no nvcc on this machine"
    cuda="(cuda skipped)"
fi
echo "ok kernels_compile (c99 c11 c++17 $cuda)"
