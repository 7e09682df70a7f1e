#!/bin/sh
# Issue 14: CPU of method = hybrid against pure guiding centre (gc-midpoint-pphi: the
# non-adiabatic protons stop NONADIABATIC at once) and pure full orbit
# (boris, 0.05 gyro) on the flagship ensemble (runs/hybrid-dipole.run),
# shortened to DURATION (default 20 s: a pure full-orbit run of its 50 MeV
# electrons costs ~0.5 s of CPU per simulated second).  Push CPU seconds
# from /timing/rank_cpu_seconds; ratios on stdout, nothing passes or fails.
set -u
GCPUSH=${GCPUSH:-$(pwd)/bin/gcpush}
PY=${PY:-/usr/bin/python3}
DURATION=${DURATION:-20 s}
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
base="$TMP/base.run"
sed "s/^duration = .*/duration = $DURATION/; s/^trajectory = .*/trajectory = none/" runs/hybrid-dipole.run > "$base"
variant() { # NAME SED-SCRIPT
    sed "s|^file       = .*|file       = $TMP/$1.h5|; $2" "$base" > "$TMP/$1.run"
    "$GCPUSH" --quiet "$TMP/$1.run" || { echo "bench hybrid: $1 failed" >&2; exit 1; }
}
variant hybrid ""
variant gc "s/^method       = hybrid/method = gc-midpoint-pphi/; /^gc  /d; /^fo  /d; /^switch_to/d; /^fo_dt/d"
variant fo "s/^method       = hybrid/method = boris/; /^gc  /d; /^fo  /d; /^switch_to/d; /^fo_dt/d; s/^dt           = .*/dt = 0.05 gyro/"
"$PY" - "$TMP" "$DURATION" <<'PY'
import sys, h5py, numpy as np
d, dur = sys.argv[1], sys.argv[2]
cpu = {k: h5py.File("%s/%s.h5" % (d, k), "r")["timing/rank_cpu_seconds"][:].sum() for k in ("hybrid", "gc", "fo")}
h = h5py.File(d + "/hybrid.h5", "r")["hybrid"]
tfo, tgc, sw = h["t_fo"][:], h["t_gc"][:], h["switches"][:]
st = h5py.File(d + "/gc.h5", "r")["particles/final/status"][:]
N = len(sw)
print("hybrid vs pure guiding centre and pure full orbit, flagship ensemble, %s (%d particles)" % (dur, N))
print("  non-adiabatic: %d of %d stop NONADIABATIC as gc-midpoint-pphi; %d spend time as full orbits in the hybrid, %d switch"
      % (np.count_nonzero(st == 4), N, np.count_nonzero(tfo > 0), np.count_nonzero(sw)))
for k in ("gc", "hybrid", "fo"):
    print("  %-7s push CPU %8.3f s" % (k, cpu[k]))
print("  hybrid / gc = %.2f   fo / hybrid = %.1f" % (cpu["hybrid"] / cpu["gc"], cpu["fo"] / cpu["hybrid"]))
PY
