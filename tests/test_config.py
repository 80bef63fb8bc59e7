"""Process settings: nothing at import, everything through femshell.configure()."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest


def _run(code, **env_changes):
    env = {k: v for k, v in os.environ.items()
           if k not in env_changes and not k.startswith("JAX_") and k != "OPENBLAS_NUM_THREADS"}
    env.update({k: v for k, v in env_changes.items() if v is not None})
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_importing_femshell_changes_no_process_setting():
    # the environment and every jax.config entry are the same before and after importing the package,
    # the shell (element kernels, loads), the mesh and the analysis
    code = """
import json, os, jax
env, cfg = dict(os.environ), {k: repr(v) for k, v in jax.config.values.items()}
import femshell, femshell.shell, femshell.shell.element, femshell.shell.loads, femshell.mesh, femshell.analysis
now = {k: repr(v) for k, v in jax.config.values.items()}
print(json.dumps({"env": sorted(set(os.environ.items()) ^ set(env.items())),
                  "jax": sorted(k for k in set(cfg) | set(now) if cfg.get(k) != now.get(k))}))
"""
    assert _run(code) == {"env": [], "jax": []}


def test_kernels_compute_in_float64_without_the_global_switch():
    # x64 stays off globally, yet energies, gradients and Hessians are float64: an energy difference
    # of 1e-12 relative (below float32's 6e-8) is resolved
    import jax

    from femshell.mesh import sphere
    from femshell.shell import Material, ShellModel, natural_curvature

    assert not jax.config.jax_enable_x64
    mesh = sphere(3.0, n_vertices=300)
    model = ShellModel(mesh, Material(), natural_curvature(mesh.points, mesh.triangles, 0.1, 1 / 3.0))
    u = model.initial_unknowns() + 1e-3 * np.random.default_rng(0).standard_normal(model.n_free)
    e, g = model.energy_and_gradient(u)
    assert g.dtype == np.float64 and model.hessian(u).dtype == np.float64
    du = 1e-12 * np.abs(u).max() * np.sign(g)
    assert model.energy(u + du) - model.energy(u) == pytest.approx(g @ du, rel=1e-3)
    assert not jax.config.jax_enable_x64                 # the kernels switched float64 on only around their calls


@pytest.mark.parametrize("given, expected", [(None, "1"), ("3", "3")])
def test_configure_puts_numpys_blas_on_one_thread_unless_the_environment_says(given, expected):
    # OpenBLAS's idle worker spins after each vector product and takes a core from the sparse solves
    code = "import json, os, femshell; femshell.configure(); import numpy; print(json.dumps(os.environ.get('OPENBLAS_NUM_THREADS')))"
    assert _run(code, OPENBLAS_NUM_THREADS=given) == expected


def test_the_cli_configures_the_process(tmp_path):
    code = ("import json, os, femshell.cli; femshell.cli.main([]); "
            "print(json.dumps([os.environ.get('OPENBLAS_NUM_THREADS'), os.environ.get('JAX_COMPILATION_CACHE_DIR')]))")
    assert _run(code, XDG_CACHE_HOME=str(tmp_path), FEMSHELL_JAX_CACHE=None) == ["1", str(tmp_path / "femshell-jax")]


def test_configure_threads_and_jax_cache(tmp_path):
    # before jax is imported the cache goes through jax's own variables (no import cost), after it
    # through jax.config, where a directory already set is kept
    code = f"""
import json, os, femshell
out = [femshell.configure(blas_threads=None, threads=2, jax_cache_dir={str(tmp_path / 'a')!r})]
import jax
out.append(jax.config.jax_compilation_cache_dir)
out.append(femshell.configure(jax_cache_dir={str(tmp_path / 'b')!r})["jax_compilation_cache_dir"])
from femshell.shell.element import element_threads
out.append(element_threads())
print(json.dumps(out))
"""
    a = str(tmp_path / "a")
    assert _run(code) == [{"FEMSHELL_THREADS": "2", "MKL_NUM_THREADS": "2", "JAX_COMPILATION_CACHE_DIR": a}, a, a, 2]


@pytest.mark.parametrize("kwargs, message", [({"threads": 0}, "threads must be a whole number >= 1"),
                                             ({"blas_threads": 1.5}, "blas_threads must be a whole number >= 1")])
def test_configure_refuses_bad_counts(kwargs, message):
    import femshell

    with pytest.raises(ValueError, match=message):
        femshell.configure(jax_cache_dir=False, **kwargs)
