r"""The disk of the seed paper's wrinkling test: its mesh, rest state and problem, and its states moved between disks.

A free flat disk of radius R1 and thickness h (E = 1, ν = 0.5) whose inner circle r < R2 grows isotropically by
the stretch s = 1 + ε: target metric (1 + ε)² ā₀ and thickness h/(1 + ε)² (volume conserving) there, nothing
changes outside, flat target curvature (theory §1.6; Zakharov & Dasbiswas, section 4). Mesh:
:func:`femshell.linear_buckling._disk_mesh` (gmsh, the circle r = R2 in the mesh edges); rigid motions are removed
by six pinned position components (:class:`~femshell.shell.ShellModel` for a shell without supports).

The problem has no length of its own: Π(s x, s h) = s³ Π(x, h), so a disk's states depend on R2/h, R1/R2 and ε
only. :meth:`Disk.radius_problem` uses it to sweep R2 on one mesh, :func:`magnified` to give a scaled twin its
problem's state (:func:`twins`), and :meth:`Disk.carried` moves a state onto another mesh. A state counts as a
result when it is an equilibrium (|∇Π| ≤ ``EQUILIBRIUM_RTOL`` of the flat disk's), stable (no negative eigenvalue
of the constrained Hessian) and resolved (no mid-edge normal turned by ``FOLD_LIMIT_DEG`` or more):
:meth:`Disk.final_check`.
"""

from __future__ import annotations

import math

import numpy as np

from ..._checks import finite
from ...linear_buckling import _disk_mesh
from ...mesh.interpolation import interpolate_p1
from ...mesh.surface import SurfaceMesh
from ...shell import Material, RestState, ShellModel
from ...shell.rest_state import metric
from ...solvers.continuation import GrowthParameter
from ...solvers.linear import LinearSolverError, factorize
from . import measures

EPS_END = 0.5          # the paper's Λmax/Λmin − 1
NU = 0.5
#: R1 / R2 of the free edge where R2 > 20 / OUTER_FACTOR (:func:`outer_radius`; the levels set their own)
OUTER_FACTOR = 5.0
#: a final state is an equilibrium when |∇Π(u)| <= this · |∇Π| of the flat disk at the same ε (Newton
#: stops at 1e-9 of each step's own imbalance; a state whose Newton failed sits near 5e-3)
EQUILIBRIUM_RTOL = 1e-6


def outer_radius(R2, factor=OUTER_FACTOR):
    """R1 = max(20, ``factor`` · R2): the free edge ≥ ``factor`` · R2 (issue 4: at least 5) and ≥ 10 h (h = 2)
    away from the grown region."""
    return max(20.0, factor * R2)


def eps_scale(h, R2):
    """A scale of the critical growth strain for the arclength norm (not a result): a third of the
    clamped-plate value k² h²/(12 (1 + ν) R2²), k² = 14.68 (the elastic rim is softer than a clamp),
    at most EPS_END/5 (steps of at most ~0.1 in ε: crossings come one at a time, each located cheaply)."""
    return min(14.682 * h * h / (12.0 * (1.0 + NU) * R2 * R2) / 3.0, EPS_END / 5.0)


def svk_ellipticity_stretch(nu=NU):
    """Stretch below which the SVK membrane loses ellipticity (:attr:`Material.svk_ellipticity_stretch`),
    √(3/4) = 0.866 for ν = 0.5."""
    return Material(nu=nu).svk_ellipticity_stretch


