"""Stiff and extreme inputs: steep sigmoids, huge production and diffusion with huge time steps, large
growth. Each test states its pass criterion; together they run in well under a minute.

Longer extreme cases (frustrated growth up to s = 2 of a spherical cap and of a disk centre, meshes with
5-degree slivers and strongly graded sizes, the thin-shell conditioning study) are validation rows:
``femshell validate extremes``, ``poor-meshes``, ``thin-shell-locking``.
"""

import warnings

import numpy as np
import pytest

from femshell.chemistry import ReactionDiffusion, curvature_source
from femshell.growth import (contractility, dstretch_dc, element_average, stretch, target_curvature,
                             target_metric, target_thickness)
from femshell.solvers.linear import factorize


@pytest.fixture
def strict_floats():
    """Any overflow, invalid operation or division by zero raises; any warning is an error.
    (Underflow is allowed: e^{-x} rounding to 0 for huge x is the correct answer.)"""
    with np.errstate(over="raise", invalid="raise", divide="raise", under="ignore"), warnings.catch_warnings():
        warnings.simplefilter("error")
        yield


# ------------------------------------------------------------------------------------ sigmoid

@pytest.mark.parametrize("b", [1.0, 10.0, 100.0, 1000.0])
@pytest.mark.parametrize("c_star", [0.1, -1e3, 1e3])
def test_steep_sigmoid_is_finite_bounded_and_monotone(strict_floats, b, c_star):
    """Pass: Λ, s, ds/dc finite for |b (c − c*)| up to 2e6; Λmin ≤ Λ ≤ Λmax; Λ non-increasing and s
    non-decreasing in c; ds/dc ≥ 0; the limits are exact far from c*."""
    lam_max, lam_min = 15.0, 10.0
    c = np.concatenate([np.linspace(-2e3, 2e3, 4001), c_star + np.linspace(-5.0, 5.0, 2001) / b])
    c.sort()
    lam = contractility(c, lam_max, lam_min, b, c_star)
    s = stretch(c, None, lam_max, lam_min, b, c_star)
    ds = dstretch_dc(c, None, lam_max, lam_min, b, c_star)
    for v in (lam, s, ds):
        assert np.all(np.isfinite(v))
    assert np.all((lam >= lam_min) & (lam <= lam_max))
    assert np.all(np.diff(lam) <= 0) and np.all(np.diff(s) >= 0) and np.all(ds >= 0)
    assert np.all((s >= 1.0) & (s <= lam_max / lam_min))
    far_below, far_above = c < c_star - 800 / b, c > c_star + 800 / b
    assert np.all(lam[far_below] == lam_max) and np.all(lam[far_above] == lam_min)
    assert np.all(s[far_below] == 1.0) and np.all(s[far_above] == lam_max / lam_min)
    # the targets built from these stretches stay finite and positive
    tri = np.arange(len(c) - len(c) % 3).reshape(-1, 3)
    se = element_average(s, tri)
    a = target_metric(np.broadcast_to(np.eye(2), (len(tri), 2, 2)), se)
    assert np.all(np.isfinite(a)) and np.all(np.linalg.det(a) > 0)
    assert np.all(np.isfinite(target_thickness(1.0, se))) and np.all(target_thickness(1.0, se) > 0)
    assert np.all(np.isfinite(target_curvature(a, 1 / 30)))


def test_steep_sigmoid_derivative_is_the_finite_difference_even_at_b_1000(strict_floats):
    c = 0.1 + np.linspace(-3e-3, 3e-3, 61)
    h = 1e-7
    fd = (stretch(c + h, b=1000.0) - stretch(c - h, b=1000.0)) / (2 * h)
    np.testing.assert_allclose(dstretch_dc(c, b=1000.0), fd, rtol=1e-5, atol=1e-6)


# ------------------------------------------------------------------------------------ chemistry

@pytest.fixture(scope="module")
def sphere_mesh():
    from femshell.mesh.generators import sphere

    m = sphere(radius=30.0, n_vertices=600, seed=0)
    return m.points, m.triangles


@pytest.mark.parametrize("D", [0.0, 1.5, 1e2])
@pytest.mark.parametrize("dt", [0.01, 1.0, 100.0])
@pytest.mark.parametrize("w", [15.0, 1e3])
def test_reaction_diffusion_with_huge_production_diffusion_and_steps(strict_floats, sphere_mesh, D, dt, w):
    """Pass: after 20 steps c is finite, c ≥ 0 (without clipping on this Delaunay mesh), and
    max c ≤ max(max c0, max P/β) (the discrete maximum principle of the chemistry step)."""
    pts, tri = sphere_mesh
    rng = np.random.default_rng(0)
    H = rng.uniform(-1.0, 10.0, len(pts))                # curvatures up to 200 Hs: P saturates at w Hs
    P = curvature_source(H, w=w, Hs=0.05)
    c = rng.uniform(0.0, 5.0, len(pts))
    bound = max(c.max(), P.max() / 1.0)
    rd = ReactionDiffusion(tri, len(pts), D=D, beta=1.0, points=pts, factorize=factorize)
    for k in range(20):
        # the surface moves as well: stretched by up to 10x and back
        c = rd.step(c, dt, source=P, points=pts * (1.0 + 9.0 * (k % 2)))
        assert np.all(np.isfinite(c)) and np.all(c >= 0.0)
        assert c.max() <= bound * (1 + 1e-12)
    assert rd.n_clipped == 0
    if dt == 100.0:   # 20 steps of dt = 100 reach the steady state; D = 0: exactly P/β
        if D == 0.0:
            np.testing.assert_allclose(c, P, rtol=1e-12, atol=1e-12)
        else:
            # steady state: β ∫c = ∫P exactly (K 1 = 0)
            assert np.sum(rd.mass * c) == pytest.approx(np.sum(rd.mass * P), rel=1e-8)
    rd.free()


