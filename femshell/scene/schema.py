r"""Scene files: the TOML format and its validation.

A scene is a TOML file (or an embedded scene name, see :func:`femshell.scene.list_scenes`)
with a one-line ``description`` and these sections (all lengths in cell sizes, time
in 1/β, E = 1 by default: theory §1.3)::

    description = "one line shown by `femshell scenes`"

    [mesh]        kind = "sphere" | "hemisphere" | "disk" | "plate" | "strip" | "annulus"
                  | "cylinder" | "file", the generator's arguments (radius, n_vertices or
                  edge_length, ...; see MESH_KEYS) or file = "path" (relative to the scene)
    [material]    E (> 0, default 1), nu (0 <= nu <= 0.5, default 0.5),
                  law = "svk" (St Venant–Kirchhoff, theory §1.2, default) | "neo-hookean"
    [shell]       thickness h (> 0, required), thickness_mode = "volume" | "uniform",
                  natural_curvature = "mesh" (the drawn mesh is stress free) or k0 (1/length)
    [growth]      law = "none" | "uniform" | "inner_region" | "contractility"
                  uniform: strain (s = 1 + strain everywhere)
                  inner_region: strain, inner_radius, transition (the disk test, theory §1.6)
                  contractility: lam_max, lam_min, lam0, b, c_star (theory §1.1)
    [chemistry]   D, w, Hs, beta (only with solver.kind = "time" or "pattern-continuation")
    [[boundary]]  type = "clamped" | "simply_supported" | "symmetry" | "prescribed", curve = "name"
                  (symmetry: axis, value; prescribed: components, displacement)
    [[loads]]     type = "point_force" | "area_load" | "edge_force" | "dead_pressure"
                  | "follower_pressure" | "edge_moment" (curve, point, force, traction,
                  pressure, moment); all loads are multiplied by the load factor
    [initial]     kind = "spot" | "spots" | "none"; amplitude, width, elongation, pole, direction,
                  distance; spots: layout = "icosahedron" | "random", count, seed
    [solver]      kind = "static" | "continuation" | "time" | "linear-buckling" | "pattern-continuation" and its
                  controls (SOLVER_KEYS)
    [output]      every, checkpoint_every, pictures, movie, fields, picture_field, cmap,
                  progress_interval

Validation (:func:`validate`) checks everything before anything is computed and raises
one :class:`SceneError` listing every problem, one line each, naming the key path::

    scene.toml: [material] nu = 0.7 is out of range: 0 <= nu <= 0.5
    scene.toml: [materail] is not a section; did you mean [material]?

Every number is finite, and a non-zero one has a magnitude in ``MAGNITUDE`` = [1e-30, 1e30].
Each key's type, range and default is a field of its section's class in :mod:`femshell.scene.config`;
reading, writing and ``--set`` overrides of the text are in :mod:`.text`.
"""

from __future__ import annotations

import difflib
import math
from pathlib import Path

from .config import (BOUNDARY_TYPES, LOAD_OPTIONAL, LOAD_TYPES, MESH_CONFIGS, SOLVER_CONFIGS, TIME_KINDS, BoundaryConfig,
                     ChemistryConfig, GROWTH_LAWS, GrowthConfig, InitialConfig, LoadConfig, MaterialConfig,
                     OutputConfig, Scene, ShellConfig, Spec, _fmt, specs)
# re-exported: the scene's text functions were this module's
from .text import SceneError, _show, apply_overrides, dump_toml, parse_override, parse_scene  # noqa: F401

__all__ = ["SceneError", "Scene", "parse_scene", "validate", "apply_overrides", "parse_override",
           "dump_toml", "MESH_KEYS", "SOLVER_KEYS", "FIELDS", "CURVES", "SECTIONS"]


# ----------------------------------------------------------------------------- key specifications

F, I, B, S = "float", "int", "bool", "str"
#: Magnitude of any non-zero number in a scene: a guard against overflow and underflow in the
#: products of scene numbers that the energies and the chemistry form (E h³ κ², w Hs/β, D dt).
MAGNITUDE = (1e-30, 1e30)
#: generator arguments per mesh kind (angles in degrees)
MESH_KEYS = {kind: specs(cls) for kind, cls in MESH_CONFIGS.items()}

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


SECTIONS = {"material": specs(MaterialConfig), "shell": specs(ShellConfig), "growth": specs(GrowthConfig),
            "chemistry": specs(ChemistryConfig), "initial": specs(InitialConfig), "output": specs(OutputConfig)}

SOLVER_KEYS = {kind: specs(cls) for kind, cls in SOLVER_CONFIGS.items()}
_KINDS_TEXT = ", ".join(f'"{k}"' for k in SOLVER_CONFIGS)

