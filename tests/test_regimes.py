"""femshell.analysis.regimes: the regime rules on synthetic fields on a sphere with known answers, and the
embedded regime scenes (each names its regime; slow: each reaches it)."""

import json

import numpy as np
import pytest

from femshell.analysis import REGIMES, classify_regime, find_spots, regime_of_field
from femshell.cli import main
from femshell.mesh.generators import sphere
from femshell.scene import list_scenes, load_scene

R = 10.0
C_STAR = 0.3
OCTAHEDRON = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]


@pytest.fixture(scope="module")
def ball():
    return sphere(R, n_vertices=2500)


def bumps(points, directions, width=2.0):
    """Gaussian bumps of amplitude 1 in the geodesic distance from each direction."""
    x = points / np.linalg.norm(points, axis=1)[:, None]
    c = np.zeros(len(points))
    for d in directions:
        d = np.asarray(d, float) / np.linalg.norm(d)
        c += np.exp(-(R * np.arccos(np.clip(x @ d, -1, 1)) / width) ** 2)
    return c


def band(points, axis, half_width=1.2, start_angle=None):
    """1 on a band of geodesic half-width ``half_width`` around the great circle normal to ``axis`` (0 off
    it); with ``start_angle``, only the arc of the circle with azimuth beyond that angle (an open band)."""
    x = points / np.linalg.norm(points, axis=1)[:, None]
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    c = np.exp(-(R * np.arcsin(np.clip(x @ a, -1, 1)) / half_width) ** 2)
    if start_angle is not None:
        e1 = np.cross(a, [0.0, 0.0, 1.0] if abs(a[2]) < 0.9 else [1.0, 0.0, 0.0])
        e1 /= np.linalg.norm(e1)
        phi = np.arctan2(x @ np.cross(a, e1), x @ e1)
        c *= phi > start_angle
    return c


@pytest.mark.parametrize("field, expected", [
    (lambda p: 0.1 * bumps(p, OCTAHEDRON[:2]), "decay"),                 # below c* everywhere
    (lambda p: np.zeros(len(p)), "decay"),
    (lambda p: bumps(p, OCTAHEDRON[4:5]), "single bulge"),
    (lambda p: bumps(p, OCTAHEDRON), "spots"),
    (lambda p: bumps(p, OCTAHEDRON[:2]), "spots"),
    (lambda p: band(p, (0, 0, 1)), "ridges"),                            # the equator's band, closed
    (lambda p: band(p, (0, 0, 1), start_angle=-2.0) + band(p, (1, 0, 0), start_angle=1.0), "ridges"),
    (lambda p: band(p, (0, 0, 1)) + bumps(p, OCTAHEDRON[4:6]), "mixed"),  # equator + both poles
    (lambda p: 0.5 + 0.0 * p[:, 0], "uniform"),
    (lambda p: 1 - 0.9 * bumps(p, OCTAHEDRON[4:5], width=1.5), "uniform"),  # one hole in a covering
])
def test_known_regimes_on_the_sphere(ball, field, expected):
    c = field(ball.points)
    assert regime_of_field(ball.points, ball.triangles, c, C_STAR) == expected
    # the summary's pattern table classifies as the measures do
    assert classify_regime(find_spots(ball.points, ball.triangles, c, C_STAR).as_dict()) == expected


def test_every_rule_is_reachable_and_ordered():
    table = lambda n, r, f: {"n_spots": n, "n_ridges": r, "fraction_patterned": f}
    got = [classify_regime(table(0, 0, 0.0)), classify_regime(table(1, 0, 0.95)), classify_regime(table(2, 2, 0.3)),
           classify_regime(table(3, 1, 0.3)), classify_regime(table(1, 0, 0.1)), classify_regime(table(5, 0, 0.3))]
    assert tuple(got) == REGIMES
    # uniform is read before the kinds: one ridge covering 95 % is uniform, at 50 % it is a ridge
    assert classify_regime(table(1, 1, 0.95)) == "uniform" and classify_regime(table(1, 1, 0.5)) == "ridges"
    assert classify_regime(table(1, 0, 0.6), uniform_fraction=0.5) == "uniform"


@pytest.mark.parametrize("bad, words", [
    ({"n_spots": 1}, "n_ridges"),
    ({"n_spots": -1, "n_ridges": 0, "fraction_patterned": 0.1}, "n_spots"),
    ({"n_spots": 1, "n_ridges": 2, "fraction_patterned": 0.1}, "exceeds"),
    ({"n_spots": 1, "n_ridges": 0, "fraction_patterned": 1.5}, "fraction_patterned"),
    (None, "PatternMeasures"),
])
def test_bad_pattern_is_named(bad, words):
    with pytest.raises(ValueError, match=words):
        classify_regime(bad)


# ----------------------------------------------------------------------------- the regime scenes

#: each embedded regime scene and the regime its description names (docs/regimes.md)
REGIME_SCENES = {"sphere-regime-decay": "decay", "sphere-regime-single-bulge": "single bulge",
                 "default": "spots", "sphere-regime-mixed": "mixed"}


def test_regime_scenes_name_their_regime():
    scenes = list_scenes()
    assert {name for name in scenes if name.startswith("sphere-regime-")} <= set(REGIME_SCENES)
    for name, regime in REGIME_SCENES.items():
        assert f"'{regime}'" in scenes[name] or (name == "default" and "spots over the sphere" in scenes[name])
        sc = load_scene(name)
        assert sc["mesh"]["radius"] == 15.0 and sc["initial"]["kind"] == "spot"      # one seed, as the paper


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(REGIME_SCENES))
def test_regime_scene_reaches_its_regime(name, tmp_path):
    # the whole scene as shipped (1-5 CPU-minutes each): the classifier's regime of its end state, and
    # the shape resolved (no fold past the run's warning limit)
    out = tmp_path / name
    assert main(["run", name, "--out", str(out), "-q", "--set", "output.pictures=false"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] in ("t_final", "stationary")
    assert classify_regime(summary["final"]["pattern"]) == REGIME_SCENES[name]
    assert summary["final"]["edges_folded_over_limit"] == 0
