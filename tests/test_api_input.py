"""Bad arguments through the Python API: a ValueError from femshell naming the argument, not a numpy error."""

import numpy as np
import pytest

from femshell.growth import target_thickness
from femshell.mesh.generators import disk
from femshell.shell import Clamped, EdgeForce, EdgeMoment, Material, ShellModel, flat_rest_state


@pytest.fixture(scope="module")
def small_disk():
    return disk(radius=1.0, edge_length=0.3)


def test_thickness_per_vertex_instead_of_per_element(small_disk):
    m = small_disk
    with pytest.raises(ValueError, match=rf"one value per element \(shape \({m.n_triangles},\)\), "
                                         rf"got shape \({m.n_vertices},\)"):
        flat_rest_state(m.points, m.triangles, np.full(m.n_vertices, 0.01))
    with pytest.raises(ValueError, match=r"same shape, got \(5,\) and \(4,\)"):
        target_thickness(np.full(5, 2.0), np.ones(4))


def test_load_on_a_curve_the_mesh_does_not_have(small_disk):
    m = small_disk
    with pytest.raises(ValueError, match="mesh has no boundary curve 'inner'; it has: outer"):
        EdgeForce(m, "inner", (0.0, 0.0, 1.0))
    with pytest.raises(ValueError, match="mesh has no boundary curve 'inner'; it has: outer"):
        ShellModel(m, Material(), flat_rest_state(m.points, m.triangles, 0.01), [Clamped("outer")],
                   [EdgeMoment("inner", 1.0)])


def test_rest_state_of_another_mesh(small_disk):
    m = small_disk
    model = ShellModel(m, Material(), flat_rest_state(m.points, m.triangles, 0.01), [Clamped("outer")])
    with pytest.raises(ValueError, match=f"rest state has {m.n_triangles - 1} elements, mesh has {m.n_triangles}"):
        model.set_rest_state(flat_rest_state(m.points, m.triangles[:-1], 0.01))
