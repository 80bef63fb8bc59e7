"""femshell.solvers.linear: solves, inertia, refactorisation, errors, smallest eigenvalues."""

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from femshell.solvers.linear import (LinearSolverError, Refactorizer, available_backends, factorize,
                                     smallest_eigenvalues)

BACKENDS = [pytest.param(b, marks=pytest.mark.skipif(b not in available_backends(), reason=f"{b} unavailable"))
            for b in ("pardiso", "superlu")]


def random_spd(n, seed, density=0.002):
    rng = np.random.default_rng(seed)
    B = sp.random(n, n, density=density, random_state=seed, data_rvs=rng.standard_normal)
    return (B @ B.T + sp.diags(rng.uniform(0.5, 2.0, n))).tocsr()


def random_indefinite(n, seed, density=0.003, zero_diagonal_every=0):
    rng = np.random.default_rng(seed)
    B = sp.random(n, n, density=density, random_state=seed, data_rvs=rng.standard_normal)
    d = rng.standard_normal(n)
    if zero_diagonal_every:
        d[::zero_diagonal_every] = 0.0
    A = (B + B.T + sp.diags(d)).tocsr()
    A.eliminate_zeros()
    return A


def laplacian_2d(m, neumann=False):
    T = sp.diags([-np.ones(m - 1), 2 * np.ones(m), -np.ones(m - 1)], [-1, 0, 1]).tolil()
    if neumann:
        T[0, 0] = T[-1, -1] = 1.0
    T = T.tocsr()
    I = sp.identity(m, format="csr")
    return (sp.kron(T, I) + sp.kron(I, T)).tocsr()


def rel_residual(A, x, b):
    return np.linalg.norm(A @ x - b) / np.linalg.norm(b)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", ["random", "laplacian"])
def test_spd_solve_matches_spsolve(backend, name):
    A = random_spd(2000, 1) if name == "random" else laplacian_2d(45)
    b = np.random.default_rng(2).standard_normal(A.shape[0])
    f = factorize(A, "spd", backend)
    x = f.solve(b)
    ref = spla.spsolve(A.tocsc(), b)
    assert np.linalg.norm(x - ref) <= 1e-9 * np.linalg.norm(ref)
    assert f.inertia == (A.shape[0], 0, 0)
    assert f.backend == backend and f.factor_time > 0
    # several right-hand sides at once
    B = np.random.default_rng(3).standard_normal((A.shape[0], 3))
    X = f.solve(B)
    assert X.shape == B.shape and rel_residual(A, X, B) < 1e-10
    f.free()


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("zero_diag", [0, 7])
def test_indefinite_solve_matches_spsolve(backend, zero_diag):
    A = random_indefinite(2000, 4, zero_diagonal_every=zero_diag)
    b = np.random.default_rng(5).standard_normal(A.shape[0])
    f = factorize(A, "symmetric_indefinite", backend)
    x = f.solve(b)
    ref = spla.spsolve(A.tocsc(), b)
    assert np.linalg.norm(x - ref) <= 1e-8 * np.linalg.norm(ref)
    assert rel_residual(A, x, b) < 1e-10


@pytest.mark.parametrize("backend", BACKENDS)
def test_inertia_against_eigvalsh(backend):
    n_checked = 0
    for seed in range(12):
        A = random_indefinite(200, seed, density=0.05, zero_diagonal_every=(0 if seed % 3 else 9))
        ev = np.linalg.eigvalsh(A.toarray())
        if np.abs(ev).min() < 1e-8:
            continue
        f = factorize(A, "symmetric_indefinite", backend)
        assert f.inertia == (int((ev > 0).sum()), int((ev < 0).sum()), 0), f"seed {seed}"
        n_checked += 1
    assert n_checked >= 10


@pytest.mark.parametrize("backend", BACKENDS)
def test_inertia_of_shifted_laplacian(backend):
    A = laplacian_2d(30)
    ev = np.linalg.eigvalsh(A.toarray())
    # the square grid has double eigenvalues: shift into a clear gap above the 7th or so
    k = 7 + int(np.argmax(np.diff(ev[6:20]) > 1e-3))
    sigma = 0.5 * (ev[k - 1] + ev[k])             # k eigenvalues below the shift
    f = factorize(A - sigma * sp.identity(A.shape[0]), "symmetric_indefinite", backend)
    assert f.inertia == (A.shape[0] - k, k, 0)


