"""Linear buckling of flat plates: an independent planar reference built on scikit-fem.

This module is deliberately separate from femshell's own shell code (design.md 1.2):
it solves the classical two-step linear theory of a flat plate with scikit-fem's
elements, so that the nonlinear shell solver can be checked against it.

1. **Prestress** (:func:`membrane_prestress`): plane-stress linear elasticity with an
   isotropic eigenstrain ``g`` per triangle (the linearisation of the grown target metric
   ``(1 + g)^2 a0`` of design.md 1.1 is ``a0 + 2 g a0``, i.e. the strain ``g I``),
   P2 (default) or P1 Lagrange displacements. Returns the membrane force per triangle
   ``N = t sigma`` with ``sigma = C (eps(u) - g I)``; compression is negative.
2. **Buckling** (:func:`buckling_loads`): Kirchhoff plate with the Morley element,
   ``K_b w = mu K_g w`` with ``K_b = ∫ D [(1-nu) w_,ab v_,ab + nu Δw Δv]``,
   ``D = E t^3 / (12 (1 - nu^2))`` per triangle, and ``K_g = -∫ N_ab w_,a v_,b`` (the
   minus sign makes compression give ``mu > 0``). ``mu`` is the factor by which the
   prestress must be multiplied to buckle the plate: for a prestress caused by growth
   ``g`` the critical growth strain of the linear theory is ``mu * g``.
3. **Mode analysis** (:func:`azimuthal_wavenumber`, :func:`mode_wavenumber`): Fourier
   analysis of a mode sampled on circles, giving the number of azimuthal wrinkles.
4. **The disk test of design.md 1.6** (:func:`critical_growth_strain`: the critical
   growth strain of a disk grown inside r < R2; :func:`critical_inner_radius`: the
   smallest R2 at which a given growth buckles, for the first mode or for a given n).

Units: lengths in the cell size, E = 1 by default (design.md 3); ``mu`` is dimensionless,
``N`` has units of E times length.

Boundary conditions of the bending problem
------------------------------------------
``"clamped"``: w and the normal slope (the Morley edge dofs ``u_n``) vanish on the boundary.
``"simply_supported"``: w vanishes at the boundary vertices only. (Checked: on a polygonal
approximation of a circle the Morley element converges to the simply supported
circle, not to the Babuška-paradox limit Δw = 0; see the validation case.)
``"free"``: the bending stiffness has the three rigid modes ``w = a + b x + c y``. For a
free body whose prestress is self-equilibrated (div N = 0, N n = 0 on the edge, which is
what :func:`membrane_prestress` produces with ``boundary="free"``), ``∫ N dA = 0``; so
the rigid modes are in the null space of K_g as well as of K_b (K_g(r, v) =
-∫ N_ab r_,a v_,b = -r_,a ∫ N_ab v_,b = 0 after integrating by parts). The pencil is then
singular on the rigid modes and regular on any complement, with the same eigenvalues on
every complement. We take the complement {w : w(p_i) = 0 at three well-spread
non-collinear vertices p_i} (pinning), which makes K_b positive definite, and remove the
rigid part of each returned mode by an L2 projection. In the discrete setting K_g r is
only approximately zero (the P2 prestress is equilibrated in the P2 weak sense, the
Morley functions are nonconforming), so the eigenvalues depend slightly on the pinned
vertices: :attr:`BucklingResult.info` reports the relative coupling (``rigid_leak``), the
order of that dependence, not a bound. Measured on the free disk R1 = 10, R2 = 2 (h = 2,
nu = 0.5, first three modes): 3.8e-3, 2.0e-3, 1.0e-3 at 328, 542, 1 101 vertices, falling with
the mesh size; randomly chosen pinned rim vertices moved mu by up to 1 % at 542 vertices
(about five times the leak; as much as the mesh error there), interior ones by more. A
non-equilibrated N with a free edge would be meaningless.

Eigen solver
------------
K_g is indefinite (tension and compression), so it cannot be the B matrix of an ARPACK
generalised problem. We solve the equivalent problem ``K_g w = lambda K_b w``,
``lambda = 1 / mu``, with ``scipy.sparse.linalg.eigsh(K_g, M=K_b, Minv=K_b^{-1},
which="LA")``: the Krylov operator is ``K_b^{-1} K_g``, exactly the shift-invert operator
of the original pencil about ``mu = 0``, and asking for the largest algebraic lambda
returns the smallest positive mu only, so negative mu (buckling under the reversed load)
never crowd the positive ones out. The inner solver for ``K_b^{-1}`` is chosen with
``solver=`` (``"splu"``, ``"pardiso"``, ``"pyamg"``); timings are in
:attr:`BucklingResult.timings`. Measured on the clamped disk (k = 8 + 4 extra, ~52-59
solves; 2 cores shared with other jobs, load 8-10, so absolute times are inflated):

==========  ========  ======================  ===========================  ======================
vertices    dofs      splu setup / eigsh      pardiso setup / eigsh        pyamg SA + FGMRES
==========  ========  ======================  ===========================  ======================
2 000       7 865     0.02 s / 0.06 s         0.36 s / 0.09 s              0.06 s / 8.5 s (80 it/solve)
30 000      119 445   2.1 s / 7.8 s           2.2 s / 20.7 s               --
60 000      239 272   5.3 s / 9.5 s           3.7 s / 41.8 s               --
==========  ========  ======================  ===========================  ======================

splu (SuperLU, MMD_AT_PLUS_A, symmetric mode) is the default: the Morley K_b is
scalar with ~4 unknowns per vertex, so its factorisation is cheap, and its triangular
solves beat PARDISO's (whose solve phase suffers from MKL threads on a shared machine:
set MKL_NUM_THREADS=1). pyamg is not an option for this fourth-order operator: CG
stagnated (FGMRES needed), 80 iterations per solve at 2 000 vertices and over 800 s in
all at 3 200.

Example
-------
>>> import numpy as np
>>> from skfem import MeshTri
>>> m = MeshTri.init_circle(4)                   # unit disk
>>> p, t = m.p.T, m.t.T
>>> N = membrane_prestress(p, t, growth_strain=1e-3, nu=0.3, thickness=0.1, boundary="clamped")
>>> res = buckling_loads(p, t, N, nu=0.3, thickness=0.1, bc="clamped", k=3)
>>> gc = res.mu[0] * 1e-3                        # critical growth strain
>>> round(float(gc * 12 * 1.3 / 0.1**2), 1)     # k^2 = 14.682 for the clamped disk
14.7
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ._checks import integer
from .solvers.linear import available_backends, factorize

__all__ = ["membrane_prestress", "buckling_loads", "BucklingResult", "azimuthal_wavenumber",
           "mode_wavenumber", "critical_growth_strain", "CriticalGrowth", "critical_inner_radius",
           "CriticalRadius", "bending_stiffness"]


# ----------------------------------------------------------------------------- helpers

def bending_stiffness(E, nu, thickness):
    """Plate bending stiffness D = E t^3 / (12 (1 - nu^2)) (units of E times length^3)."""
    return np.asarray(E, float) * np.asarray(thickness, float) ** 3 / (12.0 * (1.0 - nu ** 2))


def _mesh2d(points2d, triangles):
    """A scikit-fem MeshTri from (n, 2|3) points and (m, 3) triangles, triangles made counter-clockwise.

    Element order is preserved, so per-triangle arrays stay aligned with ``triangles``.
    """
    from skfem import MeshTri

    p = np.asarray(points2d, float)
    if p.ndim != 2 or p.shape[1] not in (2, 3):
        raise ValueError(f"points2d must have shape (n, 2) or (n, 3), got {p.shape}")
    if p.shape[1] == 3:
        if np.ptp(p[:, 2]) > 1e-9 * max(np.ptp(p[:, :2], axis=0).max(), 1e-300):
            raise ValueError("points are not in a plane z = const; this module treats flat plates only")
        p = p[:, :2]
    t = np.array(triangles, dtype=np.int64).reshape(-1, 3)
    e1 = p[t[:, 1]] - p[t[:, 0]]
    e2 = p[t[:, 2]] - p[t[:, 0]]
    area2 = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    if np.any(area2 == 0):
        raise ValueError(f"triangle {int(np.flatnonzero(area2 == 0)[0])} has zero area")
    cw = area2 < 0
    t[cw] = t[cw][:, [0, 2, 1]]
    return MeshTri(np.ascontiguousarray(p.T), np.ascontiguousarray(t.T))


def _per_triangle(value, m, name, positive=False):
    """Broadcast a scalar or a per-triangle array to shape (m,); finite (and > 0 if ``positive``)."""
    try:
        a = np.asarray(value, float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number or one number per triangle, got {value!r}") from None
    a = np.full(m, float(a)) if a.ndim == 0 else a.reshape(-1)
    if a.shape != (m,):
        raise ValueError(f"{name} must be a scalar or have one value per triangle ({m}), got shape {a.shape}")
    bad = ~np.isfinite(a) | ((a <= 0) if positive else False)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{name} must be finite{' and > 0' if positive else ''}, got {a[i]:g} at triangle {i}")
    return a


def _poisson(nu) -> float:
    """Poisson's ratio of a plate, in (-1, 0.5]."""
    try:
        v = float(nu)
    except (TypeError, ValueError):
        v = math.nan
    if not -1.0 < v <= 0.5:
        raise ValueError(f"nu must be in (-1, 0.5], got {nu!r}")
    return v


