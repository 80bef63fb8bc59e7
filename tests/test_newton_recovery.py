"""Newton failure recovery: failed load steps are cut and retried; after a bounded number of cuts the
run stops with a NewtonError that carries the last converged state; no NaN ever leaves the solver."""

import numpy as np
import pytest
import scipy.sparse as sp

from femshell.solvers.newton import NewtonError, follow_load, minimize


class SofteningSprings:
    """n independent springs with a bounded restoring force k tanh(u) under a dead load λ f.

    Π(u) = Σ k log cosh(u_i) − λ f·u. An equilibrium exists only while λ |f_i| < k: the
    load has a limit point at λ = k / max|f_i|, beyond which Newton cannot converge
    (the energy decreases without bound) — a snap-through with nothing to snap to.
    log cosh is evaluated without overflow, so the energy stays finite for any u.
    """

    def __init__(self, f, k=1.0):
        self.f = np.asarray(f, float)
        self.k = k
        self.load_factor = 0.0
        self.loads = [object()]            # minimize() takes its residual scale from the load
        self.calls = {"hessian": 0}

    @staticmethod
    def _logcosh(u):
        a = np.abs(u)
        return a + np.log1p(np.exp(-2 * a)) - np.log(2.0)

    def energy(self, u):
        return float(self.k * self._logcosh(u).sum() - self.load_factor * self.f @ u)

    def gradient(self, u):
        return self.k * np.tanh(u) - self.load_factor * self.f

    def load_gradient(self, u):
        return self.f

    def hessian(self, u):
        self.calls["hessian"] += 1
        e = np.exp(-2 * np.abs(u))                  # sech² u = 4 e^{-2|u|} / (1 + e^{-2|u|})², no overflow
        return sp.diags(self.k * 4 * e / (1 + e) ** 2).tocsr()

    def limit_load(self):
        return self.k / np.abs(self.f).max()


def test_steps_beyond_the_limit_point_are_cut_then_the_run_stops_with_the_last_converged_state():
    prob = SofteningSprings(f=[1.0, 0.5, 0.25])
    factors = np.linspace(0.3, 2.1, 7)           # the limit is at λ = 1
    accepted = []
    messages = []
    with pytest.raises(NewtonError) as info:
        follow_load(prob, np.zeros(3), factors, max_cuts=5, max_iter=30,
                    callback=lambda lam, res: accepted.append(lam), log=messages.append)
    exc = info.value
    assert "cannot be cut further (max_cuts = 5" in str(exc)
    # the steps before the limit point were delivered, those after it were not
    assert accepted == [lam for lam in factors if lam < 1.0]
    # the load factor is left at the last converged one, below the limit, and the state carried
    # by the error is the equilibrium there: finite, with a residual at round-off level
    last = prob.load_factor
    assert factors[len(accepted) - 1] <= last < prob.limit_load()
    u = exc.result.u
    assert np.all(np.isfinite(u)) and np.isfinite(exc.result.energy)
    assert np.linalg.norm(prob.gradient(u)) <= 1e-8 * np.linalg.norm(last * prob.f)
    np.testing.assert_allclose(np.tanh(u), last * prob.f, rtol=1e-8)
    # every failure was logged as a cut, and the number of cuts is bounded
    cuts = [m for m in messages if "step cut" in m]
    assert 5 <= len(cuts) <= 5 * (len(factors) - len(accepted)) + 5
    # the bisection closed in on the limit point
    assert last > 0.9 * prob.limit_load()


def test_bounded_work_when_every_step_fails():
    prob = SofteningSprings(f=[1.0])
    with pytest.raises(NewtonError) as info:
        follow_load(prob, np.zeros(1), [3.0], max_cuts=3, max_iter=10, log=None)
    # each cut halves the step, a success doubles it back once, and the step is never cut below
    # 2**-max_cuts of the interval: at most 2**max_cuts converged and 2**max_cuts + max_cuts + 1
    # failed Newton solves, of at most max_iter + 1 Hessians each (here: 3 + 4 solves)
    assert prob.calls["hessian"] <= (2 * 2**3 + 3 + 1) * (10 + 1)
    assert prob.load_factor < prob.limit_load()
    assert np.all(np.isfinite(info.value.result.u))


