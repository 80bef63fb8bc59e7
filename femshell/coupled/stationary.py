r"""Stationary states of the mechanochemical shell as one nonlinear system in (u, c) (theory §2.9).

    F_u(u, c) = ∇_u Π(u; ā, b̄, h̄ of s(c))                              = 0   (mechanical equilibrium)
    F_c(u, c) = M(x) (P(H(u)) − β c) − D K(x) c                          = 0   (chemistry at rest)

u are the shell's free unknowns (positions and edge unknowns), c the vertex concentrations; M(x) is
the lumped P1 mass and K(x) the cotangent stiffness of the current surface, H the vertex mean
curvature of :class:`~femshell.growth.GrowthRestState` and s(c) the element stretches of the element
means of c: exactly the quantities of the time loop (:mod:`femshell.coupled.loop`), whose chemistry
step (M + γ D K) c⁺ = M (c e^{−β dt} + γ P) has c⁺ = c iff F_c = 0. A stationary state of the loop
is therefore a root. :meth:`StationaryProblem.jacobian` is the exact Jacobian

    J = [[K_uu, ∂F_u/∂c], [∂F_c/∂u, −β M − D K]]

(:mod:`femshell.coupled.stationary_jacobian` for the two coupling blocks); it is not symmetric and is
factorised by SuperLU's LU with partial pivoting (:class:`femshell.solvers.lu.LUFactorization`).
:func:`stationary_state` runs Newton on it from a loop's state.

Example
-------
>>> from femshell.coupled import CoupledLoop, MechanochemicalModel, stationary_state    # doctest: +SKIP
>>> loop = CoupledLoop(mesh, MechanochemicalModel(...), stepping, c0=InitialSpot())      # doctest: +SKIP
>>> loop.run()                                                                            # doctest: +SKIP
>>> root = stationary_state(loop)          # Newton on (u, c) from the loop's end state  # doctest: +SKIP
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .._checks import finite as _finite, integer as _integer
from ..growth import element_average
from ..solvers.linear import LinearSolverError
from ..solvers.lu import LUFactorization
from .equilibrium import strain_force_unit
from .stationary_jacobian import chemistry_element_derivatives, force_stretch_derivative

__all__ = ["StationaryProblem", "StationaryResult", "stationary_state"]


class StationaryProblem:
    """The residual F(u, c) and its Jacobian for one shell, growth law and chemistry (module docstring).

    Parameters
    ----------
    shell : ShellModel; growth : GrowthRestState (with its stretch law); params : MechanochemicalModel;
    chemistry : P1Assembler of the mesh's triangles (:attr:`ReactionDiffusion.assembler`).

    Evaluating sets the shell's rest state to the one of the c evaluated (``growth.apply``).
    """

    def __init__(self, shell, growth, params, chemistry):
        self.shell, self.growth, self.params, self.chemistry = shell, growth, params, chemistry
        self.triangles = np.asarray(shell.mesh.triangles)
        self.n_u = shell.n_free
        self.n_c = shell.mesh.n_vertices
        self.free_index = shell.assembler.free_index
        self.force_unit = strain_force_unit(shell, growth, params)

    def set_params(self, params):
        """Take new model parameters: the stretch law s(c), the target thickness h0 and the force unit
        follow (the mesh, the boundary conditions and the rest-curvature law stay)."""
        if (params.thickness_mode, params.rest_curvature, params.natural_curvature) != (
                self.params.thickness_mode, self.params.rest_curvature, self.params.natural_curvature):
            raise ValueError("set_params changes the model's parameters, not its thickness or rest-curvature law")
        h0_changed = params.h0 != self.params.h0
        self.params = params
        self.growth.stretch_law = params.stretch
        self.growth.h0 = params.h0
        if h0_changed:      # the unit strain's force depends on the thickness only
            self.force_unit = strain_force_unit(self.shell, self.growth, params)

    @classmethod
    def of_loop(cls, loop) -> "StationaryProblem":
        """The problem of a :class:`~femshell.coupled.CoupledLoop` (its shell, growth, parameters, mesh)."""
        return cls(loop.shell, loop.growth, loop.params, loop.chemistry.assembler)

    # ---- unknowns ---------------------------------------------------------------------------------
    def join(self, u, c) -> np.ndarray:
        """z = [u, c]."""
        return np.concatenate([np.asarray(u, dtype=float), np.asarray(c, dtype=float)])

    def split(self, z):
        """(u, c) of z."""
        z = np.asarray(z, dtype=float)
        if z.shape != (self.n_u + self.n_c,):
            raise ValueError(f"z must have {self.n_u} shell unknowns and {self.n_c} concentrations, "
                             f"shape ({self.n_u + self.n_c},), got {z.shape}")
        return z[:self.n_u], z[self.n_u:]

    def _set_growth(self, c):
        s = self.growth.stretch(c)
        self.growth.apply(s)
        return s

    # ---- residual ---------------------------------------------------------------------------------
    def residual(self, z) -> np.ndarray:
        """F(z) = [F_u, F_c] (forces, then concentration per time times area)."""
        u, c = self.split(z)
        self._set_growth(c)
        p = self.params
        points = self.shell.positions(u)
        mass = self.chemistry.mass_lumped(points)
        _, H_vertex = self.growth.mean_curvature(u)
        f_c = mass * (p.source(H_vertex) - p.beta * c)
        if p.D > 0:
            f_c -= p.D * (self.chemistry.stiffness(points) @ c)
        return np.concatenate([self.shell.gradient(u), f_c])

    # ---- Jacobian ---------------------------------------------------------------------------------
    def jacobian(self, z) -> sp.csr_matrix:
        """dF/dz (CSR, (n_u + n_c)²): the four blocks of the module docstring, exact."""
        u, c = self.split(z)
        s = self._set_growth(c)
        shell, p = self.shell, self.params
        q = shell.full(u)[shell.element_dofs]
        edges = (shell.edge_kind_el, shell.edge_direction_el, shell.face_edge_sign)
        rest = self.growth.rest_state(s)
        points = shell.positions(u)
        mass = self.chemistry.mass_lumped(points)
        chem = -p.beta * sp.diags(mass)
        if p.D > 0:
            chem = chem - p.D * self.chemistry.stiffness(points)
        blocks = [[shell.hessian(u), self._force_concentration(q, c, s, rest, edges)],
                  [self._chemistry_shape(q, u, c, edges), chem]]
        return sp.bmat(blocks, format="csr")

    def _force_concentration(self, q, c, s, rest, edges):
        """∂F_u/∂c: Σ_e ∂(∇W_e)/∂s_e · ds/dc(c_e) / 3 into each of the element's vertices."""
        rate = force_stretch_derivative(q, (rest.metric, rest.curvature, rest.thickness),
                                        self.growth.rest_state_derivative(s), *edges, self.shell.material)
        ds_dc = self.params.dstretch_dc(element_average(c, self.triangles)) / 3.0
        rows = np.broadcast_to(self.free_index[self.shell.element_dofs][:, :, None], (len(q), 21, 3))
        cols = np.broadcast_to(self.triangles[:, None, :], rows.shape)
        data = np.broadcast_to((rate * ds_dc[:, None])[:, :, None], rows.shape)
        return _coo(data, rows, cols, (self.n_u, self.n_c))

    def _chemistry_shape(self, q, u, c, edges):
        r"""∂F_c/∂u: with the vertex sums A_i = Σ_T A_T (= 3 m_i) and N_i = Σ_T A_T H_T (H_i = N_i / A_i),

            ∂F_c,i = ⅓ [P'(H_i) (∂N_i − H_i ∂A_i) + (P(H_i) − β c_i) ∂A_i] − D ∂(K c)_i.
        """
        p, tri = self.params, self.triangles
        d_area, d_area_h, d_stiff = chemistry_element_derivatives(q, self.growth.k_ref, c[tri], *edges)
        _, H = self.growth.mean_curvature(u)
        slope = p.source_slope(H)
        coef_area = (p.source(H) - p.beta * c - slope * H) / 3.0
        data = (slope / 3.0)[tri][:, :, None] * d_area_h[:, None, :] + coef_area[tri][:, :, None] * d_area[:, None, :]
        if p.D > 0:
            data = data - p.D * d_stiff
        rows = np.broadcast_to(tri[:, :, None], data.shape)
        cols = np.broadcast_to(self.free_index[self.shell.element_dofs][:, None, :], data.shape)
        return _coo(data, rows, cols, (self.n_c, self.n_u))

    # ---- measures ---------------------------------------------------------------------------------
    def residual_norms(self, z, f=None):
        """(|F_u| / force unit, max_i |F_c,i / m_i| / (β c_scale)): the force imbalance in units of a
        uniform unit strain's, and the largest rate of change of c per unit time relative to
        c_scale = max(max c, 1 % of c_max) (the loop's scale of stationarity), times 1/β."""
        u, c = self.split(z)
        f = self.residual(z) if f is None else f
        mass = self.chemistry.mass_lumped(self.shell.positions(u))
        p = self.params
        c_scale = max(float(np.max(np.abs(c))), 1e-2 * p.c_max if math.isfinite(p.c_max) else 0.0, 1e-300)
        rate = float(np.max(np.abs(f[self.n_u:] / mass))) / (c_scale * (p.beta if p.beta > 0 else 1.0))
        return float(np.linalg.norm(f[:self.n_u])) / self.force_unit, rate


