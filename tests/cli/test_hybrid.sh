#!/bin/sh
# method = hybrid (issue 14): bad keys name file:line:key before anything
# runs; the output layout (/hybrid, both final forms, trajectory modes) holds
# together; the same file on 1 and 3 ranks and through a checkpoint and
# --restart.
set -u
. "$(dirname "$0")/lib.sh"
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
cd "$TMP"
MPIRUN="mpirun --oversubscribe --bind-to none"

# protons of 5-50 MeV at L = 3-6: adiabatic ones stay guiding centres, the
# others switch (130 particles: three chunks, so ranks share the work)
cat > hy.run <<'RUN'
[scene]
name     = hy
field    = dipole
duration = 5 s
seed     = 11
[particles]
species  = proton
count    = 130
energy   = 5 MeV .. 50 MeV log
L        = 3 .. 6
pitch    = 20 deg .. 80 deg
[integrator]
method       = hybrid
gc           = gc-rk4
fo           = boris
switch_to_fo = 0.1
switch_to_gc = 0.05
fo_dt        = 0.05 gyro
dt           = 0.01 bounce
[diagnostics]
invariants = mu K L energy
events     = bounce drift loss
[output]
file       = OUT
trajectory = 50 samples
RUN

# ---- bad input: file:line: [integrator] key, exit status 2, no output ----
bad() {
    name=$1 pattern=$2
    "$GCPUSH" case.run > out.txt 2> err.txt && die "$name: exit status 0"
    grep -q -- "$pattern" err.txt || die "$name: message '$(cat err.txt)' lacks '$pattern'"
    ls bad.h5* > /dev/null 2>&1 && die "$name: left an output file"
    return 0
}
sed "s/OUT/bad.h5/" hy.run > base.run
sed "s/^gc           = gc-rk4/gc           = boris/" base.run > case.run
bad gc-not-gc "case.run:14: \[integrator\] gc: 'boris' is not a guiding-centre method"
sed "s/^fo           = boris/fo           = gc-rk4/" base.run > case.run
bad fo-not-fo "case.run:15: \[integrator\] fo: 'gc-rk4' is not a full-orbit method"
sed "s/^switch_to_gc = 0.05/switch_to_gc = 0.2/" base.run > case.run
bad no-hysteresis "case.run:17: \[integrator\] switch_to_gc: must lie in (0, switch_to_fo"
sed "s/^fo_dt        = 0.05 gyro/fo_dt        = 1 ms/" base.run > case.run
bad fo-dt-unit "case.run:18: \[integrator\] fo_dt: is a fraction of the local gyro-period"
sed "s/^fo_dt        = 0.05 gyro/fo_dt        = 0.5 gyro/" base.run > case.run
bad fo-dt-range "case.run:18: \[integrator\] fo_dt: must lie in (0, 0.25\]"
sed "s/^fo_dt        = 0.05 gyro/adiabaticity = 0.1/" base.run > case.run
bad adiabaticity "case.run:18: \[integrator\] adiabaticity: method = hybrid switches at switch_to_fo"
sed "s/^method       = hybrid/method       = gc-rk4/" base.run > case.run
bad keys-without-hybrid "case.run:14: \[integrator\] gc: unknown key"

# ---- a run: layout and consistency ----
sed "s/OUT/h1.h5/" hy.run > h1.run
"$GCPUSH" --quiet h1.run || die "hybrid run failed"
"$PY" - h1.h5 <<'PY' || die "hybrid output inconsistent"
import sys
import h5py, numpy as np
f = h5py.File(sys.argv[1], "r")
assert f.attrs["method"] in (b"hybrid", "hybrid"), f.attrs["method"]
h, fin = f["hybrid"], f["particles/final"]
N = len(f["particles/id"])
for k in ("x", "u", "X", "ppar", "mu", "t", "status"):
    assert fin[k].shape[0] == N, k
for k in ("X", "ppar", "mu"):
    assert f["particles/initial/" + k].shape[0] == N, k
