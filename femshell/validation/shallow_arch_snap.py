r"""Snap-through of a shallow pinned arch: continuation through two limit points (folds).

A shell strip (length L = 10, width b = 0.5, thickness h = 0.1, E = 1, **ν = 0**) drawn as
the shallow arch z = w0(x) = e sin(πx/L) and made stress free in that shape (rest forms =
the drawn forms), both ends pinned and immovable (:class:`~femshell.shell.SimplySupported`
on the end edges: positions held, rotation free), long edges free, carries a dead load
q(x) = λ q̂ sin(πx/L) per unit rest area pointing down (−z). With ν = 0 and free long
edges the strip bends like a beam of I = b h³/12, A = b h (no anticlastic curvature, no
Poisson stress across the width), radius of gyration r = h/√12. The load factor λ is the
continuation parameter (:class:`~femshell.solvers.continuation.LoadParameter`).

Shallow-arch theory (Timoshenko & Gere sec. 7.5; Bažant & Cedolin sec. 2.8)
---------------------------------------------------------------------------
w(x) upward, w = a sin(kx), k = π/L: with a sine load the symmetric equilibrium of
EI (w − w0)'''' + P w'' = −q (P the uniform compression) is exactly a sine, so one mode
is the whole symmetric solution. Between immovable supports ∫u' dx = 0, so the axial
strain is uniform, ε = (1/2L) ∫ (w'² − w0'²) dx, N = EA ε, and::

    U = (EI/2) ∫ (w'' − w0'')² dx + (EA L/2) ε²
      = EI k⁴ L (a − e)²/4 + EA k⁴ L (a² − e²)²/32,
    work of the load: W = −∫ q w dx = −λ Q̂ a L/2   (Q̂ = q̂ b, per unit length),

and ∂(U − W)/∂a = 0 gives, with ξ = a/r, η = e/r and the load unit Q̂ = EI k⁴ r
(per unit width q̂ = D k⁴ r, D = E h³/12),

    λ(ξ) = (η − ξ) + ξ (η² − ξ²)/4.

Limit points: dλ/dξ = −1 + (η² − 3ξ²)/4 = 0 at ξ = ±ξ*, ξ* = √((η² − 4)/3), which
exist when η > 2 (a flatter arch just stiffens, no snap):

    upper fold (snap-through)   λ_max = η + (η² − 4)^{3/2}/(6√3)   at ξ = +ξ*
    lower fold (inverted arch)  λ_min = η − (η² − 4)^{3/2}/(6√3)   at ξ = −ξ*

∂²Π/∂a² ∝ −dλ/dξ: the path is stable (no negative eigenvalue) for ξ > ξ* and ξ < −ξ*
and has exactly one negative eigenvalue (the symmetric mode) between the folds.

Antisymmetric bifurcation: adding c sin(2kx) (orthogonal in ∫w'², so no coupling at
first order), its stiffness is ∂²Π/∂c² = 8 EI k⁴ L − EA k⁴ L (e² − a²)/2, i.e. it
vanishes when the compression P = EA k² (e² − a²)/4 = EI k² (η² − ξ²)/4 reaches the
second Euler load 4 EI k²: at ξ_b² = η² − 16. This needs η > 4, and it comes before the
upper fold (ξ_b > ξ*) iff η² − 16 > (η² − 4)/3, i.e. η > √22 ≈ 4.69. So for
2 < η < √22 the arch snaps symmetrically at a limit point, and for η < 4 there is no
branch point anywhere on the symmetric path. We take **η = e/r = 3.5**: the largest
compression on the whole path (at ξ = 0) is η²/16 = 0.77 of the antisymmetric critical
force, so the continuation must see no branch point. Then

    λ_max = 5.78018,  ξ* = 1.65831,  λ_min = 1.21982.

Theory error: shallow-arch (Marguerre) kinematics drop terms of relative order
(πe/L)² = 1.0e-3 here (e/L = 0.0101: slope² against 1 in strain and curvature, span vs
arc length, and the dead vertical load per rest area against a transverse load per span);
the finest meshes show this floor (Richardson-extrapolated λ_max 0.09 % below theory).

Tolerances (about three times the measured error, not below twice the theory floor):
on the quick mesh (40 edges along the span) the errors are 0.15 % on λ_max, 0.03 % on ξ at the
fold, 0.38 % on λ_min (the difference η − (η² − 4)^{3/2}/(6√3) = 3.5 − 2.28: relative errors
are amplified by λ_max/λ_min ≈ 4.7) and 0.16 % on the whole load–displacement curve
(max |λ − λ(ξ)| / λ_max), so the quick level allows 0.5 %, 0.3 %, 1.2 %, 0.5 % (a load 2 %
off, a lumping error say, fails λ_max and the curve). The full study (h = 0.5 ... 0.0625)
reaches the theory floor on its finest mesh (0.10 %, 0.03 %, 0.04 %, 0.10 %) and allows 0.3 %
on each (0.2 % on ξ), and 0.5 % on the h²-Richardson extrapolation of λ_max (5x the (πe/L)²
theory error). The observed order against theory flattens at the theory floor; the order from
successive differences of the three finest meshes (no reference needed) is reported too. The
qualitative rows (the continuation passes both folds without stopping and reaches the stable inverted
branch; exactly two folds "LP" and no branch point are marked; the number of negative
eigenvalues is 0, then 1 between the folds, then 0) must hold on every mesh.
"""

