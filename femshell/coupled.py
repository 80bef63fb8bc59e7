r"""The mechanochemical time loop (design.md 1.4): growth -> stable equilibrium -> curvature -> chemistry.

Physics and solver orchestration only: no files, no pictures. The scene runner gives
callbacks for output and checkpoints and stores :meth:`CoupledLoop.state_dict`.

One step of length dt, from an accepted state (t, c, u) where u is a stable equilibrium
of the shell grown by s(c):

1. chemistry on the CURRENT surface x(u): c⁺ = step(c, dt, P(H(u))) (or P extrapolated to
   the step's midpoint, ``TimeStepping.source_rule``) with
   :class:`~femshell.chemistry.ReactionDiffusion` (degradation integrated exactly, diffusion
   implicitly; for D = 0 the exact update node by node, no stiffness built);
2. step control: Δs = max over elements |s(c⁺) − s(c)|; if Δs > ``ds_max`` the step
   is cut and redone (the mechanics has not been touched yet, so this is cheap);
3. growth: ā = s² ā0, b̄ = s² b̄0, h̄ = h0/s² (or h0) with s = s(c⁺) per element
   (:class:`~femshell.growth.GrowthRestState`), and ``ShellModel.set_rest_state`` (cached pattern);
4. mechanics: :func:`~femshell.solvers.newton.minimize` with ``stable=True`` warm
   started from u (or from the secant prediction u + (dt/dt_prev)(u − u_prev) when
   that has lower energy): a local minimum, never a saddle. A Newton failure cuts dt
   and redoes the step from the last accepted state (a Newton that stops making progress
   gives up early, ``TimeStepping.newton_stall``), except where Newton ran out of
   iterations or stalled on a tiny Δs: a fold, past which the minimisation goes on (a snap,
   ``TimeStepping.snap_ds``);
5. accept: t += dt, (c, u) ← (c⁺, u⁺), H from the new shape; the next dt grows by at
   most ``grow`` while Δs stays below ``ds_max`` (dt_next = dt · min(grow, safety · ds_max/Δs)),
   and stays within the stability limit of the staggering (below).

**Why the staggering limits dt.** The chemistry step holds the source P(H(u)) of the
start of the step; the shape that c⁺ makes changes P. Linearised about a fixed point
c = P/β, with G = ∂P/∂c through the mechanics, a perturbation δ is multiplied per step by
a = 1 − q (1 − g/β), q = 1 − e^{−β dt} (diffusion only damps more), for an eigenvalue g of G.
A bulge flattens itself as it grows (g < 0, the negative feedback that makes a spot
stationary), and where the growth law is steep g is large: in the ``spots`` scenario
the unlimited step oscillates about the fixed point for ever (max|Δc| / (dt c) ≈
1e-2 … 1e-1 at dt ≈ 0.2 … 1, R = 15, 2 700 vertices) and becomes stationary with dt ≤ 0.1
(measured: g/β ≈ −20 needs β dt < 0.1). After each step the loop estimates the gain
from the change it just made, g ≈ min ΔP_i/Δc_i over the vertices that changed most (the
step's change of the source against its change of c, the way explicit ODE solvers
detect stiffness; :func:`feedback_gain`), and bounds the next dt so that
a ≥ −``feedback_amplification`` (:func:`feedback_step_limit`). Where the change is slow
and smooth the estimate is small and dt grows; an oscillating mode that grows dominates
Δc and the next estimate sees it. (An implicit coupling solved by Anderson iteration was
measured at ~3× the mechanical solves of this bound, and a diagonal one does not stabilise
the spot's edge: docs/theory.md section 6.)

After ``max_cuts`` cuts in one step (or dt < ``dt_min``) the loop stops with a
:class:`CoupledError` whose message says why; the loop still holds the last accepted
state (the rest state of the shell is restored), ready to be checkpointed. Nothing
is ever accepted with a non-finite value.

**Rest curvature and H (how design.md's "H relative to k0" is implemented).**
design.md 1.1 asks for ā⁻¹ b̄ = k0 I and 1.3 for H = ½ tr(a⁻¹ b) − k0. On a polyhedral
sphere the discrete second fundamental form of the drawn mesh at zero edge angles,
b_mesh = ``model.fundamental_forms(model.initial_unknowns())[1]``, is *not* k0 ā0
element by element: ½ tr(ā0⁻¹ b_mesh) scatters around 1/R on gmsh meshes (L2 7–10 %,
up to a factor 2 on single elements) and the scatter shrinks only like h^0.4 under
refinement (the mid-edge normal at zero edge angle is the mean of the two face
normals, not the surface normal; measured in the ``curvature`` validation case).
With b̄ = k0 ā0 the untouched sphere would therefore not be stress free, and H of
the relaxed shape would carry a small spurious signal that the source P(H) turns
into chemistry. So, by default (``rest_curvature="mesh"``):

* b̄ = s² b_mesh, hence ā⁻¹ b̄ = ā0⁻¹ b_mesh ≈ k0 I: the growth multiplies the rest
  metric and keeps the mesh's own rest curvature tensor, and the drawn mesh at zero
  edge angles is *exactly* stress free at s = 1;
* H = ½ tr(a⁻¹ b) − ½ tr(ā0⁻¹ b_mesh) per element (``mean_curvature(a, b, k_ref)`` with the
  per-element reference k_ref = ½ tr(ā0⁻¹ b_mesh) ≈ k0), so the untouched shape has
  H = 0 exactly, and H of a deformed shape is the change of the discrete mean
  curvature from the rest mesh (accuracy below: a few per cent at the vertices,
  with an element-scale scatter that does not vanish under refinement). H per
  element is averaged to the vertices with the areas of the current surface
  (:func:`femshell.geometry.element_to_vertex`). With outward normals H > 0 where
  the shell bulges outward.

``rest_curvature="k0"`` is design.md's literal form, b̄ = k0 s² ā0 and H relative to
k0; the initial equilibrium then relaxes the mesh first (a displacement of ~1e-4 R)
and the untouched sphere keeps a small uniform H ≈ (0.03–0.5 %) k0 > 0 (finer meshes:
less), so c settles at a uniform c ≈ w H ≪ c* instead of exactly 0.

Accuracy of the two (validation case ``curvature``, a unit sphere stretched into a
spheroid z × 1.1, error of H − H_rest relative to its L2 norm, edge 0.3 … 0.07 R):
"mesh" 11 → 8 % per element (does not converge: the relaxed angles partly
reproduce the rest mesh's scatter) and 7.7 → 2.7 % averaged to the vertices (order
≈ 0.6 on the finest four meshes); "k0" 17 → 1.0 % per element and 18 → 1.1 % at the vertices (order ≈ 2).

Units (design.md section 3): lengths in cell sizes, time in 1/β, E = 1.

Example
-------
>>> from femshell.mesh.generators import sphere                                  # doctest: +SKIP
>>> from femshell.coupled import MechanochemicalModel, TimeStepping, InitialSpot, CoupledLoop
>>> mesh = sphere(30.0, n_vertices=2500)                                          # doctest: +SKIP
>>> params = MechanochemicalModel(h0=2.0, radius=30.0, c_star=0.1, D=0.0)
>>> loop = CoupledLoop(mesh, params, TimeStepping(t_final=20.0), c0=InitialSpot())  # doctest: +SKIP
>>> result = loop.run(callback=lambda rec, lp: print(rec.t, rec.max_c, rec.n_spots))  # doctest: +SKIP
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field, fields, replace

import numpy as np

from ._checks import finite as _finite, finite_vector, integer as _integer
from ._interrupts import committing, step_scope
from .chemistry import ReactionDiffusion, curvature_source
from .geometry import element_to_vertex, mean_curvature
from .growth import REST_CURVATURES, THICKNESS_MODES, GrowthRestState, contractility, stretch
from .shell import Material, RestState, ShellModel
from .shell.model import FOLD_LIMIT_DEG
from .solvers.linear import BACKENDS, LinearSolverError, Refactorizer
from .solvers.newton import NewtonError, minimize

__all__ = ["MechanochemicalModel", "GrowthRestState", "InitialSpot", "gaussian_spot", "TimeStepping",
           "StepRecord", "RunResult", "CoupledError", "CoupledLoop", "REST_CURVATURES", "feedback_gain",
           "feedback_step_limit", "stable_extrapolation", "SOURCE_RULES"]

#: 2: edge unknowns are tangents of the mid-edge normals' turning angles (1: the angles)
STATE_VERSION = 2


class CoupledError(RuntimeError):
    """The time loop could not make a step; the loop still holds the last accepted state."""


# ----------------------------------------------------------------------------- parameters

@dataclass(frozen=True)
class MechanochemicalModel:
    """Physical parameters of the mechanochemical shell (theory §1.1–1.3, defaults of §1.5).

    Lengths are in cell sizes and times in 1/β (theory §3).

    Parameters
    ----------
    nu, E : Poisson ratio in (−1, 0.5] and Young's modulus (> 0; only scales energies).
    h0 : rest thickness (length, > 0).
    thickness_mode : "volume" (h̄ = h0/s², default) or "uniform" (h̄ = h0).
    radius, k0 : natural curvature k0 = 1/radius (1/length) of ``rest_curvature="k0"``
        (b̄ = k0 ā), which needs one of them (both: they must agree; k0 = 0 for a flat
        sheet). With ``rest_curvature="mesh"`` (default) they are not used: the mesh's
        own curvature is the rest curvature (module docstring).
    lam_max, lam_min : contractility of untouched and saturated tissue, 0 < Λmin ≤ Λmax.
    lam0 : reference contractility Λ0 of s = Λ0/Λ(c) (default Λmax). Note s(0) =
        Λmax/Λ(0) = 1 + 1.5e-5 with the defaults (Λ(0) is not exactly Λmax); pass
        ``lam0=contractility(0, ...)`` for s(0) = 1 exactly.
    b : steepness of the switch (1/concentration, > 0; not the second fundamental form b of the
        shell); c_star : threshold c* (≥ 0).
    w : production rate (concentration·length/time, ≥ 0); Hs : saturation curvature (1/length, > 0).
    beta : degradation rate (1/time, ≥ 0; the β of ∂c/∂t = … − βc, not the elastic β = E/(2(1 + ν))
        of the energy); D : diffusion coefficient (length²/time, ≥ 0).
    rest_curvature : "mesh" (default) or "k0", see the module docstring.
    membrane_law : "svk" (design.md 1.2) or "neo-hookean", which stays stable where a confined
        spot is compressed below 0.866 of its target length (:mod:`femshell.shell.element`).

    >>> from femshell.coupled import MechanochemicalModel
    >>> p = MechanochemicalModel()          # design.md 1.5's spots: h0 = 2, c* = 0.1, w = 15, D = 0
    >>> round(p.c_max, 6), round(p.s_max, 6)   # saturation w Hs/β and the largest stretch Λmax/Λmin
    (0.75, 1.5)
    >>> round(float(p.stretch(0.2)), 4)     # a vertex well above c*: nearly the full stretch
    1.5
    """

    nu: float = 0.5
    E: float = 1.0
    h0: float = 2.0
    thickness_mode: str = "volume"
    radius: float | None = None
    k0: float | None = None
    lam_max: float = 15.0
    lam_min: float = 10.0
    lam0: float | None = None
    b: float = 100.0
    c_star: float = 0.1
    w: float = 15.0
    Hs: float = 0.05
    beta: float = 1.0
    D: float = 0.0
    rest_curvature: str = "mesh"
    membrane_law: str = "svk"

    def __post_init__(self):
        _finite("nu (Poisson ratio)", self.nu, -1.0, 0.5, lo_open=True, text="(-1, 0.5]")
        _finite("E (Young's modulus)", self.E, 0.0, lo_open=True, text="(0, inf)")
        _finite("h0 (rest thickness)", self.h0, 0.0, lo_open=True, text="(0, inf)")
        if self.thickness_mode not in THICKNESS_MODES:
            raise ValueError(f"thickness_mode must be one of {THICKNESS_MODES}, got {self.thickness_mode!r}")
        if self.radius is not None:
            _finite("radius (R, k0 = 1/R)", self.radius, 0.0, lo_open=True, text="(0, inf)")
        if self.k0 is not None:
            _finite("k0 (natural curvature)", self.k0)
        if self.radius is not None and self.k0 is not None and not math.isclose(1.0 / self.radius, self.k0,
                                                                                 rel_tol=1e-9):
            raise ValueError(f"radius = {self.radius} and k0 = {self.k0} disagree (k0 must be 1/radius); "
                             "give only one of them")
        _finite("lam_min (Λmin)", self.lam_min, 0.0, lo_open=True, text="(0, inf)")
        _finite("lam_max (Λmax)", self.lam_max, self.lam_min, text=f"[lam_min = {self.lam_min}, inf)")
        if self.lam0 is not None:
            _finite("lam0 (Λ0)", self.lam0, 0.0, lo_open=True, text="(0, inf)")
        _finite("b (steepness of the contractility switch)", self.b, 0.0, lo_open=True, text="(0, inf)")
        _finite("c_star (threshold c*)", self.c_star, 0.0,
                text="[0, inf) (c >= 0, so c* < 0 would pattern everything)")
        _finite("w (production rate)", self.w, 0.0)
        _finite("Hs (saturation curvature)", self.Hs, 0.0, lo_open=True, text="(0, inf)")
        _finite("beta (degradation rate)", self.beta, 0.0)
        _finite("D (diffusion coefficient)", self.D, 0.0)
        Material(self.E, self.nu, self.membrane_law)    # checks the law
        if self.rest_curvature not in REST_CURVATURES:
            raise ValueError(f"rest_curvature must be one of {REST_CURVATURES}, got {self.rest_curvature!r}")
        if self.rest_curvature == "k0" and self.radius is None and self.k0 is None:
            # k0 = 0 by default made a sphere's whole surface 'curved' (H ≈ 1/R) and patterned it at t = 0
            raise ValueError("rest_curvature='k0' needs the natural curvature: give radius (k0 = 1/R) or k0 "
                             "(0 for a flat sheet)")
        _store_numbers(self)

    # derived quantities
    @property
    def natural_curvature(self) -> float:
        """k0 (1/length): 1/radius, or k0, or 0."""
        if self.radius is not None:
            return 1.0 / self.radius
        return 0.0 if self.k0 is None else float(self.k0)

    @property
    def material(self) -> Material:
        return Material(E=self.E, nu=self.nu, law=self.membrane_law)

    @property
    def reference_contractility(self) -> float:
        """Λ0 (default Λmax)."""
        return self.lam_max if self.lam0 is None else float(self.lam0)

    @property
    def c_max(self) -> float:
        """Steady concentration of a saturated bulge, w Hs / β (inf when β = 0)."""
        return self.w * self.Hs / self.beta if self.beta > 0 else float("inf")

    @property
    def s_max(self) -> float:
        """Largest stretch, Λ0 / Λmin."""
        return self.reference_contractility / self.lam_min

    def contractility(self, c):
        return contractility(c, self.lam_max, self.lam_min, self.b, self.c_star)

    def stretch(self, c):
        """s(c) = Λ0 / Λ(c) (dimensionless), any shape."""
        return stretch(c, self.lam0, self.lam_max, self.lam_min, self.b, self.c_star)

    def source(self, H):
        """P(H) = w H / (1 + H/Hs) for H > 0, else 0 (concentration/time)."""
        return curvature_source(H, self.w, self.Hs)

    def as_dict(self) -> dict:
        return asdict(self)


# ----------------------------------------------------------------------------- growth

# ----------------------------------------------------------------------------- initial condition

def gaussian_spot(points, amplitude: float, width: float, *, pole=(0.0, 0.0, 1.0), center=None,
                  elongation: float = 1.0, direction=None, distance: str = "geodesic") -> np.ndarray:
    r"""c0 = amplitude · exp(−(r/width)²) about a pole (concentration at the vertices, (n,)).

    ``distance``: "geodesic" (R_eff · angle from the pole seen from ``center``; R_eff the
    mean distance of the points from ``center``, default their centroid), "chord"
    (straight distance to the pole point center + R_eff · pole) or "planar" (distance
    from the axis through ``center`` along ``pole``: for flat meshes). With
    ``elongation`` e ≠ 1 the spot is stretched by e along the tangent ``direction``
    at the pole (default: the x axis projected on the tangent plane):
    r² = (ξ/e)² + η² in tangent coordinates (ξ along ``direction``).

    >>> import numpy as np
    >>> from femshell.mesh.generators import sphere
    >>> from femshell.coupled import gaussian_spot
    >>> m = sphere(10.0, n_vertices=2000)
    >>> c = gaussian_spot(m.points, 0.75, 3.0, center=(0, 0, 0))   # amplitude 0.75, width 3, north pole
    >>> theta = np.arccos(m.points[:, 2] / np.linalg.norm(m.points, axis=1))
    >>> bool(np.allclose(c, 0.75 * np.exp(-(10 * theta / 3.0) ** 2), atol=1e-3))    # r = R θ
    True
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"points must have shape (n, 3), got {pts.shape}")
    amplitude = _finite("spot amplitude", amplitude, 0.0)
    width = _finite("spot width", width, 0.0, lo_open=True, text="(0, inf)")
    elongation = _finite("spot elongation", elongation, 0.0, lo_open=True, text="(0, inf)")
    if distance not in ("geodesic", "chord", "planar"):
        raise ValueError(f"distance must be 'geodesic', 'chord' or 'planar', got {distance!r}")
    p = np.asarray(pole, dtype=float)
    if p.shape != (3,) or not np.linalg.norm(p) > 0:
        raise ValueError(f"pole must be a non-zero 3-vector, got {pole!r}")
    p = p / np.linalg.norm(p)
    xyz = "three finite numbers (x, y, z)"
    ctr = pts.mean(axis=0) if center is None else finite_vector("center", center, 3, xyz)
    d = pts - ctr
    dirv = np.array([1.0, 0.0, 0.0]) if direction is None else finite_vector("direction", direction, 3, xyz)
    e1 = dirv - (dirv @ p) * p
    if np.linalg.norm(e1) < 1e-8:
        e1 = np.array([0.0, 1.0, 0.0]) - p[1] * p
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(p, e1)
    if distance == "planar":
        xi, eta = d @ e1, d @ e2
    else:
        r_eff = float(np.linalg.norm(d, axis=1).mean())
        if distance == "geodesic":
            rn = np.maximum(np.linalg.norm(d, axis=1), 1e-300)
            rho = r_eff * np.arccos(np.clip((d @ p) / rn, -1.0, 1.0))
        else:
            rho = np.linalg.norm(d - r_eff * p, axis=1)
        phi = np.arctan2(d @ e2, d @ e1)
        xi, eta = rho * np.cos(phi), rho * np.sin(phi)
    r2 = (xi / elongation) ** 2 + eta**2
    # a width beyond 1e150 is a uniform field; width**2 would raise OverflowError there
    return amplitude * np.exp(-r2 / (width**2 if width < 1e150 else math.inf))


