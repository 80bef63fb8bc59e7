"""femshell.solvers.continuation: folds, branch points, multiplicity, branch switching, output, a shell case."""

import csv
import json
import math

import numpy as np
import pytest
import scipy.sparse as sp

from femshell.io import write_branch_csv, write_special_points
from femshell.solvers.continuation import (Branch, ContinuationError, GrowthParameter, LoadParameter, continuation,
                                           switch_branch)
from femshell.solvers.corrector import _Engine


# ----------------------------------------------------------------------------- analytic problems

class Truss:
    """Shallow (von Mises) truss with two extra unknowns.

    Π = ¼ (w² − 2w)² + ½ (1 + w) v² + ½ (z − w)² − λ w. On v = 0, z = w the equilibrium is
    λ = w³ − 3w² + 2w: a fold (snap-through) at w = 1 − 1/√3, λ = 2/(3√3).
    """

    def set_parameter(self, lam):
        self.lam = lam

    def energy(self, u):
        w, v, z = u
        return 0.25 * (w * w - 2 * w) ** 2 + 0.5 * (1 + w) * v * v + 0.5 * (z - w) ** 2 - self.lam * w

    def gradient(self, u):
        w, v, z = u
        return np.array([(w * w - 2 * w) * (w - 1) + 0.5 * v * v - (z - w) - self.lam, (1 + w) * v, z - w])

    def hessian(self, u):
        w, v, z = u
        a = 0.5 * ((2 * w - 2) ** 2 + 2 * (w * w - 2 * w)) + 1
        return sp.csr_matrix(np.array([[a, v, -1.0], [v, 1 + w, 0.0], [-1.0, 0.0, 1.0]]))


class Pitchfork:
    """Π = ½ (x − λ)² + ½ (1 − λ) y² + ¼ y⁴: trivial branch y = 0, supercritical branches y² = λ − 1."""

    def set_parameter(self, lam):
        self.lam = lam

    def energy(self, u):
        x, y = u
        return 0.5 * (x - self.lam) ** 2 + 0.5 * (1 - self.lam) * y * y + 0.25 * y**4

    def gradient(self, u):
        x, y = u
        return np.array([x - self.lam, (1 - self.lam) * y + y**3])

    def hessian(self, u):
        x, y = u
        return sp.csr_matrix(np.diag([1.0, 1 - self.lam + 3 * y * y]))


class Square:
    """A double branch point with square (D4) symmetry at λ = 1.

    Π = ½ (x − λ)² + ½ (1 − λ)(y² + z²) + ¼ (y² + z²)² + c y² z²: branches along the axes
    (y² = λ − 1, stable for c > 0) and the diagonals (unstable for c > 0).
    """

    c = 0.5

    def set_parameter(self, lam):
        self.lam = lam

    def energy(self, u):
        x, y, z = u
        r2 = y * y + z * z
        return 0.5 * (x - self.lam) ** 2 + 0.5 * (1 - self.lam) * r2 + 0.25 * r2 * r2 + self.c * y * y * z * z

    def gradient(self, u):
        x, y, z = u
        r2 = y * y + z * z
        a = 1 - self.lam
        return np.array([x - self.lam, a * y + r2 * y + 2 * self.c * y * z * z,
                         a * z + r2 * z + 2 * self.c * z * y * y])

    def hessian(self, u):
        x, y, z = u
        r2 = y * y + z * z
        a, c = 1 - self.lam, self.c
        off = 2 * y * z + 4 * c * y * z
        return sp.csr_matrix(np.array([[1.0, 0, 0], [0, a + r2 + 2 * y * y + 2 * c * z * z, off],
                                       [0, off, a + r2 + 2 * z * z + 2 * c * y * y]]))


class Touch:
    """An eigenvalue (λ − 1)² + 1e-4 that touches (nearly) zero at λ = 1 without crossing."""

    def set_parameter(self, lam):
        self.lam = lam

    def energy(self, u):
        return 0.5 * (u[0] - self.lam) ** 2 + 0.5 * ((self.lam - 1) ** 2 + 1e-4) * u[1] ** 2

    def gradient(self, u):
        return np.array([u[0] - self.lam, ((self.lam - 1) ** 2 + 1e-4) * u[1]])

    def hessian(self, u):
        return sp.csr_matrix(np.diag([1.0, (self.lam - 1) ** 2 + 1e-4]))


