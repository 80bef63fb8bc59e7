"""The compiled C element kernel (femshell.shell.fast_element) against the JAX reference."""

import jax
import numpy as np
import pytest

from femshell.mesh.generators import plate, sphere
from femshell.shell import (Clamped, Material, RestState, ShellModel, SimplySupported, Symmetry, metric,
                            natural_curvature, uniform_growth)
from femshell.shell import element as el
from femshell.shell import fast_element

from test_shell_derivatives import _central


@pytest.fixture(scope="module")
def square():
    return plate(1.0, 1.0, edge_length=0.2, structured=True, diagonal="alternate")


def _grown_model(mesh, law, bcs, seed):
    """A model with anisotropic growth, rest curvature and a thickness that varies per element,
    at a randomly perturbed state."""
    rng = np.random.default_rng(seed)
    rest = uniform_growth(mesh.points, mesh.triangles, thickness=0.1, strain=0.2, k0=0.7)
    thickness = 0.1 * (1.0 + 0.5 * rng.random(mesh.n_triangles))
    rest = RestState(rest.metric * [[1.1, 1.0], [1.0, 1.0]], rest.curvature, thickness)
    model = ShellModel(mesh, Material(1.0, 0.35, law=law), rest, bcs, remove_rigid_modes=False)
    return model, model.initial_unknowns() + 0.05 * rng.standard_normal(model.n_free)


@pytest.mark.parametrize("law", ["svk", "neo-hookean"])
@pytest.mark.parametrize("bcs", [
    [],
    [Clamped("left"), SimplySupported("bottom")],
    [Symmetry("x"), Symmetry("y", 0.0), Clamped("top")],
])
def test_compiled_element_equals_jax(square, law, bcs):
    """Energies, gradients and Hessians of every element (interior, free, clamped and symmetry
    edges) equal JAX's automatic derivatives of element_energy to 1e-12 of their largest entry."""
    model, u = _grown_model(square, law, bcs, seed=3)
    args = model._element_args(model.full(u))
    kinds = set(np.unique(model.edge_kind_el))
    assert kinds >= ({el.INTERIOR, el.FREE} if not bcs else {el.INTERIOR, el.CLAMPED})
    assert el.SYMMETRY in kinds or not any(isinstance(b, Symmetry) for b in bcs)

    def energy(*a):
        return el.element_energy(*a, law=el.membrane_law(law))

    with el.float64():
        batched = [jax.jit(jax.vmap(f, in_axes=el._AXES)) for f in (energy, jax.grad(energy), jax.hessian(energy))]
        e_ref, g_ref, h_ref = (np.asarray(f(*args)) for f in batched)
    e, g, h = fast_element.hessians(law, *args, with_gradients=True)
    assert np.abs(e - e_ref).max() <= 1e-12 * np.abs(e_ref).max()
    assert np.all(np.abs(g - g_ref) <= 1e-12 * np.abs(g_ref).max(axis=1)[:, None])
    assert np.all(np.abs(h - h_ref) <= 1e-12 * np.abs(h_ref).max(axis=(1, 2))[:, None, None])
    assert np.array_equal(h, np.swapaxes(h, 1, 2))                      # exactly symmetric
    np.testing.assert_array_equal(fast_element.hessians(law, *args), h)
    e_only, g_only = fast_element.energies_and_gradients(law, *args)    # the reverse sweeps alone: the same bits
    np.testing.assert_array_equal(e_only, e)
    np.testing.assert_array_equal(g_only, g)


def test_model_hessian_compiled_by_default_and_jax_on_request(square):
    model, u = _grown_model(square, "neo-hookean", [Clamped("left")], seed=4)
    assert model.hessian_kernel == "compiled"
    K = model.hessian(u)
    model.hessian_kernel = "jax"
    K_jax = model.hessian(u)
    assert np.array_equal(K.indices, K_jax.indices) and np.array_equal(K.indptr, K_jax.indptr)
    assert np.abs(K.data - K_jax.data).max() <= 1e-12 * np.abs(K_jax.data).max()
    with pytest.raises(ValueError, match=r"hessian_kernel must be one of \('compiled', 'jax'\), got 'numba'"):
        ShellModel(square, Material(), model.rest, hessian_kernel="numba")