class Disk:
    """The disk model of one case: mesh, ShellModel, the ε-parametrised rest state, the problem.

    ``rest_of(eps)``: target metric (1 + ε)² ā₀ and thickness h/(1 + ε)² for elements whose
    centroid is inside r < R2, ā₀ and h outside; flat target curvature.
    """

    def __init__(self, h, R2, resolution, R1=None, law="svk", refine_inside=False):
        self.h, self.R2 = float(h), float(R2)
        self.R1 = outer_radius(R2) if R1 is None else float(R1)
        p2, tri = _disk_mesh(self.R1, self.R2, resolution, refine_inside=refine_inside)
        self.points = np.column_stack([p2, np.zeros(len(p2))])
        self.triangles = tri
        self.mesh = SurfaceMesh(self.points, tri)
        self.a0 = metric(self.points, tri)
        c = self.points[tri].mean(axis=1)
        self.inside = np.hypot(c[:, 0], c[:, 1]) < self.R2
        self.model = ShellModel(self.mesh, Material(1.0, NU, law=law), self.rest_of(0.0))
        self.problem = GrowthParameter(self.model, self.rest_of, parameter_scale=eps_scale(h, R2),
                                       length_scale=self.h)
        self._plane = np.column_stack([np.ones(len(p2)), p2])

    @property
    def n_vertices(self):
        return self.mesh.n_vertices

    def rest_of(self, eps, h=None):
        """Rest state at growth strain ε (class docstring); ``h``: the ungrown thickness (default the disk's)."""
        h = self.h if h is None else h
        s2 = np.where(self.inside, (1.0 + eps) ** 2, 1.0)
        thick = np.where(self.inside, h / (1.0 + eps) ** 2, h)
        return RestState(self.a0 * s2[:, None, None], np.zeros_like(self.a0), thick)

    def radius_problem(self, eps=EPS_END):
        r"""The inner radius R2 as a continuation parameter at growth strain ``eps``, on this mesh (no remeshing).

        A disk has no length of its own, Π(s x, s h) = s³ Π(x, h) (tests/test_validation_cases.py), so the disk
        of inner radius R2' = s R2, outer radius s R1 and thickness h is this mesh's disk of thickness h/s
        magnified by s. The parameter λ = R2' sets the thickness h R2/R2' on this mesh; a state u of it is the
        disk R2' with positions s times those of u and energy s³ Π(u) (:meth:`radius_energy`). R1/R2 stays fixed
        (the full level's R1 = 10 R2). A :class:`~femshell.solvers.continuation.GrowthParameter` over a
        ShellModel of its own, so :attr:`problem` is not disturbed; arclength scales h (positions), R2/10 (λ).

        >>> d = Disk(2.0, 3.0, 3, R1=20.0)
        >>> p = d.radius_problem()
        >>> p.set_parameter(6.0)
        >>> float(p.model.rest.thickness.max())    # h R2 / R2' outside the grown circle
        1.0
        """
        eps = float(eps)
        R2 = self.R2

        def rest(radius):
            radius = finite("R2", radius, 0.0, lo_open=True, text="(0, inf)")
            return self.rest_of(eps, self.h * R2 / radius)

        model = ShellModel(self.mesh, self.model.material, rest(R2))
        return GrowthParameter(model, rest, parameter_scale=R2 / 10.0, length_scale=self.h)

    def radius_energy(self, problem, u):
        """Energy of the disk of inner radius ``problem.parameter`` (:meth:`radius_problem`) in state u: s³ Π(u)."""
        return float((problem.parameter / self.R2) ** 3 * problem.model.energy(u))

    def carried(self, other, u):
        """State u of the disk ``other`` (another mesh of the same case, or of a case whose R2 scales to this one's)
        as free unknowns of this mesh: its positions, magnified by R2/other.R2, interpolated linearly at this mesh's
        vertices (:func:`~femshell.mesh.interpolation.interpolate_p1`) and moved rigidly onto this mesh's pins, with
        zero edge unknowns (:meth:`~femshell.shell.ShellModel.unknowns_from_positions`). A start for Newton."""
        s = self.R2 / other.R2
        x = interpolate_p1(s * other.points, other.triangles, s * other.model.positions(u), self.points)
        return self.model.unknowns_from_positions(x)

    def _off_plane(self, z):
        """z minus its best-fit plane a + b X + c Y (X, Y reference): a rigid tilt is no wave."""
        return z - self._plane @ np.linalg.lstsq(self._plane, z, rcond=None)[0]

    def deflection(self, u):
        """w: the z of the deformed vertices minus their best-fit plane."""
        return self._off_plane(self.model.positions(u)[:, 2])

    def mode_deflection(self, v):
        """Out-of-plane part of a direction v in the free unknowns (a critical mode), best-fit plane removed."""
        return self._off_plane(self.model.mode_displacements(v)[:, 2])

    def count(self, w):
        """Wrinkles of w on the counting circle (:func:`.measures.wrinkle_count`)."""
        return measures.wrinkle_count(self, w)

    def spectrum(self, w, k_max=16):
        """|ŵ_k|, k = 0..k_max, on the counting circle (:func:`.measures.counting_spectrum`)."""
        return measures.counting_spectrum(self, w, k_max)

    def min_stretch(self, u):
        """Smallest principal stretch √eig(ā⁻¹a) (current over target) of the grown elements."""
        a, _ = self.model.fundamental_forms(u)
        m = np.einsum("eij,ejk->eik", self.model.rest.metric_inverse, a)[self.inside]
        tr, det = m[:, 0, 0] + m[:, 1, 1], m[:, 0, 0] * m[:, 1, 1] - m[:, 0, 1] * m[:, 1, 0]
        return float(np.sqrt(np.min(0.5 * tr - np.sqrt(np.maximum(0.25 * tr * tr - det, 0.0)))))

    def record(self, u):
        w = self.deflection(u)
        return {"w_max": float(np.abs(w).max()), "wrinkles": self.count(w)}

    def azimuthal_power(self, z, radii, k_max=24):
        """|ẑ_k|², k = 0..k_max, summed over the material circles r = radii · R2 (:func:`.measures.azimuthal_power`)."""
        return measures.azimuthal_power(self, z, radii, k_max)

    def rim_mode(self, w, radii=measures.INNER_RIM_RADII, k_max=24):
        """(k, relative amplitude) of the rim's dominant lobes (:func:`.measures.rim_mode`)."""
        return measures.rim_mode(self, w, radii, k_max)

    def mode_wavenumber(self, modes):
        """Dominant azimuthal wavenumber of critical mode(s) (:func:`.measures.mode_wavenumber`)."""
        return measures.mode_wavenumber(self, modes)

    def relative_residual(self, u, eps, problem=None):
        """|∇Π(u)| / |∇Π(flat)| at ε: the imbalance left in u against that of the ungrown shape. ``problem``: the
        parametrised problem whose parameter ``eps`` is (default :attr:`problem`; e.g. :meth:`radius_problem`)."""
        problem = problem or self.problem
        problem.set_parameter(eps)
        model = problem.model
        flat = np.linalg.norm(model.gradient(model.initial_unknowns()))
        return float(np.linalg.norm(model.gradient(u)) / max(flat, 1e-300))

    def final_check(self, u, eps, log=None, problem=None):
        """Whether state u at ε counts as a result (module docstring): a dict of n_negative (None, and
        a line in ``log``, when the Hessian is not finite), residual (:meth:`relative_residual`), over_folded
        (:meth:`~femshell.shell.ShellModel.over_folded_edges`), largest_turn (degrees) and result (a resolved
        stable equilibrium). ``problem``: as for :meth:`relative_residual`."""
        try:
            n_negative = self.n_negative(u, eps, problem)
        except LinearSolverError as exc:     # a collapsed state has no finite Hessian: no result, say why
            n_negative = None
            if log:
                log(f"    stability at {'eps' if problem is None else 'parameter'} = {eps:g} not decided: {exc}")
        residual = self.relative_residual(u, eps, problem)
        over_folded = len(self.model.over_folded_edges(u))
        return dict(n_negative=n_negative, residual=residual, over_folded=over_folded,
                    largest_turn=float(self.model.edge_turning_angles(u).max()),
                    result=n_negative == 0 and residual <= EQUILIBRIUM_RTOL and over_folded == 0)

    def end_state(self, u, log=None):
        """What the rows say of a state u at ε = 0.5: :meth:`final_check`'s numbers with count, rim
        (:meth:`rim_mode`) and energy; a state that is not finite has count and energy None, rim (0, nan),
        residual None and is no result."""
        check = self.final_check(u, EPS_END, log=log)
        energy = float(self.model.energy(u))
        finite = math.isfinite(energy) and math.isfinite(check["residual"]) and bool(np.all(np.isfinite(u)))
        w = self.deflection(u)
        rim = self.rim_mode(w) if finite else (0, math.nan)
        return dict(count=int(self.count(w)) if finite else None, rim=[int(rim[0]), float(rim[1])],
                    energy=energy if finite else None, n_negative=check["n_negative"],
                    residual=check["residual"] if finite else None, over_folded=int(check["over_folded"]),
                    largest_turn=float(check["largest_turn"]), result=bool(finite and check["result"]))

    def n_negative(self, u, eps, problem=None):
        """Negative eigenvalues of the constrained Hessian at (u, ε) (inertia of its LDLᵀ); ``problem``: as for
        :meth:`relative_residual`."""
        problem = problem or self.problem
        problem.set_parameter(eps)
        fac = factorize(problem.model.hessian(u), kind="symmetric_indefinite")
        try:
            return int(fac.inertia[1])
        finally:
            fac.free()