@pytest.mark.skipif("pardiso" not in available_backends(), reason="pardiso unavailable")
def test_pardiso_refactor_reuses_analysis():
    A = laplacian_2d(40)
    f = factorize(A, "spd", "pardiso")
    b = np.ones(A.shape[0])
    A2 = (A + sp.diags(np.linspace(0.1, 1.0, A.shape[0]))).tocsr()
    f.refactor(A2)
    assert f.n_analyses == 1 and f.n_factorizations == 2 and f.analysis_time == 0.0
    assert rel_residual(A2, f.solve(b), b) < 1e-12
    # a changed pattern is analysed again
    A3 = (A2 + sp.diags(np.ones(A.shape[0] - 5), 5) + sp.diags(np.ones(A.shape[0] - 5), -5)).tocsr() * 1.0
    A3 = (A3 + 10 * sp.identity(A.shape[0])).tocsr()
    f.refactor(A3)
    assert f.n_analyses == 2
    assert rel_residual(A3, f.solve(b), b) < 1e-12
    # factorize(reuse=...) refactorises the same object
    g = factorize(A3 * 2.0, "spd", "pardiso", reuse=f)
    assert g is f and f.n_analyses == 2
    assert rel_residual(A3 * 2.0, g.solve(b), b) < 1e-12
    f.free()
    with pytest.raises(LinearSolverError, match="freed"):
        f.solve(b)


@pytest.mark.skipif("pardiso" not in available_backends(), reason="pardiso unavailable")
def test_a_collected_pardiso_factor_is_freed_at_once_or_in_a_run_at_the_next_factorisation(monkeypatch):
    # in a run, not in the garbage collector's callback, where a Ctrl-C's exception would be dropped
    import gc

    from femshell._interrupts import interruptible
    from femshell.solvers import pardiso

    gc.collect()                                  # factors left by earlier tests in this process: freed now,
    pardiso._free_collected()                      # not inside the counts below
    freed = []
    free = pardiso._free_pardiso
    monkeypatch.setattr(pardiso, "_free_pardiso", lambda s: (freed.append(id(s)), free(s)))
    A = laplacian_2d(30)
    b = np.ones(A.shape[0])
    f = factorize(A, "spd", "pardiso")
    handle = id(f._impl.solver)
    del f                                         # outside a run: freed at once
    assert freed == [handle] and pardiso._COLLECTED == []
    with interruptible():
        f = factorize(A, "spd", "pardiso")
        handle = id(f._impl.solver)
        del f
        assert [id(s) for s in pardiso._COLLECTED] == [handle] and freed == [freed[0]]
        g = factorize(A, "spd", "pardiso")        # the next factorisation frees it
        assert pardiso._COLLECTED == [] and freed[-1] == handle
        assert rel_residual(A, g.solve(b), b) < 1e-12
        g.free()                                  # an explicit free frees at once
        assert pardiso._COLLECTED == [] and len(freed) == 3


# Run in a child process: MKL reads MKL_THREADING_LAYER once, when it is loaded.
_THREADED_CHILD = """
import numpy as np, scipy.sparse as sp
from femshell.solvers.linear import Refactorizer
from femshell.solvers.pardiso import PARALLEL_MIN_NNZ, _mkl_threads
m = 160
T = sp.diags([np.full(m - 1, -1.0), np.full(m, 4.0), np.full(m - 1, -1.0)], [-1, 0, 1])
S = sp.diags([np.full(m - 1, -1.0), np.full(m - 1, -1.0)], [-1, 1])
K = sp.kron(sp.kron(sp.eye(m), T) + sp.kron(S, sp.eye(m)), np.full((6, 6), 0.1) + np.eye(6)).tocsr()
assert sp.triu(K).nnz >= PARALLEL_MIN_NNZ
r = Refactorizer("pardiso")
b = np.ones(K.shape[0])
for k in range(3):
    Kk = K * (1.0 + 0.1 * k)
    x = r(Kk).solve(b)
    print(_mkl_threads(), float(np.abs(Kk @ x - b).max() / np.abs(b).max()))
"""