from __future__ import annotations

import math

import numpy as np

from ..mesh.generators import strip
from ..mesh.surface import SurfaceMesh
from ..shell import DeadLoad, Material, ShellModel, SimplySupported
from ..shell.loads import lumped_vertex_forces
from ..solvers.continuation import LoadParameter, continuation
from ..solvers.linear import factorize
from .clamped_plate_growth_buckling import convergence_axes, richardson_row
from .common import order_row
from .framework import Row, timed

NAME = "shallow-arch-snap"
DESCRIPTION = ("pinned shallow arch e/r = 3.5 (shell strip, nu = 0) under a sine load: continuation through "
               "the snap-through fold and the lower fold vs shallow-arch theory; LP marks, stability 0 -> 1 -> 0")
SOURCE = ("shallow-arch theory, one sine mode (exact for a sine load): lambda = (eta - xi) + xi (eta^2 - xi^2)/4 "
          "in units of EI k^4 r; folds at xi = +-sqrt((eta^2 - 4)/3); antisymmetric bifurcation needs "
          "eta > sqrt(22). Timoshenko & Gere, Theory of Elastic Stability (1961) sec. 7.5; Bazant & Cedolin, "
          "Stability of Structures (1991) sec. 2.8 (derivation in the module docstring)")

LENGTH, WIDTH, THICKNESS = 10.0, 0.5, 0.1
ETA = 3.5                                   # rise over radius of gyration, e/r
R_GYR = THICKNESS / math.sqrt(12.0)
RISE = ETA * R_GYR
K = math.pi / LENGTH
#: load unit per rest area: q_hat = D k^4 r (per width), D = E h^3/12 (nu = 0, E = 1)
Q_HAT = THICKNESS**3 / 12.0 * K**4 * R_GYR
#: edge lengths; quick: one mesh of <= 256 triangles (one element-kernel chunk, the cost of a Hessian is the
#: same for 40 or 160 triangles), run time ~ 20 s of continuation on a loaded 2-core machine
LEVELS = {"quick": [0.25], "full": [0.5, 0.25, 0.125, 0.0625]}
#: finest-mesh tolerances (lambda_max, xi at the fold, lambda_min, load-displacement curve); see the docstring
TOL = {"quick": (0.005, 0.003, 0.012, 0.005), "full": (0.003, 0.002, 0.003, 0.003)}
TOL_RICHARDSON = 0.005
#: continuation end: back up the stable inverted branch to this multiple of lambda_max (theory)
LAM_STOP_RATIO = 1.2

_LAST = {}


def theory_load(xi, eta=ETA):
    """λ(ξ) = (η − ξ) + ξ (η² − ξ²)/4 (load in units of EI k⁴ r, ξ = a/r)."""
    xi = np.asarray(xi, float)
    return (eta - xi) + xi * (eta**2 - xi**2) / 4.0


def fold_theory(eta=ETA):
    """(ξ*, λ_max, λ_min) of the shallow-arch folds; requires η > 2."""
    if eta <= 2.0:
        raise ValueError(f"no limit point for e/r = {eta} <= 2")
    xs = math.sqrt((eta**2 - 4.0) / 3.0)
    d = (eta**2 - 4.0) ** 1.5 / (6.0 * math.sqrt(3.0))
    return xs, eta + d, eta - d


def antisymmetric_bifurcation(eta=ETA):
    """ξ_b = √(η² − 16) where the antisymmetric mode goes critical, or None when η ≤ 4 (never)."""
    return math.sqrt(eta**2 - 16.0) if eta > 4.0 else None


