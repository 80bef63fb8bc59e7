"""Typed scene configuration: one dataclass per scene section.

Each field carries its TOML type, allowed range, default and a one-line description
(:func:`key`); :mod:`.schema` validates a scene against these classes and :class:`SceneConfig`
holds the validated scene as objects. A default that is a parameter of the model (E, ν,
Λmax, w, the initial spot, the time loop's controls) is not written here: it is read from the
model's own parameter class (:class:`~femshell.coupled.MechanochemicalModel`,
:class:`~femshell.coupled.InitialSpot`, :class:`~femshell.coupled.TimeStepping`) when needed.

Units: lengths in cell sizes, time in 1/β, E = 1 by default (theory §1.3).
"""

from __future__ import annotations

import copy
from dataclasses import MISSING, dataclass, field, fields
from pathlib import Path

__all__ = ["Spec", "key", "specs", "Scene", "SceneConfig", "MESH_CONFIGS", "SOLVER_CONFIGS", "TIME_KINDS", "BOUNDARY_TYPES",
           "LOAD_TYPES", "GROWTH_LAWS", "MaterialConfig", "ShellConfig", "GrowthConfig", "ChemistryConfig",
           "InitialConfig", "OutputConfig", "StaticSolver", "ContinuationSolver", "TimeSolver", "BoundaryConfig",
           "LoadConfig"]

F, I, B, S = "float", "int", "bool", "str"
POS = dict(lo=0.0, lo_open=True)
NONNEG = dict(lo=0.0)


class Spec:
    """One key: its type, range, default and a short description.

    ``kind``: "float", "int", "bool", "str", "path", "vec3" (three numbers), "pair" (two
    numbers), "strlist", "num_or_str" (a number or one of ``choices``).
    ``lo``/``hi`` with ``lo_open``/``hi_open``: the allowed range (closed by default).
    ``default`` is computed on use where it comes from a model class (``factory``).
    """

    def __init__(self, kind, default=None, doc="", *, lo=None, hi=None, lo_open=False, hi_open=False,
                 choices=None, required=False, factory=None):
        self.kind, self._default, self.doc, self.factory = kind, default, doc, factory
        self.lo, self.hi, self.lo_open, self.hi_open = lo, hi, lo_open, hi_open
        self.choices, self.required = choices, required

    @property
    def default(self):
        return self.factory() if self.factory is not None else copy.deepcopy(self._default)

    def range_text(self, name):
        parts = []
        if self.lo is not None:
            parts.append(f"{_fmt(self.lo)} {'<' if self.lo_open else '<='} ")
        parts.append(name)
        if self.hi is not None:
            parts.append(f" {'<' if self.hi_open else '<='} {_fmt(self.hi)}")
        return "".join(parts)


def _fmt(v):
    if isinstance(v, float) and v.is_integer() and abs(v) < 1e15:
        return str(int(v))
    return repr(v) if isinstance(v, str) else str(v)


def key(kind, doc, default=None, *, factory=None, lo=None, hi=None, lo_open=False, hi_open=False, choices=None,
        required=False, docs=None):
    """A dataclass field that is a scene key (``docs``: a description per [[boundary]]/[[loads]] type)."""
    meta = dict(kind=kind, doc=doc, lo=lo, hi=hi, lo_open=lo_open, hi_open=hi_open, choices=choices,
                required=required, docs=docs or {})
    if factory is not None:
        return field(default_factory=factory, metadata=meta)
    if isinstance(default, (list, dict)):
        return field(default_factory=lambda: copy.deepcopy(default), metadata=meta)
    return field(default=default, metadata=meta)


def _spec(f, doc=None) -> Spec:
    m = f.metadata
    factory = default = None
    if f.default_factory is not MISSING:
        factory = f.default_factory
    elif f.default is not MISSING:
        default = f.default
    return Spec(m["kind"], default, m["doc"] if doc is None else doc, lo=m["lo"], hi=m["hi"], lo_open=m["lo_open"],
                hi_open=m["hi_open"], choices=m["choices"], required=m["required"], factory=factory)