class Drifting:
    """Π(u) = Σ log cosh(u − L λ²): the equilibrium u = L λ² moves along a curved path, and Newton
    (convex energy, bounded gradient) needs more iterations the farther the start is from it. With a
    small iteration budget every step of the path must be short: the path needs many small steps."""

    def __init__(self, L):
        self.L = L
        self.load_factor = 0.0

    def _x(self, u):
        return u - self.L * self.load_factor**2

    def energy(self, u):
        a = np.abs(self._x(u))
        return float(np.sum(a + np.log1p(np.exp(-2 * a)) - np.log(2.0)))

    def gradient(self, u):
        return np.tanh(self._x(u))

    def hessian(self, u):
        e = np.exp(-2 * np.abs(self._x(u)))
        return sp.diags(4 * e / (1 + e) ** 2).tocsr()


def test_a_path_that_needs_many_small_steps_is_followed_to_the_end():
    # With max_iter = 3, steps of 1/16 of the interval fail all along the path and steps of 1/32
    # converge: 32 steps are needed. A success must not restore the whole remaining interval while
    # the cuts keep counting (the old stepping): that spent all max_cuts cuts on the first two steps
    # and stopped at load factor 1/32.
    prob = Drifting(L=200.0)
    messages = []
    (res,) = follow_load(prob, np.zeros(2), [1.0], max_cuts=6, max_iter=3, log=messages.append)
    assert res.converged
    np.testing.assert_allclose(res.u, 200.0, rtol=1e-9)
    n_cuts = sum("step cut" in m for m in messages)
    assert 10 <= n_cuts <= 2**6 + 6 + 1             # many cuts along the path, within the bound


def test_the_error_result_of_follow_load_has_no_nan():
    prob = SofteningSprings(f=[1.0, 0.5])
    with pytest.raises(NewtonError) as info:
        follow_load(prob, np.zeros(2), [0.5, 2.0], max_cuts=2, max_iter=20, log=None)
    r = info.value.result
    assert np.isfinite(r.residual) and np.isfinite(r.energy)


def test_cut_steps_start_from_the_state_u0_is_in_equilibrium_at():
    prob = SofteningSprings(f=[1.0])
    prob.load_factor = 1.0                         # as ShellModel.__init__ leaves it
    (res,) = follow_load(prob, np.zeros(1), [0.95], max_cuts=6, max_iter=5, log=None)
    assert res.converged and np.tanh(res.u[0]) == pytest.approx(0.95)


def test_a_step_that_needs_more_iterations_than_allowed_succeeds_after_cuts():
    prob = SofteningSprings(f=[1.0])
    with pytest.raises(NewtonError, match="did not converge in 5 iterations"):   # the direct solve needs more
        prob.load_factor = 0.95
        minimize(prob, np.zeros(1), max_iter=5, log=None)
    prob.load_factor = 0.0                         # u0 = 0 is the equilibrium at load factor 0
    messages = []
    (res,) = follow_load(prob, np.zeros(1), [0.95], max_cuts=6, max_iter=5, log=messages.append)
    assert any("step cut" in m for m in messages)
    assert res.converged and np.tanh(res.u[0]) == pytest.approx(0.95)


def test_a_tiny_iteration_budget_fails_cleanly_and_keeps_the_last_iterate():
    prob = SofteningSprings(f=[1.0, 0.5])
    prob.load_factor = 0.99                        # near the limit: many iterations needed
    with pytest.raises(NewtonError) as info:
        minimize(prob, np.zeros(2), max_iter=2, log=None)
    r = info.value.result
    assert "did not converge in 2 iterations" in str(info.value)
    assert not r.converged and np.all(np.isfinite(r.u)) and np.isfinite(r.residual)
    assert len(r.history) == 3


