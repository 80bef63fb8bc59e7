"""Registry, result rows, JSON and plot output of the validation cases."""

from __future__ import annotations

import importlib
import inspect
import json
import math
import os
import time
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from pathlib import Path

from ..io import atomic_write_text

# command-line name -> module in this package; a case is listed here once it exists
CASES = {
    "patch-tests": "patch_tests",
    "cantilever-end-moment": "cantilever_end_moment",
    "cantilever-end-shear": "cantilever_end_shear",
    "scordelis-lo": "scordelis_lo",
    "pinched-cylinder": "pinched_cylinder",
    "pinched-hemisphere": "pinched_hemisphere",
    "clamped-plate-pressure": "clamped_plate_pressure",
    "linear-buckling-plates": "linear_buckling_plates",
    "clamped-plate-growth-buckling": "clamped_plate_growth_buckling",
    "euler-strip": "euler_strip",
    "shallow-arch-snap": "shallow_arch_snap",
    "disk-wrinkles": "disk_wrinkles",
    "wrinkle-scaling": "wrinkle_scaling",
    "sphere-patterns": "sphere_patterns",
    "spot-scaling": "spot_scaling",
    "laplace-beltrami-sphere": "laplace_beltrami_sphere",
    "curvature": "curvature",
    "thin-shell-locking": "thin_shell_locking",
    "poor-meshes": "poor_meshes",
    "extremes": "extremes",
    "sphere-pressure-buckling": "sphere_pressure_buckling",
    "cylinder-axial-buckling": "cylinder_axial_buckling",
    "uniform-sphere-pattern": "uniform_sphere_pattern",
}
LEVELS = ("quick", "full")


@dataclass
class Row:
    """One validated quantity; ``reference`` and ``tolerance`` may be None (reported only)."""

    quantity: str
    value: float
    reference: float | None = None
    tolerance: float | None = None
    n_vertices: int = 0
    wall_s: float = 0.0
    rel_error: float | None = None
    passed: bool | None = None

    def __post_init__(self):
        self.value = float(self.value)
        self.n_vertices = int(self.n_vertices or 0)       # None (e.g. read back from a JSON): not given
        self.wall_s = float(self.wall_s or 0.0)
        if self.tolerance is not None:
            self.tolerance = float(self.tolerance)
            if not (math.isfinite(self.tolerance) and self.tolerance >= 0):
                raise ValueError(f"row {self.quantity!r}: tolerance must be a finite number >= 0 or None, "
                                 f"got {self.tolerance}")
        if self.reference is not None:
            ref = float(self.reference)
            self.reference = ref
            if not math.isfinite(self.value):
                self.rel_error = None
            else:
                scale = abs(ref) if ref != 0 else 1.0  # absolute error against a zero reference
                self.rel_error = abs(self.value - ref) / scale
        if self.tolerance is not None:
            self.passed = bool(self.rel_error is not None and self.rel_error <= self.tolerance)


#: a row reported without a tolerance whose value is further than this from its reference is named
#: beside the verdict, so that "passed" is not read as covering it
REPORTED_OFF = 0.1


def verdict(rows) -> str:
    """'passed' or 'FAILED' with what it covers: the toleranced rows that passed, and the rows reported
    without a tolerance that are more than REPORTED_OFF from their reference (rows or their JSON dicts).

    >>> verdict([Row("a", 1.0, 1.0, 0.1), Row("n", 0.0, 8.0)])
    'passed (1 of 1 toleranced rows; 1 of 1 rows reported without a tolerance are more than 10 % from their reference: n)'
    """
    rows = [asdict(r) if isinstance(r, Row) else r for r in rows]
    checked = [r for r in rows if r["tolerance"] is not None]
    ok = all(r["passed"] for r in checked)
    text = f"{'passed' if ok else 'FAILED'} ({sum(r['passed'] is True for r in checked)} of {len(checked)} toleranced rows"
    reported = [r for r in rows if r["tolerance"] is None and r["reference"] is not None]
    off = [r["quantity"] for r in reported if r["rel_error"] is None or r["rel_error"] > REPORTED_OFF]
    if off:
        names = "; ".join(off[:3]) + (f"; … ({len(off) - 3} more)" if len(off) > 3 else "")
        text += (f"; {len(off)} of {len(reported)} rows reported without a tolerance are more than "
                 f"{100 * REPORTED_OFF:g} % from their reference: {names}")
    return text + ")"


