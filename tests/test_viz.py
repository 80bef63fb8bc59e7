"""femshell.viz: top view of a sphere, bifurcation diagram, GIF movie, render_run of a tiny run."""

import sys

import numpy as np
import pytest
from PIL import Image

from femshell import viz
from femshell.io import TimeSeriesWriter


def test_import_is_cheap():
    import subprocess
    code = "import sys, femshell.viz; print('pyvista' in sys.modules, 'matplotlib' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "False"]


@pytest.fixture(scope="module")
def small_sphere():
    from femshell.mesh.generators import sphere
    return sphere(radius=1.0, n_vertices=600)


def test_top_view_png(tmp_path, small_sphere):
    m = small_sphere
    p = viz.top_view(m.points, m.triangles, ("z", m.points[:, 2]), tmp_path / "top.png", title="z")
    assert p == tmp_path / "top.png"
    img = np.asarray(Image.open(p).convert("RGB"), dtype=float)
    assert img.shape == (800, 800, 3)
    assert img.std() > 10                         # not blank
    centre = img[350:450, 300:370]                # the north pole: top of the viridis map (yellow)
    assert centre[..., 0].mean() > 120 and centre[..., 2].mean() < 120
    with pytest.raises(ValueError, match="field 'c' holds NaN"):
        viz.top_view(m.points, m.triangles, ("c", np.full(m.n_vertices, np.nan)), tmp_path / "nan.png")
    for clim in ((np.nan, 1.0), (1.0, 0.0), (1.0,)):
        with pytest.raises(ValueError, match="clim must be two finite numbers"):
            viz.top_view(m.points, m.triangles, m.points[:, 2], tmp_path / "nan.png", clim=clim)
    assert not (tmp_path / "nan.png").exists()


def test_render_run(tmp_path, small_sphere):
    m = small_sphere
    w = TimeSeriesWriter(tmp_path, m)
    for k in range(3):
        c = 0.25 * k * np.exp(-((m.points[:, 0] ** 2 + m.points[:, 1] ** 2) / 0.1)) * (m.points[:, 2] > 0)
        w.write(0.5 * k, m.points * (1 + 0.05 * c[:, None]), {"c": c, "H": m.points[:, 2]})
    files = viz.render_run(tmp_path)
    names = [p.relative_to(tmp_path).as_posix() for p in files]
    assert names == ["pictures/top_000000.png", "pictures/top_000001.png", "pictures/top_000002.png",
                     "pictures/side_last.png", "movie.gif"]
    with Image.open(tmp_path / "movie.gif") as g:
        assert g.n_frames == 3 and g.size == (800, 800)
    # a rendering of fewer frames replaces the earlier top_NNNNNN.png, not a user's file there
    (tmp_path / "pictures" / "top_mine.png").write_bytes(b"mine")
    viz.render_run(tmp_path, every=2, movie=False)
    assert sorted(p.name for p in (tmp_path / "pictures").glob("top_*.png")) == [
        "top_000000.png", "top_000002.png", "top_mine.png"]
    viz.render_run(tmp_path)

    # a broken frame, a bad colour map or frame rate: refused before any picture is replaced
    before = {p: p.read_bytes() for p in (tmp_path / "pictures").iterdir()}
    for kwargs, words in (({"cmap": "no-such-map"}, "unknown colour map 'no-such-map'"),
                          ({"fps": 0.001}, r"fps must be a number in \[0.002, 50\]")):
        with pytest.raises(ValueError, match=words):
            viz.render_run(tmp_path, **kwargs)
    import meshio   # the writer refuses NaN points itself: break a frame file by hand

    frame = meshio.read(tmp_path / "series_000001.vtu")
    frame.points[5] = np.nan
    meshio.write(tmp_path / "series_000001.vtu", frame)
    with pytest.raises(ValueError, match="series_000001.vtu: points hold NaN"):
        viz.render_run(tmp_path, cmap="plasma")
    assert {p: p.read_bytes() for p in (tmp_path / "pictures").iterdir()} == before