def specs(cls, names=None, variant=None) -> dict:
    """name -> :class:`Spec` of the scene keys of ``cls`` (only ``names``, in the class's order, if given).

    ``variant``: the [[boundary]]/[[loads]] type whose description of a key is used where it has one.
    """
    out = {}
    for f in fields(cls):
        if "kind" not in f.metadata or (names is not None and f.name not in names):
            continue
        out[f.name] = _spec(f, f.metadata["docs"].get(variant))
    return out


def _model(cls_name, name, convert=None):
    """A default factory reading field ``name`` of the model class ``cls_name`` of femshell.coupled."""
    def factory():
        # deferred: femshell.coupled imports jax and the coupled loop; a scene is read and checked without them
        from .. import coupled

        value = next(f for f in fields(getattr(coupled, cls_name)) if f.name == name).default
        return convert(value) if convert is not None else value
    return factory


def _as_list(value):
    return None if value is None else [float(x) for x in value]


MODEL, SPOT, STEPPING = "MechanochemicalModel", "InitialSpot", "TimeStepping"


# ----------------------------------------------------------------------------- mesh

def _n_vertices():
    return key(I, "target number of vertices", lo=10, hi=5_000_000)


def _edge_length():
    return key(F, "target edge length", **POS)


def _seed():
    return key(I, "gmsh random seed (meshes are deterministic for a seed)", 0, lo=0, hi=2**31 - 1)


def _radius(default=1.0, doc="radius"):
    return key(F, doc, default, **POS)


def _structured():
    return key(B, "regular grid of right triangles (no gmsh)", False)


def _diagonal():
    return key(S, "diagonal of a structured grid", "right", choices=("right", "left", "alternate", "crossed"))


@dataclass(frozen=True)
class SphereMesh:
    radius: float = _radius()
    n_vertices: int | None = _n_vertices()
    edge_length: float | None = _edge_length()
    seed: int = _seed()


@dataclass(frozen=True)
class HemisphereMesh:
    radius: float = _radius()
    hole_angle: float | None = key(F, "polar hole half-angle (degrees)", lo=0.0, hi=90.0, lo_open=True, hi_open=True)
    n_vertices: int | None = _n_vertices()
    edge_length: float | None = _edge_length()
    seed: int = _seed()


@dataclass(frozen=True)
class DiskMesh:
    radius: float = _radius(doc="radius R1")
    inner_radius: float | None = key(F, "conforming inner circle R2", **POS)
    inner_edge_length: float | None = key(F, "edge length near the inner circle", **POS)
    refine_inside: bool = key(B, "inner_edge_length over the whole inner disk, not only near the circle", False)
    n_vertices: int | None = _n_vertices()
    edge_length: float | None = _edge_length()
    seed: int = _seed()


@dataclass(frozen=True)
class PlateMesh:
    lx: float = key(F, "x side", 1.0, **POS)
    ly: float = key(F, "y side", 1.0, **POS)
    structured: bool = _structured()
    diagonal: str = _diagonal()
    n_vertices: int | None = _n_vertices()
    edge_length: float | None = _edge_length()
    seed: int = _seed()


@dataclass(frozen=True)
class StripMesh:
    length: float = key(F, "x length", 10.0, **POS)
    width: float = key(F, "y width", 1.0, **POS)
    structured: bool = _structured()
    diagonal: str = _diagonal()
    n_vertices: int | None = _n_vertices()
    edge_length: float | None = _edge_length()
    seed: int = _seed()


@dataclass(frozen=True)
class AnnulusMesh:
    inner_radius: float = key(F, "inner radius", 0.5, **POS)
    outer_radius: float = key(F, "outer radius", 1.0, **POS)
    slit: bool = key(B, "cut along the positive x axis", False)
    n_vertices: int | None = _n_vertices()
    edge_length: float | None = _edge_length()
    seed: int = _seed()


@dataclass(frozen=True)
class CylinderMesh:
    radius: float = _radius()
    length: float = key(F, "length", 1.0, **POS)
    angle_range: tuple | None = key("pair", "panel angles [theta0, theta1] in degrees")
    n_vertices: int | None = _n_vertices()
    edge_length: float | None = _edge_length()
    seed: int = _seed()


@dataclass(frozen=True)
class FileMesh:
    file: str = key("path", "mesh file (.vtu, .msh, .xdmf, .obj, .stl, .ply, .off, ...: what meshio reads), "
                            "relative to the scene file", required=True)
    merge_vertices: bool = key(B, "merge vertices that coincide (an STL file stores each triangle's corners "
                                  "separately)", False)


