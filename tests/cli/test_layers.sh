#!/bin/sh
# The layers of docs/DESIGN.md kept true (issue 12):
#   0 base + kernels  include/gcpush/{api,error,units,particles,kernels,field_kernels}.h,
#                     src/{error,units,particles}.c
#   1 fields          fields/, include/gcpush/{field,grid}.h
#   2 pushers         src/pushers/, include/gcpush/{pusher,gc,hybrid}.h
#   3 diagnostics     src/diag/, include/gcpush/invariants.h
#   4 run             src/run/, include/gcpush/{run,section,sweep,results}.h
#   5 io / par / CLI  src/io/, src/par/, src/gcpush.c, include/gcpush/{io,grid_file,gcpush}.h
# 1. Include directions: a file includes only headers of its own layer or below;
#    hdf5.h and mpi.h only in layer 5.
# 2. The shared library exports only gcp_ symbols (built with -fvisibility=hidden,
#    public headers marking the API), the static library defines only gcp_ globals,
#    and private gcp_ helpers (declared in *_priv.h) are not in the .so's dynamic table.
# 3. Every public header a PIC code includes compiles alone with plain cc, without
#    the MPI or HDF5 include paths (so none pulls in mpi.h or hdf5.h).
# Env: BUILD (build dir, default build).
set -u
root=$(cd "$(dirname "$0")/../.." && pwd)
BUILD=${BUILD:-build}
cd "$root" || exit 1
fail=0
say() { echo "test_layers: $*" >&2; fail=1; }

layer_of() { # path (repo-relative) -> layer number, or empty when not layered
    case "$1" in
    include/gcpush/api.h | include/gcpush/error.h | include/gcpush/units.h | include/gcpush/particles.h | \
        include/gcpush/kernels.h | include/gcpush/field_kernels.h | src/error.c | src/units.c | src/particles.c) echo 0 ;;
    include/gcpush/field.h | include/gcpush/grid.h | fields/*) echo 1 ;;
    include/gcpush/pusher.h | include/gcpush/gc.h | include/gcpush/hybrid.h | src/pushers/*) echo 2 ;;
    include/gcpush/invariants.h | src/diag/*) echo 3 ;;
    include/gcpush/run.h | include/gcpush/section.h | include/gcpush/sweep.h | include/gcpush/results.h | src/run/*) echo 4 ;;
    include/gcpush/io.h | include/gcpush/grid_file.h | include/gcpush/gcpush.h | src/io/* | src/par/* | \
        src/gcpush.c) echo 5 ;;
    *) echo "" ;;
    esac
}

resolve() { # including file, included name -> repo path of the header (empty if system)
    dir=$(dirname "$1")
    for cand in "$dir/$2" "include/$2" "src/$2" "fields/$2"; do
        [ -f "$cand" ] && { echo "$cand" | sed 's|^\./||'; return; }
    done
    echo ""
}

files=$(ls src/*.c src/*/*.c src/*/*.h fields/*.c fields/*.h include/gcpush/*.h 2>/dev/null)
for f in $files; do
    lf=$(layer_of "$f")
    [ -n "$lf" ] || { say "$f: no layer (add it to layer_of)"; continue; }
    for inc in $(sed -n 's/^[[:space:]]*#[[:space:]]*include[[:space:]]*["<]\([^">]*\)[">].*/\1/p' "$f"); do
        case "$inc" in
        mpi.h | hdf5.h | hdf5_hl.h)
            [ "$lf" -lt 5 ] && say "$f (layer $lf) includes <$inc>: only io/par/CLI may"
            continue ;;
        esac
        h=$(resolve "$f" "$inc")
        [ -n "$h" ] || continue # a system header
        lh=$(layer_of "$h")
        [ -n "$lh" ] || { say "$h: no layer (add it to layer_of)"; continue; }
        [ "$lh" -gt "$lf" ] && say "$f (layer $lf) includes $inc (layer $lh): layers call only downward"
    done
done

# 2. Exported symbols.
so=$BUILD/libgcpush.so
a=$BUILD/libgcpush.a
if [ -f "$so" ] && [ -f "$a" ]; then
    bad=$(nm -D --defined-only "$so" | awk '{print $NF}' | grep -v '^gcp_' | grep -v '^_' | head -5)
    [ -z "$bad" ] || say "$so exports non-gcp_ symbols: $bad"
    # (names starting with "__" are the compiler's: ASan's __odr_asan.gcp_*)
    bad=$(nm -g --defined-only "$a" | awk 'NF == 3 {print $3}' | grep -v '^gcp_' | grep -v '^__' | head -5)
    [ -z "$bad" ] || say "$a defines non-gcp_ globals: $bad"
    # private helpers must not be exported: one of each private header
    for p in gcp_block_classify gcp_field_alloc gcp_spl_build gcp_results_columns; do
        nm -D --defined-only "$so" | awk '{print $NF}' | grep -qx "$p" &&
            say "$so exports the private $p (-fvisibility=hidden lost?)"
    done
    # and the public API is there
    for p in gcp_field_eval gcp_field_dipole gcp_pusher_types gcp_gc_potential; do
        nm -D --defined-only "$so" | awk '{print $NF}' | grep -qx "$p" ||
            say "$so does not export the public $p"
    done
