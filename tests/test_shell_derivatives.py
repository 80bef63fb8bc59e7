"""Exact gradient and Hessian of the shell energy against central finite differences."""

import numpy as np
import pytest

from femshell.mesh.generators import plate, sphere
from femshell.shell import (Clamped, EdgeMoment, FollowerPressure, Material, PointForce, Prescribed, RestState,
                            ShellModel, SimplySupported, Symmetry, metric, natural_curvature, uniform_growth)


def _central(f, u, d, eps):
    """Fourth-order central difference of f along d (error O(eps^4))."""
    return (-f(u + 2 * eps * d) + 8 * f(u + eps * d) - 8 * f(u - eps * d) + f(u - 2 * eps * d)) / (12 * eps)


def _fd_check(model, u, rng, eps=1e-6):
    d = rng.standard_normal(u.shape)
    g = model.gradient(u)
    fd_g = _central(model.energy, u, d, eps)
    assert fd_g == pytest.approx(g @ d, rel=1e-7, abs=1e-10 * np.abs(g).sum())
    e_both, g_both = model.energy_and_gradient(u)     # the line search's one-pass pair
    assert e_both == pytest.approx(model.energy(u), rel=1e-13, abs=1e-15)
    np.testing.assert_array_equal(g_both, g)
    H = model.hessian(u)
    fd_h = _central(model.gradient, u, d, eps)
    assert np.linalg.norm(fd_h - H @ d) <= 1e-6 * np.linalg.norm(fd_h)
    assert abs(H - H.T).max() <= 1e-12 * abs(H).max()


@pytest.fixture(scope="module")
def square():
    return plate(1.0, 1.0, edge_length=0.2, structured=True, diagonal="alternate")


@pytest.mark.parametrize("bcs", [
    [],
    [Clamped("left")],
    [SimplySupported("left"), Clamped("bottom")],
    [Symmetry("x"), Symmetry("y", 0.0), Prescribed("top", components=(2,))],
])
def test_plate_derivatives_all_boundary_kinds(square, bcs):
    rng = np.random.default_rng(0)
    # grown, naturally curved, anisotropically stretched targets
    rest = uniform_growth(square.points, square.triangles, thickness=0.1, strain=0.2, k0=0.7)
    rest = RestState(rest.metric * [[1.1, 1.0], [1.0, 1.0]], rest.curvature, rest.thickness)
    model = ShellModel(square, Material(1.0, 0.35), rest, bcs, remove_rigid_modes=False)
    u = model.initial_unknowns() + 0.05 * rng.standard_normal(model.n_free)
    _fd_check(model, u, rng)


def test_plate_with_loads_derivatives(square):
    rng = np.random.default_rng(1)
    rest = natural_curvature(square.points, square.triangles, 0.05, 0.3)
    loads = [EdgeMoment("right", 0.7), PointForce(square, [3, 5], (0.1, -0.2, 0.3)), FollowerPressure(0.4)]
    model = ShellModel(square, Material(1.0, 0.0), rest, [Clamped("left")], loads)
    model.load_factor = 1.7
    u = model.initial_unknowns() + 0.05 * rng.standard_normal(model.n_free)
    _fd_check(model, u, rng)


def test_loads_keep_the_shells_hessian_pattern(square):
    """On the flat state the coupling entries are exact zeros; a sparse sum with the loads' matrices
    dropped them, and every load step handed the factorisation a new pattern to analyse."""
    rest = natural_curvature(square.points, square.triangles, 0.05, 0.0)
    loads = [EdgeMoment("right", 0.7), FollowerPressure(0.4)]
    model = ShellModel(square, Material(1.0, 0.0), rest, [Clamped("left")], loads)
    model.load_factor = 0.3
    u = model.initial_unknowns()
    K = model.hessian(u)
    assert K.nnz == model.assembler.nnz and np.array_equal(K.indices, model.assembler.indices)
    bare = ShellModel(square, Material(1.0, 0.0), rest, [Clamped("left")]).hessian(u)
    added = sum(model._load_assemblers[i][0].matrix(load.hessian_blocks(model.full(u))[1])
                for i, load in enumerate(loads))
    np.testing.assert_allclose(K.toarray(), (bare - 0.3 * added).toarray(), rtol=0, atol=1e-14 * abs(K).max())