class Logarithmic:
    """Π(u) = Σ (u − a log u), minimum at u = a. From u > 2a the full Newton step
    (u ↦ 2u − u²/a) lands at u ≤ 0, where the energy is NaN or inf: the line search must back
    off instead of accepting a non-finite state."""

    def __init__(self, a):
        self.a = np.asarray(a, float)

    def energy(self, u):
        with np.errstate(invalid="ignore", divide="ignore"):
            return float(np.sum(u - self.a * np.log(u)))

    def gradient(self, u):
        return 1 - self.a / u

    def hessian(self, u):
        return sp.diags(self.a / u**2).tocsr()


def test_line_search_never_accepts_a_non_finite_energy():
    prob = Logarithmic([2.0, 3.0])
    seen = []
    energy = prob.energy
    prob.energy = lambda u: seen.append(np.array(u)) or energy(u)
    res = minimize(prob, np.array([6.5, 1.0]), log=None)
    np.testing.assert_allclose(res.u, [2.0, 3.0], rtol=1e-8)
    assert np.isfinite(res.energy)
    assert any(np.any(s <= 0) for s in seen)       # a trial did leave the domain ...
    assert np.all(res.u > 0)                        # ... and was rejected


def test_shell_load_steps_too_large_for_newton_are_cut_and_the_run_completes():
    """Cantilever strip rolled by an end moment to a quarter and a half circle in two requested steps
    with a budget of 30 Newton iterations: from the flat state the steps need more (a flat start
    stretches the strip spuriously), they fail, are cut, and the cut steps reach the exact circles."""
    from femshell.mesh.generators import strip
    from femshell.shell import Clamped, EdgeMoment, Material, ShellModel, flat_rest_state

    L, W, H, E = 12.0, 1.0, 0.1, 1.2e6
    mesh = strip(L, W, edge_length=0.5, structured=True, diagonal="alternate")
    m_max = 2 * np.pi * E * W * H**3 / 12 / L
    model = ShellModel(mesh, Material(E, 0.0), flat_rest_state(mesh.points, mesh.triangles, H),
                       [Clamped("left")], [EdgeMoment("right", -m_max / W)])
    # the reference state is the equilibrium at load factor 0 (follow_load's default start), whatever
    # load_factor a fresh ShellModel has (test_cut_steps_start_from_the_state_u0_is_in_equilibrium_at)
    model.load_factor = 0.0
    messages = []
    results = follow_load(model, model.initial_unknowns(), [0.25, 0.5], max_cuts=4, max_iter=30, rtol=1e-8,
                          log=messages.append)
    assert sum("step cut" in m for m in messages) >= 2
    tip = mesh.topology.boundary_vertex_groups["right"]
    for frac, res in zip([0.25, 0.5], results):
        assert res.converged and np.all(np.isfinite(res.u))
        theta = 2 * np.pi * frac
        x = model.positions(res.u)
        assert -(x[tip, 0] - mesh.points[tip, 0]).mean() == pytest.approx(L * (1 - np.sin(theta) / theta), rel=0.02)
        assert (x[tip, 2] - mesh.points[tip, 2]).mean() == pytest.approx(L * (1 - np.cos(theta)) / theta, rel=0.02)


class NonlinearChain:
    """A chain of unit springs between n beads with a stiffening on-site potential, under a dead load λ f:
    Π(u) = Σ ½ (u_{i+1} − u_i)² + Σ (½ u_i² + ¼ a u_i⁴) − λ f·u. Convex, so the minimiser is unique;
    the Hessian is tridiagonal and changes with u (the quartic term), as a shell's does with its shape."""

    def __init__(self, n=40, a=5.0):
        self.n, self.a = n, a
        self.f = np.sin(np.linspace(0.0, 3.0, n)) + 0.3
        self.load_factor = 0.0
        self.loads = [object()]
        self.calls = {"hessian": 0}
        D = sp.diags([-np.ones(n - 1), np.ones(n - 1)], [0, 1], shape=(n - 1, n))
        self.L = (D.T @ D).tocsr()

    def energy(self, u):
        return float(0.5 * u @ (self.L @ u) + np.sum(0.5 * u**2 + 0.25 * self.a * u**4) - self.load_factor * self.f @ u)

    def gradient(self, u):
        return self.L @ u + u + self.a * u**3 - self.load_factor * self.f

    def load_gradient(self, u):
        return self.f

    def hessian(self, u):
        self.calls["hessian"] += 1
        return (self.L + sp.diags(1.0 + 3.0 * self.a * u**2)).tocsr()


