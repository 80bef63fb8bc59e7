"""Read and write a :class:`~femshell.mesh.SurfaceMesh` through meshio (writes .msh, .vtu, .xdmf; reads
those and every triangle format meshio reads: .obj, .stl, .ply, .off, .vtk, ...).

File convention (the same for the three formats):

* the triangles are one "triangle" cell block; the boundary curves are one
  "line" cell block of vertex-pair segments;
* integer cell data ``"boundary_id"``: 0 on triangles, k = 1, 2, ... on the
  segments of the k-th boundary curve;
* the curve names in gmsh's field-data form ``{name: [k, 1]}`` (id, dimension 1).
  In .msh (gmsh 2.2 binary, which gmsh, meshio and ParaView read) these are
  physical names and the element tags ``gmsh:physical`` carry the ids (there
  is no boundary_id array), so gmsh shows the curves as physical groups;
  meshio does not write field data to .vtu and
  .xdmf, so :func:`write_mesh` adds it itself: a VTK ``<FieldData>`` block in
  the .vtu and an XDMF ``<Information>`` element in the format meshio's XDMF
  reader parses. Readers that ignore them (ParaView) still see boundary_id.

:func:`read_mesh` also reads .msh files written by gmsh itself (physical
curve groups become named boundary curves; unnamed physical ids are called
``"curve-<id>"``) and drops the vertices no triangle uses (gmsh keeps
geometry points). The mesh ``name`` is not stored; a read mesh is named after
its file.

Limitation: .msh files carry point data but no cell data, because meshio
5.3's gmsh 2.2 reader splits element data wrongly when a file has two cell
blocks (triangles and lines); :func:`write_mesh` refuses cell data for .msh.

Lengths are whatever the mesh carries (design units); nothing is rescaled.

Example
-------
>>> import tempfile, os
>>> from femshell.mesh import plate, write_mesh, read_mesh
>>> m = plate(1.0, 1.0, edge_length=0.25, structured=True)
>>> path = os.path.join(tempfile.mkdtemp(), "plate.vtu")
>>> write_mesh(m, path)
>>> sorted(read_mesh(path).boundary)
['bottom', 'left', 'right', 'top']
"""

from __future__ import annotations

import contextlib
import io
import os
import shutil
import sys
import tempfile
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from .surface import SurfaceMesh
from .topology import MeshError

__all__ = ["write_mesh", "read_mesh", "MESH_FORMATS"]

#: file extension -> meshio format name
MESH_FORMATS = {".msh": "gmsh22", ".vtu": "vtu", ".xdmf": "xdmf"}

_BOUNDARY_ID = "boundary_id"
_INTERNAL = (_BOUNDARY_ID, "gmsh:physical", "gmsh:geometrical")


def _format(path: Path) -> str:
    ext = path.suffix.lower()
    if ext not in MESH_FORMATS:
        raise ValueError(f"unknown mesh file extension '{path.suffix}' of {path}; "
                         f"allowed: {', '.join(MESH_FORMATS)}")
    return MESH_FORMATS[ext]


def _read_format(path: Path) -> str:
    """meshio's format for reading ``path``: the three written formats, else any meshio reads
    (.obj, .stl, .ply, .off, .vtk, ...; double extensions such as .vol.gz too)."""
    import meshio

    name = path.name.lower()
    if path.suffix.lower() in MESH_FORMATS:
        return "gmsh" if path.suffix.lower() == ".msh" else MESH_FORMATS[path.suffix.lower()]
    known = meshio.extension_to_filetypes
    ext = next((e for e in sorted(known, key=len, reverse=True) if name.endswith(e)), None)
    if ext is None:
        raise ValueError(f"unknown mesh file extension '{path.suffix}' of {path}; femshell reads what meshio "
                         f"reads: {', '.join(sorted(known))}")
    return known[ext][0]


#: vertices closer than this fraction of the mean triangle edge count as one (merge_vertices)
MERGE_TOL = 1e-6


