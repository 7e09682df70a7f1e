#!/bin/sh
# Faults and hostile input lose nothing (issue 15): crafted checkpoints,
# output paths, long lines, large run files, disk full, stale temporaries.
# Each case: a clear message, a non-zero exit, nothing half-written.
set -u
. "$(dirname "$0")/lib.sh"
here=$(cd "$(dirname "$0")/../.." && pwd)
cd "$TMP"

# 128 protons in the mirror (2 chunks of 64), no trajectory: rows of 164 bytes
cat > ck.run <<'RUN'
[scene]
name     = ck
field    = mirror
duration = 1 us
seed     = 7
[field]
B0    = 1 T
Lm    = 0.5 m
z_max = 1 m
[particles]
species  = proton
count    = 128
energy   = 10 keV
position = 0 0 0 m
pitch    = 5 deg .. 90 deg
[integrator]
method   = boris
dt       = 0.05 gyro
[output]
file       = ck.h5
RUN

# ckpt FILE ROWS FIRST_ID NWRITTEN: a checkpoint of ck.run claiming ROWS rows,
# holding NWRITTEN rows with ids FIRST_ID.. (all columns but id and pop zero)
ckpt() {
    "$PY" - "$@" <<'PY'
import os, struct, sys
out, rows, first, nw = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
text = open(os.environ.get("RUN", "ck.run"), "rb").read()
b = b"GCPCKPT3" + struct.pack("=qqq", 0, rows, len(text)) + text
b += struct.pack("=q", 6) + b"ck.run" + struct.pack("=d", 0.0)
cols = [("q", 1), ("i", 1), ("d", 3), ("d", 3), ("d", 1), ("d", 3), ("d", 3),
        ("i", 1), ("i", 1), ("q", 1), ("d", 1), ("d", 1), ("d", 1), ("d", 1)]
for k, (f, per) in enumerate(cols):
    for r in range(nw):
        v = first + r if k == 0 else 0
        b += struct.pack("=" + f * per, *([v] * per))
b += struct.pack("=q", 0)
open(out, "wb").write(b)
PY
}

# restart_fails WHAT: --restart ck.h5 must fail (exit 1) within 20 s with a
# message naming the checkpoint, and leave no output
restart_fails() {
    timeout -s KILL 20 "$GCPUSH" --quiet --restart ck.h5 > out.txt 2> err.txt
    rc=$?
    [ $rc = 1 ] || die "$1: exit status $rc, not 1: $(cat err.txt)"
    grep -q "$2" err.txt || die "$1: message '$(cat err.txt)' does not say '$2'"
    [ -f ck.h5 ] && die "$1: an output file was written"
    rm -f ck.h5.ckpt.*
}

# 2. sizes read from a checkpoint are checked before any allocation
ckpt ck.h5.ckpt.0 9223372036854775807 0 0
restart_fails "row count 2^63-1" "ck.h5.ckpt.0"
ckpt ck.h5.ckpt.0 4611686018427387904 0 0
restart_fails "row count 2^62" "ck.h5.ckpt.0"
ckpt ck.h5.ckpt.0 200 0 64
restart_fails "more rows than the run has particles" "ck.h5.ckpt.0"

# 9. a chunk with missing particles: the restart fails saying which (128
# particles make chunks of 32, gcp_scene_chunk_size: ids 0..31 whole, 32..62
# of 32..63)
ckpt ck.h5.ckpt.0 63 0 63
restart_fails "a chunk missing a particle" "particles 32 \.\. 63"
# 4. clean-up deletes exactly the checkpoints: not OUT.ckpt.0.bak, and an
# output name with glob characters matches itself only
ckpt ck.h5.ckpt.0 64 0 64
echo keep > ck.h5.ckpt.0.bak
"$GCPUSH" --quiet --restart ck.h5 || die "restart from two whole chunks failed"
[ -f ck.h5.ckpt.0 ] && die "the checkpoint was left after a finished run"
[ -f ck.h5.ckpt.0.bak ] || die "clean-up deleted ck.h5.ckpt.0.bak"
sed 's/^file       = ck.h5/file       = c*.h5\ncheckpoint = 1 ms/' ck.run > glob.run
echo keep > ck.h5.ckpt.1
"$GCPUSH" --quiet glob.run || die "a run writing 'c*.h5' failed"
[ -f 'c*.h5' ] || die "no output 'c*.h5'"
[ -f ck.h5.ckpt.1 ] || die "clean-up of 'c*.h5' deleted ck.h5.ckpt.1"
rm -f ck.h5 ck.h5.ckpt.* 'c*.h5'

