#!/bin/sh
# The diagnostics scripts on a small run with invariants and losses, their
# numbers asserted: analysis/invariant_drift.py, periods.py, losses.py.
#
# Two small full-orbit (boris) runs in Earth's dipole at L = 4:
#  e.run: 1 MeV electrons (eps = rho/L_B ~ 1e-3) for 1 s (~3 bounces): three
#    at a_eq = 3 deg (inside the 5.47 deg loss cone), six at 20..85 deg;
#  p.run: 10 MeV protons (eps ~ 0.1) for 180 s (two drift orbits).
# Expected, from the physics (tolerances at each check):
#   - electrons: gyro-averaged first-order mu steady to O(eps^2) (< 1e-5 per
#     bounce; measured ~1e-7), K to the J quadrature (< 1e-7 per bounce);
#     bounce periods = dipole theory to O(eps) (the theory starts from the
#     first-order guiding centre at one gyrophase: < 2e-3); every electron
#     inside the loss cone precipitates, none outside;
#   - protons: L* per drift orbit kept to O(eps^2) (< 3e-2 per drift period),
#     bounce periods to O(eps) (< 1e-1; measured up to 6e-2).
# The same electrons and protons pushed as guiding centres with gc-gl2
# (g.run; symplectic, order 2; 200 steps per bounce) tighten these: L* per
# drift orbit to round-off (the discrete Noether theorem keeps p_phi, i.e.
# the drift shell: < 1e-12 -- exact by construction, so this checks the
# analysis, not the integrator's accuracy, which the periods and K below
# check), K per bounce to the integrator's O(dt^2) (< 1e-6), mu exactly,
# bounce and drift periods to O(dt^2) = (2 pi / 200)^2 / 12 ~ 1e-4 (< 5e-4).
set -u
. "$(dirname "$0")/lib.sh"
A=$(cd "$(dirname "$0")/../../analysis" && pwd)
cd "$TMP"
cat > e.run <<'RUN'
[scene]
name     = analysis-e
field    = dipole
duration = 1 s
seed     = 7
[particles.in]
species  = electron
count    = 3
energy   = 1 MeV
L        = 4
pitch    = 3 deg
[particles.out]
species  = electron
count    = 6
energy   = 1 MeV
L        = 4
pitch    = 20 deg .. 85 deg
[integrator]
method   = boris
dt       = 0.05 gyro
[diagnostics]
invariants = mu K L
events     = bounce drift loss
[output]
file = e.h5
RUN
sed 's/analysis-e/analysis-p/; s/duration = 1 s/duration = 180 s/; s/electron/proton/; s/1 MeV/10 MeV/; s/e.h5/p.h5/' e.run > p.run
# guiding centres: electrons and protons together, one drift orbit of the protons
# (10 MeV protons at L = 4 have eps = rho |grad B| / B ~ 0.1-0.15: past the default
# adiabaticity threshold 0.1 they would end NONADIABATIC at once -- checked
# below -- so g.run raises it to 0.2 to push them)
sed 's/analysis-e/analysis-g/; s/duration = 1 s/duration = 250 s/; s/^method   = boris/method   = gc-gl2\nadiabaticity = 0.2/; s/^dt       = 0.05 gyro/dt       = 0.005 bounce/; s/e.h5/g.h5/' e.run > g.run
cat >> g.run <<'RUN'
[particles.p]
species  = proton
count    = 6
energy   = 10 MeV
L        = 4
pitch    = 20 deg .. 85 deg
RUN
"$GCPUSH" --quiet g.run > run.txt 2>&1 || die "g.run failed: $(cat run.txt)"
sed 's/^adiabaticity = 0.2//; s/g.h5/g01.h5/; s/duration = 250 s/duration = 1 s/' g.run > g01.run
"$GCPUSH" g01.run > run.txt 2>&1 || die "g01.run failed: $(cat run.txt)"
grep -q "NONADIABATIC  6" run.txt || die "10 MeV protons at L = 4 not flagged NONADIABATIC at eps > 0.1: $(cat run.txt)"
"$GCPUSH" --quiet e.run > run.txt 2>&1 || die "e.run failed: $(cat run.txt)"
"$GCPUSH" --quiet p.run > run.txt 2>&1 || die "p.run failed: $(cat run.txt)"