def test_quasi_newton_on_the_held_factorisation_reaches_newtons_equilibrium_with_one_hessian():
    from femshell.solvers.linear import Refactorizer

    prob = NonlinearChain()
    facs = (Refactorizer(), Refactorizer())
    prob.load_factor = 1.0
    u1 = minimize(prob, np.zeros(prob.n), rtol=1e-10, factorizers=facs, log=None).u
    # the reference at the next load: plain Newton, fresh factorisations, tight tolerance
    prob.load_factor = 1.2
    ref = minimize(prob, u1, rtol=1e-13, log=None).u
    prob.calls["hessian"] = 0
    res = minimize(prob, u1, rtol=1e-10, factorizers=facs, quasi_newton=20, stable=True, log=None)
    assert res.converged and res.stable
    assert 0 < res.quasi_newton_iterations <= 20 and res.iterations == 0
    assert prob.calls["hessian"] == 1                      # only the stability check at the end
    assert np.abs(res.u - ref).max() < 1e-8 * np.abs(ref).max()
    # held factorisation far from the new Hessian: quasi-Newton stalls or runs out, Newton finishes
    prob.load_factor = 8.0
    far = minimize(prob, res.u, rtol=1e-10, factorizers=facs, quasi_newton=3, log=None)
    ref_far = minimize(prob, res.u, rtol=1e-13, log=None).u
    assert far.quasi_newton_iterations <= 3 and far.iterations > 0
    assert np.abs(far.u - ref_far).max() < 1e-8 * np.abs(ref_far).max()
    # nothing held (new factorizers): plain Newton
    fresh = minimize(prob, res.u, rtol=1e-10, factorizers=(Refactorizer(), Refactorizer()), quasi_newton=20, log=None)
    assert fresh.quasi_newton_iterations == 0 and fresh.iterations > 0
    for f in facs:
        f.free()


class MisscaledQuadratic:
    """Π = ½|u|² with a Hessian 1e10 times too stiff: every Newton step is accepted and lowers Π,
    but by a relative 2e-10 only, and the residual hardly falls: Newton creeps, as it does with
    shifted steps about a near-singular shell Hessian."""

    def __init__(self, n=5):
        self.n = n

    def energy(self, u):
        return float(0.5 * u @ u)

    def gradient(self, u):
        return u.copy()

    def hessian(self, u):
        return sp.identity(self.n, format="csr") * 1e10


def test_a_creeping_newton_gives_up_after_the_stall_window_and_a_converging_one_does_not():
    u0 = np.linspace(1.0, 2.0, 5)
    with pytest.raises(NewtonError, match="stalled at iteration 6") as err:
        minimize(MisscaledQuadratic(), u0, max_iter=60, stall=6, log=None)
    assert err.value.stalled and err.value.result.iterations == 6
    with pytest.raises(NewtonError, match="did not converge in 60") as err:   # without: the whole budget
        minimize(MisscaledQuadratic(), u0, max_iter=60, log=None)
    assert not err.value.stalled and err.value.result.iterations == 60
    # problems that converge are not stopped, also where Newton needs many damped iterations
    prob = NonlinearChain()
    for lam in (1.0, 8.0, 40.0):
        prob.load_factor = lam
        a = minimize(prob, np.zeros(prob.n), rtol=1e-12, stall=2, log=None)
        b = minimize(prob, np.zeros(prob.n), rtol=1e-12, log=None)
        assert a.converged and a.iterations == b.iterations and np.array_equal(a.u, b.u)
    springs = SofteningSprings(np.linspace(0.5, 1.0, 8))
    springs.load_factor = 0.99 * springs.limit_load()        # near the limit point: a long Newton path
    a = minimize(springs, np.zeros(8), rtol=1e-10, stall=3, log=None)
    b = minimize(springs, np.zeros(8), rtol=1e-10, log=None)
    assert a.converged and a.iterations == b.iterations > 3


