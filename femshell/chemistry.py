r"""The mechanogen on the deformed surface: P1 surface finite elements (theory §1.3, §2.7).

    ∂t c = D Δ_Γ c + P(H) − β c,      P(H) = w H / (1 + H/Hs) for H > 0, else 0

Δ_Γ is the Laplace–Beltrami operator of the CURRENT surface, discretised with P1
(piecewise-linear) elements on the same triangles as the shell: the cotangent
stiffness K and the lumped (diagonal) mass M, so that

    M dc/dt = −D K c + M (P − β c).

Units: lengths in cell sizes, time in 1/β, c in the model's
concentration unit; K is dimensionless (cotangent weights), M is length² (vertex
areas), D is length²/time, β is 1/time, w is concentration·length/time, Hs is 1/length.

This module is physics only: it knows triangles and vertex positions, not the shell.
The topology of the surface never changes during a run while the points move every
step, so the sparsity pattern and the COO→CSR scatter are computed once
(:class:`P1Assembler`) and each new geometry costs one vectorised pass.

Example
-------
>>> import numpy as np
>>> from femshell.chemistry import surface_mass_lumped, surface_stiffness
>>> pts = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0]]); tri = np.array([[0, 1, 2]])
>>> surface_mass_lumped(pts, tri)            # one third of the area 1/2 per vertex
array([0.16666667, 0.16666667, 0.16666667])
>>> surface_stiffness(pts, tri).toarray()
array([[ 1. , -0.5, -0.5],
       [-0.5,  0.5,  0. ],
       [-0.5,  0. ,  0.5]])
"""

from __future__ import annotations

import math
import time
import warnings

import numpy as np
import scipy.sparse as sp

from ._checks import finite, flat_or_spatial_surface, real_array, triangle_array, vertex_indices

__all__ = ["P1Assembler", "surface_mass_lumped", "surface_stiffness", "curvature_source", "curvature_source_slope",
           "ReactionDiffusion",
           "W", "HS"]

#: the paper's source: production rate w and saturation curvature Hs, the defaults here and of
#: MechanochemicalModel (femshell.coupled)
W, HS = 15.0, 0.05


def _edges_and_areas(pts, tri):
    """Edge vectors e_k = p_{k+2} − p_{k+1} (opposite local vertex k) and twice the areas."""
    p = pts[tri]                                     # (m, 3 vertices, 3 coords)
    e = p[:, [2, 0, 1]] - p[:, [1, 2, 0]]            # (m, 3, 3)
    twice_area = np.linalg.norm(np.cross(e[:, 1], e[:, 2]), axis=1)
    return e, twice_area


def _check_areas(twice_area, e):
    # a degenerate triangle has no well-defined cotangent: stop with where it is
    scale = np.einsum("mki,mki->m", e, e)            # sum of squared edge lengths
    bad = ~(twice_area > 1e-14 * scale)
    if bad.any():
        f = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{int(bad.sum())} degenerate (zero-area) triangle(s), first triangle {f} "
                         f"(area {twice_area[f] / 2:.3g}); the cotangent Laplacian is undefined there")


