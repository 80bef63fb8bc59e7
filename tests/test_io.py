"""femshell.io: atomic files, no NaN in results, PVD/VTU time series with resume, checkpoints."""

import json
import os
import warnings
from pathlib import Path

import meshio
import numpy as np
import pytest

from femshell.io import (CheckpointError, TimeSeriesWriter, atomic_write, atomic_write_json, check_generated,
                         find_series, load_checkpoint, read_frame, read_pvd, replace_generated, save_checkpoint,
                         write_summary)
from femshell.mesh import SurfaceMesh


@pytest.fixture
def square():
    """A unit square of two triangles (4 vertices)."""
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    return SurfaceMesh(pts, np.array([[0, 1, 2], [0, 2, 3]]))


def _leftovers(d):
    return [p for p in os.listdir(d) if ".tmp-" in p]


# ----------------------------------------------------------------------------- atomic files

def test_atomic_write_keeps_old_file_when_writer_raises(tmp_path):
    p = tmp_path / "result.txt"
    p.write_text("good")

    def bad_writer(tmp):
        with open(tmp, "w") as f:
            f.write("half a fi")
        raise RuntimeError("killed")

    with pytest.raises(RuntimeError, match="killed"):
        atomic_write(p, bad_writer)
    assert p.read_text() == "good"
    assert _leftovers(tmp_path) == []

    atomic_write(p, lambda tmp: Path(tmp).write_text("better"))
    assert p.read_text() == "better"
    assert _leftovers(tmp_path) == []


def test_generated_page_rewritten_between_markers_and_bad_page_named(tmp_path):
    begin, end = "<!-- BEGIN -->", "<!-- END -->"
    page = tmp_path / "page.md"
    page.write_text(f"head\n{begin}\nold\n{end}\ntail\n")
    replace_generated(page, begin, end, "new")
    assert page.read_text() == f"head\n{begin}\nnew\n{end}\ntail\n"
    with pytest.raises(ValueError, match="missing.md: cannot read"):
        check_generated(tmp_path / "missing.md", begin, end)
    (tmp_path / "plain.md").write_text("no markers\n")
    with pytest.raises(ValueError, match="plain.md: no generated-part markers"):
        replace_generated(tmp_path / "plain.md", begin, end, "new")
    assert (tmp_path / "plain.md").read_text() == "no markers\n"


def test_json_refuses_nan_and_names_the_key(tmp_path):
    p = tmp_path / "summary.json"
    p.write_text('{"old": 1}')
    doc = {"case": "x", "rows": [{"value": 1.0}, {"value": 2.0}, {"value": 3.0}, {"value": float("nan")}]}
    with pytest.raises(ValueError, match=r"summary\.json: rows\[3\]\.value is NaN"):
        atomic_write_json(p, doc)
    with pytest.raises(ValueError, match=r"summary\.json: final\.amplitude is -inf"):
        write_summary(tmp_path, {"final": {"amplitude": np.float64(-np.inf)}})
    with pytest.raises(ValueError, match=r"summary\.json: c_max\[1\] is inf"):
        write_summary(tmp_path, {"c_max": np.array([0.1, np.inf])})
    with pytest.raises(ValueError, match=r"summary\.json: counts has two keys that are both '1'"):
        write_summary(tmp_path, {"counts": {1: 3, "1": 4}})     # json.dumps writes both, a reader keeps one
    assert json.loads(p.read_text()) == {"old": 1}   # untouched

    out = write_summary(tmp_path, {"steps": np.int64(3), "wall_s": np.float32(1.5), "ok": np.bool_(True),
                                   "reference": None, "c": np.array([0.0, 0.5])})
    assert out == p
    assert json.loads(p.read_text()) == {"steps": 3, "wall_s": 1.5, "ok": True, "reference": None,
                                         "c": [0.0, 0.5]}


# ----------------------------------------------------------------------------- time series

def _frame_fields(k, n=4, m=2):
    return ({"c": np.linspace(0, 1, n) * k, "u": np.arange(3 * n, dtype=float).reshape(n, 3) + k},
            {"s": np.full(m, 1.0 + 0.1 * k)})


