"""femshell.analysis: spot counts, ridge classification, the paper's radius/spacing, profiles, wrinkles."""

import math

import numpy as np
import pytest

from femshell.analysis import (azimuthal_power, azimuthal_spectrum, count_spots, count_wrinkles, find_spots,
                               polar_profile, spot_radius, spot_spacing, vertex_areas)
from femshell.mesh.generators import disk, plate, sphere

R = 10.0


@pytest.fixture(scope="module")
def ball():
    return sphere(R, n_vertices=2500)


def bumps(points, directions, width, amplitude=1.0):
    """Sum of Gaussian bumps in the geodesic distance from each direction."""
    x = points / np.linalg.norm(points, axis=1)[:, None]
    c = np.zeros(len(points))
    for d in directions:
        d = np.asarray(d, float) / np.linalg.norm(d)
        rho = R * np.arccos(np.clip(x @ d, -1, 1))
        c += amplitude * np.exp(-(rho / width) ** 2)
    return c


OCTAHEDRON = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]


@pytest.mark.parametrize("k", [1, 3, 6])
def test_k_bumps_give_k_spots(ball, k):
    width, c_star = 2.0, 0.3
    c = bumps(ball.points, OCTAHEDRON[:k], width)
    pm = find_spots(ball.points, ball.triangles, c, c_star)
    assert pm.n_spots == k and pm.n_ridges == 0 and pm.kind == "spots"
    # each region is the geodesic disk rho < w sqrt(ln(1/c*)); area 2 pi R^2 (1 - cos(rho/R))
    rho = width * math.sqrt(math.log(1 / c_star))
    disk_area = 2 * math.pi * R**2 * (1 - math.cos(rho / R))
    for reg in pm.regions:
        assert reg.area == pytest.approx(disk_area, rel=0.03)
        assert reg.aspect < 1.3 and reg.isoperimetric < 1.2
        assert 0.8 < reg.elongation < 1.2 and reg.inscribed_radius == pytest.approx(rho, rel=0.1)
    assert pm.area_low == pytest.approx(k * disk_area, rel=0.03)
    assert pm.area_total == pytest.approx(4 * math.pi * R**2, rel=0.01)
    assert pm.spot_radius == pytest.approx(math.sqrt(disk_area / math.pi), rel=0.02)
    assert count_spots(ball.points, ball.triangles, c, c_star) == k


def test_count_spots_counts_what_find_spots_keeps(ball):
    # the count alone (every step of a run) against the full measures: noisy fields whose regions
    # include single vertices barely over c*, which both must leave out (min_area)
    rng = np.random.default_rng(3)
    counts = set()
    for _ in range(6):
        dirs = rng.standard_normal((8, 3))
        c = bumps(ball.points, dirs, 1.5) + 0.25 * rng.random(ball.n_vertices)
        for c_star in (0.3, 0.6, 0.9, 1.3):
            pm = find_spots(ball.points, ball.triangles, c, c_star)
            assert count_spots(ball.points, ball.triangles, c, c_star) == pm.n_spots
            counts.add((pm.n_spots, pm.ignored_regions > 0))
    assert len({n for n, _ in counts}) > 3 and any(ignored for _, ignored in counts)


def test_nothing_above_threshold(ball):
    pm = find_spots(ball.points, ball.triangles, np.zeros(ball.n_vertices), 0.1)
    assert pm.n_spots == 0 and pm.kind == "none" and pm.area_low == 0
    assert math.isnan(pm.spot_radius) and math.isnan(pm.spacing)
    assert pm.as_dict()["spot_radius"] is None


def test_band_and_arc_are_ridges(ball):
    z = ball.points[:, 2]
    ring = np.exp(-(z / 1.0) ** 2)                          # a closed band around the equator
    pm = find_spots(ball.points, ball.triangles, ring, 0.3)
    assert pm.n_spots == 1 and pm.n_ridges == 1 and pm.regions[0].kind == "ridge"
    arc = ring * (ball.points[:, 1] > 2.0)                  # an open arc of it
    pm = find_spots(ball.points, ball.triangles, arc, 0.3)
    assert pm.n_spots == 1 and pm.regions[0].kind == "ridge" and pm.regions[0].aspect > 3


