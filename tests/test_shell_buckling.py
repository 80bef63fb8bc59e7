"""femshell.linear_buckling.shell_buckling_loads: linear buckling of a shell state (guide: continuation)."""

import numpy as np
import pytest
import scipy.sparse.linalg as spla

from femshell import linear_buckling as lb
from femshell.mesh import generators
from femshell.shell import Clamped, DeadPressure, FollowerPressure, Material, ShellModel, uniform_growth
from femshell.solvers.parameters import GrowthParameter

NU = 0.3


def test_clamped_plate_converges_to_the_scikit_fem_reference():
    # a clamped disk grown uniformly: the shell's own Hessian and its growth derivative against the planar
    # Morley reference (prestress + K_g) on the same meshes. The two elements differ, so they agree up
    # to discretisation errors that shrink as h² (a factor 4 from 500 to 2000 vertices; asked: 2.5)
    t, g = 0.01, 1e-4
    diffs = []
    for n in (500, 2000):
        m = generators.disk(1.0, n_vertices=n)
        model = ShellModel(m, Material(1.0, NU), uniform_growth(m.points, m.triangles, t, 0.0), [Clamped("outer")])
        growth = GrowthParameter(model, lambda s: uniform_growth(m.points, m.triangles, t, s), parameter_scale=g)
        growth.set_parameter(0.0)
        res = lb.shell_buckling_loads(growth, model.initial_unknowns(), k=3)
        p2, tri = np.asarray(m.points)[:, :2], np.asarray(m.triangles)
        N = lb.membrane_prestress(p2, tri, g, nu=NU, thickness=t, boundary="clamped")
        ref = lb.buckling_loads(p2, tri, N, nu=NU, thickness=t, bc="clamped", k=3).mu * g
        diffs.append(np.abs(res.parameters / ref - 1))
        assert res.info["rigid_motions"] == 0 and res.p0 == 0.0
        assert np.allclose(res.increments, res.parameters)
    assert np.all(diffs[1] < diffs[0] / 2.5), diffs
    assert np.all(diffs[1] < 1e-2), diffs
    # and the exact clamped disk, k² = j₁,₁² = 14.682 (g_c = k² t² / (12 (1 + ν)))
    assert res.parameters[0] * 12 * (1 + NU) / t ** 2 == pytest.approx(14.682, rel=1e-2)


@pytest.fixture(scope="module")
def sphere_under_pressure():
    R, t = 1.0, 0.04                                       # R/t = 25
    m = generators.sphere(R, n_vertices=2000)
    p_classical = 2 * t ** 2 / (R ** 2 * np.sqrt(3 * (1 - NU ** 2)))

    def model(pressure, **kw):
        mo = ShellModel(m, Material(1.0, NU), t, [], [FollowerPressure(pressure)], **kw)   # stress free as drawn
        mo.load_factor = 0.0
        return mo

    free = model(-p_classical, remove_rigid_modes=False)
    return m, model, free, lb.shell_buckling_loads(free, free.initial_unknowns(), k=4)