def test_time_series_roundtrip_with_meshio(tmp_path, square):
    w = TimeSeriesWriter(tmp_path, square)
    times = [0.0, 0.1, 0.25]
    for k, t in enumerate(times):
        pd, cd = _frame_fields(k)
        w.write(t, square.points + [0, 0, 0.01 * k], pd, cd)
    entries = read_pvd(tmp_path / "series.pvd")
    assert [t for t, _ in entries] == times
    assert [p.name for _, p in entries] == ["series_000000.vtu", "series_000001.vtu", "series_000002.vtu"]
    for k, (t, p) in enumerate(entries):
        m = meshio.read(p)
        pd, cd = _frame_fields(k)
        np.testing.assert_array_equal(m.points, square.points + [0, 0, 0.01 * k])
        np.testing.assert_array_equal(m.cells_dict["triangle"], square.triangles)
        np.testing.assert_array_equal(m.point_data["c"], pd["c"])
        np.testing.assert_array_equal(m.point_data["u"], pd["u"])
        np.testing.assert_array_equal(m.cell_data["s"][0], cd["s"])
    f = read_frame(entries[-1][1], entries[-1][0])
    assert f.time == 0.25 and set(f.point_data) == {"c", "u"}
    assert find_series(tmp_path) == tmp_path / "series.pvd"
    assert find_series(tmp_path, "series") == find_series(tmp_path, "series.pvd") == tmp_path / "series.pvd"
    assert _leftovers(tmp_path) == []


def test_time_series_refuses_nonfinite_naming_the_field(tmp_path, square):
    w = TimeSeriesWriter(tmp_path, square)
    with pytest.raises(ValueError, match="point field 'c'.*NaN"):
        w.write(0.0, point_data={"c": np.array([0, np.nan, 0, 0])})
    with pytest.raises(ValueError, match="cell field 'stretch'.*inf"):
        w.write(0.0, cell_data={"stretch": np.array([1.0, np.inf])})
    with pytest.raises(ValueError, match="point field 'c' has shape"):
        w.write(0.0, point_data={"c": np.zeros(3)})
    with pytest.raises(ValueError, match="points hold non-finite"):
        w.write(0.0, points=np.full((4, 3), np.nan))
    with pytest.raises(ValueError, match=r"has shape \(4, 0\); expected .* k >= 1"):
        w.write(0.0, point_data={"c": np.zeros((4, 0))})
    assert len(w) == 0 and not list(tmp_path.glob("*.vtu"))
    w.write(0.0, point_data={"c": np.zeros(4)})
    with pytest.raises(ValueError, match="times must increase"):
        w.write(0.0, point_data={"c": np.zeros(4)})


def test_time_series_resume_truncates_to_checkpoint(tmp_path, square):
    """Run to t = 0.4 (checkpoint at 0.2), get killed, resume: same series as an uninterrupted run."""
    times = [0.0, 0.1, 0.2, 0.3, 0.4]
    ref_dir, run_dir = tmp_path / "ref", tmp_path / "run"
    ref = TimeSeriesWriter(ref_dir, square)
    for k, t in enumerate(times):
        ref.write(t, point_data=_frame_fields(k)[0])

    w = TimeSeriesWriter(run_dir, square)
    for k, t in enumerate(times[:4]):
        w.write(t, point_data=_frame_fields(k)[0])
    (run_dir / "series_000004.vtu").write_text("torn frame of the killed run")   # orphan, not in the .pvd
    del w

    w = TimeSeriesWriter(run_dir, square, resume=True)
    assert w.times == times[:4]
    assert not (run_dir / "series_000004.vtu").exists()
    removed = w.truncate_after(0.2)
    assert [p.name for p in removed] == ["series_000003.vtu"]
    assert w.times == [0.0, 0.1, 0.2]
    assert [t for t, _ in read_pvd(run_dir / "series.pvd")] == [0.0, 0.1, 0.2]
    for k, t in enumerate(times[3:], start=3):
        w.write(t, point_data=_frame_fields(k)[0])

    a, b = read_pvd(ref_dir / "series.pvd"), read_pvd(run_dir / "series.pvd")
    assert [(t, p.name) for t, p in a] == [(t, p.name) for t, p in b]
    for (_, pa), (_, pb) in zip(a, b):
        ma, mb = meshio.read(pa), meshio.read(pb)
        np.testing.assert_array_equal(ma.points, mb.points)
        np.testing.assert_array_equal(ma.point_data["c"], mb.point_data["c"])
    assert sorted(p.name for p in run_dir.iterdir()) == sorted(p.name for p in ref_dir.iterdir())

    # a new (not resumed) run in the same directory starts a fresh series, but the earlier one
    # stays until the new run's first frame passes its checks
    earlier, index = sorted(run_dir.glob("series_*.vtu")), read_pvd(run_dir / "series.pvd")
    w = TimeSeriesWriter(run_dir, square)
    with pytest.raises(ValueError, match="non-finite"):
        w.write(0.0, point_data={"c": np.array([0, np.nan, 0, 0])})
    assert sorted(run_dir.glob("series_*.vtu")) == earlier and read_pvd(run_dir / "series.pvd") == index
    w.write(0.0, point_data={"c": np.zeros(4)})
    assert [p.name for _, p in read_pvd(run_dir / "series.pvd")] == ["series_000000.vtu"]
    assert [p.name for p in run_dir.glob("series_*.vtu")] == ["series_000000.vtu"]


