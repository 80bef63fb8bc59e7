r"""Physical parameters of the mechanochemical shell (theory §1.1–1.3): one frozen dataclass.

c -> contractility Λ(c) -> stretch s(c) = Λ0/Λ(c); shape -> H -> source P(H) = w H/(1 + H/Hs);
∂t c = D Δ_Γ c + P(H) − β c. Units: lengths in cell sizes, time in 1/β, E = 1.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

from .._checks import finite as _finite
from ..chemistry import HS, W, curvature_source, curvature_source_slope
from ..growth import B, C_STAR, LAM_MAX, LAM_MIN, REST_CURVATURES, THICKNESS_MODES, contractility, dstretch_dc, stretch
from ..shell import Material

__all__ = ["MechanochemicalModel", "store_numbers"]


@dataclass(frozen=True)
class MechanochemicalModel:
    """Physical parameters of the mechanochemical shell (theory §1.1–1.3), the paper's values (§1.5) as defaults.

    Every default of the model is one of these fields (scenes take theirs from them): Λmax = 15,
    Λmin = 10, b = 100, c* = 0.1 (:data:`femshell.growth.LAM_MAX` …, also the defaults of the
    growth functions), w = 15, Hs = 0.05 (:data:`femshell.chemistry.W`, ``HS``, also those of
    :func:`~femshell.chemistry.curvature_source`), β = 1, h0 = 2 (also the spot width of
    :class:`~femshell.coupled.initial.InitialSpot`), D = 0.

    Lengths are in cell sizes and times in 1/β.

    Parameters
    ----------
    nu, E : Poisson ratio in (−1, 0.5] and Young's modulus (> 0; only scales energies).
    h0 : rest thickness (length, > 0).
    thickness_mode : "volume" (h̄ = h0/s², default) or "uniform" (h̄ = h0).
    radius, k0 : natural curvature k0 = 1/radius (1/length) of ``rest_curvature="k0"``
        (b̄ = k0 ā), which needs one of them (both: they must agree; k0 = 0 for a flat
        sheet). With ``rest_curvature="mesh"`` (default) they are not used: the mesh's
        own curvature is the rest curvature (:class:`~femshell.growth.GrowthRestState`).
    lam_max, lam_min : contractility of untouched and saturated tissue, 0 < Λmin ≤ Λmax.
    lam0 : reference contractility Λ0 of s = Λ0/Λ(c) (default Λmax). Note s(0) =
        Λmax/Λ(0) = 1 + 1.5e-5 with the defaults (Λ(0) is not exactly Λmax); pass
        ``lam0=contractility(0, ...)`` for s(0) = 1 exactly.
    b : steepness of the switch (1/concentration, > 0; not the second fundamental form b of the
        shell); c_star : threshold c* (≥ 0).
    w : production rate (concentration·length/time, ≥ 0); Hs : saturation curvature (1/length, > 0).
    beta : degradation rate (1/time, ≥ 0; the β of ∂c/∂t = … − βc, not the elastic β = E/(2(1 + ν))
        of the energy); D : diffusion coefficient (length²/time, ≥ 0).
    rest_curvature : "mesh" (default) or "k0", see :class:`~femshell.growth.GrowthRestState`.
    membrane_law : "svk" (theory §1.2) or "neo-hookean", which stays stable where a confined
        spot is compressed below 0.866 of its target length (:mod:`femshell.shell.element`).

    >>> from femshell.coupled import MechanochemicalModel
    >>> p = MechanochemicalModel()          # the paper's spots: h0 = 2, c* = 0.1, w = 15, D = 0
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
    lam_max: float = LAM_MAX
    lam_min: float = LAM_MIN
    lam0: float | None = None
    b: float = B
    c_star: float = C_STAR
    w: float = W
    Hs: float = HS
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
        store_numbers(self)

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

    def dstretch_dc(self, c):
        """ds/dc of :meth:`stretch` (1/concentration), any shape."""
        return dstretch_dc(c, self.lam0, self.lam_max, self.lam_min, self.b, self.c_star)

    def source(self, H):
        """P(H) = w H / (1 + H/Hs) for H > 0, else 0 (concentration/time)."""
        return curvature_source(H, self.w, self.Hs)

    def source_slope(self, H):
        """dP/dH of :meth:`source` (concentration·length/time)."""
        return curvature_source_slope(H, self.w, self.Hs)

    def as_dict(self) -> dict:
        return asdict(self)


def store_numbers(obj):
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
