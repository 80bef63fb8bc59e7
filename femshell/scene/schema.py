r"""Scene files: the TOML format, its validation and ``--set`` overrides.

A scene is a TOML file (or an embedded scene name, see :func:`femshell.scene.list_scenes`)
with a one-line ``description`` and these sections (all lengths in cell sizes, time
in 1/β, E = 1 by default: design.md section 3)::

    description = "one line shown by `femshell scenes`"

    [mesh]        kind = "sphere" | "hemisphere" | "disk" | "plate" | "strip" | "annulus"
                  | "cylinder" | "file", the generator's arguments (radius, n_vertices or
                  edge_length, ...; see MESH_KEYS) or file = "path" (relative to the scene)
    [material]    E (> 0, default 1), nu (0 <= nu <= 0.5, default 0.5),
                  law = "svk" (design.md's St Venant–Kirchhoff, default) | "neo-hookean"
    [shell]       thickness h (> 0, required), thickness_mode = "volume" | "uniform",
                  natural_curvature = "mesh" (the drawn mesh is stress free) or k0 (1/length)
    [growth]      law = "none" | "uniform" | "inner_region" | "contractility"
                  uniform: strain (s = 1 + strain everywhere)
                  inner_region: strain, inner_radius, transition (the disk test, design.md 1.6)
                  contractility: lam_max, lam_min, lam0, b, c_star (design.md 1.1)
    [chemistry]   D, w, Hs, beta (only with solver.kind = "time")
    [[boundary]]  type = "clamped" | "simply_supported" | "symmetry" | "prescribed", curve = "name"
                  (symmetry: axis, value; prescribed: components, displacement)
    [[loads]]     type = "point_force" | "area_load" | "edge_force" | "dead_pressure"
                  | "follower_pressure" | "edge_moment" (curve, point, force, traction,
                  pressure, moment); all loads are multiplied by the load factor
    [initial]     kind = "spot" | "spots" | "none"; amplitude, width, elongation, pole, direction,
                  distance; spots: layout = "icosahedron" | "random", count, seed
    [solver]      kind = "static" | "continuation" | "time" and its controls (SOLVER_KEYS)
    [output]      every, checkpoint_every, pictures, movie, fields, picture_field, cmap,
                  progress_interval

Validation (:func:`validate`) checks everything before anything is computed and raises
one :class:`SceneError` listing every problem, one line each, naming the key path::

    scene.toml: [material] nu = 0.7 is out of range: 0 <= nu <= 0.5
    scene.toml: [materail] is not a section; did you mean [material]?

Every number is finite, and a non-zero one has a magnitude in ``MAGNITUDE`` = [1e-30, 1e30].

Overrides (``femshell run SCENE --set solver.t_final=5``): ``section.key=value`` where
value is TOML (``3``, ``0.5``, ``true``, ``"text"``, ``[1, 2]``) or a bare word taken as
a string (``--set mesh.kind=disk``); ``boundary.0.curve=left`` reaches into the list of
tables. Setting ``mesh.n_vertices`` drops a ``mesh.edge_length`` of the file and vice
versa, so that a scene can always be made smaller from the command line.
"""

from __future__ import annotations

import copy
import difflib
import math
try:
    import tomllib
except ImportError:  # Python 3.10
    import tomli as tomllib
from dataclasses import dataclass
from pathlib import Path

__all__ = ["SceneError", "Scene", "parse_scene", "validate", "apply_overrides", "parse_override",
           "dump_toml", "MESH_KEYS", "SOLVER_KEYS", "FIELDS", "CURVES", "SECTIONS"]


class SceneError(ValueError):
    """A scene that cannot be run; ``errors`` holds one line per problem."""

    def __init__(self, errors):
        if isinstance(errors, str):
            errors = [errors]
        self.errors = list(errors)
        super().__init__("\n".join(self.errors))


# ----------------------------------------------------------------------------- key specifications

class Spec:
    """One key: its type, range, default and a short description.

    ``kind``: "float", "int", "bool", "str", "path", "vec3" (three numbers), "pair" (two
    numbers), "strlist", "num_or_str" (a number or one of ``choices``).
    ``lo``/``hi`` with ``lo_open``/``hi_open``: the allowed range (closed by default).
    """

    def __init__(self, kind, default=None, doc="", *, lo=None, hi=None, lo_open=False, hi_open=False,
                 choices=None, required=False):
        self.kind, self.default, self.doc = kind, default, doc
        self.lo, self.hi, self.lo_open, self.hi_open = lo, hi, lo_open, hi_open
        self.choices, self.required = choices, required

    def range_text(self, name):
        parts = []
        if self.lo is not None:
            parts.append(f"{_fmt(self.lo)} {'<' if self.lo_open else '<='} ")
        parts.append(name)
        if self.hi is not None:
            parts.append(f" {'<' if self.hi_open else '<='} {_fmt(self.hi)}")
        return "".join(parts)


def _fmt(v):
    if isinstance(v, float) and v.is_integer() and abs(v) < 1e15:
        return str(int(v))
    return repr(v) if isinstance(v, str) else str(v)