def _rejected(res) -> str | None:
    """Why an equilibrium from Newton cannot be accepted (non-finite, or a saddle), or None."""
    if not (np.all(np.isfinite(res.u)) and math.isfinite(res.energy)):
        return "Newton returned a non-finite state"
    if res.stable is False:     # minimize reports a saddle it could not leave; never accept one
        return f"the equilibrium is a saddle ({res.n_negative} negative eigenvalues)"
    return None


@dataclass(frozen=True)
class InitialSpot:
    """The initial condition of design.md 1.4: c = 0 except a Gaussian spot at a pole.

    ``amplitude`` default c_max = w Hs/β; ``width`` d default h0; other fields as in
    :func:`gaussian_spot`.
    """

    amplitude: float | None = None
    width: float | None = None
    elongation: float = 1.0
    pole: tuple = (0.0, 0.0, 1.0)
    direction: tuple | None = None
    distance: str = "geodesic"

    def __post_init__(self):        # what can be checked without the mesh: said where the spot is made
        if self.amplitude is not None:
            _finite("spot amplitude", self.amplitude, 0.0)
        if self.width is not None:
            _finite("spot width", self.width, 0.0, lo_open=True, text="(0, inf)")
        _finite("spot elongation", self.elongation, 0.0, lo_open=True, text="(0, inf)")

    def field(self, points, params: MechanochemicalModel) -> np.ndarray:
        if self.amplitude is None:
            amp = params.c_max
            if not math.isfinite(amp):
                raise ValueError("spot amplitude defaults to c_max = w Hs / beta, infinite for beta = 0: give one")
        else:
            amp = _finite("spot amplitude", self.amplitude, 0.0)
        width = params.h0 if self.width is None else self.width
        return gaussian_spot(points, amp, width, pole=self.pole, elongation=self.elongation,
                             direction=self.direction, distance=self.distance)


