#!/bin/sh
# The run files in runs/ are examples: each must validate, and the small
# ones run here with their physics checked from the output file.
set -u
. "$(dirname "$0")/lib.sh"
RUNS=$(cd "$(dirname "$0")/../../runs" && pwd)
for r in "$RUNS"/*.run "$RUNS"/*/*.run; do
    [ -f "$r" ] || continue
    case "$(basename "$r")" in grid-*) continue ;; esac   # inputs of `gcpush grid` (make runs them)
    (cd "$(dirname "$RUNS")" && "$GCPUSH" --check "$r" > /dev/null) || die "$r does not validate"
done
cd "$TMP"

# uniform.run: E x B drift.  The guiding centre X = x + (v - v_E) x b / Omega
# (Omega = q B / gamma m) moves at v_E = E x B / B^2 = (0, -1000, 0) m/s.
# From the initial and final states of 20 gyro periods: the pusher's phase and
# radius errors at omega dt = 0.13 are ~(omega dt)^2/12 ~ 1.3e-3 of the
# gyroradius (0.46 m for the proton) against a 1.3 m drift, so 1% is a bound
# that holds with margin and fails on a wrong drift.
sed "s|^file .*|file = uniform.h5|" "$RUNS/uniform.run" > u.run
"$GCPUSH" --quiet u.run || die "uniform.run failed"
"$PY" - uniform.h5 <<'PYEOF' || die "uniform.run: E x B drift"
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1], "r")
c = 299792458.0
B = np.array([0, 0, 1e-3]); E = np.array([1.0, 0, 0])
vE = np.cross(E, B) / B.dot(B)
q = f["particles/charge"][:]; m = f["particles/mass"][:]
assert (f["particles/final/status"][:] == 0).all()
def gc(x, u, q, m):
    g = np.sqrt(1 + u.dot(u) / c**2)
    Om = q * np.linalg.norm(B) / (g * m)
    return x + np.cross(u / g - vE, B / np.linalg.norm(B)) / Om
for p in range(len(q)):
    X0 = gc(f["particles/initial/x"][p], f["particles/initial/u"][p], q[p], m[p])
    X1 = gc(f["particles/final/x"][p], f["particles/final/u"][p], q[p], m[p])
    v = (X1 - X0) / f["particles/final/t"][p]
    print("E x B drift of %s: %s m/s (theory %s)" % (f["particles/species"][p].decode(), v.round(3), vE))
    assert np.linalg.norm(v - vE) < 0.01 * np.linalg.norm(vE), v
PYEOF

# mirror.run: the loss cone of mirror ratio R = 1 + (z_max/Lm)^2 = 5 is
# asin(sqrt(1/R)) = 26.57 deg.  Particles at least 1 deg outside it stay,
# 1 deg inside leave (first-order adiabatic theory: rho/Lm = 0.03 moves the
# effective boundary by well under a degree).
sed "s|^file .*|file = mirror.h5|" "$RUNS/mirror.run" > m.run
"$GCPUSH" --quiet m.run || die "mirror.run failed"
"$PY" - mirror.h5 <<'PYEOF' || die "mirror.run: loss cone"
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1], "r")
u = f["particles/initial/u"][:]; s = f["particles/final/status"][:]
a = np.degrees(np.arccos(np.abs(u[:, 2]) / np.linalg.norm(u, axis=1)))
lc = np.degrees(np.arcsin(np.sqrt(1 / 5.0)))
assert (s[a > lc + 1] == 0).all() and (s[a < lc - 1] == 2).all(), list(zip(a.round(1), s))
print("mirror: %d trapped, %d lost, loss cone %.2f deg" % ((s == 0).sum(), (s == 2).sum(), lc))
PYEOF
# /particles/final/status is an HDF5 enum (issue 13): h5dump and h5py show
# the names, the values are the status codes
h5dump -d /particles/final/status mirror.h5 > dump.txt 2>&1 || die "h5dump: $(head -3 dump.txt)"
grep -q 'H5T_ENUM' dump.txt && grep -q '"LEFT_DOMAIN"' dump.txt && grep -q '"ALIVE"' dump.txt ||
    die "status is not an enum with names: $(head -20 dump.txt)"
