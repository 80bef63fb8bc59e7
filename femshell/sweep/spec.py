r"""A sweep's specification (``SPEC.toml``): the base scene, the axes varied over it, the points.

::

    description = "the paper's Fig. 2 grid"      # optional, one line
    scene = "default"          # an embedded scene name or a .toml path (relative to this file)
    mode = "product"           # "product" (every combination, default) or "zip" (the i-th of each)
    measures = ["regime", "n_spots", "spot_radius"]   # optional: the table's measure columns (default: all)

    [set]                      # optional: scene keys set at every point (as femshell run --set)
    "solver.t_final" = 100

    [vary]                     # the axes: a dotted scene key and a non-empty list of its values
    "growth.c_star" = [0.05, 0.1, 0.2]
    "shell.thickness" = [1.0, 2.0]

    [plot]                     # optional: the phase diagram's axes (default: the first two of [vary])
    x = "growth.c_star"
    y = "shell.thickness"

:func:`load_spec` checks everything before anything starts: the spec's own keys and types, and the
scene of every point, validated by the code ``femshell run`` uses (:func:`femshell.scene.load_scene`
with the point's values as ``--set`` overrides), so an unknown key, a wrong type or a value out of
the key's range is named with the point it belongs to. Problems are raised together as one
:class:`~femshell.scene.SceneError`, one line each.
"""

from __future__ import annotations

import difflib
import itertools
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..scene import load_scene
from ..scene.text import SceneError, _show, parse_scene

#: the measure columns of the results table, in their order (see :mod:`femshell.sweep.table`)
MEASURES = ("t", "stationary", "regime", "n_spots", "spot_radius", "spacing", "fraction_patterned", "n_ridges",
            "max_c", "max_H", "max_face_angle_deg", "steps", "wall_s", "worker")
SPEC_KEYS = ("description", "scene", "mode", "measures", "set", "vary", "plot")
MODES = ("product", "zip")


@dataclass(frozen=True)
class Point:
    """One run of a sweep: its directory name ``key`` and its values of the axes ``{dotted key: value}``."""

    index: int
    key: str
    values: dict

    def overrides(self, fixed: dict) -> list:
        """The ``--set`` overrides of this point: the spec's [set], then its own values."""
        return [(k.split("."), v) for k, v in {**fixed, **self.values}.items()]


@dataclass
class SweepSpec:
    """A validated sweep specification (:func:`load_spec`)."""

    label: str
    scene: str                  # the embedded name, or the absolute path of the scene file
    mode: str
    axes: list                  # dotted keys, in the spec's order
    fixed: dict                 # [set]
    measures: list
    plot_axes: tuple            # (x, y or None)
    points: list = field(default_factory=list)
    description: str = ""

    def as_dict(self) -> dict:
        """What identifies the sweep (kept in its manifest; a resume must give the same)."""
        return {"scene": self.scene, "mode": self.mode, "axes": self.axes, "set": self.fixed,
                "points": [{"key": p.key, "values": p.values} for p in self.points]}


def short_names(axes) -> dict:
    """Each axis's name in point keys and plot labels: its last part ("c_star"), or the whole dotted key where
    two axes share a last part."""
    last = [a.split(".")[-1] for a in axes]
    return {a: (s if last.count(s) == 1 else a) for a, s in zip(axes, last)}


def _text(v) -> str:
    """A value in a point's directory name: short, and only letters, digits, '.', '_', '-' and '+'."""
    if isinstance(v, float):
        v = f"{v:.6g}"
    return re.sub(r"[^A-Za-z0-9._+-]+", "-", str(v)) or "x"


def point_key(index: int, values: dict, names: dict) -> str:
    """``003_c_star=0.1_thickness=2``: the point's number (its order in the spec), then its values."""
    return f"{index:03d}_" + "_".join(f"{_text(names[k])}={_text(v)}" for k, v in values.items())


def _check_axes(raw_vary, label, errors) -> dict:
    if not isinstance(raw_vary, dict) or not raw_vary:
        errors.append(f"{label}: [vary] must be a table of at least one axis, e.g. \"growth.c_star\" = [0.05, 0.1]")
        return {}
    axes = {}
    for k, v in raw_vary.items():
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z0-9_]+)+", k):
            errors.append(f"{label}: [vary] \"{k}\" is not a dotted scene key (section.key, e.g. growth.c_star)")
        elif isinstance(v, dict) or not isinstance(v, list):
            errors.append(f"{label}: [vary] \"{k}\" = {_show(v)} must be a list of values, e.g. [{_show(v)}]")
        elif not v:
            errors.append(f"{label}: [vary] \"{k}\" = [] is empty: give at least one value")
        else:
            axes[k] = v
    return axes


def _spec_fields(raw, label, errors):
    """(scene, mode, measures, fixed, description) of the spec's own keys, problems appended to ``errors``."""
    for k in raw:
        if k not in SPEC_KEYS:
            s = difflib.get_close_matches(k, SPEC_KEYS, n=1, cutoff=0.6)
            errors.append(f"{label}: unknown key '{k}'{f'; did you mean {s[0]!r}?' if s else ''} "
                          f"(valid: {', '.join(SPEC_KEYS)})")
    scene = raw.get("scene")
    if not isinstance(scene, str) or not scene.strip():
        errors.append(f"{label}: scene = {_show(scene) if scene is not None else '(missing)'} must name the base "
                      "scene: an embedded scene name (femshell scenes) or a .toml path")
    mode = raw.get("mode", "product")
    if mode not in MODES:
        errors.append(f"{label}: mode = {_show(mode)} must be one of {', '.join(map(_show, MODES))}")
    measures = raw.get("measures", list(MEASURES))
    if not (isinstance(measures, list) and measures and all(isinstance(m, str) for m in measures)):
        errors.append(f"{label}: measures = {_show(measures)} must be a non-empty list of names from: "
                      f"{', '.join(MEASURES)}")
        measures = list(MEASURES)
    for m in measures:
        if m not in MEASURES:
            s = difflib.get_close_matches(m, MEASURES, n=1, cutoff=0.6)
            errors.append(f"{label}: measures: unknown measure {_show(m)}{f'; did you mean {s[0]!r}?' if s else ''} "
                          f"(valid: {', '.join(MEASURES)})")
    fixed = raw.get("set", {})
    if not isinstance(fixed, dict):
        errors.append(f"{label}: [set] must be a table of dotted scene keys and values")
        fixed = {}
    desc = raw.get("description", "")
    if not isinstance(desc, str):
        errors.append(f"{label}: description = {_show(desc)} must be a string")
        desc = ""
    return scene, mode, [m for m in measures if m in MEASURES], fixed, desc


