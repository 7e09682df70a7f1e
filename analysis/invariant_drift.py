#!/usr/bin/python3
"""Relative drift of the adiabatic invariants mu, K and L* in a gcpush output file.

    invariant_drift.py OUT.h5 [-o OUT.png]

Reads /invariants/mu (mu at each equator point), /invariants/bounce (K per bounce) and
/invariants/drift (L* per drift orbit).  For each particle and invariant X with samples X_0 .. X_n
over a time span dt, the drift rate is r = |X_n - X_0| / |X_0| / dt; it is reported

    per bounce        r * T_b   (T_b: the particle's mean measured bounce period)
    per drift period  r * T_d   (T_d: its mean measured drift period; particles without a
                                 completed drift orbit are left out of this column)

A particle needs two samples of X.  The table on stdout gives, per method and species and
invariant, the number of particles, the median, the 95th percentile and the worst particle (its
id).  The PNG shows the distributions (log10 of the relative drift per bounce).

method = hybrid: every /invariants row carries the mode of the sample that closed it (0 guiding
centre, 1 full orbit, gyro-averaged), so mu is followed across the switches.  The run is then
also summarised by its largest mu jumps between successive equator rows (a curvature scattering
event shows as one), and a fourth panel draws mu(t) / mu(0) of those particles, full-orbit rows
filled, guiding-centre rows open, their full-orbit stretches (/hybrid/events) shaded.
"""

import argparse
import os
import sys

sys.dont_write_bytecode = True
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import numpy as np  # noqa: E402

import gcpush_h5 as g5  # noqa: E402


def per_particle(table, col):
    """{id: (t array, value array)} of one table column."""
    out = {}
    if table is None or len(table["id"]) == 0:
        return out
    ids, t, v = table["id"], table["t"], table[col]
    order = np.lexsort((t, ids))
    ids, t, v = ids[order], t[order], v[order]
    cut = np.flatnonzero(np.diff(ids)) + 1
    for a, b in zip(np.r_[0, cut], np.r_[cut, len(ids)]):
        out[int(ids[a])] = (t[a:b], v[a:b])
    return out


def rates(series):
    """{id: relative drift rate [1/s]} for particles with two samples or more."""
    r = {}
    for i, (t, v) in series.items():
        if len(v) >= 2 and t[-1] > t[0] and v[0] != 0 and np.all(np.isfinite(v)):
            r[i] = abs(v[-1] - v[0]) / abs(v[0]) / (t[-1] - t[0])
    return r


def mu_jumps(mu, nmax=6):
    """Hybrid runs: [(id, t, jump)] of the largest relative changes of mu between successive
    equator rows of a particle, largest first (at most nmax particles, one row each)."""
    best = {}
    for i, (t, v) in per_particle(mu, "mu").items():
        if len(v) < 2:
            continue
        r = np.abs(v[1:] / v[:-1] - 1.0)
        k = int(np.nanargmax(r)) if np.any(np.isfinite(r)) else None
        if k is not None:
            best[i] = (float(t[k + 1]), float(r[k]))
    ranked = sorted(best.items(), key=lambda kv: -kv[1][1])[:nmax]
    return [(i, t, j) for i, (t, j) in ranked]


def fo_stretches(events, pid, t_end):
    """[(t0, t1)] full-orbit stretches of particle pid from /hybrid/events (direction +1 starts
    one, -1 ends it); a particle that starts as a full orbit opens with one from 0."""
    if events is None:
        return []
    sel = events["id"] == pid
    t, d = events["t"][sel], events["direction"][sel]
    out, t0 = [], (0.0 if len(d) and d[0] < 0 else None)
    for ti, di in zip(t, d):
        if di > 0:
            t0 = ti
        elif t0 is not None:
            out.append((t0, ti))
            t0 = None
    if t0 is not None:
        out.append((t0, t_end))
    return out