def test_sphere_derivatives_curved_state():
    rng = np.random.default_rng(2)
    mesh = sphere(radius=2.0, n_vertices=150)
    rest = RestState(1.3 * metric(mesh.points, mesh.triangles), 0.4 * metric(mesh.points, mesh.triangles), 0.2)
    model = ShellModel(mesh, Material(1.0, 0.5), rest, loads=[FollowerPressure(0.1)])
    u = model.initial_unknowns() + 0.02 * rng.standard_normal(model.n_free)
    _fd_check(model, u, rng)


def test_sphere_bending_measures_its_own_curvature():
    """b = a / R on a fine sphere with outward normals (H = 1/R), to discretisation accuracy."""
    from femshell.geometry import mean_curvature

    mesh = sphere(radius=3.0, n_vertices=2000)
    model = ShellModel(mesh, Material(), natural_curvature(mesh.points, mesh.triangles, 0.1, 0.0))
    a, b = model.fundamental_forms(model.initial_unknowns())
    H = mean_curvature(a, b)
    assert np.median(H) == pytest.approx(1 / 3.0, rel=0.02)


@pytest.mark.parametrize("bcs", [
    [],
    [Clamped("left"), SimplySupported("bottom")],
    [Symmetry("x"), Symmetry("y", 0.0), Clamped("top")],
])
def test_split_element_hessian_equals_autodiff_hessian(square, bcs):
    """The split Hessian (metric + 13-unknown edge parts) is jax.hessian of the element energy."""
    import jax

    from femshell.shell import element as el

    rng = np.random.default_rng(3)
    rest = uniform_growth(square.points, square.triangles, thickness=0.1, strain=0.2, k0=0.7)
    rest = RestState(rest.metric * [[1.1, 1.0], [1.0, 1.0]], rest.curvature, rest.thickness)
    model = ShellModel(square, Material(1.0, 0.35), rest, bcs, remove_rigid_modes=False)
    q = model.full(model.initial_unknowns() + 0.05 * rng.standard_normal(model.n_free))
    args = model._element_args(q)
    with el.float64():
        reference = np.asarray(jax.jit(jax.vmap(jax.hessian(el.element_energy), in_axes=el._AXES))(*args))
    interior = (model.edge_kind_el == el.INTERIOR).all(axis=1)
    scale = np.abs(reference).max(axis=(1, 2))[:, None, None]
    for H in (el.batch_hessian(*args), el.batch_hessian_grouped(interior, *args)):
        assert np.all(np.abs(np.asarray(H) - reference) <= 1e-12 * scale)
    if interior.any():
        H = el.batch_hessian_interior(*[np.asarray(a)[interior] if i not in (5, 6) else a for i, a in enumerate(args)])
        assert np.all(np.abs(H - reference[interior]) <= 1e-12 * scale[interior])


def test_hessian_exactly_symmetric_on_distorted_elements():
    """Badly distorted elements made the forward-over-reverse Hessian asymmetric by ~1e-10 here
    (1e-8 seen on a thick disk), which a symmetric factorisation refuses; it is symmetrised."""
    mesh = plate(1.0, 1.0, edge_length=0.1)
    rest = uniform_growth(mesh.points, mesh.triangles, thickness=0.5, strain=0.5, k0=0.0)
    model = ShellModel(mesh, Material(1.0, 0.5), rest, [], remove_rigid_modes=False)
    u = model.initial_unknowns() + 0.5 * np.random.default_rng(4).standard_normal(model.n_free)
    K = model.hessian(u)
    assert abs(K - K.T).max() == 0.0


