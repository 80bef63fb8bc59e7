"""A model built from a thickness takes the drawn mesh as its stress-free shape; a flat rest state on a
curved mesh warns with the energy it holds at rest."""

import warnings

import numpy as np
import pytest

from femshell.mesh import generators
from femshell.shell import (Clamped, DeadPressure, Material, PrestressWarning, ShellModel, flat_rest_state,
                            natural_curvature)


@pytest.fixture(scope="module")
def ball():
    return generators.sphere(1.0, n_vertices=600)


def test_curved_mesh_is_stress_free_at_rest(ball):
    with warnings.catch_warnings():
        warnings.simplefilter("error")                      # no PrestressWarning on this path
        model = ShellModel(ball, Material(1.0, 0.3), 0.02)
    u = model.initial_unknowns()
    mem, bend = model.energy_parts(u)
    assert model.drawn_curved
    # the forms' own round-off: against the energy of a 1e-3 strain, and the force of a 1e-6 displacement
    assert abs(mem.sum() + bend.sum()) < 1e-20
    g = model.gradient(u)
    K = model.hessian(u)
    displacement = 1e-6 * np.random.default_rng(0).standard_normal(len(u))   # not a rigid motion
    assert np.linalg.norm(g) < 1e-10 * np.linalg.norm(K @ displacement)
    np.testing.assert_array_equal(model.rest.thickness, 0.02)


def test_flat_rest_state_on_a_curved_mesh_warns_with_the_energy(ball):
    with pytest.warns(PrestressWarning, match=r"strain energy at rest [0-9.e-]+.*ShellModel\(mesh, material, thickness"):
        model = ShellModel(ball, Material(1.0, 0.3), flat_rest_state(ball.points, ball.triangles, 0.02))
    # the bending energy of b - b̄ = a/R on a unit sphere: (h³/12) (2α + 2β) 4π (faceted: within 5 %)
    mat = model.material
    expected = 0.02 ** 3 / 12 * (2 * mat.alpha + 2 * mat.beta) * 4 * np.pi
    assert model.strain_energy(model.initial_unknowns()) == pytest.approx(expected, rel=5e-2)
    with warnings.catch_warnings():                          # a rest curvature given on purpose is taken as meant
        warnings.simplefilter("error")
        ShellModel(ball, Material(1.0, 0.3), natural_curvature(ball.points, ball.triangles, 0.02, 1.0))


def test_flat_mesh_from_a_thickness_is_the_flat_rest_state():
    m = generators.disk(1.0, n_vertices=300)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        a = ShellModel(m, Material(1.0, 0.3), 0.01, [Clamped("outer")], [DeadPressure(m, 1e-6)])
    b = ShellModel(m, Material(1.0, 0.3), flat_rest_state(m.points, m.triangles, 0.01), [Clamped("outer")],
                   [DeadPressure(m, 1e-6)])
    assert not a.drawn_curved
    for name in ("metric", "curvature", "thickness"):
        np.testing.assert_array_equal(getattr(a.rest, name), getattr(b.rest, name))
    with pytest.raises(ValueError, match="thickness must be > 0"):
        ShellModel(m, Material(1.0, 0.3), -0.01)