"$PY" - mirror.h5 <<'PYEOF' || die "status enum: h5py"
import sys, h5py
ds = h5py.File(sys.argv[1], "r")["particles/final/status"]
e = h5py.check_enum_dtype(ds.dtype)
want = ["ALIVE", "PRECIPITATED", "LEFT_DOMAIN", "LEFT_GRID", "NONADIABATIC", "NONFINITE", "STEP_FAILED"]
assert e and {v: k for k, v in e.items()} == dict(enumerate(want)), e
PYEOF
# the output says when an invariant is undefined and why (issue 13): L* in
# the IGRF field (no vector potential), and when events come at all
RE_ROOT=$(cd "$RUNS/.." && pwd)
cat > igrf.run <<RUN
[scene]
name     = igrf-lstar
field    = igrf
duration = 2 s
seed     = 5
[field]
file  = $RE_ROOT/fields/data/igrf14coeffs.txt
epoch = 2020
[particles]
species  = proton
count    = 2
energy   = 1 MeV
position = 4 0 0 RE
pitch    = 60 deg
[integrator]
method = gc-rk4
dt     = 2 ms
[diagnostics]
invariants = L
events     = drift
[output]
file = igrf.h5
RUN
"$GCPUSH" --quiet igrf.run || die "igrf.run failed"
"$PY" - igrf.h5 <<'PYEOF' || die "igrf: no word on the undefined L*"
import sys, h5py
f = h5py.File(sys.argv[1], "r")
assert b"vector potential" in f["invariants/drift"].attrs["Lstar_undefined"]
assert b"no equator point" in f["invariants"].attrs["sampling"]
# per particle, why (issue 13): an HDF5 enum column per quantity
u = f["invariants/undefined"]
names = {v: k for k, v in h5py.check_enum_dtype(u["Lstar"].dtype).items()}
assert list(u["id"][:]) == [0, 1], u["id"][:]
assert [names[v] for v in u["Lstar"][:]] == ["NO_POTENTIAL"] * 2, u["Lstar"][:]
assert [names[v] for v in u["drift"][:]] == ["NO_TURN"] * 2, u["drift"][:]
assert [names[v] for v in u["bounce"][:]] == ["NOT_ASKED"] * 2, u["bounce"][:]
PYEOF
# ... and sharply (issue 13): the first-order correction to mu at the start
# is rho |grad B| / B = (rho / Lm)^2 = 8e-4 at the field minimum (grad B and
# the curvature vanish there), which moves sin^2 of the loss-cone angle by
# as much: 8e-4 / sin(2 a_lc) = 1e-3 rad = 0.057 deg.  So 8 protons at
# 0.12 deg inside (26.45 deg) all leave and 8 at 0.12 deg outside (26.68 deg)
# all stay, whatever their gyrophase.
cat > m2.run <<'RUN'
[scene]
name     = mirror-edge
field    = mirror
duration = 20 us
seed     = 7
[field]
B0    = 1 T
Lm    = 0.5 m
z_max = 1 m
[particles.in]
species  = proton
count    = 8
energy   = 10 keV
position = 0 0 0 m
pitch    = 26.45 deg
[particles.out]
species  = proton
count    = 8
energy   = 10 keV
position = 0 0 0 m
pitch    = 26.68 deg
[integrator]
method   = boris
dt       = 0.05 gyro
[output]
file = mirror2.h5
RUN
"$GCPUSH" --quiet m2.run || die "m2.run failed"
"$PY" - mirror2.h5 <<'PYEOF' || die "mirror: loss-cone edge"
import sys, h5py, numpy as np
s = h5py.File(sys.argv[1], "r")["particles/final/status"][:]
assert (s[:8] == 2).all() and (s[8:] == 0).all(), s
PYEOF

# dipole.run, shortened to 20 s: guiding centres with gc-gl4 (symplectic).
# Its energy error is bounded and O(dt^4), oscillating within the bounce: at
# 25 steps per bounce its range is 1e-4 (test_gc_symplectic.c), so at the
# run's 50 steps per (shortest) bounce ~1e-4/16 = 6e-6; 1e-3 holds with
# margin and fails on a secular drift or a wrong step; mu is a constant of
# the scheme (exact); statuses only from the belt mix (no STEP_FAILED).
sed "s|^file .*|file = dipole.h5|; s|^duration .*|duration = 20 s|; s|^trajectory .*|trajectory = none|" "$RUNS/dipole.run" > d.run
"$GCPUSH" --quiet d.run || die "dipole.run failed"
"$PY" - dipole.h5 <<'PYEOF' || die "dipole.run: guiding-centre energy"
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1], "r")
c, B0, RE = 299792458.0, 3.12e-5, 6.3712e6
m = f["particles/mass"][:]
def gamma(X, ppar, mu):
    r = np.linalg.norm(X, axis=1); sl = X[:, 2] / r
    B = B0 * (RE / r) ** 3 * np.sqrt(1 + 3 * sl**2)
    return np.sqrt(1 + (ppar / (m * c)) ** 2 + 2 * mu * B / (m * c**2))
g0 = gamma(f["particles/initial/X"][:], f["particles/initial/ppar"][:], f["particles/initial/mu"][:])
g1 = gamma(f["particles/final/X"][:], f["particles/final/ppar"][:], f["particles/final/mu"][:])
s = f["particles/final/status"][:]
alive = s == 0
err = np.abs(g1 - g0)[alive] / (g0 - 1)[alive]
assert set(s) <= {0, 1, 4}, set(s)
# the contract, not a measurement: no guiding-centre method modifies mu
assert (f["particles/final/mu"][:][alive] == f["particles/initial/mu"][:][alive]).all()
assert err.max() < 1e-3, err.max()
print("dipole (gc-gl4): max relative kinetic energy error %.2e over %d live guiding centres"
      % (err.max(), alive.sum()))