#: the mesh section's class per ``kind`` (generator arguments; angles in degrees)
MESH_CONFIGS = {"sphere": SphereMesh, "hemisphere": HemisphereMesh, "disk": DiskMesh, "plate": PlateMesh,
                "strip": StripMesh, "annulus": AnnulusMesh, "cylinder": CylinderMesh, "file": FileMesh}


# ----------------------------------------------------------------------------- material, shell, growth, chemistry

@dataclass(frozen=True)
class MaterialConfig:
    E: float = key(F, "Young's modulus (only scales energies)", factory=_model(MODEL, "E"), **POS)
    nu: float = key(F, "Poisson ratio", factory=_model(MODEL, "nu"), lo=0.0, hi=0.5)
    law: str = key(S, "membrane law: St Venant-Kirchhoff (theory §1.2) or neo-Hookean (stable under strong "
                   "compression)", factory=_model(MODEL, "membrane_law"), choices=("svk", "neo-hookean"))


@dataclass(frozen=True)
class ShellConfig:
    thickness: float = key(F, "shell thickness h", required=True, **POS)
    thickness_mode: str = key(S, "grown thickness: h/s^2 (volume) or h (uniform)",
                              factory=_model(MODEL, "thickness_mode"), choices=("volume", "uniform"))
    natural_curvature: object = key("num_or_str", "rest curvature: \"mesh\" (the drawn shape is stress free) or a "
                                    "number k0 (1/length)", "mesh", choices=("mesh",))


#: the [growth] keys each law takes
GROWTH_LAWS = {"none": (), "uniform": ("strain",), "inner_region": ("strain", "inner_radius", "transition"),
               "contractility": ("lam_max", "lam_min", "lam0", "b", "c_star")}


@dataclass(frozen=True)
class GrowthConfig:
    """s = 1 + strain (uniform, or inside r < R2: inner_region), or s = Λ0/Λ(c) (contractility, theory §1.1)."""

    law: str | None = key(S, "growth law", choices=tuple(GROWTH_LAWS))
    strain: float = key(F, "growth strain: linear stretch s = 1 + strain", 0.0, lo=-1.0, lo_open=True)
    inner_radius: float | None = key(F, "radius R2 of the grown region r < R2", **POS)
    transition: float = key(F, "width of a smooth step at r = R2 (0: sharp, by element centroid)", 0.0, **NONNEG)
    lam_max: float = key(F, "contractility of untouched tissue, Λmax (>= lam_min)", factory=_model(MODEL, "lam_max"),
                         **POS)
    lam_min: float = key(F, "contractility of saturated tissue, Λmin", factory=_model(MODEL, "lam_min"), **POS)
    lam0: float | None = key(F, "reference contractility Λ0 of s = Λ0/Λ(c) (default Λmax)",
                             factory=_model(MODEL, "lam0"), **POS)
    b: float = key(F, "steepness of the contractility switch (1/concentration)", factory=_model(MODEL, "b"), **POS)
    c_star: float = key(F, "threshold concentration c* (c >= 0, so c* < 0 would pattern everything)",
                        factory=_model(MODEL, "c_star"), **NONNEG)

    @property
    def grows(self) -> bool:
        return self.law not in ("none", None)


@dataclass(frozen=True)
class ChemistryConfig:
    """∂c/∂t = D Δc + w P(H) − β c (theory §1.3)."""

    D: float = key(F, "diffusion coefficient (length^2/time)", factory=_model(MODEL, "D"), **NONNEG)
    w: float = key(F, "production rate", factory=_model(MODEL, "w"), **NONNEG)
    Hs: float = key(F, "saturation curvature (1/length)", factory=_model(MODEL, "Hs"), **POS)
    beta: float = key(F, "degradation rate (1/time)", factory=_model(MODEL, "beta"), **NONNEG)


