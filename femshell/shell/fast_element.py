r"""The element energy, gradient and Hessian of :mod:`femshell.shell.element` as compiled C, in parallel
over chunks of elements. The Hessian by the same split as there,

.. math::  \nabla^2 W = J^T \frac{\partial^2 W}{\partial z^2} J
           + \sum_{ij} \frac{\partial W}{\partial a_{ij}} \nabla^2 a_{ij}
           + \sum_k \frac{\partial W}{\partial q_k} \nabla^2 q_k,

the energy and gradient :math:`\nabla W = J^T \partial W/\partial z` alone by the reverse sweeps
(:func:`energies_and_gradients`, the same bits as :func:`hessians` gives them),
with the value, gradient and Hessian of each :math:`q_k` and of W(z) generated as straight-line
code (:mod:`femshell.shell.kernel_codegen`). Equal to the JAX kernels up to rounding (the tests
compare them); the JAX path stays the reference (``ShellModel(..., gradient_kernel="jax", hessian_kernel="jax")``).

The source is compiled once by the system's C compiler (``$CC``, default ``cc``; about a second)
into the kernel cache directory (:func:`femshell.config.default_kernel_cache_dir`), under a name
that hashes the source and the command, and loaded with ctypes, which releases the GIL during a
call: chunks on several threads run in parallel. Without a working compiler :func:`library` says
why and the element falls back to JAX.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shlex
import subprocess
import tempfile
import threading
import warnings

import numpy as np

from ..config import default_kernel_cache_dir
from . import kernel_codegen

#: compiler flags: optimised, position independent, no fast-math (the results must match JAX's rounding;
#: -fno-math-errno changes no result, it lets sqrt be inlined: 14 % faster)
CFLAGS = ("-O2", "-fno-math-errno", "-std=c99", "-shared", "-fPIC")
#: elements per call (one task of the thread pool)
CHUNK = 2048
LAWS = {"svk": 0, "neo-hookean": 1}

_state = {"lib": None, "error": None, "lock": threading.Lock()}


def compile_command(source_path, library_path):
    """The compiler command: ``$CC`` (default ``cc``) with :data:`CFLAGS`."""
    return shlex.split(os.environ.get("CC", "cc")) + list(CFLAGS) + ["-o", str(library_path), str(source_path), "-lm"]


def library_path():
    """Where the compiled kernel of this source and compiler command lives (it may not exist yet)."""
    source = kernel_codegen.source()
    key = hashlib.sha256((source + " ".join(compile_command("S", "L"))).encode()).hexdigest()[:16]
    return default_kernel_cache_dir() / f"element-hessian-{key}.so", source


def _build():
    path, source = library_path()
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(dir=path.parent) as tmp:
            src, lib = os.path.join(tmp, "kernel.c"), os.path.join(tmp, "kernel.so")
            with open(src, "w") as f:
                f.write(source)
            try:
                done = subprocess.run(compile_command(src, lib), capture_output=True, text=True)
            except FileNotFoundError as exc:
                raise OSError(f"no C compiler to build the element kernel ({exc}); set CC to one") from None
            if done.returncode != 0:
                raise OSError(f"compiling the element kernel failed ({' '.join(compile_command(src, lib))}): "
                              f"{done.stderr.strip()[-500:]}")
            os.replace(lib, path)                  # atomic: a concurrent process loads a whole file or builds its own
    lib = ctypes.CDLL(str(path))
    ptr = ctypes.c_void_p
    head = [ctypes.c_int64, ctypes.c_int64] + [ptr] * 5 + [ctypes.c_double] * 2 + [ptr] * 3 + [ctypes.c_int]
    lib.element_hessians.argtypes = head + [ptr, ptr, ptr]
    lib.element_gradients.argtypes = head + [ptr, ptr]
    for f in (lib.element_hessians, lib.element_gradients):
        f.restype = None
    return lib


def library():
    """The loaded kernel library (compiled on first use), or None when it cannot be built; then
    :func:`unavailable` says why."""
    with _state["lock"]:
        if _state["lib"] is None and _state["error"] is None:
            try:
                _state["lib"] = _build()
            except (OSError, subprocess.SubprocessError) as exc:
                _state["error"] = str(exc)
                warnings.warn(f"{exc}: element gradients and Hessians by JAX instead (slower)", RuntimeWarning, stacklevel=2)
        return _state["lib"]


def unavailable():
    """Why the compiled kernel cannot be used (a sentence), or None when it can."""
    library()
    return _state["error"]


def hessians(law, q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign, executor=None,
             with_gradients=False):
    """Element Hessians (m, 21, 21) of :func:`femshell.shell.element.element_energy` with membrane law
    ``law`` ("svk" or "neo-hookean"), arguments batched as for :class:`~femshell.shell.element.Kernels`;
    chunks of :data:`CHUNK` elements run on ``executor`` (a thread pool) when given. Each element's
    Hessian is computed alone: the same bits for any chunking or thread count.
    ``with_gradients``: (energies (m,), gradients (m, 21), Hessians) instead."""
    m = len(q)
    out = np.empty((m, 21, 21))
    energies, gradients = (np.empty(m), np.empty((m, 21))) if with_gradients else (None, None)
    _run("element_hessians", law, (q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign),
         [out.ctypes.data, None if energies is None else energies.ctypes.data,
          None if gradients is None else gradients.ctypes.data], executor)
    return (energies, gradients, out) if with_gradients else out


def energies_and_gradients(law, q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign, executor=None):
    """Element energies (m,) and gradients (m, 21), as :func:`hessians` with ``with_gradients`` gives them (the
    same bits) at a fraction of its cost: no Hessian is formed."""
    m = len(q)
    energies, gradients = np.empty(m), np.empty((m, 21))
    _run("element_gradients", law, (q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign),
         [energies.ctypes.data, gradients.ctypes.data], executor)
    return energies, gradients


def _run(entry, law, args, outputs, executor):
    """Call the library's ``entry`` on chunks of the batched element ``args``, writing into ``outputs`` (pointers)."""
    lib = library()
    if lib is None:
        raise RuntimeError(f"the compiled element kernel is unavailable: {_state['error']}")
    q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign = args
    m = len(q)
    f64 = np.float64
    q, abar_inv, bbar = (np.ascontiguousarray(a, f64) for a in (q, abar_inv, bbar))
    area, hbar = (np.ascontiguousarray(np.broadcast_to(np.asarray(a, f64), (m,))) for a in (area, hbar))
    kind = np.ascontiguousarray(kind, np.int64)
    direction = np.ascontiguousarray(direction, f64)
    sign = np.ascontiguousarray(np.broadcast_to(np.asarray(sign, f64), (m, 3)))
    pointers = [a.ctypes.data for a in (q, abar_inv, bbar, area, hbar)]
    rest = [kind.ctypes.data, direction.ctypes.data, sign.ctypes.data, LAWS[law], *outputs]
    call = getattr(lib, entry)

    def run(start):
        call(start, min(m, start + CHUNK), *pointers, float(alpha), float(beta), *rest)

    starts = range(0, m, CHUNK)
    if executor is not None and len(starts) > 1:
        list(executor.map(run, starts))
    else:
        for s in starts:
            run(s)