def _store_numbers(obj):
    """Store the checked numeric fields of a frozen dataclass as float / int: a number given as a
    string ("1e-3", as YAML 1.1 reads it) passes the checks and must not stay a string."""
    for f in fields(obj):
        v = getattr(obj, f.name)
        if v is None or isinstance(v, (bool, tuple)):
            continue
        if "float" in str(f.type):
            object.__setattr__(obj, f.name, float(v))
        elif "int" in str(f.type):
            object.__setattr__(obj, f.name, int(v))


# ----------------------------------------------------------------------------- time stepping

def feedback_gain(dc, dP, fraction: float = 0.1) -> float:
    """The source's most negative gain over a step: min ΔP_i / Δc_i over the vertices whose
    |Δc_i| ≥ ``fraction`` · max |Δc| (1/time; nan if c did not change).

    For a change along one eigenvector of G = ∂P/∂c every ratio is its eigenvalue. The
    oscillating modes of a spot are local (a ring of 10–20 vertices at its edge on a 2 700-vertex
    sphere), and a global average (ΔP · Δc)/(Δc · Δc) dilutes them with the slow rest:
    −0.7 … −4.5 measured while those vertices alternated at ratios −8 … −21.
    """
    dc, dP = np.asarray(dc, float), np.asarray(dP, float)
    if dc.ndim != 1 or dP.shape != dc.shape:
        raise ValueError(f"dc and dP must be vectors of the same length, got shapes {dc.shape} and {dP.shape}")
    a = np.abs(dc)
    if not len(a) or a.max() <= 0:
        return float("nan")
    sel = a >= fraction * a.max()
    return float(np.min(dP[sel] / dc[sel]))


def feedback_step_limit(g: float, beta: float, rho: float, exponential: bool) -> float:
    r"""Largest dt whose staggered step multiplies a mode of source gain g by a ≥ −rho (inf: no limit).

    With the source held over the step, a mode δ of the chemistry c = P(c)/β with
    ∂P/∂c δ = g δ is multiplied per step by

    * ``exponential`` (the degradation integrated exactly, as femshell's chemistry does; with
      D > 0 the diffusion, left out here, only damps more): a = 1 − q (1 − g/β),
      q = 1 − e^{−β dt}; a ≥ −ρ ⇔ q ≤ (1 + ρ) β / (β − g);
    * implicit Euler in the degradation too: a = (1 + g dt)/(1 + β dt);
      a ≥ −ρ ⇔ dt (−g − ρ β) ≤ 1 + ρ.

    Only a negative feedback, g < −ρ β, limits dt; a positive one (a switch turning on)
    is bounded by the step's Δs instead.

    >>> from femshell.coupled import feedback_step_limit
    >>> round(feedback_step_limit(-19.0, 1.0, 1.0, exponential=True), 4)   # a = -1 exactly here
    0.1054
    >>> feedback_step_limit(0.5, 1.0, 0.5, exponential=True)
    inf
    """
    beta, rho = _finite("beta", beta, 0.0), _finite("rho", rho, 0.0)
    if not (math.isfinite(g) and g < -rho * beta) or rho <= 0:
        return math.inf
    if exponential and beta > 0:
        return -math.log1p(-(1.0 + rho) * beta / (beta - g)) / beta
    return (1.0 + rho) / (-g - rho * beta)


def stable_extrapolation(g: float, beta: float, rho: float, dt: float, h_prev: float) -> float:
    r"""The largest fraction θ ∈ [0, 1] of the source's extrapolation that keeps a ≥ −rho on a step dt.

    With the source P_n + θ (r/2)(P_n − P_{n−1}), r = dt/h_prev (θ = 1: Adams–Bashforth 2, see
    :class:`TimeStepping` ``source_rule``), a mode of gain g (as in :func:`feedback_step_limit`)
    follows δ_{n+1} = e^{−β dt} δ_n + φ g ((1 + θr/2) δ_n − (θr/2) δ_{n−1}), φ = (1 − e^{−β dt})/β
    (φ = dt for β = 0). Its roots ζ are real, one of each sign when g < 0; the negative one is
    ≥ −ρ iff the characteristic polynomial is ≥ 0 at −ρ:

        ρ q + k (ρ + (1 + ρ) θr/2) ≤ ρ (1 + ρ),   q = 1 − e^{−β dt},  k = −g φ.

    At θ = 0 this is the held source's bound, a ≥ −ρ, so θ falls from 1 to 0 as dt approaches
    that bound; full extrapolation (θ = 1, r = 1) needs dt ≲ 0.4 of it where the feedback is
    strong (−g/β ≫ 1, ρ = 0.5). A positive or unknown (nan) g never limits: θ = 1.

    >>> from femshell.coupled import stable_extrapolation
    >>> [round(stable_extrapolation(-20.0, 1.0, 0.5, dt, 0.03), 3) for dt in (0.02, 0.03, 0.05, 0.08)]
    [1.0, 0.992, 0.195, 0.0]
    """
    if not (math.isfinite(g) and g < 0):
        return 1.0
    q = -math.expm1(-beta * dt)
    k = -g * (q / beta if beta > 0 else dt)
    r = dt / h_prev
    theta = (rho * (1.0 + rho) - rho * q - k * rho) / (k * (1.0 + rho) * 0.5 * r)
    return float(min(1.0, max(0.0, theta)))


SOURCE_RULES = ("start", "extrapolated")