# ----------------------------------------------------------------------------- folds and branch points

def test_fold_of_the_von_mises_truss_is_located_and_passed():
    b = continuation(Truss(), np.zeros(3), 0.0, ds=0.1, max_steps=40, lam_stop=-0.2, log=None)
    folds = [p for p in b.special_points if p.kind == "fold"]
    assert len(folds) == 1
    f = folds[0]
    assert abs(f.parameter - 2 / (3 * math.sqrt(3))) < 1e-6
    assert abs(f.u[0] - (1 - 1 / math.sqrt(3))) < 1e-3
    assert (f.n_negative_before, f.n_negative_after, f.multiplicity) == (0, 1, 1)
    assert abs(f.tangent[1]) < 1e-3                       # dλ/ds = 0 at the fold
    # the branch went on past the fold, onto the unstable part, down to lam_stop exactly
    assert b.status == "lam_stop" and b.rows[-1]["parameter"] == -0.2
    after = [r for r in b.rows if r["s"] > f.s and not r["special"]]
    assert after and all(r["n_negative"] == 1 and r["stable"] is False for r in after)
    assert [r["special"] for r in b.rows].count("LP") == 1
    # rows are in arclength order
    s = [r["s"] for r in b.rows]
    assert s == sorted(s)


def test_pitchfork_is_located_classified_and_switched():
    b = continuation(Pitchfork(), np.zeros(2), 0.0, ds=0.3, ds_max=0.3, lam_stop=1.6, log=None)
    assert [p.kind for p in b.special_points] == ["branch"]
    bp = b.special_points[0]
    assert abs(bp.parameter - 1.0) < 1e-6
    assert (bp.multiplicity, bp.n_negative_before, bp.n_negative_after) == (1, 0, 1)
    assert abs(abs(bp.modes[1, 0]) - 1) < 1e-12          # the critical mode is y
    assert all(r["stable"] == (r["parameter"] < 1) for r in b.rows if not r["special"])
    for sign in (+1, -1):
        nb = switch_branch(Pitchfork(), bp, amplitude=0.05 * sign, ds=0.05, lam_stop=1.5, log=None)
        assert nb.status == "lam_stop"
        for (u, lam), r in zip(nb.states, nb.rows):
            assert abs(u[1] ** 2 - (lam - 1)) < 1e-7        # on the bifurcated branch
            assert np.sign(u[1]) == sign
            assert r["stable"] is True                     # supercritical: stable
        assert abs(nb.states[-1][1] - 1.5) < 1e-14
        assert not nb.special_points
    for kw, words in (({"amplitude": np.nan}, "amplitude must be a finite number != 0"),
                      ({"amplitude": 0.0}, "amplitude must be"), ({"parameter_scale": 0.0}, "parameter_scale must be")):
        with pytest.raises(ValueError, match=words):
            switch_branch(Pitchfork(), bp, log=None, **kw)
    with pytest.raises(TypeError, match="special_point must be a SpecialPoint .* got Branch"):
        switch_branch(Pitchfork(), b, log=None)
    with pytest.raises(ValueError, match="initial_tangent must be"):
        continuation(Pitchfork(), np.zeros(2), 0.0, ds=0.1, initial_tangent=(np.zeros(2), 0.0), log=None)


def test_double_branch_point_multiplicity_and_mode_combinations():
    b = continuation(Square(), np.zeros(3), 0.0, ds=0.3, lam_stop=2.0, log=None)
    assert len(b.special_points) == 1
    bp = b.special_points[0]
    assert bp.kind == "branch" and bp.multiplicity == 2 and bp.modes.shape == (3, 2)
    assert abs(bp.parameter - 1) < 1e-6
    assert (bp.n_negative_before, bp.n_negative_after) == (0, 2)
    # the two modes span (y, z)
    assert np.allclose(np.abs(bp.modes[0]), 0.0)
    # pick the axis branch along y, along z, and the diagonal: combinations of the two modes
    P = bp.modes[1:, :]                                   # (y, z) components of the modes
    for target, stable in (([1.0, 0.0], True), ([0.0, 1.0], True), ([1.0, 1.0], False)):
        coeffs = np.linalg.solve(P, np.array(target))
        nb = switch_branch(Square(), bp, mode=coeffs, amplitude=0.05, lam_stop=1.5, log=None)
        u, lam = nb.states[-1]
        assert lam == 1.5
        direction = np.array(target) / np.linalg.norm(target)
        assert abs(abs(u[1:] @ direction) - np.linalg.norm(u[1:])) < 1e-8   # stayed on that ray
        assert nb.rows[-1]["stable"] is stable


