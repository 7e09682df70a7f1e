#!/bin/sh
# Bad input: every failure gives one line naming file:line and key, a
# non-zero exit status, and leaves no output file behind.
set -u
. "$(dirname "$0")/lib.sh"
DATA=$(cd "$(dirname "$0")/../../fields/data" && pwd)
cd "$TMP"

good() {
cat <<'RUN'
[scene]
name     = t
field    = uniform
duration = 10 gyro
seed     = 1

[field]
B = 0 0 1 T

[particles]
species   = proton
count     = 3
energy    = 1 keV
position  = 0 0 0 m
direction = 1 0 0

[integrator]
method = boris
dt     = 0.1 gyro

[output]
file = out.h5
RUN
}

# expect NAME PATTERN: runs gcpush on case.run, wants failure matching PATTERN
expect() {
    name=$1 pattern=$2
    rm -f out.h5 out.h5.tmp-*
    if "$GCPUSH" case.run > stdout.txt 2> stderr.txt; then die "$name: exit status 0"; fi
    grep -q -- "$pattern" stderr.txt || die "$name: message '$(cat stderr.txt)' lacks '$pattern'"
    [ "$(wc -l < stderr.txt)" -le 1 ] || die "$name: more than one line: $(cat stderr.txt)"
    ls out.h5* > /dev/null 2>&1 && die "$name: output left behind: $(ls out.h5*)"
    true
}

# the good file runs, so each failure below is the edit's doing
good > case.run
"$GCPUSH" --quiet case.run || die "the reference run file fails"
[ -f out.h5 ] || die "the reference run wrote no output"
rm -f out.h5