# ----------------------------------------------------------------------------- starts at an exact equilibrium

def _clamped_disk(strain=0.0, pressure=None):
    from femshell.mesh.generators import disk
    from femshell.shell import Clamped, DeadPressure, Material, ShellModel, uniform_growth

    m = disk(radius=5.0, edge_length=1.0)
    loads = [DeadPressure(m, pressure)] if pressure is not None else []
    return ShellModel(m, Material(E=1.0, nu=0.3), uniform_growth(m.points, m.triangles, 0.2, strain),
                      [Clamped("outer")], loads)


def test_flat_plate_grown_past_buckling_is_left_for_a_stable_buckled_state():
    """The flat state is an equilibrium to round-off (uniform growth, clamped edge) but, at twice the
    critical growth strain g_c = 14.682 t^2 / (12 (1 + nu) a^2) (plate theory), a saddle: with
    stable=True Newton must leave it, not stop at the round-off floor and call it converged."""
    g_c = 14.682 * 0.2**2 / (12 * 1.3 * 5.0**2)
    model = _clamped_disk(2 * g_c)
    u0 = model.initial_unknowns()
    assert np.linalg.norm(model.gradient(u0)) < 1e-12          # the flat start is an equilibrium
    r = minimize(model, u0, stable=True, log=None)
    assert r.converged and r.stable and r.n_negative == 0
    assert r.energy < model.energy(u0) * (1 - 1e-3)              # buckled: below the flat state
    assert np.abs(model.positions(r.u)[:, 2]).max() > 0.05     # out of plane


@pytest.mark.parametrize("strain, pressure", [(0.0, None), (0.0, 0.0), (1e-12, None)])
def test_a_start_that_is_already_the_equilibrium_converges_at_once(strain, pressure):
    """No load (or a zero one) and no growth, or growth far below buckling: the flat start is the
    equilibrium, its residual is round-off with nothing to scale the tolerance; it used to end in
    'line search failed' because rtol |r(u0)| is below any iterate's round-off."""
    model = _clamped_disk(strain, pressure)
    r = minimize(model, model.initial_unknowns(), stable=True, log=None)
    assert r.converged and r.iterations == 0 and r.stable


def test_load_stepping_from_a_load_factor_of_zero():
    """At load factor 0 the unloaded start is the equilibrium (its residual is round-off): converged at
    once, and follow_load over factors starting at 0 returns (it used to halve a step of 0 forever)."""
    model = _clamped_disk(pressure=1e-6)
    u0 = model.initial_unknowns()
    model.load_factor = 0.0
    assert minimize(model, u0, log=None).iterations == 0
    out = follow_load(model, u0, [0.0, 0.5, 1.0], log=None)
    assert [r.converged for r in out] == [True, True, True]
    for bad in ([np.nan], [0.5, np.inf]):
        with pytest.raises(ValueError, match="must be finite"):
            follow_load(model, u0, bad, log=None)
    with pytest.raises(ValueError, match=f"u0 must be a vector of the problem's {model.n_free} free unknowns"):
        minimize(model, u0[:-1], log=None)
    for kw, words in (({"max_iter": -1}, "max_iter must be an integer >= 0"), ({"max_iter": 2.7}, "max_iter"),
                      ({"rtol": np.nan}, r"rtol must be a finite number in \[0, inf\), got nan"), ({"atol": -1.0}, "atol must be"),
                      ({"stall": -1}, "stall must be an integer >= 1"), ({"residual_scale": -1.0}, "residual_scale")):
        with pytest.raises(ValueError, match=words):
            minimize(model, u0, log=None, **kw)