@dataclass(frozen=True)
class InitialConfig:
    """The initial concentration: Gaussian spots of ``amplitude`` and ``width`` (theory §1.4), or c = 0."""

    kind: str = key(S, "initial concentration: one Gaussian spot at `pole`, several (`layout`), or c = 0", "spot",
                    choices=("spot", "spots", "none"))
    layout: str = key(S, "spots: centres at the 12 vertices of an icosahedron (one at `pole`) or at `count` random "
                      "directions", "icosahedron", choices=("icosahedron", "random"))
    count: int = key(I, "spots: number of random centres", 12, lo=1, hi=10000)
    seed: int = key(I, "spots: random seed of the centres", 0, lo=0)
    amplitude: float | None = key(F, "spot amplitude (default c_max = w Hs / beta)", factory=_model(SPOT, "amplitude"),
                                  **NONNEG)
    width: float | None = key(F, "spot width d (default h)", factory=_model(SPOT, "width"), **POS)
    elongation: float = key(F, "spot elongation along `direction`", factory=_model(SPOT, "elongation"), **POS)
    pole: tuple = key("vec3", "direction of the spot's centre from the mesh centroid",
                      factory=_model(SPOT, "pole", _as_list))
    direction: tuple | None = key("vec3", "tangent direction of the elongation (default x; for kind = \"spots\" "
                                  "projected onto each spot's tangent plane)", factory=_model(SPOT, "direction",
                                                                                               _as_list))
    distance: str = key(S, "distance used in the Gaussian", factory=_model(SPOT, "distance"),
                        choices=("geodesic", "chord", "planar"))


@dataclass(frozen=True)
class OutputConfig:
    every: int = key(I, "write a frame every N steps (the last step is always written)", 1, lo=1)
    checkpoint_every: int = key(I, "checkpoint every N steps (1: a kill loses no finished step)", 1, lo=1)
    pictures: bool = key(B, "top and side views (and a bifurcation diagram) at the end", True)
    movie: bool = key(B, "also render a movie of all frames at the end (femshell render does it later)", False)
    fields: tuple | None = key("strlist", "fields written in each frame (default: all that the scene has)")
    picture_field: str | None = key(S, "field of the top view (default c, else displacement)")
    cmap: str = key(S, "matplotlib colour map of the pictures", "viridis")
    progress_interval: float = key(F, "seconds between progress lines (0: every step)", 0.0, **NONNEG)


# ----------------------------------------------------------------------------- solvers

#: the Newton controls every solver kind takes
NEWTON_KEYS = ("newton_rtol", "newton_max_iter", "backend")


def _max_cuts():
    return key(I, "halvings of a failed increment before giving up", 8, lo=0)


def _stable():
    return key(B, "find stable equilibria (escape saddles)", True)


def _newton_rtol():
    return key(F, "Newton tolerance relative to the residual scale", **POS)


def _newton_max_iter():
    return key(I, "Newton iterations per solve", lo=1)


def _backend():
    return key(S, "sparse linear solver back-end", "auto", choices=("auto", "pardiso", "superlu"))


@dataclass(frozen=True)
class StaticSolver:
    """Load factor and growth ramped together from 0 to 1 in ``steps`` increments."""

    kind: str = "static"
    steps: int = key(I, "increments of the load factor / growth from 0 to 1", 10, lo=1)
    max_cuts: int = _max_cuts()
    stable: bool = _stable()
    newton_rtol: float | None = _newton_rtol()
    newton_max_iter: int | None = _newton_max_iter()
    backend: str = _backend()


@dataclass(frozen=True)
class ContinuationSolver:
    """Pseudo-arclength continuation in ``parameter`` (theory §4)."""

    kind: str = "continuation"
    parameter: str = key(S, "the continuation parameter", required=True,
                         choices=("loads.factor", "growth.strain", "growth.inner_radius"))
    start: float | None = key(F, "start value (default: the scene's value, 0 for loads.factor)")
    stop: float | None = key(F, "stop exactly at this value (above or below the start: the branch sets off toward it)")
    ds: float = key(F, "first arclength step (weighted, dimensionless)", 0.05, **POS)
    ds_min: float | None = key(F, "smallest step (default 1e-5 min(ds, parameter span / parameter_scale))", **POS)
    ds_max: float | None = key(F, "largest step (default 2 ds)", **POS)
    max_steps: int = key(I, "accepted steps of one branch", 200, lo=1)
    n_eigs: int = key(I, "smallest eigenvalues recorded per step", 3, lo=0, hi=20)
    # bounded: their squares weigh the arclength norm and must stay finite and non-zero in float64
    parameter_scale: float | None = key(F, "scale of the parameter in the arclength (default |stop - start|)",
                                        lo=1e-12, hi=1e12)
    length_scale: float | None = key(F, "scale of displacements in the arclength (default the thickness)",
                                     lo=1e-12, hi=1e12)
    detect: bool = key(B, "locate folds and branch points", True)
    stop_at: tuple = key("strlist", "stop after a 'fold' or 'branch' point", [])
    switch_branch: bool = key(B, "then follow the branch born at the first branch point", False)
    switch_amplitude: float | None = key(F, "size of the jump onto the new branch (default ds)", **POS)
    switch_stop: float | None = key(F, "stop value of the new branch (default stop)")
    newton_rtol: float | None = _newton_rtol()
    newton_max_iter: int | None = _newton_max_iter()
    backend: str = _backend()


