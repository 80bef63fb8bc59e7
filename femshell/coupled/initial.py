r"""Initial concentration fields of the coupled loop: a Gaussian spot c0 = A exp(−(r/d)²).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._checks import finite as _finite, finite_vector
from .parameters import MechanochemicalModel

__all__ = ["gaussian_spot", "InitialSpot"]


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


@dataclass(frozen=True)
class InitialSpot:
    """The paper's initial condition: c = 0 except a Gaussian spot at a pole.

    ``amplitude`` default c_max = w Hs/β; ``width`` default h0 (both from the
    :class:`~femshell.coupled.parameters.MechanochemicalModel` given to :meth:`field`); other
    fields as in :func:`gaussian_spot`.
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
        """c0 at ``points`` (n, 3) for the model ``params`` (its c_max and h0 are the defaults)."""
        if self.amplitude is None:
            amp = params.c_max
            if not math.isfinite(amp):
                raise ValueError("spot amplitude defaults to c_max = w Hs / beta, infinite for beta = 0: give one")
        else:
            amp = _finite("spot amplitude", self.amplitude, 0.0)
        width = params.h0 if self.width is None else self.width
        return gaussian_spot(points, amp, width, pole=self.pole, elongation=self.elongation,
                             direction=self.direction, distance=self.distance)
