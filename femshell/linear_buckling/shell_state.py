r"""Linear buckling of any shell state: flat or curved, loaded or grown, free or supported.

The method and its equations: docs/guide/continuation.md, "Linear buckling".

At an equilibrium u₀ of the shell at parameter p₀ (the load factor λ of Π = U − λ W, or whatever
defines a growing rest state), the Hessian along the equilibrium path u₀(p) is expanded to first order,

.. math:: K(p_0 + \mu) \approx K_0 + \mu K_1, \qquad
          K_1 = \frac{dK}{dp} = \frac{\partial K}{\partial u}\,\dot u_0 + \frac{\partial K}{\partial p},
          \qquad K_0\,\dot u_0 = -\frac{\partial r}{\partial p},

and the load increments μ at which it turns singular solve the generalised eigenproblem
:math:`K_0 \varphi = -\mu K_1 \varphi`. :math:`\dot u_0` (the state's change along the path) comes from one
linear solve, :math:`K_1` from a central difference of the shell's own Hessian (exact derivatives)
along :math:`(\dot u_0, 1)`: the membrane energy of the St Venant–Kirchhoff law and a follower pressure's
work are polynomials in the positions whose Hessians the difference reproduces to round-off. From a
stress-free state this is the classical linear buckling analysis (prestress and initial-displacement
stiffness of the linear pre-buckling state); from a prestressed one its consistent update.

Rigid motions allowed by the supports are deflated, not pinned (:mod:`.deflation`): the pencil is
solved on the orthogonal complement of the rigid motions Z at u₀. Z moves along the path
(K(p) Z(p) = 0 gives K₁ Z = −K₀ Ż), so K₁ does not annihilate it; the rigid-compatible
K̃₁ = K₁ + K₀ Ż Zᵀ + Z Żᵀ K₀ (the first-order congruence that carries Z along) does, and equals K₁ on
the orthogonal complement. The eigenvalues are therefore those of (K₀, K̃₁) on any complement of Z,
a statically determinate pin set included; pins with K₁ itself shift them at first order in the
non-rigid part of Ż. A model built with rigid-body pins (``ShellModel(remove_rigid_modes=None)`` on a
free shell) is solved without them (:meth:`~femshell.shell.ShellModel.rigid_pins_released`).

Eigen solver: ARPACK (``scipy.sparse.linalg.eigsh``) with every inverse a factorisation of
:mod:`femshell.solvers.linear`. Without a target: the largest 1/μ of :math:`-K_1\varphi = \tfrac1\mu K_0\varphi`
(shift-invert about μ = 0), i.e. the smallest positive μ; with a target p_t: buckling mode
shift-invert about μ_t = p_t − p₀, the k values of μ nearest it, and the inertia of
:math:`K_0 + \mu_t K_1` counts the eigenvalues between 0 and μ_t. K₀ must be positive definite on the
complement (a stable state): the eigenproblem then is a symmetric-definite one. Its inner product is
K₀ + s Z Zᵀ, definite on the whole space, and its K₁ is P K₁ P (P the projector off Z): the rigid
motions sit at 1/μ = 0 instead of in a null space that the solver's norm cannot see (:mod:`.deflation`).

Example
-------
>>> from femshell.mesh import disk
>>> from femshell.shell import ShellModel, Material, Clamped, uniform_growth
>>> from femshell.solvers.parameters import GrowthParameter
>>> m = disk(1.0, edge_length=0.12)
>>> model = ShellModel(m, Material(1.0, 0.3), uniform_growth(m.points, m.triangles, 0.01, 0.0), [Clamped("outer")])
>>> growth = GrowthParameter(model, lambda g: uniform_growth(m.points, m.triangles, 0.01, g), parameter_scale=1e-4)
>>> growth.set_parameter(0.0)
>>> res = shell_buckling_loads(growth, model.initial_unknowns(), k=2)
>>> k2 = res.parameters[0] * 12 * 1.3 / 0.01**2          # clamped disk: k² = 14.68 (coarse mesh: 3 %)
>>> bool(abs(k2 / 14.682 - 1) < 0.03)
True
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse.linalg as spla

from .._checks import integer
from .deflation import DeflatedInverse, lifted, remove_rigid_part, rigid_motions

#: eigenpairs with a larger relative residual ‖φ + μ K₀⁻¹K₁φ‖_K₀ / ‖φ‖_K₀ are dropped: ARPACK's Ritz pairs
#: when no positive eigenvalue exists have residuals of order 1; a converged pair's eigenvalue is
#: accurate to about the residual squared (within a tight cluster the vectors are less so)
RESIDUAL_LIMIT = 1e-3

__all__ = ["shell_buckling_loads", "ShellBuckling", "buckling_pencil", "BucklingPencil"]


@dataclass
class ShellBuckling:
    """Linear buckling loads and modes of a shell state (:func:`shell_buckling_loads`).

    ``parameters`` (k,) the critical parameter values p₀ + μ, ascending; ``increments`` the μ;
    ``modes`` (n_total, k) directions in the model's full unknowns q = [x.ravel(), θ] (zero where
    fixed), rigid part removed, scaled to a largest vertex displacement of 1; ``model`` the model;
    ``p0`` the state's parameter; ``n_between`` the number of eigenvalues between 0 and the target's
    increment (None without a target or an inertia); ``info`` diagnostics.
    """

    parameters: np.ndarray
    increments: np.ndarray
    modes: np.ndarray
    model: object
    p0: float
    n_between: int | None = None
    info: dict = field(default_factory=dict)

    def displacements(self, i: int) -> np.ndarray:
        """Vertex displacements (n, 3) of mode i."""
        n = self.model.mesh.n_vertices
        return self.modes[: 3 * n, i].reshape(n, 3)


class _Path:
    """The parameter p of a problem: ``set(p)``, ∂r/∂p and the parameter's scale.

    A ShellModel: p is its load factor, ∂r/∂p = −∂W/∂u exactly. Else a parametrized problem with
    ``model``, ``set_parameter(p)`` and ``parameter`` (:mod:`femshell.solvers.parameters`): its own
    ``parameter_derivative`` where it has one, else a central difference of the gradient in p with step
    ``fd_step`` max(|p₀|, ``parameter_scale``).
    """

    def __init__(self, problem):
        self.problem = problem
        self.model = getattr(problem, "model", problem)
        if not all(hasattr(self.model, need) for need in ("hessian", "gradient", "rigid_pins_released")):
            raise TypeError(f"problem must be a ShellModel or a parametrized problem of one (LoadParameter, "
                            f"GrowthParameter), got {type(problem).__name__}")
        self.scale = float(getattr(problem, "parameter_scale", 1.0))
        self.fd_step = float(getattr(problem, "fd_step", 1e-6))
        if problem is self.model:
            if not self.model.loads:
                raise ValueError("the model has no loads, so its load factor changes nothing: give a "
                                 "GrowthParameter for a growth path")
            self.p0 = float(self.model.load_factor)
        else:
            if problem.parameter is None:
                raise ValueError(f"the {type(problem).__name__} has no parameter value yet: call set_parameter(p) "
                                 "with the parameter of the state first")
            self.p0 = float(problem.parameter)

    def set(self, p):
        if self.problem is self.model:
            self.model.load_factor = float(p)
        else:
            self.problem.set_parameter(float(p))

    def parameter_derivative(self, u):
        """∂r/∂p at (u, p₀)."""
        if self.problem is self.model:
            return -self.model.load_gradient(u)
        if hasattr(self.problem, "parameter_derivative"):
            return self.problem.parameter_derivative(u)
        step = self.fd_step * max(abs(self.p0), self.scale)
        self.set(self.p0 + step)
        gp = self.model.gradient(u)
        self.set(self.p0 - step)
        gm = self.model.gradient(u)
        self.set(self.p0)
        return (gp - gm) / (2.0 * step)


@dataclass
class BucklingPencil:
    """The linearised problem at a state (:func:`buckling_pencil`): K₀ = K(u₀), K₁ = dK/dp along the
    path (sparse, over ``model``'s free unknowns), the rigid motions Z (orthonormal columns) and their
    rate Ż along the path, the state's rate u̇₀ = du₀/dp, the mask ``free`` of the model's unknowns they
    are over (its rigid-body pins released), the ``model``, the state ``u`` over them and ``p0``.
    ``rigid_compatible_K1(x)`` applies K̃₁ = K₁ + K₀ Ż Zᵀ + Z Żᵀ K₀, which annihilates Z (module
    docstring): the pencil (K₀, K̃₁) has the same eigenvalues on every complement of Z."""

    K0: object
    K1: object
    Z: np.ndarray
    Z_rate: np.ndarray
    du_dp: np.ndarray
    free: np.ndarray
    model: object
    u: np.ndarray
    p0: float
    info: dict = field(default_factory=dict)

    def rigid_compatible_K1(self, x):
        K0Zr = self.K0 @ self.Z_rate
        return self.K1 @ x + K0Zr @ (self.Z.T @ x) + self.Z @ (K0Zr.T @ x)


def buckling_pencil(problem, u, *, fd_displacement: float = 0.05, equilibrium_rtol: float = 1e-6,
                    backend: str = "auto") -> BucklingPencil:
    """K₀, K₁ = dK/dp, the rigid motions and their rate at the equilibrium ``u`` (module docstring).

    Arguments as :func:`shell_buckling_loads`; the matrices are over the free unknowns of the model
    with its rigid-body pins released (``pencil.free``). ValueError when u is not an equilibrium, when
    the load has a resultant the supports do not hold, or when the state is not stable (K₀ has
    negative eigenvalues on the complement of the rigid motions).
    """
    if not (isinstance(fd_displacement, (int, float)) and 1e-8 <= fd_displacement <= 1.0):
        raise ValueError(f"fd_displacement must be a number in [1e-8, 1], got {fd_displacement!r}")
    path = _Path(problem)
    model = path.model
    u = np.asarray(u, dtype=float)
    if u.shape != (model.n_free,) or not np.all(np.isfinite(u)):
        raise ValueError(f"u must be a finite vector of the model's {model.n_free} free unknowns, got shape {u.shape}")
    q = model.full(u)
    info = {}
    with model.rigid_pins_released():
        ut = q[model.free]
        info["n_free"] = model.n_free
        try:
            Z = rigid_motions(model, ut)
            info["rigid_motions"] = Z.shape[1]
            g_p = path.parameter_derivative(ut)
            K0 = model.hessian(ut)
            _check_equilibrium(model, ut, K0, g_p, Z, path, equilibrium_rtol, info)
            inv0 = DeflatedInverse(K0, Z, backend)
            try:
                _check_stable(inv0, info)
                v = inv0(-g_p)                                   # du₀/dp on the complement of Z
            finally:
                inv0.free()
            _, Z_rate = rigid_motions(model, ut, v)
            K1 = _hessian_derivative(path, ut, v, fd_displacement, info)
        finally:
            path.set(path.p0)
        free = model.free.copy()
    return BucklingPencil(K0=K0, K1=K1, Z=Z, Z_rate=Z_rate, du_dp=v, free=free, model=model, u=ut, p0=path.p0,
                          info=info)


def shell_buckling_loads(problem, u, k: int = 6, *, target: float | None = None, fd_displacement: float = 0.05,
                         equilibrium_rtol: float = 1e-6, backend: str = "auto", tol: float = 1e-10,
                         extra: int = 4) -> ShellBuckling:
    """Linear buckling parameters and modes of the equilibrium ``u`` (module docstring).

    Parameters
    ----------
    problem : ShellModel, or a parametrized problem of one
        A ShellModel: the parameter is its load factor (Π = U − λ W), at ``model.load_factor``. A
        :class:`~femshell.solvers.parameters.LoadParameter`, a
        :class:`~femshell.solvers.parameters.GrowthParameter` (``rest_of(p)``) or any object with
        ``model``, ``set_parameter(p)`` and ``parameter``: its parameter, at its current value. Both are
        left as they were.
    u : the equilibrium's free unknowns in ``problem``'s model (with or without its rigid-body pins).
    k : number of eigenvalues wanted (the smallest positive ones, or the nearest to ``target``).
    target : parameter value p_t to search around (shift-invert), or None for the smallest positive.
    fd_displacement : the central difference of the Hessian moves the state by this fraction of the mean
        thickness (largest vertex displacement), and the parameter by at most 0.1 max(|p₀|, its scale).
    equilibrium_rtol : largest ‖r(u)‖ relative to ‖∂r/∂p‖ (max(|p₀|, scale)) and to the internal forces.
    backend, tol, extra : factorisation back-end (:func:`femshell.solvers.linear.factorize`), ARPACK's
        tolerance, extra Lanczos vectors asked beyond k.

    Returns
    -------
    ShellBuckling. Fewer than k values when fewer positive ones exist (no ``target``); eigenpairs whose
    residual ‖φ + μ K₀⁻¹K₁φ‖ exceeds ``RESIDUAL_LIMIT`` ‖φ‖ (energy norms; ARPACK's when no positive
    value exists) are dropped and counted in ``info["dropped"]``. ValueError as :func:`buckling_pencil`.
    """
    t0 = time.perf_counter()
    k, extra = integer("k", k, 1), integer("extra", extra, 0)
    pencil = buckling_pencil(problem, u, fd_displacement=fd_displacement, equilibrium_rtol=equilibrium_rtol,
                             backend=backend)
    K0, K1, Z, model, info = pencil.K0, pencil.K1, pencil.Z, pencil.model, pencil.info
    inv0 = DeflatedInverse(K0, Z, backend)
    try:
        if target is None:
            mu, X = _smallest_positive(K0, K1, inv0, Z, k, extra, tol)
            n_between = None
        else:
            mu, X, n_between = _nearest(K0, K1, Z, float(target) - pencil.p0, k, extra, tol, backend)
        X = remove_rigid_part(X, Z)
        # in the energy norm: ‖φ + μ K₀⁻¹K₁φ‖_K₀ / ‖φ‖_K₀ on the complement of Z
        R = X + inv0(K1 @ X) * mu if len(mu) else X
        residual = np.sqrt(np.abs(np.einsum("ik,ik->k", R, K0 @ R)) /
                           np.maximum(np.einsum("ik,ik->k", X, K0 @ X), 1e-300))
    finally:
        inv0.free()
    good = residual <= RESIDUAL_LIMIT
    info["dropped"] = int((~good).sum())
    info["residuals"] = residual[good].tolist()
    mu, X = mu[good], X[:, good]
    modes = np.zeros((model.n_total, len(mu)))
    modes[pencil.free] = X
    n = model.mesh.n_vertices
    size = np.linalg.norm(modes[: 3 * n].reshape(n, 3, -1), axis=1).max(axis=0) if len(mu) else np.ones(0)
    modes /= np.where(size > 0, size, 1.0)
    info["total_s"] = time.perf_counter() - t0
    return ShellBuckling(parameters=pencil.p0 + mu, increments=mu, modes=modes, model=model, p0=pencil.p0,
                         n_between=n_between, info=info)


def _check_equilibrium(model, u, K0, g_p, Z, path, rtol, info):
    """u an equilibrium (‖r‖ small against the load, the internal forces and the round-off floor
    ε √n max|K| max|x| of a residual) and ∂r/∂p without a part along the free rigid motions."""
    r = model.gradient(u)
    load = np.linalg.norm(g_p)
    if load == 0:
        raise ValueError("the parameter does not change the residual at this state (∂r/∂p = 0): nothing buckles")
    floor = np.finfo(float).eps * np.sqrt(len(u)) * abs(K0).max() * np.abs(model.positions(u)).max() / rtol
    scale = max(load * max(abs(path.p0), path.scale), np.linalg.norm(r + path.p0 * g_p), floor)
    info["residual"] = float(np.linalg.norm(r) / scale)
    if info["residual"] > rtol:
        raise ValueError(f"u is not an equilibrium at parameter {path.p0:.6g}: relative residual "
                         f"{info['residual']:.3g} > {rtol:g} (solve it first, e.g. femshell.solvers.newton)")
    if Z.shape[1]:
        resultant = float(np.linalg.norm(Z.T @ g_p) / load)
        info["rigid_resultant"] = resultant
        if resultant > 1e-8:
            raise ValueError(f"the load changes with the parameter by a net force or moment that no support holds "
                             f"(relative {resultant:.3g}): a free shell needs a self-equilibrated load (a closed "
                             "surface under pressure, growth) or supports")


def _check_stable(inv0, info):
    inertia = inv0.inertia
    info["inertia"] = inertia
    if inertia is not None and (inertia[1] or inertia[2]):
        raise ValueError(f"the state is not stable: its Hessian has {inertia[1]} negative and {inertia[2]} zero "
                         "eigenvalues besides the rigid motions, so linear buckling about it has no meaning "
                         "(it has buckled already; follow the branch by continuation)")


def _hessian_derivative(path, u, v, fd_displacement, info):
    """K₁ = dK/dp along (v, 1), central difference: (K(u + εv, p₀ + ε) − K(u − εv, p₀ − ε)) / 2ε."""
    model = path.model
    n = model.mesh.n_vertices
    vx = model.mode_displacements(v)
    largest = float(np.linalg.norm(vx, axis=1).max()) if n else 0.0
    thickness = float(np.mean(model.rest.thickness))
    eps = 0.1 * max(abs(path.p0), path.scale)
    if largest > 0:
        eps = min(eps, fd_displacement * thickness / largest)
    info["fd_parameter_step"] = eps
    path.set(path.p0 + eps)
    Kp = model.hessian(u + eps * v)
    path.set(path.p0 - eps)
    Km = model.hessian(u - eps * v)
    path.set(path.p0)
    return ((Kp - Km) / (2.0 * eps)).tocsr()


def _start(n, Z):
    """A fixed ARPACK start vector on the complement of Z (reproducible runs)."""
    return remove_rigid_part(np.random.default_rng(12345).standard_normal(n), Z)


def _geometric(K1, Z):
    """x ↦ −P K₁ P x (P the projector off Z): symmetric, and zero on the rigid motions."""
    return lambda x: remove_rigid_part(-(K1 @ remove_rigid_part(x, Z)), Z)


def _smallest_positive(K0, K1, inv0, Z, k, extra, tol):
    """The smallest positive μ: the largest λ = 1/μ of −P K₁ P φ = λ (K₀ + s Z Zᵀ) φ (the rigid motions
    lifted to λ = 0; module docstring of :mod:`.deflation`)."""
    n, s = K0.shape[0], inv0.scale
    nev = min(k + extra, n - Z.shape[1] - 2)
    B = spla.LinearOperator((n, n), matvec=_geometric(K1, Z), dtype=float)
    M = spla.LinearOperator((n, n), matvec=lifted(K0, Z, s), dtype=float)
    lam, X = spla.eigsh(B, k=nev, M=M, Minv=spla.LinearOperator((n, n), matvec=lambda b: inv0.lifted(b, s),
                                                                 dtype=float),
                        which="LA", tol=tol, v0=_start(n, Z), ncv=min(n - Z.shape[1] - 1, max(2 * nev + 1, 20)))
    positive = lam > 1e-12 * max(np.abs(lam).max(), 1e-300)
    lam, X = lam[positive], X[:, positive]
    order = np.argsort(-lam)[:k]
    return 1.0 / lam[order], X[:, order]


def _nearest(K0, K1, Z, shift, k, extra, tol, backend):
    """The μ nearest ``shift``: ARPACK buckling mode for (K₀ + s Z Zᵀ) φ = μ (−P K₁ P) φ, OPinv =
    (K₀ + s Z Zᵀ + shift P K₁ P)⁻¹ (the rigid motions lifted to μ = ∞)."""
    n = K0.shape[0]
    inv = DeflatedInverse(K0 + shift * K1, Z, backend)
    s = float(np.abs(K0.diagonal()).mean()) or 1.0
    try:
        nev = min(k + extra, n - Z.shape[1] - 2)
        B = spla.LinearOperator((n, n), matvec=_geometric(K1, Z), dtype=float)
        A = spla.LinearOperator((n, n), matvec=lifted(K0, Z, s), dtype=float)
        mu, X = spla.eigsh(A, k=nev, M=B, sigma=shift, mode="buckling", tol=tol, v0=_start(n, Z),
                           OPinv=spla.LinearOperator((n, n), matvec=lambda b: inv.lifted(b, s), dtype=float),
                           ncv=min(n - Z.shape[1] - 1, max(2 * nev + 1, 20)))
        n_between = None if inv.inertia is None else int(inv.inertia[1])
    finally:
        inv.free()
    order = np.argsort(np.abs(mu - shift))[:k]
    order = order[np.argsort(mu[order])]
    return mu[order], X[:, order], n_between
