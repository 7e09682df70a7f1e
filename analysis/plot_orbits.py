#!/usr/bin/python3
"""Plot particle orbits from a gcpush HDF5 output file.

usage: plot_orbits.py OUT.h5 [-o OUT.png] [--max N] [--ids 0,5,7]

Dipole scenes (lengths in Earth radii): equatorial x-y view with the Earth, meridional view
(rho = sqrt(x^2+y^2) against z, with dipole field lines r = L cos^2(lat)), and r against time.
Other fields (lengths in m, cm or mm): x-y and x-z views (R-z for a tokamak), and the kinetic
energy (or z for a mirror) against time when it says something.  Colour is by species; a cross
marks the last point of a particle whose final status is not ALIVE.  Without /trajectories only
the initial (open circles) and final (dots) positions are drawn.

Exit status 0 on success (the PNG path is printed), 1 on any error (one line on stderr).
"""

import argparse
import math
import os
import sys

sys.dont_write_bytecode = True          # no __pycache__ in the source tree
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import gcpush_h5 as g5  # noqa: E402

import h5py
import numpy as np  # noqa: E402

PROG = "plot_orbits"

SPECIES_CMAP = {"proton": "Reds", "electron": "Blues", "alpha": "Greens", "positron": "Oranges",
                "O+": "Purples", "oxygen": "Purples"}
OTHER_CMAPS = ["Oranges", "Greens", "Purples", "Greys", "YlOrBr", "PuRd"]


# ---------------------------------------------------------------- formatting

# method = hybrid: trajectory samples pushed as full orbits (the rest are guiding centres)
FO_MARK = dict(ls="none", marker=".", ms=2.5, color="k", alpha=0.6, zorder=5)


def si(v, unit, digits=3):
    """1.2e-3, "s" -> "1.2 ms"."""
    if v is None or not np.isfinite(v):
        return "?"
    if v == 0:
        return "0 " + unit
    prefixes = [(1e9, "G"), (1e6, "M"), (1e3, "k"), (1.0, ""), (1e-3, "m"), (1e-6, "\u00b5"),
                (1e-9, "n"), (1e-12, "p"), (1e-15, "f")]
    a = abs(v)
    for scale, p in prefixes:
        if a >= scale * 0.9999:
            return "%s %s%s" % (("%%.%dg" % digits) % (v / scale), p, unit)
    return "%.3g %s" % (v, unit)


def time_unit(tmax):
    """(scale, label) for a time axis that ends at tmax [s]."""
    if not np.isfinite(tmax) or tmax <= 0:
        return 1.0, "s"
    for scale, lab in ((1e-9, "ns"), (1e-6, "\u00b5s"), (1e-3, "ms"), (1.0, "s")):
        if tmax < 2000 * scale:
            return scale, lab
    if tmax < 2 * 3600 * 5:
        return 60.0, "min"
    if tmax < 3 * 86400:
        return 3600.0, "h"
    return 86400.0, "d"


def length_unit(extent):
    """(scale, label) for lengths of size `extent` [m] (non-dipole fields)."""
    if extent < 2e-2:
        return 1e-3, "mm"
    if extent < 2.0:
        return 1e-2, "cm"
    if extent < 2e4:
        return 1.0, "m"
    return 1e3, "km"


def energy_unit(emax_j):
    ev = emax_j / g5.E_CHARGE
    for scale, lab in ((1e9, "GeV"), (1e6, "MeV"), (1e3, "keV")):
        if ev >= scale:
            return scale * g5.E_CHARGE, lab
    return g5.E_CHARGE, "eV"


def energy_range_label(ek):
    """'1.2 MeV' or '1–100 MeV' for kinetic energies ek [J]."""
    ek = ek[np.isfinite(ek)]
    if len(ek) == 0:
        return ""
    lo, hi = float(ek.min()), float(ek.max())
    scale, lab = energy_unit(hi)
    if hi <= lo * 1.001:
        return "%.3g %s" % (hi / scale, lab)
    return "%.3g\u2013%.3g %s" % (lo / scale, hi / scale, lab)


def parse_ids(text):
    ids = []
    for part in text.replace(" ", "").split(","):
        if not part:
            continue
        try:
            if "-" in part[1:]:
                a, b = part.split("-", 1) if part[0] != "-" else (None, None)
                a, b = int(a), int(b)
                if b < a:
                    raise ValueError
                ids.extend(range(a, b + 1))
            else:
                ids.append(int(part))
        except (TypeError, ValueError):
            raise g5.GcpushError("--ids: '%s' is not a particle id or range a-b" % part) from None
    if not ids:
        raise g5.GcpushError("--ids: no particle ids given")
    return ids


