#!/usr/bin/python3
"""Work-precision diagram of a gcpush sweep: error against CPU seconds, one line per method.

usage: work_precision.py OUT.h5 [-o OUT.png] [--measure position_error] [--population NAME]

OUT.h5 is the output of a run file with a [sweep] section (its /sweep table).  Left panel:
the error measure against CPU seconds (log-log), one line per method (and population);
right panel: the same error against the step dt, with each fixed-step method's fitted slope
(its observed order) in the legend; adaptive methods are drawn against their tolerance in
the left panel only.  The slope is fitted on the smallest steps whose error lies above the
round-off floor (1e-9 of the largest error in the table); a method whose errors all lie
below it is labelled "round-off".  The table is printed on stdout.

Measures: position_error [m] (default), position_error_gyroradius, position_error_path,
gc_position_error [m] (guiding centres: the drift and bounce error whatever the gyrophase),
gyrophase_error [rad] (absolute value), energy_error.

Exit status 0 on success (the PNG path is printed), 1 on any error (one line on stderr).
"""

import argparse
import math
import os
import sys

sys.dont_write_bytecode = True          # no __pycache__ in the source tree
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import gcpush_h5 as g5  # noqa: E402

import numpy as np  # noqa: E402

PROG = "work_precision"
MEASURES = {
    "position_error": "final position error [m]",
    "position_error_gyroradius": "final position error / gyroradius",
    "position_error_path": "final position error / distance travelled",
    "gc_position_error": "final guiding-centre position error [m]",
    "gyrophase_error": "|gyrophase error| [rad]",
    "energy_error": "relative energy error",
}
COLUMNS = ("method", "population", "dt", "dt_given", "dt_unit", "tolerance", "cpu_seconds",
           "steps", "particles", "failed", "position_error", "position_error_gyroradius",
           "position_error_path", "gc_position_error", "gyrophase_error", "energy_error")


def read_sweep(path):
    """The /sweep table of PATH as a dict of numpy arrays, plus its attributes."""
    with g5.open_gcpush(path) as f:
        if "sweep" not in f:
            raise g5.GcpushError("%s: no /sweep table (not the output of a run file with [sweep])"
                                 % path)
        g = f["sweep"]
        t = {}
        for c in COLUMNS:
            if c not in g:
                raise g5.GcpushError("%s: /sweep has no column '%s'" % (path, c))
            v = g[c][()]
            if v.dtype.kind in "SO":
                v = np.array([g5._s(s).rstrip("\0") for s in np.atleast_1d(v)], dtype=str)
            t[c] = np.atleast_1d(v)
        n = len(t["method"])
        for c in COLUMNS:
            if len(t[c]) != n:
                raise g5.GcpushError("%s: /sweep/%s has %d rows, /sweep/method has %d"
                                     % (path, c, len(t[c]), n))
        meta = {k: g5._s(g.attrs[k]) for k in g.attrs}
        meta.update({"scene": g5.attrs(f).get("scene", "?")})
    return t, meta


def fit_order(dt, err, floor):
    """Slope of log(err) against log(dt) over the smallest steps above floor, or None."""
    ok = np.isfinite(dt) & np.isfinite(err) & (err > floor) & (dt > 0)
    if np.sum(ok) < 2:
        return None
    order = np.argsort(dt[ok])
    x = np.log(dt[ok][order][:3])
    y = np.log(err[ok][order][:3])
    return float(np.polyfit(x, y, 1)[0])


def print_table(t, meta):
    print("sweep %s: reference %s, duration %.6g s" % (meta.get("scene", "?"),
                                                      meta.get("reference", "?"),
                                                      float(meta.get("duration", float("nan")))))
    hdr = ("method", "population", "dt[s]", "tol", "steps", "cpu[s]", "pos_err[m]", "err/rho",
           "gc_err[m]", "phase[rad]", "energy", "failed")
    print("%-13s %-11s %-10s %-7s %11s %10s %10s %10s %10s %10s %10s %6s" % hdr)
    for i in range(len(t["method"])):
        tol = "%.0e" % t["tolerance"][i] if np.isfinite(t["tolerance"][i]) else "-"
        print("%-13s %-11s %-10.4g %-7s %11d %10.4g %10.3e %10.3e %10.3e %10.3e %10.3e %6d"
              % (t["method"][i], t["population"][i], t["dt"][i], tol, t["steps"][i],
                 t["cpu_seconds"][i], t["position_error"][i], t["position_error_gyroradius"][i],
                 t["gc_position_error"][i], t["gyrophase_error"][i], t["energy_error"][i], t["failed"][i]))


def main(argv):
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__.split("\n")[0])
    ap.add_argument("file", help="gcpush sweep output (HDF5)")
    ap.add_argument("-o", "--output", help="PNG to write (default: FILE with .png)")
    ap.add_argument("--measure", default="position_error", choices=sorted(MEASURES))
    ap.add_argument("--population", help="only this population")
    a = ap.parse_args(argv)
    t, meta = read_sweep(a.file)
    print_table(t, meta)
    err_all = np.abs(np.asarray(t[a.measure], dtype=float))
    keys = []
    for m, p in zip(t["method"], t["population"]):
        if (a.population is None or p == a.population) and (m, p) not in keys:
            keys.append((m, p))
    if not keys:
        raise g5.GcpushError("%s: no rows%s" % (a.file, "" if a.population is None else
                                                " for population '%s'" % a.population))
    fin = err_all[np.isfinite(err_all)]
    floor = 1e-9 * fin.max() if fin.size and fin.max() > 0 else 0.0

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 5))
    pops = sorted(set(p for _, p in keys))
    markers = "os^vD<>ph*"
    print("%-13s %-11s %s" % ("method", "population", "order (slope of error vs dt)"))
    for k, (m, p) in enumerate(keys):
        sel = (t["method"] == m) & (t["population"] == p)
        cpu = t["cpu_seconds"][sel]
        err = err_all[sel]
        dt = t["dt"][sel]
        adaptive = np.all(np.isfinite(t["tolerance"][sel]))
        label = m if len(pops) == 1 else "%s [%s]" % (m, p)
        ok = np.isfinite(err) & (err > 0) & (cpu > 0)
        if adaptive:
            slope = fit_order(t["tolerance"][sel], err, floor)
            note = "vs tol %.2f" % slope if slope is not None else "round-off"
        else:
            slope = fit_order(dt, err, floor)
            note = "order %.2f" % slope if slope is not None else "round-off"
        print("%-13s %-11s %s" % (m, p, note))
        mk = markers[k % len(markers)]
        if np.any(ok):
            line, = ax.loglog(cpu[ok], err[ok], "-" + mk, label="%s (%s)" % (label, note))
            if not adaptive:
                bx.loglog(dt[ok], err[ok], "-" + mk, color=line.get_color(),
                          label="%s (%s)" % (label, note))
    ax.set_xlabel("CPU seconds (best of repeats, all particles)")
    ax.set_ylabel(MEASURES[a.measure])
    ax.set_title("%s: error against run time\nreference: %s"
                 % (meta.get("scene", "?"), meta.get("reference", "?")), fontsize=10)
    bx.set_xlabel("dt [s]")
    bx.set_ylabel(MEASURES[a.measure])
    bx.set_title("error against step (slope = observed order)", fontsize=10)
    for x in (ax, bx):
        x.grid(True, which="both", alpha=0.3)
        if x.lines:
            x.legend(fontsize=8)
    fig.tight_layout()
    out = a.output or os.path.splitext(a.file)[0] + ".png"
    fig.savefig(out, dpi=110)
    plt.close(fig)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(g5.main_guard(PROG, main, sys.argv[1:]))