class P1Assembler:
    r"""Cached sparsity pattern of the P1 matrices on a fixed triangulation.

    The 9 entries of each triangle's local 3×3 matrix are summed into a CSR matrix
    through a scatter index computed once here (``np.unique`` of the (row, col)
    keys); afterwards :meth:`stiffness` for new points costs one vectorised pass of
    cotangents plus one ``np.bincount`` — no re-sorting, no Python loop.

    Parameters
    ----------
    triangles : (m, 3) int array
    n_vertices : int

    Example
    -------
    >>> asm = P1Assembler(np.array([[0, 1, 2]]), 3)
    >>> K = asm.stiffness(np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0]]))
    >>> float(abs(K @ np.ones(3)).max())      # constants are in the kernel
    0.0
    """

    def __init__(self, triangles, n_vertices: int):
        tri = triangle_array(triangles)
        if isinstance(n_vertices, bool) or not isinstance(n_vertices, (int, np.integer)) or n_vertices < 1:
            raise ValueError(f"n_vertices must be an integer >= 1, got {n_vertices!r}")
        n = int(n_vertices)
        vertex_indices(tri, n, of="vertices (n_vertices)")
        self.triangles = tri.astype(np.int64)
        self.n_vertices = n
        rows = np.repeat(self.triangles, 3, axis=1).ravel()       # (m*9,) local (a, b) -> row tri[a]
        cols = np.tile(self.triangles, (1, 3)).ravel()            # col tri[b]
        keys = rows * n + cols
        uniq, self._scatter = np.unique(keys, return_inverse=True)
        self._scatter = self._scatter.ravel()
        r, c = np.divmod(uniq, n)
        self.indices = c.astype(np.int32)
        self.indptr = np.zeros(n + 1, np.int64)
        np.cumsum(np.bincount(r, minlength=n), out=self.indptr[1:])
        self.indptr = self.indptr.astype(np.int32)
        self.nnz = len(uniq)
        self._vertex_of = self.triangles.ravel()
        self.n_assembled = 0                                      # how many matrices were built

    def local_stiffness(self, points):
        r"""Local 3×3 cotangent matrices (m, 3, 3), dimensionless.

        For the pair (a, b) opposite local vertex k: K_ab = −½ cot θ_k; the diagonal
        is minus the sum of the off-diagonals of its row, so constants are in the
        kernel to round-off. cot θ_k = −(e_{k+1} · e_{k+2}) / (2 A).
        """
        pts, tri = flat_or_spatial_surface(points, self.triangles)
        if len(pts) != self.n_vertices:
            raise ValueError(f"expected {self.n_vertices} points, got {len(pts)}")
        e, twice_area = _edges_and_areas(pts, tri)
        _check_areas(twice_area, e)
        cot = -np.einsum("mki,mki->mk", e[:, [1, 2, 0]], e[:, [2, 0, 1]]) / twice_area[:, None]
        half = 0.5 * cot
        loc = np.empty((len(tri), 3, 3))
        # off-diagonal (a, b) gets −½ cot of the third vertex
        loc[:, 1, 2] = loc[:, 2, 1] = -half[:, 0]
        loc[:, 2, 0] = loc[:, 0, 2] = -half[:, 1]
        loc[:, 0, 1] = loc[:, 1, 0] = -half[:, 2]
        loc[:, 0, 0] = half[:, 1] + half[:, 2]
        loc[:, 1, 1] = half[:, 2] + half[:, 0]
        loc[:, 2, 2] = half[:, 0] + half[:, 1]
        return loc

    def assemble(self, local):
        """Sum local (m, 3, 3) matrices into an (n, n) CSR matrix with the cached pattern."""
        local = np.asarray(local, dtype=float)
        if local.shape != (len(self.triangles), 3, 3):
            raise ValueError(f"local matrices must have shape ({len(self.triangles)}, 3, 3), got {local.shape}")
        data = np.bincount(self._scatter, weights=local.ravel(), minlength=self.nnz)
        self.n_assembled += 1
        return sp.csr_matrix((data, self.indices.copy(), self.indptr.copy()),
                             shape=(self.n_vertices, self.n_vertices))

    def stiffness(self, points):
        r"""P1 Laplace–Beltrami stiffness K_ij = ∫ ∇φ_i · ∇φ_j dA (dimensionless), CSR.

        Off-diagonal K_ij = −½ (cot α_ij + cot β_ij) over the angles opposite edge ij.
        """
        return self.assemble(self.local_stiffness(points))

    def mass_lumped(self, points):
        """Lumped mass: vertex area = ⅓ of the adjacent triangle areas (length²), shape (n,)."""
        pts, tri = flat_or_spatial_surface(points, self.triangles)
        if len(pts) != self.n_vertices:
            raise ValueError(f"expected {self.n_vertices} points, got {len(pts)}")
        e, twice_area = _edges_and_areas(pts, tri)
        return np.bincount(self._vertex_of, weights=np.repeat(twice_area / 6.0, 3), minlength=self.n_vertices)