BOUNDARY_KEYS = {t: specs(BoundaryConfig, names, t) for t, names in BOUNDARY_TYPES.items()}


def _load_keys(t, names):
    out = specs(LoadConfig, names, t)
    for k in LOAD_OPTIONAL.get(t, ()):
        out[k].required = False
    return out


LOAD_KEYS = {t: _load_keys(t, names) for t, names in LOAD_TYPES.items()}

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
                    out[key] = spec.default
        return out


def continuation_start(parameter, start, strain, inner_radius):
    """The parameter's value where a continuation starts: ``start``, else the scene's own value
    (0 for loads.factor); None when that value is missing (reported elsewhere)."""
    if start is not None:
        return start
    if parameter == "loads.factor":
        return 0.0
    return strain if parameter == "growth.strain" else inner_radius


def _top_keys(ck, raw, name) -> dict:
    """Unknown top-level keys; the description and the name."""
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
    return data


def _solver_section(ck, raw) -> dict:
    """[solver], checked first: the other sections depend on its kind."""
    solver_raw = raw.get("solver")
    if solver_raw is None:
        ck.err(f"[solver] is missing: give kind = {_KINDS_TEXT}")
        solver_raw = {}
    if not isinstance(solver_raw, dict):
        ck.err("[solver] must be a table")
        solver_raw = {}
    kind = solver_raw.get("kind")
    if kind is None:
        if isinstance(raw.get("solver"), dict):
            ck.err(f"[solver] kind is required: {_KINDS_TEXT}")
    elif kind not in SOLVER_KEYS:
        s = _suggest(kind, SOLVER_KEYS)
        ck.err(f"[solver] kind = {_show(kind)} is not one of {_KINDS_TEXT}"
               f"{'; did you mean ' + _show(s) + '?' if s else ''}")
        kind = None
    if kind is not None:
        others = set().union(*[set(v) for k, v in SOLVER_KEYS.items() if k != kind])
        solver = ck.section("[solver]", solver_raw, SOLVER_KEYS[kind], extra_ok=("kind",),
                            not_for=(others, f"kind = \"{kind}\""))
        solver["kind"] = kind
    else:
        solver = {"kind": None}
    return solver


def _mesh_section(ck, raw, base_dir, check_files) -> dict:
    """[mesh]: its kind, the generator's arguments or the file (resolved from ``base_dir``)."""
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
    return mesh


def _growth_section(ck, raw, data, kind):
    """[growth] with the keys of its law; returns the law (None: not known)."""
    g_raw = raw.get("growth", {})
    if not isinstance(g_raw, dict):
        ck.err("[growth] must be a table")
        g_raw = {}
    law = g_raw.get("law", "contractility" if kind in TIME_KINDS else ("none" if not g_raw else None))
    if law is None:
        ck.err("[growth] law is required: \"uniform\", \"inner_region\", \"contractility\" or \"none\"")
        data["growth"] = {"law": None}
    else:
        spec_law = ck.value("[growth]", "law", SECTIONS["growth"]["law"], law)
        if spec_law is None:
            data["growth"] = {"law": None}
        else:
            keys = {k: SECTIONS["growth"][k] for k in GROWTH_LAWS[law]}
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
    return law


def _time_sections(ck, raw, data, kind, law):
    """[chemistry] and [initial]: only the time loop has them."""
    for sec in ("chemistry", "initial"):
        if sec in raw and kind in ("static", "continuation", "linear-buckling"):
            ck.err(f"[{sec}] is given but solver.kind = \"{kind}\" has no chemistry (only kind = \"time\" "
                   "runs the mechanochemical loop); remove the section")
    if kind in TIME_KINDS:
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
    elif law == "contractility" and kind is not None:     # an unknown kind is named once, where [solver] is read
        ck.err(f"[growth] law = \"contractility\" needs the chemistry of solver.kind = \"time\" "
               f"(this scene has kind = \"{kind}\"); use law = \"uniform\" or \"inner_region\"")


def _boundary_list(ck, raw, mesh, curves) -> list:
    """[[boundary]]: each condition's type, keys and curve."""
    curves = curves_of(mesh) if mesh.get("kind") in MESH_KEYS else None
    boundary = []
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
        boundary.append(entry)
    return boundary


def _load_list(ck, raw, mesh, curves, kind) -> list:
    """[[loads]]: each load's type, keys and curve."""
    loads = []
    l_raw = raw.get("loads", [])
    if isinstance(l_raw, dict):
        l_raw = [l_raw]
    if not isinstance(l_raw, list):
        ck.err("loads must be a list of tables: write each load as [[loads]]")
        l_raw = []
    if l_raw and kind in TIME_KINDS:
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
        loads.append(entry)
    return loads


