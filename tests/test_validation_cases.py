"""Every validation case at quick level (the contract of design.md section 4): each row compares
with an independent reference (plate theory, the elastica, the classical benchmark values, series
solutions, l(l+1), the fold theory of a shallow arch) or is reported; the case passes when every
toleranced row does. The full levels are run by hand (validation/results)."""

import json
import math

import pytest

from femshell.validation import run_case
from femshell.validation.framework import CASES


@pytest.mark.parametrize("name", list(CASES))
def test_case_quick(name, tmp_path):
    assert run_case(name, "quick", tmp_path, log=lambda *a: None)
    doc = json.loads((tmp_path / f"{name}.json").read_text())
    assert doc["case"] == name and doc["level"] == "quick" and doc["source"]
    assert (tmp_path / f"{name}.png").stat().st_size > 0
    assert any(row["tolerance"] is not None for row in doc["rows"])      # something is checked
    for row in doc["rows"]:
        assert set(row) >= {"quantity", "value", "reference", "rel_error", "tolerance", "passed", "n_vertices",
                            "wall_s"}
        assert row["value"] is not None and math.isfinite(row["value"])


def test_rows_are_plain_json_numbers_and_a_bad_tolerance_is_named():
    import numpy as np

    from femshell.validation.framework import Row, _row_json

    r = Row("q", np.float32(1.0), np.float64(1.0), np.float64(0.1), n_vertices=np.int64(5), wall_s=np.float32(2))
    json.dumps(_row_json(r), allow_nan=False)          # np.bool_ / np.int64 made json.dumps fail after a run
    assert r.passed is True and type(r.n_vertices) is int
    with pytest.raises(ValueError, match="row 'q': tolerance must be a finite number >= 0 or None, got nan"):
        Row("q", 1.0, 1.0, float("nan"))


