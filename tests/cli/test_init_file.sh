#!/bin/sh
# Initial states from a file ([particles] file = ...):
#  - continuation: run A for 2T equals run B for T then run C for T from B's
#    final state (copied to /particles/initial of a small h5py file), for a
#    full-orbit and guiding-centre methods;
#  - the file's states are used as given (/particles/initial of the output
#    holds them bit for bit), the step in gyro periods of a given guiding
#    centre is 2 pi gamma m / (|q| B(X)) computed here;
#  - duration = dt takes exactly one step; a duration that is no multiple of
#    dt takes ceil(duration/dt) equal steps;
#  - 1 and 3 ranks write the same file; SIGTERM + --restart completes a
#    file-seeded run identically, and refuses a file changed in between;
#  - a non-finite row is one NONFINITE particle; the run goes on.
set -u
. "$(dirname "$0")/lib.sh"
cd "$TMP"
MPIRUN="mpirun --oversubscribe --bind-to none"

# METHOD DT DURATION OUT [FILE_P FILE_E]: 6 protons and 6 electrons in the
# dipole, drawn from the keys or (with FILE_*) read from files
scene() {
    cat <<RUN
[scene]
name     = seq
field    = dipole
duration = $3
seed     = 11
[particles.p]
species  = proton
RUN
    if [ $# -ge 5 ]; then echo "file = $5"; else cat <<'RUN'
count    = 6
energy   = 0.1 MeV .. 1 MeV log
L        = 3 .. 5
pitch    = 40 deg .. 80 deg
RUN
    fi
    printf '[particles.e]\nspecies  = electron\n'
    if [ $# -ge 6 ]; then echo "file = $6"; else cat <<'RUN'
count    = 6
energy   = 0.5 MeV .. 2 MeV log
L        = 3 .. 5
pitch    = 40 deg .. 80 deg
RUN
    fi
    cat <<RUN
[integrator]
method   = $1
dt       = $2
[output]
file     = $4
RUN
}

# final state of OUT split per population into /particles/initial of P and E
# (rows are in id order: protons 0..5, electrons 6..11)
to_init() {
    "$PY" - "$@" <<'PY' || die "to_init $*"
import sys, h5py
src, fp, fe = sys.argv[1:4]
with h5py.File(src, "r") as f:
    fin = f["particles/final"]
    names = [k for k in ("x", "u", "X", "ppar", "mu") if k in fin]
    for path, rows in ((fp, slice(0, 6)), (fe, slice(6, 12))):
        with h5py.File(path, "w") as g:
            for k in names:
                g["particles/initial/" + k] = fin[k][rows]
PY
}

# compare A B TOL: final states agree to TOL relative to each column's largest
# value, statuses and times exactly
compare() {
    "$PY" - "$@" <<'PY' || die "continuation $*"
import sys, h5py, numpy as np
a, b, tol = sys.argv[1], sys.argv[2], float(sys.argv[3])
with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
    A, B = fa["particles/final"], fb["particles/final"]
    sa, sb = A["status"][()], B["status"][()]
    assert (sa == sb).all(), "statuses %s vs %s" % (sa, sb)
    assert (sa == 0).sum() >= 8, "too few ALIVE particles to say anything: %s" % sa
    for k in ("x", "u", "X", "ppar", "mu"):
        if k not in A:
            continue
        va, vb = A[k][()][sa == 0], B[k][()][sa == 0]
        err = np.max(np.abs(va - vb)) / np.max(np.abs(va))
        assert err <= tol, "%s: %s differs by %.3g relative (tolerance %g)" % (a, k, err, tol)
        print("  %s %-4s relative difference %.2g" % (sys.argv[4], k, err))
PY
}

# Continuation.  Tolerances: boris and gc-rk4 do the same arithmetic in A
# and in B+C (static field, so a step does not depend on the time it starts
# at; the state passes through the file as doubles), hence 0; 1e-13 leaves
# room for a few hundred ulps.  gc-midpoint-pphi's Newton solve scales by the state at
# the start of the push, so C's iterations stop at a point of the same
# tolerance but a different round-off: each step may differ by its Newton
# tolerance (VI_TOL = 1e-15 of the scaled state), 100 steps add up to 1e-13;
# 1e-12 leaves a factor 10.  Any step too many or too
# few moves the state by v dt ~ 1e-4 of its size, far above every tolerance.
for case in "boris 2 us 1e-13" "gc-rk4 1 ms 1e-13" "gc-midpoint-pphi 1 ms 1e-12"; do
    set -- $case
    m=$1 dt="$2 $3" tol=$4
    scene "$m" "$dt" "100 ms" A.h5 > A.run
    scene "$m" "$dt" "50 ms" B.h5 > B.run
    scene "$m" "$dt" "50 ms" C.h5 $m-p.h5 $m-e.h5 > C.run
    "$GCPUSH" --quiet --force A.run || die "$m: run A failed"
    "$GCPUSH" --quiet --force B.run || die "$m: run B failed"
    to_init B.h5 $m-p.h5 $m-e.h5
    "$GCPUSH" --quiet --force C.run || die "$m: run C failed"
    compare A.h5 C.h5 "$tol" "$m"
done

# As given: C's /particles/initial holds the file's states bit for bit (the
# guiding centre untransformed; no full orbit, so x and u are NaN)
"$PY" - <<'PY' || die "states not used as given"
import h5py, numpy as np
with h5py.File("C.h5", "r") as c, h5py.File("gc-midpoint-pphi-p.h5", "r") as p, h5py.File("gc-midpoint-pphi-e.h5", "r") as e:
    for k in ("X", "ppar", "mu"):
        got = c["particles/initial/" + k][()]
        want = np.concatenate([p["particles/initial/" + k][()], e["particles/initial/" + k][()]])
        assert got.tobytes() == want.tobytes(), k
    assert np.isnan(c["particles/initial/x"][()]).all() and np.isnan(c["particles/initial/u"][()]).all()
    assert list(c["particles/id"][()]) == list(range(12))
    assert [s.decode() if isinstance(s, bytes) else s for s in c["particles/species"][()]] == ["proton"] * 6 + ["electron"] * 6
PY

# A step in gyro periods of given guiding centres: the shortest
# 2 pi gamma m / (|q| B(X)) of each population, gamma from ppar and mu,
# B of the dipole B0 R_E^3 / r^3 sqrt(1 + 3 sin^2 lat) computed here
scene gc-rk4 "0.5 gyro" "0.5 s" G.h5 gc-midpoint-pphi-p.h5 gc-midpoint-pphi-e.h5 > G.run
"$GCPUSH" --quiet --force G.run || die "gyro-step run failed"
mv G.h5 G1.h5
$MPIRUN -np 3 "$GCPUSH" --quiet --force G.run || die "gyro-step run on 3 ranks failed"
h5diff G1.h5 G.h5 /particles /particles > diff.txt 2>&1 || die "given guiding centres: 1 and 3 ranks differ: $(head -5 diff.txt)"
"$PY" - <<'PY' || die "gyro step of given guiding centres"
import h5py, numpy as np
c, mp, me, q = 299792458.0, 1.67262192369e-27, 9.1093837015e-31, 1.602176634e-19
B0, RE = 3.12e-5, 6.3712e6
with h5py.File("G.h5", "r") as f:
    X = f["particles/initial/X"][()]; pp = f["particles/initial/ppar"][()]
    mu = f["particles/initial/mu"][()]; dt = f["particles/dt"][()]
    T = 0.5
for rows, m in ((slice(0, 6), mp), (slice(6, 12), me)):
    r = np.linalg.norm(X[rows], axis=1); s = X[rows, 2] / r
    B = B0 * (RE / r) ** 3 * np.sqrt(1 + 3 * s * s)
    g = np.sqrt(1 + (pp[rows] / (m * c)) ** 2 + 2 * mu[rows] * B / (m * c * c))
    want = 0.5 * np.min(2 * np.pi * g * m / (q * B))
    want = T / np.ceil(T / want)          # whole steps in the duration
    assert np.allclose(dt[rows], want, rtol=1e-12, atol=0), (dt[rows], want)
    print("  gyro step of given guiding centres: %.6g s (expected %.6g s)" % (dt[rows][0], want))
PY

# duration = dt: exactly one step (full orbit and guiding centre); a
# duration of 2.5 dt: 3 steps of duration / 3
for m in boris gc-rk4 gc-midpoint-pphi; do
    scene $m "1 ms" "1 ms" one.h5 $m-p.h5 $m-e.h5 > one.run
    scene $m "1 ms" "2.5 ms" frac.h5 $m-p.h5 $m-e.h5 > frac.run
    "$GCPUSH" --quiet --force one.run || die "$m: one-step run failed"
    "$GCPUSH" --quiet --force frac.run || die "$m: 2.5-step run failed"
    "$GCPUSH" --check one.run | grep -q "1 steps of 0.001 s" || die "$m: --check: $("$GCPUSH" --check one.run)"
    "$PY" - $m <<'PY' || die "$m: steps"
import sys, h5py, numpy as np
for path, n, dt in (("one.h5", 1, 1e-3), ("frac.h5", 3, 2.5e-3 / 3)):
    with h5py.File(path, "r") as f:
        st, steps = f["particles/final/status"][()], f["timing/steps"][()]
        t, d = f["particles/final/t"][()], f["particles/dt"][()]
    alive = st == 0
    assert alive.sum() >= 8, st
    assert (steps[alive] == n).all(), (path, steps)
    assert (d == dt).all() and np.allclose(t[alive], n * dt, rtol=1e-15), (path, d, t)
print("  %s: duration = dt takes 1 step; 2.5 dt takes 3 steps of dt' = duration/3" % sys.argv[1])
PY
done

# A gcpush output as the file itself (its /particles/initial): run E from
# run D's output pushes D's particles again, so D and E agree bit for bit;
# E on 1 and 3 ranks writes the same datasets.  640 protons: 10 chunks.
ens() {
    cat <<RUN
[scene]
name     = ens
field    = dipole
duration = $2
seed     = 5
[particles]
species  = proton
$1
[integrator]
method   = boris
dt       = 0.01 gyro
[output]
file     = $3
RUN
}
ens "count = 640
energy = 0.1 MeV .. 1 MeV log
L = 2 .. 5
pitch = isotropic" "20 ms" D.h5 > D.run
"$GCPUSH" --quiet --force D.run || die "run D failed"
ens "file = D.h5" "20 ms" E.h5 > E.run
"$GCPUSH" --quiet --force E.run || die "run E failed"
$MPIRUN -np 3 "$GCPUSH" --quiet --force E.run || die "run E on 3 ranks failed"
mv E.h5 E3.h5
"$GCPUSH" --quiet --force E.run || die "run E failed"
for g in /particles; do
    h5diff D.h5 E.h5 $g $g > diff.txt 2>&1 || die "D and E differ in $g: $(head -5 diff.txt)"
    h5diff E.h5 E3.h5 $g $g > diff.txt 2>&1 || die "1 and 3 ranks differ in $g: $(head -5 diff.txt)"
done
echo "  a run seeded with another's output repeats it bit for bit; 1 and 3 ranks agree"

# Paths are relative to the working directory (like [field] file and
# [output] file), also on --restart: the run file lives in sub/, next to a
# decoy sub/D.h5 of other states, and names D.h5 of the working directory.
mkdir sub
"$PY" -c "
import h5py, numpy as np
with h5py.File('D.h5') as f, h5py.File('sub/D.h5', 'w') as g:
    g['particles/initial/x'] = f['particles/initial/x'][()] * 1.01
    g['particles/initial/u'] = f['particles/initial/u'][()]
"
ens "file = D.h5" "30 s" R.h5 | sed 's/^\[output\]/[output]\ncheckpoint = 0.05 s/' > sub/R.run
ens "file = D.h5" "30 s" ref.h5 > ref.run
# how long start-up and the whole run take (for the messages and the wait below)
start=$(date +%s%N)
"$GCPUSH" --check ref.run > /dev/null || die "reference run file refused"
boot=$(( ($(date +%s%N) - start) / 1000000 ))
start=$(date +%s%N)
"$GCPUSH" --quiet --force ref.run || die "reference run failed"
took=$(( ($(date +%s%N) - start) / 1000000 ))
# The signal goes once the first periodic checkpoint (every 0.05 s of the
# push) is on disk, i.e. while the push runs, whatever start-up and output
# cost (under the sanitizers they are most of the run).  A run that still
# ends first (exit 0: the signal came after the push) says nothing about
# SIGTERM and is tried again; any status but 0 and 3 fails at once.
rc=0
for try in 1 2 3; do
    "$GCPUSH" --quiet --force sub/R.run 2> term.txt & pid=$!
    waited=0
    while ! ls R.h5.ckpt.* > /dev/null 2>&1 && kill -0 $pid 2> /dev/null &&
          [ $waited -lt $(( took / 10 + 100 )) ]; do
        sleep 0.01; waited=$((waited + 1))
    done
    kill -TERM $pid 2> /dev/null; wait $pid; rc=$?
    [ $rc = 0 ] || break
    rm -f R.h5 R.h5.ckpt.*
done
[ $rc = 3 ] || die "SIGTERM during the push (${took} ms run, ${boot} ms to start, try $try): exit status $rc, not 3"
# the file changed since the checkpoint: refused, naming the file
cp D.h5 D.keep; "$PY" -c "
import h5py
with h5py.File('D.h5', 'r+') as f: f['particles/initial/u'][...] *= 1.001"
if "$GCPUSH" --quiet --restart R.h5 2> changed.txt; then
    die "restart from a changed file succeeded (or no particle was checkpointed: interrupted too early, ${took} ms run)"
fi
grep -q "D.h5: the initial state of particle [0-9]* differs from the one checkpointed" changed.txt ||
    die "changed file: $(cat changed.txt)"
[ -f R.h5 ] && die "a refused restart wrote its output"
mv D.keep D.h5
$MPIRUN -np 2 "$GCPUSH" --restart R.h5 > restart.txt || die "restart failed: $(cat restart.txt)"
rows=$(sed -n 's/^restart: \([0-9]*\) particles from.*/\1/p' restart.txt)
[ "${rows:-0}" -gt 0 ] || die "the restart loaded no particle: $(cat restart.txt)"
h5diff ref.h5 R.h5 /particles /particles > diff.txt 2>&1 || die "restart differs: $(head -5 diff.txt)"
echo "  --restart of a file-seeded run ($rows particles checkpointed) = the uninterrupted run"
# and a file next to the run file only is not found from elsewhere
cp sub/D.h5 sub/only.h5
sed 's/^file = D.h5/file = only.h5/' sub/R.run > sub/only.run
"$GCPUSH" --check sub/only.run > /dev/null 2> only.txt && die "sub/only.run found sub/only.h5 from $(pwd)"
grep -q "sub/only.run:8: \[particles\] file: only.h5: cannot open (no such file?)" only.txt ||
    die "missing file: $(cat only.txt)"

# A non-finite row is one NONFINITE particle (0 steps); the others run on,
# and the run says so once
"$PY" -c "
import h5py, numpy as np
with h5py.File('D.h5') as f, h5py.File('nan.h5', 'w') as g:
    x = f['particles/initial/x'][:5]; x[2, 1] = np.nan
    g['particles/initial/x'] = x; g['particles/initial/u'] = f['particles/initial/u'][:5]
"
ens "file = nan.h5" "20 ms" N.h5 > N.run
"$GCPUSH" --quiet --force N.run 2> nan.txt || die "a run with a NaN row failed: $(cat nan.txt)"
grep -q "warning: nan.h5: 1 of its 5 initial states are not finite" nan.txt || die "no warning: $(cat nan.txt)"
"$PY" -c "
import h5py
f = h5py.File('N.h5'); st = list(f['particles/final/status'][()]); n = list(f['timing/steps'][()])
assert st == [0, 0, 5, 0, 0] and n[2] == 0 and min(n[:2] + n[3:]) > 0, (st, n)
" || die "NaN row"

echo "ok init_file"
