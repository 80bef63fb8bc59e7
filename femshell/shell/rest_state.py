r"""The rest (target) state of a shell: target metric ā, curvature b̄ and thickness h̄ per element.

All three are 2x2 tensors (ā, b̄) or scalars (h̄) in each triangle's barycentric
coordinates :math:`(u, v) = (\lambda_1, \lambda_2)` of the reference mesh, the same
coordinates in which the element measures the current forms (docs/theory.md §2).

Example: a flat disk that wants to become a spherical cap of radius R has
``ā = ā0`` and ``b̄ = ā0 / R`` (:func:`natural_curvature`); a uniformly grown sheet
has ``ā = (1 + g)^2 ā0`` (:func:`uniform_growth`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def metric(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """First fundamental form a_ij = e_i . e_j, e1 = x1 - x0, e2 = x2 - x0; shape (m, 2, 2)."""
    x = points[triangles]
    e = np.stack([x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]], axis=1)  # (m, 2, 3)
    return np.einsum("mik,mjk->mij", e, e)


@dataclass
class RestState:
    """Per-element targets: ``metric`` (m,2,2), ``curvature`` (m,2,2), ``thickness`` (m,).

    The arrays are copies and read-only: a model caches what it derives from them (the inverse
    metric, the areas), so a change goes through a new RestState and ``set_rest_state``.
    """

    metric: np.ndarray
    curvature: np.ndarray
    thickness: np.ndarray

    def __post_init__(self):
        self.metric = np.array(self.metric, float)
        self.curvature = np.array(self.curvature, float)
        h = np.asarray(self.thickness, float)
        if h.ndim > 1 or h.size not in (1, len(self.metric)):
            raise ValueError(f"thickness must be a number or one value per element (shape ({len(self.metric)},)), "
                             f"got shape {h.shape}")
        self.thickness = np.broadcast_to(h.reshape(-1)[0] if h.size == 1 else h, (len(self.metric),)).copy()
        m = len(self.metric)
        if self.metric.shape != (m, 2, 2) or self.curvature.shape != (m, 2, 2):
            raise ValueError(f"target metric and curvature must have shape (m, 2, 2) with m = {m}, "
                             f"got {self.metric.shape} and {self.curvature.shape}")
        det = np.linalg.det(self.metric)
        if not np.all(np.isfinite(det)) or np.any(det <= 0) or np.any(self.metric[:, 0, 0] <= 0):
            bad = int(np.flatnonzero(~(np.isfinite(det) & (det > 0)) | (self.metric[:, 0, 0] <= 0))[0])
            raise ValueError(f"target metric of element {bad} is not positive definite: {self.metric[bad].tolist()}")
        if not np.all(np.isfinite(self.thickness) & (self.thickness > 0)):
            bad = int(np.flatnonzero(~(np.isfinite(self.thickness) & (self.thickness > 0)))[0])
            raise ValueError(f"target thickness must be > 0, element {bad} has {self.thickness[bad]}")
        if not np.all(np.isfinite(self.curvature)):
            raise ValueError("target curvature has NaN or inf entries")
        for name, t in (("metric", self.metric), ("curvature", self.curvature)):
            skew = np.abs(t[:, 0, 1] - t[:, 1, 0])
            if np.any(skew > 1e-12 * np.abs(t).max(axis=(1, 2))):
                bad = int(np.argmax(skew))
                raise ValueError(f"target {name} must be symmetric, element {bad} has {t[bad].tolist()}")
        for a in (self.metric, self.curvature, self.thickness):
            a.setflags(write=False)

    @property
    def area(self) -> np.ndarray:
        """Target area Ā = ½ √det ā of each element."""
        return 0.5 * np.sqrt(np.linalg.det(self.metric))

    @property
    def metric_inverse(self) -> np.ndarray:
        return np.linalg.inv(self.metric)


def flat_rest_state(points, triangles, thickness) -> RestState:
    """The mesh as drawn is stress free: ā = ā0, b̄ = 0."""
    a0 = metric(np.asarray(points, float), np.asarray(triangles))
    return RestState(a0, np.zeros_like(a0), thickness)


def natural_curvature(points, triangles, thickness, k0: float) -> RestState:
    """ā = ā0 and b̄ = k0 ā0: the shell wants mean curvature k0 (k0 = 1/R for a sphere of radius R)."""
    a0 = metric(np.asarray(points, float), np.asarray(triangles))
    return RestState(a0, k0 * a0, thickness)


def uniform_growth(points, triangles, thickness, strain: float, k0: float = 0.0,
                   volume_conserving: bool = False) -> RestState:
    """Isotropic growth by the linear stretch s = 1 + strain: ā = s² ā0, b̄ = k0 ā.

    With ``volume_conserving`` the thickness becomes h / s² (docs/theory.md §5).
    """
    try:
        g = float(strain) if np.ndim(strain) == 0 and not isinstance(strain, (bool, str)) else math.nan
    except (TypeError, ValueError):
        g = math.nan
    if not -1.0 < g <= 1e100:
        raise ValueError(f"growth strain must be one number in (-1, 1e100], got {strain!r}"[:200])
    s = 1.0 + g
    a0 = metric(np.asarray(points, float), np.asarray(triangles))
    h = np.asarray(thickness, float) / (s**2 if volume_conserving else 1.0)
    return RestState(s**2 * a0, k0 * s**2 * a0, h)