def test_split_pair_is_two_branch_points_and_near_pair_is_one():
    class Split(Square):
        c = 0.5
        eps = 0.05

        def gradient(self, u):
            return super().gradient(u) + np.array([0, 0, self.eps * u[2]])

        def hessian(self, u):
            return super().hessian(u) + sp.diags([0, 0, self.eps])

        def energy(self, u):
            return super().energy(u) + 0.5 * self.eps * u[2] ** 2

    b = continuation(Split(), np.zeros(3), 0.0, ds=0.3, lam_stop=2.0, log=None)
    assert [round(p.parameter, 6) for p in b.special_points] == [1.0, 1.05]
    assert [p.multiplicity for p in b.special_points] == [1, 1]
    Split.eps = 1e-3                                       # within cluster_tol = 1 %: one double point
    b = continuation(Split(), np.zeros(3), 0.0, ds=0.3, lam_stop=2.0, log=None)
    assert [p.multiplicity for p in b.special_points] == [2]


def test_touching_eigenvalue_is_flagged_as_possible_bifurcation():
    b = continuation(Touch(), np.zeros(2), 0.0, ds=0.2, ds_max=0.2, lam_stop=2.0, log=None)
    assert [p.kind for p in b.special_points] == ["possible_branch"]
    p = b.special_points[0]
    assert abs(p.parameter - 1) < 0.02 and p.label == "BP?"
    assert abs(abs(p.modes[1, 0]) - 1) < 1e-12


# ----------------------------------------------------------------------------- step control, linear algebra

def test_full_bordered_solve_when_K_is_singular():
    eng = _Engine(Pitchfork(), np.ones(2), 1.0, backend="auto", rtol=1e-10, atol=0, xtol=1e-12, max_iter=8,
                  fd_step=1e-6, n_eigs=0, log=None)
    K = sp.csr_matrix(np.diag([0.0, 2.0]))
    gl = np.array([1.0, 0.0])
    c, d = np.array([1.0, 1.0]), 0.5
    du, dl = eng.solve_bordered(K, None, gl, c, d, np.array([3.0, 4.0]), 5.0)
    A = np.array([[0, 0, 1], [0, 2, 0], [1, 1, 0.5]])
    assert np.allclose(np.concatenate([du, [dl]]), np.linalg.solve(A, [3, 4, 5]))
    assert eng.counts["bordered_full"] == 1


def test_stops_at_ds_min_with_a_message():
    class Wall(Pitchfork):
        def gradient(self, u):
            if self.lam > 0.5:
                return np.full(2, np.nan)
            return super().gradient(u)

    b = continuation(Wall(), np.zeros(2), 0.0, ds=0.1, ds_min=1e-3, lam_stop=2.0, detect=False, log=None)
    assert b.status == "ds_min"
    assert "ds_min" in b.message and "step size fell below" in b.message and "non-finite" in b.message
    assert 0.4 < b.rows[-1]["parameter"] <= 0.5
    assert "At the last accepted point" not in b.message

    class Diagnosed(Wall):             # a problem that can say what is wrong has it added to the message
        def diagnose(self, u):
            return f"the load is {self.lam:.3f}"

    b = continuation(Diagnosed(), np.zeros(2), 0.0, ds=0.1, ds_min=1e-3, lam_stop=2.0, detect=False, log=None)
    assert b.message.endswith(f"At the last accepted point the load is {b.rows[-1]['parameter']:.3f}")


