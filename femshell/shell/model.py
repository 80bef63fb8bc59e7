r"""A shell problem: mesh + material + rest state + boundary conditions + loads.

Unknowns are ``q = [x.ravel(), theta]``: vertex positions (3 per vertex) and one
rotation unknown per edge (the tangent of its mid-edge normal's turning angle).
Constrained unknowns are removed; solvers see only the free ones, ``u = q[free]``,
through :meth:`ShellModel.energy`, :meth:`ShellModel.gradient` and
:meth:`ShellModel.hessian`, which return the total potential
:math:`\Pi(u) = U(u) - \lambda W(u)` with load factor :math:`\lambda`
(``model.load_factor``), its gradient and its sparse Hessian.

Example
-------
>>> from femshell.mesh.generators import disk
>>> from femshell.shell import ShellModel, Material, Clamped, uniform_growth
>>> mesh = disk(radius=10, edge_length=1.0)
>>> rest = uniform_growth(mesh.points, mesh.triangles, thickness=0.5, strain=0.01)
>>> model = ShellModel(mesh, Material(E=1, nu=0.3), rest, [Clamped("outer")])
>>> u = model.initial_unknowns()
>>> model.energy(u) > 0
True
"""

from __future__ import annotations

import contextlib
import warnings

import numpy as np

from . import element as el
from .assembly import SparseAssembler
from .boundary import rigid_body_pins
from .materials import Material
from .rest_state import RestState, flat_rest_state


#: a mid-edge normal turned this far (degrees) from its faces marks a fold too sharp for the mesh
#: (:meth:`ShellModel.diagnose`); 90° is the limit the edge unknown approaches as it runs away
FOLD_LIMIT_DEG = 80.0


def _pinned_rigidly(x, pins, target, size):
    """x (n, 3) moved by the rigid motion that gives the six pinned (vertex, component) pairs their values in
    target (:func:`~femshell.shell.boundary.rigid_body_pins`: six equations for the six parameters of the
    motion, solved by least squares from the identity; ValueError when they have no solution)."""
    from scipy.optimize import least_squares     # deferred: scipy.optimize is slow to import, rarely needed
    from scipy.spatial.transform import Rotation

    v, c = np.array(pins).T
    want = target[v, c]

    def moved(p):
        return Rotation.from_rotvec(p[:3]).apply(x) + p[3:]

    fit = least_squares(lambda p: moved(p)[v, c] - want, np.zeros(6), xtol=1e-15, ftol=1e-15, gtol=1e-15)
    if np.abs(fit.fun).max() > 1e-9 * size:
        raise ValueError(f"no rigid motion of the positions meets the six rigid-body pins (left {np.abs(fit.fun).max():.3g}): "
                         "is the state that of this mesh?")
    return moved(fit.x)


def rest_edge_normals(points, topology, face_normals):
    """The mesh's own normal at each edge midpoint (the normal a clamped edge keeps), (n_edges, 3).

    Interior edge: the mean of its two face normals. Boundary edge of face f, whose other two
    edges are interior with mid-edge normals n1, n2: the normal field taken linear over f, with
    its mean (at the centroid) the face normal n_f, gives n = 3 n_f - n1 - n2 at the boundary
    edge's midpoint (then made orthogonal to the edge and unit). The face normal alone would
    be off by the curvature times the distance from centroid to edge, an O(h) error of a
    clamped curved edge (a naturally shaped hemisphere clamped at its equator would keep about
    ten times more bending energy). Exact on a plane. A face with two or three boundary edges (a corner) keeps its face normal.
    """
    t = topology
    ef = t.edge_faces
    out = face_normals[ef[:, 0]].copy()
    inner = ef[:, 1] >= 0
    mid = face_normals[ef[inner, 0]] + face_normals[ef[inner, 1]]
    out[inner] = mid / np.linalg.norm(mid, axis=1)[:, None]
    be = np.flatnonzero(~inner)
    if len(be) == 0:
        return out
    f = ef[be, 0]
    fe = t.face_edges[f]
    others = fe[fe != be[:, None]].reshape(-1, 2)
    nbr = ef[others]                                             # (nb, 2, 2) faces of the other edges
    across = np.where(nbr[..., 0] == f[:, None], nbr[..., 1], nbr[..., 0])
    corner = (across < 0).any(axis=1)
    guess = 3 * face_normals[f] - out[others].sum(axis=1)
    guess[corner] = face_normals[f[corner]]
    tangent = points[t.edges[be, 1]] - points[t.edges[be, 0]]
    tangent /= np.linalg.norm(tangent, axis=1)[:, None]
    guess -= np.sum(guess * tangent, axis=1)[:, None] * tangent
    out[be] = guess / np.linalg.norm(guess, axis=1)[:, None]
    return out


