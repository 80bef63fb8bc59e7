"""femshell.coupled.stationary: the stationary coupled system in (u, c), its Jacobian and Newton (theory §2.9).

Small spheres (R = 5, 200 and 400 vertices, h0 = 0.5) with the milder contractility ratio of
tests/test_coupled.py (Λmin = 13.5).
"""

import numpy as np
import pytest
from scipy.linalg import eigh

from femshell.chemistry import ReactionDiffusion
from femshell.coupled import (CoupledLoop, InitialSpot, MechanochemicalModel, StationaryProblem, TimeStepping,
                              coupled_stability, stationary_state)
from femshell.mesh.generators import sphere
from femshell.solvers.linear import factorize

R = 5.0


@pytest.fixture(scope="module")
def small_ball():
    return sphere(R, n_vertices=200, seed=0)


def perturbed_problem(mesh, thickness_mode, seed=1):
    """A problem at a random state: shape off equilibrium (H of both signs), c across the switch
    (b = 20 makes ds/dc large over the whole range), D > 0 so that every term is present."""
    p = MechanochemicalModel(h0=0.5, radius=R, lam_min=13.5, D=0.3, b=20.0, thickness_mode=thickness_mode)
    loop = CoupledLoop(mesh, p, TimeStepping(), equilibrate=False, log=None)
    problem = StationaryProblem.of_loop(loop)
    rng = np.random.default_rng(seed)
    z = problem.join(loop.u + 0.03 * rng.standard_normal(problem.n_u), rng.uniform(0.0, 0.3, problem.n_c))
    return problem, z, rng


@pytest.mark.parametrize("thickness_mode", ["volume", "uniform"])
def test_each_jacobian_block_matches_central_differences(small_ball, thickness_mode):
    problem, z, rng = perturbed_problem(small_ball, thickness_mode)
    u, c = problem.split(z)
    _, H = problem.growth.mean_curvature(u)
    assert H.min() < 0 < H.max()                      # the source's both branches are exercised
    J = problem.jacobian(z)
    n_u = problem.n_u
    parts = {"shell Hessian": (slice(0, n_u), slice(0, n_u)), "dF_u/dc": (slice(0, n_u), slice(n_u, None)),
             "dF_c/du": (slice(n_u, None), slice(0, n_u)), "dF_c/dc": (slice(n_u, None), slice(n_u, None))}
    eps = 1e-6
    for name, (rows, cols) in parts.items():
        v = np.zeros(len(z))
        v[cols] = rng.standard_normal(len(z))[cols]
        exact = (J @ v)[rows]
        fd = (problem.residual(z + eps * v) - problem.residual(z - eps * v))[rows] / (2 * eps)
        assert np.linalg.norm(exact) > 1e-3 * np.linalg.norm(problem.residual(z)[rows]), name
        assert np.linalg.norm(fd - exact) <= 1e-6 * np.linalg.norm(exact), name


def test_the_chemistry_residual_is_what_the_time_step_changes(small_ball):
    # the loop's step (M + γ D K) c⁺ = M (c e^{−β dt} + γ P) has (M + γ D K)(c⁺ − c) = γ F_c exactly
    # (e^{−β dt} − 1 + γ β = 0): F_c = 0 iff the step leaves c as it is
    problem, z, _ = perturbed_problem(small_ball, "volume")
    u, c = problem.split(z)
    f_c = problem.residual(z)[problem.n_u:]
    p, points = problem.params, problem.shell.positions(u)
    rd = ReactionDiffusion(small_ball.triangles, small_ball.n_vertices, D=p.D, beta=p.beta, points=points,
                           factorize=factorize, nonnegative=False)
    _, H = problem.growth.mean_curvature(u)
    dt = 0.5
    gamma = -np.expm1(-p.beta * dt) / p.beta
    change = rd.step(c, dt, source=p.source(H)) - c
    lhs = problem.chemistry.mass_lumped(points) * change + gamma * p.D * (problem.chemistry.stiffness(points) @ change)
    assert np.abs(lhs - gamma * f_c).max() <= 1e-12 * np.abs(f_c).max()
    assert np.abs(f_c).max() > 1e-2                     # not trivially zero