@dataclass(frozen=True)
class LinearBucklingSolver:
    """Linear buckling (docs/guide/continuation.md) of the equilibrium at factor ``at`` of the loads and
    growth strain (ramped together as by kind = "static"): the critical factors and modes."""

    kind: str = "linear-buckling"
    at: float = key(F, "factor of the loads and growth strain at the state (0: the rest shape)", 0.0, **NONNEG)
    modes: int = key(I, "buckling modes wanted", 6, lo=1, hi=50)
    target: float | None = key(F, "look for the factors nearest this one (default: the smallest above at)",
                               lo=-1e12, hi=1e12)
    steps: int = key(I, "increments of the factor from 0 to at", 10, lo=1)
    max_cuts: int = _max_cuts()
    stable: bool = _stable()
    newton_rtol: float | None = _newton_rtol()
    newton_max_iter: int | None = _newton_max_iter()
    backend: str = _backend()


def _stepping(name):
    return _model(STEPPING, name)


@dataclass(frozen=True)
class TimeSolver:
    """The mechanochemical time loop's controls (:class:`~femshell.coupled.TimeStepping`, times in 1/β)."""

    kind: str = "time"
    t_final: float = key(F, "end time (1/beta)", factory=_stepping("t_final"), **NONNEG)
    dt_initial: float = key(F, "first step", factory=_stepping("dt_initial"), **POS)
    dt_min: float = key(F, "smallest step", factory=_stepping("dt_min"), **POS)
    dt_max: float = key(F, "largest step", factory=_stepping("dt_max"), **POS)
    ds_max: float = key(F, "largest change of the stretch s per step", factory=_stepping("ds_max"), **POS)
    grow: float = key(F, "largest growth factor of dt per step", factory=_stepping("grow"), lo=1.0)
    safety: float = key(F, "safety factor of the dt prediction", factory=_stepping("safety"), lo=0.0, hi=1.0,
                        lo_open=True)
    max_cuts: int = key(I, "cuts of one step before giving up", factory=_stepping("max_cuts"), lo=0)
    stationary_rate_c: float = key(F, "stop when c changes slower than this (relative, per unit time)",
                                   factory=_stepping("stationary_rate_c"), **NONNEG)
    stationary_rate_x: float = key(F, "... and the shape slower than this (thicknesses per unit time)",
                                   factory=_stepping("stationary_rate_x"), **NONNEG)
    stationary_steps: int = key(I, "... for this many steps in a row", factory=_stepping("stationary_steps"), lo=1)
    stationary_pattern_time: float = key(F, "also stop when the pattern (regions of c > c*) has stayed the same this "
                                         "long, though c may still change (0: off)",
                                         factory=_stepping("stationary_pattern_time"), **NONNEG)
    stationary_pattern_tol: float = key(F, "... the same within this (relative area; centroids in mean region radii)",
                                        factory=_stepping("stationary_pattern_tol"), **NONNEG)
    newton_atol_strain: float = key(F, "absolute Newton tolerance (in units of a unit strain's residual)",
                                    factory=_stepping("newton_atol_strain"), **NONNEG)
    # half the loop's own default: the paper-size spheres need the finer ramp
    ramp_ds: float = key(F, "stretch increments of the initial equilibrium", 0.05, **POS)
    snap_ds: float = key(F, "a Newton failure at a stretch step this small is a fold: minimise on (0: never)",
                         factory=_stepping("snap_ds"), **NONNEG)
    snap_max_iter: int = key(I, "Newton iterations of a snap past a fold (0: never snap)",
                             factory=_stepping("snap_max_iter"), lo=0)
    quasi_newton: int = key(I, "quasi-Newton iterations on the last step's factorised Hessian before Newton (0: plain "
                            "Newton)", factory=_stepping("quasi_newton"), lo=0)
    newton_stall: int = key(I, "a Newton solve with no progress for this many iterations gives up and the step is "
                            "cut (0: never)", factory=_stepping("newton_stall"), lo=0)
    feedback_amplification: float = key(F, "dt keeps an oscillation of the staggered chemistry-mechanics step damped: "
                                        "amplification >= -this (0: no bound)",
                                        factory=_stepping("feedback_amplification"), lo=0.0, hi=1.0)
    source_rule: str = key(S, "source the chemistry holds over a step: its start's, or extrapolated to its midpoint "
                           "from the last two steps where stable (second order)", factory=_stepping("source_rule"),
                           choices=("start", "extrapolated"))
    step_control: str = key(S, "what sets the step's accuracy: its change of the stretch (ds_max), or its local error "
                            "estimate (error_tol)", factory=_stepping("step_control"), choices=("stretch", "error"))
    error_tol: float = key(F, "local error of the stretch per step (step_control = \"error\")",
                           factory=_stepping("error_tol"), **POS)
    error_ds_max: float = key(F, "largest change of the stretch per step (step_control = \"error\")",
                              factory=_stepping("error_ds_max"), **POS)
    max_steps: int | None = key(I, "stop after this many steps of one invocation (continue with --resume)",
                                factory=_stepping("max_steps"), lo=0)
    newton_rtol: float | None = _newton_rtol()
    newton_max_iter: int | None = _newton_max_iter()
    backend: str = _backend()


