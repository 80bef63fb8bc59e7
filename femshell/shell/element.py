r"""The discrete Kirchhoff–Love element: one triangle, its three neighbours' far vertices,
and one rotation unknown per edge (a geometrically nonlinear Morley element).

Unknowns of one element (21): own vertices :math:`x_0, x_1, x_2`, the vertices
:math:`p_0, p_1, p_2` across the local edges (edge ``k`` is opposite vertex ``k``),
and one rotation unknown per edge, :math:`\theta_0, \theta_1, \theta_2` (the tangent of the
edge angle, below).

**First fundamental form.** With :math:`e_1 = x_1 - x_0`, :math:`e_2 = x_2 - x_0`
(barycentric coordinates :math:`u = \lambda_1, v = \lambda_2`),
:math:`a = [e_i \cdot e_j]`.

**Mid-edge normals.** On an interior edge with unit tangent :math:`t` (global edge
orientation) and face normals :math:`n_f, n_g`, the mean normal is
:math:`m = (n_f + n_g)/|n_f + n_g|` (on a free boundary edge :math:`m = n_f`), and
the mid-edge normal is :math:`n_e = (m + \theta\, t \times m)/\sqrt{1 + \theta^2}`: it is
turned about the edge by the angle :math:`\arctan\theta` (so θ is the edge angle to first order),
and it stays on the side of the faces, :math:`n_e \cdot m > 0`, for every θ. With the angle itself
as the unknown (:math:`\cos\theta\, m + \sin\theta\, t \times m`) a normal turned past ±π/2
would read a kink between the two faces as curvature of the opposite sign: a spurious state of
lower bending energy that saddle-escaping Newton does find (a seeded disk, h = 2: an edge angle of
3.16 and an energy 2.3 % below the stable dome's). On a clamped edge :math:`n_e` is the
prescribed rest normal; on a symmetry-plane edge it is the unit vector in the plane
normal to the edge.

**Second fundamental form.** Interpolating the normal with the Crouzeix–Raviart
functions :math:`1 - 2\lambda_k` and :math:`b_{ij} = \partial_i x \cdot \partial_j n`
gives exactly

.. math::  b = 2 \begin{pmatrix} s_0 h_0 + s_1 h_1 & s_0 h_0 \\ s_0 h_0 & s_0 h_0 + s_2 h_2 \end{pmatrix},
           \qquad s_k = n_{e_k} \cdot c_k,

with :math:`c_k` the outward in-plane unit conormal of edge ``k`` and :math:`h_k` the
altitude onto it. Only the component of :math:`n_e` across the edge enters, which
is why one angle per edge suffices. For small deflections :math:`w` this is the
Morley element (exact for quadratic :math:`w`), which converges on unstructured
meshes, unlike hinge (dihedral-angle) springs. With outward normals a sphere of
radius R has :math:`b \approx a/R` (positive), on average: per element it scatters, as the mid-edge
normals of a drawn polyhedron are the mean of its face normals, and the scatter shrinks only
slowly under refinement (:mod:`femshell.validation.curvature`).

**Energy** (design.md 1.2, St Venant–Kirchhoff in metric form):

.. math::  W = \bar A \left[\frac{\bar h}{4} \|\bar a^{-1} a - I\|^2
              + \frac{\bar h^3}{12} \|\bar a^{-1}(b - \bar b)\|^2\right],\quad
           \|M\|^2 = \frac{\alpha}{2} (\operatorname{tr} M)^2 + \beta \operatorname{tr}(M^2).

**Membrane law** (:data:`MEMBRANE_LAWS`). design.md's St Venant–Kirchhoff term is
:math:`\bar h\,\psi(C)` with :math:`C = \bar a^{-1} a`, :math:`\psi = \tfrac14 \|C - I\|^2`.
It loses ellipticity under compression (equibiaxial stretch below
:math:`\sqrt{(\alpha+\beta)/(\alpha+2\beta)}`, 0.866 at ν = 0.5): a confined region grown
by more than that collapses into mesh-scale folds and inverted triangles. The optional
compressible neo-Hookean law

.. math::  \psi = \frac{\beta}{2}(\operatorname{tr} C - 2 - \ln\det C)
           + \frac{\alpha}{4}(\det C - 1 - \ln\det C)

is polyconvex (hence elliptic at every stretch), is infinite where a triangle degenerates,
and agrees with St Venant–Kirchhoff to second order in the strain (same α, β at small
strain). The bending term is the same for both. Neither law keeps a shell from folding on the
scale of one edge where the mesh is too coarse for the wrinkles a thin grown layer wants (a
resolution limit: :func:`femshell.geometry.fold_angles` shows it).

Exact gradients and Hessians come from JAX automatic differentiation of
:func:`element_energy`, in float64, vectorised over all elements.

**Split Hessian.** W depends on the unknowns only through the six numbers
:math:`z = (a_{11}, a_{12}, a_{22}, q_0, q_1, q_2)`, :math:`q_k = s_k h_k` (b is linear in q;
W is quadratic in z for St Venant–Kirchhoff, not for neo-Hookean).
The metric entries depend only on the 9 own-vertex coordinates, quadratically, and
:math:`q_k` only on the 13 unknowns :math:`y_k = (x_0, x_1, x_2, p_k, \theta_k)`, so

.. math::  \nabla^2 W = J^T \frac{\partial^2 W}{\partial z^2} J
           + \sum_{ij} \frac{\partial W}{\partial a_{ij}} \nabla^2 a_{ij}
           + \sum_k \frac{\partial W}{\partial q_k} \nabla^2 q_k,
           \qquad J = \partial z / \partial (x, p, \theta)\ (6 \times 21),

with :math:`\nabla^2 a_{ij}` constant (:math:`\nabla^2 (e_i \cdot e_j) = D_i^T D_j + D_j^T D_i`,
:math:`e_i = D_i x`) and three 13×13 Hessians of :func:`edge_q` (forward over reverse
mode; :math:`q_k` is translation invariant, so they are
:math:`T^T (\partial^2 q_k / \partial r^2) T` with the 10 relative unknowns
:math:`r = T y_k = (x_1 - x_0, x_2 - x_0, p_k - x_0, \theta_k)`). This is the same
matrix as ``jax.hessian(element_energy)`` up to rounding, at a fraction of the cost;
elements whose three edges are interior use a kernel without the clamped/symmetry
branches (:func:`batch_hessian_grouped`).
"""