def surface_mass_lumped(points, triangles):
    r"""Lumped P1 mass: m_i = Σ_{T ∋ i} |T| / 3 (length²), returned as the (n,) diagonal.

    Sums to the area of the triangulated surface.
    """
    pts, tri = flat_or_spatial_surface(points, triangles)
    _, twice_area = _edges_and_areas(pts, tri)
    return np.bincount(tri.ravel(), weights=np.repeat(twice_area / 6.0, 3), minlength=len(pts))


def surface_stiffness(points, triangles):
    r"""P1 Laplace–Beltrami (cotangent) stiffness of a triangulated surface, (n, n) CSR.

    K_ij = −½ (cot α_ij + cot β_ij) for an edge ij, K_ii = −Σ_j K_ij; symmetric,
    positive semi-definite, K 1 = 0. Dimensionless. For repeated assembly on one
    triangulation use :class:`P1Assembler` (the pattern is cached there).
    """
    pts, tri = flat_or_spatial_surface(points, triangles)
    return P1Assembler(tri, len(pts)).stiffness(pts)


def curvature_source(H, w: float = W, Hs: float = HS):
    r"""Production of mechanogen by outward curvature, P(H) = w H / (1 + H/Hs) for H > 0, else 0.

    H is the mean curvature relative to the rest curvature (1/length); P is in
    concentration per time. P saturates at w Hs (0.75 with the defaults) for H ≫ Hs.

    Example
    -------
    >>> curvature_source(np.array([-1.0, 0.0, 0.05, 1e9]))
    array([0.   , 0.   , 0.375, 0.75 ])
    """
    Hs = finite("Hs (saturation curvature)", Hs, 0.0, lo_open=True)
    w = finite("w (production rate)", w, 0.0)
    H = real_array("H", H)
    if np.isnan(H).any():
        raise ValueError(f"H has {int(np.isnan(H).sum())} NaN value(s)")
    Hp = np.maximum(H, 0.0)
    # w Hs · Hp / (Hs + Hp): the same value without overflow for huge H; H = +inf saturates
    with np.errstate(invalid="ignore"):
        ratio = np.where(np.isposinf(Hp), 1.0, Hp / (Hs + Hp))
    return w * Hs * ratio


def curvature_source_slope(H, w: float = W, Hs: float = HS):
    r"""dP/dH of :func:`curvature_source`: w Hs² / (Hs + H)² for H > 0, else 0 (concentration·length/time).

    Example
    -------
    >>> curvature_source_slope(np.array([-1.0, 0.0, 0.05]))
    array([0.  , 0.  , 3.75])
    """
    Hs = finite("Hs (saturation curvature)", Hs, 0.0, lo_open=True)
    w = finite("w (production rate)", w, 0.0)
    H = real_array("H", H)
    Hp = np.maximum(H, 0.0)
    with np.errstate(over="ignore"):
        return np.where(H > 0, w * (Hs / (Hs + Hp)) ** 2, 0.0)