def _at_quadrature(values, basis):
    """Per-element values (m,) as a field on the quadrature points of ``basis``, shape (m, nqp)."""
    return np.repeat(values[:, None], basis.X.shape[1], axis=1)


def _boundary_facets(mesh, vertices):
    """Boundary facets of a skfem mesh; with ``vertices`` only those with both ends in that set."""
    bf = mesh.boundary_facets()
    if vertices is None:
        return bf
    vs = np.zeros(mesh.p.shape[1], bool)
    vs[np.asarray(vertices, np.int64).ravel()] = True
    return bf[vs[mesh.facets[0, bf]] & vs[mesh.facets[1, bf]]]


def _spread_vertices(points, candidates):
    """Three well-spread, non-collinear vertices among ``candidates`` (indices into points)."""
    c = np.asarray(candidates, np.int64)
    x = points[c]
    centre = x.mean(0)
    i0 = int(np.argmax(np.sum((x - centre) ** 2, 1)))
    i1 = int(np.argmax(np.sum((x - x[i0]) ** 2, 1)))
    d1 = x[i1] - x[i0]
    area = np.abs(d1[0] * (x[:, 1] - x[i0, 1]) - d1[1] * (x[:, 0] - x[i0, 0]))
    i2 = int(np.argmax(area))
    if area[i2] <= 1e-12 * np.sum(d1 ** 2):
        raise ValueError("cannot find three non-collinear vertices to pin the rigid modes")
    return c[[i0, i1, i2]]


# ----------------------------------------------------------------------------- inner solvers