from __future__ import annotations

import os
import threading
from pathlib import Path

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)  # shells need float64: membrane/bending stiffness ratio ~ (R/h)^2
# compiling the element Hessian takes seconds; keep the compiled code between runs
if jax.config.jax_compilation_cache_dir is None:
    jax.config.update("jax_compilation_cache_dir",
                      os.environ.get("FEMSHELL_JAX_CACHE", os.path.join(os.path.expanduser("~"), ".cache", "femshell-jax")))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)

import jax.numpy as jnp  # noqa: E402

# edge kinds, per (element, local edge)
INTERIOR, FREE, CLAMPED, SYMMETRY = 0, 1, 2, 3


def _unit(v):
    return v / jnp.sqrt(jnp.sum(v * v))


#: what the edge unknowns are, for checkpoints to record: femshell before 2026-11-28 stored angles
EDGE_UNKNOWN = "tangent"


def turned_normal(m, t, theta):
    r""":math:`n_e = (m + \theta\, t \times m)/\sqrt{1 + \theta^2}`: m turned about the edge t by arctan θ."""
    return (m + theta * jnp.cross(t, m)) / jnp.sqrt(1.0 + theta * theta)


def mid_edge_normals(x, p, theta, kind, direction, sign):
    """The three mid-edge unit normals of one element and its unit face normal.

    x, p : (3, 3) own and across-edge vertices; theta : (3,) edge rotation unknowns (module docstring);
    kind : (3,) edge kinds; direction : (3, 3) clamped normal or symmetry-plane normal;
    sign : (3,) +1/-1 orientation of the local edge against the global edge.
    """
    nf = _unit(jnp.cross(x[1] - x[0], x[2] - x[0]))
    out = []
    for k in range(3):
        a, b = x[(k + 1) % 3], x[(k + 2) % 3]
        t = sign[k] * _unit(b - a)
        ng = _unit(jnp.cross(a - b, p[k] - b))
        m = _unit(nf + jnp.where(kind[k] == INTERIOR, 1.0, 0.0) * ng)
        rotated = turned_normal(m, t, theta[k])
        # only a symmetry edge takes the cross product: on any other edge it can vanish (an edge turned
        # onto its stored direction), and its NaN derivative would leak through the outer where
        sym = _unit(jnp.where(kind[k] == SYMMETRY, jnp.cross(direction[k], t), nf))
        sym = sym * jnp.sign(jax.lax.stop_gradient(jnp.dot(sym, nf)) + 1e-300)
        ne = jnp.where(kind[k] == CLAMPED, direction[k], jnp.where(kind[k] == SYMMETRY, sym, rotated))
        out.append(ne)
    return jnp.stack(out), nf