@pytest.mark.parametrize("degrees, width", [(90, 2.5), (90, 2.0), (240, 2.0)])
def test_bent_band_is_a_ridge_by_its_inscribed_disk(ball, degrees, width):
    # a band of width w along an arc of geodesic radius 4 around the x axis: area L w, inscribed
    # radius w/2, so elongation 4 L / (pi w); at 90 deg, w = 2.5 the second moment alone is round
    # enough (aspect < 2.5) to miss it
    x = ball.points / np.linalg.norm(ball.points, axis=1)[:, None]
    rho = R * np.arccos(np.clip(x[:, 0], -1, 1))
    phi = np.arctan2(x[:, 2], x[:, 1])
    half = math.radians(degrees) / 2
    c = np.minimum(width / 2 - np.abs(rho - 4.0), np.where(np.abs(phi) <= half, 1.0, -(np.abs(phi) - half) * 4.0))
    pm = find_spots(ball.points, ball.triangles, c, 0.0)
    length = 4.0 * 2 * half
    assert pm.n_spots == 1 and pm.n_ridges == 1
    reg = pm.regions[0]
    assert reg.area == pytest.approx(length * width, rel=0.05)
    assert reg.inscribed_radius == pytest.approx(width / 2, rel=0.1)
    assert reg.elongation == pytest.approx(4 * length / (math.pi * width), rel=0.05)


def test_field_above_threshold_everywhere_is_one_unbounded_spot(ball):
    pm = find_spots(ball.points, ball.triangles, np.ones(ball.n_vertices), 0.5)
    assert pm.n_spots == 1 and pm.fraction_patterned == pytest.approx(1.0)
    reg = pm.as_dict()["regions"][0]
    assert reg["kind"] == "spot" and reg["inscribed_radius"] is None and reg["elongation"] == 0.0


def test_elongated_spot_is_a_ridge_round_one_is_not(ball):
    from femshell.coupled import gaussian_spot

    long = gaussian_spot(ball.points, 1.0, 1.5, elongation=4.0)
    round_ = gaussian_spot(ball.points, 1.0, 1.5)
    pl, pr = (find_spots(ball.points, ball.triangles, f, 0.3) for f in (long, round_))
    assert pl.regions[0].kind == "ridge" and pl.regions[0].aspect == pytest.approx(4.0, rel=0.15)
    assert pl.regions[0].elongation == pytest.approx(4.0, rel=0.05)
    assert pr.regions[0].kind == "spot" and pr.regions[0].aspect < 1.2 and pr.regions[0].elongation < 1.1


def test_radius_and_spacing_formulas_by_hand():
    # four disks of radius 2 on a surface whose share per spot is a disk of radius 3
    A_l, A_tot = 4 * math.pi * 4.0, 4 * math.pi * 9.0
    assert spot_radius(A_l, 4) == pytest.approx(2.0)
    assert spot_spacing(A_tot, A_l, 4) == pytest.approx(2.0)           # 2 (3 - 2)
    assert math.isnan(spot_radius(1.0, 0)) and math.isnan(spot_spacing(1.0, 0.5, 0))
    with pytest.raises(ValueError):
        spot_spacing(1.0, 2.0, 1)


def test_p1_level_set_area_and_perimeter_are_exact_on_a_plate():
    m = plate(1.0, 1.0, edge_length=0.1)
    c = m.points[:, 0]                                      # linear: {x > 0.3} is a 0.7 x 1 rectangle
    pm = find_spots(m.points, m.triangles, c, 0.3)
    assert pm.n_spots == 1
    assert pm.area_low == pytest.approx(0.7, rel=1e-12)
    assert pm.regions[0].perimeter == pytest.approx(1.0, rel=1e-12)   # the level line only, not the mesh boundary
    assert pm.area_total == pytest.approx(1.0, rel=1e-12)
    assert vertex_areas(m.points, m.triangles).sum() == pytest.approx(1.0, rel=1e-12)


def test_tiny_regions_are_ignored(ball):
    c = bumps(ball.points, [(0, 0, 1)], 2.0)
    v = int(np.argmin(ball.points[:, 2]))                   # one vertex barely over, at the other pole
    c[v] = 0.3 + 1e-3
    pm = find_spots(ball.points, ball.triangles, c, 0.3)
    assert pm.n_spots == 1 and pm.ignored_regions == 1
    assert find_spots(ball.points, ball.triangles, c, 0.3, min_area=0.0).n_spots == 2


def test_polar_profile(ball):
    x = ball.points
    f = x[:, 2] / np.linalg.norm(x, axis=1)                 # cos(theta)
    prof = polar_profile(x, f, 12, triangles=ball.triangles)
    assert prof.count.sum() == ball.n_vertices
    assert np.allclose(prof.mean, np.cos(prof.theta), atol=0.02)
    assert prof.theta[0] == pytest.approx(math.pi / 24)