# 10. a restart removes the temporaries a killed run left (output and checkpoint)
ckpt ck.h5.ckpt.0 64 0 64
head -c 100000 /dev/zero > ck.h5.tmp-99999
echo x > ck.h5.ckpt.3.tmp
echo keep > ck.h5.tmp-99999.mine
"$GCPUSH" --restart ck.h5 > out.txt || die "restart with stale temporaries failed"
[ -f ck.h5.tmp-99999 ] && die "the stale output temporary survived the restart"
[ -f ck.h5.ckpt.3.tmp ] && die "the stale checkpoint temporary survived the restart"
[ -f ck.h5.tmp-99999.mine ] || die "the restart removed ck.h5.tmp-99999.mine"
grep -q "removed ck.h5.tmp-99999" out.txt || die "the restart did not say what it removed: $(cat out.txt)"
rm -f ck.h5 ck.h5.tmp-99999.mine
# 7. output paths refused before anything runs, naming file, line and key
for f in self '' . sub/ sub; do
    mkdir -p sub
    name=$f
    [ "$f" = self ] && name=bad.run
    sed "s|^file       = ck.h5|file       = $name|" ck.run > bad.run
    cp bad.run bad.orig
    "$GCPUSH" --check bad.run > out.txt 2> err.txt && die "--check accepted 'file = $name'"
    grep -q "bad.run:20: \[output\] file" err.txt || die "'file = $name': $(cat err.txt)"
    "$GCPUSH" --quiet bad.run 2> err.txt && die "a run with 'file = $name' exited 0"
    cmp -s bad.run bad.orig || die "'file = $name' changed the run file"
done
# an existing output is replaced only with --force
echo "a finished result" > ck.h5
"$GCPUSH" --quiet ck.run 2> err.txt && die "a run replaced an existing output without --force"
grep -q "ck.h5' exists.*--force" err.txt || die "existing output: $(cat err.txt)"
[ "$(cat ck.h5)" = "a finished result" ] || die "the existing output was changed"
"$GCPUSH" --quiet --force ck.run || die "--force did not replace the output"
h5dump -H ck.h5 > /dev/null || die "--force did not write an HDF5 output"
rm -f ck.h5
# 8. a line longer than 199 characters is rejected, not cut (it gave seed 7);
# blanks before a long comment are no content
pad=$(printf '%250s' '')
sed "s/^seed     = 7$/seed     = 7${pad}99/" ck.run > long.run
"$GCPUSH" --check long.run > out.txt 2> err.txt && die "a 260-character line was accepted: $(cat out.txt)"
grep -q "long.run:5: line longer than 199" err.txt || die "long line: $(cat err.txt)"
sed "s/^seed     = 7$/seed     = 7${pad}# ${pad}/" ck.run > long.run
"$GCPUSH" --check long.run > /dev/null 2> err.txt || die "blanks and a long comment rejected: $(cat err.txt)"
# 11. CR-only line ends read as lines; a section given twice is an error
tr '\n' '\r' < ck.run > cr.run
"$GCPUSH" --check cr.run > out.txt 2> err.txt || die "CR-only line ends: $(cat err.txt)"
grep -q "ok: 128 particles" out.txt || die "CR-only line ends: $(cat out.txt)"
printf '[field]\nr_max = 1 m\n' >> ck.run.dup && cat ck.run ck.run.dup > dup.run
"$GCPUSH" --check dup.run > out.txt 2> err.txt && die "a second [field] section was merged"
grep -q "dup.run:21: \[field\]: section given twice (first on line 6)" err.txt || die "duplicate section: $(cat err.txt)"
# 3. a 1 MB run file (7000 comment lines): stored whole in the output
# (attribute run_file, dense storage), through a run and a restart
"$PY" -c "
import sys
t = open('ck.run').read().replace('ck.h5', 'big.h5')
open('big.run', 'w').write(t + ''.join('# %05d %s\\n' % (i, 'x' * 140) for i in range(7000)))"
[ "$(wc -c < big.run)" -gt 1000000 ] || die "big.run is not over 1 MB"
"$GCPUSH" --quiet big.run 2> err.txt || die "a 1 MB run file: $(cat err.txt)"
same_text() {
    "$PY" -c "
import h5py, sys
a = h5py.File('big.h5', 'r').attrs['run_file']
a = a.decode() if isinstance(a, bytes) else str(a)
sys.exit(a != open('big.run').read())" || die "$1: big.h5's run_file is not big.run's text"
}
same_text "run"
rm big.h5
RUN=big.run ckpt big.h5.ckpt.0 64 0 64
"$GCPUSH" --quiet --restart big.h5 2> err.txt || die "restart of a 1 MB run file: $(cat err.txt)"
same_text "restart"
# the space reserved for the output is given back: its disk usage is its size
sed 's|^file       = ck.h5|file       = du.h5\ntrajectory = 300 samples|' ck.run > du.run
"$GCPUSH" --quiet du.run || die "du.run failed"
used=$(du -k du.h5 | cut -f1)
size=$(($(wc -c < du.h5) / 1024))
[ "$used" -le $((size + size / 4 + 64)) ] || die "du.h5 takes $used KiB on disk for $size KiB"
rm -f du.h5

