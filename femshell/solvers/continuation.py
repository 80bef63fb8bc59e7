r"""Pseudo-arclength continuation of equilibria, with stability, fold and branch-point detection (theory §4).

The object followed is a **parametrized problem**: anything with

``set_parameter(lam)``
    make ``lam`` the current parameter value (a ValueError outside its range is a failed step);
``energy(u)``, ``gradient(u)``, ``hessian(u)``
    Π, r = ∂Π/∂u and K = ∂²Π/∂u² (scipy sparse, symmetric) at the current parameter;

and optionally ``parameter_derivative(u)`` (g_λ = ∂r/∂λ; default a central difference in λ),
``dof_weights()`` (per-unknown weights of the arclength norm; default ones),
``parameter_scale`` (the scale of λ in that norm; default 1) and ``accept(u)`` (called after
every accepted step). A **non-gradient** problem (a stationary state of dynamics that is not a
gradient flow, the G+Smo style) has instead of ``energy``/``gradient``/``hessian``

``residual(u)``, ``jacobian(u)``
    r(u, λ) and J = ∂r/∂u (scipy sparse, any pattern, not symmetric), factorised by LU
    (:mod:`femshell.solvers.lu`);

and optionally ``stability(u)``, a dict with ``"stable"`` (bool or None) and scalar columns for the
branch table (its own notion of stability: J's inertia means nothing here). Its branch points are
sign changes of det J not explained by a fold (:mod:`.special_points`), its critical modes J's null
vectors; ``n_eigs`` and the "BP?" dips do not apply. The branch r(u, λ) = 0 is parametrised by the arclength s in

.. math:: \|(\delta u, \delta\lambda)\|^2 = \frac1n \sum_i w_i\, \delta u_i^2
          + \left(\frac{\delta\lambda}{\lambda_{\rm scale}}\right)^2 .

The pieces, one module each (this module gathers their public names):

* :mod:`femshell.solvers.parameters`: :class:`LoadParameter` (λ = ``model.load_factor``) and
  :class:`GrowthParameter` (λ defines the rest state) adapt a :class:`~femshell.shell.ShellModel`;
  for buckling give them ``length_scale=thickness`` (buckles grow on that scale);
* :mod:`.corrector`: bordered solves, the Newton corrector on the hyperplane, tangent, inertia
  and eigenvalues nearest zero;
* :mod:`.arclength`: :func:`continuation`, the predictor/corrector loop with step control and
  stopping (``lam_stop``, ``max_steps``, ``stop_at``, ``ds_min``, ``callback``);
* :mod:`.special_points`: folds ("LP"), branch points ("BP"), possible symmetric bifurcations
  ("BP?"), located and with their critical modes and multiplicity;
* :mod:`.switching`: :func:`switch_branch` onto a new branch at a branch point;
* :mod:`.branch`: the returned records :class:`Branch` and :class:`SpecialPoint`; writing them
  is :func:`femshell.io.write_branch_csv` and :func:`femshell.io.write_special_points`.

Example (a supercritical pitchfork at λ = 1: y = 0, or y² = λ − 1)
------------------------------------------------------------------
>>> import numpy as np, scipy.sparse as sp
>>> class Pitchfork:
...     lam = 0.0
...     def set_parameter(self, lam): self.lam = lam
...     def energy(self, u): return 0.5 * (u[0] - self.lam)**2 + 0.5 * (1 - self.lam) * u[1]**2 + 0.25 * u[1]**4
...     def gradient(self, u): return np.array([u[0] - self.lam, (1 - self.lam) * u[1] + u[1]**3])
...     def hessian(self, u): return sp.csr_matrix(np.diag([1.0, 1 - self.lam + 3 * u[1]**2]))
>>> b = continuation(Pitchfork(), np.zeros(2), 0.0, ds=0.3, ds_max=0.3, lam_stop=1.5, log=None)
>>> bp = b.special_points[0]
>>> bp.kind, round(bp.parameter, 8), bp.multiplicity
('branch', 1.0, 1)
>>> nb = switch_branch(Pitchfork(), bp, amplitude=0.1, ds=0.1, lam_stop=1.25, log=None)
>>> u, lam = nb.states[-1]                 # y² = λ − 1 on the new branch, which is stable
>>> float(round(abs(u[1]), 6)), lam, nb.rows[-1]["stable"]
(0.5, 1.25, True)
"""

from .arclength import continuation
from .branch import Branch, ContinuationError, SpecialPoint
from .parameters import GrowthParameter, LoadParameter
from .switching import switch_branch

__all__ = ["continuation", "switch_branch", "Branch", "SpecialPoint", "LoadParameter", "GrowthParameter",
           "ContinuationError"]
