"""Scene text: reading a scene's TOML, ``--set`` overrides and writing a scene back as TOML.

Overrides (``femshell run SCENE --set solver.t_final=5``): ``section.key=value`` where
value is TOML (``3``, ``0.5``, ``true``, ``"text"``, ``[1, 2]``) or a bare word taken as
a string (``--set mesh.kind=disk``); ``boundary.0.curve=left`` reaches into the list of
tables. Setting ``mesh.n_vertices`` drops a ``mesh.edge_length`` of the file and vice
versa, so that a scene can always be made smaller from the command line.
"""

from __future__ import annotations

import copy
import math
import re
try:
    import tomllib
except ImportError:  # Python 3.10
    import tomli as tomllib

from .config import _fmt

__all__ = ["SceneError", "parse_scene", "parse_override", "apply_overrides", "dump_toml", "tomllib"]


class SceneError(ValueError):
    """A scene that cannot be run; ``errors`` holds one line per problem."""

    def __init__(self, errors):
        if isinstance(errors, str):
            errors = [errors]
        self.errors = list(errors)
        super().__init__("\n".join(self.errors))


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


def parse_scene(text: str, label: str) -> dict:
    """The raw TOML dict of a scene text; syntax errors become a :class:`SceneError`."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{label}: not valid TOML: {exc}") from None


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


def _merge_tables(old: dict, new: dict) -> dict:
    """``old`` with ``new``'s keys set (tables inside merged the same way)."""
    out = dict(old)
    for k, v in new.items():
        out[k] = _merge_tables(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def apply_overrides(raw: dict, overrides, label="scene", *, note=True) -> dict:
    """A copy of ``raw`` with ``overrides`` (list of "key=value" or (parts, value)) applied.

    A table value merges into the table it replaces (``material={E=2}`` sets E and keeps the
    section's other keys), as ``material.E=2`` does.

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
        if isinstance(value, dict) and isinstance(where.get(last), dict):
            where[last] = _merge_tables(where[last], value)    # a table sets its keys, the others are kept
        else:
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


# ----------------------------------------------------------------------------- TOML writer

def _toml_key(k):
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
