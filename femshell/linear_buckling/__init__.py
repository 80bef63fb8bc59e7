"""Linear buckling of flat plates: an independent planar reference built on scikit-fem.

Deliberately separate from femshell's own shell code: the classical two-step linear theory of a
flat plate with scikit-fem's elements, against which the nonlinear shell solver is checked.

1. **Prestress** (:func:`membrane_prestress`, :mod:`.prestress`): plane-stress linear
   elasticity with the isotropic eigenstrain ``g I`` per triangle (the linearised grown
   metric (1 + g)² a₀ ≈ a₀ + 2 g a₀, theory §5); ``N = t σ``, compression negative.
2. **Buckling** (:func:`buckling_loads`, :mod:`.eigenproblem`): Kirchhoff plate with the Morley
   element, ``K_b w = μ K_g w``, ``K_b = ∫ D [(1−ν) w,ab v,ab + ν Δw Δv]``,
   ``D = E t³ / (12 (1 − ν²))``, ``K_g = −∫ N_ab w,a v,b``; for a prestress caused by growth
   g the critical growth strain of the linear theory is ``μ g``.
3. **Mode analysis** (:func:`azimuthal_wavenumber`, :func:`mode_wavenumber`, :mod:`.modes`):
   the number of azimuthal wrinkles from the Fourier spectrum of a mode on circles.
4. **The grown disk** (:func:`critical_growth_strain`, :func:`critical_inner_radius`,
   :mod:`.disk`): the critical growth strain of a disk grown inside r < R2, and the smallest
   R2 at which a given growth buckles it.

Units: lengths in the cell size, E = 1 by default; ``μ`` is dimensionless, ``N`` has units of E
times length.

Boundary conditions of the bending problem
------------------------------------------
``"clamped"``: w and the normal slope (the Morley edge dofs ``u_n``) vanish on the boundary.
``"simply_supported"``: w vanishes at the boundary vertices only (on a polygonal circle the
Morley element converges to the simply supported circle, not to the Babuška-paradox limit).
``"free"``: K_b has the rigid modes ``w = a + b x + c y``. For a self-equilibrated prestress
(``membrane_prestress(boundary="free")``: div N = 0, N n = 0 on the edge, so ∫ N dA = 0) they
are in the null space of K_g as well; the pencil is regular on any complement of them, with the
same eigenvalues. The complement taken is {w : w(p_i) = 0 at three well-spread vertices}, and
the rigid part of each mode is removed by an L2 projection. Discretely K_g r is only
approximately zero, so μ depends slightly on the pinned vertices: ``BucklingResult.info
["rigid_leak"]`` reports the relative coupling, the order of that dependence (not a bound).

Eigen solver
------------
``eigsh(K_g, M=K_b, Minv=K_b⁻¹, which="LA")`` on K_g w = λ K_b w, λ = 1/μ: the Krylov operator
K_b⁻¹ K_g is the shift-invert operator of the pencil about μ = 0, and the largest λ are the
smallest positive μ, so buckling under the reversed load never crowds them out. The inner
solver for K_b⁻¹ is ``solver=`` "splu" (default: the Morley K_b is cheap to factorise and its
triangular solves are the fastest), "pardiso" (:mod:`femshell.solvers.linear`) or "pyamg"
(FGMRES; slow on this fourth-order operator); timings are in ``BucklingResult.timings``.

Example
-------
>>> import numpy as np
>>> from skfem import MeshTri
>>> m = MeshTri.init_circle(4)                   # unit disk
>>> p, t = m.p.T, m.t.T
>>> N = membrane_prestress(p, t, growth_strain=1e-3, nu=0.3, thickness=0.1, boundary="clamped")
>>> res = buckling_loads(p, t, N, nu=0.3, thickness=0.1, bc="clamped", k=3)
>>> gc = res.mu[0] * 1e-3                        # critical growth strain
>>> round(float(gc * 12 * 1.3 / 0.1**2), 1)     # k^2 = 14.682 for the clamped disk
14.7
"""

from .disk import CriticalGrowth, CriticalRadius, _disk_mesh, critical_growth_strain, critical_inner_radius
from .eigenproblem import BucklingResult, buckling_loads
from .modes import azimuthal_wavenumber, mode_wavenumber
from .plate import bending_stiffness
from .prestress import membrane_prestress
from .shell_state import BucklingPencil, ShellBuckling, buckling_pencil, shell_buckling_loads

__all__ = ["membrane_prestress", "buckling_loads", "BucklingResult", "azimuthal_wavenumber",
           "mode_wavenumber", "critical_growth_strain", "CriticalGrowth", "critical_inner_radius",
           "CriticalRadius", "bending_stiffness", "shell_buckling_loads", "ShellBuckling",
           "buckling_pencil", "BucklingPencil"]