def test_count_wrinkles_on_a_disk():
    m = disk(radius=5.0, edge_length=0.4)
    r = np.hypot(m.points[:, 0], m.points[:, 1])
    phi = np.arctan2(m.points[:, 1], m.points[:, 0])
    for k in (2, 3, 8):
        w = (r / 5) ** 2 * np.cos(k * phi + 0.3) + 0.5 * r**2 / 25      # wrinkles on a dome
        assert count_wrinkles(m.points, w, 4.0, triangles=m.triangles) == k
        assert count_wrinkles(m.points, w, 4.0, triangles=m.triangles, method="zeros") == k
    assert count_wrinkles(m.points, w, 4.0) == 8                        # Delaunay of the points instead
    assert count_wrinkles(m.points, r**2, 4.0, triangles=m.triangles) == 0   # axisymmetric: no wrinkles
    amp = azimuthal_spectrum(m.points, np.cos(3 * phi), 3.0, triangles=m.triangles)
    assert amp[3] == pytest.approx(1.0, rel=0.02) and amp[0] < 1e-3
    with pytest.raises(ValueError, match="leaves the mesh"):
        count_wrinkles(m.points, r, 6.0, triangles=m.triangles)
    # summed over circles: r cos 3φ has |ŵ_3|² = r² on each
    power = azimuthal_power(m.points, r * np.cos(3 * phi), [2.0, 3.0, 6.0], triangles=m.triangles, skip_outside=True)
    assert int(np.argmax(power)) == 3 and power[3] == pytest.approx(2.0**2 + 3.0**2, rel=0.03)
    assert azimuthal_power(m.points, r, [6.0], triangles=m.triangles, skip_outside=True) is None
    with pytest.raises(ValueError, match="leaves the mesh"):
        azimuthal_power(m.points, r, [2.0, 6.0], triangles=m.triangles)
    ball = sphere(radius=5.0, n_vertices=200)     # a curved mesh is not projected onto the xy plane
    with pytest.raises(ValueError, match="flat mesh in the xy plane .* got z from -5"):
        count_wrinkles(ball.points, ball.points[:, 2], 4.0, triangles=ball.triangles)


def test_bad_arguments_are_named():
    m = disk(radius=5.0, edge_length=0.8)
    ball = sphere(radius=3.0, n_vertices=200)
    r = np.hypot(m.points[:, 0], m.points[:, 1])
    broken = ball.points.copy()
    broken[3, 0] = np.nan
    ones = np.ones(ball.n_vertices)
    cases = [
        (lambda: find_spots(broken, ball.triangles, ones, 0.1), "points hold NaN or infinity at 1"),
        (lambda: find_spots(ball.points, ball.triangles - 1, ones, 0.1), r"negative vertex index \(-1\)"),
        (lambda: find_spots(ball.points, ball.triangles, ones, None), "c_star must be a number, got None"),
        (lambda: find_spots(ball.points, ball.triangles, ones, 0.1, min_area=np.nan), "min_area must be"),
        (lambda: polar_profile(ball.points, ones, center=(0, 0)), r"center must be 3 finite numbers"),
        (lambda: polar_profile(ball.points, ones, n_bins=2.5), r"n_bins must be an integer in \[1, 100000\]"),
        (lambda: polar_profile(broken, ones), "points hold NaN"),
        (lambda: count_wrinkles(np.array([[0, 0], [1, 0.0], [2, 0]]), [1, 2, 3], 0.5), "cannot triangulate"),
        (lambda: count_wrinkles(m.points, r, 2.0, triangles=np.zeros((0, 3), int)), "triangles is empty"),
        (lambda: count_wrinkles(m.points, r, 2.0, triangles=m.triangles, min_mode=257),
         r"min_mode must be an integer in \[1, 256\]"),
        (lambda: count_wrinkles(m.points, r, 2.0, triangles=m.triangles, center=0.0), "center must be 2"),
        (lambda: count_wrinkles(m.points, r, 2.0, triangles=m.triangles, n_samples=np.nan), "n_samples must be"),
        (lambda: count_wrinkles(m.points, r, 2.0, triangles=m.triangles, rel_tol=-1), "rel_tol must be"),
    ]
    for call, words in cases:
        with pytest.raises(ValueError, match=words):
            call()