def analyse(path):
    with g5.open_gcpush(path) as f:
        a = g5.attrs(f)
        p = g5.read_particles(f)
        bounce = g5.read_table(f, "invariants/bounce")
        drift = g5.read_table(f, "invariants/drift")
        mu = g5.read_table(f, "invariants/mu")
        switches = g5.read_table(f, "hybrid/events")
    if bounce is None and drift is None and mu is None:
        raise g5.GcpushError("%s: no /invariants (ask for them: [diagnostics] invariants = mu K L)"
                             % path)
    method = str(a.get("method", "?"))
    species_of = dict(zip(p["id"].tolist(), p["species"].tolist()))
    Tb = {i: float(np.mean(v)) for i, (t, v) in per_particle(bounce, "period").items()}
    Td = {i: float(np.mean(v)) for i, (t, v) in per_particle(drift, "period").items()}
    series = {
        "mu": rates(per_particle(mu, "mu")),
        "K": rates(per_particle(bounce, "K")),
        "L*": rates(per_particle(drift, "Lstar")),
    }
    rows = []   # (method, species, invariant, per, values, ids)
    for name, r in series.items():
        for per, T in (("bounce", Tb), ("drift", Td)):
            for sp in sorted(set(species_of.values())):
                ids = [i for i in r if species_of.get(i) == sp and i in T]
                if not ids:
                    continue
                vals = np.array([r[i] * T[i] for i in ids])
                rows.append((method, sp, name, per, vals, np.array(ids)))
    hyb = None
    if mu is not None and "mode" in mu:
        t_end = float(np.nanmax(p["t"])) if len(p["t"]) else 0.0
        hyb = {"mu": mu, "jumps": mu_jumps(mu), "switches": switches, "t_end": t_end}
    return rows, hyb


def report_hybrid(hyb, out=sys.stdout):
    m = hyb["mu"]["mode"]
    print("hybrid: mu rows from full-orbit stretches %d, from guiding-centre steps %d"
          % (np.count_nonzero(m == 1), np.count_nonzero(m == 0)), file=out)
    for i, t, j in hyb["jumps"]:
        print("hybrid: largest mu jump of particle %d: %.3e at t = %.6g s" % (i, j, t), file=out)


def report(rows, out=sys.stdout):
    print("%-12s %-10s %-4s %-12s %6s %10s %10s %10s %8s"
          % ("method", "species", "inv", "per", "n", "median", "p95", "worst", "worst_id"), file=out)
    for method, sp, name, per, vals, ids in rows:
        k = int(np.argmax(vals))
        print("%-12s %-10s %-4s %-12s %6d %10.3e %10.3e %10.3e %8d"
              % (method, sp, name, per, len(vals), np.median(vals), np.percentile(vals, 95),
                 vals[k], ids[k]), file=out)


def plot_hybrid(ax, hyb):
    mu = hyb["mu"]
    for n, (i, _, _) in enumerate(hyb["jumps"]):
        sel = mu["id"] == i
        t, v, m = mu["t"][sel], mu["mu"][sel], mu["mode"][sel]
        c = "C%d" % (n % 10)
        ax.plot(t, v / v[0], "-", color=c, lw=0.6)
        ax.plot(t[m == 1], v[m == 1] / v[0], "o", color=c, ms=3, label="id %d" % i)
        ax.plot(t[m == 0], v[m == 0] / v[0], "o", mfc="none", color=c, ms=3)
        for t0, t1 in fo_stretches(hyb["switches"], i, hyb["t_end"]):
            ax.axvspan(t0, t1, color=c, alpha=0.06, lw=0)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("mu / mu(0) (filled: full orbit, open: guiding centre)")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7)


def plot(rows, png, hyb=None):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = ["mu", "K", "L*"]
    fig, axes = plt.subplots(1, 4 if hyb else 3, figsize=(17 if hyb else 13, 4))
    if hyb:
        plot_hybrid(axes[3], hyb)
    for ax, name in zip(axes, names):
        for method, sp, n, per, vals, ids in rows:
            if n != name or per != "bounce":
                continue
            v = np.log10(np.maximum(vals, 1e-18))
            ax.hist(v, bins=30, alpha=0.6, label="%s %s" % (method, sp))
        ax.set_xlabel("log10 relative drift of %s per bounce" % name)
        ax.set_ylabel("particles")
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=90)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("file")
    ap.add_argument("-o", "--output", help="PNG (default: FILE with .invariants.png)")
    args = ap.parse_args()
    rows, hyb = analyse(args.file)
    report(rows)
    if hyb:
        report_hybrid(hyb)
    png = args.output or os.path.splitext(args.file)[0] + ".invariants.png"
    plot(rows, png, hyb)
    print("plot: %s" % png)
    return 0


if __name__ == "__main__":
    sys.exit(g5.main_guard("invariant_drift.py", main))