def test_a_parameter_the_problem_refuses_is_a_failed_step_and_the_branch_is_kept():
    class Bounded(Pitchfork):          # as a growth strain below -1: set_parameter raises
        def set_parameter(self, lam):
            if lam < -0.5:
                raise ValueError(f"lam must be >= -0.5, got {lam}")
            super().set_parameter(lam)

    b = continuation(Bounded(), np.zeros(2), 0.0, ds=0.1, ds_min=1e-3, direction=-1, detect=False, log=None)
    assert b.status == "ds_min" and "refused parameter" in b.message
    assert -0.5 <= b.rows[-1]["parameter"] < -0.45 and len(b.rows) > 4


def test_options_and_callbacks():
    def follow(**kw):
        return continuation(Pitchfork(), np.zeros(2), 0.0, ds=0.1, detect=False, log=None, **kw)

    for kw, words in (({"grow": np.nan}, "grow must be a finite number"), ({"grow": 0.5}, "grow must be"),
                      ({"n_eigs": 10**6}, r"n_eigs must be an integer in \[0, 1000\]"),
                      ({"max_steps": 2.5}, "max_steps must be an integer"),
                      ({"max_corrector_iterations": -1}, "max_corrector_iterations"),
                      ({"lam_stop": 0.0}, "is the start's parameter")):
        with pytest.raises(ValueError, match=words):
            follow(**kw)
    said = []
    b = continuation(Pitchfork(), np.zeros(2), 0.0, ds=0.1, detect=False, log=said.append, lam_stop=-1.0,
                     max_steps=3)
    assert b.status == "max_steps" and any("behind the start" in line for line in said)
    b = follow(lam_stop=5.0, callback=lambda br, row: np.bool_(row["parameter"] > 0.3))   # a numpy bool stops
    assert b.status == "callback" and b.rows[-1]["parameter"] < 1.0
    with pytest.raises(ValueError, match="column.*parameter.*already has"):
        follow(max_steps=2, record=lambda u: {"parameter": 42.0})


def test_bad_start_raises():
    class Nowhere(Pitchfork):
        def gradient(self, u):
            return np.full(2, np.nan)

    with pytest.raises(ContinuationError, match="first point"):
        continuation(Nowhere(), np.zeros(2), 0.0, ds=0.1, log=None)


class Fold:
    """r = u² + λ − 1 (Π = u³/3 + (λ − 1) u): a fold at u = 0, λ = 1."""

    def set_parameter(self, lam):
        self.lam = lam

    def energy(self, u):
        return u[0] ** 3 / 3 + (self.lam - 1) * u[0]

    def gradient(self, u):
        return np.array([u[0] ** 2 + self.lam - 1])

    def hessian(self, u):
        return sp.csr_matrix([[2 * u[0]]])


def test_bad_arguments_and_a_singular_start_are_named():
    def follow(problem=None, u0=np.zeros(2), lam0=0.0, **kw):
        return continuation(problem or Pitchfork(), u0, lam0, **({"ds": 0.1, "log": None, "max_steps": 2} | kw))

    for kw, words in (({"weights": [1.0, 0.0]}, "weights must be finite and > 0"),
                      ({"lam0": np.nan}, "lam0 must be a finite number"),
                      ({"lam_stop": "one"}, "lam_stop must be a number, got 'one'"),
                      ({"parameter_scale": "big"}, "parameter_scale must be a number"),
                      ({"cluster_tol": np.nan}, "cluster_tol must be a finite number in"),
                      ({"dip_tol": -1}, r"dip_tol must be a finite number in \[0, 1\]"),
                      ({"problem": Fold(), "u0": np.ones(2)}, r"gradient\(u\) returned shape \(1,\) for 2 unknowns")):
        with pytest.raises(ValueError, match=words):
            follow(**kw)
    # a start exactly at the fold (or branch point) converges but has no tangent: say so
    for problem, u0 in ((Fold(), np.zeros(1)), (Pitchfork(), np.array([1.0, 0.0]))):
        with pytest.raises(ContinuationError, match="equilibrium without a tangent there: a singular point"):
            follow(problem, u0, 1.0)
    b = follow(Fold(), np.ones(1), 0.0, ds=0.2, max_steps=14, stop_at="fold")       # one kind, as a string
    assert b.status == "fold" and b.special_points[0].located


