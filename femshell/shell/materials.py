r"""Material laws of the shell: the membrane energy density and the bending quadratic form as
swappable types, and :class:`Material` (E, ν and the name of its law); docs/theory.md §2 (Energy).

With :math:`C = \bar a^{-1} a` and :math:`M = \bar a^{-1}(b - \bar b)` the element energy is
:math:`W = \bar A\,[\bar h\,\psi(C) + \tfrac{\bar h^3}{12}\,\|M\|^2]`,
:math:`\|M\|^2 = \tfrac{\alpha}{2}(\operatorname{tr} M)^2 + \beta \operatorname{tr}(M^2)`,
:math:`\alpha = E\nu/(1-\nu^2)`, :math:`\beta = E/(2(1+\nu))`. A law is a class with
``membrane(C, alpha, beta)`` (ψ), ``bending(M, alpha, beta)`` and, for the checks of a run,
``ellipticity_margin`` and ``non_elliptic`` (numpy, per element).

* :class:`StVenantKirchhoff`: :math:`\psi = \tfrac14\|C - I\|^2`. It loses ellipticity under
  compression (equibiaxial stretch below :math:`\sqrt{(\alpha+\beta)/(\alpha+2\beta)}`, 0.866 at
  ν = 0.5): a confined region grown past it collapses into mesh-scale folds.
* :class:`NeoHookean`: :math:`\psi = \tfrac{\beta}{2}(\operatorname{tr} C - 2 - \ln\det C)
  + \tfrac{\alpha}{4}(\det C - 1 - \ln\det C)`, polyconvex (elliptic at every stretch), infinite
  where a triangle degenerates, equal to St Venant–Kirchhoff to second order in the strain.

Both bend by the same quadratic form.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np


def norm2(M, alpha, beta):
    """(alpha/2) (tr M)^2 + beta tr(M^2): the St Venant–Kirchhoff quadratic form."""
    tr = M[0, 0] + M[1, 1]
    return 0.5 * alpha * tr * tr + beta * jnp.sum(M * M.T)


def _trace_and_root(C):
    """tr C and r = √(tr²/4 − det C) of C = ā⁻¹a (m, 2, 2), whose eigenvalues are λ² = tr/2 ∓ r: C is
    not symmetric, but its eigenvalues (of a v = λ² ā v) are real and positive."""
    tr, det = C[:, 0, 0] + C[:, 1, 1], C[:, 0, 0] * C[:, 1, 1] - C[:, 0, 1] * C[:, 1, 0]
    return tr, np.sqrt(np.maximum(0.25 * tr * tr - det, 0.0))


class StVenantKirchhoff:
    """ψ(C) = ¼ ‖C − I‖² per target area and thickness; bending ‖M‖² (module docstring)."""

    name = "svk"

    @staticmethod
    def membrane(C, alpha, beta):
        return 0.25 * norm2(C - jnp.eye(2), alpha, beta)

    bending = staticmethod(norm2)

    @staticmethod
    def ellipticity_margin(C, alpha, beta) -> np.ndarray:
        r"""Smallest in-plane acoustic eigenvalue at C (m, 2, 2), over β, per element; negative where
        the law is not elliptic. With F = diag(λ1, λ2) (C's eigenvalues λ²) the acoustic tensor is

        .. math:: A(n) = (\alpha + \beta) (F n)(F n)^T + \beta F^2
                  + \big(\tfrac{\alpha}{2}(\lambda_1^2 + \lambda_2^2 - 2) + \beta\, n^T (F^2 - I) n\big) I,

        minimised over 91 directions n in a quarter turn (the law is isotropic).
        """
        tr, root = _trace_and_root(C)
        lam2 = np.stack([0.5 * tr - root, 0.5 * tr + root], axis=1)
        F = np.sqrt(np.clip(lam2, 0.0, None))
        phi = np.linspace(0.0, 0.5 * np.pi, 91)
        n = np.stack([np.cos(phi), np.sin(phi)], axis=1)                        # (d, 2)
        Fn = F[:, None, :] * n[None]                                            # (m, d, 2)
        shift = 0.5 * alpha * (lam2.sum(axis=1) - 2.0)[:, None] + beta * (n[None] ** 2 * (lam2[:, None] - 1.0)).sum(-1)
        A = (alpha + beta) * Fn[..., :, None] * Fn[..., None, :]
        A = A + beta * (lam2[:, None, :, None] * np.eye(2)) + shift[..., None, None] * np.eye(2)
        tr = A[..., 0, 0] + A[..., 1, 1]
        det = A[..., 0, 0] * A[..., 1, 1] - A[..., 0, 1] * A[..., 1, 0]
        lowest = 0.5 * tr - np.sqrt(np.maximum(0.25 * tr * tr - det, 0.0))
        return lowest.min(axis=1) / beta

    @classmethod
    def non_elliptic(cls, C, alpha, beta) -> np.ndarray:
        r"""``ellipticity_margin(C) < 0`` (bool per element), evaluated in full only where the bound

        .. math:: A(n) \succeq \big(\beta (2\lambda_1^2 - 1) + \tfrac{\alpha}{2}(\lambda_1^2 + \lambda_2^2 - 2)\big) I

        (exact under equibiaxial compression) is negative.
        """
        tr, root = _trace_and_root(C)
        smallest = 0.5 * tr - root
        out = np.zeros(len(C), bool)
        bound = beta * (2.0 * smallest - 1.0) + 0.5 * alpha * (tr - 2.0)
        doubtful = np.flatnonzero(bound < 0.0)
        out[doubtful] = cls.ellipticity_margin(C[doubtful], alpha, beta) < 0
        return out


class NeoHookean:
    """ψ(C) = (β/2)(tr C − 2 − ln det C) + (α/4)(det C − 1 − ln det C); bending ‖M‖² (module docstring).

    Not finite where det C ≤ 0 (a degenerate triangle): Newton's line search rejects such steps.
    """

    name = "neo-hookean"

    @staticmethod
    def membrane(C, alpha, beta):
        det = C[0, 0] * C[1, 1] - C[0, 1] * C[1, 0]
        log_det = jnp.log(det)
        return 0.5 * beta * (C[0, 0] + C[1, 1] - 2.0 - log_det) + 0.25 * alpha * (det - 1.0 - log_det)

    bending = staticmethod(norm2)

    @staticmethod
    def ellipticity_margin(C, alpha, beta) -> np.ndarray:
        """+inf per element: polyconvex, elliptic at every stretch."""
        return np.full(len(C), np.inf)

    @staticmethod
    def non_elliptic(C, alpha, beta) -> np.ndarray:
        return np.zeros(len(C), bool)


#: the membrane laws by the name :class:`Material` takes
MEMBRANE_LAWS = {law.name: law for law in (StVenantKirchhoff, NeoHookean)}


def membrane_law(name: str):
    """The law class of a name in :data:`MEMBRANE_LAWS` (ValueError naming the choices otherwise)."""
    if name not in MEMBRANE_LAWS:
        raise ValueError(f"membrane law must be one of {tuple(MEMBRANE_LAWS)}, got {name!r}")
    return MEMBRANE_LAWS[name]


@dataclass(frozen=True)
class Material:
    """Isotropic material: Young's modulus E (energy unit), Poisson ratio nu and the membrane law.

    law : "svk" (:class:`StVenantKirchhoff`) or "neo-hookean" (:class:`NeoHookean`: the same at
    small strain, elliptic under any compression).

    The default ν = 0.3 is the engineering benchmarks' value; the paper's cell sheets use ν = 0.5
    (docs/theory.md), the default of the scenes and of the coupled model.
    """

    E: float = 1.0
    nu: float = 0.3
    law: str = "svk"

    def __post_init__(self):
        for name in ("E", "nu"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
                raise ValueError(f"{name} must be a number, got {v!r}")
        if not (np.isfinite(self.E) and self.E > 0):
            raise ValueError(f"Young's modulus E must be > 0, got {self.E}")
        if not (-1.0 < self.nu <= 0.5):
            raise ValueError(f"Poisson ratio nu must be in (-1, 0.5], got {self.nu}")
        membrane_law(self.law)

    @property
    def membrane_law(self):
        """The law class (:class:`StVenantKirchhoff` or :class:`NeoHookean`)."""
        return MEMBRANE_LAWS[self.law]

    @property
    def alpha(self) -> float:
        """α = E ν / (1 − ν²)."""
        return self.E * self.nu / (1.0 - self.nu**2)

    @property
    def beta(self) -> float:
        """β = E / (2 (1 + ν))."""
        return self.E / (2.0 * (1.0 + self.nu))

    def ellipticity_margin(self, C) -> np.ndarray:
        """The law's smallest in-plane acoustic eigenvalue at C = ā⁻¹a, over β (per element); negative
        where the membrane is not elliptic (a plane wave of in-plane displacement lowers the energy,
        the mesh scale first). Out-of-plane waves, wrinkles, are the bending term's and not counted.

        >>> float(Material(nu=0.5).ellipticity_margin(np.eye(2)[None] * 0.7)[0]) < 0     # λ = 0.84
        True
        """
        return self.membrane_law.ellipticity_margin(np.asarray(C, dtype=float).reshape(-1, 2, 2), self.alpha, self.beta)

    def non_elliptic(self, C) -> np.ndarray:
        """``ellipticity_margin(C) < 0`` (bool per element) by the law's cheap bound first: the check for
        every step of a run.

        >>> Material(nu=0.5).non_elliptic(np.stack([np.eye(2) * 0.7, np.eye(2) * 0.8])).tolist()
        [True, False]
        """
        return self.membrane_law.non_elliptic(np.asarray(C, dtype=float).reshape(-1, 2, 2), self.alpha, self.beta)

    @property
    def svk_ellipticity_stretch(self) -> float:
        r"""Principal stretch (current/target) below which the St Venant–Kirchhoff membrane loses
        ellipticity under equibiaxial compression: :math:`\sqrt{(\alpha + \beta)/(\alpha + 2\beta)}`,
        where a shear wave's second variation :math:`2(\alpha + \beta)(\lambda^2 - 1)\lambda^2|a|^2
        + 2\beta\lambda^4|a|^2` vanishes: a material instability of the law, not a buckling.

        >>> round(Material(nu=0.5).svk_ellipticity_stretch, 4)     # √(3/4)
        0.866
        """
        return math.sqrt((self.alpha + self.beta) / (self.alpha + 2.0 * self.beta))

    def bending_stiffness(self, h: float) -> float:
        """B = E h³ / (12 (1 − ν²))."""
        return self.E * h**3 / (12.0 * (1.0 - self.nu**2))
