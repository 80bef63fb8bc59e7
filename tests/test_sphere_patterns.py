"""The sphere-patterns scenarios: parameters as design.md 1.5 states them, an embedded scene for
each with the same parameters, and a run stopped part-way resumes from its checkpoint to the same
state as an uninterrupted run, and can be continued to a later end time."""

import numpy as np
import pytest

from femshell.coupled import InitialSpot
from femshell.scene import load_scene
from femshell.scene.build import coupled_parameters
from femshell.validation.sphere_patterns import SCENARIOS, model_of, paper_vertices, run_scenario

#: the embedded scene of each scenario
SCENES = {"spots": "sphere-spots", "ridges": "sphere-ridges", "decay": "sphere-decay",
          "single-bulge": "sphere-single-bulge", "propagation": "sphere-propagation",
          "large-spots": "sphere-large-spots", "small-sphere": "sphere-small",
          "uniform-thickness": "sphere-uniform-thickness", "icosahedral": "sphere-icosahedral"}


def test_scenarios_carry_the_paper_parameters():
    p = model_of(SCENARIOS["icosahedral"])
    assert p.lam_max / p.lam_min == pytest.approx(1.05) and p.h0 == 4.0 and p.c_star == 0.05 and p.w == 100.0
    assert p.natural_curvature == pytest.approx(1 / 30)
    assert model_of(SCENARIOS["uniform-thickness"]).thickness_mode == "uniform"
    assert model_of(SCENARIOS["spots"], thickness_mode="uniform").thickness_mode == "uniform"
    assert model_of(SCENARIOS["spots"]).thickness_mode == "volume"
    assert model_of(SCENARIOS["propagation"]).D == 0.5 and model_of(SCENARIOS["propagation"]).h0 == 1.0
    assert model_of(SCENARIOS["small-sphere"]).natural_curvature == pytest.approx(1 / 15)
    assert paper_vertices(30.0) == 25000 and paper_vertices(15.0) == 6250


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_every_scenario_has_an_embedded_scene_with_its_parameters(name):
    scene = load_scene(SCENES[name])
    params, _, seed = coupled_parameters(scene)
    ref = model_of(SCENARIOS[name])
    fields = ("nu", "E", "h0", "thickness_mode", "lam_max", "lam_min", "b", "c_star", "w", "Hs", "beta", "D",
              "membrane_law")
    assert {f: getattr(params, f) for f in fields} == {f: getattr(ref, f) for f in fields}
    assert scene["mesh"]["kind"] == "sphere" and scene["mesh"]["radius"] == SCENARIOS[name].radius
    assert seed == InitialSpot()                 # design.md 1.4: amplitude c_max, width h, at the pole
    if name != "decay":                          # the paper's resolution (decay: 10 000, it ends early)
        assert scene["mesh"]["n_vertices"] == paper_vertices(SCENARIOS[name].radius)


def test_interrupted_scenario_resumes_to_the_uninterrupted_state(tmp_path):
    kw = dict(t_final=0.3, n_vertices=300, radius=10.0)
    whole = run_scenario(SCENARIOS["spots"], **kw)
    ck = tmp_path / "spots.npz"
    part = run_scenario(SCENARIOS["spots"], checkpoint=ck, max_steps=3, **kw)
    assert part["status"] == "max_steps" and part["t"] < whole["t"] and ck.exists()
    rest = run_scenario(SCENARIOS["spots"], checkpoint=ck, **kw)
    assert rest["status"] == whole["status"] and rest["t"] == whole["t"]
    assert rest["steps"] == whole["steps"] and rest["saddles"] == 0 and rest["negative_c"] == 0
    # the wall time of the whole run adds up its calls (the committed records quoted the last call only)
    assert rest["wall_s_total"] > rest["wall_s"] + 0.5 * part["wall_s"]    # (part: measures after its last save)
    np.testing.assert_allclose(rest["c"], whole["c"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(rest["points"], whole["points"], rtol=0, atol=1e-10)
    later = run_scenario(SCENARIOS["spots"], checkpoint=ck, t_final=0.4, n_vertices=300, radius=10.0)
    assert later["t"] == pytest.approx(0.4) and later["steps"] > rest["steps"]    # continued, not restarted
    with pytest.raises(ValueError, match="another run"):
        run_scenario(SCENARIOS["spots"], checkpoint=ck, t_final=0.5, n_vertices=300, radius=12.0)
    with pytest.raises(ValueError, match="another run"):      # nor resumed with the other thickness law
        run_scenario(SCENARIOS["spots"], checkpoint=ck, thickness_mode="uniform", **kw)


def test_spot_scaling_leaves_failed_runs_out_of_its_fits(monkeypatch):
    """A run that failed midway or was stopped by the wall-time cap ends at a state that is not its
    pattern's: its radius must not enter the exponent (the full level's uniform-thickness h = 2.5 run
    failed at t = 63 and was fitted)."""
    from types import SimpleNamespace

    from femshell.validation import spot_scaling as ss

    radius = {1.0: 4.0, 2.0: 4.0 * 2 ** 0.5, 3.0: 4.0 * 3 ** 0.5, 4.0: 40.0, 5.0: 0.4}   # r ∝ h^(1/2) but h = 4, 5
    monkeypatch.setitem(ss.LEVELS, "quick", dict(ss.LEVELS["quick"], h=tuple(radius)))
    monkeypatch.setattr(ss, "state_rows", lambda key, r: [])
    monkeypatch.setattr(ss, "run_state", lambda key, cfg, ck, log: {
        "status": {4.0: "failed", 5.0: "wall_time"}.get(key[0], "stationary"), "t": 1.0, "max_c": 0.5, "steps": 1,
        "wall_s": 0.0,
        "measures": SimpleNamespace(n_spots=1, spot_radius=radius[key[0]], spacing=1.0)})
    rows = {r.quantity: r.value for r in ss.run("quick")}
    fitted = [v for q, v in rows.items() if q.startswith("fitted exponent of the spot radius")]
    assert fitted == [pytest.approx(0.5)]
    assert any("from 3 states, 1 degree(s) of freedom" in q for q in rows)
    assert rows["unfinished runs (failed or stopped early) left out of the sweep of h (volume-conserving thickness) "
                "at eps=0.5"] == 2
