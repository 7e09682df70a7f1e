"""Small reader for gcpush HDF5 output files, shared by the scripts in analysis/.

Layout (see /work/shared/DESIGN.md, "HDF5 output"):

    /                 attrs gcpush_version, git_hash, build_flags, run_file, run_file_name,
                      units = "SI", ranks, scene, field, method, dt [s]
    /particles        id (N) int64, species (N) bytes, charge (N) [C], mass (N) [kg]
    /particles/initial  x (N,3) [m], u (N,3) [m/s]          (u = gamma v)
    /particles/final    t (N) [s], x (N,3), u (N,3), status (N) HDF5 enum over int32 (attr `names`)
    /trajectories     t (N,S) [s], x (N,S,3), u (N,S,3), count (N)     [only if asked]
    /timing           cpu_seconds (N), steps (N), rank_cpu_seconds (ranks)

Everything is SI.  Errors the user can cause (missing file, not HDF5, not gcpush, missing group
or dataset) raise GcpushError with a one-line message; scripts catch it and exit 1 (see `main_guard`).

Use from a script in analysis/:

    sys.dont_write_bytecode = True      # keep __pycache__ out of the source tree
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import gcpush_h5 as g5
    ...
    sys.exit(g5.main_guard("my_script", main))
"""

import os
import sys

import numpy as np

R_E = 6.3712e6            # Earth radius [m] (same constant as fields/dipole)
C_LIGHT = 299792458.0     # speed of light [m/s]
E_CHARGE = 1.602176634e-19  # elementary charge [C] (eV <-> J)

# Status codes in code order (include/gcpush/particles.h); files carry their own list in
# /particles/final/status attribute `names`, which wins when present.
STATUS_NAMES = ("ALIVE", "PRECIPITATED", "LEFT_DOMAIN", "LEFT_GRID",
                "NONADIABATIC", "NONFINITE", "STEP_FAILED")
ALIVE = 0


class GcpushError(Exception):
    """A user-facing error: one line, no traceback."""


def _s(v):
    """HDF5 attribute value -> plain Python (bytes -> str, 0-d arrays -> scalars)."""
    if isinstance(v, bytes):
        return v.decode("utf-8", "replace")
    if isinstance(v, np.ndarray):
        if v.shape == () or v.size == 1:
            return _s(v.reshape(-1)[0])
        if v.dtype.kind in "SO":
            return [_s(x) for x in v]
        return v
    if isinstance(v, np.generic):
        return v.item()
    return v


def open_gcpush(path):
    """Open PATH read-only and check it is a gcpush output file (root attribute gcpush_version).

    Returns an open h5py.File (use it as a context manager)."""
    import h5py
    if not os.path.exists(path):
        raise GcpushError("%s: no such file" % path)
    if os.path.isdir(path):
        raise GcpushError("%s: is a directory" % path)
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        if not h5py.is_hdf5(path):
            raise GcpushError("%s: not an HDF5 file" % path) from None
        raise GcpushError("%s: cannot open: %s" % (path, e)) from None
    if "gcpush_version" not in f.attrs:
        f.close()
        raise GcpushError("%s: not a gcpush output file (no root attribute gcpush_version)" % path)
    return f


def attrs(f):
    """Root attributes as a dict of plain Python values (strings decoded)."""
    return {k: _s(f.attrs[k]) for k in f.attrs}


def require(f, name):
    """f[name], or GcpushError naming the file and the missing object."""
    if name not in f:
        raise GcpushError("%s: missing %s (not a complete gcpush output file?)" % (f.filename, "/" + name.lstrip("/")))
    return f[name]


def status_names(f):
    """Status names in code order: from the HDF5 enum type of /particles/final/status
    (files since issue 13), else its attribute `names`, else the built-in list."""
    if "particles/final/status" not in f:
        return list(STATUS_NAMES)
    ds = f["particles/final/status"]
    import h5py
    enum = h5py.check_enum_dtype(ds.dtype)
    if enum:
        by_code = {int(v): str(k) for k, v in enum.items()}
        return [by_code.get(c, "STATUS_%d" % c) for c in range(max(by_code) + 1)]
    try:
        names = ds.attrs["names"]
    except KeyError:
        return list(STATUS_NAMES)
    names = _s(np.asarray(names))
    if isinstance(names, str):       # one string, comma/space separated
        names = names.replace(",", " ").split()
    return [str(n) for n in names]