def test_neo_hookean_derivatives_and_split_hessian(square):
    """The neo-Hookean law's gradient and Hessian against finite differences and jax.hessian."""
    import jax

    from femshell.shell import element as el

    rng = np.random.default_rng(5)
    rest = uniform_growth(square.points, square.triangles, thickness=0.1, strain=0.2, k0=0.7)
    rest = RestState(rest.metric * [[1.1, 1.0], [1.0, 1.0]], rest.curvature, rest.thickness)
    model = ShellModel(square, Material(1.0, 0.35, law="neo-hookean"), rest, [Clamped("left")],
                       remove_rigid_modes=False)
    u = model.initial_unknowns() + 0.05 * rng.standard_normal(model.n_free)
    _fd_check(model, u, rng)
    q = model.full(u)
    args = model._element_args(q)

    def energy(*a):
        return el.element_energy(*a, law=el.NeoHookean)

    with el.float64():
        reference = np.asarray(jax.jit(jax.vmap(jax.hessian(energy), in_axes=el._AXES))(*args))
    interior = (model.edge_kind_el == el.INTERIOR).all(axis=1)
    H = np.asarray(el.kernels("neo-hookean").hessian_grouped(interior, *args))
    assert np.all(np.abs(H - reference) <= 1e-12 * np.abs(reference).max(axis=(1, 2))[:, None, None])


def test_neo_hookean_agrees_with_svk_to_second_order():
    """ψ_NH − ψ_SVK = O(strain³): halving a random strain divides the difference by ~8."""
    from femshell.shell import element as el

    rng = np.random.default_rng(6)
    G = rng.standard_normal((2, 2))
    E0 = 0.5 * (G + G.T)
    alpha, beta = 0.35 / (1 - 0.35**2), 1 / (2 * 1.35)
    diffs = []
    for t in (1e-2, 5e-3):
        C = np.eye(2) + 2 * t * E0
        with el.float64():
            svk = float(el.StVenantKirchhoff.membrane(C, alpha, beta))
            neo_hookean = float(el.NeoHookean.membrane(C, alpha, beta))
        assert svk == pytest.approx(alpha / 2 * np.trace(t * E0) ** 2 + beta * np.trace(t * E0 @ (t * E0)), rel=1e-12)
        diffs.append(abs(neo_hookean - svk) / svk)
    assert diffs[1] == pytest.approx(diffs[0] / 2, rel=0.05)   # relative difference O(strain)


@pytest.mark.parametrize("law, stable", [("svk", False), ("neo-hookean", True)])
def test_compressed_membrane_ellipticity(law, stable):
    """A flat sheet held at stretch 0.8 of its target (below SVK's equibiaxial limit √(3/4) = 0.866 at
    ν = 0.5, disk_wrinkles.svk_ellipticity_stretch) with its positions fixed at the boundary: the
    in-plane Hessian has negative eigenvalues for SVK (material instability, mesh-scale modes)
    and none for neo-Hookean. Out-of-plane motion is pinned so only the membrane law is tested."""
    from femshell.solvers.linear import factorize
    from femshell.validation.disk_wrinkles import svk_ellipticity_stretch

    assert 0.8 < svk_ellipticity_stretch(0.5)
    mesh = plate(1.0, 1.0, edge_length=0.1)
    rest = uniform_growth(mesh.points, mesh.triangles, thickness=0.01, strain=1 / 0.8 - 1, k0=0.0)
    model = ShellModel(mesh, Material(1.0, 0.5, law=law), rest,
                       [Clamped("left"), Clamped("right"), Clamped("top"), Clamped("bottom")],
                       remove_rigid_modes=False)
    K = model.hessian(model.initial_unknowns())
    n = mesh.n_vertices
    free_z = np.flatnonzero(model.free)
    in_plane = np.flatnonzero((free_z < 3 * n) & (free_z % 3 != 2))   # x, y of free vertices only
    n_negative = factorize(K[in_plane][:, in_plane].tocsc(), kind="symmetric_indefinite").inertia[1]
    assert (n_negative == 0) == stable
    n_flagged = len(model.non_elliptic_elements(model.initial_unknowns()))
    assert n_flagged == (0 if stable else len(mesh.triangles))