def test_calls_after_a_special_point_see_the_accepted_parameter():
    """record(u), accept(u) and the callback run at the point's own parameter, also after a location."""
    class Watched(Pitchfork):
        def accept(self, u):
            seen.append(("accept", self.lam))

    seen = []
    problem = Watched()
    b = continuation(problem, np.zeros(2), 0.0, ds=0.3, ds_max=0.3, lam_stop=1.5, log=None,
                     record=lambda u: {"problem_parameter": problem.lam},
                     callback=lambda br, row: seen.append(("last", br.last[1], row["parameter"])))
    assert any(r["special"] == "BP" for r in b.rows)                 # located between steps 4 and 5
    for r in b.rows:
        assert r["problem_parameter"] == r["parameter"]
    accepted = [r["parameter"] for r in b.rows if not r["special"]][1:]
    assert [x[1] for x in seen if x[0] == "accept"] == accepted
    assert all(x[1] == x[2] for x in seen if x[0] == "last")
    assert problem.lam == b.last[1] == 1.5


def test_a_detected_point_whose_location_fails_is_reported_not_dropped():
    class FoldGap(Fold):               # refuses the parameters around the fold: the location fails
        def set_parameter(self, lam):
            if 0.9999 < lam < 1.0001:
                raise ValueError("refused")
            self.lam = lam

    said = []
    b = continuation(FoldGap(), np.ones(1), 0.0, ds=0.2, ds_max=0.2, max_steps=30, stop_at=("fold",), log=said.append)
    assert b.status == "fold" and len(b.special_points) == 1
    p = b.special_points[0]
    assert not p.located and p.kind == "fold" and "location failed" in p.info["reason"]
    assert p.bracket[0] < 1.0 and p.bracket[1] > 0.99 and p.n_negative_before == 0 and p.n_negative_after == 1
    assert any("cut (LP not located" in line for line in said)    # the step was cut and retried first
    assert any("not located" in line for line in said) and "not located" in p.summary()
    # a bracket has no single parameter to misread; the table, the message and the JSON say "not located"
    assert math.isnan(p.parameter) and "reported as brackets: LP in [" in b.message
    assert [r["special"] for r in b.rows].count("LP not located") == 1
    assert len({r["s"] for r in b.rows}) == len(b.rows)              # the step's end is one row, labelled
    assert b.rows[-1]["special"] == "LP not located" and b.rows[-1]["parameter"] == p.info["state_parameter"]
    assert b.rows[-1]["parameter"] in p.bracket


class Cluster:
    """Π = ½ (x − λ)² + Σ_i [½ (c_i − λ) y_i² + ¼ y_i⁴]: branch points at λ = c_i on the trivial branch."""

    def __init__(self, c):
        self.c = np.asarray(c, float)

    def set_parameter(self, lam):
        self.lam = lam

    def energy(self, u):
        y = u[1:]
        return 0.5 * (u[0] - self.lam) ** 2 + np.sum(0.5 * (self.c - self.lam) * y * y + 0.25 * y**4)

    def gradient(self, u):
        y = u[1:]
        return np.concatenate([[u[0] - self.lam], (self.c - self.lam) * y + y**3])

    def hessian(self, u):
        y = u[1:]
        return sp.diags(np.concatenate([[1.0], self.c - self.lam + 3 * y * y])).tocsr()


def test_a_step_across_a_cluster_of_crossings_is_cut_and_every_crossing_located(monkeypatch, tmp_path):
    """40 eigenvalues cross zero within 4 % of λ (one step of ds = 0.5 crosses them all, more than one step
    locates): the step is cut until each crossing is located, with the inertia on either side."""
    c = 1.0 + 0.001 * np.arange(40)
    said = []
    b = continuation(Cluster(c), np.zeros(41), 0.0, ds=0.5, ds_max=0.5, lam_stop=1.5, log=said.append)
    assert b.status == "lam_stop" and any("cut (the inertia jumps" in line for line in said)
    bps = b.special_points
    assert all(p.located and p.kind == "branch" for p in bps) and "not located" not in b.message
    assert sum(p.info["crossings"] for p in bps) == 40 == sum(p.multiplicity for p in bps)
    for p in bps:       # each point: the c_i of its crossings, and the inertia it changes
        assert np.min(np.abs(c - p.parameter)) < 1e-6
        assert p.n_negative_before == np.sum(c < p.parameter - 1e-6)
        assert p.n_negative_after == p.n_negative_before + p.multiplicity
    # without cuts the same step leaves a bracket across most of the step: what the cut avoids
    monkeypatch.setattr("femshell.solvers.arclength.MAX_CUTS", 0)
    uncut = continuation(Cluster(c), np.zeros(41), 0.0, ds=0.5, ds_max=0.5, lam_stop=1.5, log=None)
    assert any(not p.located for p in uncut.special_points)


