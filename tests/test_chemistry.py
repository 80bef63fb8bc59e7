"""femshell.chemistry: P1 surface matrices, source, reaction–diffusion stepper."""

import warnings

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from femshell.chemistry import (P1Assembler, ReactionDiffusion, curvature_source, surface_mass_lumped,
                                surface_stiffness)
from femshell.geometry import triangle_areas
from femshell.solvers.linear import factorize, smallest_eigenvalues


@pytest.fixture(scope="module")
def unit_sphere():
    from femshell.mesh.generators import sphere

    m = sphere(radius=1.0, n_vertices=2500, seed=0)
    return m.points, m.triangles


def test_mass_sums_to_the_sphere_area(unit_sphere):
    pts, tri = unit_sphere
    m = surface_mass_lumped(pts, tri)
    assert m.shape == (len(pts),) and np.all(m > 0)
    assert m.sum() == pytest.approx(triangle_areas(pts, tri).sum(), rel=1e-14)
    # an inscribed polyhedron: a little less than 4π, by O(h²)
    assert 4 * np.pi * (1 - 5e-3) < m.sum() < 4 * np.pi


def test_stiffness_symmetric_kills_constants_and_is_psd(unit_sphere):
    pts, tri = unit_sphere
    K = surface_stiffness(pts, tri)
    assert abs(K - K.T).max() == 0.0
    assert np.abs(K @ np.ones(len(pts))).max() < 1e-12 * np.abs(K.data).max()
    x = np.random.default_rng(0).standard_normal(len(pts))
    assert x @ (K @ x) > 0
    # the cached assembler gives the same matrix and reuses its pattern for moved points
    asm = P1Assembler(tri, len(pts))
    K1 = asm.stiffness(pts)
    assert abs(K1 - K).max() == 0.0
    K2 = asm.stiffness(pts * 2.0)             # the cotangent Laplacian is scale invariant
    assert np.allclose(K2.data, K1.data) and np.array_equal(K2.indices, K1.indices)
    assert np.allclose(asm.mass_lumped(pts * 2.0), 4 * surface_mass_lumped(pts, tri))
    assert asm.n_assembled == 2


def test_stiffness_matches_scikit_fem_on_a_planar_mesh():
    skfem = pytest.importorskip("skfem")
    from skfem.helpers import dot, grad

    mesh = skfem.MeshTri.init_circle(3)
    rng = np.random.default_rng(1)
    p = mesh.p.copy()
    inner = np.linalg.norm(p, axis=0) < 0.99
    p[:, inner] += 0.02 * rng.standard_normal((2, inner.sum()))
    mesh = skfem.MeshTri(p, mesh.t)
    basis = skfem.Basis(mesh, skfem.ElementTriP1())
    ref = skfem.BilinearForm(lambda u, v, w: dot(grad(u), grad(v))).assemble(basis)
    pts = np.column_stack([mesh.p.T, np.zeros(mesh.p.shape[1])])
    K = surface_stiffness(pts, mesh.t.T)
    assert abs(K - ref).max() < 1e-12
    # rotated into 3D, the surface operator is the same
    q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    assert abs(surface_stiffness(pts @ q.T + 1.0, mesh.t.T) - ref).max() < 1e-11


def test_first_nonzero_eigenvalue_on_the_unit_sphere(unit_sphere):
    pts, tri = unit_sphere
    asm = P1Assembler(tri, len(pts))
    w = smallest_eigenvalues(asm.stiffness(pts), k=9, M=asm.mass_lumped(pts), return_vectors=False)
    assert abs(w[0]) < 1e-10
    # l (l + 1): measured errors 1.9e-5 (l = 1) and 1.5e-3 (l = 2) on this mesh
    np.testing.assert_allclose(w[1:4], 2.0, rtol=1e-4)       # l = 1: 2, three times
    np.testing.assert_allclose(w[4:9], 6.0, rtol=5e-3)       # l = 2: 6, five times


def test_curvature_source():
    H = np.array([-3.0, -1e-12, 0.0, 0.01, 0.05, 1e300])
    P = curvature_source(H, w=15, Hs=0.05)
    np.testing.assert_allclose(P[:3], 0.0)
    np.testing.assert_allclose(P[3], 15 * 0.01 / (1 + 0.01 / 0.05))
    np.testing.assert_allclose(P[4], 15 * 0.05 / 2)
    np.testing.assert_allclose(P[5], 15 * 0.05)              # saturates at w Hs, no inf/inf
    with pytest.raises(ValueError, match="Hs"):
        curvature_source(H, Hs=0.0)