@pytest.mark.parametrize("nu", [0.3, 0.5])
def test_cheap_non_elliptic_check_agrees_with_the_full_acoustic_tensor(nu):
    """Material.non_elliptic (a lower bound, full evaluation only where it is negative) against
    ellipticity_margin < 0 on random metric ratios C = ā⁻¹a (not symmetric) and at the equibiaxial limit."""
    mat = Material(1.0, nu)
    rng = np.random.default_rng(3)
    F, G = rng.uniform(0.5, 1.3, (4000, 2, 2)), rng.uniform(0.5, 1.5, (4000, 2, 2))
    abar = np.einsum("nij,nkj->nik", G, G) + 0.1 * np.eye(2)               # rest metric
    a = np.einsum("nji,njk,nkl->nil", G, np.einsum("nij,nkj->nik", F, F), G)   # current metric
    C = np.linalg.solve(abar, a)
    full = mat.ellipticity_margin(C) < 0
    assert 0.1 < full.mean() < 0.9
    assert np.array_equal(mat.non_elliptic(C), full)
    lim2 = (mat.alpha + mat.beta) / (mat.alpha + 2 * mat.beta)
    assert mat.non_elliptic(np.stack([np.eye(2) * (lim2 - 1e-6), np.eye(2) * (lim2 + 1e-6)])).tolist() == [True, False]


def test_rigid_rotation_onto_the_stored_edge_normals_has_zero_gradient(square):
    """A flat plate turned by exactly 90 degrees about x: its y-edges lie along the rest face
    normal kept for every edge. A rigid motion: zero energy, zero (finite) gradient and Hessian."""
    model = ShellModel(square, Material(), natural_curvature(square.points, square.triangles, 0.1, 0.0),
                       remove_rigid_modes=False)
    p = square.points
    turned = np.column_stack([p[:, 0], -p[:, 2], p[:, 1]])
    u = np.concatenate([turned.ravel(), np.zeros(square.topology.n_edges)])[model.free]
    assert model.energy(u) < 1e-25
    g = model.gradient(u)
    assert np.all(np.isfinite(g)) and np.abs(g).max() < 1e-12
    assert np.all(np.isfinite(model.hessian(u).data))


def test_clamped_curved_edge_keeps_the_natural_shape_nearly_unbent():
    """A hemisphere whose rest curvature is its own (b̄ = ā/R) has zero bending energy in its drawn
    shape. Clamping the equator must not bend it: with every position held and the edge rotations
    relaxed, the energy left is a small fraction of that of bending a flat sheet into the
    hemisphere (the clamped rim held the face normals, off by O(h), before: 1.2e-2 at 215 vertices)."""
    import scipy.sparse.linalg as spla

    from femshell.mesh import hemisphere

    m = hemisphere(1.0, edge_length=0.2)
    held = Prescribed(vertices=tuple(range(m.n_vertices)))

    def relaxed_bending(k0, bcs):
        model = ShellModel(m, Material(nu=0.3), natural_curvature(m.points, m.triangles, 0.01, k0), bcs)
        u = model.initial_unknowns()
        for _ in range(6):
            u = u - spla.spsolve(model.hessian(u).tocsc(), model.gradient(u))
        return model.energy_parts(u)[1].sum()

    flat_into_sphere = relaxed_bending(0.0, [held])
    assert relaxed_bending(1.0, [held]) < 1e-4 * flat_into_sphere                 # free rim
    assert relaxed_bending(1.0, [held, Clamped("equator")]) < 3e-3 * flat_into_sphere


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_sparse_assembly_against_a_dense_sum(seed):
    # the cached scatter (pattern, positions, entries touching fixed unknowns dropped) against a plain dense sum;
    # repeated unknowns in an element (a boundary element's stand-in vertices) included
    from femshell.shell.assembly import SparseAssembler

    rng = np.random.default_rng(seed)
    n_total, m, k = 40, 30, 7
    dofs = rng.integers(0, n_total, size=(m, k))
    dofs[:, 1] = dofs[:, 0]                       # a repeated unknown inside each element
    free = rng.random(n_total) < 0.7
    free[dofs[0]] = True
    asm = SparseAssembler(dofs, free)
    E = rng.standard_normal((m, k, k))
    v = rng.standard_normal((m, k))
    dense, vec = np.zeros((n_total, n_total)), np.zeros(n_total)
    np.add.at(dense, (dofs[:, :, None], dofs[:, None, :]), E)
    np.add.at(vec, dofs, v)
    K = asm.matrix(E)
    assert K.has_sorted_indices            # free unknowns in no element leave empty rows here
    assert np.allclose(K.toarray(), dense[np.ix_(free, free)], rtol=1e-14, atol=1e-14)
    assert np.allclose(asm.vector(v), vec[free], rtol=1e-14, atol=1e-14)
    touched = np.zeros((n_total, n_total), bool)
    touched[dofs[:, :, None], dofs[:, None, :]] = True
    assert asm.nnz == touched[np.ix_(free, free)].sum()       # the pattern: exactly the pairs that share an element


