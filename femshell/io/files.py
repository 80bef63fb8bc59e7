"""Atomic files: write to a hidden temporary in the same directory, flush, then ``os.replace``;
JSON without NaN or infinity; generated blocks inside hand-written files; summary.json."""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import secrets
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np


SUMMARY_NAME = "summary.json"


def _tmp_name(path: Path) -> Path:
    suffix = "".join(path.suffixes[-1:])
    return path.with_name(f".{path.name}.tmp-{os.getpid()}-{secrets.token_hex(4)}{suffix}")


_TEMPORARY = re.compile(r"\.(?P<target>.+)\.tmp-(?P<pid>\d+)-[0-9a-f]{8}(\.\w+)?")


def temporary_of(name: str):
    """(target file name, writer's pid) of a temporary file named as :func:`atomic_path` names
    them, or None for any other name: what a writer killed mid-write leaves behind.

    >>> temporary_of(".summary.json.tmp-123-0a1b2c3d.json"), temporary_of("summary.json")
    (('summary.json', 123), None)
    """
    m = _TEMPORARY.fullmatch(name)
    return (m["target"], int(m["pid"])) if m else None


def finite_or_none(v):
    """``v`` for a JSON file: numpy scalars as Python numbers, NaN and infinity as None (null);
    other values unchanged.

    >>> finite_or_none(float("nan")), finite_or_none(np.float64(2.5)), finite_or_none(np.int64(3))
    (None, 2.5, 3)
    """
    if isinstance(v, (float, np.floating)):
        return float(v) if math.isfinite(v) else None
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, np.bool_):
        return bool(v)
    return v


