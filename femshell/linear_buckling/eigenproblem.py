r"""Linear buckling loads of a flat Kirchhoff plate with prestress N (Morley element).

K_b w = μ K_g w with K_b = ∫ D [(1−ν) w,ab v,ab + ν Δw Δv], D = E t³ / (12 (1 − ν²)) per
triangle, and K_g = −∫ N_ab w,a v,b (compression gives μ > 0). μ is the factor by which the
prestress must be multiplied to buckle the plate. K_g is indefinite, so the problem solved is
K_g w = λ K_b w, λ = 1/μ, by ARPACK on the operator K_b⁻¹ K_g asking for the largest λ: the
smallest positive μ only. A free plate is pinned at three well-spread vertices and the rigid
part w = a + b x + c y is removed from each mode (see :mod:`femshell.linear_buckling`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse.linalg as spla

from .._checks import integer
from .inverse import _InverseOperator
from .plate import _at_quadrature, _boundary_facets, _mesh2d, _per_triangle, _poisson, bending_stiffness

__all__ = ["buckling_loads", "BucklingResult"]


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
        Inner solver for ``K_b^{-1}`` (splu is the fastest here, see :mod:`femshell.linear_buckling`).
    extra : int
        Extra eigenpairs computed beyond k (ARPACK converges better; also guards against
        losing one of a nearly double pair).

    Returns
    -------
    BucklingResult. Fewer than k values if the prestress has fewer compressive modes.
    """
    # deferred: scikit-fem takes over a second to import
    from skfem import Basis, ElementTriMorley

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
    Nm = _membrane_forces_per_triangle(N, m)
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

    Kb, Kg = _plate_matrices(basis, Dm, Nm, nu)
    timings["assemble_s"] = time.perf_counter() - t0

    info = {"n_dofs": basis.N, "n_vertices": mesh.p.shape[1], "n_triangles": m}
    fixed = _supported_dofs(mesh, basis, bc, supported_vertices, info)
    free = basis.complement_dofs(fixed)
    Kbf = Kb[free][:, free].tocsr()
    Kgf = Kg[free][:, free].tocsr()

    lam, X = _largest_inverse_loads(Kbf, Kgf, Nm, k + extra, solver, timings, info)
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


def _plate_matrices(basis, Dm, Nm, nu):
    """K_b = ∫ D [(1−ν) w,ab v,ab + ν Δw Δv] and K_g = −∫ N_ab w,a v,b on the Morley basis."""
    # deferred: scikit-fem takes over a second to import
    from skfem import BilinearForm
    from skfem.helpers import dd, ddot, trace

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
    return Kb, Kg


def _membrane_forces_per_triangle(N, m):
    """N as (m, 3) finite (N_xx, N_yy, N_xy) per triangle; one (3,) value is taken for every triangle."""
    Nm = np.asarray(N, float)
    if Nm.shape == (3,):
        Nm = np.tile(Nm, (m, 1))
    if Nm.shape != (m, 3):
        raise ValueError(f"N must have shape ({m}, 3) or (3,), got {Nm.shape}")
    if not np.all(np.isfinite(Nm)):
        raise ValueError(f"N holds NaN or infinity in {int((~np.isfinite(Nm)).any(axis=1).sum())} triangles")
    return Nm


def _supported_dofs(mesh, basis, bc, supported_vertices, info):
    """The Morley dofs held at zero by ``bc``; a free plate is pinned at three vertices (in ``info``)."""
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
    return fixed


def _largest_inverse_loads(Kbf, Kgf, Nm, nev, solver, timings, info):
    """The largest eigenpairs λ = 1/μ of K_g w = λ K_b w (ARPACK, shift-invert by K_b⁻¹), unsorted."""
    inv = _InverseOperator(Kbf, solver)
    timings["setup_s"] = inv.setup_s
    t1 = time.perf_counter()
    n_free = Kbf.shape[0]
    nev = min(nev, n_free - 2)
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
    return lam, X


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
    # deferred: scikit-fem takes over a second to import
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