# 1. disk full at the final write (a 1 MiB tmpfs where root may mount one):
# one message, exit 1, no temporary, other files kept, on 1 and 2 ranks
mkdir full
if mount -t tmpfs -o size=1m tmpfs full 2> /dev/null; then
    trap 'umount "$TMP/full"; rm -rf "$TMP"' EXIT
    sed 's|^file       = ck.h5|file       = full/ck.h5\ntrajectory = 3000 samples\ncheckpoint = 1 ms|' ck.run > full.run
    for np in 1 2; do
        echo "another run's checkpoint" > full/ck.h5.ckpt.7
        timeout -s KILL 60 mpirun --oversubscribe --bind-to none -np $np "$GCPUSH" --quiet full.run > out.txt 2> err.txt
        rc=$?
        [ $rc = 1 ] || die "disk full on $np rank(s): exit status $rc, not 1: $(cat err.txt)"
        [ "$(grep -c '^gcpush: full/ck.h5:' err.txt)" = 1 ] || die "disk full on $np rank(s): $(cat err.txt)"
        grep -q "needs up to .* MB free" err.txt || die "disk full on $np rank(s): $(cat err.txt)"
        ls full/ck.h5.tmp-* > /dev/null 2>&1 && die "disk full on $np rank(s): the temporary was left"
        [ -f full/ck.h5 ] && die "disk full on $np rank(s): an output was left"
        [ -f full/ck.h5.ckpt.7 ] || die "disk full on $np rank(s): a checkpoint was removed"
        rm -f full/*
    done
    umount full
    trap 'rm -rf "$TMP"' EXIT
else
    echo "skip: disk full (cannot mount a tmpfs here; needs root)"
fi
# 6. memory: --check prints the estimate; a run needing more than the node
# has (1e9 particles: ~220 GB) is refused before it starts, saying the way out
sed 's/^count    = 128/count    = 1000000000/; s/^dt       = 0.05 gyro/dt       = 1 ns/' ck.run > huge.run
"$GCPUSH" --check huge.run > out.txt 2> err.txt || die "--check of 1e9 particles: $(cat err.txt)"
grep -q "memory: about [0-9.e+]* GB on 1 rank" out.txt || die "--check gives no memory estimate: $(cat out.txt)"
timeout -s KILL 30 "$GCPUSH" --quiet huge.run > out.txt 2> err.txt
rc=$?
[ $rc = 2 ] || die "1e9 particles: exit status $rc, not 2: $(cat err.txt)"
grep -q "needs about .* GB per rank.*more ranks" err.txt || die "1e9 particles: $(cat err.txt)"
[ -f ck.h5 ] && die "1e9 particles: an output was written"
# 11. a step longer than the run is refused (it ran one step of the whole
# duration); --restart ./ck.h5 finds the run that wrote ck.h5
sed 's/^dt       = 0.05 gyro/dt       = 1e308 s/' ck.run > bigdt.run
"$GCPUSH" --check bigdt.run > out.txt 2> err.txt && die "dt = 1e308 s accepted: $(cat out.txt)"
grep -q "bigdt.run:18: \[integrator\] dt: .*longer than the run" err.txt || die "dt = 1e308 s: $(cat err.txt)"
ckpt ck.h5.ckpt.0 64 0 64
"$GCPUSH" --quiet --restart ./ck.h5 2> err.txt || die "--restart ./ck.h5: $(cat err.txt)"
[ -f ck.h5 ] || die "--restart ./ck.h5 wrote no ck.h5"
rm -f ck.h5
# 11. a G-EQDSK header asking for 99999^2 numbers in an 80 KB file: a message
# saying so, not a bare "out of memory" after an 80 GB allocation
mkdir -p fields/data
g=$here/fields/data/diiid_184833.geqdsk
{ head -1 "$g" | sed 's/  65  65$/ 99999 99999/'; tail -n +2 "$g"; } > fields/data/diiid_184833.geqdsk
cp "$here/runs/tokamak-eqdsk.run" eq.run
"$GCPUSH" --check eq.run > out.txt 2> err.txt && die "a 99999^2 EQDSK header was accepted"
grep -q "geqdsk:1: nw x nh = 99999 x 99999 asks for .* but only .* bytes follow" err.txt || die "99999^2 EQDSK: $(cat err.txt)"
echo "ok test_faults"