def _show(v):
    """A value as it would be written in TOML."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_show(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {_show(x)}" for k, x in v.items()) + "}"
    return str(v)


F, I, B, S = "float", "int", "bool", "str"
#: Magnitude of any non-zero number in a scene: a guard against overflow and underflow in the
#: products of scene numbers that the energies and the chemistry form (E h³ κ², w Hs/β, D dt).
MAGNITUDE = (1e-30, 1e30)
POS = dict(lo=0.0, lo_open=True)
NONNEG = dict(lo=0.0)

RESOLUTION = {
    "n_vertices": Spec(I, None, "target number of vertices", lo=10, hi=5_000_000),
    "edge_length": Spec(F, None, "target edge length", **POS),
    "seed": Spec(I, 0, "gmsh random seed (meshes are deterministic for a seed)", lo=0, hi=2**31 - 1),
}

#: generator arguments per mesh kind (angles in degrees)
MESH_KEYS = {
    "sphere": {"radius": Spec(F, 1.0, "radius", **POS), **RESOLUTION},
    "hemisphere": {"radius": Spec(F, 1.0, "radius", **POS),
                   "hole_angle": Spec(F, None, "polar hole half-angle (degrees)", lo=0.0, hi=90.0,
                                      lo_open=True, hi_open=True), **RESOLUTION},
    "disk": {"radius": Spec(F, 1.0, "radius R1", **POS),
             "inner_radius": Spec(F, None, "conforming inner circle R2", **POS),
             "inner_edge_length": Spec(F, None, "edge length near the inner circle", **POS),
             "refine_inside": Spec(B, False, "inner_edge_length over the whole inner disk, not only near the circle"),
             **RESOLUTION},
    "plate": {"lx": Spec(F, 1.0, "x side", **POS), "ly": Spec(F, 1.0, "y side", **POS),
              "structured": Spec(B, False, "regular grid of right triangles (no gmsh)"),
              "diagonal": Spec(S, "right", "diagonal of a structured grid",
                               choices=("right", "left", "alternate", "crossed")), **RESOLUTION},
    "strip": {"length": Spec(F, 10.0, "x length", **POS), "width": Spec(F, 1.0, "y width", **POS),
              "structured": Spec(B, False, "regular grid of right triangles (no gmsh)"),
              "diagonal": Spec(S, "right", "diagonal of a structured grid",
                               choices=("right", "left", "alternate", "crossed")), **RESOLUTION},
    "annulus": {"inner_radius": Spec(F, 0.5, "inner radius", **POS),
                "outer_radius": Spec(F, 1.0, "outer radius", **POS),
                "slit": Spec(B, False, "cut along the positive x axis"), **RESOLUTION},
    "cylinder": {"radius": Spec(F, 1.0, "radius", **POS), "length": Spec(F, 1.0, "length", **POS),
                 "angle_range": Spec("pair", None, "panel angles [theta0, theta1] in degrees"), **RESOLUTION},
    "file": {"file": Spec("path", None, "mesh file (.vtu, .msh, .xdmf, ...), relative to the scene file",
                          required=True)},
}

#: boundary curves of each generated mesh kind (None: depends on options, see curves_of)
CURVES = {"sphere": (), "hemisphere": ("equator",), "disk": ("outer",), "plate": ("left", "right", "bottom", "top"),
          "strip": ("left", "right", "bottom", "top"), "annulus": ("outer", "inner"),
          "cylinder": ("bottom", "top")}


def curves_of(mesh: dict):
    """Boundary curve names of a generated mesh section (None for a mesh file: known after reading)."""
    kind = mesh["kind"]
    if kind == "file":
        return None
    names = list(CURVES[kind])
    if kind == "hemisphere" and mesh.get("hole_angle"):
        names.append("hole")
    if kind == "annulus" and mesh.get("slit"):
        names += ["slit-a", "slit-b"]
    if kind == "cylinder" and mesh.get("angle_range"):
        names += ["side-a", "side-b"]
    return tuple(names)


SECTIONS = {
    "material": {
        "E": Spec(F, 1.0, "Young's modulus (only scales energies)", **POS),
        "nu": Spec(F, 0.5, "Poisson ratio", lo=0.0, hi=0.5),
        "law": Spec(S, "svk", "membrane law: St Venant-Kirchhoff (design.md) or neo-Hookean (stable under "
                    "strong compression)", choices=("svk", "neo-hookean")),
    },
    "shell": {
        "thickness": Spec(F, None, "shell thickness h", required=True, **POS),
        "thickness_mode": Spec(S, "volume", "grown thickness: h/s^2 (volume) or h (uniform)",
                               choices=("volume", "uniform")),
        "natural_curvature": Spec("num_or_str", "mesh", "rest curvature: \"mesh\" (the drawn shape is "
                                  "stress free) or a number k0 (1/length)", choices=("mesh",)),
    },
    "growth": {
        "law": Spec(S, None, "growth law", choices=("none", "uniform", "inner_region", "contractility")),
        "strain": Spec(F, 0.0, "growth strain: linear stretch s = 1 + strain", lo=-1.0, lo_open=True),
        "inner_radius": Spec(F, None, "radius R2 of the grown region r < R2", **POS),
        "transition": Spec(F, 0.0, "width of a smooth step at r = R2 (0: sharp, by element centroid)", **NONNEG),
        "lam_max": Spec(F, 15.0, "contractility of untouched tissue, Λmax (>= lam_min)", **POS),
        "lam_min": Spec(F, 10.0, "contractility of saturated tissue, Λmin", **POS),
        "lam0": Spec(F, None, "reference contractility Λ0 of s = Λ0/Λ(c) (default Λmax)", **POS),
        "b": Spec(F, 100.0, "steepness of the contractility switch (1/concentration)", **POS),
        "c_star": Spec(F, 0.1, "threshold concentration c* (c >= 0, so c* < 0 would pattern everything)", **NONNEG),
    },
    "chemistry": {
        "D": Spec(F, 0.0, "diffusion coefficient (length^2/time)", **NONNEG),
        "w": Spec(F, 15.0, "production rate", **NONNEG),
        "Hs": Spec(F, 0.05, "saturation curvature (1/length)", **POS),
        "beta": Spec(F, 1.0, "degradation rate (1/time)", **NONNEG),
    },
    "initial": {
        "kind": Spec(S, "spot", "initial concentration: one Gaussian spot at `pole`, several (`layout`), or c = 0",
                     choices=("spot", "spots", "none")),
        "layout": Spec(S, "icosahedron", "spots: centres at the 12 vertices of an icosahedron (one at `pole`) "
                       "or at `count` random directions", choices=("icosahedron", "random")),
        "count": Spec(I, 12, "spots: number of random centres", lo=1, hi=10000),
        "seed": Spec(I, 0, "spots: random seed of the centres", lo=0),
        "amplitude": Spec(F, None, "spot amplitude (default c_max = w Hs / beta)", **NONNEG),
        "width": Spec(F, None, "spot width d (default h)", **POS),
        "elongation": Spec(F, 1.0, "spot elongation along `direction`", **POS),
        "pole": Spec("vec3", [0.0, 0.0, 1.0], "direction of the spot's centre from the mesh centroid"),
        "direction": Spec("vec3", None, "tangent direction of the elongation (default x; for kind = \"spots\" projected onto each "
                          "spot's tangent plane)"),
        "distance": Spec(S, "geodesic", "distance used in the Gaussian", choices=("geodesic", "chord", "planar")),
    },
    "output": {
        "every": Spec(I, 1, "write a frame every N steps (the last step is always written)", lo=1),
        "checkpoint_every": Spec(I, 1, "checkpoint every N steps (1: a kill loses no finished step)", lo=1),
        "pictures": Spec(B, True, "top and side views (and a bifurcation diagram) at the end"),
        "movie": Spec(B, False, "also render a movie of all frames at the end (femshell render does it later)"),
        "fields": Spec("strlist", None, "fields written in each frame (default: all that the scene has)"),
        "picture_field": Spec(S, None, "field of the top view (default c, else displacement)"),
        "cmap": Spec(S, "viridis", "matplotlib colour map of the pictures"),
        "progress_interval": Spec(F, 0.0, "seconds between progress lines (0: every step)", **NONNEG),
    },
}

NEWTON = {
    "newton_rtol": Spec(F, None, "Newton tolerance relative to the residual scale", **POS),
    "newton_max_iter": Spec(I, None, "Newton iterations per solve", lo=1),
    "backend": Spec(S, "auto", "sparse linear solver back-end", choices=("auto", "pardiso", "superlu")),
}

SOLVER_KEYS = {
    "static": {
        "steps": Spec(I, 10, "increments of the load factor / growth from 0 to 1", lo=1),
        "max_cuts": Spec(I, 8, "halvings of a failed increment before giving up", lo=0),
        "stable": Spec(B, True, "find stable equilibria (escape saddles)"),
        **NEWTON,
    },
    "continuation": {
        "parameter": Spec(S, None, "the continuation parameter", required=True,
                          choices=("loads.factor", "growth.strain", "growth.inner_radius")),
        "start": Spec(F, None, "start value (default: the scene's value, 0 for loads.factor)"),
        "stop": Spec(F, None, "stop exactly at this value (above or below the start: the branch sets off toward it)"),
        "ds": Spec(F, 0.05, "first arclength step (weighted, dimensionless)", **POS),
        "ds_min": Spec(F, None, "smallest step (default ds/1000)", **POS),
        "ds_max": Spec(F, None, "largest step (default 2 ds)", **POS),
        "max_steps": Spec(I, 200, "accepted steps of one branch", lo=1),
        "n_eigs": Spec(I, 3, "smallest eigenvalues recorded per step", lo=0, hi=20),
        # bounded: their squares weigh the arclength norm and must stay finite and non-zero in float64
        "parameter_scale": Spec(F, None, "scale of the parameter in the arclength (default |stop - start|)",
                                lo=1e-12, hi=1e12),
        "length_scale": Spec(F, None, "scale of displacements in the arclength (default the thickness)",
                             lo=1e-12, hi=1e12),
        "detect": Spec(B, True, "locate folds and branch points"),
        "stop_at": Spec("strlist", [], "stop after a 'fold' or 'branch' point"),
        "switch_branch": Spec(B, False, "then follow the branch born at the first branch point"),
        "switch_amplitude": Spec(F, None, "size of the jump onto the new branch (default ds)", **POS),
        "switch_stop": Spec(F, None, "stop value of the new branch (default stop)"),
        **NEWTON,
    },
    "time": {
        "t_final": Spec(F, 100.0, "end time (1/beta)", **NONNEG),
        "dt_initial": Spec(F, 0.01, "first step", **POS),
        "dt_min": Spec(F, 1e-8, "smallest step", **POS),
        "dt_max": Spec(F, 2.0, "largest step", **POS),
        "ds_max": Spec(F, 0.02, "largest change of the stretch s per step", **POS),
        "grow": Spec(F, 1.5, "largest growth factor of dt per step", lo=1.0),
        "safety": Spec(F, 0.8, "safety factor of the dt prediction", lo=0.0, hi=1.0, lo_open=True),
        "max_cuts": Spec(I, 12, "cuts of one step before giving up", lo=0),
        "stationary_rate_c": Spec(F, 1e-3, "stop when c changes slower than this (relative, per unit time)",
                                  **NONNEG),
        "stationary_rate_x": Spec(F, 1e-3, "... and the shape slower than this (thicknesses per unit time)",
                                  **NONNEG),
        "stationary_steps": Spec(I, 3, "... for this many steps in a row", lo=1),
        "stationary_pattern_time": Spec(F, 0.0, "also stop when the pattern (regions of c > c*) has stayed the "
                                                "same this long, though c may still change (0: off)", **NONNEG),
        "stationary_pattern_tol": Spec(F, 0.02, "... the same within this (relative area; centroids in mean "
                                                "region radii)", **NONNEG),
        "newton_atol_strain": Spec(F, 1e-10, "absolute Newton tolerance (in units of a unit strain's residual)",
                                   **NONNEG),
        "ramp_ds": Spec(F, 0.05, "stretch increments of the initial equilibrium", **POS),
        "snap_ds": Spec(F, 1e-3, "a Newton failure at a stretch step this small is a fold: minimise on (0: never)",
                        **NONNEG),
        "snap_max_iter": Spec(I, 400, "Newton iterations of a snap past a fold (0: never snap)", lo=0),
        "quasi_newton": Spec(I, 12, "quasi-Newton iterations on the last step's factorised Hessian before "
                                    "Newton (0: plain Newton)", lo=0),
        "newton_stall": Spec(I, 10, "a Newton solve with no progress for this many iterations gives up and the "
                                    "step is cut (0: never)", lo=0),
        "feedback_amplification": Spec(F, 0.5, "dt keeps an oscillation of the staggered chemistry-mechanics step "
                                               "damped: amplification >= -this (0: no bound)", lo=0.0, hi=1.0),
        "source_rule": Spec(S, "start", "source the chemistry holds over a step: its start's, or extrapolated to "
                                        "its midpoint from the last two steps where stable (second order)",
                            choices=("start", "extrapolated")),
        "max_steps": Spec(I, None, "stop after this many steps of one invocation (continue with --resume)", lo=0),
        **NEWTON,
    },
}

BOUNDARY_KEYS = {
    "clamped": {"curve": Spec(S, None, "boundary curve", required=True)},
    "simply_supported": {"curve": Spec(S, None, "boundary curve", required=True)},
    "symmetry": {"axis": Spec(S, None, "normal axis of the mirror plane", required=True, choices=("x", "y", "z")),
                 "value": Spec(F, 0.0, "position of the plane")},
    "prescribed": {"curve": Spec(S, None, "boundary curve", required=True),
                   "components": Spec("strlist", ["x", "y", "z"], "prescribed components"),
                   "displacement": Spec("vec3", [0.0, 0.0, 0.0], "prescribed displacement")},
}

LOAD_KEYS = {
    "point_force": {"point": Spec("vec3", None, "position; the force acts on the nearest vertex"),
                    "curve": Spec(S, None, "or every vertex of this boundary curve"),
                    "force": Spec("vec3", None, "force per vertex", required=True)},
    "area_load": {"traction": Spec("vec3", None, "force per unit rest area", required=True)},
    "edge_force": {"curve": Spec(S, None, "boundary curve", required=True),
                   "force": Spec("vec3", None, "force per unit rest length", required=True)},
    "dead_pressure": {"pressure": Spec(F, None, "pressure along the rest normals", required=True)},
    "follower_pressure": {"pressure": Spec(F, None, "pressure along the current normals", required=True)},
    "edge_moment": {"curve": Spec(S, None, "boundary curve", required=True),
                    "moment": Spec(F, None, "moment per unit rest length", required=True)},
}

#: output fields: name -> (point|cell, which scenes have it)
FIELDS = {
    "c": ("point", "time", "concentration"),
    "H": ("point", "any", "mean curvature relative to the rest shape (vertex average)"),
    "Lambda": ("point", "time", "contractility Λ(c)"),
    "stretch": ("cell", "any", "growth stretch s per element"),
    "displacement": ("point", "any", "x - X"),
    "thickness": ("cell", "any", "target thickness h̄ per element"),
    "energy_density": ("cell", "any", "(membrane + bending) energy per unit rest area"),
    "membrane_energy_density": ("cell", "any", "membrane energy per unit rest area"),
    "bending_energy_density": ("cell", "any", "bending energy per unit rest area"),
}

TOP_KEYS = ("description", "name", "mesh", "material", "shell", "growth", "chemistry", "boundary", "loads",
            "initial", "solver", "output")


# ----------------------------------------------------------------------------- the validated scene

@dataclass
class Scene:
    """A validated scene: ``data`` is the complete dict with every default filled in.

    ``name``: the scene's name (embedded name or file stem); ``source``: the file it came
    from; ``label``: how error messages name it; ``base_dir``: where relative paths start.
    ``given``: the section names present in the file (a missing [chemistry] is not built).
    """

    name: str
    data: dict
    source: Path | None
    label: str
    base_dir: Path
    given: tuple = ()

    def __getitem__(self, key):
        return self.data[key]

    @property
    def kind(self) -> str:
        return self.data["solver"]["kind"]


# ----------------------------------------------------------------------------- overrides

def parse_override(text: str):
    """``"a.b=value"`` -> (["a", "b"], value); value is TOML or a bare string."""
    if "=" not in text:
        raise SceneError(f"--set {text}: expected KEY=VALUE, e.g. --set mesh.n_vertices=300")
    key, raw = text.split("=", 1)
    key = key.strip()
    parts = [p for p in key.split(".")]
    if not key or any(not p for p in parts):
        raise SceneError(f"--set {text}: the key must be section.key, e.g. solver.t_final")
    raw = raw.strip()
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw   # a bare word: a string
    return parts, value


def apply_overrides(raw: dict, overrides, label="scene", *, note=True) -> dict:
    """A copy of ``raw`` with ``overrides`` (list of "key=value" or (parts, value)) applied.

    With ``note`` the description gets the overrides appended ("[--set mesh.radius=15]"), so that
    the scene written with a run, its summary and its header do not describe the file's values alone.
    """
    data = copy.deepcopy(raw)
    errors, shown = [], []
    for ov in overrides or ():
        parts, value = parse_override(ov) if isinstance(ov, str) else ov
        shown.append(".".join(parts) + "=" + (ov.split("=", 1)[1].strip() if isinstance(ov, str) else _fmt(value)))
        note = note and parts != ["description"]    # a description given by hand is taken as it is
        where = data
        ok = True
        for i, p in enumerate(parts[:-1]):
            if isinstance(where, list):
                if not p.isdigit() or int(p) >= len(where):
                    errors.append(f"--set {'.'.join(parts)}: [{'.'.join(parts[:i])}] has {len(where)} entries; "
                                  f"'{p}' is not an index in 0..{len(where) - 1}")
                    ok = False
                    break
                where = where[int(p)]
            else:
                if p not in where:
                    if i == 0 and p in ("boundary", "loads"):
                        errors.append(f"--set {'.'.join(parts)}: the scene has no [[{p}]] list to index")
                        ok = False
                        break
                    where[p] = {}
                elif not isinstance(where[p], (dict, list)):
                    errors.append(f"--set {'.'.join(parts)}: '{'.'.join(parts[:i + 1])}' is a value, not a table")
                    ok = False
                    break
                where = where[p]
        if not ok:
            continue
        last = parts[-1]
        if isinstance(where, list):
            errors.append(f"--set {'.'.join(parts)}: give the index and key of the list entry, "
                          f"e.g. {'.'.join(parts[:-1] + ['0', last])}")
            continue
        where[last] = value
        if len(parts) == 2 and parts[0] == "mesh":   # the resolution given last wins
            other = {"n_vertices": "edge_length", "edge_length": "n_vertices"}.get(last)
            if other:
                where.pop(other, None)
    if errors:
        raise SceneError([f"{label}: {e}" for e in errors])
    desc = data.get("description")
    if note and shown and isinstance(desc, str):
        data["description"] = f"{desc} [--set {' '.join(shown)}]" if desc else f"[--set {' '.join(shown)}]"
    return data


# ----------------------------------------------------------------------------- validation

def _suggest(word, options):
    m = difflib.get_close_matches(str(word), list(options), n=1, cutoff=0.5)
    if not m:
        low = {o.lower(): o for o in options}
        m = [low[str(word).lower()]] if str(word).lower() in low else []
    return m[0] if m else None


class _Checker:
    def __init__(self, label):
        self.label = label
        self.errors = []

    def err(self, msg):
        self.errors.append(f"{self.label}: {msg}")

    def unknown(self, where, key, valid, what="key"):
        s = _suggest(key, valid)
        hint = f"; did you mean '{s}'?" if s else ""
        self.err(f"{where} unknown {what} '{key}'{hint} (valid: {', '.join(valid) or 'none'})")

    def value(self, where, name, spec: Spec, v):
        """Type and range of one value; returns the normalised value or None after an error."""
        shown = f"{where} {name} = {_show(v)}"
        k = spec.kind
        isnum = isinstance(v, (int, float)) and not isinstance(v, bool)
        if k == F:
            if not isnum:
                return self._type(shown, "a number", v)
            v = float(v)
            if not math.isfinite(v):
                self.err(f"{shown} must be a finite number")
                return None
        elif k == I:
            if isinstance(v, float) and v.is_integer():
                v = int(v)
            if not isinstance(v, int) or isinstance(v, bool):
                return self._type(shown, "an integer", v)
        elif k == B:
            if not isinstance(v, bool):
                return self._type(shown, "true or false", v)
        elif k in (S, "path"):
            if not isinstance(v, str):
                return self._type(shown, "a string", v)
            if spec.choices and v not in spec.choices:
                s = _suggest(v, spec.choices)
                hint = f"; did you mean \"{s}\"?" if s else ""
                self.err(f"{shown} is not one of {', '.join(_show(c) for c in spec.choices)}{hint}")
                return None
        elif k in ("vec3", "pair"):
            n = 3 if k == "vec3" else 2
            if (not isinstance(v, list) or len(v) != n
                    or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)):
                return self._type(shown, f"a list of {n} numbers", v)
            v = [float(x) for x in v]
            if not all(math.isfinite(x) for x in v):
                self.err(f"{shown} must hold finite numbers")
                return None
        elif k == "strlist":
            if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
                return self._type(shown, "a list of strings", v)
        elif k == "num_or_str":
            if isinstance(v, str):
                if v not in spec.choices:
                    self.err(f"{shown} must be a number or one of {', '.join(_show(c) for c in spec.choices)}")
                    return None
            elif isnum:
                v = float(v)
                if not math.isfinite(v):
                    self.err(f"{shown} must be a finite number or one of {', '.join(_show(c) for c in spec.choices)}")
                    return None
            else:
                return self._type(shown, f"a number or {', '.join(_show(c) for c in spec.choices)}", v)
        if k in (F, "vec3", "pair") or (k == "num_or_str" and isnum):
            lo, hi = MAGNITUDE
            if any(x != 0 and not lo <= abs(x) <= hi for x in (v if isinstance(v, list) else [v])):
                self.err(f"{shown} is out of range: a non-zero number's magnitude must be in [{lo:g}, {hi:g}] "
                         "(a guard against overflow in products such as E h³ κ², w Hs/β, D dt; choose other units)")
                return None
        if k in (F, I) or (k == "num_or_str" and isnum):
            bad = ((spec.lo is not None and (v <= spec.lo if spec.lo_open else v < spec.lo))
                   or (spec.hi is not None and (v >= spec.hi if spec.hi_open else v > spec.hi)))
            if bad:
                self.err(f"{shown} is out of range: {spec.range_text(name)}")
                return None
        return v

    def _type(self, shown, want, v):
        got = {bool: "a boolean", str: "a string", int: "an integer", float: "a number", list: "a list",
               dict: "a table"}.get(type(v), type(v).__name__)
        self.err(f"{shown} must be {want}, got {got}")
        return None

    def section(self, where, given: dict, specs: dict, extra_ok=(), not_for=None):
        """Validate ``given`` against ``specs``; returns the section with defaults filled in."""
        out = {}
        if not isinstance(given, dict):
            self.err(f"{where} must be a table, got {_show(given)}")
            given = {}
        for key, v in given.items():
            if key in extra_ok:
                continue
            if key not in specs:
                if not_for is not None and key in not_for[0]:
                    self.err(f"{where} {key} is not used by {not_for[1]} (it takes: {', '.join(specs) or 'nothing'})")
                else:
                    self.unknown(where, key, list(specs))
                continue
            nv = self.value(where, key, specs[key], v)
            if nv is not None:
                out[key] = nv
        for key, spec in specs.items():
            if key not in given:
                if spec.required:
                    self.err(f"{where} {key} is required ({spec.doc})")
                else:
                    out[key] = copy.deepcopy(spec.default)
        return out


def parse_scene(text: str, label: str) -> dict:
    """The raw TOML dict of a scene text; syntax errors become a :class:`SceneError`."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{label}: not valid TOML: {exc}") from None