def warm_up():
    """Compile the element kernels and load the linear solver before anything is timed."""
    d = Disk(2.0, 4.5, 3)
    u = d.model.initial_unknowns()
    d.model.energy(u)
    d.model.gradient(u)
    factorize(d.model.hessian(u), kind="symmetric_indefinite").free()



def scaled_problem(case, cfg):
    """(R2/h, R1/R2, resolution) of the (h, R2, resolution) ``case`` on a level ``cfg``: what fixes its states up to
    its scale (module docstring: no length of its own), the mesh included (:func:`_disk_mesh` meshes a disk
    scaled by a power of two alike, to round-off)."""
    h, R2, resolution = case
    return (round(R2 / h, 9), round(outer_radius(R2, cfg["outer_factor"]) / R2, 9), int(resolution))


def twins(cases, cfg):
    """{case: the case it is solved as}: the thinnest case of its :func:`scaled_problem` (itself when it is).

    >>> cfg = {"outer_factor": 10.0}
    >>> twins([(2.0, 16.0, 32), (2.0, 12.0, 24), (0.25, 2.0, 32)], cfg)[(2.0, 16.0, 32)]
    (0.25, 2.0, 32)
    >>> twins([(2.0, 16.0, 32), (2.0, 12.0, 24), (0.25, 2.0, 32)], cfg)[(2.0, 12.0, 24)]
    (2.0, 12.0, 24)
    """
    thinnest = {}
    for c in sorted(cases, key=lambda c: c[0]):
        thinnest.setdefault(scaled_problem(c, cfg), c)
    return {c: thinnest[scaled_problem(c, cfg)] for c in cases}


