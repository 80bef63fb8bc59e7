r"""Pseudo-arclength continuation of equilibria, with stability, fold and branch-point detection.

Solvers know energies and derivatives, not physics (design.md 2). The object followed is a
**parametrized problem**: anything with

``set_parameter(lam)``
    make ``lam`` the current parameter value (a ValueError outside its range is a failed step);
``energy(u)``, ``gradient(u)``, ``hessian(u)``
    Π, r = ∂Π/∂u and K = ∂²Π/∂u² (scipy sparse, symmetric) at the current parameter;

and optionally

``parameter_derivative(u)``
    g_λ = ∂r/∂λ at the current parameter (default: a central difference in λ,
    two gradient evaluations);
``dof_weights()``
    per-unknown weights of the arclength norm (default: ones);
``parameter_scale``
    the scale of λ in the arclength norm (default 1);
``accept(u)``
    called after every accepted step (path-dependent loads).

:class:`LoadParameter` (λ = ``model.load_factor``) and :class:`GrowthParameter`
(λ = anything that defines a :class:`~femshell.shell.RestState`) adapt a
:class:`~femshell.shell.ShellModel`.

Algorithm (:func:`continuation`)
--------------------------------
The branch r(u, λ) = 0 is parametrised by the pseudo-arclength s in the weighted norm

.. math:: \|(\delta u, \delta\lambda)\|^2 = \frac1n \sum_i w_i\, \delta u_i^2
          + \left(\frac{\delta\lambda}{\lambda_{\rm scale}}\right)^2

(an RMS norm over the n unknowns, so that ``ds`` does not depend on the mesh; the default
weights of the shell adapters are 1/L² for positions, L the size of the mesh, and 1 for
edge angles: every term is dimensionless and O(1) for O(1) changes). For buckling give the
adapters ``length_scale=thickness``: buckles grow on the scale of the thickness, and with
L = mesh size a post-buckled branch is so steep in this norm (λ changes by O(1)·λ_scale while
|δu|/L is 1e-3) that the first corrector after a branch switch leaves its neighbourhood.

* **Tangent** t = (t_u, t_λ): the solution of the bordered system
  [[K, g_λ], [t_prevᵀW, t_prev,λ w_λ]] t = [0, 1], normalised; so its orientation follows
  the previous tangent, and dλ/ds = t_λ changes sign exactly at a fold.
* **Predictor** (u, λ) + ds·t; **corrector**: Newton on r = 0 together with the hyperplane
  ⟨(u, λ) − predictor, t⟩_W = 0. Each bordered solve uses ONE factorisation of K and two
  right-hand sides, K x₁ = −r and K x₂ = −g_λ, then the Schur complement
  Δλ = (−N − cᵀx₁)/(d + cᵀx₂), Δu = x₁ + Δλ x₂. When K cannot be factorised, the Schur
  complement is negligible against its terms, or the bordered residual of that solution is
  not small (cancellation near a singular K), the full (n+1) bordered matrix is solved
  with SuperLU instead.
* **Step control**: ds grows by ``grow`` after a corrector that converged in at most
  ``fast_iterations`` iterations, and is halved after a failure (no convergence, divergence,
  a corrector that moved more than ``ds`` from the predictor, a tangent that turned by
  more than ``max_turn_deg``, or a parameter value the problem refuses: a ValueError from
  ``set_parameter`` or ``parameter_derivative``, e.g. a growth strain <= -1). Below
  ``ds_min`` the continuation stops with a message (``Branch.status == "ds_min"``).
* **Stability** at every accepted point: the inertia of K (symmetric-indefinite LDLᵀ,
  Sylvester's law) gives the number of negative eigenvalues; the ``n_eigs`` eigenvalues
  of smallest magnitude (shift-invert Lanczos about 0 on the same factorisation;
  Euclidean metric: their signs and zeros are what matter, their sizes depend on the
  unknowns' units) are recorded too. While the state is stable these are the smallest
  eigenvalues; once it is not, the ones nearest zero are what announces the next
  crossing (the most negative ones say little and cost shift after shift to isolate).
* **Special points** between two accepted points A, B (:class:`SpecialPoint`):

  - *fold* (limit point, "LP"): dλ/ds changes sign; located by Illinois (safeguarded
    regula falsi) on t_λ as a function of the arclength from A;
  - *branch point* ("BP"): the number of negative eigenvalues changes without a fold;
    located by Illinois on the eigenvalue that crosses zero; several crossings in one step
    are located one after the other;
  - *possible symmetric bifurcation* ("BP?"): an eigenvalue dips towards zero between
    three accepted points and comes back without changing sign (a crossing pair missed by
    the step, or a tangency): flagged, with the point at the vertex of the fitted parabola.

  Each carries the critical eigenvector(s) and the **multiplicity**: the number of
  eigenvalues whose straight-line extrapolation crosses zero within ``cluster_tol`` ×
  max(|λ*|, λ_scale) (in parameter units along the branch) of the located point — the two
  modes cos nθ, sin nθ of a disk count as one double branch point.
* **Stopping**: ``lam_stop`` (the last point is placed exactly on it by a corrector at
  fixed λ), ``max_steps``, a fold or branch point (``stop_at``), ``ds_min``, or
  ``callback`` returning a true value.

:func:`switch_branch` starts a new branch at a branch point from (u*, λ*) + a·t_new, t_new the
chosen critical mode (or combination of modes) made W-orthogonal to the old tangent, and
corrects on the hyperplane orthogonal to t_new, so the old branch cannot be re-found.

Output: a :class:`Branch` with the table (one row per accepted point and per special
point), ``to_csv``, ``save_special_points(dir, mesh_writer)`` (the writer is the caller's:
no mesh I/O here) and ``table`` columns for :func:`femshell.viz.bifurcation_diagram`.

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

from __future__ import annotations

import csv
import io
import json
import math
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .._checks import finite, integer
from .linear import LinearSolverError, factorize
from .newton import NewtonError, check_unknowns, minimize

__all__ = ["continuation", "switch_branch", "Branch", "SpecialPoint", "LoadParameter", "GrowthParameter",
           "ContinuationError"]

#: up to this many unknowns the smallest eigenvalues come from a dense eigensolver
DENSE_EIG_LIMIT = 50
#: shift (times max|diag K|) of the eigensolver when K itself cannot be factorised
SHIFT = 1e-10
#: relative accuracy asked of the Lanczos eigenvalues (shift-invert Ritz residuals)
EIG_TOL = 1e-12
#: an eigenvalue below this fraction of max|diag K| at both ends of a step is a null mode, not a crossing
NULL_EIG_TOL = 1e-10
LABELS = {"fold": "LP", "branch": "BP", "possible_branch": "BP?"}


class ContinuationError(RuntimeError):
    """The continuation could not start (the first point did not converge, bad arguments)."""


# =============================================================================== adapters

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
        h = self.fd_step * max(abs(lam), self.parameter_scale)
        self.set_parameter(lam + h)
        gp = self.model.gradient(u)
        self.set_parameter(lam - h)
        gm = self.model.gradient(u)
        self.set_parameter(lam)
        return (gp - gm) / (2.0 * h)


# =============================================================================== results

@dataclass
class SpecialPoint:
    """A fold ("fold"), branch point ("branch") or possible symmetric bifurcation ("possible_branch").

    ``located``: False when the point was detected (dλ/ds or the inertia changed sign over a
    step) but its location failed; it is then reported at the step's end, with ``bracket`` the
    step's parameter range, no ``modes`` and ``info["reason"]``.
    ``u``, ``parameter``: the state; ``tangent``: (t_u, t_λ) of the branch there;
    ``eigenvalues``: the eigenvalues of K nearest zero there, ascending; ``modes``: (n, multiplicity) the
    critical eigenvector(s) (Euclidean-orthonormal, each with its largest entry positive);
    ``n_negative_before/after``: the
    inertia on either side; ``bracket``: the parameter values of the final bracket;
    ``s``: arclength from the start of the branch; ``step``: index of the last accepted
    step before it.
    """

    kind: str
    parameter: float
    s: float
    u: np.ndarray
    tangent: tuple
    eigenvalues: np.ndarray
    modes: np.ndarray
    multiplicity: int
    n_negative_before: int | None
    n_negative_after: int | None
    step: int
    bracket: tuple = (math.nan, math.nan)
    located: bool = True
    info: dict = field(default_factory=dict)
    weights: np.ndarray | None = field(default=None, repr=False)
    parameter_scale: float = 1.0

    @property
    def label(self) -> str:
        return LABELS.get(self.kind, self.kind)

    def summary(self) -> str:
        if not self.located:
            return (f"{self.label} between parameters {self.bracket[0]:.10g} and {self.bracket[1]:.10g}, not located "
                    f"({self.info.get('reason', '')}), negative eigenvalues {self.n_negative_before} -> "
                    f"{self.n_negative_after}")
        return (f"{self.label} at parameter {self.parameter:.10g} (s = {self.s:.6g}), multiplicity "
                f"{self.multiplicity}, negative eigenvalues {self.n_negative_before} -> {self.n_negative_after}, "
                f"eigenvalues {np.array2string(np.asarray(self.eigenvalues)[:6], precision=3)}")


class Branch:
    """A followed branch: table rows, states, special points, and why it stopped.

    ``rows``: list of dicts, one per accepted point and per located special point, in
    arclength order (a point detected but not located labels the row of the step's end),
    with ``step, s, parameter, energy, n_negative, stable, eig_0..
    (eigenvalues nearest zero, ascending),
    dlam_ds, ds, iterations, special ("", "LP", "BP", "BP?"), branch, wall_s`` and the
    columns of ``record(u)``. ``states``: the matching ``(u, lam)`` (None entries when
    ``keep_states=False``; the last point is always kept). ``status``: ``"lam_stop"``,
    ``"max_steps"``, ``"fold"``, ``"branch"``, ``"ds_min"``, ``"callback"``;
    ``message`` says more; ``origin``: the :class:`SpecialPoint` a branch made by
    :func:`switch_branch` starts from (else None).
    """

    def __init__(self, label="branch", weights=None, parameter_scale=1.0):
        self.label = label
        self.rows: list[dict] = []
        self.states: list = []
        self.special_points: list[SpecialPoint] = []
        self.status = "running"
        self.message = ""
        self.weights = weights
        self.parameter_scale = parameter_scale
        self.wall_s = 0.0
        self.origin: SpecialPoint | None = None   # the branch point a switched branch starts from
        self._last = None

    def __len__(self):
        return len(self.rows)

    def __repr__(self):
        return (f"Branch({self.label!r}, {len(self.rows)} rows, {len(self.special_points)} special points, "
                f"status={self.status!r})")

    @property
    def columns(self) -> list:
        keys = []
        for r in self.rows:
            keys += [k for k in r if k not in keys]
        return keys

    @property
    def table(self) -> dict:
        """Columns as a dict of lists (the input format of :func:`femshell.viz.bifurcation_diagram`)."""
        return {k: [r.get(k) for r in self.rows] for k in self.columns}

    def column(self, name, special=True) -> np.ndarray:
        """One column as a float array; ``special=False`` leaves out the special-point rows."""
        return np.array([np.nan if r.get(name) is None else r.get(name) for r in self.rows
                         if special or not r.get("special")], dtype=float)

    @property
    def last(self):
        """(u, lam) of the last accepted point (also inside a callback; None before the first)."""
        return self._last

    def to_csv(self, path) -> Path:
        """Write the table as CSV atomically (temporary file in the same directory, then os.replace)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        buf = io.StringIO()
        cols = self.columns
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(cols)
        for r in self.rows:
            w.writerow([_csv_value(r.get(k)) for k in cols])
        _atomic_text(path, buf.getvalue())
        return path

    def save_special_points(self, directory, mesh_writer=None, prefix=None) -> list:
        """Write every special point: ``mesh_writer(stem, u, modes)`` and a JSON summary.

        ``mesh_writer(stem: Path, u: ndarray, modes: dict[str, ndarray])`` gets the
        file stem ``directory/<prefix>-special-<k>-<kind>`` (it adds its own extension),
        the state and the critical modes (``"mode_0"``, ...) as vectors of the problem's
        unknowns; it writes whatever mesh file it likes and may return its path.
        ``directory/<prefix>-special-points.json`` lists kind, parameter, multiplicity,
        eigenvalues, inertia and the file of each point. Returns the list of what the
        writer returned (stems when it returned None).
        """
        directory = Path(directory)
        directory.mkdir(parents=True, exist_ok=True)
        prefix = prefix or _slug(self.label)
        out, meta = [], []
        for k, p in enumerate(self.special_points):
            stem = directory / f"{prefix}-special-{k:02d}-{p.kind}"
            written = None
            if mesh_writer is not None:
                modes = {f"mode_{j}": p.modes[:, j] for j in range(p.modes.shape[1])}
                written = mesh_writer(stem, p.u, modes)
            out.append(written if written is not None else stem)
            meta.append({"kind": p.kind, "label": p.label, "parameter": p.parameter, "s": p.s,
                         "multiplicity": p.multiplicity, "n_negative_before": p.n_negative_before,
                         "n_negative_after": p.n_negative_after, "located": p.located,
                         "bracket": [_json_float(x) for x in p.bracket],
                         "eigenvalues": [_json_float(x) for x in np.asarray(p.eigenvalues)],
                         "step": p.step, "file": str(out[-1])})
        _atomic_text(directory / f"{prefix}-special-points.json", json.dumps(
            {"branch": self.label, "status": self.status, "special_points": meta}, indent=1))
        return out


def _slug(s):
    return "".join(c if c.isalnum() or c in "-_" else "-" for c in str(s)) or "branch"


def _csv_value(v):
    if v is None:
        return ""
    if isinstance(v, (bool, np.bool_)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    return v


def _json_float(x):
    x = float(x)
    return x if math.isfinite(x) else None


def _atomic_text(path: Path, text: str):
    # a crash mid-write must not leave half a table where a whole one was
    from ..io import atomic_write_text

    atomic_write_text(path, text)


# =============================================================================== engine

#: crossings located per step; more in one step are reported, not located
MAX_CROSSINGS_PER_STEP = 8


class _StepFailure(Exception):
    pass


class _SingularTangent(_StepFailure):
    """The bordered system of the tangent is singular (at a fold or branch point)."""


@dataclass
class _Point:
    u: np.ndarray
    lam: float
    iterations: int = 0
    K: object = None
    fac: object = None
    t_u: np.ndarray | None = None
    t_lam: float = math.nan
    n_negative: int | None = None
    eigenvalues: np.ndarray | None = None    # the ones nearest zero, ascending
    eigenvectors: np.ndarray | None = None
    eig_offset: int | None = None            # eigenvalues[i] is the (eig_offset + i)-th smallest
    energy: float = math.nan
    tangent_failed: bool = False
    # both join the branch's residual scale when the point is accepted (not for trial or location points)
    predictor_residual: float = 0.0
    parameter_residual: float = 0.0          # |∂r/∂λ| · parameter_scale


class _Engine:
    """Residuals, bordered solves, corrector and point evaluation for one problem and norm."""

    def __init__(self, problem, weights, parameter_scale, *, backend, rtol, atol, xtol, max_iter, fd_step,
                 n_eigs, log):
        self.p = problem
        self.lam_scale = float(parameter_scale)
        self.w = np.asarray(weights, float)
        self.n = len(self.w)
        self.wl = 1.0 / self.lam_scale**2
        self.backend = backend
        self.rtol, self.atol, self.xtol = rtol, atol, xtol
        self.max_iter = max_iter
        self.fd_step = fd_step
        self.n_eigs = n_eigs
        self.log = log
        self.rscale = 0.0
        self._lam = None
        self._fac = None
        self.counts = {"gradient": 0, "hessian": 0, "factorize": 0, "bordered_full": 0, "eigen": 0}

    # ---- problem access
    def diagnose(self, P):
        """The problem's reading of point P (``problem.diagnose``, optional; see minimize), or None."""
        diagnose = getattr(self.p, "diagnose", None)
        if not callable(diagnose):
            return None
        self.set(P.lam)
        return diagnose(P.u)

    def set(self, lam):
        if lam != self._lam:
            try:
                self.p.set_parameter(lam)
            except ValueError as exc:   # outside the parameter's range (a growth strain <= -1): a failed step
                self._lam = None
                raise _StepFailure(f"the problem refused parameter {lam:.9g}: {exc}") from None
            self._lam = lam

    def residual(self, u, lam):
        self.set(lam)
        self.counts["gradient"] += 1
        r = np.asarray(self.p.gradient(u), float)
        if r.shape != (self.n,):
            raise ValueError(f"problem.gradient(u) returned shape {r.shape} for {self.n} unknowns; it must return "
                             f"one value per unknown (is u0 the problem's vector of unknowns?)")
        return r

    def dlam(self, u, lam):
        self.set(lam)
        if hasattr(self.p, "parameter_derivative"):
            try:
                gl = np.asarray(self.p.parameter_derivative(u), float)
            except ValueError as exc:   # its difference step left the parameter's range
                self._lam = None        # the problem's parameter may be left at the refused value
                raise _StepFailure(f"∂r/∂λ at parameter {lam:.9g}: {exc}") from None
            if gl.shape != (self.n,):
                raise ValueError(f"problem.parameter_derivative(u) returned shape {gl.shape} for {self.n} unknowns")
            return gl
        h = self.fd_step * max(abs(lam), self.lam_scale)
        gp = self.residual(u, lam + h)
        gm = self.residual(u, lam - h)
        self.set(lam)
        return (gp - gm) / (2.0 * h)

    def hessian(self, u, lam):
        self.set(lam)
        self.counts["hessian"] += 1
        K = sp.csr_matrix(self.p.hessian(u))
        if K.shape != (self.n, self.n):
            raise ValueError(f"problem.hessian(u) returned shape {K.shape} for {self.n} unknowns; it must be "
                             f"({self.n}, {self.n})")
        return K

    def factor(self, K):
        """Symmetric-indefinite factorisation of K, or None when K is (numerically) singular."""
        self.counts["factorize"] += 1
        try:
            self._fac = factorize(K, kind="symmetric_indefinite", backend=self.backend, reuse=self._fac)
            return self._fac
        except LinearSolverError:
            if self._fac is not None:
                try:
                    self._fac.free()
                except Exception:
                    pass
            self._fac = None
            return None

    # ---- norm
    def dot(self, au, al, bu, bl):
        return float(au @ (self.w * bu)) / self.n + self.wl * al * bl

    def norm(self, au, al):
        return math.sqrt(max(self.dot(au, al, au, al), 0.0))

    def border(self, t_u, t_lam):
        """Row (c, d) of the constraint ⟨(δu, δλ), t⟩_W."""
        return self.w * t_u / self.n, self.wl * t_lam

    # ---- linear algebra
    def solve_bordered(self, K, fac, gl, c, d, rhs_u, rhs_l):
        """Solve [[K, gl], [cᵀ, d]] [du; dl] = [rhs_u; rhs_l] (rhs_u None: zero).

        Block elimination on the factorisation of K (two right-hand sides), with up to two
        steps of iterative refinement on the bordered residual (cheap: the same factor);
        the full bordered matrix is solved only when that does not give a residual below
        1e-8 of the terms, K could not be factorised, or the Schur complement vanishes.
        """
        if fac is not None:
            try:
                n = K.shape[0]
                cvec = c if np.ndim(c) else np.zeros(n)
                bu = np.zeros(n) if rhs_u is None else np.asarray(rhs_u, float)
                x2 = -fac.solve(gl)
                cx2 = float(cvec @ x2)
                schur = d + cx2
                size = abs(d) + np.linalg.norm(cvec) * np.linalg.norm(x2)
                if np.isfinite(schur) and abs(schur) > 1e-12 * size:
                    du, dl = np.zeros(n), 0.0
                    ru, rl = bu, float(rhs_l)
                    for _ in range(3):
                        x1 = fac.solve(ru) if np.any(ru) else np.zeros(n)
                        ddl = (rl - float(cvec @ x1)) / schur
                        du, dl = du + x1 + ddl * x2, dl + ddl
                        Kdu = K @ du
                        ru = bu - Kdu - gl * dl
                        rl = float(rhs_l) - float(cvec @ du) - d * dl
                        ref = max(np.linalg.norm(bu), np.linalg.norm(Kdu), np.linalg.norm(gl) * abs(dl), 1e-300)
                        if not np.all(np.isfinite(du)):
                            break
                        if np.linalg.norm(ru) <= 1e-8 * ref:
                            return du, dl
            except LinearSolverError:
                pass
        return self._full_bordered(K, gl, c, d, rhs_u, rhs_l)

    def _full_bordered(self, K, gl, c, d, rhs_u, rhs_l):
        self.counts["bordered_full"] += 1
        n = K.shape[0]
        crow = np.zeros(n) if not np.ndim(c) else c
        A = sp.bmat([[K, sp.csr_matrix(gl.reshape(-1, 1))],
                     [sp.csr_matrix(crow.reshape(1, -1)), sp.csr_matrix(np.array([[d]]))]], format="csc")
        b = np.concatenate([np.zeros(n) if rhs_u is None else rhs_u, [rhs_l]])
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                x = spla.splu(A).solve(b)
        except RuntimeError as exc:
            raise _SingularTangent(f"the bordered system is singular ({exc})") from None
        res = A @ x - b
        if not np.all(np.isfinite(x)) or np.linalg.norm(res) > 1e-6 * max(np.linalg.norm(b), np.linalg.norm(A @ x),
                                                                          1e-300):
            raise _SingularTangent("the bordered system is numerically singular")
        return x[:n], float(x[n])

    def eigs(self, K, k, vectors=False, fac=None):
        """The k eigenvalues of K nearest zero, ascending: (w, V or None, offset).

        ``w[i]`` is the (offset + i)-th smallest eigenvalue of K (offset from the inertia),
        V the orthonormal eigenvectors. Shift-invert Lanczos about 0 reuses ``fac`` (a
        symmetric-indefinite factorisation of K) when given; otherwise K − σI, σ a tiny
        negative shift, is factorised. (None, None, None) when the eigensolver fails.
        """
        n = K.shape[0]
        k = int(min(k, n))
        if k <= 0:
            return None, None, None
        self.counts["eigen"] += 1
        own = None
        try:
            if n <= DENSE_EIG_LIMIT or k >= n - 1:
                w, v = sla.eigh(K.toarray())
                sel = np.sort(np.argsort(np.abs(w), kind="stable")[:k])
                return w[sel], (v[:, sel] if vectors else None), int(sel[0])
            sigma = 0.0
            if fac is None or fac.inertia is None:
                sigma = -SHIFT * np.abs(K.diagonal()).max()
                own = factorize(K - sigma * sp.identity(n, format="csr"), kind="symmetric_indefinite",
                                backend=self.backend, allow_singular=True)
                fac = own
            below = None if fac.inertia is None else int(fac.inertia[1])
            op = spla.LinearOperator((n, n), matvec=fac.solve, matmat=fac.solve, dtype=float)
            # tol: ARPACK's default (machine precision) costs 5-20x more Lanczos iterations on
            # clustered shell spectra (cos/sin pairs) for the same printed digits (measured)
            # a fixed start vector: ARPACK's default is random, and runs should repeat bit for bit
            v0 = np.random.default_rng(0).standard_normal(n)
            w, v = spla.eigsh(K, k=k, sigma=sigma, which="LM", OPinv=op, tol=EIG_TOL, v0=v0)
            order = np.argsort(w)
            w, v = w[order], v[:, order]
            offset = None if below is None else below - int((w < sigma).sum())
            return w, (v if vectors else None), offset
        except Exception as exc:  # ARPACK non-convergence, singular shift
            if self.log:
                self.log(f"    continuation: eigensolver failed ({type(exc).__name__}: {exc})")
            return None, None, None
        finally:
            if own is not None:
                own.free()

    # ---- corrector
    def correct(self, u_p, lam_p, t=None, lam_fixed=None, max_dist=None, update_scale=True):
        """Newton from the predictor on r = 0 and the hyperplane ⟂ t (or at fixed λ). Raises _StepFailure.

        Converged when |r| ≤ rtol · scale + atol, scale the largest of this corrector's first
        residual, the predictor residuals of the accepted steps and |g_λ| · parameter_scale seen
        on the branch, or when the Newton correction is below xtol in the weighted norm. The
        point carries its first residual (``predictor_residual``; 0 with ``update_scale=False``,
        for a start far from equilibrium) for the caller to add to the scale on acceptance.
        """
        u = np.array(u_p, float)
        lam = float(lam_p if lam_fixed is None else lam_fixed)
        if t is None and lam_fixed is None:
            raise ValueError("correct needs a tangent or a fixed parameter")
        c, d = (0.0, 1.0) if lam_fixed is not None else self.border(*t)
        last_step = math.inf
        res0 = None
        K = fac = None
        for it in range(self.max_iter + 1):
            r = self.residual(u, lam)
            res = float(np.linalg.norm(r))
            if not np.isfinite(res):
                raise _StepFailure(f"non-finite residual at corrector iteration {it}")
            if res0 is None:
                res0 = res
                scale = max(self.rscale, res)
            if res <= self.rtol * scale + self.atol or last_step <= self.xtol:
                break
            if it == self.max_iter:
                raise _StepFailure(f"corrector did not converge in {self.max_iter} iterations "
                                   f"(|r| = {res:.3e}, last correction {last_step:.2e})")
            if it >= 2 and res > 1e3 * max(res0, 1e-300):
                raise _StepFailure(f"corrector diverges (|r| {res0:.2e} -> {res:.2e})")
            gl = self.dlam(u, lam)
            K = self.hessian(u, lam)
            fac = self.factor(K)
            if lam_fixed is not None:
                N = lam - lam_fixed
            else:
                N = self.dot(t[0], t[1], u - u_p, lam - lam_p)
            du, dl = self.solve_bordered(K, fac, gl, c, d, -r, -N)
            if lam_fixed is not None:
                dl = 0.0
            u = u + du
            lam = lam + dl
            last_step = self.norm(du, dl)
            if not np.isfinite(last_step):
                raise _StepFailure("non-finite Newton correction")
            if max_dist is not None and self.norm(u - u_p, lam - lam_p) > max_dist:
                raise _StepFailure(f"corrector left the neighbourhood of the predictor "
                                   f"(distance {self.norm(u - u_p, lam - lam_p):.3g} > {max_dist:.3g})")
        P = _Point(u, lam, iterations=it, predictor_residual=res0 if update_scale else 0.0)
        if K is not None and last_step <= self.xtol:
            P.K, P.fac = K, fac  # the last Hessian was taken a negligible distance away
        return P

    def finish(self, P, ref=None, direction=1.0, n_eigs=None, vectors=False):
        """Hessian, inertia, tangent (oriented along ``ref`` or ``direction``), eigenvalues, energy."""
        if P.K is None:
            P.K = self.hessian(P.u, P.lam)
            P.fac = self.factor(P.K)
        fac = P.fac
        P.n_negative = None
        if fac is not None and fac is not self._fac:
            fac = None  # refactored since: not this point's factorisation
        if fac is not None and fac.inertia is not None:
            P.n_negative = int(fac.inertia[1])
        gl = self.dlam(P.u, P.lam)
        if ref is None:
            c, d = 0.0, self.wl * direction
        else:
            c, d = self.border(*ref)
        try:
            z, tau = self.solve_bordered(P.K, fac, gl, c, d, None, 1.0)
            nt = self.norm(z, tau)
            if not (np.isfinite(nt) and nt > 0):
                raise _SingularTangent("zero tangent")
            P.t_u, P.t_lam = z / nt, tau / nt
        except _StepFailure:
            if ref is None:
                raise
            # exactly at a singular point (a pitchfork makes the bordered matrix singular too):
            # keep the reference tangent
            P.t_u, P.t_lam = ref[0].copy(), float(ref[1])
            P.tangent_failed = True
        P.parameter_residual = float(np.linalg.norm(gl)) * self.lam_scale
        k = self.n_eigs if n_eigs is None else n_eigs
        if k > 0:
            P.eigenvalues, P.eigenvectors, P.eig_offset = self.eigs(P.K, k, vectors=vectors, fac=fac)
            if P.n_negative is None and P.eigenvalues is not None and P.eig_offset is not None:
                P.n_negative = P.eig_offset + int((P.eigenvalues < 0).sum())
        self.set(P.lam)
        P.energy = float(self.p.energy(P.u))
        P.fac = None  # the shared factorisation object is refactored by the next point
        return P

    def release(self):
        if self._fac is not None:
            try:
                self._fac.free()
            except Exception:
                pass
            self._fac = None


# =============================================================================== continuation

def continuation(problem, u0, lam0, *, ds, ds_min=None, ds_max=None, lam_stop=None, max_steps=200, weights=None,
                 parameter_scale=None, direction=+1, record=None, callback=None, detect=True, log=print,
                 n_eigs=3, stop_at=(), initial_tangent=None, label="branch", keep_states=True,
                 rtol=1e-8, atol=0.0, xtol=1e-9, max_corrector_iterations=8, fast_iterations=3, grow=1.5,
                 max_turn_deg=35.0, locate_tol=1e-7, cluster_tol=0.01, dip_tol=0.1, fd_step=1e-6,
                 backend="auto") -> Branch:
    r"""Follow the equilibrium branch of ``problem`` through (u0, lam0) by pseudo-arclength continuation.

    Parameters
    ----------
    problem : a parametrized problem (module docstring).
    u0, lam0 : start; u0 is first corrected to an equilibrium at lam0 (Newton), or, with
        ``initial_tangent``, on the hyperplane through (u0, lam0) orthogonal to it.
    ds, ds_min, ds_max : first, smallest and largest step in the weighted arclength
        (defaults: ds_min = ds/1000, ds_max = 10 ds).
    lam_stop : stop exactly at this parameter value (when a step crosses it).
    max_steps : number of accepted steps.
    weights : per-unknown weights of the norm, > 0 (default ``problem.dof_weights()`` or ones).
    parameter_scale : scale of λ in the norm (default ``problem.parameter_scale`` or 1).
    direction : +1 / -1: initial sense of λ (ignored with ``initial_tangent``).
    record : ``record(u) -> dict`` of extra columns (norms, point values); default:
        ``{"norm": weighted RMS norm of u}``.
    callback : ``callback(branch, row)`` after each accepted step; returning a true value stops.
    detect : locate folds, branch points and dips (needs ``n_eigs`` ≥ 1 for dips).
    n_eigs : eigenvalues of smallest magnitude recorded per step, ascending (0: none; the
        inertia, i.e. the number of negative eigenvalues, is always recorded).
    stop_at : kinds after whose detection to stop: "fold", "branch" (one, or a sequence).
    initial_tangent : (t_u, t_λ) to orient the start (used by :func:`switch_branch`).
    rtol, atol, xtol : corrector convergence, |r| ≤ rtol·scale + atol (scale: the largest
        predictor residual of the accepted steps, or |g_λ|·parameter_scale, seen on the branch)
        or a Newton correction ≤ xtol in the weighted norm.
    locate_tol : arclength tolerance of the location of special points.
    cluster_tol : relative parameter tolerance of the multiplicity count.
    dip_tol : an eigenvalue that dips below dip_tol × its neighbours' values flags "BP?".

    Returns
    -------
    Branch
    """
    t_start = time.perf_counter()
    u0 = check_unknowns(problem, u0)
    n = len(u0)
    if weights is None:
        weights = problem.dof_weights() if hasattr(problem, "dof_weights") else np.ones(n)
    weights = np.asarray(weights, float)
    if weights.ndim and weights.shape != (n,):
        raise ValueError(f"weights must be a number or one per unknown (shape ({n},)), got shape {weights.shape}")
    weights = np.broadcast_to(weights, (n,)).copy()
    if not (np.all(weights > 0) and np.all(np.isfinite(weights))):
        # a zero weight would also leave its unknown out of the corrector's step test (xtol)
        raise ValueError("weights must be finite and > 0 (a small weight makes an unknown count little in the "
                         "arclength)")
    if parameter_scale is None:
        parameter_scale = getattr(problem, "parameter_scale", 1.0)
    parameter_scale = finite("parameter_scale", parameter_scale, 0.0, lo_open=True, text="(0, inf)")
    lam0 = finite("lam0", lam0)
    if lam_stop is not None:
        lam_stop = finite("lam_stop", lam_stop, text="(-inf, inf), or None")
    ds = finite("ds", ds, 0.0, lo_open=True, text="(0, inf)")
    ds_min = ds / 1000.0 if ds_min is None else float(ds_min)
    ds_max = 10.0 * ds if ds_max is None else float(ds_max)
    if not (0 < ds_min <= ds <= ds_max < math.inf):
        raise ValueError(f"need 0 < ds_min <= ds <= ds_max < inf, got {ds_min}, {ds}, {ds_max}")
    if direction not in (1, -1):
        raise ValueError(f"direction must be +1 or -1, got {direction}")
    grow, max_turn_deg, rtol, atol, xtol, locate_tol, fd_step, cluster_tol, dip_tol = (
        finite(name, v, lo, hi) for name, v, lo, hi in (
            ("grow", grow, 1, 100), ("max_turn_deg", max_turn_deg, 1e-6, 180), ("rtol", rtol, 0, 1),
            ("atol", atol, 0, None), ("xtol", xtol, 0, 1), ("locate_tol", locate_tol, 0, None),
            ("fd_step", fd_step, 1e-14, 0.1), ("cluster_tol", cluster_tol, 0, 1), ("dip_tol", dip_tol, 0, 1)))
    max_steps, n_eigs, max_corrector_iterations, fast_iterations = (
        integer(name, v, lo, f"an integer in [{lo}, {hi}]", hi) for name, v, lo, hi in (
            ("max_steps", max_steps, 0, 10**7), ("n_eigs", n_eigs, 0, 1000),
            ("max_corrector_iterations", max_corrector_iterations, 1, 1000), ("fast_iterations", fast_iterations, 0, 1000)))
    n_eigs = min(n_eigs, n)   # a table column per eigenvalue: no more than there are
    stop_at = (stop_at,) if isinstance(stop_at, str) else tuple(stop_at)
    bad = set(stop_at) - {"fold", "branch"}
    if bad:
        raise ValueError(f"stop_at kinds must be among 'fold', 'branch', got {sorted(bad)}")
    log = log or None
    eng = _Engine(problem, weights, parameter_scale, backend=backend, rtol=rtol, atol=atol, xtol=xtol,
                  max_iter=max_corrector_iterations, fd_step=fd_step, n_eigs=n_eigs, log=log)
    branch = Branch(label, weights, parameter_scale)
    if record is None:
        def record(u):
            return {"norm": eng.norm(u, 0.0)}
    cos_max = math.cos(math.radians(max_turn_deg))

    # ---- the first point
    try:
        if initial_tangent is None:
            # Newton at fixed λ finds the equilibrium next to u0 whatever its stability; only
            # if that fails, a minimisation (line search, shifts) looks for a stable one
            try:
                A = eng.correct(u0, lam0, lam_fixed=lam0, update_scale=False)
            except _StepFailure:
                eng.set(lam0)
                try:
                    u_start = minimize(problem, u0, rtol=1e-10, log=None, backend=backend).u
                except NewtonError as exc:
                    raise _StepFailure(f"Newton and minimisation failed ({exc})") from None
                A = eng.correct(u_start, lam0, lam_fixed=lam0, update_scale=False)
            try:
                A = eng.finish(A, None, direction)
            except _SingularTangent as exc:     # released below, as any error of the first point
                raise ContinuationError(f"the first point at parameter {lam0:.6g} is an equilibrium without a tangent "
                                        f"there: a singular point (fold or branch point); start beside it or give "
                                        f"initial_tangent ({exc})") from None
        else:
            t0u = np.asarray(initial_tangent[0], float)
            t0l = float(initial_tangent[1])
            nt = eng.norm(t0u, t0l) if t0u.shape == (n,) else math.nan
            if not (math.isfinite(nt) and nt > 0):
                eng.release()
                raise ValueError(f"initial_tangent must be (t_u of {n} unknowns, t_λ), finite and not zero")
            t0 = (t0u / nt, t0l / nt)
            A = eng.correct(u0, lam0, t=t0, update_scale=False)
            A = eng.finish(A, t0)
    except _StepFailure as exc:
        eng.release()
        raise ContinuationError(f"the first point at parameter {lam0:.6g} did not converge ({exc})") from None
    except BaseException:
        eng.release()
        raise
    branch._last = (A.u, A.lam)
    eng.rscale = max(eng.rscale, A.parameter_residual)

    if lam_stop is not None:
        if abs(lam_stop - A.lam) <= 1e-12 * max(abs(lam_stop), parameter_scale):
            eng.release()
            raise ValueError(f"lam_stop = {lam_stop:.9g} is the start's parameter: nothing to follow")
        if (lam_stop - A.lam) * A.t_lam < 0 and log:
            log(f"  continuation '{label}': lam_stop = {lam_stop:.9g} lies behind the start ({A.lam:.9g}) in the "
                "branch's direction: reached only after a fold (direction=-1 goes there directly)")

    ctx = _Context(eng, branch, record, keep_states, n_eigs, locate_tol, cluster_tol, dip_tol, log, t_start)
    ctx.add_row(A, 0.0, 0, ds=0.0)
    if log:
        log(f"  continuation '{label}': start at parameter {A.lam:.8g}, dλ/ds {A.t_lam:+.3g}, "
            f"negative eigenvalues {A.n_negative}")
    history = [(A, 0.0)]  # (point, s) of the accepted points (last three)
    s = 0.0
    step = 0
    reason = ""
    stop = None
    try:
        while True:
            if step >= max_steps:
                stop = ("max_steps", f"{max_steps} steps done")
                break
            u_p = A.u + ds * A.t_u
            lam_p = A.lam + ds * A.t_lam
            try:
                B = eng.correct(u_p, lam_p, t=(A.t_u, A.t_lam), max_dist=ds)
                B = eng.finish(B, (A.t_u, A.t_lam))
                turn = eng.dot(A.t_u, A.t_lam, B.t_u, B.t_lam)
                if turn < cos_max:
                    raise _StepFailure(f"tangent turned by {math.degrees(math.acos(max(-1, min(1, turn)))):.0f} "
                                       f"degrees")
            except _StepFailure as exc:
                reason = str(exc)
                ds *= 0.5
                if log:
                    log(f"    step from parameter {A.lam:.8g} failed ({reason}); ds -> {ds:.3g}")
                if ds < ds_min:
                    why = eng.diagnose(A)
                    stop = ("ds_min", f"step size fell below ds_min = {ds_min:.3g} at parameter {A.lam:.8g} "
                                      f"(last failure: {reason})" + (f". At the last accepted point {why}" if why else ""))
                    break
                continue
            sigma_B = eng.dot(A.t_u, A.t_lam, B.u - A.u, B.lam - A.lam)
            landed = None      # at lam_stop: "exactly", or "missed" when the step crossed it but landing failed
            near = lam_stop is not None and abs(B.lam - lam_stop) <= 1e-9 * max(abs(lam_stop), eng.lam_scale)
            if near:
                landed = "exactly"
            elif lam_stop is not None and A.lam != lam_stop and (A.lam - lam_stop) * (B.lam - lam_stop) <= 0:
                L = _land(eng, A, B, lam_stop, ds)
                if L is not None:
                    B = L
                    sigma_B = eng.dot(A.t_u, A.t_lam, B.u - A.u, B.lam - A.lam)
                    landed = "exactly"
                else:
                    landed = "missed"
            step += 1
            found = []
            if detect:
                found = ctx.detect(A, B, s, sigma_B, step - 1, history)
            eng.set(B.lam)     # the location's trial points moved the problem's parameter
            s += sigma_B
            ctx.add_row(B, s, step, ds=sigma_B,
                        special=next((p.label for p in found if p.info.get("at_step_end")), ""))
            if hasattr(problem, "accept"):
                problem.accept(B.u)
            if log:
                ev = "" if B.eigenvalues is None else f"  eig {np.array2string(B.eigenvalues[:3], precision=3)}"
                log(f"  step {step:3d}  parameter {B.lam:.8g}  ds {sigma_B:.3g}  it {B.iterations}  "
                    f"dλ/ds {B.t_lam:+.3g}  n_neg {B.n_negative}{ev}")
            history = (history + [(B, s)])[-3:]
            A = B
            branch._last = (A.u, A.lam)
            # only accepted steps: a diverged trial's residual must not loosen the later tests
            eng.rscale = max(eng.rscale, B.predictor_residual, B.parameter_residual)
            if callback is not None and bool(callback(branch, branch.rows[-1])):   # np.True_ and 1 stop too
                stop = ("callback", "the callback asked to stop")
                break
            if landed == "exactly":
                stop = ("lam_stop", f"reached parameter {B.lam:.10g}")
                break
            if landed == "missed":
                stop = ("lam_stop", f"the step crossed lam_stop = {lam_stop:.10g} but the corrector could not land "
                                    f"on it; stopped at parameter {B.lam:.10g}")
                break
            kinds = {p.kind for p in found}
            if "fold" in stop_at and "fold" in kinds:
                stop = ("fold", "stopped after a fold")
                break
            if "branch" in stop_at and "branch" in kinds:
                stop = ("branch", "stopped after a branch point")
                break
            if B.iterations <= fast_iterations:
                ds = min(ds * grow, ds_max)
    finally:
        try:
            eng.set(A.lam)     # a failed trial step may have left the problem at another parameter
        except _StepFailure:
            pass
        eng.release()
    branch.status, branch.message = stop
    if not keep_states and branch.states:
        branch.states[-1] = (A.u, A.lam)
    branch.wall_s = time.perf_counter() - t_start
    branch.counts = dict(eng.counts)
    if log:
        log(f"  continuation '{label}': {branch.status}: {branch.message}; {step} steps, "
            f"{len(branch.special_points)} special points, {branch.wall_s:.1f} s")
    return branch


def _land(eng, A, B, lam_stop, ds):
    """A point exactly at lam_stop: corrector at fixed λ from the tangent predictor (or from B)."""
    starts = []
    if abs(A.t_lam) > 1e-12:
        sig = (lam_stop - A.lam) / A.t_lam
        starts.append(A.u + sig * A.t_u)
    starts.append(B.u)
    for u_p in starts:
        try:
            L = eng.correct(u_p, lam_stop, lam_fixed=lam_stop, max_dist=2 * ds)
            return eng.finish(L, (A.t_u, A.t_lam))
        except _StepFailure:
            continue
    return None


class _Context:
    """Rows, detection and location of special points for one continuation run."""

    def __init__(self, eng, branch, record, keep_states, n_eigs, locate_tol, cluster_tol, dip_tol, log, t0):
        self.eng, self.branch, self.record = eng, branch, record
        self.keep_states, self.n_eigs = keep_states, n_eigs
        self.locate_tol, self.cluster_tol, self.dip_tol = locate_tol, cluster_tol, dip_tol
        self.log, self.t0 = log, t0
        self._step_end = None       # the end of the step being searched (an unlocated point is reported there)

    # ---- rows
    def add_row(self, P, s, step, ds, special=""):
        row = {"step": step, "s": s, "parameter": P.lam, "energy": P.energy, "n_negative": P.n_negative,
               "stable": None if P.n_negative is None else P.n_negative == 0}
        for i in range(self.n_eigs):
            ev = P.eigenvalues
            row[f"eig_{i}"] = float(ev[i]) if ev is not None and i < len(ev) else math.nan
        row.update({"dlam_ds": P.t_lam, "ds": ds, "iterations": P.iterations, "special": special,
                    "branch": self.branch.label, "wall_s": time.perf_counter() - self.t0})
        extra = self.record(P.u) or {}
        if not isinstance(extra, dict):
            raise TypeError(f"record(u) must return a dict of columns, got {type(extra).__name__}")
        clash = sorted(set(extra) & set(row))
        if clash:
            raise ValueError(f"record(u) returned column(s) {', '.join(clash)} that the branch table already has")
        row.update({k: (float(v) if isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
                        else v) for k, v in extra.items()})
        self.branch.rows.append(row)
        self.branch.states.append((P.u, P.lam) if self.keep_states else None)

    # ---- trial points along the step from A
    def point_at(self, A, sigma, n_eigs, cache):
        key = float(sigma)
        P = cache.get(key)
        if P is not None:
            return self._with_eigs(P, n_eigs) if n_eigs > 0 else P
        eng = self.eng
        P = eng.correct(A.u + sigma * A.t_u, A.lam + sigma * A.t_lam, t=(A.t_u, A.t_lam),
                        max_dist=max(abs(sigma), 1e-300) * 2)
        P = eng.finish(P, (A.t_u, A.t_lam), n_eigs=n_eigs)
        cache[key] = P
        return P

    def _with_eigs(self, P, k, vectors=False):
        """Make sure P has the k eigenvalues nearest zero (and vectors); K is kept on the point."""
        have = P.eigenvalues is not None and len(P.eigenvalues) >= min(k, len(P.u))
        if k <= 0 or (have and (P.eigenvectors is not None or not vectors)):
            return P
        if P.K is None:
            P.K = self.eng.hessian(P.u, P.lam)
        P.eigenvalues, P.eigenvectors, P.eig_offset = self.eng.eigs(P.K, k, vectors=vectors)
        return P

    def eig_at(self, P, j, k):
        """The j-th smallest eigenvalue of K at P (widening the window of eigenvalues near zero)."""
        n = len(P.u)
        k = max(k, 1)
        while True:
            self._with_eigs(P, k)
            if P.eigenvalues is None or P.eig_offset is None:
                raise _StepFailure("eigenvalues (or the inertia) unavailable at a trial point")
            i = j - P.eig_offset
            if 0 <= i < len(P.eigenvalues):
                return float(P.eigenvalues[i])
            if k >= n:
                raise _StepFailure(f"eigenvalue {j} not found")
            k = min(2 * k, n)

    # ---- detection
    def detect(self, A, B, s_A, sigma_B, step, history):
        found = []
        cache = {0.0: A, float(sigma_B): B}
        kind = None
        n0 = len(self.branch.special_points)
        self._step_end = B
        try:
            fold = np.isfinite(A.t_lam) and np.isfinite(B.t_lam) and A.t_lam * B.t_lam < 0
            if fold:
                kind = "fold"
                found += self._locate_fold(A, B, s_A, sigma_B, step, cache)
            elif A.n_negative is not None and B.n_negative is not None and A.n_negative != B.n_negative:
                kind = "branch"
                found += self._locate_crossings(A, 0.0, A, sigma_B, B, s_A, step, cache)
            kind = None
            if not found and self.n_eigs > 0 and len(history) >= 2:
                found += self._detect_dip(history + [(B, s_A + sigma_B)], step, cache, A, s_A)
        except _StepFailure as exc:
            found = list(self.branch.special_points[n0:])      # those located before the failure
            if kind is None:        # a possible (dip) point: nothing was crossed
                if self.log:
                    self.log(f"    location of a possible branch point failed: {exc}")
            else:
                # a located fold means what failed was a crossing beside it
                failed = "branch" if kind == "fold" and any(p.kind == "fold" for p in found) else kind
                found.append(self._unlocated(failed, A, B, s_A, sigma_B, step, f"its location failed: {exc}"))
        return found

    def _unlocated(self, kind, A, B, s_A, sigma_B, step, reason, crossings=None, n_before=None):
        """A special point detected in the step A → B but not located: reported at B, ``located=False``.

        The step's end is a converged state with the new inertia; its parameter is within the
        step of the special point (the bracket). It has no critical modes (no branch switching).
        """
        n_after = B.n_negative
        n_before = A.n_negative if n_before is None else n_before
        info = {"reason": reason}
        if crossings is not None:
            info["crossings"] = crossings
        p = SpecialPoint(kind=kind, parameter=float(B.lam), s=s_A + sigma_B, u=B.u.copy(), tangent=(B.t_u, B.t_lam),
                         eigenvalues=np.array([math.nan]) if B.eigenvalues is None else B.eigenvalues,
                         modes=np.zeros((len(B.u), 0)), multiplicity=0, n_negative_before=n_before,
                         n_negative_after=n_after, step=step, bracket=tuple(sorted((A.lam, B.lam))), located=False,
                         info=info, weights=self.eng.w, parameter_scale=self.eng.lam_scale)
        self.branch.special_points.append(p)
        if B is self._step_end:
            p.info["at_step_end"] = True        # the step's own row carries the label
        else:
            self.add_row(B, s_A + sigma_B, step, ds=sigma_B, special=p.label)
        if self.log:
            self.log(f"    {p.label} detected between parameters {A.lam:.8g} and {B.lam:.8g} but not located "
                     f"({reason}); reported at {B.lam:.8g}")
        return p

    def _illinois(self, f, a, fa, b, fb):
        """Root of f on [a, b] (fa, fb of opposite signs) by the Illinois method.

        Returns ((sigma, f, P) of the evaluated point nearest the root, (a, b) final bracket).
        """
        best = None
        side = 0
        c_prev = None
        tol = self.locate_tol
        f_scale = max(abs(fa), abs(fb))
        for _ in range(60):
            if abs(b - a) <= tol:
                break
            c = (a * fb - b * fa) / (fb - fa) if fb != fa else 0.5 * (a + b)
            lo, hi = min(a, b), max(a, b)
            if not (lo < c < hi):
                c = 0.5 * (a + b)
            elif c_prev is not None and abs(c - c_prev) <= tol:
                break                       # the estimates agree: converged (superlinearly)
            fc, Pc = f(c)
            if best is None or abs(fc) < abs(best[1]):
                best = (c, fc, Pc)
            if abs(fc) <= 1e-10 * f_scale:
                break                       # on the root: keep the sign-definite bracket
            if fc * fb > 0:
                b, fb = c, fc
                if side == -1:
                    fa *= 0.5
                side = -1
            else:
                a, fa = c, fc
                if side == +1:
                    fb *= 0.5
                side = +1
            c_prev = c
        self.last_error = abs(b - a) if c_prev is None or abs(b - a) <= tol else abs(c - c_prev)
        return best, (a, b)

    def _locate_fold(self, A, B, s_A, sigma_B, step, cache):
        def f(sig):
            P = self.point_at(A, sig, 0, cache)
            return P.t_lam, P

        best, (a, b) = self._illinois(f, 0.0, A.t_lam, sigma_B, B.t_lam)
        if best is None:
            best = (sigma_B, B.t_lam, B) if abs(B.t_lam) < abs(A.t_lam) else (0.0, A.t_lam, A)
        sig, _, P = best
        lo, hi = sorted((a, b))
        P_lo, P_hi = self.point_at(A, lo, 0, cache), self.point_at(A, hi, 0, cache)
        k = max(self.n_eigs, 4)
        sp_ = self._special("fold", A, P, sig, s_A, step, k, P_lo.n_negative, P_hi.n_negative,
                            (P_lo.lam, P_hi.lam), crit=None)
        out = [sp_]
        # other crossings in the same step, on either side of the fold
        if A.n_negative is not None and P_lo.n_negative is not None and A.n_negative != P_lo.n_negative and lo > 0:
            out = self._locate_crossings(A, 0.0, A, lo, P_lo, s_A, step, cache) + out
        if P_hi.n_negative is not None and B.n_negative is not None and P_hi.n_negative != B.n_negative \
                and hi < sigma_B:
            out += self._locate_crossings(A, hi, P_hi, sigma_B, B, s_A, step, cache)
        return out

    def _locate_crossings(self, A, sa, Pa, sb, Pb, s_A, step, cache):
        """Branch points between Pa (arclength sa from A) and Pb, where the inertia changes."""
        na, nb = Pa.n_negative, Pb.n_negative
        out = []
        up = nb > na
        j = na if up else na - 1
        k = max(self.n_eigs, 4)
        located = 0
        while (up and j < nb) or (not up and j >= nb):
            if located == MAX_CROSSINGS_PER_STEP:
                # each location costs several factorisations: 175 crossings in one step took minutes
                # each without a word; the first ones are where stability is lost
                rest = (nb - j) if up else (j - nb + 1)
                out.append(self._unlocated("branch", A, Pb, s_A, self.eng.dot(A.t_u, A.t_lam, Pb.u - A.u,
                                                                                 Pb.lam - A.lam), step,
                                           f"the inertia jumps from {na} to {nb} in one step; {located} crossings "
                                           f"are located, {rest} are not (a smaller ds_max resolves them)",
                                           crossings=rest, n_before=j if up else j + 1))
                break
            located += 1

            def f(sig, j=j):
                P = self.point_at(A, sig, k, cache)
                return self.eig_at(P, j, k), P

            fa = self.eig_at(Pa, j, k)
            fb = self.eig_at(Pb, j, k)
            scale = max(np.abs(Pa.K.diagonal()).max() if Pa.K is not None else 0.0,
                        np.abs(Pb.K.diagonal()).max() if Pb.K is not None else 0.0)
            if max(abs(fa), abs(fb)) <= NULL_EIG_TOL * scale:
                # a zero eigenvalue (a continuous symmetry) whose sign is round-off: not a crossing
                if self.log:
                    self.log(f"    the inertia changes between parameters {Pa.lam:.8g} and {Pb.lam:.8g} by "
                             f"an eigenvalue at round-off level ({fa:.2e}, {fb:.2e}): a null mode, ignored")
                j += 1 if up else -1
                continue
            if fa * fb > 0:
                out.append(self._unlocated("branch", A, Pb, s_A, self.eng.dot(A.t_u, A.t_lam, Pb.u - A.u,
                                                                                Pb.lam - A.lam), step,
                                           f"eigenvalue {j} does not change sign between parameters {Pa.lam:.8g} "
                                           f"and {Pb.lam:.8g} although the inertia does", n_before=j if up else j + 1))
                break
            best, (a, b) = self._illinois(f, sa, fa, sb, fb)
            if best is None:
                best = (sb, fb, Pb)
            sig, _, P = best
            lo, hi = sorted((a, b))
            P_lo = self.point_at(A, lo, k, cache) if lo > 0 else Pa
            P_hi = self.point_at(A, hi, k, cache)
            # the previous branch point may be the partner of this crossing (double eigenvalue)
            prev = self.branch.special_points[-1] if self.branch.special_points else None
            tol = self.cluster_tol * max(abs(P.lam), self.eng.lam_scale)
            if prev is not None and prev.kind == "branch" and abs(prev.parameter - P.lam) <= tol \
                    and prev.info.get("crossings", 1) < prev.multiplicity:
                prev.info["crossings"] = prev.info.get("crossings", 1) + 1
                prev.n_negative_after = P_hi.n_negative
                if self.log:
                    self.log(f"    crossing at parameter {P.lam:.10g} belongs to the {prev.label} at "
                             f"{prev.parameter:.10g} (multiplicity {prev.multiplicity})")
                j += 1 if up else -1
                continue
            sp_ = self._special("branch", A, P, sig, s_A, step, k, P_lo.n_negative, P_hi.n_negative,
                                (P_lo.lam, P_hi.lam), crit=j, ref=Pa if sa == 0 else P_lo)
            out.append(sp_)
            m = max(sp_.multiplicity, 1)
            # the crossings of the cluster that happen inside this bracket belong to this point; a
            # partner that crosses in a later step is merged into it there (see above)
            sp_.info["crossings"] = min(m, (nb - j) if up else (j - nb + 1))
            j += m if up else -m
        return out

    def _special(self, kind, A, P, sig, s_A, step, k, n_before, n_after, bracket, crit=None, ref=None):
        """Build a SpecialPoint at P: eigenpairs, critical mode(s), multiplicity."""
        eng = self.eng
        k = max(k, 4)
        self._with_eigs(P, k, vectors=True)
        w, V, off = P.eigenvalues, P.eigenvectors, P.eig_offset
        if w is None:
            w, V, off = np.array([math.nan]), np.zeros((len(P.u), 1)), None
        # crit: a global eigenvalue index; turned into an index into the window w
        if crit is None or off is None or not 0 <= crit - off < len(w):
            crit = int(np.argmin(np.abs(w)))
        else:
            crit = crit - off
        # multiplicity: eigenvalues whose linear extrapolation (in arclength) vanishes near P
        members = [crit]
        ref = ref if ref is not None else A
        ref = self._with_eigs(ref, k)
        sig_ref = eng.dot(A.t_u, A.t_lam, ref.u - A.u, ref.lam - A.lam)
        dsig = sig - sig_ref
        lam_scale = eng.lam_scale
        tol_param = self.cluster_tol * max(abs(P.lam), lam_scale)
        if ref.eigenvalues is not None and abs(dsig) > 0 and off is not None and ref.eig_offset is not None:
            wr = {ref.eig_offset + i: v for i, v in enumerate(ref.eigenvalues)}
            slopes = [(w[i] - wr[off + i]) / dsig if off + i in wr else 0.0 for i in range(len(w))]
            dlam_dsig = (P.lam - ref.lam) / dsig if kind != "fold" else None
            for i in range(len(w)):
                if i == crit or slopes[i] == 0 or not np.isfinite(slopes[i]):
                    continue
                dist_sig = abs(w[i] / slopes[i])                      # arclength to its zero
                if kind == "fold" or dlam_dsig is None:
                    dist = dist_sig * lam_scale
                else:
                    dist = dist_sig * max(abs(dlam_dsig), 1e-300)     # in parameter units
                if dist <= tol_param:
                    members.append(i)
        members.sort()
        modes = V[:, members].copy()
        for j in range(modes.shape[1]):   # sign convention: the largest entry is positive
            if modes[np.argmax(np.abs(modes[:, j])), j] < 0:
                modes[:, j] *= -1
        if n_before is not None and n_after is not None and kind != "possible_branch":
            # the bracket ends may lie beyond other crossings: count this point's own change
            sgn = 1 if n_after > n_before else -1
            n_after = n_before + sgn * (len(members) if kind == "branch" else 1)
        info = {"eigen_index": None if off is None else off + crit, "members": members, "sigma": sig,
                "sigma_error": getattr(self, "last_error", math.nan)}
        p = SpecialPoint(kind=kind, parameter=float(P.lam), s=s_A + sig, u=P.u.copy(), tangent=(P.t_u, P.t_lam),
                         eigenvalues=w, modes=modes, multiplicity=len(members), n_negative_before=n_before,
                         n_negative_after=n_after, step=step, bracket=tuple(sorted(bracket)), info=info,
                         weights=eng.w, parameter_scale=eng.lam_scale)
        self.branch.special_points.append(p)
        self.add_row(P, s_A + sig, step, ds=sig, special=p.label)
        if self.log:
            self.log(f"    {p.summary()}")
        return p

    def _detect_dip(self, pts, step, cache, A, s_A):
        """An eigenvalue that dips towards zero at the middle of three points without a sign change."""
        (P0, s0), (P1, s1), (P2, s2) = pts[-3:]
        if any(P.eigenvalues is None for P in (P0, P1, P2)):
            return []
        if len({P0.n_negative, P1.n_negative, P2.n_negative}) != 1:
            return []
        if any(P.eig_offset is None for P in (P0, P1, P2)):
            return []
        # the eigenvalue nearest zero at the middle point, followed by its index to the others
        g = P1.eig_offset + int(np.argmin(np.abs(P1.eigenvalues)))
        vals = []
        for P in (P0, P1, P2):
            i = g - P.eig_offset
            if not 0 <= i < len(P.eigenvalues):
                return []
            vals.append(float(P.eigenvalues[i]))
        for i in [g]:
            y = np.array(vals)
            if not (np.sign(y[0]) == np.sign(y[1]) == np.sign(y[2])):
                continue
            a = np.abs(y)
            if not (a[1] < a[0] and a[1] < a[2]):
                continue
            x = np.array([s0, s1, s2]) - s1
            try:
                c2, c1, c0 = np.polyfit(x, y, 2)
            except (np.linalg.LinAlgError, ValueError):
                continue
            if c2 == 0:
                continue
            xv = -c1 / (2 * c2)
            yv = c0 - c1 * c1 / (4 * c2)
            if not (x[0] < xv < x[2]):
                continue
            if not (abs(yv) <= self.dip_tol * max(a[0], a[2]) or np.sign(yv) != np.sign(y[1])):
                continue
            # evaluate at the vertex (on the step that contains it)
            k = max(self.n_eigs, 3)
            if xv <= 0:
                base, sig, base_s, ref = P0, xv - x[0], s0, P1
            else:
                base, sig, base_s, ref = P1, xv, s1, P0
            P = self.point_at(base, sig, k, cache if base is A else {})
            kind = "possible_branch"
            p = self._special(kind, base, P, sig, base_s, step, k, P1.n_negative, P1.n_negative, (P.lam, P.lam),
                              crit=i, ref=ref)
            # rows must stay in arclength order: move the special row before B if it lies before A
            if xv <= 0:
                row = self.branch.rows.pop()
                st = self.branch.states.pop()
                pos = len(self.branch.rows) - 1  # before A's row
                self.branch.rows.insert(pos, row)
                self.branch.states.insert(pos, st)
            return [p]
        return []


# =============================================================================== branch switching

def switch_branch(problem, special_point: SpecialPoint, mode=None, amplitude=None, *, ds=None, sign=+1,
                  label=None, **options) -> Branch:
    r"""Start a new branch at a branch point and follow it with :func:`continuation`.

    Parameters
    ----------
    special_point : a :class:`SpecialPoint` of kind "branch" or "possible_branch".
    mode : None (the first critical mode), an int (that critical mode), an array of
        ``multiplicity`` coefficients (a combination of the critical modes, e.g. cos/sin
        of a double disk mode), or a full vector of the unknowns.
    amplitude : distance a of the first point from the branch point in the weighted
        arclength norm (default: ``ds``); its sign (or ``sign=-1``) picks the half of a
        pitchfork.
    ds : first step on the new branch (default: |amplitude| or 0.1).
    options : passed to :func:`continuation` (ds_max, lam_stop, max_steps, record, ...).
        The weights and parameter scale of the original branch are used unless given.

    The start is (u*, λ*) + a·t_new, t_new = (φ, 0) made W-orthogonal to the old tangent
    and normalised; the first corrector works on the hyperplane orthogonal to t_new
    through that start, so it cannot fall back onto the old branch near u*.
    """
    p = special_point
    if not isinstance(p, SpecialPoint):
        raise TypeError(f"special_point must be a SpecialPoint (from branch.special_points), got {type(p).__name__}")
    if p.kind not in ("branch", "possible_branch"):
        raise ValueError(f"branch switching needs a branch point, got a {p.kind!r} point "
                         f"(at a fold the branch turns; continue through it instead)")
    if not p.located or p.modes.shape[1] == 0:
        raise ValueError(f"the branch point between parameters {p.bracket[0]:.8g} and {p.bracket[1]:.8g} was detected "
                         f"but not located, so it has no critical mode to switch along ({p.info.get('reason', '')}); "
                         "follow the branch again with a smaller ds_max")
    n = len(p.u)
    if mode is None:
        phi = p.modes[:, 0]
    elif np.ndim(mode) == 0:
        i = int(mode)
        if not 0 <= i < p.modes.shape[1]:
            raise ValueError(f"mode index must be in 0..{p.modes.shape[1] - 1}, got {mode}")
        phi = p.modes[:, i]
    else:
        coeffs = np.asarray(mode, float).ravel()
        if len(coeffs) == p.modes.shape[1]:
            phi = p.modes @ coeffs
        elif len(coeffs) == n:
            phi = coeffs
        else:
            raise ValueError(f"mode must have {p.modes.shape[1]} coefficients (the multiplicity) or {n} "
                             f"entries (a vector of unknowns), got {len(coeffs)}")
    weights = options.pop("weights", p.weights)
    if weights is None:
        weights = problem.dof_weights() if hasattr(problem, "dof_weights") else np.ones(n)
    weights = np.broadcast_to(np.asarray(weights, float), (n,))
    lam_scale = options.pop("parameter_scale", p.parameter_scale)
    if not (np.isfinite(lam_scale) and lam_scale > 0):
        raise ValueError(f"parameter_scale must be a finite number > 0, got {lam_scale}")
    wl = 1.0 / lam_scale**2

    def dot(au, al, bu, bl):
        return float(au @ (weights * bu)) / n + wl * al * bl

    tu, tl = p.tangent
    tnorm = math.sqrt(dot(tu, tl, tu, tl))
    tu, tl = tu / tnorm, tl / tnorm
    proj = dot(phi, 0.0, tu, tl)
    nu_, nl = phi - proj * tu, -proj * tl
    nn = math.sqrt(max(dot(nu_, nl, nu_, nl), 0.0))
    if not nn > 0:
        raise ValueError("the chosen mode is parallel to the old branch's tangent")
    nu_, nl = nu_ / nn, nl / nn
    if amplitude is None:
        amplitude = ds if ds is not None else 0.1
    a = float(amplitude) * (1.0 if sign >= 0 else -1.0)
    if not (math.isfinite(a) and a != 0):
        raise ValueError(f"amplitude must be a finite number != 0 (the jump onto the new branch), got {amplitude}")
    if ds is None:
        ds = abs(a) if a != 0 else 0.1
    s_ = 1.0 if a >= 0 else -1.0
    u_start = p.u + a * nu_
    lam_start = p.parameter + a * nl
    branch = continuation(problem, u_start, lam_start, ds=ds, initial_tangent=(s_ * nu_, s_ * nl),
                          weights=weights, parameter_scale=lam_scale,
                          label=label or f"from {p.label} at {p.parameter:.6g}", **options)
    branch.origin = p
    return branch