class ReactionDiffusion:
    r"""Time stepper for ∂t c = D Δ_Γ c + P − β c on a moving triangulated surface.

    The source P is held over the step. The degradation is integrated exactly (integrating
    factor e^{βt}) and the diffusion implicitly: from e^{β dt} c⁺ − c = ∫₀^dt e^{βs} ds
    (D Δ_Γ c⁺ + P), with the lumped P1 mass M and cotangent stiffness K of the current
    geometry (−Δ_Γ ≈ M⁻¹ K),

        (M + γ D K) c⁺ = M (c e^{−β dt} + γ P),      γ = (1 − e^{−β dt}) / β   (dt when β = 0).

    D = 0: the vertices decouple and this is the exact update, node by node,

        c⁺ = c e^{−β dt} + γ P;

    no stiffness matrix is assembled (``stiffness`` stays ``None``). D > 0: first order in
    dt in the diffusion only; the steady state (D K + β M) c = M P is exact for any dt, and
    the result is continuous as D → 0. (Implicit Euler, (M (1 + β dt) + dt D K) c⁺ =
    M (c + dt P), damps the degradation by 1/(1 + β dt) instead of e^{−β dt}: from c = 0
    under P = 0.5, three steps of dt = 1/β give 0.4375 against the exact 0.4751.)

    Unconditional stability and c ≥ 0. Let A = M + γ D K. K is symmetric
    positive semi-definite with K 1 = 0, so in the M-inner product the step
    c ↦ A⁻¹ M c e^{−β dt} has eigenvalues e^{−β dt} / (1 + γ D μ_k) ∈ (0, 1] (μ_k ≥ 0 the
    eigenvalues of (K, M)): no growth for any dt > 0. If every edge weight
    ½ (cot α + cot β) is ≥ 0 — true on non-obtuse triangulations and, more generally,
    when each interior edge's opposite angles sum to at most π (Delaunay) and each
    boundary edge's opposite angle is at most π/2 — then A has a positive diagonal,
    non-positive off-diagonal entries and row sums m_i > 0: a strictly
    diagonally dominant Z-matrix, hence a non-singular M-matrix with A⁻¹ ≥ 0
    entrywise. With c ≥ 0 and P ≥ 0 (P(H) ≥ 0 by definition) the right-hand side is
    ≥ 0, so c⁺ = A⁻¹ M (c e^{−β dt} + γ P) ≥ 0, and max c⁺ ≤ max (c e^{−β dt} + γ P)
    (discrete maximum principle). On meshes with negative edge weights (obtuse,
    non-Delaunay triangles) the property can fail: negative values are then set to
    zero, counted in ``n_clipped``, and a ``RuntimeWarning`` is issued once when a
    clipped value exceeds round-off (1e-10 of the maximum).

    The factorisation of A is kept while dt and the geometry are unchanged; when
    either changes, A is refactorised through ``factorize`` with the previous factor
    (a sparse direct solver reuses its symbolic analysis on the same pattern).

    Parameters
    ----------
    triangles : (m, 3) int array
    n_vertices : int
    D : float
        Diffusion coefficient, length²/time (≥ 0).
    beta : float
        Degradation rate, 1/time (≥ 0).
    points : (n, 3) array, optional
        Initial geometry (length); can also be given to :meth:`step`.
    factorize : callable, needed for D > 0
        ``factorize(A, reuse=previous)`` -> a factor with ``solve(b)`` and ``free()`` for the
        symmetric positive definite A (e.g. ``functools.partial(femshell.solvers.linear.factorize,
        kind="spd")``); it raises a RuntimeError (such as ``LinearSolverError``) when A is singular.
    nonnegative : bool
        Clip negative values (default). ``False`` for signed fields (the operator is
        linear; e.g. the spherical-harmonic validation), where nothing is clipped.

    Attributes
    ----------
    stiffness : CSR matrix or None
        K of the current geometry, ``None`` until a step with D > 0 needs it.
    mass : (n,) array or None
        Lumped mass of the current geometry (length²), ``None`` until needed.
    n_clipped : int
        How many negative values were set to zero so far.
    n_negative_weights : int
        Edges with negative cotangent weight in the last assembled geometry.

    Example
    -------
    A uniform H = 0.02 on a sphere: P = w H/(1 + H/Hs) = 0.2143 everywhere, so after one step
    c = (P/β)(1 − e^(−β dt)) = 0.02039 at every vertex (the degradation integrated exactly).

    >>> from femshell.mesh.generators import sphere
    >>> mesh = sphere(radius=30.0, n_vertices=200)
    >>> from femshell.solvers.linear import factorize
    >>> rd = ReactionDiffusion(mesh.triangles, mesh.n_vertices, D=0.4, points=mesh.points, factorize=factorize)
    >>> H = np.full(mesh.n_vertices, 0.02)          # mean curvature relative to the rest shape (1/length)
    >>> c = rd.step(np.zeros(mesh.n_vertices), dt=0.1, source=curvature_source(H))
    >>> round(float(c.min()), 5), round(float(c.max()), 5)
    (0.02039, 0.02039)
    """

    def __init__(self, triangles, n_vertices: int, D: float = 0.0, beta: float = 1.0, points=None,
                 factorize=None, nonnegative: bool = True):
        if factorize is not None and not callable(factorize):
            raise TypeError(f"factorize must be a callable factorize(A, reuse=...), got {type(factorize).__name__}")
        self._factor = None
        self._factor_dt = None
        self.D = D
        self.beta = beta
        self.factorize = factorize
        self.nonnegative = bool(nonnegative)
        self.assembler = P1Assembler(triangles, n_vertices)
        self.n_vertices = self.assembler.n_vertices
        self.stiffness = None
        self.mass = None
        self.n_clipped = 0
        self.n_negative_weights = 0
        self.n_steps = 0
        self.solve_time = 0.0
        self._points = None
        self._warned = False
        if points is not None:
            self.set_geometry(points)

    @property
    def D(self) -> float:
        """Diffusion coefficient, length²/time; setting it refactorises at the next step."""
        return self._D

    @D.setter
    def D(self, value):
        self._D = finite("diffusion coefficient D", value, 0.0)
        self._factor_dt = None

    @property
    def beta(self) -> float:
        """Degradation rate, 1/time; setting it refactorises at the next step."""
        return self._beta

    @beta.setter
    def beta(self, value):
        self._beta = finite("degradation rate beta", value, 0.0)
        self._factor_dt = None

    def set_geometry(self, points):
        """Move to a new surface geometry (same triangles); K, M and the factor are updated lazily."""
        pts = np.array(points, dtype=float)
        if pts.shape != (self.n_vertices, 3):
            raise ValueError(f"points must have shape ({self.n_vertices}, 3), got {pts.shape}")
        if self._points is not None and np.array_equal(pts, self._points):
            return
        self._points = pts
        self.stiffness = None
        self.mass = None
        self._factor_dt = None          # the factor (if any) is stale; its pattern stays valid

    def _ensure_matrices(self):
        if self._points is None:
            raise ValueError("no geometry: pass points to the constructor, set_geometry() or step()")
        if self.mass is None:
            self.mass = self.assembler.mass_lumped(self._points)
        if self.stiffness is None:
            K = self.assembler.stiffness(self._points)
            # off-diagonal K_ij = −(edge weight): count edges that break the M-matrix property
            rows = np.repeat(np.arange(self.n_vertices), np.diff(K.indptr))
            off = K.indices != rows
            self.n_negative_weights = int((K.data[off] > 1e-14 * np.abs(K.data).max()).sum() // 2)
            self.stiffness = K

    def step(self, c, dt: float, source=0.0, points=None):
        r"""Advance c by one step of length dt (time unit 1/β); returns the new c (n,).

        Parameters
        ----------
        c : (n,) array
            Concentration at the vertices (≥ 0).
        dt : float
            Time step (> 0).
        source : float or (n,) array
            P at the vertices, concentration/time, held constant over the step
            (e.g. ``curvature_source(H_vertices)``).
        points : (n, 3) array, optional
            The current geometry; omitted: the last one given.
        """
        dt = finite("time step dt", dt, 0.0, lo_open=True)
        c = real_array("c", c)
        if c.shape != (self.n_vertices,):
            raise ValueError(f"c must have shape ({self.n_vertices},), got {c.shape}")
        P = real_array("source", source)
        if P.ndim and P.shape != c.shape:
            raise ValueError(f"source must be a number or one value per vertex, shape ({self.n_vertices},), "
                             f"got shape {P.shape}")
        P = np.broadcast_to(P, c.shape)
        if not (np.all(np.isfinite(c)) and np.all(np.isfinite(P))):
            raise ValueError("c and source must be finite")
        if self.nonnegative and c.min() < 0:
            # the clip keeps every step's output >= 0; a negative input is the caller's, not the mesh's
            raise ValueError(f"c must be >= 0 (nonnegative=True), got min {c.min():.3g} at vertex {int(c.argmin())}")
        if self.nonnegative and P.min() < 0:
            # a sink would be cut off by the clip, not integrated: say so rather than blame the mesh
            raise ValueError(f"source must be >= 0 with nonnegative=True (c >= 0 holds only for a non-negative "
                             f"source), got min {P.min():.3g}; pass nonnegative=False for a signed field")
        if points is not None:
            self.set_geometry(points)
        t0 = time.perf_counter()
        decay = np.exp(-self.beta * dt)
        # γ = (1 − e^{−β dt}) / β without cancellation for small β dt; dt when β = 0
        gain = -np.expm1(-self.beta * dt) / self.beta if self.beta > 0 else dt
        with np.errstate(over="ignore"):   # an overflow is named below
            reacted = c * decay + P * gain
        if self.D == 0.0:
            out = reacted
        else:
            self._ensure_matrices()
            if self._factor is None or self._factor_dt != dt:
                if self.factorize is None:
                    raise ValueError("a step with D > 0 solves (M + gamma D K) c = b: give ReactionDiffusion a "
                                     "factorize callable (e.g. femshell.solvers.linear.factorize)")
                A = (sp.diags(self.mass) + (gain * self.D) * self.stiffness).tocsr()
                self._factor_dt = None          # until the new factorisation is complete (an interrupt in it)
                try:
                    self._factor = self.factorize(A, reuse=self._factor)
                except RuntimeError:
                    # the mass term is lost to round-off next to γ·D·K, whose null space is the constants
                    self._factor = None
                    # how far diffusion reaches in the step against the surface's own size
                    size = math.sqrt(float(self.mass.sum()))
                    reach = math.sqrt(dt * self.D) / size if size > 0 else math.inf
                    raise ValueError(f"the step dt = {dt:.6g} is too long for D = {self.D:g}, beta = {self.beta:g}: "
                                     "M + gamma D K is singular in double precision (diffusion "
                                     f"spreads over sqrt(D dt) = {reach:.3g} times the surface's size, sqrt(area), "
                                     "in one step); take a smaller dt or a smaller D: a D whose sqrt(D dt) is "
                                     "already many times the surface's size gives the same, well-mixed, "
                                     "concentration") from None
                self._factor_dt = dt
            out = self._factor.solve(self.mass * reacted) if np.all(np.isfinite(reacted)) else reacted
        if not np.all(np.isfinite(out)):   # e.g. β = 0 and dt·P past the float range
            raise ValueError(f"the step dt = {dt:.6g} overflows c (c + γ·P is past the float range): "
                             "take a smaller dt")
        if self.nonnegative:
            out = self._clip(out)
        self.solve_time += time.perf_counter() - t0
        self.n_steps += 1
        return out

    def _clip(self, c):
        neg = c < 0
        if neg.any():
            k = int(neg.sum())
            worst = float(c[neg].min())
            self.n_clipped += k
            scale = max(float(np.abs(c).max()), 1e-300)
            if worst < -1e-10 * scale and not self._warned:
                self._warned = True
                warnings.warn(f"reaction-diffusion step produced {k} negative value(s) (min {worst:.3g}, "
                              f"max |c| {scale:.3g}), set to zero; the mesh has {self.n_negative_weights} "
                              f"edge(s) with negative cotangent weight (obtuse, non-Delaunay triangles)",
                              RuntimeWarning, stacklevel=3)
            c = np.where(neg, 0.0, c)
        return c

    def free(self):
        """Release the factorisation (PARDISO memory) now."""
        if self._factor is not None:
            self._factor.free()
            self._factor = None
            self._factor_dt = None
