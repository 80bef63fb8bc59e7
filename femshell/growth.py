r"""Contractility, growth stretch and the target fields of the shell (theory §1.1).

The chemical lowers the contractility Λ of the cells; lower contractility makes the
cells want more area. With the defaults of the seed paper (Λmax = 15, Λmin = 10,
b = 100, c* = 0.1)::

    Λ(c) = Λmin + (Λmax − Λmin) · expit(b (c* − c))          [same unit as Λmax, Λmin]
    s(c) = Λ0 / Λ(c),  Λ0 = Λmax by default                   [dimensionless]
    ā = s² ā0,   h̄ = h0 / s² ("volume") or h0 ("uniform"),   b̄ = k0 ā

Units: c is a concentration in the model's own unit (the one in
which c* and c_max = w Hs / β are given), b is 1/concentration, lengths are in cell
sizes, ā and ā0 are length², h in length, k0 in 1/length, b̄ in length.

All functions are plain numpy, vectorised over elements or vertices; none of them
overflows for large |b (c − c*)| (the expit form is used, never exp(b c)).

Example
-------
>>> import numpy as np
>>> from femshell.growth import stretch
>>> np.round(stretch(np.array([0.0, 0.1, 1.0])), 4)
array([1. , 1.2, 1.5])
"""

from __future__ import annotations

import numpy as np
from scipy.special import expit

from ._checks import real_array, triangle_array, vertex_indices
from .geometry import element_to_vertex, mean_curvature

__all__ = ["contractility", "stretch", "dstretch_dc", "element_average", "target_metric",
           "target_thickness", "target_curvature", "GrowthRestState", "THICKNESS_MODES", "REST_CURVATURES",
           "LAM_MAX", "LAM_MIN", "B", "C_STAR"]

THICKNESS_MODES = ("volume", "uniform")
#: the paper's contractility switch, the defaults here and of MechanochemicalModel (femshell.coupled)
LAM_MAX, LAM_MIN, B, C_STAR = 15.0, 10.0, 100.0, 0.1
REST_CURVATURES = ("mesh", "k0")


def _check_params(lam_max, lam_min, b, c_star):
    for name, v in (("lam_max", lam_max), ("lam_min", lam_min), ("b", b), ("c_star", c_star)):
        if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
            raise ValueError(f"{name} must be one number, got {v!r}"[:200])
    if not np.isfinite(c_star):
        raise ValueError(f"c_star (c*, the threshold concentration) must be a finite number, got {c_star}")
    if not (np.isfinite(lam_min) and lam_min > 0):
        raise ValueError(f"lam_min (Λmin) must be a finite number > 0, got {lam_min}")
    if not (np.isfinite(lam_max) and lam_max >= lam_min):
        raise ValueError(f"lam_max (Λmax) must be finite and >= lam_min = {lam_min}, got {lam_max}")
    if not (np.isfinite(b) and b > 0):
        raise ValueError(f"b (steepness of the contractility switch) must be a finite number > 0, got {b}")


def _reference(lam0, lam_max, lam_min, b, c_star) -> float:
    """Λ0 (default Λmax) checked, with the other parameters."""
    _check_params(lam_max, lam_min, b, c_star)
    if lam0 is None:
        return lam_max
    if isinstance(lam0, bool) or not isinstance(lam0, (int, float, np.integer, np.floating)) \
            or not (np.isfinite(lam0) and lam0 > 0):
        raise ValueError(f"lam0 (Λ0, the reference contractility) must be a finite number > 0, got {lam0!r}"[:200])
    return lam0


def _as_finite(c, name="c"):
    c = real_array(name, c)
    bad = ~np.isfinite(c)
    if bad.any():
        first = np.unravel_index(np.flatnonzero(bad.ravel())[0], c.shape) if c.ndim else ()
        raise ValueError(f"{name} has {int(bad.sum())} non-finite value(s) (NaN or inf), first at index "
                         f"{tuple(int(i) for i in first)}")
    return c