def test_reaction_diffusion_without_decay_grows_linearly_and_stays_finite(strict_floats, sphere_mesh):
    pts, tri = sphere_mesh
    rd = ReactionDiffusion(tri, len(pts), D=1e2, beta=0.0, points=pts, factorize=factorize)
    c = np.zeros(len(pts))
    P = curvature_source(np.full(len(pts), 1e6), w=1e3)      # saturated: ≈ w Hs = 50 everywhere
    for _ in range(10):
        c = rd.step(c, 100.0, source=P)
    np.testing.assert_allclose(c, P * 100.0 * 10, rtol=1e-10)
    rd.free()


def test_diffusion_beyond_double_precision_names_how_far_it_reaches(sphere_mesh):
    """D = 1e30 swamps the mass matrix: the error says sqrt(D dt) against the surface's size."""
    pts, tri = sphere_mesh
    rd = ReactionDiffusion(tri, len(pts), D=1e30, beta=1.0, points=pts, factorize=factorize)
    size = np.sqrt(4 * np.pi) * 30.0                         # sqrt(area) of the sphere, within the mesh's error
    with pytest.raises(ValueError, match="singular in double precision") as err:
        rd.step(np.ones(len(pts)), 0.01)
    reach = float(str(err.value).split("sqrt(D dt) = ")[1].split(" ")[0])
    assert reach == pytest.approx(np.sqrt(1e30 * 0.01) / size, rel=0.01)
    rd.free()


def test_obtuse_triangles_are_clipped_with_a_warning_that_names_the_mesh(sphere_mesh):
    """Pass: on a mesh with obtuse (non-Delaunay) triangles the implicit step loses the maximum
    principle and undershoots next to a spike; c stays ≥ 0 and finite, and the warning says the mesh
    (negative cotangent weights) is the cause. (With D dt ≫ h² the step smooths everything and no
    undershoot is left; it shows at D dt ~ h²/100.)"""
    pts, tri = sphere_mesh
    rng = np.random.default_rng(3)
    bad = pts + 2.0 * rng.standard_normal(pts.shape)       # ~ 0.4 edge lengths: hundreds of obtuse angles
    c = np.zeros(len(pts))
    c[:5] = 1.0                                            # a sharp spike: the classic undershoot
    rd = ReactionDiffusion(tri, len(pts), D=1.0, beta=1.0, points=bad, factorize=factorize)
    with pytest.warns(RuntimeWarning, match="negative cotangent weight"):
        for _ in range(5):
            c = rd.step(c, 0.1)
    assert rd.n_negative_weights > 100 and rd.n_clipped > 0
    assert np.all(np.isfinite(c)) and np.all(c >= 0)
    rd.free()


# ------------------------------------------------------------------------------------ large growth

def test_free_disk_grows_to_twice_its_size():
    """Compatible growth s = 2 (area ×4, thickness /4) of a free flat disk. Pass: every step converges,
    the result is stable, finite, at zero energy, with exactly 4 times the area."""
    from femshell.mesh.generators import disk
    from femshell.shell import Material, ShellModel, uniform_growth
    from femshell.validation.extremes import grow_in_steps    # follow_load's stepping, in the growth

    mesh = disk(radius=1.0, edge_length=0.25)
    model = ShellModel(mesh, Material(1.0, 0.5), uniform_growth(mesh.points, mesh.triangles, 0.05, 0.0))
    rest_at = lambda s: uniform_growth(mesh.points, mesh.triangles, 0.05, s - 1.0,  # noqa: E731
                                       volume_conserving=True)
    s, res, stats = grow_in_steps(model, rest_at, 2.0, stable=True)
    assert s == 2.0 and res.converged and res.stable and stats["all_stable"]
    x = model.positions(res.u)
    assert np.all(np.isfinite(x))
    tri = x[mesh.triangles]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
    tri0 = mesh.points[mesh.triangles]
    area0 = 0.5 * np.linalg.norm(np.cross(tri0[:, 1] - tri0[:, 0], tri0[:, 2] - tri0[:, 0]), axis=1).sum()
    assert area / area0 == pytest.approx(4.0, rel=1e-8)
    assert res.energy <= 1e-12 * model.material.E * area0 * 0.05
