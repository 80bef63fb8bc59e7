"""From a validated scene to the objects it needs, and nothing else.

* :func:`load_scene`: a TOML file or an embedded scene name (+ ``--set`` overrides) ->
  :class:`~femshell.scene.schema.Scene` (validated; nothing is built).
* :func:`make_mesh`: the mesh (gmsh generator or file); boundary-curve names of mesh
  files are checked here against the scene's conditions and loads.
* :func:`plan`: what a run will build, as lines for ``--dry-run`` and a dict of flags;
  builds no shell model, no chemistry, no solver.
* :func:`shell_parts` (static, continuation): ShellModel with boundary conditions and
  loads, and the rest state as a function of the growth. No chemistry is built.
* :func:`time_loop` (time): the :class:`~femshell.coupled.CoupledLoop` (its chemistry builds
  a diffusion operator only for D > 0). No continuation machinery is imported.

Units: lengths in cell sizes, time in 1/β, E = 1 by default (theory §1.3).
"""

from __future__ import annotations

import difflib
import math
from dataclasses import asdict, fields
from importlib import resources
from pathlib import Path

import numpy as np

from .._interrupts import committing, step_scope
from ..analysis import count_spots, find_spots, same_pattern
from ..growth import GrowthRestState
from ..mesh import check_mesh, generators
from ..mesh.io import read_mesh
from .config import NEWTON_KEYS, TIME_KINDS, TimeSolver
from .schema import Scene, SceneError, validate
from .text import apply_overrides, parse_scene, tomllib

__all__ = ["load_scene", "list_scenes", "embedded_scene_path", "make_mesh", "plan", "boundary_conditions",
           "make_loads", "shell_parts", "ShellParts", "time_loop", "count_unknowns"]

AXIS = {"x": 0, "y": 1, "z": 2}


# ----------------------------------------------------------------------------- finding scenes

def _scenes_dir():
    return resources.files("femshell") / "scenes"


def list_scenes() -> dict:
    """Embedded scenes: name -> one-line description (sorted by name, ``default`` first)."""
    out = {}
    d = _scenes_dir()
    names = sorted(p.name[:-5] for p in d.iterdir() if p.name.endswith(".toml"))
    names.sort(key=lambda n: (n != "default", n))
    for n in names:
        try:
            desc = tomllib.loads((d / f"{n}.toml").read_text(encoding="utf-8")).get("description", "")
        except Exception as exc:  # a broken embedded scene is a bug, but listing must still work
            desc = f"(unreadable: {exc})"
        out[n] = str(desc).strip()
    return out


def embedded_scene_path(name: str):
    """The path of an embedded scene, or None."""
    p = _scenes_dir() / f"{name}.toml"
    return p if p.is_file() else None


def load_scene(scene, overrides=()) -> Scene:
    """A validated scene from a .toml path or an embedded scene name, with ``--set`` overrides.

    A :class:`Scene` (already validated) is returned as it is. Raises :class:`SceneError`
    (a ValueError) with one line per problem.
    """
    if isinstance(scene, Scene):
        if overrides:
            raise SceneError(f"scene '{scene.name}' is already loaded: give overrides to load_scene "
                             "together with its file or name")
        return scene
    if not isinstance(scene, (str, Path)):
        raise SceneError(f"a scene is a .toml path, an embedded scene name or a Scene, got {type(scene).__name__}")
    text_path = Path(str(scene)).expanduser()
    if str(scene).endswith(".toml") or text_path.is_file() or "/" in str(scene) \
            or (text_path.is_dir() and embedded_scene_path(str(scene)) is None):
        if text_path.is_dir():
            hint = (f"; it holds a run: femshell run --out {scene} --resume continues it, femshell render {scene} "
                    "draws it" if (text_path / "summary.json").exists() or (text_path / "checkpoint.npz").exists()
                    else "")
            raise SceneError(f"{scene}: a directory, not a scene file (a scene is a .toml file or an embedded "
                             f"scene name; `femshell scenes` lists them){hint}")
        if not text_path.is_file():
            raise SceneError(f"{scene}: no such scene file")
        label = str(scene)
        try:
            text = text_path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise SceneError(f"{label}: cannot read the scene file ({exc})") from None
        source, name, base = text_path.resolve(), text_path.stem, text_path.resolve().parent
    else:
        p = embedded_scene_path(str(scene))
        if p is None:
            names = list(list_scenes())
            s = difflib.get_close_matches(str(scene), names, n=1, cutoff=0.5)
            hint = f"; did you mean '{s[0]}'?" if s else ""
            raise SceneError(f"{scene}: no such scene file or embedded scene{hint} (embedded: {', '.join(names)}; "
                             "`femshell scenes` lists them)")
        label = f"{scene}.toml"
        text = p.read_text(encoding="utf-8")
        source, name, base = Path(str(p)), str(scene), Path.cwd()
    raw = parse_scene(text, label)
    raw = apply_overrides(raw, overrides, label)
    return validate(raw, name=name, label=label, source=source, base_dir=base)