def test_degenerate_triangle_is_named():
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0]])
    with pytest.raises(ValueError, match="first triangle 1"):
        surface_stiffness(pts, np.array([[0, 1, 3], [0, 1, 2]]))


def test_exponential_update_is_exact_without_diffusion(unit_sphere):
    pts, tri = unit_sphere
    n = len(pts)
    rng = np.random.default_rng(2)
    c0 = rng.uniform(0, 1, n)
    P = curvature_source(rng.normal(0, 0.05, n))
    beta = 1.0
    rd = ReactionDiffusion(tri, n, D=0.0, beta=beta, points=pts, factorize=factorize)
    t = 0.0
    c = c0
    for dt in (0.3, 1.7, 0.01, 5.0):
        c = rd.step(c, dt, P)
        t += dt
        exact = c0 * np.exp(-beta * t) + P / beta * (1 - np.exp(-beta * t))
        np.testing.assert_allclose(c, exact, rtol=1e-13, atol=1e-15)
    # β = 0: c + t P
    rd0 = ReactionDiffusion(tri, n, D=0.0, beta=0.0, factorize=factorize)
    np.testing.assert_allclose(rd0.step(c0, 2.5, P), c0 + 2.5 * P, rtol=1e-15)
    # and no stiffness (nor mass) was ever assembled
    assert rd.stiffness is None and rd.mass is None and rd.assembler.n_assembled == 0
    assert rd0.stiffness is None and rd0.assembler.n_assembled == 0


def test_diffusion_step_matches_its_linear_system(unit_sphere):
    """(M + γ D K) c⁺ = M (c e^{−β dt} + γ P), γ = (1 − e^{−β dt})/β: degradation exact, diffusion implicit."""
    pts, tri = unit_sphere
    n = len(pts)
    rng = np.random.default_rng(3)
    c = rng.uniform(0, 1, n)
    P = rng.uniform(0, 0.5, n)
    D, beta, dt = 0.7, 1.0, 0.2
    decay, gamma = np.exp(-beta * dt), (1 - np.exp(-beta * dt)) / beta
    rd = ReactionDiffusion(tri, n, D=D, beta=beta, points=pts, factorize=factorize)
    c1 = rd.step(c, dt, P)
    K = surface_stiffness(pts, tri)
    m = surface_mass_lumped(pts, tri)
    A = sp.diags(m) + gamma * D * K
    np.testing.assert_allclose(c1, spla.spsolve(A.tocsc(), m * (c * decay + gamma * P)), rtol=1e-10)
    # the factorisation is reused while dt and the geometry stay the same ...
    rd.step(c1, dt, P)
    assert rd._factor.n_factorizations == 1
    # ... and refactorised (same pattern: no new analysis) when the surface moves
    moved = pts * (1 + 0.05 * pts[:, 2:3])
    c3 = rd.step(c1, dt, P, points=moved)
    assert rd._factor.n_factorizations == 2 and rd._factor.n_analyses == 1
    K = surface_stiffness(moved, tri)
    m = surface_mass_lumped(moved, tri)
    A = sp.diags(m) + gamma * D * K
    np.testing.assert_allclose(c3, spla.spsolve(A.tocsc(), m * (c1 * decay + gamma * P)), rtol=1e-10)
    # total amount after one step: Σ m c⁺ = Σ m (c e^{−β dt} + γ P), exactly the ODE of the total (K 1 = 0)
    assert (m * c3).sum() == pytest.approx((m * (c1 * decay + gamma * P)).sum(), rel=1e-10)


def test_the_diffusion_step_is_exact_in_the_reaction_and_continuous_as_d_goes_to_zero(unit_sphere):
    """A uniform c under a uniform source is a solution of the ODE c' = P − βc for any D (K 1 = 0):
    the step reproduces its closed form for any dt; D → 0 gives the D = 0 update."""
    pts, tri = unit_sphere
    n = len(pts)
    exact = 0.5 * (1 - np.exp(-3.0))                       # c(3) from c = 0 under P = 0.5, β = 1
    for D in (0.0, 1e-12, 0.5):
        rd = ReactionDiffusion(tri, n, D=D, beta=1.0, points=pts, factorize=factorize)
        c = np.zeros(n)
        for _ in range(3):
            c = rd.step(c, 1.0, np.full(n, 0.5))
        np.testing.assert_allclose(c, exact, rtol=1e-12)   # implicit Euler: 0.4375 against 0.4751
    rng = np.random.default_rng(5)
    c0, P = rng.uniform(0, 1, n), rng.uniform(0, 0.5, n)
    # D = 1e-15 moves c by D γ |M⁻¹K c| ~ 1e-13 here: no jump at D = 0
    near = ReactionDiffusion(tri, n, D=1e-15, beta=1.0, points=pts, factorize=factorize).step(c0, 0.7, P)
    zero = ReactionDiffusion(tri, n, D=0.0, beta=1.0, factorize=factorize).step(c0, 0.7, P)
    np.testing.assert_allclose(near, zero, rtol=0, atol=1e-11)


