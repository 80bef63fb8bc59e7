"""femshell.geometry: areas and the area-weighted vertex average that carries H to the chemistry."""

import numpy as np

from femshell.geometry import element_to_vertex, triangle_areas


def test_element_to_vertex_is_the_area_weighted_mean():
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [3, 0, 0]])
    tri = np.array([[0, 1, 2], [1, 3, 2], [1, 4, 3]])
    area = triangle_areas(pts, tri)
    np.testing.assert_allclose(area, [0.5, 0.5, 1.0])
    v = element_to_vertex(np.array([1.0, 2.0, 4.0]), pts, tri)
    np.testing.assert_allclose(v[0], 1.0)
    np.testing.assert_allclose(v[1], (1 * 0.5 + 2 * 0.5 + 4 * 1.0) / 2.0)
    np.testing.assert_allclose(v[2], (1 * 0.5 + 2 * 0.5) / 1.0)
    np.testing.assert_allclose(element_to_vertex(np.full(3, 7.0), pts, tri), 7.0)
