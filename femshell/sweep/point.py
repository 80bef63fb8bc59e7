"""One point of a sweep, run on a Dask worker: an ordinary run directory made by :func:`femshell.scene.run_scene`.

:func:`run_point` is what the client submits. It starts the point's run, or resumes it from its
checkpoint when the directory holds one (a worker killed mid-point, a sweep stopped and resumed),
and returns a small record for the manifest: the run's exit code, status and message, the worker,
the wall time of this attempt. The run's own progress goes to ``run.log`` in its directory.

A running point stops at its next step (status "interrupted", checkpoint written) when the client
cancels its task (Ctrl-C of ``femshell sweep``): a watcher thread reads the task's state on the
worker and raises the run's interrupt flag (:func:`femshell._interrupts.request_interrupt`).
"""

from __future__ import annotations

import os
import socket
import time
import traceback
from pathlib import Path

from .. import _interrupts, _periodic as periodic
from ..config import configure
from ..scene import run_scene
from ..scene.rundir import CHECKPOINT, RunDir, RunDirError

LOG = "run.log"
#: seconds between two looks of the watcher at the task's state
WATCH_INTERVAL = 0.5


def _worker():
    """(this worker's address or host:pid, a function telling whether the current task was cancelled)."""
    try:
        from distributed import get_worker      # deferred: dask (only a worker has one)

        w = get_worker()
        key = w.get_current_task()
    except (ImportError, ValueError):
        return f"{socket.gethostname()}:{os.getpid()}", lambda: False

    def cancelled():
        ts = w.state.tasks.get(key)
        return ts is None or ts.state in ("cancelled", "released", "forgotten")

    return w.address, cancelled


def _stop_when_cancelled(cancelled):
    """Raise the run's interrupt flag once ``cancelled()`` says so, while the block runs."""
    def watch():
        if cancelled():
            _interrupts.request_interrupt()
            return True
        return False

    return periodic.every(WATCH_INTERVAL, watch, name="femshell-sweep-watch")


def _start(path: Path) -> dict:
    """How to start the run in ``path``: resume its checkpoint, replace a run that never reached one, or new."""
    rd = RunDir(path)
    if (path / CHECKPOINT).exists() or (path / (CHECKPOINT + ".prev")).exists():
        return {"resume": True}
    return {"overwrite": rd.has_run()}


def run_point(path, scene, overrides) -> dict:
    """Run (or resume) the scene ``scene`` with ``overrides`` in the run directory ``path``.

    Returns {"code", "status", "message", "worker", "attempt_s", "resumed"}; never raises for a run
    that fails (its status says so): an error outside the run (bad input found late, a file that
    cannot be written) is returned as status "error" with its message.
    """
    configure(threads=1)                # the element kernels and MKL on the worker's one thread
    _interrupts.clear_interrupt()       # a cancelled earlier task of this process must not stop this one
    path = Path(path)
    path.mkdir(parents=True, exist_ok=True)
    worker, cancelled = _worker()
    how = _start(path)
    t0 = time.perf_counter()
    record = {"worker": worker, "resumed": bool(how.get("resume"))}
    with open(path / LOG, "a", encoding="utf-8") as log, _stop_when_cancelled(cancelled):
        print(f"== femshell sweep point on {worker} (pid {os.getpid()}): "
              f"{'resuming' if how.get('resume') else 'starting'}", file=log, flush=True)
        try:
            code = run_scene(scene, out=path, overrides=overrides, quiet=False, stream=log, **how)
        except (RunDirError, ValueError, OSError) as exc:
            print(f"error: {exc}", file=log)
            code, record["status"], record["message"] = 2, "error", str(exc)
        except Exception as exc:         # noqa: BLE001 - a bug: recorded with its traceback, the others go on
            traceback.print_exc(file=log)
            code, record["status"], record["message"] = 1, "error", f"{type(exc).__name__}: {exc}"
        except KeyboardInterrupt:       # a stop that came before the run installed its own handling
            code, record["status"], record["message"] = 130, "interrupted", "interrupted before the run started"
    summary = RunDir(path).summary() or {}
    record.setdefault("status", summary.get("status", "error"))
    record.setdefault("message", summary.get("message", "the run wrote no summary (see run.log)"))
    record.update(code=int(code), attempt_s=time.perf_counter() - t0)
    return record