def test_concentration_stays_nonnegative_for_huge_steps(unit_sphere):
    pts, tri = unit_sphere
    n = len(pts)
    rng = np.random.default_rng(4)
    c = np.where(rng.uniform(size=n) < 0.02, 50.0, 0.0)     # sparse spikes
    H = rng.normal(0, 0.05, n)
    rd = ReactionDiffusion(tri, n, D=100.0, beta=1.0, points=pts, factorize=factorize)
    P = curvature_source(H, w=1000.0)
    for _ in range(5):
        c = rd.step(c, 100.0, P)
        assert np.all(c >= 0) and np.all(np.isfinite(c))
    # discrete maximum principle: bounded by the source's steady state
    assert c.max() <= max(50.0, P.max() / 1.0) * (1 + 1e-12)
    # gmsh's sphere is Delaunay but for a handful of edges (2 of ~7500 here), where the
    # M-matrix argument fails; clipping keeps c >= 0 there
    assert rd.n_negative_weights <= 10


def test_negative_values_on_an_obtuse_mesh_are_clipped_and_reported():
    # edge (0, 1) has both opposite angles ≈ 157°: negative cotangent weight
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0.5, 0.1, 0], [0.5, -0.1, 0]])
    tri = np.array([[0, 1, 2], [1, 0, 3]])
    rd = ReactionDiffusion(tri, 4, D=1.0, beta=1.0, points=pts, factorize=factorize)
    with pytest.warns(RuntimeWarning, match="negative"):
        c = rd.step(np.array([1.0, 0, 0, 0]), 0.01)
    assert np.all(c >= 0) and rd.n_clipped >= 1 and rd.n_negative_weights == 1
    # signed fields: no clipping when asked
    rd2 = ReactionDiffusion(tri, 4, D=1.0, beta=1.0, points=pts, nonnegative=False, factorize=factorize)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        c2 = rd2.step(np.array([1.0, 0, 0, 0]), 0.01)
    assert c2.min() < 0 and rd2.n_clipped == 0


def test_stepper_argument_checks(unit_sphere):
    pts, tri = unit_sphere
    with pytest.raises(ValueError, match="D must"):
        ReactionDiffusion(tri, len(pts), D=-1.0)
    rd = ReactionDiffusion(tri, len(pts), D=1.0, factorize=factorize)
    with pytest.raises(ValueError, match="no geometry"):
        rd.step(np.zeros(len(pts)), 0.1)
    with pytest.raises(ValueError, match="dt"):
        rd.step(np.zeros(len(pts)), 0.0, points=pts)
    with pytest.raises(ValueError, match="shape"):
        rd.step(np.zeros(3), 0.1, points=pts)


def test_diffusion_needs_the_callers_linear_solver(unit_sphere):
    """The chemistry solves with the factorisation its caller gives; D > 0 without one is named."""
    pts, tri = unit_sphere
    c = np.linspace(0.0, 1.0, len(pts))
    with pytest.raises(ValueError, match="give ReactionDiffusion a factorize callable"):
        ReactionDiffusion(tri, len(pts), D=1.0, points=pts).step(c, 0.1)
    with pytest.raises(TypeError, match="factorize must be a callable"):
        ReactionDiffusion(tri, len(pts), D=1.0, factorize="pardiso")
    calls = []

    def counting(A, reuse=None):
        calls.append(A.shape)
        return factorize(A, reuse=reuse)

    rd = ReactionDiffusion(tri, len(pts), D=1.0, points=pts, factorize=counting)
    out = rd.step(c, 0.1)
    rd.step(out, 0.1)                                   # same dt and geometry: the factor is kept
    assert calls == [(len(pts), len(pts))]
    K, M = surface_stiffness(pts, tri), surface_mass_lumped(pts, tri)
    gamma = -np.expm1(-0.1)
    direct = spla.spsolve((sp.diags(M) + gamma * K).tocsc(), M * (c * np.exp(-0.1)))
    assert np.allclose(out, direct, rtol=1e-10, atol=1e-14)