def _coincident(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """For each vertex, the lowest-numbered vertex within ``MERGE_TOL`` x the mean edge length of it
    (itself when none): an STL file stores every triangle's corners separately."""
    from scipy.spatial import cKDTree

    e = points[tri[:, [1, 2, 0]]] - points[tri]
    tol = MERGE_TOL * float(np.linalg.norm(e, axis=2).mean())
    rep = np.arange(len(points))
    pairs = cKDTree(points).query_pairs(tol, output_type="ndarray") if tol > 0 else np.zeros((0, 2), int)
    if len(pairs):
        # union-find over the close pairs, vectorised: repeat "each takes its partner's lower label"
        while True:
            lo = np.minimum(rep[pairs[:, 0]], rep[pairs[:, 1]])
            new = rep.copy()
            np.minimum.at(new, pairs[:, 0], lo)
            np.minimum.at(new, pairs[:, 1], lo)
            new = new[new]
            if np.array_equal(new, rep):
                break
            rep = new
    return rep


# ----------------------------------------------------------------------------- write

def write_mesh(mesh: SurfaceMesh, path, point_data=None, cell_data=None) -> None:
    """Write ``mesh`` (triangles and named boundary curves) to a .msh, .vtu or .xdmf file.

    ``point_data``: dict name -> array with one row per vertex; ``cell_data``:
    dict name -> array with one row per triangle (the line cells of the
    boundary curves get zeros; not for .msh, see the module docstring).
    Names ``boundary_id`` and ``gmsh:*`` are reserved. Boundary curves
    without segments are not written.

    The write is atomic: the file is written in a temporary directory next to
    ``path`` and moved into place with :func:`os.replace`, so a reader never
    sees a half-written file. An .xdmf file comes with its HDF5 data in the
    .h5 file of the same stem (meshio's naming; an existing file of that
    name is replaced); the .h5 is moved first, then the .xdmf, so the pair is
    not replaced as one unit, but neither file is ever partly written.

    >>> write_mesh(m, "out/sphere.xdmf", point_data={"c": c})   # doctest: +SKIP
    """
    import meshio

    path = Path(path)
    fmt = _format(path)
    if not isinstance(mesh, SurfaceMesh):
        raise TypeError(f"write_mesh needs a SurfaceMesh, got {type(mesh).__name__}")
    n, m = mesh.n_vertices, mesh.n_triangles
    if not np.all(np.isfinite(mesh.points)):
        raise ValueError(f"mesh has {int(np.count_nonzero(~np.isfinite(mesh.points).all(axis=1)))} vertices with "
                         "non-finite coordinates (NaN or inf); nothing written")
    point_data = {str(k): _checked(k, v, n, "vertex") for k, v in (point_data or {}).items()}
    cell_data = {str(k): _checked(k, v, m, "triangle") for k, v in (cell_data or {}).items()}
    for k in list(point_data) + list(cell_data):
        if k in _INTERNAL or k.startswith("gmsh:"):
            raise ValueError(f"data name '{k}' is reserved for the mesh file convention")
    if cell_data and fmt == "gmsh22":
        raise ValueError("cell_data cannot be stored in .msh (meshio cannot read it back); use .vtu or .xdmf")

    names = [k for k, v in mesh.boundary.items() if len(v)]
    segs = [np.asarray(mesh.boundary[k], np.int64).reshape(-1, 2) for k in names]
    ids = [np.full(len(s), i + 1, np.int64) for i, s in enumerate(segs)]
    cells = [("triangle", mesh.triangles.astype(np.int64))]
    data = {_BOUNDARY_ID: [np.zeros(m, np.int64)]}
    if segs:
        lines = np.concatenate(segs)
        cells.append(("line", lines))
        data[_BOUNDARY_ID].append(np.concatenate(ids))
    for k, v in cell_data.items():
        data[k] = [v] + ([np.zeros((len(lines),) + v.shape[1:], v.dtype)] if segs else [])
    field_data = {k: np.array([i + 1, 1]) for i, k in enumerate(names)}
    if fmt == "gmsh22":
        # gmsh's own tags: physical = curve id (triangles: one surface group after the curves)
        surface_id = len(names) + 1
        data["gmsh:physical"] = [np.full(m, surface_id, np.int32)] + ([data[_BOUNDARY_ID][1].astype(np.int32)]
                                                                       if segs else [])
        data["gmsh:geometrical"] = [a.astype(np.int32) for a in data["gmsh:physical"]]
        del data[_BOUNDARY_ID]   # element data would not read back; the physical tags carry the ids
        field_data["surface"] = np.array([surface_id, 2])
    out = meshio.Mesh(np.asarray(mesh.points, float), cells, point_data=point_data, cell_data=data,
                      field_data=field_data)

    path.parent.mkdir(parents=True, exist_ok=True)
    tmpdir = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent))
    try:
        tmp = tmpdir / path.name   # same file name: the .xdmf refers to its .h5 by name
        if fmt == "gmsh22":
            meshio.write(tmp, out, file_format=fmt, binary=True)  # meshio's ASCII .msh data reader is broken
        else:
            meshio.write(tmp, out, file_format=fmt)
        if fmt == "vtu":
            _add_vtu_field_data(tmp, field_data)
        elif fmt == "xdmf":
            _add_xdmf_information(tmp, field_data)
            h5 = tmp.with_suffix(".h5")
            if h5.exists():
                os.replace(h5, path.with_suffix(".h5"))
        os.replace(tmp, path)
    finally:
        shutil.rmtree(tmpdir, ignore_errors=True)