@pytest.mark.skipif("pardiso" not in available_backends(), reason="pardiso unavailable")
def test_threaded_pardiso_refactorises_after_solves():
    # factorise -> solve -> refactorise of a matrix above PARALLEL_MIN_NNZ with MKL's GNU
    # OpenMP layer: solves on fewer threads than the analysis made the next refactorisation
    # segfault (measured at 25k vertices); the thread count is now pinned for every phase
    import glob
    import os
    import subprocess
    import sys

    if not glob.glob(os.path.join(sys.prefix, "lib", "libmkl_gnu_thread.so*")):
        pytest.skip("MKL's GNU threading layer is not installed")
    from femshell.config import REPRODUCIBLE_ENV

    # not the test process's reproducible mode (conftest): MKL on all its threads
    env = {**{k: v for k, v in os.environ.items() if k not in REPRODUCIBLE_ENV}, "MKL_THREADING_LAYER": "GNU"}
    out = subprocess.run([sys.executable, "-c", _THREADED_CHILD], env=env, capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, f"child exited with {out.returncode}: {out.stderr[-2000:]}"
    rows = [line.split() for line in out.stdout.split("\n") if line.strip()]
    assert len(rows) == 3
    if int(rows[0][0]) < 2:
        pytest.skip("MKL has one thread here: the threaded path is not exercised")
    assert all(float(res) < 1e-10 for _, res in rows)


def _variable_after_import(module, name, env_changes, then=""):
    """The environment variable ``name`` in a child process after ``import module`` and the statement
    ``then``, with the parent's environment minus the variables in ``env_changes``, then those of them
    that are not None."""
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k not in env_changes}
    env.update({k: v for k, v in env_changes.items() if v is not None})
    code = f"import os, {module}, numpy; {then or 'pass'}; print(os.environ.get({name!r}))"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout.strip()


@pytest.mark.parametrize("layer, cbwr", [(None, None), ("SEQUENTIAL", "AUTO,STRICT"), ("GNU", None)])
def test_strict_reproducibility_only_on_the_sequential_layer(layer, cbwr):
    # MKL's strict reproducibility mode serves bit-for-bit resumes, which only the sequential
    # layer gives (femshell.configure(reproducible=True) chooses it); on a threaded one, the default,
    # it would only slow PARDISO down (solves 2.5x at 25k vertices).
    # It is chosen when MKL is first loaded, not when the module is imported.
    env = {"MKL_CBWR": None, "MKL_THREADING_LAYER": layer, "MKL_NUM_THREADS": None, "FEMSHELL_THREADS": None}
    assert _variable_after_import("femshell.solvers.linear", "MKL_CBWR", env) == "None"
    assert _variable_after_import("femshell.solvers.linear", "MKL_THREADING_LAYER", env) == str(layer)
    got = _variable_after_import("femshell.solvers.linear", "MKL_CBWR", env,
                                 then="femshell.solvers.linear.available_backends()")
    assert got == str(cbwr)