class DoubleWell:
    """Π = (x² − 1)²/4 + y²/2: a saddle at the origin, minima at x = ±1 (minimize's docstring example)."""

    def energy(self, u):
        return (u[0] ** 2 - 1) ** 2 / 4 + u[1] ** 2 / 2

    def gradient(self, u):
        return np.array([u[0] ** 3 - u[0], u[1]])

    def hessian(self, u):
        return sp.csr_matrix(np.diag([3 * u[0] ** 2 - 1, 1.0]))


def test_a_saddle_met_on_the_last_iteration_is_not_returned_as_converged():
    """Stepping off the saddle on the last allowed iteration leaves a point that is no equilibrium."""
    with pytest.raises(NewtonError, match="left a saddle on its last iteration") as err:
        minimize(DoubleWell(), np.array([0.0, 0.3]), stable=True, max_iter=1, log=None)
    r = err.value.result
    assert not r.converged and r.residual == pytest.approx(np.linalg.norm(DoubleWell().gradient(r.u)))
    r = minimize(DoubleWell(), np.array([0.0, 0.3]), stable=True, log=None)
    assert r.converged and r.stable and abs(abs(r.u[0]) - 1) < 1e-8


def test_a_saddle_of_one_unknown_is_left_for_a_minimum():
    class One:
        def energy(self, u):
            return -u[0] ** 2 / 2 + u[0] ** 4 / 4

        def gradient(self, u):
            return np.array([-u[0] + u[0] ** 3])

        def hessian(self, u):
            return sp.csr_matrix([[-1 + 3 * u[0] ** 2]])

    r = minimize(One(), np.array([0.0]), stable=True, log=None)
    assert r.converged and r.stable and abs(abs(r.u[0]) - 1) < 1e-8


def test_max_step_caps_the_quasi_newton_steps_too():
    from femshell.solvers.linear import Refactorizer

    K = sp.csr_matrix(np.diag([2.0, 1.0]))
    f = np.array([20.0, 10.0])

    class Quadratic:
        def energy(self, u):
            return 0.5 * u @ (K @ u) - f @ u

        def gradient(self, u):
            return K @ u - f

        def hessian(self, u):
            return K

    pair = (Refactorizer(), Refactorizer())
    pair[0](K)                                     # a held Cholesky: the quasi-Newton phase runs on it
    with pytest.raises(NewtonError) as err:
        minimize(Quadratic(), np.zeros(2), max_step=0.01, factorizers=pair, quasi_newton=5, max_iter=0, log=None)
    assert np.abs(err.value.result.u).max() <= 5 * 0.01 * (1 + 1e-12)    # five steps of at most 0.01


def test_an_error_result_is_attached_when_the_hessian_cannot_be_factorised():
    class Broken(DoubleWell):
        def hessian(self, u):
            return sp.csr_matrix(np.diag([np.nan, 1.0]))

    with pytest.raises(NewtonError, match="could not be factorised") as err:
        minimize(Broken(), np.array([0.5, 0.3]), log=None)
    assert err.value.result is not None and np.array_equal(err.value.result.u, [0.5, 0.3])


def test_follow_load_cuts_are_bounded_by_the_float_resolution():
    class Wall:                      # no equilibrium past a load factor of 0.5
        load_factor = 0.0

        def energy(self, u):
            return 0.5 * (u[0] - self.load_factor) ** 2 if self.load_factor <= 0.5 else np.nan

        def gradient(self, u):
            return np.array([u[0] - self.load_factor])

        def hessian(self, u):
            return sp.csr_matrix([[1.0]])

    with pytest.raises(ValueError, match=r"max_cuts must be an integer in \[0, 50\], got 100"):
        follow_load(Wall(), np.zeros(1), [1.0], max_cuts=100, log=None)
    p = Wall()
    with pytest.raises(NewtonError, match="cannot be cut further") as err:
        follow_load(p, np.zeros(1), [1.0], max_cuts=50.0, log=None)
    assert p.load_factor == 0.5 and err.value.result.u[0] == pytest.approx(0.5)

    class FarWall(Wall):             # the same wall at a load factor of 1e6 + 0.5: the float spacing
        def energy(self, u):         # there (1.2e-10) is far above 2**-50 of the interval
            return 0.5 * (u[0] - self.load_factor) ** 2 if self.load_factor <= 1e6 + 0.5 else np.nan

    p = FarWall()
    with pytest.raises(NewtonError, match="below the float resolution") as err:
        follow_load(p, np.array([1e6]), [1e6 + 1.0], start=1e6, max_cuts=50, log=None)
    assert p.load_factor == 1e6 + 0.5 and err.value.result.u[0] == pytest.approx(1e6 + 0.5)


