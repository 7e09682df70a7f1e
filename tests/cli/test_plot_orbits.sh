#!/bin/sh
# analysis/plot_orbits.py on synthetic gcpush output files (no gcpush binary needed):
#  - a dipole scene, 2 protons + 2 electrons bouncing and drifting, one electron PRECIPITATED,
#    with /trajectories (NaN padded) and without; both give a valid PNG and exit 0;
#  - a missing file, a non-gcpush HDF5 file, a gcpush file without /particles, a bad --ids:
#    exit 1 with a one-line message on stderr and no traceback.
# Usage: sh tests/cli/test_plot_orbits.sh      ($PY: python to use, default /usr/bin/python3)
set -u

PY=${PY:-/usr/bin/python3}
PYTHONDONTWRITEBYTECODE=1; export PYTHONDONTWRITEBYTECODE
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
script="$root/analysis/plot_orbits.py"

tmp=$(mktemp -d "${TMPDIR:-/tmp}/test_plot_orbits.XXXXXX") || { echo "FAIL test_plot_orbits: mktemp" >&2; exit 1; }
trap 'rm -rf "$tmp"' EXIT
trap 'rm -rf "$tmp"; exit 1' HUP INT TERM

fail() { echo "FAIL test_plot_orbits: $*" >&2; exit 1; }

# ---- synthetic files -------------------------------------------------------------------------
cat > "$tmp/make.py" <<'EOF'
import sys
import numpy as np
import h5py

RE = 6.3712e6
QE = 1.602176634e-19
C = 299792458.0
MP, ME = 1.67262192369e-27, 9.1093837015e-31

def dipole_orbit(L, lam_m, tb, td, rg, tg, phi0, t, lost_at=None):
    """Kinematic guiding centre on field line L: bounce between +-lam_m with period tb, drift in
    longitude with period td (sign = direction), plus a gyration of radius rg [RE], period tg."""
    lam = lam_m * np.sin(2 * np.pi * t / tb)
    if lost_at is not None:                     # slides down the field line to 100 km altitude
        lam = np.minimum(lam_m * t / lost_at, lam_m)
    r = L * np.cos(lam) ** 2
    phi = phi0 + 2 * np.pi * t / td
    gc = np.stack([r * np.cos(lam) * np.cos(phi), r * np.cos(lam) * np.sin(phi), r * np.sin(lam)], -1)
    # gyration in the plane spanned by e_phi and the radial direction (roughly perpendicular to B)
    ephi = np.stack([-np.sin(phi), np.cos(phi), np.zeros_like(phi)], -1)
    er = np.stack([np.cos(lam) * np.cos(phi), np.cos(lam) * np.sin(phi), np.sin(lam)], -1)
    g = 2 * np.pi * t / tg
    return (gc + rg * (np.cos(g)[:, None] * ephi + np.sin(g)[:, None] * er)) * RE

def main(path, mode):
    if mode == "notgcpush":
        with h5py.File(path, "w") as f:
            f.attrs["creator"] = "somebody else"
            f["data"] = np.arange(10.0)
        return
    S = 1500
    T = 60.0
    t = np.linspace(0, T, S)
    # species, L, mirror latitude, bounce period, drift period, gyroradius [RE], energy [MeV]
    parts = [("proton", 4.0, 0.45, 6.0, -70.0, 0.12, 10.0),
             ("proton", 3.0, 0.25, 5.0, -90.0, 0.08, 5.0),
             ("electron", 5.0, 0.6, 4.0, 150.0, 0.0, 1.0),
             ("electron", 2.5, 1.0, 4.0, 200.0, 0.0, 0.5)]   # PRECIPITATED
    N = len(parts)
    tr_t = np.full((N, S), np.nan)
    tr_x = np.full((N, S, 3), np.nan)
    tr_u = np.full((N, S, 3), np.nan)
    count = np.zeros(N, np.int64)
    status = np.zeros(N, np.int32)
    for i, (sp, L, lm, tb, td, rg, e) in enumerate(parts):
        m = MP if sp == "proton" else ME
        lost_at = None
        if i == 3:
            status[i] = 1
            lam_surf = np.arccos(np.sqrt((1 + 1e5 / RE) / L))
            lm, lost_at = lam_surf, 1.2
        x = dipole_orbit(L, lm, tb, td, rg, 0.4, 1.0 * i, t, lost_at)
        n = S if lost_at is None else int(np.searchsorted(t, lost_at)) + 1
        gamma = 1 + e * 1e6 * QE / (m * C * C)
        u = np.gradient(x, t, axis=0)
        u *= (gamma * C * np.sqrt(1 - 1 / gamma ** 2)) / np.linalg.norm(u, axis=1)[:, None]
        tr_t[i, :n], tr_x[i, :n], tr_u[i, :n], count[i] = t[:n], x[:n], u[:n], n
    with h5py.File(path, "w") as f:
        a = f.attrs
        a["gcpush_version"] = "0.1.0"
        a["git_hash"] = "synthetic"
        a["build_flags"] = "none"
        a["run_file"] = "[scene]\nname = synthetic-dipole\nfield = dipole\n"
        a["run_file_name"] = "synthetic.run"
        a["units"] = "SI"
        a["ranks"] = np.int32(1)
        a["scene"] = "synthetic-dipole"
        a["field"] = "dipole"
        a["method"] = "boris"
        a["dt"] = 1e-3
        if mode == "noparticles":
            return
        p = f.create_group("particles")
        p["id"] = np.arange(N, dtype=np.int64)
        p["species"] = np.array([q[0] for q in parts], dtype="S16")
        p["charge"] = np.array([QE if q[0] == "proton" else -QE for q in parts])
        p["mass"] = np.array([MP if q[0] == "proton" else ME for q in parts])
        p["initial/x"] = tr_x[:, 0]
        p["initial/u"] = tr_u[:, 0]
        last = count - 1
        p["final/t"] = tr_t[np.arange(N), last]
        p["final/x"] = tr_x[np.arange(N), last]
        p["final/u"] = tr_u[np.arange(N), last]
        st = p.create_dataset("final/status", data=status)
        st.attrs["names"] = np.array([b"ALIVE", b"PRECIPITATED", b"LEFT_DOMAIN", b"LEFT_GRID",
                                      b"NONADIABATIC", b"NONFINITE", b"STEP_FAILED"])
        if mode == "traj":
            g = f.create_group("trajectories")
            g["t"], g["x"], g["u"], g["count"] = tr_t, tr_x, tr_u, count
        tm = f.create_group("timing")
        tm["cpu_seconds"] = np.full(N, 0.01)
        tm["steps"] = count * 100
        tm["rank_cpu_seconds"] = np.array([0.04])

