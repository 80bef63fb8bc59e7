"""The wrinkle-scaling measure and fit on fields and data with known answers."""

import math

import numpy as np
import pytest

from femshell.io import load_checkpoint, save_checkpoint
from femshell.validation.disk import branches
from femshell.validation import wrinkle_scaling as ws
from femshell.validation.disk_wrinkles import Disk


@pytest.fixture(scope="module")
def disk():
    return Disk(0.5, ws.R2, 10)


@pytest.mark.parametrize("k", [3, 7])
def test_rim_wavenumber_of_a_dome_with_k_waves(disk, k):
    P = disk.points
    r, phi = np.hypot(P[:, 0], P[:, 1]), np.arctan2(P[:, 1], P[:, 0])
    dome = np.exp(-((r / ws.R2) ** 2))
    band = np.exp(-(((r - ws.R2) / 1.5) ** 2))
    n, rel = ws.rim_wavenumber(disk, dome + 0.2 * band * np.cos(k * phi))
    assert n == k
    # independent reference: the same ratio from the analytic fields on the rim circles
    rr = np.array(ws.RIM_RADII) * ws.R2
    expect = math.sqrt(np.sum((0.2 * np.exp(-(((rr - ws.R2) / 1.5) ** 2))) ** 2) / np.sum(np.exp(-((rr / ws.R2) ** 2)) ** 2))
    # P1 interpolation (edge 0.3, 7 waves: ~9 edges per wave): a few per cent
    assert rel == pytest.approx(expect, rel=0.1)
    # disk-wrinkles' inside-rim measure is the same on its own circles
    from femshell.validation.disk_wrinkles import INNER_RIM_RADII

    k_in, rel_in = disk.rim_mode(dome + 0.2 * band * np.cos(k * phi))
    rr = np.array(INNER_RIM_RADII) * ws.R2
    expect = math.sqrt(np.sum((0.2 * np.exp(-(((rr - ws.R2) / 1.5) ** 2))) ** 2) / np.sum(np.exp(-((rr / ws.R2) ** 2)) ** 2))
    assert k_in == k and rel_in == pytest.approx(expect, rel=0.1)
    # an axisymmetric dome has no rim wave
    assert ws.rim_wavenumber(disk, dome)[1] < 1e-2


@pytest.mark.parametrize("k", [2, 8])
def test_single_mode_seed_has_that_wavenumber_at_the_rim(disk, k):
    z = ws.seed_shape(disk, waves=ws.SEED_WAVES, modes=(k,))
    n, rel = ws.rim_wavenumber(disk, z)
    assert n == k
    power = disk.azimuthal_power(z, ws.RIM_RADII, 24)
    others = np.delete(power[2:], k - 2)
    assert others.max() < 1e-3 * power[k]
    # the broadband seed spreads its power over k = 2 ... 16
    broad = disk.azimuthal_power(ws.seed_shape(disk), ws.RIM_RADII, 24)
    assert np.count_nonzero(broad[2:17] > 0.1 * broad[2:17].max()) >= 10


def test_fit_exponent_recovers_a_power_law():
    h = np.array([0.25, 0.5, 1.0, 2.0])
    n = 2 * math.pi * ws.R2 / (4.0 * h**0.5)        # exact λ = 4 h^(1/2), non-integer n
    p, sp = ws.fit_exponent(h, n)
    assert p == pytest.approx(0.5, abs=1e-12)
    assert 0 < sp < 0.2
    # integer counts of the same law: the exponent within its reported uncertainty of 1/2
    p, sp = ws.fit_exponent(h, np.round(n))
    assert abs(p - 0.5) <= 2 * sp


def test_fit_exponent_needs_two_distinct_values():
    assert all(math.isnan(v) for v in ws.fit_exponent([0.5], [4]))
    assert all(math.isnan(v) for v in ws.fit_exponent([0.5, 0.5], [4, 5]))