# invariant_drift.py: columns method species inv per n median p95 worst worst_id
check() { # $1 file $2 species $3 inv $4 per $5 max-worst $6 min-n
    line=$(awk -v s="$2" -v i="$3" -v p="$4" '$2 == s && $3 == i && $4 == p' "$1")
    [ -n "$line" ] || die "invariant_drift.py: no row '$2 $3 $4': $(cat "$1")"
    echo "$line" | awk -v w="$5" -v n="$6" '{ exit !($8 <= w && $5 >= n) }' ||
        die "invariant_drift.py: $2 $3 per $4: $line (want worst <= $5, n >= $6)"
}
# periods.py: columns species period n median p95 worst worst_id
pcheck() { # $1 file $2 species $3 period $4 max-worst $5 min-n
    line=$(awk -v s="$2" -v w="$3" '$1 == s && $2 == w' "$1")
    [ -n "$line" ] || die "periods.py: no row '$2 $3': $(cat "$1")"
    echo "$line" | awk -v m="$4" -v n="$5" '{ exit !($6 <= m && $3 >= n) }' ||
        die "periods.py: $2 $3: $line (want worst <= $4, n >= $5)"
}
for r in e p g; do
    "$PY" "$A/invariant_drift.py" $r.h5 -o inv$r.png > inv$r.txt 2> err.txt || die "invariant_drift.py $r.h5: $(cat err.txt)"
    [ -s inv$r.png ] || die "invariant_drift.py wrote no PNG"
    "$PY" "$A/periods.py" $r.h5 -o per$r.png > per$r.txt 2> err.txt || die "periods.py $r.h5: $(cat err.txt)"
    [ -s per$r.png ] || die "periods.py wrote no PNG"
    "$PY" "$A/losses.py" $r.h5 -o loss$r.png > loss$r.txt 2> err.txt || die "losses.py $r.h5: $(cat err.txt)"
    [ -s loss$r.png ] || die "losses.py wrote no PNG"
done
check inve.txt electron mu bounce 1e-5 6
check inve.txt electron K bounce 1e-7 6
pcheck pere.txt electron bounce 2e-3 6
check invp.txt proton 'L*' drift 3e-2 6
pcheck perp.txt proton bounce 1e-1 6

# (mu of a guiding-centre method: the contract, constant by construction, not a measurement)
check invg.txt electron mu bounce 1e-12 6
check invg.txt electron K bounce 1e-6 6
check invg.txt proton K bounce 1e-6 6
check invg.txt proton 'L*' drift 1e-12 6
pcheck perg.txt electron bounce 5e-4 6
pcheck perg.txt proton bounce 5e-4 6
pcheck perg.txt proton drift 5e-4 6

lc=$(grep '^loss cone:' losse.txt) || die "losses.py: no loss-cone line: $(cat losse.txt)"
echo "$lc" | awk '{ gsub(/[(),]/, " "); exit !($4 == 3 && $6 == 3 && $8 == 6 && $10 == 0) }' ||
    die "losses.py: $lc (the 3 electrons inside the loss cone precipitate, the 6 outside do not)"
grep -q "^electron *PRECIPITATED *3 " losse.txt || die "losses.py: $(cat losse.txt)"
# every dataset of the output carries its unit (issue 13), in full-orbit
# and guiding-centre files with invariants and losses
"$PY" - e.h5 g.h5 <<'PY' || die "datasets without a units attribute"
import sys, h5py
for fn in sys.argv[1:]:
    f = h5py.File(fn, "r")
    miss = []
    f.visititems(lambda n, o: miss.append(n) if isinstance(o, h5py.Dataset) and "units" not in o.attrs else None)
    assert not miss, (fn, miss)
    assert f.attrs["duration_units"] in (b"s", "s")
PY
echo "ok test_analysis"