good | sed 's/^\[field\]/[field/' > case.run;            expect syntax 'case.run:7: syntax error'
good | sed 's/^\[output\]/[outptu]/' > case.run;         expect unknown-section 'case.run:2[0-9]: \[outptu\]: unknown section'
good | sed 's/^seed .*/sede = 1/' > case.run;             expect unknown-key 'case.run:5: \[scene\] sede: unknown key'
good | sed '/^method/d' > case.run;                       expect missing-key '\[integrator\] method: required key is missing'
good | sed 's/^energy .*/energy = 1 keV/;s/^count .*/count = 3/;s/^energy .*/energy = 1 m/' > case.run
expect bad-unit 'case.run:13: \[particles\] energy: expected an energy unit'
good | sed 's/^energy .*/energy = 1000/' > case.run;      expect no-unit '\[particles\] energy: expected an energy with a unit'
good | sed 's/^count .*/count = -5/' > case.run;          expect negative-count 'case.run:12: \[particles\] count: must be in 1'
good | sed 's/^dt .*/dt = 0 s/' > case.run;               expect zero-dt 'case.run:19: \[integrator\] dt: must be > 0'
good | sed 's/^dt .*/dt = -1 s/' > case.run;              expect negative-dt '\[integrator\] dt: must be > 0'
good | sed 's/^position .*/position = nan 0 0 m/' > case.run; expect nan-position '\[particles\] position: a component is not a finite number'
good | sed 's/^energy .*/energy = nan MeV/' > case.run;   expect nan-energy '\[particles\] energy: value is not a finite number'
good | sed 's/^energy .*/energy = 0 MeV/' > case.run;     expect zero-energy '\[particles\] energy: kinetic energy must be > 0'
# a start the run cannot carry is the key's fault, not dt's or duration's:
# inside the dipole's atmosphere (it would precipitate at step 0), and an
# energy whose momentum overflows a double
good | sed 's/^field    = uniform/field    = dipole/; /^B = /d' > case.run
expect position-in-earth "case.run:13: \[particles\] position: r = 0 m is inside the atmosphere of field 'dipole' (r < r_inner = 6.4712e+06 m = R_E + 100 km): the particle would precipitate at once"
rc=0; "$GCPUSH" --check case.run > /dev/null 2>&1 || rc=$?
[ "$rc" = 2 ] || die "position-in-earth --check: exit status $rc, want 2"
good | sed 's/^energy .*/energy = 1e300 eV/' > case.run
expect huge-energy "case.run:13: \[particles\] energy: 1e+300 eV is beyond what double precision can carry for a proton"
good | sed 's/^energy .*/energy = 1e300 eV/; s/^dt .*/dt = 1 ms/; s/^duration .*/duration = 1 s/' > case.run
expect huge-energy-seconds "case.run:13: \[particles\] energy: 1e+300 eV is beyond what double precision"
good | sed 's/^species .*/species = muon/' > case.run;    expect unknown-species "unknown species 'muon'"
good | sed 's/^method .*/method = leapfrog/' > case.run;  expect unknown-method "unknown method 'leapfrog'"
good | sed 's/^field .*/field = quadrupole/' > case.run;  expect unknown-field "unknown field model 'quadrupole'"
good | sed 's/^B = .*/B = 0 0 1 V\/m/' > case.run;        expect field-unit '\[field\] B: expected a magnetic field unit'
good | sed 's/^duration .*/duration = 2 drift/' > case.run; expect no-drift-period 'no drift period'
good | sed 's/^file = .*/file = no\/such\/dir\/out.h5/' > case.run; expect unwritable "\[output\] file: cannot write 'no/such/dir/out.h5'"
good | sed 's/^method = boris/method = boris\ntolerance = 1e-9/' > case.run; expect tolerance-fixed 'tolerance applies only to adaptive'
# [integrator] arithmetic: ieee or fast, fast for full-orbit methods only
good | sed 's/^method = boris/method = boris\narithmetic = quick/' > case.run
expect arithmetic-word 'case.run:[0-9]*: \[integrator\] arithmetic: expected ieee or fast'
good | sed 's/^method = boris/method = gc-rk4\narithmetic = fast/' > case.run
expect arithmetic-gc 'case.run:[0-9]*: \[integrator\] arithmetic: fast applies only to full-orbit'
good | sed 's/^method = boris/method = boris\narithmetic = fast/' > case.run
"$GCPUSH" --quiet case.run || die "arithmetic = fast fails on the reference run file"
rm -f out.h5
good | sed 's/^direction .*/pitch = 30 deg/' | sed 's/^position .*/L = 4/' > case.run; expect L-needs-dipole 'L shells need field = dipole'
good | sed 's/^file = out.h5/file = out.h5\ncompression = 12/' > case.run; expect bad-compression '\[output\] compression: expected none or a deflate level 1..9'
good | sed '/^\[output\]/,$d' > case.run;                 expect missing-section '\[output\] section is missing'
printf '[scene]\nname = x\000\n' > case.run;              expect nul-byte 'NUL byte'
# missing and corrupt field files: named with the run file's line and key
good | sed 's/^field    = uniform/field    = grid/; s/^B = .*/file = missing-grid.h5/' > case.run
expect missing-grid "case.run:8: \[field\] file: missing-grid.h5: cannot open grid file"
echo garbage > corrupt.h5
good | sed 's/^field    = uniform/field    = grid/; s/^B = .*/file = corrupt.h5/' > case.run
expect corrupt-grid "case.run:8: \[field\] file: corrupt.h5: not an HDF5 file"
good | sed 's/^field    = uniform/field    = eqdsk/; s/^B = .*/file = corrupt.h5/' > case.run
expect corrupt-eqdsk "case.run:8: \[field\] file: corrupt.h5:1: expected 48 characters"
# a grid file whose origin is NaN: named as the origin, not as a spacing error
"$PY" - <<'PY' || die "making nan-origin.h5"
import h5py, numpy as np
with h5py.File("nan-origin.h5", "w") as f:
    f.attrs["geometry"] = "axisymmetric"
    f.attrs["origin"] = [1.0, float("nan")]
    f.attrs["spacing"] = [0.1, 0.1]
    f["Bphi"] = np.ones((11, 11))
    f["BR"] = np.zeros((11, 11))
    f["BZ"] = np.zeros((11, 11))
