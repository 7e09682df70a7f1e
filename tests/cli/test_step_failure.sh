#!/bin/sh
# Issue 11: a particle that cannot be stepped ends STEP_FAILED with the reason
# in the output (/particles/final/step_failure, an HDF5 enum like status) and
# one line in the log naming its id, the method, the time and the reason.
# gc-midpoint-pphi at 0.5 bounce per step: the predictor of the first step
# is so far from the solution that Newton cannot converge (a fixed-step
# method never shortens its step), so every particle fails at t = 0 with
# NO_CONVERGENCE; at 0.02 bounce the same particles are pushed with no
# failure and no log line (the check can fail both ways).  ~0.3 s.
set -u
. "$(dirname "$0")/lib.sh"
cd "$TMP"
cat > fail.run <<'RUN'
[scene]
name     = fail
field    = dipole
duration = 10 s
seed     = 3
[particles]
species  = proton
count    = 4
energy   = 1 MeV
L        = 4
pitch    = 30 deg .. 60 deg
[integrator]
method   = gc-midpoint-pphi
dt       = 0.5 bounce
[output]
file     = fail.h5
RUN
"$GCPUSH" --quiet fail.run > out.txt 2> err.txt || die "the run failed: $(cat err.txt)"
[ "$(grep -c '^gcpush: particle [0-3] STEP_FAILED (gc-midpoint-pphi) at t = 0 s: NO_CONVERGENCE' err.txt)" = 4 ] ||
    die "log: $(cat err.txt)"
"$PY" - fail.h5 NO_CONVERGENCE <<'PYEOF' || die "step_failure in the output"
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1], "r")
d = f["particles/final/step_failure"]
names = h5py.check_enum_dtype(d.dtype)
assert names is not None and names["NONE"] == 0, names
st = f["particles/final/status"][:]
sf = d[:]
assert (st == 6).all() and (sf == names[sys.argv[2]]).all(), (st, sf)
print("step_failure:", [k for v in sf for k, w in names.items() if w == v])
PYEOF
sed -i 's/^dt .*/dt       = 0.02 bounce/; s/^duration .*/duration = 1 s/' fail.run
"$GCPUSH" --quiet --force fail.run > out.txt 2> err.txt || die "the run at 0.02 bounce failed: $(cat err.txt)"
grep -q STEP_FAILED err.txt && die "a log line without a failure: $(cat err.txt)"
"$PY" - fail.h5 <<'PYEOF' || die "step_failure at 0.02 bounce"
import sys, h5py
f = h5py.File(sys.argv[1], "r")
assert (f["particles/final/status"][:] != 6).all()
assert (f["particles/final/step_failure"][:] == 0).all()
PYEOF
echo "ok test_step_failure"
