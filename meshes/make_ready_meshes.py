"""Regenerate the small ready meshes in this directory (see README.md).

    .venv/bin/python meshes/make_ready_meshes.py        # from the repository root

Each mesh comes from a femshell.mesh generator with a fixed seed, so rerunning
gives the same files on the same gmsh version.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from femshell.mesh import annulus, cylinder, disk, hemisphere, plate, sphere, write_mesh  # noqa: E402

#: file name -> (generator call, expected Euler characteristic, expected boundary names)
READY = {
    "sphere_r1_500.msh": (lambda: sphere(radius=1.0, n_vertices=500, seed=0), 2, []),
    "disk_r10_R2_3.vtu": (lambda: disk(radius=10.0, edge_length=1.0, inner_radius=3.0,
                                       inner_edge_length=0.5, seed=0), 1, ["inner", "outer"]),
    "plate_1x1.vtu": (lambda: plate(1.0, 1.0, edge_length=0.1, seed=0), 1, ["bottom", "left", "right", "top"]),
    "annulus_slit.vtu": (lambda: annulus(0.5, 1.0, edge_length=0.1, slit=True, seed=0), 1,
                         ["inner", "outer", "slit-a", "slit-b"]),
    "cylinder_r1_l2.vtu": (lambda: cylinder(radius=1.0, length=2.0, edge_length=0.2, seed=0), 0, ["bottom", "top"]),
    "hemisphere_r1.vtu": (lambda: hemisphere(radius=1.0, edge_length=0.15, seed=0), 1, ["equator"]),
}


def main():
    if len(sys.argv) > 1:                  # no options: say so instead of overwriting the meshes
        print(__doc__.strip() + "\n\n(takes no arguments)", file=sys.stderr)
        sys.exit(0 if sys.argv[1] in ("-h", "--help") else 2)
    for name, (make, _, _) in READY.items():
        mesh = make()
        write_mesh(mesh, HERE / name)
        size = (HERE / name).stat().st_size
        print(f"{name:22s} {mesh.n_vertices:6d} vertices {mesh.n_triangles:6d} triangles {size / 1024:7.1f} KB  "
              f"({mesh.name})")


if __name__ == "__main__":
    main()
