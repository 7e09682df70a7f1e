#!/bin/sh
# Stiff and extreme cases: runs every runs/stiff/*.run and checks the
# behaviour written at the top of each file (the unit-level ones are in
# tests/unit/test_stiff.c).
set -u
. "$(dirname "$0")/lib.sh"
ROOT=$(pwd)
cd "$TMP"
for r in omega-dt gamma-extremes exb-0.999 exb-1.001 loss-cone absurd-energy; do
    "$GCPUSH" --quiet "$ROOT/runs/stiff/$r.run" > /dev/null 2> "$r.err" || die "runs/stiff/$r.run: $(tail -1 "$r.err")"
done
"$PY" - <<'PY' || die "stiff-case expectations (above)"
import math, sys
import h5py, numpy as np

bad = []
def check(ok, what):
    if not ok:
        bad.append(what)

def table(path):
    with h5py.File(path, "r") as f:
        g = f["sweep"]
        t = {k: g[k][()] for k in g}
    t["method"] = np.array([m.decode().rstrip("\0") if isinstance(m, bytes) else m for m in t["method"]])
    return t

num = ("position_error", "gc_position_error", "energy_error", "cpu_seconds")

# omega_c dt = 1 .. 1e4
t = table("stiff-omega-dt.h5")
check(np.all(t["failed"] == 0), "omega-dt: a particle did not end ALIVE")
for k in num:
    check(np.all(np.isfinite(t[k])), "omega-dt: non-finite %s" % k)
check(np.all(t["energy_error"] < 1e-9), "omega-dt: energy not bounded: %s" % t["energy_error"])
zu = t["method"] == "boris-zu"
check(np.all(t["position_error_gyroradius"][~zu] <= 2.0 + 1e-6), "omega-dt: position beyond the gyro circle")
# boris-zu: on a circle of radius v dt / (2 |tan(w dt/2)|) = rho (w dt/2)/|tan(w dt/2)|
w = 2 * math.pi * 100000.3 / t["steps"][zu]
check(np.all(t["position_error_gyroradius"][zu] <= 2.0 + w / np.abs(np.tan(w / 2)) + 1e-6),
      "omega-dt: boris-zu beyond its circle")
check(np.all(np.abs(t["gyrophase_error"][zu]) < 1e-5), "omega-dt: boris-zu phase not exact")
b = (t["method"] == "boris") & (2 * math.pi * t["dt_given"] < math.pi)
wdt = 2 * math.pi * 100000.3 / t["steps"][b]
lag = -t["steps"][b] * (wdt - 2 * np.arctan(wdt / 2))
check(np.all(np.abs(t["gyrophase_error"][b] - lag) < 1e-6 * np.abs(lag) + 1e-6),
      "omega-dt: boris phase %s, documented 2 atan(w dt/2) lag %s" % (t["gyrophase_error"][b], lag))

# gamma 1 .. 2e6
t = table("stiff-gamma.h5")
check(np.all(t["failed"] == 0), "gamma: a particle did not end ALIVE")
for k in num:
    check(np.all(np.isfinite(t[k])), "gamma: non-finite %s" % k)
check(np.all(t["energy_error"] < 1e-9), "gamma: energy error %s" % t["energy_error"])
zu = t["method"] == "boris-zu"
check(np.all(t["position_error_gyroradius"][zu] < 1e-3), "gamma: boris-zu not exact")

# E/cB = 0.999: vay keeps the guiding centre; 1.001: no NaN, conserved W + q phi
for name, vaytol in (("stiff-exb-0999.h5", 1e-6), ("stiff-exb-1001.h5", 1e-6)):
    t = table(name)
    check(np.all(t["failed"] == 0), "%s: a particle did not end ALIVE" % name)
    for k in num:
        check(np.all(np.isfinite(t[k])), "%s: non-finite %s" % (name, k))
    v = t["method"] == "vay"
    check(np.all(t["gc_position_error"][v] < vaytol), "%s: vay guiding centre off %s" % (name, t["gc_position_error"][v]))
    fine = t["dt"] == t["dt"].min()
    check(np.all(t["position_error_path"][fine] < 1e-2), "%s: position at the smallest step %s" % (name, t["position_error_path"][fine]))
    check(np.all(t["energy_error"] < 1e-4), "%s: energy %s" % (name, t["energy_error"]))

# loss cone and absurd energy (ordinary output)
with h5py.File("stiff-loss-cone.h5", "r") as f:
    st = f["particles/final/status"][()]
    r = np.linalg.norm(f["particles/final/x"][()], axis=1)
check(list(st[:4]) == [1] * 4, "loss-cone: not PRECIPITATED: %s" % st[:4])
check(np.all(r[:4] < 6.3712e6 + 1.2e5), "loss-cone: precipitated above the atmosphere")
check(list(st[4:]) == [0] * 4, "loss-cone: trapped ones lost: %s" % st[4:])
with h5py.File("stiff-absurd-energy.h5", "r") as f:
    st = f["particles/final/status"][()]
    ok = np.all(np.isfinite(f["particles/final/x"][()])) and np.all(np.isfinite(f["particles/final/u"][()]))
check(st[0] == 2 and ok, "absurd-energy: status %s, finite %s" % (st[0], ok))
for b in bad:
    print("FAIL:", b, file=sys.stderr)
sys.exit(1 if bad else 0)
PY
# energy 0 is a run-file error naming the key
sed 's/^energy    = 1e30 eV/energy    = 0 eV/' "$ROOT/runs/stiff/absurd-energy.run" > zero.run
if "$GCPUSH" zero.run > /dev/null 2> zero.err; then die "energy = 0 accepted"; fi
grep -q "zero.run:.*\[particles\] energy: kinetic energy must be > 0" zero.err || die "energy 0: $(cat zero.err)"
echo "ok test_stiff"