PY
good | sed 's/^field    = uniform/field    = grid/; s/^B = .*/file = nan-origin.h5/' > case.run
expect nan-grid-origin "case.run:8: \[field\] file: nan-origin.h5: attribute /origin\[1\] = nan (axis Z): not finite"
# an IGRF table with a row left out (its coefficient would be taken as 0):
# refused, naming the table, the file key's line and the missing (n, m)
grep -v '^h  3  2 ' "$DATA/igrf14coeffs.txt" > igrf-holed.txt
good | sed 's/^field    = uniform/field    = igrf/; s/^B = .*/file = igrf-holed.txt\nepoch = 2020/; s/^position .*/position = 4 0 0 RE/' > case.run
expect igrf-missing-row "case.run:8: \[field\] file: igrf-holed.txt: row h 3 2 (degree n = 3, order m = 2) is missing"
"$GCPUSH" missing.run > /dev/null 2> stderr.txt && die "missing file: exit 0"
grep -q "missing.run: cannot open" stderr.txt || die "missing file: $(cat stderr.txt)"
"$GCPUSH" --frobnicate > /dev/null 2>&1 && die "unknown option: exit 0"

# [particles] file = ...: every unusable file is refused before anything
# runs, naming run file, line and key, then the state file and dataset
"$PY" - <<'PY' || die "making the state files"
import h5py, numpy as np
x = np.zeros((3, 3)); u = np.tile([1e5, 0.0, 0.0], (3, 1))
def make(name, **d):
    with h5py.File(name, "w") as f:
        f.create_group("particles/initial")
        for k, v in d.items():
            f["particles/initial/" + k] = v
make("s.h5", x=x, u=u)
make("gc.h5", X=x, ppar=np.ones(3) * 1e-22, mu=np.ones(3) * 1e-16)
make("negmu.h5", X=x, ppar=np.ones(3) * 1e-22, mu=np.array([1e-16, -1.0, 1e-16]))
make("shape.h5", x=np.zeros((3, 2)), u=u)
make("rows.h5", x=x, u=np.zeros((4, 3)))
make("int.h5", x=np.zeros((3, 3), dtype=np.int32), u=u)
make("empty.h5", x=np.zeros((0, 3)), u=np.zeros((0, 3)))
make("nan.h5", x=x * np.nan, u=u)
with h5py.File("nogroup.h5", "w") as f:
    f["x"] = x
PY
states() { good | sed "s/^count .*/file = $1/; /^energy/d; /^position/d; /^direction/d"; }
states s.h5 > case.run
"$GCPUSH" --quiet case.run || die "a good state file fails"
rm -f out.h5
states s.h5 | sed 's/^file = s.h5/count = 3\nfile = s.h5/' > case.run
"$GCPUSH" --quiet case.run || die "a state file with a matching count fails"
rm -f out.h5
states nope.h5 > case.run;      expect file-missing 'case.run:12: \[particles\] file: nope.h5: cannot open (no such file?)'
states corrupt.h5 > case.run;   expect file-not-hdf5 'case.run:12: \[particles\] file: corrupt.h5: not an HDF5 file'
states nogroup.h5 > case.run;   expect file-no-group 'file: nogroup.h5: no group /particles/initial'
states gc.h5 > case.run;        expect fo-needs-x 'file: gc.h5: dataset /particles/initial/x is missing (full-orbit methods start from x'
states s.h5 | sed 's/^method .*/method = gc-rk4/' > case.run
expect gc-needs-X 'file: s.h5: dataset /particles/initial/X is missing (guiding-centre methods start from X'
states negmu.h5 | sed 's/^method .*/method = gc-rk4/' > case.run
expect negative-mu 'file: negmu.h5: /particles/initial/mu\[1\] = -1: mu must be >= 0'
states shape.h5 > case.run;     expect file-shape 'shape.h5: /particles/initial/x has the wrong shape (expected (N, 3))'
states rows.h5 > case.run;      expect file-rows 'rows.h5: /particles/initial/u has 4 rows, the datasets before it 3'
states int.h5 > case.run;       expect file-int 'int.h5: /particles/initial/x is not floating-point'
states empty.h5 > case.run;     expect file-empty 'empty.h5: /particles/initial/x has 0 rows'
states nan.h5 > case.run;       expect file-all-nan 'nan.h5: none of its 3 initial states is finite'
states s.h5 | sed 's/^file = s.h5/count = 4\nfile = s.h5/' > case.run
expect file-count 'case.run:12: \[particles\] count: is 4, but s.h5 holds 3 initial states'
for k in "energy = 1 keV" "position = 0 0 0 m" "direction = 1 0 0" "pitch = 30 deg" "phase = 0 deg" "longitude = 0 deg"; do
    states s.h5 | sed "s/^file = s.h5/file = s.h5\n$k/" > case.run
    expect "file-with-${k%% *}" "case.run:13: \[particles\] ${k%% *}: conflicts with file = s.h5"
