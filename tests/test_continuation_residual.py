"""Continuation of non-gradient problems (residual + unsymmetric Jacobian): det J's sign from the LU, folds,
transcritical and pitchfork branch points located against their analytic parameters, problem-supplied stability."""

import math

import numpy as np
import pytest
import scipy.sparse as sp

from femshell.solvers.continuation import continuation, switch_branch
from femshell.solvers.linear import LinearSolverError
from femshell.solvers.lu import LUFactorization, permutation_sign


class _Dynamics:
    """u' = F(u, λ); stable when every eigenvalue of J has a negative real part."""

    lam = 0.0

    def set_parameter(self, lam):
        self.lam = lam

    def stability(self, u):
        ev = np.linalg.eigvals(self.jacobian(u).toarray())
        return {"stable": bool(np.all(ev.real < 0)), "mu_0": float(ev.real.max())}


class Pitchfork(_Dynamics):
    """F = [x (λ − 1 − y), x² − y]: trivial branch x = y = 0 (stable for λ < 1), pitchfork at λ = 1 onto
    x² = y = λ − 1. J = [[λ − 1 − y, −x], [2x, −1]] is not symmetric."""

    def residual(self, u):
        x, y = u
        return np.array([x * (self.lam - 1 - y), x * x - y])

    def jacobian(self, u):
        x, y = u
        return sp.csr_matrix(np.array([[self.lam - 1 - y, -x], [2 * x, -1.0]]))


class Transcritical(_Dynamics):
    """F = [x (λ − y), x − y, z − x y − λ] (3 unknowns): the branches x = y = 0 and x = y = λ exchange
    stability at λ = 0. (The third equation makes J's third column a non-trivial part of the LU.)"""

    def residual(self, u):
        x, y, z = u
        return np.array([x * (self.lam - y), x - y, -z + x * y + self.lam])

    def jacobian(self, u):
        x, y, z = u
        return sp.csr_matrix(np.array([[self.lam - y, -x, 0.0], [1.0, -1.0, 0.0], [y, x, -1.0]]))


class Fold(_Dynamics):
    """F = [1 − λ − x², x³ − x/2 − y]: x = ±√(1 − λ), a fold at λ = 1 (x = 0); stable for x > 0."""

    def residual(self, u):
        x, y = u
        return np.array([1 - self.lam - x * x, x**3 - 0.5 * x - y])

    def jacobian(self, u):
        x, y = u
        return sp.csr_matrix(np.array([[-2 * x, 0.0], [3 * x * x - 0.5, -1.0]]))


def test_det_sign_matches_dense_determinant():
    rng = np.random.default_rng(3)
    checked = 0
    for n in (1, 2, 3, 7, 25, 80):
        for _ in range(20):
            A = rng.standard_normal((n, n)) * (rng.random((n, n)) < 0.4) + np.diag(rng.standard_normal(n))
            sign = np.sign(np.linalg.det(A))
            try:
                f = LUFactorization(sp.csr_matrix(A))
            except LinearSolverError:
                assert abs(np.linalg.det(A)) < 1e-10
                continue
            assert f.det_sign == sign
            b = rng.standard_normal(n)
            assert np.allclose(A @ f.solve(b), b) and np.allclose(A.T @ f.solve(b, transpose=True), b)
            checked += 1
    assert checked > 100
    assert permutation_sign([1, 0, 2]) == -1 and permutation_sign([1, 2, 0]) == 1 and permutation_sign([]) == 1


def test_singular_matrix_is_a_clear_error():
    with pytest.raises(LinearSolverError, match="singular"):
        LUFactorization(sp.csr_matrix(np.array([[1.0, 2.0], [2.0, 4.0]])))
    with pytest.raises(LinearSolverError, match="square"):
        LUFactorization(sp.csr_matrix(np.ones((2, 3))))


@pytest.mark.parametrize("ds", [0.13, 0.31])
def test_pitchfork_located_and_switched(ds):
    b = continuation(Pitchfork(), np.zeros(2), 0.0, ds=ds, lam_stop=2.0, log=None)
    assert b.status == "lam_stop"
    (bp,) = b.special_points
    assert bp.kind == "branch" and bp.located
    assert abs(bp.parameter - 1.0) < 1e-6
    # the critical mode is J's null vector at λ = 1, (1, 0)
    assert np.allclose(np.abs(bp.modes[:, 0]), [1.0, 0.0], atol=1e-6)
    stable = [r["stable"] for r in b.rows if not r["special"]]
    lam = [r["parameter"] for r in b.rows if not r["special"]]
    assert all(s == (lv < 1) for s, lv in zip(stable, lam))
    assert all(r["det_sign"] == (1 if r["parameter"] < 1 else -1) for r in b.rows if abs(r["parameter"] - 1) > 1e-3)
    nb = switch_branch(Pitchfork(), bp, amplitude=0.1, ds=0.1, lam_stop=1.5, log=None)
    u, lam_end = nb.states[-1]
    assert lam_end == 1.5 and abs(u[0] ** 2 - 0.5) < 1e-8 and abs(u[1] - 0.5) < 1e-8
    assert nb.rows[-1]["stable"] is True       # the supercritical branch takes over the stability


def test_transcritical_located_on_both_branches():
    b = continuation(Transcritical(), np.zeros(3), -1.0, ds=0.17, lam_stop=1.0, log=None)
    (bp,) = b.special_points
    assert bp.kind == "branch" and abs(bp.parameter) < 1e-6
    assert [r["stable"] for r in b.rows if not r["special"] and r["parameter"] < -1e-3] == \
        [True] * sum(1 for r in b.rows if not r["special"] and r["parameter"] < -1e-3)
    # on the other branch x = y = λ, z = λ² + λ
    u0 = np.array([-0.8, -0.8, 0.64 - 0.8])
    b2 = continuation(Transcritical(), u0, -0.8, ds=0.21, lam_stop=0.9, log=None)
    (bp2,) = b2.special_points
    assert bp2.kind == "branch" and abs(bp2.parameter) < 1e-6
    u, lam = b2.states[-1]
    assert np.allclose(u, [0.9, 0.9, 0.81 + 0.9], atol=1e-8)
    assert b2.rows[-1]["stable"] is True and b2.rows[0]["stable"] is False


def test_fold_located_with_stability_change():
    b = continuation(Fold(), np.array([-1.0, -0.5]), 0.0, ds=0.13, max_steps=25, log=None)
    folds = [p for p in b.special_points if p.kind == "fold"]
    assert len(folds) == 1 and not [p for p in b.special_points if p.kind == "branch"]
    assert abs(folds[0].parameter - 1.0) < 1e-6
    assert np.allclose(np.abs(folds[0].modes[:, 0]), np.array([1.0, 0.5]) / math.sqrt(1.25), atol=1e-4)
    rows = [r for r in b.rows if not r["special"]]
    assert rows[0]["stable"] is False and rows[-1]["stable"] is True
    # a fold changes det J's sign but not the augmented determinant's: no branch point is reported
    assert {r["det_sign"] for r in rows[:3]} != {r["det_sign"] for r in rows[-3:]}


def test_energy_rows_keep_their_columns():
    from tests.test_continuation import Pitchfork as EnergyPitchfork
    b = continuation(EnergyPitchfork(), np.zeros(2), 0.0, ds=0.3, ds_max=0.3, lam_stop=1.5, log=None)
    assert "det_sign" not in b.rows[0] and "eig_0" in b.rows[0] and b.special_points[0].multiplicity == 1