def fundamental_forms(x, p, theta, kind, direction, sign):
    """First and second fundamental forms (2x2 each) in the element's barycentric coordinates."""
    e1, e2 = x[1] - x[0], x[2] - x[0]
    a = jnp.array([[e1 @ e1, e1 @ e2], [e1 @ e2, e2 @ e2]])
    ne, nf = mid_edge_normals(x, p, theta, kind, direction, sign)
    twice_area = jnp.sqrt(a[0, 0] * a[1, 1] - a[0, 1] * a[0, 1])  # explicit: jnp.linalg.det is an LU call
    s, h = [], []
    for k in range(3):
        d = x[(k + 2) % 3] - x[(k + 1) % 3]
        length = jnp.sqrt(d @ d)
        conormal = jnp.cross(d, nf) / length
        s.append(ne[k] @ conormal)
        h.append(twice_area / length)
    q0, q1, q2 = s[0] * h[0], s[1] * h[1], s[2] * h[2]
    b = 2.0 * jnp.array([[q0 + q1, q0], [q0, q0 + q2]])
    return a, b


def norm2(M, alpha, beta):
    """(alpha/2) (tr M)^2 + beta tr(M^2): the St Venant–Kirchhoff quadratic form."""
    tr = M[0, 0] + M[1, 1]
    return 0.5 * alpha * tr * tr + beta * jnp.sum(M * M.T)


def svk_membrane(C, alpha, beta):
    """ψ(C) = ¼ ‖C − I‖² (design.md 1.2), C = ā⁻¹a: energy per target area and thickness."""
    return 0.25 * norm2(C - jnp.eye(2), alpha, beta)


def neo_hookean_membrane(C, alpha, beta):
    """ψ(C) = (β/2)(tr C − 2 − ln det C) + (α/4)(det C − 1 − ln det C) (module docstring).

    Not finite where det C ≤ 0 (a degenerate triangle): Newton's line search rejects such steps.
    """
    det = C[0, 0] * C[1, 1] - C[0, 1] * C[1, 0]
    log_det = jnp.log(det)
    return 0.5 * beta * (C[0, 0] + C[1, 1] - 2.0 - log_det) + 0.25 * alpha * (det - 1.0 - log_det)


MEMBRANE_LAWS = {"svk": svk_membrane, "neo-hookean": neo_hookean_membrane}


def _membrane_and_bending(a, b, abar_inv, bbar, area, hbar, alpha, beta, membrane):
    bend = abar_inv @ (b - bbar)
    return (area * hbar * membrane(abar_inv @ a, alpha, beta),
            area * hbar**3 / 12.0 * norm2(bend, alpha, beta))


def element_membrane_bending(q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign,
                             membrane=svk_membrane):
    """The membrane and bending parts of :func:`element_energy` separately (for output)."""
    a, b = fundamental_forms(q[:9].reshape(3, 3), q[9:18].reshape(3, 3), q[18:], kind, direction, sign)
    return _membrane_and_bending(a, b, abar_inv, bbar, area, hbar, alpha, beta, membrane)


def element_energy(q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign, membrane=svk_membrane):
    """Strain energy of one element.

    q : (21,) [x0, x1, x2, p0, p1, p2 (3 each), theta0, theta1, theta2];
    abar_inv, bbar : (2, 2) inverse target metric and target curvature;
    area : target area; hbar : target thickness; alpha, beta : material constants;
    membrane : ψ(C, alpha, beta), one of :data:`MEMBRANE_LAWS`.
    """
    mem, bend = element_membrane_bending(q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign,
                                         membrane)
    return mem + bend


_AXES = (0, 0, 0, 0, 0, None, None, 0, 0, 0)
CHUNK_SMALL, CHUNK = 256, 4096
CHUNK_HESSIAN = 256