# ----------------------------------------------------------------------------- mesh

def make_mesh(scene: Scene):
    """The scene's mesh (gmsh or file); SceneError for generator errors and unknown curve names."""
    m = asdict(scene.mesh)
    kind = scene.mesh_kind
    try:
        if kind == "file":
            mesh = read_mesh(m["file"], merge_vertices=m.get("merge_vertices", False))
            report = check_mesh(mesh)   # a drawn mesh may be degenerate, tangled or misoriented: say so now
            if report.n_components > 1:
                _check_pieces_supported(mesh, report.n_components, scene.boundary, Path(m["file"]).name)
        else:
            kw = {k: v for k, v in m.items() if v is not None}
            if kind == "hemisphere" and "hole_angle" in kw:
                kw["hole_angle"] = math.radians(kw["hole_angle"])
            if kind == "cylinder" and "angle_range" in kw:
                kw["angle_range"] = tuple(math.radians(a) for a in kw["angle_range"])
            if kind in ("sphere", "hemisphere", "disk", "annulus", "cylinder") and "structured" in kw:
                kw.pop("structured")
            if kind in ("plate", "strip") and not kw.get("structured"):
                kw.pop("diagonal", None)
            mesh = getattr(generators, kind)(**kw)
    except (ValueError, RuntimeError, OSError) as exc:
        raise SceneError(f"{scene.label}: [mesh] {kind}: {exc}") from None
    if kind == "file":
        curves = tuple(mesh.topology.boundary_edge_groups)
        errors = []
        for sec, items in (("boundary", scene.boundary), ("loads", scene.loads)):
            for i, it in enumerate(items):
                c = it.curve
                if c is not None and c not in curves:
                    errors.append(f"{scene.label}: [[{sec}]] #{i + 1} curve = \"{c}\" is not a boundary curve of "
                                  f"{Path(m['file']).name} (curves: {', '.join(curves) or 'none: the mesh is closed'})")
        if errors:
            raise SceneError(errors)
    return mesh


