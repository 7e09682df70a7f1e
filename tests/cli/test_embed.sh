#!/bin/sh
# A PIC code embeds the kernels through the installed header only (issue 8):
# `make install PREFIX=$TMP/prefix`, then tests/embed/pic1d.c is compiled with
# nothing but `pkg-config --cflags gcpush` and -lm (kernels.h is header-only:
# no -lgcpush), as C (struct-of-arrays batch kernels), C with -DPIC_AOS (the
# array-of-structs adapter) and C++17 (both layouts), and each binary must
# reproduce the Langmuir and upper-hybrid frequencies of its discrete
# dispersion relation to 2e-4 relative (derivation in pic1d.c; pic1d exits
# non-zero otherwise).
set -u
root=$(cd "$(dirname "$0")/../.." && pwd)
. "$root/tests/cli/lib.sh"
debug=0
[ "${BUILD:-build}" = build-debug ] && debug=1
prefix="$TMP/prefix"
${MAKE:-make} --no-print-directory -C "$root" install PREFIX="$prefix" DEBUG=$debug \
    >"$TMP/install.log" 2>&1 || { cat "$TMP/install.log" >&2; die "make install PREFIX=$prefix failed"; }
[ -f "$prefix/include/gcpush/kernels.h" ] || die "make install did not install gcpush/kernels.h"
[ -f "$prefix/lib/pkgconfig/gcpush.pc" ] || die "make install did not install gcpush.pc"
cflags=$(PKG_CONFIG_PATH="$prefix/lib/pkgconfig" pkg-config --cflags gcpush) \
    || die "pkg-config --cflags gcpush fails on the installed gcpush.pc"
case "$cflags" in *"-I$prefix/include"*) ;; *) die "installed Cflags lack -I$prefix/include: $cflags" ;; esac

# Linking without -lgcpush is the header-only check: an undefined gcp_
# symbol would fail the build.  Copy the source out of the tree so that nothing can resolve
# <gcpush/kernels.h> from the repository's include/.
cp "$root/tests/embed/pic1d.c" "$TMP/pic1d.c"
cd "$TMP" || die "cd $TMP"
W="-O2 -Wall -Wextra -Werror"
build() { # name compiler flags...
    name=$1; shift
    # shellcheck disable=SC2086
    "$@" $cflags pic1d.c -o "$name" -lm || die "embedding build failed: $*"
}
build pic_c     ${CC_HOST:-cc} -std=c99 $W
build pic_c_aos ${CC_HOST:-cc} -std=c11 $W -DPIC_AOS
build pic_cxx   ${CXX:-g++} -std=c++17 $W -x c++
build pic_cxx_aos ${CXX:-g++} -std=c++17 $W -DPIC_AOS -x c++
for b in pic_c pic_c_aos pic_cxx pic_cxx_aos; do
    ./"$b" >"$b.out" 2>&1 || { cat "$b.out" >&2; die "$b: frequency off its discrete dispersion relation"; }
done
cat pic_c.out
echo "ok embed (installed header, pkg-config --cflags, C99/C11/C++17, SoA and AoS)"