@pytest.mark.skipif("pardiso" not in available_backends(), reason="pardiso unavailable")
def test_the_default_mkl_layer_is_threaded_on_every_cpu_and_the_reproducible_mode_is_sequential():
    import os
    import subprocess
    import sys

    env = {"MKL_CBWR": None, "MKL_THREADING_LAYER": None, "MKL_NUM_THREADS": None, "FEMSHELL_THREADS": None,
           "OMP_NUM_THREADS": None}
    then = ("femshell.solvers.linear.available_backends(); from femshell.solvers.pardiso import _mkl_threads; "
            "from femshell.config import element_threads; "
            "print(os.environ['MKL_THREADING_LAYER'], _mkl_threads(), element_threads())")
    threaded = _variable_after_import("femshell.solvers.linear", "MKL_CBWR", env, then=then).split()
    if threaded[0] != "GNU":
        pytest.skip("MKL's GNU threading layer (or libgomp) is not installed")
    assert threaded[1] == threaded[2]                    # MKL's threads: as many as the kernels use
    assert threaded[-1] == "None"                        # no strict mode on threads
    single = _variable_after_import("femshell.solvers.linear", "MKL_CBWR", env,
                                    then="import femshell; femshell.configure(reproducible=True); " + then).split()
    assert single == ["SEQUENTIAL", "1", "1", "AUTO,STRICT"]
    # once MKL is loaded threaded, the reproducible mode is refused, not silently half-applied
    late = ("femshell.solvers.linear.available_backends(); import femshell\n"
            "try:\n    femshell.configure(reproducible=True)\nexcept ValueError as e:\n    print('refused', e)")
    code = f"import os, femshell.solvers.linear\n{late}"
    out = subprocess.run([sys.executable, "-c", code], env={k: v for k, v in os.environ.items() if k not in env},
                         capture_output=True, text=True, timeout=120)
    assert "refused the reproducible mode must be chosen before the first factorisation" in out.stdout, out.stderr


@pytest.mark.parametrize("backend", BACKENDS)
def test_refactorizer_inertia_through_a_loss_of_definiteness(backend):
    """A shifted Laplacian swept through its lowest eigenvalues, the way Newton meets a buckling
    load: every inertia must equal the count of dense eigenvalues below the shift, whichever of
    Cholesky or LDLᵀ produced it, and the solves must be right."""
    A = laplacian_2d(12, neumann=False).tocsr()
    ev = np.linalg.eigvalsh(A.toarray())
    b = np.random.default_rng(1).standard_normal(A.shape[0])
    r = Refactorizer(backend)
    # PD, indefinite (two sizes), PD again: the object must recover Cholesky after LDLᵀ
    shifts = [0.5 * ev[0], 0.5 * (ev[0] + ev[1]), 0.5 * (ev[3] + ev[4]), 0.3 * ev[0], 0.1 * ev[0]]
    for sigma in shifts:
        K = (A - sigma * sp.identity(A.shape[0])).tocsr()
        f = r(K)
        n_neg = int((ev < sigma).sum())
        assert f.inertia == (len(ev) - n_neg, n_neg, 0)
        assert rel_residual(K, f.solve(b), b) < 1e-10
    if backend == "pardiso":
        # Cholesky for the PD matrices (the first, and the last two: the first PD one after the
        # indefinite stretch is found by LDLᵀ), one failed Cholesky, LDLᵀ for the rest
        assert r.counts == {"cholesky": 2, "cholesky_failed": 1, "ldlt": 3}
        # each kind analysed its pattern once
        assert r._spd.n_analyses == 1 and r._ldl.n_analyses == 1
    else:
        assert r.counts == {"cholesky": 0, "cholesky_failed": 0, "ldlt": 5}
    r.free()


@pytest.mark.skipif("pardiso" not in available_backends(), reason="pardiso unavailable")
def test_a_failed_cholesky_keeps_its_analysis_for_the_next_matrix(monkeypatch):
    """The shift search's first attempts fail: the pattern is analysed once, by the first attempt, and
    the Cholesky that then succeeds refactorises it, giving the same solution bit for bit as a fresh
    factorisation (a Cholesky's analysis depends on the pattern only)."""
    from femshell.solvers import pardiso

    analyses = []
    factor = pardiso._Pardiso.factor
    monkeypatch.setattr(pardiso._Pardiso, "factor", lambda self, U, analyse: (analyses.append(analyse),
                                                                           factor(self, U, analyse))[1])
    A = laplacian_2d(12, neumann=False).tocsr()
    ev = np.linalg.eigvalsh(A.toarray())
    b = np.random.default_rng(3).standard_normal(A.shape[0])
    r = Refactorizer("pardiso")
    for sigma in (0.5 * (ev[1] + ev[2]), 0.5 * (ev[0] + ev[1])):          # two failures
        assert r.positive_definite((A - sigma * sp.identity(A.shape[0])).tocsr()) is None
    K = (A - 0.5 * ev[0] * sp.identity(A.shape[0])).tocsr()
    f = r.positive_definite(K)
    assert analyses == [True, False, False] and f.analysis_time == 0.0
    fresh = factorize(K, "spd", "pardiso")
    assert np.array_equal(f.solve(b), fresh.solve(b))
    # through __call__: a failed first Cholesky, LDLᵀ for it and the next; Cholesky again on the kept analysis
    analyses.clear()
    r2 = Refactorizer("pardiso")
    r2((A - 0.5 * (ev[0] + ev[1]) * sp.identity(A.shape[0])).tocsr())
    r2(K)
    assert r2(K) is r2._spd and r2.counts == {"cholesky": 1, "cholesky_failed": 1, "ldlt": 2}
    assert analyses == [True, True, False, False] and np.array_equal(r2.last.solve(b), fresh.solve(b))
    for x in (r, r2, fresh):
        x.free()