def _coo(data, rows, cols, shape):
    """Sum (data, rows, cols) into a CSR matrix, dropping entries whose row or column is −1 (fixed)."""
    data, rows, cols = (np.asarray(a).ravel() for a in (data, rows, cols))
    keep = (rows >= 0) & (cols >= 0)
    return sp.csr_matrix((data[keep], (rows[keep], cols[keep])), shape=shape)


@dataclass
class StationaryResult:
    """What :func:`stationary_state` found.

    u, c : the root (shell free unknowns, vertex concentrations); converged : bool; iterations : Newton
    steps; history : (force, rate) of :meth:`StationaryProblem.residual_norms` at the start and after each
    step; message : why it stopped.
    """

    u: np.ndarray
    c: np.ndarray
    converged: bool
    iterations: int
    history: list = field(default_factory=list)
    message: str = ""


def stationary_state(loop, tol: float = 1e-9, max_iter: int = 30, problem: StationaryProblem | None = None,
                     u=None, c=None) -> StationaryResult:
    """Newton on F(u, c) = 0 from the loop's state (or from ``u``, ``c``), to both measures of
    :meth:`StationaryProblem.residual_norms` ≤ ``tol``.

    Each step solves J δ = −F by SuperLU (LU with partial pivoting; J is not symmetric) and is halved
    (at most 20 times) until ‖(F_u / force unit, F_c / (m β c_scale))‖₂ decreases. The loop's state and rest
    state are left as they were.
    """
    tol = _finite("tol", tol, 0.0, lo_open=True, text="(0, inf)")
    max_iter = _integer("max_iter", max_iter, 0)
    problem = problem or StationaryProblem.of_loop(loop)
    z = problem.join(loop.u if u is None else u, loop.c if c is None else c)
    try:
        return _newton(problem, z, tol, max_iter)
    finally:
        loop.growth.apply(loop.s)