else
    say "$so or $a missing (build first)"
fi

# 3. Public headers of a PIC code: alone, plain cc, no MPI/HDF5 include path.
CC_PLAIN=${CC_PLAIN:-cc}
for h in kernels.h field_kernels.h field.h pusher.h gc.h particles.h grid.h invariants.h error.h units.h \
    section.h run.h sweep.h results.h grid_file.h gcpush.h; do
    printf '#include <gcpush/%s>\nint gcp_layers_probe_;\n' "$h" |
        $CC_PLAIN -std=c11 -Wall -Wextra -Werror -fsyntax-only -Iinclude -x c - 2>/tmp/layers.$$ ||
        say "gcpush/$h does not compile alone with plain $CC_PLAIN: $(head -3 /tmp/layers.$$)"
done
rm -f /tmp/layers.$$

# 4. No FMA contraction: the build promises -ffp-contract=off results
#    (bit-identical scalar, batch and AoS kernels), so no object of the
#    library or CLI holds an x86 fused multiply-add, except the explicit
#    fma() calls of GCP_NR_FMA_/GCP_NR_CROSS_ (include/gcpush/kernels.h) in
#    the two objects that use them; fma() never gives vfmaddsub/vfmsubadd,
#    so those are refused everywhere.  GCC 12's SLP vectoriser fused them
#    into tokamak_potential and gc_gauss_wlift.c despite the flag (Makefile:
#    NOFUSE_OBJ).  Other targets (and the -O1 DEBUG=1 build) have none to find.
#    boris_fast.o is the opt-in fast arithmetic tier (arithmetic = fast): its
#    explicit _mm512_fmadd/fmsub/fnmadd intrinsics are its arithmetic, never
#    used by the IEEE path.
FMA_OK="src/pushers/boris_nr.o src/pushers/fo_step.o src/pushers/boris_fast.o"
if [ -f "$a" ] && command -v objdump > /dev/null; then
    for o in "$a" $BUILD/src/gcpush.o; do
        [ -f "$o" ] || continue
        objdump -d --no-show-raw-insn "$o" | awk -v ok=" $FMA_OK " -v top="$o" '
            /^In archive/ { next }
            /: +file format/ { obj = $1; sub(/:$/, "", obj); sub(/.*\//, "", obj); next }
            /^[0-9a-f]+ <.*>:$/ { fn = $2; sub(/:$/, "", fn); next }
            /\tv?f(n)?m(add|sub)/ {
                allowed = 0
                for (i = 1; i <= split(ok, w, " "); i++) { n = w[i]; sub(/.*\//, "", n); if (n == obj) allowed = 1 }
                if (!allowed || /fm(addsub|subadd)/) bad[obj " " fn]++
            }
            END { for (k in bad) print k ": " bad[k] " FMA instruction(s)" }' > /tmp/layers.$$
        [ -s /tmp/layers.$$ ] && say "FMA contraction in $o: $(head -5 /tmp/layers.$$ | tr '\n' ';')"
    done
    rm -f /tmp/layers.$$
fi

# 5. Code outside fields/ never asks which model it has (issue 12): it asks the
#    capability bits and the forms a model declares, so no &gcp_field_<model>
#    type object is named there (the callback type is a constructor's, not a test).
models=$(sed -n 's/^extern const struct gcp_field_type \(gcp_field_[a-z_]*\);.*/\1/p' include/gcpush/field.h |
    grep -v '^gcp_field_callback$')
[ -n "$models" ] || say "no model type objects found in include/gcpush/field.h"
for m in $models; do
    hits=$(grep -rn "&$m\b" src --include='*.c' --include='*.h' 2>/dev/null)
    [ -n "$hits" ] && say "model type test outside fields/: $(echo "$hits" | head -3 | tr '\n' ';')"
done
# ... nor compares the model's name (sc->field_model, a model argument) with
# a string: the name is for messages and the output's `field` attribute.
hits=$(grep -rnE 'strn?cmp\([^;]*(field_model|model)\b[^;]*"[a-z_-]+"|strn?cmp\("[a-z_-]+", *[a-z_>.-]*model\)' \
    src --include='*.c' --include='*.h' 2>/dev/null)
[ -n "$hits" ] && say "model name test outside fields/: $(echo "$hits" | head -3 | tr '\n' ';')"

[ $fail = 0 ] && echo "ok layers (include directions, exported symbols, MPI-free public headers, no FMA contraction, no model-type tests)"
exit $fail