def _plot_axes(raw, axes, label, errors):
    plot = raw.get("plot", {})
    if not isinstance(plot, dict):
        errors.append(f"{label}: [plot] must be a table with x and y (axes of [vary])")
        plot = {}
    for k in plot:
        if k not in ("x", "y"):
            errors.append(f"{label}: [plot] unknown key '{k}' (valid: x, y)")
    names = list(axes)
    x = plot.get("x", names[0] if names else None)
    y = plot.get("y", next((a for a in names if a != x), None))
    for which, a in (("x", x), ("y", y)):
        if a is not None and a not in axes:
            errors.append(f"{label}: [plot] {which} = {_show(a)} is not an axis of [vary] "
                          f"(axes: {', '.join(map(_show, names))})")
    if x is not None and x == y:
        errors.append(f"{label}: [plot] x and y are the same axis {_show(x)}")
    return x, y


def _points(axes: dict, mode, label, errors) -> list:
    names = short_names(list(axes))
    if mode == "zip":
        lengths = {k: len(v) for k, v in axes.items()}
        if len(set(lengths.values())) > 1:
            errors.append(f"{label}: mode = \"zip\" needs lists of one length; [vary] has "
                          + ", ".join(f"{k}: {n}" for k, n in lengths.items()))
            return []
        combos = list(zip(*axes.values()))
    else:
        combos = list(itertools.product(*axes.values()))
    seen = {}
    for i, c in enumerate(combos):
        text = _show(list(c))
        if text in seen:
            errors.append(f"{label}: points {seen[text]} and {i} have the same values ({', '.join(axes)} = "
                          f"{', '.join(map(_show, c))}): give each point once")
            return []
        seen[text] = i
    return [Point(i, point_key(i, dict(zip(axes, c)), names), dict(zip(axes, c))) for i, c in enumerate(combos)]


def _scene_problems(scene, overrides) -> list:
    """The lines of the SceneError of the scene ``scene`` with ``overrides``, without the scene's own label."""
    try:
        load_scene(scene, overrides)
    except SceneError as exc:
        return [re.sub(r"^\S+: ", "", line).replace("--set ", "") for line in exc.errors]
    return []


def _check_points(scene, axes, points, fixed, label, errors):
    """Every axis's values, then every point's scene, validated as ``femshell run`` validates a scene;
    one line per distinct problem, naming the axis and value (or the point) it comes from."""
    fixed_parts = [(k.split("."), v) for k, v in fixed.items()]
    for line in _scene_problems(scene, fixed_parts):
        errors.append(f"{label}: [set]: {line}")
    if errors:
        return
    for axis, values in axes.items():
        seen = set()
        for v in values:
            for line in _scene_problems(scene, fixed_parts + [(axis.split("."), v)]):
                if line not in seen:
                    seen.add(line)
                    errors.append(f"{label}: [vary] \"{axis}\" = {_show(v)}: {line}")
    if errors:
        return
    for p in points:                    # a combination can be wrong where each value alone is not
        for line in _scene_problems(scene, p.overrides(fixed)):
            where = ", ".join(f"{k} = {_show(v)}" for k, v in p.values.items())
            errors.append(f"{label}: point {p.key} ({where}): {line}")
        if len(errors) > 20:
            errors.append(f"{label}: ... (more problems not listed)")
            return


def load_spec(path) -> SweepSpec:
    """The validated :class:`SweepSpec` of the file ``path``; a :class:`SceneError` lists every problem."""
    path = Path(path)
    label = str(path)
    if not path.is_file():
        raise SceneError(f"{label}: no such sweep specification file")
    try:
        raw = parse_scene(path.read_text(encoding="utf-8"), label)
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"{label}: cannot read the sweep specification ({exc})") from None
    errors = []
    scene, mode, measures, fixed, desc = _spec_fields(raw, label, errors)
    axes = _check_axes(raw.get("vary"), label, errors)
    for k in set(fixed) & set(axes):
        errors.append(f"{label}: \"{k}\" is both in [set] and in [vary]: keep it in one")
    plot_axes = _plot_axes(raw, axes, label, errors)
    if errors:                          # the spec itself is wrong: the points would repeat its problems
        raise SceneError(errors)
    if scene.endswith(".toml") or "/" in scene:
        scene = str((path.parent / scene).resolve())
    points = _points(axes, mode, label, errors)
    if not errors:
        _check_points(scene, axes, points, fixed, label, errors)
    if errors:
        raise SceneError(errors)
    return SweepSpec(label, scene, mode, list(axes), fixed, measures, plot_axes, points, desc)


def value_text(v) -> str:
    """A value as the table and the plots show it."""
    if isinstance(v, float) and math.isfinite(v):
        return f"{v:.6g}"
    return str(v)
