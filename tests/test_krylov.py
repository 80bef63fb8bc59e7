"""Krylov solves on a held factorisation (femshell.solvers.krylov) and Newton's refactorise-when-it-pays path:
the same equilibria as the direct path to the Newton tolerance, fewer factorisations, and never a saddle."""

import numpy as np
import pytest
import scipy.sparse as sp

from femshell.solvers.krylov import preconditioned_solve
from femshell.solvers.linear import Refactorizer, factorize
from femshell.solvers.newton import minimize

from test_newton_recovery import NonlinearChain


def _laplacian(n, shift):
    return (sp.diags([-np.ones(n - 1), 2 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1]) + shift * sp.identity(n)).tocsr()


def test_cg_on_a_positive_definite_factor_and_gmres_on_an_indefinite_one():
    n = 300
    rng = np.random.default_rng(0)
    b = rng.standard_normal(n)
    drift = sp.diags(0.02 * rng.random(n))                  # the new matrix: the old one, changed a little
    K0 = _laplacian(n, 0.05)
    out = preconditioned_solve((K0 + drift).tocsr(), factorize(K0, "spd"), b, rtol=1e-10, max_iter=40)
    assert out.method == "cg" and out.converged and 0 < out.iterations < 40
    assert np.linalg.norm((K0 + drift) @ out.x - b) <= 1e-10 * np.linalg.norm(b)
    # indefinite: an LDLᵀ factor (inertia with negative eigenvalues) preconditions GMRES
    K1 = _laplacian(n, -0.01)
    f1 = factorize(K1, "symmetric_indefinite")
    assert f1.inertia[1] > 0
    near = (K1 + 0.01 * drift).tocsr()                      # (K1's eigenvalue nearest zero is 9e-4)
    out = preconditioned_solve(near, f1, b, rtol=1e-10, max_iter=40)
    assert out.method == "gmres" and out.converged
    assert np.linalg.norm(near @ out.x - b) <= 1e-10 * np.linalg.norm(b)
    # an indefinite matrix with a positive definite factor: CG meets negative curvature and says so
    out = preconditioned_solve(K1, factorize(K0, "spd"), b, rtol=1e-10, max_iter=40)
    assert not out.converged and out.negative_curvature
    # too few iterations: not converged, judged by the true residual
    out = preconditioned_solve((K0 + 50 * drift).tocsr(), factorize(K0, "spd"), b, rtol=1e-12, max_iter=2)
    assert not out.converged and out.iterations == 2


def test_krylov_newton_reaches_the_direct_equilibrium_with_fewer_factorisations():
    prob = NonlinearChain(n=60)
    results = {}
    for path in ("direct", "krylov"):
        pair = (Refactorizer(), Refactorizer())
        u = np.zeros(prob.n)
        out = []
        for lam in (1.0, 1.1, 1.2):                          # a load stepping on one pair of factorizers
            prob.load_factor = lam
            res = minimize(prob, u, rtol=1e-10, stable=True, factorizers=pair, linear_solver=path, log=None)
            assert res.converged and res.stable
            out.append(res)
            u = res.u
        results[path] = out
        for f in pair:
            f.free()
    for d, k in zip(results["direct"], results["krylov"]):
        # both converged to |∇Π| ≤ 1e-10 |load|; K ≥ I here, so the states differ by at most 2e-10 |load|
        assert np.abs(d.u - k.u).max() <= 2e-10 * np.linalg.norm(prob.f) * 1.2
        assert d.factorizations == d.iterations + 1 and d.krylov_solves == 0
    # started with the previous state's factor held: Krylov steps, and fewer factorisations than the direct path
    for d, k in zip(results["direct"][1:], results["krylov"][1:]):
        assert k.krylov_solves >= 1 and k.factorizations < d.factorizations
    assert sum(r.factorizations for r in results["krylov"]) <= 0.6 * sum(r.factorizations for r in results["direct"])


class DoubleWell:
    """Π = (x² − 1)²/4 + y²/2 + ε x⁴ summed over copies: minima at x = ±1, a saddle at x = 0."""

    def energy(self, u):
        return float((u[0] ** 2 - 1) ** 2 / 4 + u[1] ** 2 / 2)

    def gradient(self, u):
        return np.array([u[0] ** 3 - u[0], u[1]])

    def hessian(self, u):
        return sp.csr_matrix(np.diag([3 * u[0] ** 2 - 1, 1.0]))


