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
good | sed 's/^species .*/species = muon/' > case.run;    expect unknown-species "unknown species 'muon'"
good | sed 's/^method .*/method = leapfrog/' > case.run;  expect unknown-method "unknown method 'leapfrog'"
good | sed 's/^field .*/field = quadrupole/' > case.run;  expect unknown-field "unknown field model 'quadrupole'"
good | sed 's/^B = .*/B = 0 0 1 V\/m/' > case.run;        expect field-unit '\[field\] B: expected a magnetic field unit'
good | sed 's/^duration .*/duration = 2 drift/' > case.run; expect no-drift-period 'no drift period'
good | sed 's/^file = .*/file = no\/such\/dir\/out.h5/' > case.run; expect unwritable "\[output\] file: cannot write 'no/such/dir/out.h5'"
good | sed 's/^method = boris/method = boris\ntolerance = 1e-9/' > case.run; expect tolerance-fixed 'tolerance applies only to adaptive'
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
"$GCPUSH" missing.run > /dev/null 2> stderr.txt && die "missing file: exit 0"
grep -q "missing.run: cannot open" stderr.txt || die "missing file: $(cat stderr.txt)"
"$GCPUSH" --frobnicate > /dev/null 2>&1 && die "unknown option: exit 0"

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

# --check validates without writing anything
good > case.run
"$GCPUSH" --check case.run > stdout.txt || die "--check fails on a good file"
[ -f out.h5 ] && die "--check wrote output"
echo "ok test_bad_input"