done
states s.h5 | sed 's/^\[output\]/[sweep]\nmethods = boris\ndt = 0.1 gyro\nreference = analytic\n[output]/' > case.run
expect file-sweep 'case.run:12: \[particles\] file: a \[sweep\] draws its particles from the keys'

# symplectic guiding-centre methods need a canonical chart (issue 11): refused
# before the run, at --check time too, naming file:line, [integrator] method
# and why, exit status 2 (never a run in which every particle fails)
gc() { good | sed "s/^method = boris/method = $1/; s/^dt     = 0.1 gyro/dt     = 1 ms/"; }
igrf() { sed "s|^field    = uniform|field    = igrf|; s|^B = .*|file = $DATA/igrf14coeffs.txt\nepoch = 2020|; s|^position .*|position = 4 0 0 RE|"; }
gc gc-gl4 | igrf > case.run
expect gl4-in-igrf "case.run:19: \[integrator\] method: method 'gc-gl4' cannot run in the igrf field: curl-free chart: the field is not axisymmetric"
rc=0; "$GCPUSH" --check case.run > /dev/null 2>&1 || rc=$?
[ "$rc" = 2 ] || die "gl4-in-igrf --check: exit status $rc, want 2"
gc gc-gl2 | sed 's/^field    = uniform/field    = grid/; s|^B = .*|file = '"$DATA"'/dipole.h5|; s|^position .*|position = 4 0 0 RE|' > case.run
expect gl2-in-grid "\[integrator\] method: method 'gc-gl2' cannot run in the grid field"
gc gc-midpoint-pphi | igrf > case.run
expect midpoint-in-igrf "method 'gc-midpoint-pphi' cannot run in the igrf field: the field model has no analytic vector potential"
gc gc-vi > case.run
expect gc-vi-renamed "case.run:18: \[integrator\] method: gc-vi is gone: it was not a variational integrator; use gc-gl2 or gc-gl4"
# [diagnostics] sample_every: a whole number of steps (issue 13)
diag() { good | sed "s/^\[output\]/[diagnostics]\ninvariants = mu\nsample_every = $1\n\n[output]/"; }
diag 0 > case.run;      expect sample-every-zero 'case.run:23: \[diagnostics\] sample_every: must be in 1 .. 1000000000, got 0'
diag 2.5 > case.run;    expect sample-every-fraction "case.run:23: \[diagnostics\] sample_every: expected a whole number, got '2.5'"
diag '10 s' > case.run; expect sample-every-unit "case.run:23: \[diagnostics\] sample_every: expected a whole number, got '10 s'"
diag 16 > case.run
"$GCPUSH" --quiet case.run || die "sample_every = 16 refused"
# gyration in a uniform field mirrors nowhere: its mu rows come every 16 of its 100 steps, up to
# its last gyro-averaged sample (the middle of its last whole gyration, 95 steps): 5 rows
"$PY" - out.h5 <<'PY' || die "sample_every = 16: rows not at 16 dt"
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1], "r")
s, dt = f["invariants/samples"], f["particles/dt"][0]
assert np.array_equal(s["id"][:], np.repeat([0, 1, 2], 5)), s["id"][:]
assert np.allclose(s["t"][:], np.tile(16 * dt * np.arange(1, 6), 3), rtol=1e-12), s["t"][:] / dt
PY
rm -f out.h5

# --check validates without writing anything
good > case.run
"$GCPUSH" --check case.run > stdout.txt || die "--check fails on a good file"
[ -f out.h5 ] && die "--check wrote output"
echo "ok test_bad_input"