@dataclass(frozen=True)
class TimeStepping:
    """Controls of the time loop (times in 1/β).

    Parameters
    ----------
    t_final : end time. dt_initial, dt_min, dt_max : first, smallest and largest step.
    ds_max : largest allowed change of the stretch s in any element per step.
    grow : largest growth factor of dt from one step to the next; safety : factor on
        the predicted dt (dt_next = dt · min(grow, safety · ds_max / Δs)).
    max_cuts : cuts of one step (Δs too large or Newton failed) before giving up.
    stationary_rate_c : stop when max|Δc| / (dt · c_scale) stays below this for
        ``stationary_steps`` steps in a row, together with
    stationary_rate_x : max|Δx| / (dt · h0) (shape change per unit time in thicknesses);
        c_scale = max(max c, 1e-2 c_max). Set either to 0 to never stop early.
    stationary_pattern_time, stationary_pattern_tol : a second, coarser stop: the pattern, the
        regions where c > c* (:func:`~femshell.analysis.find_spots`), has stayed the same within
        ``stationary_pattern_tol`` (:func:`~femshell.analysis.same_pattern`: the numbers of spots
        and ridges, the patterned area, the region centroids) for ``stationary_pattern_time``.
        For runs whose pattern settles while a few vertices at the spots' edges go on changing
        for ever (a strong source: docs/sphere-patterns.md, "When the pattern is stationary but c
        is not"). It does not see c build up below c* (a ring before it nucleates): give it a time
        longer than such a build-up. 0 (default): only the rate test above. The tolerance
        must exceed the regions' own jitter: on the 2 697-vertex w = 60 run their area jitters
        by 0.2 % and their centroids by up to 1 % of their radius, so 0.01 restarts the clock
        every 0.5–2 time units there; 0.02 (default) does not, and still sees the drift of the
        6 265-vertex w = 120 spots while they settle (4 % of their radius over 8 time units).
    newton_rtol, newton_atol_strain : convergence |∇Π| ≤ rtol · |∇Π(u_start)| + atol, with
        atol = newton_atol_strain × (the residual of a uniform unit strain).
    newton_max_iter, newton_backend : passed to :func:`~femshell.solvers.newton.minimize`.
    quasi_newton : each Newton solve first takes up to this many quasi-Newton iterations on
        the factorisation of the last converged state's Hessian (its stability check), which
        the loop keeps (``minimize(quasi_newton=...)``; after a cut, the factorisation the
        failed attempt left); the converged state is then checked by a fresh factorisation as
        before. 0: plain Newton (one more Hessian assembly and factorisation per step). Needs
        a Cholesky factor, so PARDISO: with SuperLU every solve is plain Newton.
    ramp_ds : largest stretch increment of the initial equilibrium (growth ramped from
        s = 1 to s(c0), with a secant predictor; cut on Newton failure, grown by 1.5 after success).
        Scenes default to 0.05 (``solver.ramp_ds``), half of this default, for the paper-size spheres.
    predictor : start Newton from the secant prediction u + (h/h_prev)(u − u_prev) when
        it has lower energy than u (a grown rest state leaves the old shape compressed,
        near buckling, where Newton from the old shape needs many iterations).
    snap_ds, snap_max_iter : a fold of the quasi-static path. When Newton runs out of
        iterations (or stalls) on a step whose Δs ≤ ``snap_ds``, no equilibrium is left near the old
        shape (a tiny growth increment would otherwise converge in a few iterations): the
        minimisation goes on from Newton's last iterate (lower energy than the start) for
        up to ``snap_max_iter`` more iterations, and the shell snaps to the stable
        equilibrium it reaches. Without this the loop creeps towards the fold with ever
        smaller steps. At most one snap is tried per step (where it does not settle the
        cuts go on as usual). ``snap_max_iter = 0`` disables it.
    newton_stall : a Newton solve that has made no progress for this many iterations (the
        residual not halved, the energy down by less than 1e-7 of itself) gives up and the step
        is cut, instead of running to ``newton_max_iter`` (``minimize(stall=...)``; not in a
        snap, which may creep legitimately). 0: never.
    feedback_amplification : the next dt keeps the staggering's amplification of an
        oscillating mode, estimated from the last step, at a ≥ −this (module docstring,
        :func:`feedback_step_limit`; 0 < value ≤ 1: 1 is the stability limit itself, smaller
        damps an oscillation faster). 0: no bound.
    source_rule : the source P(H) the chemistry holds over a step. "start": P of the step's
        start (the staggering above, first order in dt). "extrapolated": P at the step's
        midpoint extrapolated from the last two accepted states (Adams–Bashforth 2, second
        order, no extra solve), as far as that keeps an oscillation within
        ``feedback_amplification`` (:func:`stable_extrapolation`: a strong negative feedback
        allows full extrapolation only on 0.4 of the held source's dt; the step keeps its
        length and extrapolates less, down to P_n at the held source's own bound).
    max_steps : stop after this many accepted steps in one call of :meth:`CoupledLoop.run`.
    """

    t_final: float = 100.0
    dt_initial: float = 0.01
    dt_min: float = 1e-8
    dt_max: float = 2.0
    ds_max: float = 0.02
    grow: float = 1.5
    safety: float = 0.8
    max_cuts: int = 12
    stationary_rate_c: float = 1e-3
    stationary_rate_x: float = 1e-3
    stationary_steps: int = 3
    stationary_pattern_time: float = 0.0
    stationary_pattern_tol: float = 0.02
    newton_rtol: float = 1e-6
    newton_atol_strain: float = 1e-10
    newton_max_iter: int = 40
    newton_backend: str = "auto"
    quasi_newton: int = 12
    ramp_ds: float = 0.1
    predictor: bool = True
    snap_ds: float = 1e-3
    snap_max_iter: int = 400
    newton_stall: int = 10
    feedback_amplification: float = 0.5
    source_rule: str = "start"
    max_steps: int | None = None

    def __post_init__(self):
        _finite("t_final", self.t_final, 0.0)
        _finite("dt_min", self.dt_min, 0.0, lo_open=True, text="(0, inf)")
        _finite("dt_max", self.dt_max, self.dt_min, text=f"[dt_min = {self.dt_min}, inf)")
        _finite("dt_initial", self.dt_initial, self.dt_min, self.dt_max,
                text=f"[dt_min = {self.dt_min}, dt_max = {self.dt_max}]")
        _finite("ds_max", self.ds_max, 0.0, lo_open=True, text="(0, inf)")
        _finite("grow", self.grow, 1.0)
        _finite("safety", self.safety, 0.0, 1.0, lo_open=True, text="(0, 1]")
        _integer("max_cuts", self.max_cuts, 0)
        _finite("stationary_rate_c", self.stationary_rate_c, 0.0)
        _finite("stationary_rate_x", self.stationary_rate_x, 0.0)
        _integer("stationary_steps", self.stationary_steps, 1)
        _finite("stationary_pattern_time", self.stationary_pattern_time, 0.0)
        _finite("stationary_pattern_tol", self.stationary_pattern_tol, 0.0)
        _finite("newton_rtol", self.newton_rtol, 0.0, lo_open=True, text="(0, inf)")
        _finite("newton_atol_strain", self.newton_atol_strain, 0.0)
        _integer("newton_max_iter", self.newton_max_iter, 1)
        _integer("quasi_newton", self.quasi_newton, 0)
        _integer("newton_stall", self.newton_stall, 0)
        if self.newton_backend not in BACKENDS:
            raise ValueError(f"newton_backend must be one of {BACKENDS}, got {self.newton_backend!r}")
        _finite("ramp_ds", self.ramp_ds, 0.0, lo_open=True, text="(0, inf)")
        _finite("snap_ds", self.snap_ds, 0.0)
        _finite("feedback_amplification", self.feedback_amplification, 0.0, 1.0)
        _integer("snap_max_iter", self.snap_max_iter, 0)
        if self.source_rule not in SOURCE_RULES:
            raise ValueError(f"source_rule must be one of {SOURCE_RULES}, got {self.source_rule!r}")
        if self.max_steps is not None:
            _integer("max_steps", self.max_steps, 0, "None or an integer >= 0")
        _store_numbers(self)

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass
class StepRecord:
    """What happened in one accepted step (or the initial state, step 0).

    t, dt : time after the step and the step length (1/β). newton_iterations : full Newton
    iterations of the accepted solve (0 when its quasi-Newton iterations sufficed); cuts :
    rejected attempts before it. max_c : max c; max_H, min_H : extremes of the vertex H
    (1/length); max_s : largest stretch; ds : max
    |Δs| of the step; energy : elastic energy (E·length³); n_spots : N_sp (regions
    with c > c*); rate_c, rate_x : the stationarity measures (TimeStepping);
    stable : the Hessian at the equilibrium had no negative eigenvalue; wall_s :
    wall time of the step (s); snapped : the shell jumped to another equilibrium past a
    fold of the quasi-static path (``TimeStepping.snap_ds``); feedback_gain : the source's
    most negative gain over the step (:func:`feedback_gain`, 1/time), which bounds the next dt;
    non_elliptic : elements whose membrane law is not elliptic (St Venant–Kirchhoff compressed
    past its limit, :meth:`~femshell.shell.model.ShellModel.non_elliptic_elements`); over_folded :
    edges whose mid-edge normal is turned by 80° or more from its faces, a fold sharper than one
    element carries (:meth:`~femshell.shell.model.ShellModel.diagnose`).
    """

    step: int
    t: float
    dt: float
    newton_iterations: int
    cuts: int
    max_c: float
    max_H: float
    min_H: float
    max_s: float
    ds: float
    energy: float
    n_spots: int
    rate_c: float
    rate_x: float
    stable: bool | None
    wall_s: float
    snapped: bool = False
    feedback_gain: float = float("nan")
    non_elliptic: int = 0
    over_folded: int = 0

    def as_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass
class RunResult:
    """How :meth:`CoupledLoop.run` ended.

    status : "t_final", "stationary", "max_steps", "wall_time", "interrupted" or "failed";
    message : human-readable reason; steps : accepted steps in this call; t : final
    time; wall_s : wall time of the call; last : the last :class:`StepRecord`.
    """

    status: str
    message: str
    steps: int
    t: float
    wall_s: float
    last: StepRecord | None = None
    records: list = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.status != "failed"


