#!/bin/sh
# A grid file as a new user writes it with h5py's defaults (issue 13): the
# `geometry` attribute a variable-length UTF-8 string (was reported
# "missing"), and the poloidal field given by psi alone with use_psi = yes
# (every full-orbit particle was NONFINITE: the spline was located without
# the derivatives B takes from psi).  End to end: the psi-only grid and a
# grid of the same field given by its components BR, BZ, Bphi give the
# same orbits, for a full orbit (boris) and a guiding centre (gc-rk4).
#
# Field: B_phi = B0 R0 / R, psi = k ((R - R0)^2 + Z^2) [Wb/rad], so
# B_R = -(1/R) dpsi/dZ = -2 k Z / R, B_Z = (1/R) dpsi/dR = 2 k (R - R0) / R.
# psi is quadratic: its cubic spline and the spline's derivatives are exact
# (a cubic B-spline interpolant reproduces polynomials up to degree 3), so
# the psi grid gives B to round-off; the component grid interpolates 1/R
# with the cubic spline's error (5/384) h^4 |d^4(1/R)/dR^4| = (5/384) h^4
# 24/R^5 = 1.9e-9 relative at R = 2.3 m (h = 0.025 m).  Over 20 gyrations
# (126 rad) that error in the gyrofrequency moves a particle by ~1e-9 x 126
# x rho (7 mm) ~ 1e-9 m, and the drift by less: tolerance 1e-9 of R0
# (measured 3.5e-11).
set -u
. "$(dirname "$0")/lib.sh"
cd "$TMP"
"$PY" - <<'PY' || die "writing the grids with h5py"
import h5py, numpy as np
R = np.linspace(1.0, 3.0, 81); Z = np.linspace(-1.0, 1.0, 81)
RR, ZZ = np.meshgrid(R, Z)             # shape (nZ, nR), R fastest
B0, R0, k = 2.0, 2.0, 0.2
for name, psi_only in (("psi.h5", True), ("comp.h5", False)):
    with h5py.File(name, "w") as f:
        f.attrs["geometry"] = "axisymmetric"   # h5py default: variable-length UTF-8
        f.attrs["origin"] = [R[0], Z[0]]
        f.attrs["spacing"] = [R[1] - R[0], Z[1] - Z[0]]
        f["Bphi"] = B0 * R0 / RR
        if psi_only:
            f["psi"] = k * ((RR - R0) ** 2 + ZZ ** 2)
        else:
            f["BR"] = -2 * k * ZZ / RR
            f["BZ"] = 2 * k * (RR - R0) / RR
PY
for m in boris gc-rk4; do
    for g in psi comp; do
        dt="0.05 gyro"
        [ $m = gc-rk4 ] && dt="0.5 gyro"
        use=""
        [ $g = psi ] && use="use_psi = yes"
        cat > $m-$g.run <<RUN
[scene]
name     = h5py-grid
field    = grid
duration = 20 gyro
seed     = 3
[field]
file = $g.h5
$use
[particles]
species  = proton
count    = 4
energy   = 10 keV
position = 2.3 0 0.1 m
pitch    = 30 deg .. 80 deg
[integrator]
method = $m
dt     = $dt
[output]
file = $m-$g.h5
RUN
        "$GCPUSH" --quiet $m-$g.run > $m-$g.txt 2>&1 || die "$m on $g.h5: $(cat $m-$g.txt)"
    done
done
"$PY" - <<'PY' || die "psi-only and component grids disagree"
import h5py, numpy as np
for m, key in (("boris", "x"), ("gc-rk4", "X")):
    a = h5py.File(m + "-psi.h5", "r")["particles/final"]
    b = h5py.File(m + "-comp.h5", "r")["particles/final"]
    assert (a["status"][()] == 0).all() and (b["status"][()] == 0).all(), (m, a["status"][()], b["status"][()])
    d = np.abs(a[key][()] - b[key][()]).max() / 2.0
    print("%s: psi-only vs component grid: %.2e of R0" % (m, d))
    assert d < 1e-9, (m, d)
PY
echo "ok test_grid_h5py"
