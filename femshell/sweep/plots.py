"""A sweep's pictures: the phase diagram of the regimes and a contact sheet of the points' top views.

``phase_diagram.png`` — one marker per point over the spec's plot axes x and y ([plot], default the
first two axes of [vary]), its shape and colour the regime (:func:`femshell.analysis.classify_regime`)
and its label N_spots; a point that has not finished is drawn hollow, with the regime of its last state
and the time reached (grey when it has none yet), and a failed point is a grey cross. The other
axes make the panels, one per combination of their values. ``contact_sheet.png`` — each point's
``pictures/top.png`` (drawn by its run) under its values, in the spec's order.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

from ..analysis import REGIMES
from .spec import MEASURES, short_names, value_text
from .table import POINTS, rows

PHASE = "phase_diagram.png"
SHEET = "contact_sheet.png"
#: (marker, colour) of each regime
STYLE = dict(zip(REGIMES, [("o", "#9e9e9e"), ("s", "#8c564b"), ("^", "#d62728"), ("D", "#9467bd"),
                           ("o", "#1f77b4"), ("h", "#2ca02c")]))


def _positions(values):
    """Plot positions of an axis's values: the numbers themselves, or 0, 1, ... for words."""
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        return {v: float(v) for v in values}, False
    return {v: float(i) for i, v in enumerate(values)}, True


def _axis_values(manifest, axis):
    seen = []
    for p in manifest["points"]:
        v = p["values"][axis]
        if v not in seen:
            seen.append(v)
    return seen


def _phase_panel(ax, manifest, table, x, y, panel):
    names = short_names(manifest["axes"])
    xs, xwords = _positions(_axis_values(manifest, x))
    ys, ywords = _positions(_axis_values(manifest, y)) if y else ({None: 0.0}, True)
    for p, row in zip(manifest["points"], table):
        if any(p["values"][a] != v for a, v in panel.items()):
            continue
        px, py = xs[p["values"][x]], ys[p["values"][y] if y else None]
        regime, status = row.get("regime"), manifest["state"][p["key"]]["status"]
        if status == "failed":
            ax.scatter(px, py, marker="x", s=90, color="0.5", zorder=3)
        elif regime in STYLE:
            marker, colour = STYLE[regime]
            finished = status == "finished"
            ax.scatter(px, py, marker=marker, s=140, zorder=3, linewidths=1.0 if finished else 2.0,
                       facecolor=colour if finished else "none", edgecolor="k" if finished else colour)
            label = "" if row.get("n_spots") is None else str(row["n_spots"])
            if not finished and row.get("t") is not None:
                label += f" (t = {row['t']:.3g})"
            if label:
                ax.annotate(label, (px, py), textcoords="offset points", xytext=(9, 6), fontsize=8)
        else:
            ax.scatter(px, py, marker="o", s=90, color="0.5", facecolor="none", zorder=3)
    ax.set_xticks(list(xs.values()), [value_text(v) for v in xs])
    ax.set_yticks(list(ys.values()), [value_text(v) for v in ys] if y else [""])
    ax.set_xlabel(names[x])
    if y:
        ax.set_ylabel(names[y])
    ax.margins(0.15)
    ax.grid(alpha=0.3)
    if panel:
        ax.set_title(", ".join(f"{names[a]} = {value_text(v)}" for a, v in panel.items()), fontsize=9)


def phase_diagram(out: Path, manifest: dict, table: list) -> Path:
    import matplotlib                  # deferred: matplotlib is a large import
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    from ..io import atomic_path

    x, y = manifest["plot"]
    others = [a for a in manifest["axes"] if a not in (x, y)]
    panels = [dict(zip(others, combo)) for combo in itertools.product(*(_axis_values(manifest, a) for a in others))]
    ncol = min(len(panels), 3)
    nrow = math.ceil(len(panels) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.6 * nrow), squeeze=False)
    for ax, panel in zip(axes.flat, panels):
        _phase_panel(ax, manifest, table, x, y, panel)
    for ax in list(axes.flat)[len(panels):]:
        ax.set_visible(False)
    handles = [Line2D([], [], marker=m, color=c, linestyle="", markeredgecolor="k", markersize=9, label=r)
               for r, (m, c) in STYLE.items()]
    handles += [Line2D([], [], marker="x", color="0.5", linestyle="", markersize=9, label="failed"),
                Line2D([], [], marker="o", color="0.5", markerfacecolor="none", linestyle="", markersize=9,
                       label="not finished (hollow: its regime so far)")]
    fig.suptitle(manifest.get("description") or f"regimes over {', '.join(manifest['axes'])}", fontsize=10)
    fig.tight_layout()
    fig.legend(handles=handles, loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize=8,
               title="regime (label: N_spots)")
    path = Path(out) / PHASE
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png", bbox_inches="tight")
    plt.close(fig)
    return path


def contact_sheet(out: Path, manifest: dict, table: list) -> Path:
    import matplotlib                  # deferred: matplotlib is a large import
    matplotlib.use("Agg")
    import matplotlib.image as mpimg
    import matplotlib.pyplot as plt

    from ..io import atomic_path

    names = short_names(manifest["axes"])
    n = len(manifest["points"])
    ncol = min(n, 5)
    nrow = math.ceil(n / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(2.6 * ncol, 2.9 * nrow), squeeze=False)
    for ax, p, row in zip(axes.flat, manifest["points"], table):
        top = Path(out) / POINTS / p["key"] / "pictures" / "top.png"
        if top.is_file():
            ax.imshow(mpimg.imread(top))
        else:
            ax.text(0.5, 0.5, f"no picture\n({row.get('status')})", ha="center", va="center", fontsize=8,
                    transform=ax.transAxes)
        status = manifest["state"][p["key"]]["status"]
        verdict = row.get("regime") or row.get("status")
        if status not in ("finished", "failed") and row.get("regime") and row.get("t") is not None:
            verdict = f"{row['regime']} so far ({status} at t = {row['t']:.3g})"
        label = "\n".join([", ".join(f"{names[a]}={value_text(v)}" for a, v in p["values"].items()), verdict])
        ax.set_title(label, fontsize=7)
        ax.set_xticks([])
        ax.set_yticks([])
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    fig.tight_layout()
    path = Path(out) / SHEET
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png", bbox_inches="tight")
    plt.close(fig)
    return path


def plot_sweep(out, manifest: dict) -> list:
    """Draw the phase diagram and the contact sheet of the sweep in ``out`` (its ``manifest``); their paths."""
    table = rows(out, {**manifest, "measures": list(MEASURES)})
    return [phase_diagram(Path(out), manifest, table), contact_sheet(Path(out), manifest, table)]
