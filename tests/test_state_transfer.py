"""Carrying a shell state between meshes: P1 interpolation and positions as unknowns."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from femshell.mesh import disk
from femshell.mesh.interpolation import interpolate_p1, locate
from femshell.shell import Material, RestState, ShellModel, metric, uniform_growth
from femshell.solvers.newton import minimize


def test_p1_interpolation_between_two_meshes_of_a_disk_is_exact_for_linear_fields():
    src, dst = disk(1.0, edge_length=0.2, seed=1), disk(1.0, edge_length=0.13, seed=2)
    a, b = src.points[:, :2], dst.points[:, :2]
    field = np.column_stack([1.0 + 2.0 * a[:, 0] - 3.0 * a[:, 1], -a[:, 1]])
    got = interpolate_p1(src.points, src.triangles, field, dst.points)
    want = np.column_stack([1.0 + 2.0 * b[:, 0] - 3.0 * b[:, 1], -b[:, 1]])
    assert np.abs(got - want).max() < 1e-12
    # the two inscribed polygons differ: some boundary vertices of dst lie outside src, and are extended
    _, lam = locate(src.points, src.triangles, dst.points)
    assert (lam.min(axis=1) < -1e-9).any() and lam.min() > -0.05
    # a quadratic field is not reproduced: P1 on src, whose edges ℓ ~ 0.2, errs by up to ~ℓ²/4 for |x|²
    quad = interpolate_p1(src.points, src.triangles, (a ** 2).sum(1), dst.points)
    assert 1e-4 < np.abs(quad - (b ** 2).sum(1)).max() < 0.04


def test_p1_interpolation_refuses_a_curved_source_and_mismatched_values():
    m = disk(1.0, edge_length=0.3)
    bent = m.points.copy()
    bent[:, 2] = bent[:, 0] ** 2
    with pytest.raises(ValueError, match="must be flat"):
        interpolate_p1(bent, m.triangles, bent[:, 0], m.points)
    with pytest.raises(ValueError, match="one row per mesh vertex"):
        interpolate_p1(m.points, m.triangles, np.zeros(3), m.points)


def _free_disk():
    m = disk(1.0, edge_length=0.25, seed=3)
    return ShellModel(m, Material(1.0, 0.3), uniform_growth(m.points, m.triangles, 0.05, 0.02))


def test_positions_moved_rigidly_give_back_the_pinned_state():
    model = _free_disk()
    x = model.mesh.points.copy()
    x[:, 2] = 0.1 * (x[:, 0] ** 2 - 0.5 * x[:, 1] ** 2)       # a saddle, zero edge unknowns
    x[:, :2] *= 1.01
    u = model.unknowns_from_positions(x)
    moved = Rotation.from_rotvec([0.3, -0.2, 0.5]).apply(model.positions(u)) + [1.0, -2.0, 0.5]
    u2 = model.unknowns_from_positions(moved)
    assert np.abs(model.positions(u2) - model.positions(u)).max() < 1e-10
    assert abs(model.energy(u2) - model.energy(u)) <= 1e-12 * model.energy(u)
    with pytest.raises(ValueError, match=r"\(.*, 3\) array"):
        model.unknowns_from_positions(x[:-1])


def test_a_buckled_state_carried_to_a_finer_mesh_relaxes_to_that_mesh_s_own_equilibrium():
    """A buckled state of a free disk with a grown centre, carried to a finer mesh of the same disk: Newton from it
    reaches the equilibrium that the finer mesh's own solve (from the same pushed flat start) reaches."""
    def model_of(edge):
        m = disk(1.0, edge_length=edge, inner_radius=0.5, inner_edge_length=edge, refine_inside=True, seed=4)
        a0 = metric(m.points, m.triangles)
        inside = np.hypot(*m.points[m.triangles].mean(1)[:, :2].T) < 0.5
        grown = a0 * np.where(inside, 1.04, 1.0)[:, None, None]
        return ShellModel(m, Material(1.0, 0.3), RestState(grown, np.zeros_like(a0), 0.02))

    def buckled(model):
        x = model.positions(model.initial_unknowns())
        x[:, 2] += 0.05 * np.maximum(0.0, 1.0 - (x[:, :2] ** 2).sum(1) / 0.25)    # off the flat saddle
        return minimize(model, model.unknowns_from_positions(x), stable=True, max_iter=100, log=None).u

    coarse, fine = model_of(0.1), model_of(0.07)
    uc = buckled(coarse)
    assert coarse.energy(uc) < 0.2 * coarse.energy(coarse.initial_unknowns())
    xf = interpolate_p1(coarse.mesh.points, coarse.mesh.triangles, coarse.positions(uc), fine.mesh.points)
    carried = minimize(fine, fine.unknowns_from_positions(xf), stable=True, max_iter=100, log=None)
    own = buckled(fine)
    assert carried.converged and abs(fine.energy(carried.u) / fine.energy(own) - 1.0) < 1e-9
    assert np.abs(fine.positions(carried.u) - fine.positions(own)).max() < 1e-6