class _InverseOperator:
    """``K^{-1}`` for an SPD sparse K by one of several back-ends, with setup and solve timings."""

    def __init__(self, K, solver="splu", rtol=1e-10, maxiter=300):
        self.K = K = sp.csr_matrix(K)
        self.solver = solver
        self.n_solves = 0
        self.solve_s = 0.0
        self.iterations = 0
        t0 = time.perf_counter()
        if solver == "splu":
            lu = spla.splu(sp.csc_matrix(K), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                           options={"SymmetricMode": True})
            self._solve = lu.solve
        elif solver == "pardiso":
            self._fac = factorize(K, kind="spd", backend="pardiso")
            self._solve = self._fac.solve
        elif solver == "pyamg":
            import pyamg

            ml = pyamg.smoothed_aggregation_solver(K, symmetry="symmetric", max_coarse=500)
            M = ml.aspreconditioner(cycle="V")

            def solve(b):
                res = []
                # FGMRES, not CG: with CG some right-hand sides that ARPACK produces stagnated
                # at a residual of 1e-5 (measured on the Morley plate matrix)
                x = ml.solve(b, tol=rtol, accel="fgmres", maxiter=maxiter, residuals=res)
                self.iterations += len(res)
                if not res or res[-1] > rtol * max(res[0], 1e-300) * 10:
                    raise RuntimeError(f"pyamg-preconditioned FGMRES did not reach {rtol:g} in {maxiter} "
                                       f"iterations (residual ratio {res[-1] / res[0]:.1e}); "
                                       "use solver='splu' or 'pardiso'")
                return x

            self._ml, self._M = ml, M
            self._solve = solve
        else:
            raise ValueError(f"unknown solver '{solver}' (splu, pardiso, pyamg)")
        self.setup_s = time.perf_counter() - t0

    def __call__(self, b):
        t0 = time.perf_counter()
        x = self._solve(np.asarray(b, float).ravel())
        self.solve_s += time.perf_counter() - t0
        self.n_solves += 1
        return x

    def operator(self):
        n = self.K.shape[0]
        return spla.LinearOperator((n, n), matvec=self, dtype=float)


# ----------------------------------------------------------------------------- prestress

def membrane_prestress(points2d, triangles, growth_strain, E=1.0, nu=0.3, thickness=1.0,
                       boundary="clamped", order=2, return_displacement=False, solver="auto"):
    """Membrane forces of a flat sheet with an isotropic eigenstrain (plane stress, linear).

    Parameters
    ----------
    points2d : (n, 2) or (n, 3) array
        Vertex coordinates of a flat mesh (z ignored if constant).
    triangles : (m, 3) int array
    growth_strain : float or (m,) array
        Isotropic eigenstrain g per triangle (piecewise constant): the stress-free strain
        is ``g I`` (linearised growth: target metric (1+g)^2 a0 ≈ (1 + 2g) a0).
    E, nu : float
        Young's modulus (scalar or per triangle) and Poisson ratio.
    thickness : float or (m,) array
        Thickness t per triangle; N = t sigma.
    boundary : "clamped", "free" or int array
        ``"clamped"``: u = 0 on the whole boundary; an int array: u = 0 on the boundary
        edges whose two vertices are in that vertex set (e.g.
        ``mesh.topology.boundary_vertex_groups["outer"]``), the rest of the edge is free;
        ``"free"``: no support; three dofs are pinned to stop the in-plane rigid modes
        (the eigenstrain load is self-equilibrated, so the stress does not depend on which).
    order : 1 or 2
        Lagrange degree of the displacement (P2 is the default: a piecewise constant
        eigenstrain jump is then resolved one order better at the same mesh).
    return_displacement : bool
        Also return ``(u, basis)`` (skfem vector basis and its dof vector).
    solver : "auto", "splu", "pardiso" or "pyamg"
        Linear solver for the stiffness matrix (SPD after the constraints). "auto":
        pardiso above 50 000 unknowns if pypardiso imports (measured 2-4x faster than
        splu on the P2 system at 30k-60k vertices: 14 s against 61 s in total at 60k),
        splu below (no MKL start-up cost).

    Returns
    -------
    N : (m, 3) array
        ``(N_xx, N_yy, N_xy)`` per triangle (area average over the triangle; with P2 the
        stress is linear inside a triangle), compression negative.
    """
    from skfem import Basis, BilinearForm, ElementTriP1, ElementTriP2, ElementVector, LinearForm
    from skfem.helpers import ddot, div, sym_grad, trace

    mesh = _mesh2d(points2d, triangles)
    m = mesh.t.shape[1]
    g = _per_triangle(growth_strain, m, "growth_strain")
    t = _per_triangle(thickness, m, "thickness", positive=True)
    Ee = _per_triangle(E, m, "E", positive=True)
    nu = _poisson(nu)
    if order not in (1, 2):
        raise ValueError("order must be 1 or 2")
    elem = ElementVector(ElementTriP2() if order == 2 else ElementTriP1())
    basis = Basis(mesh, elem)
    lam_ = nu / (1.0 - nu ** 2)   # plane stress: sigma = E/(1-nu^2) [(1-nu) eps + nu tr(eps) I]
    mu2_ = 1.0 / (1.0 + nu)       # 2 G / E

    @BilinearForm
    def stiffness(u, v, w):
        eu, ev = sym_grad(u), sym_grad(v)
        return w.tE * (lam_ * trace(eu) * trace(ev) + mu2_ * ddot(eu, ev))

    @LinearForm
    def load(v, w):   # ∫ t C(g I) : eps(v) = ∫ t E g / (1 - nu) div v
        return w.tEg / (1.0 - nu) * div(v)

    tE = _at_quadrature(t * Ee, basis)
    K = stiffness.assemble(basis, tE=tE)
    f = load.assemble(basis, tEg=_at_quadrature(t * Ee * g, basis))

    if isinstance(boundary, str) and boundary == "free":
        # the eigenstrain load is self-equilibrated (f . r = 0 for every rigid mode r), so
        # pinning any 3 dofs that stop the rigid motions leaves the stress unchanged: u at
        # vertex A, and at B (the vertex farthest from A) the component that a rotation
        # about A moves most. (Lagrange multipliers with the rigid modes would couple
        # every dof to three dense rows and ruin the sparse factorisation.)
        pts = mesh.p.T
        a = int(np.argmax(np.sum((pts - pts.mean(0)) ** 2, 1)))
        b = int(np.argmax(np.sum((pts - pts[a]) ** 2, 1)))
        d = pts[b] - pts[a]
        fixed = np.array([basis.nodal_dofs[0, a], basis.nodal_dofs[1, a],
                          basis.nodal_dofs[1, b] if abs(d[0]) >= abs(d[1]) else basis.nodal_dofs[0, b]])
    else:
        if isinstance(boundary, str):
            if boundary != "clamped":
                raise ValueError(f"boundary must be 'clamped', 'free' or a vertex index array, got '{boundary}'")
            facets = _boundary_facets(mesh, None)
        else:
            facets = _boundary_facets(mesh, boundary)
        fixed = basis.get_dofs(facets).all()
        if len(fixed) == 0:
            raise ValueError("no boundary edge is clamped; use boundary='free'")
    free = basis.complement_dofs(fixed)
    u = np.zeros(K.shape[0])
    if solver == "auto":
        solver = "pardiso" if len(free) > 50_000 and "pardiso" in available_backends() else "splu"
    u[free] = _InverseOperator(K[free][:, free], solver)(f[free])

    N = _membrane_forces(basis, u, t, Ee, g, nu)
    if return_displacement:
        return N, (u, basis)
    return N


