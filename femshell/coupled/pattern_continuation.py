r"""Continuation of stationary mechanochemical patterns in a model parameter (theory §2.9).

The stationary system F(z; λ) = 0, z = (u, c) (:class:`~femshell.coupled.stationary.StationaryProblem`),
is a non-gradient parametrised problem of :func:`femshell.solvers.continuation.continuation`: residual F,
unsymmetric Jacobian J = ∂F/∂z, and ∂F/∂λ. :class:`PatternParameter` makes λ one field of the
:class:`~femshell.coupled.MechanochemicalModel` (:data:`PARAMETERS`); setting it rebuilds what depends on
it (the stretch law s(c), the target thickness, the force unit). ∂F/∂λ is exact where F is linear in λ,

    ∂F/∂w = [0, M P(H)/w],   ∂F/∂β = [0, −M c],   ∂F/∂D = [0, −K c],

and a central difference of F in λ for c*, h0 and Λmax/Λmin, which enter through s(c) and the shell's
rest state. The branch's folds are sign changes of dλ/ds, its branch points sign changes of
det [[J, ∂F/∂λ], [tᵀ, 0]] (:mod:`femshell.solvers.special_points`); the stability recorded per point is
the coupled dynamics' (:func:`~femshell.coupled.stationary_stability.coupled_stability`: the leading
eigenvalues μ of S v = μ M v and the shell Hessian's inertia), and the critical mode at a special point
is J's null vector, split into the concentration and the shape (:func:`critical_mode_fields`).
Not re-exported by :mod:`femshell.coupled`, which does not load the continuation machinery.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from .._checks import finite as _finite, integer as _integer
from ..chemistry import curvature_source
from ..geometry import vertex_normals
from ..solvers.continuation import continuation
from .stationary_stability import coupled_stability

__all__ = ["PARAMETERS", "PatternParameter", "continue_pattern", "critical_mode_fields"]

#: the parameters a pattern can be followed in: name -> (meaning, how ∂F/∂λ is computed)
PARAMETERS = {
    "w": ("production rate w", "exact"),
    "beta": ("degradation rate β", "exact"),
    "D": ("diffusion coefficient D", "exact"),
    "c_star": ("contractility threshold c*", "central difference"),
    "h0": ("rest thickness h0", "central difference"),
    "lam_ratio": ("contractility ratio Λmax/Λmin (Λmax fixed)", "central difference"),
}


def _parameter_value(params, name):
    if name == "lam_ratio":
        return params.lam_max / params.lam_min
    return float(getattr(params, name))


def _with_parameter(params, name, value):
    """The MechanochemicalModel with ``name`` set to ``value`` (a ValueError names the range)."""
    if name == "lam_ratio":
        if not (math.isfinite(value) and value >= 1.0):
            raise ValueError(f"lam_ratio = Λmax/Λmin must be >= 1, got {value}")
        return replace(params, lam_min=params.lam_max / value)
    return replace(params, **{name: float(value)})


class PatternParameter:
    """A :class:`StationaryProblem` as a parametrised non-gradient problem in one model parameter.

    ``name``: a key of :data:`PARAMETERS`. Unknowns z = (u, c). Arclength weights: 1/L² for the
    positions (L = ``length_scale``, default h0), 1 for the edge unknowns, 1/c_scale² for the
    concentrations (default c_max = w Hs/β, or max c when that is not finite). ``n_modes``: how many
    of the leading μ :meth:`stability` reports (``stability=False``: none is computed). The problem's shell and growth are shared with the
    loop it was made of: the continuation leaves them at the last parameter it set.
    """

    def __init__(self, problem, name, *, length_scale=None, c_scale=None, parameter_scale=None, n_modes=4,
                 fd_step=1e-6, stability=True):
        if name not in PARAMETERS:
            raise ValueError(f"parameter must be one of {', '.join(PARAMETERS)}, got {name!r}")
        self.problem, self.name = problem, name
        p = problem.params
        self.n_free = problem.n_u + problem.n_c
        self.length_scale = _finite("length_scale", p.h0 if length_scale is None else length_scale, 0.0,
                                    lo_open=True, text="(0, inf)")
        if c_scale is None:
            c_scale = p.c_max if math.isfinite(p.c_max) and p.c_max > 0 else 1.0
        self.c_scale = _finite("c_scale", c_scale, 0.0, lo_open=True, text="(0, inf)")
        value = _parameter_value(p, name)
        if parameter_scale is None:
            parameter_scale = abs(value) if value != 0 else 1.0
        self.parameter_scale = _finite("parameter_scale", parameter_scale, 0.0, lo_open=True, text="(0, inf)")
        self.n_modes = _integer("n_modes", n_modes, 1)
        self.fd_step = _finite("fd_step", fd_step, 1e-14, 0.1)
        self._lam = value
        if not stability:           # the continuation then records no stability (and saves its eigenproblems)
            self.stability = None

    @property
    def parameter(self) -> float:
        return self._lam

    def set_parameter(self, lam):
        lam = float(lam)
        if lam != self._lam:
            self.problem.set_params(_with_parameter(self.problem.params, self.name, lam))
            self._lam = lam

    def residual(self, z):
        return self.problem.residual(z)

    def jacobian(self, z):
        return self.problem.jacobian(z)

    def parameter_derivative(self, z):
        """∂F/∂λ at the current parameter: exact for w, β, D; a central difference otherwise (module docstring)."""
        pb, p = self.problem, self.problem.params
        u, c = pb.split(z)
        out = np.zeros(self.n_free)
        if self.name in ("w", "beta", "D"):
            points = pb.shell.positions(u)
            if self.name == "w":
                _, H = pb.growth.mean_curvature(u)
                out[pb.n_u:] = pb.chemistry.mass_lumped(points) * curvature_source(H, 1.0, p.Hs)
            elif self.name == "beta":
                out[pb.n_u:] = -pb.chemistry.mass_lumped(points) * c
            else:
                out[pb.n_u:] = -(pb.chemistry.stiffness(points) @ c)
            return out
        lam = self._lam
        step = self.fd_step * max(abs(lam), self.parameter_scale)
        self.set_parameter(lam + step)
        fp = pb.residual(z)
        self.set_parameter(lam - step)
        fm = pb.residual(z)
        self.set_parameter(lam)
        return (fp - fm) / (2.0 * step)

    def dof_weights(self):
        shell = self.problem.shell
        idx = np.flatnonzero(shell.free)
        w_u = np.where(idx < 3 * shell.mesh.n_vertices, 1.0 / self.length_scale**2, 1.0)
        return np.concatenate([w_u, np.full(self.problem.n_c, 1.0 / self.c_scale**2)])

    def stability(self, z):
        """{"stable", "n_unstable", "n_negative_mechanical", "mu_0", "mu_0_imag", ...}: the coupled dynamics'
        leading ``n_modes`` eigenvalues μ (largest real part first) at the root z."""
        u, c = self.problem.split(z)
        try:
            st = coupled_stability(self.problem, u, c, k=self.n_modes)
        except ValueError:          # the shell Hessian is singular here: no reduced Jacobian
            return {"stable": None, "n_unstable": math.nan, "n_negative_mechanical": math.nan,
                    **{f"mu_{i}{part}": math.nan for i in range(self.n_modes) for part in ("", "_imag")}}
        out = {"stable": st.stable, "n_unstable": int(np.count_nonzero(st.eigenvalues.real > 0)),
               "n_negative_mechanical": st.n_negative_mechanical}
        mu = np.asarray(st.eigenvalues, dtype=complex)
        for i in range(self.n_modes):
            out[f"mu_{i}"] = float(mu[i].real) if i < len(mu) else math.nan
            out[f"mu_{i}_imag"] = float(mu[i].imag) if i < len(mu) else math.nan
        return out


def continue_pattern(problem, u, c, name, *, ds, lam_stop=None, max_steps=100, n_modes=4, length_scale=None,
                     c_scale=None, parameter_scale=None, record=None, label=None, log=None, **options):
    """Follow the stationary state (u, c) of ``problem`` in the parameter ``name`` (:data:`PARAMETERS`).

    (u, c) must be a root at the problem's current parameters (e.g. :func:`stationary_state`'s; the
    first point is corrected by Newton at fixed λ). ``options`` go to
    :func:`~femshell.solvers.continuation.continuation` (``ds_max``, ``direction``, ``stop_at``,
    ``rtol``, ...). ``record(z) -> dict`` adds columns to each row (default: max c;
    :func:`femshell.scene.pattern_output.pattern_measures` gives the pattern's area and spot radius).
    Returns the :class:`~femshell.solvers.continuation.Branch`: its rows carry those columns and
    :meth:`PatternParameter.stability`; the parameter is left at the branch's last point.
    """
    pp = PatternParameter(problem, name, length_scale=length_scale, c_scale=c_scale,
                          parameter_scale=parameter_scale, n_modes=n_modes)
    z0 = problem.join(u, c)
    return continuation(pp, z0, pp.parameter, ds=ds, lam_stop=lam_stop, max_steps=max_steps,
                        record=record or (lambda z: {"max_c": float(np.max(problem.split(z)[1]))}),
                        label=label or name, log=log, **options)


def critical_mode_fields(problem, z, mode) -> dict:
    """Vertex fields of a critical mode (a vector of the unknowns z): ``mode_c`` (its concentration part,
    scaled to max |·| = 1), ``mode_normal`` (the normal displacement of its shape part at the state z, with
    the same scale) and ``mode_displacement`` (n, 3)."""
    u, _ = problem.split(z)
    du, dc = problem.split(mode)
    scale = float(np.max(np.abs(dc))) or float(np.max(np.abs(du))) or 1.0
    points = problem.shell.positions(u)
    dx = (problem.shell.positions(u + du) - points) / scale
    normals = vertex_normals(points, problem.triangles)
    return {"mode_c": dc / scale, "mode_normal": np.sum(dx * normals, axis=1), "mode_displacement": dx}
