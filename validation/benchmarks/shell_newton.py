"""Cost of one Newton iteration of the shell on spheres of about 2 500, 10 000 and 25 000 vertices.

The state is a grown, buckled-looking one: the polar cap (z > 0.8 R) grows by 20 %
(volume-conserving thickness) and the positions carry a smooth bump, so the Hessian
is indefinite as it is in a wrinkling run. Prints, per mesh: assembly of energy,
gradient and Hessian; symmetric-indefinite factorisation (first, with analysis, and a
refactorisation reusing it); one solve; one whole Newton iteration of
Newton (Hessian + refactorisation + solve + one energy-and-gradient evaluation of the
line search); and the process's peak resident memory so far (a per-mesh figure needs one size
per invocation: the previous mesh's peak stays in it).

    python validation/benchmarks/shell_newton.py [--sizes 2500 10000 25000]

Results (assembly, factorisation and Newton iteration per mesh) are in docs/studies/benchmarks.md.
"""

from __future__ import annotations

import argparse
import resource
import time

import numpy as np

from femshell.mesh.generators import sphere
from femshell.shell import Material, RestState, ShellModel
from femshell.solvers.linear import factorize


def grown_sphere(n_vertices, radius=30.0, h=2.0, growth=1.2, law="svk", bump=0.05):
    """Sphere R, thickness h, stress free as drawn (ν = 0.5, ``law``), whose polar cap z > 0.8 R grows
    by ``growth`` (volume-conserving thickness), started from the sphere with a smooth bump of
    ``bump`` h on the cap."""
    mesh = sphere(radius=radius, n_vertices=n_vertices)
    model = ShellModel(mesh, Material(1.0, 0.5, law=law), h)
    rest = model.stress_free_rest_state()
    z = mesh.points[mesh.triangles].mean(1)[:, 2]
    s = np.where(z > 0.8 * radius, growth, 1.0)
    model.set_rest_state(RestState(rest.metric * s[:, None, None] ** 2, rest.curvature * s[:, None, None] ** 2,
                                   h / s**2))
    x = mesh.points.copy()
    cap = np.exp(-((x[:, 2] - radius) / (0.3 * radius)) ** 2)
    x += bump * h * cap[:, None] * x / radius
    q = model.full(model.initial_unknowns())
    q[: 3 * mesh.n_vertices] = x.ravel()
    return model, q[model.free]


def best_of(f, repeat=2):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t)
    return min(times), out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[2500, 10000, 25000])
    args = ap.parse_args()
    if any(n < 100 for n in args.sizes):
        ap.error(f"--sizes must be vertex counts >= 100, got {args.sizes}")
    import scipy.sparse as sp
    factorize(sp.identity(10, format="csr") * 2.0, kind="symmetric_indefinite").free()   # loads PARDISO: not
    # in the first mesh's factor time (1.13 s against 0.43 s measured at 2 500 vertices)
    print(f"{'vertices':>9} {'unknowns':>9} {'nnz(K)':>10} {'E+g':>7} {'Hessian':>8} {'factor':>7} "
          f"{'refactor':>8} {'solve':>6} {'Newton it':>9} {'inertia-':>8} {'peak RSS so far':>15}")
    for n in args.sizes:
        model, u = grown_sphere(n)
        model.energy(u), model.gradient(u), model.hessian(u)  # compile / warm caches
        t_eg, _ = best_of(lambda: (model.energy(u), model.gradient(u)))
        t_h, K = best_of(lambda: model.hessian(u))
        t = time.perf_counter()
        fac = factorize(K, kind="symmetric_indefinite")
        t_f = time.perf_counter() - t
        t_rf, _ = best_of(lambda: fac.refactor(K))
        g = model.gradient(u)
        t_s, _ = best_of(lambda: fac.solve(g))
        per_it = t_h + t_rf + t_s + t_eg  # Hessian, refactorisation, solve, one line-search evaluation
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024**2
        print(f"{model.mesh.n_vertices:>9} {model.n_free:>9} {K.nnz:>10} {t_eg:>7.3f} {t_h:>8.3f} {t_f:>7.2f} "
              f"{t_rf:>8.2f} {t_s:>6.3f} {per_it:>9.2f} {fac.inertia[1]:>8} {rss:>13.2f}GB", flush=True)
        fac.free()
        model = K = fac = None      # released before the next mesh is built


if __name__ == "__main__":
    main()