def contractility(c, lam_max: float = LAM_MAX, lam_min: float = LAM_MIN, b: float = B, c_star: float = C_STAR):
    r"""Cell contractility Λ(c) = Λmin + (Λmax − Λmin) · expit(b (c* − c)).

    This equals (Λmax e^{b c*} + Λmin e^{b c}) / (e^{b c*} + e^{b c}) (theory §1.1)
    but never overflows: expit(x) = 1 / (1 + e^{−x}) is evaluated stably for any x.

    Parameters
    ----------
    c : array_like
        Concentration (model concentration unit), any shape.
    lam_max, lam_min : float
        Contractility of untouched (c ≪ c*) and saturated (c ≫ c*) tissue; 0 < Λmin ≤ Λmax.
    b : float
        Steepness of the switch, 1 / concentration unit; > 0.
    c_star : float
        Threshold concentration.

    Returns
    -------
    ndarray, same shape as ``c``: Λ in the unit of ``lam_max``.

    Example
    -------
    >>> float(contractility(0.1))    # at the threshold, halfway
    12.5
    """
    _check_params(lam_max, lam_min, b, c_star)
    c = _as_finite(c)
    with np.errstate(over="ignore"):          # b (c* − c) = ±inf: expit gives the right limit, 0 or 1
        return lam_min + (lam_max - lam_min) * expit(b * (c_star - c))


def stretch(c, lam0: float | None = None, lam_max: float = LAM_MAX, lam_min: float = LAM_MIN,
            b: float = B, c_star: float = C_STAR):
    r"""Linear growth stretch of the rest lengths, s(c) = Λ0 / Λ(c) (dimensionless).

    Λ0 = Λmax by default (the contractility of untouched tissue), so s = 1 for c ≪ c*
    and s = Λmax / Λmin (1.5 with the defaults) for c ≫ c*.

    Example
    -------
    >>> float(stretch(-1e3, b=1000)), float(stretch(1e3, b=1000))
    (1.0, 1.5)
    """
    lam0 = _reference(lam0, lam_max, lam_min, b, c_star)
    return lam0 / contractility(c, lam_max, lam_min, b, c_star)


def dstretch_dc(c, lam0: float | None = None, lam_max: float = LAM_MAX, lam_min: float = LAM_MIN,
                b: float = B, c_star: float = C_STAR):
    r"""Derivative ds/dc of :func:`stretch` (1 / concentration unit).

    With x = b (c* − c) and σ = expit::

        dΛ/dc = −b (Λmax − Λmin) σ(x) σ(−x),      ds/dc = −Λ0 / Λ² · dΛ/dc  ≥ 0

    σ(x) σ(−x) is the overflow-free form of e^x / (1 + e^x)².

    Example
    -------
    >>> float(dstretch_dc(0.1))      # b (Λmax − Λmin) / 4 · Λmax / 12.5² at c = c*
    12.0
    """
    lam0 = _reference(lam0, lam_max, lam_min, b, c_star)
    lam = contractility(c, lam_max, lam_min, b, c_star)
    with np.errstate(over="ignore"):
        x = b * (c_star - np.asarray(c, dtype=float))
        # b last: far from c* the product σ(x) σ(−x) is 0, and b · 0 = 0 even for a huge b
        dlam = -((lam_max - lam_min) * expit(x) * expit(-x)) * b
        return -lam0 / lam**2 * dlam


def element_average(c_vertices, triangles):
    r"""Mean of the three vertex values of each triangle, c_e = (c_i + c_j + c_k) / 3.

    Parameters
    ----------
    c_vertices : (n,) or (n, ...) array
        Values at the vertices (any unit; the result has the same unit).
    triangles : (m, 3) int array

    Returns
    -------
    (m,) or (m, ...) array.

    Example
    -------
    >>> element_average(np.array([0.0, 3.0, 6.0, 9.0]), np.array([[0, 1, 2], [1, 2, 3]]))
    array([3., 6.])
    """
    c = _as_finite(c_vertices, "vertex values")
    tri = triangle_array(triangles)
    vertex_indices(tri, len(c), of="vertex values")
    return c[tri].mean(axis=1)