def test_the_shift_search_keeps_the_hessians_pattern():
    """K + τD as a sparse sum dropped K's explicit zeros (those of a flat shell's coupling entries):
    each trial, and each step of a load path, handed the Cholesky a new pattern to analyse."""
    from femshell.solvers.linear import Refactorizer
    from femshell.solvers.negative_curvature import shift_to_positive

    K = sp.csr_matrix((np.array([-1.0, 0.0, 0.0, 2.0]), np.array([0, 1, 0, 1]), np.array([0, 2, 4])), shape=(2, 2))
    seen = []
    f = Refactorizer()
    real = f.positive_definite
    f.positive_definite = lambda A: (seen.append((A.nnz, A.toarray())), real(A))[1]
    fac, tau = shift_to_positive(K, f, {"factorize": 0.0})
    assert fac is not None and tau > 0.5
    assert all(nnz == 4 for nnz, _ in seen)                  # the explicit zeros are kept
    np.testing.assert_array_equal(seen[-1][1], np.diag([-1.0 + tau, 2.0 + 2.0 * tau]))
    f.free()


class CountedQuartic:
    """Π(u) = Σ u⁴/4 + u²/2 − u, counting the energy and gradient evaluations; with ``both`` it
    also offers ``energy_and_gradient``."""

    def __init__(self, both):
        self.calls = {"energy": 0, "gradient": 0, "both": 0}
        if both:
            self.energy_and_gradient = self._both

    @staticmethod
    def _energy(u):
        return float(np.sum(u**4 / 4 + u**2 / 2 - u))

    @staticmethod
    def _gradient(u):
        return u**3 + u - 1

    def energy(self, u):
        self.calls["energy"] += 1
        return self._energy(u)

    def gradient(self, u):
        self.calls["gradient"] += 1
        return self._gradient(u)

    def _both(self, u):
        self.calls["both"] += 1
        return self._energy(u), self._gradient(u)

    def hessian(self, u):
        return sp.diags(3 * u**2 + 1).tocsr()


def test_line_search_takes_energy_and_gradient_in_one_pass_where_offered():
    runs = {}
    for both in (False, True):
        prob = CountedQuartic(both)
        res = minimize(prob, np.full(5, 3.0), rtol=1e-12, log=None)
        runs[both] = (res, prob.calls)
    (plain, plain_calls), (paired, paired_calls) = runs[False], runs[True]
    root = 0.6823278038280193                         # u³ + u − 1 = 0
    np.testing.assert_allclose(paired.u, root, rtol=1e-10)
    assert paired.iterations == plain.iterations
    # every full step was a paired evaluation: one call where there were two
    assert paired_calls["both"] >= paired.iterations > 0
    assert paired_calls["energy"] + paired_calls["gradient"] + paired_calls["both"] < \
        plain_calls["energy"] + plain_calls["gradient"]


def _hinge(fold_deg, law="svk", growth=1.0):
    """Two triangles of a unit flat rhombus, their shared edge on the x-axis, the second face turned about
    it by ``fold_deg``; every vertex held, so only the four edge unknowns are free."""
    from femshell.mesh.surface import SurfaceMesh
    from femshell.shell import Material, ShellModel
    from femshell.shell.boundary import Prescribed
    from femshell.shell.rest_state import RestState, metric

    a = np.radians(fold_deg)
    flat = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0]], float)
    pts = flat.copy()
    pts[3] = [0.5, -np.cos(a), -np.sin(a)]
    tri = np.array([[0, 1, 2], [1, 0, 3]])
    a0 = metric(flat, tri) * growth**2
    return ShellModel(SurfaceMesh(pts, tri), Material(1.0, 0.3, law=law),
                      RestState(a0, np.zeros_like(a0), np.full(2, 0.1)), [Prescribed(vertices=np.arange(4))])