def _fsync(path: Path) -> None:
    """Flush a file's data, or make a rename in a directory durable (best effort: not every file
    system allows opening a directory)."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _raise_for_target(exc: BaseException, tmp: Path, path: Path) -> None:
    """An OSError about the temporary file is raised again naming ``path``, the file the user asked for."""
    if isinstance(exc, OSError) and exc.filename is not None and Path(exc.filename) == tmp:
        raise type(exc)(exc.errno, f"{exc.strerror} (a new {path.name} is written next to it first)",
                        str(path)) from exc


@contextlib.contextmanager
def atomic_path(path) -> Iterator[Path]:
    """Context manager: yields a temporary path next to ``path``; on normal exit it replaces ``path``.

    Write the complete file to the yielded path inside the ``with`` block. If the
    block raises, the temporary file is deleted and ``path`` is left untouched.
    The temporary path keeps the extension of ``path`` (``x.png`` -> ``.x.png.tmp-..-...png``)
    so libraries that pick the format from the extension work.

    >>> import tempfile, os
    >>> p = os.path.join(tempfile.mkdtemp(), "a.txt")
    >>> with atomic_path(p) as tmp:
    ...     _ = open(tmp, "w").write("hello")
    >>> open(p).read()
    'hello'
    """
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{path} is a directory; cannot write a file there")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _tmp_name(path)
    try:
        yield tmp
        if not tmp.exists():
            raise OSError(f"{path}: the writer did not create the temporary file {tmp.name}")
        _fsync(tmp)
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        _raise_for_target(exc, tmp, path)
        raise
    _fsync(path.parent)


def atomic_write(path, writer: Callable[[Path], Any]) -> Path:
    """Write ``path`` atomically: ``writer(tmp_path)`` writes the whole file, then it replaces ``path``.

    If ``writer`` raises (or the process dies), ``path`` keeps its old content and the
    temporary file is removed (when the process survives). Returns ``Path(path)``.
    """
    with atomic_path(path) as tmp:
        writer(tmp)
    return Path(path)


def atomic_write_text(path, text: str, encoding: str = "utf-8") -> Path:
    """Write a text file atomically (see :func:`atomic_write`)."""
    def w(tmp):
        with open(tmp, "w", encoding=encoding) as f:
            f.write(text)
    return atomic_write(path, w)


def check_writable_dir(path, what: str) -> Path:
    """Make ``path`` a directory (with parents) and check that files can be created in it, or a
    ValueError naming ``what`` (a command-line option): before hours of computing, not after."""
    import tempfile

    path = Path(path)
    if path.exists() and not path.is_dir():
        raise ValueError(f"{what} {path} is a file, not a directory: choose a directory")
    try:
        path.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=path).close()
    except OSError as exc:
        raise ValueError(f"{what} {path}: cannot write there ({exc.strerror or exc})") from None
    return path


def check_generated(path, begin: str, end: str) -> str:
    """The text of a page whose generated part lies between the marker lines ``begin`` and
    ``end``; ValueError naming the file when it cannot be read or a marker is missing. Scripts
    call it before computing, so that a wrong page is reported at once, not after the run."""
    path = Path(path)
    try:
        doc = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ValueError(f"{path}: cannot read the page whose table is to be rewritten ({exc.strerror})") from None
    if begin not in doc or end not in doc:
        raise ValueError(f"{path}: no generated-part markers ({begin} ... {end})")
    return doc


def replace_generated(path, begin: str, end: str, text: str) -> Path:
    """Replace what lies between the marker lines ``begin`` and ``end`` of a text file (a page
    whose tables a script generates) by ``text``, atomically; the markers stay. ValueError
    naming the file when it cannot be read or a marker is missing (:func:`check_generated`)."""
    path = Path(path)
    doc = check_generated(path, begin, end)
    head, rest = doc.split(begin, 1)
    tail = rest.split(end, 1)[1]
    return atomic_write_text(path, f"{head}{begin}\n{text}\n{end}{tail}")


def _key_path(parent: str, key) -> str:
    if isinstance(key, int):
        return f"{parent}[{key}]"
    return f"{parent}.{key}" if parent else str(key)


def to_json_safe(obj, where: str = "", _path: str = ""):
    """``obj`` converted to plain JSON types, refusing NaN and infinity.

    numpy scalars and arrays become Python numbers and lists, ``Path`` becomes
    ``str``, tuples become lists, dict keys must be ``str`` (int/float/bool keys
    are converted as ``json`` would). Raises ValueError ``"<where>: <key path> is NaN"``
    (or ``inf``/``-inf``) and TypeError for objects JSON cannot hold, naming the key path
    (``rows[3].value``; ``where`` is usually the file name).
    """
    label = (lambda p: f"{where}: {p or '(top level)'}") if where else (lambda p: p or "(top level)")
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        if not math.isfinite(v):
            raise ValueError(f"{label(_path)} is {_nonfinite_name(v)}; result files never hold NaN or "
                             "infinity (store null, or leave the entry out)")
        return v
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, dict):
        out = {}
        for k, v in obj.items():
            if isinstance(k, (bool, np.bool_)):
                k = "true" if k else "false"
            elif isinstance(k, (int, np.integer)):
                k = str(int(k))
            elif isinstance(k, (float, np.floating)):
                k = repr(float(k))
            elif not isinstance(k, str):
                raise TypeError(f"{label(_path)} has a key {k!r} of type {type(k).__name__}; "
                                "JSON keys must be strings")
            if k in out:        # {1: .., "1": ..}: json.dumps would write the key twice, a reader keeps one
                raise ValueError(f"{label(_path)} has two keys that are both {k!r} in JSON")
            out[k] = to_json_safe(v, where, _key_path(_path, k))
        return out
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind in "fiubUS":
            return to_json_safe(obj.tolist(), where, _path)
        raise TypeError(f"{label(_path)} is an array of dtype {obj.dtype}, not JSON-serialisable")
    if isinstance(obj, (list, tuple)):
        return [to_json_safe(v, where, _key_path(_path, i)) for i, v in enumerate(obj)]
    if isinstance(obj, complex):
        raise TypeError(f"{label(_path)} is a complex number, not JSON-serialisable")
    raise TypeError(f"{label(_path)} is a {type(obj).__name__}, not JSON-serialisable")


def _nonfinite_name(v) -> str:
    v = complex(v)
    if math.isnan(v.real) or math.isnan(v.imag):
        return "NaN"
    x = v.real if math.isinf(v.real) else v.imag
    return "inf" if x > 0 else "-inf"


def atomic_write_json(path, obj, indent: int | None = 1) -> Path:
    """Write ``obj`` as JSON atomically; refuses NaN/inf naming the key path.

    Example of the error: ``ValueError: summary.json: rows[3].value is NaN; ...``.
    The file is validated completely before anything is written.
    """
    path = Path(path)
    safe = to_json_safe(obj, where=path.name)
    text = json.dumps(safe, indent=indent, allow_nan=False, ensure_ascii=False) + "\n"
    return atomic_write_text(path, text)


def write_summary(out_dir, summary: dict) -> Path:
    """Write ``out_dir/summary.json`` atomically (no NaN/inf; see :func:`atomic_write_json`)."""
    if not isinstance(summary, dict):
        raise TypeError(f"summary must be a dict, got {type(summary).__name__}")
    return atomic_write_json(Path(out_dir) / SUMMARY_NAME, summary)
