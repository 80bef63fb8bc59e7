"""gmsh sessions for the generators: a fresh deterministic model, meshing, and the meshed surface
taken out as a :class:`~femshell.mesh.SurfaceMesh` with femshell's orientation (outward, +z on
flat meshes; boundary segments with the surface on their left)."""

from __future__ import annotations

import itertools
import signal
from contextlib import contextmanager, suppress

import numpy as np

from .surface import SurfaceMesh

#: gmsh 2D algorithm: 6 = Frontal-Delaunay (near-equilateral triangles, deterministic on one thread).
MESH_ALGORITHM = 6

_seq = itertools.count()


@contextmanager
def _gmsh_model(seed, algorithm=MESH_ALGORITHM):
    """A fresh gmsh model with deterministic, silent options; cleaned up afterwards.

    Starts gmsh if needed (and finalises it again); in a session the caller
    started, adds a temporary model, restores the changed options and the
    caller's current model.
    """
    import gmsh        # deferred: importing gmsh costs ~0.3 s and is needed only to mesh

    started = not gmsh.isInitialized()
    if started:
        # interruptible=False: no SIGINT handler (which fails outside the main thread). gmsh still
        # resets SIGTERM to its default action, which would kill a run that handles it (femshell
        # run, the studies) without its orderly stop: put Python's handler back
        on_term = signal.getsignal(signal.SIGTERM)
        gmsh.initialize(readConfigFiles=False, interruptible=False)
        if on_term is not None:
            with suppress(ValueError):      # outside the main thread no handler can be set
                signal.signal(signal.SIGTERM, on_term)
        previous_model = None
    else:
        previous_model = gmsh.model.getCurrent()
    options = {
        "General.Terminal": 0,
        "General.Verbosity": 2,             # errors and warnings are still recorded for exceptions
        "General.NumThreads": 1,            # one thread: the only way gmsh meshes are reproducible
        "Mesh.MaxNumThreads1D": 1,
        "Mesh.MaxNumThreads2D": 1,
        "Mesh.RandomSeed": seed,
        "Mesh.Algorithm": algorithm,
        "Mesh.ElementOrder": 1,
        "Mesh.RecombineAll": 0,
        "Mesh.MeshSizeFromCurvature": 0,    # size comes from edge_length / fields only
        "Mesh.MeshSizeFromPoints": 0,
        "Mesh.MeshSizeExtendFromBoundary": 0,
    }
    saved = {}
    for key, value in options.items():
        if not started:
            saved[key] = gmsh.option.getNumber(key)
        gmsh.option.setNumber(key, value)
    for key in ("Mesh.MeshSizeMin", "Mesh.MeshSizeMax"):
        if not started:
            saved[key] = gmsh.option.getNumber(key)
    model = f"femshell-generator-{next(_seq)}"
    gmsh.model.add(model)
    try:
        yield gmsh
    finally:
        try:
            gmsh.model.setCurrent(model)
            gmsh.model.remove()
        finally:
            if started:
                gmsh.finalize()
            else:
                for key, value in saved.items():
                    gmsh.option.setNumber(key, value)
                if previous_model:
                    try:
                        gmsh.model.setCurrent(previous_model)
                    except Exception:  # the caller's model may be gone; nothing to restore
                        pass


def _uniform_size(gmsh, h):
    gmsh.option.setNumber("Mesh.MeshSizeMin", h)
    gmsh.option.setNumber("Mesh.MeshSizeMax", h)


def _generate(gmsh, what):
    gmsh.model.occ.synchronize()
    try:
        gmsh.model.mesh.generate(2)
    except Exception as exc:  # gmsh raises a bare Exception with its last error
        raise RuntimeError(f"gmsh failed to mesh {what}: {exc}") from exc


def _extract(gmsh, surfaces, classify):
    """Triangles of the given surface entities and named line elements of the curves.

    ``classify(xyz)`` gets the (k, 3) coordinates of the nodes of one curve's
    line elements and returns the boundary name or None (curve not returned,
    e.g. a seam). Returns compact points, triangles, {name: segments}.
    """
    tags, coords, _ = gmsh.model.mesh.getNodes()
    coords = coords.reshape(-1, 3)
    lookup = np.full(int(tags.max()) + 1, -1, np.int64)
    lookup[tags.astype(np.int64)] = np.arange(len(tags))
    tri = np.concatenate([gmsh.model.mesh.getElementsByType(2, s)[1] for s in surfaces]).astype(np.int64)
    tri = lookup[tri].reshape(-1, 3)

    curves = {}
    for _, c in gmsh.model.getEntities(1):
        seg = gmsh.model.mesh.getElementsByType(1, c)[1].astype(np.int64)
        if len(seg) == 0:
            continue
        seg = lookup[seg].reshape(-1, 2)
        name = classify(coords[np.unique(seg)])
        if name is not None:
            curves.setdefault(name, []).append(seg)
    curves = {k: np.concatenate(v) for k, v in curves.items()}

    # drop nodes that no triangle uses (gmsh keeps geometry points) and renumber compactly
    used = np.unique(tri)
    new = np.full(len(coords), -1, np.int64)
    new[used] = np.arange(len(used))
    points = coords[used]
    tri = new[tri]
    curves = {k: new[v] for k, v in curves.items()}
    for k, v in curves.items():
        if (v < 0).any():
            raise RuntimeError(f"curve '{k}' has nodes that no triangle uses; the gmsh mesh is not conforming")
    return points, tri, curves


# ----------------------------------------------------------------------------- orientation

def _orient(points, tri, outward):
    """Flip triangles whose normal points against ``outward(centroids)`` (swap two columns)."""
    p = points[tri]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    flip = np.einsum("ij,ij->i", n, outward(p.mean(axis=1))) < 0
    tri = tri.copy()
    tri[flip] = tri[flip][:, [0, 2, 1]]
    return tri


def _orient_segments(tri, seg, n_vertices):
    """Boundary segments turned to run along their triangle's edge (surface on the left)."""
    seg = np.asarray(seg, np.int64).reshape(-1, 2)
    directed = np.sort((tri * n_vertices + tri[:, [1, 2, 0]]).ravel())
    key = seg[:, 0] * n_vertices + seg[:, 1]
    pos = np.minimum(np.searchsorted(directed, key), len(directed) - 1)
    forward = directed[pos] == key
    return np.where(forward[:, None], seg, seg[:, ::-1])


def _finish(points, tri, curves, outward, name, interior=()):
    """Orient triangles and boundary segments; build the SurfaceMesh."""
    tri = _orient(points, tri, outward)
    n = len(points)
    boundary = {}
    for key, seg in curves.items():
        if key in interior:
            # an interior curve has triangles on both sides: keep it counter-clockwise about +z
            p = points[seg]
            ccw = p[:, 0, 0] * p[:, 1, 1] - p[:, 0, 1] * p[:, 1, 0] >= 0
            boundary[key] = np.where(ccw[:, None], seg, seg[:, ::-1])
        else:
            boundary[key] = _orient_segments(tri, seg, n)
    return SurfaceMesh(points, tri, boundary, name)


def _up(c):
    return np.broadcast_to(np.array([0.0, 0.0, 1.0]), c.shape)


def _radial(c):
    return c


def _away_from_axis(c):
    return np.column_stack([c[:, 0], c[:, 1], np.zeros(len(c))])


def _on(values, target, tol):
    return bool(np.all(np.abs(values - target) <= tol))