# ---------------------------------------------------------------- data

def collect(path, nmax, ids):
    """Everything the plot needs, as a dict."""
    with g5.open_gcpush(path) as f:
        meta = g5.attrs(f)
        p = g5.read_particles(f)
        n = len(p["id"])
        if n == 0:
            raise g5.GcpushError("%s: the file holds no particles" % path)
        if ids is not None:
            where = {int(v): i for i, v in enumerate(p["id"])}
            missing = [i for i in ids if i not in where]
            if missing:
                raise g5.GcpushError("%s: no particle with id %s (ids run %d..%d)"
                                     % (path, ",".join(map(str, missing[:5])),
                                        p["id"].min(), p["id"].max()))
            rows = np.array(sorted(set(where[i] for i in ids)), dtype=np.int64)
        else:
            rows = g5.pick_even(p["species"], nmax)
        traj = g5.read_trajectories(f, rows)
    return {"meta": meta, "p": p, "rows": rows, "traj": traj, "n": n}


def is_dipole(meta, p):
    field = str(meta.get("field", "")).lower()
    if field:
        return field == "dipole" or field == "igrf"
    r = np.linalg.norm(p["x0"], axis=1)          # no attribute: guess from the scale
    return bool(np.all(np.isfinite(r)) and np.median(r) > 1.2 * g5.R_E)


# ---------------------------------------------------------------- drawing

def species_styles(species_shown):
    """species -> colormap; keeps the first-appearance order."""
    import matplotlib
    out = {}
    k = 0
    for s in dict.fromkeys(species_shown):
        name = SPECIES_CMAP.get(s)
        if name is None:
            name = OTHER_CMAPS[k % len(OTHER_CMAPS)]
            k += 1
        out[s] = matplotlib.colormaps[name]
    return out


def particle_colours(species_rows, cmaps):
    """One colour per drawn particle: shades of its species' colormap."""
    cols = [None] * len(species_rows)
    for s, cmap in cmaps.items():
        idx = [i for i, sp in enumerate(species_rows) if sp == s]
        shades = np.linspace(0.55, 0.9, len(idx)) if len(idx) > 1 else [0.75]
        for i, sh in zip(idx, shades):
            cols[i] = cmap(sh)
    return cols


def draw_earth_equatorial(ax):
    from matplotlib.patches import Circle
    ax.add_patch(Circle((0, 0), 1.0, facecolor="#9ecae1", edgecolor="#08306b", lw=0.8, zorder=5))


def draw_earth_meridional(ax):
    from matplotlib.patches import Wedge
    ax.add_patch(Wedge((0, 0), 1.0, -90, 90, facecolor="#9ecae1", edgecolor="#08306b", lw=0.8,
                       zorder=5))


def nice_L_values(lmax):
    """A few field-line L values spanning 2..lmax (at most ~7)."""
    top = max(2, int(math.ceil(lmax)))
    for step in (1, 2, 5, 10, 20, 50):
        ls = list(range(2 if step == 1 else step, top + 1, step))
        if len(ls) <= 7:
            return ls or [2]
    return [top]