def continuation_start(solver: dict, growth: dict):
    """The parameter's value where a continuation starts: ``solver.start``, else the scene's own value
    (0 for loads.factor); None when that value is missing (reported elsewhere)."""
    if solver.get("start") is not None:
        return solver["start"]
    p = solver["parameter"]
    if p == "loads.factor":
        return 0.0
    return growth.get("strain" if p == "growth.strain" else "inner_radius")


def validate(raw: dict, *, name: str, label: str, source=None, base_dir=None, check_files=True) -> Scene:
    """Check a raw scene dict completely; returns a :class:`Scene` with all defaults filled in.

    Raises :class:`SceneError` with one line per problem found (all of them, not only the first).
    ``check_files=False`` resolves a mesh file's path without requiring the file (to compare a
    stored scene whose mesh has moved since).
    """
    ck = _Checker(label)
    base_dir = Path(base_dir) if base_dir is not None else (Path(source).parent if source else Path.cwd())
    data = {}
    for key in raw:
        if key not in TOP_KEYS:
            s = _suggest(key, TOP_KEYS)
            is_table = isinstance(raw[key], (dict, list))
            what = f"[{key}] is not a section" if is_table else f"'{key}' is not a top-level key"
            ck.err(f"{what}{'; did you mean ' + ('[' + s + ']' if s not in ('description', 'name') else repr(s)) + '?' if s else ''}"
                   f" (sections: {', '.join(k for k in TOP_KEYS if k not in ('description', 'name'))})")
    desc = raw.get("description", "")
    if not isinstance(desc, str):
        ck.err(f"description = {_show(desc)} must be a string")
        desc = ""
    elif "\n" in desc.strip():
        ck.err("description must be one line (it is what `femshell scenes` prints)")
    data["description"] = desc.strip()
    nm = raw.get("name", name)
    data["name"] = nm if isinstance(nm, str) and nm else name

    # --- solver first: the other sections depend on its kind
    solver_raw = raw.get("solver")
    if solver_raw is None:
        ck.err("[solver] is missing: give kind = \"static\", \"continuation\" or \"time\"")
        solver_raw = {}
    if not isinstance(solver_raw, dict):
        ck.err("[solver] must be a table")
        solver_raw = {}
    kind = solver_raw.get("kind")
    if kind is None:
        if isinstance(raw.get("solver"), dict):
            ck.err("[solver] kind is required: \"static\", \"continuation\" or \"time\"")
    elif kind not in SOLVER_KEYS:
        s = _suggest(kind, SOLVER_KEYS)
        ck.err(f"[solver] kind = {_show(kind)} is not one of \"static\", \"continuation\", \"time\""
               f"{'; did you mean ' + _show(s) + '?' if s else ''}")
        kind = None
    if kind is not None:
        others = set().union(*[set(v) for k, v in SOLVER_KEYS.items() if k != kind])
        solver = ck.section("[solver]", solver_raw, SOLVER_KEYS[kind], extra_ok=("kind",),
                            not_for=(others, f"kind = \"{kind}\""))
        solver["kind"] = kind
    else:
        solver = {"kind": None}
    data["solver"] = solver

    # --- mesh
    mesh_raw = raw.get("mesh")
    if mesh_raw is None:
        ck.err("[mesh] is missing: give kind = \"sphere\" (or disk, plate, ...) or file = \"path\"")
        mesh_raw = {}
    if not isinstance(mesh_raw, dict):
        ck.err("[mesh] must be a table")
        mesh_raw = {}
    mkind = mesh_raw.get("kind", "file" if "file" in mesh_raw else None)
    mesh = {"kind": mkind}
    if mkind is None:
        if raw.get("mesh") is not None:
            ck.err("[mesh] kind is required: one of " + ", ".join(_show(k) for k in MESH_KEYS))
    elif mkind not in MESH_KEYS:
        s = _suggest(mkind, MESH_KEYS)
        ck.err(f"[mesh] kind = {_show(mkind)} is not one of {', '.join(_show(k) for k in MESH_KEYS)}"
               f"{'; did you mean ' + _show(s) + '?' if s else ''}")
        mesh["kind"] = None
    else:
        others = set().union(*[set(v) for k, v in MESH_KEYS.items() if k != mkind])
        mesh.update(ck.section("[mesh]", mesh_raw, MESH_KEYS[mkind], extra_ok=("kind",),
                               not_for=(others, f"kind = \"{mkind}\"")))
        if mesh.get("n_vertices") is not None and mesh.get("edge_length") is not None:
            ck.err("[mesh] give either n_vertices or edge_length, not both")
        if mkind == "annulus" and mesh.get("inner_radius") and mesh.get("outer_radius") \
                and mesh["inner_radius"] >= mesh["outer_radius"]:
            ck.err(f"[mesh] inner_radius = {mesh['inner_radius']:g} must be less than outer_radius = "
                   f"{mesh['outer_radius']:g}")
        if mkind == "disk" and mesh.get("inner_radius") is not None and mesh["inner_radius"] >= mesh["radius"]:
            ck.err(f"[mesh] inner_radius = {mesh['inner_radius']:g} must be less than radius = {mesh['radius']:g}")
        if mkind == "cylinder" and mesh.get("angle_range") is not None:
            t0, t1 = mesh["angle_range"]
            if not 0 < t1 - t0 < 360:
                ck.err(f"[mesh] angle_range = {_show(mesh['angle_range'])} must have 0 < theta1 - theta0 < 360 "
                       "(degrees)")
        if mkind == "file" and mesh.get("file"):
            p = Path(mesh["file"]).expanduser()
            full = p if p.is_absolute() else base_dir / p
            if check_files and not full.is_file():
                ck.err(f"[mesh] file = {_show(mesh['file'])}: no such file ({full})")
            else:
                mesh["file"] = str(full.resolve())
    data["mesh"] = mesh

    # --- material, shell
    data["material"] = ck.section("[material]", raw.get("material", {}), SECTIONS["material"])
    if "shell" not in raw:
        ck.err("[shell] is missing: give at least thickness = h (> 0)")
        data["shell"] = ck.section("[shell]", {"thickness": 1.0}, SECTIONS["shell"])
    else:
        data["shell"] = ck.section("[shell]", raw["shell"], SECTIONS["shell"])

    # --- growth
    g_raw = raw.get("growth", {})
    if not isinstance(g_raw, dict):
        ck.err("[growth] must be a table")
        g_raw = {}
    law = g_raw.get("law", "contractility" if kind == "time" else ("none" if not g_raw else None))
    LAW_KEYS = {"none": (), "uniform": ("strain",), "inner_region": ("strain", "inner_radius", "transition"),
                "contractility": ("lam_max", "lam_min", "lam0", "b", "c_star")}
    if law is None:
        ck.err("[growth] law is required: \"uniform\", \"inner_region\", \"contractility\" or \"none\"")
        data["growth"] = {"law": None}
    else:
        spec_law = ck.value("[growth]", "law", SECTIONS["growth"]["law"], law)
        if spec_law is None:
            data["growth"] = {"law": None}
        else:
            keys = {k: SECTIONS["growth"][k] for k in LAW_KEYS[law]}
            others = set(SECTIONS["growth"]) - set(keys) - {"law"}
            data["growth"] = ck.section("[growth]", g_raw, keys, extra_ok=("law",),
                                        not_for=(others, f"law = \"{law}\""))
            data["growth"]["law"] = law
            gr = data["growth"]
            if law == "contractility" and gr.get("lam_max") is not None and gr.get("lam_min") is not None \
                    and gr["lam_max"] < gr["lam_min"]:
                ck.err(f"[growth] lam_max = {_fmt(gr['lam_max'])} is out of range: lam_min = "
                       f"{_fmt(gr['lam_min'])} <= lam_max")
    law = data["growth"].get("law")

    # --- chemistry, initial: only for the time loop
    for sec in ("chemistry", "initial"):
        if sec in raw and kind in ("static", "continuation"):
            ck.err(f"[{sec}] is given but solver.kind = \"{kind}\" has no chemistry (only kind = \"time\" "
                   "runs the mechanochemical loop); remove the section")
    if kind == "time":
        data["chemistry"] = ck.section("[chemistry]", raw.get("chemistry", {}), SECTIONS["chemistry"])
        data["initial"] = ck.section("[initial]", raw.get("initial", {}), SECTIONS["initial"])
        if law is not None and law != "contractility":
            ck.err(f"[growth] law = \"{law}\" cannot run in time: the time loop grows the shell by the "
                   "contractility law Λ(c); use law = \"contractility\" (or solver.kind = \"static\")")
        ini = data["initial"]
        given_ini = raw.get("initial", {}) if isinstance(raw.get("initial"), dict) else {}
        if ini.get("kind") != "spots":
            for k in ("layout", "count", "seed"):
                if k in given_ini:
                    ck.err(f"[initial] {k} is used only with kind = \"spots\"")
                ini.pop(k, None)
        elif ini.get("layout") == "icosahedron":
            for k in ("count", "seed"):
                if k in given_ini:
                    ck.err(f"[initial] {k} is used only with layout = \"random\" (an icosahedron has 12 vertices)")
                ini.pop(k, None)
        for k in ("pole", "direction"):
            if ini.get(k) is not None and not any(ini[k]):
                ck.err(f"[initial] {k} = [0, 0, 0] must be a non-zero vector")
        beta = data["chemistry"].get("beta")
        if data["initial"].get("kind") in ("spot", "spots") and data["initial"].get("amplitude") is None and beta == 0:
            ck.err("[initial] amplitude is required when [chemistry] beta = 0 (its default c_max = w Hs / beta "
                   "is infinite)")
    elif law == "contractility":
        ck.err(f"[growth] law = \"contractility\" needs the chemistry of solver.kind = \"time\" "
               f"(this scene has kind = \"{kind}\"); use law = \"uniform\" or \"inner_region\"")

    # --- boundary conditions
    curves = curves_of(mesh) if mesh.get("kind") in MESH_KEYS else None
    data["boundary"] = []
    b_raw = raw.get("boundary", [])
    if isinstance(b_raw, dict):
        b_raw = [b_raw]
    if not isinstance(b_raw, list):
        ck.err("boundary must be a list of tables: write each condition as [[boundary]]")
        b_raw = []
    for i, bc in enumerate(b_raw):
        where = f"[[boundary]] #{i + 1}"
        if not isinstance(bc, dict):
            ck.err(f"{where} must be a table with type = ...")
            continue
        t = bc.get("type")
        if t not in BOUNDARY_KEYS:
            s = _suggest(t, BOUNDARY_KEYS) if isinstance(t, str) else None
            ck.err(f"{where} type = {_show(t) if t is not None else '(missing)'} is not one of "
                   f"{', '.join(_show(k) for k in BOUNDARY_KEYS)}{'; did you mean ' + _show(s) + '?' if s else ''}")
            continue
        others = set().union(*[set(v) for v in BOUNDARY_KEYS.values()]) - set(BOUNDARY_KEYS[t])
        entry = ck.section(where, bc, BOUNDARY_KEYS[t], extra_ok=("type",), not_for=(others, f"type = \"{t}\""))
        entry["type"] = t
        if "components" in entry:
            bad = [c for c in entry["components"] if c not in ("x", "y", "z")]
            if bad or not entry["components"]:
                ck.err(f"{where} components = {_show(entry['components'])} must be a non-empty list of "
                       "\"x\", \"y\", \"z\"")
        c = entry.get("curve")
        if c is not None and curves is not None and c not in curves:
            if not curves:
                ck.err(f"{where} {t} on curve '{c}': a {mesh['kind']} mesh is closed and has no boundary curve "
                       "(a free closed shell needs no boundary condition: its rigid-body motions are removed "
                       "automatically)")
            else:
                s = _suggest(c, curves)
                ck.err(f"{where} curve = {_show(c)} is not a boundary curve of the {mesh['kind']} mesh"
                       f"{'; did you mean ' + _show(s) + '?' if s else ''} (curves: {', '.join(curves)})")
        data["boundary"].append(entry)

    # --- loads
    data["loads"] = []
    l_raw = raw.get("loads", [])
    if isinstance(l_raw, dict):
        l_raw = [l_raw]
    if not isinstance(l_raw, list):
        ck.err("loads must be a list of tables: write each load as [[loads]]")
        l_raw = []
    if l_raw and kind == "time":
        ck.err("[[loads]] are not supported by the time loop (solver.kind = \"time\"); use \"static\" or "
               "\"continuation\"")
    for i, ld in enumerate(l_raw):
        where = f"[[loads]] #{i + 1}"
        if not isinstance(ld, dict):
            ck.err(f"{where} must be a table with type = ...")
            continue
        t = ld.get("type")
        if t not in LOAD_KEYS:
            s = _suggest(t, LOAD_KEYS) if isinstance(t, str) else None
            ck.err(f"{where} type = {_show(t) if t is not None else '(missing)'} is not one of "
                   f"{', '.join(_show(k) for k in LOAD_KEYS)}{'; did you mean ' + _show(s) + '?' if s else ''}")
            continue
        others = set().union(*[set(v) for v in LOAD_KEYS.values()]) - set(LOAD_KEYS[t])
        entry = ck.section(where, ld, LOAD_KEYS[t], extra_ok=("type",), not_for=(others, f"type = \"{t}\""))
        entry["type"] = t
        if t == "point_force" and (entry.get("point") is None) == (entry.get("curve") is None):
            ck.err(f"{where} point_force needs exactly one of point = [x, y, z] or curve = \"name\"")
        c = entry.get("curve")
        if c is not None and curves is not None and c not in curves:
            if not curves:
                ck.err(f"{where} {t} on curve '{c}': a {mesh['kind']} mesh is closed and has no boundary curve")
            else:
                s = _suggest(c, curves)
                ck.err(f"{where} curve = {_show(c)} is not a boundary curve of the {mesh['kind']} mesh"
                       f"{'; did you mean ' + _show(s) + '?' if s else ''} (curves: {', '.join(curves)})")
        data["loads"].append(entry)

    # --- solver consistency
    if kind == "static":
        if law in ("none", None) and not data["loads"]:
            ck.err("solver.kind = \"static\" with no growth and no [[loads]] has nothing to solve: the rest "
                   "shape is the answer")
    if kind == "continuation" and solver.get("parameter"):
        p = solver["parameter"]
        if p == "loads.factor" and not data["loads"]:
            ck.err("[solver] parameter = \"loads.factor\" but the scene has no [[loads]]")
        if p == "growth.strain" and law not in ("uniform", "inner_region"):
            ck.err(f"[solver] parameter = \"growth.strain\" needs [growth] law = \"uniform\" or \"inner_region\" "
                   f"(this scene has law = {_show(law)})")
        if p == "growth.inner_radius":
            if law != "inner_region":
                ck.err(f"[solver] parameter = \"growth.inner_radius\" needs [growth] law = \"inner_region\" "
                       f"(this scene has law = {_show(law)})")
            elif not data["growth"].get("transition"):
                ck.err("[solver] parameter = \"growth.inner_radius\" needs [growth] transition > 0: with a sharp "
                       "region boundary the rest state jumps as R2 passes an element, which is not a smooth "
                       "parameter")
        for key in ("start", "stop", "switch_stop"):
            v = solver.get(key)
            if v is None:
                continue
            if p == "growth.strain" and not v > -1.0:
                ck.err(f"[solver] {key} = {_fmt(v)} is out of range for growth.strain: > -1 (a stretch 1 + g > 0)")
            if p == "growth.inner_radius" and not v > 0:
                ck.err(f"[solver] {key} = {_fmt(v)} is out of range for growth.inner_radius: 0 < R2")
        if solver.get("detect") is False:
            # without detection there is no special point to stop at or to switch from
            for key, bad in (("stop_at", bool(solver.get("stop_at"))), ("switch_branch", solver.get("switch_branch"))):
                if bad:
                    ck.err(f"[solver] {key} = {_show(solver[key])} needs detect = true (no fold or branch point is "
                           "located without it)")
        for k in solver.get("stop_at") or []:
            if k not in ("fold", "branch"):
                ck.err(f"[solver] stop_at = {_show(solver['stop_at'])}: entries must be \"fold\" or \"branch\"")
        if solver.get("ds_min") and solver.get("ds") and solver["ds_min"] > solver["ds"]:
            ck.err(f"[solver] ds_min = {_fmt(solver['ds_min'])} must be <= ds = {_fmt(solver['ds'])}")
        if solver.get("ds_max") and solver.get("ds") and solver["ds_max"] < solver["ds"]:
            ck.err(f"[solver] ds_max = {_fmt(solver['ds_max'])} must be >= ds = {_fmt(solver['ds'])}")
    if law == "inner_region" and data["growth"].get("inner_radius") is None:
        r2 = mesh.get("inner_radius") if mesh.get("kind") == "disk" else None
        if r2 is None:
            ck.err("[growth] inner_radius is required for law = \"inner_region\" (or give [mesh] inner_radius "
                   "of a disk)")
        else:
            data["growth"]["inner_radius"] = r2
    if law == "inner_region" and mesh.get("kind") == "disk" and mesh.get("radius"):
        # a grown region r < R2 covering the whole disk is uniform growth: a slip of R2 for a diameter, say
        values = [("[growth] inner_radius", data["growth"].get("inner_radius"))]
        if kind == "continuation" and solver.get("parameter") == "growth.inner_radius":
            values += [(f"[solver] {k}", solver.get(k)) for k in ("start", "stop", "switch_stop")]
        for what, v in values:
            if v is not None and v >= mesh["radius"]:
                ck.err(f"{what} = {_fmt(v)} is out of range: 0 < R2 < the disk's radius {_fmt(mesh['radius'])} "
                       "(r < R2 would cover the whole disk; law = \"uniform\" grows it all)")
    if kind == "continuation" and solver.get("parameter") and solver.get("stop") is not None:
        start, stop = continuation_start(solver, data["growth"]), solver["stop"]
        if start is not None and start == stop:
            given = "start" if solver.get("start") is not None else f"the start ({solver['parameter']})"
            ck.err(f"[solver] stop = {_fmt(stop)} equals {given} = {_fmt(start)}: nothing to follow")
    if kind == "time":
        st = solver
        if all(st.get(k) is not None for k in ("dt_min", "dt_max")) and st["dt_max"] < st["dt_min"]:
            ck.err(f"[solver] dt_max = {_fmt(st['dt_max'])} is out of range: dt_min = {_fmt(st['dt_min'])} <= dt_max")
        if all(st.get(k) is not None for k in ("dt_min", "dt_max", "dt_initial")) and \
                not st["dt_min"] <= st["dt_initial"] <= st["dt_max"]:
            ck.err(f"[solver] dt_initial = {_fmt(st['dt_initial'])} is out of range: dt_min <= dt_initial <= dt_max "
                   f"({_fmt(st['dt_min'])} .. {_fmt(st['dt_max'])})")

    # --- output
    data["output"] = ck.section("[output]", raw.get("output", {}), SECTIONS["output"])
    out = data["output"]
    have = [f for f, (_, scope, _) in FIELDS.items() if scope == "any" or scope == kind]
    if out.get("fields") is None:
        out["fields"] = have
    else:
        for f in out["fields"]:
            if f not in FIELDS:
                s = _suggest(f, FIELDS)
                ck.err(f"[output] fields: unknown field '{f}'{'; did you mean ' + repr(s) + '?' if s else ''} "
                       f"(fields: {', '.join(FIELDS)})")
            elif f not in have:
                ck.err(f"[output] fields: '{f}' exists only in time-loop scenes (solver.kind = \"time\")")
    pf = out.get("picture_field")
    if pf is None:
        out["picture_field"] = "c" if kind == "time" else "displacement"
    elif pf not in have and pf not in ("radius", "z"):
        ck.err(f"[output] picture_field = {_show(pf)} is not a field of this scene (fields: {', '.join(have)}, "
               "radius, z)")
    try:
        import matplotlib

        if out.get("cmap") and out["cmap"] not in matplotlib.colormaps:
            s = _suggest(out["cmap"], list(matplotlib.colormaps))
            ck.err(f"[output] cmap = {_show(out['cmap'])} is not a matplotlib colour map"
                   f"{'; did you mean ' + _show(s) + '?' if s else ''}")
    except ImportError:   # pragma: no cover - matplotlib is a dependency
        pass

    if ck.errors:
        raise SceneError(ck.errors)
    given = tuple(k for k in raw if k in TOP_KEYS)
    return Scene(name=data["name"], data=data, source=Path(source) if source else None, label=label,
                 base_dir=base_dir, given=given)