def short_reason(exc, limit=100) -> str:
    """The first clause of an error message, cut at a word (for a row's quantity name)."""
    text = str(exc).split(";")[0].strip()
    if len(text) <= limit:
        return text
    return text[:limit].rsplit(" ", 1)[0] + " …"


@contextmanager
def timed():
    """``with timed() as t: ...`` then ``t()`` is the elapsed wall time in seconds."""
    t0 = time.perf_counter()
    box = [None]
    yield lambda: box[0] if box[0] is not None else time.perf_counter() - t0
    box[0] = time.perf_counter() - t0


def list_cases() -> dict:
    """name -> one-line description of every available case."""
    out = {}
    for name in CASES:
        mod = _load(name)
        if mod is not None:
            out[name] = mod.DESCRIPTION
    return out


def _load(name):
    try:
        return importlib.import_module(f"{__package__}.{CASES[name]}")
    except ModuleNotFoundError as exc:
        if exc.name == f"{__package__}.{CASES[name]}":
            return None
        raise


def run_case(name: str, level: str = "quick", out_dir: str | os.PathLike = "validation-out", log=print) -> bool:
    """Run one case, write NAME.json and NAME.png into ``out_dir``; True if every toleranced row passed."""
    if name not in CASES or _load(name) is None:
        raise KeyError(f"unknown validation case '{name}'; available: {', '.join(list_cases())}")
    if level not in LEVELS:
        raise ValueError(f"level must be one of {LEVELS}, got '{level}'")
    mod = _load(name)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    # cases with long full levels keep checkpoints next to their results and report progress
    accepts = inspect.signature(mod.run).parameters
    extra = {k: v for k, v in (("out_dir", out), ("log", log)) if k in accepts}
    rows = mod.run(level, **extra)
    total = time.perf_counter() - t0
    for r in rows:
        status = "" if r.passed is None else ("PASS" if r.passed else "FAIL")
        ref = "" if r.reference is None else f" ref {r.reference:.6g}"
        err = "" if r.rel_error is None else f" err {r.rel_error:.2e}"
        tol = "" if r.tolerance is None else f" tol {r.tolerance:.2g}"
        log(f"  {r.quantity:<48} {r.value:.6g}{ref}{err}{tol}  n={r.n_vertices} {r.wall_s:.2f}s {status}")
    doc = {"case": name, "level": level, "source": mod.SOURCE, "description": mod.DESCRIPTION,
           "total_wall_s": total, "rows": [_row_json(r) for r in rows]}
    atomic_write_text(out / f"{name}.json", json.dumps(doc, indent=1))
    _plot(mod, rows, out / f"{name}.png", f"{name} ({level})")
    ok = all(r.passed for r in rows if r.tolerance is not None)
    log(f"{name}: {verdict(rows)}, {total:.1f} s")
    return ok


def _row_json(r: Row) -> dict:
    d = asdict(r)
    for k in ("value", "reference", "rel_error", "wall_s"):
        if isinstance(d[k], float) and not math.isfinite(d[k]):
            d[k] = None  # never NaN in a result file
    return {k: d[k] for k in ("quantity", "value", "reference", "rel_error", "tolerance", "passed",
                              "n_vertices", "wall_s")}


def _plot(mod, rows, path: Path, title: str):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if hasattr(mod, "plot"):
        fig = plt.figure(figsize=(10, 4.5))
        mod.plot(rows, fig)
    else:
        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4.5))
        series = {}
        for r in rows:
            if r.rel_error is not None and r.n_vertices > 0:
                series.setdefault(r.quantity.split(" @")[0], []).append(r)
        for q, rs in series.items():
            rs = sorted(rs, key=lambda r: r.n_vertices)
            err = [max(r.rel_error, 1e-16) for r in rs]
            ax1.loglog([r.n_vertices for r in rs], err, "o-", label=q)
            ax2.loglog([max(r.wall_s, 1e-3) for r in rs], err, "o-", label=q)
        ax1.set_xlabel("vertices")
        ax2.set_xlabel("wall time [s]")
        for ax in (ax1, ax2):
            ax.set_ylabel("relative error")
            ax.grid(True, which="both", alpha=0.3)
        if series:
            ax1.legend(fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    tmp = path.with_name(f".{path.stem}.tmp.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    os.replace(tmp, path)