def plot_dipole(fig, d, sel, cols, mark, have_traj):
    """Three (or two, without trajectories) panels in Earth radii."""
    ax_eq = fig.add_subplot(1, 3 if have_traj else 2, 1)
    ax_mer = fig.add_subplot(1, 3 if have_traj else 2, 2)
    ax_t = fig.add_subplot(1, 3, 3) if have_traj else None

    rmax = 1.5
    zmax = 0.0
    lmax = 2.0
    tmax = 0.0
    for s in sel:
        xr = s["pts"] / g5.R_E
        rho = np.hypot(xr[:, 0], xr[:, 1])
        r = np.linalg.norm(xr, axis=1)
        if len(r):
            rmax = max(rmax, float(np.nanmax(r)))
            zmax = max(zmax, float(np.nanmax(np.abs(xr[:, 2]))))
            cos2 = np.where(r > 0, (rho / np.where(r > 0, r, 1.0)) ** 2, 1.0)
            lsh = np.where(cos2 > 1e-3, r / np.maximum(cos2, 1e-3), np.nan)
            if np.any(np.isfinite(lsh)):
                lmax = max(lmax, float(np.nanmax(lsh)))
        if len(s["ts"]):
            tmax = max(tmax, float(np.nanmax(s["ts"])))
    lmax = min(lmax, 3 * rmax)
    lim = 1.08 * rmax
    zl = max(1.15 * zmax, 0.45 * lim, 1.1)

    # field lines and L circles, drawn faintly underneath
    lat = np.linspace(-np.pi / 2, np.pi / 2, 721)
    for L in nice_L_values(min(lmax, lim)):
        c2 = np.cos(lat) ** 2
        rr = L * c2
        ok = rr >= 1.0
        ax_mer.plot(rr[ok] * np.cos(lat[ok]), rr[ok] * np.sin(lat[ok]), color="0.6", lw=0.6,
                    ls="-", zorder=1)
        # label at the top of the line (lat 35.26 deg: rho = 0.544 L, z = 0.385 L) if in view
        if 0.544 * L < 0.95 * lim and 0.385 * L < 0.9 * zl:
            ax_mer.text(0.544 * L, 0.385 * L, "L=%d" % L, fontsize=7, color="0.4", ha="center",
                        va="bottom", zorder=2, clip_on=True)
        ph = np.linspace(0, 2 * np.pi, 361)
        ax_eq.plot(L * np.cos(ph), L * np.sin(ph), color="0.75", lw=0.5, ls=":", zorder=1)

    tscale, tlab = time_unit(tmax)
    for s, c in zip(sel, cols):
        xr = s["xs"] / g5.R_E
        rho = np.hypot(xr[:, 0], xr[:, 1])
        if s["traj"]:
            ax_eq.plot(xr[:, 0], xr[:, 1], color=c, lw=0.7, alpha=0.9, zorder=3)
            ax_mer.plot(rho, xr[:, 2], color=c, lw=0.7, alpha=0.9, zorder=3)
            ax_t.plot(s["ts"] / tscale, np.linalg.norm(xr, axis=1), color=c, lw=0.7, alpha=0.9)
            if s["fo"] is not None and s["fo"].any():
                fo = s["fo"]
                ax_eq.plot(xr[fo, 0], xr[fo, 1], **FO_MARK)
                ax_mer.plot(rho[fo], xr[fo, 2], **FO_MARK)
                ax_t.plot(s["ts"][fo] / tscale, np.linalg.norm(xr[fo], axis=1), **FO_MARK)
            start_mk = dict(marker="o", ms=3.5, mfc=c, mec="k", mew=0.4)
        else:
            start_mk = dict(marker="o", ms=5, mfc="none", mec=c, mew=1.0)
            fin = s["xf"] / g5.R_E
            if not s["lost"]:
                for ax, (a, b) in ((ax_eq, (fin[0], fin[1])), (ax_mer, (np.hypot(fin[0], fin[1]), fin[2]))):
                    ax.plot([a], [b], ls="none", marker="o", ms=4, color=c, zorder=4)
        x0 = s["x0"] / g5.R_E
        ax_eq.plot([x0[0]], [x0[1]], ls="none", zorder=4, **start_mk)
        ax_mer.plot([np.hypot(x0[0], x0[1])], [x0[2]], ls="none", zorder=4, **start_mk)
        if s["lost"]:
            xl = s["xlast"] / g5.R_E
            ax_eq.plot([xl[0]], [xl[1]], **mark(c))
            ax_mer.plot([np.hypot(xl[0], xl[1])], [xl[2]], **mark(c))
            if ax_t is not None and len(s["ts"]):
                ax_t.plot([s["ts"][-1] / tscale], [np.linalg.norm(xl)], **mark(c))

    draw_earth_equatorial(ax_eq)
    draw_earth_meridional(ax_mer)
    ax_eq.set_xlim(-lim, lim)
    ax_eq.set_ylim(-lim, lim)
    ax_eq.set_aspect("equal")
    ax_eq.set_xlabel(r"$x$ [$R_E$]")
    ax_eq.set_ylabel(r"$y$ [$R_E$]")
    ax_eq.set_title("equatorial plane (view from north)", fontsize=10)

    ax_mer.set_xlim(0, lim)
    ax_mer.set_ylim(-zl, zl)
    ax_mer.set_aspect("equal")
    ax_mer.axhline(0, color="0.85", lw=0.5, zorder=0)
    ax_mer.set_xlabel(r"$\rho=\sqrt{x^2+y^2}$ [$R_E$]")
    ax_mer.set_ylabel(r"$z$ [$R_E$]")
    ax_mer.set_title(r"meridional plane, field lines $r = L\cos^2\lambda$", fontsize=10)

    if ax_t is not None:
        ax_t.set_xlabel("t [%s]" % tlab)
        ax_t.set_ylabel(r"$r$ [$R_E$]")
        ax_t.set_title("geocentric distance", fontsize=10)
        ax_t.set_xlim(left=0)
        ax_t.grid(alpha=0.3)
        ax_t.axhline(1.0, color="#08306b", lw=0.6, ls="--")
    return [ax_eq, ax_mer] + ([ax_t] if ax_t is not None else [])