def _membrane_forces(basis, u, t, E, g, nu):
    from skfem.helpers import sym_grad

    eps = sym_grad(basis.interpolate(u))           # (2, 2, m, nqp)
    exx = eps[0, 0] - g[:, None]
    eyy = eps[1, 1] - g[:, None]
    exy = eps[0, 1]
    c = (E * t)[:, None] / (1.0 - nu ** 2)
    Nxx = c * (exx + nu * eyy)
    Nyy = c * (eyy + nu * exx)
    Nxy = c * (1.0 - nu) * exy
    wq = basis.dx / basis.dx.sum(1, keepdims=True)
    return np.column_stack([(Nxx * wq).sum(1), (Nyy * wq).sum(1), (Nxy * wq).sum(1)])


# ----------------------------------------------------------------------------- buckling

@dataclass
class BucklingResult:
    """Smallest positive load factors and modes of ``K_b w = mu K_g(N) w``.

    ``mu`` (k,) ascending; ``modes`` (n_dofs, k) Morley dof vectors (vertex values ``u``
    and edge normal slopes ``u_n``), normalised to max |w| = 1 at the vertices, rigid
    part removed for a free plate; ``basis`` the skfem Morley basis; ``timings`` in
    seconds (assembly, factorisation/setup, eigen solve); ``info`` diagnostics.
    """

    mu: np.ndarray
    modes: np.ndarray
    basis: object
    bc: str
    timings: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)

    def values_at(self, points2d, which=None):
        """Mode values w at points (p, 2): array (p, k) (or (p,) for one mode index ``which``)."""
        x = np.asarray(points2d, float)[:, :2].T
        P = self.basis.probes(x).tocsr()
        out = P @ (self.modes if which is None else self.modes[:, which])
        return out