# ----------------------------------------------------------------------------- TOML writer

def _toml_key(k):
    import re
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else _show(k)


def _toml_value(v):
    if isinstance(v, float):
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        if math.isnan(v):
            return "nan"
        return repr(v)
    return _show(v)


def dump_toml(data: dict) -> str:
    """A TOML text of a scene dict (scalars, lists of scalars, tables, lists of tables); None is left out."""
    lines = []
    scalars = {k: v for k, v in data.items() if not isinstance(v, (dict, list)) or
               (isinstance(v, list) and not any(isinstance(x, dict) for x in v))}
    for k, v in scalars.items():
        if v is not None:
            lines.append(f"{_toml_key(k)} = {_toml_value(v)}")
    for k, v in data.items():
        if isinstance(v, dict):
            lines.append("")
            lines.append(f"[{_toml_key(k)}]")
            for kk, vv in v.items():
                if vv is not None:
                    lines.append(f"{_toml_key(kk)} = {_toml_value(vv)}")
        elif isinstance(v, list) and any(isinstance(x, dict) for x in v):
            for item in v:
                lines.append("")
                lines.append(f"[[{_toml_key(k)}]]")
                for kk, vv in item.items():
                    if vv is not None:
                        lines.append(f"{_toml_key(kk)} = {_toml_value(vv)}")
    return "\n".join(lines).lstrip("\n") + "\n"