def build(h, length=LENGTH, width=WIDTH, thickness=THICKNESS, eta=ETA):
    """Arch model on a structured strip mesh of edge length h. Returns (mesh, model, mid-span vertices, r)."""
    r = thickness / math.sqrt(12.0)
    e, k = eta * r, math.pi / length
    m0 = strip(length, width, edge_length=h, structured=True)
    p = np.array(m0.points)
    p[:, 2] = e * np.sin(k * p[:, 0])
    mesh = SurfaceMesh(p, m0.triangles, m0.boundary, m0.name + f" shallow arch e={e:.4g}")
    xc = p[mesh.triangles].mean(axis=1)[:, 0]
    traction = np.zeros((mesh.n_triangles, 3))
    traction[:, 2] = -thickness**3 / 12.0 * k**4 * r * np.sin(k * xc)
    model = ShellModel(mesh, Material(E=1.0, nu=0.0), thickness,      # the drawn arch is stress free
                       [SimplySupported("left"), SimplySupported("right")],
                       [DeadLoad(lumped_vertex_forces(mesh, traction))])
    model.load_factor = 0.0
    mid = np.flatnonzero(np.abs(p[:, 0] - 0.5 * length) <= 1e-9 * length)
    if len(mid) == 0:
        raise ValueError(f"edge length {h} puts no vertex at mid-span")
    return mesh, model, mid, r


def follow(h, lam_stop_ratio=LAM_STOP_RATIO, log=None, **options):
    """Continuation in λ from the unloaded arch to λ = lam_stop_ratio λ_max on the inverted branch.

    ``lam_stop_ratio`` must exceed 1 (a smaller target is met on the way up to the first fold);
    None: no target (stop by ``max_steps`` or a ``callback`` in ``options``).
    Returns (mesh, model, branch); the rows carry ``xi`` = mid-span rise / r.
    """
    mesh, model, mid, r = build(h)
    _, lam_max, _ = fold_theory()
    problem = LoadParameter(model, length_scale=r, parameter_scale=lam_max)

    def record(u):
        return {"xi": float(model.positions(u)[mid, 2].mean() / r)}

    opts = dict(ds=0.5, ds_max=1.0, max_steps=100, n_eigs=3, locate_tol=1e-6)
    opts.update(options)
    lam_stop = None if lam_stop_ratio is None else lam_stop_ratio * lam_max
    branch = continuation(problem, model.initial_unknowns(), 0.0, lam_stop=lam_stop,
                          record=record, label=f"arch h={h:g}", log=log, **opts)
    return mesh, model, branch


def fold_checks(branch):
    """Qualitative checks of a branch: dict of booleans (see the module docstring) and the two folds."""
    folds = [p for p in branch.special_points if p.kind == "fold"]
    others = [p for p in branch.special_points if p.kind != "fold"]
    pts = [r for r in branch.rows if not r["special"]]
    xs, _, _ = fold_theory()
    out = {"passed": False, "marked": False, "inertia": False}
    out["marked"] = len(folds) == 2 and not others and [r["special"] for r in branch.rows].count("LP") == 2 \
        and (folds[0].n_negative_before, folds[0].n_negative_after) == (0, 1) \
        and (folds[1].n_negative_before, folds[1].n_negative_after) == (1, 0)
    if len(folds) >= 2:
        s1, s2 = folds[0].s, folds[1].s
        before = [r["n_negative"] for r in pts if r["s"] < s1]
        between = [r["n_negative"] for r in pts if s1 < r["s"] < s2]
        after = [r["n_negative"] for r in pts if r["s"] > s2]
        out["inertia"] = bool(before and between and after and set(before) == {0} and set(between) == {1}
                              and set(after) == {0})
        out["passed"] = branch.status in ("lam_stop", "callback") and bool(after) and pts[-1]["xi"] < -xs \
            and pts[-1]["stable"] is True
    return out, folds


def warm_up():
    """Compile the element kernels (chunk of 256 elements) and load the solver before anything is timed."""
    _, model, _, _ = build(0.5)
    u = model.initial_unknowns()
    model.energy(u)
    model.gradient(u)
    factorize(model.hessian(u), kind="symmetric_indefinite").free()