def _merit(problem, z):
    f = problem.residual(z)
    norms = problem.residual_norms(z, f)
    return f, norms, math.hypot(*norms) if all(math.isfinite(v) for v in norms) else math.inf


def _newton(problem, z, tol, max_iter):
    f, norms, merit = _merit(problem, z)
    history = [norms]
    for it in range(max_iter + 1):
        if max(norms) <= tol:
            u, c = problem.split(z)
            return StationaryResult(u.copy(), c.copy(), True, it, history, f"converged in {it} Newton steps")
        if it == max_iter:
            break
        try:
            step = -LUFactorization(problem.jacobian(z)).solve(f)
        except LinearSolverError as exc:
            u, c = problem.split(z)
            return StationaryResult(u.copy(), c.copy(), False, it, history, f"singular Jacobian: {exc}")
        for _ in range(21):
            trial = z + step
            try:
                f_t, norms_t, merit_t = _merit(problem, trial)
            except (ValueError, FloatingPointError):    # a trial past a degenerate triangle or c < 0
                merit_t = math.inf
            if merit_t < merit:
                break
            step *= 0.5
        else:
            u, c = problem.split(z)
            return StationaryResult(u.copy(), c.copy(), False, it, history,
                                    f"no decrease of the residual along the Newton step (force {norms[0]:.3g}, "
                                    f"rate {norms[1]:.3g})")
        z, f, norms, merit = trial, f_t, norms_t, merit_t
        history.append(norms)
    u, c = problem.split(z)
    return StationaryResult(u.copy(), c.copy(), False, max_iter, history,
                            f"not converged in {max_iter} Newton steps (force {norms[0]:.3g}, rate {norms[1]:.3g}, "
                            f"tol {tol:g})")