def test_bad_input_is_named(small_ball):
    problem, z, _ = perturbed_problem(small_ball, "volume")
    with pytest.raises(ValueError, match=rf"z must have {problem.n_u} shell unknowns and {problem.n_c} concentrations"):
        problem.residual(z[:-1])
    loop = CoupledLoop(small_ball, problem.params, TimeStepping(), equilibrate=False, log=None)
    with pytest.raises(ValueError, match=r"tol must be a finite number in \(0, inf\)"):
        stationary_state(loop, tol=0.0)


@pytest.fixture(scope="module")
def stationary_run():
    """A spot that a time run makes stationary (D = 0): rate test at the loop's default 1e-3."""
    mesh = sphere(R, n_vertices=400, seed=0)
    p = MechanochemicalModel(h0=0.5, radius=R, lam_min=13.5, D=0.0)
    st = TimeStepping(t_final=80.0, dt_initial=0.05, ramp_ds=0.2)
    loop = CoupledLoop(mesh, p, st, c0=InitialSpot(amplitude=0.3, width=1.0), log=None)
    result = loop.run()
    assert result.status == "stationary"
    return loop


def test_newton_reproduces_the_time_run_s_stationary_spot(stationary_run):
    loop = stationary_run
    st, p = loop.stepping, loop.params
    c_time, x_time = loop.c.copy(), loop.points.copy()
    problem = StationaryProblem.of_loop(loop)
    force0, rate0 = problem.residual_norms(problem.join(loop.u, loop.c))
    assert rate0 <= st.stationary_rate_c                  # the time run's end is a root to its own tolerance
    root = stationary_state(loop, tol=1e-9, problem=problem)
    assert root.converged and root.iterations <= 4, root.message
    assert max(root.history[-1]) <= 1e-9
    assert np.array_equal(loop.c, c_time)                 # the loop's state is untouched
    # the same spot, to the distance the stationarity tolerance allows: a rate below r per unit time
    # is at most r c_scale / β from a fixed point that relaxes at least at β (D = 0: c = P/β)
    c_scale = max(c_time.max(), 1e-2 * p.c_max)
    assert np.abs(root.c - c_time).max() <= st.stationary_rate_c * c_scale / p.beta
    assert np.abs(problem.shell.positions(root.u) - x_time).max() <= st.stationary_rate_x * p.h0 / p.beta
    assert np.array_equal(root.c > p.c_star, c_time > p.c_star) and (root.c > p.c_star).sum() >= 3
    # and the root is a fixed point of the loop itself: one more time step does not move it
    assert root.c.min() > -1e-12 * c_scale                # c = P/β ≥ 0 at a root, up to round-off
    loop.load_state_dict({**loop.state_dict(), "c": np.maximum(root.c, 0.0), "u": root.u})
    record = loop.advance()
    assert record.rate_c < 1e-7 and record.rate_x < 1e-7


def test_command_line_from_a_run_directory(tmp_path, capsys):
    import json

    from femshell.cli import main

    scene = tmp_path / "ball.toml"
    scene.write_text('[mesh]\nkind = "sphere"\nradius = 5.0\nn_vertices = 150\n[shell]\nthickness = 1.0\n'
                     '[growth]\nlaw = "contractility"\n[chemistry]\nD = 0.2\n[initial]\nkind = "none"\n'
                     '[solver]\nkind = "time"\nt_final = 10.0\n[output]\npictures = false\n')
    out = tmp_path / "run"
    assert main(["run", str(scene), "--out", str(out), "-q"]) == 0
    capsys.readouterr()
    assert main(["stationary", "--from", str(out)]) == 0
    said = capsys.readouterr().out
    assert "converged in" in said and "newton  0" in said
    result = json.loads((out / "stationary.json").read_text())
    assert result["converged"] and max(result["history"][-1].values()) <= 1e-9
    assert (out / "stationary.vtu").is_file()
    assert main(["stationary", "--from", str(tmp_path / "none")]) == 2
    assert "no such directory (give the --out of a femshell run)" in capsys.readouterr().err
    assert main(["stationary", "--from", str(out), "--max-iter", "-1"]) == 2
    assert "--max-iter must be >= 0, got -1" in capsys.readouterr().err


