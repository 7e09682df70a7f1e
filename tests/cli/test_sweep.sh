#!/bin/sh
# [sweep]: the table on stdout, /sweep in the output (layout of README
# "Output"), analysis/work_precision.py, and bad [sweep] sections (one line
# naming file:line and key, exit 2, no output left behind).
set -u
. "$(dirname "$0")/lib.sh"
ROOT=$(pwd)
cd "$TMP"
sed 's/^file = sweep-gyration.h5/file = out.h5/' "$ROOT/runs/sweep-gyration.run" > sw.run
"$GCPUSH" --check sw.run > check.txt 2>&1 || die "--check: $(cat check.txt)"
grep -q "ok: sweep of 4 method" check.txt || die "--check says: $(cat check.txt)"
[ ! -e out.h5 ] || die "--check wrote output"
"$GCPUSH" sw.run > table.txt 2> progress.txt || die "sweep run failed: $(tail -2 progress.txt)"
# an existing sweep output is not replaced without --force (issue 15, item 7)
if "$GCPUSH" sw.run > /dev/null 2> again.txt; then die "a sweep replaced its existing output"; fi
grep -q "out.h5' exists: remove it or run with --force" again.txt || die "sweep over an existing output: $(cat again.txt)"
grep -q "^sweep sweep-gyration: 1 particle" table.txt || die "no table header: $(head -2 table.txt)"
[ "$(grep -c '^higuera-cary ' table.txt)" = 7 ] || die "table rows: $(cat table.txt)"
"$PY" - <<'PY' || die "/sweep layout or values"
import sys, h5py, numpy as np
f = h5py.File("out.h5", "r")
for a in ("gcpush_version", "git_hash", "build_flags", "run_file", "units"):
    assert a in f.attrs, a
g = f["sweep"]
assert g.attrs["reference"] in (b"analytic", "analytic")
cols = ("method population dt dt_given dt_unit tolerance cpu_seconds steps particles failed "
        "position_error position_error_gyroradius position_error_path gc_position_error "
        "gyrophase_error bounce_phase_error drift_phase_error energy_error mu_drift K_drift Lstar_drift").split()
for c in cols:
    assert c in g and g[c].shape == (28,), c
    assert "units" in g[c].attrs, c
m = np.array([x.decode() for x in g["method"][()]])
e = g["position_error"][()]
assert np.all(g["failed"][()] == 0)
assert np.all(g["cpu_seconds"][()] > 0)
assert np.all(e[m == "boris-zu"] < 1e-9), e[m == "boris-zu"]
b = e[m == "boris"]
slope = np.log(b[-3] / b[-1]) / np.log(4.0)
assert 1.9 < slope < 2.1, slope          # the second order of boris
assert np.all(g["energy_error"][()] < 1e-12)
for c in ("mu_drift", "K_drift", "Lstar_drift", "bounce_phase_error", "drift_phase_error"):
    assert np.all(np.isnan(g[c][()])), c  # no bounce or drift in a uniform field
PY
"$PY" "$ROOT/analysis/work_precision.py" out.h5 -o wp.png > wp.txt 2> wp.err || die "work_precision: $(cat wp.err)"
[ -s wp.png ] || die "no PNG"
grep -q "^boris .*order 2" wp.txt || die "no fitted order: $(tail -6 wp.txt)"
# errors: one line, exit 1
if "$PY" "$ROOT/analysis/work_precision.py" nothere.h5 > /dev/null 2> e.txt; then die "missing file accepted"; fi
[ "$(wc -l < e.txt)" = 1 ] && grep -q "work_precision: error: nothere.h5: no such file" e.txt || die "$(cat e.txt)"

# the invariant columns: runs/sweep-dipole-gc.run cut down to 2 protons, gc-gl2
# and gc-rk4 at 3 steps, for 3 drift periods (of the first proton, 84 s;
# about 250 s, some 130 bounces), so that every particle has >= 2 drift
# events (the second drifts in 110 s: at 2.3 periods it had one, and its
# NaN L* drift rate was hidden by the old keep_max, issue 13)
sed 's/^file = .*/file = inv.h5/; s/^duration = .*/duration = 3 drift/; s/^count   = 4/count   = 2/;
     s/^methods   = .*/methods   = gc-gl2 gc-rk4/; s/^dt        = .*/dt        = 0.5 0.25 0.125 gyro/;
     s/^reference = .*/reference = gc-rk8pd 1e-12/; /^tolerance/d' "$ROOT/runs/sweep-dipole-gc.run" > inv.run
# (the reference of the guiding-centre model itself, gc-rk8pd: the columns
# below measure the methods' convergence, which the full-orbit reference of
# runs/sweep-dipole-gc.run hides under the model's own O(eps) error)
"$GCPUSH" inv.run > inv.txt 2> inv.err || die "invariant sweep failed: $(tail -2 inv.err)"
"$PY" - <<'PY' || die "invariant columns"
import h5py, numpy as np
g = h5py.File("inv.h5", "r")["sweep"]
D = g.attrs["duration"]
m = np.array([x.decode() for x in g["method"][()]])
col = lambda c, meth: g[c][()][m == meth]
vi = lambda c: col(c, "gc-gl2")
for c in ("mu_drift", "K_drift", "Lstar_drift", "bounce_phase_error", "drift_phase_error"):
    assert np.all(np.isfinite(g[c][()])), (c, g[c][()])
