"""Running a sweep on Dask distributed: the output directory, the cluster, the points' tasks, Ctrl-C.

``DIR`` (``--out``, default ``./<spec name>-sweep``) holds ``manifest.json``, ``points/<key>/`` (one
ordinary run directory per point, see :mod:`femshell.scene.runner`), ``results.csv`` (+ ``.parquet``),
``phase_diagram.png`` and ``contact_sheet.png``.

* Each point is one task, :func:`femshell.sweep.point.run_point`, on a worker process with one thread
  (the element kernels and MKL told so). The default cluster is a ``LocalCluster`` with one worker per
  CPU (at most one per point to run); ``scheduler`` names an existing cluster's scheduler instead,
  whose workers must run one thread each (``dask worker --nthreads 1``) and see ``DIR``.
* A worker that dies mid-point (``kill -9``) loses at most the step in progress: Dask runs the task
  again on a worker, which resumes the point from its checkpoint. A point that fails is recorded and
  the others go on.
* ``resume``: a sweep killed or stopped (the client by ``kill -9``, Ctrl-C) continues: the spec must
  give the same points; finished points are skipped, failed ones too unless ``retry_failed``, the
  others resume from their checkpoints. Without ``resume`` a ``DIR`` holding a sweep is refused.
* Ctrl-C (or SIGTERM) cancels the points' tasks; each running point stops at its next step with a checkpoint
  (waited for up to ``STOP_GRACE_S``; a second Ctrl-C stops waiting), then the cluster is closed and
  the manifest says "interrupted" for them. Exit codes: 0 every point finished, 1 some failed,
  130 interrupted.
"""

from __future__ import annotations

import contextlib
import logging
import sys
import time
import uuid
from pathlib import Path

from .._interrupts import interruptible
from ..scene.rundir import LOCK, RunDir, RunDirError, pid_alive
from .point import run_point
from .table import (MANIFEST, POINTS, new_manifest, point_state, read_manifest, rows, write_manifest,
                    write_results)

#: seconds a Ctrl-C waits for the running points to write their checkpoint and stop
STOP_GRACE_S = 60.0
#: the thread settings of a local worker's process, set before it starts (MKL reads its variable once)
WORKER_ENV = {"FEMSHELL_THREADS": "1", "MKL_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}


def default_out(spec) -> Path:
    return Path(f"{Path(spec.label).stem}-sweep")


def _prepared_manifest(spec, out: Path, resume: bool) -> dict:
    """The manifest to run from: a new one, or (``resume``) the one in ``out`` after checking it is this sweep."""
    old = read_manifest(out)
    if old is None:
        if resume:
            raise RunDirError(f"{out}: nothing to resume (no {MANIFEST}); start the sweep without --resume")
        if out.is_dir() and any(f.name != LOCK for f in out.iterdir()):
            raise RunDirError(f"{out} is not empty and holds no sweep: choose another --out")
        return new_manifest(spec)
    if not resume:
        raise RunDirError(f"{out} already holds a sweep ({MANIFEST}); use --resume to continue it, or choose another "
                          "--out")
    ident = spec.as_dict()
    diffs = [k for k in ident if old.get(k) != ident[k]]
    if diffs:
        raise RunDirError(f"{out}: the sweep there was made with another spec ({', '.join(diffs)} differ), so it "
                          "cannot be resumed with this one: resume with its own spec, or choose another --out")
    old.update(measures=spec.measures, plot=list(spec.plot_axes), description=spec.description)
    return old


def _to_run(spec, manifest, retry_failed) -> list:
    skip = ("finished",) if retry_failed else ("finished", "failed")
    return [p for p in spec.points if manifest["state"][p.key]["status"] not in skip]


def _local_workers(n_points) -> int:
    from dask.system import CPU_COUNT       # deferred: dask; CPUs this process may use, within a container's limit

    return max(1, min(CPU_COUNT, n_points))


@contextlib.contextmanager
def _client(scheduler, workers, n_points):
    """A Dask client: of the cluster at ``scheduler``, or of a new LocalCluster (closed at the end)."""
    from distributed import Client, LocalCluster      # deferred: dask is a large import

    if scheduler:
        client = Client(scheduler, timeout="15s")
        try:
            threads = {w["id"] if "id" in w else a: w.get("nthreads", 1)
                       for a, w in client.scheduler_info()["workers"].items()}
            many = {k: n for k, n in threads.items() if n != 1}
            if many:
                raise RunDirError(f"--scheduler {scheduler}: femshell sweep runs one point per worker process; "
                                  f"start the workers with one thread (dask worker --nthreads 1); found "
                                  + ", ".join(f"{k}: {n} threads" for k, n in many.items()))
            yield client, f"the cluster at {scheduler} ({len(threads)} workers now)"
        finally:
            client.close()
        return
    n = workers or _local_workers(n_points)
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address=None, silence_logs=logging.ERROR, env=WORKER_ENV)
    client = Client(cluster)
    try:
        yield client, f"a local cluster of {n} worker process{'es' if n > 1 else ''} (one thread each)"
    finally:
        client.close()
        cluster.close()


def _line(p, rec, state) -> str:
    worker = rec.get("worker") or "?"
    return (f"{p.key}: {rec.get('status')} ({state}) in {rec.get('attempt_s', 0.0):.1f} s on {worker}"
            + (f": {rec['message']}" if state != "finished" and rec.get("message") else ""))


