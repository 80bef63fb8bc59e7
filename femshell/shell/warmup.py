"""Compiling every element kernel a run uses once, ahead of the first run (``femshell warmup``).

The C element Hessian (:mod:`femshell.shell.fast_element`) is built into the kernel cache and the
JAX kernels (energy, energy and gradient, energy parts, fundamental forms) of each membrane law are
compiled for both of their chunk shapes (:func:`femshell.shell.element._batched`), which JAX keeps in
its persistent cache when :func:`femshell.configure` has set one. A later process loads them instead
of compiling: no mesh size compiles anything anew.
"""

from __future__ import annotations

import time

import numpy as np

from ..mesh.generators import sphere
from . import element as el
from . import fast_element
from .materials import MEMBRANE_LAWS, Material
from .model import ShellModel
from .rest_state import flat_rest_state

#: vertices of the warm-up sphere: between CHUNK and 2 CHUNK - CHUNK_SMALL elements, so that one big
#: chunk and several small ones are evaluated
WARMUP_VERTICES = 3000


def warm_up(laws=tuple(MEMBRANE_LAWS)) -> list:
    """Compile (or load) the element kernels; returns [(what, wall seconds), ...]. The C kernel's
    entry is skipped, with the reason, when no C compiler works (:func:`fast_element.unavailable`)."""
    done = []
    t = time.perf_counter()
    reason = fast_element.unavailable()
    done.append(("C element Hessian" if reason is None else f"C element Hessian unavailable ({reason})",
                 time.perf_counter() - t))
    mesh = sphere(radius=1.0, n_vertices=WARMUP_VERTICES)
    assert el.CHUNK < mesh.n_triangles < 2 * el.CHUNK - el.CHUNK_SMALL, mesh.n_triangles
    rng = np.random.default_rng(0)
    for law in laws:
        t = time.perf_counter()
        model = ShellModel(mesh, Material(1.0, 0.3, law=law), flat_rest_state(mesh.points, mesh.triangles, 0.1))
        u = model.initial_unknowns() + 1e-3 * rng.standard_normal(model.n_free)
        model.energy(u), model.energy_and_gradient(u), model.hessian(u)
        model.energy_parts(u), model.fundamental_forms(u)
        done.append((f"JAX kernels of the {law} law", time.perf_counter() - t))
    return done