def buckling_loads(points2d, triangles, N, E=1.0, nu=0.3, thickness=1.0, D=None, bc="clamped",
                   k=6, supported_vertices=None, solver="splu", extra=4):
    """Smallest positive linear buckling load factors of a flat plate with prestress N.

    Solves ``K_b w = mu K_g w`` with the Morley element (see the module docstring).

    Parameters
    ----------
    points2d, triangles : the plate mesh (the same one the prestress was computed on).
    N : (m, 3) array or length-3 sequence
        Membrane forces ``(N_xx, N_yy, N_xy)`` per triangle (or one uniform value),
        compression negative (as returned by :func:`membrane_prestress`).
    E, nu, thickness : material and thickness per triangle, giving
        ``D = E t^3 / (12 (1 - nu^2))``; or give ``D`` (scalar or per triangle) directly.
    bc : "clamped", "simply_supported" or "free"
        Bending support of the boundary (all of it, or only the boundary edges with both
        vertices in ``supported_vertices``, the rest free).
    k : int
        Number of positive load factors wanted.
    solver : "splu", "pardiso" or "pyamg"
        Inner solver for ``K_b^{-1}`` (splu measured fastest, see the module docstring).
    extra : int
        Extra eigenpairs computed beyond k (ARPACK converges better; also guards against
        losing one of a nearly double pair).

    Returns
    -------
    BucklingResult. Fewer than k values if the prestress has fewer compressive modes.
    """
    from skfem import Basis, BilinearForm, ElementTriMorley
    from skfem.helpers import dd, ddot, trace

    timings = {}
    t0 = time.perf_counter()
    mesh = _mesh2d(points2d, triangles)
    m = mesh.t.shape[1]
    basis = Basis(mesh, ElementTriMorley())
    nu = _poisson(nu)
    k, extra = integer("k", k, 1), integer("extra", extra, 0)
    if D is None:
        Dm = bending_stiffness(_per_triangle(E, m, "E", positive=True),
                               nu, _per_triangle(thickness, m, "thickness", positive=True))
    else:
        Dm = _per_triangle(D, m, "D", positive=True)
    Nm = np.asarray(N, float)
    if Nm.shape == (3,):
        Nm = np.tile(Nm, (m, 1))
    if Nm.shape != (m, 3):
        raise ValueError(f"N must have shape ({m}, 3) or (3,), got {Nm.shape}")
    if not np.all(np.isfinite(Nm)):
        raise ValueError(f"N holds NaN or infinity in {int((~np.isfinite(Nm)).any(axis=1).sum())} triangles")
    if supported_vertices is not None:
        sv = np.asarray(supported_vertices).ravel()
        if sv.size and (sv.dtype.kind not in "iu" or sv.min() < 0 or sv.max() >= mesh.p.shape[1]):
            raise ValueError(f"supported_vertices must be vertex indices in [0, {mesh.p.shape[1] - 1}]")

    if _no_compression(Nm, Dm.min(), np.ptp(mesh.p, axis=1).max()):
        # K_g is negative semidefinite (or compressive only at round-off level): no positive mu exists
        # (ARPACK would crawl towards the dense cluster of lambda = 1/mu near 0- instead)
        return BucklingResult(mu=np.zeros(0), modes=np.zeros((basis.N, 0)), basis=basis, bc=bc,
                              timings={"total_s": time.perf_counter() - t0},
                              info={"n_dofs": basis.N, "n_vertices": mesh.p.shape[1], "n_triangles": m,
                                    "no_compression": True})

    @BilinearForm
    def bending(u, v, w):
        return w.D * ((1.0 - nu) * ddot(dd(u), dd(v)) + nu * trace(dd(u)) * trace(dd(v)))

    @BilinearForm
    def geometric(u, v, w):   # -∫ N_ab u_,a v_,b : compression gives a positive form
        gu, gv = u.grad, v.grad
        return -(w.Nxx * gu[0] * gv[0] + w.Nyy * gu[1] * gv[1]
                 + w.Nxy * (gu[0] * gv[1] + gu[1] * gv[0]))

    Kb = bending.assemble(basis, D=_at_quadrature(Dm, basis))
    Kg = geometric.assemble(basis, Nxx=_at_quadrature(Nm[:, 0], basis),
                            Nyy=_at_quadrature(Nm[:, 1], basis), Nxy=_at_quadrature(Nm[:, 2], basis))
    timings["assemble_s"] = time.perf_counter() - t0

    info = {"n_dofs": basis.N, "n_vertices": mesh.p.shape[1], "n_triangles": m}
    if bc in ("clamped", "simply_supported"):
        facets = _boundary_facets(mesh, supported_vertices)
        dofs = basis.get_dofs(facets)
        fixed = dofs.all() if bc == "clamped" else dofs.all("u")
        if len(fixed) == 0:
            raise ValueError("no supported boundary edge; use bc='free'")
        if supported_vertices is not None and len(fixed) < 3:
            raise ValueError("too few supported dofs to prevent rigid motion")
        if bc == "simply_supported":
            try:
                _spread_vertices(mesh.p.T, np.unique(mesh.facets[:, facets]))
            except ValueError:
                raise ValueError("the simply supported vertices all lie on one straight line: the plate could "
                                 "rotate about it (singular bending stiffness, spurious mu ~ 0); support another "
                                 "edge too, or clamp this one") from None
    elif bc == "free":
        pin = _spread_vertices(mesh.p.T, np.unique(mesh.facets[:, mesh.boundary_facets()]))
        fixed = basis.nodal_dofs[0, pin]
        info["pinned_vertices"] = pin
    else:
        raise ValueError(f"bc must be 'clamped', 'simply_supported' or 'free', got '{bc}'")
    free = basis.complement_dofs(fixed)
    Kbf = Kb[free][:, free].tocsr()
    Kgf = Kg[free][:, free].tocsr()

    inv = _InverseOperator(Kbf, solver)
    timings["setup_s"] = inv.setup_s
    t1 = time.perf_counter()
    n_free = Kbf.shape[0]
    nev = min(k + extra, n_free - 2)
    ncv = min(n_free - 1, max(2 * nev + 1, 20))
    v0 = np.random.default_rng(12345).standard_normal(n_free)   # reproducible ARPACK start
    try:
        lam, X = spla.eigsh(Kgf, k=nev, M=Kbf, Minv=inv.operator(), which="LA", ncv=ncv, tol=1e-10, v0=v0)
    except spla.ArpackNoConvergence as exc:
        n_min = _smallest_principal(Nm)
        raise RuntimeError(f"the eigen solver (ARPACK) found {len(exc.eigenvalues)} of {nev} buckling modes before "
                           f"its iteration limit: the largest compression ({-n_min.min():.3g}) is "
                           f"{-n_min.min() / np.abs(Nm).max():.3g} of the largest membrane force, so the positive "
                           "eigenvalues 1/mu drown in the tension's; if so small a compression is meant, ask for "
                           "fewer modes (k, extra)") from None
    timings["eigsh_s"] = time.perf_counter() - t1
    timings["inner_solve_s"] = inv.solve_s
    info.update(solver=solver, inner_solves=inv.n_solves, inner_iterations=inv.iterations)

    order = np.argsort(-lam)
    lam, X = lam[order], X[:, order]
    pos = lam > 1e-12 * max(np.abs(lam).max(), 1e-300)
    lam, X = lam[pos][:k], X[:, pos][:, :k]
    mu = 1.0 / lam
    modes = np.zeros((basis.N, len(mu)))
    modes[free] = X
    if bc == "free":
        modes, leak = _remove_rigid(basis, modes, Kg)
        info["rigid_leak"] = leak
    vmax = np.abs(modes[basis.nodal_dofs[0]]).max(0)
    modes /= np.where(vmax > 0, vmax, 1.0)
    timings["total_s"] = time.perf_counter() - t0
    return BucklingResult(mu=mu, modes=modes, basis=basis, bc=bc, timings=timings, info=info)


def _smallest_principal(N):
    """The smaller principal membrane force of each triangle (negative: compressive)."""
    return 0.5 * (N[:, 0] + N[:, 1]) - np.sqrt(0.25 * (N[:, 0] - N[:, 1]) ** 2 + N[:, 2] ** 2)