PYEOF
# [integrator] arithmetic = fast (opt-in, boris: src/pushers/boris_fast.c)
# against the default IEEE run of the same scene, with the invariant
# observer on (the fast push then goes a step a call, the sampler observing
# each fast step).  1 MeV protons at L = 4, 4000 steps of 0.05 gyro: the two
# runs' steps agree to ~1 ulp (test_boris_fast.c) and the difference grows
# with the phase error, linearly in the steps on these regular orbits (~N
# eps |x| ~ 1e-12 relative): positions and momenta within 1e-9 of each
# other; |u| of each kept to 8 eps sqrt(N) (Boris's exact rotation); the
# same statuses.  Where the CPU has no
# AVX-512F the two runs are the same run (gcpush's note says so).
for a in ieee fast; do
cat > ar_$a.run <<RUN
[scene]
name     = arith
field    = dipole
duration = 200 gyro
seed     = 3
[field]
B0 = 3.12e-5 T
[particles]
species  = proton
count    = 24
energy   = 1 MeV
L        = 3.5 .. 4.5
pitch    = 30 deg .. 80 deg
[integrator]
method     = boris
dt         = 0.05 gyro
arithmetic = $a
[diagnostics]
invariants = mu
[output]
file = ar_$a.h5
RUN
"$GCPUSH" --quiet ar_$a.run 2> ar_$a.err || die "arithmetic = $a run failed: $(cat ar_$a.err)"
done
"$PY" - ar_ieee.h5 ar_fast.h5 <<'PYEOF' || die "arithmetic = fast against ieee"
import sys, h5py, numpy as np
a, b = (h5py.File(p, "r") for p in sys.argv[1:3])
fa, fb = a["particles/final"], b["particles/final"]
assert (fa["status"][:] == fb["status"][:]).all()
xa, xb, ua, ub = fa["x"][:], fb["x"][:], fa["u"][:], fb["u"][:]
dx = np.linalg.norm(xa - xb, axis=1) / np.linalg.norm(xa, axis=1)
du = np.linalg.norm(ua - ub, axis=1) / np.linalg.norm(ua, axis=1)
assert dx.max() < 1e-9 and du.max() < 1e-9, (dx.max(), du.max())
u0 = np.linalg.norm(a["particles/initial/u"][:], axis=1)
n = 4000
for u in (ua, ub):
    assert (np.abs(np.linalg.norm(u, axis=1) / u0 - 1) <= 8 * 2.2e-16 * np.sqrt(n)).all()
print("arithmetic fast vs ieee (boris, dipole): |dx|/|x| <= %.1e, |du|/|u| <= %.1e" % (dx.max(), du.max()))
PYEOF
# The root attribute `arithmetic` records the step that ran: ieee for the
# default; fast where this CPU has AVX-512F (the fast tier's requirement:
# boris_fast.c), and then no note; ieee with the note otherwise.  In the
# analytic tokamak the fast tier has no tile: ieee and the note, whatever
# the CPU.
grep -qw avx512f /proc/cpuinfo && have512=1 || have512=0
cat > ar_tok.run <<RUN
[scene]
name     = arith-tokamak
field    = tokamak
duration = 200 gyro
seed     = 3
[field]
B0 = 2 T
R0 = 3 m
a  = 1 m
q0 = 1
qa = 3
[particles]
species  = proton
count    = 4
energy   = 10 keV
position = 3.5 0 0 m
pitch    = 30 deg .. 80 deg
[integrator]
method     = boris
dt         = 0.05 gyro
arithmetic = fast
[output]
file = ar_tok.h5
RUN
"$GCPUSH" --quiet ar_tok.run 2> ar_tok.err || die "arithmetic = fast in the tokamak failed: $(cat ar_tok.err)"
grep -q "no fast step for 'boris' in field 'tokamak'" ar_tok.err || die "no note for fast in the tokamak"
"$PY" - ar_ieee.h5 ar_fast.h5 ar_tok.h5 $have512 "$(cat ar_fast.err)" <<'PYEOF' || die "attribute arithmetic"
import sys, h5py
att = [h5py.File(p, "r").attrs["arithmetic"] for p in sys.argv[1:4]]
att = [a.decode() if isinstance(a, bytes) else a for a in att]
have512, note = sys.argv[4] == "1", sys.argv[5]
assert att[0] == "ieee", att
assert att[1] == ("fast" if have512 else "ieee"), (att, have512)
assert ("no fast step" in note) == (not have512), note
assert att[2] == "ieee", att
print("attribute arithmetic: ieee run %s, fast run %s (AVX-512F: %s), tokamak fast run %s"
      % (att[0], att[1], have512, att[2]))
PYEOF

echo "ok test_runs"