def element_threads() -> int:
    """How many chunks of elements are evaluated at once, each on its own thread.

    ``FEMSHELL_THREADS`` if set; else the smaller of ``MKL_NUM_THREADS`` and ``OMP_NUM_THREADS``
    where set (what confines a process to one core for its linear algebra confines the element
    kernels too); else the CPUs this process may run on, within a container's CPU limit. Each chunk is one compiled call on
    fixed-size arrays, so the results are the same bit for bit at any count; two threads
    halve the time of the shell's Hessian on 2 cores (a 25 000-vertex sphere: 2.1–2.4 s on one,
    1.17 s on two, measured).
    """
    text = os.environ.get("FEMSHELL_THREADS", "").strip()
    if text:
        if not (text.isdigit() and int(text) >= 1):
            raise ValueError(f"FEMSHELL_THREADS = {text!r} must be a whole number >= 1 (threads)")
        return int(text)
    # the libraries' own variables as they read them: "2,1" (OpenMP's nested levels) is 2 at the top;
    # what they would ignore ("", "0", "many") is ignored here too
    given = [int(v) for v in (os.environ.get(n, "").split(",")[0].strip() for n in ("MKL_NUM_THREADS", "OMP_NUM_THREADS"))
             if v.isdigit() and int(v) >= 1]
    if given:
        return min(given)
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    quota = _cpu_quota()
    return max(1, min(cpus, quota)) if quota else cpus


#: where a container's CPU limit is read (cgroup v2, then v1)
CGROUP_CPU_FILES = (("/sys/fs/cgroup/cpu.max",), ("/sys/fs/cgroup/cpu/cpu.cfs_quota_us", "/sys/fs/cgroup/cpu/cpu.cfs_period_us"))


