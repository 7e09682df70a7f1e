#!/usr/bin/python3
"""Loss times and the equatorial pitch-angle distribution before and after, from a gcpush file.

    losses.py OUT.h5 [-o OUT.png]

Reads /losses {id, t, status, x} (the crossing of the atmosphere interpolated within the step)
and /losses/initial {L, alpha_eq, alpha_lc} (the start classification: equatorial pitch angle of
the initial guiding centre and the dipole loss cone at its L).

stdout:
  - per species and status: count, median / min / max loss time;
  - the loss-cone check: particles that started inside the loss cone (alpha_eq < alpha_lc or
    > 180 deg - alpha_lc) and how many of them precipitated, those that started outside and how
    many precipitated;
  - the equatorial pitch-angle distribution (10 bins over 0..90 deg, folded) at the start and of
    the particles still alive at the end.
The PNG: histogram of loss times; pitch-angle distributions before and after, the loss cone marked.
"""

import argparse
import os
import sys

sys.dont_write_bytecode = True
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import numpy as np  # noqa: E402

import gcpush_h5 as g5  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("file")
    ap.add_argument("-o", "--output", help="PNG (default: FILE with .losses.png)")
    args = ap.parse_args()
    with g5.open_gcpush(args.file) as f:
        p = g5.read_particles(f)
        loss = g5.read_table(f, "losses")
        init = g5.read_table(f, "losses/initial")
    if loss is None or init is None:
        raise g5.GcpushError("%s: no /losses ([diagnostics] events = loss)" % args.file)
    names = p["status_names"]
    row = {int(i): k for k, i in enumerate(p["id"])}
    sp_of = p["species"]
    print("%-10s %-14s %6s %12s %12s %12s" % ("species", "status", "n", "t_median", "t_min", "t_max"))
    for sp in sorted(set(sp_of.tolist())):
        sel = np.array([sp_of[row[int(i)]] == sp for i in loss["id"]], dtype=bool)
        for s in sorted(set(loss["status"][sel].tolist())):
            t = loss["t"][sel & (loss["status"] == s)]
            print("%-10s %-14s %6d %12.6g %12.6g %12.6g"
                  % (sp, g5.status_name(s, names), len(t), np.median(t), t.min(), t.max()))
    aeq = np.degrees(np.asarray(init["alpha_eq"], dtype=float))
    alc = np.degrees(np.asarray(init["alpha_lc"], dtype=float))
    fold = np.minimum(aeq, 180 - aeq)
    inside = fold < alc
    precip = p["status"] == 1
    ok = np.isfinite(fold) & np.isfinite(alc)
    print("loss cone: inside %d (precipitated %d), outside %d (precipitated %d)"
          % (np.sum(inside & ok), np.sum(inside & ok & precip), np.sum(~inside & ok),
             np.sum(~inside & ok & precip)))
    bins = np.linspace(0, 90, 11)
    alive = p["status"] == 0
    hb, _ = np.histogram(fold[ok], bins)
    ha, _ = np.histogram(fold[ok & alive], bins)
    print("pitch-angle bins [deg]: " + " ".join("%g" % b for b in bins))
    print("before: " + " ".join("%d" % h for h in hb))
    print("after:  " + " ".join("%d" % h for h in ha))

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    if len(loss["t"]):
        axes[0].hist(loss["t"], bins=30)
    axes[0].set_xlabel("loss time [s]")
    axes[0].set_ylabel("particles")
    axes[1].hist(fold[ok], bins, histtype="step", label="start")
    axes[1].hist(fold[ok & alive], bins, histtype="stepfilled", alpha=0.5, label="alive at end")
    if np.any(ok):
        axes[1].axvline(np.nanmedian(alc), color="k", ls="--", lw=0.8, label="loss cone (median L)")
    axes[1].set_xlabel("equatorial pitch angle [deg]")
    axes[1].legend(fontsize=8)
    fig.tight_layout()
    png = args.output or os.path.splitext(args.file)[0] + ".losses.png"
    fig.savefig(png, dpi=90)
    print("plot: %s" % png)
    return 0


if __name__ == "__main__":
    sys.exit(g5.main_guard("losses.py", main))