def target_metric(rest_metric, s):
    r"""Target first fundamental form of isotropic growth, ā = s² ā0 (length²).

    Parameters
    ----------
    rest_metric : (m, 2, 2) array
        ā0, the first fundamental form of the rest mesh per element (length²).
    s : (m,) array or float
        Linear stretch per element (dimensionless, > 0).

    Example
    -------
    >>> target_metric(np.eye(2)[None], np.array([1.5]))[0]
    array([[2.25, 0.  ],
           [0.  , 2.25]])
    """
    a0 = np.asarray(rest_metric, dtype=float)
    if a0.ndim != 3 or a0.shape[1:] != (2, 2):
        raise ValueError(f"rest_metric must have shape (m, 2, 2), got {a0.shape}")
    if not np.all(np.isfinite(a0)):
        raise ValueError(f"rest_metric holds non-finite values in {int((~np.isfinite(a0)).any(axis=(1, 2)).sum())} "
                         "element(s)")
    s = _check_stretch(s, len(a0))
    return (s * s)[:, None, None] * a0


def target_thickness(h0, s, mode: str = "volume"):
    r"""Target thickness h̄ (length).

    ``mode="volume"`` (default, volume-conserving growth): h̄ = h0 / s²;
    ``mode="uniform"``: h̄ = h0.

    Parameters
    ----------
    h0 : float or (m,) array
        Rest thickness (length, > 0).
    s : float or (m,) array
        Linear stretch per element (dimensionless, > 0).

    Example
    -------
    >>> target_thickness(2.0, np.array([1.0, 2.0]))
    array([2. , 0.5])
    >>> target_thickness(2.0, np.array([1.0, 2.0]), mode="uniform")
    array([2., 2.])
    """
    if mode not in THICKNESS_MODES:
        raise ValueError(f"thickness mode must be one of {THICKNESS_MODES}, got {mode!r}")
    h0 = real_array("h0", h0)
    if h0.ndim > 1:
        raise ValueError(f"rest thickness h0 must be a number or one value per element, got shape {h0.shape}")
    if not (np.all(np.isfinite(h0)) and np.all(h0 > 0)):
        raise ValueError(f"rest thickness h0 must be finite and > 0, got min {np.min(h0)}")
    s = np.asarray(s, dtype=float)
    s = _check_stretch(s, s.shape[0] if s.ndim else None)
    if h0.ndim and s.ndim and h0.shape != s.shape:
        raise ValueError(f"h0 and s must be numbers or arrays of one value per element of the same shape, "
                         f"got {h0.shape} and {s.shape}")
    if mode == "volume":
        return h0 / (s * s)
    return np.broadcast_to(h0, np.broadcast_shapes(h0.shape, s.shape)).astype(float)


def target_curvature(target_metric, k0):
    r"""Target second fundamental form b̄ = k0 ā (length), i.e. ā⁻¹ b̄ = k0 I.

    Parameters
    ----------
    target_metric : (m, 2, 2) array
        ā per element (length²).
    k0 : float or (m,) array
        Natural curvature, 1/length (1/R for a sphere of radius R, 0 for a flat sheet).

    Example
    -------
    >>> round(float(target_curvature(np.eye(2)[None] * 4.0, 1 / 30)[0, 0, 0]), 6)
    0.133333
    """
    a = np.asarray(target_metric, dtype=float)
    if a.ndim != 3 or a.shape[1:] != (2, 2):
        raise ValueError(f"target_metric must have shape (m, 2, 2), got {a.shape}")
    k0 = np.asarray(k0, dtype=float)
    if not np.all(np.isfinite(k0)):
        raise ValueError("k0 must be finite")
    if k0.ndim == 0:
        return float(k0) * a
    if k0.shape != (len(a),):
        raise ValueError(f"k0 must be a scalar or have shape ({len(a)},), got {k0.shape}")
    return k0[:, None, None] * a


def _check_stretch(s, m):
    s = _as_finite(s, "stretch s")
    if s.ndim > 1 or (m is not None and s.ndim == 1 and len(s) != m):
        raise ValueError(f"stretch s must be a scalar or have shape ({m},), got {s.shape}")
    if np.any(s <= 0):
        raise ValueError(f"stretch s must be > 0, got min {s.min()}")
    if np.any((s < 1e-100) | (s > 1e100)):   # s² and h/s² stay representable
        raise ValueError(f"stretch s must be in [1e-100, 1e100], got {s.min():.3g} to {s.max():.3g}")
    return np.broadcast_to(s, (m,)) if (s.ndim == 0 and m is not None) else s


