"""Benchmark: wall time and vertex-count accuracy of the sphere generator (and the others).

    cd /work/main && python3 validation/benchmarks/mesh_timing.py            # spheres 2.5k, 25k, 100k
    python3 validation/benchmarks/mesh_timing.py --all                       # every generator at 25k too

Prints one line per mesh: target and actual vertex count, relative error, and
the wall time of the generator call (gmsh meshing + extraction + orientation),
best of ``--repeat`` runs. The sphere has the seed paper's radius R = 30
(theory §1.5); the generators run gmsh on one thread.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from femshell.mesh import annulus, cylinder, disk, hemisphere, plate, sphere, strip  # noqa: E402


def timed(make, repeat):
    best, mesh = float("inf"), None
    for _ in range(repeat):
        t = time.perf_counter()
        mesh = make()
        best = min(best, time.perf_counter() - t)
    return mesh, best


def row(label, n, make, repeat):
    mesh, t = timed(make, repeat)
    err = (mesh.n_vertices - n) / n
    print(f"{label:34s} {n:8d} {mesh.n_vertices:8d} {100 * err:+7.2f} % {t:8.2f} s", flush=True)
    return mesh, t


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[2500, 25000, 100000])
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--all", action="store_true", help="also time the other generators at 25 000 vertices")
    args = ap.parse_args(argv)
    if args.repeat < 1 or min(args.sizes) < 10:
        ap.error(f"--repeat must be >= 1 and --sizes vertex counts >= 10, got {args.repeat} and {args.sizes}")
    print(f"{'mesh':34s} {'target':>8s} {'actual':>8s} {'error':>9s} {'time':>10s}")
    for n in args.sizes:
        row("sphere R=30", n, lambda: sphere(radius=30.0, n_vertices=n), args.repeat)
    if args.all:
        n = 25000
        for label, make in [
            ("hemisphere R=30", lambda: hemisphere(30.0, n_vertices=n)),
            ("disk R=10", lambda: disk(10.0, n_vertices=n)),
            ("plate 2x1", lambda: plate(2.0, 1.0, n_vertices=n)),
            ("plate 2x1 structured", lambda: plate(2.0, 1.0, n_vertices=n, structured=True)),
            ("strip 10x1", lambda: strip(10.0, 1.0, n_vertices=n)),
            ("annulus 0.5..1 slit", lambda: annulus(0.5, 1.0, n_vertices=n, slit=True)),
            ("cylinder R=1 L=3", lambda: cylinder(1.0, 3.0, n_vertices=n)),
        ]:
            row(label, n, make, args.repeat)


if __name__ == "__main__":
    main()
