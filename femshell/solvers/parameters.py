"""Parameter adapters: a :class:`~femshell.shell.ShellModel` as a parametrized problem for continuation.

A parametrized problem has ``set_parameter(lam)``, ``energy(u)``, ``gradient(u)``, ``hessian(u)``
and optionally ``parameter_derivative(u)`` (g_λ = ∂r/∂λ), ``dof_weights()``, ``parameter_scale`` and
``accept(u)`` (see :mod:`femshell.solvers.continuation`). :class:`LoadParameter` takes λ as the load
factor (Π = U − λ W); :class:`GrowthParameter` takes λ as whatever defines the rest state.
"""

from __future__ import annotations

import numpy as np

__all__ = ["LoadParameter", "GrowthParameter"]


class _ModelAdapter:
    """Common part of the ShellModel adapters: energy, derivatives, weights, accept."""

    def __init__(self, model, *, length_scale=None, parameter_scale=1.0):
        self.model = model
        pts = np.asarray(model.mesh.points, float)
        self.length_scale = float(np.ptp(pts, axis=0).max()) if length_scale is None else float(length_scale)
        if not (self.length_scale > 0):
            raise ValueError(f"length_scale must be > 0, got {self.length_scale}")
        self.parameter_scale = float(parameter_scale)
        if not (self.parameter_scale > 0):
            raise ValueError(f"parameter_scale must be > 0, got {parameter_scale}")

    def energy(self, u):
        return self.model.energy(u)

    def gradient(self, u):
        return self.model.gradient(u)

    def energy_and_gradient(self, u):
        return self.model.energy_and_gradient(u)

    def hessian(self, u):
        return self.model.hessian(u)

    def dof_weights(self):
        """1/L² for the free position unknowns, 1 for the edge unknowns (L = ``length_scale``)."""
        idx = np.flatnonzero(self.model.free)
        return np.where(idx < 3 * self.model.mesh.n_vertices, 1.0 / self.length_scale**2, 1.0)

    def accept(self, u):
        self.model.accept(u)

    def diagnose(self, u):
        return self.model.diagnose(u)

    @property
    def n_free(self):
        return self.model.n_free

    # minimize() asks these of a problem to scale its residual
    @property
    def loads(self):
        return getattr(self.model, "loads", [])

    @property
    def load_factor(self):
        return self.model.load_factor

    def load_gradient(self, u):
        return self.model.load_gradient(u)


class LoadParameter(_ModelAdapter):
    """λ = ``model.load_factor`` (Π = U − λ W); ∂r/∂λ = −∂W/∂u exactly.

    ``length_scale`` (default: the largest extent of the mesh) weights positions in the
    arclength norm; ``parameter_scale`` (default 1) is the scale of λ.
    """

    def __init__(self, model, **kw):
        if not getattr(model, "loads", None):
            raise ValueError("LoadParameter needs a model with loads: the load factor scales them, and this "
                             "model has none (GrowthParameter follows a growth instead)")
        super().__init__(model, **kw)

    def set_parameter(self, lam):
        self.model.load_factor = float(lam)

    @property
    def parameter(self):
        return self.model.load_factor

    def parameter_derivative(self, u):
        return -self.model.load_gradient(u)


class GrowthParameter(_ModelAdapter):
    """λ defines the rest state: ``rest_of(lam) -> RestState``; set_parameter calls model.set_rest_state.

    Example: uniform growth strain g,
    ``GrowthParameter(model, lambda g: uniform_growth(mesh.points, mesh.triangles, t, g), parameter_scale=1e-4)``.
    ∂r/∂λ is a central difference in λ (two gradient evaluations) with step
    ``fd_step`` × max(|λ|, parameter_scale).
    """

    def __init__(self, model, rest_of, *, length_scale=None, parameter_scale=1.0, fd_step=1e-6):
        super().__init__(model, length_scale=length_scale, parameter_scale=parameter_scale)
        self.rest_of = rest_of
        self.fd_step = float(fd_step)
        if not 1e-14 <= self.fd_step <= 0.1:
            raise ValueError(f"fd_step must be in [1e-14, 0.1] (relative difference step in λ), got {fd_step}")
        self._lam = None

    def set_parameter(self, lam):
        lam = float(lam)
        if lam != self._lam:
            self.model.set_rest_state(self.rest_of(lam))
            self._lam = lam

    @property
    def parameter(self):
        return self._lam

    def parameter_derivative(self, u):
        lam = self._lam
        step = self.fd_step * max(abs(lam), self.parameter_scale)
        self.set_parameter(lam + step)
        gp = self.model.gradient(u)
        self.set_parameter(lam - step)
        gm = self.model.gradient(u)
        self.set_parameter(lam)
        return (gp - gm) / (2.0 * step)