def test_a_fold_sharper_than_one_element_is_named_when_newton_fails():
    """Past a 90° fold between two faces, θ = 0 of their edge is an energy maximum and the mid-edge normal
    runs towards 90° without an equilibrium: stable Newton fails, and the error says where and why (the
    shell's ``diagnose``). Below 90° the same hinge has its equilibrium and nothing to report."""
    model = _hinge(130.0)
    u0 = model.initial_unknowns() + 1e-3
    with pytest.raises(NewtonError) as info:
        minimize(model, u0, stable=True, max_iter=60, log=None)
    msg = str(info.value)
    assert "did not converge in 60 iterations" in msg
    assert "1 of 5 mid-edge normals are turned by 80° or more" in msg and "(0.5, 0, 0)" in msg
    assert "refine the mesh" in msg
    assert model.edge_turning_angles(info.value.result.u).max() > 89.0

    model = _hinge(60.0)
    res = minimize(model, model.initial_unknowns() + 1e-3, stable=True, log=None)
    assert res.converged and res.stable
    assert model.edge_turning_angles(res.u).max() < 10.0
    assert model.diagnose(res.u) is None


def test_diagnose_names_elements_past_the_svk_ellipticity_limit():
    """Grown by 1.3 (current/target stretch 0.77, below the SVK limit 0.806 at ν = 0.3), both SVK elements
    have lost ellipticity; grown by 1.1 (0.91) neither has; the neo-Hookean law has no such limit."""
    model = _hinge(0.0, growth=1.3)
    msg = model.diagnose(model.initial_unknowns())
    assert msg.startswith("2 elements are compressed past the stretch 0.806")
    for other in (_hinge(0.0, growth=1.1), _hinge(0.0, law="neo-hookean", growth=1.3)):
        assert other.diagnose(other.initial_unknowns()) is None


class _Diagnosed(SofteningSprings):
    def diagnose(self, u):
        return f"spring 0 is stretched to {u[0]:.1f}" if abs(u[0]) > 1 else None


def test_any_problem_s_diagnosis_is_appended_to_newton_s_error():
    """The solver knows no physics: whatever problem it solves may say what is wrong with the last iterate."""
    prob = _Diagnosed(f=[1.0, 0.5])
    prob.load_factor = 1.5                         # past the limit load 1: no equilibrium, u[0] runs off
    with pytest.raises(NewtonError) as info:
        minimize(prob, np.zeros(2), max_iter=5, log=None)
    assert str(info.value).endswith(f"At the last iterate spring 0 is stretched to {info.value.result.u[0]:.1f}")


def test_a_saddle_whose_well_is_narrower_than_the_first_escape_step_is_still_left():
    """Π = (x² − w²)²/4 + (y − Y)²/2 with w = 0.1 and a far coordinate Y = 1000 (as positions on a large shell):
    the escape's first step, 1e-3 · max|u| = 1 along x, overshoots the well (Π rises); a smaller step lowers Π,
    since the curvature along x is negative at the saddle, and Newton ends at a minimum x = ±w."""
    w, Y = 0.1, 1000.0

    class NarrowWell:
        def energy(self, u):
            return (u[0] ** 2 - w * w) ** 2 / 4 + (u[1] - Y) ** 2 / 2

        def gradient(self, u):
            return np.array([u[0] ** 3 - w * w * u[0], u[1] - Y])

        def hessian(self, u):
            return sp.csr_matrix(np.diag([3 * u[0] ** 2 - w * w, 1.0]))

    r = minimize(NarrowWell(), np.array([0.0, Y]), stable=True, log=None)
    assert r.converged and r.stable and abs(abs(r.u[0]) - w) < 1e-8