@dataclass(frozen=True)
class PatternContinuationSolver(TimeSolver):
    """A time scene's loop to its end, then its stationary pattern followed in a model parameter (theory §2.9)."""

    kind: str = "pattern-continuation"
    parameter: str = key(S, "the model parameter the stationary pattern is followed in", required=True,
                         choices=("w", "beta", "D", "c_star", "h0", "lam_ratio"))
    stop: float | None = key(F, "stop exactly at this value of the parameter")
    direction: int = key(I, "+1: set off towards larger values, -1: smaller", 1, lo=-1, hi=1)
    continuation_ds: float = key(F, "first arclength step (weighted, dimensionless)", 0.02, **POS)
    continuation_ds_max: float | None = key(F, "largest arclength step (default 10 continuation_ds)", **POS)
    continuation_steps: int = key(I, "accepted points of the branch", 50, lo=1)
    stop_at: tuple = key("strlist", "stop after a 'fold' or 'branch' point", [])
    n_modes: int = key(I, "leading eigenvalues of the coupled dynamics recorded per point", 4, lo=1, hi=20)
    stationary_tol: float = key(F, "Newton tolerance of the stationary state the branch starts from", 1e-9, **POS)


#: solver kinds that run the mechanochemical time loop (chemistry, initial condition, time controls)
TIME_KINDS = ("time", "pattern-continuation")

SOLVER_CONFIGS = {"static": StaticSolver, "continuation": ContinuationSolver, "time": TimeSolver,
                  "linear-buckling": LinearBucklingSolver, "pattern-continuation": PatternContinuationSolver}


# ----------------------------------------------------------------------------- boundary conditions and loads

#: the keys each [[boundary]] type takes
BOUNDARY_TYPES = {"clamped": ("curve",), "simply_supported": ("curve",), "symmetry": ("axis", "value"),
                  "prescribed": ("curve", "components", "displacement")}


@dataclass(frozen=True)
class BoundaryConfig:
    type: str
    curve: str | None = key(S, "boundary curve", required=True)
    axis: str | None = key(S, "normal axis of the mirror plane", required=True, choices=("x", "y", "z"))
    value: float = key(F, "position of the plane", 0.0)
    components: tuple = key("strlist", "prescribed components", ["x", "y", "z"])
    displacement: tuple = key("vec3", "prescribed displacement", [0.0, 0.0, 0.0])