def test_a_case_that_stops_with_an_error_fails_and_the_next_cases_run(tmp_path, monkeypatch, capsys):
    """A solver error inside a case used to end `validate` with 'error:' and exit 2 (bad input), or a
    traceback, and the cases after it did not run."""
    import types

    from femshell.cli import main
    from femshell.validation import framework

    (tmp_path / "broken.json").write_text('{"earlier": true}')
    fake = types.SimpleNamespace(DESCRIPTION="raises", SOURCE="none",
                                 run=lambda level: (_ for _ in ()).throw(RuntimeError("Newton diverged")))
    real_load = framework._load
    monkeypatch.setitem(framework.CASES, "broken", "broken")
    monkeypatch.setattr(framework, "_load", lambda name: fake if name == "broken" else real_load(name))
    assert main(["validate", "broken", "patch-tests", "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "broken: FAILED: the case stopped with RuntimeError: Newton diverged" in err
    assert "the earlier" in err and json.loads((tmp_path / "broken.json").read_text()) == {"earlier": True}
    assert json.loads((tmp_path / "patch-tests.json").read_text())["case"] == "patch-tests"   # ran after it


def test_disk_loss_of_stability_where_the_branch_turns_is_a_fold():
    # a loss of stability where dλ/ds also changes sign is a fold (limit point): the disk case snaps there
    # instead of trying a branch switch (its corrector diverged at the h = 0.25 dome's fold)
    from types import SimpleNamespace

    import numpy as np

    from femshell.validation import disk_wrinkles as dw

    import scipy.sparse.linalg as spla

    d = dw.Disk(2.0, 3.0, 3)
    u0 = d.model.initial_unknowns()
    d.problem.set_parameter(0.10001)
    phi = spla.eigsh(d.model.hessian(u0), k=1, sigma=0.0, v0=np.ones(len(u0)))[1][:, 0]     # the softest mode
    other = np.random.default_rng(0).standard_normal(len(u0))
    other -= (other @ phi) * phi                                                             # orthogonal to it
    kinds = []
    # (dλ/ds after the crossing, the step's direction): a fold needs both the turn and the step along the mode
    for turn, step in ((+1.0, phi), (-1.0, phi), (-1.0, other)):
        rows = [{"special": "", "n_negative": 0, "dlam_ds": 0.1, "parameter": 0.1},
                {"special": "", "n_negative": 1, "dlam_ds": turn * 0.1, "parameter": 0.10001}]
        branch = SimpleNamespace(status="callback", rows=rows, states=[(u0, 0.1), (u0 + 1e-6 * step, 0.10001)])
        sp = dw.loss_of_stability(d, branch)
        assert sp.bracket == (0.1, 0.10001) and np.isfinite(sp.eigenvalues).all()
        kinds.append((sp.kind, round(sp.info["mode_tangent_cosine"], 3)))
    assert kinds == [("branch", 1.0), ("fold", 1.0), ("branch", 0.0)]


def test_disk_final_state_residual_tells_an_equilibrium_from_a_failed_relaxation():
    """The residual row's measure: the grown flat disk is its own reference (1); the equilibrium Newton
    reaches is below EQUILIBRIUM_RTOL; Newton stopped after one iteration is not."""
    from femshell.solvers.newton import NewtonError, minimize
    from femshell.validation import disk_wrinkles as dw

    d = dw.Disk(2.0, 3.0, 3)
    d.problem.set_parameter(0.05)
    u0 = d.model.initial_unknowns()
    assert d.relative_residual(u0, 0.05) == 1.0
    u = minimize(d.problem, u0, log=None).u
    assert d.relative_residual(u, 0.05) <= dw.EQUILIBRIUM_RTOL
    with pytest.raises(NewtonError) as info:
        minimize(d.problem, u0, max_iter=1, log=None)
    assert d.relative_residual(info.value.result.u, 0.05) > dw.EQUILIBRIUM_RTOL


def test_a_flat_disk_has_no_wrinkles_whatever_its_round_off():
    """A deflection of round-off size (the flat disk carried back from a dome: |w| ~ 1e-23) counts 0, where the
    same pattern at 0.1 h counts its waves."""
    import numpy as np

    from femshell.validation import disk_wrinkles as dw

    d = dw.Disk(2.0, 3.0, 4)
    x, y = d.points[:, 0], d.points[:, 1]
    wave = np.cos(3 * np.arctan2(y, x)) * np.exp(-((np.hypot(x, y) - 3.0) / 1.5) ** 2)
    assert d.count(1e-23 * wave) == 0 and d.count(0.1 * d.h * wave) == 3


def test_the_disk_has_no_length_of_its_own():
    """Dimensional analysis: stretching energy ∝ h · area, bending ∝ h³ · curvature² · area, so the disk
    scaled by s with its thickness has Π(s x, s h) = s³ Π(x, h) at the same ε and edge unknowns (gradient
    s² on positions, s³ on the dimensionless edge unknowns). Its states, ε_c and counts then depend on
    R2/h and R1/R2 only: the h = 2 disk at R2 = 12 is the h = 0.5 disk at R2 = 3."""
    import numpy as np

    from femshell.validation import disk_wrinkles as dw

    s = 4.0
    a = dw.Disk(0.5, 3.0, 3, R1=20.0, law="neo-hookean")
    b = dw.Disk(0.5 * s, 3.0 * s, 3, R1=20.0 * s, law="neo-hookean")
    assert np.array_equal(a.triangles, b.triangles) and np.allclose(b.points, s * a.points, rtol=0, atol=1e-12)
    n_pos = 3 * a.mesh.n_vertices
    rng = np.random.default_rng(1)
    q = a.model.full(a.model.initial_unknowns())
    q[:n_pos] += 0.025 * rng.standard_normal(n_pos)           # a wrinkled, sheared state of a
    q[n_pos:] += 0.1 * rng.standard_normal(len(q) - n_pos)
    qb = q.copy()
    qb[:n_pos] *= s
    ua, ub = q[a.model.free], qb[b.model.free]
    for d in (a, b):
        d.problem.set_parameter(0.3)
    assert b.model.energy(ub) == pytest.approx(s ** 3 * a.model.energy(ua), rel=1e-12)
    ga, gb = a.model.gradient(ua), b.model.gradient(ub)
    pos = np.flatnonzero(a.model.free) < n_pos
    np.testing.assert_allclose(gb[pos], s ** 2 * ga[pos], rtol=0, atol=1e-12 * np.abs(s ** 2 * ga).max())
    np.testing.assert_allclose(gb[~pos], s ** 3 * ga[~pos], rtol=0, atol=1e-12 * np.abs(s ** 3 * ga).max())


def test_the_inner_radius_is_a_parameter_of_one_mesh():
    """Disk.radius_problem at λ = s R2 is the disk of radii s R2, s R1 and the same h, meshed anew: Π(s x) of that
    disk equals s³ Π(x) of the parametrised one (radius_energy), its position gradient s² times, edge s³ times."""
    import numpy as np

    from femshell.validation import disk_wrinkles as dw

    s, eps = 2.0, 0.3     # gmsh meshes a disk scaled by a power of two alike, to round-off
    a = dw.Disk(0.5, 3.0, 3, R1=20.0, law="neo-hookean")
    b = dw.Disk(0.5, 3.0 * s, 3, R1=20.0 * s, law="neo-hookean")       # gmsh's mesh of the larger disk
    p = a.radius_problem(eps)
    p.set_parameter(3.0 * s)
    b.problem.set_parameter(eps)
    n_pos = 3 * a.mesh.n_vertices
    q = a.model.full(a.model.initial_unknowns())
    rng = np.random.default_rng(2)
    q[:n_pos] += 0.025 * rng.standard_normal(n_pos)
    q[n_pos:] += 0.1 * rng.standard_normal(len(q) - n_pos)
    qb = q.copy()
    qb[:n_pos] *= s
    ua, ub = q[a.model.free], qb[b.model.free]
    assert np.array_equal(a.triangles, b.triangles) and np.allclose(b.points, s * a.points, rtol=0, atol=1e-12)
    assert b.model.energy(ub) == pytest.approx(a.radius_energy(p, ua), rel=1e-12)
    ga, gb = p.model.gradient(ua), b.model.gradient(ub)
    pos = np.flatnonzero(a.model.free) < n_pos
    np.testing.assert_allclose(gb[pos], s ** 2 * ga[pos], rtol=0, atol=1e-12 * np.abs(s ** 2 * ga).max())
    np.testing.assert_allclose(gb[~pos], s ** 3 * ga[~pos], rtol=0, atol=1e-12 * np.abs(s ** 3 * ga).max())
    a.problem.set_parameter(eps)        # the disk's own ε problem is untouched by the radius one
    assert a.model.rest.thickness.max() == 0.5
    with pytest.raises(ValueError, match="R2"):
        p.set_parameter(0.0)


def test_a_radius_sweep_carries_a_state_to_equilibria_of_the_larger_disks_and_resumes(tmp_path, monkeypatch):
    """Each state of sweep_radius, magnified to its radius, balances the disk meshed at that radius (independent
    mesh and model); a second call reads the checkpoint back without solving."""
    import numpy as np

    from femshell.validation import disk_wrinkles as dw
    from femshell.validation.disk import branches

    a = dw.Disk(1.0, 3.0, 3, R1=15.0, law="neo-hookean")
    a.problem.set_parameter(0.02)
    u0 = branches.minimize(a.problem, a.model.initial_unknowns(), stable=True, log=None).u
    ck = tmp_path / "sweep.npz"
    rows, states = dw.sweep_radius(a, u0, [6.0, 12.0], eps=0.02, checkpoint=ck, meta={"case": "test"})
    n_pos = 3 * a.mesh.n_vertices
    pos = np.flatnonzero(a.model.free) < n_pos
    for r, u in zip(rows, states):
        s = r["R2"] / 3.0
        b = dw.Disk(1.0, r["R2"], 3, R1=15.0 * s, law="neo-hookean")
        ub = np.where(pos, s * u, u)
        assert b.relative_residual(ub, 0.02) <= 10 * r["residual"] + 1e-10 and r["residual"] <= dw.EQUILIBRIUM_RTOL
        assert r["energy"] == pytest.approx(b.model.energy(ub), rel=1e-12) and r["result"]
    monkeypatch.setattr(branches, "minimize", lambda *a, **k: pytest.fail("a saved step was solved again"))
    again, states2 = dw.sweep_radius(a, u0, [6.0, 12.0], eps=0.02, checkpoint=ck, meta={"case": "test"})
    assert again == rows and np.array_equal(states2, states)
    with pytest.raises(ValueError, match="radii"):
        dw.sweep_radius(a, u0, [6.0, 24.0], eps=0.02, checkpoint=ck, meta={"case": "test"})
    with pytest.raises(ValueError, match="another run"):
        dw.sweep_radius(a, u0, [6.0, 12.0], eps=0.03, checkpoint=ck, meta={"case": "test"})


def test_disk_end_state_is_the_lowest_energy_result_of_the_relaxations():
    from femshell.validation.disk_wrinkles import select_lowest

    c = [dict(energy=2.0, result=True), dict(energy=1.0, result=False), dict(energy=1.5, result=True),
         dict(energy=1.7, result=True)]
    assert select_lowest(c) == 2                   # the over-folded or unstable lower state does not count
    assert select_lowest([dict(energy=2.0, result=False), dict(energy=1.0, result=False)]) == 0


def test_a_carried_state_is_counted_only_when_it_is_a_lower_result():
    from femshell.validation import disk_wrinkles as dw

    rec = dict(count=5, rim=[5, 0.3], energy=1.0, result=True, n_negative_final=0, residual=1e-12, over_folded=0,
               largest_turn=10.0)

    def cand(R2, count, energy, result=True):
        return ("u%g" % R2, dict(from_R2=R2, count=count, rim=[count, 0.2], energy=energy, result=result,
                                 n_negative=0 if result else 1, residual=1e-11, over_folded=0, largest_turn=20.0))

    u, r = dw.with_carried("own", rec, [cand(2.5, 6, 0.999), cand(3.5, 4, 0.99, result=False)])
    assert u == "u2.5" and r["count"] == 6 and r["counted_from"] == 2.5 and r["largest_turn"] == 20.0
    assert [c["from_R2"] for c in r["carried"]] == [2.5, 3.5]        # the unstable lower one does not count
    u, r = dw.with_carried("own", rec, [cand(2.5, 5, 1.0 - 1e-12)])   # the same state, reached both ways
    assert u == "own" and r["count"] == 5 and r["counted_from"] is None
    u, r = dw.with_carried("own", dict(rec, result=False), [cand(2.5, 6, 1.5)])
    assert u == "u2.5" and r["result"] and r["counted_from"] == 2.5    # a result beats a lower non-result


def test_disk_end_states_carried_to_the_neighbouring_radius_reach_its_own_equilibrium(tmp_path, monkeypatch):
    """Each end state swept to the neighbouring case's R2 and carried to its mesh relaxes to that case's own
    state (the dome, grown there independently from the flat disk: energy to 1e-9), which is then kept;
    saved and read back."""
    import numpy as np

    from femshell.validation import disk_wrinkles as dw
    from femshell.validation.disk import branches

    cfg = dict(dw.LEVELS["quick"], pushes=1)
    solved = {}
    for c in cfg["cases"]:
        d = dw._case_disk(dw._case_meta(*c, cfg))
        u, _ = dw._relax(d.problem, d.model.initial_unknowns(), 0.0, dw.EPS_END, (), None)    # grown in steps
        check = d.final_check(u, dw.EPS_END)
        solved[c] = (d, u, dict(count=d.count(d.deflection(u)), energy=float(d.model.energy(u)),
                                result=check["result"]))
    monkeypatch.setenv("FEMSHELL_THREADS", "1")
    out = dw.exchange_states(cfg, solved, tmp_path)
    assert len(list(tmp_path.glob("carried-*.npz"))) == 2 and len(list(tmp_path.glob("sweep-carried-*.npz"))) == 2
    for c in cfg["cases"]:
        d, u, rec = out[c]
        (carried,) = rec["carried"]
        assert solved[c][2]["result"] and carried["result"] and carried["count"] == rec["count"] == 0
        assert carried["energy"] == pytest.approx(solved[c][2]["energy"], rel=1e-9)
        assert rec["counted_from"] is None and np.array_equal(u, solved[c][1])
    monkeypatch.setattr(branches, "minimize", lambda *a, **k: pytest.fail("a saved carried state was solved again"))
    again = dw.exchange_states(cfg, solved, tmp_path)
    assert all(again[c][2]["carried"] == out[c][2]["carried"] for c in cfg["cases"])


def test_a_disk_that_is_another_magnified_takes_its_end_state_magnified_and_checked_there():
    """The h = 2, R2 = 4 disk is the h = 1, R2 = 2 one magnified by 2 (R1 = 10 R2 both): the thinner's dome,
    magnified, is the thicker's own equilibrium (grown there independently from the flat disk: energy to 1e-9,
    8 = 2³ times the thinner's), stable and counted there; disks of other meshes are refused."""
    import numpy as np

    from femshell.validation import disk_wrinkles as dw

    cfg = {"cases": [(2.0, 4.0, 3), (1.0, 2.0, 3)], "refine_inside": True, "law": "neo-hookean",
           "outer_factor": 10.0, "pushes": 1}
    twin, rep = cfg["cases"]
    assert dw.twins(cfg["cases"], cfg) == {twin: rep, rep: rep} and dw.meshed_alike(twin, rep, cfg)
    assert not dw.meshed_alike((2.0, 4.0, 4), rep, cfg)
    grown = {}
    for c in cfg["cases"]:
        d = dw._case_disk(dw._case_meta(*c, cfg))
        u, _ = dw._relax(d.problem, d.model.initial_unknowns(), 0.0, dw.EPS_END, (), None)
        grown[c] = (d, u, float(d.model.energy(u)))
    d, u, energy = grown[rep]
    candidates = [dict(push=None, count=0, energy=energy, result=True)]
    solved = {rep: (d, u, dict(count=d.count(d.deflection(u)), energy=energy, result=True, candidates=candidates,
                               carried=[], counted_from=None))}
    out = dw.with_twins(cfg, solved, dw.twins(cfg["cases"], cfg))
    assert out[rep] is solved[rep] and list(out) == cfg["cases"]
    d2, u2, rec = out[twin]
    assert rec["twin_of"] == [1.0, 2.0] and rec["result"] and rec["n_negative_final"] == 0
    assert rec["residual"] <= dw.EQUILIBRIUM_RTOL and rec["count"] == solved[rep][2]["count"]
    assert abs(d.deflection(u)).max() > 0.1 * d.h          # a dome, not the flat disk
    assert rec["energy"] == pytest.approx(8.0 * energy, rel=1e-12) == rec["candidates"][0]["energy"]
    assert rec["energy"] == pytest.approx(grown[twin][2], rel=1e-9)
    np.testing.assert_allclose(d2.model.positions(u2), 2.0 * d.model.positions(u), rtol=0, atol=1e-12)
    other = dw.Disk(2.0, 4.0, 4, R1=40.0, law="neo-hookean", refine_inside=True)
    with pytest.raises(ValueError, match="not one mesh scaled"):
        dw.magnified(d, u, other)


def test_disk_relaxations_start_from_the_snap_pushed_both_ways_along_each_critical_mode():
    from types import SimpleNamespace

    import numpy as np

    from femshell.validation import disk_wrinkles as dw

    d = SimpleNamespace(h=2.0, n_vertices=2)
    modes = np.array([[1.0, 0.0], [-0.5, 0.0], [0.0, 4.0], [0.0, 0.0], [0.0, 0.0], [0.0, -2.0], [9.0, 9.0]])
    sp = SimpleNamespace(u=np.zeros(7), modes=modes)
    starts = dw.pushed_starts(d, sp, 5)
    assert [p for p, _ in starts] == ["+phi1", "-phi1", "+phi2", "-phi2"]    # two per mode computed, at most
    a = dw.SWITCH_AMPLITUDE * d.h
    np.testing.assert_allclose(starts[0][1], a * modes[:, 0])                  # largest position component a
    np.testing.assert_allclose(starts[3][1], -a * modes[:, 1] / 4.0)
    assert [p for p, _ in dw.pushed_starts(d, sp, 1)] == ["+phi1"]
    with pytest.raises(ValueError, match="pushes"):
        dw.follow(2.0, 3.0, 3, pushes=0)


def test_disk_cases_solved_in_worker_processes_are_checkpointed_and_read_back(tmp_path, monkeypatch):
    """The full level's path: cases solved two at once in spawned workers, each saved; a second call reads them
    back without solving, the same states as solving here; a checkpoint of another setting, or whose saved
    numbers its state does not give again, is refused."""
    import numpy as np

    from femshell.io import load_checkpoint, save_checkpoint
    from femshell.validation import disk_wrinkles as dw
    from femshell.validation.disk import cases

    cfg = {"cases": [(2.0, 3.0, 3), (2.0, 4.0, 3)], "refine_inside": False, "law": "svk", "outer_factor": 5.0,
           "pushes": 2}
    monkeypatch.setenv("FEMSHELL_THREADS", "2")
    lines = []
    solved = dw.solve_cases(cfg, tmp_path, log=lines.append)
    assert "2 at once" in lines[0] and len(list(tmp_path.glob("case-*.npz"))) == 2
    c = cfg["cases"][1]
    d, u, rec = solved[c]
    here = dw.solve_case(dw._case_meta(*c, cfg))                     # the same case solved in this process
    np.testing.assert_allclose(u, here[1], rtol=0, atol=1e-9 * np.abs(u).max())
    assert rec["count"] == here[2]["count"] and rec["result"] == here[2]["result"]
    assert rec["residual"] <= dw.EQUILIBRIUM_RTOL and d.n_vertices == here[0].n_vertices
    monkeypatch.setattr(cases, "follow", lambda *a, **k: pytest.fail("a saved case was solved again"))
    again = dw.solve_cases(cfg, tmp_path)
    assert all(np.array_equal(again[c][1], solved[c][1]) for c in cfg["cases"])
    with pytest.raises(ValueError, match="pushes"):
        dw.solve_cases(dict(cfg, pushes=4), tmp_path)
    path = dw.case_checkpoint(tmp_path, c)          # a saved count that this code does not find for its state
    state, meta = load_checkpoint(path)
    record = json.loads(str(state["record"]))
    save_checkpoint(path, {"u": state["u"], "record": json.dumps(dict(record, count=record["count"] + 1))}, meta)
    with pytest.raises(ValueError, match="differs from what it saved"):
        dw.solve_cases(cfg, tmp_path)


def test_refinement_ladder_order_and_richardson_without_the_reference():
    """v(h) = 1 − 0.3 (h/h0)^1.5 (h ∝ n^−1/2): the order from three values alone is 1.5 and the Richardson
    estimate with it is 1; with two meshes the assumed order is said and nothing is toleranced."""
    from femshell.validation.shell_buckling import convergence_rows, order_from_values

    ns = [1000, 2000, 4000, 8000]
    values = [1 - 0.3 * (n / 1000) ** -0.75 for n in ns]
    assert abs(order_from_values(ns, values) - 1.5) < 1e-9
    rows = {r.quantity: r for r in convergence_rows("q", ns, values, tol=1e-6)}
    assert abs(rows["observed order of q from its three finest values"].value - 1.5) < 1e-9
    assert rows["q, Richardson from the two finest meshes with that order"].passed
    assert abs(rows["observed order of q error against the reference (finest 4 meshes)"].value - 1.5) < 1e-9
    two = convergence_rows("q", ns[:2], values[:2], tol=1e-6)
    assert [r.tolerance for r in two] == [None, None] and "(assumed)" in two[-1].quantity
    assert order_from_values(ns[:3], [0.9, 0.95, 1.01]) is None        # differences that do not shrink