def test_a_resumed_series_keeps_frames_that_are_symlinks(tmp_path, square):
    # a run directory assembled from links (to a copy elsewhere) is a run like any other
    src, linked = tmp_path / "src", tmp_path / "linked"
    w = TimeSeriesWriter(src, square)
    for k, t in enumerate([0.0, 0.1, 0.2]):
        w.write(t, point_data=_frame_fields(k)[0])
    linked.mkdir()
    for p in src.iterdir():
        (linked / p.name).symlink_to(p)
    w = TimeSeriesWriter(linked, square, resume=True)
    assert w.times == [0.0, 0.1, 0.2]
    assert sorted(p.name for p in linked.glob("series_*.vtu")) == ["series_000000.vtu", "series_000001.vtu",
                                                                   "series_000002.vtu"]
    # a frame outside the run directory is still dropped, and said to be
    (linked / "series.pvd").unlink()
    (linked / "series.pvd").write_text((src / "series.pvd").read_text().replace("series_000002.vtu",
                                                                                "../src/series_000002.vtu"))
    with pytest.warns(RuntimeWarning, match="series_000002.vtu at time 0.2 is missing or outside"):
        w = TimeSeriesWriter(linked, square, resume=True)
    assert w.times == [0.0, 0.1]
    # frames without their index cannot be resumed: said, and nothing deleted
    (src / "series.pvd").unlink()
    frames = sorted(p.name for p in src.glob("series_*.vtu"))
    with pytest.raises(ValueError, match="series.pvd is missing: the frames of .* cannot be resumed"):
        TimeSeriesWriter(src, square, resume=True)
    assert sorted(p.name for p in src.glob("series_*.vtu")) == frames


# ----------------------------------------------------------------------------- checkpoints

def _state(k):
    return {"x": np.arange(300.0).reshape(100, 3) * k, "c": np.linspace(0, 1, 100) + k,
            "time": 0.1 * k, "step": k, "scene": "sphere-spots", "converged": True}


def test_checkpoint_roundtrip_and_prev(tmp_path):
    p = tmp_path / "checkpoint.npz"
    save_checkpoint(p, _state(1), {"time": 0.1, "step": 1, "params": {"h": 2.0}})
    assert not (tmp_path / "checkpoint.npz.prev").exists()
    save_checkpoint(p, _state(2), {"time": 0.2, "step": 2, "params": {"h": 2.0}})
    state, meta = load_checkpoint(p)
    ref = _state(2)
    assert meta == {"time": 0.2, "step": 2, "params": {"h": 2.0}}
    assert set(state) == set(ref)
    np.testing.assert_array_equal(state["x"], ref["x"])
    np.testing.assert_array_equal(state["c"], ref["c"])
    assert state["time"] == 0.2 and isinstance(state["time"], float)
    assert state["step"] == 2 and isinstance(state["step"], int)
    assert state["scene"] == "sphere-spots" and state["converged"] is True
    prev_state, prev_meta = load_checkpoint(tmp_path / "checkpoint.npz.prev")
    assert prev_meta["step"] == 1 and prev_state["step"] == 1
    assert _leftovers(tmp_path) == []

    with pytest.raises(ValueError, match="state 'c' holds non-finite values"):
        save_checkpoint(p, {**_state(3), "c": np.array([0.0, np.nan])})
    with pytest.raises(ValueError, match=r"meta: time is NaN"):
        save_checkpoint(p, _state(3), {"time": float("nan")})
    assert load_checkpoint(p)[1]["step"] == 2   # the refused saves changed nothing


