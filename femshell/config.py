"""Process settings, made explicitly: :func:`configure`.

Importing femshell changes nothing in the process: no environment variable, no ``jax.config``
entry. ``femshell`` (the CLI) calls :func:`configure` first; a script using the Python API calls
it once at its start, before numpy is imported, for the same settings::

    import femshell
    femshell.configure()                 # BLAS on one thread, JAX's compiled code kept on disk
    import numpy as np

By default the element kernels and MKL PARDISO use every CPU the process may use (a resumed
run then continues the uninterrupted one to round-off); ``configure(reproducible=True)``
(``femshell run --reproducible``) trades that speed for bit-for-bit repeatable runs.

The element kernels compute in float64 whether or not this is called (they switch on jax's
float64 mode, thread-locally, around each call: :func:`femshell.shell.element.float64`).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

#: where a container's CPU limit is read (cgroup v2, then v1)
CGROUP_CPU_FILES = (("/sys/fs/cgroup/cpu.max",), ("/sys/fs/cgroup/cpu/cpu.cfs_quota_us", "/sys/fs/cgroup/cpu/cpu.cfs_period_us"))

#: the environment of the reproducible mode (:func:`configure`): MKL's sequential layer in its strict
#: conditional-numerical-reproducibility mode, one thread for MKL and the element kernels
REPRODUCIBLE_ENV = {"MKL_THREADING_LAYER": "SEQUENTIAL", "MKL_CBWR": "AUTO,STRICT", "MKL_NUM_THREADS": "1",
                    "FEMSHELL_THREADS": "1"}

#: JAX keeps compiled code on disk when compiling it took at least this long (seconds)
JAX_CACHE_MIN_COMPILE_SECONDS = 0.5


def _user_cache_dir(variable: str, name: str) -> Path:
    """``$variable`` if set, else ``name`` in the user's cache directory (``$XDG_CACHE_HOME``, default ``~/.cache``)."""
    given = os.environ.get(variable, "").strip()
    if given:
        return Path(given).expanduser()
    base = os.environ.get("XDG_CACHE_HOME", "").strip() or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / name


def default_jax_cache_dir() -> Path:
    """``$FEMSHELL_JAX_CACHE`` if set, else ``femshell-jax`` in the user's cache directory
    (``$XDG_CACHE_HOME``, default ``~/.cache``)."""
    return _user_cache_dir("FEMSHELL_JAX_CACHE", "femshell-jax")


def default_kernel_cache_dir() -> Path:
    """Where the compiled C element kernel is kept (:mod:`femshell.shell.fast_element`):
    ``$FEMSHELL_KERNEL_CACHE`` if set, else ``femshell-kernels`` in the user's cache directory."""
    return _user_cache_dir("FEMSHELL_KERNEL_CACHE", "femshell-kernels")


def configure(*, blas_threads: int | None = 1, threads: int | None = None,
              jax_cache_dir: str | os.PathLike | None | bool = True, reproducible: bool = False) -> dict:
    """Apply femshell's process settings; returns what was set, ``{name: value}``.

    blas_threads : threads of numpy's own BLAS (OpenBLAS), set as ``OPENBLAS_NUM_THREADS``
        unless the environment already sets it; None leaves it alone. One thread by default: its
        vector products gain nothing from threads, and its idle workers spin after each one,
        taking a core from the sparse solves and element kernels. Takes effect only when set
        before numpy is imported.
    threads : CPUs for the element kernels and MKL (PARDISO): sets ``FEMSHELL_THREADS`` and
        ``MKL_NUM_THREADS`` (MKL reads it when it loads); None: as :func:`element_threads` finds.
    jax_cache_dir : where JAX keeps compiled element kernels between runs (compiling the Hessian
        takes seconds). True: :func:`default_jax_cache_dir`; a path: there; False or None: no
        cache. A cache directory already configured in JAX is kept.
    reproducible : bit-for-bit repeatable results, from one process to the next (a resumed run
        repeats the uninterrupted one exactly): MKL's sequential layer in its strict conditional
        numerical reproducibility mode (``MKL_THREADING_LAYER=SEQUENTIAL``,
        ``MKL_CBWR=AUTO,STRICT``) and one thread for MKL and the element kernels. It must be chosen
        before MKL is loaded (before the first factorisation): a ValueError otherwise. Without
        it, a large factorisation runs on every core and its last bits may differ between processes.

    >>> import os; old = dict(os.environ)
    >>> configure(blas_threads=None, threads=2, jax_cache_dir=False)
    {'FEMSHELL_THREADS': '2', 'MKL_NUM_THREADS': '2'}
    >>> os.environ.clear(); os.environ.update(old)
    """
    for name, value in (("blas_threads", blas_threads), ("threads", threads)):
        if value is not None:
            _check_count(name, value)
    if reproducible not in (True, False):
        raise ValueError(f"reproducible must be True or False, got {reproducible!r}")
    if reproducible and threads not in (None, 1):
        raise ValueError(f"reproducible runs use one thread; got threads={threads}")
    done = {}
    if reproducible:
        done.update(_reproducible())
    if blas_threads is not None:
        done["OPENBLAS_NUM_THREADS"] = os.environ.setdefault("OPENBLAS_NUM_THREADS", str(blas_threads))
    if threads is not None:
        for name in ("FEMSHELL_THREADS", "MKL_NUM_THREADS"):
            os.environ[name] = done[name] = str(threads)
    if jax_cache_dir not in (None, False):
        path = default_jax_cache_dir() if jax_cache_dir is True else Path(jax_cache_dir).expanduser()
        done.update(_jax_cache(str(path)))
    return done