def _check_pieces_supported(mesh, n_pieces, boundary, name):
    """A mesh of several pieces needs supports on each: a free shell is pinned as one piece, and a piece
    without a support floats (a singular Hessian, met only after the step cuts)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    if not boundary:
        raise ValueError(f"{name} has {n_pieces} separate pieces; a free shell is pinned against rigid motion as "
                         "one piece, so give each piece supports ([[boundary]]) or use a mesh of one piece")
    e = mesh.topology.edges
    n = mesh.n_vertices
    _, piece = connected_components(coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)), directed=False)
    groups = mesh.topology.boundary_vertex_groups
    held = {int(p) for b in boundary if b.curve in groups for p in piece[groups[b.curve]]}
    free = [k for k in range(n_pieces) if k not in held]
    if free:
        where = "; ".join(f"piece {k}: {int(np.sum(piece == k))} vertices around "
                          f"{np.round(mesh.points[piece == k].mean(axis=0), 3).tolist()}" for k in free[:3])
        raise ValueError(f"{name} has {n_pieces} separate pieces and {len(free)} of them no support ({where}); "
                         "give each piece a [[boundary]] curve, or merge duplicate vertices if the pieces should "
                         "be one surface")


def boundary_conditions(scene: Scene, mesh) -> list:
    from ..shell import Clamped, Prescribed, SimplySupported, Symmetry      # deferred: jax

    out = []
    for bc in scene.boundary:
        t = bc.type
        if t == "clamped":
            out.append(Clamped(bc.curve))
        elif t == "simply_supported":
            out.append(SimplySupported(bc.curve))
        elif t == "symmetry":
            out.append(Symmetry(bc.axis, bc.value))
        else:
            comps = tuple(sorted({AXIS[c] for c in bc.components}))
            out.append(Prescribed(curve=bc.curve, components=comps, displacement=tuple(bc.displacement)))
    return out


def make_loads(scene: Scene, mesh) -> list:
    # deferred: jax
    from ..shell import AreaLoad, DeadLoad, DeadPressure, EdgeForce, EdgeMoment, FollowerPressure, PointForce

    out = []
    for ld in scene.loads:
        t = ld.type
        if t == "point_force":
            if ld.point is not None:
                v = int(np.argmin(np.linalg.norm(mesh.points - np.asarray(ld.point), axis=1)))
                out.append(PointForce(mesh, [v], list(ld.force)))
            else:
                verts = mesh.topology.boundary_vertex_groups[ld.curve]
                out.append(PointForce(mesh, verts, list(ld.force)))
        elif t == "area_load":
            out.append(AreaLoad(mesh, list(ld.traction)))
        elif t == "edge_force":
            out.append(EdgeForce(mesh, ld.curve, list(ld.force)))
        elif t == "dead_pressure":
            out.append(DeadPressure(mesh, ld.pressure))
        elif t == "follower_pressure":
            out.append(FollowerPressure(ld.pressure))
        elif t == "edge_moment":
            out.append(EdgeMoment(ld.curve, ld.moment))
        else:  # pragma: no cover - validated
            raise SceneError(f"{scene.label}: unknown load type {t}")
    assert all(isinstance(x, (DeadLoad, FollowerPressure, EdgeMoment)) for x in out)
    return out


def count_unknowns(mesh, bcs) -> dict:
    """Free unknowns of the shell (as ShellModel counts them) without building the model."""
    from ..shell.boundary import rigid_body_pins      # deferred: jax
    from ..shell.element import CLAMPED, FREE, INTERIOR, SYMMETRY

    t = mesh.topology
    n, ne = mesh.n_vertices, t.n_edges
    fixed = np.zeros((n, 3), bool)
    values = mesh.points.copy()
    kind = np.where(t.edge_faces[:, 1] >= 0, INTERIOR, FREE)
    direction = np.zeros((ne, 3))
    for bc in bcs:
        bc.apply(mesh, fixed, values, kind, direction)
    pinned = 0
    if not fixed.any():
        for v, c in rigid_body_pins(mesh.points):
            fixed[v, c] = True
        pinned = 6
    fixed_theta = int(((kind == CLAMPED) | (kind == SYMMETRY)).sum())
    total = 3 * n + ne
    free = total - int(fixed.sum()) - fixed_theta
    return {"total": total, "free": free, "positions_fixed": int(fixed.sum()), "angles_fixed": fixed_theta,
            "rigid_pins": pinned}


# ----------------------------------------------------------------------------- growth of mechanics scenes

def centroid_radius(mesh) -> np.ndarray:
    """Distance of each triangle's centroid from the z axis (the disk test's r)."""
    c = mesh.points[mesh.triangles].mean(axis=1)
    return np.hypot(c[:, 0], c[:, 1])


def stretch_field(growth, mesh, strain=None, inner_radius=None) -> np.ndarray:
    """Element stretches s (m,) of a mechanics growth law (:class:`GrowthConfig`; theory §1.1, §1.6).

    uniform: s = 1 + g; inner_region: s = 1 + g f(r), f the step 1 for r < R2 (by centroid), or
    f = expit(2 (R2 − r)/transition) for transition > 0.
    """
    m = mesh.n_triangles
    law = growth.law
    g = (growth.strain or 0.0) if strain is None else strain
    if law in ("none", None):
        return np.ones(m)
    if law == "uniform":
        return np.full(m, 1.0 + g)
    r2 = growth.inner_radius if inner_radius is None else inner_radius
    r = centroid_radius(mesh)
    w = growth.transition or 0.0
    if w > 0:
        from scipy.special import expit
        frac = expit(2.0 * (r2 - r) / w)
    else:
        frac = (r < r2).astype(float)
    return 1.0 + g * frac


class ShellParts:
    """The mechanics of a static or continuation scene.

    ``model`` (ShellModel with conditions and loads), ``growth`` (its
    :class:`~femshell.growth.GrowthRestState`), ``rest_for(s)`` -> RestState, ``apply(s)`` (kept in ``s``),
    ``mean_curvature(u)`` -> H per element and per vertex.
    """

    def __init__(self, scene: Scene, mesh):
        from ..shell import Material, ShellModel      # deferred: jax

        self.scene = scene
        self.mesh = mesh
        mat, sh = scene.material, scene.shell
        self.h0 = sh.thickness
        self.mode = sh.thickness_mode
        self.bcs = boundary_conditions(scene, mesh)
        self.loads = make_loads(scene, mesh)
        try:
            # the thickness: a flat mesh gets flat_rest_state, a curved one its drawn shape as the stress-free one
            self.model = ShellModel(mesh, Material(E=mat.E, nu=mat.nu, law=mat.law), self.h0, self.bcs,
                                    self.loads)
        except ValueError as exc:
            raise SceneError(f"{scene.label}: {'[mesh]' if 'metric' in str(exc) else '[[boundary]]'}: {exc}") from None
        k0 = sh.natural_curvature
        self.growth = GrowthRestState(self.model, self.h0, self.mode, "mesh" if k0 == "mesh" else "k0",
                                      0.0 if k0 == "mesh" else float(k0))
        self.rest_for = self.growth.rest_state
        self.mean_curvature = self.growth.mean_curvature
        self.s = np.ones(mesh.n_triangles)
        if self.model.drawn_curved and k0 != "mesh":
            self.apply(self.s)          # a given rest curvature k0 holds before (and without) any growth

    def apply(self, s):
        self.s = np.asarray(s, dtype=float)
        self.growth.apply(self.s)


def shell_parts(scene: Scene, mesh) -> ShellParts:
    return ShellParts(scene, mesh)


# ----------------------------------------------------------------------------- the time loop

def coupled_parameters(scene: Scene):
    """MechanochemicalModel, TimeStepping and the initial condition of a time scene."""
    from ..coupled import InitialSpot, MechanochemicalModel, TimeStepping      # deferred: jax

    mat, sh, gr, ch, ini, so = (scene.material, scene.shell, scene.growth, scene.chemistry, scene.initial,
                                scene.solver)
    k0 = sh.natural_curvature
    try:
        params = MechanochemicalModel(
            nu=mat.nu, E=mat.E, membrane_law=mat.law, h0=sh.thickness, thickness_mode=sh.thickness_mode,
            k0=None if k0 == "mesh" else float(k0), lam_max=gr.lam_max, lam_min=gr.lam_min,
            lam0=gr.lam0, b=gr.b, c_star=gr.c_star, w=ch.w, Hs=ch.Hs, beta=ch.beta, D=ch.D,
            rest_curvature="mesh" if k0 == "mesh" else "k0")
    except ValueError as exc:
        raise SceneError(f"{scene.label}: [growth]/[chemistry]: {exc}") from None
    # every time-loop control of the scene is a TimeStepping field of the same name; the Newton ones only if given
    kw = {f.name: getattr(so, f.name) for f in fields(TimeSolver) if f.name not in ("kind", *NEWTON_KEYS)}
    if so.newton_rtol is not None:
        kw["newton_rtol"] = so.newton_rtol
    if so.newton_max_iter is not None:
        kw["newton_max_iter"] = so.newton_max_iter
    kw["newton_backend"] = so.backend
    try:
        stepping = TimeStepping(**kw)
    except ValueError as exc:
        raise SceneError(f"{scene.label}: [solver] {exc}") from None
    c0 = None
    if ini.kind in ("spot", "spots"):
        c0 = InitialSpot(amplitude=ini.amplitude, width=ini.width, elongation=ini.elongation,
                         pole=tuple(ini.pole), direction=None if ini.direction is None else tuple(ini.direction),
                         distance=ini.distance)
    return params, stepping, c0


def spot_centres(ini) -> np.ndarray:
    """Unit directions of the spots of ``[initial] kind = "spots"`` (k, 3).

    "icosahedron": the 12 vertices of a regular icosahedron, turned so that one of them
    is ``pole``; "random": ``count`` directions uniform on the sphere (``seed``), the first
    one moved to ``pole``.
    """
    pole = np.asarray(ini.pole, float)
    pole = pole / np.linalg.norm(pole)
    if ini.layout == "icosahedron":
        phi = (1 + math.sqrt(5)) / 2
        v = np.array([[-1, phi, 0], [1, phi, 0], [-1, -phi, 0], [1, -phi, 0], [0, -1, phi], [0, 1, phi],
                      [0, -1, -phi], [0, 1, -phi], [phi, 0, -1], [phi, 0, 1], [-phi, 0, -1], [-phi, 0, 1]], float)
    else:
        rng = np.random.default_rng(int(ini.seed))
        v = rng.standard_normal((int(ini.count), 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    a = v[0] if ini.layout == "random" else v[5]
    # rotation taking a to the pole (Rodrigues)
    w = np.cross(a, pole)
    s, c = np.linalg.norm(w), float(a @ pole)
    if s < 1e-12:
        rot = np.eye(3) if c > 0 else -np.eye(3)
    else:
        k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
        rot = np.eye(3) + k + k @ k * ((1 - c) / s**2)
    return v @ rot.T


def initial_concentration(scene: Scene, mesh, params):
    """The c0 given to the time loop: an InitialSpot, a vertex array (several spots) or None."""
    from ..coupled import gaussian_spot      # deferred: jax

    ini = scene.initial
    _, _, spot = coupled_parameters(scene)
    if ini.kind != "spots":
        return spot
    amp = params.c_max if ini.amplitude is None else ini.amplitude
    width = params.h0 if ini.width is None else ini.width
    pts = np.asarray(mesh.points, float)
    # each vertex takes its largest spot (overlapping spots do not add up above the amplitude)
    direction = None if ini.direction is None else tuple(ini.direction)
    return np.max([gaussian_spot(pts, amp, width, pole=tuple(p), elongation=ini.elongation, direction=direction,
                                 distance=ini.distance) for p in spot_centres(ini)], axis=0)


def loop_observers(log=None):
    """The callbacks of a run's coupled loop: regions counted and compared by :mod:`femshell.analysis`,
    each step's commit held against Ctrl-C/SIGTERM (:mod:`femshell._interrupts`), progress to ``log``."""
    from ..coupled import LoopObservers      # deferred: jax

    return LoopObservers(log=log, count_regions=count_spots, measure_pattern=find_spots, same_pattern=same_pattern,
                         commit=committing, step_scope=step_scope)