mode, sw, tgc, tfo = h["mode"][:], h["switches"][:], h["t_gc"][:], h["t_fo"][:]
alive = fin["status"][:] == 0
# time in the two modes adds up to the time pushed
assert np.allclose((tgc + tfo)[alive], fin["t"][alive], rtol=1e-12, atol=0), "t_gc + t_fo != t"
ev = h["events"]
ids, t, d = ev["id"][:], ev["t"][:], ev["direction"][:]
assert ev["X"].shape == (len(ids), 3)
# events sorted by (id, t); one row per switch; directions alternate
assert np.all(np.diff(ids) >= 0)
assert np.array_equal(np.bincount(ids, minlength=N), sw), "switch counts != event rows"
for i in np.unique(ids):
    di = d[ids == i]
    ti = t[ids == i]
    assert np.all(np.diff(ti) > 0), i
    assert np.all(di[1:] == -di[:-1]), ("directions do not alternate", i, di)
# the final mode follows from the start and the number of switches
assert np.all(np.isin(mode, (0, 1)))
# mixed: some particles switch, some stay guiding centres throughout
assert sw.max() >= 1 and np.count_nonzero((sw == 0) & (mode == 0)) >= 1, (sw, mode)
# GC -> FO above switch_to_fo, FO -> GC below switch_to_gc
eps = ev["eps"][:]
assert np.all(eps[d > 0] > 0.1) and np.all(eps[d < 0] < 0.05)
# every particle's final state in both forms: the particle's guiding centre is
# within a gyroradius-sized distance of X (first-order transformations)
x, X = fin["x"][:], fin["X"][:]
ok = alive & np.isfinite(x).all(1) & np.isfinite(X).all(1)
assert ok.sum() >= alive.sum() - 2
r = np.linalg.norm(x[ok] - X[ok], axis=1) / np.linalg.norm(X[ok], axis=1)
assert r.max() < 0.5, r.max()
# trajectories: a mode per sample, -1 after count; ppar only for GC samples
tm, cnt = f["trajectories/mode"][:], f["trajectories/count"][:]
pp, u = f["trajectories/ppar"][:], f["trajectories/u"][:]
for i in range(N):
    c = cnt[i]
    assert np.all(tm[i, c:] == -1) and np.all(np.isin(tm[i, :c], (0, 1)))
    assert np.all(np.isfinite(pp[i, :c][tm[i, :c] == 0]))
    assert np.all(np.isnan(pp[i, :c][tm[i, :c] == 1]))
    assert np.all(np.isfinite(u[i, :c][tm[i, :c] == 1]))
print("switching particles: %d of %d, switches %d, full-orbit share %.3f"
      % (np.count_nonzero(sw), N, sw.sum(), tfo.sum() / (tfo + tgc).sum()))
# the observer across switches (issue 14): every /invariants table has a mode
# column; rows from full-orbit stretches (1) belong to particles that switched
inv = f["invariants"]
for k in ("bounce", "drift", "mu", "energy"):
    m, i = inv[k]["mode"][:], inv[k]["id"][:]
    assert np.all(np.isin(m, (0, 1))), k
    assert np.all(sw[i[m == 1]] > 0) or np.all(tfo[i[m == 1]] > 0), k
assert np.count_nonzero(inv["mu"]["mode"][:] == 1) > 0, "no mu row from a full-orbit stretch"
assert np.count_nonzero(inv["mu"]["mode"][:] == 0) > 0
PY