@pytest.mark.parametrize("backend", BACKENDS)
def test_positive_definite_answers_without_an_ldlt(backend):
    """The shift search's question, "is A - sigma I positive definite?", against dense eigenvalues:
    a Cholesky factor (solving right) below the lowest eigenvalue, None above it (singular
    included), and with PARDISO no LDLᵀ is made for the matrices that fail."""
    A = laplacian_2d(12, neumann=False).tocsr()
    ev = np.linalg.eigvalsh(A.toarray())
    b = np.random.default_rng(2).standard_normal(A.shape[0])
    r = Refactorizer(backend)
    for sigma in (0.5 * (ev[0] + ev[1]), ev[0], 0.5 * ev[0], 0.5 * (ev[2] + ev[3]), 0.9 * ev[0]):
        K = (A - sigma * sp.identity(A.shape[0])).tocsr()
        f = r.positive_definite(K)
        assert (f is not None) == (sigma < ev[0]), sigma
        assert r.last is f
        if f is not None:
            assert rel_residual(K, f.solve(b), b) < 1e-10
    if backend == "pardiso":
        assert r.counts == {"cholesky": 2, "cholesky_failed": 3, "ldlt": 0}
    r.free()


@pytest.mark.parametrize("backend", BACKENDS)
def test_nan_and_inf_entries_are_named(backend):
    A = laplacian_2d(10).astype(float)
    A.data[A.indptr[17]] = np.nan
    A.data[A.indptr[23] + 1] = np.nan
    A.data[A.indptr[40]] = np.inf
    with pytest.raises(LinearSolverError, match=r"NaN and infinite entries in 3 row\(s\), first row 17"):
        factorize(A, "spd", backend)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("kind", ["spd", "symmetric_indefinite"])
def test_singular_matrix_is_reported(backend, kind):
    A = laplacian_2d(20, neumann=True)       # constants are in the kernel: singular
    with pytest.raises(LinearSolverError, match="singular"):
        factorize(A, kind, backend)


@pytest.mark.parametrize("backend", BACKENDS)
def test_singular_block_names_the_unknown(backend):
    # a free 1D chain (singular) next to a well-posed diagonal block
    n = 50
    T = sp.diags([-np.ones(n - 1), 2 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1]).tolil()
    T[0, 0] = T[-1, -1] = 1.0
    A = sp.block_diag([sp.diags(np.arange(1.0, n + 1)), T.tocsr() * 1.7]).tocsr()
    with pytest.raises(LinearSolverError, match="singular") as exc:
        factorize(A, "spd", backend)
    import re

    where = re.search(r"at unknown (\d+)", str(exc.value))
    if where:                                 # SuperLU's exact zero pivot does not say where
        assert int(where.group(1)) >= n