def test_element_chunks_on_threads_give_the_same_bits(monkeypatch, tmp_path):
    # chunks of elements evaluated on several threads: the same energy, gradient and Hessian, bit for bit
    from femshell import config
    from femshell.shell import element

    mesh = sphere(3.0, n_vertices=600)
    model = ShellModel(mesh, Material(1.0, 0.3), natural_curvature(mesh.points, mesh.triangles, 0.1, 1 / 3.0))
    u = model.initial_unknowns() + 1e-3 * np.random.default_rng(0).standard_normal(model.n_free)
    out = {}
    for threads in ("1", "3"):
        monkeypatch.setenv("FEMSHELL_THREADS", threads)
        assert element.element_threads() == int(threads)
        out[threads] = (model.energy(u), model.gradient(u), model.hessian(u).data)
        pool = element._pool["executor"]
        model.hessian(u), model.gradient(u)
        assert element._pool["executor"] is pool          # one pool for calls of any chunk count (was remade)
    assert out["1"][0] == out["3"][0]
    assert np.array_equal(out["1"][1], out["3"][1]) and np.array_equal(out["1"][2], out["3"][2])
    assert len(mesh.triangles) > 2 * element.CHUNK_HESSIAN              # the Hessian did run in several chunks
    monkeypatch.delenv("FEMSHELL_THREADS")
    monkeypatch.setenv("MKL_NUM_THREADS", "1")
    assert element.element_threads() == 1                               # a process confined to one core stays there
    monkeypatch.setenv("MKL_NUM_THREADS", "0")
    monkeypatch.setenv("OMP_NUM_THREADS", "3,1")                       # OpenMP's nested form: 3 at the top
    assert element.element_threads() == 3
    # no variable set: the CPUs, within a container's limit (cgroup v2 "200000 100000": 2 CPUs; "max": none)
    monkeypatch.delenv("MKL_NUM_THREADS")
    monkeypatch.delenv("OMP_NUM_THREADS")
    limit = tmp_path / "cpu.max"
    monkeypatch.setattr(config, "CGROUP_CPU_FILES", ((str(limit),),))
    monkeypatch.setattr(config.os, "sched_getaffinity", lambda pid: set(range(16)))
    for text, expected in (("200000 100000", 2), ("50000 100000", 1), ("max 100000", 16)):
        limit.write_text(text + "\n")
        assert element.element_threads() == expected, text
    monkeypatch.setenv("FEMSHELL_THREADS", "two")
    with pytest.raises(ValueError, match="FEMSHELL_THREADS = 'two' must be a whole number >= 1"):
        element.element_threads()


def test_mid_edge_normal_cannot_turn_past_the_faces():
    """The edge unknown θ is the tangent of the turning angle: n_e = (m + θ t×m)/√(1 + θ²) is a unit
    vector turned by arctan θ, so n_e·m > 0 for every θ. An angle unknown (cos θ m + sin θ t×m) turns past
    ±π/2, where the normal reads a kink between its faces as curvature of the opposite sign (a spurious
    lower-energy state Newton found on a seeded disk at θ = 3.16; docs/studies/disk-crosscheck.md)."""
    from femshell.shell.bending import turned_normal
    from femshell.shell.element import float64
    rng = np.random.default_rng(3)
    m = rng.standard_normal(3)
    m /= np.linalg.norm(m)
    t = np.cross(m, rng.standard_normal(3))
    t /= np.linalg.norm(t)
    for theta in (-1e6, -3.16, -1.0, 0.0, 1e-4, 2.0, 3.16, 1e6):
        with float64():
            n = np.asarray(turned_normal(m, t, theta))
        assert np.linalg.norm(n) == pytest.approx(1.0, abs=1e-14)
        assert n @ m > 0
        assert np.arctan2(n @ np.cross(t, m), n @ m) == pytest.approx(np.arctan(theta), abs=1e-14)