#: the keys each [[loads]] type takes, and which of them are optional
LOAD_TYPES = {"point_force": ("point", "curve", "force"), "area_load": ("traction",), "edge_force": ("curve", "force"),
              "dead_pressure": ("pressure",), "follower_pressure": ("pressure",), "edge_moment": ("curve", "moment")}
LOAD_OPTIONAL = {"point_force": ("point", "curve")}


@dataclass(frozen=True)
class LoadConfig:
    """A load; every load is multiplied by the load factor."""

    type: str
    point: tuple | None = key("vec3", "position; the force acts on the nearest vertex")
    curve: str | None = key(S, "boundary curve", required=True,
                            docs={"point_force": "or every vertex of this boundary curve"})
    force: tuple | None = key("vec3", "force per unit rest length", required=True,
                              docs={"point_force": "force per vertex"})
    traction: tuple | None = key("vec3", "force per unit rest area", required=True)
    pressure: float | None = key(F, "pressure along the rest normals", required=True,
                                 docs={"follower_pressure": "pressure along the current normals"})
    moment: float | None = key(F, "moment per unit rest length", required=True)


# ----------------------------------------------------------------------------- the whole scene

def _frozen(value):
    """Lists of the TOML form as tuples (the typed objects are immutable)."""
    return tuple(_frozen(v) for v in value) if isinstance(value, list) else value


def _make(cls, section: dict):
    """``cls`` of a validated section; a key the section does not take (another law's, type's) is None."""
    return cls(**{f.name: _frozen(section.get(f.name)) for f in fields(cls)
                  if f.name in section or "kind" in f.metadata})


@dataclass(frozen=True)
class SceneConfig:
    """A validated scene as objects; ``chemistry`` and ``initial`` are None outside the time loop.

    ``mesh_kind`` names the mesh section's class (``mesh`` is one of :data:`MESH_CONFIGS`).
    """

    description: str
    mesh_kind: str
    mesh: object
    material: MaterialConfig
    shell: ShellConfig
    growth: GrowthConfig
    chemistry: ChemistryConfig | None
    initial: InitialConfig | None
    boundary: tuple
    loads: tuple
    solver: object
    output: OutputConfig

    @classmethod
    def from_dict(cls, data: dict) -> "SceneConfig":
        """The objects of a validated scene dict (every default filled in)."""
        mesh = data["mesh"]
        kind = data["solver"]["kind"]
        return cls(
            description=data["description"], mesh_kind=mesh["kind"], mesh=_make(MESH_CONFIGS[mesh["kind"]], mesh),
            material=_make(MaterialConfig, data["material"]), shell=_make(ShellConfig, data["shell"]),
            growth=_make(GrowthConfig, data["growth"]),
            chemistry=_make(ChemistryConfig, data["chemistry"]) if "chemistry" in data else None,
            initial=_make(InitialConfig, data["initial"]) if "initial" in data else None,
            boundary=tuple(_make(BoundaryConfig, b) for b in data["boundary"]),
            loads=tuple(_make(LoadConfig, x) for x in data["loads"]),
            solver=_make(SOLVER_CONFIGS[kind], data["solver"]), output=_make(OutputConfig, data["output"]))


@dataclass
class Scene:
    """A validated scene: ``config`` holds it as objects (:class:`~femshell.scene.config.SceneConfig`),
    ``data`` as the complete TOML dict with every default filled in (what is written and compared).

    ``name``: the scene's name (embedded name or file stem); ``source``: the file it came
    from; ``label``: how error messages name it; ``base_dir``: where relative paths start.
    ``given``: the section names present in the file (a missing [chemistry] is not built).
    The sections are attributes (``scene.solver.ds``, ``scene.growth.law``, ...).
    """

    name: str
    data: dict
    source: Path | None
    label: str
    base_dir: Path
    given: tuple = ()
    config: SceneConfig = field(default=None, repr=False)

    def __post_init__(self):
        if self.config is None:
            self.config = SceneConfig.from_dict(self.data)

    def __getitem__(self, key):
        """The TOML form of a section (``scene["mesh"]["kind"]``), for scripts; femshell uses the attributes."""
        return self.data[key]

    def __getattr__(self, name):
        if name in SceneConfig.__dataclass_fields__:
            return getattr(self.config, name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    @property
    def kind(self) -> str:
        return self.config.solver.kind
