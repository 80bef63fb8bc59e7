r"""Bifurcation diagram of the paper's disk test: growth ε on the x-axis, mode shapes at the branch points.

The disk of theory §1.6 (free disk, inner circle r < R2 grown by the linear stretch 1 + ε and
thinned to h/(1 + ε)²) is followed exactly as the ``disk-wrinkles`` validation case does
(:func:`femshell.validation.disk.branches.follow`): pseudo-arclength continuation of the flat
state in ε with the inertia of the Hessian at every point, the loss of stability bisected on the
inertia, branch switching along the critical mode, secondary switches where a followed branch
loses stability. This script additionally continues the flat branch past its first instability
(unstable, dashed) until that continuation stops (h = 2, R2 = 3: at ε = 0.43, where its tangent
turns at a further branch point) and draws

* left: the largest deflection |w| (best-fit plane removed) against ε, solid where the state is a
  minimum (no negative eigenvalue), dashed where it is not, branch points as circles labelled by
  the azimuthal wavenumber n of their critical mode and the number of eigenvalues that cross, a fold
  where the last branch turned back and the shell snapped (h = 0.25) as a square;
* right: the critical mode of each branch point and fold (its out-of-plane part, seen from above,
  r ≤ 2 R2) and the state reached at ε = 0.5.

    python validation/disk_bifurcation_diagram.py [--h 2] [--R2 3] [--resolution 8] [--law svk]
        [--out docs/images/disk-bifurcation-diagram.png]

It also writes the branches as CSV next to the picture (NAME.csv: branch, ε, |w|max, wrinkles,
negative eigenvalues); h = 2, R2 = 3 at resolution 8 takes minutes.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np

from femshell.io import check_writable_dir
from femshell.validation.disk import EPS_END, _follow_branch, follow


def branch_points(branch):
    """(ε, |w|max, stable) of the regular points of a branch."""
    rows = [r for r in branch.rows if not r["special"]]
    return (np.array([r["parameter"] for r in rows]), np.array([r["w_max"] for r in rows]),
            np.array([r["n_negative"] == 0 for r in rows]))


def draw(result, flat, path, title):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = result["disk"]
    sps, folds = result["switch_points"], result["folds"]
    n_panels = len(sps) + len(folds) + 1
    fig = plt.figure(figsize=(5 + 2.6 * n_panels, 4.8))
    gs = fig.add_gridspec(1, 2, width_ratios=[5, 2.6 * n_panels])
    ax = fig.add_subplot(gs[0])
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, br in enumerate([flat] + result["branches"][1:]):
        eps, w, stable = branch_points(br)
        col = colours[k % len(colours)]
        # each point's stability styles the segment that ends at it, so the two runs meet
        unstable = ~stable
        unstable[:-1] |= unstable[1:]
        for mask, style in ((stable, "-"), (unstable, "--")):
            if not mask.any():
                continue
            # draw each stability run as its own segment (a masked array breaks the line)
            ax.plot(eps, np.ma.masked_where(~mask, w / d.h), style, color=col,
                    label=f"{br.label} ({'stable' if style == '-' else 'unstable'})")
    for k, sp in enumerate(sps):
        n = d.mode_wavenumber(sp.modes)
        ax.plot(sp.parameter, 0.0 if k == 0 else np.interp(sp.parameter, *branch_points(result["branches"][k])[:2])
                / d.h, "ko", mfc="w")
        ax.annotate(f"BP{k + 1}: n={n}, {sp.multiplicity} mode(s)", (sp.parameter, 0.0), textcoords="offset points",
                    xytext=(4, 8 + 12 * k), fontsize=8)
    for k, sp in enumerate(folds):      # where the last branch turned back and the shell snapped
        ax.plot(sp.parameter, branch_points(result["branches"][-1])[1][-1] / d.h, "ks", mfc="w")
        ax.annotate(f"LP{k + 1}: n={d.mode_wavenumber(sp.modes)}, snap", (sp.parameter, 0.0),
                    textcoords="offset points", xytext=(4, 8 + 12 * (len(sps) + k)), fontsize=8)
    ax.plot(EPS_END, np.abs(result["w"]).max() / d.h, "k*", ms=10,
            label=f"state at ε = {EPS_END} ({result['count']} wrinkles{', relaxed' if result['relaxed'] else ''})")
    ax.set_xlabel("growth ε (linear stretch 1 + ε inside r < R2)")
    ax.set_ylabel("max |w| / h")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=7, loc="upper left")
    ax.grid(alpha=0.3)
    sub = gs[1].subgridspec(1, n_panels)
    x, y = d.points[:, 0], d.points[:, 1]
    near = np.hypot(x, y)[d.triangles].max(axis=1) < 2 * d.R2
    tri = d.triangles[near]
    fields = [(f"BP{k + 1} mode, ε = {sp.parameter:.4g}", d.mode_deflection(sp.modes[:, 0]))
              for k, sp in enumerate(sps)]
    fields += [(f"LP{k + 1} mode, ε = {sp.parameter:.4g}", d.mode_deflection(sp.modes[:, 0])) for k, sp in enumerate(folds)]
    fields.append((f"w at ε = {EPS_END}", result["w"]))
    for k, (name, z) in enumerate(fields):
        a = fig.add_subplot(sub[k])
        lim = max(float(np.abs(z).max()), 1e-30)
        a.tripcolor(x, y, tri, z, shading="gouraud", cmap="RdBu_r", vmin=-lim, vmax=lim)
        t = np.linspace(0, 2 * np.pi, 200)
        a.plot(d.R2 * np.cos(t), d.R2 * np.sin(t), "k:", lw=0.8)
        a.set_xlim(-2 * d.R2, 2 * d.R2)
        a.set_ylim(-2 * d.R2, 2 * d.R2)
        a.set_aspect("equal")
        a.set_axis_off()
        a.set_title(name, fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--h", type=float, default=2.0)
    ap.add_argument("--R2", type=float, default=3.0)
    ap.add_argument("--resolution", type=int, default=8, help="edges per R2 along the grown circle")
    ap.add_argument("--law", choices=("svk", "neo-hookean"), default="svk",
                    help="membrane law (the disk-wrinkles case's full level runs neo-hookean)")
    ap.add_argument("--out", type=Path, default=Path("docs/images/disk-bifurcation-diagram.png"),
                    help="picture, with its .csv beside it (default: the committed "
                         "docs/images/disk-bifurcation-diagram.png, relative to the current directory; replaced)")
    args = ap.parse_args(argv)
    if args.resolution < 2 or args.h <= 0 or args.R2 <= 0:
        ap.error("--resolution needs an integer >= 2 (edges per R2), --h and --R2 numbers > 0")
    if args.out.suffix.lower() not in (".png", ".pdf", ".svg"):     # before the continuation, not after it
        ap.error(f"--out must end in .png, .pdf or .svg (a picture), got {args.out}")
    try:
        check_writable_dir(args.out.parent, "--out's directory")    # before the continuation, not after
    except ValueError as exc:
        sys.exit(str(exc))
    result = follow(args.h, args.R2, args.resolution, log=print, law=args.law)
    d = result["disk"]
    flat = _follow_branch(d, None, callback=None, max_steps=200)       # past the first instability
    print(f"flat branch continued past its instability: {flat.status} ({flat.message})")
    draw(result, flat, args.out,
         f"disk h = {args.h:g}, R2 = {args.R2:g}, {d.n_vertices} vertices (R2/{args.resolution} at the circle)")
    with open(args.out.with_suffix(".csv"), "w", newline="") as f:
        out = csv.writer(f)
        out.writerow(["branch", "eps", "w_max", "wrinkles", "n_negative"])
        for br in [flat] + result["branches"][1:]:
            for r in br.rows:
                if not r["special"]:
                    out.writerow([br.label, f"{r['parameter']:.6g}", f"{r['w_max']:.6g}", r["wrinkles"],
                                  r["n_negative"]])
    print(f"wrote {args.out} and {args.out.with_suffix('.csv')}")


if __name__ == "__main__":
    main()