def test_render_run_colour_range_is_the_one_a_single_picture_gets(tmp_path, small_sphere, monkeypatch):
    # c of order 1e-108 at the start of a run: the colour bar of every frame starts at 0, as top_view's own
    m = small_sphere
    w = TimeSeriesWriter(tmp_path, m)
    for k in range(2):
        w.write(float(k), m.points, {"c": np.full(m.n_vertices, 1e-108) + k * (m.points[:, 2] > 0)})
    seen = []
    monkeypatch.setattr(viz, "top_view", lambda *a, clim=None, **k: seen.append(clim))
    viz.render_run(tmp_path, movie=False)
    assert seen == [(0.0, 1.0)] * 2


def test_bifurcation_diagram(tmp_path):
    lam = np.linspace(0, 2, 41)
    rows = [{"parameter": float(l), "amplitude": 0.0, "stable": bool(l < 1), "branch": "trivial"} for l in lam]
    a = np.linspace(0, 1, 21)
    rows += [{"parameter": float(1 + s * t - t ** 3), "amplitude": float(t), "stable": bool(t > 0.577),
              "branch": "buckled"} for t in a for s in [0.0]]
    p = viz.bifurcation_diagram(rows, x="parameter", y="amplitude", path=tmp_path / "bif.png",
                                special_points=[{"x": 1.0, "y": 0.0, "kind": "BP", "label": "BP1"},
                                                {"x": 1 - 2 / (3 * np.sqrt(3)), "y": 0.577, "kind": "fold",
                                                 "label": "LP1"}], title="test")
    img = np.asarray(Image.open(p).convert("RGB"))
    assert img.shape[2] == 3 and img.std() > 5
    cols = {"parameter": lam, "amplitude": lam ** 2, "stable": lam < 1.5}
    assert viz.bifurcation_diagram(cols, y="amplitude", path=tmp_path / "bif2.png").exists()
    with pytest.raises(ValueError, match="no column 'energy'"):
        viz.bifurcation_diagram(cols, y="energy", path=tmp_path / "bif3.png")


def test_picture_paths_and_csv_stability_flags(tmp_path, small_sphere):
    m = small_sphere
    with pytest.raises(ValueError, match="picture path .*frame must end in one of .png"):
        viz.top_view(m.points, m.triangles, m.points[:, 2], tmp_path / "frame")
    (tmp_path / "d.png").mkdir()
    with pytest.raises(ValueError, match="is a directory"):
        viz.top_view(m.points, m.triangles, m.points[:, 2], tmp_path / "d.png")
    rows = [{"parameter": "0", "amplitude": "0", "stable": "True"}, {"parameter": "1", "amplitude": "1",
                                                                    "stable": "False"}]
    assert viz._stable_flags([r["stable"] for r in rows], 2) == [True, False]    # bool("False") is True
    assert viz.bifurcation_diagram(rows, path=tmp_path / "b.png").exists()
    with pytest.raises(ValueError, match="stable flag 'maybe'"):
        viz._stable_flags(["maybe"], 1)
    with pytest.raises(TypeError, match="got NoneType"):
        viz.bifurcation_diagram(None, path=tmp_path / "c.png")


def test_render_movie_from_arrays_and_callback(tmp_path):
    frames = [np.full((40, 60, 3), 40 * k, np.uint8) for k in range(4)]
    p = viz.render_movie(frames, tmp_path / "a.gif", fps=10)
    with Image.open(p) as g:
        assert g.n_frames == 4 and g.size == (60, 40)
    p = viz.render_movie(lambda i: frames[i], tmp_path / "b.gif", n_frames=2)
    with Image.open(p) as g:
        assert g.n_frames == 2
    made = []
    with pytest.raises(ValueError, match="not supported"):
        viz.render_movie(lambda i: made.append(i) or frames[i], tmp_path / "c.avi", n_frames=2)
    assert made == []                                  # refused before a frame was drawn
    # a GIF stores frame times in 1/100 s and viewers slow frames under 2/100 s to 1/10 s
    with pytest.raises(ValueError, match=r"fps must be a number in \[0.002, 50\] frames per second for a GIF"):
        viz.render_movie(frames, tmp_path / "d.gif", fps=60)
    with Image.open(viz.render_movie(frames, tmp_path / "e.gif", fps=50)) as g:
        assert g.info["duration"] == 20