def status_name(code, names=STATUS_NAMES):
    """Name of status CODE (int), or "STATUS_<code>" when unknown."""
    code = int(code)
    return names[code] if 0 <= code < len(names) else "STATUS_%d" % code


def read_particles(f):
    """Per-particle arrays (all length N, SI), as a dict:

    id, species (numpy str array), charge [C], mass [kg], x0 (N,3) [m], u0 (N,3) [m/s],
    t (N) [s], x (N,3) [m], u (N,3) [m/s], status (N) int, status_names (list);
    gc (bool): a guiding-centre run, whose x is the final guiding centre X, with
    ppar [kg m/s] and mu [J/T] and u all NaN."""
    require(f, "particles")
    p = {}
    p["id"] = np.asarray(require(f, "particles/id")[()], dtype=np.int64)
    sp = require(f, "particles/species")[()]
    p["species"] = np.array([_s(s).strip().rstrip("\0") for s in np.atleast_1d(sp)], dtype=str)
    p["charge"] = np.asarray(require(f, "particles/charge")[()], dtype=float)
    p["mass"] = np.asarray(require(f, "particles/mass")[()], dtype=float)
    p["x0"] = np.asarray(require(f, "particles/initial/x")[()], dtype=float).reshape(-1, 3)
    p["u0"] = np.asarray(require(f, "particles/initial/u")[()], dtype=float).reshape(-1, 3)
    p["t"] = np.asarray(require(f, "particles/final/t")[()], dtype=float)
    # a guiding-centre run ends with X, p_par, mu instead of x, u (u is NaN then); a hybrid
    # run (method = hybrid, /hybrid) has both: x, u the particle, X, ppar, mu its guiding centre
    p["hybrid"] = "hybrid" in f
    p["gc"] = "particles/final/X" in f and not p["hybrid"]
    if p["hybrid"]:
        p["x"] = np.asarray(require(f, "particles/final/x")[()], dtype=float).reshape(-1, 3)
        p["u"] = np.asarray(require(f, "particles/final/u")[()], dtype=float).reshape(-1, 3)
        p["X"] = np.asarray(require(f, "particles/final/X")[()], dtype=float).reshape(-1, 3)
        p["ppar"] = np.asarray(require(f, "particles/final/ppar")[()], dtype=float)
        p["mu"] = np.asarray(require(f, "particles/final/mu")[()], dtype=float)
        for k in ("mode", "switches", "t_gc", "t_fo"):
            p[k] = np.asarray(require(f, "hybrid/" + k)[()])
    elif p["gc"]:
        p["x"] = np.asarray(f["particles/final/X"][()], dtype=float).reshape(-1, 3)
        p["ppar"] = np.asarray(require(f, "particles/final/ppar")[()], dtype=float)
        p["mu"] = np.asarray(require(f, "particles/final/mu")[()], dtype=float)
        p["u"] = np.full_like(p["x"], np.nan)
    else:
        p["x"] = np.asarray(require(f, "particles/final/x")[()], dtype=float).reshape(-1, 3)
        p["u"] = np.asarray(require(f, "particles/final/u")[()], dtype=float).reshape(-1, 3)
    p["status"] = np.asarray(require(f, "particles/final/status")[()], dtype=np.int64)
    p["status_names"] = status_names(f)
    n = len(p["id"])
    for k in ("species", "charge", "mass", "x0", "u0", "t", "x", "u", "status"):
        if len(p[k]) != n:
            raise GcpushError("%s: /particles/%s has %d rows, /particles/id has %d"
                              % (f.filename, k, len(p[k]), n))
    return p


def has_trajectories(f):
    return "trajectories" in f and "x" in f["trajectories"]