class GrowthRestState:
    r"""The rest state of a growing shell and the mean curvature H measured from it (theory §1.1, §2.7).

    Element stretches s -> RestState(ā = s² ā0, b̄ = s² b̄0, h̄(s)) -> ``model.set_rest_state``,
    and a shape u -> H = ½ tr(a⁻¹ b) − k_ref per element and per vertex. ā0 and b_mesh are the
    fundamental forms of ``model`` at its initial unknowns (the drawn mesh at zero edge angles).

    ``rest_curvature="mesh"``: b̄0 = b_mesh and k_ref = ½ tr(ā0⁻¹ b_mesh), so the drawn mesh is
    exactly stress free at s = 1 and has H = 0; ``"k0"``: b̄0 = k0 ā0 and k_ref = k0.
    ``stretch_law`` maps concentrations to stretches (s(c), e.g. :func:`stretch`); it is needed
    only by :meth:`stretch`.

    Attributes
    ----------
    a0, b0 : (m, 2, 2) rest metric (length²) and rest curvature (length) at s = 1.
    b_mesh : (m, 2, 2) the drawn mesh's second fundamental form (length).
    k_ref : (m,) the per-element reference of H (1/length).
    """

    def __init__(self, model, h0: float, thickness_mode: str = "volume", rest_curvature: str = "mesh",
                 k0: float = 0.0, stretch_law=None):
        if thickness_mode not in THICKNESS_MODES:
            raise ValueError(f"thickness mode must be one of {THICKNESS_MODES}, got {thickness_mode!r}")
        if rest_curvature not in REST_CURVATURES:
            raise ValueError(f"rest_curvature must be one of {REST_CURVATURES}, got {rest_curvature!r}")
        self.model = model
        self.h0 = h0
        self.thickness_mode = thickness_mode
        self.stretch_law = stretch_law
        self.triangles = np.asarray(model.mesh.triangles)
        a0, b_mesh = model.fundamental_forms(model.initial_unknowns())
        self.a0 = np.array(a0, dtype=float)
        self.b_mesh = np.array(b_mesh, dtype=float)
        if rest_curvature == "mesh":
            self.b0 = self.b_mesh
            self.k_ref = mean_curvature(self.a0, self.b_mesh, 0.0)
        else:
            self.b0 = float(k0) * self.a0
            self.k_ref = np.full(len(self.a0), float(k0))

    def stretch(self, c_vertices) -> np.ndarray:
        """s per element from the vertex concentrations: the element mean of c, then the stretch law."""
        if self.stretch_law is None:
            raise ValueError("this growth has no stretch law s(c): give stretch_law to map concentrations")
        c = np.asarray(c_vertices)
        n = self.model.mesh.n_vertices
        if c.shape != (n,):
            raise ValueError(f"c must have one value per vertex, shape ({n},), got {c.shape}")
        return self.stretch_law(element_average(c, self.triangles))

    def rest_state(self, s):
        """The grown targets (a :class:`~femshell.shell.RestState`) for the element stretches ``s`` (m,)."""
        from .shell import RestState        # deferred: femshell.shell loads jax, the functions above do not

        s = np.asarray(s, dtype=float)
        s2 = (s * s)[:, None, None]
        return RestState(target_metric(self.a0, s), s2 * self.b0, target_thickness(self.h0, s, self.thickness_mode))

    def rest_state_derivative(self, s):
        """d(ā, b̄, h̄)/ds of :meth:`rest_state` at the element stretches ``s`` (m,): three arrays
        (m, 2, 2), (m, 2, 2), (m,): 2s ā0, 2s b̄0 and −2 h0/s³ ("volume") or 0 ("uniform")."""
        s = _check_stretch(np.asarray(s, dtype=float), len(self.a0))
        two_s = (2.0 * s)[:, None, None]
        if self.thickness_mode == "volume":
            dh = -2.0 * np.asarray(self.h0, dtype=float) / s**3
        else:
            dh = np.zeros_like(s)
        return two_s * self.a0, two_s * self.b0, np.broadcast_to(dh, s.shape).astype(float)

    def apply(self, s):
        """``model.set_rest_state(rest_state(s))``."""
        self.model.set_rest_state(self.rest_state(s))

    def mean_curvature(self, u):
        """H per element and per vertex (1/length) of the state ``u``, measured from k_ref."""
        a, b = self.model.fundamental_forms(u)
        H = mean_curvature(np.asarray(a), np.asarray(b), self.k_ref)
        return H, element_to_vertex(H, self.model.positions(u), self.triangles)