def _continuation_consistency(ck, data, solver, law):
    """The continuation parameter against the growth, the loads and its range."""
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


def _solver_consistency(ck, data, kind, law):
    """What one section asks of another (the solver of the growth and loads, ranges of the parameter)."""
    solver, mesh = data["solver"], data["mesh"]
    if kind in ("static", "linear-buckling"):
        if law in ("none", None) and not data["loads"]:
            ck.err(f"solver.kind = \"{kind}\" with no growth and no [[loads]] has nothing to solve: the rest "
                   "shape is the answer")
    if kind == "linear-buckling" and solver.get("target") is not None and solver["target"] <= solver.get("at", 0.0):
        ck.err(f"[solver] target = {_fmt(solver['target'])} must be > at = {_fmt(solver.get('at', 0.0))} (the "
               "factors searched lie beyond the state)")
    if kind == "continuation" and solver.get("parameter"):
        _continuation_consistency(ck, data, solver, law)
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
        gr = data["growth"]
        start = continuation_start(solver["parameter"], solver.get("start"), gr.get("strain"), gr.get("inner_radius"))
        stop = solver["stop"]
        if start is not None and start == stop:
            given = "start" if solver.get("start") is not None else f"the start ({solver['parameter']})"
            ck.err(f"[solver] stop = {_fmt(stop)} equals {given} = {_fmt(start)}: nothing to follow")
    if kind in TIME_KINDS:
        st = solver
        if all(st.get(k) is not None for k in ("dt_min", "dt_max")) and st["dt_max"] < st["dt_min"]:
            ck.err(f"[solver] dt_max = {_fmt(st['dt_max'])} is out of range: dt_min = {_fmt(st['dt_min'])} <= dt_max")
        if all(st.get(k) is not None for k in ("dt_min", "dt_max", "dt_initial")) and \
                not st["dt_min"] <= st["dt_initial"] <= st["dt_max"]:
            ck.err(f"[solver] dt_initial = {_fmt(st['dt_initial'])} is out of range: dt_min <= dt_initial <= dt_max "
                   f"({_fmt(st['dt_min'])} .. {_fmt(st['dt_max'])})")


def _output_section(ck, raw, data, kind):
    """[output]: fields, picture field and colour map against what the scene has."""
    data["output"] = ck.section("[output]", raw.get("output", {}), SECTIONS["output"])
    out = data["output"]
    have = [f for f, (_, scope, _) in FIELDS.items() if scope == "any" or scope == kind
            or (scope == "time" and kind in TIME_KINDS)]
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
        out["picture_field"] = "c" if kind in TIME_KINDS else "displacement"
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


def validate(raw: dict, *, name: str, label: str, source=None, base_dir=None, check_files=True) -> Scene:
    """Check a raw scene dict completely; returns a :class:`Scene` with all defaults filled in.

    Raises :class:`SceneError` with one line per problem found (all of them, not only the first).
    ``check_files=False`` resolves a mesh file's path without requiring the file (to compare a
    stored scene whose mesh has moved since).
    """
    ck = _Checker(label)
    base_dir = Path(base_dir) if base_dir is not None else (Path(source).parent if source else Path.cwd())
    data = _top_keys(ck, raw, name)
    data["solver"] = solver = _solver_section(ck, raw)
    kind = solver["kind"]
    data["mesh"] = mesh = _mesh_section(ck, raw, base_dir, check_files)
    data["material"] = ck.section("[material]", raw.get("material", {}), SECTIONS["material"])
    if "shell" not in raw:
        ck.err("[shell] is missing: give at least thickness = h (> 0)")
        data["shell"] = ck.section("[shell]", {"thickness": 1.0}, SECTIONS["shell"])
    else:
        data["shell"] = ck.section("[shell]", raw["shell"], SECTIONS["shell"])
    law = _growth_section(ck, raw, data, kind)
    _time_sections(ck, raw, data, kind, law)
    curves = curves_of(mesh) if mesh.get("kind") in MESH_KEYS else None
    data["boundary"] = _boundary_list(ck, raw, mesh, curves)
    data["loads"] = _load_list(ck, raw, mesh, curves, kind)
    _solver_consistency(ck, data, kind, law)
    _output_section(ck, raw, data, kind)

    if ck.errors:
        raise SceneError(ck.errors)
    given = tuple(k for k in raw if k in TOP_KEYS)
    return Scene(name=data["name"], data=data, source=Path(source) if source else None, label=label,
                 base_dir=base_dir, given=given)