# an adiabatic particle's observer output is the plain guiding-centre run's,
# bit for bit: the same GC calls with the same per-step sampler (hybrid.h).
# (Without trajectories: the hybrid cuts its pushes at trajectory samples,
# and its step times t_K + j dt then differ from t0 + k dt by an ulp.)
sed "s/OUT/hn.h5/; /^trajectory/d" hy.run > hn.run
sed "s/OUT/gc.h5/; /^trajectory/d; s/^method       = hybrid/method       = gc-rk4/; /^gc  /d; /^fo  /d; /^switch_to/d; /^fo_dt/d" hy.run > gc.run
"$GCPUSH" --quiet hn.run || die "hybrid run without trajectories failed"
"$GCPUSH" --quiet gc.run || die "plain gc-rk4 run failed"
"$PY" - hn.h5 gc.h5 <<'PY' || die "hybrid observer differs from the plain GC run's on adiabatic particles"
import sys
import h5py, numpy as np
h, g = h5py.File(sys.argv[1], "r"), h5py.File(sys.argv[2], "r")
t_fo = h["hybrid/t_fo"][:]
st = g["particles/final/status"][:].astype(int)
keep = np.flatnonzero((t_fo == 0) & (st == 0))  # GC all along in both runs
assert len(keep) >= 20, len(keep)
for k in ("bounce", "drift", "mu", "energy"):
    hi, gi = h["invariants"][k]["id"][:], g["invariants"][k]["id"][:]
    for col in [c for c in g["invariants"][k] if c not in ("id",)]:
        a = h["invariants"][k][col][:][np.isin(hi, keep)]
        b = g["invariants"][k][col][:][np.isin(gi, keep)]
        assert a.shape == b.shape and np.array_equal(a, b, equal_nan=True), (k, col, a.shape, b.shape)
print("adiabatic particles: %d with identical /invariants rows" % len(keep))
PY

# the orbit plot marks the full-orbit stretches (analysis/gcpush_h5.py reads hybrid files)
"$PY" "$ROOT/analysis/plot_orbits.py" h1.h5 -o h1.png --max 12 > plot.txt 2>&1 ||
    die "plot_orbits.py on a hybrid file: $(tail -3 plot.txt)"
[ -s h1.png ] || die "plot_orbits.py wrote no picture"
# ... and invariant_drift.py follows mu across the switches (issue 14)
"$PY" "$ROOT/analysis/invariant_drift.py" h1.h5 -o h1inv.png > inv.txt 2>&1 ||
    die "invariant_drift.py on a hybrid file: $(tail -3 inv.txt)"
grep -q "^hybrid: mu rows from full-orbit stretches [1-9]" inv.txt ||
    die "invariant_drift.py: no full-orbit mu rows: $(cat inv.txt)"
grep -q "^hybrid: largest mu jump of particle" inv.txt || die "invariant_drift.py: no mu jumps"
[ -s h1inv.png ] || die "invariant_drift.py wrote no picture"

# ---- 1 and 3 ranks: the same data ----
sed "s/OUT/h3.h5/" hy.run > h3.run
$MPIRUN -np 3 "$GCPUSH" --quiet h3.run || die "hybrid run on 3 ranks failed"
for g in /particles /trajectories /hybrid /invariants /losses; do
    h5diff h1.h5 h3.h5 $g $g > diff.txt 2>&1 || die "1 and 3 ranks differ in $g: $(head -5 diff.txt)"
done
# ---- SIGTERM halfway, then --restart on 2 ranks: the uninterrupted file ----
# (about 2.5 s of push on an idle core: a run shorter than the first checkpoint
# interval plus the signal's delivery finishes before SIGTERM reaches it)
sed "s/OUT/ref.h5/; s/^count    = 130/count    = 3200/; s/^duration = 5 s/duration = 12 s/; s/^\[output\]/[output]\ncheckpoint = 0.1 s/" hy.run > ref.run
sed "s/ref.h5/long.h5/" ref.run > long.run
"$GCPUSH" --quiet ref.run || die "reference run failed"
# stop it once it has checkpointed (it is pushing then, its handler set)
"$GCPUSH" --quiet long.run 2> term.txt & pid=$!
i=0
while ! ls long.h5.ckpt.* > /dev/null 2>&1 && [ $i -lt 600 ]; do sleep 0.05; i=$((i + 1)); done
kill -TERM $pid; wait $pid; rc=$?
[ $rc = 3 ] || die "SIGTERM: exit status $rc, not 3 ($(cat term.txt))"
$MPIRUN -np 2 "$GCPUSH" --quiet --restart long.h5 || die "restart failed"
for g in /particles /trajectories /hybrid /invariants /losses; do
    h5diff ref.h5 long.h5 $g $g > diff.txt 2>&1 || die "restart differs in $g: $(head -5 diff.txt)"
done
echo "ok test_hybrid"