class PrestressWarning(UserWarning):
    """A model whose drawn shape is not stress free in a way that looks unintended: a flat rest state
    (zero target curvature) on a curved mesh."""


class ShellModel:
    """The discrete shell energy (docs/theory.md §2) with exact derivatives (see module docstring).

    Parameters
    ----------
    mesh : SurfaceMesh
        Reference mesh; its points are the initial positions.
    material : Material
    rest : RestState or thickness
        Target metric, curvature and thickness per element; or the thickness (a number or one per
        triangle), and the mesh as drawn is the stress-free shape (:meth:`stress_free_rest_state`; on a
        flat mesh that is :func:`~femshell.shell.flat_rest_state`). A flat rest state (b̄ = 0) on a curved
        mesh is prestressed: it warns (:class:`PrestressWarning`) with the energy at rest.
    boundary_conditions : list
        Objects from :mod:`femshell.shell.boundary`.
    loads : list
        Objects from :mod:`femshell.shell.loads`.
    remove_rigid_modes : bool or None
        Pin six position components (statically determinate) so that a free
        shell has no rigid-body null space. ``None``: only when no boundary
        condition fixes any position.
    hessian_kernel, gradient_kernel : "compiled" or "jax"
        How the element Hessians, and the element energies and gradients, are computed
        (:data:`~femshell.shell.element.ELEMENT_KERNELS`): compiled C (JAX where no C compiler works), or
        the JAX reference; the same to rounding. Settable later as the attributes of the same names.
    """

    def __init__(self, mesh, material: Material, rest: RestState, boundary_conditions=(), loads=(),
                 remove_rigid_modes=None, hessian_kernel="compiled", gradient_kernel="compiled"):
        if not all(hasattr(mesh, k) for k in ("points", "triangles", "topology")):
            raise TypeError(f"mesh must be a SurfaceMesh (see femshell.mesh), got {type(mesh).__name__}")
        if not isinstance(material, Material):
            raise TypeError(f"material must be a Material, got {type(material).__name__}")
        thickness = None
        if not isinstance(rest, RestState):
            if isinstance(rest, (bool, str)) or not isinstance(rest, (int, float, np.integer, np.floating, np.ndarray)):
                raise TypeError(f"rest must be a RestState or a thickness (a number or one per triangle), "
                                f"got {type(rest).__name__}")
            thickness = rest
            rest = flat_rest_state(mesh.points, mesh.triangles, thickness)
        for name, items, method in (("boundary_conditions", boundary_conditions, "apply"), ("loads", loads, "setup")):
            if not isinstance(items, (list, tuple)):
                kind = type(items).__name__
                raise TypeError(f"{name} must be a list, got {kind} (write [{kind}(...)])")
            for item in items:
                if not hasattr(item, method):
                    raise TypeError(f"{name} holds a {type(item).__name__}, not a femshell "
                                    f"{'boundary condition' if method == 'apply' else 'load'}")
        self.mesh = mesh
        self.material = material
        self.hessian_kernel = el.check_element_kernel(hessian_kernel)
        self.gradient_kernel = el.check_element_kernel(gradient_kernel, "gradient_kernel")
        self.topology = t = mesh.topology
        n, ne, m = mesh.n_vertices, t.n_edges, mesh.n_triangles
        if len(rest.metric) != m:
            raise ValueError(f"rest state has {len(rest.metric)} elements, mesh has {m} triangles")
        self.n_total = 3 * n + ne
        self.load_factor = 1.0

        # the checks femshell.mesh.check_mesh makes in full, here the ones whose failure would only
        # show later as a NaN energy or a bending energy of the wrong sign
        if not np.all(np.isfinite(mesh.points)):
            bad = np.flatnonzero(~np.isfinite(mesh.points).all(axis=1))
            raise ValueError(f"mesh points hold NaN or infinity at {len(bad)} vertices (first: {bad[0]})")
        if len(t.inconsistent_edges):
            raise ValueError(f"the mesh's triangles are not consistently oriented ({len(t.inconsistent_edges)} "
                             "interior edges between triangles of opposite orientation): the bending energy "
                             "would change sign across them; fix with femshell.mesh.orient_consistently")
        fixed_pos = np.zeros((n, 3), bool)
        values = mesh.points.copy()
        edge_kind = np.where(t.edge_faces[:, 1] >= 0, el.INTERIOR, el.FREE)
        nf = np.cross(mesh.points[t.triangles[:, 1]] - mesh.points[t.triangles[:, 0]],
                      mesh.points[t.triangles[:, 2]] - mesh.points[t.triangles[:, 0]])
        twice_area = np.linalg.norm(nf, axis=1)
        if not np.all(twice_area > 0):
            bad = np.flatnonzero(~(twice_area > 0))
            raise ValueError(f"{len(bad)} triangles of the mesh have zero area (first: {bad[0]}, vertices "
                             f"{mesh.triangles[bad[0]].tolist()}); see femshell.mesh.check_mesh")
        nf /= twice_area[:, None]
        edge_direction = rest_edge_normals(mesh.points, t, nf)  # what a clamped edge holds
        for bc in boundary_conditions:
            bc.apply(mesh, fixed_pos, values, edge_kind, edge_direction)
        if remove_rigid_modes is None:
            remove_rigid_modes = not fixed_pos.any()
        self.rigid_pins = rigid_body_pins(mesh.points) if remove_rigid_modes else []
        for v, c in self.rigid_pins:
            fixed_pos[v, c] = True
        self.boundary_conditions = list(boundary_conditions)

        # edges whose normal is prescribed have no rotation unknown
        fixed_theta = (edge_kind == el.CLAMPED) | (edge_kind == el.SYMMETRY)
        self.fixed = np.concatenate([fixed_pos.ravel(), fixed_theta])
        self.free = ~self.fixed
        self.q_fixed = np.concatenate([values.ravel(), np.zeros(ne)])
        self.edge_kind = edge_kind

        # element stencils: own vertices, across-edge vertices, edge angles
        opp = np.where(t.face_opposite >= 0, t.face_opposite, t.triangles)  # boundary: harmless stand-in
        self.element_dofs = np.concatenate([
            (3 * t.triangles[:, :, None] + np.arange(3)).reshape(m, 9),
            (3 * opp[:, :, None] + np.arange(3)).reshape(m, 9),
            3 * n + t.face_edges], axis=1)
        self.edge_kind_el = edge_kind[t.face_edges]
        self.edge_direction_el = edge_direction[t.face_edges]
        self.face_edge_sign = t.face_edge_sign.astype(float)
        inner = t.edge_faces[:, 1] >= 0
        n0, n1 = nf[t.edge_faces[inner, 0]], nf[t.edge_faces[inner, 1]]
        #: whether the drawn mesh bends anywhere (a fold between two faces): then b(mesh) ≠ 0
        self.drawn_curved = bool(np.any(np.linalg.norm(np.cross(n0, n1), axis=1) > 1e-10)
                                 or np.any(np.sum(n0 * n1, axis=1) < 0))
        self.set_rest_state(rest)
        if thickness is not None and self.drawn_curved:
            self.set_rest_state(self.stress_free_rest_state())     # the drawn shape is the stress-free one

        self.loads = list(loads)
        for load in self.loads:
            load.setup(self)
        # the unknowns by node (a vertex's three positions, an edge's unknown): the pattern from node pairs
        element_nodes = np.concatenate([t.triangles, opp, n + t.face_edges], axis=1)
        slot = np.concatenate([np.repeat(np.arange(6), 3), 6 + np.arange(3)])
        dof_node = np.concatenate([np.repeat(np.arange(n), 3), n + np.arange(ne)])
        self.assembler_nodes = (element_nodes, slot, dof_node)
        self.assembler = SparseAssembler(self.element_dofs, self.free, nodes=self.assembler_nodes)
        self._load_assemblers = {}
        if thickness is None and self.drawn_curved and not np.any(rest.curvature):
            self._warn_prestress()

    def _warn_prestress(self):
        """A :class:`PrestressWarning` naming the energy the drawn curved shape holds in a flat rest state."""
        mem, bend = self.energy_parts(self.initial_unknowns())
        warnings.warn(f"the rest state is flat (zero curvature b̄, as from flat_rest_state) but the mesh is curved: "
                      f"the shell as drawn is not stress free (strain energy at rest {mem.sum() + bend.sum():.4g}: "
                      f"bending {bend.sum():.4g}, membrane {mem.sum():.4g}). For the drawn shape as the stress-free "
                      "one give the thickness instead of a rest state, ShellModel(mesh, material, thickness, ...), "
                      "or call model.set_rest_state(model.stress_free_rest_state()); to keep this prestress on "
                      "purpose, filter femshell.shell.PrestressWarning", PrestressWarning, stacklevel=3)

    @contextlib.contextmanager
    def rigid_pins_released(self):
        """Within the block this model is without its six rigid-body pins: the unknowns they held are
        free (``free``, ``n_free`` and every vector and matrix over the free unknowns grow by six); the
        pins are back on exit. Nothing else changes (rest state, load factor, conditions, loads).

        For methods that remove the rigid motions another way, such as deflating the null space
        (:func:`femshell.linear_buckling.shell_buckling_loads`). A model without pins is left as it is.
        """
        saved = (self.rigid_pins, self.fixed, self.free, self.assembler, self._load_assemblers)
        if self.rigid_pins:
            if getattr(self, "_released", None) is None:
                fixed = self.fixed.copy()
                for v, c in self.rigid_pins:
                    fixed[3 * v + c] = False
                self._released = (fixed, SparseAssembler(self.element_dofs, ~fixed))
            fixed, assembler = self._released
            self.rigid_pins, self.fixed, self.free = [], fixed, ~fixed
            self.assembler, self._load_assemblers = assembler, {}
        try:
            yield self
        finally:
            self.rigid_pins, self.fixed, self.free, self.assembler, self._load_assemblers = saved

    # ---- rest state -------------------------------------------------------------------------
    def set_rest_state(self, rest: RestState):
        """Replace the targets (growth changes them every step); the pattern stays cached."""
        if len(rest.metric) != self.mesh.n_triangles:
            raise ValueError(f"rest state has {len(rest.metric)} elements, mesh has {self.mesh.n_triangles} triangles")
        self.rest = rest
        self._abar_inv = rest.metric_inverse
        self._bbar = rest.curvature
        self._area = rest.area
        self._hbar = rest.thickness

    # ---- unknown vectors ------------------------------------------------------------------------
    @property
    def n_free(self) -> int:
        return int(self.free.sum())

    def initial_unknowns(self) -> np.ndarray:
        """Free unknowns of the reference configuration (zero edge angles)."""
        return self.q_fixed[self.free].copy()

    def from_edge_angles(self, u: np.ndarray) -> np.ndarray:
        """Free unknowns written with edge *angles* θ (older checkpoints, where
        n_e = cos θ m + sin θ t×m) as this model's edge unknowns tan θ: the same mid-edge normals.

        A ValueError if an angle is at or past ±π/2: that normal pointed away from its faces (a
        spurious state, :mod:`femshell.shell.bending`) and has no counterpart.
        """
        q = self.full(u)
        n_pos = 3 * self.mesh.n_vertices
        angles = q[n_pos:]
        flipped = np.abs(angles) >= 0.5 * np.pi
        if flipped.any():
            raise ValueError(f"{int(flipped.sum())} edge angle(s) at or past ±π/2 (largest {np.abs(angles).max():.3g}): "
                             "those mid-edge normals point away from their faces, a state the current element "
                             "cannot represent; start this run afresh")
        q[n_pos:] = np.tan(angles)
        return q[self.free]

    def unknowns_from_positions(self, x: np.ndarray) -> np.ndarray:
        """Free unknowns of the state with vertex positions x (n, 3) and zero edge unknowns (each mid-edge
        normal the mean of its faces' normals): a start for Newton, e.g. a state carried from another mesh
        (:func:`femshell.mesh.interpolation.interpolate_p1`).

        A shell held only by the six rigid-body pins is first moved rigidly (which changes no energy) so that
        the pinned components take their prescribed values; every other prescribed position component must
        agree with x already (ValueError naming the largest difference otherwise).

        >>> from femshell.mesh import disk
        >>> from femshell.shell import flat_rest_state
        >>> m = disk(1.0, edge_length=0.3)
        >>> model = ShellModel(m, Material(1.0, 0.3), flat_rest_state(m.points, m.triangles, 0.01))
        >>> u = model.unknowns_from_positions(m.points + [0.0, 0.0, 1.0])    # lifted: a rigid motion
        >>> bool(np.allclose(model.positions(u), m.points)), bool(abs(model.energy(u)) < 1e-20)
        (True, True)
        """
        x = np.asarray(x, dtype=float)
        n = self.mesh.n_vertices
        if x.shape != (n, 3) or not np.all(np.isfinite(x)):
            raise ValueError(f"positions must be a finite ({n}, 3) array, one row per vertex, got shape {x.shape}")
        fixed = ~self.free[: 3 * n].reshape(n, 3)
        target = self.q_fixed[: 3 * n].reshape(n, 3)
        size = float(np.ptp(self.mesh.points, axis=0).max())
        if self.rigid_pins:
            x = _pinned_rigidly(x, self.rigid_pins, target, size)
        off = np.abs(x - target)[fixed]
        if off.size and off.max() > 1e-9 * size:
            raise ValueError(f"positions differ from the prescribed ones by up to {off.max():.3g} (mesh size "
                             f"{size:.3g}): a state of this model keeps its supports where they are")
        q = self.q_fixed.copy()
        q[: 3 * n] = np.where(fixed, target, x).ravel()
        return q[self.free]

    def full(self, u: np.ndarray) -> np.ndarray:
        """All unknowns q from the free ones u."""
        q = self.q_fixed.copy()
        q[self.free] = u
        return q

    def positions(self, u: np.ndarray) -> np.ndarray:
        """Vertex positions (n, 3) of a state."""
        return self.full(u)[: 3 * self.mesh.n_vertices].reshape(-1, 3)

    def mode_displacements(self, v: np.ndarray) -> np.ndarray:
        """Vertex displacements (n, 3) of a direction v in the free unknowns (an eigenvector, a
        tangent): the prescribed components do not move, so they are zero, not q_fixed."""
        q = np.zeros(self.n_total)
        q[self.free] = v
        return q[: 3 * self.mesh.n_vertices].reshape(-1, 3)

    # ---- energy and derivatives -----------------------------------------------------------------
    @property
    def _kernels(self) -> el.Kernels:
        return el.kernels(self.material.law)

    def _element_args(self, q):
        mat = self.material
        return (q[self.element_dofs], self._abar_inv, self._bbar, self._area, self._hbar,
                mat.alpha, mat.beta, self.edge_kind_el, self.edge_direction_el, self.face_edge_sign)

    def strain_energy(self, u) -> float:
        return float(np.sum(self._kernels.evaluate(*self._element_args(self.full(u)),
                                                   gradient_kernel=self.gradient_kernel)[0]))

    def energy_parts(self, u):
        """Membrane and bending energy per element, two (m,) arrays."""
        mem, bend = self._kernels.parts(*self._element_args(self.full(u)))
        return np.asarray(mem), np.asarray(bend)

    def external_work(self, u) -> float:
        q = self.full(u)
        return sum(load.work(q) for load in self.loads)

    def energy(self, u) -> float:
        """Total potential Π = U − λ W."""
        e = self.strain_energy(u)
        if self.loads:
            e -= self.load_factor * self.external_work(u)
        return e

    def _element_values_and_gradient(self, u):
        """Element strain energies (m,) and the assembled ∂U/∂u, from one compiled pass."""
        e, g, _ = self._kernels.evaluate(*self._element_args(self.full(u)), gradient=True,
                                         gradient_kernel=self.gradient_kernel)
        return e, self.assembler.vector(np.asarray(g))

    def gradient(self, u) -> np.ndarray:
        """∂Π/∂u over the free unknowns."""
        _, r = self._element_values_and_gradient(u)
        if self.loads:
            r -= self.load_factor * self.load_gradient(u)
        return r

    def energy_and_gradient(self, u):
        """(Π, ∂Π/∂u) from one pass over the elements.

        With the compiled kernel (``gradient_kernel``) the energy is :meth:`energy`'s bit for bit; on
        the JAX path another compiled function sums it: the two agree to round-off, not always bit for bit.
        """
        e, r = self._element_values_and_gradient(u)
        e = float(np.sum(e))
        if self.loads:
            e -= self.load_factor * self.external_work(u)
            r -= self.load_factor * self.load_gradient(u)
        return e, r

    def load_gradient(self, u) -> np.ndarray:
        """∂W/∂u: minus the derivative of the residual with respect to the load factor."""
        q = self.full(u)
        return sum((load.gradient(q) for load in self.loads), np.zeros(self.n_total))[self.free]

    def hessian(self, u):
        """∂²Π/∂u² as a CSR matrix over the free unknowns (symmetric, possibly indefinite)."""
        q = self.full(u)
        interior = (self.edge_kind_el == el.INTERIOR).all(axis=1)  # these skip the boundary branches
        _, _, h = self._kernels.evaluate(*self._element_args(q), hessian=True, interior=interior,
                                         hessian_kernel=self.hessian_kernel)
        K = self.assembler.matrix(np.asarray(h))
        own_pattern = True
        for i, load in enumerate(self.loads):
            blocks = load.hessian_blocks(q)
            if blocks is None:
                continue
            dofs, h = blocks
            if i not in self._load_assemblers:
                asm = SparseAssembler(dofs, self.free)
                self._load_assemblers[i] = (asm, self.assembler.slots_of(asm))
            asm, slots = self._load_assemblers[i]
            M = asm.matrix(h)
            if slots is not None and own_pattern:
                # in place, on the shell's own pattern: a sparse sum would drop the exact zeros of a flat
                # state and hand the factorisation a new pattern (a new symbolic analysis)
                K.data[slots] -= self.load_factor * M.data
            else:
                K, own_pattern = K - self.load_factor * M, False
        return K

    def accept(self, u):
        """Tell path-dependent loads (edge moments) that ``u`` is an accepted state."""
        q = self.full(u)
        for load in self.loads:
            if hasattr(load, "update_branch"):
                load.update_branch(q)

    def stress_free_rest_state(self, u=None, thickness=None) -> RestState:
        """The rest state in which state ``u`` (default: the reference) has zero energy: ā = a(u), b̄ = b(u).

        A curved mesh drawn as a shell's natural shape (a cylinder, a sphere) has a discrete
        curvature close to, but not exactly, 1/R; using its own forms makes it exactly stress free.
        """
        a, b = self.fundamental_forms(self.initial_unknowns() if u is None else u)
        return RestState(a, b, self.rest.thickness if thickness is None else thickness)

    def membrane_ellipticity(self, u) -> np.ndarray:
        """:meth:`Material.ellipticity_margin` of every element at state u, C = ā⁻¹a (negative where
        the membrane law is not elliptic: results there depend on the mesh)."""
        return self.material.ellipticity_margin(self._metric_ratio(u))

    def non_elliptic_elements(self, u) -> np.ndarray:
        """Indices of the elements whose membrane law is not elliptic at state u
        (:meth:`Material.non_elliptic`; the cheap check for every step of a run)."""
        if self.material.law != "svk":
            return np.zeros(0, np.int64)
        return np.flatnonzero(self.material.non_elliptic(self._metric_ratio(u)))

    def edge_turning_angles(self, u) -> np.ndarray:
        """Angle (degrees, in [0, 90)) by which each edge's mid-edge normal is turned about the edge from
        the mean normal of its faces: arctan |θ| of the edge unknown θ (:func:`~femshell.shell.bending.turned_normal`)."""
        return np.degrees(np.arctan(np.abs(self.full(u)[3 * self.mesh.n_vertices:])))

    def over_folded_edges(self, u) -> np.ndarray:
        """Indices of the edges whose mid-edge normal is turned by ``FOLD_LIMIT_DEG`` or more from its faces
        (:meth:`edge_turning_angles`): folds sharper than one element carries (:meth:`diagnose`)."""
        return np.flatnonzero(self.edge_turning_angles(u) >= FOLD_LIMIT_DEG)

    def diagnose(self, u) -> str | None:
        """What about state u may explain a failed solve, in words, or None when nothing is found.

        Newton (:func:`femshell.solvers.newton.minimize`) appends this to its error. Two checks:

        * mid-edge normals turned by ``FOLD_LIMIT_DEG`` or more (:meth:`over_folded_edges`): where the
          two faces of an edge fold by more than 90°, θ = 0 is a maximum of that edge's bending energy
          and its unknown runs towards 90° (θ → ∞) without an equilibrium; the mesh is too coarse for
          the folds of this state;
        * elements whose St Venant–Kirchhoff membrane has lost ellipticity
          (:meth:`non_elliptic_elements`): they buckle in plane at the mesh scale.
        """
        found = []
        over = self.over_folded_edges(u)
        if len(over):
            turned = self.edge_turning_angles(u)
            worst = over[np.argmax(turned[over])]
            mid = self.positions(u)[self.topology.edges[worst]].mean(axis=0)
            found.append(f"{len(over)} of {len(turned)} mid-edge normals are turned by {FOLD_LIMIT_DEG:g}° or more "
                         f"from their faces (largest {turned[worst]:.2f}°, at the edge with midpoint "
                         f"({mid[0]:.4g}, {mid[1]:.4g}, {mid[2]:.4g})): the shell folds more sharply there than one "
                         "element can carry; refine the mesh where it folds")
        non_elliptic = self.non_elliptic_elements(u)
        if len(non_elliptic):
            found.append(f"{len(non_elliptic)} elements are compressed past the stretch "
                         f"{self.material.svk_ellipticity_stretch:.3f} where the St Venant–Kirchhoff membrane loses "
                         "ellipticity (results there depend on the mesh; Material(law=\"neo-hookean\") has no such limit)")
        return "; ".join(found) or None

    def _metric_ratio(self, u) -> np.ndarray:
        """C = ā⁻¹a per element (m, 2, 2) at state u."""
        a, _ = self.fundamental_forms(u)
        return np.linalg.solve(self.rest.metric, np.asarray(a))

    def fundamental_forms(self, u):
        """Current first and second fundamental forms per element, (m,2,2) each."""
        a, b = self._kernels.forms(*self._element_args(self.full(u)))
        return a, b