def plot_generic(fig, d, sel, cols, mark, have_traj, field):
    """x-y and x-z (R-z for a tokamak) views, plus energy (or z) against time when useful."""
    allx = np.concatenate([s["pts"] for s in sel], axis=0)
    extent = float(np.max(np.abs(allx))) if len(allx) else 1.0
    span = float(np.max(np.ptp(allx, axis=0))) if len(allx) else 1.0
    lscale, llab = length_unit(max(span, 1e-12) if span > 0 else max(extent, 1e-12))

    toroidal = field == "tokamak"

    def second(x):
        if toroidal:
            return np.hypot(x[..., 0], x[..., 1]), x[..., 2]
        return x[..., 0], x[..., 2]

    # third panel: kinetic energy when it changes, else z for a mirror, else nothing
    third = None
    tmax = 0.0
    if have_traj:
        for s in sel:
            if len(s["ts"]):
                tmax = max(tmax, float(np.nanmax(s["ts"])))
        varies = False
        for s in sel:
            if s["ek"] is not None and len(s["ek"]) > 1:
                e = s["ek"][np.isfinite(s["ek"])]
                if len(e) > 1 and np.ptp(e) > 1e-3 * max(np.max(np.abs(e)), 1e-300):
                    varies = True
        if varies:
            third = "energy"
        elif field == "mirror":
            third = "z"
    npan = 3 if third else 2
    ax1 = fig.add_subplot(1, npan, 1)
    ax2 = fig.add_subplot(1, npan, 2)
    ax3 = fig.add_subplot(1, 3, 3) if third else None
    tscale, tlab = time_unit(tmax)
    escale, elab = 1.0, "J"
    if third == "energy":
        emax = max(float(np.nanmax(s["ek"])) for s in sel if s["ek"] is not None and len(s["ek"]))
        escale, elab = energy_unit(emax)

    for s, c in zip(sel, cols):
        x = s["xs"] / lscale
        a2, b2 = second(x)
        if s["traj"]:
            ax1.plot(x[:, 0], x[:, 1], color=c, lw=0.7, alpha=0.9, zorder=3)
            ax2.plot(a2, b2, color=c, lw=0.7, alpha=0.9, zorder=3)
            if s["fo"] is not None and s["fo"].any():
                ax1.plot(x[s["fo"], 0], x[s["fo"], 1], **FO_MARK)
                ax2.plot(a2[s["fo"]], b2[s["fo"]], **FO_MARK)
            if third == "energy" and s["ek"] is not None:
                ax3.plot(s["ts"] / tscale, s["ek"] / escale, color=c, lw=0.8)
            elif third == "z":
                ax3.plot(s["ts"] / tscale, x[:, 2], color=c, lw=0.8)
            start_mk = dict(marker="o", ms=3.5, mfc=c, mec="k", mew=0.4)
        else:
            start_mk = dict(marker="o", ms=5, mfc="none", mec=c, mew=1.0)
            if not s["lost"]:
                xf = s["xf"] / lscale
                af, bf = second(xf)
                ax1.plot([xf[0]], [xf[1]], ls="none", marker="o", ms=4, color=c, zorder=4)
                ax2.plot([af], [bf], ls="none", marker="o", ms=4, color=c, zorder=4)
        x0 = s["x0"] / lscale
        a0, b0 = second(x0)
        ax1.plot([x0[0]], [x0[1]], ls="none", zorder=4, **start_mk)
        ax2.plot([a0], [b0], ls="none", zorder=4, **start_mk)
        if s["lost"]:
            xl = s["xlast"] / lscale
            al, bl = second(xl)
            ax1.plot([xl[0]], [xl[1]], **mark(c))
            ax2.plot([al], [bl], **mark(c))
            if ax3 is not None and len(s["ts"]):
                yl = (s["ek"][-1] / escale if third == "energy" and s["ek"] is not None
                      else xl[2])
                ax3.plot([s["ts"][-1] / tscale], [yl], **mark(c))

    for ax in (ax1, ax2):
        ax.grid(alpha=0.3)
        xl, yl = ax.get_xlim(), ax.get_ylim()
        wx, wy = xl[1] - xl[0], yl[1] - yl[0]
        if wx > 0 and wy > 0 and 1 / 3 < wx / wy < 3:
            ax.set_aspect("equal", adjustable="datalim")
    ax1.set_xlabel("x [%s]" % llab)
    ax1.set_ylabel("y [%s]" % llab)
    ax1.set_title("x\u2013y view", fontsize=10)
    if toroidal:
        ax2.set_xlabel("R = $\\sqrt{x^2+y^2}$ [%s]" % llab)
        ax2.set_title("poloidal (R\u2013z) view", fontsize=10)
    else:
        ax2.set_xlabel("x [%s]" % llab)
        ax2.set_title("x\u2013z view", fontsize=10)
    ax2.set_ylabel("z [%s]" % llab)
    if ax3 is not None:
        ax3.grid(alpha=0.3)
        ax3.set_xlabel("t [%s]" % tlab)
        if third == "energy":
            ax3.set_ylabel("kinetic energy [%s]" % elab)
            ax3.set_title("kinetic energy", fontsize=10)
        else:
            ax3.set_ylabel("z [%s]" % llab)
            ax3.set_title("position along the axis", fontsize=10)
    return [a for a in (ax1, ax2, ax3) if a is not None]