def _record(manifest, p, rec):
    st = manifest["state"][p.key]
    state = "failed" if rec.get("status") == "error" else point_state(rec.get("status", "error"))
    st.update(status=state, message=rec.get("message"), worker=rec.get("worker"), attempts=st.get("attempts", 0) + 1)
    return state


def _wait_for_stops(out, points, grace):
    """Wait until no point of ``points`` holds its run directory's lock (a live pid), for up to ``grace`` s."""
    end = time.monotonic() + grace
    while time.monotonic() < end:
        busy = []
        for p in points:
            lock = out / POINTS / p.key / LOCK
            with contextlib.suppress(OSError, ValueError):
                if lock.exists() and pid_alive(int(lock.read_text().strip() or "0")):
                    busy.append(p)
        if not busy:
            return
        time.sleep(0.5)


def _run_points(spec, out, manifest, todo, client, bar):
    """Submit the points, record each as it ends; returns the exit code (130 after Ctrl-C)."""
    from distributed import as_completed      # deferred: dask

    token = uuid.uuid4().hex[:8]
    futures = {}
    for p in todo:
        manifest["state"][p.key]["status"] = "submitted"      # to the scheduler: queued or running
        futures[client.submit(run_point, str(out / POINTS / p.key), spec.scene, p.overrides(spec.fixed),
                              key=f"femshell-{p.key}-{token}", pure=False)] = p
    write_manifest(out, manifest)
    left = dict(futures)
    try:
        for fut in as_completed(list(futures)):
            p = left.pop(fut)
            try:
                rec = fut.result()
            except Exception as exc:     # noqa: BLE001 - the task itself died (a worker lost too often)
                rec = {"status": "error", "message": f"{type(exc).__name__}: {exc}"}
            state = _record(manifest, p, rec)
            write_manifest(out, manifest)
            bar.update(1)
            bar.write(_line(p, rec, state), file=bar.fp)
    except KeyboardInterrupt:
        client.cancel(list(left))
        bar.write(f"interrupted: stopping {len(left)} point(s) at their next step (Ctrl-C again: stop now) ...",
                  file=bar.fp)
        with contextlib.suppress(KeyboardInterrupt):
            _wait_for_stops(out, left.values(), STOP_GRACE_S)
        for p in left.values():
            manifest["state"][p.key].update(status="interrupted", message="the sweep was interrupted")
        write_manifest(out, manifest)
        return 130
    return 0


def run_sweep(spec, out=None, *, scheduler=None, workers=None, resume=False, retry_failed=False, plot=True,
              stream=None) -> int:
    """Run the points of the validated ``spec`` (:func:`~femshell.sweep.load_spec`) into ``out``; the exit code.

    Raises :class:`~femshell.scene.RunDirError` (a ValueError, exit code 2) for an ``out`` or a cluster
    that cannot be used, before any point starts.
    """
    from tqdm import tqdm                     # deferred: only a sweep draws a progress bar

    stream = stream or sys.stdout
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise RunDirError(f"--workers must be a whole number >= 1, got {workers!r}")
    if workers is not None and scheduler:
        raise RunDirError("--workers sizes the local cluster; with --scheduler the cluster's own workers run the points")
    out = Path(out) if out else default_out(spec)
    if out.exists() and not out.is_dir():
        raise RunDirError(f"--out {out} is a file, not a directory")
    out = out.resolve()
    rd = RunDir(out)
    with rd.lock():
        manifest = _prepared_manifest(spec, out, resume)
        todo = _to_run(spec, manifest, retry_failed)
        write_manifest(out, manifest)
        done = sum(s["status"] == "finished" for s in manifest["state"].values())
        failed = len(spec.points) - done - len(todo)
        print(f"sweep {Path(spec.label).name}: {len(spec.points)} points of scene {spec.scene} ({spec.mode} of "
              f"{', '.join(spec.axes)}) into {out}/" + (f"; {done} finished" if done else "")
              + (f", {failed} failed (skipped; --retry-failed runs them again)" if failed else ""), file=stream,
              flush=True)
        code = 0
        if todo:
            with _client(scheduler, workers, len(todo)) as (client, what):
                print(f"running {len(todo)} point(s) on {what}", file=stream, flush=True)
                with tqdm(total=len(todo), unit="point", file=stream, dynamic_ncols=True, leave=False) as bar, \
                        interruptible():      # SIGTERM stops the sweep as Ctrl-C does
                    code = _run_points(spec, out, manifest, todo, client, bar)
        summary_code = finish(out, manifest, stream, plot=plot and code != 130)
    return code or summary_code


def finish(out, manifest, stream, *, plot=True) -> int:
    """Write the results table (and the plots); print the tally; 0 when every point finished, else 1."""
    table = rows(out, manifest)
    paths = write_results(out, table)
    if plot:
        from .plots import plot_sweep     # deferred: matplotlib

        try:
            paths += plot_sweep(out, manifest)
        except Exception as exc:      # noqa: BLE001 - the table is written; a plot that fails is a warning
            print(f"warning: the sweep's plots failed: {type(exc).__name__}: {exc}", file=sys.stderr)
    states = [s["status"] for s in manifest["state"].values()]
    tally = ", ".join(f"{states.count(s)} {s}" for s in ("finished", "failed", "interrupted", "submitted", "pending")
                      if states.count(s))
    print(f"points: {tally}; wrote {', '.join(str(Path(p).relative_to(out)) for p in paths)} in {out}/",
          file=stream, flush=True)
    return 0 if all(s == "finished" for s in states) else 1