def run(level, log=None):
    warm_up()                 # JIT and MKL start-up outside the timed rows
    sizes = LEVELS[level]
    tol_q, tol_x, tol_m, tol_c = TOL[level]
    xs, lam_max, lam_min = fold_theory()
    rows = []
    for i, h in enumerate(sizes):
        finest = i == len(sizes) - 1
        with timed() as t:
            mesh, model, branch = follow(h, log=log)
        nv = mesh.n_vertices
        checks, folds = fold_checks(branch)
        at = f" @ h={h:g}"
        upper = folds[0] if folds else None
        lower = folds[1] if len(folds) > 1 else None

        def xi_of(p):
            return branch.rows[[r["special"] == "LP" and r["s"] == p.s for r in branch.rows].index(True)]["xi"]

        rows.append(Row("lambda at the snap-through fold / lambda_max" + at,
                        upper.parameter / lam_max if upper else math.nan, 1.0, tol_q if finest else None, nv, t()))
        rows.append(Row("rise xi = a/r at the snap-through fold / xi*" + at,
                        xi_of(upper) / xs if upper else math.nan, 1.0, tol_x if finest else None, nv, t()))
        rows.append(Row("lambda at the lower fold / lambda_min" + at,
                        lower.parameter / lam_min if lower else math.nan, 1.0, tol_m if finest else None, nv, t()))
        rows.append(Row("rise xi at the lower fold / (-xi*)" + at,
                        xi_of(lower) / -xs if lower else math.nan, 1.0, tol_x if finest else None, nv, t()))
        pts = [r for r in branch.rows if not r["special"]]
        dev = max(abs(r["parameter"] - float(theory_load(r["xi"]))) for r in pts) / lam_max
        rows.append(Row("load-displacement curve: max |lambda - lambda(xi)| / lambda_max" + at, dev, 0.0,
                        tol_c if finest else None, nv, t()))
        rows.append(Row("passed both folds without stopping, ends stable on the inverted branch" + at,
                        float(checks["passed"]), 1.0, 0.0, nv, t()))
        rows.append(Row("marked: exactly two LP (0->1, 1->0 negative eigenvalues), no branch point" + at,
                        float(checks["marked"]), 1.0, 0.0, nv, t()))
        rows.append(Row("negative eigenvalues 0 before, 1 between, 0 after the folds" + at,
                        float(checks["inertia"]), 1.0, 0.0, nv, t()))
        rows.append(Row("continuation steps" + at, len(pts) - 1, None, None, nv, t()))
        if finest:
            _LAST["branch"] = branch
            _LAST["h"] = h
    for q in ("lambda at the snap-through fold / lambda_max", "lambda at the lower fold / lambda_min"):
        rows += order_row(q, rows)            # against theory: flattens at the (pi e/L)^2 floor
        rows += difference_order_row(q, rows, sizes)
    rows += richardson_row("lambda at the snap-through fold / lambda_max", rows, sizes, TOL_RICHARDSON)
    return rows


def difference_order_row(quantity, rows, sizes):
    """Order p from the three finest meshes, p = log2(|v(2h) − v(h)| / |v(h) − v(h/2)|): needs no reference,
    so the shallow-arch theory error (a constant floor) does not enter; 2 expected (O(h²))."""
    vals = {float(r.quantity.split(" @ h=")[1]): r.value for r in rows
            if r.quantity.startswith(quantity + " @ h=") and math.isfinite(r.value)}
    hs = [h for h in sizes if h in vals]
    if len(hs) < 3:
        return []
    d1, d2 = abs(vals[hs[-3]] - vals[hs[-2]]), abs(vals[hs[-2]] - vals[hs[-1]])
    if not (d1 > 0 and d2 > 0):
        return []
    p = math.log(d1 / d2) / math.log(hs[-2] / hs[-1])
    return [Row(f"observed order of {quantity} from successive differences, h={hs[-3]:g}..{hs[-1]:g}", p)]


def plot(rows, fig):
    """Error against vertices and wall time; load-displacement curve of the finest mesh against theory."""
    convergence_axes(fig.add_subplot(1, 3, 1), fig.add_subplot(1, 3, 2), rows,
                     lambda q: q.startswith(("lambda at", "rise")))
    ax = fig.add_subplot(1, 3, 3)
    xs, lam_max, lam_min = fold_theory()
    xi = np.linspace(-1.12 * ETA, 1.02 * ETA, 400)
    ax.plot(xi, theory_load(xi), "k-", lw=0.8, label="shallow-arch theory")
    b = _LAST.get("branch")
    if b is not None:
        pts = [r for r in b.rows if not r["special"]]
        x = np.array([r["xi"] for r in pts])
        y = np.array([r["parameter"] for r in pts])
        st = np.array([bool(r["stable"]) for r in pts])
        ax.plot(x, y, "-", color="tab:blue", lw=0.6, alpha=0.6)
        ax.plot(x[st], y[st], "o", color="tab:blue", ms=3.5, label="stable")
        ax.plot(x[~st], y[~st], "o", mfc="none", color="tab:red", ms=3.5, label="unstable (1 neg. eig.)")
        lp = [r for r in b.rows if r["special"] == "LP"]
        ax.plot([r["xi"] for r in lp], [r["parameter"] for r in lp], "k*", ms=9, label="LP (located)")
        ax.set_title(f"shell strip h={_LAST.get('h')}, e/r = {ETA}", fontsize=8)
    ax.plot([xs, -xs], [lam_max, lam_min], "x", color="k", ms=7)
    ax.set_xlabel("mid-span rise a / r")
    ax.set_ylabel("load factor  q / (D k^4 r)")
    ax.invert_xaxis()
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=6)
