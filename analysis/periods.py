#!/usr/bin/python3
"""Measured bounce and drift periods against dipole guiding-centre theory, over the ensemble.

    periods.py OUT.h5 [-o OUT.png]

Measured: /invariants/bounce/period and /invariants/drift/period (mean per particle).
Theory (pure dipole, computed here independently of the C code), from each particle's initial
guiding centre (first-order: X = x - b x p/(qB)), its L = r/(R_E cos^2 lat) and equatorial pitch
angle sin^2 a_eq = sin^2 a B_eq/B(X):

    T_b = 4 L R_E / v  T(y),   T(y) = int_0^lm cos l sqrt(1 + 3 sin^2 l) / sqrt(1 - y^2 b(l)) dl
    T_d = 2 pi / <w>,  <w> the bounce average (weight ds / v_par) of the azimuthal rate of the
          gradient-curvature drift  v_d = gamma m (v_par^2 + v_perp^2/2) (B x grad B) / (q B^3)

(Schulz & Lanzerotti 1974, ch. 1), b(l) = sqrt(1 + 3 sin^2 l)/cos^6 l.  Quadrature: l = lm sin(s),
Gauss-Legendre in s, which removes the inverse square root at the mirror point.

stdout: per species, the number of particles and the median, 95th percentile and worst relative
difference |T/T_theory - 1| of each period.  The PNG plots measured against theory.
"""

import argparse
import os
import sys

sys.dont_write_bytecode = True
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import numpy as np  # noqa: E402

import gcpush_h5 as g5  # noqa: E402

B0_EARTH = 3.12e-5


def dipole_B(x, B0):
    """B [T] of the dipole with moment along -z (fields/dipole.c), x (..., 3)."""
    c = B0 * g5.R_E ** 3
    r2 = np.sum(x * x, axis=-1)
    c5 = c / (r2 * r2 * np.sqrt(r2))
    z = x[..., 2]
    return np.stack([-3 * c5 * z * x[..., 0], -3 * c5 * z * x[..., 1], c5 * (r2 - 3 * z * z)], -1)


def bratio(l):
    return np.sqrt(1 + 3 * np.sin(l) ** 2) / np.cos(l) ** 6


def mirror_lat(y):
    lo, hi = 0.0, 0.5 * np.pi - 1e-12
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if y * y * bratio(mid) < 1:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


_S, _W = np.polynomial.legendre.leggauss(400)
_S = 0.25 * np.pi * (_S + 1)           # s in (0, pi/2)
_W = 0.25 * np.pi * _W


def theory(L, y, v, gm, q, B0):
    """(T_b, T_d) [s] of a particle at L with y = sin a_eq, speed v, gamma m, charge q."""
    lm = mirror_lat(y)
    l = lm * np.sin(_S)
    dl = lm * np.cos(_S) * _W                    # dl = lm cos(s) ds
    b = bratio(l)
    w = 1 - y * y * b
    # 1/sqrt(w) ~ 1/sqrt(lm - l) ~ 1/cos(s): times cos(s) from dl, finite
    wb = np.cos(l) * np.sqrt(1 + 3 * np.sin(l) ** 2) / np.sqrt(np.maximum(w, 1e-300))
    Ty = np.sum(wb * dl)
    Tb = 4 * L * g5.R_E / v * Ty
    # drift: grad|B| by central differences of the analytic |B| (relative step 1e-6)
    r = L * g5.R_E * np.cos(l) ** 2
    x = np.stack([r * np.cos(l), np.zeros_like(l), r * np.sin(l)], -1)
    B = dipole_B(x, B0)
    Bm = np.linalg.norm(B, axis=-1)
    gB = np.zeros_like(x)
    for j in range(3):
        h = 1e-6 * r
        d = np.zeros_like(x)
        d[:, j] = h
        gB[:, j] = (np.linalg.norm(dipole_B(x + d, B0), axis=-1)
                    - np.linalg.norm(dipole_B(x - d, B0), axis=-1)) / (2 * h)
    Beq = B0 / L ** 3
    vperp2 = v * v * y * y * Bm / Beq
    vpar2 = np.maximum(v * v - vperp2, 0)
    cross_y = B[:, 2] * gB[:, 0] - B[:, 0] * gB[:, 2]
    vd = gm * (vpar2 + 0.5 * vperp2) * cross_y / (q * Bm ** 3)
    wd = vd / (r * np.cos(l))
    W = np.sum(wd * wb * dl)
    Td = 2 * np.pi * Ty / abs(W)
    return Tb, Td