# ----------------------------------------------------------------------------- the loop

class CoupledLoop:
    """The staggered quasi-static mechanochemical loop (module docstring).

    Parameters
    ----------
    mesh : SurfaceMesh
        The rest shape (a sphere of radius R for the paper's cases).
    params : MechanochemicalModel
    stepping : TimeStepping, optional
    c0 : InitialSpot, (n,) array or None
        Initial concentration (None: zero everywhere).
    boundary_conditions : sequence
        Shell boundary conditions (none for a closed sphere: the six rigid-body
        components are pinned by ShellModel's default).
    equilibrate : bool
        Find the stable equilibrium of the initial growth s(c0) now (ramped in steps of
        ``stepping.ramp_ds``). :meth:`from_state_dict` skips it.
    log : callable or None
        ``log(str)`` for one line per step and every cut.

    Attributes
    ----------
    t, dt, step, c, u : the current state (dt is the proposal for the next step).
    s : (m,) element stretches of c; H, H_vertex : H per element / vertex (1/length).
    shell : ShellModel; growth : GrowthRestState; chemistry : ReactionDiffusion.
    """

    def __init__(self, mesh, params: MechanochemicalModel, stepping: TimeStepping | None = None, c0=None,
                 boundary_conditions=(), equilibrate: bool = True, log=None):
        if not isinstance(params, MechanochemicalModel):
            raise TypeError(f"params must be a MechanochemicalModel, got {type(params).__name__}")
        if stepping is not None and not isinstance(stepping, TimeStepping):
            raise TypeError(f"stepping must be a TimeStepping, got {type(stepping).__name__}")
        if not all(hasattr(mesh, k) for k in ("points", "triangles", "topology")):
            raise TypeError(f"mesh must be a SurfaceMesh (see femshell.mesh), got {type(mesh).__name__}")
        self.mesh = mesh
        self.params = params
        self.stepping = stepping or TimeStepping()
        self.log = log
        n = mesh.n_vertices
        # the rest state at s = 1 is replaced by GrowthRestState right away
        from .shell.rest_state import metric

        a0 = metric(np.asarray(mesh.points, float), np.asarray(mesh.triangles))
        self.shell = ShellModel(mesh, params.material,
                                RestState(a0, params.natural_curvature * a0, params.h0), boundary_conditions)
        self.growth = GrowthRestState(self.shell, params.h0, params.thickness_mode, params.rest_curvature,
                                      params.natural_curvature, params.stretch)
        self.chemistry = ReactionDiffusion(mesh.triangles, n, D=params.D, beta=params.beta, points=mesh.points)
        self._length = float(params.h0)
        self._atol = self._residual_floor()
        # one pair for the whole run: the Hessian's sparsity pattern is analysed once
        self._factorizers = (Refactorizer(self.stepping.newton_backend), Refactorizer(self.stepping.newton_backend))

        if c0 is None:
            c = np.zeros(n)
        elif isinstance(c0, InitialSpot):
            c = c0.field(np.asarray(mesh.points, float), params)
        else:
            c = np.array(c0, dtype=float)
            if c.shape != (n,):
                raise ValueError(f"c0 must have one value per vertex, shape ({n},), got {c.shape}")
        if not np.all(np.isfinite(c)) or np.any(c < 0):
            raise ValueError("initial concentration c0 must be finite and >= 0")
        self.t = 0.0
        self.dt = float(self.stepping.dt_initial)
        self.step = 0
        self.c = c
        self.u = self.shell.initial_unknowns()
        self.stationary_count = 0
        self._pattern_anchor = None       # (t, PatternMeasures, c, points) since which the pattern is the same
        self._pattern_now = None          # (step, PatternMeasures) of the last step followed
        self.n_rejected = 0
        self.n_snaps = 0
        self.newton_total = 0
        self.last_newton_iterations = 0
        self._last_ds = 0.0
        self._u_prev, self._h_prev = None, 0.0
        self._source_prev = None        # P at the previous accepted state (source_rule = "extrapolated")
        self._extrapolate = 0.0         # the fraction of its source's extrapolation the next step takes
        self._last_rates = (float("nan"), float("nan"))
        self._last_gain = float("nan")
        self._last_stable = None
        self.s = self.growth.stretch(self.c)
        if equilibrate:
            self._equilibrate_initial()
        else:
            self.growth.apply(self.s)
        self._update_curvature()
        if equilibrate:
            self._say_non_elliptic()
            self._say_over_folded()

    # ---- helpers ------------------------------------------------------------------------------
    def _say(self, msg):
        if self.log:
            self.log(msg)

    def _say_non_elliptic(self):
        """Log the elements of the current state that are compressed past SVK's limit, if any."""
        if self.non_elliptic:
            limit = self.shell.material.svk_ellipticity_stretch
            self._say(f"  step {self.step} t = {self.t:.6g}: {self.non_elliptic} elements are compressed past the "
                      f"St Venant–Kirchhoff membrane's ellipticity limit (equibiaxial stretch {limit:.3g}): "
                      "a triangle there can collapse on the mesh scale, and Newton then stalls; "
                      "the neo-Hookean membrane (scene: material.law = \"neo-hookean\"; API: membrane_law) "
                      "stays elliptic")

    def _say_over_folded(self):
        """Log the edges of the current state folded more sharply than one element carries, if any."""
        if self.over_folded:
            self._say(f"  step {self.step} t = {self.t:.6g}: {self.over_folded} mid-edge normals are turned by "
                      f"{FOLD_LIMIT_DEG:g}° or more from their faces: the shell folds there more sharply than one "
                      "element carries, and the shape there is the mesh's; a finer mesh resolves it")

    def _steep_switch_hint(self, ds) -> str:
        """Why no dt meets ds_max: s(c) jumps where c crosses c* (a large b makes Λ(c) a step)."""
        p = self.params
        return (f"; the stretch still jumps by {ds:.3g} in a step of dt_min: where c crosses c* = {p.c_star:g}, "
                f"s(c) rises by {p.s_max - 1:.3g} over a change of c of about 8/b = {8 / p.b:.3g} (b = {p.b:g}), "
                "less than any step resolves; a smaller b (scene: growth.b) or a larger ds_max (solver.ds_max) "
                "lets the loop step across the switch")

    def _non_elliptic_hint(self) -> str:
        """Why a step may fail that the user can act on: St Venant–Kirchhoff past its limit."""
        if not self.non_elliptic:
            return ""
        return (f"; {self.non_elliptic} elements of the last accepted state are compressed past the St Venant–"
                "Kirchhoff ellipticity limit, where triangles can collapse: the neo-Hookean membrane "
                "(scene: material.law = \"neo-hookean\"; API: membrane_law) stays elliptic")

    def _residual_floor(self) -> float:
        """atol of Newton: newton_atol_strain × |∇Π| of a uniform unit strain (by a 1e-3 difference)."""
        u0 = self.shell.initial_unknowns()
        m = len(self.growth.a0)
        self.growth.apply(np.ones(m))
        g1 = self.shell.gradient(u0)
        self.growth.apply(np.full(m, 1.001))
        g2 = self.shell.gradient(u0)
        self.growth.apply(np.ones(m))
        unit = float(np.linalg.norm(g2 - g1)) / 1e-3
        if not (math.isfinite(unit) and unit > 0):
            unit = self.params.E * self.params.h0 * math.sqrt(float(np.sum(self.shell.rest.area)))
        return self.stepping.newton_atol_strain * unit

    def _newton(self, u_start, max_iter=None, residual_scale=None, stall=True):
        st = self.stepping
        return minimize(self.shell, u_start, stable=True, rtol=st.newton_rtol, atol=self._atol,
                        max_iter=int(max_iter or st.newton_max_iter), residual_scale=residual_scale,
                        factorizers=self._factorizers, quasi_newton=st.quasi_newton,
                        stall=(st.newton_stall or None) if stall else None, log=None)

    def _snap_applies(self, failed: NewtonError, ds: float) -> bool:
        """Newton ran out of iterations or stalled (not a failed line search) at Δs ≤ snap_ds, snaps enabled."""
        st = self.stepping
        last = failed.result
        return not (st.snap_max_iter == 0 or ds > st.snap_ds or last is None
                    or (last.iterations < st.newton_max_iter and not failed.stalled)
                    or not np.all(np.isfinite(last.u)))

    def _snap(self, last, ds: float):
        """The stable equilibrium past a fold (``TimeStepping.snap_ds``), or None if it does not settle.

        ``last`` is the failed Newton's last iterate (:class:`NewtonResult`), of lower energy than
        the old shape; the minimisation goes on from there with the residual scale of the original
        start, so the tolerance is the one the step would have had.
        """
        st = self.stepping
        self._say(f"  step {self.step + 1} t = {self.t:.6g}: no equilibrium near the old shape at Δs = {ds:.3g} "
                  f"(a fold): minimising on for up to {st.snap_max_iter} iterations")
        try:
            res = self._newton(last.u, max_iter=st.snap_max_iter, residual_scale=last.residual_scale, stall=False)
        except NewtonError as exc:
            self._say(f"  step {self.step + 1}: the snap did not settle: {exc}")
            return None
        return replace(res, iterations=last.iterations + res.iterations)

    def _predict(self, u, u_prev, ratio):
        """Secant predictor u + ratio (u − u_prev) for the current rest state, if it lowers the energy.

        A grown rest state leaves the previous shape compressed; a compressed shell is
        near (or past) buckling, where Newton from the old shape struggles. The secant
        step moves most of the way along the growth path first.
        """
        if u_prev is None or not (ratio > 0 and math.isfinite(ratio)):
            return u
        guess = u + min(ratio, 2.0) * (u - u_prev)
        try:
            e_guess = self.shell.energy(guess)
        except (ValueError, FloatingPointError):
            return u
        return guess if (math.isfinite(e_guess) and e_guess < self.shell.energy(u)) else u

    def _update_curvature(self):
        self.H, self.H_vertex = self.growth.mean_curvature(self.u)
        self.energy = float(self.shell.strain_energy(self.u))
        self.non_elliptic = len(self.shell.non_elliptic_elements(self.u))
        self.over_folded = len(self.shell.over_folded_edges(self.u))

    @property
    def points(self) -> np.ndarray:
        """Current vertex positions (n, 3)."""
        return self.shell.positions(self.u)

    @property
    def source(self) -> np.ndarray:
        """P(H) at the vertices for the current shape (concentration/time)."""
        return self.params.source(self.H_vertex)

    def _equilibrate_initial(self):
        """Stable equilibrium for s(c0), the growth ramped up from s = 1 in increments ≤ ramp_ds."""
        st = self.stepping
        target = self.s
        ones = np.ones_like(target)
        span = float(np.max(np.abs(target - 1.0))) if len(target) else 0.0
        lam, dlam = 0.0, 1.0 if span <= st.ramp_ds else st.ramp_ds / span
        u = self.u
        u_prev, lam_prev = None, None
        iters = 0
        cuts = cuts_in_row = 0
        t_start = t_said = time.perf_counter()
        while True:
            trial = min(1.0, lam + dlam)
            s = ones + trial * (target - ones)
            self.growth.apply(s)
            start = u if u_prev is None else self._predict(u, u_prev, (trial - lam) / (lam - lam_prev))
            try:
                res = self._newton(start)
                why = _rejected(res)
            except NewtonError as exc:
                why = exc
            if why is not None:
                cuts += 1
                cuts_in_row += 1
                if cuts_in_row > st.max_cuts or dlam < 1e-6:
                    self.growth.apply(ones + lam * (target - ones))
                    # measured on thin shells (h = 1e-3 on R = 15): ramp_ds 0.02 and 200 iterations succeed
                    raise CoupledError(f"initial equilibrium: Newton failed at growth fraction {trial:.4g} "
                                       f"after {cuts_in_row} cuts of one ramp step ({why}); a smaller ramp_ds (now "
                                       f"{st.ramp_ds:g}) and a larger newton_max_iter (now {st.newton_max_iter}) "
                                       "help thin or strongly grown shells")
                dlam *= 0.5
                self._say(f"  initial equilibrium: Newton failed at fraction {trial:.4g}; ramp step cut to {dlam:.3g}")
                continue
            u_prev, lam_prev = u, lam
            u, lam = res.u, trial
            cuts_in_row = 0
            iters += res.iterations
            self._last_stable = res.stable
            if lam >= 1.0:
                break
            now = time.perf_counter()
            if now - t_said >= 10.0:       # a thin or strongly grown shell can take minutes here
                t_said = now
                self._say(f"initial equilibrium: growth fraction {lam:.3g} after {now - t_start:.0f} s "
                          f"({iters} Newton iterations, {cuts} cuts)")
            dlam = min(1.0 - lam, 1.5 * dlam)
        self.u = u
        self.last_newton_iterations = iters
        self.newton_total += iters
        self._say(f"initial equilibrium: {iters} Newton iterations, {cuts} cuts, max s {float(target.max()):.4g}")

    # ---- one step -----------------------------------------------------------------------------
    @property
    def done(self) -> bool:
        """t reached t_final or the pattern is stationary."""
        return self._at_end() or self.is_stationary

    def _at_end(self) -> bool:
        tf = self.stepping.t_final
        return self.t >= tf - 1e-12 * max(1.0, abs(tf))

    @property
    def is_stationary(self) -> bool:
        """c and the shape stopped changing (the rate test), or the pattern did (``stationary_pattern_time``)."""
        return self.stationary_reason != ""

    @property
    def stationary_reason(self) -> str:
        """Why the run is stationary: a sentence, or "" while it is not."""
        st = self.stepping
        if st.stationary_rate_c > 0 and st.stationary_rate_x > 0 and self.stationary_count >= st.stationary_steps:
            return (f"rates of c and shape {self._last_rates[0]:.2g}, {self._last_rates[1]:.2g} per unit "
                    f"time for {self.stationary_count} steps")
        held = self.pattern_unchanged_for
        if st.stationary_pattern_time > 0 and held >= st.stationary_pattern_time * (1 - 1e-12):
            m = self._pattern_anchor[1]
            return (f"the pattern ({m.n_spots} region(s), {100 * m.fraction_patterned:.3g} % of the area) has stayed "
                    f"the same within {st.stationary_pattern_tol:g} since t = {self._pattern_anchor[0]:.6g}")
        return ""

    @property
    def pattern_unchanged_for(self) -> float:
        """Time over which the pattern has stayed the same (0 unless ``stationary_pattern_time`` > 0)."""
        return 0.0 if self._pattern_anchor is None else self.t - self._pattern_anchor[0]

    def _follow_pattern(self):
        """Restart the pattern's clock where it is no longer the one it was (``stationary_pattern_time``)."""
        from .analysis import find_spots, same_pattern

        pts = self.points
        now = find_spots(pts, self.mesh.triangles, self.c, self.params.c_star)
        self._pattern_now = (self.step, now)
        anchor = self._pattern_anchor
        if anchor is None or not same_pattern(anchor[1], now, self.stepping.stationary_pattern_tol):
            self._pattern_anchor = (self.t, now, self.c.copy(), pts)

    def advance(self) -> StepRecord:
        """Make one accepted step (cutting dt as needed); returns its record.

        Raises :class:`CoupledError` (the state is unchanged) when the step cannot be
        made within ``max_cuts`` cuts or dt would fall below ``dt_min``.
        """
        st = self.stepping
        wall0 = time.perf_counter()
        if self._at_end():
            raise CoupledError(f"t = {self.t:.6g} has reached t_final = {st.t_final:.6g}")
        points = self.points
        source = self.params.source(self.H_vertex)
        dt = float(self.dt)
        cuts = 0
        reason = ""
        ds = 0.0
        snapped = snap_tried = False
        try:
            while True:
                snapped = False
                remaining = st.t_final - self.t
                last = dt >= remaining * (1 - 1e-12)
                h = remaining if last else dt
                if h < st.dt_min * (1 - 1e-12) and not last:
                    raise CoupledError(f"step {self.step + 1} at t = {self.t:.6g}: dt = {h:.3g} fell below dt_min = "
                                       f"{st.dt_min:.3g} ({reason}); the last accepted state is kept"
                                       + (self._steep_switch_hint(ds) if reason.startswith("max |Δs|") else "")
                                       + self._non_elliptic_hint())
                try:
                    c_new = self.chemistry.step(self.c, h, source=self._held_source(source, h), points=points)
                except (ValueError, FloatingPointError, ArithmeticError, LinearSolverError) as exc:
                    raise CoupledError(f"step {self.step + 1} at t = {self.t:.6g}: the chemistry step failed: "
                                       f"{exc}") from exc
                if not np.all(np.isfinite(c_new)):
                    ok, reason = False, "non-finite concentration"
                    ds = float("inf")
                    s_new = None
                else:
                    s_new = self.growth.stretch(c_new)
                    ds = float(np.max(np.abs(s_new - self.s))) if len(s_new) else 0.0
                    ok = ds <= st.ds_max * (1 + 1e-12)
                    reason = "" if ok else f"max |Δs| = {ds:.3g} > ds_max = {st.ds_max:.3g}"
                res = None
                if ok:
                    self.growth.apply(s_new)
                    start = self.u
                    if st.predictor and self._u_prev is not None and self._h_prev > 0:
                        start = self._predict(self.u, self._u_prev, h / self._h_prev)
                    try:
                        res = self._newton(start)
                    except NewtonError as exc:
                        # one snap per step: where it does not settle, the cuts that follow are plain
                        res = None
                        if not snap_tried and self._snap_applies(exc, ds):
                            snap_tried = True
                            res = self._snap(exc.result, ds)
                        snapped = res is not None
                        if not snapped:
                            ok, reason = False, f"Newton failed: {exc}"
                    why = _rejected(res) if ok else None
                    if why:
                        ok, reason = False, why
                    if not ok:
                        self.growth.apply(self.s)           # back to the accepted rest state
                if ok:
                    break
                cuts += 1
                self.n_rejected += 1
                if cuts > st.max_cuts:
                    raise CoupledError(f"step {self.step + 1} at t = {self.t:.6g} failed after {st.max_cuts} cuts "
                                       f"(last dt = {h:.3g}: {reason}); the last accepted state is kept"
                                       + self._non_elliptic_hint())
                factor = 0.5
                if math.isfinite(ds) and ds > st.ds_max:
                    factor = min(0.5, max(0.1, st.safety * st.ds_max / ds))
                dt = h * factor
                self._say(f"  step {self.step + 1} t = {self.t:.6g}: cut to dt = {dt:.3g} ({reason})")
        except BaseException:
            self.growth.apply(self.s)       # an error or Ctrl-C mid-attempt: back to the accepted rest state
            raise

        # accept: all at once (a Ctrl-C here would leave half a step: c new, rest state old)
        with committing():
            before = self.state_dict()
            try:
                return self._accept(c_new, s_new, res, h, last, ds, cuts, snapped, points, source, wall0)
            except BaseException:
                self.load_state_dict(before)      # an error while committing: not half a step
                raise

    def _held_source(self, source, h: float):
        """The source the chemistry holds over a step of length h from the current state.

        ``source_rule = "extrapolated"``: P at the step's midpoint extrapolated from the last two
        accepted states (Adams–Bashforth 2), P_n + θ (h / 2h_prev)(P_n − P_{n−1}) with θ the
        fraction of the extrapolation that is stable (:func:`stable_extrapolation`, decided with
        the next dt), kept within P's range [0, w Hs]. Otherwise, and where there is no
        previous state (the first step, after a snap), P_n itself.
        """
        if not (self._extrapolate > 0 and self._source_prev is not None and self._h_prev > 0):
            return source
        mid = source + (0.5 * self._extrapolate * h / self._h_prev) * (source - self._source_prev)
        return np.clip(mid, 0.0, self.params.w * self.params.Hs)

    def _accept(self, c_new, s_new, res, h, last, ds, cuts, snapped, points, source, wall0) -> StepRecord:
        """Commit the step of length h to the attempt's c, stretch and equilibrium; returns its record."""
        st = self.stepping
        x_old = points
        c_old = self.c
        self.c = c_new
        # a snap is no trend: the secant through it would predict a second jump
        self._u_prev, self._h_prev = (None, 0.0) if snapped else (self.u, h)
        self._source_prev = None if snapped else source
        self.n_snaps += int(snapped)
        self.u = res.u
        self.s = s_new
        self.t = st.t_final if last else self.t + h
        self.step += 1
        self.last_newton_iterations = res.iterations
        self.newton_total += res.iterations
        self._last_stable = res.stable
        self._last_ds = ds
        was_elliptic, was_resolved = self.non_elliptic == 0, self.over_folded == 0
        self._update_curvature()
        if was_elliptic:
            self._say_non_elliptic()
        if was_resolved:
            self._say_over_folded()
        self._follow_stationarity(c_old, x_old, h)
        self.dt = self._next_dt(h, ds, cuts, c_old, source)
        rec = self.record(dt=h, cuts=cuts, wall_s=time.perf_counter() - wall0, snapped=snapped)
        self._say(f"step {rec.step:5d} t {rec.t:10.5g} dt {rec.dt:9.3g} newton {rec.newton_iterations:2d} "
                  f"(+{res.quasi_newton_iterations} quasi) "
                  f"cuts {cuts} max c {rec.max_c:.4g} max H {rec.max_H:.4g} ds {ds:.3g} "
                  f"spots {rec.n_spots} {rec.wall_s:.2f}s{' snapped' if snapped else ''}")
        return rec

    def _follow_stationarity(self, c_old, x_old, h: float):
        """Rates of change of c and of the shape over the accepted step of length h, and the stationarity counters.

        rate_c = max|c − c_old| / (h c_scale), rate_x = max|x − x_old| / (h h0) with c_scale the
        largest |c| (at least 1 % of c_max) and h0 the shell's thickness (the length of the model).
        """
        st, p = self.stepping, self.params
        c_scale = max(float(np.max(np.abs(self.c))) if len(self.c) else 0.0,
                      1e-2 * p.c_max if math.isfinite(p.c_max) else 0.0, 1e-300)
        rate_c = float(np.max(np.abs(self.c - c_old))) / (h * c_scale) if len(self.c) else 0.0
        rate_x = float(np.max(np.abs(self.points - x_old))) / (h * self._length)
        self._last_rates = (rate_c, rate_x)
        if rate_c < st.stationary_rate_c and rate_x < st.stationary_rate_x:
            self.stationary_count += 1
        else:
            self.stationary_count = 0
        if st.stationary_pattern_time > 0:
            self._follow_pattern()

    def _next_dt(self, h: float, ds: float, cuts: int, c_old, source_old) -> float:
        """dt of the next step after an accepted one of length h that changed the stretch by ds.

        Grows while Δs stays small, never beyond a step that had to be cut, and stays within
        the stability limit of the staggering (module docstring).
        """
        st, p = self.stepping, self.params
        grow = st.grow if ds <= 0 else min(st.grow, st.safety * st.ds_max / ds)
        nxt = h * max(grow, 0.1)
        if cuts:
            nxt = min(nxt, h)
        self._last_gain = feedback_gain(self.c - c_old, p.source(self.H_vertex) - source_old)
        if st.feedback_amplification > 0:
            nxt = min(nxt, feedback_step_limit(self._last_gain, p.beta, st.feedback_amplification,
                                               exponential=True))
        nxt = float(min(st.dt_max, max(st.dt_min, nxt)))
        self._extrapolate = (stable_extrapolation(self._last_gain, p.beta, st.feedback_amplification or 1.0, nxt, h)
                             if st.source_rule == "extrapolated" else 0.0)
        return nxt

    def record(self, dt: float = 0.0, cuts: int = 0, wall_s: float = 0.0, snapped: bool = False) -> StepRecord:
        """The :class:`StepRecord` of the current state."""
        from .analysis import count_spots

        pts = self.points
        if self._pattern_now is not None and self._pattern_now[0] == self.step:
            n_spots = self._pattern_now[1].n_spots          # found by _follow_pattern for this step
        else:
            n_spots = count_spots(pts, self.mesh.triangles, self.c, self.params.c_star)
        return StepRecord(step=self.step, t=float(self.t), dt=float(dt),
                          newton_iterations=int(self.last_newton_iterations),
                          cuts=int(cuts), max_c=float(self.c.max()) if len(self.c) else 0.0,
                          max_H=float(self.H_vertex.max()), min_H=float(self.H_vertex.min()),
                          max_s=float(self.s.max()), ds=float(self._last_ds), energy=float(self.energy),
                          n_spots=int(n_spots), rate_c=float(self._last_rates[0]),
                          rate_x=float(self._last_rates[1]), stable=self._last_stable, wall_s=float(wall_s),
                          snapped=bool(snapped), feedback_gain=float(self._last_gain),
                          non_elliptic=int(self.non_elliptic), over_folded=int(self.over_folded))

    # ---- loops --------------------------------------------------------------------------------
    def iterate(self, max_steps: int | None = None):
        """Generator: one :class:`StepRecord` per accepted step until t_final or stationarity.

        Raises :class:`CoupledError` when a step fails (the loop keeps the last accepted state).
        """
        k = 0
        while not self.done and (max_steps is None or k < max_steps):
            rec = self.advance()
            k += 1
            yield rec

    def run(self, callback=None, *, checkpoint=None, checkpoint_every: int = 10, max_steps: int | None = None,
            wall_time: float | None = None, keep_records: bool = False) -> RunResult:
        """Step until t_final, stationarity, ``max_steps`` (default ``stepping.max_steps``) or ``wall_time`` (s).

        ``callback(record, loop)`` after each accepted step (write frames there);
        ``checkpoint(state_dict, record)`` every ``checkpoint_every`` accepted steps and
        once at the end, whatever the reason, including a failed step (then with the
        last accepted state). A failure does not raise: the result has status "failed"
        and the message. Neither does Ctrl-C (KeyboardInterrupt): the run ends with status
        "interrupted" on the last accepted state, checkpointed. Any other exception (from the
        callback, or an unexpected solver error) is raised after that checkpoint.
        ``keep_records`` keeps all step records in the result.
        """
        checkpoint_every = _integer("checkpoint_every", checkpoint_every, 1)
        if wall_time is not None:
            _finite("wall_time", wall_time, 0.0)
        max_steps = self.stepping.max_steps if max_steps is None else _integer("max_steps", max_steps, 0)
        t0 = time.perf_counter()
        k = 0
        last = None
        records = []
        status, message = None, ""
        dirty = False
        try:
            while True:
                if self._at_end():
                    status, message = "t_final", f"reached t_final = {self.stepping.t_final:g}"
                    break
                if self.is_stationary:
                    status, message = "stationary", f"stationary at t = {self.t:.6g}: {self.stationary_reason}"
                    break
                if max_steps is not None and k >= max_steps:
                    status, message = "max_steps", f"stopped after {k} steps (max_steps)"
                    break
                if wall_time is not None and time.perf_counter() - t0 >= wall_time:
                    status, message = "wall_time", f"stopped after {time.perf_counter() - t0:.1f} s (wall_time)"
                    break
                with step_scope():      # a Ctrl-C once the step commits waits for its callback and checkpoint
                    last = self.advance()
                    k += 1
                    dirty = True
                    if keep_records:
                        records.append(last)
                    if callback is not None:
                        callback(last, self)
                    if checkpoint is not None and k % int(checkpoint_every) == 0:
                        checkpoint(self.state_dict(), last)
                        dirty = False
        except CoupledError as exc:
            status, message = "failed", str(exc)
            self._say(f"coupled loop stopped: {exc}")
        except KeyboardInterrupt:
            # Ctrl-C (or SIGTERM, where the caller maps it to KeyboardInterrupt) mid-step: the
            # accepted state is intact, but a trial step may have changed the rest state
            self.growth.apply(self.s)
            status, message = "interrupted", f"interrupted at t = {self.t:.6g} after {k} step(s) of this run"
            self._say(f"coupled loop {message}")
        except BaseException as exc:
            # not a failed step but an error (a callback's, a solver's): raised, after the
            # accepted steps are checkpointed (unless the checkpoint is what failed)
            if checkpoint is not None and dirty:
                try:
                    checkpoint(self.state_dict(), last)
                except Exception as ck:
                    self._say(f"coupled loop: the checkpoint after the error failed too: {ck}")
                    if hasattr(exc, "add_note"):                # Python >= 3.11
                        exc.add_note(f"the checkpoint of the last {k} step(s) was not written: {ck}")
            raise
        if checkpoint is not None and dirty:
            checkpoint(self.state_dict(), last if last is not None else self.record())
        return RunResult(status, message, k, float(self.t), time.perf_counter() - t0, last, records)

    # ---- checkpoints --------------------------------------------------------------------------
    def state_dict(self) -> dict:
        """Everything the loop needs to continue bit for bit: numbers and arrays only (no RNG).

        Keys: version, t, dt, step, c (n,), u (free unknowns), u_prev and h_prev (the
        previous accepted state and step, for the secant predictor and the extrapolated
        source; u_prev empty at step 0), extrapolate (the fraction θ of :func:`stable_extrapolation`
        the next step takes), stationary_count, n_rejected, n_snaps, newton_total,
        last_newton_iterations, last_ds, n_vertices, n_free, held_cholesky (whether the last
        state's Hessian is held as a Cholesky factor for the quasi-Newton start of the next step:
        a resumed loop factorises it again, so that it continues exactly as the uninterrupted
        one), pattern_anchor_t, pattern_anchor_c and pattern_anchor_points (when and with which c
        and shape the pattern last changed, for ``stationary_pattern_time``; left out when it is
        not followed).
        Store with :func:`femshell.io.save_checkpoint`; parameters go in its meta.
        """
        return {"version": STATE_VERSION, "t": float(self.t), "dt": float(self.dt), "step": int(self.step),
                "c": self.c.copy(), "u": np.asarray(self.u, float).copy(),
                "stationary_count": int(self.stationary_count), "n_rejected": int(self.n_rejected),
                "n_snaps": int(self.n_snaps),
                "newton_total": int(self.newton_total), "last_newton_iterations": int(self.last_newton_iterations),
                "last_ds": float(self._last_ds), "n_vertices": int(self.mesh.n_vertices),
                "u_prev": (np.zeros(0) if self._u_prev is None else np.asarray(self._u_prev, float).copy()),
                "h_prev": float(self._h_prev), "extrapolate": float(self._extrapolate),
                "n_free": int(self.shell.n_free),
                "held_cholesky": int(self._held_cholesky()),
                **self._pattern_anchor_state()}

    def _pattern_anchor_state(self) -> dict:
        a = self._pattern_anchor
        if a is None:
            return {}
        return {"pattern_anchor_t": float(a[0]), "pattern_anchor_c": a[2].copy(), "pattern_anchor_points": a[3].copy()}

    def _held_cholesky(self) -> bool:
        held = self._factorizers[0].last
        return held is not None and held.kind == "spd"

    def load_state_dict(self, state: dict):
        """Continue from :meth:`state_dict` output (same mesh, parameters and stepping)."""
        need = ("t", "dt", "step", "c", "u")
        missing = [k for k in need if k not in state]
        if missing:
            raise ValueError(f"state dict lacks {', '.join(missing)}")
        version = int(state.get("version", STATE_VERSION))
        if version > STATE_VERSION:
            raise ValueError(f"state version {version} is newer than this femshell ({STATE_VERSION})")
        c = np.array(state["c"], dtype=float)
        u = np.array(state["u"], dtype=float)
        # version 1 stored edge angles: read as tangents they would be other normals
        from_angles = version < 2
        if c.shape != (self.mesh.n_vertices,):
            raise ValueError(f"state c has shape {c.shape}, the mesh has {self.mesh.n_vertices} vertices")
        if u.shape != (self.shell.n_free,):
            raise ValueError(f"state u has shape {u.shape}, the shell has {self.shell.n_free} free unknowns "
                             "(other mesh or boundary conditions?)")
        if not (np.all(np.isfinite(c)) and np.all(np.isfinite(u))):
            raise ValueError("state holds non-finite values")
        if from_angles:
            u = self.shell.from_edge_angles(u)
        if np.any(c < 0):
            raise ValueError(f"state c is negative at {int(np.count_nonzero(c < 0))} vertices (a concentration is >= 0)")
        t = _finite("state t", state["t"], 0.0)
        dt = _finite("state dt", state["dt"], 0.0, lo_open=True, text="(0, inf)")
        step = _integer("state step", state["step"], 0)
        st = self.stepping
        self.t = t
        # the stepping may differ from the run that wrote the state (a new dt_max): stay within it
        self.dt = min(st.dt_max, max(st.dt_min, dt))
        self.step = step
        self.c = c
        self.u = u
        self.stationary_count = int(state.get("stationary_count", 0))
        self.n_rejected = int(state.get("n_rejected", 0))
        self.n_snaps = int(state.get("n_snaps", 0))
        self.newton_total = int(state.get("newton_total", 0))
        self.last_newton_iterations = int(state.get("last_newton_iterations", 0))
        self._last_ds = float(state.get("last_ds", 0.0))
        u_prev = np.array(state.get("u_prev", np.zeros(0)), dtype=float)
        self._u_prev = u_prev if u_prev.shape == u.shape else None
        if from_angles and self._u_prev is not None:
            self._u_prev = self.shell.from_edge_angles(self._u_prev)
        self._h_prev = float(state.get("h_prev", 0.0)) if self._u_prev is not None else 0.0
        self._source_prev = None
        # θ as chosen for the stored dt (a dt clamped to a smaller dt_max only makes it more stable)
        self._extrapolate = (float(state.get("extrapolate", 0.0))
                             if self.stepping.source_rule == "extrapolated" else 0.0)
        if self._extrapolate > 0 and self._u_prev is not None:
            self._source_prev = self.params.source(self.growth.mean_curvature(self._u_prev)[1])
        self._last_rates = (float("nan"), float("nan"))
        self._last_gain = float("nan")
        self._last_stable = None
        self._pattern_anchor = self._pattern_now = None
        t_a = float(state.get("pattern_anchor_t", float("nan")))
        c_a = np.array(state.get("pattern_anchor_c", np.zeros(0)), dtype=float)
        x_a = np.array(state.get("pattern_anchor_points", np.zeros((0, 3))), dtype=float)
        # restored only where it is followed: a stale clock would otherwise be checkpointed on
        if (self.stepping.stationary_pattern_time > 0 and math.isfinite(t_a) and c_a.shape == c.shape
                and x_a.shape == (len(c), 3)):
            from .analysis import find_spots

            self._pattern_anchor = (t_a, find_spots(x_a, self.mesh.triangles, c_a, self.params.c_star), c_a, x_a)
        self.s = self.growth.stretch(self.c)
        self.growth.apply(self.s)
        self._update_curvature()
        for f in self._factorizers:
            f.free()
        if state.get("held_cholesky", 0) and self.stepping.quasi_newton:
            try:
                self._factorizers[0](self.shell.hessian(self.u))
            except LinearSolverError:
                self._factorizers[0].free()     # the next step starts with plain Newton

    @classmethod
    def from_state_dict(cls, mesh, params: MechanochemicalModel, state: dict,
                        stepping: TimeStepping | None = None, boundary_conditions=(), log=None) -> "CoupledLoop":
        """A loop that continues from ``state`` (no initial equilibrium is computed).

        The state holds no parameters: give the run's own ``params`` and ``stepping`` (None is
        ``TimeStepping()``, the defaults) to continue it bit for bit. Others are taken as given
        (continuing a state under new parameters is a use, not an error); the proposed dt is
        kept within the new stepping's [dt_min, dt_max].
        """
        loop = cls(mesh, params, stepping, c0=None, boundary_conditions=boundary_conditions,
                   equilibrate=False, log=log)
        loop.load_state_dict(state)
        return loop