def make_plot(d, out_png, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    meta, p, rows, traj = d["meta"], d["p"], d["rows"], d["traj"]
    names = p["status_names"]
    have_traj = traj is not None

    # one record per drawn particle
    sel = []
    for k, i in enumerate(rows):
        tr = traj[k] if have_traj else None
        used_traj = tr is not None and len(tr["x"]) > 0
        xs = tr["x"] if used_traj else np.zeros((0, 3))
        ts = tr["t"] if used_traj else np.zeros(0)
        ek = None
        if used_traj and tr["u"] is not None:
            ek = g5.kinetic_energy(tr["u"], p["mass"][i])
        status = int(p["status"][i])
        xf = p["x"][i]
        xlast = xs[-1] if used_traj else xf
        if not np.all(np.isfinite(xlast)):
            xlast = xs[-1] if len(xs) else p["x0"][i]
        pts = np.concatenate([xs, p["x0"][i][None, :], xlast[None, :], xf[None, :]], axis=0)
        pts = pts[np.all(np.isfinite(pts), axis=1)]          # everything that sets the limits
        # hybrid runs: the samples pushed as full orbits, marked on the orbit
        fo = tr["mode"] == 1 if used_traj and tr.get("mode") is not None else None
        sel.append({"row": i, "pts": pts, "species": p["species"][i], "xs": xs, "ts": ts, "ek": ek,
                    "fo": fo,
                    "traj": used_traj, "x0": p["x0"][i], "xf": xf, "xlast": xlast,
                    "status": status, "lost": status != g5.ALIVE})

    species_rows = [s["species"] for s in sel]
    cmaps = species_styles(species_rows)
    cols = particle_colours(species_rows, cmaps)

    def mark(c):
        return dict(ls="none", marker="X", ms=9, mfc=c, mec="k", mew=0.8, zorder=7)

    field = str(meta.get("field", "")).lower()
    dipole = is_dipole(meta, p)
    npan = 3 if have_traj else 2
    fig = plt.figure(figsize=(5.2 * npan, 4.4 if have_traj else 5.4))
    if dipole:
        plot_dipole(fig, d, sel, cols, mark, have_traj)
    else:
        plot_generic(fig, d, sel, cols, mark, have_traj, field)

    # legend: species (with counts and energies), start marker, lost marker(s)
    handles = []
    ek0_all = g5.kinetic_energy(p["u0"], p["mass"])
    for s, cmap in cmaps.items():
        shown = sum(1 for q in sel if q["species"] == s)
        total = int(np.sum(p["species"] == s))
        erange = energy_range_label(ek0_all[[q["row"] for q in sel if q["species"] == s]])
        lab = "%s: %d of %d shown" % (s, shown, total) if shown != total else "%s: %d" % (s, shown)
        if erange:
            lab += ", %s" % erange
        handles.append(Line2D([], [], color=cmap(0.75), lw=2, label=lab))
    if have_traj:
        handles.append(Line2D([], [], ls="none", marker="o", ms=4, mfc="0.6", mec="k", mew=0.4,
                              label="start"))
    else:
        handles.append(Line2D([], [], ls="none", marker="o", ms=5, mfc="none", mec="0.3",
                              label="initial position"))
        handles.append(Line2D([], [], ls="none", marker="o", ms=4, color="0.3",
                              label="final position"))
    lost = {}
    for s in sel:
        if s["lost"]:
            nm = g5.status_name(s["status"], names)
            lost[nm] = lost.get(nm, 0) + 1
    if lost:
        lab = "ended " + ", ".join("%s (%d)" % (k, v) for k, v in sorted(lost.items()))
        handles.append(Line2D([], [], ls="none", marker="X", ms=8, mfc="0.6", mec="k", mew=0.8,
                              label=lab))
    if any(s["fo"] is not None and s["fo"].any() for s in sel):
        handles.append(Line2D([], [], label="full orbit (hybrid)", **FO_MARK))
    ncol = min(len(handles), 5 if npan == 3 else 3)
    nrow = -(-len(handles) // ncol)
    fig.legend(handles=handles, loc="lower center", ncol=ncol, fontsize=9, frameon=False)

    # title
    scene = meta.get("scene") or meta.get("run_file_name") or os.path.basename(path)
    method = meta.get("method", "?")
    # /particles/dt: each particle's step (one per population)
    with h5py.File(path, "r") as fdt:
        pdt = np.asarray(fdt["particles/dt"][()], dtype=float) if "particles/dt" in fdt else np.array([])
    pdt = pdt[np.isfinite(pdt) & (pdt > 0)]
    if pdt.size and pdt.min() == pdt.max():
        dts = "dt = " + si(pdt[0], "s")
    elif pdt.size:
        dts = "dt = %s .. %s" % (si(pdt.min(), "s"), si(pdt.max(), "s"))
    else:
        dts = "dt not recorded"
    line1 = "%s \u2014 %s field, %s, %s" % (scene, meta.get("field", "?"), method, dts)
    tot_lost = int(np.sum(p["status"] != g5.ALIVE))
    line2 = "%d of %d particles shown" % (len(sel), d["n"])
    if tot_lost:
        line2 += " (%d of %d ended not ALIVE)" % (tot_lost, d["n"])
    if not have_traj:
        line2 += " \u2014 no /trajectories in file: initial and final positions only"
    # a plain figure text, not suptitle: tight_layout then keeps exactly the room we give it
    height = fig.get_size_inches()[1]
    fig.text(0.5, 1 - 0.08 / height, line1 + "\n" + line2, ha="center", va="top", fontsize=11)
    fig.tight_layout(rect=(0, (0.1 + 0.25 * nrow) / height, 1, 1 - 0.68 / height))
    foot = "gcpush %s (%s)" % (meta.get("gcpush_version", "?"), meta.get("git_hash", "?"))
    fig.text(0.995, 0.005, foot, ha="right", va="bottom", fontsize=6, color="0.5")
    # write next to the target and rename, so a failure never leaves a half-written PNG
    base, ext = os.path.splitext(out_png)
    fmt = ext[1:].lower() if ext[1:].lower() in ("png", "pdf", "svg") else "png"
    tmp = os.path.join(os.path.dirname(out_png) or ".",
                       ".%s.%d.tmp" % (os.path.basename(out_png), os.getpid()))
    try:
        fig.savefig(tmp, dpi=150, format=fmt)
        os.replace(tmp, out_png)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    finally:
        plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(prog="plot_orbits.py",
                                 description="Plot particle orbits from a gcpush HDF5 output file.")
    ap.add_argument("file", metavar="OUT.h5", help="gcpush output file")
    ap.add_argument("-o", "--output", metavar="OUT.png",
                    help="PNG to write (default: OUT_orbits.png next to the input)")
    ap.add_argument("--max", type=int, default=20, metavar="N",
                    help="draw at most N particles, spread evenly over the ensemble and species "
                         "(default 20)")
    ap.add_argument("--ids", metavar="ID,ID,...",
                    help="draw exactly these particle ids (comma list; a-b ranges allowed)")
    a = ap.parse_args(argv)
    if a.max < 1:
        raise g5.GcpushError("--max must be at least 1")
    ids = parse_ids(a.ids) if a.ids is not None else None
    out = a.output or os.path.splitext(a.file)[0] + "_orbits.png"
    outdir = os.path.dirname(out) or "."
    if not os.path.isdir(outdir):
        raise g5.GcpushError("cannot write %s: no directory %s" % (out, outdir))
    d = collect(a.file, a.max, ids)
    make_plot(d, out, a.file)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(g5.main_guard(PROG, main))