def _one_mesh_scaled(points, triangles, points_ref, triangles_ref, s):
    """Whether (points, triangles) is the mesh (points_ref, triangles_ref) scaled by s (points to 1e-12 of the
    size)."""
    return (points.shape == points_ref.shape and np.array_equal(triangles, triangles_ref)
            and np.abs(points - s * points_ref).max() <= 1e-12 * float(np.ptp(points, axis=0).max()))


def meshed_alike(case, rep, cfg):
    """Whether :func:`_disk_mesh` meshes the disks of ``case`` and ``rep`` as one mesh scaled: a mesh generator
    that meshes them otherwise makes them two problems."""
    (p, t), (q, r) = (_disk_mesh(outer_radius(c[1], cfg["outer_factor"]), c[1], c[2],
                                 refine_inside=cfg["refine_inside"]) for c in (case, rep))
    return _one_mesh_scaled(p, t, q, r, case[0] / rep[0])


def magnified(d_from, u, d_to):
    """State u of the disk ``d_from`` as a state of ``d_to``, the same disk scaled by s = d_to.h / d_from.h: its
    positions times s, its edge unknowns (dimensionless) as they are; Π scales by s³. A ValueError when d_to's
    mesh or supports are not d_from's scaled by s."""
    s = d_to.h / d_from.h
    a, b = d_from.model, d_to.model
    if not (_one_mesh_scaled(d_to.points, d_to.triangles, d_from.points, d_from.triangles, s)
            and np.array_equal(a.free, b.free)):
        raise ValueError(f"the disks h={d_from.h:g} R2={d_from.R2:g} and h={d_to.h:g} R2={d_to.R2:g} are not one "
                         f"mesh scaled by {s:g}: solve both")
    q = a.full(u)
    q[: 3 * d_from.n_vertices] *= s
    return q[b.free]