def test_seeded_state_resumes_from_its_checkpoint(tmp_path, monkeypatch):
    """A ramp interrupted after its first ε step resumes there and ends where the uninterrupted ramp
    ends; a finished ramp is read back without a solve; a checkpoint of another ramp is refused."""
    d = Disk(1.0, ws.R2, 4)
    whole, _ = ws.seeded_state(d, 0.2, 0.1)
    ck = tmp_path / "dome.npz"
    solve, calls = branches.minimize, []   # the ramp's solves (branches.stable_state)

    def interrupted(*a, **k):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return solve(*a, **k)

    monkeypatch.setattr(branches, "minimize", interrupted)
    with pytest.raises(KeyboardInterrupt):
        ws.seeded_state(d, 0.2, 0.1, checkpoint=ck)
    monkeypatch.setattr(branches, "minimize", solve)
    resumed, _ = ws.seeded_state(d, 0.2, 0.1, checkpoint=ck)
    assert np.abs(resumed - whole).max() <= 1e-8 * np.abs(whole).max()

    def no_solve(*a, **k):
        raise AssertionError("a finished ramp was solved again")

    monkeypatch.setattr(branches, "minimize", no_solve)
    again, _ = ws.seeded_state(d, 0.2, 0.1, checkpoint=ck)
    np.testing.assert_array_equal(again, resumed)
    with pytest.raises(ValueError, match="another run"):
        ws.seeded_state(d, 0.3, 0.1, checkpoint=ck)
    with pytest.raises(ValueError, match="modes"):
        ws.seeded_state(d, 0.2, 0.1, checkpoint=ck, modes=(8,))
    # written before the edge unknown became a tangent (no edge_unknown in its meta): its unknowns are angles
    state, meta = load_checkpoint(ck)
    del meta["edge_unknown"]
    save_checkpoint(ck, state, meta)
    with pytest.raises(ValueError, match="edge_unknown"):
        ws.seeded_state(d, 0.2, 0.1, checkpoint=ck)


def test_growth_history_snapshots_and_checkpoint(tmp_path, monkeypatch):
    """One growth history gives its end state and the snapshots its relaxation passes (not one on the followed
    branch); the finished history is read back without a solve; a checkpoint of another law, ε or snapshot set is
    refused."""
    ck = tmp_path / "path.npz"
    # h = 1, resolution 4: the dome branch is followed to eps ~ 0.39, the relaxation goes on from there
    d, states, summary = ws.growth_history(1.0, 0.5, 4, "svk", snapshots=(0.2, 0.45), checkpoint=ck)
    assert sorted(states) == [0.45, 0.5]
    assert summary["relaxed"] and 0.0 < summary["eps_first"] < 0.2
    # independent of the bookkeeping: each state is an equilibrium at its own ε, and they differ
    for eps, u in states.items():
        assert d.relative_residual(u, eps) <= ws.EQUILIBRIUM_RTOL
    assert np.abs(states[0.45] - states[0.5]).max() > 1e-3

    def no_follow(*a, **k):
        raise AssertionError("a finished history was solved again")

    monkeypatch.setattr(ws, "follow", no_follow)
    d2, again, summary2 = ws.growth_history(1.0, 0.5, 4, "svk", snapshots=(0.45, 0.2), checkpoint=ck)
    assert sorted(again) == sorted(states) and summary2 == summary and d2.n_vertices == d.n_vertices
    for eps in states:
        np.testing.assert_array_equal(again[eps], states[eps])
    with pytest.raises(ValueError, match="law"):
        ws.growth_history(1.0, 0.5, 4, "neo-hookean", snapshots=(0.2, 0.45), checkpoint=ck)
    with pytest.raises(ValueError, match="eps"):
        ws.growth_history(1.0, 0.4, 4, "svk", snapshots=(0.2,), checkpoint=ck)
    with pytest.raises(ValueError, match="snapshots"):
        ws.growth_history(1.0, 0.5, 4, "svk", checkpoint=ck)


def test_history_plan_grows_each_h_once():
    plan = ws.history_plan({"h": (0.25, 0.5), "eps": (0.3, 0.5, 0.4), "h_fixed": 0.25, "resolution": 24,
                            "mesh_check": ((0.5, 0.5, 28),)})
    assert plan == {(0.25, 24): (0.5, [0.3, 0.4]), (0.5, 24): (0.5, []), (0.5, 28): (0.5, [])}


@pytest.mark.parametrize("kw, match", [({"eps_end": 0.0}, "eps_end"), ({"eps_end": 1.5}, "eps_end"),
                                       ({"eps_end": True}, "eps_end"), ({"snapshots": (0.5,)}, "snapshots"),
                                       ({"eps_end": 0.4, "snapshots": (0.3, -0.1)}, "snapshots")])
def test_follow_refuses_an_impossible_growth_range(kw, match):
    from femshell.validation.disk_wrinkles import follow

    with pytest.raises(ValueError, match=match):
        follow(1.0, ws.R2, 4, **kw)
