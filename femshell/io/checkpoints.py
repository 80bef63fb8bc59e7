"""Checkpoints: one ``.npz`` (no pickle) of state arrays with a JSON header; the previous one kept
as ``<path>.prev`` and read back when the current one is corrupt (never rotated when it failed to read)."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import warnings
import zipfile
from pathlib import Path

import numpy as np

from .files import _fsync, _nonfinite_name, _raise_for_target, _tmp_name, to_json_safe

CHECKPOINT_FORMAT = "femshell-checkpoint"
CHECKPOINT_VERSION = 1
_HEADER_KEY = "__femshell_header__"


class CheckpointError(ValueError):
    """A checkpoint file is missing, unreadable or not a femshell checkpoint."""


def _prev_path(path: Path) -> Path:
    return path.with_name(path.name + ".prev")


#: checkpoints this process wrote (and verified), by resolved path -> their (inode, size, mtime):
#: rotating one into ``.prev`` needs no second read
_VERIFIED: dict = {}


def _signature(path: Path) -> tuple:
    st = path.stat()
    return st.st_ino, st.st_size, st.st_mtime_ns


def _readable(path: Path) -> bool:
    """Whether ``path`` is a readable checkpoint (one this process wrote and nobody changed since, or
    one that reads back)."""
    if _VERIFIED.get(str(path.resolve())) == _signature(path):
        return True
    try:
        _read_checkpoint(path)
    except (CheckpointError, OSError):
        return False
    return True


def save_checkpoint(path, state: dict, meta: dict | None = None) -> Path:
    """Save a checkpoint atomically; the checkpoint it replaces is kept as ``<path>.prev``.

    ``state``: name -> numpy array, float, int, bool or str (names must not start
    with "__"). Float values must be finite (ValueError naming the key otherwise).
    ``meta``: JSON-serialisable dict (time, step, scene, parameters ...; no NaN).
    The file is an uncompressed ``.npz`` (readable without pickle) with the meta as
    JSON inside. Sequence: new file complete in a temporary file -> the current
    checkpoint is linked (or copied) to ``.prev`` atomically -> the new file replaces
    the current one. At every instant ``path`` is a complete checkpoint. A current file
    that does not read (the one a resume fell back from) is replaced without becoming
    ``.prev``: the readable ``.prev`` stays the fallback.
    """
    path = Path(path)
    if path.suffix != ".npz":
        raise ValueError(f"checkpoint path must end in .npz, got {path.name}")
    if not isinstance(state, dict):
        raise TypeError(f"state must be a dict, got {type(state).__name__}")
    if meta is not None and not isinstance(meta, dict):
        raise TypeError(f"meta must be a dict, got {type(meta).__name__}")
    kinds, arrays = {}, {}
    for k, v in state.items():
        if not isinstance(k, str) or not k or k.startswith("__"):
            raise ValueError(f"checkpoint state keys must be non-empty strings not starting with '__', got {k!r}")
        if isinstance(v, (bool, np.bool_)):
            kinds[k], a = "bool", np.asarray(bool(v))
        elif isinstance(v, (int, np.integer)):
            if not -2**63 <= int(v) < 2**63:
                raise ValueError(f"checkpoint state '{k}' = {v} does not fit in 64 bits")
            kinds[k], a = "int", np.asarray(int(v), dtype=np.int64)
        elif isinstance(v, (float, np.floating)):
            kinds[k], a = "float", np.asarray(float(v))
        elif isinstance(v, str):
            kinds[k], a = "str", np.asarray(v)
        elif isinstance(v, np.ndarray):
            kinds[k], a = "array", v
            if a.dtype.kind not in "biufcUS":
                raise TypeError(f"checkpoint state '{k}' has dtype {a.dtype}; only numeric, bool and "
                                "string arrays are stored (no pickle)")
        else:
            raise TypeError(f"checkpoint state '{k}' is a {type(v).__name__}; store numpy arrays, "
                            "numbers or strings")
        if a.dtype.kind in "fc" and not np.all(np.isfinite(a)):
            bad = a[~np.isfinite(a)].flat[0]
            raise ValueError(f"{path.name}: state '{k}' holds non-finite values ({_nonfinite_name(bad)}); "
                             "refusing to checkpoint a broken state")
        arrays[k] = a
    header = {"format": CHECKPOINT_FORMAT, "version": CHECKPOINT_VERSION, "kinds": kinds,
              "meta": to_json_safe(meta or {}, where=f"{path.name} meta")}
    arrays[_HEADER_KEY] = np.frombuffer(json.dumps(header, allow_nan=False).encode("utf-8"), dtype=np.uint8)

    if path.is_dir():
        raise ValueError(f"checkpoint path {path} is a directory")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _tmp_name(path)
    try:
        with open(tmp, "wb") as f:
            np.savez(f, **arrays)
            f.flush()
            os.fsync(f.fileno())
        _read_checkpoint(tmp)   # verify what was written before it replaces anything
        if path.exists() and _readable(path):
            prev, prev_tmp = _prev_path(path), _tmp_name(_prev_path(path))
            try:
                os.link(path, prev_tmp)
            except OSError:
                shutil.copy2(path, prev_tmp)
            os.replace(prev_tmp, prev)
        os.replace(tmp, path)
        _VERIFIED[str(path.resolve())] = _signature(path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        _raise_for_target(exc, tmp, path)
        raise
    _fsync(path.parent)
    return path


def _read_checkpoint(path: Path):
    try:
        # our own handle: np.load leaks the one it opens when the file is not an archive
        with open(path, "rb") as fh:
            # anything but a zip archive would reach np.load's pickle branch and its advice to unpickle
            if fh.read(4) != b"PK\x03\x04":
                raise CheckpointError(f"{path}: not a femshell checkpoint (not an .npz archive)")
            fh.seek(0)
            with np.load(fh, allow_pickle=False) as z:
                if _HEADER_KEY not in z.files:
                    raise CheckpointError(f"{path}: not a femshell checkpoint (no header)")
                header = json.loads(bytes(z[_HEADER_KEY]).decode("utf-8"))
                if not isinstance(header, dict) or not isinstance(header.get("kinds"), dict):
                    raise CheckpointError(f"{path}: not a femshell checkpoint (malformed header)")
                if header.get("format") != CHECKPOINT_FORMAT:
                    raise CheckpointError(f"{path}: not a femshell checkpoint (format {header.get('format')!r})")
                if header.get("version", 0) > CHECKPOINT_VERSION:
                    raise CheckpointError(f"{path}: checkpoint version {header.get('version')} is newer than "
                                          f"this femshell reads ({CHECKPOINT_VERSION})")
                kinds = header["kinds"]
                missing = sorted(set(kinds) - set(z.files))
                if missing:
                    raise CheckpointError(f"{path}: state entries missing: {', '.join(missing)}")
                state = {}
                for k, kind in kinds.items():
                    a = z[k]   # reading each member checks its CRC
                    if kind == "array":
                        state[k] = a
                    elif kind == "float":
                        state[k] = float(a)
                    elif kind == "int":
                        state[k] = int(a)
                    elif kind == "bool":
                        state[k] = bool(a)
                    elif kind == "str":
                        state[k] = str(a)
                    else:
                        raise CheckpointError(f"{path}: unknown kind {kind!r} of state '{k}'")
                return state, header.get("meta", {})
    except CheckpointError:
        raise
    except FileNotFoundError:
        raise
    except (zipfile.BadZipFile, OSError, ValueError, KeyError, EOFError, json.JSONDecodeError,
            UnicodeDecodeError, TypeError) as e:
        raise CheckpointError(f"{path}: corrupt or unreadable checkpoint ({type(e).__name__}: {e})") from None


def load_checkpoint(path) -> tuple[dict, dict]:
    """Load ``(state, meta)`` saved by :func:`save_checkpoint`.

    If ``path`` is corrupt (truncated, bad CRC, not a checkpoint) or missing while
    ``<path>.prev`` exists, the previous checkpoint is loaded instead with a
    RuntimeWarning (the resumed run then repeats the steps after that checkpoint).
    Raises FileNotFoundError when neither exists and CheckpointError (a ValueError)
    when no readable checkpoint is left.
    """
    path = Path(path)
    prev = _prev_path(path)
    if not path.exists() and not prev.exists():
        raise FileNotFoundError(f"{path}: no checkpoint (and no {prev.name}) to resume from")
    try:
        return _read_checkpoint(path)
    except (CheckpointError, FileNotFoundError) as e:
        first = e if path.exists() else FileNotFoundError(f"{path}: missing")
        if not prev.exists():
            raise
    try:
        state, meta = _read_checkpoint(prev)
    except CheckpointError as e2:
        raise CheckpointError(f"no readable checkpoint: {first}; and {e2}") from None
    warnings.warn(f"{first}; loaded the previous checkpoint {prev.name} instead", RuntimeWarning, stacklevel=2)
    return state, meta
