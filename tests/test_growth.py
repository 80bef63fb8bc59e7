"""femshell.growth: contractility, stretch, target fields (design.md 1.1)."""

import warnings

import numpy as np
import pytest

from femshell.growth import (contractility, dstretch_dc, element_average, stretch, target_curvature,
                             target_metric, target_thickness)


def naive_contractility(c, lam_max=15.0, lam_min=10.0, b=100.0, c_star=0.1):
    """design.md's first form, which overflows for large b c."""
    return (lam_max * np.exp(b * c_star) + lam_min * np.exp(b * c)) / (np.exp(b * c_star) + np.exp(b * c))


def test_limits_of_the_stretch():
    assert stretch(-1.0) == pytest.approx(1.0, abs=1e-12)
    assert stretch(0.0) == pytest.approx(1.0, abs=1e-3)         # c = 0 ≪ c* = 0.1 (b c* = 10)
    assert stretch(2.0) == pytest.approx(1.5, abs=1e-12)
    assert stretch(0.1) == pytest.approx(15.0 / 12.5)           # halfway in Λ at c = c*
    assert stretch(10.0, lam0=12.0) == pytest.approx(1.2)       # configurable Λ0
    # the paper's weak-growth case Λmax/Λmin = 1.05
    assert stretch(1.0, lam_max=10.5, lam_min=10.0, c_star=0.05) == pytest.approx(1.05)


def test_no_overflow_for_steep_switch_and_large_c():
    c = np.array([-1e3, -1.0, 0.0, 0.1, 1.0, 1e3])
    with warnings.catch_warnings():
        warnings.simplefilter("error")          # any overflow RuntimeWarning fails the test
        lam = contractility(c, b=1000.0)
        s = stretch(c, b=1000.0)
        ds = dstretch_dc(c, b=1000.0)
    for arr in (lam, s, ds):
        assert np.all(np.isfinite(arr))
    assert lam[0] == 15.0 and lam[-1] == 10.0
    assert s[0] == 1.0 and s[-1] == 1.5
    assert ds[0] == 0.0 and ds[-1] == 0.0


def test_matches_the_naive_exp_form_where_it_does_not_overflow():
    rng = np.random.default_rng(0)
    for lam_max, lam_min, b, c_star in ((15, 10, 100, 0.1), (15, 10, 100, 0.3), (10.5, 10, 50, 0.05),
                                        (15, 10, 7.0, -0.2)):
        c = rng.uniform(-2, 2, 200)
        ok = np.abs(b * c) < 600                 # exp stays finite
        with np.errstate(over="ignore", invalid="ignore"):
            ref = naive_contractility(c[ok], lam_max, lam_min, b, c_star)
        np.testing.assert_allclose(contractility(c[ok], lam_max, lam_min, b, c_star), ref, rtol=1e-13)
        np.testing.assert_allclose(stretch(c[ok], None, lam_max, lam_min, b, c_star), lam_max / ref, rtol=1e-13)


def test_derivative_against_finite_differences():
    c = np.linspace(-0.2, 0.5, 57)
    for b in (10.0, 100.0):
        h = 1e-4 / b                             # truncation ~ (h b)² / 6, round-off ~ 1e-16 / h
        fd = (stretch(c + h, b=b) - stretch(c - h, b=b)) / (2 * h)
        np.testing.assert_allclose(dstretch_dc(c, b=b), fd, rtol=1e-6, atol=1e-9)
    fd = (stretch(c + 1e-6, lam0=12.0) - stretch(c - 1e-6, lam0=12.0)) / 2e-6
    np.testing.assert_allclose(dstretch_dc(c, lam0=12.0), fd, rtol=1e-6, atol=1e-9)


def test_element_average_and_targets():
    tri = np.array([[0, 1, 2], [1, 2, 3]])
    c = np.array([0.0, 0.3, 0.6, 0.9])
    np.testing.assert_allclose(element_average(c, tri), [0.3, 0.6])
    a0 = np.array([[[1.0, 0.2], [0.2, 2.0]], [[3.0, 0.0], [0.0, 1.0]]])
    s = np.array([1.2, 1.5])
    a = target_metric(a0, s)
    np.testing.assert_allclose(a, a0 * (s ** 2)[:, None, None])
    np.testing.assert_allclose(target_thickness(2.0, s), 2.0 / s ** 2)
    np.testing.assert_allclose(target_thickness(np.array([1.0, 2.0]), s, mode="uniform"), [1.0, 2.0])
    np.testing.assert_allclose(target_thickness(2.0, s, mode="uniform"), [2.0, 2.0])
    # volume conservation: area stretch s² times thickness h̄ gives h0
    np.testing.assert_allclose(target_thickness(2.0, s) * s ** 2, 2.0)
    b = target_curvature(a, 1 / 30)
    # ā⁻¹ b̄ = k0 I
    np.testing.assert_allclose(np.linalg.solve(a, b), np.broadcast_to(np.eye(2) / 30, (2, 2, 2)), atol=1e-15)
    np.testing.assert_allclose(target_curvature(a, np.array([0.0, 0.5]))[1], 0.5 * a[1])


def test_parameter_validation():
    with pytest.raises(ValueError, match="lam_min"):
        contractility(0.0, lam_min=0.0)
    with pytest.raises(ValueError, match="lam_max"):
        contractility(0.0, lam_max=5.0, lam_min=10.0)
    with pytest.raises(ValueError, match="b "):
        stretch(0.0, b=-1.0)
    with pytest.raises(ValueError, match="lam0"):
        stretch(0.0, lam0=0.0)
    with pytest.raises(ValueError, match="non-finite"):
        stretch(np.array([0.0, np.nan]))
    with pytest.raises(ValueError, match="h0"):
        target_thickness(0.0, 1.0)
    with pytest.raises(ValueError, match="mode"):
        target_thickness(1.0, 1.0, mode="area")
    with pytest.raises(ValueError, match="> 0"):
        target_metric(np.eye(2)[None], np.array([-1.0]))
    with pytest.raises(ValueError, match="shape"):
        target_metric(np.eye(2), np.array([1.0]))
    with pytest.raises(ValueError, match="vertex values"):
        element_average(np.zeros(3), np.array([[0, 1, 3]]))