def read_trajectories(f, rows=None):
    """Trajectory samples of the particles at row indices ROWS (default: all), NaN padding trimmed.

    Returns a list (in the order of ROWS) of dicts {t (S_i,), x (S_i,3), u (S_i,3) or None,
    mode (S_i,) or None (hybrid runs: 0 guiding centre, 1 full orbit)}, or None when the file
    has no /trajectories.  Only the requested rows are read from disk."""
    if not has_trajectories(f):
        return None
    g = f["trajectories"]
    n = g["x"].shape[0]
    rows = np.arange(n) if rows is None else np.asarray(rows, dtype=np.int64).reshape(-1)
    if len(rows) == 0:
        return []
    if rows.min() < 0 or rows.max() >= n:
        raise GcpushError("%s: trajectory row out of range" % f.filename)
    uniq, inv = np.unique(rows, return_inverse=True)   # h5py wants increasing indices
    sel = list(uniq)
    xs = g["x"][sel]
    ts = g["t"][sel] if "t" in g else None
    us = g["u"][sel] if "u" in g else None
    ms = g["mode"][sel] if "mode" in g else None
    count = (np.asarray(g["count"][sel], dtype=np.int64) if "count" in g
             else np.full(len(sel), xs.shape[1], dtype=np.int64))
    out = []
    for k in inv:
        c = int(min(max(count[k], 0), xs.shape[1]))
        x = np.asarray(xs[k, :c], dtype=float).reshape(-1, 3)
        t = np.asarray(ts[k, :c], dtype=float) if ts is not None else np.arange(c, dtype=float)
        u = np.asarray(us[k, :c], dtype=float).reshape(-1, 3) if us is not None else None
        ok = np.all(np.isfinite(x), axis=1) & np.isfinite(t)   # belt and braces: drop any NaN left
        m = np.asarray(ms[k, :c], dtype=np.int64) if ms is not None else None
        out.append({"t": t[ok], "x": x[ok], "u": u[ok] if u is not None else None,
                    "mode": m[ok] if m is not None else None})
    return out


def read_table(f, name):
    """An event table (/invariants/bounce, /invariants/drift, /invariants/mu, /losses, ...) as a
    dict of numpy arrays (rows sorted by (id, t)), or None when the file has none."""
    if name.strip("/") not in f:
        return None
    g = f[name.strip("/")]
    return {k: np.asarray(g[k][()]) for k in g if not hasattr(g[k], "keys")}


def kinetic_energy(u, mass):
    """Relativistic kinetic energy [J] from u = gamma v [m/s] (..., 3) and mass [kg]."""
    u = np.asarray(u, dtype=float)
    u2 = np.sum(u * u, axis=-1) / C_LIGHT ** 2
    # (gamma - 1) written without cancellation for small u
    return np.asarray(mass) * C_LIGHT ** 2 * u2 / (np.sqrt(1.0 + u2) + 1.0)


def pick_even(species, nmax):
    """Row indices of at most NMAX particles, spread evenly over the ensemble and over species.

    Each species gets an equal share (a species with fewer particles gives its unused share to the
    others); inside a species, particles are taken at evenly spaced positions.  Sorted result."""
    species = np.asarray(species)
    n = len(species)
    if nmax <= 0 or n == 0:
        return np.zeros(0, dtype=np.int64)
    if nmax >= n:
        return np.arange(n, dtype=np.int64)
    kinds = list(dict.fromkeys(species.tolist()))       # first-appearance order
    avail = {k: int(np.sum(species == k)) for k in kinds}
    share = {k: 0 for k in kinds}
    left = nmax
    open_ = [k for k in kinds]
    while left > 0 and open_:
        each = max(left // len(open_), 1)
        for k in list(open_):
            take = min(each, avail[k] - share[k], left)
            share[k] += take
            left -= take
            if share[k] >= avail[k]:
                open_.remove(k)
            if left == 0:
                break
    rows = []
    for k in kinds:
        idx = np.flatnonzero(species == k)
        m = share[k]
        if m > 0:
            pos = np.round(np.linspace(0, len(idx) - 1, m)).astype(np.int64)
            rows.extend(idx[np.unique(pos)])
    return np.sort(np.asarray(rows, dtype=np.int64))


def main_guard(prog, fn, *args):
    """Run fn(*args); turn GcpushError / OSError / KeyError into one stderr line and exit 1."""
    try:
        rc = fn(*args)
    except GcpushError as e:
        print("%s: error: %s" % (prog, e), file=sys.stderr)
        return 1
    except (OSError, KeyError, ValueError) as e:
        print("%s: error: %s" % (prog, e), file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("%s: interrupted" % prog, file=sys.stderr)
        return 130
    except Exception as e:               # a bug or a file we do not understand: still one line
        if os.environ.get("GCPUSH_DEBUG"):
            raise
        print("%s: error: %s: %s (set GCPUSH_DEBUG=1 for a traceback)"
              % (prog, type(e).__name__, e), file=sys.stderr)
        return 1
    return 0 if rc is None else rc