def test_no_saddle_is_accepted_on_the_krylov_path():
    # held: the positive definite factor of the minimum's Hessian. From x = 0 the Krylov steps (CG on the
    # held factor) go straight to the saddle (0, 0), where Newton's direct steps would go too; the
    # convergence test factorises the saddle's own Hessian, finds its negative eigenvalue and leaves it
    prob = DoubleWell()
    pair = (Refactorizer(), Refactorizer())
    assert minimize(prob, np.array([1.0, 0.0]), stable=True, factorizers=pair, log=None).stable
    res = minimize(prob, np.array([0.0, 0.3]), stable=True, factorizers=pair, linear_solver="krylov", log=None)
    assert res.krylov_solves >= 1                          # the held factor was used
    assert res.converged and res.stable and res.n_negative == 0
    assert abs(abs(res.u[0]) - 1.0) < 1e-6 and abs(res.u[1]) < 1e-6
    # without stable=True the saddle is returned, reported as one by its exact inertia
    res = minimize(prob, np.array([0.0, 0.3]), factorizers=pair, linear_solver="krylov", log=None)
    assert res.converged and res.n_negative == 1 and res.stable is False
    for f in pair:
        f.free()


def test_linear_solver_is_checked():
    with pytest.raises(ValueError, match="linear_solver must be one of"):
        minimize(DoubleWell(), np.zeros(2), linear_solver="cg", log=None)


def test_continuation_corrector_on_krylov_solves_finds_the_same_fold_with_fewer_factorisations(monkeypatch):
    from femshell.solvers import corrector
    from femshell.solvers.continuation import continuation

    from test_continuation import Truss

    out = {}
    for path in ("direct", "krylov"):
        monkeypatch.setattr(corrector, "DEFAULT_LINEAR_SOLVER", path)
        out[path] = continuation(Truss(), np.zeros(3), 0.0, ds=0.1, max_steps=40, lam_stop=-0.2, log=None)
    d, k = out["direct"], out["krylov"]
    assert k.counts["krylov_solves"] > 0 and k.counts["factorize"] < 0.5 * d.counts["factorize"]
    (fd,), (fk,) = d.special_points, k.special_points
    assert fd.kind == fk.kind == "fold" and abs(fk.parameter - fd.parameter) < 1e-9
    assert [r["n_negative"] for r in d.rows] == [r["n_negative"] for r in k.rows]


def test_continuation_corrector_on_krylov_solves_finds_the_same_branch_point(monkeypatch):
    # the coarse clamped disk of test_continuation: its first branch point on the flat branch, direct and Krylov
    from femshell.mesh.generators import disk
    from femshell.shell import Clamped, Material, ShellModel, uniform_growth
    from femshell.solvers import corrector
    from femshell.solvers.continuation import GrowthParameter, continuation

    t, nu = 0.01, 0.3
    mesh = disk(radius=1.0, edge_length=0.2)
    rest = lambda g: uniform_growth(mesh.points, mesh.triangles, t, g)  # noqa: E731
    gc = 14.682 * t * t / (12 * (1 + nu))
    out = {}
    for path in ("direct", "krylov"):
        monkeypatch.setattr(corrector, "DEFAULT_LINEAR_SOLVER", path)
        model = ShellModel(mesh, Material(1.0, nu), rest(0.0), [Clamped("outer")])
        prob = GrowthParameter(model, rest, parameter_scale=gc, length_scale=t)
        out[path] = continuation(prob, model.initial_unknowns(), 0.0, ds=0.3, ds_max=0.3, lam_stop=1.3 * gc,
                                 n_eigs=2, stop_at=("branch",), log=None)
    d, k = out["direct"], out["krylov"]
    assert d.counts["krylov_solves"] == 0 and k.counts["krylov_solves"] > 0
    # a flat branch: one corrector step per point, made on the held factor; the point's own factorisation
    # (its inertia) is all that is left, as on the direct path, where that step's factor is the point's
    assert k.counts["factorize"] <= d.counts["factorize"] and k.counts["hessian"] <= d.counts["hessian"]
    bd, bk = d.special_points[0], k.special_points[0]
    assert bd.kind == bk.kind == "branch" and bd.multiplicity == bk.multiplicity == 1
    assert abs(bk.parameter - bd.parameter) <= 1e-6 * gc       # the location's tolerance (locate_tol 1e-7 in s)
    # every accepted point's inertia is exact on both paths: the same stability along the branch
    inertia = {path: [r["n_negative"] for r in b.rows if not r["special"]] for path, b in out.items()}
    assert inertia["direct"] == inertia["krylov"]
