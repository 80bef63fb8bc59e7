"""femshell.coupled.pattern_continuation: a stationary spot followed in a model parameter (theory §2.9).

A small sphere (R = 5, 300 vertices, h0 = 0.5, Λmin = 13.5 as in tests/test_stationary.py) whose time
run ends in a stationary spot.
"""

import json
import math

import meshio
import numpy as np
import pytest

from femshell.coupled import CoupledLoop, InitialSpot, MechanochemicalModel, StationaryProblem, TimeStepping, \
    stationary_state
from femshell.coupled.pattern_continuation import PARAMETERS, PatternParameter, continue_pattern, critical_mode_fields
from femshell.mesh.generators import sphere
from femshell.scene.pattern_output import pattern_measures, write_pattern_branch

R = 5.0


@pytest.fixture(scope="module")
def spot():
    mesh = sphere(R, n_vertices=300, seed=0)
    p = MechanochemicalModel(h0=0.5, radius=R, lam_min=13.5, D=0.1)
    st = TimeStepping(t_final=80.0, dt_initial=0.05, ramp_ds=0.2)
    loop = CoupledLoop(mesh, p, st, c0=InitialSpot(amplitude=0.3, width=1.0), log=None)
    assert loop.run().status == "stationary"
    problem = StationaryProblem.of_loop(loop)
    root = stationary_state(loop, problem=problem)
    assert root.converged
    return loop, problem, root


@pytest.mark.parametrize("name", sorted(PARAMETERS))
def test_parameter_derivative_matches_a_difference_of_the_residual(spot, name):
    _, problem, root = spot
    params = problem.params
    try:
        pp = PatternParameter(problem, name)
        z = problem.join(root.u, root.c)
        lam = pp.parameter
        g = pp.parameter_derivative(z)
        eps = 1e-4 * pp.parameter_scale
        pp.set_parameter(lam + eps)
        fp = problem.residual(z)
        pp.set_parameter(lam - eps)
        fm = problem.residual(z)
        pp.set_parameter(lam)
        fd = (fp - fm) / (2 * eps)
        assert np.linalg.norm(g) > 0
        assert np.linalg.norm(g - fd) <= 1e-5 * np.linalg.norm(g), PARAMETERS[name]
        assert np.array_equal(problem.residual(z), problem.residual(z))   # the parameter is back
    finally:
        problem.set_params(params)


def test_bad_parameter_is_named(spot):
    _, problem, _ = spot
    with pytest.raises(ValueError, match="parameter must be one of w, beta, D, c_star, h0, lam_ratio"):
        PatternParameter(problem, "Hs")
    pp = PatternParameter(problem, "lam_ratio")
    with pytest.raises(ValueError, match="lam_ratio = Λmax/Λmin must be >= 1"):
        pp.set_parameter(0.5)


def test_branch_in_w_ends_at_the_root_newton_finds_there(spot):
    loop, problem, root = spot
    params = problem.params
    w1 = params.w * 1.02
    try:
        branch = continue_pattern(problem, root.u, root.c, "w", ds=0.02, lam_stop=w1, max_steps=10, n_modes=3,
                                  record=lambda z: pattern_measures(problem, z))
        assert branch.status == "lam_stop", branch.message
        z_end, lam_end = branch.states[-1]
        assert lam_end == pytest.approx(w1, rel=1e-12)
        row = branch.rows[-1]
        for key in ("max_c", "patterned_area", "spot_radius", "n_spots", "mu_0", "mu_0_imag", "stable", "det_sign"):
            assert key in row
        assert row["n_spots"] == 1 and row["stable"] is True and row["mu_0"] < 0
        assert row["patterned_area"] == pytest.approx(math.pi * row["spot_radius"] ** 2, rel=1e-12)
        # an independent Newton at w1 from the start's root lands on the branch's end
        problem.set_params(params)
        loop_w1 = CoupledLoop.from_state_dict(loop.mesh, MechanochemicalModel(**{**params.as_dict(), "w": w1}),
                                              {**loop.state_dict(), "u": root.u, "c": root.c}, loop.stepping)
        newton = stationary_state(loop_w1, tol=1e-10)
        assert newton.converged
        u_end, c_end = problem.split(z_end)
        assert np.abs(newton.c - c_end).max() <= 1e-7 * c_end.max()
        # the spot grows with the production rate
        assert branch.rows[-1]["max_c"] > branch.rows[0]["max_c"]
        assert branch.rows[-1]["patterned_area"] >= branch.rows[0]["patterned_area"]
        fields = critical_mode_fields(problem, z_end, np.ones(len(z_end)))
        assert fields["mode_c"].shape == (problem.n_c,) and fields["mode_normal"].shape == (problem.n_c,)
    finally:
        problem.set_params(params)


def test_measures_of_the_root(spot):
    _, problem, root = spot
    m = pattern_measures(problem, problem.join(root.u, root.c))
    assert m["max_c"] == root.c.max() and m["n_spots"] == 1 and 0 < m["patterned_area"] < 4 * math.pi * R**2