def _cpu_quota():
    """Whole CPUs a container's CPU limit allows (``docker --cpus=2`` on a larger host: 2), None without one."""
    for files in CGROUP_CPU_FILES:
        try:
            fields = " ".join(Path(f).read_text().strip() for f in files).split()
        except (OSError, ValueError):
            continue
        try:
            quota, period = int(fields[0]), int(fields[1])      # v2 "max 100000" has no number: no limit
        except (ValueError, IndexError):
            return None
        return max(1, quota // period) if quota > 0 and period > 0 else None
    return None


_pool = {"threads": 0, "executor": None, "lock": threading.Lock()}


def _executor(threads: int):
    """A pool of ``threads`` workers, kept between calls (made anew when the count changes or after a fork)."""
    with _pool["lock"]:
        if _pool["threads"] != threads:
            if _pool["executor"] is not None:
                _pool["executor"].shutdown(wait=False)
            from concurrent.futures import ThreadPoolExecutor

            _pool["executor"] = ThreadPoolExecutor(threads, thread_name_prefix="femshell-elements")
            _pool["threads"] = threads
        return _pool["executor"]


if hasattr(os, "register_at_fork"):      # a forked child has none of the parent's threads
    os.register_at_fork(after_in_child=lambda: _pool.update(threads=0, executor=None, lock=threading.Lock()))


def _batched(fn, chunk=None, chunk_small=None):
    """Vectorise ``fn`` over elements in fixed-size chunks.

    JAX compiles once per array shape; two fixed chunk sizes (the bulk in big chunks,
    the rest in small ones, the last padded with copies of element 0) mean two
    compilations serve every mesh size with little wasted work, and bound the memory
    of the (m, 21, 21) Hessian intermediates. The Hessian kernels use one small size
    (:data:`CHUNK_HESSIAN`): their intermediates stay in cache, which makes them about
    1.5x faster per element than in chunks of 4096, and compiling them once is costly.
    """
    chunk = CHUNK if chunk is None else chunk
    chunk_small = CHUNK_SMALL if chunk_small is None else chunk_small
    compiled = jax.jit(jax.vmap(fn, in_axes=_AXES))

    def run(q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign):
        per_element = [q, abar_inv, bbar, area, hbar, kind, direction, sign]
        m = len(q)
        # big chunks for the bulk, small ones for the rest: little padding at any size
        n_big, rest = divmod(m, chunk)
        n_big += rest > 0 and rest >= chunk - chunk_small
        starts = [(i * chunk, chunk) for i in range(n_big)]
        starts += [(s, chunk_small) for s in range(n_big * chunk, m, chunk_small)]

        def one(start_size):
            start, size = start_size
            part = [a[start:start + size] for a in per_element]
            k = len(part[0])
            if k < size:
                part = [np.concatenate([a, np.repeat(a[:1], size - k, axis=0)]) for a in part]
            out = compiled(part[0], part[1], part[2], part[3], part[4], alpha, beta, part[5], part[6], part[7])
            return jax.tree_util.tree_map(lambda o: np.asarray(o)[:k], out)

        threads = element_threads()
        # JAX releases the GIL while a compiled call runs: chunks on several threads run in parallel
        if threads > 1 and len(starts) > 1:
            pieces = list(_executor(threads).map(one, starts))
        else:
            pieces = [one(s) for s in starts]
        if len(pieces) == 1:
            return pieces[0]
        return jax.tree_util.tree_map(lambda *o: np.concatenate(o), *pieces)

    return run


def edge_q(y, k, kind, direction, sign):
    """:math:`q_k = s_k h_k` of local edge ``k`` from its 13 unknowns y = [x0, x1, x2, p_k, theta_k].

    ``kind=None``: an interior edge, without the clamped/symmetry branches. Same
    arithmetic as :func:`fundamental_forms`.
    """
    x = y[:9].reshape(3, 3)
    p, th = y[9:12], y[12]
    nf = _unit(jnp.cross(x[1] - x[0], x[2] - x[0]))
    a, b = x[(k + 1) % 3], x[(k + 2) % 3]
    t = sign * _unit(b - a)
    ng = _unit(jnp.cross(a - b, p - b))
    if kind is None:
        m = _unit(nf + ng)
        ne = turned_normal(m, t, th)
    else:
        m = _unit(nf + jnp.where(kind == INTERIOR, 1.0, 0.0) * ng)
        rotated = turned_normal(m, t, th)
        sym = _unit(jnp.where(kind == SYMMETRY, jnp.cross(direction, t), nf))     # see mid_edge_normals
        sym = sym * jnp.sign(jax.lax.stop_gradient(jnp.dot(sym, nf)) + 1e-300)
        ne = jnp.where(kind == CLAMPED, direction, jnp.where(kind == SYMMETRY, sym, rotated))
    e1, e2 = x[1] - x[0], x[2] - x[0]
    twice_area = jnp.sqrt((e1 @ e1) * (e2 @ e2) - (e1 @ e2) * (e1 @ e2))
    d = b - a
    length = jnp.sqrt(d @ d)
    conormal = jnp.cross(d, nf) / length
    return (ne @ conormal) * (twice_area / length)


def energy_of_forms(z, abar_inv, bbar, area, hbar, alpha, beta, membrane=svk_membrane):
    """:func:`element_energy` as a function of z = (a11, a12, a22, q0, q1, q2) (quadratic for SVK)."""
    a = jnp.array([[z[0], z[1]], [z[1], z[2]]])
    b = 2.0 * jnp.array([[z[3] + z[4], z[3]], [z[3], z[3] + z[5]]])
    mem, bend = _membrane_and_bending(a, b, abar_inv, bbar, area, hbar, alpha, beta, membrane)
    return mem + bend


# q_k is translation invariant: a function of r = (x1 - x0, x2 - x0, p_k - x0, theta_k) = T y (10 of 13)
_RELATIVE = np.zeros((10, 13))
_RELATIVE[np.arange(9), np.arange(3, 12)] = 1.0
_RELATIVE[np.arange(9), np.tile(np.arange(3), 3)] = -1.0
_RELATIVE[9, 12] = 1.0


def _edge_q_relative(r, k, kind, direction, sign):
    return edge_q(jnp.concatenate([jnp.zeros(3), r]), k, kind, direction, sign)


_D = np.array([[-1.0, 1.0, 0.0], [-1.0, 0.0, 1.0]])  # e_i = sum_v D[i, v] x_v
# Hessians of a11, a12, a22 in vertex space (times I3 per coordinate)
_METRIC_HESS = np.stack([2 * np.outer(_D[0], _D[0]), np.outer(_D[0], _D[1]) + np.outer(_D[1], _D[0]),
                         2 * np.outer(_D[1], _D[1])])


def _split_hessian(interior, membrane=svk_membrane):
    """The element Hessian by the split of the module docstring (``interior``: all edges interior)."""

    def hessian(q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign):
        x = q[:9].reshape(3, 3)
        e1, e2 = x[1] - x[0], x[2] - x[0]
        z, hess = [e1 @ e1, e1 @ e2, e2 @ e2], []
        zero = jnp.zeros(3)
        rows = [jnp.concatenate([-2 * e1, 2 * e1, zero]), jnp.concatenate([-(e1 + e2), e2, e1]),
                jnp.concatenate([-2 * e2, zero, 2 * e2])]
        rows = [jnp.concatenate([r, jnp.zeros(12)]) for r in rows]
        for k in range(3):
            r = jnp.concatenate([q[3:9] - jnp.tile(q[:3], 2), q[9 + 3 * k:12 + 3 * k] - q[:3], q[18 + k:19 + k]])
            args = (k, None if interior else kind[k], direction[k], sign[k])
            grad = jax.grad(_edge_q_relative)
            hr, gr = jax.jacfwd(lambda v: (grad(v, *args),) * 2, has_aux=True)(r)
            gk, hk = gr @ _RELATIVE, _RELATIVE.T @ hr @ _RELATIVE  # back to y = [x0, x1, x2, p_k, theta_k]
            z.append(_edge_q_relative(r, *args))
            row = jnp.zeros(21).at[:9].set(gk[:9]).at[9 + 3 * k:12 + 3 * k].set(gk[9:12])
            rows.append(row.at[18 + k].set(gk[12]))
            hess.append(hk)
        z, J = jnp.stack(z), jnp.stack(rows)  # (6,), (6, 21)
        forms = (abar_inv, bbar, area, hbar, alpha, beta, membrane)
        dw = jax.grad(energy_of_forms)(z, *forms)
        H = J.T @ jax.hessian(energy_of_forms)(z, *forms) @ J
        hxx = jnp.kron(jnp.einsum("i,iab->ab", dw[:3], _METRIC_HESS), jnp.eye(3))
        for k in range(3):
            w = dw[3 + k] * hess[k]
            hxx = hxx + w[:9, :9]
            pk, tk = slice(9 + 3 * k, 12 + 3 * k), 18 + k
            H = H.at[:9, pk].add(w[:9, 9:12]).at[pk, :9].add(w[9:12, :9]).at[pk, pk].add(w[9:12, 9:12])
            H = H.at[:9, tk].add(w[:9, 12]).at[tk, :9].add(w[12, :9])
            H = H.at[pk, tk].add(w[9:12, 12]).at[tk, pk].add(w[12, 9:12]).at[tk, tk].add(w[12, 12])
        H = H.at[:9, :9].add(hxx)
        # forward-over-reverse Hessians are symmetric only up to rounding, which on badly
        # distorted elements reaches ~1e-8 of the largest entry: enough for a symmetric
        # factorisation's check to refuse the assembled matrix
        return 0.5 * (H + H.T)

    return hessian


class Kernels:
    """The batched energy, gradient, Hessian and parts of one membrane law (compiled on first use):
    ``k.energy(*args)`` gives the (m,) element energies, with ``args`` as for :func:`batch_energy`.

    >>> k = kernels("neo-hookean")
    >>> k.law
    'neo-hookean'
    """

    def __init__(self, law: str):
        if law not in MEMBRANE_LAWS:
            raise ValueError(f"membrane law must be one of {tuple(MEMBRANE_LAWS)}, got {law!r}")
        membrane = MEMBRANE_LAWS[law]

        def energy(*args):
            return element_energy(*args, membrane=membrane)

        def parts(*args):
            return element_membrane_bending(*args, membrane=membrane)

        self.law = law
        self.energy = _batched(energy)
        self.value_and_grad = _batched(jax.value_and_grad(energy))
        self.parts = _batched(parts)
        self.hessian = _batched(_split_hessian(False, membrane), CHUNK_HESSIAN, CHUNK_HESSIAN)
        self.hessian_interior = _batched(_split_hessian(True, membrane), CHUNK_HESSIAN, CHUNK_HESSIAN)

    def hessian_grouped(self, interior, q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign):
        """:attr:`hessian`, with the elements flagged in ``interior`` (all three edges
        interior) through the kernel without boundary branches; same result."""
        args = [q, abar_inv, bbar, area, hbar, kind, direction, sign]
        if interior.all():
            return self.hessian_interior(q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign)
        if not interior.any():
            return self.hessian(q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign)
        out = np.empty((len(q), 21, 21))
        for mask, fn in ((interior, self.hessian_interior), (~interior, self.hessian)):
            a = [np.asarray(v)[mask] for v in args]
            out[mask] = fn(a[0], a[1], a[2], a[3], a[4], alpha, beta, a[5], a[6], a[7])
        return out


_KERNELS = {}


def kernels(law: str = "svk") -> Kernels:
    """The :class:`Kernels` of a membrane law, built once per process."""
    if law not in _KERNELS:
        _KERNELS[law] = Kernels(law)
    return _KERNELS[law]


_SVK = kernels("svk")
batch_energy = _SVK.energy
batch_value_and_grad = _SVK.value_and_grad
batch_hessian = _SVK.hessian
batch_hessian_interior = _SVK.hessian_interior
batch_hessian_grouped = _SVK.hessian_grouped
batch_parts = _SVK.parts


def _forms(q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign):
    return fundamental_forms(q[:9].reshape(3, 3), q[9:18].reshape(3, 3), q[18:], kind, direction, sign)


batch_forms = _batched(_forms)
