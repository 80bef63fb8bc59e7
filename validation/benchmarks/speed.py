"""Speed of the shell's hot paths, today's path against the new one side by side (issue 63).

On the sphere of the ``sphere-spots`` scene (R = 30, h = 2, ~25 000 vertices; ``--vertices`` for
another size), in a grown, buckled-looking state (:func:`shell_newton.grown_sphere`), one row per
quantity: CPU seconds of the process (``time.process_time``: all its threads) and wall seconds of
the old path and the new one, and their ratios old/new. The load average (``os.getloadavg``) is
printed before and after: on a shared machine quote CPU seconds and ratios, not wall time alone.

* element Hessian: the (m, 21, 21) element Hessians, JAX (grouped split Hessian) against the
  compiled C kernel (:mod:`femshell.shell.fast_element`); ``Hessian assembled``: plus the scatter
  into the CSR matrix (``ShellModel.hessian``); ``sparsity pattern``: the CSR pattern and scatter
  positions from all m k² element entries against from the m kn² node pairs; ``energy and
  gradient``: ``ShellModel.energy_and_gradient`` by JAX against the compiled reverse sweeps;
* set-up cold and warm (``--setup``): a fresh process importing femshell, meshing the sphere (gmsh),
  building the model (sparsity pattern; old: from the element entries) and evaluating energy,
  gradient and Hessian once; cold with
  empty JAX and kernel caches, warm from the ones the cold run left (with the split into mesh,
  model and first evaluation);
* ``--scaling [N ...]``: the element Hessian at 6k/12k/25k/50k vertices and the exponent p of
  a least-squares fit time ∝ vertices^p, old and new.

* ``--solve``: the linear-solver rows of :mod:`speed_solve` at the same size: PARDISO factorisation
  and refactorisation, two stable Newton solves with direct solves (old) and with the held factor
  as a Krylov preconditioner (new: factorisations, Krylov iterations, CPU per Newton iteration),
  and ``--coupled-steps`` steps of the coupled loop on both paths.
* ``--newton``: a Newton iteration (:mod:`speed_newton`): wall and CPU seconds per iteration of
  today's path (JAX element Hessian, a factorisation per iteration, MKL sequential) and the new
  ones (compiled Hessian and threads; direct and Krylov), each in a fresh process, with ratios and
  each part's share (element Hessian, assembly, factorisation, back-substitution, Krylov, line search).

    python validation/benchmarks/speed.py [--vertices 25000] [--setup] [--scaling [6000 12000 25000 50000]]
                                          [--solve [--coupled-steps 4]] [--newton]

More element-level rows are functions of the form ``section(model, u) -> [(label, old, new), ...]``
in :data:`SECTIONS`, with ``old``/``new`` the (cpu, wall) pairs of :func:`measure`.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import speed_newton  # noqa: E402
import speed_solve  # noqa: E402
from shell_newton import grown_sphere  # noqa: E402

from femshell.shell.assembly import SparseAssembler  # noqa: E402

#: the scaling sizes of issue 63
SCALING_SIZES = (6000, 12000, 25000, 50000)


def measure(fn, repeat=2):
    """(cpu, wall) seconds of ``fn()``, the best of ``repeat`` calls (after none: warm it first)."""
    best = (np.inf, np.inf)
    for _ in range(repeat):
        c, w = time.process_time(), time.perf_counter()
        fn()
        best = min(best, (time.process_time() - c, time.perf_counter() - w))
    return best


def element_args(model, u):
    from femshell.shell import element as el
    args = model._element_args(model.full(u))
    interior = (model.edge_kind_el == el.INTERIOR).all(axis=1)
    return args, interior


def element_hessians(model, u, kernel):
    """A function computing the element Hessians of state u by ``kernel`` ("jax" or "compiled"), on the
    threads the model uses (:func:`femshell.config.element_threads`)."""
    args, interior = element_args(model, u)
    return lambda: model._kernels.evaluate(*args, hessian=True, interior=interior, hessian_kernel=kernel)[2]


def hessian_section(model, u):
    """Element Hessians and the assembled Hessian, JAX against compiled C."""
    old, new = element_hessians(model, u, "jax"), element_hessians(model, u, "compiled")
    old(), new()                                    # compile or load from the caches
    rows = [("element Hessian", measure(old), measure(new))]

    def assembled(kernel):
        model.hessian_kernel = kernel
        return measure(lambda: model.hessian(u))

    rows.append(("Hessian assembled", assembled("jax"), assembled("compiled")))
    model.hessian_kernel = "compiled"

    def energy_and_gradient(kernel):
        model.gradient_kernel = kernel
        model.energy_and_gradient(u)                # compile or load from the caches
        return measure(lambda: model.energy_and_gradient(u))

    rows.append(("energy and gradient", energy_and_gradient("jax"), energy_and_gradient("compiled")))
    rows.append(("sparsity pattern", measure(lambda: SparseAssembler(model.element_dofs, model.free), repeat=1),
                 measure(lambda: SparseAssembler(model.element_dofs, model.free, nodes=model.assembler_nodes),
                         repeat=1)))
    return rows


SECTIONS = [hessian_section]

SETUP_SCRIPT = r"""
import json, os, sys, time
def cpu():                      # this process and the compiler it ran (os.times: self and children)
    return sum(os.times()[:4])
c0, w0 = cpu(), time.perf_counter()
import femshell
femshell.configure()
from femshell.scene import build
from femshell.shell import Material, ShellModel, flat_rest_state
n, kernel = int(sys.argv[1]), sys.argv[2]
if kernel == "jax":             # today's path: also the sparsity pattern from all m k^2 entries
    from femshell.shell import assembly, model as shell_model
    shell_model.SparseAssembler = lambda dofs, free, nodes=None: assembly.SparseAssembler(dofs, free)