def test_an_inseparable_cluster_is_located_or_bracketed_and_said_so(tmp_path):
    """40 equal eigenvalues: no cut separates them; what is not located is a narrowed bracket, said as such."""
    b = continuation(Cluster(np.ones(40)), np.zeros(41), 0.0, ds=0.5, ds_max=0.5, lam_stop=1.5, log=None)
    located = [p for p in b.special_points if p.located]
    brackets = [p for p in b.special_points if not p.located]
    assert located and all(abs(p.parameter - 1.0) < 1e-6 for p in located)
    assert len(brackets) == 1 and brackets[0].bracket[0] <= 1.0 <= brackets[0].bracket[1]
    assert brackets[0].bracket[1] - brackets[0].bracket[0] < 0.05            # cut five times from a step of 0.5
    assert sum(p.info["crossings"] for p in b.special_points) == 40
    assert "1 special point(s) detected but not located" in b.message
    write_special_points(b, tmp_path)
    meta = json.loads((tmp_path / "branch-special-points.json").read_text())["special_points"]
    assert [m["parameter"] is None for m in meta] == [not p.located for p in b.special_points]
    assert meta[-1]["located"] is False and meta[-1]["bracket"] == list(brackets[0].bracket)


def test_default_ds_min_scales_with_the_step_and_the_parameter_span():
    """ds_min defaults to 1e-5 min(ds, |lam_stop − lam0| / parameter_scale): a wall stops the run there."""
    class Wall(Pitchfork):
        def set_parameter(self, lam):
            if lam > 0.5:
                raise ValueError("refused")
            self.lam = lam

    for kw, ds_min in (({"ds": 0.1}, 1e-6), ({"ds": 0.1, "lam_stop": 0.9}, 1e-6),
                       ({"ds": 0.1, "lam_stop": 0.6, "parameter_scale": 100.0}, 6e-8)):
        b = continuation(Wall(), np.zeros(2), 0.0, detect=False, log=None, **kw)
        assert b.status == "ds_min" and f"ds_min = {ds_min:.3g}" in b.message


def test_a_missed_landing_on_lam_stop_stops_there_and_says_so():
    class Refuses(Pitchfork):          # lam_stop itself is refused: the step crosses it, landing fails
        def set_parameter(self, lam):
            if lam == 1.0:
                raise ValueError("refused")
            self.lam = lam

    for log in (None, print):
        b = continuation(Refuses(), np.zeros(2), 0.0, ds=0.3, ds_max=0.3, lam_stop=1.0, max_steps=12, log=log,
                         detect=False)
        assert b.status == "lam_stop" and "could not land" in b.message
        assert len(b.rows) < 8 and 1.0 < b.rows[-1]["parameter"] < 1.3


# ----------------------------------------------------------------------------- output

def test_csv_special_points_and_table(tmp_path):
    b = continuation(Pitchfork(), np.zeros(2), 0.0, ds=0.3, lam_stop=1.5, record=lambda u: {"y": u[1]},
                     label="trivial", log=None)
    assert isinstance(b, Branch)
    path = write_branch_csv(b, tmp_path / "out" / "branch.csv")
    with open(path) as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(b.rows)
    assert {"parameter", "n_negative", "stable", "eig_0", "y", "special", "energy"} <= set(rows[0])
    assert [r["special"] for r in rows].count("BP") == 1
    assert float(rows[-1]["parameter"]) == 1.5
    assert not list((tmp_path / "out").glob(".*"))          # no temporary files left
    table = b.table
    assert len(table["parameter"]) == len(b.rows)

    calls = []

    def writer(stem, u, modes):
        calls.append((stem, u.copy(), {k: v.copy() for k, v in modes.items()}))
        return str(stem) + ".fake"

    out = write_special_points(b, tmp_path / "sp", writer)
    assert out == [calls[0][0].as_posix() + ".fake"]
    assert list(calls[0][2]) == ["mode_0"]
    meta = json.loads((tmp_path / "sp" / "trivial-special-points.json").read_text())
    assert meta["special_points"][0]["kind"] == "branch"
    assert abs(meta["special_points"][0]["parameter"] - 1) < 1e-6


