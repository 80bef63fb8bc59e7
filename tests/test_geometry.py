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


def test_fold_angles_small_on_a_resolved_sphere_and_180_on_a_folded_pair():
    from femshell.geometry import fold_angles
    from femshell.mesh.generators import sphere

    mesh = sphere(2.0, n_vertices=400, seed=0)
    ang = fold_angles(mesh.points, mesh.triangles, mesh.topology.edge_faces)
    assert len(ang) == mesh.topology.n_edges                       # closed: every edge has two faces
    edge = np.linalg.norm(np.diff(mesh.points[mesh.topology.edges], axis=1), axis=2).mean()
    assert ang.max() < 3 * np.degrees(edge / 2.0)                  # ~ edge / R between neighbours
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0.2, 0.2, 1e-9]])   # the second face folded back
    tri = np.array([[0, 1, 2], [2, 1, 3]])
    assert fold_angles(pts, tri, np.array([[0, 1]]))[0] > 179.0