def test_sphere_deflation_equals_statically_determinate_pins(sphere_under_pressure):
    m, _, free, res = sphere_under_pressure
    # near the classical pressure (discretisation error of the faceted sphere: a few per cent, from below)
    assert 0.85 < res.parameters[0] < 1.02
    assert res.info["rigid_motions"] == 6
    # the same pencil on the complement of a 3-2-1 pin set: pole A all, pole B the two components normal
    # to AB, equator vertex C the one normal to ABC, with the rigid-compatible K̃₁
    pencil = lb.buckling_pencil(free, free.initial_unknowns())
    x = m.points
    a, b, c = int(np.argmax(x[:, 2])), int(np.argmin(x[:, 2])), int(np.argmax(x[:, 0]))
    keep = np.setdiff1d(np.arange(pencil.K0.shape[0]), [3 * a, 3 * a + 1, 3 * a + 2, 3 * b, 3 * b + 1, 3 * c + 1])
    K0 = pencil.K0[keep][:, keep].tocsc()
    n = len(keep)

    def minus_K1(y):
        full = np.zeros(pencil.K0.shape[0])
        full[keep] = y
        return -pencil.rigid_compatible_K1(full)[keep]

    lu = spla.splu(K0)
    lam = spla.eigsh(spla.LinearOperator((n, n), matvec=minus_K1, dtype=float), k=8, M=K0,
                     Minv=spla.LinearOperator((n, n), matvec=lu.solve, dtype=float), which="LA", tol=1e-12,
                     v0=np.random.default_rng(0).standard_normal(n))[0]
    pinned = np.sort(1.0 / lam[lam > 0])[:4]
    # all four, inside the sphere's near-degenerate multiplet (3e-4 wide), to 1e-6
    np.testing.assert_allclose(pinned, res.parameters, rtol=1e-6)
    assert max(res.info["residuals"]) < 1e-9


def test_sphere_modes_have_no_rigid_part_and_pins_are_released(sphere_under_pressure):
    m, model, free, res = sphere_under_pressure
    x = m.points - m.points.mean(axis=0)
    for i in range(len(res.parameters)):
        d = res.displacements(i)
        assert np.linalg.norm(d, axis=1).max() == pytest.approx(1.0)
        assert np.abs(d.sum(axis=0)).max() < 1e-8 * np.abs(d).sum()
        assert np.abs(np.cross(x, d).sum(axis=0)).max() < 1e-8 * np.abs(np.cross(x, d)).sum()
    pinned = model(free.loads[0].pressure)                  # the default six rigid-body pins
    assert pinned.rigid_pins
    again = lb.shell_buckling_loads(pinned, pinned.initial_unknowns(), k=2)
    np.testing.assert_allclose(again.parameters, res.parameters[:2], rtol=1e-8)    # threaded round-off


def test_sphere_under_internal_pressure_does_not_buckle(sphere_under_pressure):
    _, model, free, _ = sphere_under_pressure
    inflated = model(-free.loads[0].pressure, remove_rigid_modes=False)
    res = lb.shell_buckling_loads(inflated, inflated.initial_unknowns(), k=2)
    assert len(res.parameters) == 0


def test_follower_pressure_stiffness_is_symmetric(sphere_under_pressure):
    _, _, free, res = sphere_under_pressure
    K = free.hessian(free.initial_unknowns() + 0.01 * res.modes[free.free, 0])
    assert abs(K - K.T).max() <= 1e-12 * abs(K).max()


def test_bad_input_is_named():
    m = generators.disk(1.0, n_vertices=200)
    model = ShellModel(m, Material(1.0, NU), uniform_growth(m.points, m.triangles, 0.01, 0.0), [Clamped("outer")])
    growth = GrowthParameter(model, lambda s: uniform_growth(m.points, m.triangles, 0.01, s), parameter_scale=1e-4)
    with pytest.raises(ValueError, match="set_parameter"):
        lb.shell_buckling_loads(growth, model.initial_unknowns())
    with pytest.raises(ValueError, match="no loads"):
        lb.shell_buckling_loads(model, model.initial_unknowns())
    loaded = ShellModel(m, Material(1.0, NU), uniform_growth(m.points, m.triangles, 0.01, 0.0), [Clamped("outer")],
                        [DeadPressure(m, 1e-6)])
    with pytest.raises(ValueError, match="not an equilibrium"):     # load factor 1 at the unloaded shape
        lb.shell_buckling_loads(loaded, loaded.initial_unknowns())
    growth.set_parameter(0.0)
    with pytest.raises(ValueError, match="free unknowns"):
        lb.shell_buckling_loads(growth, model.initial_unknowns()[:-1])
    with pytest.raises(ValueError, match="k must be"):
        lb.shell_buckling_loads(growth, model.initial_unknowns(), k=0)