def time_loop(scene: Scene, mesh, state=None, log=None, observers=None):
    """The CoupledLoop of a time scene: a fresh one (initial equilibrium computed) or from ``state``;
    ``observers`` default :func:`loop_observers` (``log``)."""
    from ..coupled import CoupledLoop      # deferred: jax

    params, stepping, _ = coupled_parameters(scene)
    bcs = boundary_conditions(scene, mesh)
    observers = loop_observers(log) if observers is None else observers
    if state is not None:
        return CoupledLoop.from_state_dict(mesh, params, state, stepping, boundary_conditions=bcs, log=log,
                                           observers=observers)
    c0 = initial_concentration(scene, mesh, params)
    return CoupledLoop(mesh, params, stepping, c0=c0, boundary_conditions=bcs, log=log, observers=observers)


# ----------------------------------------------------------------------------- dry run

def _source_text(scene: Scene) -> str:
    """Where a scene came from, short: an embedded one as femshell/scenes/NAME.toml, a file as given."""
    src = scene.source
    if src is None:
        return scene.label
    src = Path(src)
    if src.parent == Path(_scenes_dir()):
        return f"femshell/scenes/{src.name}"
    return str(src)


def _time_plan(scene: Scene, lines: list, flags: dict, operators: list):
    """The dry-run lines of a time scene's chemistry, initial condition and loop."""
    so, sh = scene.solver, scene.shell
    ch, ini = scene.chemistry, scene.initial
    flags["chemistry"] = True
    flags["time_loop"] = True
    if ch.D > 0:
        flags["diffusion_operator"] = True
        operators.append("P1 Laplace-Beltrami stiffness + lumped mass on the deformed surface (D > 0)")
        chem = f"D={ch.D:g}: P1 Laplace-Beltrami operator, diffusion implicit, degradation exact"
    else:
        chem = "D=0: exact exponential update per vertex (no diffusion operator built)"
    lines.append(f"  chemistry  {chem}; w={ch.w:g} Hs={ch.Hs:g} beta={ch.beta:g} "
                 f"(c_max = {ch.w * ch.Hs / ch.beta if ch.beta else math.inf:g})")
    if ini.kind == "spots":
        n = 12 if ini.layout == "icosahedron" else ini.count
        lines.append(f"  initial    {n} Gaussian spots ({ini.layout}, one at pole {tuple(ini.pole)}): "
                     f"amplitude {ini.amplitude if ini.amplitude is not None else 'c_max'} width "
                     f"{ini.width if ini.width is not None else sh.thickness}")
    elif ini.kind == "spot":
        lines.append(f"  initial    Gaussian spot at pole {tuple(ini.pole)}: amplitude "
                     f"{ini.amplitude if ini.amplitude is not None else 'c_max'} width "
                     f"{ini.width if ini.width is not None else sh.thickness} elongation "
                     f"{ini.elongation:g}")
    else:
        lines.append("  initial    c = 0")
    pattern_stop = (f" or pattern unchanged for {so.stationary_pattern_time:g}"
                    if so.stationary_pattern_time else "")
    lines.append(f"  solver     mechanochemical time loop: t_final={so.t_final:g}, dt in [{so.dt_min:g}, "
                 f"{so.dt_max:g}], ds_max={so.ds_max:g}"
                 + (", source extrapolated to each step's midpoint where stable"
                    if so.source_rule == "extrapolated" else "")
                 + (f", steps by their local error <= {so.error_tol:g} (|Δs| <= {so.error_ds_max:g})"
                    if so.step_control == "error" else "")
                 + ", stationary below rates "
                 f"{so.stationary_rate_c:g}/{so.stationary_rate_x:g} for {so.stationary_steps} steps"
                 f"{pattern_stop}; Newton to stable equilibria")