def _reproducible() -> dict:
    """The environment of the reproducible mode (see :func:`configure`); refused once MKL is loaded otherwise."""
    pardiso = sys.modules.get("femshell.solvers.pardiso")    # not imported here: MKL is not loaded without it
    if pardiso is not None and not pardiso.mkl_reproducible_or_unloaded():
        raise ValueError("the reproducible mode must be chosen before the first factorisation (MKL is already "
                         "loaded in its threaded mode in this process): call femshell.configure(reproducible=True) "
                         "at the start of the process")
    os.environ.update(REPRODUCIBLE_ENV)
    return dict(REPRODUCIBLE_ENV)


def _check_count(name, value):
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ValueError(f"{name} must be a whole number >= 1 (threads), got {value!r}")


def _jax_cache(path: str) -> dict:
    """JAX's persistent compilation cache at ``path``: through ``jax.config`` once jax is imported,
    else through the variables jax reads when it is (so a command that never needs jax does not pay
    for importing it)."""
    if "jax" not in sys.modules:
        os.environ.setdefault("JAX_COMPILATION_CACHE_DIR", path)
        os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", str(JAX_CACHE_MIN_COMPILE_SECONDS))
        return {"JAX_COMPILATION_CACHE_DIR": os.environ["JAX_COMPILATION_CACHE_DIR"]}
    jax = sys.modules["jax"]
    if jax.config.jax_compilation_cache_dir is None:
        jax.config.update("jax_compilation_cache_dir", path)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", JAX_CACHE_MIN_COMPILE_SECONDS)
    return {"jax_compilation_cache_dir": jax.config.jax_compilation_cache_dir}


def element_threads() -> int:
    """How many chunks of elements the kernels evaluate at once, each on its own thread.

    ``FEMSHELL_THREADS`` if set; else the smaller of ``MKL_NUM_THREADS`` and ``OMP_NUM_THREADS``
    where set (what confines a process's linear algebra to one core confines the kernels too);
    else the CPUs this process may run on, within a container's CPU limit. Each chunk is one
    compiled call on fixed-size arrays, so the results are the same bit for bit at any count.
    """
    text = os.environ.get("FEMSHELL_THREADS", "").strip()
    if text:
        if not (text.isdigit() and int(text) >= 1):
            raise ValueError(f"FEMSHELL_THREADS = {text!r} must be a whole number >= 1 (threads)")
        return int(text)
    # the libraries' own variables as they read them: "2,1" (OpenMP's nested levels) is 2 at the top;
    # what they would ignore ("", "0", "many") is ignored here too
    given = [int(v) for v in (os.environ.get(n, "").split(",")[0].strip() for n in ("MKL_NUM_THREADS", "OMP_NUM_THREADS"))
             if v.isdigit() and int(v) >= 1]
    if given:
        return min(given)
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    quota = _cpu_quota()
    return max(1, min(cpus, quota)) if quota else cpus


def _cpu_quota():
    """Whole CPUs a container's CPU limit allows (``docker --cpus=2`` on a larger host: 2), None without one."""
    for files in CGROUP_CPU_FILES:
        try:
            fields = " ".join(Path(f).read_text().strip() for f in files).split()
        except (OSError, ValueError):
            continue
        try:
            quota, period = int(fields[0]), int(fields[1])      # v2 "max 100000" has no number: no limit
        except (ValueError, IndexError):
            return None
        return max(1, quota // period) if quota > 0 and period > 0 else None
    return None