def initial_gc(p, B0):
    """L, y = sin a_eq, v, gamma m per particle from the initial full-orbit state."""
    x, u, m, q = p["x0"], p["u0"], p["mass"], p["charge"]
    pm = m[:, None] * u
    B = dipole_B(x, B0)
    b = B / np.linalg.norm(B, axis=-1)[:, None]
    X = x - np.cross(b, pm) / (q * np.linalg.norm(B, axis=-1))[:, None]
    BX = dipole_B(X, B0)
    BXm = np.linalg.norm(BX, axis=-1)
    ppar = np.sum(pm * BX, -1) / BXm
    p2 = np.sum(pm * pm, -1)
    r = np.linalg.norm(X, axis=-1)
    L = r / (g5.R_E * (1 - (X[:, 2] / r) ** 2))
    y2 = (1 - ppar * ppar / p2) * (B0 / L ** 3) / BXm
    gm = np.sqrt(m * m + p2 / g5.C_LIGHT ** 2)
    return L, np.sqrt(np.clip(y2, 0, 1)), np.sqrt(p2) / gm, gm


def analyse(path):
    with g5.open_gcpush(path) as f:
        a = g5.attrs(f)
        p = g5.read_particles(f)
        bounce = g5.read_table(f, "invariants/bounce")
        drift = g5.read_table(f, "invariants/drift")
    if a.get("field") != "dipole":
        raise g5.GcpushError("%s: field '%s': the theory here is the dipole's" % (path, a.get("field")))
    if bounce is None and drift is None:
        raise g5.GcpushError("%s: no /invariants/bounce or /invariants/drift "
                             "([diagnostics] events = bounce drift)" % path)
    B0 = B0_EARTH
    run = str(a.get("run_file", ""))
    for line in run.splitlines():
        w = line.split("#")[0].split()
        if len(w) >= 4 and w[0] == "B0" and w[1] == "=" and w[3] == "T":
            B0 = float(w[2])
    L, y, v, gm = initial_gc(p, B0)
    row = {int(i): k for k, i in enumerate(p["id"])}
    out = []   # (species, which, ids, measured, theory)
    for which, tab in (("bounce", bounce), ("drift", drift)):
        if tab is None or len(tab["id"]) == 0:
            continue
        ids = np.unique(tab["id"])
        meas = np.array([tab["period"][tab["id"] == i].mean() for i in ids])
        th = []
        for i in ids:
            k = row[int(i)]
            tb, td = theory(L[k], y[k], v[k], gm[k], p["charge"][k], B0)
            th.append(tb if which == "bounce" else td)
        th = np.array(th)
        for sp in sorted(set(p["species"].tolist())):
            sel = np.array([p["species"][row[int(i)]] == sp for i in ids])
            if sel.any():
                out.append((sp, which, ids[sel], meas[sel], th[sel], L[[row[int(i)] for i in ids[sel]]]))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("file")
    ap.add_argument("-o", "--output", help="PNG (default: FILE with .periods.png)")
    args = ap.parse_args()
    out = analyse(args.file)
    print("%-10s %-7s %6s %10s %10s %10s %8s" % ("species", "period", "n", "median", "p95", "worst",
                                                "worst_id"))
    for sp, which, ids, meas, th, L in out:
        e = np.abs(meas / th - 1)
        k = int(np.argmax(e))
        print("%-10s %-7s %6d %10.3e %10.3e %10.3e %8d" % (sp, which, len(ids), np.median(e),
                                                           np.percentile(e, 95), e[k], ids[k]))
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    for ax, which in zip(axes, ("bounce", "drift")):
        for sp, w, ids, meas, th, L in out:
            if w == which:
                ax.loglog(th, meas, "o", ms=4, label=sp)
        lim = ax.get_xlim()
        ax.plot(lim, lim, "k-", lw=0.6)
        ax.set_xlabel("dipole theory %s period [s]" % which)
        ax.set_ylabel("measured [s]")
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
    fig.tight_layout()
    png = args.output or os.path.splitext(args.file)[0] + ".periods.png"
    fig.savefig(png, dpi=90)
    print("plot: %s" % png)
    return 0


if __name__ == "__main__":
    sys.exit(g5.main_guard("periods.py", main))