main(sys.argv[1], sys.argv[2])
EOF

for mode in traj notraj notgcpush noparticles; do
    "$PY" "$tmp/make.py" "$tmp/$mode.h5" "$mode" || fail "could not write synthetic file ($mode)"
done

# PNG signature (8 bytes: 89 50 4E 47 0D 0A 1A 0A) and size in bytes
check_png() {
    [ -f "$1" ] || fail "$1 was not written"
    sig=$(od -An -tx1 -N8 "$1" | tr -d ' \n')
    [ "$sig" = "89504e470d0a1a0a" ] || fail "$1 is not a PNG (signature $sig)"
    size=$(wc -c < "$1" | tr -d ' ')
    [ "$size" -gt 20000 ] || fail "$1 is suspiciously small ($size bytes)"
    [ "$size" -lt 10000000 ] || fail "$1 is suspiciously large ($size bytes)"
}

# ---- good files -------------------------------------------------------------------------------
for mode in traj notraj; do
    out=$("$PY" "$script" "$tmp/$mode.h5" -o "$tmp/$mode.png" 2>"$tmp/$mode.err")
    rc=$?
    [ $rc -eq 0 ] || { cat "$tmp/$mode.err" >&2; fail "$mode: exit $rc, expected 0"; }
    check_png "$tmp/$mode.png"
    [ "$out" = "$tmp/$mode.png" ] || fail "$mode: printed '$out', expected the PNG path"
done

# --max and --ids, default output name
"$PY" "$script" "$tmp/traj.h5" --max 2 >/dev/null 2>"$tmp/max.err" || { cat "$tmp/max.err" >&2; fail "--max 2 failed"; }
check_png "$tmp/traj_orbits.png"
"$PY" "$script" "$tmp/traj.h5" --ids 0,3 -o "$tmp/ids.png" >/dev/null 2>"$tmp/ids.err" || { cat "$tmp/ids.err" >&2; fail "--ids 0,3 failed"; }
check_png "$tmp/ids.png"

# ---- errors: exit 1, one line on stderr, no traceback ----------------------------------------
expect_error() {  # name, then the arguments
    name=$1; shift
    "$PY" "$script" "$@" -o "$tmp/err.png" >/dev/null 2>"$tmp/err.txt"
    rc=$?
    [ $rc -eq 1 ] || { cat "$tmp/err.txt" >&2; fail "$name: exit $rc, expected 1"; }
    [ -s "$tmp/err.txt" ] || fail "$name: no message on stderr"
    [ "$(wc -l < "$tmp/err.txt" | tr -d ' ')" -eq 1 ] || { cat "$tmp/err.txt" >&2; fail "$name: message is not one line"; }
    ! grep -q Traceback "$tmp/err.txt" || fail "$name: traceback on stderr"
    [ ! -e "$tmp/err.png" ] || fail "$name: wrote a PNG anyway"
}
expect_error "missing file" "$tmp/does-not-exist.h5"
expect_error "non-gcpush HDF5 file" "$tmp/notgcpush.h5"
grep -q "not a gcpush" "$tmp/err.txt" || fail "non-gcpush message does not say it is not a gcpush file"
printf 'not hdf5 at all\n' > "$tmp/text.h5"
expect_error "not an HDF5 file" "$tmp/text.h5"
expect_error "no /particles group" "$tmp/noparticles.h5"
grep -q "particles" "$tmp/err.txt" || fail "missing-group message does not name /particles"
expect_error "unknown --ids" "$tmp/traj.h5" --ids 99

echo "ok test_plot_orbits"