def _checked(name, value, n, what):
    a = np.asarray(value)
    if a.ndim == 0 or len(a) != n:
        raise ValueError(f"data '{name}' must have one row per {what} ({n}), got shape {a.shape}")
    if not (np.issubdtype(a.dtype, np.number) or a.dtype == bool):
        raise ValueError(f"data '{name}' must be numbers, got dtype {a.dtype}")
    if np.issubdtype(a.dtype, np.inexact) and not np.all(np.isfinite(a)):
        raise ValueError(f"data '{name}' has {int(np.count_nonzero(~np.isfinite(a)))} non-finite values "
                         "(NaN or inf); a mesh file holds finite numbers only")
    return a


def _add_vtu_field_data(path, field_data):
    """Insert a VTK <FieldData> block (curve name -> [id, 1]) that meshio's VTU reader reads."""
    if not field_data:
        return
    tree = ET.parse(path)
    grid = tree.getroot().find("UnstructuredGrid")
    fd = ET.Element("FieldData")
    for name, value in field_data.items():
        da = ET.SubElement(fd, "DataArray", type="Int64", Name=name, NumberOfTuples=str(len(value)),
                           format="ascii")
        da.text = " ".join(str(int(v)) for v in value)
    grid.insert(0, fd)   # VTK expects FieldData before the Piece
    tree.write(path, xml_declaration=True)


def _add_xdmf_information(path, field_data):
    """Insert the <Information> element that meshio's XDMF reader turns into field data."""
    if not field_data:
        return
    tree = ET.parse(path)
    grid = tree.getroot().find("Domain/Grid")
    root = ET.Element("main")
    for name, (tag, dim) in field_data.items():
        ET.SubElement(root, "map", key=name, dim=str(int(dim))).text = str(int(tag))
    info = ET.Element("Information", Name="Information", Value=str(len(field_data)))
    info.text = ET.tostring(root, encoding="unicode")
    grid.insert(0, info)
    tree.write(path, xml_declaration=True)


# ----------------------------------------------------------------------------- read

def meshio_read(path, file_format=None):
    """``meshio.read`` that raises :class:`MeshError` (a ValueError) for a damaged file.

    meshio prints why a file could not be read and then calls ``sys.exit(1)``: its words go
    into the message instead, and the process lives on.
    """
    import meshio

    said = io.StringIO()
    try:
        with contextlib.redirect_stdout(said), contextlib.redirect_stderr(said), warnings.catch_warnings():
            # meshio's binary-STL size test overflows on an ASCII file's header, harmlessly
            warnings.filterwarnings("ignore", "overflow encountered", RuntimeWarning)
            raw = meshio.read(path, file_format=file_format)
    except (Exception, SystemExit) as exc:   # meshio raises assorted errors for damaged files
        why = " ".join(said.getvalue().split()).removeprefix("Error: ") or str(exc) or type(exc).__name__
        raise MeshError(f"cannot read mesh file {path}: {why}") from None
    if said.getvalue().strip():
        sys.stderr.write(said.getvalue())
    return raw