def _no_compression(N, D_min, diameter):
    """True if no triangle is compressed beyond round-off, i.e. no buckling factor below ~1e12.

    Round-off: below 1e-14 of the largest |N| (a free body's self-equilibrated prestress of a
    uniform growth is 1e-17, not 0), or so small that any buckling factor, ~ D / (N L^2) with L
    the plate's size, would exceed 1e12.
    """
    compression = max(-float(_smallest_principal(N).min()), 0.0)
    return compression <= max(1e-14 * np.abs(N).max(), 1e-12 * D_min / diameter ** 2)


def _remove_rigid(basis, modes, Kg):
    """L2-orthogonal removal of w = a + b x + c y from Morley modes; also the K_g leak on them.

    The rigid modes are the L2 projections of 1, x, y onto the Morley space (exact: the
    space contains every quadratic polynomial). The leak is the largest coupling
    ``|r^T K_g w| / sqrt(r^T M r  w^T M w)`` between a tilt r and a returned mode w, over that
    mode's own ``|w^T K_g w| / w^T M w``: 0 when K_g r = 0 (an exactly equilibrated free
    prestress), and the order of the relative amount by which the eigenvalues depend on which
    complement of the rigid modes is taken (see the module docstring).
    """
    from skfem import BilinearForm, LinearForm

    @BilinearForm
    def mass(u, v, w):
        return u * v

    M = mass.assemble(basis).tocsc()
    lu = spla.splu(M)
    R = np.column_stack([lu.solve(LinearForm(lambda v, w, f=f: f(w.x) * v).assemble(basis))
                         for f in (lambda x: 1.0 + 0 * x[0], lambda x: x[0], lambda x: x[1])])
    G = R.T @ (M @ R)
    coef = np.linalg.solve(G, R.T @ (M @ modes))
    out = modes - R @ coef
    T = R[:, 1:]
    Mw = np.einsum("ik,ik->k", out, M @ out)
    rq_modes = np.abs(np.einsum("ik,ik->k", out, Kg @ out)) / Mw
    coupling = np.abs(T.T @ (Kg @ out)) / np.sqrt(np.einsum("ij,ij->j", T, M @ T)[:, None] * Mw[None, :])
    return out, float((coupling / np.maximum(rq_modes, 1e-300)).max()) if out.shape[1] else 0.0


# ----------------------------------------------------------------------------- mode analysis

def azimuthal_wavenumber(points2d, w_at_points, radius=None, center=(0.0, 0.0), n_max=None,
                         return_spectrum=False):
    """Dominant azimuthal wavenumber of a function sampled on a circle.

    Parameters
    ----------
    points2d : (p, 2) array
        Sample points on a circle about ``center`` (any angular order; angles need not be
        uniform, the Fourier integrals use the trapezoidal rule in the sorted angle).
    w_at_points : (p,) array
        Values there.
    radius : float, optional
        Circle radius for the wavelength (default: mean distance of the points).
    n_max : int, optional
        Largest n considered (default p // 2 - 1).

    Returns
    -------
    (n, wavelength): n the wavenumber with the largest Fourier amplitude (0 for an
    axisymmetric function), wavelength ``2 pi radius / n`` (inf for n = 0). With
    ``return_spectrum=True`` also the amplitudes ``A_n`` (n = 0..n_max) of
    ``w ≈ Σ A_n cos(n θ - φ_n)``.
    """
    x = np.asarray(points2d, float)[:, :2] - np.asarray(center, float)[:2]
    w = np.asarray(w_at_points, float).ravel()
    th = np.arctan2(x[:, 1], x[:, 0])
    order = np.argsort(th)
    th, w = th[order], w[order]
    if radius is None:
        radius = float(np.mean(np.hypot(x[:, 0], x[:, 1])))
    p = len(th)
    n_max = p // 2 - 1 if n_max is None else int(n_max)
    dth = np.diff(np.concatenate([th, [th[0] + 2 * np.pi]]))
    wt = 0.5 * (dth + np.roll(dth, 1))              # periodic trapezoid weights
    ns = np.arange(n_max + 1)
    c = (np.exp(-1j * np.outer(ns, th)) * (w * wt)).sum(1) / (2 * np.pi)
    amp = np.abs(c) * np.where(ns == 0, 1.0, 2.0)
    n = int(np.argmax(amp))
    wavelength = np.inf if n == 0 else 2 * np.pi * radius / n
    if return_spectrum:
        return n, wavelength, amp
    return n, wavelength


