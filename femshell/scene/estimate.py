"""What a scene's mesh will cost, from its vertex count, before anything is meshed.

The vertex count comes from the ``[mesh]`` section (``n_vertices``, or the surface's area over
an equilateral triangle's for ``edge_length``; :func:`expected_vertices`); memory and time are
fitted to runs of the embedded ``sphere-seeded-spots`` scene (sphere, time loop, neo-Hookean
membrane) on 2 cores (:class:`Estimate`):

    memory    ≈ MEM_BASE + MEM_PER_VERTEX · N            (peak resident memory of the run, bytes)
    meshing   ≈ MESH_S_PER_VERTEX · N                     (gmsh, seconds)
    time step ≈ STEP_S_PER_VERTEX · N^STEP_EXPONENT      (a step of the time loop, idle cores, seconds)

The memory is fitted to 2 000 and 8 000 vertices and errs high beyond; the times are those of
idle cores (on cores other jobs share, several times longer) and of steps of a few
quasi-Newton iterations (a nucleating spot needs more). They say whether a run fits and its
order of cost. :func:`machine_memory` reads the physical and the available memory (Linux
/proc/meminfo).
"""

from __future__ import annotations

import math
import os

from ..mesh.generators import AREA_FACTOR, AREA_FACTOR_FLAT, BOUNDARY_LINEAR, SPHERE_LINEAR

__all__ = ["expected_vertices", "estimate", "machine_memory", "Estimate"]

# fitted to the sphere-seeded-spots scene (sphere, time loop, neo-Hookean membrane); see the module docstring
MEM_BASE = 0.73e9
MEM_PER_VERTEX = 105e3
MESH_S_PER_VERTEX = 3.4e-4
STEP_S_PER_VERTEX = 2.7e-5
STEP_EXPONENT = 1.2
#: a run this large or larger prints progress while gmsh meshes
LARGE_MESH = 50_000


def _area(kind: str, m: dict) -> tuple[float, float, float]:
    """(area, linear excess length, area factor) of a generated surface (the generators' calibration:
    the excess is BOUNDARY_LINEAR x the boundary's length, SPHERE_LINEAR x the radius on a sphere)."""
    pi = math.pi
    if kind == "sphere":
        r = m.get("radius", 1.0)
        return 4 * pi * r * r, SPHERE_LINEAR * r, AREA_FACTOR
    if kind == "hemisphere":
        r = m.get("radius", 1.0)
        return 2 * pi * r * r, BOUNDARY_LINEAR * 2 * pi * r, AREA_FACTOR
    if kind == "disk":
        r = m.get("radius", 1.0)
        return pi * r * r, BOUNDARY_LINEAR * 2 * pi * r, AREA_FACTOR_FLAT
    if kind in ("plate", "strip"):
        a, b = (m.get("lx", 1.0), m.get("ly", 1.0)) if kind == "plate" else (m.get("length", 10.0), m.get("width", 1.0))
        return a * b, BOUNDARY_LINEAR * 2 * (a + b), AREA_FACTOR_FLAT
    if kind == "annulus":
        ro, ri = m.get("outer_radius", 1.0), m.get("inner_radius", 0.5)
        return pi * (ro * ro - ri * ri), BOUNDARY_LINEAR * 2 * pi * (ro + ri), AREA_FACTOR_FLAT
    if kind == "cylinder":
        ar = m.get("angle_range")
        frac = abs(ar[1] - ar[0]) / 360.0 if ar else 1.0
        r, length = m.get("radius", 1.0), m.get("length", 1.0)
        edge = 2 * 2 * pi * r * frac + (2 * length if ar else 0.0)
        return 2 * pi * r * length * frac, BOUNDARY_LINEAR * edge, AREA_FACTOR_FLAT
    raise KeyError(kind)


def expected_vertices(mesh: dict) -> int | None:
    """About how many vertices a ``[mesh]`` section gives (None: a mesh file, or no resolution given,
    which the generators keep small)."""
    kind = mesh.get("kind")
    if kind == "file" or kind is None:
        return None
    if mesh.get("n_vertices") is not None:
        return int(mesh["n_vertices"])
    h = mesh.get("edge_length")
    if h is None or not h > 0:
        return None
    area, linear, factor = _area(kind, mesh)
    n = factor * 2.0 * (area / h) / (math.sqrt(3.0) * h) + linear / h
    hi, r2 = mesh.get("inner_edge_length"), mesh.get("inner_radius")
    if kind == "disk" and hi and r2:      # the finer edges inside (or about) the inner circle, counted as inside
        n += 2.0 * (math.pi * r2 * r2) / math.sqrt(3.0) * (1.0 / hi ** 2 - 1.0 / h ** 2)
    return int(round(n))


class Estimate:
    """Peak memory (bytes), meshing time and time of a step (seconds) of a run on ``n_vertices``."""

    def __init__(self, n_vertices: int):
        self.n_vertices = int(n_vertices)
        self.memory = MEM_BASE + MEM_PER_VERTEX * n_vertices
        self.meshing_s = MESH_S_PER_VERTEX * n_vertices
        self.step_s = STEP_S_PER_VERTEX * n_vertices ** STEP_EXPONENT

    def text(self) -> str:
        return (f"~{_bytes(self.memory)} memory, ~{_seconds(self.step_s)} per time step, meshing "
                f"~{_seconds(self.meshing_s)} (estimated from {self.n_vertices} vertices, for idle cores: several "
                "times longer when other jobs share them)")


def estimate(n_vertices: int) -> Estimate:
    return Estimate(n_vertices)


def machine_memory() -> tuple[float | None, float | None]:
    """(physical, available) memory in bytes (None where it cannot be read)."""
    total = avail = None
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            info = {line.split(":")[0]: float(line.split()[1]) * 1024 for line in f if line.count(":") == 1}
        total, avail = info.get("MemTotal"), info.get("MemAvailable")
    except (OSError, ValueError, IndexError):
        try:
            total = float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
        except (ValueError, OSError, AttributeError):
            pass
    return total, avail


def _bytes(b: float) -> str:
    return f"{b / 1e9:.2g} GB" if b >= 1e9 else f"{b / 1e6:.0f} MB"


def _seconds(s: float) -> str:
    if s < 60:
        return f"{s:.2g} s"
    if s < 3600:
        return f"{s / 60:.2g} min"
    return f"{s / 3600:.2g} h"
