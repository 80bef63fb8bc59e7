"""Meshes: gmsh generators, meshio I/O, topology and checks."""

from .surface import SurfaceMesh
from .topology import MeshError, Topology, build_topology

__all__ = ["SurfaceMesh", "Topology", "MeshError", "build_topology"]
from .checks import (MeshReport, check_mesh, format_quality, orient_consistently, quality_report,
                     warn_poor_quality)
__all__ += ["MeshReport", "check_mesh", "orient_consistently", "quality_report", "format_quality",
            "warn_poor_quality"]
from .generators import annulus, cylinder, disk, edge_length_for_vertices, hemisphere, plate, sphere, strip
from .io import MESH_FORMATS, read_mesh, write_mesh
__all__ += ["sphere", "disk", "plate", "strip", "annulus", "cylinder", "hemisphere", "edge_length_for_vertices",
            "read_mesh", "write_mesh", "MESH_FORMATS"]