# gc-gl2 carries mu as a constant: the per-bounce mu changes by round-off only
assert np.all(vi("mu_drift") * D < 1e-12), vi("mu_drift") * D
# K: second order, and symplectic (no secular growth): the relative change
# over the run is bounded by the amplitude of its oscillation (measured
# 1.35e-6 at 0.5 gyro, ~1/30 of a bounce, over 3 drift periods; 2e-7 at
# 2.3, a luckier phase: the bound is 2x the amplitude) and falls at least
# like dt^2 (each halving divides it by >= 4, here allowing 2.5; measured
# 570 and 8)
K = vi("K_drift")
assert np.all(K * D < 3e-6), K * D
assert np.all(K[1:] < K[:-1] / 2.5), K
# gc-gl2 conserves p_phi in the axisymmetric dipole (discrete Noether, exact
# by construction): L* is steady to round-off
assert np.all(vi("Lstar_drift") * D < 1e-10), vi("Lstar_drift") * D
# bounce and drift phase errors fall as dt^2 (gc-gl2 is second order).  The
# floor (reference error + mirror-point interpolation, O(dt^2) of the run
# itself) is below 2e-4 rad (gc-rk4 at 0.25 gyro), < 0.2 % of gc-gl2's
# smallest bounce phase error, and the next term is O((dt/T_b)^2) ~ 1e-3
# relative: the observed order is 2 within ~0.01; allow 1.8 .. 2.2
for c in ("bounce_phase_error", "drift_phase_error"):
    e = vi(c)
    order = np.log2(e[:-1] / e[1:])
    assert np.all((order > 1.8) & (order < 2.2)), (c, e, order)
# gc-rk4 is more accurate at each step
assert np.all(col("bounce_phase_error", "gc-rk4") < vi("bounce_phase_error")), "rk4 vs vi"
PY

# a NaN is the worst error, not none (issue 13): at 2.3 drift periods the
# second proton (drift period 110 s against the first's 84 s) has one drift
# event, so its L* drift rate cannot be measured and neither can the
# row's maximum -- NaN, where the old keep_max reported the first proton's
# alone; K (two bounce events each) stays measured
sed 's/^duration = .*/duration = 2.3 drift/; s/^methods   = .*/methods   = gc-rk4/;
     s/^dt        = .*/dt        = 0.5 gyro/; s/^file = .*/file = nan.h5/' inv.run > nan.run
"$GCPUSH" nan.run > nan.txt 2> nan.err || die "NaN sweep failed: $(tail -2 nan.err)"
"$PY" - <<'PY' || die "a NaN per-particle error must make the row NaN"
import h5py, numpy as np
g = h5py.File("nan.h5", "r")["sweep"]
assert np.all(np.isnan(g["Lstar_drift"][()])), g["Lstar_drift"][()]
assert np.all(np.isfinite(g["K_drift"][()])), g["K_drift"][()]
PY

# bad [sweep] sections
bad() {
    name=$1 pattern=$2
    rm -f out.h5 out.h5.tmp-*
    if "$GCPUSH" case.run > /dev/null 2> err.txt; then die "$name: accepted"; fi
    [ "$(wc -l < err.txt)" = 1 ] || die "$name: more than one line: $(cat err.txt)"
    grep -q -- "$pattern" err.txt || die "$name: '$(cat err.txt)' lacks '$pattern'"
    [ -z "$(ls out.h5* 2>/dev/null)" ] || die "$name: output left behind"
}
sed 's/^methods   = .*/methods   = boris warp-drive/' sw.run > case.run
bad "unknown method" "case.run:26: \[sweep\] methods: unknown method 'warp-drive'"
sed 's/^dt        = .*/dt        = 0.1 0.05/' sw.run > case.run
bad "dt without unit" "\[sweep\] dt: expected a time"
sed 's/^dt        = .*/dt        = 0.1 x gyro/' sw.run > case.run
bad "dt not a number" "\[sweep\] dt: expected a number, got 'x'"
sed 's/^reference = .*/reference = boris-zu 1e-3/' sw.run > case.run
bad "reference without unit" "\[sweep\] reference: fixed-step method 'boris-zu' takes a step"
sed 's/^reference = .*/reference = gc-rk8pd 1e-3 gyro/' sw.run > case.run
bad "adaptive reference with a step" "\[sweep\] reference: adaptive method 'gc-rk8pd' takes a tolerance"
sed 's/^reference = .*/reference = fo-rk8pd 1e-3 gyro/' sw.run > case.run
bad "fo-rk8pd with a step" "\[sweep\] reference: adaptive method 'fo-rk8pd' takes a tolerance"
sed 's/^reference = .*/reference = fo-rk9 1e-13/' sw.run > case.run
bad "unknown reference" "\[sweep\] reference: unknown method 'fo-rk9' (a method, or fo-rk8pd"
sed 's/^reference = .*/reference = analytic\ntolerance = 1e-8/' sw.run > case.run
bad "tolerance without adaptive" "\[sweep\] tolerance: tolerance applies only to adaptive"
sed 's/^reference = .*/reference = analytic\nrepeat = 3/' sw.run > case.run
bad "unknown key" "\[sweep\] repeat"
sed 's/^methods   = .*/methods   = gc-rk45/' sw.run > case.run
bad "dt without fixed-step methods" "\[sweep\] dt: no fixed-step method in methods"
sed 's/^methods   = .*/methods   = gc-rk45/; /^dt        = /d' sw.run > case.run
bad "adaptive without tolerance" "\[sweep\] tolerance: required for the adaptive"
sed 's/^file = out.h5/file = out.h5\ntrajectory = 10 samples/' sw.run > case.run
bad "trajectory" "\[output\] trajectory: a sweep writes no trajectories"
sed 's/^reference = .*/reference = analytic/; s/^field    = uniform/field    = dipole/; s/^B = 0 0 1e-3 T//; s/^position = 0 0 0 m/position = 4 0 0 RE/' sw.run > case.run
bad "analytic in a dipole" "\[sweep\] reference: no analytic answer in field 'dipole'"
echo "ok test_sweep"