@pytest.mark.parametrize("backend", BACKENDS)
def test_zero_row_and_not_spd_and_asymmetric(backend):
    A = laplacian_2d(10).tolil()
    A[5, :] = 0
    A[:, 5] = 0
    with pytest.raises(LinearSolverError, match="zero .* row.*first row 5"):
        factorize(A.tocsr(), "spd", backend)
    C = laplacian_2d(10).tocsr()                      # stored zeros, as new values on a held pattern can be
    rows = np.repeat(np.arange(C.shape[0]), np.diff(C.indptr))
    C.data[(rows == 99) | (C.indices == 99) | (rows == 7) | (C.indices == 7)] = 0.0
    with pytest.raises(LinearSolverError, match="2 zero .* row.*first row 7"):
        factorize(C, "spd", backend)
    with pytest.raises(LinearSolverError, match="not positive definite"):
        factorize(sp.diags([1.0, 2.0, -1.0, 3.0]).tocsr(), "spd", backend)
    B = laplacian_2d(10).tolil()
    B[3, 4] = 0.5
    with pytest.raises(LinearSolverError, match="not symmetric"):
        factorize(B.tocsr(), "spd", backend)


def test_bad_arguments():
    with pytest.raises(ValueError, match="kind"):
        factorize(sp.identity(3, format="csr"), kind="cholesky")
    with pytest.raises(ValueError, match="backend"):
        factorize(sp.identity(3, format="csr"), backend="mumps")
    f = factorize(sp.identity(3, format="csr"), backend="auto")
    assert f.backend == available_backends()[0]
    with pytest.raises(ValueError, match="right-hand side"):
        f.solve(np.ones(4))


@pytest.mark.parametrize("backend", BACKENDS)
def test_smallest_eigenvalues_spd_with_mass(backend):
    A = laplacian_2d(25)                      # 625 unknowns: the sparse path
    n = A.shape[0]
    M = np.random.default_rng(0).uniform(0.5, 1.5, n)
    ref = sla.eigh(A.toarray(), np.diag(M), eigvals_only=True)[:6]
    ev = smallest_eigenvalues(A, k=6, M=M, backend=backend, return_vectors=False)
    assert np.allclose(ev, ref, rtol=1e-8, atol=1e-10)
    ev, V = smallest_eigenvalues(A, k=3, M=sp.diags(M), backend=backend)
    assert np.allclose(V.T @ (M[:, None] * V), np.eye(3), atol=1e-8)
    assert np.allclose(A @ V, (M[:, None] * V) * ev, atol=1e-8)


@pytest.mark.parametrize("backend", BACKENDS)
def test_smallest_eigenvalues_indefinite(backend):
    A = laplacian_2d(25)
    n = A.shape[0]
    ev_all = np.linalg.eigvalsh(A.toarray())
    # a few eigenvalues just below zero (an unstable equilibrium near a bifurcation)
    k = 3 + int(np.argmax(np.diff(ev_all[2:20]) > 1e-3))
    Ks = (A - 0.5 * (ev_all[k - 1] + ev_all[k]) * sp.identity(n)).tocsr()
    ref = np.linalg.eigvalsh(Ks.toarray())[:5]
    assert np.allclose(smallest_eigenvalues(Ks, k=5, backend=backend)[0], ref, rtol=1e-8, atol=1e-10)
    # and two eigenvalues far below the default shift
    d = np.zeros(n)
    d[[10, 300]] = [-50.0, -80.0]
    Kf = (A + sp.diags(d)).tocsr()
    ref = np.linalg.eigvalsh(Kf.toarray())[:4]
    assert np.allclose(smallest_eigenvalues(Kf, k=4, backend=backend)[0], ref, rtol=1e-8, atol=1e-10)


def test_smallest_eigenvalues_dense_path_and_free_body():
    A = laplacian_2d(10, neumann=True)        # 100 unknowns: dense path; one zero eigenvalue
    ev = smallest_eigenvalues(A, k=3, return_vectors=False)
    assert abs(ev[0]) < 1e-12 and np.allclose(ev, np.linalg.eigvalsh(A.toarray())[:3])
    A = laplacian_2d(25, neumann=True)        # sparse path: the shift keeps K − σM non-singular
    ev = smallest_eigenvalues(A, k=3, return_vectors=False)
    assert abs(ev[0]) < 1e-10 and np.allclose(ev, np.linalg.eigvalsh(A.toarray())[:3], atol=1e-10)