scene = build.load_scene("sphere-spots", [f"mesh.n_vertices={n}"])
c1, w1 = cpu(), time.perf_counter()
mesh = build.make_mesh(scene)
c2, w2 = cpu(), time.perf_counter()
model = ShellModel(mesh, Material(1.0, 0.5), flat_rest_state(mesh.points, mesh.triangles, 2.0),
                   hessian_kernel=kernel, gradient_kernel=kernel)
c3, w3 = cpu(), time.perf_counter()
u = model.initial_unknowns()
model.energy_and_gradient(u), model.hessian(u)
c4, w4 = cpu(), time.perf_counter()
print(json.dumps({"import": [c1 - c0, w1 - w0], "mesh": [c2 - c1, w2 - w1], "model": [c3 - c2, w3 - w2],
                  "first evaluation": [c4 - c3, w4 - w3], "total": [c4 - c0, w4 - w0]}))
"""


def setup_run(n, kernel, caches):
    """One fresh process's set-up times {part: [cpu, wall]}, its JAX and kernel caches in ``caches``
    (CPU: the child's and its compiler's, from the start of its script)."""
    env = dict(os.environ, FEMSHELL_JAX_CACHE=str(Path(caches) / "jax"), NUMBA_CACHE_DIR=str(Path(caches) / "compiled"))
    env.pop("JAX_COMPILATION_CACHE_DIR", None)
    out = subprocess.run([sys.executable, "-c", SETUP_SCRIPT, str(n), kernel], env=env, capture_output=True,
                         text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def setup_section(n):
    """Set-up cold (empty caches) and warm (the caches the cold run filled), old and new."""
    rows = {}
    for kernel in ("jax", "compiled"):
        with tempfile.TemporaryDirectory(prefix="femshell-speed-") as caches:
            rows[kernel] = (setup_run(n, kernel, caches), setup_run(n, kernel, caches))
    out = []
    for i, state in enumerate(("cold", "warm")):
        for part in ("total", "import", "mesh", "model", "first evaluation"):
            label = f"set-up {state}" if part == "total" else f"  {state}: {part}"
            out.append((label, tuple(rows["jax"][i][part]), tuple(rows["compiled"][i][part])))
    return out


def scaling_section(sizes):
    """Prints the element Hessian per size, old and new, and the fitted exponents."""
    rows, times = [], {"old": [], "new": []}
    verts = []
    for n in sizes:
        model, u = grown_sphere(n)
        old = measure(element_hessians(model, u, "jax"), repeat=1 if n > 30000 else 2)
        new = measure(element_hessians(model, u, "compiled"))
        verts.append(model.mesh.n_vertices)
        times["old"].append(old[0])
        times["new"].append(new[0])
        rows.append((f"element Hessian {model.mesh.n_vertices}", old, new))
        model = None
    print_rows(rows)
    if len(sizes) > 1:
        fit = {k: np.polyfit(np.log(verts), np.log(v), 1)[0] for k, v in times.items()}
        print(f"fitted exponent (CPU time ∝ vertices^p): old p = {fit['old']:.2f}, new p = {fit['new']:.2f}")


def print_rows(rows):
    print(f"{'':24} {'old CPU s':>10} {'new CPU s':>10} {'ratio':>7} {'old wall s':>11} {'new wall s':>11} {'ratio':>7}")
    for label, old, new in rows:
        ratios = [o / n if n > 0 else np.inf for o, n in zip(old, new)]
        print(f"{label:24} {old[0]:>10.3f} {new[0]:>10.3f} {ratios[0]:>7.2f} {old[1]:>11.3f} {new[1]:>11.3f} "
              f"{ratios[1]:>7.2f}", flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vertices", type=int, default=25000)
    ap.add_argument("--setup", action="store_true", help="set-up cold and warm in fresh processes")
    ap.add_argument("--scaling", type=int, nargs="*", help=f"element Hessian per size (default {SCALING_SIZES})")
    ap.add_argument("--solve", action="store_true", help="factorisation, Krylov and Newton rows (speed_solve)")
    ap.add_argument("--coupled-steps", type=int, default=4, help="coupled steps per path with --solve (0: none)")
    ap.add_argument("--newton", action="store_true", help="a Newton iteration per path and its parts (speed_newton)")
    args = ap.parse_args(argv)
    if args.coupled_steps < 0:
        ap.error(f"--coupled-steps must be >= 0, got {args.coupled_steps}")
    sizes = SCALING_SIZES if args.scaling == [] else args.scaling
    if args.vertices < 100 or (sizes and min(sizes) < 100):
        ap.error(f"--vertices and --scaling take vertex counts >= 100, got {args.vertices} and {sizes}")
    if args.newton:          # first: its fresh processes each load MKL in their own mode
        speed_newton.print_table(speed_newton.measure_paths(args.vertices, list(speed_newton.PATHS)))
    import femshell
    femshell.configure()
    print(f"load average {os.getloadavg()[0]:.2f}; old = JAX element Hessian, new = compiled C (fast_element)")
    model, u = grown_sphere(args.vertices)
    print(f"sphere R = 30, h = 2: {model.mesh.n_vertices} vertices, {model.mesh.n_triangles} elements, "
          f"{model.n_free} unknowns")
    rows = []
    for section in SECTIONS:
        rows += section(model, u)
    print_rows(rows)
    model = None
    if args.setup:
        print_rows(setup_section(args.vertices))
    if sizes:
        scaling_section(sizes)
    if args.solve:
        speed_solve.print_rows(args.vertices, args.coupled_steps)
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