def test_the_spot_s_fold_in_w_is_where_the_coupled_dynamics_loses_stability(spot, tmp_path):
    # det J = det K · det S (K the shell Hessian, S the Schur complement): with K positive definite a fold of the
    # stationary branch is a zero eigenvalue μ of S v = μ M v, the stable spot's end
    _, problem, root = spot
    params = problem.params
    try:
        branch = continue_pattern(problem, root.u, root.c, "w", ds=0.02, max_steps=20, n_modes=2,
                                  stop_at="fold", record=lambda z: pattern_measures(problem, z))
        assert branch.status == "fold", branch.message
        (lp,) = branch.special_points
        assert lp.kind == "fold" and lp.located and params.w < lp.parameter < 1.1 * params.w
        rows = [r for r in branch.rows if not r["special"]]
        before = [r for r in rows if r["dlam_ds"] > 0]
        after = [r for r in rows if r["dlam_ds"] < 0]
        assert all(r["stable"] for r in before) and after and not any(r["stable"] for r in after)
        at_fold = next(r for r in branch.rows if r["special"] == "LP")
        assert abs(at_fold["mu_0"]) <= 1e-4 * params.beta and at_fold["n_negative_mechanical"] == 0
        assert abs(at_fold["mu_0_imag"]) == 0
        # the critical mode is J's null vector: a concentration change with its shape change
        fields = critical_mode_fields(problem, lp.u, lp.modes[:, 0])
        assert np.abs(fields["mode_c"]).max() == pytest.approx(1.0)
        z = lp.u
        pp = PatternParameter(problem, "w")
        pp.set_parameter(lp.parameter)
        assert np.linalg.norm(problem.jacobian(z) @ lp.modes[:, 0]) <= 1e-4 * np.linalg.norm(
            problem.jacobian(z) @ np.ones(len(z)))
        # the files: table, special point with its mode, diagrams
        out = write_pattern_branch(branch, problem, tmp_path, parameter="w")
        doc = json.loads(out["json"].read_text())
        assert doc["status"] == "fold" and len(doc["rows"]) == len(branch.rows)
        assert [r["special"] for r in doc["rows"]].count("LP") == 1
        (vtu,) = out["special_points"]
        fields = meshio.read(vtu).point_data
        assert np.allclose(fields["c"], problem.split(lp.u)[1])
        assert np.abs(fields["mode_0_c"]).max() == pytest.approx(1.0) and fields["mode_0_displacement"].shape[1] == 3
        assert len(out["diagrams"]) == 3 and len(out["mode_pictures"]) == 1
        assert all(p.stat().st_size > 1000 for p in out["diagrams"] + out["mode_pictures"])
        special = json.loads((tmp_path / "w-special-points.json").read_text())["special_points"]
        assert special[0]["kind"] == "fold" and special[0]["parameter"] == lp.parameter
    finally:
        problem.set_params(params)


def test_the_uniform_sphere_reduction_in_its_limits():
    from femshell.validation import uniform_sphere_pattern as usp
    # both terms of the energy vanish at ρ = sR when k0 = 1/(sR): the root is that radius exactly
    s = 1.3
    p = MechanochemicalModel(h0=0.5, k0=1 / (s * usp.RADIUS), rest_curvature="k0", b=usp.B_SWITCH)
    assert usp.sphere_radius(s, p) == pytest.approx(s * usp.RADIUS, rel=1e-12)
    # k0 = 0: q² = 1 − h̄²/(6 s² R²) in closed form (h̄ = h0/s²), below sR and towards it as the shell thins
    flat = usp.model()
    for h0 in (0.5, 0.05, 2.0):
        p = MechanochemicalModel(**{**flat.as_dict(), "h0": h0})
        hb = h0 / s**2
        assert usp.sphere_radius(s, p) == pytest.approx(s * usp.RADIUS * (1 - hb**2 / (6 * s**2 * usp.RADIUS**2)) ** 0.5,
                                                         rel=1e-12)
    # the uniform concentration solves βc = P(1/ρ(s(c)))
    c = usp.uniform_concentration(7.0, usp.model(7.0))
    H = 1 / usp.sphere_radius(float(flat.stretch(c)), flat)
    assert c == pytest.approx(7.0 * H / (1 + H / flat.Hs), rel=1e-12)


# ----------------------------------------------------------------------------- the scene kind

def _guide_scene():
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "docs" / "guide" / "continuation.md").read_text()
    (block,) = [b for b in re.findall(r"^```toml\n(.*?)^```", text, flags=re.S | re.M)
                if 'kind = "pattern-continuation"' in b]
    return block


def test_pattern_continuation_scene_of_the_guide_runs(tmp_path, capsys):
    from femshell.cli import main

    scene = tmp_path / "spot.toml"
    scene.write_text(_guide_scene())
    out = tmp_path / "run"
    assert main(["run", str(scene), "--out", str(out), "-q"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    pc = summary["final"]["pattern_continuation"]
    assert summary["status"] == "done" and pc["status"] == "fold" and pc["parameter"] == "w"
    (lp,) = pc["special_points"]
    assert lp["kind"] == "fold" and 15.0 < lp["parameter"] < 17.0
    rows = json.loads((out / "pattern" / "w-branch.json").read_text())["rows"]
    assert rows[0]["parameter"] == 15.0 and rows[0]["stable"] and rows[0]["n_spots"] == 1
    for name in ("w-branch.csv", "w-special-points.json", "w-special-00-fold.vtu", "w-special-00-fold-mode.png",
                 "w-diagram-max_c.png", "w-diagram-spot_radius.png", "w-diagram-patterned_area.png"):
        assert (out / "pattern" / name).is_file(), name
    capsys.readouterr()
    assert main(["run", str(scene), "--out", str(tmp_path / "dry"), "--dry-run"]) == 0
    assert "followed in w to 17" in capsys.readouterr().out


def test_pattern_continuation_scene_keys_are_checked(tmp_path):
    from femshell.scene import SceneError, load_scene

    good = _guide_scene()
    for bad, said in ((good.replace('parameter = "w"', 'parameter = "Hs"'), "parameter"),
                      (good.replace("continuation_steps = 20", "continuation_steps = 0"), "continuation_steps"),
                      (good.replace('[solver]\n', '[solver]\nswitch_branch = true\n'), "switch_branch")):
        path = tmp_path / "bad.toml"
        path.write_text(bad)
        with pytest.raises(SceneError, match=said):
            load_scene(str(path))