def test_load_parameter_adapter_on_a_stub_model():
    """LoadParameter: λ is model.load_factor, ∂r/∂λ = −∂W/∂u; weights 1/L² on positions, 1 on angles."""

    class Mesh:
        points = np.array([[0.0, 0, 0], [2.0, 0, 0], [0, 1.0, 0]])
        n_vertices = 3

    class Stub:  # Π(u) = ¼ (w² − 2w)² − λ w in the first free unknown, ½ u² in the others
        mesh = Mesh()
        free = np.array([True] * 9 + [True, False])
        load_factor = 0.0
        loads = [object()]

        def energy(self, u):
            return 0.25 * (u[0] ** 2 - 2 * u[0]) ** 2 + 0.5 * u[1:] @ u[1:] - self.load_factor * u[0]

        def gradient(self, u):
            g = np.concatenate([[(u[0] ** 2 - 2 * u[0]) * (u[0] - 1)], u[1:]])
            return g - self.load_factor * self.load_gradient(u)

        def load_gradient(self, u):
            e = np.zeros(len(u))
            e[0] = 1.0
            return e

        def hessian(self, u):
            d = np.ones(len(u))
            d[0] = 0.5 * ((2 * u[0] - 2) ** 2 + 2 * (u[0] ** 2 - 2 * u[0]))
            return sp.diags(d).tocsr()

        def accept(self, u):
            self.accepted = getattr(self, "accepted", 0) + 1

    model = Stub()
    prob = LoadParameter(model, length_scale=2.0)
    w = prob.dof_weights()
    assert np.allclose(w, [0.25] * 9 + [1.0])
    b = continuation(prob, np.zeros(10), 0.0, ds=0.1, lam_stop=0.5, stop_at=("fold",), log=None)
    assert b.status == "fold"
    assert abs(b.special_points[0].parameter - 2 / (3 * math.sqrt(3))) < 1e-6
    assert model.accepted == len([r for r in b.rows if not r["special"]]) - 1


# ----------------------------------------------------------------------------- a shell

def test_clamped_disk_growth_buckling_coarse():
    """Coarse clamped disk: the first inertia change of the flat branch within 10 % of k² = 14.682."""
    from femshell.mesh.generators import disk
    from femshell.shell import Clamped, Material, ShellModel, uniform_growth

    t, nu = 0.01, 0.3
    mesh = disk(radius=1.0, edge_length=0.2)        # 120 vertices
    rest = lambda g: uniform_growth(mesh.points, mesh.triangles, t, g)  # noqa: E731
    model = ShellModel(mesh, Material(1.0, nu), rest(0.0), [Clamped("outer")])
    gc = 14.682 * t * t / (12 * (1 + nu))
    prob = GrowthParameter(model, rest, parameter_scale=gc, length_scale=t)
    b = continuation(prob, model.initial_unknowns(), 0.0, ds=0.3, ds_max=0.3, lam_stop=1.3 * gc, n_eigs=2,
                     stop_at=("branch",), log=None)
    bp = b.special_points[0]
    assert bp.kind == "branch" and bp.multiplicity == 1
    eps = ((1 + bp.parameter) ** 2 - 1) / 2
    assert abs(eps / gc - 1) < 0.10
    # the flat branch stays flat, and its critical mode is out of plane
    assert np.abs(model.positions(bp.u)[:, 2]).max() < 1e-12
    q = np.zeros(model.n_total)
    q[model.free] = bp.modes[:, 0]
    disp = q[: 3 * mesh.n_vertices].reshape(-1, 3)
    assert np.abs(disp[:, :2]).max() < 1e-8 * np.abs(disp[:, 2]).max()