# ----------------------------------------------------------------------------- stability in the coupled dynamics

def test_stability_of_the_untouched_sphere_is_the_chemistry_s_own_decay(small_ball):
    # c = 0 on the drawn sphere: H = 0, P = P' = 0, so ∂F_c/∂u = 0 and S = −β M − D K: μ_k = −β − D λ_k
    # with λ_k the eigenvalues of (K, M) (0, then the l = 1 triplet ≈ 2/R², ...)
    p = MechanochemicalModel(h0=0.5, radius=R, lam_min=13.5, D=0.3)
    loop = CoupledLoop(small_ball, p, TimeStepping(), equilibrate=False, log=None)
    problem = StationaryProblem.of_loop(loop)
    result = coupled_stability(problem, loop.u, loop.c, k=7)
    points = problem.shell.positions(loop.u)
    lam = eigh(problem.chemistry.stiffness(points).toarray(), np.diag(problem.chemistry.mass_lumped(points)),
               eigvals_only=True)[:7]
    assert np.allclose(result.eigenvalues, -p.beta - p.D * lam, rtol=1e-10, atol=1e-12)
    assert lam[1] * R**2 == pytest.approx(2.0, rel=0.05)       # the l = 1 harmonics on the sphere
    assert result.stable and result.n_negative_mechanical == 0 and result.method == "dense"


def test_stability_of_the_stationary_spot_predicts_the_time_loop_s_decay(stationary_run):
    loop = stationary_run
    problem = StationaryProblem.of_loop(loop)
    root = stationary_state(loop, problem=problem)
    dense = coupled_stability(problem, root.u, root.c, k=6, method="dense")
    assert dense.stable                                     # the time run went there: it is an attractor
    assert dense.c_modes.shape == (problem.n_c, 6) and dense.shape_modes.shape == (problem.n_u, 6)
    arpack = coupled_stability(problem, root.u, root.c, k=6, method="shift-invert")
    # the same six, up to which of a complex pair a cut at six keeps
    for a, b in zip(arpack.eigenvalues, dense.eigenvalues):
        assert a.real == pytest.approx(b.real, rel=1e-8) and abs(a.imag) == pytest.approx(abs(b.imag), abs=1e-8)
    # the loop from the root plus a small multiple of the leading mode decays at Re μ1 (first order in dt)
    mu, mode = dense.leading.real, np.real(dense.c_modes[:, 0])
    assert -loop.params.beta < mu < 0                      # the spot's feedback slows the decay below β's
    dt = 0.05                                               # the loop's rate is 1 % off μ1 here
    stepping = TimeStepping(t_final=2.0, dt_initial=dt, dt_max=dt, dt_min=dt / 10, stationary_rate_c=0.0,
                            feedback_amplification=0.0)
    perturbed = CoupledLoop.from_state_dict(loop.mesh, loop.params, {**loop.state_dict(), "u": root.u, "dt": dt, "t": 0.0, "step": 0,
                                            "c": np.maximum(root.c + 1e-3 * root.c.max() * mode, 0.0)}, stepping)
    t, amplitude = [], []
    for _ in perturbed.iterate():
        t.append(perturbed.t)
        amplitude.append(abs(np.dot(perturbed.c - root.c, mode)))
    t, amplitude = np.array(t), np.array(amplitude)
    rate = np.polyfit(t[t > 1.0], np.log(amplitude[t > 1.0]), 1)[0]
    assert rate == pytest.approx(mu, rel=0.02)
