"""The kill/resume matrix on a tiny scene: every way a run can be stopped ends in a directory that
``femshell run --out DIR --resume --reproducible`` (without naming the scene again) completes bit for
bit as the uninterrupted run, and that ``femshell render DIR`` draws. A run killed in the default
(threaded) mode continues to round-off (:func:`test_kill_9_mid_run_in_the_default_mode`).

kill -9 is real: ``femshell run`` in a subprocess that kills itself at a chosen point (no timing
races). SIGTERM and SIGINT are raised in this process, as in the other end-to-end tests.
"""

import json
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from femshell.cli import main
from femshell.config import REPRODUCIBLE_ENV
from femshell.io import load_checkpoint
from femshell.scene import runner

from test_scene_e2e import _tree, assert_same_run, run, sets

# 150 vertices, 3 time steps
TINY = ["mesh.n_vertices=150", "solver.t_final=0.06", "output.every=1"]

# a femshell run that kills itself (SIGKILL) at a point named by argv[1]; the rest of argv is the command line
KILLER = r"""
import os, signal, sys
from pathlib import Path
from femshell.cli import main
from femshell.scene import runner

def kill():
    os.kill(os.getpid(), signal.SIGKILL)

def before(cls, name, when=lambda self, *a: True):
    real = getattr(cls, name)
    def wrapped(self, *a, **k):
        if when(self, *a):
            kill()
        return real(self, *a, **k)
    setattr(cls, name, wrapped)

def after(cls, name, when):
    real = getattr(cls, name)
    def wrapped(self, *a, **k):
        out = real(self, *a, **k)
        if when(self, *a):
            kill()
        return out
    setattr(cls, name, wrapped)

point = sys.argv[1]
if point == "equilibrium":                 # start-up: nothing accepted yet
    before(runner.TimeRunner, "initialise")
elif point == "first-checkpoint":          # start-up: the first checkpoint written, scene.toml not yet
    before(runner.RunDir, "start")
elif point == "mid-run":                   # after the checkpoint of step 2
    after(runner.BaseRunner, "checkpoint", lambda self: self.step == 2)
elif point == "pictures":                  # summary.json says finished, the final pictures are being drawn
    before(runner.TimeRunner, "pictures")
elif point == "overwrite-moving":          # --overwrite: half of the earlier run's files set aside
    real_rename, calls = Path.rename, [0]
    def rename(self, target):
        calls[0] += 1
        if calls[0] == 3:
            kill()
        return real_rename(self, target)
    Path.rename = rename
elif point == "overwrite-started":         # --overwrite: the new run's first checkpoint written
    before(runner.RunDir, "start")
sys.exit(main(sys.argv[2:]))
"""


def killed_run(point, out, *args, reproducible=True):
    """``femshell run default --out OUT TINY ARGS`` killed at ``point``; asserts that it was. With
    ``--reproducible`` or in the default mode: either way without the test process's reproducible
    environment (conftest), so that the command line alone sets the mode."""
    env = {k: v for k, v in os.environ.items() if k not in REPRODUCIBLE_ENV}
    # the subprocesses compile the shell's kernels: cache every compilation, not only the long ones
    env.setdefault("JAX_COMPILATION_CACHE_DIR", os.environ.get(
        "FEMSHELL_JAX_CACHE", str(Path.home() / ".cache" / "femshell-jax")))
    env["JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"] = "0"
    cmd = [sys.executable, "-c", KILLER, point, "run", "default", "--out", str(out), "-q", *sets(TINY), *args,
           *(["--reproducible"] if reproducible else [])]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == -signal.SIGKILL, proc.stderr[-3000:]


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    out = tmp_path_factory.mktemp("matrix") / "run"
    assert run("default", out, overrides=TINY, pictures=True, extra=["--reproducible"]) == 0
    return out


def resume(out, capsys=None):
    """``femshell run --out OUT --resume --reproducible``, without the scene."""
    return main(["run", "--out", str(out), "--resume", "-q", "--reproducible"])


def assert_complete(out, uninterrupted):
    """Finished as the uninterrupted run, bit for bit, with its final pictures; render draws it."""
    assert_same_run(uninterrupted, out)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "t_final" and not summary["files"]["pictures_pending"]
    for name in ("top.png", "side.png"):
        assert (out / "pictures" / name).stat().st_size > 1000
    assert main(["render", str(out), "--no-movie", "--every", "1000"]) == 0
    assert (out / "pictures" / "side_last.png").stat().st_size > 1000


