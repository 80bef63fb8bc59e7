"""The coupled loop's error-based step control (TimeStepping.step_control = "error", theory §2.8).

The local error estimate against the exact step of a source linear in time, the PI controller on a
model error, and the loop: every accepted step within error_tol, a larger error cut, the error
controlled (a quarter of the tolerance halves the error of a first-order run), bit-identical resumes.
Small sphere and spot as in test_coupled.py.
"""

import math

import numpy as np
import pytest
from scipy.integrate import quad

from femshell.coupled import (CoupledLoop, InitialSpot, MechanochemicalModel, TimeStepping, error_step_factor,
                              held_source_error)
from femshell.io import load_checkpoint, save_checkpoint
from femshell.mesh.generators import sphere
from femshell.scene.build import loop_observers

OBSERVERS = loop_observers()
SPOT = dict(h0=0.5, radius=5.0, lam_min=13.5, D=0.0)


@pytest.fixture(scope="module")
def ball():
    return sphere(5.0, n_vertices=400, seed=0)


def _exact_linear_source(c0, p0, p1, dt, beta):
    """c(dt) of dc/dt = p0 + (p1 − p0) t/dt − β c: the variation-of-constants integral by adaptive quadrature."""
    def integral(a, b):
        return quad(lambda tau: math.exp(-beta * (dt - tau)) * (a + (b - a) * tau / dt), 0.0, dt,
                    epsabs=1e-15, epsrel=1e-13)[0]
    return np.exp(-beta * dt) * c0 + np.array([integral(a, b) for a, b in zip(p0, p1)])


@pytest.mark.parametrize("beta", [0.0, 1e-7, 1.0, 30.0])
def test_the_error_estimate_is_the_exact_step_of_a_source_linear_in_time(beta):
    rng = np.random.default_rng(1)
    c0, p0, p1 = rng.uniform(0, 1, 5), rng.uniform(0, 2, 5), rng.uniform(0, 2, 5)
    held = p0 + 0.3 * (p0 - rng.uniform(0, 2, 5))       # an extrapolated source, not P_n
    dt = 0.2
    phi = dt if beta == 0 else -math.expm1(-beta * dt) / beta
    stepped = math.exp(-beta * dt) * c0 + phi * held     # what the chemistry step makes of the held source
    exact = _exact_linear_source(c0, p0, p1, dt, beta)
    assert np.allclose(stepped + held_source_error(held, p0, p1, dt, beta), exact, rtol=1e-9, atol=1e-12)
    # a constant source: no error where the held source is P_n
    assert np.array_equal(held_source_error(p0, p0, p0, dt, beta), np.zeros(5))


def test_the_pi_controller_settles_where_safety_puts_it_on_a_second_order_error():
    """err = C dt² (the staggered step's local error): the step sequence converges monotonically to
    the dt whose error ratio is safety^(1/0.36), from below and from above."""
    C, tol, safety = 50.0, 0.01, 0.8
    target = math.sqrt(safety ** (1 / 0.36) * tol / C)
    for dt in (1e-4, 0.1):
        prev, ratios = None, []
        for _ in range(60):
            r = C * dt * dt / tol
            dt *= error_step_factor(r, prev, safety, grow=1.5)
            prev = r
            ratios.append(r)
        assert dt == pytest.approx(target, rel=1e-6)
    assert error_step_factor(0.25, None, 0.8, 1.5) == 1.5                    # bounded by grow
    assert error_step_factor(1e6, None, 0.8, 1.5) == 0.2                     # ... and by shrink
    assert error_step_factor(4.0, None, 0.8, 1.5) == pytest.approx(0.4)      # elementary: safety r^(-1/2)
    assert error_step_factor(0.0, 0.5, 0.8, 1.5) == 1.5                      # no error seen: grow


def test_step_control_settings_are_checked():
    assert TimeStepping().step_control == "stretch"                           # the old rule stays the default
    with pytest.raises(ValueError, match=r"step_control must be one of \('stretch', 'error'\), got 'errors'"):
        TimeStepping(step_control="errors")
    with pytest.raises(ValueError, match="error_tol"):
        TimeStepping(error_tol=0.0)
    with pytest.raises(ValueError, match="error_ds_max"):
        TimeStepping(error_ds_max=-1.0)
    assert TimeStepping(step_control="error", error_ds_max=0.3).stretch_limit == 0.3
    assert TimeStepping(ds_max=0.04).stretch_limit == 0.04


def _run(ball, t_final=1.0, **stepping):
    p = MechanochemicalModel(**SPOT)
    st = TimeStepping(t_final=t_final, dt_initial=0.05, ramp_ds=0.2, **stepping)
    loop = CoupledLoop(ball, p, st, c0=InitialSpot(amplitude=0.3, width=1.0), observers=OBSERVERS)
    records = list(loop.iterate())
    return loop, records


def test_error_control_keeps_every_step_within_its_tolerance_and_cuts_a_larger_one(ball):
    tol = 2e-4
    loop, records = _run(ball, t_final=0.5, step_control="error", error_tol=tol)
    errors = np.array([r.step_error for r in records])
    assert np.all(errors <= tol) and errors.max() > 0.3 * tol                # used, not idle
    assert loop.n_rejected >= 1                                              # dt_initial = 0.05 is too long
    assert records[0].cuts >= 1 and records[0].dt < 0.05


def test_error_control_controls_the_error_a_quarter_of_the_tolerance_halves_it(ball):
    """A first-order step with its local error (∝ dt²) held at tol: the global error ∝ dt ∝ √tol."""
    reference, _ = _run(ball, ds_max=0.005)
    err, steps = {}, {}
    for tol in (4e-3, 1e-3):
        loop, _ = _run(ball, step_control="error", error_tol=tol)
        err[tol] = np.abs(loop.c - reference.c).max() / loop.params.c_max
        steps[tol] = loop.step
    assert 0.3 < err[1e-3] / err[4e-3] < 0.7
    assert 1.4 < steps[1e-3] / steps[4e-3] < 2.8
    # the stretch rule's record carries the same estimate
    assert math.isfinite(reference.record().step_error)


def test_resume_under_error_control_is_bitwise_identical(ball, tmp_path):
    """The controller's memory (the last error ratio) is in the state."""
    p = MechanochemicalModel(**SPOT)
    st = TimeStepping(t_final=10.0, dt_initial=0.05, ramp_ds=0.2, step_control="error", error_tol=1e-3)
    loop = CoupledLoop(ball, p, st, c0=InitialSpot(amplitude=0.3, width=1.0), observers=OBSERVERS)
    for rec in loop.iterate(max_steps=4):
        if rec.step == 3:
            save_checkpoint(tmp_path / "ck.npz", loop.state_dict(), {})
            assert loop._error_ratio is not None
    state, _ = load_checkpoint(tmp_path / "ck.npz")
    resumed = CoupledLoop.from_state_dict(ball, p, state, st, observers=OBSERVERS)
    resumed.advance()
    assert resumed.t == loop.t and resumed.dt == loop.dt
    assert np.array_equal(resumed.c, loop.c) and np.array_equal(resumed.u, loop.u)