def test_model_energy_and_gradient_compiled_by_default_and_jax_on_request(square):
    """The model's energy and gradient come from the compiled kernel (energy() and energy_and_gradient()'s energy
    then agree bit for bit), equal to the JAX reference's to rounding."""
    model, u = _grown_model(square, "svk", [Clamped("left")], seed=7)
    assert model.gradient_kernel == "compiled"
    e, g = model.energy_and_gradient(u)
    assert e == model.energy(u)
    np.testing.assert_array_equal(g, model.gradient(u))
    model.gradient_kernel = "jax"
    e_jax, g_jax = model.energy_and_gradient(u)
    assert abs(e - e_jax) <= 1e-12 * abs(e_jax) and abs(model.energy(u) - e_jax) <= 1e-12 * abs(e_jax)
    assert np.abs(g - g_jax).max() <= 1e-12 * np.abs(g_jax).max()
    with pytest.raises(ValueError, match=r"gradient_kernel must be one of \('compiled', 'jax'\), got 'numba'"):
        ShellModel(square, Material(), model.rest, gradient_kernel="numba")


def test_jax_hessian_against_finite_differences():
    """The reference path keeps its own finite-difference check (curved, grown sphere, both laws)."""
    mesh = sphere(radius=2.0, n_vertices=150)
    rng = np.random.default_rng(6)
    rest = RestState(1.3 * metric(mesh.points, mesh.triangles), 0.4 * metric(mesh.points, mesh.triangles),
                     0.2 * (1.0 + rng.random(mesh.n_triangles)))
    for law in ("svk", "neo-hookean"):
        model = ShellModel(mesh, Material(1.0, 0.3, law=law), rest, hessian_kernel="jax")
        u = model.initial_unknowns() + 0.02 * rng.standard_normal(model.n_free)
        d = rng.standard_normal(u.shape)
        fd = _central(model.gradient, u, d, 1e-6)
        assert np.linalg.norm(fd - model.hessian(u) @ d) <= 1e-6 * np.linalg.norm(fd)


def test_chunks_on_threads_give_the_same_bits():
    from concurrent.futures import ThreadPoolExecutor

    mesh = sphere(3.0, n_vertices=2500)
    model = ShellModel(mesh, Material(1.0, 0.3), natural_curvature(mesh.points, mesh.triangles, 0.1, 1 / 3.0))
    u = model.initial_unknowns() + 1e-3 * np.random.default_rng(0).standard_normal(model.n_free)
    args = model._element_args(model.full(u))
    assert mesh.n_triangles > 2 * fast_element.CHUNK
    with ThreadPoolExecutor(3) as pool:
        np.testing.assert_array_equal(fast_element.hessians("svk", *args, executor=pool),
                                      fast_element.hessians("svk", *args))
        for threaded, alone in zip(fast_element.energies_and_gradients("svk", *args, executor=pool),
                                   fast_element.energies_and_gradients("svk", *args)):
            np.testing.assert_array_equal(threaded, alone)


def test_without_a_compiler_the_jax_path_serves(square, monkeypatch, tmp_path):
    monkeypatch.setenv("CC", str(tmp_path / "no-such-compiler"))
    monkeypatch.setenv("FEMSHELL_KERNEL_CACHE", str(tmp_path / "cache"))
    with pytest.raises(OSError, match="no-such-compiler"):
        fast_element._build()
    monkeypatch.setitem(fast_element._state, "lib", None)
    monkeypatch.setitem(fast_element._state, "error", "no compiler")
    assert fast_element.unavailable() == "no compiler"
    model, u = _grown_model(square, "svk", [], seed=5)
    K = model.hessian(u)                                                # falls back to JAX
    e, g = model.energy_and_gradient(u)
    model.hessian_kernel = model.gradient_kernel = "jax"
    np.testing.assert_array_equal(K.data, model.hessian(u).data)
    assert (e, g.tolist()) == (model.energy_and_gradient(u)[0], model.energy_and_gradient(u)[1].tolist())
    with pytest.raises(RuntimeError, match="compiled element kernel is unavailable: no compiler"):
        fast_element.hessians("svk", *model._element_args(model.full(u)))


def test_warmup_command_builds_the_kernels_into_the_caches(monkeypatch, tmp_path, capsys):
    import threading

    from femshell.cli import main

    monkeypatch.setenv("FEMSHELL_KERNEL_CACHE", str(tmp_path / "kernels"))
    monkeypatch.setattr(fast_element, "_state", {"lib": None, "error": None, "lock": threading.Lock()})
    assert main(["warmup"]) == 0
    out = capsys.readouterr().out
    assert "C element Hessian:" in out and "svk law" in out and "neo-hookean law" in out
    assert str(tmp_path / "kernels") in out
    built = list((tmp_path / "kernels").glob("element-hessian-*.so"))
    assert built == [fast_element.library_path()[0]]