def test_kill_9_at_start_up(uninterrupted, tmp_path, capsys):
    # before the first accepted state: nothing to resume, and the same command starts it again
    out = tmp_path / "early"
    killed_run("equilibrium", out, "--set", "output.pictures=true")
    assert resume(out) == 2
    assert "nothing to resume" in capsys.readouterr().err
    assert run("default", out, overrides=TINY, pictures=True, extra=["--reproducible"]) == 0
    assert_complete(out, uninterrupted)
    # the first checkpoint written, scene.toml not yet: the checkpoint's own scene resumes it
    out = tmp_path / "first"
    killed_run("first-checkpoint", out, "--set", "output.pictures=true")
    assert not (out / "scene.toml").exists()
    assert resume(out) == 0
    assert_complete(out, uninterrupted)


def test_kill_9_mid_run_in_the_default_mode(uninterrupted, tmp_path):
    """Killed without --reproducible (MKL threaded, no strict reproducibility: each factorisation may
    differ from the reproducible run's in its last bits) and resumed without it: the run continues the
    reproducible one to round-off. (The resume runs in this process, which conftest put in the
    reproducible mode: MKL's mode is fixed once it is loaded.) Each state is a Newton solution to
    |∇Π| ≤ newton_rtol |∇Π(start)| + atol, newton_rtol = 1e-6: round-off in the solves moves it by far
    less than that tolerance's share of the step's change, itself a fraction of the state's size, so the
    states must agree to 1e-6 of their size, and the times, which the step rule derives from them."""
    out = tmp_path / "run"
    killed_run("mid-run", out, "--set", "output.pictures=true", reproducible=False)
    assert load_checkpoint(out / "checkpoint.npz")[1]["step"] == 2
    assert main(["run", "--out", str(out), "--resume", "-q"]) == 0
    sa, ma = load_checkpoint(uninterrupted / "checkpoint.npz")
    sb, mb = load_checkpoint(out / "checkpoint.npz")
    assert ma["step"] == mb["step"]
    for k in ("c", "u"):
        assert np.abs(sa[k] - sb[k]).max() <= 1e-6 * np.abs(sa[k]).max(), k
    assert sb["t"] == pytest.approx(sa["t"], rel=1e-6) and sb["dt"] == pytest.approx(sa["dt"], rel=1e-6)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "t_final" and not summary["files"]["pictures_pending"]


def test_kill_9_while_the_final_pictures_are_drawn(uninterrupted, tmp_path):
    """summary.json said finished, the pictures were missing, and --resume said "nothing to do"."""
    out = tmp_path / "run"
    killed_run("pictures", out, "--set", "output.pictures=true")
    assert json.loads((out / "summary.json").read_text())["files"]["pictures_pending"]
    assert not (out / "pictures" / "top.png").exists()
    assert resume(out) == 0                 # (render draws them too: test_scene_e2e's Ctrl-C cases)
    assert_complete(out, uninterrupted)


@pytest.mark.parametrize("point", ["overwrite-moving", "overwrite-started"])
def test_kill_9_during_an_overwrite(uninterrupted, tmp_path, point):
    """The earlier run waited in .femshell-replaced; --resume said "no scene.toml to resume from" and
    render found no series. Any later command puts it back, without the scene named again."""
    out = tmp_path / "run"
    assert run("default", out, overrides=TINY, extra=["--max-steps", "1", "--reproducible"]) == 0      # paused after step 1
    before = _tree(out)
    killed_run(point, out, "--overwrite", "--set", "output.pictures=true", "--set", "solver.t_final=0.02")
    assert (out / runner.REPLACED).is_dir()
    if point == "overwrite-started":        # render is the next command
        assert main(["render", str(out), "--no-movie", "--every", "1000"]) == 0
        shutil.rmtree(out / "pictures")     # the earlier run had none
        assert _tree(out) == before
    assert main(["run", "--out", str(out), "--resume", "-q", "--reproducible", "--set", "output.pictures=true"]) == 0
    assert not (out / runner.REPLACED).exists()
    assert_complete(out, uninterrupted)


@pytest.mark.usefixtures("ctrl_c_raises")
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_stop_mid_run_and_a_second_one_while_the_results_are_written(uninterrupted, tmp_path, monkeypatch, sig):
    """SIGTERM (or Ctrl-C) in step 2; with SIGINT, a second Ctrl-C while the results are written."""
    from femshell import io as fio

    advance = runner.TimeRunner.advance
    write_summary = fio.write_summary

    def stopped_in_step_2(self):
        if self.step == 1:
            signal.raise_signal(sig)
        return advance(self)

    def second_ctrl_c(*a, **k):
        signal.raise_signal(signal.SIGINT)
        return write_summary(*a, **k)

    monkeypatch.setattr(runner.TimeRunner, "advance", stopped_in_step_2)
    if sig == signal.SIGINT:
        monkeypatch.setattr(fio, "write_summary", second_ctrl_c)
    out = tmp_path / "run"
    assert run("default", out, overrides=TINY, pictures=True, extra=["--reproducible"]) == 130
    monkeypatch.undo()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["steps"] == 1
    assert resume(out) == 0
    assert_complete(out, uninterrupted)