def test_checkpoint_falls_back_to_prev_when_corrupt(tmp_path):
    p = tmp_path / "checkpoint.npz"
    save_checkpoint(p, _state(1), {"step": 1})
    save_checkpoint(p, _state(2), {"step": 2})
    data = bytearray(p.read_bytes())
    data[len(data) // 3] ^= 0xFF            # flip a byte inside the array data
    p.write_bytes(bytes(data))
    with pytest.warns(RuntimeWarning, match="corrupt.*checkpoint.npz.prev"):
        state, meta = load_checkpoint(p)
    assert meta == {"step": 1} and state["step"] == 1

    p.write_bytes(bytes(data[: len(data) // 2]))   # truncated, as by a full disk
    with pytest.warns(RuntimeWarning):
        assert load_checkpoint(p)[1] == {"step": 1}

    (tmp_path / "checkpoint.npz.prev").write_bytes(b"garbage")
    with pytest.raises(CheckpointError, match="no readable checkpoint"):
        load_checkpoint(p)
    # random bytes: named as not a checkpoint, without numpy's advice to unpickle them
    p.write_bytes(np.random.default_rng(0).bytes(2000))
    (tmp_path / "checkpoint.npz.prev").unlink()
    with pytest.raises(CheckpointError, match="not an .npz archive") as err:
        load_checkpoint(p)
    assert "pickle" not in str(err.value)
    with pytest.raises(FileNotFoundError, match="no checkpoint"):
        load_checkpoint(tmp_path / "missing.npz")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        save_checkpoint(p, _state(3), {"step": 3})   # a corrupt current file is simply replaced
        assert load_checkpoint(p)[1] == {"step": 3}


def test_a_checkpoint_that_failed_to_read_is_never_rotated_into_prev(tmp_path):
    """A resume that fell back to .prev, then saved: the corrupt file became .prev, and the one step
    after had no readable fallback (issue 65, item 5)."""
    p = tmp_path / "checkpoint.npz"
    save_checkpoint(p, _state(1), {"step": 1})
    save_checkpoint(p, _state(2), {"step": 2})
    data = bytearray(p.read_bytes())
    data[len(data) // 3] ^= 0xFF
    p.write_bytes(bytes(data))
    with pytest.warns(RuntimeWarning, match="previous checkpoint"):
        assert load_checkpoint(p)[1] == {"step": 1}
    save_checkpoint(p, _state(2), {"step": 2})              # the resumed run's next checkpoint
    prev = tmp_path / "checkpoint.npz.prev"
    assert load_checkpoint(prev)[1] == {"step": 1}         # still the readable fallback
    p.write_bytes(bytes(data))                             # and if the new one is lost too
    with pytest.warns(RuntimeWarning):
        assert load_checkpoint(p)[1] == {"step": 1}
    # a readable current checkpoint, also one another process wrote, is still rotated
    save_checkpoint(p, _state(3), {"step": 3})
    p.write_bytes(p.read_bytes())                          # same content, not written by save_checkpoint
    save_checkpoint(p, _state(4), {"step": 4})
    assert load_checkpoint(prev)[1] == {"step": 3}


def test_paths_and_values_that_cannot_be_written_or_read(tmp_path):
    (tmp_path / "isdir.npz").mkdir()
    with pytest.raises(ValueError, match="is a directory"):
        save_checkpoint(tmp_path / "isdir.npz", _state(1))
    with pytest.raises(TypeError, match="meta must be a dict, got list"):
        save_checkpoint(tmp_path / "m.npz", _state(1), [1, 2])
    with pytest.raises(ValueError, match="does not fit in 64 bits"):
        save_checkpoint(tmp_path / "big.npz", {"n": 2**70})
    with pytest.raises(ValueError, match="is a directory; cannot write a file there"):
        atomic_write_json(tmp_path, {"a": 1})
    np.savez(tmp_path / "list.npz", __femshell_header__=np.frombuffer(b"[1, 2]", np.uint8))
    with pytest.raises(CheckpointError, match="malformed header"):
        load_checkpoint(tmp_path / "list.npz")
    with pytest.raises(ValueError, match="is a directory, not a PVD file"):
        read_pvd(tmp_path)
    (tmp_path / "nan.pvd").write_text('<VTKFile type="Collection"><Collection>'
                                      '<DataSet timestep="nan" file="a.vtu"/></Collection></VTKFile>')
    with pytest.raises(ValueError, match="without a finite numeric timestep"):
        read_pvd(tmp_path / "nan.pvd")


def test_a_failed_atomic_write_names_the_target_not_the_temporary_file(tmp_path, monkeypatch):
    """A directory where the temporary file cannot be made (read-only) was reported as
    '.summary.json.tmp-1234-abcd.json: Permission denied'."""
    import builtins

    from femshell.io import atomic_write_text

    real = builtins.open

    def refusing(file, *a, **k):
        if ".tmp-" in str(file):
            raise PermissionError(13, "Permission denied", str(file))
        return real(file, *a, **k)

    monkeypatch.setattr(builtins, "open", refusing)
    with pytest.raises(PermissionError) as err:
        atomic_write_text(tmp_path / "summary.json", "{}")
    assert err.value.filename == str(tmp_path / "summary.json") and "Permission denied" in err.value.strerror
    assert list(tmp_path.iterdir()) == []