def read_mesh(path, with_data=False, merge_vertices=False):
    """Read a surface mesh from any triangle file meshio reads: .msh, .vtu, .xdmf (the formats
    :func:`write_mesh` writes, with named boundary curves), .obj, .stl, .ply, .off, .vtk, ...

    Returns a :class:`SurfaceMesh` whose boundary curves are the named line
    cells of the file (see the module docstring). With ``with_data=True``
    returns ``(mesh, point_data, cell_data)``: the file's vertex data (rows of
    the returned vertices) and triangle data (one row per triangle), without
    the file-convention arrays.

    Vertices that coincide (closer than ``MERGE_TOL`` x the mean edge length) leave the
    triangles unconnected there. ``merge_vertices=True`` merges them (a RuntimeWarning says
    how many). An STL file stores every triangle's corners and meshio merges only the
    bit-identical ones: there, coinciding vertices are refused with their count unless merged;
    in other formats they are kept (the two sides of a slit coincide).

    Raises FileNotFoundError (with the path) for a missing file, ValueError
    for an unknown extension, :class:`MeshError` for a file without triangles,
    with coinciding vertices, or with boundary segments that are not edges of the triangles.

    >>> mesh = read_mesh("meshes/sphere_r1_500.vtu")     # doctest: +SKIP
    """
    path = Path(path)
    fmt = _read_format(path)
    if not path.is_file():
        raise FileNotFoundError(f"mesh file not found: {path}")
    raw = meshio_read(path, fmt)

    blocks = [(i, c) for i, c in enumerate(raw.cells) if c.type == "triangle"]
    if not blocks:
        types = sorted({c.type for c in raw.cells}) or ["none"]
        raise MeshError(f"mesh file {path} has no triangles (cell types: {', '.join(types)})")
    # a surface made of triangles and other faces would lose the others without a word
    other = sorted({c.type for c in raw.cells if c.type not in ("triangle", "line", "vertex")})
    if other:
        raise MeshError(f"mesh file {path} has cells other than triangles ({', '.join(other)}); femshell needs a "
                        "triangle mesh (split the other faces into triangles, e.g. with gmsh)")
    tri = np.concatenate([c.data for _, c in blocks]).astype(np.int64)
    bad = (tri < 0) | (tri >= len(raw.points))
    if bad.any():
        raise MeshError(f"mesh file {path}: triangle {int(np.argmax(bad.any(axis=1)))} has vertex index "
                        f"{int(tri[bad][0])}, outside [0, {len(raw.points) - 1}] (the file's points)")
    line_blocks = [(i, c) for i, c in enumerate(raw.cells) if c.type == "line"]

    boundary = {}
    if line_blocks:
        seg = np.concatenate([c.data for _, c in line_blocks]).astype(np.int64)
        key = next((k for k in (_BOUNDARY_ID, "gmsh:physical") if k in raw.cell_data), None)
        if key is None:
            ids = np.zeros(len(seg), np.int64)
        else:
            ids = np.concatenate([np.asarray(raw.cell_data[key][i]) for i, _ in line_blocks]).astype(np.int64)
        names = {int(v[0]): str(k) for k, v in raw.field_data.items()
                 if np.size(v) >= 2 and int(np.ravel(v)[1]) == 1}
        for i in np.unique(ids):   # a loop over the handful of curves
            boundary[names.get(int(i), f"curve-{int(i)}")] = seg[ids == i]

    # keep only the vertices that triangles use (gmsh files carry geometry points)
    points = np.asarray(raw.points, float)
    used = np.unique(tri)
    point_data = {k: np.asarray(v) for k, v in raw.point_data.items() if not k.startswith("gmsh:")}
    if len(used) < len(points):
        new = np.full(len(points), -1, np.int64)
        new[used] = np.arange(len(used))
        tri = new[tri]
        for k, s in boundary.items():
            if (new[s] < 0).any():
                raise MeshError(f"boundary curve '{k}' in {path} has a vertex that no triangle uses")
            boundary[k] = new[s]
        points = points[used]
        point_data = {k: v[used] for k, v in point_data.items()}
    points, tri, boundary, point_data = _merged(path, points, tri, boundary, point_data, merge_vertices)
    mesh = SurfaceMesh(points, tri, boundary, name=path.name)
    mesh.topology   # validate now: non-manifold edges or stray segments raise MeshError here
    if not with_data:
        return mesh
    cell_data = {k: np.concatenate([np.asarray(v[i]) for i, _ in blocks])
                 for k, v in raw.cell_data.items() if k not in _INTERNAL and not k.startswith("gmsh:")}
    return mesh, point_data, cell_data


def _merged(path, points, tri, boundary, point_data, merge):
    """The mesh with coinciding vertices merged (``merge``) or, in an STL file, refused (see :func:`read_mesh`);
    elsewhere they may be meant (the two sides of a slit) and are kept unless merging is asked for."""
    if not merge and path.suffix.lower() != ".stl":
        return points, tri, boundary, point_data
    rep = _coincident(points, tri)
    n_dup = int(np.count_nonzero(rep != np.arange(len(points))))
    if not n_dup:
        return points, tri, boundary, point_data
    if not merge:
        raise MeshError(f"mesh file {path}: {n_dup} of its {len(points)} vertices coincide with another (within "
                        f"{MERGE_TOL:g} of the mean edge length), so the triangles are not connected there (an STL "
                        "file stores each triangle's corners separately); merge them: [mesh] merge_vertices = true "
                        "in a scene, read_mesh(..., merge_vertices=True) in Python")
    keep = np.unique(rep)
    new = np.full(len(points), -1, np.int64)
    new[keep] = np.arange(len(keep))
    tri = new[rep[tri]]
    collapsed = (tri[:, 0] == tri[:, 1]) | (tri[:, 1] == tri[:, 2]) | (tri[:, 2] == tri[:, 0])
    if collapsed.any():
        raise MeshError(f"mesh file {path}: merging its {n_dup} coinciding vertices collapses "
                        f"{int(collapsed.sum())} triangles to lines or points (triangles smaller than "
                        f"{MERGE_TOL:g} of the mean edge); repair the mesh")
    warnings.warn(f"mesh file {path}: merged {n_dup} vertices that coincide with another (within {MERGE_TOL:g} of "
                  f"the mean edge length): {len(points)} -> {len(keep)} vertices", RuntimeWarning, stacklevel=3)
    boundary = {k: new[rep[s]] for k, s in boundary.items()}
    return points[keep], tri, boundary, {k: v[keep] for k, v in point_data.items()}