def _shown(value):
    """A mesh argument as the scene's TOML has it (a pair as a list)."""
    return list(value) if isinstance(value, tuple) else value


def plan(scene: Scene, mesh=None) -> tuple[list, dict]:
    """(lines, flags): what a run of ``scene`` builds. Builds the mesh if not given, nothing else."""
    if mesh is None:
        mesh = make_mesh(scene)
    kind = scene.kind
    t = mesh.topology
    bcs = boundary_conditions(scene, mesh)
    try:
        unk = count_unknowns(mesh, bcs)
    except ValueError as exc:
        raise SceneError(f"{scene.label}: [[boundary]]: {exc}") from None
    # a disk's "inner" circle is a named curve of interior edges (the mesh is refined inside it), not a boundary
    curves = [k + (" (interior)" if len(e) and np.all(t.edge_faces[e, 1] >= 0) else "")
              for k, e in t.boundary_edge_groups.items()]
    lines = [f"scene '{scene.name}' ({_source_text(scene)}): {scene.description or '(no description)'}"]
    args = ", ".join(f"{k}={_shown(v)}" for k, v in asdict(scene.mesh).items() if v is not None)
    lines.append(f"  mesh       {scene.mesh_kind}({args}): {mesh.n_vertices} vertices, {mesh.n_triangles} triangles, "
                 f"{t.n_edges} edges; " + (f"curves {', '.join(curves)}" if curves else "closed (no boundary)"))
    mat, sh = scene.material, scene.shell
    lines.append(f"  shell      Kirchhoff-Love mid-edge element, E={mat.E:g} nu={mat.nu:g} "
                 f"membrane={mat.law} h={sh.thickness:g} "
                 f"thickness_mode={sh.thickness_mode} rest curvature={sh.natural_curvature}")
    lines.append(f"  unknowns   {unk['free']} free of {unk['total']} (3 per vertex + 1 per edge; "
                 f"{unk['positions_fixed']} position components and {unk['angles_fixed']} edge angles fixed"
                 + (", rigid-body motions pinned" if unk["rigid_pins"] else "") + ")")
    bl = ", ".join(f"{b.type}({b.curve or b.axis})" for b in scene.boundary) or "none (free)"
    lines.append(f"  boundary   {bl}")
    if scene.loads:
        ll = ", ".join(f"{x.type}" + (f"({x.curve})" if x.curve else "") for x in scene.loads)
        lines.append(f"  loads      {ll} (times the load factor)")
    gr = scene.growth
    law = gr.law
    if law == "contractility":
        lines.append(f"  growth     contractility: Λmax={gr.lam_max:g} Λmin={gr.lam_min:g} "
                     f"Λ0={gr.lam0 if gr.lam0 is not None else gr.lam_max:g} b={gr.b:g} c*={gr.c_star:g}")
    elif law == "uniform":
        lines.append(f"  growth     uniform: s = 1 + {gr.strain:g}")
    elif law == "inner_region":
        lines.append(f"  growth     inner region r < {gr.inner_radius:g}: s = 1 + {gr.strain:g}"
                     + (f", smooth step of width {gr.transition:g}" if gr.transition else ""))
    else:
        lines.append("  growth     none")
    operators = ["shell energy, gradient and Hessian (JAX, sparse assembly)", "sparse LDLᵀ (Newton, inertia)"]
    flags = {"mesh": True, "shell": True, "chemistry": False, "diffusion_operator": False, "time_loop": False,
             "continuation": False, "loads": bool(scene.loads), "n_vertices": mesh.n_vertices,
             "n_triangles": mesh.n_triangles, "unknowns": unk["free"], "solver": kind}
    so = scene.solver
    if kind in TIME_KINDS:
        _time_plan(scene, lines, flags, operators)
        if kind == "pattern-continuation":
            flags["continuation"] = True
            operators.append("LU of the coupled Jacobian (stationary Newton, bordered solves, det J's sign)")
            lines.append(f"  then       the stationary pattern (Newton on (u, c)) followed in {so.parameter}"
                         + (f" to {so.stop:g}" if so.stop is not None else "") + f", at most {so.continuation_steps} "
                         f"points, ds={so.continuation_ds:g}; {so.n_modes} leading eigenvalues per point")
    elif kind == "static":
        lines.append(f"  solver     static: {so.steps} increments of the load factor / growth from 0 to 1, "
                     f"Newton to {'stable ' if so.stable else ''}equilibria (up to {so.max_cuts} cuts)")
    elif kind == "linear-buckling":
        operators.append("bordered (rigid-motion deflated) shift-invert Lanczos of the buckling pencil")
        lines.append(f"  solver     linear buckling at factor {so.at:g} of the loads / growth"
                     + (f" (reached in {so.steps} increments)" if so.at > 0 else " (the rest shape)")
                     + f": {so.modes} modes" + (f" nearest factor {so.target:g}" if so.target is not None else ""))
    else:
        flags["continuation"] = True
        operators.append("bordered solves, shift-invert Lanczos for the smallest eigenvalues")
        lines.append(f"  solver     pseudo-arclength continuation in {so.parameter} from "
                     f"{so.start if so.start is not None else 'the scene value'} to {so.stop}, ds={so.ds:g}, "
                     f"max {so.max_steps} steps; folds/branch points located: {so.detect}"
                     + ("; then the branch of the first branch point" if so.switch_branch else ""))
    lines.append(f"  operators  {'; '.join(operators)}")
    out = scene.output
    lines.append(f"  output     frame every {out.every} step(s): series.pvd + VTU with {', '.join(out.fields)}; "
                 f"checkpoint every {out.checkpoint_every} step(s); summary.json"
                 + ("; pictures" if out.pictures else "") + ("; movie" if out.movie else ""))
    not_built = [name for name, on in (("chemistry", flags["chemistry"]), ("diffusion operator",
                                        flags["diffusion_operator"]), ("time loop", flags["time_loop"]),
                                       ("continuation", flags["continuation"]), ("loads", flags["loads"])) if not on]
    lines.append(f"  not built  {', '.join(not_built) or '-'}")
    return lines, flags