def mode_wavenumber(result: BucklingResult, which=0, radii=None, center=(0.0, 0.0), n_samples=512,
                    n_max=60):
    """Azimuthal wavenumber n of mode ``which`` (or of every mode: ``which=None``).

    The mode is sampled at ``n_samples`` equally spaced angles on each circle of
    ``radii`` about ``center`` (default: 0.2, 0.35, ..., 0.95 times the largest circle
    inside the mesh) and the Fourier power spectra of the circles are added, so a mode
    that lives near one radius is still found. Returns (n, wavelength, power) for one
    mode, with the wavelength ``2 pi r / n`` at the circle of largest amplitude, or
    lists of them for ``which=None``.
    """
    mesh = result.basis.mesh
    c = np.asarray(center, float)[:2]
    if radii is None:
        bverts = np.unique(mesh.facets[:, mesh.boundary_facets()])
        rin = np.hypot(*(mesh.p[:, bverts] - c[:, None])).min()
        radii = rin * np.linspace(0.2, 0.95, 6)
    radii = np.atleast_1d(np.asarray(radii, float))
    th = 2 * np.pi * np.arange(n_samples) / n_samples
    n_max = min(n_max, n_samples // 2 - 1)
    idx = slice(None) if which is None else [which]
    k = result.modes[:, idx].shape[1]
    power = np.zeros((n_max + 1, k))
    amp_r = np.zeros((len(radii), k))
    for j, r in enumerate(radii):
        pts = c + r * np.column_stack([np.cos(th), np.sin(th)])
        w = result.basis.probes(pts.T).tocsr() @ result.modes[:, idx]          # (n_samples, k)
        amp = np.abs(np.fft.rfft(w, axis=0)[: n_max + 1]) / n_samples
        amp[1:] *= 2.0
        power += amp ** 2
        amp_r[j] = amp.max(0)
    ns = np.argmax(power, axis=0)
    rbest = radii[np.argmax(amp_r, axis=0)]
    wls = [np.inf if n == 0 else 2 * np.pi * r / n for n, r in zip(ns, rbest)]
    if which is None:
        return [int(n) for n in ns], wls, power
    return int(ns[0]), wls[0], power[:, 0]


# ----------------------------------------------------------------------------- the disk test

@dataclass
class CriticalGrowth:
    """Linear critical growth of a disk with a grown inner region (design.md 1.6).

    ``eps_c = mu * g0``: the critical growth strain in the linear theory for the
    thickness field used (for ``thin_grown`` the grown region has the thickness
    h / (1 + g0)^2 of the nominal growth g0; eps_c is self-consistent only where mu ≈ 1).
    ``n`` is the azimuthal wavenumber of the first mode, ``ns`` of every returned mode.
    """

    eps_c: float
    mu: np.ndarray
    n: int
    ns: list
    wavelength: float
    result: BucklingResult
    n_vertices: int
    wall_s: float


def critical_growth_strain(R1, R2, h, g0=0.5, nu=0.5, E=1.0, thin_grown=True, bc="free",
                           resolution=8, edge_length=None, inner_edge_length=None, k=4, mesh=None,
                           seed=0, solver="splu"):
    """Linear critical growth strain of a flat disk grown by g0 inside r < R2.

    The disk has radius R1, thickness h outside and ``h / (1 + g0)^2`` inside (if
    ``thin_grown``, design.md 1.6; else h), isotropic linear eigenstrain g0 inside
    r < R2 and 0 outside. Its outer edge is ``bc`` ("free" as in the paper, or
    "clamped"; the same edge condition is used in plane and out of plane).

    Mesh: ``femshell.mesh.generators.disk(R1, edge_length, inner_radius=R2,
    inner_edge_length=...)`` with, by default, inner_edge_length = R2 / resolution and
    edge_length = 4 R2 / resolution within [R1 / 25, R1 / 5] (the gmsh size grows from the inner
    value near the circle to edge_length with gradient 0.3). In linear plate theory
    the only length that shapes the modes is R2 (and R1); h only scales mu as h^2,
    so the mesh follows R2. Or pass ``mesh`` (a SurfaceMesh or (points, triangles)
    whose edges follow the circle r = R2).

    Returns a :class:`CriticalGrowth` (eps_c = mu[0] * g0 and the wavenumber n of the
    first mode, from :func:`mode_wavenumber` on circles r in [0.3, 1.5] R2).
    """
    t0 = time.perf_counter()
    for name, v in (("R1", R1), ("R2", R2), ("h", h), ("g0", g0), ("E", E)):
        if not (isinstance(v, (int, float, np.integer, np.floating)) and math.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
    if not R2 < R1:
        raise ValueError(f"R2 must be < R1, got R2 = {R2}, R1 = {R1}")
    resolution = integer("resolution", resolution, 1)
    if mesh is None:
        mesh = _disk_mesh(R1, R2, resolution, edge_length, inner_edge_length, seed)
    if hasattr(mesh, "points"):
        pts, tri = np.asarray(mesh.points)[:, :2], np.asarray(mesh.triangles)
    else:
        pts, tri = np.asarray(mesh[0])[:, :2], np.asarray(mesh[1])
    cen = pts[tri].mean(1)
    inside = np.hypot(cen[:, 0], cen[:, 1]) < R2
    g = np.where(inside, g0, 0.0)
    t = np.where(inside, h / (1.0 + g0) ** 2 if thin_grown else h, h)
    N = membrane_prestress(pts, tri, g, E=E, nu=nu, thickness=t, boundary="free" if bc == "free" else "clamped")
    res = buckling_loads(pts, tri, N, E=E, nu=nu, thickness=t, bc=bc, k=k, solver=solver)
    radii = R2 * np.array([0.3, 0.5, 0.7, 0.85, 1.0, 1.15, 1.3, 1.5])
    radii = radii[radii < 0.98 * R1]
    ns, wls, _ = mode_wavenumber(res, None, radii=radii) if len(res.mu) else ([], [np.inf], None)
    wl = wls[0]
    return CriticalGrowth(eps_c=float(res.mu[0] * g0), mu=res.mu, n=ns[0] if ns else -1, ns=ns,
                          wavelength=wl, result=res, n_vertices=len(pts),
                          wall_s=time.perf_counter() - t0)


def _disk_mesh(R1, R2, resolution=8, edge_length=None, inner_edge_length=None, seed=0, refine_inside=False):
    """(points (n, 2), triangles) of a disk of radius R1 with the circle R2 in its edges (``refine_inside``:
    the whole inner disk at the inner edge length, :func:`femshell.mesh.generators.disk`)."""
    from .mesh import generators

    if inner_edge_length is None:
        inner_edge_length = R2 / resolution
    if edge_length is None:
        edge_length = min(max(4.0 * R2 / resolution, R1 / 25.0), R1 / 5.0)
    m = generators.disk(R1, edge_length=edge_length, inner_radius=R2,
                        inner_edge_length=min(inner_edge_length, edge_length), seed=seed,
                        refine_inside=refine_inside)
    return np.asarray(m.points)[:, :2].copy(), np.asarray(m.triangles)


def _radial_morph(points, R2_from, R2_to, R1):
    """Move the circle r = R2_from to r = R2_to, keeping r = R1 and the centre fixed.

    Piecewise linear in r (scaling inside, affine in the annulus): the same triangulation
    at a nearby R2, so that mu(R2) is a smooth function for the root finder instead of
    jumping with every remeshing.
    """
    r = np.hypot(points[:, 0], points[:, 1])
    rn = np.where(r <= R2_from, r * (R2_to / R2_from),
                  R2_to + (r - R2_from) * (R1 - R2_to) / (R1 - R2_from))
    scale = np.where(r > 0, rn / np.where(r > 0, r, 1.0), 1.0)
    return points * scale[:, None]


@dataclass
class CriticalRadius:
    """Smallest grown radius R2 at which the disk buckles at growth g0 (mu = 1), linear theory.

    ``R2``: the root; ``mu``: mu of the target mode on the last mesh (≈ 1); ``n``: the
    target mode's azimuthal wavenumber (that of the first mode if no n was asked);
    ``history``: [(R2, mu_target)] of every evaluation; ``last``: the
    :class:`CriticalGrowth` of the last evaluation; ``converged``: |mu − 1| < rtol was
    reached within maxiter evaluations (if not, R2 is the last iterate, not a root).
    """

    R2: float
    mu: float
    n: int
    history: list
    last: CriticalGrowth
    n_vertices: int
    wall_s: float
    converged: bool = True


def critical_inner_radius(R1, h, g0=0.5, n=None, nu=0.5, E=1.0, thin_grown=True, bc="free",
                          resolution=8, R2_start=None, k=None, rtol=1e-3, maxiter=12, seed=0,
                          solver="splu"):
    """Smallest R2 where the disk of :func:`critical_growth_strain` buckles at growth g0.

    Solves ``mu_target(R2) = 1`` where mu_target is the first load factor (``n=None``)
    or the lowest one whose mode has ``n`` azimuthal waves, remeshing at every R2.
    The root is found in the variables (log R2, log mu): linear plate theory makes
    mu ∝ R2^-2 up to the weak dependence on R1 / R2, so the first step is the scaling
    step ``R2 <- R2 sqrt(mu)``, then a secant step, safeguarded by bisection of the
    bracket once the root is bracketed. Stops when |mu - 1| < rtol (a remeshing
    makes mu(R2) jump at the level of the discretisation error, so the mesh made at the first R2 is morphed radially to the next
    R2s, and remade only when R2 has moved by more than 20 %, which keeps mu(R2)
    smooth). ``k`` modes per evaluation (default 4, or 8 + 6 n for a
    target n; doubled if no mode with n waves is among them).
    """
    t0 = time.perf_counter()
    maxiter = integer("maxiter", maxiter, 1)
    kk = k if k is not None else (4 if n is None else 8 + 6 * n)
    converged = False
    x = np.log(R2_start if R2_start is not None else h)
    hist, pts = [], []
    lo = hi = None   # bracket: f(lo) > 0 (stable, mu > 1), f(hi) < 0
    last = None
    ref = None       # (R2 of the mesh, points, triangles): morphed, remeshed when R2 moved > 20 %
    for _ in range(maxiter):
        R2 = float(np.exp(x))
        if R2 >= 0.9 * R1:
            raise ValueError(f"no root below R2 = 0.9 R1 (R1 = {R1}); is g0 = {g0} too small? "
                             f"(R2, mu) so far: {hist}")
        if ref is None or not (1 / 1.2 < R2 / ref[0] < 1.2):
            ref = (R2,) + _disk_mesh(R1, R2, resolution, seed=seed)
        mesh = (_radial_morph(ref[1], ref[0], R2, R1), ref[2])
        while True:
            cg = critical_growth_strain(R1, R2, h, g0=g0, nu=nu, E=E, thin_grown=thin_grown, bc=bc,
                                        k=kk, mesh=mesh, solver=solver)
            if n is None:
                mu_t, n_t = float(cg.mu[0]), cg.n
                break
            hits = [i for i, m_ in enumerate(cg.ns) if m_ == n]
            if hits:
                mu_t, n_t = float(cg.mu[hits[0]]), n
                break
            if kk >= 200:
                raise RuntimeError(f"no mode with n = {n} among the first {kk} modes at R2 = {R2:.4g}")
            kk *= 2
        last = cg
        f = float(np.log(mu_t))
        hist.append((R2, mu_t))
        pts.append((x, f))
        if abs(mu_t - 1.0) < rtol:
            converged = True
            break
        if f > 0:
            lo = x if lo is None else max(lo, x)
        else:
            hi = x if hi is None else min(hi, x)
        if len(pts) >= 2 and pts[-1][1] != pts[-2][1]:
            (x1, f1), (x2, f2) = pts[-2], pts[-1]
            slope = (f2 - f1) / (x2 - x1)
            xn = x2 - f2 / slope if slope < 0 else x2 + f2 / 2.0
        else:
            xn = x + f / 2.0          # mu ∝ R2^-2
        xn = min(max(xn, x - np.log(2.0)), x + np.log(2.0))   # at most a factor 2 per step
        if lo is not None and hi is not None and not (min(lo, hi) < xn < max(lo, hi)):
            xn = 0.5 * (lo + hi)      # safeguard: bisection of the bracket
        x = xn
    return CriticalRadius(R2=hist[-1][0], mu=hist[-1][1], n=n_t, history=hist, last=last,
                          n_vertices=last.n_vertices, wall_s=time.perf_counter() - t0, converged=converged)
